#pragma once
// The simulation panel: the case's organ as the frame shows it (fitted shape, camera frame) simulated by a
// simcore::Session on the session's own thread (play, pause, single step, reset); material and run
// parameters edited live go to the session as timestamped input events (applied at the next step
// boundary, recorded with the run); a 3D view of the deformed mesh coloured by displacement or von Mises
// stress. No simulation state lives here: the panel shows and asks; the session is run for it by a SessionHost
// (sessionhost.hpp), which starts it through the application core (app/sessionlauncher.hpp), as `rehearse gesture`
// starts its own (app/sessionstart.hpp); the settings are a SimulationForm, the drawing a SimulationView.
#include <rehearse/app/case.hpp>
#include <rehearse/app/recording.hpp>
#include <rehearse/app/sessionstart.hpp>
#include "rehearse/ui/simulationview.hpp"
#include "rehearse/ui/sessionhost.hpp"

#include <rehearse/simcore/session/forceloop.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QElapsedTimer>
#include <QWidget>

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

class QLabel;
class QPushButton;

namespace rehearse::ui {
class SimulationForm;
class Throttle;
}

namespace rehearse::ui {

/// What the simulation runs (app/sessionstart.hpp: the panel asks, the application core starts it).
using SimulationSetup = app::SessionRequest;

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
  /// Reset as a person asks for it (the button, Shift+F5): a rehearsal that changed the organ and is not recorded
  /// (unkeptWork) is asked about first ("resetRehearsalBox": Reset / Cancel), as quitting and opening are.
  void resetAsked();
  /// An instrument input (tip pose, jaws) for the session's next step, in the camera frame; plays the
  /// simulation when it is paused (a grasp acts on a live organ). False when no session runs.
  bool post(simcore::InputEvent e);
  /// The case's material from a DejaVu preset (eye, kidney, liver or uterus) on its organ: emits materialEdited.
  void applyPreset(const QString& name);
  bool isPlaying() const { return playing_; }
  std::shared_ptr<const SimulationFrame> lastFrame() const { return last_; }
  /// The tool-force loop of the current session (1 kHz on its own thread; the instrument's tip drives its
  /// virtual device), null while no session runs. A haptic device driver would take the VirtualDevice's place.
  const simcore::ForceLoop* forceLoop() const { return host_->forceLoop(); }
  /// The current session (read-only: its setup and counters), null while none runs.
  const simcore::Session* session() const { return host_->session(); }
  SimulationSetup setup() const;
  /// Two materials whose equilibrium differs (all but where the tissue tears).
  static bool mechanicallyOther(app::MaterialSettings a, app::MaterialSettings b);
  QString statusText() const;
  /// The distance from the converged answer the status line shows (m, N; issue 64).
  struct ShownError {
    double position = std::numeric_limits<double>::quiet_NaN(), force = 0;
    bool unknown = false;  ///< said "not known"
  };
  /// What it shows after frame `f`, having shown `last`: the step's own estimate; "not known" where the step's check
  /// said so, or where the step did not converge and estimated nothing (the last step's estimate is not its distance:
  /// after a tear a step inexact at a relative residual of 1.8 was shown with the step before's 5e-06 mm); between the
  /// steps that estimate (every 10th in the window) the last one; nothing for a model that estimates nothing.
  static ShownError shownError(const SimulationFrame& f, const ShownError& last);
  /// Starts the simulation again from rest, recording the session into the case file `file` (SQLite, as it
  /// runs: app::Recorder) with `meta`. One sentence on error (nothing started then), empty on success.
  QString startRecording(const QString& file, const app::SessionMeta& meta);
  /// Ends the recording (the session is marked complete); the simulation goes on unrecorded. False when the session
  /// had recorded no step and is not kept (SessionHost::stopRecording).
  bool stopRecording();
  bool recording() const { return host_->recording(); }
  qint64 recordingId() const;
  /// What the instruments did to the organ since the session's start or its last Reset that nothing keeps (the case
  /// keeps no simulation state, a recording keeps the session): "cut or torn, burnt, 2 clips", empty when nothing
  /// (or when it is being recorded). The window asks before it ends such a rehearsal (quit, new or another case).
  QString unkeptWork() const;
  /// Whether the case `after` starts another session where `before` had one running (setCase): another organ, shape,
  /// pose, attachments or support, or another gravity before anything was cut (postRunParameters); such an edit, undo
  /// or redo ends the rehearsal (the window asks first).
  bool startsAnew(const app::Case& before, const app::Case& after) const;
  /// What the instruments did to the organ, from a frame (SimulationPanel::unkeptWork compares and words it).
  struct Work {
    std::size_t cutFaces = 0, elements = 0, burnt = 0, clips = 0;
    double bloodLoss = 0;
  };
  static Work workOf(const SimulationFrame& f);
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
  /// Play, Step or Reset clicked (or Reset's question answered): the keys go back to the frame view (MainWindow).
  void keysBack();
  void statusChanged(const QString& text);
  /// A session started: how it starts (in equilibrium on what, the held nodes), in sentences longer than the panel's
  /// lines hold; the window keeps them in its Messages panel.
  void startSaid(const QString& words);
  /// Play or Pause taken (the button, F5, a step's entry or exit).
  void playingChanged(bool playing);
  /// An instrument's input (a press, a release, a key) played the rehearsal that was paused.
  void playedByInput();
  /// The simulation went back to rest (Reset): what the instruments were doing is over.
  void wasReset();
  /// The case's organ changed (another mesh, shape, place or attachments): its session was replaced by a new one at
  /// rest (or none, while the organ has no place over the frame); what the old one drew is gone.
  void sessionReplaced();
  /// The user edited the material (fields or preset): the window makes it an undoable edit of the case.
  void materialEdited(const rehearse::app::MaterialSettings& material);
  void frameShown(long steps);
  /// The recording could not go on (one sentence); the simulation goes on.
  void recordingStopped(const QString& why);
  /// Reset while recording: the recorded session ended and the run from rest is recorded as a new session.
  void recordingRestarted(const QString& text);

