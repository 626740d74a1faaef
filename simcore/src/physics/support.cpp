// The elastic foundation under an organ (support.hpp).
#include <rehearse/simcore/support.hpp>

#include <rehearse/simcore/mesh.hpp>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>

namespace rehearse::simcore {

SupportPlacement placeSupports(const std::vector<std::array<int, 4>>& tets, const std::vector<Eigen::Vector3d>& shape,
                               const Eigen::VectorXd& lumpedMass, const std::vector<int>& fixedNodes,
                               const Eigen::Vector3d& gravity, double modulus) {
  SupportPlacement p;
  const std::size_t n = shape.size();
  if (!(gravity.norm() > 0)) {
    p.problem = "without gravity there is no weight to carry";
    return p;
  }
  if (!(modulus > 0) || !std::isfinite(modulus)) {
    p.problem = "the support's modulus is not positive";
    return p;
  }
  if (static_cast<std::size_t>(lumpedMass.size()) != n) {
    p.problem = "the masses do not match the shape";
    return p;
  }
  const Eigen::Vector3d down = gravity.normalized();
  // Each node's share of the outward surface vector (area times normal, a third of each boundary triangle's).
  Mesh volume;
  volume.points = shape;
  volume.tets = tets;
  std::vector<Eigen::Vector3d> normal(n, Eigen::Vector3d::Zero());
  for (const auto& t : boundaryTriangles(volume, false)) {
    const Eigen::Vector3d a = shape[static_cast<std::size_t>(t[0])], b = shape[static_cast<std::size_t>(t[1])],
                          c = shape[static_cast<std::size_t>(t[2])];
    const Eigen::Vector3d an = 0.5 * (b - a).cross(c - a) / 3.0;
    for (int v : t) normal[static_cast<std::size_t>(v)] += an;
  }
  std::vector<char> held(n, 0);
  for (int f : fixedNodes)
    if (f >= 0 && static_cast<std::size_t>(f) < n) held[static_cast<std::size_t>(f)] = 1;
  // The weight and its line of action.
  const double M = lumpedMass.sum();
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) com += lumpedMass[static_cast<Eigen::Index>(i)] * shape[i];
  com /= M;
  // Two directions across gravity.
  Eigen::Vector3d e1 = down.unitOrthogonal(), e2 = down.cross(e1);
  std::vector<int> nodes;
  std::vector<double> share;  // projected area along gravity (the footprint's)
  for (std::size_t i = 0; i < n; ++i) {
    const double projected = normal[i].dot(down);
    if (held[i] || !(projected > 0)) continue;
    nodes.push_back(static_cast<int>(i));
    share.push_back(projected);
    p.area += projected;
  }
  if (nodes.empty()) {
    p.problem = "no surface faces along gravity";
    return p;
  }
  // Pressure linear across the footprint, w_i = a_i (c0 + c1 d1_i + c2 d2_i): the weights sum to one and their moment
  // about the centre of mass across gravity is zero (3 equations, 3 unknowns).
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const Eigen::Vector3d d = shape[static_cast<std::size_t>(nodes[k])] - com;
    const Eigen::Vector3d row(1.0, d.dot(e1), d.dot(e2));
    A += share[k] * row * row.transpose();
  }
  Eigen::Vector3d coef = Eigen::Vector3d::Zero();
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(A);
  if (lu.rank() == 3) {
    coef = lu.solve(Eigen::Vector3d(1, 0, 0));
  } else {
    // A footprint along a line (or a point): uniform pressure; the moment is left to the material and the held nodes.
    double sum = 0;
    for (double s : share) sum += s;
    coef = Eigen::Vector3d(1.0 / sum, 0, 0);
  }
  const Eigen::Vector3d weight = M * gravity;  // N, along gravity
  p.anchors.reserve(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const auto i = static_cast<std::size_t>(nodes[k]);
    const Eigen::Vector3d d = shape[i] - com;
    const double w = share[k] * (coef[0] + coef[1] * d.dot(e1) + coef[2] * d.dot(e2));
    if (w < 0) ++p.pulling;
    NodeAnchor a;
    a.node = nodes[k];
    a.stiffness = modulus * share[k];
    // At the shape the spring's force k (at - x) is -w M g: it carries its share of the weight.
    a.at = shape[i] - (w / a.stiffness) * weight;
    p.stiffness += a.stiffness;
    p.anchors.push_back(a);
  }
  p.load = weight.norm();
  return p;
}

std::vector<int> attachmentPatches(const Mesh& volume, const std::vector<int>& picked, std::size_t* lone) {
  const std::size_t nodes = volume.points.size();
  const auto& tets = volume.tets;
  std::vector<int> out = picked;
  if (lone) *lone = 0;
  std::vector<char> isPicked(nodes, 0);
  for (int v : picked)
    if (v >= 0 && static_cast<std::size_t>(v) < nodes) isPicked[static_cast<std::size_t>(v)] = 1;
  std::vector<std::vector<int>> onSurface(nodes), inVolume(nodes);
  auto link = [&](std::vector<std::vector<int>>& n, int a, int b) {
    if (a < 0 || b < 0 || static_cast<std::size_t>(a) >= nodes || static_cast<std::size_t>(b) >= nodes) return;
    if (!isPicked[static_cast<std::size_t>(a)] && !isPicked[static_cast<std::size_t>(b)]) return;  // only picks' rings
    n[static_cast<std::size_t>(a)].push_back(b);
    n[static_cast<std::size_t>(b)].push_back(a);
  };
  for (const auto& f : boundaryTriangles(volume, false))
    for (int i = 0; i < 3; ++i) link(onSurface, f[static_cast<std::size_t>(i)], f[static_cast<std::size_t>((i + 1) % 3)]);
  for (const auto& t : tets)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) link(inVolume, t[static_cast<std::size_t>(i)], t[static_cast<std::size_t>(j)]);
  for (int v : picked) {
    if (v < 0 || static_cast<std::size_t>(v) >= nodes) continue;
    const auto& surface = onSurface[static_cast<std::size_t>(v)];
    const auto& ring = surface.empty() ? inVolume[static_cast<std::size_t>(v)] : surface;
    const bool alone = std::none_of(ring.begin(), ring.end(), [&](int u) { return isPicked[static_cast<std::size_t>(u)] != 0; });
    if (!alone || ring.empty()) continue;
    out.insert(out.end(), ring.begin(), ring.end());
    if (lone) ++*lone;
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace rehearse::simcore
