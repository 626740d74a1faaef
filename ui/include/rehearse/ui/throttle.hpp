#pragma once
// Text read by eyes need not change 100 times a second: a Throttle runs its action at most every
// `intervalMs` (15 Hz by default) and always once more after the last request, so the newest state is
// shown. Measured in bench_rehearsal_view: status labels set at every simulation step cost the live view
// 3-6 fps on two cores.
#include <QElapsedTimer>
#include <QTimer>

#include <functional>

namespace rehearse::ui {

class Throttle {
 public:
  Throttle(QObject* parent, std::function<void()> action, int intervalMs = 66) : timer_(new QTimer(parent)), action_(std::move(action)), interval_(intervalMs) {
    timer_->setSingleShot(true);
    QObject::connect(timer_, &QTimer::timeout, parent, [this] { run(); });
  }
  ~Throttle() { delete timer_; }
  Throttle(const Throttle&) = delete;
  Throttle& operator=(const Throttle&) = delete;
  /// Runs the action now if it last ran long enough ago, else once when the interval is over.
  void request() {
    if (timer_->isActive()) return;
    const qint64 since = clock_.isValid() ? clock_.elapsed() : interval_;
    if (since >= interval_) run();
    else timer_->start(static_cast<int>(interval_ - since));
  }
  /// Runs a pending action now (e.g. before a test or a screenshot reads the text).
  void flush() {
    if (timer_->isActive()) {
      timer_->stop();
      run();
    }
  }

 private:
  void run() {
    clock_.restart();
    action_();
  }
  QTimer* timer_;
  std::function<void()> action_;
  int interval_;
  QElapsedTimer clock_;
};

}  // namespace rehearse::ui