 private:
  using RecordRequest = SessionHost::RecordRequest;
  /// A new session (recorded when `record`): the old one's recording ends unless `record` goes on with it.
  void startSession(const SimulationSetup& s, std::optional<RecordRequest> record = std::nullopt);
  void sessionStarted(const QString& words);
  void sessionRefused(const QString& why, bool wasRecorded);
  void startToggled(bool inEquilibrium);
  void postMaterial(const app::MaterialSettings& before, const app::MaterialSettings& m);
  void onFrame(std::shared_ptr<const SimulationFrame> f);
  void onFailed(const QString& message);
  void materialFieldsEdited();
  void postRunParameters();
  void updateButtons();

  /// The run parameters as last asked of the session (built into it, then posted): the session applies them at its next
  /// step boundary, so its own setup lags the list; compared with it, a quick scroll through the Solver list (exact,
  /// lagged-PCG, chord) posted exact and lagged-PCG, then nothing for chord, and the session ran lagged-PCG.
  struct Asked {
    double timeStep = 0, graspRadius = 0, clipLength = 0, accuracy = 0;
    simcore::NewtonMethod method = simcore::kInteractiveMethod;
    simcore::BodyModel model = simcore::BodyModel::Fem;
    Eigen::Vector3d gravity = Eigen::Vector3d::Zero();
  } asked_;
  std::optional<RecordRequest> recordRequest_;  ///< what is being recorded (a reset starts a new session with it)
  std::shared_ptr<const SimulationFrame> superseded_;  ///< the frame on show when the last session started
  bool resetPending_ = false;  ///< Reset asked, its frame (step 0) not shown yet
  std::optional<Work> kept_;  ///< what a recording of this session, stopped, keeps (unkeptWork: only more is unkept)
  SessionHost* host_ = nullptr;                 ///< runs the session (a child of the panel)
  QString startWord_;  ///< how the session started: in equilibrium where the frame shows it, or why not
  bool startRefused_ = false;  ///< the last start was refused (a run setting changed on the panel tries again)
  qint64 resetEnded_ = 0;  ///< the recorded session a Reset ended: said once it is complete (SessionHost::recordingRetired)
  app::MaterialSettings builtWith_;  ///< the material the session's body was built with
  SimulationView* view_ = nullptr;
  SimulationForm* form_ = nullptr;  ///< the material (the case's), the run's settings and the colouring
  QPushButton* playButton_ = nullptr;
  QPushButton* stepButton_ = nullptr;
  QPushButton* resetButton_ = nullptr;
  QLabel* status_ = nullptr;
  std::unique_ptr<Throttle> statusThrottle_;
  std::shared_ptr<const app::Case> organ_;
  std::shared_ptr<const SimulationFrame> last_;
  ShownError shown_;  // the distance the status line shows
  bool playing_ = false;
  struct {
    QElapsedTimer clock;
    int frames = 0;
    double fps = 0;
  } rate_;
  QString error_;
};

}  // namespace rehearse::ui
