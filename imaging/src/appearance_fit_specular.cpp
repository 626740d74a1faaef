// fitAppearance's stage 3: the specular lobe (ks and the roughness) on the frame itself, the light and kd refined
// with them, and the ks of channels clipped at the highlight (appearance_fit_stages.hpp).
#include "appearance_fit_stages.hpp"

#include <opencv2/imgproc.hpp>

#include <array>
#include <limits>
#include <utility>

namespace rehearse::imaging::detail {

// Stage 3: ks and the roughness on the frame itself, the light and kd refined with them; the highlights
// and their surroundings all count, the rest of the organ subsampled.
void AppearanceFitter::fitSpecular() {
  const auto t0 = tick();
  report(0.7, "fitting the specular reflectance and roughness");
  const cv::Mat1b clean = res_.usable & ~res_.foreign;
  if (res_.highlightFound) {
    const std::vector<Sample> specSamples = specularSamples(clean);
    roughnessOnGrid(specSamples);
    refineWithHighlights(specSamples);
    est_.lin = solveLinear(specSamples, est_.lit, est_.sigma, true, nullptr);
    if (res_.highlightsDisagree) specularOverShadingKd(specSamples);
    for (int c = 0; c < 3; ++c) censoredKs(specSamples, c);
    res_.stages.push_back({"specular and roughness (I)", rmsLevels(specSamples, est_.lit, est_.sigma, true),
                           ms(t0, tick()), specSamples.size()});
  } else {
    est_.lin = solveLinear(diffuse_.kept, est_.lit, est_.sigma, false, nullptr);
    // No specular part to fit: the residual is the diffuse model's on the frame itself.
    const std::vector<Sample> onFrame = collect(in_.frame, in_.g, clean, in_.o.maxSamples);
    res_.stages.push_back({"specular and roughness (I)", rmsLevels(onFrame, est_.lit, est_.sigma, false),
                           ms(t0, tick()), onFrame.size()});
  }
}

// The highlights and their surroundings (within 30 px), then the rest of the organ, half the samples each.
std::vector<Sample> AppearanceFitter::specularSamples(const cv::Mat1b& clean) const {
  cv::Mat1b near;
  cv::dilate(res_.separation.highlights, near, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(61, 61)));
  near &= clean;
  std::vector<Sample> specSamples = collect(in_.frame, in_.g, near, in_.o.maxSamples / 2);
  const std::vector<Sample> rest = collect(in_.frame, in_.g, clean & ~near, in_.o.maxSamples / 2);
  specSamples.insert(specSamples.end(), rest.begin(), rest.end());
  return specSamples;
}

// The roughness first on a log grid (the cost is not convex in it), then everything together
// (refineWithHighlights): the highlights pin the light better than the diffuse shading does.
void AppearanceFitter::roughnessOnGrid(const std::vector<Sample>& specSamples) {
  double bestCost = std::numeric_limits<double>::infinity();
  for (double sg = 0.02; sg <= kMaxRoughness; sg *= 1.25) {
    Eigen::VectorXd r;
    solveLinear(specSamples, est_.lit, sg, true, &r);
    if (r.squaredNorm() < bestCost) bestCost = r.squaredNorm(), est_.sigma = sg;
  }
}

// Kept only when it still explains the shading (the diffuse stage's share, within 2 points): on real tissue
// the glints of wet facets far finer than the mesh can pull the light where the shading says it is not.
void AppearanceFitter::refineWithHighlights(const std::vector<Sample>& specSamples) {
  auto diffuseShare = [&](const Light& l) { return shareOf(l, {}); };
  const Light before = est_.lit;
  const double sigmaBefore = est_.sigma, shareBefore = diffuseShare(before);
  const bool ok = refine(specSamples, est_.lit, est_.sigma, true);
  if (diffuseShare(est_.lit) < shareBefore - 0.02) {
    est_.lit = before;
    est_.sigma = sigmaBefore;
    res_.highlightsDisagree = true;
  } else {
    est_.settled = ok && est_.settled;
  }
}

