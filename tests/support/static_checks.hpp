#pragma once
// What the static models' tests check against (test_precomputed, test_fastbodies): an instrument's hold as the
// session's grasp makes it, and the linear law's static balance of a state, assembled here from the setup.
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/mesh.hpp>
#include <rehearse/simcore/session/body.hpp>

#include <algorithm>
#include <map>
#include <vector>

namespace rehearse::testing {

// An instrument's hold of `node` at `at` (m): three bilateral rows along x, y, z, as the session's grasp makes them.
inline std::vector<simcore::ScalarConstraint> holdAt(int node, const Eigen::Vector3d& at) {
  std::vector<simcore::ScalarConstraint> rows;
  for (int a = 0; a < 3; ++a) {
    simcore::ScalarConstraint c;
    c.nodes[0] = node;
    c.weights[0] = 1;
    c.direction = Eigen::Vector3d::Unit(a);
    c.value = at(a);
    rows.push_back(c);
  }
  return rows;
}

// The first surface node of the setup's mesh that the body does not hold fixed.
inline int firstFreeSurfaceNode(const simcore::BodySetup& s, const simcore::DeformableBody& body) {
  for (const auto& t : simcore::boundaryTriangles(s.mesh, false))
    for (int v : t)
      if (!body.fixedMask()[static_cast<std::size_t>(v)]) return v;
  return -1;
}

// The linear law's static balance of positions `x` on the setup's rest shape (its mesh in metres, or `rest`):
// K (x - rest) - M g at every node that is not fixed (nor marked in `skip`), summed over the nodes where it does not
// vanish (1e-8 of the largest nodal weight: what an instrument, or a held free piece, pushes there).
struct Balance {
  std::size_t loaded = 0;                           ///< free nodes off equilibrium
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< their residuals' sum (N)
  std::size_t nodes = 0;                            ///< the mesh's
};
inline Balance linearBalance(const simcore::BodySetup& s, const Eigen::VectorXd& x,
                             const std::vector<char>& skip = {}) {
  simcore::Mesh mesh = s.mesh;
  mesh.convertToMetres();
  if (!s.rest.empty()) mesh.points = s.rest;
  simcore::MaterialParams fallback = s.material;
  fallback.model = simcore::MaterialModel::Linear;
  std::map<int, simcore::MaterialParams> byLabel = s.byLabel;
  for (auto& [label, m] : byLabel) m.model = simcore::MaterialModel::Linear;
  const simcore::FemModel model = simcore::FemModel::build(mesh, byLabel, fallback);
  Eigen::VectorXd res = simcore::elasticStiffness(model, model.restVector()) * (x - model.restVector());
  std::vector<char> fixed(model.nodeCount(), 0);
  for (int v : s.fixedNodes) fixed[static_cast<std::size_t>(v)] = 1;
  double load = 0;
  for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(model.nodeCount()); ++i) {
    res.segment<3>(3 * i) -= model.lumpedMass(i) * s.settings.gravity;
    load = std::max(load, model.lumpedMass(i) * s.settings.gravity.norm());
  }
  Balance b;
  b.nodes = model.nodeCount();
  for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(model.nodeCount()); ++i) {
    const auto v = static_cast<std::size_t>(i);
    if (fixed[v] || (!skip.empty() && skip[v])) continue;
    if (res.segment<3>(3 * i).norm() > 1e-8 * load) {
      ++b.loaded;
      b.force += res.segment<3>(3 * i);
    }
  }
  return b;
}

}  // namespace rehearse::testing
