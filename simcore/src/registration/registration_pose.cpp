// The pose and the sag refined onto the contour's bindings (registration): Gauss-Newton's normal equations in the
// pose's increments and the load, Levenberg-Marquardt with a prior on the load.
#include <rehearse/simcore/registration.hpp>

#include "registration_parts.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

namespace rehearse::simcore::detail {

namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return m;
}

// The pose and, when U has columns, the sag with it: the bound point is base + U a (base: the shape's
// bound point; U: 3n x k, k = 0 or 3, the held model's linear response to a unit body acceleration along
// each model axis; a: the load, m/s^2), its projection compared with its contour point, or, when
// `pointToLine`, with the line through it along the contour (the distance along the normal).
struct PoseSagProblem {
  const Eigen::VectorXd& base;
  const Eigen::MatrixXd& U;
  const std::vector<Binding>& bindings;
  const std::vector<View>& views;
  bool pointToLine;

  Eigen::Index size() const { return 6 + U.cols(); }
  bool useLine(const Binding& b) const { return pointToLine && b.normal.squaredNorm() > 0; }
  // At most 9 unknowns: fixed-capacity matrices, no heap allocation per bound point.
  using Basis = Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, 3>;
  using Row = Eigen::Matrix<double, 1, Eigen::Dynamic, Eigen::RowMajor, 1, 9>;
  Basis basis(const Binding& b) const { return (1 - b.t) * U.middleRows(3 * b.a, 3) + b.t * U.middleRows(3 * b.b, 3); }
  Eigen::Vector3d at(const Binding& b, const Eigen::Vector3d& load) const {
    Eigen::Vector3d p = point(base, b);
    if (U.cols()) p += basis(b) * load;
    return p;
  }
  double pointResidual(const Binding& b, const Pose& pose, const Eigen::Vector3d& load) const {
    return b.pxPerMetre * (pose.R * b.surfaceNormal).dot(pose.apply(at(b, load)) - b.target);
  }
  // The sum of squared distances (px^2); infinite when a point is behind the camera.
  double cost(const Pose& pose, const Eigen::Vector3d& load) const {
    double c = 0;
    for (const auto& b : bindings) {
      if (b.surfacePoint) {
        c += std::pow(pointResidual(b, pose, load), 2);
        continue;
      }
      const View& v = views[static_cast<std::size_t>(b.view)];
      const Eigen::Vector3d q = v.motion.apply(pose.apply(at(b, load)));
      if (q.z() <= 0) return std::numeric_limits<double>::infinity();
      const Eigen::Vector2d r = v.camera.project(q) - b.contour;
      c += useLine(b) ? std::pow(b.normal.dot(r), 2) : r.squaredNorm();
    }
    return c;
  }
  // Gauss-Newton's normal equations in (rotation increment, translation, load), camera frame increments.
  void normalEquations(const Pose& pose, const Eigen::Vector3d& load, Eigen::MatrixXd& JtJ,
                       Eigen::VectorXd& Jtr) const {
    const Eigen::Index n = size();
    JtJ = Eigen::MatrixXd::Zero(n, n);
    Jtr = Eigen::VectorXd::Zero(n);
    Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, 9> dq(3, n);
    Eigen::Matrix<double, 2, Eigen::Dynamic, 0, 2, 9> J(2, n);
    for (const auto& b : bindings) {
      if (b.surfacePoint) {  // across the surface, the normal held as it is
        const Eigen::Vector3d q1 = pose.apply(at(b, load));
        dq.leftCols<3>() = -skew(q1);
        dq.middleCols<3>(3).setIdentity();
        if (U.cols()) dq.rightCols(U.cols()) = pose.R * basis(b);
        const Row Jn = b.pxPerMetre * (pose.R * b.surfaceNormal).transpose() * dq;
        JtJ.noalias() += Jn.transpose() * Jn;
        Jtr.noalias() += Jn.transpose() * pointResidual(b, pose, load);
        continue;
      }
      // The increments are the first camera's (q1 its point); the binding's view sees q = motion (q1).
      const View& v = views[static_cast<std::size_t>(b.view)];
      const Pinhole& cam = v.camera;
      const Eigen::Vector3d q1 = pose.apply(at(b, load));
      const Eigen::Vector3d q = v.motion.apply(q1);
      const Eigen::Vector2d r = cam.project(q) - b.contour;
      Eigen::Matrix<double, 2, 3> dpi;
      const double fx = cam.K(0, 0), fy = cam.K(1, 1), z = q.z();
      dpi << fx / z, cam.K(0, 1) / z, -(fx * q.x() + cam.K(0, 1) * q.y()) / (z * z), 0, fy / z, -fy * q.y() / (z * z);
      dq.leftCols<3>() = -skew(q1);
      dq.middleCols<3>(3).setIdentity();
      if (U.cols()) dq.rightCols(U.cols()) = pose.R * basis(b);
      J.noalias() = dpi * v.motion.R * dq;
      if (useLine(b)) {
        const Row Jn = b.normal.transpose() * J;
        JtJ.noalias() += Jn.transpose() * Jn;
        Jtr.noalias() += Jn.transpose() * b.normal.dot(r);
      } else {
        JtJ.noalias() += J.transpose() * J;
        Jtr.noalias() += J.transpose() * r;
      }
    }
  }
};

