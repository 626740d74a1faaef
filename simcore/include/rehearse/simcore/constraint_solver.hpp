#pragma once
// The constraint solver of the FEM (one part of the integrator, tested alone against a dense KKT solve in
// tests/simcore/test_constraint_solver.cpp): scalar linear constraints on node positions (attachments as
// Lagrange multipliers, the elastic fit's image-plane constraints, tool grasps and contacts), solved as SOFA's
// constraint correction does: with A factorised (the caller's Newton matrix) and dx_free = A^-1 rhs,
//   A dx = rhs + H^T mu,   H (x + s dx) = value  (bilateral)  or  >= value with mu >= 0 (unilateral),
// through the Schur complement W = H A^-1 H^T and projected Gauss-Seidel on W mu = e, e = (value - H x)/s - H dx_free;
// a bilateral set that Gauss-Seidel cannot settle (ill-conditioned W) takes a dense LDL^T of W (m x m).
// Nodes fixed by projection take no constraint force. Sized once: a solve with the same constraints and
// factor allocates nothing.
#include <rehearse/simcore/linear_solver.hpp>

#include <Eigen/Dense>

#include <array>
#include <vector>

namespace rehearse::simcore {

/// One scalar linear constraint on positions: sum_k weights[k] * direction . x[nodes[k]] = value
/// (unused slots have node -1). Unilateral constraints only push (>=), bilateral ones hold (=).
struct ScalarConstraint {
  std::array<int, 4> nodes{-1, -1, -1, -1};
  std::array<double, 4> weights{0, 0, 0, 0};
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
  double value = 0;  ///< m
  bool unilateral = false;
};

/// The tool's force on the tissue (N) from its constraint rows and their multipliers (row k's is lambda[first + k],
/// first = lambda.size() - rows.size(): a body's own rows, e.g. Lagrange attachments, come first): each row's
/// multiplier along its direction, spread by its weights' sum; `holdsOnly`: the bilateral rows alone.
Eigen::Vector3d toolForceOf(const std::vector<ScalarConstraint>& rows, const Eigen::VectorXd& lambda, bool holdsOnly);
/// Throws MeshError with one sentence for a constraint on a missing node, or without node, direction or value.
void validateConstraint(const ScalarConstraint& c, std::size_t nodeCount);
/// The constraint's left side at positions `x` (3n): sum_k weights[k] * direction . x[nodes[k]].
double constraintValue(const ScalarConstraint& c, const Eigen::VectorXd& x);

/// The compliance blocks A^-1 [e_x e_y e_z] of mesh nodes for one factor A (3 columns per node). Each node's block is
/// solved alone, so it has the same bits whenever and wherever it is solved (the stepping thread, the thread building
/// a factor, a replay, either core: CholmodSolver::solveUnitBlocks spreads a call's new blocks over the threads): which
/// nodes are cached changes the time a step takes, never its result.
class NodeCompliance {
 public:
  /// Blocks for every node of `rows` (not fixed) with `factor` as it is now; kept while the factor is the same object
  /// at the same factorisation count. Bounded (24 MB, at least 16 nodes): full, it starts again from these rows' nodes.
  /// False when a solve failed.
  bool prepare(CholmodSolver& factor, const std::vector<ScalarConstraint>& rows, const std::vector<char>& fixed);
  /// The same for a list of nodes (the ones outside the mesh or fixed skipped): a body built on another thread solves
  /// the blocks of the nodes the tool holds and touches there, so the first step after a cut or a tear does not.
  bool prepare(CholmodSolver& factor, const std::vector<int>& nodes, const std::vector<char>& fixed);
  /// The 3n x 3 block of `node` (prepare() made it).
  auto block(int node) const {
    return cols_.middleCols<3>(3 * static_cast<Eigen::Index>(slotOf_[static_cast<std::size_t>(node)]));
  }
  std::size_t memoryBytes() const {
    return sizeof(double) * static_cast<std::size_t>(cols_.size()) +
           sizeof(int) * (slotOf_.size() + slotNodes_.size() + newNodes_.size() + newSlots_.size());
  }

