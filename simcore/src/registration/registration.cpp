// Elastic registration of the organ onto a sketched contour (registration.hpp): registerToContour drives the stages of
// detail::ContourRegistration (contour_registration.hpp says which file holds which); triangulateTrack.
#include <rehearse/simcore/registration.hpp>

#include "contour_registration.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <utility>

namespace rehearse::simcore {

using namespace detail;

bool triangulateTrack(const Pinhole& first, const Pinhole& other, const Pose& motion, const Eigen::Vector2d& inFirst,
                      const Eigen::Vector2d& inOther, Eigen::Vector3d& point, double& gapPx) {
  // Midpoint of the shortest segment between the two rays (first camera frame).
  const Eigen::Vector3d d1 = first.ray(inFirst), d2 = motion.R.transpose() * other.ray(inOther);
  const Eigen::Vector3d c2 = -motion.R.transpose() * motion.t;
  const double b = d1.dot(d2), denominator = 1 - b * b;
  if (!(denominator > std::pow(std::sin(0.2 * M_PI / 180), 2))) return false;
  const Eigen::Vector3d w = -c2;  // first origin minus second
  const double s = (b * d2.dot(w) - d1.dot(w)) / denominator, u = (d2.dot(w) - b * d1.dot(w)) / denominator;
  if (!(s > 0 && u > 0)) return false;
  const Eigen::Vector3d p1 = s * d1, p2 = c2 + u * d2;
  point = 0.5 * (p1 + p2);
  gapPx = first.K(0, 0) * (p1 - p2).norm() / point.z();
  return point.allFinite() && point.z() > 0;
}

namespace detail {

// The start: the given pose, the shape under the given load (the rest shape but for a given gravity's sag), recorded
// as iteration 0.
void ContourRegistration::recordStart() {
  res.pose = start;
  res.x = shapeOf(current.load);
  current.first = record(0, "start", 0);
}

// The load the elastic stage uses (the one the rigid stage found, or the told gravity), and the rigid stage's end.
RigidEnd ContourRegistration::endRigidStage() {
  if (!sag.U.size() && sag.downKnown)  // (an organ the fit does not hold: the told gravity is the elastic stage's)
    current.load = res.pose.R.transpose() * o.gravityCamera;  // the told gravity, in the frame of the pose found
  settings.gravity = current.load;
  res.load = current.load;
  RigidEnd end;
  end.pose = res.pose;
  end.x = res.x;
  end.mean = score(res.x, res.pose);
  return end;
}

}  // namespace detail

RegistrationResult registerToContour(const FemModel& model, const std::vector<int>& fixedNodes,
                                     SimulationSettings settings, const std::vector<std::array<int, 3>>& surface,
                                     const std::vector<std::vector<Eigen::Vector2d>>& contour, const Pose& start,
                                     const Pinhole& camera, const RegistrationOptions& o) {
  ContourRegistration fit(model, fixedNodes, settings, surface, contour, start, camera, o);
  RegistrationResult& res = fit.res;
  // The problem: the frames (some set aside), the seen points, the contours and curves checked (MeshError when
  // unusable) and resampled; then the sag's responses and prior, and the start recorded.
  fit.setUpProblem();
  fit.setUpSag();
  fit.recordStart();
  if (res.cancelled) {
    res.status = "cancelled";
    return std::move(res);
  }
  const bool rigid = o.rigidPrepass || !o.elastic;
  // Rigid pre-pass: the pose (and the sag) refined on the bindings (ICP), from the best of a few candidates.
  if (rigid) fit.rigidStage();
  // Does the contour determine the pose? (alternatives that fit nearly as well; a deeper minimum adopted)
  if (rigid && o.probeAmbiguity) fit.probePoses();
  // Does the contour determine the sag? (the rigid fit again with the sag's prior loosened)
  if (fit.sag.U.size() && o.probeAmbiguity && !res.cancelled) fit.probeSag();
  // How far the result may be from the truth (RegistrationUncertainty).
  if (rigid && !res.cancelled) fit.estimateBound();
  const RigidEnd rigidEnd = fit.endRigidStage();
  if (res.cancelled) {
    res.status = "cancelled";
    return std::move(res);
  }
  if (o.elastic && o.rigidPrepass && rigidEnd.mean > 0.02 * fit.problem.diag) {
    // No pose near the start brings the organ's outline near the contour: deforming it there would only
    // stretch it onto another shape.
    res.status =
        "failed: after the rigid fit the contour is still " + std::to_string(static_cast<int>(rigidEnd.mean)) +
        " px from the organ's silhouette on average; it may belong to another organ or the start pose is too far";
    return std::move(res);
  }
  if (!o.elastic) {
    res.ok = true;
    res.converged = true;
    res.status = "rigid fit: mean distance " + pixels(rigidEnd.mean);
  } else {
    fit.elasticStage(rigidEnd);
  }
  // The verdict: a fit far from the contour fails; the bound's far ends; an ambiguous fit said so.
  fit.checkFinalFit();
  fit.computeEnds();
  fit.sayAmbiguity();
  if (!fit.problem.setAside.empty()) res.status += "; " + fit.problem.setAside;
  res.setAsideFrames = fit.problem.setAsideFrames;
  return std::move(res);
}

}  // namespace rehearse::simcore
