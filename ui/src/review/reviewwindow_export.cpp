// The review window's exports (issue 16): the first attempt's video span and PDF report, written on a worker with a
// replayer of its own while a progress dialog shows (and Cancel stops a video), and where they are suggested.
#include "rehearse/ui/reviewwindow.hpp"

#include "reviewparts.hpp"

#include <QDir>
#include <QEventLoop>
#include <QFileInfo>
#include <QLabel>
#include <QProgressDialog>
#include <QTimer>
#include <QtConcurrent/QtConcurrentRun>

#include <algorithm>
#include <atomic>

namespace rehearse::ui {

QString ReviewWindow::suggestedExportPath(const QString& extension) const {
  // Beside the case file, named after it and the session shown: "liver-session-3.mp4".
  const auto& a = attempts_[0];
  const QFileInfo kase(file_);
  const QString dir = file_.isEmpty() ? QDir::homePath() : kase.absolutePath();
  const QString base = file_.isEmpty() ? tr("review") : kase.completeBaseName();
  const QString session = a ? tr("-session-%1").arg(a->recording.summary.id) : QString();
  return QDir(dir).filePath(base + session + "." + extension);
}

QString ReviewWindow::exportFirst(const QString& doing, bool cancellable, const ExportWork& write) {
  auto& a = attempts_[0];
  if (!a || !a->ready) return tr("The session is still being replayed; export when its timeline shows.");
  setPlaying(false);
  // On a worker (issue 62: a report froze the window 9 s, a video 6 s): a replayer of its own (the view's stays where
  // it is) and a copy of the view's renderer (the view may turn meanwhile); progress and Cancel here.
  auto renderer = std::make_shared<app::ReviewRenderer>(a->renderer(threeD_));
  struct Shared {
    std::atomic<int> done{0}, total{0};
    std::atomic<bool> cancel{false};
  };
  auto shared = std::make_shared<Shared>();
  QProgressDialog progress(doing, cancellable ? tr("Cancel") : QString(), 0, 0, this);
  progress.setObjectName(QStringLiteral("exportProgress"));
  progress.setWindowModality(Qt::WindowModal);
  progress.setMinimumDuration(300);
  if (!cancellable) progress.setCancelButton(nullptr);
  connect(&progress, &QProgressDialog::canceled, this, [shared] { shared->cancel = true; });
  struct Outcome {
    QString status, error;
  };
  QFutureWatcher<Outcome> watcher;
  QEventLoop loop;
  exporting_ = true;
  connect(&watcher, &QFutureWatcher<Outcome>::finished, &loop, &QEventLoop::quit);
  ReviewAttempt* attempt = a.get();
  watcher.setFuture(QtConcurrent::run([attempt, renderer, shared, write]() -> Outcome {
    try {
      app::Replayer replayer(attempt->recording);  // (building it takes a while on a large organ: here, not on the GUI thread)
      replayer.avoidCheckpoints(attempt->result.verify);
      return {write(*attempt, replayer, *renderer,
                    [shared](int done, int total) {
                      shared->done = done;
                      shared->total = total;
                      return !shared->cancel.load();
                    }),
              {}};
    } catch (const std::exception& e) {
      return {{}, QString::fromStdString(e.what())};
    }
  }));
  QTimer poll;
  poll.setInterval(100);
  connect(&poll, &QTimer::timeout, this, [&] {
    if (shared->cancel) return;
    const int total = shared->total;
    if (total > 0) {
      progress.setMaximum(total);
      progress.setLabelText(tr("%1: frame %2 of %3").arg(doing).arg(shared->done.load()).arg(total));
      progress.setValue(std::min(shared->done.load(), total - 1));
    } else {
      progress.setValue(0);  // (busy: shown after its minimum duration)
    }
  });
  poll.start();
  progress.setValue(0);
  if (!watcher.isFinished()) loop.exec();
  exporting_ = false;
  poll.stop();
  const Outcome out = watcher.result();
  progress.reset();
  if (!out.error.isEmpty())
    return out.error == QLatin1String("cancelled") ? tr("The export was cancelled; the partial file was left as it is.")
                                                   : out.error;
  status_->setText(out.status);
  return {};
}

QString ReviewWindow::exportVideo(const QString& path, double from, double to) {
  return exportFirst(tr("Writing the video"), true,
                     [this, path, from, to](ReviewAttempt& a, app::Replayer& replayer, const app::ReviewRenderer& r,
                                            const std::function<bool(int, int)>& progress) {
                       const long first = a.stepAt(from);
                       const int frames =
                           app::writeReviewVideo(replayer, r, a.result.timeline, first, std::max(a.stepAt(to), first + 1),
                                                 25, path.toStdString(), progress);
                       return tr("Video of %1 frames written to %2").arg(frames).arg(path);
                     });
}

QString ReviewWindow::exportReport(const QString& path) {
  const auto thresholds = thresholds_;
  return exportFirst(tr("Writing the report (replaying the session for its key frames)"), false,
                     [this, path, thresholds](ReviewAttempt& a, app::Replayer& replayer, const app::ReviewRenderer& r,
                                              const std::function<bool(int, int)>&) {
                       app::writeReviewPdf(app::makeReviewReport(a.recording, a.result, thresholds, replayer, r),
                                      path.toStdString());
                       return tr("Report written to %1").arg(path);
                     });
}

}  // namespace rehearse::ui
