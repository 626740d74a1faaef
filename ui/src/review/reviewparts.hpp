#pragma once
// The review window's internals shared by its files (reviewwindow*.cpp): the timeline and view widgets
// (reviewwidgets.cpp), a seek's result, the replay's hand-over to the GUI thread, and one attempt's state.
#include "rehearse/ui/reviewwindow.hpp"

#include <QFutureWatcher>
#include <QImage>
#include <QLabel>
#include <QPointF>
#include <QWidget>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

class QTableWidget;

namespace rehearse::ui {

// The attempt's force over time, the events as ticks, the threshold dashed and the playhead; a click or a
// drag seeks (through `seek`, the window's common time).
class TimelineWidget : public QWidget {
 public:
  std::function<void(double)> seek;
  /// The samples replayed so far (all of them once the replay is done).
  std::shared_ptr<const std::vector<app::TimelineSample>> timeline;
  double threshold = 0, now = 0;
  double total = 1;               ///< s: the time axis' length (the session's, expected from its steps while replaying)
  long replayed = 0, steps = 0;   ///< while the replay runs: how far it is
  bool done = false;              ///< the replay is complete
  TimelineWidget();
  double timeAt(double x) const {
    return std::clamp((x - 8) / std::max(1.0, width() - 16.0), 0.0, 1.0) * total;
  }
  double xAt(double t) const { return 8 + t / std::max(1e-9, total) * (width() - 16.0); }

 protected:
  void paintEvent(QPaintEvent*) override;
  void mousePressEvent(QMouseEvent* e) override;
  void mouseMoveEvent(QMouseEvent* e) override;
};

// The view: the rendered image, scaled to fit; a drag turns the 3D view.
class ViewLabel : public QLabel {
 public:
  std::function<void(double, double)> turn;
  ViewLabel();

 protected:
  void resizeEvent(QResizeEvent* e) override;  // the picture follows the view's size
  void mousePressEvent(QMouseEvent* e) override;
  void mouseMoveEvent(QMouseEvent* e) override;

 private:
  QPointF last_;
};

// Where a seek landed (computed off the GUI thread: a seek replays up to a checkpoint interval of steps, a second or
// more on a large organ; issue 62 measured a 7.6 s freeze while dragging the timeline).
struct SeekResult {
  long step = 0;
  long generation = 0;  ///< ReviewAttempt::viewGeneration it was drawn for
  QImage image;         ///< the view's picture (drawn on the worker too)
  QImage scaled;        ///< the same at the view's size
  std::string note;     ///< Replayer::lastSeekNote
  std::string error;    ///< the seek failed (a damaged recording)
};

// Between a session's replay (on the window's replay pool) and the GUI thread: the replay leaves what it has so far here
// (the GUI thread takes it on a timer; nothing is posted to a window that may be gone), and stops when asked.
struct ReplayControl {
  std::mutex mutex;
  std::condition_variable changed;
  bool stop = false;
  long holdAt = -1;  ///< the replay waits after this step until it is changed (ReviewWindow::holdReplaysAt)
  bool fresh = false;
  long step = 0, steps = 0;
  std::shared_ptr<const std::vector<app::TimelineSample>> line;
  app::VerifyResult verify;
  std::chrono::steady_clock::time_point published;
  void halt() {
    {
      std::lock_guard<std::mutex> lock(mutex);
      stop = true;
    }
    changed.notify_all();
  }
  void hold(long step) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      holdAt = step;
    }
    changed.notify_all();
  }
};

// The view's replayer and renderers, built on a worker (a large organ's session takes a while to build).
struct ReviewViewer {
  std::shared_ptr<app::Replayer> replayer;
  std::unique_ptr<app::ReviewRenderer> frame, orbit;
};

class ReviewAttempt {
 public:
  ~ReviewAttempt() {
    // Nothing is waited for: the replay stops at its next step, and the reading, the view's building and a seek hold
    // what they use (their watchers go with the attempt, so nothing lands here).
    if (control) control->halt();
  }
  std::unique_ptr<QFutureWatcher<app::Recording>> loader;
  QWidget* widget = nullptr;
  QLabel* title = nullptr;
  ViewLabel* view = nullptr;
  TimelineWidget* timelineView = nullptr;
  QTableWidget* table = nullptr;
  app::Recording recording;
  app::ReplayResult result;
  std::shared_ptr<app::Replayer> replayer;  ///< the view's (a seek on a worker holds it too)
  std::unique_ptr<app::ReviewRenderer> frameRenderer, orbitRenderer;
  bool ready = false;
  QString error;
  QFutureWatcher<app::ReplayResult>* watcher = nullptr;
  std::shared_ptr<ReplayControl> control;
  std::unique_ptr<QFutureWatcher<std::shared_ptr<ReviewViewer>>> viewerWatcher;
  bool viewable = false;  ///< the replayer and renderers are built: the view seeks (as far as the replay has checked)
  /// The samples replayed so far (the whole timeline once ready), the checksums and checkpoints compared so far, how
  /// far the replay is and how long the session is expected to be (its steps times its time step).
  std::shared_ptr<const std::vector<app::TimelineSample>> line = std::make_shared<const std::vector<app::TimelineSample>>();
  app::VerifyResult checkedSoFar;
  long replayed = 0, replaySteps = 0;
  double expectedDuration = 0;
  // The view's seek, one at a time on a worker: the newest step asked for while one runs is sought next (a drag's
  // intermediate positions are skipped); the view shows `shown` (its snapshot) until the next one lands.
  std::unique_ptr<QFutureWatcher<SeekResult>> seeker;
  long wanted = -1;  ///< the step the window's time asks for
  long shown = -1;   ///< the step the view shows (-1: none yet)
  long lastStep = 0; ///< Replayer::steps(), read once (the replayer is the worker's while a seek runs)
  std::string seekNote;
  long viewGeneration = 0;   ///< counts changes of the view (3D or frame, a turn): a picture for an older one is stale
  long shownGeneration = -1; ///< the generation of the picture shown
  bool stale() const { return shown != wanted || shownGeneration != viewGeneration; }

  /// The last step a seek may go to: the replay's checked part until it is done.
  long reachable() const { return viewable ? (ready ? lastStep : std::min(replayed, lastStep)) : 0; }
  long stepAt(double t) const { return std::min(app::stepAtTime(*line, t), reachable()); }
  /// The time shown so far (the replayed part).
  double available() const { return line->empty() ? 0 : line->back().time; }
  /// The view's renderer: the case's frame, or the 3D view (always without a case camera).
  const app::ReviewRenderer& renderer(bool threeD) const { return threeD || !frameRenderer ? *orbitRenderer : *frameRenderer; }
  double duration() const { return ready ? available() : std::max(expectedDuration, available()); }
};

}  // namespace rehearse::ui