 private:
  Eigen::MatrixXd cols_;
  std::vector<int> slotOf_, slotNodes_;  // node -> slot (-1: none), slot -> node
  std::vector<int> newNodes_, newSlots_;  // prepare()'s missing nodes and their slots (scratch)
  std::vector<int> rowNodes_;            // the rows' nodes, in their order (scratch)
  const CholmodSolver* factor_ = nullptr;
  int factorisations_ = -1;
};

class ConstraintSolver {
 public:
  /// The constraints (checked with validateConstraint) and the nodes fixed by projection (1: fixed). W (and A^-1 H^T)
  /// are kept when only the values changed (the same rows: a grasp whose tip moves), the factor being the same.
  void setConstraints(std::vector<ScalarConstraint> constraints, const std::vector<char>& fixed);
  const std::vector<ScalarConstraint>& constraints() const { return constraints_; }
  Eigen::Index size() const { return static_cast<Eigen::Index>(constraints_.size()); }
  /// The factor changed: W is rebuilt at the next solve.
  void invalidate() { schurValid_ = false; }
  /// Corrects `dx` (in: the free solution A^-1 rhs, projected; out: the constrained one) with the factor
  /// `A` of the caller's matrix; `x` the current positions, `s` the position scale of dx (the time step for
  /// velocities, 1 for positions). `carried`: multipliers whose forces dx already holds (through another
  /// operator than the factor): the total ones are solved for and dx moves by the change only.
  /// Gauss-Seidel sweeps are added to `sweeps`. False when a solve failed or gave non-finite values.
  bool solve(CholmodSolver& A, const Eigen::VectorXd& x, double s, Eigen::VectorXd& dx, int& sweeps,
             const Eigen::VectorXd* carried = nullptr);
  /// The multipliers (total, N·s/m... in the units of rhs) of the last solve; the next solve starts from
  /// them (warm start). Reset them with multipliers().setZero(size()).
  Eigen::VectorXd& multipliers() { return lambda_; }
  /// After a solve: fixes its active set (the bilateral constraints and the unilateral ones that push, multiplier > 0)
  /// and factorises that set's block of W, for projectedSolve. False when there is no W yet.
  bool fixActiveSet();
  /// The constraint preconditioner of the fixed active set a, with the same factor A as the last solve:
  ///   z = A^-1 r - A^-1 H_a^T y,  y = W_aa^-1 H_a A^-1 r,
  /// so that H_a z = 0 (z stays on the constraints) and r - H_a^T y is r net of the constraint forces: a residual
  /// r = rhs + H^T mu - A d is answered by the multipliers mu - y.
  /// y is over all constraints (zero off the set), in the units of r. Allocates nothing once sized.
  bool projectedSolve(CholmodSolver& A, const Eigen::VectorXd& r, Eigen::VectorXd& z, Eigen::VectorXd& y);
  /// W = H A^-1 H^T of the last solve (m x m; the constraints' compliance through the factor), empty before it.
  const Eigen::MatrixXd& schur() const { return W_; }
  /// H^T (3n x m, dense) as of the last solve (empty before it).
  const Eigen::MatrixXd& transposedH() const { return Ht_; }
  /// Largest |H x - value| (bilateral) or max(0, value - H x) (unilateral), m.
  double violation(const Eigen::VectorXd& x) const;
  int gaussSeidelIterations = 300;  ///< sweeps; then bilateral sets take a dense solve of W
  /// Sets with unilateral constraints (contact) that Gauss-Seidel has not settled in this many sweeps are
  /// solved by an active set on W (dense solves of the active constraints' block, small), which ends with
  /// the exact complementary solution in a few iterations where Gauss-Seidel took hundreds of sweeps; when
  /// the active set does not settle, Gauss-Seidel goes on to gaussSeidelIterations.
  int activeSetAfterSweeps = 20;
  /// Active-set iterations of the last solve (0 when Gauss-Seidel settled it alone).
  int activeSetIterations() const { return activeSetIterations_; }
  double gaussSeidelTolerance = 1e-10;  ///< relative change of the multipliers
  /// A^-1 H^T from one solve of H^T's m columns instead of the nodes' cached compliance blocks (3 columns a node, each
  /// solved alone): right where the factor changes between solves and nothing is reused (static solves: a rebinding
  /// registration's 97 rows on 97 nodes took 291 single-node columns in 97 calls, 0.5 s of a 1 s fit), and where every
  /// row has a node of its own. Deterministic either way (the result depends on the rows and the factor only).
  bool directColumns = false;
  std::size_t memoryBytes() const {
    return sizeof(double) * static_cast<std::size_t>(Ht_.size() + A_.size() + W_.size()) + compliance_.memoryBytes();
  }
  /// The nodes' compliance blocks W is made of (a factor built on another thread comes with its own: swapped in).
  NodeCompliance& compliance() { return compliance_; }

 private:
  std::vector<ScalarConstraint> constraints_;
  std::vector<char> fixed_;
  Eigen::MatrixXd Ht_, A_, W_;  // H^T, A^-1 H^T, W = H A^-1 H^T
  Eigen::VectorXd e_, lambda_, Wlambda_;
  Eigen::LDLT<Eigen::MatrixXd> Wfactor_;  // W's dense factorisation, when Gauss-Seidel stalls on it
  bool WfactorValid_ = false;
  // The active set's buffers (kept between solves: no allocation once sized).
  std::vector<char> active_;
  std::vector<Eigen::Index> activeIndex_;
  Eigen::MatrixXd Wa_;
  Eigen::VectorXd ea_, la_, candidate_;
  Eigen::LDLT<Eigen::MatrixXd> WaFactor_;
  int activeSetIterations_ = 0;
  // fixActiveSet / projectedSolve: the set's indices, its block of W factorised, H_a A^-1 r.
  std::vector<Eigen::Index> fixedSet_;
  Eigen::MatrixXd fixedW_;
  Eigen::LDLT<Eigen::MatrixXd> fixedFactor_;
  Eigen::VectorXd fixedT_, fixedY_;
  bool activeSet();
  NodeCompliance compliance_;  // the blocks of the rows' nodes, for the factor of the last solve
  bool schurDirect_ = false;
  bool schurValid_ = false;  // A_ and W_ belong to the current factor and constraints
  // The factor they were computed with, and its factorisation count then (a belt to invalidate()'s braces).
  const CholmodSolver* schurFactor_ = nullptr;
  int schurFactorisations_ = -1;
};

}  // namespace rehearse::simcore
