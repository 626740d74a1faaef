#pragma once
// The session the Simulation panel shows, run for the GUI (private to ui/): started on a worker through the application
// core (app/sessionlauncher.hpp) while the old one is joined and its recording completed off the GUI thread, recorded
// when asked, its snapshots made into frames on the session's thread and handed to the GUI thread, the tool-force loop
// beside it. What is asked while the session is being built (a step, Play) runs once it is there. The panel only shows
// and asks; this holds no widget but the build's progress dialog.
#include <rehearse/app/sessionlauncher.hpp>
#include "rehearse/ui/simulationview.hpp"

#include <rehearse/simcore/session/forceloop.hpp>

#include <QFuture>
#include <QObject>
#include <QPointer>
#include <QProgressDialog>
#include <QString>

#include <atomic>
#include <cstdint>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::ui {

class SessionHost : public QObject {
  Q_OBJECT
 public:
  /// Where a session is recorded (the case file) and as what.
  struct RecordRequest {
    std::string file;
    app::SessionMeta meta;
  };
  /// `dialogs`: the widget the build's progress dialog belongs to.
  explicit SessionHost(QWidget* dialogs);
  ~SessionHost() override;  ///< joins the session and completes its recording

  /// A new session for `s` (recorded when `record`), built on a worker: started() or refused() when it is done. The
  /// current one is retired at once; false (and nothing started) when `s` has no organ volume.
  bool start(const app::SessionRequest& s, std::optional<RecordRequest> record);
  simcore::Session* session() const { return session_.get(); }
  const simcore::ForceLoop* forceLoop() const { return forceLoop_.get(); }
  void setColouring(int colouring);  ///< 0 displacement, 1 von Mises (republishes the current state)
  /// The model asked of the running session (a long build of it shows its progress, with Cancel).
  void modelAsked(simcore::BodyModel model);
  /// An input for the session's next step (the tool's pose also moves the force loop's device). False without one.
  bool post(simcore::InputEvent e);
  void play();      ///< (once built, when it is being built)
  void pause();     ///< (and Play asked meanwhile forgotten)
  void stepOnce();  ///< (once built, when it is being built)
  void reset();     ///< back to the start (nothing asked meanwhile kept)

  /// A recording is written or its session is being built (and was not stopped meanwhile).
  bool recording() const { return recording_ != nullptr || (recordPending_ && !cancelRecord_); }
  std::int64_t recordingId() const { return recording_ ? recording_->id() : 0; }
  /// The recording ends complete (the session goes on unrecorded); a recorded session being built is not recorded.
  /// False when the session had recorded no step and was dropped from the file (StepRecording::discarded), or was
  /// still being built.
  bool stopRecording();
  /// A write the file refused since: why, and the recording stopped (empty when none).
  QString recordingFailure();
  void suspendRecording();                    ///< before the case file is copied and replaced
  void recordingFileReplaced(const std::string& file);  ///< ... and after: the recording goes on into `file`
  /// Waits for the sessions replaced to be joined and their recordings completed.
  void waitForRetired();

 signals:
  /// The session built runs (paused): how it started, in a sentence (empty when there is nothing to say).
  void started(const QString& words);
  /// The organ was not started: why, with what to change; `wasRecorded`: a recording was asked for.
  void refused(const QString& why, bool wasRecorded);
  void frame(std::shared_ptr<const SimulationFrame> f);
  void restProgress(const QString& text);  ///< the rest shape's solves as they go
  void recordingStopped(const QString& why);
  /// A recorded session replaced (a reset, a new organ) is complete in the file: its id, its last step, and whether it
  /// was dropped for recording no step.
  void recordingRetired(qint64 id, long lastStep, bool discarded);

 private:
  struct Built {
    app::SessionStart::Outcome outcome = app::SessionStart::Outcome::Cancelled;
    QString words;  ///< how it started, or why not
    std::shared_ptr<simcore::Session> session;
    std::shared_ptr<app::StepRecording> recording;
    std::shared_ptr<FrameBasis> basis;
    bool wasRecorded = false;  ///< a recording was asked for
  };
  void retire();
  app::LaunchOptions launchOptions(long generation, const std::optional<RecordRequest>& record);
  /// The start's outcome in one sentence the assistant can act on; `body`: the body as it starts.
  static QString startWords(const app::SessionRequest& s, const app::SessionStart& start,
                            const simcore::BodySetup& body);
  void adopt(Built built);  ///< on the GUI thread
  /// The body's build (the precomputed responses) is `done` (0..1) along: a progress dialog with Cancel past 0.4 s.
  void showBuildProgress(double done);

  QWidget* dialogs_;
  std::shared_ptr<simcore::Session> session_;
  /// The sessions replaced (a reset, a new organ) being joined and their recordings completed, off the GUI thread.
  std::shared_future<void> retired_;
  std::shared_ptr<app::StepRecording> recording_;  ///< while recording: written from the session's thread (step hook)
  bool recordPending_ = false;                     ///< the recorded session is being built
  bool cancelRecord_ = false;                      ///< ... and the recording was stopped meanwhile
  simcore::VirtualDevice device_;                  ///< the mouse-driven instrument's tip, for the force loop
  std::unique_ptr<simcore::ForceLoop> forceLoop_;  ///< declared after session_: stopped before it goes
  /// The sessions being built (a newer one asked for cancels the older ones): the host waits for them before it goes.
  std::vector<QFuture<void>> builds_;
  long generation_ = 0;                            ///< bumped per session: frames of an older one are dropped
  std::shared_ptr<app::RestShapeCache> startCache_ = std::make_shared<app::RestShapeCache>();
  /// Set when a newer session replaces the one being built (its rest-shape solve stops early).
  std::shared_ptr<std::atomic<bool>> buildCancelled_ = std::make_shared<std::atomic<bool>>(false);
  /// Set by the build progress dialog's Cancel: the precomputed responses being built stop (the session keeps its
  /// model).
  std::shared_ptr<std::atomic<bool>> precomputeCancelled_ = std::make_shared<std::atomic<bool>>(false);
  QPointer<QProgressDialog> buildDialog_;
  std::atomic<int> colouring_{0};
  simcore::BodyModel model_ = simcore::BodyModel::Fem;  ///< the model whose build shows its progress
  bool pendingPlay_ = false;  ///< Play pressed while the session was being built ...
  int pendingSteps_ = 0;      ///< ... and single steps
};

}  // namespace rehearse::ui
