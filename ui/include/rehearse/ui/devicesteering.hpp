#pragma once
// A 3D mouse (or any simcore::MotionDevice) moving the active instrument in step 7, beside the mouse (issue 37).
// Simulate > Connect 3D Mouse connects to spacenavd (app/spacenav.hpp); a timer reads the device 100 times a second,
// steers the instrument's tip (simcore::steer: push to move, turn to pivot about the trocar) and posts its moves
// to the session as the mouse's tools do (so they are recorded and replayed); button 1 (the left one) works the active
// instrument while held: the grasper's jaws, the scissors' blade, the cautery's power; a press closes a clip. A
// device with force output gets the force loop's force. The device's words (connected, lost, what it cannot do) go
// to the status bar.
#include <rehearse/simcore/session/device.hpp>

#include <QElapsedTimer>
#include <QObject>
#include <QString>

#include <functional>
#include <memory>
#include <optional>

class QAction;
class QMenu;
class QTimer;

namespace rehearse::ui {

class FrameView;
class SimulationPanel;

class DeviceSteering : public QObject {
  Q_OBJECT
 public:
  DeviceSteering(FrameView* view, SimulationPanel* panel, std::function<void(const QString&)> say,
                 QObject* parent = nullptr);
  ~DeviceSteering() override;
  void addActions(QMenu* menu);
  /// Connects to spacenavd; false (said) when there is no daemon.
  bool connectSpaceNav();
  /// Uses `device` (tests: a simcore::ScriptedDevice); replaces the one connected.
  void connectDevice(std::unique_ptr<simcore::MotionDevice> device);
  void disconnectDevice();
  bool connected() const { return device_ != nullptr; }
  const simcore::MotionDevice* device() const { return device_.get(); }
  /// Reads and steers once (the timer calls it every 10 ms; tests may call it directly). `dt`: s since the last.
  void tick(double dt);
  /// Where the device puts the instrument's tip (camera frame, m); none before its first move.
  std::optional<Eigen::Vector3d> tip() const { return tip_; }
  simcore::SteeringSettings& settings() { return settings_; }

 signals:
  void connectedChanged(bool connected);

 private:
  void pressed(bool down);
  int instrument() const;  ///< the active instrument's index (the tools' numbering), -1 outside the instruments
  Eigen::Vector3d startTip() const;

  FrameView* view_;
  SimulationPanel* panel_;
  std::function<void(const QString&)> say_;
  std::unique_ptr<simcore::MotionDevice> device_;
  QTimer* timer_ = nullptr;
  QElapsedTimer clock_;  ///< since the last read
  QAction* action_ = nullptr;
  simcore::DeviceReading reading_;
  simcore::SteeringSettings settings_;
  std::optional<Eigen::Vector3d> tip_;
  bool held_ = false;  ///< button 1 held (the instrument working)
  int heldBy_ = -1;    ///< the instrument it works
  bool saidTwist_ = false, saidStep_ = false;
};

}  // namespace rehearse::ui
