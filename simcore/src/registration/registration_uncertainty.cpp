// The registration's bound (RegistrationUncertainty): the cost's curvature at the rigid stage's end, the spread of the
// hypotheses that fit as well (the alternatives, the loosened sag), the estimated camera motions' share, and the far
// ends of where the organ may be.
#include "contour_registration.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace rehearse::simcore::detail {

// How many independent points residuals along a contour are worth: n over their integrated autocorrelation time,
// 1 + 2 sum_k rho_k, summed while the correlations stay positive (Sokal's window; a smooth misfit, the deformation the
// pose cannot explain, is correlated over long stretches of the contour). `lagOne` gets rho_1.
double autocorrelationTime(const std::vector<double>& r, double* lagOne) {
  double sum2 = 0;
  for (double v : r) sum2 += v * v;
  double tau = 1;
  for (std::size_t k = 1; sum2 > 0 && k < r.size() / 4; ++k) {
    double c = 0;
    for (std::size_t i = 0; i + k < r.size(); ++i) c += r[i] * r[i + k];
    const double rho = c / sum2;
    if (k == 1 && lagOne) *lagOne = rho;
    if (!(rho > 0)) break;
    tau += 2 * rho;
  }
  return tau;
}

// A direction of the fit's unknowns in words, from its parts in metres at the organ: a turn (axis times angle times the
// organ's extent), a move, the sag; the largest names it.
std::string describeDirection(const Eigen::Vector3d& turn, const Eigen::Vector3d& move, double sag) {
  const char* axes[] = {"X (across the image)", "Y (down the image)", "Z (the view)"};
  Eigen::Index axis = 0;
  if (sag >= turn.norm() && sag >= move.norm()) return "the organ's sag";
  if (turn.norm() >= move.norm()) {
    turn.cwiseAbs().maxCoeff(&axis);
    return std::string("a turn about the camera's ") + axes[axis] + " axis";
  }
  move.cwiseAbs().maxCoeff(&axis);
  return axis == 2 ? "a move along the view" : std::string("a move along the camera's ") + axes[axis] + " axis";
}

