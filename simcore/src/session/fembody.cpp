#include <rehearse/simcore/session/body.hpp>

#include "bodymesh.hpp"

#include <Eigen/Dense>

namespace rehearse::simcore {
namespace {

class FemBody final : public DeformableBody {
 public:
  explicit FemBody(const BodySetup& s)
      : model_(build(s)),
        integrator_(model_, s.fixedNodes, withoutEnergy(s.settings)),
        settings_(s.settings),
        topology_(s.topology),
        labels_(s.mesh.tetLabels),
        start_(s.start) {
    if (!start_.empty() && start_.size() != model_.nodeCount())
      throw MeshError("The body's start positions (" + std::to_string(start_.size()) + ") do not match its mesh (" +
                      std::to_string(model_.nodeCount()) + " nodes).");
    integrator_.setVerifyEveryEstimate(s.topology > 0);
    labels_.resize(model_.tets.size(), 0);
    fixed_.assign(model_.nodeCount(), 0);
    for (int i : s.fixedNodes)
      if (i >= 0 && static_cast<std::size_t>(i) < fixed_.size()) fixed_[static_cast<std::size_t>(i)] = 1;
  }
  std::size_t nodeCount() const override { return model_.nodeCount(); }
  SimulationState initialState() const override {
    SimulationState s = integrator_.initialState();
    for (std::size_t i = 0; i < start_.size(); ++i) s.x.segment<3>(3 * static_cast<Eigen::Index>(i)) = start_[i];
    return s;
  }
  StepReport step(SimulationState& state) override { return stepped(state, true); }
  std::optional<StepReport> stepAgain(SimulationState& state) override { return stepped(state, false); }
  StepReport stepped(SimulationState& state, bool swapIn) {
    StepReport rep = integrator_.step(state, swapIn);
    // The tool force's error (issue 64): the force the multipliers' estimated change makes on the tool.
    if (std::isfinite(rep.errorPosition))
      rep.errorForce = integrator_.constraints().empty()
                           ? 0.0
                           : integrator_.errorMultipliers().size() == 0
                                 ? std::numeric_limits<double>::quiet_NaN()
                                 : toolForceOf(integrator_.constraints(), integrator_.errorMultipliers(), false).norm();
    return rep;
  }
  bool installRequestedFactor() override { return integrator_.installRequestedFactor(); }
  bool factorPending() const override { return integrator_.factorPending(); }
  void requestAgain(const SimulationState& state) override { integrator_.requestAgain(state); }
  bool prepareFactor(const Eigen::VectorXd& x, const std::vector<int>& toolNodes) override {
    return integrator_.prepareLagged(x, toolNodes);
  }
  void setToolConstraints(std::vector<ScalarConstraint> c) override { integrator_.setConstraints(std::move(c)); }
  int topologyVersion() const override { return topology_; }
  const std::vector<Eigen::Vector3d>& restPositions() const override { return model_.rest; }
  void stress(const SimulationState& state, std::vector<double>& out) const override {
    vonMisesStress(model_, state.x, out);
  }
  const std::vector<std::array<int, 4>>& tetrahedra() const override { return model_.tets; }
  double mass() const override { return model_.lumpedMass.sum(); }
  Eigen::Vector3d toolForce(bool holdsOnly) const override {
    // The tool constraints come after the attachments' (Lagrange mode) in the multipliers.
    return toolForceOf(integrator_.constraints(), integrator_.multipliers(), holdsOnly);
  }
  Eigen::Matrix3d toolStiffness() const override {
    const double h = settings_.timeStep;
    if (!(h > 0)) return Eigen::Matrix3d::Zero();
    return toolStiffnessOf(integrator_.constraints(), integrator_.multipliers(), integrator_.constraintCompliance(),
                           1 / (h * h));
  }
  const std::vector<char>& fixedMask() const override { return fixed_; }
  const std::vector<int>& labels() const override { return labels_; }
  Eigen::Vector3d appliedForce(const std::vector<int>& nodes, const SimulationState& state, const Eigen::VectorXd& v0,
                               double h) const override {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    if (nodes.empty() || !(h > 0)) return sum;
    Eigen::VectorXd f;
    TangentState tangent;
    prepareTangentState(model_, state.x, tangent, &f);
    Eigen::VectorXd Kv;
    applyStiffness(model_, tangent, state.v, Kv);
    for (int i : nodes) {
      const auto k = static_cast<Eigen::Index>(3 * i);
      const double m = model_.lumpedMass[i];
      const Eigen::Vector3d v = state.v.segment<3>(k);
      sum += m * (v - v0.segment<3>(k)) / h + settings_.rayleighMass * m * v +
             settings_.rayleighStiffness * Kv.segment<3>(k) - f.segment<3>(k) - m * settings_.gravity;
    }
    return sum;
  }

