// The registration's ambiguity: does the contour determine the pose? Short rigid fits from poses spread around the
// result name the alternatives that fit nearly as well elsewhere (or adopt a deeper minimum the rigid stage missed);
// and, at the end, an ambiguous fit's status: which alternatives, or how far the bound goes, and what would decide.
#include "contour_registration.hpp"

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace rehearse::simcore::detail {

// Does the contour determine the pose? Short rigid fits from poses spread around the result: an end that
// fits nearly as well with the organ elsewhere is an alternative the contour cannot tell from it; one that
// fits clearly better (by more than adoptShare) is a deeper minimum the rigid stage missed (the start was
// in another basin): the fit continues from there (up to adoptRounds times) and is probed again.
void ContourRegistration::probePoses() {
  for (int round = 0; !res.cancelled; ++round) {
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
    const double resultScore = current.probedScore = score(res.x, res.pose);
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
}

// An ambiguous fit's status: which alternatives, or the sag, or the bound beyond the tolerance, and what would decide
// it.
void ContourRegistration::sayAmbiguity() {
  const bool beyondTolerance = res.uncertainty.computed && !(res.uncertainty.surfaceMm <= o.toleranceMm);
  if (!(res.ok && (!res.alternatives.empty() || sagProbe.undetermined || beyondTolerance))) return;
  // Say which alternatives, and what would decide: the stretch of the organ's outline that no contour
  // covers (named by where it lies on the organ), or a curve on the organ when the outline is whole.
  res.ambiguous = true;
  const std::string text = ambiguityText();
  const std::string decide = whatWouldDecide();
  res.status = text + decide + " (the fit: " + res.status + ")";
}

// Which alternatives make the fit ambiguous (or the sag, or the bound).
std::string ContourRegistration::ambiguityText() const {
  const double probedScore = current.probedScore;
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
  return text;
}

// What would decide an ambiguous fit: the contour along the stretch of the organ's outline that is not drawn, or a
// curve on the organ, or a second frame.
std::string ContourRegistration::whatWouldDecide() {
  std::string decide;
  // What one outline cannot give at all: the depth's parallax.
  const std::string secondFrame =
      problem.views.size() == 1 ? ", or a second frame with the scope moved 1-2 cm sideways" : "";
  const auto& sil = silhouette(res.x, res.pose)[0];
  Eigen::Vector2d all = Eigen::Vector2d::Zero(), open = Eigen::Vector2d::Zero();
  double allLength = 0, openLength = 0;
  const double gapPx = std::max(10.0, 0.01 * problem.diag);
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
  if (!problem.held && o.elastic && o.estimateSag && res.alternatives.empty() && !sagProbe.undetermined &&
      !std::isfinite(res.uncertainty.surfaceMm))
    decide.clear();
  return decide;
}

}  // namespace rehearse::simcore::detail