// The cost's curvature's share of RegistrationUncertainty (see there), at the rigid stage's end; `facing` and
// `onSurface` get which nodes are on the surface facing the camera and on the surface at all.
RegistrationUncertainty estimateUncertainty(const std::vector<detail::Binding>& bindings, const Eigen::VectorXd& base,
                                            const Eigen::MatrixXd& U, const std::vector<detail::View>& views,
                                            bool sliding, const Pose& pose, const Eigen::Vector3d& load,
                                            const Eigen::Matrix3d& prior, const FemModel& model,
                                            const std::vector<std::array<int, 3>>& surface, const Eigen::VectorXd& x,
                                            const Eigen::Vector3d& centre, std::vector<char>& facing,
                                            std::vector<char>& onSurface, Eigen::VectorXd& weakestDirection) {
  RegistrationUncertainty u;
  std::vector<double> r;
  const Eigen::MatrixXd H = detail::poseSagInformation(base, U, bindings, views, sliding, pose, load, prior, r);
  const Eigen::Index p = H.rows();
  if (static_cast<Eigen::Index>(r.size()) <= p || !H.allFinite()) return u;
  double sum2 = 0;
  for (double v : r) sum2 += v * v;
  u.misfitPx = std::sqrt(sum2 / static_cast<double>(r.size()));
  const double tau = autocorrelationTime(r, &u.correlation);
  u.autocorrelationTime = tau;
  // The residuals' variance (px^2; at least a tenth of a pixel: the contour's own drawing).
  const double variance = std::max(sum2 / static_cast<double>(r.size() - static_cast<std::size_t>(p)), 0.01);
  const double inflation = std::min(tau, static_cast<double>(r.size()) / static_cast<double>(p));
  // The covariance of (rotation, translation, load): variance * inflation * H^-1, by eigenvalues (a direction of
  // negligible curvature: undetermined).
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(H);
  if (eig.info() != Eigen::Success) return u;
  const double largest = eig.eigenvalues().maxCoeff();
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(p, p);
  bool singular = false;
  for (Eigen::Index k = 0; k < p; ++k) {
    const double l = eig.eigenvalues()[k];
    if (!(l > 1e-12 * largest)) {
      singular = true;
      continue;
    }
    C += eig.eigenvectors().col(k) * eig.eigenvectors().col(k).transpose() / l;
  }
  C *= variance * inflation;
  // Each node's position (camera frame): dq = -[q]x dw + dt + R U_node da.
  auto nodeCovariance = [&](std::size_t i) {
    const Eigen::Vector3d q = pose.apply(x.segment<3>(3 * static_cast<Eigen::Index>(i)));
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(3, p);
    J.block<3, 3>(0, 0) << 0, q.z(), -q.y(), -q.z(), 0, q.x(), q.y(), -q.x(), 0;
    J.block<3, 3>(0, 3).setIdentity();
    if (U.cols()) J.rightCols(U.cols()) = pose.R * U.middleRows(3 * static_cast<Eigen::Index>(i), 3);
    return Eigen::Matrix3d(J * C * J.transpose());
  };
  onSurface.assign(model.nodeCount(), 0);
  facing.assign(model.nodeCount(), 0);
  for (const auto& t : surface) {
    const Eigen::Vector3d a = pose.apply(x.segment<3>(3 * t[0])), b = pose.apply(x.segment<3>(3 * t[1])),
                          c = pose.apply(x.segment<3>(3 * t[2]));
    const bool front = (b - a).cross(c - a).dot(a) < 0;
    for (int v : t) {
      onSurface[static_cast<std::size_t>(v)] = 1;
      facing[static_cast<std::size_t>(v)] |= front;
    }
  }
  double surfaceSum = 0, target = 0;
  std::size_t facingCount = 0;
  for (std::size_t i = 0; i < model.nodeCount(); ++i) {
    if (onSurface[i] && !facing[i]) continue;
    const Eigen::Matrix3d S = nodeCovariance(i);
    const double twoSigma = 2 * std::sqrt(std::max(0.0, S.trace()));
    if (facing[i]) surfaceSum += twoSigma, ++facingCount;
    if (!onSurface[i]) target = std::max(target, twoSigma);
  }
  if (facingCount == 0) return u;
  u.computed = true;
  u.curvatureMm = 1e3 * surfaceSum / static_cast<double>(facingCount);
  u.surfaceMm = singular ? std::numeric_limits<double>::infinity() : u.curvatureMm;
  u.targetMm = singular ? std::numeric_limits<double>::infinity() : 1e3 * std::max(target, u.curvatureMm / 1e3);
  // The weakest direction: the covariance's largest eigenvector, its parts in metres at the organ (a turn by its
  // lever, the organ's extent from its centre; the load by the sag it makes).
  double lever = 0;
  for (std::size_t i = 0; i < model.nodeCount(); ++i)
    lever = std::max(lever, (x.segment<3>(3 * static_cast<Eigen::Index>(i)) - centre).norm());
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(p);
  scale.head<3>().setConstant(lever);
  if (U.cols()) scale.tail(U.cols()).setConstant(U.norm() / std::sqrt(static_cast<double>(U.rows())));
  const Eigen::MatrixXd Cm = scale.asDiagonal() * C * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> weak(Cm);
  const Eigen::VectorXd v = weak.eigenvectors().col(p - 1);
  // (the move named is the organ centre's: the pose's translation is about the camera, where a turn alone moves a far
  // organ sideways; a tilt about the organ's centre is a turn, not a move)
  const Eigen::Vector3d centreMove = v.segment<3>(3) + (v.head<3>() / lever).cross(pose.apply(centre));
  u.weakest = describeDirection(v.head<3>(), centreMove, U.cols() ? v.tail(U.cols()).norm() : 0.0);
  // In (turn, move, load) again, moving the organ by about a millimetre (a unit step would turn it by radians).
  weakestDirection = 1e-3 * scale.cwiseInverse().asDiagonal() * v;
  return u;
}

// The curvature's share at the rigid stage's end, and its weakest direction as the hypothesis the far ends lie towards.
void ContourRegistration::curvatureBound() {
  const auto bindings = rigidBindings(silhouette(res.x, res.pose), res.x, res.pose);
  Eigen::VectorXd weakestDirection;
  const Eigen::MatrixXd& U = sag.U;
  // (the sag's prior loosened as its probe loosens it: the prior's scale is a choice, not a measurement)
  res.uncertainty = estimateUncertainty(
      bindings, U.size() ? sag.rest : res.x, U, problem.views, o.sliding, res.pose, current.load,
      U.size() ? Eigen::Matrix3d(priorMatrix(res.pose, bindings.size()) / o.sagProbeLoosen) : Eigen::Matrix3d::Zero(),
      model, surface, res.x, problem.centre, facing, onSurface, weakestDirection);
  if (res.uncertainty.computed && weakestDirection.size() >= 6) {
    toward.fromPose = res.pose;
    toward.fromX = res.x;
    const Eigen::Vector3d w = weakestDirection.head<3>();
    const Eigen::Matrix3d turn =
        w.norm() > 0 ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() : Eigen::Matrix3d::Identity();
    toward.pose.R = turn * res.pose.R;
    toward.pose.t = turn * res.pose.t + weakestDirection.segment<3>(3);
    toward.x = res.x;
    if (U.cols() && weakestDirection.size() == 6 + U.cols()) toward.x += U * weakestDirection.tail(U.cols());
  }
}

