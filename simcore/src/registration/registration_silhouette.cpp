// The organ's visible silhouette in the camera, distances to it and the contour's and curves' residuals (registration).
#include <rehearse/simcore/registration.hpp>

#include "registration_parts.hpp"

#include <algorithm>
#include <array>
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

SilhouetteGrid::SilhouetteGrid(const std::vector<SilhouetteEdge>& edges) : edges_(edges) {
  if (edges.empty()) return;
  Eigen::Vector2d lo = edges[0].pa, hi = edges[0].pa;
  for (const auto& e : edges)
    for (const Eigen::Vector2d& q : {e.pa, e.pm, e.pb}) {
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  if (!lo.allFinite() || !hi.allFinite()) return;  // (no grid: every query tries every edge)
  // About one edge per cell, at least a pixel wide, at most 256 cells a side.
  const Eigen::Vector2d extent = (hi - lo).cwiseMax(1.0);
  cell_ = std::max({1.0, std::sqrt(extent.prod() / static_cast<double>(edges.size())), extent.maxCoeff() / 256});
  nx_ = static_cast<int>(extent.x() / cell_) + 1;
  ny_ = static_cast<int>(extent.y() / cell_) + 1;
  origin_ = lo;
  std::vector<std::array<int, 4>> boxes(edges.size());
  start_.assign(static_cast<std::size_t>(nx_) * ny_ + 1, 0);
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const auto& e = edges[i];
    const Eigen::Vector2d a = (e.pa.cwiseMin(e.pm).cwiseMin(e.pb) - origin_) / cell_,
                          b = (e.pa.cwiseMax(e.pm).cwiseMax(e.pb) - origin_) / cell_;
    boxes[i] = {std::clamp(static_cast<int>(a.x()), 0, nx_ - 1), std::clamp(static_cast<int>(a.y()), 0, ny_ - 1),
                std::clamp(static_cast<int>(b.x()), 0, nx_ - 1), std::clamp(static_cast<int>(b.y()), 0, ny_ - 1)};
    for (int y = boxes[i][1]; y <= boxes[i][3]; ++y)
      for (int x = boxes[i][0]; x <= boxes[i][2]; ++x) ++start_[static_cast<std::size_t>(y) * nx_ + x + 1];
  }
  for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
  items_.resize(static_cast<std::size_t>(start_.back()));
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (std::size_t i = 0; i < edges.size(); ++i)
    for (int y = boxes[i][1]; y <= boxes[i][3]; ++y)
      for (int x = boxes[i][0]; x <= boxes[i][2]; ++x)
        items_[static_cast<std::size_t>(fill[static_cast<std::size_t>(y) * nx_ + x]++)] = static_cast<int>(i);
}

int SilhouetteGrid::nearest(const Eigen::Vector2d& p, const Eigen::Vector2d& normal, double minDot, double& distance,
                            double& t) const {
  distance = std::numeric_limits<double>::infinity();
  t = 0;
  int best = -1;
  const bool any = normal.squaredNorm() == 0;
  auto tryEdge = [&](int i) {
    const auto& e = edges_[static_cast<std::size_t>(i)];
    if (!any && std::abs(normal.dot(e.normal)) < minDot) return;
    double d;
    const double s = e.nearest(p, &d);
    if (d < distance || (d == distance && i < best)) distance = d, t = s, best = i;
  };
  if (nx_ == 0 || !p.allFinite()) {
    for (std::size_t i = 0; i < edges_.size(); ++i) tryEdge(static_cast<int>(i));
    return best;
  }
  // Rings of cells around p's (clamped into the grid): a cell r rings out is at least (r - 1) cells from p, so the
  // search stops once the nearest found is nearer than that.
  const Eigen::Vector2d q = (p - origin_) / cell_;
  const int cx =
                std::clamp(static_cast<int>(std::floor(std::clamp(q.x(), -1.0, static_cast<double>(nx_)))), 0, nx_ - 1),
            cy =
                std::clamp(static_cast<int>(std::floor(std::clamp(q.y(), -1.0, static_cast<double>(ny_)))), 0, ny_ - 1);
  const int rings = std::max({cx, nx_ - 1 - cx, cy, ny_ - 1 - cy});
  auto visit = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= nx_ || y >= ny_) return;
    const std::size_t c = static_cast<std::size_t>(y) * nx_ + x;
    for (int k = start_[c]; k < start_[c + 1]; ++k) tryEdge(items_[static_cast<std::size_t>(k)]);
  };
  for (int r = 0; r <= rings; ++r) {
    if (distance < (r - 1) * cell_) break;
    if (r == 0) {
      visit(cx, cy);
      continue;
    }
    for (int x = cx - r; x <= cx + r; ++x) visit(x, cy - r), visit(x, cy + r);
    for (int y = cy - r + 1; y <= cy + r - 1; ++y) visit(cx - r, y), visit(cx + r, y);
  }
  return best;
}

