// The registration's rigid stage: the pose (and the load, with the sag) refined on the bindings by ICP, from the best
// of a few candidate starts, then basin hopping; and the short ICP runs the ambiguity probes and the bound reuse.
#include "contour_registration.hpp"

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace rehearse::simcore::detail {

// Correspondences for the pose (the shape is x): the contour onto the silhouette's edges, the curves' nodes onto
// their image curves, the seen points onto the surface.
std::vector<Binding> ContourRegistration::rigidBindings(const Silhouettes& sil, const Eigen::VectorXd& x,
                                                        const Pose& pose) const {
  std::vector<Binding> b;
  for (std::size_t v = 0; v < problem.views.size(); ++v) {
    auto one = bindForRigid(problem.samples[v], sil[v], o);
    for (auto& binding : one) binding.view = static_cast<int>(v);
    b.insert(b.end(), one.begin(), one.end());
  }
  const auto c = bindCurves(problem.curves, x, pose, camera, nullptr);
  b.insert(b.end(), c.begin(), c.end());
  auto p = bindPoints(problem.seen, surface, x, pose, camera);
  if (!p.empty() && b.size() > 6) {
    // The two kinds weighed by what each is worth: a seen point by its depth's noise (the tracker's, in both
    // frames), a contour point by the outline's misfit over its correlation length (the model's error, not noise,
    // is what mostly remains along an outline).
    std::vector<double> r;
    static const Eigen::MatrixXd none;
    detail::poseSagInformation(x, none, b, problem.views, o.sliding, pose, Eigen::Vector3d::Zero(),
                               Eigen::Matrix3d::Zero(), r);
    double sum2 = 0;
    for (double v : r) sum2 += v * v;
    const double contourSigma =
        std::sqrt(std::max(sum2 / static_cast<double>(r.size()), 0.01) * autocorrelationTime(r));
    const double pointSigma = std::sqrt(2.0) * std::max(o.trackNoisePx, 0.05);
    for (auto& binding : p) binding.pxPerMetre *= contourSigma / pointSigma;
  }
  b.insert(b.end(), p.begin(), p.end());
  return b;
}

// One ICP iteration's update of the pose (and of the load, with the sag) on its bindings.
void ContourRegistration::refine(const Eigen::VectorXd& x, const std::vector<Binding>& bindings, Pose& pose,
                                 Eigen::Vector3d& a) const {
  if (!sag.U.size()) {
    pose = refinePose(x, bindings, pose, problem.views, o.sliding);
    return;
  }
  refinePoseAndSag(sag.rest, sag.U, bindings, problem.views, o.sliding, pose, a, sag.givenLoad,
                   priorMatrix(pose, bindings.size()));
}

// A short ICP run of the pose alone from `pose` (the shape is res.x): its end and score. Safe to run on several
// threads at once (its own silhouettes, not the shared last one).
std::pair<Pose, double> ContourRegistration::shortIcpHeld(Pose pose, int iterations) const {
  for (int k = 0; k < iterations; ++k) {
    const auto bindings = rigidBindings(silhouettesOf(res.x, pose), res.x, pose);
    if (bindings.size() < 3) break;
    pose = refinePose(res.x, bindings, pose, problem.views, o.sliding);
  }
  return std::make_pair(pose, measure(silhouettesOf(res.x, pose), res.x, pose).score());
}

// A short ICP run from `pose` and the load a (pose and sag): its end and score. Safe to run on several threads at
// once, as shortIcpHeld.
ContourRegistration::IcpEnd ContourRegistration::shortIcp(Pose pose, Eigen::Vector3d a, int iterations) const {
  for (int k = 0; k < iterations; ++k) {
    const Eigen::VectorXd x = shapeOf(a);
    const auto bindings = rigidBindings(silhouettesOf(x, pose), x, pose);
    if (bindings.size() < sag.fewest) break;
    refine(x, bindings, pose, a);
  }
  const Eigen::VectorXd x = shapeOf(a);
  return IcpEnd{pose, a, measure(silhouettesOf(x, pose), x, pose).score()};
}

// The best of short ICP runs from several poses (in parallel; the first of equal ends wins).
ContourRegistration::IcpEnd ContourRegistration::bestOf(const std::vector<Pose>& starts, const Eigen::Vector3d& a,
                                                        int iterations) const {
  std::vector<IcpEnd> ends(starts.size());
  tbb::parallel_for(std::size_t(0), starts.size(),
                    [&](std::size_t i) { ends[i] = shortIcp(starts[i], a, iterations); });
  std::size_t best = 0;
  for (std::size_t i = 1; i < ends.size(); ++i)
    if (ends[i].score < ends[best].score) best = i;
  return ends[best];
}

// Twelve poses around `pose`: moved by +-distance (m) along and turned by +-degrees about each camera axis
// (turns about the organ's centre of mass), in that order.
std::vector<Pose> ContourRegistration::posesAround(const Pose& pose, double distance, double degrees) const {
  std::vector<Pose> out;
  for (int axis = 0; axis < 3; ++axis)
    for (int sgn : {-1, 1}) {
      Pose moved = pose;
      moved.t += sgn * distance * Eigen::Vector3d::Unit(axis);
      out.push_back(moved);
      out.push_back(pose.turnedAbout(
          Eigen::AngleAxisd(sgn * degrees * M_PI / 180, Eigen::Vector3d::Unit(axis)).toRotationMatrix(),
          pose.apply(problem.centre)));
    }
  return out;
}

// ICP from res.pose (pose and sag) until it settles, keeping the best; then basin hopping: short ICP
// runs from small moves along and turns about the camera axes, a clearly better end continues (a partial
// contour leaves shallow local minima, the outline sliding along itself). `bestMean` is the score to beat.
void ContourRegistration::polish(double previous, double bestMean) {
  Eigen::Vector3d& load = current.load;
  Pose bestPose = res.pose;
  Eigen::Vector3d bestLoad = load;
  for (int k = 0; k < o.rigidIterations; ++k) {
    const auto bindings = rigidBindings(silhouette(res.x, res.pose), res.x, res.pose);
    if (bindings.size() < sag.fewest) break;
    refine(res.x, bindings, res.pose, load);
    res.x = shapeOf(load);
    const auto ri = record(++current.iteration, "rigid", bindings.size());
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
    record(++current.iteration, "rigid", 0);
  }
}

// Candidate starts that the silhouette alone suggests: the start, the projected organ's centroid moved onto the
// contour's, and +-15 degrees about the optical axis from each.
std::vector<Pose> ContourRegistration::startCandidates() {
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
  const Eigen::Vector3d organ = res.pose.apply(problem.centre);
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
      candidates.push_back(candidates[i].turnedAbout(dR, candidates[i].apply(problem.centre)));
    }
  return candidates;
}

// Rigid pre-pass: the pose refined on the bindings (ICP), the shape unchanged (but for the sag).
void ContourRegistration::rigidStage() {
  // A few short ICP runs from the start and from candidates that the silhouette alone suggests (the
  // projected organ's centroid moved onto the contour's, and +-15 degrees about the optical axis), to
  // stay out of the local minima of a single ICP; the best continues below.
  const IcpEnd end = bestOf(startCandidates(), current.load, 4);
  res.pose = end.pose;
  current.load = end.load;
  res.x = shapeOf(current.load);
  const RegistrationIteration& first = current.first;
  double bestMean = score(res.x, res.pose);
  if (bestMean >= first.score()) {  // the candidates did not help: ICP from the start as given
    res.pose = start;
    bestMean = first.score();
    current.load = sag.givenLoad;
    res.x = shapeOf(current.load);
  }
  polish(first.score(), bestMean);
}

}  // namespace rehearse::simcore::detail
