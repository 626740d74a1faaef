// Input devices: the 3D mouse's steering of the instrument and the scripted test double (device.hpp).
#include <rehearse/simcore/session/device.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace rehearse::simcore {
namespace {
// Each axis past the dead zone, rescaled so that motion starts from zero at its edge and reaches 1 at full travel.
Eigen::Vector3d pastDeadZone(const Eigen::Vector3d& v, double dead) {
  Eigen::Vector3d out;
  for (int a = 0; a < 3; ++a) {
    const double x = std::clamp(v(a), -1.0, 1.0);
    out(a) = std::abs(x) <= dead ? 0.0 : std::copysign((std::abs(x) - dead) / (1 - dead), x);
  }
  return out;
}
}  // namespace

SteeringStep steer(const Eigen::Vector3d& tip, const Eigen::Vector3d& trocar, const DeviceReading& reading, double dt,
                   const SteeringSettings& settings) {
  SteeringStep out;
  out.tip = tip;
  if (reading.kind != DeviceReading::Kind::Rate || !(dt > 0) || !reading.translation.allFinite() ||
      !reading.rotation.allFinite())
    return out;
  const double dead = std::clamp(settings.deadZone, 0.0, 0.9);
  const Eigen::Vector3d t = settings.axes * pastDeadZone(reading.translation, dead);
  const Eigen::Vector3d w = settings.axes * pastDeadZone(reading.rotation, dead);
  Eigen::Vector3d p = tip + settings.speed * dt * t;
  const Eigen::Vector3d shaft = p - trocar;
  if (w.squaredNorm() > 0 && shaft.norm() > 1e-9) {
    const Eigen::Vector3d axis = shaft.normalized();
    const Eigen::Vector3d pivot = w - axis * axis.dot(w);  // the twist about the shaft itself moves nothing
    out.twisted = std::abs(axis.dot(w)) > 0.5 * w.norm();
    const double angle = settings.turnRate * dt * pivot.norm();
    if (angle > 0) p = trocar + Eigen::AngleAxisd(angle, pivot.normalized()) * shaft;
  }
  out.moved = (p - tip).squaredNorm() > 0;
  out.tip = p;
  return out;
}

bool ScriptedDevice::read(DeviceReading& reading, std::string& /*error*/) {
  std::lock_guard<std::mutex> lock(m_);
  if (next_ >= script_.size()) return false;
  reading = script_[next_++];
  return true;
}

void ScriptedDevice::render(const Eigen::Vector3d& force) {
  std::lock_guard<std::mutex> lock(m_);
  if (forceOutput_) rendered_.push_back(force);
}

std::vector<Eigen::Vector3d> ScriptedDevice::rendered() const {
  std::lock_guard<std::mutex> lock(m_);
  return rendered_;
}

std::size_t ScriptedDevice::played() const {
  std::lock_guard<std::mutex> lock(m_);
  return next_;
}

}  // namespace rehearse::simcore
