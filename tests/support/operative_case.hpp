#pragma once
// A cholecystectomy-like case on a real organ shape (issue 36), for its test and its benchmark: the patient liver's CT
// surface (scikit-surgery) meshed, a cystic artery labelled through it (the patient's own vessels are separate
// surfaces the volume does not carry), a scene that declares where each material tears, and a gesture script that uses
// every instrument: two clips across the artery, a cut between them, a line burnt with the cautery hook, and the
// grasper pulling the liver's far end until it tears. Written into a folder as liver.msh, scene.json and chole.json.
#include "realorgan.hpp"

#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <nlohmann/json.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

namespace rehearse::testing {

struct OperativeCase {
  std::size_t elements = 0, nodes = 0;
  int artery = 0;                                  ///< elements labelled the cystic artery
  double depth = 0;                                ///< m, its centre below the surface
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  ///< m, the bounding box
};

/// Writes the case into `dir` from the liver surface at `liverPath`. `targetTets`: the meshing's target.
inline OperativeCase writeOperativeCase(const std::string& liverPath, const std::string& dir,
                                        std::size_t targetTets = 10000) {
  auto point = [](const Eigen::Vector3d& p) { return nlohmann::json{p.x(), p.y(), p.z()}; };
  simcore::TetrahedraliseOptions to;
  to.allowSelfIntersections = true;
  to.targetTets = targetTets;
  simcore::Mesh m = simcore::tetrahedraliseSurface(loadOrganSurface(liverPath), to);
  // The organ's axes: e0 its longest, e2 its thinnest.
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : m.points) c += p / static_cast<double>(m.points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : m.points) cov += (p - c) * (p - c).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const Eigen::Vector3d e0 = es.eigenvectors().col(2), e1 = es.eigenvectors().col(1), e2 = es.eigenvectors().col(0);
  // The cystic artery: the elements whose centres lie within 9 mm of a 70 mm segment along e0 through the node
  // deepest inside the organ (farthest from its surface; the mean of the nodes may lie outside a liver). The
  // mesh's elements are about 12 mm across: a thinner tube would not be connected.
  const std::vector<int> surface = surfaceNodes(m);
  OperativeCase out;
  double deepest = -1;
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    double d = 1e9;
    for (int n : surface) d = std::min(d, (m.points[i] - m.points[static_cast<std::size_t>(n)]).norm());
    if (d > deepest) deepest = d, c = m.points[i];
  }
  for (std::size_t t = 0; t < m.tets.size(); ++t) {
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int k : m.tets[t]) q += m.points[static_cast<std::size_t>(k)] / 4;
    const double s = std::clamp((q - c).dot(e0), -0.035, 0.035);
    if ((q - (c + s * e0)).norm() < 0.009) {
      m.tetLabels[t] = 2;
      ++out.artery;
    }
  }
  m.setLabelName(1, "liver");
  m.setLabelName(2, "cystic artery");
  Eigen::AlignedBox3d box;
  for (const auto& p : m.points) box.extend(p);
  out.elements = m.tets.size();
  out.nodes = m.points.size();
  out.depth = deepest;
  out.size = box.sizes();
  // Held by the attachments at its near end (the 15 % of its surface nodes least far along e0).
  std::vector<std::pair<double, int>> along;
  for (int n : surface) along.emplace_back((m.points[static_cast<std::size_t>(n)] - c).dot(e0), n);
  std::sort(along.begin(), along.end());
  std::vector<int> held;
  for (std::size_t k = 0; k < along.size() * 15 / 100; ++k) held.push_back(along[k].second);
  const Eigen::Vector3d farEnd = m.points[static_cast<std::size_t>(along.back().second)];
  // The cautery's line: on the surface node facing the trocar (least far along e2) nearest the centre line.
  Eigen::Vector3d facing = c;
  double best = 1e9;
  for (int n : surface) {
    const Eigen::Vector3d& p = m.points[static_cast<std::size_t>(n)];
    const double score = (p - c).dot(e2) + 0.3 * std::abs((p - c).dot(e0));
    if (score < best) best = score, facing = p;
  }
  simcore::saveMesh(m, dir + "/liver.msh");
  nlohmann::json scene = {{"components",
                           {{{"type", "mesh"}, {"file", "liver.msh"}, {"unit", "m"}},
                            {{"type", "material"},
                             {"model", "corotational"},
                             {"young", 27e3},
                             {"poisson", 0.4},
                             {"density", 1079},
                             {"tear_strain", 0.3}},
                            {{"type", "material"},
                             {"label", 2},
                             {"model", "corotational"},
                             {"young", 200e3},
                             {"poisson", 0.45},
                             {"density", 1079},
                             {"tear_strain", 0.6}},
                            {{"type", "attachments"}, {"nodes", held}},
                            {{"type", "damping"}, {"rayleigh_mass", 1.0}, {"rayleigh_stiffness", 0.0}},
                            {{"type", "implicit_euler"}, {"dt", 0.01}}}}};
  std::ofstream(dir + "/scene.json") << scene.dump(1);
  const Eigen::Vector3d trocar = c - 0.25 * e2;
  nlohmann::json events = nlohmann::json::array();
  events.push_back({{"t", 0.1}, {"tool", "clip applier"}, {"tip", point(c - 0.016 * e0)}});
  events.push_back({{"t", 0.1}, {"clip", "close"}});
  events.push_back({{"t", 0.2}, {"tip", point(c + 0.016 * e0)}});
  events.push_back({{"t", 0.2}, {"clip", "close"}});
  events.push_back({{"t", 0.4}, {"tool", "scissors"}, {"tip", point(c - 0.045 * e1 + 0.03 * e2)}});
  events.push_back({{"t", 0.4}, {"cut", "on"}});
  events.push_back({{"t", 0.4}, {"move", point(0.09 * e1)}, {"over", 0.3}});
  events.push_back({{"t", 0.75}, {"cut", "off"}});
  events.push_back({{"t", 0.9}, {"tool", "cautery"}, {"tip", point(facing)}});
  events.push_back({{"t", 0.9}, {"energy", "on"}});
  events.push_back({{"t", 0.9}, {"move", point(0.01 * e1)}, {"over", 0.4}});
  events.push_back({{"t", 1.35}, {"energy", "off"}});
  events.push_back({{"t", 1.5}, {"tool", "grasper"}, {"tip_near", point(farEnd)}});
  events.push_back({{"t", 1.5}, {"jaws", "close"}});
  events.push_back({{"t", 1.6}, {"move", point(0.08 * e0)}, {"over", 1.2}});
  nlohmann::json script = {{"format", "rehearse-gesture"},
                           {"duration", 3.0},
                           {"dt", 0.01},
                           {"tools",
                            {{"blade_length_mm", 100},
                             {"trocar", point(trocar)},
                             {"clip_length_mm", 45},
                             {"clip_min_squeeze", 0.8},
                             {"max_grasp_force_n", 1000},
                             {"grasp_radius_mm", 12}}},
                           {"events", events}};
  std::ofstream(dir + "/chole.json") << script.dump(1);
  return out;
}

}  // namespace rehearse::testing
