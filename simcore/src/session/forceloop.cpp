#include <rehearse/simcore/session/forceloop.hpp>

#include <algorithm>
#include <cmath>

#include <pthread.h>
#include <sched.h>

namespace rehearse::simcore {

ToolForceModel toolForceModel(const Snapshot& s, double maxGraspForce) {
  ToolForceModel m;
  m.step = s.step;
  m.tip = s.tool.tip;
  m.force = s.tool.force;
  m.stiffness = s.tool.stiffness;
  m.maxForce = s.tool.held.empty() ? 0 : maxGraspForce;  // the jaws' hold caps the pull; contact has no cap
  return m;
}

Eigen::Vector3d extrapolateForce(const ToolForceModel& m, const Eigen::Vector3d& position) {
  Eigen::Vector3d f = m.force + m.stiffness * (position - m.tip);
  if (!f.allFinite()) return m.force.allFinite() ? m.force : Eigen::Vector3d::Zero();
  if (m.maxForce > 0 && f.norm() > m.maxForce) f *= m.maxForce / f.norm();
  return f;
}

void VirtualDevice::setPosition(const Eigen::Vector3d& p) {
  std::lock_guard<std::mutex> lock(m_);
  position_ = p;
  positioned_ = true;
}
Eigen::Vector3d VirtualDevice::position() {
  std::lock_guard<std::mutex> lock(m_);
  return position_;
}
void VirtualDevice::render(const Eigen::Vector3d& force) {
  std::lock_guard<std::mutex> lock(m_);
  rendered_ = force;
}
Eigen::Vector3d VirtualDevice::rendered() const {
  std::lock_guard<std::mutex> lock(m_);
  return rendered_;
}

ForceLoop::ForceLoop(std::function<ToolForceModel()> source, HapticDevice* device, double rateHz)
    : source_(std::move(source)), device_(device), rate_(rateHz > 0 ? rateHz : 1000), started_(std::chrono::steady_clock::now()) {}

ForceLoop::~ForceLoop() { stop(); }

void ForceLoop::start() {
  if (thread_.joinable()) return;
  quit_ = false;
  thread_ = std::thread([this] { run(); });
}

void ForceLoop::stop() {
  quit_ = true;
  if (thread_.joinable()) thread_.join();
}

Eigen::Vector3d ForceLoop::tick() {
  const ToolForceModel model = source_ ? source_() : ToolForceModel{};
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  if (model.step >= 0) f = device_ ? extrapolateForce(model, device_->position()) : model.force;
  if (device_) device_->render(-f);
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  std::lock_guard<std::mutex> lock(m_);
  samples_.push_back({t, f});
  while (!samples_.empty() && samples_.front().time < t - 10.0) samples_.pop_front();
  ++ticks_;
  return f;
}

void ForceLoop::run() {
  // Haptic loops run at a real-time priority where the system grants one (a 1 ms sleep per period leaves the
  // other threads their time); where it does not, at the normal one, and timing() says which.
  sched_param param{};
  param.sched_priority = std::max(1, sched_get_priority_min(SCHED_FIFO));
  realtime_ = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
  using clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<clock::duration>(std::chrono::duration<double>(1.0 / rate_));
  const auto begin = clock::now();
  auto next = begin;
  auto last = begin;
  bool first = true;
  while (!quit_) {
    tick();
    const auto now = clock::now();
    {
      std::lock_guard<std::mutex> lock(m_);
      if (!first) {
        periods_.push_back(std::chrono::duration<double, std::milli>(now - last).count());
        if (periods_.size() > 10000) periods_.pop_front();
      }
      runSeconds_ = std::chrono::duration<double>(now - begin).count();
      ++runTicks_;
    }
    first = false;
    last = now;
    // Absolute deadlines: the rate is the nominal one on average (a tick a little late is followed by a
    // shorter wait); after a stall of more than 10 periods the schedule restarts instead of bursting.
    next += period;
    if (next + 10 * period < now) next = now;
    std::this_thread::sleep_until(next);
  }
}

std::vector<ForceSample> ForceLoop::samples(double seconds) const {
  std::lock_guard<std::mutex> lock(m_);
  std::vector<ForceSample> out;
  if (samples_.empty()) return out;
  const double from = samples_.back().time - seconds;
  for (const auto& s : samples_)
    if (s.time >= from) out.push_back(s);
  return out;
}

ForceLoop::Timing ForceLoop::timing() const {
  std::vector<double> p;
  Timing t;
  {
    std::lock_guard<std::mutex> lock(m_);
    p.assign(periods_.begin(), periods_.end());
    t.ticks = ticks_;
    t.rateHz = runSeconds_ > 0 ? static_cast<double>(runTicks_) / runSeconds_ : 0;
    t.realtime = realtime_;
  }
  if (p.empty()) return t;
  auto at = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(std::lround(q * static_cast<double>(v.size() - 1)))];
  };
  t.medianPeriodMs = at(p, 0.5);
  t.p99PeriodMs = at(p, 0.99);
  t.maxPeriodMs = at(p, 1.0);
  const double nominal = 1000.0 / rate_;
  std::vector<double> dev(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) dev[i] = std::abs(p[i] - nominal);
  t.jitterMs = at(dev, 0.99);
  return t;
}

}  // namespace rehearse::simcore
