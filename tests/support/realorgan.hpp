#pragma once
// A real organ seen through a real laparoscope, for the elastic fit's test and benchmark (issue 13): the
// organ's surface from ../shared/data in metres, the scikit-surgery camera, the view of the organ's broad
// face, the region that holds it (its back), and markers on the surface the camera sees.
#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

namespace rehearse::testing {

/// Metres, whatever the file's unit (the files are in mm or m; no organ is over 2 m or under 2 cm across);
/// only the labelled part `part` when given.
inline simcore::Mesh loadOrganSurface(const std::string& path, const std::string& part = {}) {
  // Read as mm (loadMesh refuses coordinates beyond 10 m, which a mm file read as metres has); a file in metres then
  // measures under 2 mm across and is scaled back below, the same test as before in the other unit.
  simcore::Mesh m = simcore::loadMesh(path, {"mm"});
  if (!part.empty()) {
    std::vector<std::array<int, 3>> kept;
    for (std::size_t i = 0; i < m.triangles.size(); ++i)
      if (m.labelName(m.triangleLabels[i]) == part) kept.push_back(m.triangles[i]);
    if (kept.empty()) throw simcore::MeshError(path + " has no part named " + part);
    m.triangles = kept;
    m.triangleLabels.assign(kept.size(), 1);
    m.labelNames = {{1, part}};
    m.compact();
  }
  m.convertToMetres();
  Eigen::AlignedBox3d box;
  for (const auto& p : m.points) box.extend(p);
  if (box.diagonal().norm() <= 2e-3)
    for (auto& p : m.points) p *= 1e3;
  return m;
}

/// The scikit-surgery laparoscope (its calibration of the 1920x1080 frame in ../shared/data).
inline imaging::Camera scikitSurgeryCamera() {
  imaging::Camera cam;
  cam.K << 2012.186314, 0, 944.7173708, 0, 2017.966019, 617.1093984, 0, 0, 1;
  cam.width = 1920;
  cam.height = 1080;
  return cam;
}

/// The organ's broadest face towards the camera (principal axes: largest along the image's x, smallest
/// along the view), tilted 15 and 10 degrees so it is not a textbook view, at the depth where it spans 70 %
/// of the image, its centre on the image's centre.
inline Pose broadsideView(const simcore::Mesh& volume, const imaging::Camera& cam) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : volume.points) c += p;
  c /= static_cast<double>(volume.points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : volume.points) cov += (p - c) * (p - c).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  Eigen::Matrix3d R0;
  R0.row(0) = es.eigenvectors().col(2).transpose();
  R0.row(1) = es.eigenvectors().col(1).transpose();
  R0.row(2) = es.eigenvectors().col(0).transpose();
  if (R0.determinant() < 0) R0.row(2) *= -1;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(15 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix() *
                            Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix() * R0;
  double ex = 0, ey = 0, ez = 0;
  for (const auto& p : volume.points) {
    const Eigen::Vector3d q = R * (p - c);
    ex = std::max(ex, std::abs(q.x())), ey = std::max(ey, std::abs(q.y())), ez = std::max(ez, std::abs(q.z()));
  }
  const double z = std::max(2 * ex * cam.fx() / (0.7 * cam.width), 2 * ey * cam.fy() / (0.7 * cam.height)) + ez;
  Pose pose;
  pose.R = R;
  pose.t = Eigen::Vector3d(0, 0, z) - R * c;
  pose.t.x() += (0.5 * cam.width - cam.cx()) * z / cam.fx();
  pose.t.y() += (0.5 * cam.height - cam.cy()) * z / cam.fy();
  return pose;
}

