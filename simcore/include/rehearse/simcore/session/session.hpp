#pragma once
// The simulation session (no Qt): owns a deformable body and its complete state on its own thread, takes
// timestamped input events through a mailbox (applied at the next step boundary, in order), publishes a
// snapshot after every step for the views, and records every applied event with the step it applied at,
// so that a replay of the recording from the same start gives the same states bit for bit.
//
// This is the room for the rest of rehearsal: the tool-force loop (a second, faster loop reading the
// body's snapshot, issue 15), topology changes (a cut replaces the body, carrying the state across,
// applied at a step boundary like any event), and recording into the case file (checkpoints every N
// steps + the event list, issue 16). The GUI's Simulation panel and the rehearse step drive a Session;
// tests drive it without its thread through advance().
#include <rehearse/simcore/session/body.hpp>
#include <rehearse/simcore/session/contact.hpp>
#include <rehearse/simcore/session/input.hpp>
#include <rehearse/simcore/session/instrument.hpp>
#include <rehearse/simcore/session/sessionloop.hpp>
#include <rehearse/simcore/session/strokes.hpp>
#include <rehearse/simcore/session/topologybuilds.hpp>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <future>
#include <mutex>
#include <optional>
#include <thread>

namespace rehearse::simcore {

/// What the tools hold between steps (part of a checkpoint: it decides the next step's constraints).
struct ToolState {
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  bool jawClosed = false;
  std::vector<int> held;  ///< the nodes the jaws hold (within the grasp radius when they closed), nearest first
  std::vector<Eigen::Vector3d> heldOffset;  ///< each held node's place relative to `jawTip` (m), kept while held
  /// Where the jaws are (m, body frame): the tip of the instrument that closed them (`jawTool`), which the held nodes'
  /// places are relative to. With ToolSettings::jawsKeepTheirHold another instrument moving the tip leaves it where
  /// it is (the grasper's traction held while the scissors cut); without, it follows every move of the tip.
  Eigen::Vector3d jawTip = Eigen::Vector3d::Zero();
  int jawTool = 0;  ///< the instrument (InputEvent::tool) that closed the jaws
  bool cutting = false;
  Eigen::Vector3d cutFrom = Eigen::Vector3d::Zero();  ///< the tip where the blade's last sweep ended (while cutting)
  Eigen::Vector3d force =
      Eigen::Vector3d::Zero();  ///< N, the tool's force on the tissue after the last step (grasp and contact)
  /// N, the jaws' share of `force` (the held nodes' constraints; the rest is the shaft's contact): what the grasp
  /// holds, and what decides a slip.
  Eigen::Vector3d graspForce = Eigen::Vector3d::Zero();
  Eigen::Matrix3d stiffness =
      Eigen::Matrix3d::Zero();  ///< N/m, d(force)/d(tip) over the next step (DeformableBody::toolStiffness)
  bool present = false;         ///< an instrument is in the scene (a pose was given): contact is detected
  int contacts = 0;             ///< surface triangles the instrument touches at the last step
  int pierced = 0;              ///< surface triangles its shaft passes through (contact cannot push those)
  /// Contact being eased: (surface triangle, the distance from the shaft's axis it is held at now, m), for triangles
  /// that were inside the shaft when they became free to touch it; the distance grows to the radius at
  /// ToolSettings::depenetrationSpeed. Sorted by triangle.
  std::vector<std::pair<int, double>> easing;
  /// The named structures' labels this blade stroke has cut (a stroke's cut updates through one structure are one
  /// event: "vessel cut", "portal vein cut", "tumour margin breached"...; Mesh::labelKind).
  std::vector<int> structuresCut;
  /// Nodes the jaws let go of (a release or a slip), sorted: free of the shaft's contact while they are inside its
  /// radius and the instrument stays where it let go (the tissue leaves the open jaws); eased out otherwise.
  std::vector<int> released;
};

/// The organ's boundary after a cut: triangles (node indices, outward) and which of them are cut tissue
/// (not on the uncut organ's surface).
struct CutSurface {
  std::vector<std::array<int, 3>> triangles;
  std::vector<char> cut;
  std::vector<int> labels;  ///< the element label of each triangle's tetrahedron (a cut vessel's faces carry its label)
  std::size_t cutCount = 0;
  std::vector<Eigen::Vector3d> rest;  ///< the cut mesh's rest positions (m, body frame)
};

/// Published after every step (and after reset): read by the views on any thread.
struct Snapshot {
  long step = 0;
  double time = 0;                         ///< s, simulated
  std::vector<Eigen::Vector3d> positions;  ///< per node, body frame (m)
  StepReport report;                       ///< of the last step (ok at rest)
  int topologyVersion = 0;
  ToolState tool;
  MaterialParams material;          ///< in use (shows when a live edit took effect)
  std::string message;              ///< a sentence about the last applied input, when it needs one
  std::vector<double> stress;       ///< per element von Mises stress (Pa), only while setPublishStress(true)
  std::vector<std::string> events;  ///< what happened at this step ("grasp", "release", "slip", "cut", "vessel cut",
                                    ///< "cut through label N" per label cut, "clip", "clip misplaced", "bleeding",
                                    ///< "bleeding stopped", "tear", "<structure> torn", "attachment torn")
  OperativeField field;             ///< the clips on the tissue, the stumps that bleed, the blood lost
  double mass = 0;                  ///< kg, the body's total
  std::size_t elements = 0;
  std::uint64_t responseKey = 0;  ///< the precomputed responses the body uses (ResponseCache), 0 without
  BodyModel model = BodyModel::Fem;  ///< the deformable model that ran the step
  /// The elements (node indices) at this step: shared between snapshots until a cut changes them.
  std::shared_ptr<const std::vector<std::array<int, 4>>> tets;
  std::shared_ptr<const std::vector<int>> labels;    ///< the elements' labels (burnt ones: isBurnt), shared likewise
  Eigen::Vector3d trocar = Eigen::Vector3d::Zero();  ///< where the shafts enter (m, body frame)
  double toolRadius = 0;  ///< m: the shafts' radius for contact (0: the shafts do not touch the tissue)
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();  ///< m/s^2, body frame (the way blood runs)
  /// After a cut (topologyVersion > 0): the boundary to draw, cut tissue marked; null before any cut.
  std::shared_ptr<const CutSurface> surface;
};

/// Everything needed to continue a run exactly from a step: the body's setup (parameters as edited so
/// far), the complete state, the tools, and a cut under way (being built, and the rest of the sweep).
struct Checkpoint {
  long step = 0;
  BodySetup setup;
  SimulationState state;
  ToolState tool;
  OperativeField field;
  std::optional<TopologyChange> pendingChange;
  std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> restOfSweep;
};

/// What a recorder reads after every step (on the stepping thread, under the session's lock: read it there,
/// do not call back into the session).
struct StepRecord {
  long step = 0;                                      ///< steps done (1 after the first)
  const std::vector<InputEvent>* recorded = nullptr;  ///< every event applied so far, with its step
  const SimulationState* state = nullptr;             ///< the complete state after the step
  const Snapshot* snapshot = nullptr;                 ///< what was just published
  const class Session* session = nullptr;
  Checkpoint checkpoint() const;  ///< the complete state here
};

/// What the loop extrapolates from: one physics step's tool force and stiffness at the tip it had.
struct ToolForceModel {
  long step = -1;                                       ///< the physics step it came from (-1: none yet)
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();        ///< m, where the tool was at that step
  Eigen::Vector3d force = Eigen::Vector3d::Zero();      ///< N, the tool's force on the tissue there
  Eigen::Matrix3d stiffness = Eigen::Matrix3d::Zero();  ///< N/m, d force / d tip
  double maxForce = 0;                                  ///< N, the cap (0: none)
  /// m: how far from `tip` the linear model is trusted (the shaft's radius, or the grasp radius): beyond it the contact
  /// set is another one, so the extrapolation goes no further (a device far from the last step's tip, after a jump of
  /// the instrument, read 18 kN on the patient liver). 0: unbounded.
  double reach = 0;
};

/// It runs the instruments (instrument.hpp) as their host: what they may ask of the body at a step boundary.
class Session : private InstrumentHost {
 public:
  /// Builds the body (throws MeshError with one sentence for an unusable setup).
  explicit Session(BodySetup setup);
  ~Session();  ///< stops the thread (waits for the step in progress)
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  /// Any thread: an input for the next step boundary (its wallTime is set here when left at 0).
  void post(InputEvent e);
  /// Any thread: play paced to real time on the session's thread, pause, one step, back to rest.
  void play();
  void pause();
  void stepOnce();
  void reset();
  bool playing() const { return loop_.playing(); }
  /// Any thread: the last published snapshot (never null).
  std::shared_ptr<const Snapshot> snapshot() const;
  /// Any thread, without a lock (the tool-force loop's source): the last published step's tool force and
  /// stiffness at its tip, capped at the scene's maximum grasp force while the jaws hold.
  ToolForceModel toolForce() const;
  /// Called on the session's thread after each publish (the GUI queues a repaint from it). Set before play.
  void setPublishedCallback(std::function<void()> f);
  /// Any thread: whether snapshots carry the elements' von Mises stress (costs one pass over the elements).
  /// The next snapshot is published at once with it.
  void setPublishStress(bool on);
  /// Called on the stepping thread after every step, under the session's lock (a recorder writes from it).
  /// Set before play, or while paused.
  void setStepHook(std::function<void(const StepRecord&)> f);
  /// Drops the inputs posted and not applied yet (a replay seeking elsewhere posts its own).
  void discardPending();
  /// A headless run's end: the cut under way (its body being built) is applied now, waiting for it, so that the run's
  /// last mesh has every cut the blade made. True when one was applied.
  bool applyPendingChange();

