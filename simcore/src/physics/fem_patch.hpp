#pragma once
// Issue 61: a patch of a model's nodes and what touches them (elements, springs, anchors), for the nonlinear
// elimination of the few nodes whose residual a lagged factor leaves (a torn flap springing back): their rows of the
// forces, the energy of what touches them, their block of the stiffness, all exactly the whole model's there.
// Internal to simcore; defined in fem.cpp.
#include <rehearse/simcore/fem.hpp>

#include <Eigen/Sparse>

#include <vector>

namespace rehearse::simcore::detail {

struct NodePatch {
  std::vector<int> nodes;     ///< global node numbers: the local unknowns' order (3 each)
  std::vector<int> local;     ///< per global node: its index in nodes, or -1
  std::vector<int> elements;  ///< elements with a node in the patch (ascending)
  std::vector<int> springs;   ///< springs with a node in the patch
  std::vector<int> anchors;   ///< anchors on a patch node
};

/// From p.nodes: the rest of the patch.
void completePatch(const FemModel& m, NodePatch& p);
/// The elastic forces' rows of the patch's nodes at x (3|B|): elasticForces' there.
void patchForces(const FemModel& m, const NodePatch& p, const Eigen::VectorXd& x, Eigen::VectorXd& fB);
/// The elastic energy of what touches the patch: the model's energy less a part the patch's nodes do not change.
double patchEnergy(const FemModel& m, const NodePatch& p, const Eigen::VectorXd& x);
/// scale K_BB(x) into `out` (triplets of local rows and columns), each element's matrix projected as `projection`.
void patchStiffness(const FemModel& m, const NodePatch& p, const Eigen::VectorXd& x, TangentProjection projection,
                    double scale, std::vector<Eigen::Triplet<double>>& out);
/// The patch's rows of K v for the configuration `at` was prepared at (3|B|): applyStiffness's there.
void patchStiffnessProduct(const FemModel& m, const NodePatch& p, const TangentState& at, const Eigen::VectorXd& v,
                           Eigen::VectorXd& outB);

}  // namespace rehearse::simcore::detail