/// The nodes on a volume mesh's surface, sorted.
inline std::vector<int> surfaceNodes(const simcore::Mesh& v) {
  std::vector<int> nodes;
  for (const auto& t : simcore::boundaryTriangles(v, false)) nodes.insert(nodes.end(), t.begin(), t.end());
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

/// The `share` of a volume mesh's surface nodes highest against gravity along +y (smallest y; at least 3): what holds a
/// real organ in the benchmarks and tests that hang it with gravity down the image.
inline std::vector<int> highestSurfaceNodes(const simcore::Mesh& v, double share) {
  std::vector<std::pair<double, int>> height;
  for (int n : surfaceNodes(v)) height.emplace_back(v.points[static_cast<std::size_t>(n)].y(), n);
  std::sort(height.begin(), height.end());
  std::vector<int> held;
  const auto count = std::min(height.size(), std::max<std::size_t>(3, static_cast<std::size_t>(share * height.size())));
  for (std::size_t k = 0; k < count; ++k) held.push_back(height[k].second);
  return held;
}

/// The picks an assistant makes to hold an organ under gravity along +z (issue 61): none, one node, 22 along its top
/// (the surface nodes highest against gravity: a thin band), the 8 % highest. Each named.
inline std::vector<std::pair<const char*, std::vector<int>>> assistantPicks(const simcore::Mesh& v) {
  std::vector<std::pair<double, int>> height;
  for (int n : surfaceNodes(v)) height.emplace_back(v.points[static_cast<std::size_t>(n)].z(), n);
  std::sort(height.begin(), height.end());
  auto highest = [&](std::size_t count) {
    std::vector<int> held;
    for (std::size_t k = 0; k < count && k < height.size(); ++k) held.push_back(height[k].second);
    return held;
  };
  return {{"none", {}},
          {"one", highest(1)},
          {"22 along the top", highest(22)},
          {"8 % highest", highest(static_cast<std::size_t>(0.08 * static_cast<double>(height.size())))}};
}

/// Where the grasper bites free tissue on an organ held by `held` under gravity along +z (issue 61's pulls): the front
/// surface node nearest the organ's middle across the view (within 30 mm of it), at least 15 mm from every held node;
/// and the direction across the view away from the held nodes (-y with none). bite -1: no such node.
struct FreeBite {
  int bite = -1;
  Eigen::Vector3d away = Eigen::Vector3d(0, -1, 0);
};
inline FreeBite freeBite(const simcore::Mesh& v, const std::vector<Eigen::Vector3d>& shape, const std::vector<int>& held) {
  FreeBite b;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : shape) centre += p;
  centre /= static_cast<double>(shape.size());
  double best = 1e300;
  for (int n : surfaceNodes(v)) {
    const Eigen::Vector3d& p = shape[static_cast<std::size_t>(n)];
    bool free = true;
    for (int h : held) free = free && (shape[static_cast<std::size_t>(h)] - p).norm() >= 0.015;
    if (!free || (p - centre).head<2>().norm() > 0.03) continue;
    if (p.z() < best) best = p.z(), b.bite = n;
  }
  if (b.bite < 0 || held.empty()) return b;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int h : held) mean += shape[static_cast<std::size_t>(h)];
  mean /= static_cast<double>(held.size());
  Eigen::Vector3d away = shape[static_cast<std::size_t>(b.bite)] - mean;
  away.z() = 0;
  if (away.norm() > 1e-6) b.away = away.normalized();
  return b;
}

/// A real organ's surface meshed as the rehearsal meshes it (self-intersections allowed, seed 0), about `tets` tets.
inline simcore::Mesh meshedOrgan(const simcore::Mesh& surface, std::size_t tets) {
  simcore::TetrahedraliseOptions to;
  to.allowSelfIntersections = true;
  to.targetTets = tets;
  to.seed = 0;
  return simcore::tetrahedraliseSurface(surface, to);
}

/// The depth (m, camera frame at `pose`) beyond which lie the `share` of the surface nodes farthest from
/// the camera.
inline double farthestShareDepth(const simcore::Mesh& v, const Pose& pose, double share) {
  std::vector<double> z;
  for (int n : surfaceNodes(v)) z.push_back(pose.apply(v.points[n]).z());
  std::sort(z.begin(), z.end());
  z.erase(std::unique(z.begin(), z.end()), z.end());
  return z[std::min(z.size() - 1, static_cast<std::size_t>(static_cast<double>(z.size()) * (1 - share)))];
}

/// Surface nodes at or beyond `depth` (the held back of the organ).
inline std::vector<int> surfaceNodesBeyond(const simcore::Mesh& v, const Pose& pose, double depth) {
  std::vector<int> held;
  for (int n : surfaceNodes(v))
    if (pose.apply(v.points[n]).z() >= depth) held.push_back(n);
  return held;
}

