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

#include <atomic>
#include <chrono>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace rehearse::simcore {

/// What the loop extrapolates from: one physics step's tool force and stiffness at the tip it had.
struct ToolForceModel {
  long step = -1;                                        ///< the physics step it came from (-1: none yet)
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();         ///< m, where the tool was at that step
  Eigen::Vector3d force = Eigen::Vector3d::Zero();       ///< N, the tool's force on the tissue there
  Eigen::Matrix3d stiffness = Eigen::Matrix3d::Zero();   ///< N/m, d force / d tip
  double maxForce = 0;                                   ///< N, the cap (0: none)
};
/// From a session's snapshot (its tool and the scene's maximum grasp force).
ToolForceModel toolForceModel(const Snapshot& s, double maxGraspForce);

/// f0 + K (p - p0), its length capped at maxForce (when > 0). N, the tool's force on the tissue.
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
  mutable std::mutex m_;
  Eigen::Vector3d position_ = Eigen::Vector3d::Zero(), rendered_ = Eigen::Vector3d::Zero();
  bool positioned_ = false;
};

struct ForceSample {
  double time = 0;  ///< s since the loop started
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< N, on the tissue
};

class ForceLoop {
 public:
  /// `source` gives the latest model (called every tick: keep it cheap and thread-safe); `device` is not owned.
  ForceLoop(std::function<ToolForceModel()> source, HapticDevice* device, double rateHz = 1000);
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
  std::function<ToolForceModel()> source_;
  HapticDevice* device_;
  double rate_;
  std::chrono::steady_clock::time_point started_;
  std::atomic<bool> quit_{false};
  std::atomic<bool> realtime_{false};
  std::thread thread_;
  mutable std::mutex m_;  // samples and periods
  std::deque<ForceSample> samples_;
  std::deque<double> periods_;  // ms
  long ticks_ = 0, runTicks_ = 0;
  double runSeconds_ = 0;
};

}  // namespace rehearse::simcore
