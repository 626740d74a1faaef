#include "rehearse/ui/jobrunner.hpp"

#include <QtConcurrent/QtConcurrent>

namespace rehearse::ui {

JobRunner::JobRunner(QObject* parent) : QObject(parent) {
  connect(&watcher_, &QFutureWatcher<std::function<void()>>::finished, this, [this] {
    busy_ = false;  // (a finish step may start the next job)
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
  // Until the last job's finish step ran, not only until its worker is done: the watcher's finished signal comes as a
  // posted event, and a job started before it is handled would replace the watcher's future and drop that signal, and
  // with it the last job's result (an elastic fit or an import done and never applied).
  if (busy_) {
    emit refused(tr("Another job is running; wait for it or cancel it (Esc)."));
    return false;
  }
  busy_ = true;
  cancel_ = false;
  emit busyChanged(true, message);
  Progress progress = [this](double f, QString stage) {
    QMetaObject::invokeMethod(this, [this, f, stage] { emit this->progress(f, stage); }, Qt::QueuedConnection);
  };
  watcher_.setFuture(QtConcurrent::run([this, job = std::move(job), progress]() -> std::function<void()> { return job(cancel_, progress); }));
  return true;
}

}  // namespace rehearse::ui
