// The registration's elastic stage: the bound points held on their rays (image plane only), static equilibrium,
// rebind, repeat; its status; and the final checks any fit must pass (the contour near the organ's silhouette).
#include "contour_registration.hpp"
#include <rehearse/simcore/words.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

namespace rehearse::simcore::detail {
namespace {
// An element crushed below this share of its rest volume (or turned inside out) is a shape the organ cannot take: the
// simulation's steps keep every element above it (Integrator's inversion floor), and the case refuses a flat one.
constexpr double kCrushedVolume = 0.01;

// The elements of shape x below kCrushedVolume of their rest volume.
std::vector<int> crushedElements(const FemModel& model, const Eigen::VectorXd& x) {
  std::vector<int> out;
  for (std::size_t e = 0; e < model.tets.size(); ++e) {
    const auto& t = model.tets[e];
    auto at = [&](int k) { return x.segment<3>(3 * static_cast<Eigen::Index>(t[static_cast<std::size_t>(k)])); };
    auto rest = [&](int k) { return model.rest[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])]; };
    Eigen::Matrix3d now, was;
    for (int k = 0; k < 3; ++k) now.col(k) = at(k + 1) - at(0), was.col(k) = rest(k + 1) - rest(0);
    const double J = now.determinant() / was.determinant();
    if (!(J >= kCrushedVolume)) out.push_back(static_cast<int>(e));
  }
  return out;
}
}  // namespace

// The elastic stage's bindings for the shape x (the pose is res.pose): the contour onto the silhouette's vertices,
// outliers beyond `outlierFloor` (as dropOutliers) and `cap` dropped, the curves' nodes onto their image curves.
std::vector<Binding> ContourRegistration::elasticBindings(const Eigen::VectorXd& x, double outlierFloor, double cap) {
  // One binding per node: a node on the outline of two frames a short move apart would be held on two nearly
  // parallel planes, which meet far from it (the first frame's binding holds it).
  std::vector<Binding> bindings;
  std::vector<char> boundNode(model.nodeCount(), 0);
  const Silhouettes& sils = silhouette(x, res.pose);
  for (std::size_t v = 0; v < problem.views.size(); ++v) {
    for (auto b : bindContour(problem.samples[v], problem.segmentStarts[v], sils[v], problem.fixed, o, outlierFloor)) {
      if (boundNode[static_cast<std::size_t>(b.a)]) continue;
      boundNode[static_cast<std::size_t>(b.a)] = 1;
      b.view = static_cast<int>(v);
      bindings.push_back(b);
    }
  }
  bindings.erase(std::remove_if(bindings.begin(), bindings.end(), [&](const Binding& b) { return b.distance > cap; }),
                 bindings.end());
  if (!problem.curves.empty()) {
    // A node on a curve follows its curve (one binding, hence one set of ray constraints, per node).
    auto curveBindings = bindCurves(problem.curves, x, res.pose, camera, &problem.fixed);
    dropOutliers(curveBindings, o.outlierFactor, outlierFloor);
    std::vector<char> onCurve(model.nodeCount(), 0);
    for (const auto& b : curveBindings) onCurve[b.a] = 1;
    bindings.erase(std::remove_if(bindings.begin(), bindings.end(),
                                  [&](const Binding& b) { return b.view == 0 && onCurve[b.a] != 0; }),
                   bindings.end());
    bindings.insert(bindings.end(), curveBindings.begin(), curveBindings.end());
  }
  return bindings;
}

