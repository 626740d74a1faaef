// The organ's visible silhouette in the camera, distances to it and the contour's and curves' residuals (registration).
#include <rehearse/simcore/registration.hpp>

#include "registration_parts.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <queue>
#include <set>
#include <unordered_map>

namespace rehearse::simcore {

namespace detail {

void checkCamera(const Pinhole& c) {
  if (!(c.K(0, 0) > 0) || !(c.K(1, 1) > 0) || c.width <= 0 || c.height <= 0 || !c.K.allFinite() ||
      std::abs(c.K(2, 2) - 1) > 1e-9)
    throw MeshError(
        "The camera is unusable (its focal lengths and image size must be positive); load a calibration first.");
}

// "0.57 px", for statuses.
std::string pixels(double px) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f px", px);
  return text;
}

// Closest point of segment [a, b] to p: returns the parameter in [0, 1].
double closestParameter(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p) {
  const Eigen::Vector2d d = b - a;
  const double l2 = d.squaredNorm();
  return l2 > 0 ? std::clamp((p - a).dot(d) / l2, 0.0, 1.0) : 0.0;
}

// Distance from p to the nearest silhouette edge (px).
double distanceToSilhouette(const std::vector<SilhouetteEdge>& silhouette, const Eigen::Vector2d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& e : silhouette) {
    double d;
    e.nearest(p, &d);
    best = std::min(best, d);
  }
  return best;
}

Foot nearestOnPolyline(const std::vector<Eigen::Vector2d>& line, const Eigen::Vector2d& p) {
  Foot f;
  if (line.size() == 1) return {line[0], Eigen::Vector2d::Zero(), (line[0] - p).norm(), true};
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d tangent = line[i + 1] - line[i];
    const double t = closestParameter(line[i], line[i + 1], p);
    const Eigen::Vector2d q = line[i] + t * tangent;
    const double d = (q - p).norm();
    const Eigen::Vector2d n =
        tangent.norm() > 0 ? Eigen::Vector2d(-tangent.y(), tangent.x()).normalized() : Eigen::Vector2d::Zero();
    if (d < f.distance) f = {q, n, d, (i == 0 && t == 0.0) || (i + 2 == line.size() && t == 1.0)};
  }
  return f;
}

Eigen::Vector3d point(const Eigen::VectorXd& x, const Binding& b) {
  return (1 - b.t) * x.segment<3>(3 * b.a) + b.t * x.segment<3>(3 * b.b) + 4 * b.t * (1 - b.t) * b.bulge;
}

}  // namespace detail

using namespace detail;

double SilhouetteEdge::nearest(const Eigen::Vector2d& p, double* distance) const {
  const double s0 = closestParameter(pa, pm, p), s1 = closestParameter(pm, pb, p);
  const double d0 = (pa + s0 * (pm - pa) - p).norm(), d1 = (pm + s1 * (pb - pm) - p).norm();
  if (distance) *distance = std::min(d0, d1);
  return d0 <= d1 ? 0.5 * s0 : 0.5 + 0.5 * s1;
}

