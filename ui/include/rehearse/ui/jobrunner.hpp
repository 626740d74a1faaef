#pragma once
// One long job at a time on a worker thread (import and meshing, opening a video, the elastic fit), with
// progress, cancel (Esc) and a finish step that runs back on the GUI thread. The pages start jobs; the main
// window shows busy/progress in the status bar. A job returns the function that applies its result, so a
// worker never touches a widget.
#include <QFutureWatcher>
#include <QObject>
#include <QString>

#include <atomic>
#include <functional>

namespace rehearse::ui {

class JobRunner : public QObject {
  Q_OBJECT
 public:
  /// Reports a fraction in [0, 1] and the stage's words; callable from the worker.
  using Progress = std::function<void(double, QString)>;
  /// Runs on the worker; returns what to do on the GUI thread when it is done (may be empty).
  using Job = std::function<std::function<void()>(const std::atomic<bool>& cancel, const Progress& progress)>;

  explicit JobRunner(QObject* parent = nullptr);
  ~JobRunner() override;
  /// Starts `job` unless another one runs (then false, with a sentence through busyChanged's message).
  bool run(const QString& message, Job job);
  void cancel() { cancel_ = true; }
  /// True from run() until the job's finish step has run on the GUI thread (not only until the worker is done: a job
  /// finished whose result is not applied yet still counts, so that a next job never replaces it unapplied).
  bool isRunning() const { return busy_; }
  void waitForFinished() { watcher_.waitForFinished(); }

 signals:
  void busyChanged(bool busy, const QString& message);
  void progress(double fraction, const QString& stage);
  void refused(const QString& message);

 private:
  std::atomic<bool> cancel_{false};
  QFutureWatcher<std::function<void()>> watcher_;
  bool busy_ = false;
};

}  // namespace rehearse::ui