// Elastic: bound points held on their rays (image plane only), static equilibrium, rebind, repeat.
void ContourRegistration::elasticStage(const RigidEnd& rigid) {
  const double rigidMean = rigid.mean, diag = problem.diag;
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
  // Nodes whose binding crushed the tissue: not bound again. A binding pulls one surface node onto its ray, whatever
  // lies in the way; where the contour is not this organ's outline there (a hand's stroke off the organ, a fold), it
  // pulled nodes through their neighbours: a person's contour on the patient liver, fitted without attachments, turned
  // 2-3 elements inside out, or left 2 flat and the fit refused.
  std::vector<char> unbound(model.nodeCount(), 0);
  std::string crushedStop;
  for (int k = 0; k < o.maxIterations; ++k) {
    std::vector<Binding> bindings = elasticBindings(state.x, outlierFloor, cap);
    bindings.erase(std::remove_if(bindings.begin(), bindings.end(),
                                  [&](const Binding& b) { return unbound[static_cast<std::size_t>(b.a)] != 0; }),
                   bindings.end());
    if (bindings.size() < 3) {
      failure = "no part of the contour could be bound to the organ's silhouette (" +
                std::to_string(bindings.size()) +
                " points); the contour may belong to another organ or lie outside the organ's view";
      break;
    }
    std::vector<ScalarConstraint> cs;
    for (const auto& b : bindings) {
      const View& v = problem.views[static_cast<std::size_t>(b.view)];
      rayConstraints(b, viewPose(v, res.pose), v.camera, o.sliding, cs);
    }
    integrator.setConstraints(cs);
    const SimulationState before = state;
    const StepReport rep = integrator.solveStatic(state);
    if (!rep.ok) {
      state = before;
      failure = "the elastic solve did not converge (" + rep.status + ")";
      break;
    }
    if (const std::vector<int> crushed = crushedElements(model, state.x); !crushed.empty()) {
      // The bound nodes of the crushed elements are let go, or failing any, those of the elements beside them; the
      // iteration is taken again from where it started without them.
      std::vector<char> near(model.nodeCount(), 0);
      for (int e : crushed)
        for (int n : model.tets[static_cast<std::size_t>(e)]) near[static_cast<std::size_t>(n)] = 1;
      auto letGo = [&] {
        int released = 0;
        for (const auto& b : bindings)
          if (near[static_cast<std::size_t>(b.a)] && !unbound[static_cast<std::size_t>(b.a)])
            unbound[static_cast<std::size_t>(b.a)] = 1, ++released;
        return released;
      };
      int released = letGo();
      if (released == 0) {
        std::vector<char> ring = near;
        for (const auto& t : model.tets) {
          bool touches = false;
          for (int n : t) touches = touches || near[static_cast<std::size_t>(n)];
          if (touches)
            for (int n : t) ring[static_cast<std::size_t>(n)] = 1;
        }
        near = ring;
        released = letGo();
      }
      state = before;
      if (released == 0) {  // (not met in the cases measured) the best shape before it stands, said so
        crushedStop = "; it stopped where it crushed " + quantity(crushed.size(), "element", "elements") +
                      " with no binding beside them to let go";
        break;
      }
      continue;
    }
    res.x = state.x;
    const auto ri = record(++current.iteration, "elastic", bindings.size());
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
  elasticStatus(rigid, bestMean, failure);
  if (const auto let = std::count(unbound.begin(), unbound.end(), 1); let > 0)
    res.status += "; " + quantity(static_cast<std::size_t>(let), "silhouette node", "silhouette nodes") +
                  " left free where binding them crushed the tissue";
  res.status += crushedStop;
}

// The elastic stage's outcome: cancelled, no better than the rigid start (which is kept), failed, or its best.
void ContourRegistration::elasticStatus(const RigidEnd& rigid, double bestMean, const std::string& failure) {
  const double rigidMean = rigid.mean;
  if (res.cancelled) {
    res.status = "cancelled; the best result so far is kept";
    res.ok = true;
  } else if (bestMean >= rigidMean && current.iteration > 0 && failure.empty()) {
    res.x = rigid.x;
    res.pose = rigid.pose;
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
                 ": mean distance " + pixels(bestMean) + " (start " + pixels(current.first.score()) + ")";
  }
}

// A fit that still leaves the contour far from the organ did not find it.
void ContourRegistration::checkFinalFit() {
  const double diag = problem.diag;
  const double finalMean = score(res.x, res.pose);
  if (res.ok && finalMean > 0.02 * diag) {
    res.ok = false;
    res.status =
        "failed: the contour stays " + std::to_string(static_cast<int>(finalMean)) +
        " px from the organ's silhouette on average; it may belong to another organ or the start pose is too far";
  }
  // Nor did one that leaves most of the contour off the silhouette (the outline of another organ, reached
  // only in part by stretching this one).
  if (res.ok && problem.points > 1) {
    const double nearPx = std::max(8.0, 0.01 * diag);
    const Silhouettes& sils = silhouette(res.x, res.pose);
    std::size_t near = 0, all = 0;
    for (std::size_t v = 0; v < problem.views.size(); ++v) {
      const SilhouetteGrid grid(sils[v]);
      for (const auto& seg : *problem.contours[v])
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
}

}  // namespace rehearse::simcore::detail
