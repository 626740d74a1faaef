// The registration's sag (see RegistrationOptions::estimateSag): the held model's linear responses to a small body
// acceleration along each model axis, scaled to 1 m/s^2, so that the rigid stage fits the pose and the load together
// (the shape rest + U load); the load's prior; and the sag's probe (does the contour determine the sag?).
#include "contour_registration.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace rehearse::simcore::detail {

void ContourRegistration::setUpSag() {
  sag.rest = model.restVector();
  sag.downKnown = o.gravityCamera.allFinite() && o.gravityCamera.norm() > 0;
  // The prior's centre: the given gravity (model frame), usually none. The gravity told in the camera frame
  // gives the sag's direction only (how far the organ sags depends on a stiffness the fit does not know).
  sag.givenLoad = settings.gravity.allFinite() ? settings.gravity : Eigen::Vector3d::Zero();
  current.load = sag.givenLoad;
  if (o.rigidPrepass && o.elastic && o.estimateSag && problem.held) sag.U = sagResponses();
  // The prior's weight per bound point and (m/s^2)^2: the RMS node move per unit load over sagScaleMm.
  const Eigen::MatrixXd& U = sag.U;
  const double sagPerLoad = U.size() ? U.norm() / std::sqrt(static_cast<double>(sag.rest.size())) : 0.0;
  sag.weight = std::pow(sagPerLoad / (1e-3 * o.sagScaleMm), 2);
  sag.fewest = U.size() ? 6 : 3;
}

// The held model's responses (3n x 3) to a unit body acceleration along each model axis; empty when a solve fails.
Eigen::MatrixXd ContourRegistration::sagResponses() const {
  const Eigen::VectorXd& rest = sag.rest;
  SimulationSettings linear = settings;
  linear.gravity.setZero();
  if (linear.staticStepTolerance <= 0) linear.staticStepTolerance = 1e-9;
  linear.staticChord = true;  // (linear: the first axis's factor serves the others)
  Integrator responses(model, fixedNodes, linear);
  const double small = 0.01;  // m/s^2: a sag of micrometres, where the model is linear
  Eigen::MatrixXd basis(rest.size(), 3);
  bool usable = true;
  for (int axis = 0; axis < 3 && usable; ++axis) {
    SimulationState st = responses.initialState();
    Eigen::VectorXd f = Eigen::VectorXd::Zero(rest.size());
    for (std::size_t i = 0; i < model.nodeCount(); ++i)
      f.segment<3>(3 * static_cast<Eigen::Index>(i)) = model.lumpedMass[i] * small * Eigen::Vector3d::Unit(axis);
    const StepReport rep = responses.solveStatic(st, f);
    usable = rep.ok && st.x.allFinite();
    if (usable) basis.col(axis) = (st.x - rest) / small;
  }
  if (usable) return basis;
  return Eigen::MatrixXd();
}

// Told which way is down: the directions (camera frame) of the sag that gravity alone cannot give and the outline
// barely shows, as a projector (see priorMatrix).
Eigen::Matrix3d ContourRegistration::downAcrossCamera() const {
  const Eigen::Vector3d g = o.gravityCamera.normalized(), inImage = g.cross(Eigen::Vector3d::UnitZ());
  if (inImage.norm() <= 0.05) return Eigen::Matrix3d::Identity() - g * g.transpose();  // down along the view
  const Eigen::Vector3d mixed = g.cross(inImage.normalized());
  return mixed * mixed.transpose();
}

// The prior's matrix for a pose and a number of bound points: isotropic, or, told which way is down, a
// sag across that direction costs downAcross^2 times more.
Eigen::Matrix3d ContourRegistration::priorMatrix(const Pose& pose, std::size_t bound) const {
  const double w = sag.weight * static_cast<double>(bound);
  if (!sag.downKnown) return w * Eigen::Matrix3d::Identity();
  // Told which way is down, only what the outline cannot show is taken from it: the sag's part along the view,
  // relative to its part in the image (the sag across `d` in the plane of `d` and the view costs downAcross^2
  // times more). Its part across `d` in the image plane the outline shows, and another load (an instrument, a
  // retractor) may well put it there: not penalised beyond the usual prior. (Penalising every part across `d`
  // made fits worse wherever a load other than gravity pushed the organ.) Down along the view: all of it.
  const Eigen::Matrix3d acrossModel = pose.R.transpose() * downAcrossCamera() * pose.R;
  return w * (Eigen::Matrix3d::Identity() + (o.downAcross * o.downAcross - 1) * acrossModel);
}

// The shape under the load a.
Eigen::VectorXd ContourRegistration::shapeOf(const Eigen::Vector3d& a) const {
  return sag.U.size() ? Eigen::VectorXd(sag.rest + sag.U * a) : Eigen::VectorXd(sag.rest);
}

// Does the contour determine the sag? The rigid fit again with the sag's prior loosened: when the load
// the contour alone asks for is more than twice the one found (the prior, not the contour, decided most
// of the sag) and the two put the organ more than sagDecisiveMm apart, the contour does not show how far
// the organ sags (typically its sagging side is not drawn), and the depth of the pose with it.
void ContourRegistration::probeSag() {
  Pose p = res.pose;
  Eigen::Vector3d a = current.load;
  for (int k = 0; k < 8; ++k) {
    const Eigen::VectorXd x = shapeOf(a);
    const auto bindings = rigidBindings(silhouettesOf(x, p), x, p);
    if (bindings.size() < sag.fewest) break;
    refinePoseAndSag(sag.rest, sag.U, bindings, problem.views, o.sliding, p, a, sag.givenLoad,
                     priorMatrix(p, bindings.size()) / o.sagProbeLoosen);
  }
  const Eigen::VectorXd x = shapeOf(a);
  sagProbe.pose = p;
  sagProbe.x = x;
  double sum = 0;
  for (std::size_t i = 0; i < model.nodeCount(); ++i)
    sum += (p.apply(x.segment<3>(3 * i)) - res.pose.apply(res.x.segment<3>(3 * i))).norm();
  sagProbe.apartMm = 1e3 * sum / static_cast<double>(model.nodeCount());
  const double found = (current.load - sag.givenLoad).norm(), alone = (a - sag.givenLoad).norm();
  sagProbe.share = alone > 0 ? found / alone : 1.0;
  sagProbe.undetermined = sagProbe.share < o.sagDeterminedShare && sagProbe.apartMm > o.sagDecisiveMm;
  res.sagDetermined = !sagProbe.undetermined;
  res.sagShare = sagProbe.share;
  res.sagApartMm = sagProbe.apartMm;
}

}  // namespace rehearse::simcore::detail
