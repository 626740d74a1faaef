#pragma once
// The trainer's review window (issue 16): the sessions recorded in a case file, one attempt or two side by
// side in sync; each with its view (the organ over the case's frame, or a 3D view turned with the mouse),
// the instrument's path, a timeline of its force with the events marked (grasp, slip, cut, vessel cut, force
// over the threshold) that seeks on click and drag, and its metrics with the trainer's thresholds. Play,
// pause, speed, step, and export of a video span and a PDF report. Keyboard: Space play/pause, Left/Right
// one step (Shift: ten), Home/End, V frame/3D view, Ctrl+E video, Ctrl+P report.
#include <rehearse/app/review.hpp>

#include <QMainWindow>

#include <array>
#include <functional>
#include <memory>
#include <optional>

class QComboBox;
class QLabel;
class QTimer;
class QSplitter;
class QDoubleSpinBox;
class QThreadPool;

namespace rehearse::ui {

class ReviewAttempt;

/// When a session started, as a person reads it: the recording's UTC time ("2026-11-30T03:21:20Z") in this machine's
/// time zone and the locale's short format; the text itself when it is not such a time.
QString sessionTime(const std::string& startedUtc);

class ReviewWindow : public QMainWindow {
  Q_OBJECT
 public:
  /// `file`: a case file with recorded sessions; `camera` and `frame`: the case's (the organ is drawn over the
  /// frame, in that camera's frame: the GUI's sessions are), else a virtual camera.
  explicit ReviewWindow(const QString& file, std::optional<imaging::Camera> camera = std::nullopt, cv::Mat3b frame = {}, QWidget* parent = nullptr);
  /// The same over any store of sessions (the training database): `list` called on the GUI thread, `load` too unless
  /// `loadOnWorker` (then on a worker thread, so that a large session is read while the window answers).
  ReviewWindow(std::function<std::vector<app::RecordingSummary>()> list, std::function<app::Recording(qint64)> load, const QString& title,
               std::optional<imaging::Camera> camera = std::nullopt, cv::Mat3b frame = {}, QWidget* parent = nullptr,
               bool loadOnWorker = false);
  ~ReviewWindow() override;

  /// Shows session `id` as attempt 0 (the first) or 1 (compared side by side; id <= 0 removes it). Replays it
  /// once for its timeline and metrics (on a worker thread; `ready` tells when); meanwhile the timeline grows
  /// and the view seeks as far as the replay has checked.
  void openSession(int attempt, qint64 id);
  bool ready(int attempt) const;
  /// How many steps the attempt's replay has checked so far (all of them once ready): until it is done the timeline
  /// grows and the view seeks as far as that.
  long stepsReplayed(int attempt) const;
  /// Every replay (running or started later) waits after step `step` until this is called again with another (-1: none);
  /// for tests that look at the window while a replay runs, however fast the machine.
  void holdReplaysAt(long step);
  int attemptsShown() const;
  /// The common time (s) both attempts show, each clamped to its own duration.
  double time() const { return time_; }
  void seekTime(double seconds);
  void stepBy(int steps);  ///< on the first attempt's steps
  void setPlaying(bool on);
  bool playing() const { return playing_; }
  void setSpeed(double factor);
  /// The step the view shows (its seek runs off the GUI thread, so it lands after the time moved) and the step the
  /// window's time asks for; seeking(): a seek is under way or due.
  long stepShown(int attempt) const;
  long stepWanted(int attempt) const;
  bool seeking() const;
  double duration(int attempt) const;
  app::SessionMetrics metrics(int attempt) const;
  std::vector<app::Verdict> verdicts(int attempt) const;
  /// Thresholds for the metrics' pass/fail (JSON as `rehearse replay --thresholds` takes); one sentence on error.
  /// From a case file they are kept in it (the case's thresholds, which `rehearse replay` uses too).
  QString setThresholds(const QString& json);
  QString thresholdsText() const { return thresholdsText_; }
  bool threeD() const { return threeD_; }
  void setThreeD(bool on);
  /// Writes attempt 0's span [from, to] s as MP4 / its report as PDF; one sentence on error, empty on success.
  QString exportVideo(const QString& path, double from, double to);
  /// Lists the sessions again (ones recorded meanwhile appear), keeping what is shown; also done on activation.
  void refreshSessions();
  QString exportReport(const QString& path);
  QString statusText() const;
  QImage viewImage(int attempt) const;

 signals:
  void attemptReady(int attempt);

 protected:
  void keyPressEvent(QKeyEvent* e) override;
  bool event(QEvent* e) override;

 private:
  void tick();
  void refresh();
  void pollReplays();  ///< takes the running replays' progress (their timeline so far, how far they checked)
  QString attemptTitle(const ReviewAttempt& a) const;
  void beginReplay(ReviewAttempt& a, int attempt);  ///< once its recording is read
  void startSeek(ReviewAttempt& a);
  QString suggestedExportPath(const QString& extension) const;
  void seekLanded(ReviewAttempt& a);
  void fillSessionLists();
  void fillMetrics(ReviewAttempt& a);
  /// Runs an export of the first attempt on a worker (a replayer of its own, a copy of the view's renderer) while the
  /// window stays responsive, with a progress dialog (`doing`; Cancel when `cancellable`); `write` returns the status
  /// sentence. One sentence on error, empty on success.
  using ExportWork = std::function<QString(ReviewAttempt&, app::Replayer&, const app::ReviewRenderer&,
                                           const std::function<bool(int, int)>& progress)>;
  QString exportFirst(const QString& doing, bool cancellable, const ExportWork& write);
  void build(const QString& title);
  std::function<std::vector<app::RecordingSummary>()> list_;
  std::function<app::Recording(qint64)> load_;
  std::optional<imaging::Camera> camera_;
  cv::Mat3b frame_;
  std::vector<app::RecordingSummary> sessions_;
  std::array<std::unique_ptr<ReviewAttempt>, 2> attempts_;
  std::vector<app::Threshold> thresholds_;
  QString thresholdsText_;
  QString file_;  // the case file the sessions come from (empty: another store)
  QSplitter* split_ = nullptr;
  QComboBox* first_ = nullptr;
  QComboBox* second_ = nullptr;
  QComboBox* speed_ = nullptr;
  QLabel* status_ = nullptr;
  QTimer* timer_ = nullptr;
  QTimer* progressTimer_ = nullptr;
  QThreadPool* replayPool_ = nullptr;
  long holdReplaysAt_ = -1;
  bool loadOnWorker_ = false;  ///< `load_` may run on a worker (a case file: a connection of its own)
  double time_ = 0;
  double speedFactor_ = 1;
  bool playing_ = false;
  bool threeD_ = false;
  bool exporting_ = false;  ///< an export's worker reads attempt 0: it is not replaced meanwhile
  qint64 lastTick_ = 0;
};

}  // namespace rehearse::ui
