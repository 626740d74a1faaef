#pragma once
// From a case to a running rehearsal, one way for the GUI's Simulation panel and `rehearse gesture` (issue 63): the
// case's organ and what the panel (or the command line) sets -> the body a session simulates (bodySetup) -> its start
// (prepareStart: the rest shape that sags into the registered shape, or at rest on it; the tissue around it placed;
// refused when nothing holds it or no equilibrium exists there) -> simcore::Session. The panel only shows and asks:
// the outcome says what happened, with the solve's numbers, and each caller words it (the GUI in its translations).
#include <rehearse/app/case.hpp>
#include <rehearse/simcore/inverse_rest.hpp>
#include <rehearse/simcore/session/body.hpp>

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>

namespace rehearse::app {

/// What a rehearsal runs: the case's organ as the frame shows it (its fitted shape once there is one, posed in the
/// camera frame, metres), its attachments, the case's material and the run's parameters (the Simulation panel's).
struct SessionRequest {
  std::shared_ptr<const Case> organ;
  simcore::MaterialModel model = simcore::MaterialModel::Corotational;
  double young = 27e3;  ///< Pa, parenchyma
  double poisson = 0.4;
  double density = 1000;   ///< kg/m^3
  double vesselYoung = 0;  ///< Pa, label 2 (0: as the parenchyma)
  double timeStep = 0.01;  ///< s
  simcore::NewtonMethod method = simcore::kInteractiveMethod;
  /// m: the accuracy each step is asked for (SimulationSettings::accuracyPosition, with 0.5 % of the tool force; the
  /// panel's Accuracy, e.g. 0.05 mm); 0: the relative residual alone (1e-6). Off by default for now: with 0.05 mm the
  /// default, test_review_gui's replay froze the window 28-116 ms in 5 runs (42-58 ms off), not yet understood.
  double accuracy = 0;
  /// The deformable model (the Solver list's last entry: Cotin's precomputed linear elasticity; it cannot cut).
  simcore::BodyModel bodyModel = simcore::BodyModel::Fem;
  double vesselPoisson = 0.45;
  Eigen::Vector3d gravity = Eigen::Vector3d(0, 0, 9.81);  ///< m/s^2 in the camera frame (default: into the scene)
  /// m: the instruments' shaft radius for contact (a 5 mm laparoscopic instrument): the tissue is pushed, not
  /// penetrated; 0 turns contact off.
  double toolRadius = 0.0025;
  /// m: the grasper's bite: closing the jaws holds the free nodes within this distance of the tip (a coarse mesh's
  /// nodes can be a centimetre apart: 6 mm may hold one).
  double graspRadius = 0.006;
  double clipLength = 0.009;  ///< m, the clip applier's jaws
  double tearStrain = 0;      ///< where the tissue tears (MaterialSettings::tearStrain; 0: never)
  /// The organ starts where the frame shows it, in equilibrium under gravity on its attachments: the rest shape that
  /// sags into the registered one is solved first (simcore/inverse_rest.hpp). Off: it starts at rest on that shape
  /// (and sags away from it).
  bool startInEquilibrium = true;
  /// Pa/m: the tissue around the organ carries it (simcore/support.hpp; the case's MaterialSettings::supportModulus);
  /// 0: only the held nodes hold it. The FEM only (the other models hang the organ from its held nodes).
  double supportModulus = 1e5;
};

/// The body a session simulates: the case's organ as the frame shows it (current shape, posed in the camera frame),
/// its attachments and material by label, the run's settings, as the GUI runs it (the factor rebuilt on the second
/// thread, a cut's body taken as soon as it is built).
simcore::BodySetup bodySetup(const SessionRequest& s);

/// The last rest shape solved, by the key of the body and support it was solved for: a Reset, or Record, of the same
/// organ takes it again instead of solving again (12 s on a 16k-tet liver). Shared between threads.
class RestShapeCache {
 public:
  std::optional<simcore::InverseRestResult> find(std::uint64_t key) const;
  void keep(std::uint64_t key, const simcore::InverseRestResult& r);

 private:
  mutable std::mutex mutex_;
  std::uint64_t key_ = 0;
  std::optional<simcore::InverseRestResult> result_;
};

/// How a body starts (prepareStart).
struct StartOptions {
  /// In equilibrium where it is (the rest shape that sags into the body's shape solved first); false: at rest on it.
  bool inEquilibrium = true;
  /// Pa/m: the tissue around the organ carries it (the FEM only; other models hang it from their held nodes); 0: none.
  double supportModulus = 0;
  /// Each static solve of the rest shape (its number, its equilibrium's distance from the shape in m); false cancels.
  std::function<bool(int, double)> progress;
  RestShapeCache* cache = nullptr;  ///< the rest shape solved for the same body before (none: solved)
  /// A lone attachment holds its neighbours on the surface too (simcore::attachmentPatches: one pinned node crushes
  /// its own elements); false: the held nodes as given (a scene's or preset's own). The window asks it for its clicks
  /// (launchSession), `rehearse gesture` for a case's attachments and nodes given as a file (--fixed-nodes).
  bool attachmentPatches = false;
};

/// What prepareStart found.
struct SessionStart {
  enum class Outcome {
    Ready,          ///< `body` is ready for simcore::Session
    NothingHolds,   ///< under gravity with no held node and no support that can carry it: it would fall
    NoEquilibrium,  ///< no rest shape has its equilibrium at the shape (`rest` says how close the best came)
    Cancelled,      ///< the progress callback stopped the solve
  };
  enum class Start {
    Weightless,     ///< no gravity: at rest where it is
    InEquilibrium,  ///< its rest shape solved: it stays where it is until an instrument acts
    SagsFromShape,  ///< at rest on the shape: it sags from it under gravity (on the tissue placed there, if any)
  };
  Outcome outcome = Outcome::Ready;
  Start start = Start::Weightless;
  simcore::BodySetup body;
  /// A support was asked but the body's model hangs the organ from its held nodes only (the FEM alone stands it on
  /// the tissue around it).
  bool supportNotInModel = false;
  bool reused = false;                         ///< the rest shape came from the cache (the same organ as before)
  std::size_t picked = 0;  ///< attachments given (the body's held nodes before StartOptions::attachmentPatches)
  std::size_t lone = 0;    ///< of them, lone picks that hold their neighbours on the surface too
  std::size_t held = 0;    ///< nodes the body holds
  /// "The lone attachment holds its 6 neighbours too (7 nodes held): ..." (on the surface, or inside the organ for a
  /// pick inside it). Empty when no pick is lone.
  std::string patchesSentence() const;
  std::optional<simcore::InverseRestResult> rest;  ///< the solve, when one was made or reused
};

/// `body` (its shape: `rest`, or the mesh's points when empty) made ready to start as `options` asks: in equilibrium
/// (its rest shape solved and the supports placed by the solve), or at rest on its shape (the supports placed there).
/// Never throws for a numerical failure: the outcome says it. Throws simcore's errors for a body that is not one.
SessionStart prepareStart(simcore::BodySetup body, const StartOptions& options);

}  // namespace rehearse::app
