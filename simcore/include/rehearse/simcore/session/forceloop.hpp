#pragma once
// The tool-force loop (issue 15): the force on the instrument computed at 1 kHz on its own thread, as
// haptic loops do, from the last physics step's result and the tissue's local stiffness there
// (ToolState::force and ::stiffness: the constraint solve's compliance), extrapolated to where the
// instrument is now: f(p) = f0 + K (p - p0), capped at the scene's maximum grasp force (above it the
// tissue slips at the next step). The physics runs at 100 Hz; the loop renders at 1 kHz between steps.
//
// HapticDevice is the interface a device driver implements (read the stylus position, render a force);
// VirtualDevice stands for it when there is none (the mouse: the GUI sets its position, the loop's force
// is only shown). The loop keeps the last seconds of forces for the GUI's chart and its own tick times.
#include <rehearse/simcore/session/session.hpp>

#include <Eigen/Core>

#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace rehearse::simcore {

/// From a session's snapshot (its tool, the scene's maximum grasp force and the model's reach, m: toolReach).
ToolForceModel toolForceModel(const Snapshot& s, double maxGraspForce, double reach = 0);
/// How far from the step's tip its force model is trusted (m): the shaft's radius, or the grasp radius without a shaft.
double toolReach(const ToolSettings& t);

/// f0 + K (p - p0), p - p0 no longer than the model's reach (when > 0), the force's length capped at maxForce (when
/// > 0). N, the tool's force on the tissue.
Eigen::Vector3d extrapolateForce(const ToolForceModel& m, const Eigen::Vector3d& position);

class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  /// The instrument tip's position (m, the session's frame). Called on the loop's thread.
  virtual Eigen::Vector3d position() = 0;
  /// The force the device renders to the hand: the tissue's reaction, minus the tool's force on it (N).
  virtual void render(const Eigen::Vector3d& force) = 0;
};

/// No device: the position is set from elsewhere (the GUI's instrument), the rendered force is kept.
class VirtualDevice final : public HapticDevice {
 public:
  void setPosition(const Eigen::Vector3d& p);
  Eigen::Vector3d position() override;
  void render(const Eigen::Vector3d& force) override;
  Eigen::Vector3d rendered() const;

 private:
  SeqCell<3> position_, rendered_;  // lock-free: the loop never waits on the GUI
};

struct ForceSample {
  double time = 0;  ///< s since the loop started
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< N, on the tissue
};

class ForceLoop {
 public:
  /// `source` gives the latest model (called every tick: keep it cheap and thread-safe); `device` is not owned.
  ForceLoop(std::function<ToolForceModel()> source, HapticDevice* device, double rateHz = 1000);
  /// A model that computes the force itself at the device's position each tick (the parameterized mesh's FFD and Hertz
  /// law, paramesh.hpp): `forceAt(p)` is the tool's force on the tissue at p (N), called on the loop's thread only.
  ForceLoop(std::function<Eigen::Vector3d(const Eigen::Vector3d&)> forceAt, HapticDevice* device, double rateHz = 1000);
  ~ForceLoop();  ///< stops the thread
  ForceLoop(const ForceLoop&) = delete;
  ForceLoop& operator=(const ForceLoop&) = delete;

  void start();
  void stop();
  bool running() const { return thread_.joinable(); }
  /// One iteration (the thread calls it; tests call it without the thread): reads the model and the device
  /// position, renders minus the extrapolated force, records the sample. Returns the force on the tissue.
  Eigen::Vector3d tick();
  /// The samples of the last `seconds` (oldest first; at most the last 10 s are kept).
  std::vector<ForceSample> samples(double seconds) const;
  struct Timing {
    long ticks = 0;
    double rateHz = 0;        ///< ticks per second of running time
    double medianPeriodMs = 0, p99PeriodMs = 0, maxPeriodMs = 0;
    double jitterMs = 0;      ///< p99 of |period - nominal|
    bool realtime = false;    ///< the thread got a real-time (SCHED_FIFO) priority
  };
  /// Over the last 10,000 periods of the thread.
  Timing timing() const;
  double rateHz() const { return rate_; }

 private:
  void run();
  void record(const ForceSample& sample, double periodMs, bool runTick, double runSeconds = 0);
  struct Pending {  // the loop thread's own, while the readers hold m_
    std::array<ForceSample, 256> sample{};
    std::array<double, 256> period{};
    std::size_t samples = 0, periods = 0;
    long ticks = 0, runTicks = 0;
    double runSeconds = 0;
  };
  Pending pending_;
  std::function<ToolForceModel()> source_;
  std::function<Eigen::Vector3d(const Eigen::Vector3d&)> forceAt_;
  HapticDevice* device_;
  double rate_;
  std::chrono::steady_clock::time_point started_;
  std::atomic<bool> quit_{false};
  std::atomic<bool> realtime_{false};
  std::thread thread_;
  mutable std::mutex m_;  // samples and periods (the loop only try-locks it)
  // Rings allocated once (the loop thread never allocates: malloc can wait on locks of other threads).
  template <typename T>
  struct Ring {
    std::vector<T> data;
    std::size_t head = 0, count = 0;  // the oldest at head
    void push(const T& v) {
      if (count < data.size()) data[(head + count++) % data.size()] = v;
      else if (!data.empty()) {
        data[head] = v;
        head = (head + 1) % data.size();
      }
    }
    const T& at(std::size_t i) const { return data[(head + i) % data.size()]; }
  };
  Ring<ForceSample> samples_;  // the last 10 s
  Ring<double> periods_;       // ms, the last 10,000
  long ticks_ = 0, runTicks_ = 0;
  double runSeconds_ = 0;
};

}  // namespace rehearse::simcore