std::vector<SilhouetteEdge> visibleSilhouette(const std::vector<std::array<int, 3>>& triangles,
                                              const Eigen::VectorXd& x, const Pose& pose, const Pinhole& camera) {
  checkCamera(camera);
  const std::size_t n = static_cast<std::size_t>(x.size() / 3);
  std::vector<Eigen::Vector3d> pc(n);
  std::vector<Eigen::Vector2d> pix(n);
  std::vector<char> used(n, 0);
  for (const auto& t : triangles)
    for (int v : t) {
      if (v < 0 || static_cast<std::size_t>(v) >= n)
        throw MeshError("A surface triangle refers to a node that does not exist.");
      used[v] = 1;
    }
  for (std::size_t i = 0; i < n; ++i) {
    pc[i] = pose.apply(x.segment<3>(3 * i));
    if (!used[i]) continue;
    if (!(pc[i].z() > 1e-6) || !pc[i].allFinite())
      throw MeshError(
          "The organ is behind the camera (or crosses its image plane); place it in front of the camera first.");
    pix[i] = camera.project(pc[i]);
  }
  // Vertex normals (area-weighted, model frame) for the edges' bulge.
  std::vector<Eigen::Vector3d> normals(n, Eigen::Vector3d::Zero());
  for (const auto& t : triangles) {
    const Eigen::Vector3d a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
    const Eigen::Vector3d fn = (b - a).cross(c - a);
    for (int v : t) normals[v] += fn;
  }
  for (auto& nv : normals)
    if (nv.norm() > 0) nv.normalize();
  // Front faces (the nearest surface of a closed organ is always a front face, so only they are drawn).
  std::vector<char> front(triangles.size(), 0);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const auto& t = triangles[f];
    front[f] = (pc[t[1]] - pc[t[0]]).cross(pc[t[2]] - pc[t[0]]).dot(pc[t[0]]) < 0;
  }
  // Depth buffer at up to 800 pixels across (it only decides which vertices are hidden; the silhouette's
  // edges are the exact projected mesh edges): the nearest depth per pixel.
  const double scale = std::min(1.0, 800.0 / std::max(camera.width, camera.height));
  const int W = std::max(1, static_cast<int>(camera.width * scale)),
            H = std::max(1, static_cast<int>(camera.height * scale));
  std::vector<float> depth(static_cast<std::size_t>(W) * H, std::numeric_limits<float>::infinity());
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    if (!front[f]) continue;
    const auto& t = triangles[f];
    const Eigen::Vector2d a = pix[t[0]] * scale, b = pix[t[1]] * scale, c = pix[t[2]] * scale;
    const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (std::abs(area) < 1e-12) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()})))),
              x1 = std::min(W - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()})))),
              y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()})))),
              y1 = std::min(H - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
    const double iz[3] = {1 / pc[t[0]].z(), 1 / pc[t[1]].z(), 1 / pc[t[2]].z()};
    for (int py = y0; py <= y1; ++py)
      for (int px = x0; px <= x1; ++px) {
        const Eigen::Vector2d p(px + 0.5, py + 0.5);
        const double w0 = ((b - p).x() * (c - p).y() - (b - p).y() * (c - p).x()) / area;
        const double w1 = ((c - p).x() * (a - p).y() - (c - p).y() * (a - p).x()) / area;
        const double w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float z = static_cast<float>(1 / (w0 * iz[0] + w1 * iz[1] + w2 * iz[2]));  // perspective-correct
        float& d = depth[static_cast<std::size_t>(py) * W + px];
        d = std::min(d, z);
      }
  }
  // A vertex is visible unless a nearer surface covers all of its 3x3 pixel neighbourhood.
  std::vector<char> visible(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!used[i]) continue;
    const int px = static_cast<int>(std::floor(pix[i].x() * scale)),
              py = static_cast<int>(std::floor(pix[i].y() * scale));
    const double eps = 2e-3 * pc[i].z() + 1e-4;
    bool vis = px < 0 || py < 0 || px >= W || py >= H;  // outside the image: not occluded by anything drawn
    for (int dy = -1; dy <= 1 && !vis; ++dy)
      for (int dx = -1; dx <= 1 && !vis; ++dx) {
        const int qx = px + dx, qy = py + dy;
        if (qx < 0 || qy < 0 || qx >= W || qy >= H) continue;
        vis = depth[static_cast<std::size_t>(qy) * W + qx] >= pc[i].z() - eps;
      }
    visible[i] = vis;
  }
  // Visible faces: front-facing with three visible vertices.
  std::vector<char> faceVisible(triangles.size(), 0);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const auto& t = triangles[f];
    faceVisible[f] = front[f] && visible[t[0]] && visible[t[1]] && visible[t[2]];
  }
  // Silhouette: edges between a visible face and a non-visible one (or no other face). Edges as (low
  // node, high node, face), sorted so the two faces of an edge are neighbours.
  std::vector<std::array<int, 3>> halfEdges;
  halfEdges.reserve(3 * triangles.size());
  for (std::size_t f = 0; f < triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = triangles[f][k], b = triangles[f][(k + 1) % 3];
      halfEdges.push_back({std::min(a, b), std::max(a, b), static_cast<int>(f)});
    }
  std::sort(halfEdges.begin(), halfEdges.end());
  std::vector<SilhouetteEdge> out;
  for (std::size_t i = 0; i < halfEdges.size();) {
    std::size_t j = i + 1;
    while (j < halfEdges.size() && halfEdges[j][0] == halfEdges[i][0] && halfEdges[j][1] == halfEdges[i][1]) ++j;
    const int f0 = halfEdges[i][2], f1 = j - i >= 2 ? halfEdges[i + 1][2] : -1;
    const int edgeA = halfEdges[i][0], edgeB = halfEdges[i][1];
    i = j;
    const bool v0 = faceVisible[f0], v1 = f1 >= 0 && faceVisible[f1];
    if (v0 == v1) continue;
    const int vf = v0 ? f0 : f1;
    SilhouetteEdge e;
    e.a = edgeA;
    e.b = edgeB;
    e.pa = pix[e.a];
    e.pb = pix[e.b];
    const Eigen::Vector2d d = e.pb - e.pa;
    if (d.norm() < 1e-9) continue;
    e.normal = Eigen::Vector2d(-d.y(), d.x()).normalized();
    int third = triangles[vf][0];
    for (int v : triangles[vf])
      if (v != e.a && v != e.b) third = v;
    if (e.normal.dot(pix[third] - e.pa) > 0) e.normal = -e.normal;  // away from the visible face
    // PN-triangle edge: the middle of the cubic through the nodes tangent to their planes. At most a
    // quarter of the edge's length (creases and bad normals would otherwise throw it far off).
    const Eigen::Vector3d A = x.segment<3>(3 * e.a), B = x.segment<3>(3 * e.b);
    e.bulge = -((B - A).dot(normals[e.a]) * normals[e.a] + (A - B).dot(normals[e.b]) * normals[e.b]) / 8;
    const double cap = 0.25 * (B - A).norm();
    if (!(e.bulge.norm() <= cap))
      e.bulge = e.bulge.allFinite() && e.bulge.norm() > 0 ? Eigen::Vector3d(e.bulge.normalized() * cap)
                                                          : Eigen::Vector3d::Zero();
    const Eigen::Vector3d mid = pose.apply(0.5 * (A + B) + e.bulge);
    e.pm = mid.z() > 1e-6 ? camera.project(mid) : Eigen::Vector2d(0.5 * (e.pa + e.pb));
    out.push_back(e);
  }
  return out;
}

