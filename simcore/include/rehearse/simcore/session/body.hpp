#pragma once
// One interface for a deformable body: what the simulation session steps, whatever the model behind it.
// The tetrahedral FEM implements it now (FemBody); the fast models of the older simulators (precomputed
// linear elasticity, the parameterized mesh with free-form deformation) and a cut (a body whose topology
// changed, topologyVersion() + 1, state carried across by transferState) implement it later.
// Units: SI. Positions are in the frame the body was built in (the session builds it in the camera frame).
#include <rehearse/simcore/cut.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/session/field.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::simcore {

/// The instruments' settings of a scene (SI units).
struct ToolSettings {
  double graspRadius = 0.006;   ///< m: closing the jaws holds the nodes within this distance of the tip
  double maxGraspForce = 15.0;  ///< N: above this pull the tissue slips out of the jaws (an event)
  /// The jaws let go at maxGraspForce within a step's change: before a step that would pull the held tissue past it
  /// (the last step's grasp force and tool stiffness, extrapolated along the jaws' move), the jaws go only as far as the
  /// force reaches it, and the tissue slips after that step when the force it solved came within 5 % of the limit (else
  /// the jaws hold there: the first-order prediction overshot). false: a step's whole move was taken and the tissue slipped
  /// after it, however far past the limit the force had gone (a quick 20 mm pull let go at 34.9 N of 15; the sessions
  /// recorded before this existed).
  bool slipAtLimit = true;
  /// With slipAtLimit: a held-back step whose solved grasp force still came out past the limit (more than 2 %: the
  /// first order missed the tissue's give, or the step did not converge) is taken again from its start, the jaws moved
  /// back along their move by regula falsi on the force (at most two more solves, only on such a step; FEM bodies), so
  /// the tissue slips at the limit, not a step's change past it. false: the first-order hold-back alone (the phantom's
  /// slow pulls slipped at 21.5 and 37.4 N of 15 on steps that did not converge, the patient liver's at 15.7-16.9 N;
  /// the sessions recorded before this existed).
  bool slipResolved = true;
  /// Where the instruments' shafts enter (m, body frame); unset: above the organ towards the camera
  /// (the session sets it from the rest shape: twice the organ's radius from its centre along (0, -1, -2)).
  std::optional<Eigen::Vector3d> trocar;
  double bladeLength = 0.03;  ///< m: the cutting instrument's blade, from the tip back along the shaft
  /// A tip deeper in the tissue than the blade is long has cut its way there: the sweep reaches back along the shaft to
  /// where the shaft last crosses the surface (2 mm beyond), so the stroke opens the surface above it. false: the blade's
  /// length only (a stroke 40 mm deep with a 30 mm blade cut a crack 10 mm under an intact surface; the sessions
  /// recorded before this existed, whose replays must cut as they did).
  bool bladeReachesTheSurface = true;
  /// m: the instrument's radius for contact (its shaft, from the tip to the trocar, is a capsule of this
  /// radius); the boundary triangles near it are kept out by unilateral constraints at their closest points
  /// to its axis (between nodes too). 0 (no contact) unless a scene states its instrument's radius.
  double toolRadius = 0;
  /// m/s: surface that is already inside the shaft when it becomes free to touch it (the jaws open on it, the blade
  /// stops cutting, a cut changes the surface, the instrument appears) is pushed out at most this fast, instead of all
  /// at once in one step (an impulse of m d / h^2: the 5.7 N spike after a steady release). Contact the instrument
  /// makes by moving is pushed as before. 0: at once (the sessions recorded before it existed).
  double depenetrationSpeed = 0.02;
  /// Steps between a cut's sweep and the step boundary its new body replaces the old one at, whatever the factor
  /// refresh: the new body is built on another thread meanwhile (the stepping thread waits at that boundary if it is
  /// not ready). So a cut is applied at the same step in every run, synchronous or asynchronous, and a run ends with
  /// the same mesh each time (scripts, benchmarks, tests). -1: a synchronous run cuts at once and an asynchronous one
  /// when the build is ready, never waiting (the GUI's rehearsal, and the sessions recorded before this existed;
  /// their replays follow the recorded CutApplied events). Measured on the liver preset, headless (steps of about
  /// 2 ms): a cut's step waits about 50 ms with 5, none with -1.
  int cutLatencySteps = 5;
  /// Steps between the tissue passing its tear strain and the step boundary its torn body replaces the old one at,
  /// whatever the refresh and the cut's latency (a tear opens in 50 ms): so the same pull tears the same way in every
  /// run. Applied when built (-1), the GUI's tears depended on the second thread: the patient liver pulled fast tore 8
  /// times in one run and 55 in another, each tear's pieces over-stretched in turn, the steps 1.9 s at the median (97
  /// of 150 inexact); with 5, 7 tears in every run, 24-29 ms (BENCHMARKS.md). Sessions recorded before it existed:
  /// their cut's latency, as their tears had.
  int tearLatencySteps = 5;
  /// A tear's torn body comes in at that boundary if built by then, else at the first boundary after (TopologyChange::
  /// late; recorded, replays follow). With the asynchronous refresh only. Not used by the window: measured on the
  /// patient liver (bench_operative, 2026-12-02) the tear steps no longer waited (200-330 ms) but the pull tore 16
  /// times instead of 7, 58 of 151 steps inexact, p99 7.8 s: the torn body came in on a state its factor and its tear
  /// front were not made for, and each late tear over-stretched the next. An experiment kept for the bench; false:
  /// it waits (the sessions recorded before it existed, and the window's).
  bool tearWhenBuilt = false;
  /// A tear the over-stretched element cannot make alone (its square, as large as the element, crosses edges the
  /// elements around it share, and the cut's front snaps those to nodes: nothing is crossed) is made across its
  /// neighbours too, a square twice the element's reach. false: refused, as the sessions recorded before this existed
  /// did (the patient liver pulled beside an attachment stayed at 235 % where it tears at 110 %, "the tear could not be
  /// made there", until the jaws slipped).
  bool tearThroughNeighbours = true;
  /// Tissue tears while the jaws hold it (what pulls it; not a shaft's contact): a tear grows while pulled and stops
  /// when released (issue 61: the patient liver pulled 20 mm, then its tear strain set to 15 %, tore 5 times while
  /// held and 17 more over the 100 steps after the release, the torn flap sagging on its weight). false: whatever
  /// stretches it (the sessions recorded before this existed).
  bool tearOnlyUnderLoad = true;
  /// And only while the jaws pull it: a tear is asked at a step the jaws moved (the held tissue's grip, from the held
  /// nodes at the step's start, to where the jaws are), not while they hold still. A held tear grows as the pull goes
  /// on and stops when the hand does (issue 61: "growing only while pulled"). test_patient_start's path (the patient
  /// liver held by 22 clicks along its top edge, its lone clicks with their neighbours: 42 nodes; pulled 1 mm a move
  /// until a tear shows, then held 10 steps and released): 3 tears in each of 3 runs without it, 1 in each of 2 with it;
  /// test_tear aHeldTearGrowsOnlyWhilePulled. false: every step the jaws hold it (the sessions recorded before this).
  bool tearOnlyWhilePulled = true;
  /// A tear parts the tissue along the faces of the over-stretched elements it runs through (the plane across the worst
  /// one's stretch, through its centre, and the over-stretched elements it crosses next to it; the elements holding a
  /// node the jaws hold, their bite, stay with the jaws when any other element is over-stretched): those elements are
  /// taken out of the mesh and the nodes stay; a node no element holds any more is pinned where it is, and the jaws
  /// let go of it. The unknowns do not change, so the steps after a tear keep a factor of their size and solve a
  /// tangent that changed little: on the patient liver's pull the steps after the tears took 24-28 ms at the median
  /// and 112-139 ms at the 99th percentile, against 34-49 and 631-1,044 ms re-meshed; with the bite kept, 31-35 and
  /// 97-119 ms, and the pull tears 16-18 times instead of 5-6 (BENCHMARKS.md, issue 61). An experiment kept for the bench,
  /// not the window's: the tissue it takes out is lost (its mass too). false: each tear splits its element across the
  /// stretch through the cut's re-meshing (the window's, and the sessions recorded before this existed).
  bool tearRemovesElements = false;
  CutSettings cut;  ///< snapping and the quality the re-meshing keeps
  /// The jaws keep their hold where their own instrument left them while another instrument moves (InputEvent::tool:
  /// the grasper's traction while the scissors cut, as an assistant holds it); false: they follow every move of the
  /// tip, whichever instrument made it (the sessions recorded before this existed: their scissors dragged what the
  /// jaws held).
  bool jawsKeepTheirHold = true;
  ClipSettings clip;        ///< the clip applier's jaws and clips (field.hpp)
  CauterySettings cautery;  ///< the cautery hook's reach, burn time and the stiffening of burnt tissue (field.hpp)
  BleedingSettings bleeding;  ///< how fast a cut vessel bleeds (field.hpp)
  bool operator==(const ToolSettings& o) const {
    return graspRadius == o.graspRadius && maxGraspForce == o.maxGraspForce && slipAtLimit == o.slipAtLimit &&
           slipResolved == o.slipResolved &&
           trocar.has_value() == o.trocar.has_value() && (!trocar || *trocar == *o.trocar) &&
           bladeLength == o.bladeLength && bladeReachesTheSurface == o.bladeReachesTheSurface &&
           toolRadius == o.toolRadius && depenetrationSpeed == o.depenetrationSpeed &&
           cutLatencySteps == o.cutLatencySteps && tearLatencySteps == o.tearLatencySteps &&
           tearWhenBuilt == o.tearWhenBuilt &&
           tearThroughNeighbours == o.tearThroughNeighbours && tearOnlyUnderLoad == o.tearOnlyUnderLoad &&
           tearOnlyWhilePulled == o.tearOnlyWhilePulled &&
           tearRemovesElements == o.tearRemovesElements &&
           cut.snap == o.cut.snap &&
           cut.minQuality == o.cut.minQuality && cut.minVolumeFraction == o.cut.minVolumeFraction &&
           jawsKeepTheirHold == o.jawsKeepTheirHold && clip == o.clip && cautery == o.cautery && bleeding == o.bleeding;
  }
};