  /// The deterministic core: applies the events due at this boundary, then one step, then publishes.
  /// The thread calls it; tests call it directly (never both at once: it locks).
  StepReport advance();
  /// The events applied so far, with their steps (the recording).
  std::vector<InputEvent> recorded() const;
  Checkpoint checkpoint() const;
  /// Continues from a checkpoint (the body is rebuilt from its setup when that differs).
  void restore(const Checkpoint& c);
  /// The complete state (a copy, under the lock).
  SimulationState state() const;
  const BodySetup& setup() const { return setup_; }
  /// Contact detections run so far (0 in a scene without instruments: none is built or run).
  long contactQueries() const { return contactQueries_; }
  /// What the session built for its instruments (a scene builds only what it uses): the contact's
  /// bounding-volume hierarchies (only with a shaft radius), the cuts' re-meshings and cut surfaces (only
  /// once a blade cuts). Read on the session's thread or while it is paused.
  struct Constructions {
    long contactHierarchies = 0;
    long cutMeshes = 0;
    long cutSurfaces = 0;
  };
  Constructions constructions() const { return constructions_; }

 private:
  void apply(const InputEvent& e, std::string& message);
  void rebuildBody();
  void updateToolConstraints();
  /// Before a step: the jaws held back where the grasp force reaches the limit (ToolSettings::slipAtLimit); true when
  /// they were (the tissue then slips after the step).
  bool limitJawsAtGraspForce();
  /// After a step the jaws made (jawMove_): when the grasp force it solved is past the limit by more than 2 %, the step
  /// is taken again from `start` with the jaws moved back along their move (ToolSettings::slipResolved); the report of
  /// the step kept.
  StepReport resolveGraspLimit(const SimulationState& start, StepReport first);
  bool jawsAtGraspLimit() const override { return slipDue_; }
  bool stepConverged() const override { return stepConverged_; }
  // InstrumentHost: what an instrument may ask of the session.
  const Eigen::VectorXd& positions() const override { return state_.x; }
  const std::vector<char>& fixedMask() const override { return body_->fixedMask(); }
  const ToolSettings& tools() const override { return setup_.tools; }
  const SimulationSettings& settings() const override { return setup_.settings; }
  double meanEdge() const override { return meanEdge_; }
  void emitEvent(const std::string& event) override { events_.push_back(event); }
  void seedContactEasing() override { seedEasing_ = true; }
  void finishTopologyChange(std::string& message) override { finishPendingChange(true, message); }
  bool topologyChangeUnderWay() const override { return builds_.underWay(); }
  bool cut(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
           std::string& message) override;  ///< true when the tissue changed (or will)
  void cutWhenIn(const Eigen::Vector3d& from, const Eigen::Vector3d& to) override { strokes_.cutWhenIn(from, to); }
  void forgetCutProgress() override;
  void beginStroke() override;
  OperativeField& field() override { return field_; }
  bool burn(const std::vector<int>& elements, std::string& message) override;
  const std::vector<std::array<int, 4>>& elements() const override { return body_->tetrahedra(); }
  const std::vector<int>& elementLabels() const override { return body_->labels(); }
  double time() const override { return state_.time; }
  const Mesh& mesh() const override { return setup_.mesh; }
  void fieldChanged(std::string& message) override;
  OperativeField field_;  ///< clips, bleeding stumps, blood lost (field.hpp; part of a checkpoint)
  /// The stumps again (after a cut or a clip), with their events and sentence.
  void updateBleeds(std::string& message);
  std::vector<std::unique_ptr<Instrument>> instruments_ = makeInstruments();

