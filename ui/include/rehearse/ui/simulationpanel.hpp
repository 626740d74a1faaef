#pragma once
// The simulation panel: the case's organ as the frame shows it (fitted shape, camera frame) simulated by a
// simcore::Session on the session's own thread (play, pause, single step, reset); material and run
// parameters edited live go to the session as timestamped input events (applied at the next step
// boundary, recorded with the run); a 3D view of the deformed mesh coloured by displacement or von Mises
// stress. No simulation state lives here: the panel only draws the session's published snapshots, and the session
// starts through the application core (app/sessionstart.hpp), as `rehearse gesture` starts its own.
#include <rehearse/app/case.hpp>
#include <rehearse/app/recording.hpp>
#include <rehearse/app/sessionstart.hpp>
#include "rehearse/ui/organview.hpp"

#include <rehearse/simcore/session/forceloop.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QElapsedTimer>
#include <QPointer>
#include <QProgressDialog>
#include <QWidget>

#include <atomic>
#include <cstdint>
#include <future>
#include <memory>
#include <optional>
#include <vector>

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QPushButton;

namespace rehearse::ui {
class Throttle;
}

namespace rehearse::ui {

/// What the simulation runs (app/sessionstart.hpp: the panel asks, the application core starts it).
using SimulationSetup = app::SessionRequest;

/// Published after each step: positions and the coloured quantity per node.
struct SimulationFrame {
  std::vector<Eigen::Vector3d> positions;  ///< per node, camera frame (m)
  std::vector<double> value;               ///< per node: displacement (mm) or von Mises (kPa)
  double valueMax = 0;
  double valueScale = 0;  ///< top of the colour bar: the 98th percentile (stress peaks at attachments)
  int colouring = 0;      ///< 0 displacement, 1 von Mises
  simcore::StepReport report;
  double time = 0;  ///< simulated time (s)
  long steps = 0;
  double youngInUse = 0;        ///< Pa (shows when a live edit took effect)
  Qt::HANDLE thread = nullptr;  ///< the thread that computed it (never the GUI thread)
  std::shared_ptr<const app::Case> organ;
  QString message;                  ///< the session's sentence about the last applied input, if any
  simcore::ToolState tool;          ///< the instrument after the step (tip, held nodes, force on the tissue)
  std::vector<std::string> events;  ///< grasp, release, slip, cut, vessel cut at this step
  std::shared_ptr<const simcore::CutSurface> surface;  ///< after a cut: the boundary to draw (cut tissue marked)
  simcore::OperativeField field;                       ///< clips, bleeding stumps, blood lost, the cautery's heat
  std::shared_ptr<const std::vector<int>> labels;      ///< the elements' labels (burnt ones: simcore::isBurnt)
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();   ///< m/s^2, camera frame
  /// The nodes the tissue around the organ carries (BodySetup::supports; drawn beneath the organ), none without.
  std::shared_ptr<const std::vector<int>> supports;
  /// Steps since the start (or the last Reset) that did not converge to the scene's tolerance: every step counted,
  /// whether or not its frame was drawn.
  long stepsNotConverged = 0;
  std::size_t elements = 0;
  std::uint64_t responseKey = 0;  ///< the precomputed model's responses (simcore::ResponseCache), 0 for the FEM
  simcore::BodyModel model = simcore::BodyModel::Fem;           ///< the deformable model that ran the step
  Eigen::Vector3d trocar = Eigen::Vector3d::Zero();             ///< where the instruments enter (camera frame, m)
  double mass = 0;                                              ///< kg
  std::shared_ptr<const std::vector<std::array<int, 4>>> tets;  ///< the elements at this step
  /// Elements inside out after this step (when the report counts any): their indices, their nodes (per node, 1 when
  /// one of its elements is) and their centroids (camera frame, m), for the warning drawn on the organ.
  std::vector<int> inverted;
  std::vector<char> invertedNode;
  std::vector<Eigen::Vector3d> invertedAt;
};

/// The warning a frame's step calls for, in one sentence (empty when none): elements inside out, or a step held back
/// to keep them from inverting. Shown on the organ in the simulation view and over the frame in step 7.
QString warningText(const SimulationFrame& f);

/// Draws a SimulationFrame: the organ's surface with the frame's positions, per-vertex colours and a
/// colour bar; turntable controls as in the organ view.
class SimulationView : public QWidget {
  Q_OBJECT
 public:
  explicit SimulationView(QWidget* parent = nullptr);
  void setFrame(std::shared_ptr<const SimulationFrame> f);
  /// No frame, and why (drawn in its place; empty: the invitation to start).
  void clearFrame(const QString& why);
  QSize sizeHint() const override { return {420, 320}; }

