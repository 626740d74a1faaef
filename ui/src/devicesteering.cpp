// A 3D mouse moving the active instrument (devicesteering.hpp).
#include "rehearse/ui/devicesteering.hpp"

#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/simulationpanel.hpp"
#include "tools/tools.hpp"

#include <rehearse/app/spacenav.hpp>

#include <QAction>
#include <QMenu>
#include <QTimer>

#include <algorithm>

namespace rehearse::ui {

DeviceSteering::DeviceSteering(FrameView* view, SimulationPanel* panel, std::function<void(const QString&)> say,
                               QObject* parent)
    : QObject(parent), view_(view), panel_(panel), say_(std::move(say)) {
  timer_ = new QTimer(this);
  timer_->setInterval(10);
  timer_->setTimerType(Qt::PreciseTimer);
  // The time since the last read moves the tip (a timer's period varies under load; a long stall counts 50 ms at most).
  connect(timer_, &QTimer::timeout, this, [this] {
    const double dt = clock_.isValid() ? std::min(0.05, clock_.nsecsElapsed() * 1e-9) : 0.010;
    clock_.restart();
    tick(dt);
  });
}

DeviceSteering::~DeviceSteering() = default;

void DeviceSteering::addActions(QMenu* menu) {
  action_ = menu->addAction(tr("Connect &3D Mouse"), this, [this] {
    if (device_)
      disconnectDevice();
    else
      connectSpaceNav();
  });
  action_->setObjectName(QStringLiteral("connect3DMouse"));
  action_->setCheckable(true);
  action_->setToolTip(
      tr("A 3D mouse (through spacenavd) moves the instrument in step 7: push the cap to move it, turn it to pivot "
         "the shaft about the trocar; its left button works the instrument. The mouse works as before."));
  connect(this, &DeviceSteering::connectedChanged, action_, &QAction::setChecked);
}

bool DeviceSteering::connectSpaceNav() {
  std::string why;
  auto d = app::openSpaceNav(why);
  if (!d) {
    say_(QString::fromStdString(why));
    emit connectedChanged(device_ != nullptr);
    return false;
  }
  connectDevice(std::move(d));
  return true;
}

void DeviceSteering::connectDevice(std::unique_ptr<simcore::MotionDevice> device) {
  disconnectDevice();
  device_ = std::move(device);
  reading_ = {};
  tip_.reset();
  saidTwist_ = saidStep_ = false;
  say_(tr("%1 connected: push the cap to move the instrument, turn it to pivot the shaft about the trocar, its left "
          "button works the instrument (step 7).")
           .arg(QString::fromStdString(device_->name())));
  clock_.invalidate();
  timer_->start();
  emit connectedChanged(true);
}

void DeviceSteering::disconnectDevice() {
  if (!device_) return;
  if (held_) pressed(false);
  timer_->stop();
  device_.reset();
  view_->setDeviceTip(std::nullopt, false);
  emit connectedChanged(false);
}

int DeviceSteering::instrument() const {
  switch (view_->tool()) {
    case Tool::Grasp:
      return 0;
    case Tool::Scissors:
      return 1;
    case Tool::Clip:
      return 3;
    case Tool::Cautery:
      return 4;
    default:
      return -1;
  }
}

Eigen::Vector3d DeviceSteering::startTip() const {
  // Where the instrument is, else on the organ's surface at the frame's centre, else its centre of gravity.
  if (const auto f = panel_->lastFrame(); f && f->tool.present) return f->tool.tip;
  const auto& c = view_->caseData();
  if (!c) return Eigen::Vector3d::Zero();
  if (const auto hit = view_->liveSurfaceAt(Eigen::Vector2d(0.5 * c->camera.width, 0.5 * c->camera.height)))
    return *hit;
  return c->pose.apply(c->organ->centreOfGravity);
}

void DeviceSteering::tick(double dt) {
  if (!device_) return;
  std::string error;
  simcore::DeviceReading r;
  if (device_->read(r, error)) reading_ = r;
  if (!error.empty()) {
    say_(QString::fromStdString(error));
    disconnectDevice();
    return;
  }
  const int tool = instrument();
  const bool moving = reading_.translation.norm() > settings_.deadZone || reading_.rotation.norm() > settings_.deadZone;
  const bool button = (reading_.buttons & 1u) != 0;
  const auto& c = view_->caseData();
  if (tool < 0 || !c || !c->hasPose || !panel_->session()) {
    if ((moving || button) && !saidStep_) {
      say_(
          tr("The 3D mouse moves the instruments of step 7: take one (R grasper, B scissors, U clip applier, J "
             "cautery hook) on the placed organ."));
      saidStep_ = true;
    }
    if (!button && held_) pressed(false);
    view_->setDeviceTip(std::nullopt, false);
    return;
  }
  saidStep_ = false;
  if (!tip_) {
    if (!moving && !button) return;
    tip_ = startTip();
  }
  const auto f = panel_->lastFrame();
  const Eigen::Vector3d trocar = f ? f->trocar : Eigen::Vector3d::Zero();
  const simcore::SteeringStep s = simcore::steer(*tip_, trocar, reading_, dt, settings_);
  if (s.twisted && !saidTwist_) {
    say_(
        tr("Turning the cap about the shaft does nothing: the instrument's roll is not modelled (tilt it to pivot the "
           "shaft)."));
    saidTwist_ = true;
  }
  if (s.moved) {
    tip_ = s.tip;
    tools::postInstrument(*view_, simcore::InputKind::ToolPose, *tip_, false, held_ ? heldBy_ : tool);
  }
  if (button != held_) pressed(button);
  view_->setDeviceTip(tip_, held_);
  if (device_->rendersForce() && panel_->forceLoop()) {
    const auto samples = panel_->forceLoop()->samples(0.05);
    device_->render(samples.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(-samples.back().force));
  }
}

void DeviceSteering::pressed(bool down) {
  const int tool = down ? instrument() : heldBy_;
  held_ = down;
  heldBy_ = down ? tool : -1;
  if (tool < 0 || !tip_) return;
  const Eigen::Vector3d tip = *tip_;
  switch (tool) {
    case 0:
      if (down) tools::postInstrument(*view_, simcore::InputKind::ToolPose, tip, false, 0);
      tools::postInstrument(*view_, simcore::InputKind::Jaw, tip, down, 0);
      break;
    case 1:
      tools::postInstrument(*view_, simcore::InputKind::Cut, tip, down, 1);
      break;
    case 3:
      if (down) tools::postInstrument(*view_, simcore::InputKind::Clip, tip, true, 3);
      break;
    case 4:
      tools::postInstrument(*view_, simcore::InputKind::Energy, tip, down, 4);
      break;
    default:
      break;
  }
}

}  // namespace rehearse::ui