  // Topology changes (topology.cpp), one mechanism whatever computed the new mesh (cutting.cpp: the blade's sweep):
  // a request, the new body built at once or on another thread while the old body goes on stepping, and a swap at a
  // step boundary (the first after it is ready, or the change's own applyAt), the state carried across from where
  // the tissue is by then (the change's interpolation of new nodes).
  /// Applies `change` now (synchronous refresh without a latency), or starts building its body on another thread.
  /// False, with `message`, when the new body could not be built (the old one stays).
  bool changeTopology(TopologyChange change, std::string& message);
  /// Swaps the pending change's body in when it is ready (or, with `wait`, after waiting); true when swapped.
  bool finishPendingChange(bool wait, std::string& message);
  /// What every applied change does after the body changed: elements, surfaces, contact, then its events.
  void topologyChanged(const TopologyChange& change, std::string& message);
  /// What a burn applied says: the elements burnt, the stumps it stopped.
  void burnEvents(std::string& message);
  /// The change under way and the bodies built and dropped on other threads (topologybuilds.hpp).
  TopologyBuilds builds_;

  /// The cut module's new mesh (copies of the body's, cut) as the next body's setup: new nodes held where their
  /// originals were (duplicates of fixed nodes fixed), topology + 1, applied after the scene's latency (a tear's
  /// own, ToolSettings::tearLatencySteps, for kind Tear).
  TopologyChange changeFromCut(const CutResult& r, std::vector<Eigen::Vector3d> rest,
                               std::vector<std::array<int, 4>> tets, std::vector<int> labels, CutProgress progress,
                               ChangeKind kind) const;