double SilhouetteGrid::distance(const Eigen::Vector2d& p) const {
  double d, t;
  nearest(p, Eigen::Vector2d::Zero(), 0, d, t);
  return d;
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

namespace {

// A surface's edges (low node, high node) in order with their first two faces (-1: none), from the triangles:
// (low node, high node, face) sorted, so the two faces of an edge are neighbours. Kept per thread for the last surface
// asked about (a fit asks hundreds of times for the same one; comparing the triangles costs far less than sorting).
const std::vector<std::array<int, 4>>& edgeFaces(const std::vector<std::array<int, 3>>& triangles) {
  thread_local std::vector<std::array<int, 3>> cachedTriangles;
  thread_local std::vector<std::array<int, 4>> cached;
  thread_local bool valid = false;
  if (valid && cachedTriangles == triangles) return cached;
  std::vector<std::array<int, 3>> halfEdges;
  halfEdges.reserve(3 * triangles.size());
  for (std::size_t f = 0; f < triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = triangles[f][k], b = triangles[f][(k + 1) % 3];
      halfEdges.push_back({std::min(a, b), std::max(a, b), static_cast<int>(f)});
    }
  std::sort(halfEdges.begin(), halfEdges.end());
  cached.clear();
  for (std::size_t i = 0; i < halfEdges.size();) {
    std::size_t j = i + 1;
    while (j < halfEdges.size() && halfEdges[j][0] == halfEdges[i][0] && halfEdges[j][1] == halfEdges[i][1]) ++j;
    cached.push_back({halfEdges[i][0], halfEdges[i][1], halfEdges[i][2], j - i >= 2 ? halfEdges[i + 1][2] : -1});
    i = j;
  }
  cachedTriangles = triangles;
  valid = true;
  return cached;
}

// The surface's nodes in the camera frame and in the image, and which of them its triangles use (only those are
// projected).
struct ProjectedNodes {
  std::vector<Eigen::Vector3d> pc;
  std::vector<Eigen::Vector2d> pix;
  std::vector<char> used;
};

ProjectedNodes projectNodes(const std::vector<std::array<int, 3>>& triangles, const Eigen::VectorXd& x,
                            const Pose& pose, const Pinhole& camera) {
  const std::size_t n = static_cast<std::size_t>(x.size() / 3);
  ProjectedNodes p{std::vector<Eigen::Vector3d>(n), std::vector<Eigen::Vector2d>(n), std::vector<char>(n, 0)};
  for (const auto& t : triangles)
    for (int v : t) {
      if (v < 0 || static_cast<std::size_t>(v) >= n)
        throw MeshError("A surface triangle refers to a node that does not exist.");
      p.used[v] = 1;
    }
  for (std::size_t i = 0; i < n; ++i) {
    p.pc[i] = pose.apply(x.segment<3>(3 * i));
    if (!p.used[i]) continue;
    if (!(p.pc[i].z() > 1e-6) || !p.pc[i].allFinite())
      throw MeshError(
          "The organ is behind the camera (or crosses its image plane); place it in front of the camera first.");
    p.pix[i] = camera.project(p.pc[i]);
  }
  return p;
}

// Vertex normals (area-weighted, model frame) for the edges' bulge.
std::vector<Eigen::Vector3d> vertexNormals(const std::vector<std::array<int, 3>>& triangles, const Eigen::VectorXd& x,
                                           std::size_t n) {
  std::vector<Eigen::Vector3d> normals(n, Eigen::Vector3d::Zero());
  for (const auto& t : triangles) {
    const Eigen::Vector3d a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
    const Eigen::Vector3d fn = (b - a).cross(c - a);
    for (int v : t) normals[v] += fn;
  }
  for (auto& nv : normals)
    if (nv.norm() > 0) nv.normalize();
  return normals;
}

// Depth buffer at up to 800 pixels across (it only decides which vertices are hidden; the silhouette's
// edges are the exact projected mesh edges): the nearest surface's inverse depth per pixel (affine in the image, so
// interpolated exactly along a row; 0: nothing drawn). Only the box the front faces cover is cleared (kept per
// thread: a fit asks hundreds of times).
struct DepthBuffer {
  double scale;
  int W, H;
  int bx0, bx1, by0, by1;  // the box drawn into
  std::vector<float>& inverseDepth;

  DepthBuffer(const Pinhole& camera, const std::vector<std::array<int, 3>>& triangles, const std::vector<char>& front,
              const std::vector<Eigen::Vector2d>& pix);
  void draw(const std::array<int, 3>& t, const std::vector<Eigen::Vector2d>& pix,
            const std::vector<Eigen::Vector3d>& pc);
  double depthAt(int x, int y) const {  // the nearest surface's depth there (infinite: nothing drawn)
    if (x < bx0 || x > bx1 || y < by0 || y > by1) return std::numeric_limits<double>::infinity();
    const float iz = inverseDepth[static_cast<std::size_t>(y) * W + x];
    return iz > 0 ? 1.0 / iz : std::numeric_limits<double>::infinity();
  }
  static std::vector<float>& threadBuffer() {
    thread_local std::vector<float> buffer;
    return buffer;
  }
};

DepthBuffer::DepthBuffer(const Pinhole& camera, const std::vector<std::array<int, 3>>& triangles,
                         const std::vector<char>& front, const std::vector<Eigen::Vector2d>& pix)
    : scale(std::min(1.0, 800.0 / std::max(camera.width, camera.height))),
      W(std::max(1, static_cast<int>(camera.width * scale))),
      H(std::max(1, static_cast<int>(camera.height * scale))),
      bx0(W),
      bx1(-1),
      by0(H),
      by1(-1),
      inverseDepth(threadBuffer()) {
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    if (!front[f]) continue;
    for (int v : triangles[f]) {
      const Eigen::Vector2d q = pix[v] * scale;
      // (clamped before the cast: a node just in front of the camera projects millions of pixels out)
      bx0 = std::min(bx0, static_cast<int>(std::clamp(std::floor(q.x()), 0.0, W - 1.0)));
      bx1 = std::max(bx1, static_cast<int>(std::clamp(std::ceil(q.x()), 0.0, W - 1.0)));
      by0 = std::min(by0, static_cast<int>(std::clamp(std::floor(q.y()), 0.0, H - 1.0)));
      by1 = std::max(by1, static_cast<int>(std::clamp(std::ceil(q.y()), 0.0, H - 1.0)));
    }
  }
  inverseDepth.resize(static_cast<std::size_t>(W) * H);
  for (int y = by0; y <= by1; ++y)
    std::fill_n(inverseDepth.begin() + static_cast<std::ptrdiff_t>(y) * W + bx0, std::max(0, bx1 - bx0 + 1), 0.0f);
}

// Draws front face `t` into the buffer.
void DepthBuffer::draw(const std::array<int, 3>& t, const std::vector<Eigen::Vector2d>& pix,
                       const std::vector<Eigen::Vector3d>& pc) {
  const Eigen::Vector2d corner[3] = {pix[t[0]] * scale, pix[t[1]] * scale, pix[t[2]] * scale};
  const Eigen::Vector2d &a = corner[0], &b = corner[1], &c = corner[2];
  const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
  if (std::abs(area) < 1e-12) return;
  const double left = std::floor(std::min({a.x(), b.x(), c.x()})), right = std::ceil(std::max({a.x(), b.x(), c.x()})),
               top = std::floor(std::min({a.y(), b.y(), c.y()})), bottom = std::ceil(std::max({a.y(), b.y(), c.y()}));
  if (right < 0 || bottom < 0 || left > W - 1 || top > H - 1) return;  // wholly outside the buffer
  const int x0 = static_cast<int>(std::max(left, 0.0)), x1 = static_cast<int>(std::min(right, W - 1.0)),
            y0 = static_cast<int>(std::max(top, 0.0)), y1 = static_cast<int>(std::min(bottom, H - 1.0));
  // The barycentric weights at pixel centre (X, Y): w_k = (e0 + ex X + ey Y) / area for the corners u, v after k;
  // the inverse depth the same weights' mix of the corners' (exact under perspective).
  double e0[3], ex[3], ey[3];
  double iz0 = 0, izx = 0, izy = 0;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2d &u = corner[(k + 1) % 3], &v = corner[(k + 2) % 3];
    // (u.x - X)(v.y - Y) - (u.y - Y)(v.x - X)
    e0[k] = (u.x() * v.y() - u.y() * v.x()) / area;
    ex[k] = (u.y() - v.y()) / area;
    ey[k] = (v.x() - u.x()) / area;
    const double iz = 1 / pc[t[k]].z();
    iz0 += e0[k] * iz, izx += ex[k] * iz, izy += ey[k] * iz;
  }
  for (int py = y0; py <= y1; ++py) {
    const double Y = py + 0.5;
    // The row's span inside the triangle: every weight >= 0 at the pixel centre px + 0.5.
    double from = x0, to = x1;
    for (int k = 0; k < 3; ++k) {
      const double offset = e0[k] + ey[k] * Y, slope = ex[k];
      if (slope > 0)
        from = std::max(from, std::ceil(-offset / slope - 0.5));
      else if (slope < 0)
        to = std::min(to, std::floor(-offset / slope - 0.5));
      else if (offset < 0)
        from = to + 1;
    }
    if (!(from <= to)) continue;
    float* row = inverseDepth.data() + static_cast<std::ptrdiff_t>(py) * W;
    const double rowIz = iz0 + izy * Y + izx * 0.5;
    for (int px = static_cast<int>(from), last = static_cast<int>(to); px <= last; ++px)
      row[px] = std::max(row[px], static_cast<float>(rowIz + izx * px));
  }
}