// Levenberg-Marquardt on the problem, with a prior (a - a0)' P (a - a0) on the load (P per (m/s^2)^2).
void refinePoseAndSag(const PoseSagProblem& pr, Pose& pose, Eigen::Vector3d& a, const Eigen::Vector3d& a0,
                      const Eigen::Matrix3d& prior) {
  const bool sag = pr.U.cols() > 0;
  auto cost = [&](const Pose& p, const Eigen::Vector3d& load) {
    return pr.cost(p, load) + (sag ? (load - a0).dot(prior * (load - a0)) : 0.0);
  };
  double lambda = 1e-3;
  double current = cost(pose, a);
  Eigen::MatrixXd JtJ;
  Eigen::VectorXd Jtr;
  for (int it = 0; it < 10; ++it) {
    pr.normalEquations(pose, a, JtJ, Jtr);
    if (sag) {
      JtJ.bottomRightCorner<3, 3>() += prior;
      Jtr.tail<3>() += prior * (a - a0);
    }
    bool improved = false;
    for (int tries = 0; tries < 8 && !improved; ++tries) {
      Eigen::MatrixXd A = JtJ;
      A.diagonal() *= 1 + lambda;
      const Eigen::VectorXd delta = -A.ldlt().solve(Jtr);
      if (!delta.allFinite()) break;
      const Eigen::Vector3d w = delta.head<3>();
      const Eigen::Matrix3d dR =
          w.norm() > 0 ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() : Eigen::Matrix3d::Identity();
      Pose trial;
      trial.R = dR * pose.R;
      trial.t = dR * pose.t + delta.segment<3>(3);
      const Eigen::Vector3d load = sag ? Eigen::Vector3d(a + delta.tail<3>()) : a;
      const double c = cost(trial, load);
      if (c < current) {
        pose = trial;
        a = load;
        current = c;
        lambda = std::max(lambda / 10, 1e-9);
        improved = true;
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
}

}  // namespace

void refinePoseAndSag(const Eigen::VectorXd& base, const Eigen::MatrixXd& U, const std::vector<Binding>& bindings,
                      const std::vector<View>& views, bool pointToLine, Pose& pose, Eigen::Vector3d& a,
                      const Eigen::Vector3d& a0, const Eigen::Matrix3d& prior) {
  refinePoseAndSag(PoseSagProblem{base, U, bindings, views, pointToLine}, pose, a, a0, prior);
}

Eigen::MatrixXd poseSagInformation(const Eigen::VectorXd& base, const Eigen::MatrixXd& U,
                                   const std::vector<Binding>& bindings, const std::vector<View>& views,
                                   bool pointToLine, const Pose& pose, const Eigen::Vector3d& a,
                                   const Eigen::Matrix3d& prior, std::vector<double>& residuals) {
  const PoseSagProblem pr{base, U, bindings, views, pointToLine};
  Eigen::MatrixXd JtJ;
  Eigen::VectorXd Jtr;
  pr.normalEquations(pose, a, JtJ, Jtr);
  if (U.cols()) JtJ.bottomRightCorner<3, 3>() += prior;
  residuals.clear();
  for (const auto& b : bindings) {
    if (b.surfacePoint) continue;  // (the residuals along the contours only: their correlation is along them)
    const View& v = views[static_cast<std::size_t>(b.view)];
    const Eigen::Vector3d q = v.motion.apply(pose.apply(pr.at(b, a)));
    const Eigen::Vector2d r = q.z() > 0 ? Eigen::Vector2d(v.camera.project(q) - b.contour) : Eigen::Vector2d::Zero();
    residuals.push_back(pr.useLine(b) ? b.normal.dot(r) : r.norm());
  }
  return JtJ;
}

// The pose alone, the shape x as it is.
Pose refinePose(const Eigen::VectorXd& x, const std::vector<Binding>& bindings, Pose pose,
                const std::vector<View>& views, bool pointToLine) {
  static const Eigen::MatrixXd none;
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  refinePoseAndSag(PoseSagProblem{x, none, bindings, views, pointToLine}, pose, a, a, Eigen::Matrix3d::Zero());
  return pose;
}

}  // namespace rehearse::simcore::detail