  // Tearing (tearing.cpp): after a step, the element stretched furthest past its material's tear strain
  // (MaterialParams::tearStrain) is split across its largest stretch, through the cut's re-meshing, as a change of
  // kind Tear; its events and sentence are said at once. One change at a time: while one is being built the next
  // waits.
  void tearOverStretched(std::string& message);
  void settleHeldBackClips(std::string& message);
  bool saidNoTear_ = false;   ///< the precomputed model's sentence that it does not tear, said once
  /// The jaws were held back this step to let go at the grasp limit (ToolSettings::slipAtLimit): the tissue slips
  /// after it. Set and read within one advance().
  bool slipDue_ = false;
  /// The jaws hold tissue and move this step (ToolSettings::tearOnlyWhilePulled: a held tear grows only while pulled):
  /// the grip at the step's start, from the held nodes less their offsets, is not where the jaws are. Set and read
  /// within one advance() (from the state alone: a restored session decides it the same way).
  bool jawsPull_ = false;
  /// This step's move of the jaws (limitJawsAtGraspForce, after its hold-back): from where the last step left them
  /// (`from`) along `move`. Set and read within one advance(); valid only when the jaws hold and make their own move.
  struct JawMove {
    bool valid = false;
    Eigen::Vector3d from = Eigen::Vector3d::Zero(), move = Eigen::Vector3d::Zero();
  } jawMove_;
  /// The tool's rows as last made (updateToolConstraints; the instruments' holds first): a step taken again changes
  /// only the jaws' own.
  std::vector<ScalarConstraint> toolRows_;
  bool stepConverged_ = true;  ///< the last step's outcome was Converged (InstrumentHost::stepConverged)
  bool tearRefused_ = false;  ///< the last tear could not be made (said once until one is made)
  bool tearHeld_ = false;     ///< an over-stretched element not torn because the step did not converge (said once)

  // The cut (cutting.cpp): what the blade's sweep asks of the cut module, and what a cut says.
  /// The blade's stroke and the rest of a sweep asked for while a cut was being built (strokes.hpp; the rest of the
  /// sweep is part of a checkpoint, the stroke is not).
  StrokeTracker strokes_;
  /// After a swap: the rest of the sweep the blade finished while the change was being built.
  void continueSweep(std::string& message);
  /// The stroke's sentence once nothing of it is under way any more.
  void finishStroke(std::string& message);
  /// A cut applied (either way): its events ("cut", "cut through label N", "vessel cut" once per vessel and stroke),
  /// and the new surface's triangles inside the shaft eased out from the next constraints on.
  void cutEvents(const std::vector<int>& cutLabels, std::string& message);
  void publish(const StepReport& rep, const std::string& message, std::vector<std::string> events = {});
  void run();
  friend struct StepRecord;
  Checkpoint checkpointLocked() const;
  std::function<void(const StepRecord&)> stepHook_;

