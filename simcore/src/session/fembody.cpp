#include <rehearse/simcore/session/body.hpp>

namespace rehearse::simcore {
namespace {

class FemBody final : public DeformableBody {
 public:
  explicit FemBody(const BodySetup& s) : model_(build(s)), integrator_(model_, s.fixedNodes, s.settings) {}
  std::size_t nodeCount() const override { return model_.nodeCount(); }
  SimulationState initialState() const override { return integrator_.initialState(); }
  StepReport step(SimulationState& state) override { return integrator_.step(state); }
  void setToolConstraints(std::vector<ScalarConstraint> c) override { integrator_.setConstraints(std::move(c)); }
  int topologyVersion() const override { return 0; }
  const std::vector<Eigen::Vector3d>& restPositions() const override { return model_.rest; }
  void stress(const SimulationState& state, std::vector<double>& out) const override { vonMisesStress(model_, state.x, out); }
  const std::vector<std::array<int, 4>>& tetrahedra() const override { return model_.tets; }

 private:
  static FemModel build(const BodySetup& s) {
    Mesh mesh = s.mesh;
    mesh.convertToMetres();
    if (!s.rest.empty()) {
      if (s.rest.size() != mesh.points.size())
        throw MeshError("The body's rest positions (" + std::to_string(s.rest.size()) + ") do not match its mesh (" +
                        std::to_string(mesh.points.size()) + " nodes).");
      mesh.points = s.rest;
    }
    return FemModel::build(mesh, s.byLabel, s.material);
  }
  FemModel model_;
  Integrator integrator_;
};

}  // namespace

std::unique_ptr<DeformableBody> makeFemBody(const BodySetup& setup) { return std::make_unique<FemBody>(setup); }

}  // namespace rehearse::simcore