// A vertex is visible unless a nearer surface covers all of its 3x3 pixel neighbourhood.
std::vector<char> visibleNodes(const ProjectedNodes& p, const DepthBuffer& depth) {
  const std::size_t n = p.pc.size();
  const double scale = depth.scale;
  const int W = depth.W, H = depth.H;
  std::vector<char> visible(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!p.used[i]) continue;
    const int px = static_cast<int>(std::clamp(std::floor(p.pix[i].x() * scale), -2.0, W + 1.0)),
              py = static_cast<int>(std::clamp(std::floor(p.pix[i].y() * scale), -2.0, H + 1.0));
    const double eps = 2e-3 * p.pc[i].z() + 1e-4;
    bool vis = px < 0 || py < 0 || px >= W || py >= H;  // outside the image: not occluded by anything drawn
    for (int dy = -1; dy <= 1 && !vis; ++dy)
      for (int dx = -1; dx <= 1 && !vis; ++dx) {
        const int qx = px + dx, qy = py + dy;
        if (qx < 0 || qy < 0 || qx >= W || qy >= H) continue;
        vis = depth.depthAt(qx, qy) >= p.pc[i].z() - eps;
      }
    visible[i] = vis;
  }
  return visible;
}

// The silhouette edge between nodes a and b of visible face `vf`: its normal away from the face and its bulge. False
// when it is too short to have a normal.
bool silhouetteEdge(int a, int b, const std::array<int, 3>& vf, const Eigen::VectorXd& x,
                    const std::vector<Eigen::Vector3d>& normals, const std::vector<Eigen::Vector2d>& pix,
                    const Pose& pose, const Pinhole& camera, SilhouetteEdge& e) {
  e.a = a;
  e.b = b;
  e.pa = pix[e.a];
  e.pb = pix[e.b];
  const Eigen::Vector2d d = e.pb - e.pa;
  if (d.norm() < 1e-9) return false;
  e.normal = Eigen::Vector2d(-d.y(), d.x()).normalized();
  int third = vf[0];
  for (int v : vf)
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
  return true;
}

}  // namespace

