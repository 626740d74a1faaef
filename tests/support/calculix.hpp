#pragma once
// CalculiX (ccx, an independent FEM code) as a reference for our tests: writes the mesh as C3D4 elements
// with a material per element label, fixed nodes and gravity, runs a static step (NLGEOM when asked) and
// reads back the nodal displacements. Used by test_calculix (like against like) and test_registration
// (ground truth on a finer mesh than the fit's).
#include "test_support.hpp"

#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/mesh.hpp>

#include <QProcess>
#include <QProcessEnvironment>

#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

struct CcxMaterial {
  double young = 0, poisson = 0, density = 0;
  bool neoHooke = false;  ///< *HYPERELASTIC, NEO HOOKE with C10 = mu/2, D1 = 2/K; else *ELASTIC
};

/// Nodal displacements (3n, metres) of the static equilibrium under gravity `g` (m/s^2, a vector), the
/// `fixed` nodes (0-based) held; elements with a label in `byLabel` take that material, the others
/// `fallback`; `forces` (N, by 0-based node) are applied as point loads; `prescribed` nodes are moved by
/// the given displacements (m), and `reaction`, when given, receives the sum of the support forces (N) on
/// them. Empty when ccx failed (its output's end is logged).
inline Eigen::VectorXd runCalculixStatic(const rehearse::simcore::Mesh& mesh, const std::map<int, CcxMaterial>& byLabel, const CcxMaterial& fallback,
                                         const Eigen::Vector3d& g, bool nlgeom, const std::vector<int>& fixed, const std::string& name,
                                         const std::map<int, Eigen::Vector3d>& forces = {}, const std::map<int, Eigen::Vector3d>& prescribed = {},
                                         Eigen::Vector3d* reaction = nullptr) {
  const std::string dir = tempPath("ccx-" + name);
  std::filesystem::create_directories(dir);
  std::string inp = "*NODE\n";
  char buf[200];
  for (std::size_t i = 0; i < mesh.points.size(); ++i) {
    // ccx reads at most 20 characters per number: 13 significant digits.
    std::snprintf(buf, sizeof buf, "%zu, %.13g, %.13g, %.13g\n", i + 1, mesh.points[i].x(), mesh.points[i].y(), mesh.points[i].z());
    inp += buf;
  }
  // One element set per material.
  std::map<int, std::vector<std::size_t>> groups;  // -1: fallback
  for (std::size_t e = 0; e < mesh.tets.size(); ++e) {
    const int label = e < mesh.tetLabels.size() ? mesh.tetLabels[e] : 0;
    groups[byLabel.count(label) ? label : -1].push_back(e);
  }
  for (const auto& [label, elements] : groups) {
    inp += "*ELEMENT, TYPE=C3D4, ELSET=E" + std::to_string(label + 1) + "\n";
    for (std::size_t e : elements) {
      const auto& t = mesh.tets[e];
      std::snprintf(buf, sizeof buf, "%zu, %d, %d, %d, %d\n", e + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1);
      inp += buf;
    }
  }
  inp += "*NSET, NSET=NALL, GENERATE\n1, " + std::to_string(mesh.points.size()) + ", 1\n*NSET, NSET=FIX\n";
  for (int i : fixed) inp += std::to_string(i + 1) + "\n";
  inp += "*BOUNDARY\nFIX, 1, 3\n";
  if (!prescribed.empty()) {
    inp += "*NSET, NSET=PRESC\n";
    for (const auto& [node, d] : prescribed) inp += std::to_string(node + 1) + "\n";
  }
  for (const auto& [label, elements] : groups) {
    const CcxMaterial& m = label < 0 ? fallback : byLabel.at(label);
    const std::string set = "E" + std::to_string(label + 1);
    if (m.neoHooke) {
      const rehearse::simcore::Lame l = rehearse::simcore::Lame::fromYoung(m.young, m.poisson);
      const double C10 = l.mu / 2, D1 = 2 / (l.lambda + 2 * l.mu / 3);
      std::snprintf(buf, sizeof buf, "*MATERIAL, NAME=M%s\n*HYPERELASTIC, NEO HOOKE\n%.13g, %.13g\n*DENSITY\n%.13g\n", set.c_str(), C10, D1, m.density);
    } else {
      std::snprintf(buf, sizeof buf, "*MATERIAL, NAME=M%s\n*ELASTIC\n%.17g, %.17g\n*DENSITY\n%.17g\n", set.c_str(), m.young, m.poisson, m.density);
    }
    inp += std::string(buf) + "*SOLID SECTION, ELSET=" + set + ", MATERIAL=M" + set + "\n";
  }
  inp += nlgeom ? "*STEP, NLGEOM, INC=200\n*STATIC\n0.05, 1.0, 1e-6, 0.1\n" : "*STEP\n*STATIC\n";
  if (!prescribed.empty()) {
    inp += "*BOUNDARY\n";
    for (const auto& [node, d] : prescribed)
      for (int k = 0; k < 3; ++k) {
        std::snprintf(buf, sizeof buf, "%d, %d, %d, %.13g\n", node + 1, k + 1, k + 1, d[k]);
        inp += buf;
      }
  }
  const double gn = g.norm();
  if (gn > 0) inp += "*DLOAD\n";
  for (const auto& [label, elements] : groups) {
    if (!(gn > 0)) break;
    std::snprintf(buf, sizeof buf, "E%d, GRAV, %.17g, %.17g, %.17g, %.17g\n", label + 1, gn, g.x() / gn, g.y() / gn, g.z() / gn);
    inp += buf;
  }
  if (!forces.empty()) {
    inp += "*CLOAD\n";
    for (const auto& [node, f] : forces)
      for (int k = 0; k < 3; ++k)
        if (f[k] != 0) {
          std::snprintf(buf, sizeof buf, "%d, %d, %.13g\n", node + 1, k + 1, f[k]);
          inp += buf;
        }
  }
  inp += "*NODE PRINT, NSET=NALL\nU\n";
  if (!prescribed.empty()) inp += "*NODE PRINT, NSET=PRESC\nRF\n";
  inp += "*END STEP\n";
  writeFile(dir + "/job.inp", inp);
  QProcess p;
  p.setWorkingDirectory(QString::fromStdString(dir));
  QProcessEnvironment env = QProcessEnvironment::systemEnvironment();
  env.insert("OMP_NUM_THREADS", "1");
  p.setProcessEnvironment(env);
  p.start("ccx", {"-i", "job"});
  if (!p.waitForFinished(600000) || p.exitCode() != 0) {
    const QByteArray out = p.readAllStandardOutput();
    qWarning("ccx failed: %s", out.right(1500).constData());
    return {};
  }
  // The rows (node id, three values) of the last block of job.dat whose header holds `header`.
  const std::string dat = readFile(dir + "/job.dat");
  auto lastBlock = [&dat](const char* header) {
    std::istringstream in(dat);
    std::string line;
    std::map<long, Eigen::Vector3d> rows, block;
    bool inBlock = false;
    while (std::getline(in, line)) {
      if (line.find(header) != std::string::npos) {
        inBlock = true;
        block.clear();
        continue;
      }
      if (!inBlock) continue;
      std::istringstream l(line);
      long id;
      double x, y, z;
      if (l >> id >> x >> y >> z) block[id] = Eigen::Vector3d(x, y, z);
      else if (!block.empty()) inBlock = false, rows = block;
    }
    if (inBlock && !block.empty()) rows = block;
    return rows;
  };
  Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(mesh.points.size()));
  for (const auto& [id, d] : lastBlock("displacements (vx,vy,vz)")) u.segment<3>(3 * (id - 1)) = d;
  if (reaction) {  // the support forces on the prescribed nodes, summed
    reaction->setZero();
    for (const auto& [id, f] : lastBlock("forces (fx,fy,fz)")) *reaction += f;
  }
  return u;
}
