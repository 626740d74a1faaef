// fitAppearance's result: Theta as delivered, the shares of the shading it explains, and the status sentence
// (appearance_fit_stages.hpp).
#include "appearance_fit_stages.hpp"

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

namespace rehearse::imaging::detail {

// A channel clipped all over its highlight: its ks is not in the frame. A highlight has the light's
// colour (the specular reflection of tissue does not tint it much), so it takes the measured channels'
// mean, and the status says so.
void AppearanceFitter::fillUnmeasuredKs() {
  if (!res_.highlightFound) return;
  Projected& lin = est_.lin;
  double sum = 0;
  int n = 0;
  for (int c = 0; c < 3; ++c)
    if (res_.ksMeasured[static_cast<std::size_t>(c)]) sum += lin.ks[c], ++n;
  const char* names[] = {"red", "green", "blue"};
  for (int c = 0; c < 3; ++c)
    if (!res_.ksMeasured[static_cast<std::size_t>(c)]) {
      lin.ks[c] = n ? sum / n : 0.0;
      unmeasured_ += std::string(unmeasured_.empty() ? "" : " and ") + names[c];
    }
}

void AppearanceFitter::deliverTheta() {
  res_.theta.lightPosition = est_.lit.position;
  res_.theta.falloff = est_.lit.falloff;
  res_.theta.kd = est_.lin.kd;
  res_.theta.ks = res_.highlightFound ? est_.lin.ks : Eigen::Vector3d::Zero();
  res_.theta.roughness = est_.sigma;
  res_.lightAtBound = est_.lit.position.norm() > 0.97 * kLightBound;
}

// The share Theta as delivered explains of the organ's shading: its diffuse part (light, fall-off and kd after
// the specular stage) on the specular-free image's samples of the diffuse stage; and what any smooth function
// of the image position explains of the same samples.
void AppearanceFitter::measureShares() {
  const std::vector<Sample>& all = diffuse_.all;
  Eigen::VectorXd r(3 * static_cast<Eigen::Index>(all.size()));
  for (std::size_t i = 0; i < all.size(); ++i) {
    double d, sp;
    basis(all[i], est_.lit, est_.sigma, d, sp);
    r.segment<3>(3 * static_cast<Eigen::Index>(i)) = (all[i].rgb - res_.theta.kd * d).cwiseProduct(all[i].weight);
  }
  res_.explained = std::clamp(explainedShare(all, r), 0.0, 1.0);
  res_.smoothShare = smoothShareOf(all);
  res_.textureOnly = res_.explained < in_.o.poorShare;
}

void AppearanceFitter::writeStatus() {
  char text[600];
  std::snprintf(
      text, sizeof text,
      "%s; the diffuse model explains %d %% of the organ's shading (a smooth function of the image position: %.0f "
      "%%)%s",
      res_.highlightFound ? "fitted"
                          : "no specular highlight found: the light started at the lens and the specular part is not "
                            "determined (ks = 0)",
      explainedPercent(res_.explained), static_cast<double>(explainedPercent(res_.smoothShare)),  // floored, as the page and the verdict say it
      res_.textureOnly ? ": too little, so the organ is shown with the frame's own texture, not re-shaded" : "");
  res_.status = text;
  if (!res_.sources.empty()) {
    // Which light the frame shows: the scope's alone, and each second source tried beside it.
    const AppearanceFitResult::Source* used = nullptr;
    std::string tried;
    for (const auto& s : res_.sources) {
      if (s.used) used = &s;
      tried += std::string(tried.empty() ? "" : ", ") + s.name + " " +
               std::to_string(explainedPercent(s.explainedWith)) + " %";
    }
    const std::string alone = std::to_string(explainedPercent(res_.scopeExplained));
    if (used)
      res_.status += "; the scope's light alone explains " + alone + " %, with " + used->name + " " +
                     std::to_string(explainedPercent(used->explainedWith)) +
                     " %, which is used (tried beside the scope's light: " + tried +
                     "); a second source can also stand in for an organ registered where the frame does not show it, so "
                     "check the registration (the overlay) before trusting the light";
    else
      res_.status += "; no second light source is borne out (the scope's light alone " + alone + " %; with " + tried + ")";
  }
  // A part is seen when the scope's light explains at least a point less without it than with every part (the share the
  // status and the page give for the scope's light: a second source's stage may refit it after the parts' check).
  const double scope = res_.sources.empty() ? res_.explained : res_.scopeExplained;
  std::string notSeen;
  int unseen = 0;
  for (auto& c : res_.checks) {
    c.holds = scope - c.explainedWithout >= 0.01;
    if (!c.holds) notSeen += std::string(notSeen.empty() ? "" : ", ") + c.part, ++unseen;
  }
  if (!notSeen.empty())
    res_.status += "; the frame does not bear out the scope light's " + notSeen +
                   (unseen == 1 ? " (without it, the scope's light explains as much)"
                                : " (without each, the scope's light explains as much)");
  if (res_.lightAtBound)
    res_.status += "; the light ends on the search's bound (" + std::to_string(static_cast<int>(kLightBound * 1e3)) +
                   " mm from the lens): the frame does not place it";
  if (res_.highlightsDisagree)
    res_.status +=
        "; the highlights would move the light where the shading says it is not (glints of facets finer than the "
        "mesh): the shading's light is kept";
  if (!est_.settled)
    res_.status += "; the fit did not settle within its evaluation budget: the values are the last it reached";
  if (!unmeasured_.empty())
    res_.status += "; the " + unmeasured_ + " channel is clipped all over the highlight, so its specular reflectance is not measured: taken as the other channels' mean";
}

AppearanceFitResult AppearanceFitter::finish() {
  report(1.0, "done");
  return std::move(res_);
}

}  // namespace rehearse::imaging::detail
