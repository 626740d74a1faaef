#include <rehearse/simcore/registration.hpp>

#include "registration_parts.hpp"

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <limits>
#include <map>
#include <queue>

namespace rehearse::simcore {

using namespace detail;

namespace {

struct Sample {
  Eigen::Vector2d pixel, normal;
};

// Contour points at uniform spacing with their 2D normals (perpendicular to the local tangent).
std::vector<Sample> contourSamples(const std::vector<std::vector<Eigen::Vector2d>>& contour, double spacing) {
  std::vector<Sample> out;
  for (const auto& seg : contour) {
    if (seg.size() < 2) continue;
    std::vector<Eigen::Vector2d> pts{seg.front()};
    double carry = 0;
    for (std::size_t i = 1; i < seg.size(); ++i) {
      const Eigen::Vector2d a = seg[i - 1], b = seg[i];
      const double len = (b - a).norm();
      double s = spacing - carry;
      while (s <= len) {
        pts.push_back(a + (b - a) * (s / len));
        s += spacing;
      }
      carry = len - (s - spacing);
    }
    if ((pts.back() - seg.back()).norm() > 0.25 * spacing) pts.push_back(seg.back());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector2d t = pts[std::min(i + 1, pts.size() - 1)] - pts[i > 0 ? i - 1 : 0];
      const Eigen::Vector2d n = t.norm() > 0 ? Eigen::Vector2d(-t.y(), t.x()).normalized() : Eigen::Vector2d(0, 0);
      out.push_back({pts[i], n});
    }
  }
  return out;
}

// Bindings further than `factor` times the median distance (and than `floorPx`) are outliers.
void dropOutliers(std::vector<Binding>& bindings, double factor, double floorPx) {
  if (bindings.empty()) return;
  std::vector<double> d;
  for (const auto& b : bindings) d.push_back(b.distance);
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  const double limit = std::max(factor * d[d.size() / 2], floorPx);
  bindings.erase(std::remove_if(bindings.begin(), bindings.end(), [&](const Binding& b) { return b.distance > limit; }),
                 bindings.end());
}

// For the rigid pass: every contour point to the nearest compatible point of the silhouette edges (the
// pose has six unknowns, so many correspondences anywhere on the edges are best), outliers dropped.
std::vector<Binding> bindForRigid(const std::vector<Sample>& samples, const std::vector<SilhouetteEdge>& sil,
                                  const RegistrationOptions& o) {
  std::vector<Binding> out;
  const SilhouetteGrid grid(sil);
  for (const auto& s : samples) {
    double d, t;
    const int i = grid.nearest(s.pixel, s.normal, o.normalDot, d, t);
    if (i < 0) continue;
    const SilhouetteEdge& e = sil[static_cast<std::size_t>(i)];
    out.push_back({e.a, e.b, t, s.pixel, d, e.normal, e.bulge});
  }
  dropOutliers(out, o.outlierFactor, 4.0);
  return out;
}

// Binds the silhouette to the contour at the silhouette's vertices (the projected surface nodes on the
// silhouette, with the mean normal of their silhouette edges): each vertex to the foot of its
// perpendicular on the nearest compatible stretch of contour (so nothing pulls along the outline), vertices
// whose nearest contour point is an open end of the contour are left free (a partial contour says nothing
// beyond its ends), and far outliers are dropped. Binding at nodes keeps the constraints consistent: one
// pair of constraints across the ray per node.
std::vector<Binding> bindContour(const std::vector<Sample>& samples, const std::vector<std::size_t>& segmentStarts,
                                 const std::vector<SilhouetteEdge>& sil, const std::vector<char>& fixed,
                                 const RegistrationOptions& o, double floorPx) {
  std::map<int, std::pair<Eigen::Vector2d, Eigen::Vector2d>> vertices;  // node -> pixel, summed normal
  for (const auto& e : sil)
    for (int k = 0; k < 2; ++k) {
      const int node = k ? e.b : e.a;
      if (fixed[node]) continue;  // held by the ligaments: cannot follow
      auto [it, added] = vertices.try_emplace(node, k ? e.pb : e.pa, Eigen::Vector2d::Zero());
      it->second.second += e.normal;
    }
  std::vector<Binding> out;
  for (const auto& [node, pn] : vertices) {
    const Eigen::Vector2d n = pn.second.norm() > 0 ? Eigen::Vector2d(pn.second.normalized()) : Eigen::Vector2d::Zero();
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector2d foot = Eigen::Vector2d::Zero(), footNormal = Eigen::Vector2d::Zero();
    bool atEnd = false;
    for (std::size_t sgi = 0; sgi < segmentStarts.size(); ++sgi) {
      const std::size_t begin = segmentStarts[sgi],
                        end = sgi + 1 < segmentStarts.size() ? segmentStarts[sgi + 1] : samples.size();
      for (std::size_t i = begin; i + 1 < end; ++i) {
        const Sample &p = samples[i], &q = samples[i + 1];
        const Eigen::Vector2d tangent = q.pixel - p.pixel;
        if (tangent.norm() == 0) continue;
        const Eigen::Vector2d cn(-tangent.y() / tangent.norm(), tangent.x() / tangent.norm());
        if (n.squaredNorm() > 0 && std::abs(cn.dot(n)) < o.normalDot) continue;
        const double t = closestParameter(p.pixel, q.pixel, pn.first);
        const Eigen::Vector2d f = p.pixel + t * tangent;
        const double d = (f - pn.first).norm();
        if (d < best) {
          best = d;
          foot = f;
          footNormal = cn;
          atEnd = (i == begin && t == 0.0) || (i + 2 == end && t == 1.0);
        }
      }
    }
    if (std::isfinite(best) && !(atEnd && best > 2.0)) out.push_back({node, node, 0, foot, best, footNormal});
  }
  dropOutliers(out, o.outlierFactor, floorPx);
  return out;
}

// Every node of the anatomical curves to the nearest point of its image curve (one binding per node; nodes
// whose nearest point is an open end, further than 2 px, are left free; fixed nodes too when given).
std::vector<Binding> bindCurves(const std::vector<AnatomicalCurve>& curves, const Eigen::VectorXd& x, const Pose& pose,
                                const Pinhole& cam, const std::vector<char>* fixed) {
  std::vector<Binding> out;
  std::vector<char> seen(static_cast<std::size_t>(x.size() / 3), 0);
  for (const auto& c : curves)
    for (int node : c.nodes) {
      if (seen[node] || (fixed && (*fixed)[node])) continue;
      seen[node] = 1;
      const Eigen::Vector3d q = pose.apply(x.segment<3>(3 * node));
      if (!(q.z() > 1e-6)) continue;
      const Foot f = nearestOnPolyline(c.image, cam.project(q));
      if (std::isfinite(f.distance) && !(f.atEnd && f.distance > 2.0))
        out.push_back({node, node, 0, f.point, f.distance, f.normal});
    }
  return out;
}

// The bound point on the ray through its contour point: two constraints across the ray (model frame). When
// sliding, one: the point on the plane through the camera centre and the contour's tangent line there, so
// it is held across the contour and free along it.
void rayConstraints(const Binding& b, const Pose& pose, const Pinhole& cam, bool sliding,
                    std::vector<ScalarConstraint>& out) {
  if (sliding && b.normal.squaredNorm() > 0) {
    const Eigen::Vector3d line(b.normal.x(), b.normal.y(), -b.normal.dot(b.contour));  // the tangent line in the image
    const Eigen::Vector3d plane = cam.K.transpose() * line;  // camera frame, through the centre
    ScalarConstraint c;
    c.nodes = {b.a, b.b, -1, -1};
    c.weights = {1 - b.t, b.t, 0, 0};
    c.direction = (pose.R.transpose() * plane).normalized();
    c.value = -plane.dot(pose.t) / plane.norm();
    out.push_back(c);
    return;
  }
  const Eigen::Vector3d d = (pose.R.transpose() * cam.ray(b.contour)).normalized();
  const Eigen::Vector3d origin = -pose.R.transpose() * pose.t;
  Eigen::Vector3d helper = Eigen::Vector3d::Unit(0);
  if (std::abs(d.x()) > 0.6) helper = Eigen::Vector3d::Unit(1);
  const Eigen::Vector3d n1 = d.cross(helper).normalized(), n2 = d.cross(n1).normalized();
  for (const Eigen::Vector3d& n : {n1, n2}) {
    ScalarConstraint c;
    c.nodes = {b.a, b.b, -1, -1};
    c.weights = {1 - b.t, b.t, 0, 0};
    c.direction = n;
    c.value = n.dot(origin);
    out.push_back(c);
  }
}

// A surface point seen in two frames (triangulated, first camera frame) and how much a metre across the surface there
// is worth in the tracker's pixels (the depth's: f b / z^2, less when the motion is uncertain).
struct SeenPoint {
  Eigen::Vector3d target;
  double pxPerMetre;
};

// Each seen point to the nearest surface node facing the first camera (its normal from the shape x), held across the
// surface there; far ones (more than 3x the median, at least 4 px) dropped.
std::vector<Binding> bindPoints(const std::vector<SeenPoint>& points, const std::vector<std::array<int, 3>>& surface,
                                const Eigen::VectorXd& x, const Pose& pose, const Pinhole& cam) {
  std::vector<Binding> out;
  if (points.empty()) return out;
  std::vector<Eigen::Vector3d> normal(static_cast<std::size_t>(x.size() / 3), Eigen::Vector3d::Zero());
  for (const auto& t : surface) {
    const Eigen::Vector3d a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
    const Eigen::Vector3d n = (b - a).cross(c - a);  // area-weighted
    for (int v : t) normal[static_cast<std::size_t>(v)] += n;
  }
  std::vector<int> front;
  for (std::size_t i = 0; i < normal.size(); ++i) {
    if (normal[i].squaredNorm() == 0) continue;
    normal[i].normalize();
    if ((pose.R * normal[i]).dot(pose.apply(x.segment<3>(3 * static_cast<Eigen::Index>(i)))) < 0)
      front.push_back(static_cast<int>(i));
  }
  for (const auto& p : points) {
    double best = std::numeric_limits<double>::infinity();
    int node = -1;
    for (int i : front) {
      const double d = (pose.apply(x.segment<3>(3 * i)) - p.target).squaredNorm();
      if (d < best) best = d, node = i;
    }
    if (node < 0) continue;
    Binding b{node, node, 0, cam.project(p.target), cam.K(0, 0) * std::sqrt(best) / p.target.z()};
    b.surfacePoint = true;
    b.target = p.target;
    b.surfaceNormal = normal[static_cast<std::size_t>(node)];
    b.pxPerMetre = p.pxPerMetre;
    out.push_back(b);
  }
  dropOutliers(out, 3.0, 4.0);
  return out;
}

}  // namespace

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