/// The deformable model a scene chooses (issue 37). Fem: the tetrahedral FEM with implicit Euler (the default, every
/// law, cuts and tears). Precomputed: Cotin, Delingette and Ayache's precomputed linear elasticity (precomputed.hpp):
/// quasi-static, the exact linear static answer under the instruments by superposition of responses computed when the
/// body is built, tool forces at haptic rate; it cannot cut, tear, clip or burn (its responses are the intact
/// organ's: the session refuses those with a sentence). Hybrid: their hybrid model (hybrid.hpp): a FEM region around
/// where the instruments work (it grows as they move and cut) coupled to the rest's precomputed responses; quasi-static
/// and linear, equal to the linear static answer of the whole organ; it cuts, tears, clips and burns. Ffd: the
/// parameterized mesh (paramesh.hpp): the surface's geometry image deformed by a Gaussian free-form deformation around
/// the grasp or the deepest contact, Hertz's force; geometric (no equilibrium, said by every step), it cannot cut,
/// tear, clip or burn.
enum class BodyModel { Fem, Precomputed, Hybrid, Ffd };
/// "fem", "precomputed", "hybrid", "ffd" (inline: the recording codec, built alone for fuzzing, reads and writes it)
inline std::string bodyModelName(BodyModel m) {
  switch (m) {
    case BodyModel::Precomputed:
      return "precomputed";
    case BodyModel::Hybrid:
      return "hybrid";
    case BodyModel::Ffd:
      return "ffd";
    default:
      return "fem";
  }
}
/// Parses bodyModelName's words; throws MeshError naming them otherwise.
inline BodyModel bodyModelFromString(const std::string& name) {
  for (BodyModel m : {BodyModel::Fem, BodyModel::Precomputed, BodyModel::Hybrid, BodyModel::Ffd})
    if (name == bodyModelName(m)) return m;
  throw MeshError("Unknown deformable model \"" + name + "\": fem, precomputed, hybrid or ffd.");
}
/// Whether the model changes the tissue's elements (cuts, tears, clips, burns): the FEM and the hybrid model.
inline bool bodyModelChangesTissue(BodyModel m) { return m == BodyModel::Fem || m == BodyModel::Hybrid; }