 private:
  // Nothing in a session reads a step's energy (the command line's simulate reports it): one pass over the elements
  // less per step (7 % of a grasp-pull's time on the patient liver at 16k tets).
  static SimulationSettings withoutEnergy(SimulationSettings s) {
    s.reportEnergy = false;
    return s;
  }
  static FemModel build(const BodySetup& s) {
    const Mesh mesh = restMesh(s);
    FemModel m = FemModel::build(mesh, s.byLabel, s.material);
    for (const auto& a : s.supports)
      if (a.node < 0 || static_cast<std::size_t>(a.node) >= m.nodeCount() || !(a.stiffness >= 0) || !a.at.allFinite())
        throw MeshError("A support of the organ names node " + std::to_string(a.node) + " of " +
                        std::to_string(m.nodeCount()) + " or is not a finite spring: the body cannot be built.");
    m.anchors = s.supports;
    setVolumeBarrier(m, s.settings.volumeBarrier);
    return m;
  }
  FemModel model_;
  Integrator integrator_;
  SimulationSettings settings_;
  int topology_ = 0;
  std::vector<int> labels_;
  std::vector<char> fixed_;
  std::vector<Eigen::Vector3d> start_;
};

}  // namespace

Eigen::Matrix3d toolStiffnessOf(const std::vector<ScalarConstraint>& c, const Eigen::VectorXd& lambda,
                                const Eigen::MatrixXd& W, double scale) {
  if (c.empty() || lambda.size() < static_cast<Eigen::Index>(c.size()) || W.rows() != lambda.size())
    return Eigen::Matrix3d::Zero();
  const Eigen::Index first = lambda.size() - static_cast<Eigen::Index>(c.size());
  std::vector<Eigen::Index> active;
  for (std::size_t k = 0; k < c.size(); ++k)
    if (!c[k].unilateral || lambda[first + static_cast<Eigen::Index>(k)] > 0)
      active.push_back(first + static_cast<Eigen::Index>(k));
  if (active.empty()) return Eigen::Matrix3d::Zero();
  const auto m = static_cast<Eigen::Index>(active.size());
  // G: how each constraint's value moves with the tool (its direction: grasp holds and contacts move with it); S: how
  // its multiplier acts on the tool force (toolForceOf: the direction times its weights' sum).
  Eigen::MatrixXd Wa(m, m), G(m, 3), S(m, 3);
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index j = 0; j < m; ++j)
      Wa(i, j) = W(active[static_cast<std::size_t>(i)], active[static_cast<std::size_t>(j)]);
    const auto& ci = c[static_cast<std::size_t>(active[static_cast<std::size_t>(i)] - first)];
    // A row whose weights sum to zero (a clip: one node against another) is the tissue's own, not the tool's: it
    // neither moves with the tool nor acts on it.
    const double spread = ci.weights[0] + ci.weights[1] + ci.weights[2] + ci.weights[3];
    G.row(i) = spread != 0 ? Eigen::RowVector3d(ci.direction.transpose()) : Eigen::RowVector3d::Zero();
    S.row(i) = spread * ci.direction.transpose();
  }
  // Redundant holds make W_a singular: the pivoted LDL^T's solve leaves their share at zero.
  const Eigen::MatrixXd X = Wa.ldlt().solve(G);
  if (!X.allFinite()) return Eigen::Matrix3d::Zero();
  const Eigen::Matrix3d K = scale * (S.transpose() * X);
  return 0.5 * (K + K.transpose());
}

std::unique_ptr<DeformableBody> makeFemBody(const BodySetup& setup) { return std::make_unique<FemBody>(setup); }

std::unique_ptr<DeformableBody> makeBody(const BodySetup& setup) {
  if (!setup.supports.empty() && setup.model != BodyModel::Fem) {
    // The other models' responses are of the organ held at its attachments alone: they hang it from its held nodes
    // (the session says so; the FEM stands it on its supports again).
    BodySetup held = setup;
    held.supports.clear();
    return makeBody(held);
  }
  switch (setup.model) {
    case BodyModel::Precomputed:
      return makePrecomputedBody(setup);
    case BodyModel::Hybrid:
      return makeHybridBody(setup);
    case BodyModel::Ffd:
      return makeFfdBody(setup);
    default:
      return makeFemBody(setup);
  }
}

}  // namespace rehearse::simcore
