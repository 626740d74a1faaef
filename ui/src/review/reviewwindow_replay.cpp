// The review window's replays and view (issue 16): each attempt's replay for its timeline and metrics on the window's
// pool, its progress taken on a timer; the view's seeks, one at a time on a worker; the common time, playing and
// stepping, and the status line.
#include "rehearse/ui/reviewwindow.hpp"

#include "reviewparts.hpp"

#include <QComboBox>
#include <QDateTime>
#include <QLabel>
#include <QSysInfo>
#include <QTimer>
#include <QtConcurrent/QtConcurrentRun>

#include <algorithm>
#include <chrono>
#include <mutex>

namespace rehearse::ui {

namespace {

QImage toQImage(const cv::Mat3b& m) { return QImage(m.data, m.cols, m.rows, static_cast<qsizetype>(m.step), QImage::Format_BGR888).copy(); }

}  // namespace

void ReviewWindow::holdReplaysAt(long step) {
  holdReplaysAt_ = step;
  for (auto& a : attempts_)
    if (a && a->control) a->control->hold(step);
}

long ReviewWindow::stepsReplayed(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a ? a->replayed : 0;
}

void ReviewWindow::pollReplays() {
  bool running = false;
  for (auto& a : attempts_) {
    if (!a || a->ready || !a->error.isEmpty()) continue;
    running = true;
    if (!a->control) continue;  // still being read
    {
      std::lock_guard<std::mutex> lock(a->control->mutex);
      if (!a->control->fresh) continue;
      a->control->fresh = false;
      a->line = a->control->line;
      a->checkedSoFar = a->control->verify;
      a->replayed = a->control->step;
      a->replaySteps = a->control->steps;
    }
    a->timelineView->timeline = a->line;
    a->timelineView->replayed = a->replayed;
    a->timelineView->steps = a->replaySteps;
    a->timelineView->total = std::max({a->expectedDuration, a->available(), 1e-3});
    a->title->setText(attemptTitle(*a) + tr("<br>replaying to check it: step %1 of %2").arg(a->replayed).arg(a->replaySteps));
    refresh();
  }
  if (!running) progressTimer_->stop();
}

void ReviewWindow::beginReplay(ReviewAttempt& attempt0, int attempt) {
  ReviewAttempt* a = &attempt0;
  a->title->setText(attemptTitle(*a));
  // The replay for the timeline and the metrics, off the GUI thread (on the window's own pool: the seeks and exports
  // run on the global one, so a long replay does not hold them back). Its progress is taken on a timer (pollReplays):
  // the timeline grows as it runs and the view seeks as far as it has checked.
  a->control = std::make_shared<ReplayControl>();
  a->control->holdAt = holdReplaysAt_;
  a->expectedDuration = static_cast<double>(a->recording.summary.steps) * a->recording.setup.settings.timeStep;
  a->timelineView->total = std::max(a->expectedDuration, 1e-3);
  a->watcher = new QFutureWatcher<app::ReplayResult>(this);
  ReviewAttempt* raw = a;
  connect(a->watcher, &QFutureWatcher<app::ReplayResult>::finished, this, [this, raw, attempt] {
    try {
      raw->result = raw->watcher->result();
      raw->line = std::make_shared<const std::vector<app::TimelineSample>>(raw->result.timeline);
      raw->checkedSoFar = raw->result.verify;
      raw->replayed = raw->replaySteps = raw->result.verify.steps;
      raw->timelineView->timeline = raw->line;
      raw->timelineView->total = std::max(raw->available(), 1e-9);
      raw->timelineView->done = true;
      raw->timelineView->threshold = raw->result.metrics.forceThresholdN;
      raw->ready = true;
      // Whether this replay is the run that was recorded, in the attempt's title (red when it is not).
      const bool verified = app::replayVerified(raw->result.verify);
      raw->title->setText(attemptTitle(*raw) +
                          tr("<br><span style=\"color:%1\">%2</span>")
                              .arg(verified ? QStringLiteral("#60c060") : QStringLiteral("#ff5050"))
                              .arg((QString::fromStdString(app::replayCheckSentence(raw->result.verify)) +
                                    tr(" - replayed here, on %1").arg(QSysInfo::machineHostName()))
                                       .toHtmlEscaped()));
      fillMetrics(*raw);
    } catch (const std::exception& e) {
      raw->error = QString::fromStdString(e.what());
    }
    refresh();
    emit attemptReady(attempt);
  });
  app::ReplayOptions options;
  options.strain = true;
  options.timeline = true;
  options.checkpoints = !a->recording.checkpointSource;  // a database session's connection is this thread's
  options.progress = [control = a->control](long step, long steps, const app::ReplayResult& soFar) {
    std::unique_lock<std::mutex> lock(control->mutex);
    if (control->stop) return false;
    const auto now = std::chrono::steady_clock::now();
    if (step == 1 || step == steps || step == control->holdAt || now - control->published > std::chrono::milliseconds(100)) {
      control->line = std::make_shared<const std::vector<app::TimelineSample>>(soFar.timeline);
      control->verify = soFar.verify;
      control->step = step;
      control->steps = steps;
      control->fresh = true;
      control->published = now;
    }
    control->changed.wait(lock, [&] { return control->stop || control->holdAt != step; });
    return !control->stop;
  };
  const app::Recording rec = a->recording;
  a->watcher->setFuture(QtConcurrent::run(replayPool_, [rec, options] { return app::replayRecording(rec, options); }));
  // The view's replayer and renderers, built on a worker too; the view seeks once they are.
  a->viewerWatcher = std::make_unique<QFutureWatcher<std::shared_ptr<ReviewViewer>>>();
  connect(a->viewerWatcher.get(), &QFutureWatcher<std::shared_ptr<ReviewViewer>>::finished, this, [this, raw] {
    try {
      const auto viewer = raw->viewerWatcher->result();
      raw->replayer = std::move(viewer->replayer);
      raw->orbitRenderer = std::move(viewer->orbit);
      raw->frameRenderer = std::move(viewer->frame);
      raw->lastStep = raw->replayer->steps();
      raw->seeker = std::make_unique<QFutureWatcher<SeekResult>>();
      connect(raw->seeker.get(), &QFutureWatcher<SeekResult>::finished, this, [this, raw] { seekLanded(*raw); });
      raw->viewable = true;
    } catch (const std::exception& e) {
      raw->error = QString::fromStdString(e.what());
    }
    refresh();
  });
  const std::optional<imaging::Camera> camera = camera_;
  const cv::Mat3b frame = frame_;
  a->viewerWatcher->setFuture(QtConcurrent::run([rec, camera, frame] {
    auto v = std::make_shared<ReviewViewer>();
    v->replayer = std::make_shared<app::Replayer>(rec);
    v->orbit = std::make_unique<app::ReviewRenderer>(rec.setup, 800, 600);
    if (camera) v->frame = std::make_unique<app::ReviewRenderer>(rec.setup, 0, 0, camera, frame);
    return v;
  }));
  if (!progressTimer_->isActive()) progressTimer_->start();
  status_->setText(tr("Replaying session %1 to check it, for its timeline and metrics...").arg(a->recording.summary.id));
}

long ReviewWindow::stepShown(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a && a->replayer ? a->shown : -1;
}

long ReviewWindow::stepWanted(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a && a->viewable ? a->stepAt(time_) : -1;
}

bool ReviewWindow::seeking() const {
  return std::any_of(attempts_.begin(), attempts_.end(), [](const auto& a) {
    return a && a->seeker && (a->seeker->isRunning() || (a->viewable && a->error.isEmpty() && a->stale()));
  });
}

void ReviewWindow::startSeek(ReviewAttempt& a) {
  if (!a.seeker || a.seeker->isRunning() || !a.error.isEmpty()) return;  // the one running lands first
  const long step = a.wanted, generation = a.viewGeneration;
  const std::shared_ptr<app::Replayer> replayer = a.replayer;
  // The picture is drawn there too, with a copy of the view's renderer (a turn may change the view's meanwhile).
  auto renderer = std::make_shared<app::ReviewRenderer>(a.renderer(threeD_));
  const auto timeline = a.line;  // the samples so far (a new vector replaces it as the replay goes on)
  const app::VerifyResult checked = a.checkedSoFar;  // the checkpoints it found damaged are not started from
  const std::string who = "session " + std::to_string(a.recording.summary.id);
  const QSize size = a.view->size();
  a.seeker->setFuture(QtConcurrent::run([replayer, renderer, timeline, checked, who, size, step, generation] {
    SeekResult r;
    r.step = step;
    r.generation = generation;
    try {
      replayer->avoidCheckpoints(checked);
      replayer->seek(step);
      r.note = replayer->lastSeekNote();
      const QImage img = toQImage(renderer->render(*replayer->snapshot(), app::tipPath(*timeline, step),
                                                   app::captionAt(*timeline, step, who)));
      r.image = img;
      r.scaled = img.scaled(size, Qt::KeepAspectRatio, Qt::SmoothTransformation);
    } catch (const std::exception& e) {
      r.error = e.what();
    }
    return r;
  }));
}

void ReviewWindow::seekLanded(ReviewAttempt& a) {
  const SeekResult r = a.seeker->result();
  if (!r.error.empty()) {  // a damaged checkpoint: said, and the attempt shows no more
    a.error = tr("Session %1 cannot be shown at step %2: %3")
                  .arg(a.recording.summary.id)
                  .arg(r.step)
                  .arg(QString::fromStdString(r.error));
    a.view->setText(a.error);
  } else {
    a.shown = r.step;
    a.shownGeneration = r.generation;
    a.seekNote = r.note;
    // Drawn at the view's size when the seek started; a view laid out or resized since (a session just opened is
    // laid out after its first seek starts: its picture came out blank) is scaled here.
    const QSize wanted = r.image.size().scaled(a.view->size(), Qt::KeepAspectRatio);
    const QImage fitted =
        r.scaled.size() == wanted ? r.scaled : r.image.scaled(wanted, Qt::IgnoreAspectRatio, Qt::SmoothTransformation);
    a.view->setPixmap(QPixmap::fromImage(fitted));
    a.view->setProperty("image", r.image);
  }
  if (a.error.isEmpty() && a.stale()) startSeek(a);  // the newest position (or view) asked meanwhile
  refresh();
}

void ReviewWindow::seekTime(double seconds) {
  double longest = 0;
  for (const auto& a : attempts_)
    if (a) longest = std::max(longest, a->duration());
  time_ = std::clamp(seconds, 0.0, longest);
  refresh();
}

void ReviewWindow::stepBy(int steps) {
  const auto& a = attempts_[0];
  if (!a || !a->viewable || a->line->empty()) return;
  const long target = std::clamp(a->stepAt(time_) + steps, 0L, a->reachable());
  const app::TimelineSample* s = app::sampleAt(*a->line, target);
  const double t = s ? s->time : 0.0;
  setPlaying(false);
  seekTime(t);
}

void ReviewWindow::setPlaying(bool on) {
  playing_ = on && attempts_[0] && attempts_[0]->viewable;
  if (playing_) {
    if (time_ >= duration(0) - 1e-9) time_ = 0;  // from the start again
    lastTick_ = 0;
    timer_->start();
  } else {
    timer_->stop();
  }
  refresh();
}

void ReviewWindow::setSpeed(double factor) {
  speedFactor_ = std::clamp(factor, 0.05, 16.0);
  const int i = speed_->findData(speedFactor_);
  if (i >= 0 && i != speed_->currentIndex()) speed_->setCurrentIndex(i);
}

void ReviewWindow::setThreeD(bool on) {
  threeD_ = on;
  for (auto& a : attempts_)
    if (a) ++a->viewGeneration;
  refresh();
}

void ReviewWindow::tick() {
  const qint64 now = QDateTime::currentMSecsSinceEpoch();
  const double dt = lastTick_ ? (now - lastTick_) / 1000.0 : 0.0;
  lastTick_ = now;
  // While a replay runs, playing goes as far as it has replayed and waits there; at the end of the longest, it stops.
  double longest = 0, available = 0;
  bool replaying = false;
  for (const auto& a : attempts_)
    if (a && a->error.isEmpty()) {
      longest = std::max(longest, a->duration());
      available = std::max(available, a->available());
      replaying = replaying || !a->ready;
    }
  time_ = std::max(time_, std::min(replaying ? available : longest, time_ + dt * speedFactor_));
  if (!replaying && time_ >= longest) playing_ = false, timer_->stop();
  refresh();
}

void ReviewWindow::refresh() {
  QStringList state, seekNotes;
  for (std::size_t k = 0; k < attempts_.size(); ++k) {
    auto& a = attempts_[k];
    if (!a) continue;
    if (!a->error.isEmpty()) {
      a->view->setText(a->error);
      continue;
    }
    a->timelineView->now = time_;
    a->timelineView->update();
    if (!a->viewable) continue;
    // The playhead moves at once; the view follows when its seek lands (off the GUI thread).
    a->wanted = a->stepAt(time_);
    if (a->stale()) startSeek(*a);
    QString where = a->shown == a->wanted || a->shown < 0
                        ? tr("session %1: step %2 of %3").arg(a->recording.summary.id).arg(a->wanted).arg(a->lastStep)
                        : tr("session %1: step %2 of %3 (seeking from %4)")
                              .arg(a->recording.summary.id)
                              .arg(a->wanted)
                              .arg(a->lastStep)
                              .arg(a->shown);
    if (!a->ready) where += tr(", replayed to %1").arg(a->replayed);
    state << where;
    if (!a->seekNote.empty())  // a damaged checkpoint passed over: said, the view still shows the step
      seekNotes << tr("session %1: %2").arg(a->recording.summary.id).arg(QString::fromStdString(a->seekNote));
  }
  const QString mode = threeD_ || !camera_ ? tr("3D view (drag to turn)") : tr("over the case's frame");
  // A seek that passed over a damaged checkpoint says so first (the status line is cut at the window's width; the
  // whole sentence is its tooltip).
  const QString line = tr("%1  t = %2 s  %3  %4x  %5").arg(playing_ ? tr("playing") : tr("paused")).arg(time_, 0, 'f', 2).arg(state.join("; ")).arg(speedFactor_).arg(mode);
  status_->setText(seekNotes.isEmpty() ? line : seekNotes.join("; ") + "  |  " + line);
  status_->setToolTip(status_->text());
}

}  // namespace rehearse::ui
