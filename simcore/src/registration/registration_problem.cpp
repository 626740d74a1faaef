// The registration's problem (its first stage): the frames (an estimated motion too uncertain sets its frame aside),
// the features seen in two frames triangulated, the contours and anatomical curves checked and resampled, the held
// nodes; and how a state (shape and pose) is measured against it: its silhouettes, its distances, an iteration
// recorded.
#include "contour_registration.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rehearse::simcore::detail {

ContourRegistration::ContourRegistration(const FemModel& model, const std::vector<int>& fixedNodes,
                                         const SimulationSettings& settings,
                                         const std::vector<std::array<int, 3>>& surface,
                                         const ContourSegments& contour, const Pose& start, const Pinhole& camera,
                                         const RegistrationOptions& o)
    : t0(std::chrono::steady_clock::now()),
      model(model),
      fixedNodes(fixedNodes),
      settings(settings),
      surface(surface),
      contour(contour),
      start(start),
      camera(camera),
      o(o) {}

double ContourRegistration::elapsedMs() const {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void ContourRegistration::setUpProblem() {
  setUpFrames();
  problem.seen = triangulateSeen();
  checkContours();
  sampleContours();
  for (std::size_t i = 0; i < model.nodeCount(); ++i) problem.centre += model.rest[i] * model.lumpedMass[i];
  problem.centre /= model.lumpedMass.sum();
  problem.diag = std::hypot(camera.width, camera.height);
}

void ContourRegistration::setUpFrames() {
  checkCamera(camera);
  // The frames: the first's camera and contour, then the further ones'.
  problem.views = std::vector<View>{{camera, Pose{}}};
  problem.contours = std::vector<const ContourSegments*>{&contour};
  // A frame whose estimated motion leaves the depth more uncertain than the tolerance is set aside (said in the
  // status): through it, its outline and features would drag the fit by as much (a 0.6 degree turn error put the
  // sagged liver of test_registration 50 mm off), where the first frame alone does better.
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
      problem.setAside += std::string(problem.setAside.empty() ? "" : "; ") + text;
      problem.setAsideFrames.push_back(static_cast<int>(i));
      continue;
    }
    problem.frames.push_back(f);
  }
  for (const auto& f : problem.frames) {
    problem.views.push_back({f.camera, f.motion});
    problem.contours.push_back(&f.contour);
  }
}

