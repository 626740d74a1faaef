#pragma once
// The operative-field block test_field and test_incorrect_actions share: 30 x 12 x 12 mm of 2 mm cubes held at both
// ends, a vessel of 2.5 mm radius along x through its middle (the elements whose centres lie within that radius:
// label 2, named `name`), stiffer than the tissue around it, no gravity; the shafts come down from above it, the
// blade is 50 mm, a cut applies at once.
#include "box_mesh.hpp"

#include <rehearse/simcore/session/session.hpp>

#include <cmath>

namespace rehearse::testing {

constexpr double kAxisY = 0.006, kAxisZ = 0.006, kVesselRadius = 0.0025;

inline simcore::BodySetup vesselBlock(const char* name = "hepatic artery",
                                      simcore::NewtonMethod method = simcore::NewtonMethod::Exact) {
  simcore::BodySetup s;
  s.mesh = boxMesh(0.03, 0.012, 0.012, 15, 6, 6);
  for (std::size_t t = 0; t < s.mesh.tets.size(); ++t) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int k : s.mesh.tets[t]) c += s.mesh.points[static_cast<std::size_t>(k)] / 4;
    if (std::hypot(c.y() - kAxisY, c.z() - kAxisZ) < kVesselRadius) s.mesh.tetLabels[t] = 2;
  }
  s.mesh.setLabelName(1, "parenchyma");
  s.mesh.setLabelName(2, name);
  s.fixedNodes = nodesAtX(s.mesh, 0.0);
  for (int n : nodesAtX(s.mesh, 0.03)) s.fixedNodes.push_back(n);
  s.material = {simcore::MaterialModel::Corotational, 20e3, 0.45, 1000};
  s.byLabel[2] = {simcore::MaterialModel::Corotational, 100e3, 0.45, 1000};
  s.settings.method = method;
  s.settings.gravity.setZero();
  s.settings.timeStep = 0.01;
  s.tools.trocar = Eigen::Vector3d(0.015, kAxisY, 0.1);  // above the block: shafts come down along -z
  s.tools.bladeLength = 0.05;
  s.tools.cutLatencySteps = -1;
  return s;
}

}  // namespace rehearse::testing