/// Up to `count` of the surface nodes the camera sees on the deformed mesh (`deformed`: positions per
/// node), spread by farthest-point sampling over the rest positions.
inline std::vector<int> visibleMarkers(const simcore::Mesh& rest, const std::vector<Eigen::Vector3d>& deformed,
                                       const Pose& pose, const imaging::Camera& cam, std::size_t count) {
  const auto tris = simcore::boundaryTriangles(rest, false);
  std::vector<double> verts;
  for (const auto& p : deformed) verts.insert(verts.end(), {p.x(), p.y(), p.z()});
  const SurfaceView view{verts.data(), deformed.size(), tris.front().data(), tris.size()};
  const imaging::Rasterization ras = imaging::rasterize(cam, pose, view);
  std::vector<int> visible;
  for (int n : surfaceNodes(rest)) {
    const Eigen::Vector3d q = pose.apply(deformed[n]);
    const Eigen::Vector2d px = cam.project(q);
    const int x = static_cast<int>(px.x()), y = static_cast<int>(px.y());
    if (x < 0 || y < 0 || x >= cam.width || y >= cam.height) continue;
    if (std::abs(ras.depth(y, x) - q.z()) < 0.002) visible.push_back(n);
  }
  if (visible.empty()) return {};
  std::vector<int> markers{visible.front()};
  std::vector<double> nearest(visible.size(), 1e300);
  while (markers.size() < count && markers.size() < visible.size()) {
    int best = -1;
    double far = -1;
    for (std::size_t i = 0; i < visible.size(); ++i) {
      nearest[i] = std::min(nearest[i], (rest.points[visible[i]] - rest.points[markers.back()]).norm());
      if (nearest[i] > far) far = nearest[i], best = visible[i];
    }
    markers.push_back(best);
  }
  return markers;
}

/// Features a tracker would find on the organ in two frames (issue 38's second frame): up to `count` vertices of the
/// surface (vertices of `view`, model frame) that both cameras see (depth-tested in each), taken at random (seeded),
/// projected into the first camera (`pose`) and the second (`motion` after it), each pixel moved by Gaussian noise of
/// `noisePx`. Pairs (first frame's pixel, second frame's).
inline std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> trackedFeatures(const SurfaceView& view,
                                                                                const Pose& pose, const Pose& motion,
                                                                                const imaging::Camera& cam,
                                                                                std::size_t count, double noisePx,
                                                                                unsigned seed) {
  Pose second;
  second.R = motion.R * pose.R;
  second.t = motion.R * pose.t + motion.t;
  const imaging::Rasterization r1 = imaging::rasterize(cam, pose, view), r2 = imaging::rasterize(cam, second, view);
  auto seenIn = [&](const imaging::Rasterization& r, const Pose& p, const Eigen::Vector3d& v, Eigen::Vector2d& px) {
    const Eigen::Vector3d q = p.apply(v);
    if (q.z() <= 0) return false;
    px = cam.project(q);
    const int x = static_cast<int>(px.x()), y = static_cast<int>(px.y());
    return x >= 0 && y >= 0 && x < cam.width && y < cam.height && std::abs(r.depth(y, x) - q.z()) < 0.002;
  };
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> both;
  std::vector<char> onSurface(view.vertexCount, 0);
  for (std::size_t t = 0; t < 3 * view.triangleCount; ++t) onSurface[static_cast<std::size_t>(view.triangles[t])] = 1;
  for (std::size_t i = 0; i < view.vertexCount; ++i) {
    if (!onSurface[i]) continue;
    const Eigen::Vector3d v = view.vertex(i);
    Eigen::Vector2d a, b;
    if (seenIn(r1, pose, v, a) && seenIn(r2, second, v, b)) both.emplace_back(a, b);
  }
  std::mt19937 rng(seed);
  std::shuffle(both.begin(), both.end(), rng);
  if (both.size() > count) both.resize(count);
  std::normal_distribution<double> noise(0.0, noisePx);
  for (auto& [a, b] : both) {
    a += Eigen::Vector2d(noise(rng), noise(rng));
    b += Eigen::Vector2d(noise(rng), noise(rng));
  }
  return both;
}

}  // namespace rehearse::testing
