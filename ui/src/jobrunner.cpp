#include "rehearse/ui/jobrunner.hpp"

#include <QtConcurrent/QtConcurrent>

namespace rehearse::ui {

JobRunner::JobRunner(QObject* parent) : QObject(parent) {
  connect(&watcher_, &QFutureWatcher<std::function<void()>>::finished, this, [this] {
    emit busyChanged(false, {});
    auto finish = watcher_.result();
    if (finish) finish();
  });
}

JobRunner::~JobRunner() {
  cancel_ = true;
  watcher_.waitForFinished();
}

bool JobRunner::run(const QString& message, Job job) {
  if (watcher_.isRunning()) {
    emit refused(tr("Another job is running; wait for it or cancel it (Esc)."));
    return false;
  }
  cancel_ = false;
  emit busyChanged(true, message);
  Progress progress = [this](double f, QString stage) {
    QMetaObject::invokeMethod(this, [this, f, stage] { emit this->progress(f, stage); }, Qt::QueuedConnection);
  };
  watcher_.setFuture(QtConcurrent::run([this, job = std::move(job), progress]() -> std::function<void()> { return job(cancel_, progress); }));
  return true;
}

}  // namespace rehearse::ui