namespace {

// How many independent points residuals along a contour are worth: n over their integrated autocorrelation time,
// 1 + 2 sum_k rho_k, summed while the correlations stay positive (Sokal's window; a smooth misfit, the deformation the
// pose cannot explain, is correlated over long stretches of the contour). `lagOne` gets rho_1.
double autocorrelationTime(const std::vector<double>& r, double* lagOne = nullptr) {
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

}  // namespace

RegistrationResult registerToContour(const FemModel& model, const std::vector<int>& fixedNodes,
                                     SimulationSettings settings, const std::vector<std::array<int, 3>>& surface,
                                     const std::vector<std::vector<Eigen::Vector2d>>& contour, const Pose& start,
                                     const Pinhole& camera, const RegistrationOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&] {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  checkCamera(camera);
  // The frames: the first's camera and contour, then the further ones'.
  std::vector<detail::View> views{{camera, Pose{}}};
  std::vector<const std::vector<std::vector<Eigen::Vector2d>>*> contours{&contour};
  // A frame whose estimated motion leaves the depth more uncertain than the tolerance is set aside (said in the
  // status): through it, its outline and features would drag the fit by as much (a 0.6 degree turn error put the
  // sagged liver of test_registration 50 mm off), where the first frame alone does better.
  std::vector<RegistrationFrame> frames;
  std::string setAside;
  std::vector<int> setAsideFrames;
  for (std::size_t i = 0; i < o.frames.size(); ++i) {
    const auto& f = o.frames[i];
    checkCamera(f.camera);
    const Eigen::Matrix3d RtR = f.motion.R.transpose() * f.motion.R;
    if (!f.motion.R.allFinite() || !f.motion.t.allFinite() || !RtR.isIdentity(1e-6) || f.motion.R.determinant() < 0)
      throw MeshError("The camera's motion to another frame is not a rotation and a move; estimate it again.");
    if (!(f.motionDepthSigmaM >= 0) || !std::isfinite(f.motionDepthSigmaM))
      throw MeshError("The camera motion's uncertainty is not a non-negative number; estimate the motion again.");
    if (f.motionAtOneSigma) {
      const Pose& m = *f.motionAtOneSigma;
      if (!m.R.allFinite() || !m.t.allFinite() || !(m.R.transpose() * m.R).isIdentity(1e-6) || m.R.determinant() < 0)
        throw MeshError("The camera motion's uncertainty is not a rotation and a move; estimate the motion again.");
    }
    if (1e3 * f.motionDepthSigmaM > o.toleranceMm) {
      char text[300];
      std::snprintf(text, sizeof text,
                    "frame %zu was set aside: its camera motion, estimated from the frames, leaves the depth uncertain "
                    "by %.0f mm (1 sigma), more than the %.1f mm asked for (a longer move between the frames, or the "
                    "motion of a tracked or stereo scope, would make it count)",
                    i + 2, 1e3 * f.motionDepthSigmaM, o.toleranceMm);
      setAside += std::string(setAside.empty() ? "" : "; ") + text;
      setAsideFrames.push_back(static_cast<int>(i));
      continue;
    }
    frames.push_back(f);
  }
  for (const auto& f : frames) {
    views.push_back({f.camera, f.motion});
    contours.push_back(&f.contour);
  }
  // The features tracked into further frames, triangulated through the views' motions (rays passing more than 3 px
  // apart: a mismatch, dropped).
  auto triangulateSeen = [&] {
    std::vector<SeenPoint> out;
    for (std::size_t f = 0; f < frames.size(); ++f) {
      const auto& frame = frames[f];
      const Pose& motion = views[f + 1].motion;
      const double baseline = motion.t.norm();
      for (const auto& [a, b] : frame.tracks) {
        Eigen::Vector3d p;
        double gap = 0;
        if (!a.allFinite() || !b.allFinite() || !triangulateTrack(camera, frame.camera, motion, a, b, p, gap) ||
            gap > 3.0)
          continue;
        // Its depth's noise (m): the tracker's through the baseline, and the estimated motion's, whose uncertainty
        // moves every triangulated depth (with a poorly known motion the points weigh little, cannot drag the fit off).
        const double pxPerMetre = camera.K(0, 0) * baseline / (p.z() * p.z());
        const double trackSigma = std::sqrt(2.0) * std::max(o.trackNoisePx, 0.05);
        const double depthSigma = std::hypot(trackSigma / pxPerMetre, frame.motionDepthSigmaM);
        out.push_back({p, trackSigma / depthSigma});
      }
    }
    return out;
  };
  std::vector<SeenPoint> seen = triangulateSeen();
  std::size_t points = 0;
  // Points further than this from the image are not a sketch of it (and resampling them would take forever).
  const double farPx = 100.0 * std::max(camera.width, camera.height);
  auto farAway = [&](const Eigen::Vector2d& p) { return p.cwiseAbs().maxCoeff() > farPx; };
  for (const auto& seg : contour) {
    points += seg.size();
    for (const auto& p : seg) {
      if (!p.allFinite()) throw MeshError("The contour has a point that is not a number.");
      if (farAway(p))
        throw MeshError("The contour has points far outside the image; check that it belongs to this frame.");
    }
  }
  for (std::size_t v = 1; v < contours.size(); ++v) {
    std::size_t count = 0;
    for (const auto& seg : *contours[v]) {
      count += seg.size();
      for (const auto& p : seg)
        if (!p.allFinite() || farAway(p))
          throw MeshError("The outline on frame " + std::to_string(v + 1) +
                          " has a point that is not a number or lies far outside the image.");
    }
    if (count < 2) throw MeshError("The outline on frame " + std::to_string(v + 1) + " is empty; sketch it first.");
  }
  // Anatomical curves: checked, and their image curves resampled like the contour.
  std::vector<AnatomicalCurve> curves = o.curves;
  for (auto& c : curves) {
    if (c.nodes.size() < 2 || c.image.size() < 2)
      throw MeshError("An anatomical curve (" + c.type +
                      ") needs at least two nodes on the organ and two points in the image.");
    for (int node : c.nodes)
      if (node < 0 || static_cast<std::size_t>(node) >= model.nodeCount())
        throw MeshError("An anatomical curve (" + c.type + ") refers to node " + std::to_string(node) +
                        ", which the organ does not have.");
    for (const auto& p : c.image) {
      if (!p.allFinite())
        throw MeshError("An anatomical curve (" + c.type + ") has an image point that is not a number.");
      if (farAway(p))
        throw MeshError("An anatomical curve (" + c.type +
                        ") has points far outside the image; check that it belongs to this frame.");
    }
    std::vector<Eigen::Vector2d> resampled;
    for (const auto& sample : contourSamples({c.image}, o.spacing)) resampled.push_back(sample.pixel);
    c.image = resampled;
  }
  if (points == 0 && curves.empty()) throw MeshError("The contour is empty; sketch the organ's outline first.");
  if (points == 1 && curves.empty())
    throw MeshError("The contour has a single point; sketch at least a short stretch of the outline.");
  if (surface.empty()) throw MeshError("The organ has no surface triangles.");

  std::vector<char> fixed(model.nodeCount(), 0);
  for (int f : fixedNodes)
    if (f >= 0 && static_cast<std::size_t>(f) < fixed.size()) fixed[f] = 1;
  // Each frame's contour samples, its segments' starts among them.
  std::vector<std::vector<std::size_t>> segmentStarts(views.size());
  std::vector<std::vector<Sample>> samples(views.size());
  for (std::size_t v = 0; v < views.size(); ++v)
    for (const auto& seg : *contours[v]) {
      const auto one = contourSamples({seg}, o.spacing);
      if (one.size() < 2) continue;
      segmentStarts[v].push_back(samples[v].size());
      samples[v].insert(samples[v].end(), one.begin(), one.end());
    }
  // The organ's silhouette in every frame.
  using Silhouettes = std::vector<std::vector<SilhouetteEdge>>;
  auto silhouettesOf = [&](const Eigen::VectorXd& x, const Pose& pose) {
    Silhouettes out;
    for (const auto& v : views) out.push_back(visibleSilhouette(surface, x, detail::viewPose(v, pose), v.camera));
    return out;
  };
  // The silhouettes of the last state asked for: recording an iteration and binding the next one look at
  // the same state, and the depth buffer is the costly part.
  struct {
    Eigen::VectorXd x;
    Pose pose;
    Silhouettes edges;
    bool valid = false;
  } last;
  auto silhouette = [&](const Eigen::VectorXd& x, const Pose& pose) -> const Silhouettes& {
    if (!(last.valid && last.x == x && last.pose.R == pose.R && last.pose.t == pose.t)) {
      last.edges = silhouettesOf(x, pose);
      last.x = x;
      last.pose = pose;
      last.valid = true;
    }
    return last.edges;
  };
  RegistrationResult res;
  res.x = model.restVector();
  res.pose = start;
  // The distances of the silhouette contour and of the curves, for a shape, a pose and its silhouette.
  auto measure = [&](const Silhouettes& sil, const Eigen::VectorXd& x, const Pose& pose) {
    RegistrationIteration r;
    r.residual = contourResidual(contour, sil[0]);
    for (std::size_t v = 1; v < views.size(); ++v) {  // all frames' distances as one (means weighted by points)
      const Residual2D more = contourResidual(*contours[v], sil[v]);
      const std::size_t n = r.residual.points + more.points;
      if (n == 0) continue;
      r.residual.mean = (r.residual.mean * r.residual.points + more.mean * more.points) / n;
      r.residual.rms =
          std::sqrt((r.residual.rms * r.residual.rms * r.residual.points + more.rms * more.rms * more.points) / n);
      r.residual.hausdorff = std::max(r.residual.hausdorff, more.hausdorff);
      r.residual.points = n;
    }
    r.curves = curveResidual(curves, x, pose, camera);
    if (!seen.empty()) {
      ResidualSum sum;
      for (const auto& b : bindPoints(seen, surface, x, pose, camera))
        sum.add(std::abs(b.pxPerMetre * (pose.R * b.surfaceNormal).dot(pose.apply(x.segment<3>(3 * b.a)) - b.target)));
      r.points = sum.result();
    }
    return r;
  };
  auto record = [&](int it, const char* stage, std::size_t bound) {
    RegistrationIteration ri = measure(silhouette(res.x, res.pose), res.x, res.pose);
    ri.iteration = it;
    ri.stage = stage;
    ri.bound = bound;
    ri.wallMs = elapsed();
    res.iterations.push_back(ri);
    if (o.onIteration && !o.onIteration(ri, res.x, res.pose)) res.cancelled = true;
    return ri;
  };
  // The mean distance over the silhouette contour and the curves, for a shape and a pose.
  auto score = [&](const Eigen::VectorXd& x, const Pose& pose) {
    return measure(silhouette(x, pose), x, pose).score();
  };
  // Correspondences for the pose (the shape is res.x): the contour onto the silhouette's edges, the curves'
  // nodes onto their image curves.
  auto rigidBindings = [&](const Silhouettes& sil, const Eigen::VectorXd& x, const Pose& pose) {
    std::vector<Binding> b;
    for (std::size_t v = 0; v < views.size(); ++v) {
      auto one = bindForRigid(samples[v], sil[v], o);
      for (auto& binding : one) binding.view = static_cast<int>(v);
      b.insert(b.end(), one.begin(), one.end());
    }
    const auto c = bindCurves(curves, x, pose, camera, nullptr);
    b.insert(b.end(), c.begin(), c.end());
    auto p = bindPoints(seen, surface, x, pose, camera);
    if (!p.empty() && b.size() > 6) {
      // The two kinds weighed by what each is worth: a seen point by its depth's noise (the tracker's, in both
      // frames), a contour point by the outline's misfit over its correlation length (the model's error, not noise,
      // is what mostly remains along an outline).
      std::vector<double> r;
      static const Eigen::MatrixXd none;
      detail::poseSagInformation(x, none, b, views, o.sliding, pose, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero(),
                                 r);
      double sum2 = 0;
      for (double v : r) sum2 += v * v;
      const double contourSigma =
          std::sqrt(std::max(sum2 / static_cast<double>(r.size()), 0.01) * autocorrelationTime(r));
      const double pointSigma = std::sqrt(2.0) * std::max(o.trackNoisePx, 0.05);
      for (auto& binding : p) binding.pxPerMetre *= contourSigma / pointSigma;
    }
    b.insert(b.end(), p.begin(), p.end());
    return b;
  };
  // The sag (see RegistrationOptions::estimateSag): the held model's linear responses to a small body
  // acceleration along each model axis, scaled to 1 m/s^2; the rigid stage then fits the pose and the load
  // (the shape rest + U load) together.
  const Eigen::VectorXd rest = model.restVector();
  const bool downKnown = o.gravityCamera.allFinite() && o.gravityCamera.norm() > 0;
  // The prior's centre: the given gravity (model frame), usually none. The gravity told in the camera frame
  // gives the sag's direction only (how far the organ sags depends on a stiffness the fit does not know).
  const Eigen::Vector3d givenLoad = settings.gravity.allFinite() ? settings.gravity : Eigen::Vector3d::Zero();
  Eigen::Vector3d load = givenLoad;
  Eigen::MatrixXd U;  // empty: the shape stays the rest shape in the rigid stage
  const bool held = std::find(fixed.begin(), fixed.end(), 1) != fixed.end();
  if (o.rigidPrepass && o.elastic && o.estimateSag && held) {
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
    if (usable) U = basis;
  }
  // The prior's weight per bound point and (m/s^2)^2: the RMS node move per unit load over sagScaleMm.
  const double sagPerLoad = U.size() ? U.norm() / std::sqrt(static_cast<double>(rest.size())) : 0.0;
  const double sagWeight = std::pow(sagPerLoad / (1e-3 * o.sagScaleMm), 2);
  // Told which way is down: the directions (camera frame) of the sag that gravity alone cannot give and the outline
  // barely shows, as a projector (see priorMatrix).
  auto downAcrossCamera = [&]() -> Eigen::Matrix3d {
    const Eigen::Vector3d g = o.gravityCamera.normalized(), inImage = g.cross(Eigen::Vector3d::UnitZ());
    if (inImage.norm() <= 0.05) return Eigen::Matrix3d::Identity() - g * g.transpose();  // down along the view
    const Eigen::Vector3d mixed = g.cross(inImage.normalized());
    return mixed * mixed.transpose();
  };
  // The prior's matrix for a pose and a number of bound points: isotropic, or, told which way is down, a
  // sag across that direction costs downAcross^2 times more.
  auto priorMatrix = [&](const Pose& pose, std::size_t bound) -> Eigen::Matrix3d {
    const double w = sagWeight * static_cast<double>(bound);
    if (!downKnown) return w * Eigen::Matrix3d::Identity();
    // Told which way is down, only what the outline cannot show is taken from it: the sag's part along the view,
    // relative to its part in the image (the sag across `d` in the plane of `d` and the view costs downAcross^2
    // times more). Its part across `d` in the image plane the outline shows, and another load (an instrument, a
    // retractor) may well put it there: not penalised beyond the usual prior. (Penalising every part across `d`
    // made fits worse wherever a load other than gravity pushed the organ.) Down along the view: all of it.
    const Eigen::Matrix3d acrossModel = pose.R.transpose() * downAcrossCamera() * pose.R;
    return w * (Eigen::Matrix3d::Identity() + (o.downAcross * o.downAcross - 1) * acrossModel);
  };
  auto shapeOf = [&](const Eigen::Vector3d& a) -> Eigen::VectorXd {
    return U.size() ? Eigen::VectorXd(rest + U * a) : Eigen::VectorXd(rest);
  };
  res.x = shapeOf(load);
  // One ICP iteration's update of the pose (and of the load, with the sag) on its bindings.
  auto refine = [&](const Eigen::VectorXd& x, const std::vector<Binding>& bindings, Pose& pose, Eigen::Vector3d& a) {
    if (!U.size()) {
      pose = refinePose(x, bindings, pose, views, o.sliding);
      return;
    }
    refinePoseAndSag(rest, U, bindings, views, o.sliding, pose, a, givenLoad, priorMatrix(pose, bindings.size()));
  };
  const std::size_t fewest = U.size() ? 6 : 3;  // bindings an update needs
  const RegistrationIteration first = record(0, "start", 0);
  if (res.cancelled) {
    res.status = "cancelled";
    return res;
  }
  // A short ICP run from `pose` (the shape is res.x): its end and score. Safe to run on several threads at
  // once (its own silhouettes, not the shared last one).
  struct IcpEnd {
    Pose pose;
    Eigen::Vector3d load;
    double score;
  };
  auto shortIcpHeld = [&](Pose pose, int iterations) {
    for (int k = 0; k < iterations; ++k) {
      const auto bindings = rigidBindings(silhouettesOf(res.x, pose), res.x, pose);
      if (bindings.size() < 3) break;
      pose = refinePose(res.x, bindings, pose, views, o.sliding);
    }
    return std::make_pair(pose, measure(silhouettesOf(res.x, pose), res.x, pose).score());
  };
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // the organ's centre of mass (model frame)
  for (std::size_t i = 0; i < model.nodeCount(); ++i) centre += model.rest[i] * model.lumpedMass[i];
  centre /= model.lumpedMass.sum();
  auto shortIcp = [&](Pose pose, Eigen::Vector3d a, int iterations) {
    for (int k = 0; k < iterations; ++k) {
      const Eigen::VectorXd x = shapeOf(a);
      const auto bindings = rigidBindings(silhouettesOf(x, pose), x, pose);
      if (bindings.size() < fewest) break;
      refine(x, bindings, pose, a);
    }
    const Eigen::VectorXd x = shapeOf(a);
    return IcpEnd{pose, a, measure(silhouettesOf(x, pose), x, pose).score()};
  };
  int iteration = 0;
  // The best of short ICP runs from several poses (in parallel; the first of equal ends wins).
  auto bestOf = [&](const std::vector<Pose>& starts, const Eigen::Vector3d& a, int iterations) {
    std::vector<IcpEnd> ends(starts.size());
    tbb::parallel_for(std::size_t(0), starts.size(),
                      [&](std::size_t i) { ends[i] = shortIcp(starts[i], a, iterations); });
    std::size_t best = 0;
    for (std::size_t i = 1; i < ends.size(); ++i)
      if (ends[i].score < ends[best].score) best = i;
    return ends[best];
  };
  // Twelve poses around `pose`: moved by +-distance (m) along and turned by +-degrees about each camera axis
  // (turns about the organ's centre of mass), in that order.
  auto posesAround = [&](const Pose& pose, double distance, double degrees) {
    std::vector<Pose> out;
    for (int axis = 0; axis < 3; ++axis)
      for (int sgn : {-1, 1}) {
        Pose moved = pose;
        moved.t += sgn * distance * Eigen::Vector3d::Unit(axis);
        out.push_back(moved);
        out.push_back(pose.turnedAbout(
            Eigen::AngleAxisd(sgn * degrees * M_PI / 180, Eigen::Vector3d::Unit(axis)).toRotationMatrix(),
            pose.apply(centre)));
      }
    return out;
  };
  // ICP from res.pose (pose and sag) until it settles, keeping the best; then basin hopping: short ICP
  // runs from small moves along and turns about the camera axes, a clearly better end continues (a partial
  // contour leaves shallow local minima, the outline sliding along itself). `bestMean` is the score to beat.
  auto polish = [&](double previous, double bestMean) {
    Pose bestPose = res.pose;
    Eigen::Vector3d bestLoad = load;
    for (int k = 0; k < o.rigidIterations; ++k) {
      const auto bindings = rigidBindings(silhouette(res.x, res.pose), res.x, res.pose);
      if (bindings.size() < fewest) break;
      refine(res.x, bindings, res.pose, load);
      res.x = shapeOf(load);
      const auto ri = record(++iteration, "rigid", bindings.size());
      if (ri.score() < bestMean) {
        bestMean = ri.score();
        bestPose = res.pose;
        bestLoad = load;
      }
      if (res.cancelled || std::abs(previous - ri.score()) < 0.1 * o.tolerance) break;
      previous = ri.score();
    }
    res.pose = bestPose;
    load = bestLoad;
    res.x = shapeOf(load);
    for (int round = 0; round < 3 && !res.cancelled && o.hops; ++round) {
      const IcpEnd hop = bestOf(posesAround(res.pose, o.hopDistance, o.hopDegrees), load, 3);
      if (!(hop.score < bestMean - o.tolerance)) break;
      res.pose = hop.pose;
      load = hop.load;
      res.x = shapeOf(load);
      bestMean = hop.score;
      record(++iteration, "rigid", 0);
    }
  };
  // Rigid pre-pass: the pose refined on the bindings (ICP), the shape unchanged.
  if (o.rigidPrepass || !o.elastic) {
    // A few short ICP runs from the start and from candidates that the silhouette alone suggests (the
    // projected organ's centroid moved onto the contour's, and +-15 degrees about the optical axis), to
    // stay out of the local minima of a single ICP; the best continues below.
    {
      const auto& sil = silhouette(res.x, res.pose)[0];
      Eigen::Vector2d silCentre = Eigen::Vector2d::Zero(), contourCentre = Eigen::Vector2d::Zero();
      double silLength = 0, contourLength = 0;
      for (const auto& e : sil) {
        const double l = (e.pb - e.pa).norm();
        silCentre += 0.5 * l * (e.pa + e.pb);
        silLength += l;
      }
      for (const auto& seg : contour)
        for (std::size_t i = 1; i < seg.size(); ++i) {
          const double l = (seg[i] - seg[i - 1]).norm();
          contourCentre += 0.5 * l * (seg[i] + seg[i - 1]);
          contourLength += l;
        }
      const Eigen::Vector3d organ = res.pose.apply(centre);
      std::vector<Pose> candidates{res.pose};
      if (silLength > 0 && contourLength > 0) {
        const Eigen::Vector2d shift = contourCentre / contourLength - silCentre / silLength;
        Pose moved = res.pose;
        moved.t += Eigen::Vector3d(shift.x() * organ.z() / camera.K(0, 0), shift.y() * organ.z() / camera.K(1, 1), 0);
        candidates.push_back(moved);
      }
      const std::size_t base = candidates.size();
      for (std::size_t i = 0; i < base; ++i)
        for (double deg : {-15.0, 15.0}) {
          const Eigen::Matrix3d dR = Eigen::AngleAxisd(deg * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
          candidates.push_back(candidates[i].turnedAbout(dR, candidates[i].apply(centre)));
        }
      const IcpEnd end = bestOf(candidates, load, 4);
      res.pose = end.pose;
      load = end.load;
      res.x = shapeOf(load);
    }
    double bestMean = score(res.x, res.pose);
    if (bestMean >= first.score()) {  // the candidates did not help: ICP from the start as given
      res.pose = start;
      bestMean = first.score();
      load = givenLoad;
      res.x = shapeOf(load);
    }
    polish(first.score(), bestMean);
  }
  // Does the contour determine the pose? Short rigid fits from poses spread around the result: an end that
  // fits nearly as well with the organ elsewhere is an alternative the contour cannot tell from it; one that
  // fits clearly better (by more than adoptShare) is a deeper minimum the rigid stage missed (the start was
  // in another basin): the fit continues from there (up to adoptRounds times) and is probed again.
  double probedScore = 0;  // the rigid result's, which the alternatives' are compared with
  for (int round = 0; (o.rigidPrepass || !o.elastic) && o.probeAmbiguity && !res.cancelled; ++round) {
    res.alternatives.clear();
    std::vector<Eigen::Vector3d> sample;  // up to 400 nodes, to measure how far apart two poses put the organ
    const std::size_t stride = std::max<std::size_t>(1, model.nodeCount() / 400);
    for (std::size_t i = 0; i < model.nodeCount(); i += stride) sample.push_back(res.x.segment<3>(3 * i));
    auto apart = [&](const Pose& a, const Pose& b) {
      double sum = 0;
      for (const auto& p : sample) sum += (a.apply(p) - b.apply(p)).norm();
      return sum / static_cast<double>(sample.size());
    };
    const std::vector<Pose> probes = posesAround(res.pose, o.probeDistance, o.probeDegrees);
    std::vector<std::pair<Pose, double>> ends(probes.size());
    tbb::parallel_for(std::size_t(0), probes.size(), [&](std::size_t i) {
      try {
        // The shape as fitted (the load held): an alternative is another place for the same organ.
        ends[i] = shortIcpHeld(probes[i], 6);
      } catch (const MeshError&) {
        ends[i] = {probes[i], std::numeric_limits<double>::infinity()};  // moved behind the camera: not an alternative
      }
    });
    const double resultScore = probedScore = score(res.x, res.pose);
    const double limit = std::max(resultScore + o.ambiguityPx, resultScore * (1 + o.ambiguityShare));
    std::vector<RegistrationAlternative> fitting;  // the ends that fit nearly as well, far from the result
    for (const auto& [pose, sc] : ends) {
      if (!(sc <= limit)) continue;
      const double mm = 1e3 * apart(pose, res.pose);
      if (mm > o.ambiguityMm) fitting.push_back({pose, sc, mm});
    }
    // The alternatives span that set: its far ends, the truth among or between them. The farthest from the result
    // first, then each time the one farthest from the result and from those chosen (one per place: none within
    // ambiguityMm of another), up to three.
    while (res.alternatives.size() < 3) {
      const RegistrationAlternative* next = nullptr;
      double farthest = o.ambiguityMm;
      for (const auto& f : fitting) {
        double nearest = f.apartMm;
        for (const auto& a : res.alternatives) nearest = std::min(nearest, 1e3 * apart(a.pose, f.pose));
        if (nearest > farthest) farthest = nearest, next = &f;
      }
      if (!next) break;
      res.alternatives.push_back(*next);
    }
    const auto deeper =
        std::min_element(ends.begin(), ends.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
    if (round >= o.adoptRounds || deeper == ends.end() || !(deeper->second < resultScore * (1 - o.adoptShare))) break;
    res.pose = deeper->first;
    ++res.adopted;
    polish(deeper->second, score(res.x, res.pose));
  }
  // Does the contour determine the sag? The rigid fit again with the sag's prior loosened: when the load
  // the contour alone asks for is more than twice the one found (the prior, not the contour, decided most
  // of the sag) and the two put the organ more than sagDecisiveMm apart, the contour does not show how far
  // the organ sags (typically its sagging side is not drawn), and the depth of the pose with it.
  struct {
    bool undetermined = false;
    double share = 1, apartMm = 0;
    Pose pose;
    Eigen::VectorXd x;  // where the loosened sag puts the organ (empty: not probed)
  } sagProbe;
  if (U.size() && o.probeAmbiguity && !res.cancelled) {
    Pose p = res.pose;
    Eigen::Vector3d a = load;
    for (int k = 0; k < 8; ++k) {
      const Eigen::VectorXd x = shapeOf(a);
      const auto bindings = rigidBindings(silhouettesOf(x, p), x, p);
      if (bindings.size() < fewest) break;
      refinePoseAndSag(rest, U, bindings, views, o.sliding, p, a, givenLoad,
                       priorMatrix(p, bindings.size()) / o.sagProbeLoosen);
    }
    const Eigen::VectorXd x = shapeOf(a);
    sagProbe.pose = p;
    sagProbe.x = x;
    double sum = 0;
    for (std::size_t i = 0; i < model.nodeCount(); ++i)
      sum += (p.apply(x.segment<3>(3 * i)) - res.pose.apply(res.x.segment<3>(3 * i))).norm();
    sagProbe.apartMm = 1e3 * sum / static_cast<double>(model.nodeCount());
    const double found = (load - givenLoad).norm(), alone = (a - givenLoad).norm();
    sagProbe.share = alone > 0 ? found / alone : 1.0;
    sagProbe.undetermined = sagProbe.share < o.sagDeterminedShare && sagProbe.apartMm > o.sagDecisiveMm;
    res.sagDetermined = !sagProbe.undetermined;
    res.sagShare = sagProbe.share;
    res.sagApartMm = sagProbe.apartMm;
  }
  // The bound's direction as a hypothesis the fit's far ends lie towards (RegistrationUncertainty::ends): the pose and
  // shape it moves the result (`from`) to.
  struct {
    Pose pose, fromPose;
    Eigen::VectorXd x, fromX;  // empty: none
  } toward;
  std::vector<char> facing, onSurface;
  if ((o.rigidPrepass || !o.elastic) && !res.cancelled) {
    const auto bindings = rigidBindings(silhouette(res.x, res.pose), res.x, res.pose);
    Eigen::VectorXd weakestDirection;
    // (the sag's prior loosened as its probe loosens it: the prior's scale is a choice, not a measurement)
    res.uncertainty = estimateUncertainty(
        bindings, U.size() ? rest : res.x, U, views, o.sliding, res.pose, load,
        U.size() ? Eigen::Matrix3d(priorMatrix(res.pose, bindings.size()) / o.sagProbeLoosen) : Eigen::Matrix3d::Zero(),
        model, surface, res.x, centre, facing, onSurface, weakestDirection);
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
    // The hypotheses' spread, measured where the bound speaks: over the surface facing the camera (mean) and the
    // inner nodes (largest), from the result's nodes to the hypothesis's (camera frame, mm).
    auto spreadOf = [&](const Pose& pose, const Eigen::VectorXd& x) {
      double sum = 0, inner = 0;
      std::size_t count = 0;
      for (std::size_t i = 0; i < model.nodeCount(); ++i) {
        const auto k = static_cast<Eigen::Index>(3 * i);
        const double d = 1e3 * (pose.apply(x.segment<3>(k)) - res.pose.apply(res.x.segment<3>(k))).norm();
        if (facing[i]) sum += d, ++count;
        if (!onSurface[i]) inner = std::max(inner, d);
      }
      return std::make_pair(count ? sum / static_cast<double>(count) : 0.0, inner);
    };
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
    if (res.uncertainty.computed) {
      res.uncertainty.spreadMm = spread;
      // Where the hypotheses spread more than the curvature allows, they name the weakest direction.
      if (spread > res.uncertainty.curvatureMm) {
        if (!farthest) {
          res.uncertainty.weakest = "the organ's sag";
          toward.pose = sagProbe.pose;
          toward.x = sagProbe.x;
        } else {
          toward.pose = farthest->pose;
          toward.x = res.x;
          double lever = 0;
          for (std::size_t i = 0; i < model.nodeCount(); ++i)
            lever = std::max(lever, (res.x.segment<3>(3 * static_cast<Eigen::Index>(i)) - centre).norm());
          const Eigen::AngleAxisd turn(farthest->pose.R * res.pose.R.transpose());
          res.uncertainty.weakest = describeDirection(turn.axis() * turn.angle() * lever,
                                                      farthest->pose.apply(centre) - res.pose.apply(centre), 0.0);
        }
      }
      res.uncertainty.surfaceMm += spread;
      res.uncertainty.targetMm += std::max(spreads.second, spread);
      // An estimated camera motion's uncertainty: where the estimate gives its 1-sigma motion, the pose fitted again
      // through it (held shape, short ICP, like the alternatives) and twice how far that moves the surface facing the
      // camera; else twice how far it moves the triangulated depths (a single feature's, wider than the fit's).
      std::optional<Pose> motionRefit;  // the largest motion share's refit
      for (std::size_t f = 0; f < frames.size(); ++f) {
        if (!(frames[f].motionDepthSigmaM > 0)) continue;
        double share = 2e3 * frames[f].motionDepthSigmaM;
        if (frames[f].motionAtOneSigma && measured) {
          const std::vector<detail::View> savedViews = views;
          const std::vector<SeenPoint> savedSeen = seen;
          views[f + 1].motion = *frames[f].motionAtOneSigma;
          seen = triangulateSeen();
          try {
            const Pose refit = shortIcpHeld(res.pose, 6).first;
            share = 2 * spreadOf(refit, res.x).first;
            if (share > res.uncertainty.motionMm) motionRefit = refit;
          } catch (const MeshError&) {
            share = std::numeric_limits<double>::infinity();  // the organ behind a camera: unbounded
          }
          views = savedViews;
          seen = savedSeen;
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
      // An organ the fit holds nowhere: its sag cannot be estimated (a body load on a free organ has no equilibrium)
      // and the outline of an organ sagging on its ligaments is then explained by a wrong pose, as far from the
      // truth as the sag is deep -- a bound that leaves the sag out would be a confident wrong answer. Unbounded,
      // and said, with what would bound it.
      if (!held && o.elastic && o.estimateSag) {
        res.uncertainty.surfaceMm = res.uncertainty.targetMm = std::numeric_limits<double>::infinity();
        res.uncertainty.weakest =
            "the organ's sag (no node is held: mark where the ligaments hold the organ, step 1, and the fit estimates "
            "it)";
      }
    }
  }
  if (!U.size() && downKnown)  // (an organ the fit does not hold: the told gravity is the elastic stage's)
    load = res.pose.R.transpose() * o.gravityCamera;  // the told gravity, in the frame of the pose found
  settings.gravity = load;
  res.load = load;
  const Pose rigidPose = res.pose;
  const Eigen::VectorXd rigidX = res.x;
  const double rigidMean = score(res.x, res.pose);
  if (res.cancelled) {
    res.status = "cancelled";
    return res;
  }
  const double diag = std::hypot(camera.width, camera.height);
  if (o.elastic && o.rigidPrepass && rigidMean > 0.02 * diag) {
    // No pose near the start brings the organ's outline near the contour: deforming it there would only
    // stretch it onto another shape.
    res.status =
        "failed: after the rigid fit the contour is still " + std::to_string(static_cast<int>(rigidMean)) +
        " px from the organ's silhouette on average; it may belong to another organ or the start pose is too far";
    return res;
  }
  if (!o.elastic) {
    res.ok = true;
    res.converged = true;
    res.status = "rigid fit: mean distance " + pixels(rigidMean);
  } else {
    // Elastic: bound points held on their rays (image plane only), static equilibrium, rebind, repeat.
    // Equilibrium to 10 micrometres is far below a pixel at endoscope distances (and projected Newton,
    // which the constraints often need, converges only linearly to tighter tolerances).
    if (settings.staticStepTolerance <= 0) settings.staticStepTolerance = 1e-5;
    // Each rebinding moves the organ a little: the last solve's factorisation serves the next ones.
    settings.staticChord = true;
    Integrator integrator(model, fixedNodes, settings);
    SimulationState state = integrator.initialState();
    state.x = res.x;
    double bestMean = rigidMean;
    // Converged when neither the silhouette's nor the curves' mean distance moves any more (their mixture,
    // the score, can stand still while the curves still move), or when three iterations in a row did not
    // improve on the best (rebinding can cycle between a few nearly equal states).
    RegistrationIteration previous = res.iterations.back();
    int stalled = 0;
    // Bindings further than this are outliers: as far as the start was off (so parts of the silhouette that
    // must travel are still bound), but at least 4 px and at most 2 % of the image diagonal.
    const double outlierFloor = std::clamp(rigidMean, 4.0, 0.02 * diag);
    // And a hard cap, whatever the median: after the rigid stage the drawn contour lies within a few pixels
    // of the silhouette, so a silhouette vertex much further from it is on the part of the outline that was
    // not drawn (or on an occluding fold inside it), and binding it would drag it across the organ. Such a
    // vertex is free (costs nothing); it is bound again once the deformation brings it near the contour.
    // (Without the rigid stage the start may be off by more: no cap then.)
    const double cap =
        o.rigidPrepass ? std::clamp(4 * rigidMean, 8.0, 0.02 * diag) : std::numeric_limits<double>::infinity();
    Eigen::VectorXd bestX = res.x;
    std::string failure;
    for (int k = 0; k < o.maxIterations; ++k) {
      // One binding per node: a node on the outline of two frames a short move apart would be held on two nearly
      // parallel planes, which meet far from it (the first frame's binding holds it).
      std::vector<Binding> bindings;
      std::vector<char> boundNode(model.nodeCount(), 0);
      const Silhouettes& sils = silhouette(state.x, res.pose);
      for (std::size_t v = 0; v < views.size(); ++v) {
        for (auto b : bindContour(samples[v], segmentStarts[v], sils[v], fixed, o, outlierFloor)) {
          if (boundNode[static_cast<std::size_t>(b.a)]) continue;
          boundNode[static_cast<std::size_t>(b.a)] = 1;
          b.view = static_cast<int>(v);
          bindings.push_back(b);
        }
      }
      bindings.erase(
          std::remove_if(bindings.begin(), bindings.end(), [&](const Binding& b) { return b.distance > cap; }),
          bindings.end());
      if (!curves.empty()) {
        // A node on a curve follows its curve (one binding, hence one set of ray constraints, per node).
        auto curveBindings = bindCurves(curves, state.x, res.pose, camera, &fixed);
        dropOutliers(curveBindings, o.outlierFactor, outlierFloor);
        std::vector<char> onCurve(model.nodeCount(), 0);
        for (const auto& b : curveBindings) onCurve[b.a] = 1;
        bindings.erase(std::remove_if(bindings.begin(), bindings.end(),
                                      [&](const Binding& b) { return b.view == 0 && onCurve[b.a] != 0; }),
                       bindings.end());
        bindings.insert(bindings.end(), curveBindings.begin(), curveBindings.end());
      }
      if (bindings.size() < 3) {
        failure = "no part of the contour could be bound to the organ's silhouette (" +
                  std::to_string(bindings.size()) +
                  " points); the contour may belong to another organ or lie outside the organ's view";
        break;
      }
      std::vector<ScalarConstraint> cs;
      for (const auto& b : bindings) {
        const detail::View& v = views[static_cast<std::size_t>(b.view)];
        rayConstraints(b, detail::viewPose(v, res.pose), v.camera, o.sliding, cs);
      }
      integrator.setConstraints(cs);
      const SimulationState before = state;
      const StepReport rep = integrator.solveStatic(state);
      if (!rep.ok) {
        state = before;
        failure = "the elastic solve did not converge (" + rep.status + ")";
        break;
      }
      res.x = state.x;
      const auto ri = record(++iteration, "elastic", bindings.size());
      stalled = ri.score() < bestMean - o.tolerance ? 0 : stalled + 1;
      if (ri.score() < bestMean) {
        bestMean = ri.score();
        bestX = res.x;
      }
      if (res.cancelled) break;
      if ((std::abs(previous.residual.mean - ri.residual.mean) < o.tolerance &&
           std::abs(previous.curves.mean - ri.curves.mean) < o.tolerance) ||
          stalled >= 3) {
        res.converged = true;
        break;
      }
      previous = ri;
    }
    res.x = bestX;
    if (res.cancelled) {
      res.status = "cancelled; the best result so far is kept";
      res.ok = true;
    } else if (bestMean >= rigidMean && iteration > 0 && failure.empty()) {
      res.x = rigidX;
      res.pose = rigidPose;
      res.ok = true;
      res.status = "the elastic fit did not improve on the rigid start (" + pixels(rigidMean) + "); the start is kept";
    } else if (!failure.empty() && bestMean >= rigidMean) {
      res.ok = false;
      res.status = "failed: " + failure;
    } else {
      res.ok = true;
      res.status = (res.converged     ? "converged"
                    : failure.empty() ? "not converged in " + std::to_string(o.maxIterations) + " iterations"
                                      : "stopped: " + failure) +
                   ": mean distance " + pixels(bestMean) + " (start " + pixels(first.score()) + ")";
    }
  }
  // A fit that still leaves the contour far from the organ did not find it.
  const double finalMean = score(res.x, res.pose);
  if (res.ok && finalMean > 0.02 * diag) {
    res.ok = false;
    res.status =
        "failed: the contour stays " + std::to_string(static_cast<int>(finalMean)) +
        " px from the organ's silhouette on average; it may belong to another organ or the start pose is too far";
  }
  // Nor did one that leaves most of the contour off the silhouette (the outline of another organ, reached
  // only in part by stretching this one).
  if (res.ok && points > 1) {
    const double nearPx = std::max(8.0, 0.01 * diag);
    const Silhouettes& sils = silhouette(res.x, res.pose);
    std::size_t near = 0, all = 0;
    for (std::size_t v = 0; v < views.size(); ++v) {
      const SilhouetteGrid grid(sils[v]);
      for (const auto& seg : *contours[v])
        for (const auto& p : seg) near += grid.distance(p) <= nearPx, ++all;
    }
    const double share = static_cast<double>(near) / static_cast<double>(all);
    if (share < 0.5) {
      res.ok = false;
      res.status = "failed: after the fit only " + std::to_string(static_cast<int>(100 * share)) +
                   " % of the contour lies within " + std::to_string(static_cast<int>(nearPx)) +
                   " px of the organ's silhouette; it may belong to another organ or the start pose is too far";
    }
  }
  // The far ends of where the organ may be: the result moved each way towards the bound's hypothesis (its turn and move
  // scaled by k about the result's pose, its shape change by k), k such that the surface facing the camera moves by the
  // bound on average (three fixed-point steps each way: the move is nearly proportional to k).
  if (res.ok && res.uncertainty.computed && std::isfinite(res.uncertainty.surfaceMm) &&
      toward.x.size() == res.x.size() && toward.fromX.size() == res.x.size() && facing.size() == model.nodeCount()) {
    // (turned about the organ's centre, which moves as the hypothesis moves it: a turn about the camera would move a
    // far organ by its second order too, unevenly each way)
    const Eigen::AngleAxisd full(toward.pose.R * toward.fromPose.R.transpose());
    const Eigen::Vector3d move = toward.pose.apply(centre) - toward.fromPose.apply(centre);
    const Eigen::Vector3d pivot = res.pose.apply(centre);
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
  const bool beyondTolerance = res.uncertainty.computed && !(res.uncertainty.surfaceMm <= o.toleranceMm);
  if (res.ok && (!res.alternatives.empty() || sagProbe.undetermined || beyondTolerance)) {
    // Say which alternatives, and what would decide: the stretch of the organ's outline that no contour
    // covers (named by where it lies on the organ), or a curve on the organ when the outline is whole.
    res.ambiguous = true;
    char text[320];
    if (res.alternatives.empty() && !sagProbe.undetermined) {
      if (std::isfinite(res.uncertainty.surfaceMm))
        std::snprintf(text, sizeof text,
                      "ambiguous: the surface may be up to %.1f mm from where the fit put it, more than the %.1f mm "
                      "asked for (weakest: %s)",
                      res.uncertainty.surfaceMm, o.toleranceMm, res.uncertainty.weakest.c_str());
      else
        std::snprintf(text, sizeof text, "ambiguous: the contour does not determine %s",
                      res.uncertainty.weakest.c_str());
    } else if (res.alternatives.empty()) {
      std::snprintf(text, sizeof text,
                    "ambiguous: the contour does not show how far the organ sags (the sag found is %.0f %% of what the "
                    "contour alone asks for, "
                    "and the two put the organ %.1f mm apart)",
                    100 * sagProbe.share, sagProbe.apartMm);
    } else if (res.alternatives.size() == 1) {
      const auto& alt = res.alternatives.front();
      // "Nearly as well" only when it does fit worse: one that fits slightly better (below the margin the fit adopts
      // another pose by) is said so, never presented as the lesser.
      std::snprintf(text, sizeof text,
                    "ambiguous: another pose %.0f mm away fits the contour %s the rigid fit (%.2f px against %.2f px)",
                    alt.apartMm, alt.score < probedScore ? "slightly better than" : "nearly as well as", alt.score,
                    probedScore);
    } else {
      const auto& alt = *std::min_element(res.alternatives.begin(), res.alternatives.end(),
                                          [](const auto& a, const auto& b) { return a.score < b.score; });
      double nearest = alt.apartMm, farthest = alt.apartMm;
      for (const auto& a : res.alternatives)
        nearest = std::min(nearest, a.apartMm), farthest = std::max(farthest, a.apartMm);
      std::snprintf(text, sizeof text,
                    "ambiguous: %zu other poses, %.0f to %.0f mm away, fit the contour %s the rigid fit (the best %.2f "
                    "px against %.2f px)",
                    res.alternatives.size(), nearest, farthest,
                    alt.score < probedScore ? "as well as or slightly better than" : "nearly as well as", alt.score,
                    probedScore);
    }
    std::string decide;
    // What one outline cannot give at all: the depth's parallax.
    const std::string secondFrame = views.size() == 1 ? ", or a second frame with the scope moved 1-2 cm sideways" : "";
    const auto& sil = silhouette(res.x, res.pose)[0];
    Eigen::Vector2d all = Eigen::Vector2d::Zero(), open = Eigen::Vector2d::Zero();
    double allLength = 0, openLength = 0;
    const double gapPx = std::max(10.0, 0.01 * diag);
    for (const auto& e : sil) {
      const double l = (e.pb - e.pa).norm();
      const Eigen::Vector2d mid = e.pm;
      all += l * mid;
      allLength += l;
      double nearest = std::numeric_limits<double>::infinity();
      for (const auto& seg : contour)
        for (const auto& p : seg) nearest = std::min(nearest, (p - mid).norm());
      if (nearest > gapPx) open += l * mid, openLength += l;
    }
    if (allLength > 0 && openLength > 0.1 * allLength) {
      const Eigen::Vector2d d = open / openLength - all / allLength;
      const char* vertical = d.y() < -0.4 * d.norm() ? "upper " : d.y() > 0.4 * d.norm() ? "lower " : "";
      const char* horizontal = d.x() < -0.4 * d.norm() ? "left" : d.x() > 0.4 * d.norm() ? "right" : "";
      std::string where = std::string(vertical) + horizontal;
      if (where.empty()) where = "undrawn";
      if (where.back() == ' ') where.pop_back();
      if (where == "upper") where = "top";
      if (where == "lower") where = "bottom";
      decide = "; the contour along the organ's " + where + " side (" +
               std::to_string(static_cast<int>(100 * openLength / allLength)) +
               " % of its outline is not drawn), a ridge or ligament curve" + secondFrame + ", would decide it";
    } else {
      decide = "; a ridge or ligament curve drawn on the organ (step 3)" + secondFrame + " would decide it";
    }
    // (an organ held nowhere: the attachments decide first; its weakest direction says so)
    if (!held && o.elastic && o.estimateSag && res.alternatives.empty() && !sagProbe.undetermined &&
        !std::isfinite(res.uncertainty.surfaceMm))
      decide.clear();
    res.status = text + decide + " (the fit: " + res.status + ")";
  }
  if (!setAside.empty()) res.status += "; " + setAside;
  res.setAsideFrames = setAsideFrames;
  return res;
}

}  // namespace rehearse::simcore
