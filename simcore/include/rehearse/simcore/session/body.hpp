#pragma once
// One interface for a deformable body: what the simulation session steps, whatever the model behind it.
// The tetrahedral FEM implements it now (FemBody); the fast models of the older simulators (precomputed
// linear elasticity, the parameterized mesh with free-form deformation) and a cut (a body whose topology
// changed, topologyVersion() + 1, state carried across by transferState) implement it later.
// Units: SI. Positions are in the frame the body was built in (the session builds it in the camera frame).
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/integrator.hpp>

#include <memory>
#include <string>
#include <vector>

namespace rehearse::simcore {

/// What a FEM body is built from (all of it is recorded with a session, so a replay rebuilds the same body).
struct BodySetup {
  Mesh mesh;                               ///< tets (metres); its points are replaced by `rest` when given
  std::vector<Eigen::Vector3d> rest;       ///< rest positions (m), e.g. the fitted organ in the camera frame; empty: mesh.points
  std::vector<int> fixedNodes;             ///< ligament attachments
  MaterialParams material;                 ///< parenchyma and unlisted labels
  std::map<int, MaterialParams> byLabel;   ///< e.g. the vessels' label
  SimulationSettings settings;             ///< time step, method, gravity (m/s^2, in the body's frame), ...
};

class DeformableBody {
 public:
  virtual ~DeformableBody() = default;
  virtual std::size_t nodeCount() const = 0;
  /// The body at rest (t = 0).
  virtual SimulationState initialState() const = 0;
  /// One time step of the complete state (rolled back with a status when it fails).
  virtual StepReport step(SimulationState& state) = 0;
  /// Tool constraints (grasp holds, contacts) for the next steps; replaces the previous ones.
  virtual void setToolConstraints(std::vector<ScalarConstraint> constraints) = 0;
  /// Bumped by every topology change (a cut); views rebuild what they derived from the topology.
  virtual int topologyVersion() const = 0;
  virtual const std::vector<Eigen::Vector3d>& restPositions() const = 0;
  /// Per-element von Mises stress at a state (Pa), for colouring.
  virtual void stress(const SimulationState& state, std::vector<double>& out) const = 0;
  virtual const std::vector<std::array<int, 4>>& tetrahedra() const = 0;
};

/// The co-rotational / hyperelastic tetrahedral FEM with implicit Euler (FemModel + Integrator).
/// Throws MeshError for an unusable setup (no tets, invalid material).
std::unique_ptr<DeformableBody> makeFemBody(const BodySetup& setup);

}  // namespace rehearse::simcore