class HybridElasticity;

/// What a FEM body is built from (all of it is recorded with a session, so a replay rebuilds the same body).
struct BodySetup {
  Mesh mesh;  ///< tets (metres); its points are replaced by `rest` when given
  std::vector<Eigen::Vector3d>
      rest;  ///< rest positions (m), e.g. the fitted organ in the camera frame; empty: mesh.points
  /// The positions at t = 0 (m), when the body starts deformed: the registered shape in equilibrium on the rest shape
  /// solved for it (inverse_rest.hpp). Empty: it starts at rest. Cleared by a topology change (the state carries on).
  std::vector<Eigen::Vector3d> start;
  /// The positions a tear's stretch is measured from (m): the state the organ started in (`start`: the in-vivo organ is
  /// not torn, whatever its rest shape sags through to reach it), carried through cuts and tears like the state (new
  /// nodes interpolated). Empty: the rest shape (bodies that start at rest, and sessions recorded before it existed).
  std::vector<Eigen::Vector3d> tearFrom;
  std::vector<int> fixedNodes;            ///< ligament attachments
  /// The tissue around the organ carrying it (support.hpp): zero-length springs from nodes of the surface facing along
  /// gravity, preloaded to carry the weight at the registered shape. Kept by node through cuts and tears (the nodes
  /// a cut adds carry none). The FEM only (the other models hang the organ from its held nodes). Empty: none (the
  /// sessions recorded before this existed).
  std::vector<NodeAnchor> supports;
  MaterialParams material;                ///< parenchyma and unlisted labels
  std::map<int, MaterialParams> byLabel;  ///< e.g. the vessels' label
  SimulationSettings settings;            ///< time step, method, gravity (m/s^2, in the body's frame), ...
  ToolSettings tools;
  int topology = 0;  ///< bumped by every cut (the mesh above is then the cut one, in metres)
  BodyModel model = BodyModel::Fem;  ///< the deformable model the body is
  CutProgress cut;   ///< the blade's cut while it is on (cutTetrahedra's `progress`)
  /// Told the share done (0..1) while a body takes long to build (the precomputed model's responses); false cancels
  /// the build (makeBody then throws with the sentence). Not part of what is recorded.
  std::function<bool(double)> buildProgress;
  /// The hybrid model's FEM region: the elements within 30 mm of these points (m, the body's frame); empty: the
  /// surface's point nearest the trocar. Carried from body to body by the session (DeformableBody::carryInto), derived
  /// from what the instruments did, so not recorded: a replay grows the same region at the same steps.
  std::vector<Eigen::Vector3d> regionCentres;
  /// The hybrid model before a topology change: its rest's responses are kept when the change left the rest as it was.
  std::shared_ptr<const HybridElasticity> hybridBefore;
};