// The hypotheses' spread, measured where the bound speaks: over the surface facing the camera (mean) and the
// inner nodes (largest), from the result's nodes to the hypothesis's (camera frame, mm).
std::pair<double, double> ContourRegistration::spreadOf(const Pose& pose, const Eigen::VectorXd& x) const {
  double sum = 0, inner = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < model.nodeCount(); ++i) {
    const auto k = static_cast<Eigen::Index>(3 * i);
    const double d = 1e3 * (pose.apply(x.segment<3>(k)) - res.pose.apply(res.x.segment<3>(k))).norm();
    if (facing[i]) sum += d, ++count;
    if (!onSurface[i]) inner = std::max(inner, d);
  }
  return std::make_pair(count ? sum / static_cast<double>(count) : 0.0, inner);
}

// The bound at the rigid stage's end: the curvature's share, then the hypotheses' and the estimated motions' added.
void ContourRegistration::estimateBound() {
  curvatureBound();
  std::pair<double, double> spreads{0, 0};
  const bool measured = facing.size() == model.nodeCount();  // (not when the curvature could not be estimated)
  if (measured && sagProbe.x.size()) spreads = spreadOf(sagProbe.pose, sagProbe.x);
  const RegistrationAlternative* farthest = nullptr;
  for (const auto& a : res.alternatives) {
    if (!measured) break;
    const auto s = spreadOf(a.pose, res.x);
    if (s.first > spreads.first) spreads.first = s.first, farthest = &a;
    spreads.second = std::max(spreads.second, s.second);
  }
  const double spread = spreads.first;
  if (!res.uncertainty.computed) return;
  res.uncertainty.spreadMm = spread;
  // Where the hypotheses spread more than the curvature allows, they name the weakest direction.
  if (spread > res.uncertainty.curvatureMm) nameFarthest(farthest);
  res.uncertainty.surfaceMm += spread;
  res.uncertainty.targetMm += std::max(spreads.second, spread);
  addMotionShare(spread, measured);
  // An organ the fit holds nowhere: its sag cannot be estimated (a body load on a free organ has no equilibrium)
  // and the outline of an organ sagging on its ligaments is then explained by a wrong pose, as far from the
  // truth as the sag is deep -- a bound that leaves the sag out would be a confident wrong answer. Unbounded,
  // and said, with what would bound it.
  if (!problem.held && o.elastic && o.estimateSag) {
    res.uncertainty.surfaceMm = res.uncertainty.targetMm = std::numeric_limits<double>::infinity();
    res.uncertainty.weakest =
        "the organ's sag (no node is held: mark where the ligaments hold the organ, step 1, and the fit estimates "
        "it)";
  }
}

// The hypothesis that spreads farthest (an alternative, or the loosened sag when none) names the weakest direction
// and is the one the far ends lie towards.
void ContourRegistration::nameFarthest(const RegistrationAlternative* farthest) {
  if (!farthest) {
    res.uncertainty.weakest = "the organ's sag";
    toward.pose = sagProbe.pose;
    toward.x = sagProbe.x;
  } else {
    toward.pose = farthest->pose;
    toward.x = res.x;
    double lever = 0;
    for (std::size_t i = 0; i < model.nodeCount(); ++i)
      lever = std::max(lever, (res.x.segment<3>(3 * static_cast<Eigen::Index>(i)) - problem.centre).norm());
    const Eigen::AngleAxisd turn(farthest->pose.R * res.pose.R.transpose());
    res.uncertainty.weakest = describeDirection(turn.axis() * turn.angle() * lever,
                                                farthest->pose.apply(problem.centre) - res.pose.apply(problem.centre),
                                                0.0);
  }
}