  BodySetup setup_;
  BodySetup uncut_;      ///< the setup the session started from (reset goes back to its mesh)
  double meanEdge_ = 0;  ///< m, of the uncut mesh: the blade's sweep is applied in steps of it
  std::unique_ptr<DeformableBody> body_;
  std::shared_ptr<const std::vector<std::array<int, 4>>> tets_;
  std::shared_ptr<const std::vector<int>> labels_;  ///< body_->labels(), shared with the snapshots until it changes
  /// The body's elements or their labels changed: the shared copies the snapshots carry are made again.
  void elementsChanged() {
    tets_ = std::make_shared<const std::vector<std::array<int, 4>>>(body_->tetrahedra());
    labels_ = std::make_shared<const std::vector<int>>(body_->labels());
  }
  std::shared_ptr<const CutSurface> surface_;  ///< after a cut
  void updateCutSurface();
  void updateSurfaceNodes();
  ContactSurface contact_;  ///< the boundary contact acts on, per topology
  void useContactSurface(ContactSurface c);
  std::shared_ptr<PointBvh> bvh_;  ///< over surfaceNodes_, refitted before each contact query
  long contactQueries_ = 0;
  Constructions constructions_;
  int contactConstraints_ = 0;  ///< contact constraints in the body now (touching or within reach)
  /// The nodes of the tool's rows now (a topology change's build solves their compliance blocks).
  std::vector<int> toolNodes_;
  /// Surface became free to touch the shaft at this boundary (release, blade off, cut applied, instrument appeared):
  /// what is inside it then is eased out (ToolState::easing). Set and consumed within one advance().
  bool seedEasing_ = false;
  SimulationState state_;
  ToolState tool_;
  long steps_ = 0;
  std::vector<InputEvent> recorded_;
  std::vector<std::string> events_;  ///< what the events applied at this boundary did, for the next snapshot
  std::chrono::steady_clock::time_point started_;

  mutable std::mutex stepMutex_;  // body, state, tools, strokes, recording
  /// The session's thread, its mailbox, control flags and what is published (sessionloop.hpp; its own mutex, the
  /// "mailbox" one, taken after stepMutex_ when both are held).
  SessionLoop loop_;
};

/// Runs a body from rest through `steps` steps with a recorded list of events (each applied at its
/// `step`); calls `each` after every step with the complete state. Deterministic: the same inputs give
/// bit-identical states.
/// A replay runs an asynchronous refresh as a deferred one (the recording's Factor events install the factors).
void replay(const BodySetup& setup, const std::vector<InputEvent>& events, long steps,
            const std::function<void(long step, const SimulationState&)>& each);
/// The setup a replay builds its session from: an asynchronous refresh becomes a deferred one (the
/// recording's Factor events install the factors where the live run swapped them in).
BodySetup replaySetup(BodySetup setup);
/// The cut mesh's boundary, each triangle marked as the organ's own surface or cut tissue (against the uncut setup's).
std::shared_ptr<const CutSurface> makeCutSurface(const BodySetup& uncutSetup, const Mesh& cutMesh, double meanEdge);
/// How many pieces the elements make (elements sharing a node are one piece): whether a cut went through.
std::size_t connectedPieces(const std::vector<std::array<int, 4>>& tets, std::size_t nodes);
/// Each node's piece (0, 1, ... in the order the elements reach them; -1: a node of no element).
std::vector<int> nodePieces(const std::vector<std::array<int, 4>>& tets, std::size_t nodes);
/// The pieces' volumes at rest (m^3, positions `rest`), largest first: as many as connectedPieces.
std::vector<double> pieceVolumes(const std::vector<std::array<int, 4>>& tets, const std::vector<Eigen::Vector3d>& rest);
/// The same, `each` given the replaying session (its snapshot: the tool, the events of the step).
void replaySession(const BodySetup& setup, const std::vector<InputEvent>& events, long steps,
                   const std::function<void(long step, const Session&)>& each);

}  // namespace rehearse::simcore