class DeformableBody {
 public:
  virtual ~DeformableBody() = default;
  virtual std::size_t nodeCount() const = 0;
  /// The body at rest (t = 0).
  virtual SimulationState initialState() const = 0;
  /// One time step of the complete state (rolled back with a status when it fails).
  virtual StepReport step(SimulationState& state) = 0;
  /// The step taken again from `state`, its start (the tool's rows changed since the first try): the factor the first
  /// try used, nothing swapped in. nullopt: this body does not take a step again (then the first try stands).
  virtual std::optional<StepReport> stepAgain(SimulationState& /*state*/) { return std::nullopt; }
  /// Deferred factor refresh (a replay of an asynchronous run): builds the factor requested earlier and uses
  /// it from the next step; false when none was requested (Integrator::installRequestedFactor).
  virtual bool installRequestedFactor() { return false; }
  /// A lagged factor was requested and is not swapped in yet (Integrator::factorPending).
  virtual bool factorPending() const { return false; }
  /// A restored state's requested factor is requested again (Integrator::requestAgain).
  virtual void requestAgain(const SimulationState& /*state*/) {}
  /// Builds the lagged factor at positions `x` now (Integrator::prepareLagged); true when the body keeps one,
  /// which a state naming (x, the time step) then uses without refactorising.
  /// `toolNodes`: the nodes the instruments hold and touch, whose compliance the first constrained step needs.
  virtual bool prepareFactor(const Eigen::VectorXd& /*x*/, const std::vector<int>& /*toolNodes*/ = {}) { return false; }
  /// Tool constraints (grasp holds, contacts) for the next steps; replaces the previous ones.
  virtual void setToolConstraints(std::vector<ScalarConstraint> constraints) = 0;
  /// Bumped by every topology change (a cut); views rebuild what they derived from the topology.
  virtual int topologyVersion() const = 0;
  virtual const std::vector<Eigen::Vector3d>& restPositions() const = 0;
  /// Per-element von Mises stress at a state (Pa), for colouring.
  virtual void stress(const SimulationState& state, std::vector<double>& out) const = 0;
  virtual const std::vector<std::array<int, 4>>& tetrahedra() const = 0;
  /// Total mass (kg).
  virtual double mass() const = 0;
  /// The force (N) that something other than the body's material, gravity, inertia and damping applies to
  /// `nodes` at `state`, which a step of length `h` reached from velocities `previousVelocity`: the backward
  /// Euler balance M (v - v0) / h + alpha M v + beta K(x) v - f(x) - M g summed over them. For nodes a tool
  /// holds it is the tool's force on the tissue.
  virtual Eigen::Vector3d appliedForce(const std::vector<int>& nodes, const SimulationState& state,
                                       const Eigen::VectorXd& previousVelocity, double h) const = 0;
  /// The force (N) the tool constraints applied to the body in the last step: the constraint solver's
  /// multipliers along their directions (what the step used, whatever its Newton method). `holdsOnly`: the
  /// bilateral constraints' share alone (the jaws' hold, without the shaft's contact).
  virtual Eigen::Vector3d toolForce(bool holdsOnly = false) const = 0;
  /// The tool's local stiffness (N/m): how the tool force (toolForce) changes per metre the tool moves over
  /// the next step, G^T W_a^-1 G / h^2 from the last solve's compliance W restricted to the tool constraints
  /// that act (bilateral holds, pushing contacts), G their directions (each moves with the tool). Zero
  /// without acting tool constraints. What a haptic loop extrapolates the force with between steps.
  virtual Eigen::Matrix3d toolStiffness() const { return Eigen::Matrix3d::Zero(); }
  /// The nodes fixed by the setup (ligament attachments), 1 for fixed.
  virtual const std::vector<char>& fixedMask() const = 0;
  /// Per element label (the mesh's), e.g. the vessels'.
  virtual const std::vector<int>& labels() const = 0;
  /// What building the body took, in one sentence, when that is worth saying (the precomputed model's responses:
  /// how many, how long, how much memory); empty otherwise.
  virtual std::string buildNote() const { return {}; }
  /// What the next body of this organ (a topology change, a parameter edit) takes from this one (the hybrid model's
  /// region and responses); nothing for the others.
  virtual void carryInto(BodySetup& /*next*/) const {}
  /// The key of the precomputed responses the body uses (ResponseCache; the case file stores them), 0 without.
  virtual std::uint64_t responseKey() const { return 0; }
};