 protected:
  void paintEvent(QPaintEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void mouseDoubleClickEvent(QMouseEvent*) override;
  void wheelEvent(QWheelEvent*) override;

 private:
  std::shared_ptr<const SimulationFrame> frame_;
  QString emptyText_;
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();  ///< the organ's centre of gravity (m)
  double size_ = 0.05;                                ///< its bounding sphere's radius (m), from the first frame
  Turntable turntable_;
};

class SimulationPanel : public QWidget {
  Q_OBJECT
 public:
  explicit SimulationPanel(QWidget* parent = nullptr);
  ~SimulationPanel() override;

  /// The case to simulate: a new organ, shape, pose or attachments resets the simulation; a new
  /// material is applied at the next step boundary, keeping the state.
  void setCase(std::shared_ptr<const app::Case> c);
  void play();
  void pause();
  void togglePlay();
  void stepOnce();
  void reset();
  /// An instrument input (tip pose, jaws) for the session's next step, in the camera frame; plays the
  /// simulation when it is paused (a grasp acts on a live organ). False when no session runs.
  bool post(simcore::InputEvent e);
  /// The case's material from a DejaVu preset (eye, kidney, liver or uterus) on its organ: emits materialEdited.
  void applyPreset(const QString& name);
  bool isPlaying() const { return playing_; }
  std::shared_ptr<const SimulationFrame> lastFrame() const { return last_; }
  /// The tool-force loop of the current session (1 kHz on its own thread; the instrument's tip drives its
  /// virtual device), null while no session runs. A haptic device driver would take the VirtualDevice's place.
  const simcore::ForceLoop* forceLoop() const { return forceLoop_.get(); }
  /// The current session (read-only: its setup and counters), null while none runs.
  const simcore::Session* session() const { return session_.get(); }
  SimulationSetup setup() const;
  QString statusText() const;
  /// Starts the simulation again from rest, recording the session into the case file `file` (SQLite, as it
  /// runs: app::Recorder) with `meta`. One sentence on error (nothing started then), empty on success.
  QString startRecording(const QString& file, const app::SessionMeta& meta);
  /// Ends the recording (the session is marked complete); the simulation goes on unrecorded.
  void stopRecording();
  bool recording() const { return recorder_ != nullptr || recordPending_; }
  qint64 recordingId() const;
  /// How the current session started: where the frame shows it, in equilibrium (and whether its rest shape was solved
  /// for the last session already), or why the organ will sag; empty without gravity or attachments.
  QString startSentence() const { return startWord_; }
  /// Before the case file is saved (copied and replaced): the recorder commits, empties its WAL and closes the
  /// file; the steps meanwhile are kept in memory until caseFileReplaced().
  void suspendRecording();
  /// The case file was saved anew (replaced), or the save ended: the recording goes on into `file`.
  void caseFileReplaced(const QString& file);
  /// The key of the precomputed responses the session's body uses (the case file stores them), 0 for the FEM.
  std::uint64_t responseKey() const { return last_ ? last_->responseKey : 0; }

 signals:
  void statusChanged(const QString& text);
  /// The user edited the material (fields or preset): the window makes it an undoable edit of the case.
  void materialEdited(const rehearse::app::MaterialSettings& material);
  void frameShown(long steps);
  /// The recording could not go on (one sentence); the simulation goes on.
  void recordingStopped(const QString& why);
  /// Reset while recording: the recorded session ended and the run from rest is recorded as a new session.
  void recordingRestarted(const QString& text);

 private:
  struct FrameContext;
  static std::shared_ptr<const SimulationFrame> makeFrame(const FrameContext& ctx, const simcore::Snapshot& snap,
                                                          int colouring);
  /// With `record`: the new session is recorded (the recorder made on the worker from the session's setup).
  struct RecordRequest {
    std::string file;
    app::SessionMeta meta;
  };
  void startSession(const SimulationSetup& s, std::optional<RecordRequest> record = std::nullopt);
  void postMaterial(const app::MaterialSettings& before, const app::MaterialSettings& m);
  void onFrame(std::shared_ptr<const SimulationFrame> f);
  void onFailed(const QString& message);
  void materialFieldsEdited();
  void postRunParameters();
  /// The body's build (the precomputed responses) is `done` (0..1) along: a progress dialog with Cancel past 0.4 s.
  void showBuildProgress(double done);
  void updateMass();
  void updateButtons();
  void fillMaterial(const app::MaterialSettings& m);
  app::MaterialSettings fieldsMaterial() const;

