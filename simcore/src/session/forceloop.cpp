#include <rehearse/simcore/session/forceloop.hpp>

#include <algorithm>
#include <cmath>

#include <pthread.h>
#include <sched.h>

namespace rehearse::simcore {

ToolForceModel toolForceModel(const Snapshot& s, double maxGraspForce, double reach) {
  ToolForceModel m;
  m.step = s.step;
  m.tip = s.tool.tip;
  m.force = s.tool.force;
  // The stiffness is extrapolated with only when it is the tissue's under what acts now: a step that reached its
  // equations' answer (converged, within the accuracy asked, or inexact by design, as the linearised method's one solve),
  // and something still held or touched. After a slip or on a step that did not converge the force is held instead: a
  // person's chart rose to 5-194 kN between steps that solved 16-25 N (the patient liver, the jaws' stiffness
  // extrapolated with nothing held and no cap, and an unconverged step's compliance).
  const StepReport& r = s.report;
  const bool solved = r.outcome == StepStatus::Converged || r.withinAccuracy ||
                      (r.outcome == StepStatus::Inexact && r.keptBestOf == 0 && !r.guardStalled && !r.errorUnknown);
  const bool acting = !s.tool.held.empty() || s.tool.contacts > 0;
  m.stiffness = solved && acting ? s.tool.stiffness : Eigen::Matrix3d::Zero();
  m.maxForce = s.tool.held.empty() ? 0 : maxGraspForce;  // the jaws' hold caps the pull; contact has no cap
  m.reach = reach;
  return m;
}

double toolReach(const ToolSettings& t) { return t.toolRadius > 0 ? t.toolRadius : t.graspRadius; }

Eigen::Vector3d extrapolateForce(const ToolForceModel& m, const Eigen::Vector3d& position) {
  Eigen::Vector3d d = position - m.tip;
  if (m.reach > 0 && d.norm() > m.reach) d *= m.reach / d.norm();  // the linear model holds near the step's tip only
  Eigen::Vector3d f = m.force + m.stiffness * d;
  if (!f.allFinite()) return m.force.allFinite() ? m.force : Eigen::Vector3d::Zero();
  if (m.maxForce > 0 && f.norm() > m.maxForce) f *= m.maxForce / f.norm();
  return f;
}

void VirtualDevice::setPosition(const Eigen::Vector3d& p) { position_.store({p.x(), p.y(), p.z()}); }
Eigen::Vector3d VirtualDevice::position() {
  const auto v = position_.load();
  return {v[0], v[1], v[2]};
}
void VirtualDevice::render(const Eigen::Vector3d& force) { rendered_.store({force.x(), force.y(), force.z()}); }
Eigen::Vector3d VirtualDevice::rendered() const {
  const auto v = rendered_.load();
  return {v[0], v[1], v[2]};
}

ForceLoop::ForceLoop(std::function<ToolForceModel()> source, HapticDevice* device, double rateHz)
    : source_(std::move(source)), device_(device), rate_(rateHz > 0 ? rateHz : 1000), started_(std::chrono::steady_clock::now()) {
  samples_.data.resize(static_cast<std::size_t>(std::ceil(10.0 * rate_)) + 1);
  periods_.data.resize(10000);
}

ForceLoop::ForceLoop(std::function<Eigen::Vector3d(const Eigen::Vector3d&)> forceAt, HapticDevice* device,
                     double rateHz)
    : ForceLoop(std::function<ToolForceModel()>(), device, rateHz) {
  forceAt_ = std::move(forceAt);
}

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
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  if (forceAt_) {
    if (device_) f = forceAt_(device_->position());
  } else {
    const ToolForceModel model = source_ ? source_() : ToolForceModel{};
    if (model.step >= 0) f = device_ ? extrapolateForce(model, device_->position()) : model.force;
  }
  if (device_) device_->render(-f);
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  record({t, f}, -1, false);
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
    record({}, first ? -1 : std::chrono::duration<double, std::milli>(now - last).count(), true, std::chrono::duration<double>(now - begin).count());
    first = false;
    last = now;
    // Absolute deadlines: the rate is the nominal one on average (a tick a little late is followed by a
    // shorter wait); after a stall of more than 10 periods the schedule restarts instead of bursting.
    next += period;
    if (next + 10 * period < now) next = now;
    std::this_thread::sleep_until(next);
  }
}

// The loop never waits for the lock that the GUI's readers take (a preempted reader holding it would stall
// a real-time thread): what it cannot store now waits in a small buffer of its own until the next tick.
void ForceLoop::record(const ForceSample& sample, double periodMs, bool runTick, double runSeconds) {
  Pending& p = pending_;
  if (!runTick) {
    if (p.samples < p.sample.size()) p.sample[p.samples++] = sample;
    ++p.ticks;
  } else {
    if (periodMs >= 0 && p.periods < p.period.size()) p.period[p.periods++] = periodMs;
    ++p.runTicks;
    p.runSeconds = runSeconds;
  }
  std::unique_lock<std::mutex> lock(m_, std::try_to_lock);
  if (!lock.owns_lock()) return;
  for (std::size_t k = 0; k < p.samples; ++k) samples_.push(p.sample[k]);
  for (std::size_t k = 0; k < p.periods; ++k) periods_.push(p.period[k]);
  ticks_ += p.ticks;
  runTicks_ += p.runTicks;
  if (p.runSeconds > 0) runSeconds_ = p.runSeconds;
  p = Pending{};
}

std::vector<ForceSample> ForceLoop::samples(double seconds) const {
  std::lock_guard<std::mutex> lock(m_);
  std::vector<ForceSample> out;
  if (samples_.count == 0) return out;
  const double newest = samples_.at(samples_.count - 1).time, from = newest - std::min(seconds, 10.0);
  for (std::size_t i = 0; i < samples_.count; ++i)
    if (samples_.at(i).time >= from) out.push_back(samples_.at(i));
  return out;
}

ForceLoop::Timing ForceLoop::timing() const {
  std::vector<double> p;
  Timing t;
  {
    std::lock_guard<std::mutex> lock(m_);
    p.resize(periods_.count);
    for (std::size_t i = 0; i < periods_.count; ++i) p[i] = periods_.at(i);
    t.ticks = ticks_;
    t.rateHz = runSeconds_ > 0 && runTicks_ > 1 ? static_cast<double>(runTicks_ - 1) / runSeconds_ : 0;  // periods per second
    t.realtime = realtime_;
  }
  if (p.empty()) return t;
  // The quantiles by selection, not by sorting: the Rehearse page asks on the GUI thread, where four sorts of the last
  // 10,000 periods took 4-10 ms (a visible share of a frame).
  auto at = [](std::vector<double>& v, double q) {
    const auto k = static_cast<std::ptrdiff_t>(std::lround(q * static_cast<double>(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[static_cast<std::size_t>(k)];
  };
  t.maxPeriodMs = *std::max_element(p.begin(), p.end());
  t.p99PeriodMs = at(p, 0.99);
  t.medianPeriodMs = at(p, 0.5);
  const double nominal = 1000.0 / rate_;
  for (double& v : p) v = std::abs(v - nominal);
  t.jitterMs = at(p, 0.99);
  return t;
}

}  // namespace rehearse::simcore