/// toolForceOf (the tool's force from its rows' multipliers): constraint_solver.hpp.
/// The tool's stiffness (N/m), scale * S^T W_a^-1 G over the rows that act (bilateral; unilateral ones that push), W
/// the rows' compliance indexed like lambda: how the tool force changes per metre the tool moves (DeformableBody::
/// toolStiffness). Zero when no row acts or W does not match.
Eigen::Matrix3d toolStiffnessOf(const std::vector<ScalarConstraint>& rows, const Eigen::VectorXd& lambda,
                                const Eigen::MatrixXd& W, double scale);

/// The co-rotational / hyperelastic tetrahedral FEM with implicit Euler (FemModel + Integrator).
/// Throws MeshError for an unusable setup (no tets, invalid material).
std::unique_ptr<DeformableBody> makeFemBody(const BodySetup& setup);
/// Cotin's precomputed linear elasticity (BodyModel::Precomputed; precomputedbody.cpp): its responses are computed here
/// (about a second per thousand surface nodes). Throws MeshError when nothing holds the organ.
std::unique_ptr<DeformableBody> makePrecomputedBody(const BodySetup& setup);
/// The hybrid model (BodyModel::Hybrid; hybridbody.cpp). Throws MeshError when nothing holds the organ.
std::unique_ptr<DeformableBody> makeHybridBody(const BodySetup& setup);
/// The parameterized mesh with free-form deformation (BodyModel::Ffd; ffdbody.cpp). Throws MeshError when the organ's
/// surface cannot be mapped onto a square (not one closed piece without handles).
std::unique_ptr<DeformableBody> makeFfdBody(const BodySetup& setup);
/// The default trocar: above the organ (rest positions, m) towards the camera, twice its radius from its centre.
Eigen::Vector3d defaultTrocar(const std::vector<Eigen::Vector3d>& rest);
/// The body the setup's model names.
std::unique_ptr<DeformableBody> makeBody(const BodySetup& setup);

}  // namespace rehearse::simcore
