// Barycentric embedding of points in a tetrahedral mesh (fem.hpp): inner structures' surfaces, markers, and
// the organ's visual surface, which is finer than the simulation mesh and follows it (Courtecuisse et al.
// 2014; SOFA's barycentric visual mappings).
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/session/contact.hpp>

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>

namespace rehearse::simcore {

SurfaceEmbedding embedPoints(const std::vector<Eigen::Vector3d>& rest, const std::vector<std::array<int, 4>>& tets,
                             const std::vector<Eigen::Vector3d>& points) {
  SurfaceEmbedding out;
  // Each element's inverse edge matrix (l = B (p - x0) gives weights 1 - sum(l), l); flat ones hold nothing.
  std::vector<Eigen::Matrix3d> B(tets.size());
  std::vector<char> usable(tets.size(), 0);
  Eigen::AlignedBox3d box;
  for (std::size_t e = 0; e < tets.size(); ++e) {
    const auto& t = tets[e];
    Eigen::Matrix3d D;
    for (int k = 0; k < 3; ++k) D.col(k) = rest[t[k + 1]] - rest[t[0]];
    const double scale = std::max({D.col(0).norm(), D.col(1).norm(), D.col(2).norm()});
    const double det = D.determinant();
    if (!(std::abs(det) > 1e-12 * scale * scale * scale) || !std::isfinite(det)) continue;
    B[e] = D.inverse();
    usable[e] = 1;
    for (int v : t) box.extend(rest[v]);
  }
  if (box.isEmpty()) throw MeshError("The mesh has no tetrahedron of any volume to embed points in.");
  const std::size_t usableCount = static_cast<std::size_t>(std::count(usable.begin(), usable.end(), 1));
  for (const auto& p : points)
    if (!p.allFinite()) throw MeshError("A point to embed has a coordinate that is not a number.");
  // About two elements per cell; at most 2^21 cells (a flat box would otherwise ask for 256^3 of them).
  double cell = std::cbrt(box.volume() / static_cast<double>(usableCount)) * 2 + 1e-12;
  while (((box.sizes() / cell).array().ceil() + 1).prod() > double(1 << 21)) cell *= 1.25;
  const Eigen::Array3i dims = ((box.sizes() / cell).array().ceil().cast<int>() + 1).max(1).min(256);
  auto cellOf = [&](const Eigen::Vector3d& p) {
    Eigen::Array3i c = ((p - box.min()).array() / cell).floor().cast<int>();
    return c.max(0).min(dims - 1).eval();
  };
  auto index = [&](int i, int j, int k) { return static_cast<std::size_t>((i * dims[1] + j) * dims[2] + k); };
  std::vector<std::vector<int>> grid(static_cast<std::size_t>(dims.prod()));
  for (std::size_t e = 0; e < tets.size(); ++e) {
    if (!usable[e]) continue;
    Eigen::AlignedBox3d b;
    for (int v : tets[e]) b.extend(rest[v]);
    const Eigen::Array3i lo = cellOf(b.min()), hi = cellOf(b.max());
    for (int i = lo[0]; i <= hi[0]; ++i)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int k = lo[2]; k <= hi[2]; ++k) grid[index(i, j, k)].push_back(static_cast<int>(e));
  }
  auto weights = [&](int e, const Eigen::Vector3d& p) {
    const Eigen::Vector3d l = B[static_cast<std::size_t>(e)] * (p - rest[tets[static_cast<std::size_t>(e)][0]]);
    return Eigen::Vector4d(1 - l.sum(), l[0], l[1], l[2]);
  };
  // Distance from p to element e (0 inside): the nearest of the faces opposite a negative weight.
  auto distance = [&](int e, const Eigen::Vector3d& p, const Eigen::Vector4d& w) {
    if (w.minCoeff() >= 0) return 0.0;
    static constexpr int face[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};  // opposite node k
    const auto& t = tets[static_cast<std::size_t>(e)];
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 4; ++k) {
      if (w[k] >= 0) continue;
      Eigen::Vector3d bw;
      const Eigen::Vector3d q = closestOnTriangle(p, rest[t[face[k][0]]], rest[t[face[k][1]]], rest[t[face[k][2]]], bw);
      best = std::min(best, (q - p).norm());
    }
    return best;
  };
  out.nodes.reserve(points.size());
  out.weights.reserve(points.size());
  for (const auto& p : points) {
    int best = -1;
    double bestDistance = std::numeric_limits<double>::infinity();
    Eigen::Vector4d bestW = Eigen::Vector4d::Zero();
    auto consider = [&](int e) {
      const Eigen::Vector4d w = weights(e, p);
      // Inside: the element whose smallest weight is largest (the one that holds p most firmly at a shared face).
      const double d = w.minCoeff() >= -1e-12 ? -w.minCoeff() : distance(e, p, w);
      if (d < bestDistance) bestDistance = d, best = e, bestW = w;
    };
    const Eigen::Array3i c = cellOf(p);
    for (int e : grid[index(c[0], c[1], c[2])]) consider(e);
    // Outside every element of its cell: rings of cells around it, until the nearest element found is nearer
    // than any cell not searched yet (or the whole grid was searched).
    for (int r = 1; bestDistance > 1e-12; ++r) {
      const int lo0 = std::max(0, c[0] - r), hi0 = std::min(dims[0] - 1, c[0] + r);
      const int lo1 = std::max(0, c[1] - r), hi1 = std::min(dims[1] - 1, c[1] + r);
      const int lo2 = std::max(0, c[2] - r), hi2 = std::min(dims[2] - 1, c[2] + r);
      for (int i = lo0; i <= hi0; ++i)
        for (int j = lo1; j <= hi1; ++j)
          for (int k = lo2; k <= hi2; ++k)
            if (std::max({std::abs(i - c[0]), std::abs(j - c[1]), std::abs(k - c[2])}) == r)
              for (int e : grid[index(i, j, k)]) consider(e);
      const bool all =
          lo0 == 0 && lo1 == 0 && lo2 == 0 && hi0 == dims[0] - 1 && hi1 == dims[1] - 1 && hi2 == dims[2] - 1;
      // A point outside the grid's box is clamped into it: the cells not searched are then nearer by up to its
      // distance from the box.
      const double beyond = (p - p.cwiseMax(box.min()).cwiseMin(box.max())).norm();
      if (all || (best >= 0 && bestDistance <= r * cell - beyond)) break;
    }
    if (bestDistance > 1e-12) {
      ++out.outside;
      out.farthestOutside = std::max(out.farthestOutside, bestDistance);
    }
    out.nodes.push_back(tets[static_cast<std::size_t>(best)]);
    out.weights.push_back(bestW);
  }
  return out;
}

std::vector<Eigen::Vector3d> mapEmbedded(const SurfaceEmbedding& e, const std::vector<Eigen::Vector3d>& nodes) {
  std::vector<Eigen::Vector3d> out(e.nodes.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i].setZero();
    for (int k = 0; k < 4; ++k) out[i] += e.weights[i][k] * nodes[static_cast<std::size_t>(e.nodes[i][k])];
  }
  return out;
}

}  // namespace rehearse::simcore