// kd stays the shading's (the diffuse stage's); ks and the roughness are fitted on top of it.
void AppearanceFitter::specularOverShadingKd(const std::vector<Sample>& specSamples) {
  const Light& lit = est_.lit;
  const Eigen::Vector3d kd = solveLinear(diffuse_.kept, lit, est_.sigma, false, nullptr).kd;
  auto ksFor = [&](double sg, double* cost) {
    Eigen::Vector3d num = Eigen::Vector3d::Zero(), den = Eigen::Vector3d::Zero();
    std::vector<std::pair<double, double>> terms(specSamples.size());
    for (std::size_t i = 0; i < specSamples.size(); ++i) {
      basis(specSamples[i], lit, sg, terms[i].first, terms[i].second);
      const Eigen::Vector3d rest = specSamples[i].rgb - kd * terms[i].first;
      num += terms[i].second * rest.cwiseProduct(specSamples[i].weight);
      den += terms[i].second * terms[i].second * specSamples[i].weight;
    }
    const Eigen::Vector3d ks = num.cwiseQuotient(den.cwiseMax(1e-30)).cwiseMax(0.0);
    if (cost) {
      *cost = 0;
      for (std::size_t i = 0; i < specSamples.size(); ++i)
        *cost += (specSamples[i].rgb - kd * terms[i].first - ks * terms[i].second)
                     .cwiseProduct(specSamples[i].weight)
                     .squaredNorm();
    }
    return ks;
  };
  double best = std::numeric_limits<double>::infinity();
  for (double sg = 0.02; sg <= kMaxRoughness; sg *= 1.25) {
    double c;
    ksFor(sg, &c);
    if (c < best) best = c, est_.sigma = sg;
  }
  est_.lin.kd = kd;
  est_.lin.ks = ksFor(est_.sigma, nullptr);
}

// A channel clipped at the highlight (left out of the solve above) still says something: the model must
// reach at least the clipped value there. Its ks is refitted with that as a one-sided (censored) term.
void AppearanceFitter::censoredKs(const std::vector<Sample>& specSamples, int c) {
  Projected& lin = est_.lin;
  std::vector<std::array<double, 4>> terms;  // diffuse, specular, value, clipped
  std::size_t clipped = 0;
  for (const auto& smp : specSamples) {
    double d, sp;
    basis(smp, est_.lit, est_.sigma, d, sp);
    terms.push_back({d, sp, smp.rgb[c], smp.weight[c] == 0 ? 1.0 : 0.0});
    clipped += smp.weight[c] == 0 && sp > 0;
  }
  if (clipped < 20) return;
  auto cost = [&](double ks) {
    double sum = 0;
    for (const auto& t : terms) {
      const double e = t[2] - (lin.kd[c] * t[0] + ks * t[1]);
      sum += t[3] > 0 ? (e > 0 ? e * e : 0.0) : e * e;
    }
    return sum;
  };
  // Unclipped samples where the specular term matters: without them the channel's ks is not measured.
  double spMax = 0;
  std::size_t informative = 0;
  for (const auto& t : terms) spMax = std::max(spMax, t[1]);
  for (const auto& t : terms) informative += t[3] == 0 && t[1] > 0.05 * spMax;
  if (informative < 20) {
    res_.ksMeasured[static_cast<std::size_t>(c)] = false;
    return;
  }
  double lo = 0, hi = 4 * std::max({lin.ks.maxCoeff(), lin.ks[c], 1e-4});
  for (int it = 0; it < 80; ++it) {  // golden section: the cost is convex in ks
    const double a = hi - 0.618 * (hi - lo), b = lo + 0.618 * (hi - lo);
    if (cost(a) < cost(b)) hi = b;
    else lo = a;
  }
  lin.ks[c] = 0.5 * (lo + hi);
}

}  // namespace rehearse::imaging::detail
