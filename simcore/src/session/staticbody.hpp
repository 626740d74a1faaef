#pragma once
// What the quasi-static bodies share (precomputedbody.cpp, hybridbody.cpp): the linear law's model of the setup, its
// fixed nodes and start, the instruments' rows with their multipliers and compliance, and a step that asks the model
// for the static answer under the rows and reports it (the rows' violation, elements turned inside out). The
// velocities are the positions' change over the step (for what reads them); no inertia, no damping.
#include <rehearse/simcore/session/body.hpp>

#include "bodymesh.hpp"

#include <algorithm>
#include <chrono>

namespace rehearse::simcore {

class StaticBody : public DeformableBody {
 public:
  explicit StaticBody(const BodySetup& s) : settings_(s.settings), topology_(s.topology), labels_(s.mesh.tetLabels) {
    const Mesh mesh = restMesh(s);
    // Linear elasticity of the declared moduli and densities, whatever law the scene names (the stiffness at rest is
    // the same for every law here; the stress drawn is the linear law's too).
    MaterialParams fallback = s.material;
    fallback.model = MaterialModel::Linear;
    std::map<int, MaterialParams> byLabel = s.byLabel;
    for (auto& [label, m] : byLabel) m.model = MaterialModel::Linear;
    model_ = FemModel::build(mesh, byLabel, fallback);
    labels_.resize(model_.tets.size(), 0);
    fixed_.assign(model_.nodeCount(), 0);
    for (int i : s.fixedNodes)
      if (i >= 0 && static_cast<std::size_t>(i) < fixed_.size()) fixed_[static_cast<std::size_t>(i)] = 1;
    base_ = model_.restVector();
    if (!s.start.empty()) {
      // Started from the registered shape, which is the equilibrium: the instruments' displacements add to it.
      if (s.start.size() != model_.nodeCount())
        throw MeshError("The body's start positions (" + std::to_string(s.start.size()) + ") do not match its mesh (" +
                        std::to_string(model_.nodeCount()) + " nodes).");
      for (std::size_t i = 0; i < s.start.size(); ++i) base_.segment<3>(3 * static_cast<Eigen::Index>(i)) = s.start[i];
      started_ = true;
    }
  }
  std::size_t nodeCount() const override { return model_.nodeCount(); }
  SimulationState initialState() const override {
    SimulationState s;
    s.x = base_ + u0_;
    s.v.setZero(s.x.size());
    return s;
  }
  StepReport step(SimulationState& state) override {
    const auto began = std::chrono::steady_clock::now();
    StepReport rep;
    const double h = settings_.timeStep;
    rep.timeStepUsed = h;
    rep.tolerance = settings_.tolerance;
    Eigen::VectorXd u;
    std::string why;
    bool solved = solveRows(u, why);
    if (solved && !u.allFinite()) {  // never "converged" on NaN positions
      solved = false;
      why = "the model gave a displacement that is not finite";
    }
    if (!solved) {
      rep.ok = false;
      rep.outcome = StepStatus::Failed;
      rep.status = "failed: " + why;
      lambda_.setZero(static_cast<Eigen::Index>(rows_.size()));
      return rep;
    }
    const Eigen::VectorXd x = base_ + u;
    state.v = h > 0 ? Eigen::VectorXd((x - state.x) / h) : Eigen::VectorXd::Zero(x.size());
    state.x = x;
    state.time += h;
    state.forcesValid = false;
    double violation = 0;
    for (const auto& c : rows_) {
      const double g = constraintValue(c, x);
      violation = std::max(violation, c.unilateral ? std::max(0.0, c.value - g) : std::abs(g - c.value));
    }
    rep.constraintViolation = violation;
    rep.ok = true;
    // The linear answer is exact for its model whatever the displacement; past small strains its elements may turn
    // inside out, which the report says as for any body.
    const VolumeRatios vr = volumeRatios(model_, x);
    rep.invertedElements = vr.inverted;
    rep.minVolumeRatio = vr.smallest;
    rep.smallestElement = vr.smallestElement;
    rep.outcome = vr.inverted > 0 ? StepStatus::Inverted : StepStatus::Converged;
    rep.status = vr.inverted > 0 ? "inverted" : "converged";
    rep.wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - began).count();
    return rep;
  }
  void setToolConstraints(std::vector<ScalarConstraint> c) override { rows_ = std::move(c); }
  int topologyVersion() const override { return topology_; }
  const std::vector<Eigen::Vector3d>& restPositions() const override { return model_.rest; }
  void stress(const SimulationState& state, std::vector<double>& out) const override {
    vonMisesStress(model_, state.x, out);
  }
  const std::vector<std::array<int, 4>>& tetrahedra() const override { return model_.tets; }
  double mass() const override { return model_.lumpedMass.sum(); }
  Eigen::Vector3d toolForce(bool holdsOnly) const override { return toolForceOf(rows_, lambda_, holdsOnly); }
  // Exact for a linear static model while the same rows act (W is the rows' compliance in m/N).
  Eigen::Matrix3d toolStiffness() const override { return toolStiffnessOf(rows_, lambda_, W_, 1.0); }
  const std::vector<char>& fixedMask() const override { return fixed_; }
  const std::vector<int>& labels() const override { return labels_; }
  Eigen::Vector3d appliedForce(const std::vector<int>& nodes, const SimulationState&, const Eigen::VectorXd&,
                               double) const override {
    // Static: what acts on these nodes besides the material and gravity is the instruments' rows' force on them.
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    if (lambda_.size() != static_cast<Eigen::Index>(rows_.size())) return sum;
    for (std::size_t r = 0; r < rows_.size(); ++r)
      for (int k = 0; k < 4; ++k)
        if (std::find(nodes.begin(), nodes.end(), rows_[r].nodes[static_cast<std::size_t>(k)]) != nodes.end())
          sum += lambda_[static_cast<Eigen::Index>(r)] * rows_[r].weights[static_cast<std::size_t>(k)] *
                 rows_[r].direction;
    return sum;
  }

 protected:
  /// The displacement u from base_ under rows_ (its multipliers into lambda_, the rows' compliance into W_).
  virtual bool solveRows(Eigen::VectorXd& u, std::string& why) = 0;

  SimulationSettings settings_;
  int topology_ = 0;
  std::vector<int> labels_;
  FemModel model_;
  std::vector<char> fixed_;
  Eigen::VectorXd base_;  ///< the rest shape, or the registered shape that is the equilibrium (started_)
  bool started_ = false;
  Eigen::VectorXd
      u0_;  ///< the displacement from base_ at t = 0: the sag when started from rest, else zero (the ctor's)
  std::vector<ScalarConstraint> rows_;
  Eigen::VectorXd lambda_;
  Eigen::MatrixXd W_;
};

}  // namespace rehearse::simcore