Residual2D contourResidual(const std::vector<std::vector<Eigen::Vector2d>>& contour,
                           const std::vector<SilhouetteEdge>& silhouette) {
  ResidualSum sum;
  for (const auto& seg : contour)
    for (const auto& p : seg) sum.add(distanceToSilhouette(silhouette, p));
  return sum.result();
}

std::vector<int> surfacePath(const std::vector<std::array<int, 3>>& triangles,
                             const std::vector<Eigen::Vector3d>& points, int from, int to) {
  const int n = static_cast<int>(points.size());
  if (from < 0 || to < 0 || from >= n || to >= n) return {};
  if (from == to) return {from};
  std::vector<std::vector<int>> neighbours(points.size());
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      if (a < 0 || b < 0 || a >= n || b >= n) continue;
      neighbours[a].push_back(b);
      neighbours[b].push_back(a);
    }
  std::vector<double> dist(points.size(), std::numeric_limits<double>::infinity());
  std::vector<int> previous(points.size(), -1);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  dist[from] = 0;
  queue.push({0.0, from});
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > dist[v]) continue;
    if (v == to) break;
    for (int w : neighbours[v]) {
      const double nd = d + (points[w] - points[v]).norm();
      if (nd < dist[w]) {
        dist[w] = nd;
        previous[w] = v;
        queue.push({nd, w});
      }
    }
  }
  if (previous[to] < 0) return {};
  std::vector<int> path{to};
  while (path.back() != from) path.push_back(previous[path.back()]);
  std::reverse(path.begin(), path.end());
  return path;
}

Residual2D curveResidual(const std::vector<AnatomicalCurve>& curves, const Eigen::VectorXd& x, const Pose& pose,
                         const Pinhole& camera) {
  ResidualSum sum;
  std::vector<Eigen::Vector2d> projected;
  for (const auto& c : curves) {
    projected.clear();
    for (int node : c.nodes) {
      const Eigen::Vector3d q = pose.apply(x.segment<3>(3 * node));
      if (!(q.z() > 1e-6))
        throw MeshError(
            "A node of an anatomical curve is behind the camera; place the organ in front of the camera first.");
      projected.push_back(camera.project(q));
    }
    if (projected.empty()) continue;
    for (const auto& p : c.image) sum.add(nearestOnPolyline(projected, p).distance);
  }
  return sum.result();
}

}  // namespace rehearse::simcore