// The features tracked into further frames, triangulated through the views' motions (rays passing more than 3 px
// apart: a mismatch, dropped).
std::vector<SeenPoint> ContourRegistration::triangulateSeen() const {
  std::vector<SeenPoint> out;
  for (std::size_t f = 0; f < problem.frames.size(); ++f) {
    const auto& frame = problem.frames[f];
    const Pose& motion = problem.views[f + 1].motion;
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
}

// Every frame's contour and the anatomical curves checked (MeshError when unusable); the curves' image curves
// resampled like the contour.
void ContourRegistration::checkContours() {
  // Points further than this from the image are not a sketch of it (and resampling them would take forever).
  const double farPx = 100.0 * std::max(camera.width, camera.height);
  auto farAway = [&](const Eigen::Vector2d& p) { return p.cwiseAbs().maxCoeff() > farPx; };
  for (const auto& seg : contour) {
    problem.points += seg.size();
    for (const auto& p : seg) {
      if (!p.allFinite()) throw MeshError("The contour has a point that is not a number.");
      if (farAway(p))
        throw MeshError("The contour has points far outside the image; check that it belongs to this frame.");
    }
  }
  for (std::size_t v = 1; v < problem.contours.size(); ++v) {
    std::size_t count = 0;
    for (const auto& seg : *problem.contours[v]) {
      count += seg.size();
      for (const auto& p : seg)
        if (!p.allFinite() || farAway(p))
          throw MeshError("The outline on frame " + std::to_string(v + 1) +
                          " has a point that is not a number or lies far outside the image.");
    }
    if (count < 2) throw MeshError("The outline on frame " + std::to_string(v + 1) + " is empty; sketch it first.");
  }
  // Anatomical curves: checked, and their image curves resampled like the contour.
  std::vector<AnatomicalCurve>& curves = problem.curves;
  curves = o.curves;
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
  const std::size_t points = problem.points;
  if (points == 0 && curves.empty()) throw MeshError("The contour is empty; sketch the organ's outline first.");
  if (points == 1 && curves.empty())
    throw MeshError("The contour has a single point; sketch at least a short stretch of the outline.");
  if (surface.empty()) throw MeshError("The organ has no surface triangles.");
}

// The held nodes, and each frame's contour samples with its segments' starts among them.
void ContourRegistration::sampleContours() {
  problem.fixed.assign(model.nodeCount(), 0);
  for (int f : fixedNodes)
    if (f >= 0 && static_cast<std::size_t>(f) < problem.fixed.size()) problem.fixed[f] = 1;
  problem.held = std::find(problem.fixed.begin(), problem.fixed.end(), 1) != problem.fixed.end();
  problem.segmentStarts.resize(problem.views.size());
  problem.samples.resize(problem.views.size());
  for (std::size_t v = 0; v < problem.views.size(); ++v)
    for (const auto& seg : *problem.contours[v]) {
      const auto one = contourSamples({seg}, o.spacing);
      if (one.size() < 2) continue;
      problem.segmentStarts[v].push_back(problem.samples[v].size());
      problem.samples[v].insert(problem.samples[v].end(), one.begin(), one.end());
    }
}

// The organ's silhouette in every frame.
Silhouettes ContourRegistration::silhouettesOf(const Eigen::VectorXd& x, const Pose& pose) const {
  Silhouettes out;
  for (const auto& v : problem.views) out.push_back(visibleSilhouette(surface, x, viewPose(v, pose), v.camera));
  return out;
}

// The silhouettes of x and pose, from the last state's when it is the same.
const Silhouettes& ContourRegistration::silhouette(const Eigen::VectorXd& x, const Pose& pose) {
  if (!(last.valid && last.x == x && last.pose.R == pose.R && last.pose.t == pose.t)) {
    last.edges = silhouettesOf(x, pose);
    last.x = x;
    last.pose = pose;
    last.valid = true;
  }
  return last.edges;
}

// The distances of the silhouette contour and of the curves, for a shape, a pose and its silhouette.
RegistrationIteration ContourRegistration::measure(const Silhouettes& sil, const Eigen::VectorXd& x,
                                                   const Pose& pose) const {
  RegistrationIteration r;
  r.residual = contourResidual(contour, sil[0]);
  for (std::size_t v = 1; v < problem.views.size(); ++v) {  // all frames' distances as one (means weighted by points)
    const Residual2D more = contourResidual(*problem.contours[v], sil[v]);
    const std::size_t n = r.residual.points + more.points;
    if (n == 0) continue;
    r.residual.mean = (r.residual.mean * r.residual.points + more.mean * more.points) / n;
    r.residual.rms =
        std::sqrt((r.residual.rms * r.residual.rms * r.residual.points + more.rms * more.rms * more.points) / n);
    r.residual.hausdorff = std::max(r.residual.hausdorff, more.hausdorff);
    r.residual.points = n;
  }
  r.curves = curveResidual(problem.curves, x, pose, camera);
  if (!problem.seen.empty()) {
    ResidualSum sum;
    for (const auto& b : bindPoints(problem.seen, surface, x, pose, camera))
      sum.add(std::abs(b.pxPerMetre * (pose.R * b.surfaceNormal).dot(pose.apply(x.segment<3>(3 * b.a)) - b.target)));
    r.points = sum.result();
  }
  return r;
}

// The result's state measured and recorded as an iteration (onIteration told; false cancels).
RegistrationIteration ContourRegistration::record(int it, const char* stage, std::size_t bound) {
  RegistrationIteration ri = measure(silhouette(res.x, res.pose), res.x, res.pose);
  ri.iteration = it;
  ri.stage = stage;
  ri.bound = bound;
  ri.wallMs = elapsedMs();
  res.iterations.push_back(ri);
  if (o.onIteration && !o.onIteration(ri, res.x, res.pose)) res.cancelled = true;
  return ri;
}

// The mean distance over the silhouette contour and the curves, for a shape and a pose.
double ContourRegistration::score(const Eigen::VectorXd& x, const Pose& pose) {
  return measure(silhouette(x, pose), x, pose).score();
}

}  // namespace rehearse::simcore::detail