std::vector<SilhouetteEdge> visibleSilhouette(const std::vector<std::array<int, 3>>& triangles,
                                              const Eigen::VectorXd& x, const Pose& pose, const Pinhole& camera) {
  checkCamera(camera);
  const std::size_t n = static_cast<std::size_t>(x.size() / 3);
  const ProjectedNodes p = projectNodes(triangles, x, pose, camera);
  const std::vector<Eigen::Vector3d>& pc = p.pc;
  const std::vector<Eigen::Vector3d> normals = vertexNormals(triangles, x, n);
  // Front faces (the nearest surface of a closed organ is always a front face, so only they are drawn).
  std::vector<char> front(triangles.size(), 0);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const auto& t = triangles[f];
    front[f] = (pc[t[1]] - pc[t[0]]).cross(pc[t[2]] - pc[t[0]]).dot(pc[t[0]]) < 0;
  }
  DepthBuffer depth(camera, triangles, front, p.pix);
  for (std::size_t f = 0; f < triangles.size(); ++f)
    if (front[f]) depth.draw(triangles[f], p.pix, pc);
  const std::vector<char> visible = visibleNodes(p, depth);
  // Visible faces: front-facing with three visible vertices.
  std::vector<char> faceVisible(triangles.size(), 0);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const auto& t = triangles[f];
    faceVisible[f] = front[f] && visible[t[0]] && visible[t[1]] && visible[t[2]];
  }
  // Silhouette: edges between a visible face and a non-visible one (or no other face).
  std::vector<SilhouetteEdge> out;
  for (const auto& [edgeA, edgeB, f0, f1] : edgeFaces(triangles)) {
    const bool v0 = faceVisible[f0], v1 = f1 >= 0 && faceVisible[f1];
    if (v0 == v1) continue;
    const int vf = v0 ? f0 : f1;
    SilhouetteEdge e;
    if (silhouetteEdge(edgeA, edgeB, triangles[vf], x, normals, p.pix, pose, camera, e)) out.push_back(e);
  }
  return out;
}

Residual2D contourResidual(const std::vector<std::vector<Eigen::Vector2d>>& contour,
                           const std::vector<SilhouetteEdge>& silhouette) {
  ResidualSum sum;
  const SilhouetteGrid grid(silhouette);
  for (const auto& seg : contour)
    for (const auto& p : seg) sum.add(grid.distance(p));
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