  std::shared_ptr<simcore::Session> session_;
  /// The sessions replaced (a reset, a new organ) being joined and their recordings completed, off the GUI thread.
  std::shared_future<void> retired_;
  void waitForRetired();
  /// The run parameters as last asked of the session (built into it, then posted): the session applies them at its next
  /// step boundary, so its own setup lags the list; compared with it, a quick scroll through the Solver list (exact,
  /// lagged-PCG, chord) posted exact and lagged-PCG, then nothing for chord, and the session ran lagged-PCG.
  struct Asked {
    double timeStep = 0, graspRadius = 0, clipLength = 0;
    simcore::NewtonMethod method = simcore::kInteractiveMethod;
    simcore::BodyModel model = simcore::BodyModel::Fem;
    Eigen::Vector3d gravity = Eigen::Vector3d::Zero();
  } asked_;
  std::shared_ptr<app::Recorder> recorder_;     ///< while recording: written from the session's thread (step hook)
  std::optional<RecordRequest> recordRequest_;  ///< what is being recorded (a reset starts a new session with it)
  bool recordPending_ = false;                  ///< the recorded session is being built
  bool cancelRecord_ = false;                   ///< ... and the recording was stopped meanwhile
  std::shared_ptr<std::atomic<bool>> recorderFailed_ = std::make_shared<std::atomic<bool>>(false);
  std::shared_ptr<std::string> recorderError_ = std::make_shared<std::string>();
  simcore::VirtualDevice device_;                  ///< the mouse-driven instrument's tip, for the force loop
  std::unique_ptr<simcore::ForceLoop> forceLoop_;  ///< declared after session_: stopped before it goes
  long generation_ = 0;                            ///< bumped per session: frames of an older one are dropped
  std::shared_ptr<app::RestShapeCache> startCache_;  ///< the last starting rest shape solved (made in the constructor)
  /// Set when a newer session replaces the one being built (its rest-shape solve stops early).
  std::shared_ptr<std::atomic<bool>> buildCancelled_ = std::make_shared<std::atomic<bool>>(false);
  /// Set by the build progress dialog's Cancel: the precomputed responses being built stop (the session keeps its
  /// model).
  std::shared_ptr<std::atomic<bool>> precomputeCancelled_ = std::make_shared<std::atomic<bool>>(false);
  QPointer<QProgressDialog> buildDialog_;
  QString startWord_;  ///< how the session started: in equilibrium where the frame shows it, or why not
  bool startRefused_ = false;  ///< the last start was refused (a run setting changed on the panel tries again)
  std::atomic<int> colouring_{0};
  bool pendingPlay_ = false;         ///< Play pressed while the session was being built ...
  int pendingSteps_ = 0;             ///< ... and single steps
  app::MaterialSettings builtWith_;  ///< the material the session's body was built with
  SimulationView* view_ = nullptr;
  /// The parameter form: material (the case's), run settings (the session's) and colouring.
  struct Form {
    QComboBox* preset = nullptr;
    QComboBox* model = nullptr;
    QComboBox* method = nullptr;
    QComboBox* colouring = nullptr;
    QComboBox* gravity = nullptr;
    QCheckBox* start = nullptr;  ///< start where the frame shows it (SimulationSetup::startInEquilibrium)
    QDoubleSpinBox* young = nullptr;
    QDoubleSpinBox* poisson = nullptr;
    QDoubleSpinBox* density = nullptr;
    QDoubleSpinBox* tearStrain = nullptr;  ///< % strain the tissue tears at (0: never)
    QDoubleSpinBox* support = nullptr;     ///< Pa/mm: the tissue around the organ carries it (0: none)
    QDoubleSpinBox* timeStep = nullptr;
    QDoubleSpinBox* jawBite = nullptr;  ///< the grasper's reach: closing holds the nodes within it of the tip (mm)
    QDoubleSpinBox* clipLength = nullptr;  ///< the clip applier's jaws' length (mm)
    QLabel* mass = nullptr;  ///< density x the organ's volume, so a preset's density reads as the mass it gives
  } form_;
  QPushButton* playButton_ = nullptr;
  QPushButton* stepButton_ = nullptr;
  QPushButton* resetButton_ = nullptr;
  QLabel* status_ = nullptr;
  std::unique_ptr<Throttle> statusThrottle_;
  std::shared_ptr<const app::Case> organ_;
  std::shared_ptr<const SimulationFrame> last_;
  bool playing_ = false;
  bool filling_ = false;
  struct {
    QElapsedTimer clock;
    int frames = 0;
    double fps = 0;
  } rate_;
  QString error_;
};

}  // namespace rehearse::ui