// An estimated camera motion's uncertainty: where the estimate gives its 1-sigma motion, the pose fitted again
// through it (held shape, short ICP, like the alternatives) and twice how far that moves the surface facing the
// camera; else twice how far it moves the triangulated depths (a single feature's, wider than the fit's).
void ContourRegistration::addMotionShare(double spread, bool measured) {
  std::optional<Pose> motionRefit;  // the largest motion share's refit
  for (std::size_t f = 0; f < problem.frames.size(); ++f) {
    if (!(problem.frames[f].motionDepthSigmaM > 0)) continue;
    double share = 2e3 * problem.frames[f].motionDepthSigmaM;
    if (problem.frames[f].motionAtOneSigma && measured) {
      const std::vector<View> savedViews = problem.views;
      const std::vector<SeenPoint> savedSeen = problem.seen;
      problem.views[f + 1].motion = *problem.frames[f].motionAtOneSigma;
      problem.seen = triangulateSeen();
      try {
        const Pose refit = shortIcpHeld(res.pose, 6).first;
        share = 2 * spreadOf(refit, res.x).first;
        if (share > res.uncertainty.motionMm) motionRefit = refit;
      } catch (const MeshError&) {
        share = std::numeric_limits<double>::infinity();  // the organ behind a camera: unbounded
      }
      problem.views = savedViews;
      problem.seen = savedSeen;
    }
    res.uncertainty.motionMm = std::max(res.uncertainty.motionMm, share);
  }
  if (res.uncertainty.motionMm > std::max(spread, res.uncertainty.curvatureMm)) {
    res.uncertainty.weakest = "a move along the view (the camera's motion between the frames)";
    if (motionRefit) {
      toward.pose = *motionRefit;
      toward.x = res.x;
    }
  }
  res.uncertainty.surfaceMm += res.uncertainty.motionMm;
  res.uncertainty.targetMm += res.uncertainty.motionMm;
}

// The far ends of where the organ may be: the result moved each way towards the bound's hypothesis (its turn and move
// scaled by k about the result's pose, its shape change by k), k such that the surface facing the camera moves by the
// bound on average (three fixed-point steps each way: the move is nearly proportional to k).
void ContourRegistration::computeEnds() {
  if (!(res.ok && res.uncertainty.computed && std::isfinite(res.uncertainty.surfaceMm) &&
        toward.x.size() == res.x.size() && toward.fromX.size() == res.x.size() && facing.size() == model.nodeCount()))
    return;
  // (turned about the organ's centre, which moves as the hypothesis moves it: a turn about the camera would move a
  // far organ by its second order too, unevenly each way)
  const Eigen::AngleAxisd full(toward.pose.R * toward.fromPose.R.transpose());
  const Eigen::Vector3d move = toward.pose.apply(problem.centre) - toward.fromPose.apply(problem.centre);
  const Eigen::Vector3d pivot = res.pose.apply(problem.centre);
  const Eigen::VectorXd shapeChange = toward.x - toward.fromX;
  auto endAt = [&](double k) {
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(k * full.angle(), full.axis()).toRotationMatrix();
    RegistrationEnd e;
    e.pose.R = turn * res.pose.R;
    e.pose.t = pivot + k * move + turn * (res.pose.t - pivot);
    e.x = res.x + k * shapeChange;
    return e;
  };
  auto movedMm = [&](const RegistrationEnd& e) {
    double sum = 0;
    std::size_t count = 0;
    for (std::size_t i = 0; i < model.nodeCount(); ++i) {
      if (!facing[i]) continue;
      const auto k = static_cast<Eigen::Index>(3 * i);
      sum += 1e3 * (e.pose.apply(e.x.segment<3>(k)) - res.pose.apply(res.x.segment<3>(k))).norm();
      ++count;
    }
    return count ? sum / static_cast<double>(count) : 0.0;
  };
  const double target = res.uncertainty.surfaceMm, unit = movedMm(endAt(1));
  if (unit > 1e-9 && target > 0) {
    // Each way on its own (a hypothesis's move need not be symmetric in k).
    for (const double side : {1.0, -1.0}) {
      double k = side * target / unit;
      for (int step = 0; step < 3; ++step) {
        const double atK = movedMm(endAt(k));
        if (!(atK > 1e-9)) break;
        k *= target / atK;
      }
      res.uncertainty.ends.push_back(endAt(k));
    }
  }
}

}  // namespace rehearse::simcore::detail
