#pragma once
// Input devices that move the instrument in 3D (issue 37): a 3D mouse (a 6-DoF cap that is pushed and turned, read
// through spacenavd: app/spacenav.hpp) today, a haptic arm with force output later, behind one small interface.
//
// The interface (MotionDevice), for whoever adds a device:
//   - read(): non-blocking, called by the GUI's timer (100 Hz); the device's latest reading since the last call.
//     A *rate* device (3D mouse) says how far its cap is pushed along and turned about its three axes, each -1..1 of
//     its travel; the instrument moves at a speed proportional to it (steer()). A *position* device (a haptic arm)
//     says where its stylus tip is (m, in its own frame); the instrument follows it (its frame registered once).
//     Buttons: bit i set while button i is held.
//   - rendersForce() and render(force): a device with force output receives the tissue's reaction (N, camera frame)
//     from the 1 kHz force loop; a 3D mouse has none (render does nothing).
//   - name(): what the GUI and the command line call it.
// The instrument's moves it makes are posted to the session as ToolPose events like the mouse's, so a recording keeps
// them and replays them bit for bit; the device's readings themselves are not recorded.
//
// steer() is the 3D mouse's mapping, in the camera frame (x right, y down the image, z into the scene): pushing the
// cap right / up / away from you moves the tip right / up / deeper; turning it pivots the shaft about the trocar (its
// entry point through the abdominal wall), as a laparoscopic instrument turns: the tip moves on the sphere about the
// trocar; a twist about the shaft's own axis leaves the tip where it is (the instrument's roll is not modelled, and
// steer() says so). Speeds: SteeringSettings.
#include <Eigen/Core>

#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct DeviceReading {
  enum class Kind { Rate, Position };
  Kind kind = Kind::Rate;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  ///< Rate: -1..1 per axis (device frame); Position: m
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();     ///< Rate: -1..1 per axis (about x, y, z); Position: unused
  unsigned buttons = 0;                                   ///< bit i: button i held
  bool operator==(const DeviceReading&) const = default;
};

class MotionDevice {
 public:
  virtual ~MotionDevice() = default;
  virtual std::string name() const = 0;
  /// The latest reading since the last call (false: nothing new; a rate device's cap keeps its last reading until it
  /// says otherwise, so the caller keeps the last one). Never blocks. False with `error` set when the device went away.
  virtual bool read(DeviceReading& reading, std::string& error) = 0;
  virtual bool rendersForce() const { return false; }
  /// The force to render to the hand (N, camera frame): the tissue's reaction on the instrument.
  virtual void render(const Eigen::Vector3d& /*force*/) {}
};

struct SteeringSettings {
  double speed = 0.05;     ///< m/s at full deflection (5 cm/s)
  double turnRate = 0.6;   ///< rad/s at full turn
  double deadZone = 0.04;  ///< |axis| below this is rest (a cap never returns exactly to 0)
  /// The device's axes in the camera frame (columns: where device x, y, z go). The 3D mouse's default: x right, y up
  /// (the image's -y), z towards the user (the scene's -z: pushing the cap away goes deeper).
  Eigen::Matrix3d axes = (Eigen::Matrix3d() << 1, 0, 0, 0, -1, 0, 0, 0, -1).finished();
};

struct SteeringStep {
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();  ///< the new tip (m, camera frame)
  bool moved = false;
  bool twisted = false;  ///< a twist about the shaft was asked, which does not move the tip (the roll is not modelled)
};

/// A rate reading held for `dt` seconds moves the tip from `tip`: translation (the axes, speed, dead zone), then the
/// turn pivots the shaft about `trocar` (the tip stays at its distance from it). Twists about the shaft are reported.
SteeringStep steer(const Eigen::Vector3d& tip, const Eigen::Vector3d& trocar, const DeviceReading& reading, double dt,
                   const SteeringSettings& settings = {});

/// The test double: readings played from a script (one per read() call, then none), forces rendered kept. Thread-safe.
class ScriptedDevice final : public MotionDevice {
 public:
  explicit ScriptedDevice(std::vector<DeviceReading> script, bool forceOutput = false)
      : script_(std::move(script)), forceOutput_(forceOutput) {}
  std::string name() const override { return "scripted device"; }
  bool read(DeviceReading& reading, std::string& error) override;
  bool rendersForce() const override { return forceOutput_; }
  void render(const Eigen::Vector3d& force) override;
  std::vector<Eigen::Vector3d> rendered() const;
  std::size_t played() const;

 private:
  mutable std::mutex m_;
  std::vector<DeviceReading> script_;
  std::size_t next_ = 0;
  bool forceOutput_ = false;
  std::vector<Eigen::Vector3d> rendered_;
};

}  // namespace rehearse::simcore
