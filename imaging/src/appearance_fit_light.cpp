// fitAppearance's stages 1 and 2: the light from the specular highlights, then the light, the scope's fall-off and
// the diffuse reflectance on the specular-free image (appearance_fit_stages.hpp).
#include "appearance_fit_stages.hpp"

#include <opencv2/imgproc.hpp>

#include <array>
#include <limits>
#include <utility>

namespace rehearse::imaging::detail {
namespace {

// Pixels whose colour is not the organ's: fiducial beads, dye, a tool's tip, blood (their chromaticity stands
// more than max(0.04, 6 MADs) from the organ's median in either of its two coordinates), with a 3 px margin.
cv::Mat1b foreignColour(const cv::Mat3b& image, const cv::Mat1b& organ) {
  cv::Mat1b out(image.size(), uchar(0));
  std::vector<double> cb, cg;
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x)
      if (organ(y, x)) {
        const cv::Vec3b c = image(y, x);
        const double sum = static_cast<double>(c[0]) + c[1] + c[2];
        if (sum >= 30) cb.push_back(c[0] / sum), cg.push_back(c[1] / sum);
      }
  if (cb.size() < 100) return out;
  const double mb = median(cb), mg = median(cg);
  std::vector<double> db(cb.size()), dg(cg.size());
  for (std::size_t i = 0; i < cb.size(); ++i) db[i] = std::abs(cb[i] - mb), dg[i] = std::abs(cg[i] - mg);
  const double lb = std::max(0.04, 6 * 1.4826 * median(db)), lg = std::max(0.04, 6 * 1.4826 * median(dg));
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x)
      if (organ(y, x)) {
        const cv::Vec3b c = image(y, x);
        const double sum = static_cast<double>(c[0]) + c[1] + c[2];
        if (sum >= 30 && (std::abs(c[0] / sum - mb) > lb || std::abs(c[1] / sum - mg) > lg)) out(y, x) = 255;
      }
  cv::morphologyEx(out, out, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(3, 3)));  // a lone pixel is noise
  cv::dilate(out, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
  return out;
}

// Each highlight's mirrored view ray (a speck of a pixel or two is noise or a rim glint: left out). The
// scope carries its light beside the lens, so each ray says "the light is about where I pass the
// camera": the point of each ray nearest the camera, weighted by the highlight's size.
struct Guess {
  Eigen::Vector3d x;
  double w;
};

std::vector<Guess> highlightGuesses(const cv::Mat3b& frame, const SurfaceGeometry& g, const cv::Mat1b& highlights) {
  cv::Mat1i labels;
  const int n = cv::connectedComponents(highlights, labels, 8, CV_32S);
  std::vector<int> bestValue(static_cast<std::size_t>(n), -1);
  std::vector<cv::Point> bestAt(static_cast<std::size_t>(n));
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) {
      const int l = labels(y, x);
      if (l <= 0 || g.triangle(y, x) < 0) continue;
      const cv::Vec3b c = frame(y, x);
      const int v = std::min({c[0], c[1], c[2]});
      if (v > bestValue[l]) bestValue[l] = v, bestAt[l] = {x, y};
    }
  std::vector<Guess> guesses;
  std::vector<int> size(static_cast<std::size_t>(n), 0);
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) ++size[static_cast<std::size_t>(std::max(0, labels(y, x)))];
  for (int l = 1; l < n; ++l) {
    if (bestValue[l] < 0 || size[static_cast<std::size_t>(l)] < 5) continue;
    const cv::Vec3f pf = g.position(bestAt[l]), nf = g.normal(bestAt[l]);
    const Eigen::Vector3d p(pf[0], pf[1], pf[2]), nn(nf[0], nf[1], nf[2]);
    const Eigen::Vector3d v = (-p).normalized();
    const Eigen::Vector3d r = (2 * nn.dot(v) * nn - v).normalized();
    const double along = std::max(0.0, -p.dot(r));  // the ray p + s r, s >= 0, nearest the origin
    guesses.push_back({p + along * r, static_cast<double>(size[static_cast<std::size_t>(l)])});
  }
  return guesses;
}

// The guesses averaged weighted by the highlight's size, after dropping the points far from their median (a
// highlight seen through a wrong normal). Nearly parallel rays (one smooth highlight) determine no crossing point,
// but this one.
Eigen::Vector3d lightNearGuesses(const std::vector<Guess>& guesses) {
  std::vector<double> xs[3];
  for (const auto& q : guesses)
    for (int k = 0; k < 3; ++k) xs[k].push_back(q.x[k]);
  Eigen::Vector3d mid;
  for (int k = 0; k < 3; ++k) mid[k] = median(xs[k]);
  std::vector<double> d;
  for (const auto& q : guesses) d.push_back((q.x - mid).norm());
  const double limit = std::max(3 * median(d), 0.005);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double w = 0;
  for (std::size_t i = 0; i < guesses.size(); ++i)
    if (d[i] <= limit) sum += guesses[i].w * guesses[i].x, w += guesses[i].w;
  return w > 0 ? Eigen::Vector3d(sum / w) : mid;
}

}  // namespace

// Stage 1: the light from the specular peaks. At each highlight's brightest pixel the light lies on the
// view ray mirrored about the normal; a scope carries its light beside the lens, so the point of that
// ray nearest the camera (or the point nearest all such rays) is the start.
void AppearanceFitter::lightFromHighlights() {
  const auto t0 = tick();
  report(0.0, "finding specular highlights");
  res_.separation = separateSpecular(in_.frame, res_.usable);
  Eigen::Vector3d light(0, 0, 0);
  res_.highlightFound = res_.separation.count > 0;
  if (res_.highlightFound) {
    const std::vector<Guess> guesses = highlightGuesses(in_.frame, in_.g, res_.separation.highlights);
    if (!guesses.empty()) light = lightNearGuesses(guesses);
    if (!light.allFinite()) light = Eigen::Vector3d(0, 0, 0);
  }
  // The scope's light is at its tip: the highlights' point is kept within the search's bound.
  if (light.norm() > kLightBound) light *= kLightBound / light.norm();
  est_.highlightLight = light;
  // Its residual: at the start of the next stage.
  res_.stages.push_back({"light from highlights", 0, ms(t0, tick()), 0});
}

// Stage 2: the light, the scope's fall-off and kd on the specular-free image, away from the highlights and
// from what is not the organ's colour (beads, dye, a tool).
void AppearanceFitter::fitLightAndDiffuse() {
  const auto t0 = tick();
  report(0.3, "fitting the light and the diffuse reflectance");
  diffuse_.kept = samplesAwayFromHighlights();
  est_.sigma = 0.1;
  est_.lit = Light{est_.highlightLight, 0.0};
  // What the start light leaves on I_D.
  res_.stages.front().rms = rmsLevels(diffuse_.kept, est_.lit, est_.sigma, false);
  res_.stages.front().pixels = diffuse_.kept.size();
  lightFromStarts();
  diffuse_.all = diffuse_.kept;  // the shares are over all of them, outliers included
  diffuse_.kept = trimmed(diffuse_.kept, est_.lit, est_.sigma, false);
  est_.settled = refine(diffuse_.kept, est_.lit, est_.sigma, false) && est_.settled;
  res_.explained = std::clamp(shareOf(est_.lit, {}), 0.0, 1.0);
  checkModelParts();
  res_.stages.push_back({"light and diffuse (I_D)", rmsLevels(diffuse_.kept, est_.lit, est_.sigma, false),
                         ms(t0, tick()), diffuse_.kept.size()});
}

std::vector<Sample> AppearanceFitter::samplesAwayFromHighlights() {
  res_.foreign = foreignColour(res_.separation.diffuse, res_.usable);
  if (res_.highlightFound) {  // a highlight is the light's colour, not a foreign object's: its own stage takes it
    cv::Mat1b grown;
    cv::dilate(res_.separation.highlights, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
    res_.foreign.setTo(0, grown);
  }
  cv::Mat1b away = res_.usable & ~res_.foreign;
  if (res_.highlightFound) {
    cv::Mat1b grown;
    cv::dilate(res_.separation.highlights, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
    away.setTo(0, grown);
  }
  std::vector<Sample> samples = collect(res_.separation.diffuse, in_.g, away, in_.o.maxSamples);
  if (samples.size() < 50) throw InputError("Too few organ pixels away from the highlights to fit the diffuse reflectance.");
  return samples;
}

// The highlights' light, and the scope's usual place for it (at the lens), with and without a fall-off:
// each refined, the one that explains I_D best kept (a wrong highlight, or a model that is not the frame's
// mesh, can put the first start in another valley).
void AppearanceFitter::lightFromStarts() {
  est_.settled = false;
  std::vector<Light> starts{est_.lit, {Eigen::Vector3d::Zero(), 4.0}};
  if (est_.highlightLight.norm() > 0.005) starts.push_back({Eigen::Vector3d::Zero(), 0.0});
  double best = std::numeric_limits<double>::infinity();
  for (const auto& start : starts) {
    Light l = start;
    double sg = est_.sigma;
    const bool ok = refine(diffuse_.kept, l, sg, false);
    const double cost = rmsLevels(diffuse_.kept, l, sg, false);
    if (cost < best) best = cost, est_.lit = l, est_.settled = ok;
  }
}

double AppearanceFitter::shareOf(const Light& l, const Parts& parts) const {
  const Projected p = solveLinear(diffuse_.kept, l, est_.sigma, false, nullptr, parts);
  const std::vector<Sample>& all = diffuse_.all;
  Eigen::VectorXd r(3 * static_cast<Eigen::Index>(all.size()));
  for (std::size_t i = 0; i < all.size(); ++i) {
    double d, sp;
    basis(all[i], l, est_.sigma, d, sp, parts);
    r.segment<3>(3 * static_cast<Eigen::Index>(i)) = (all[i].rgb - p.kd * d).cwiseProduct(all[i].weight);
  }
  return explainedShare(all, r);  // below 0 when the model does worse than the organ's mean colour
}

// Which parts of the model the frame bears out: each switched off in turn and the rest refitted; a part
// whose removal costs less than one point of the share explained is not seen in this frame. Each reduced
// model's light also restarts the whole model (the cost has several valleys on real tissue).
void AppearanceFitter::checkModelParts() {
  const std::array<std::pair<const char*, Parts>, 3> without{{{"cosine of incidence", {false, true, true}},
                                                              {"inverse square of distance", {true, false, true}},
                                                              {"off-axis fall-off", {true, true, false}}}};
  std::vector<Light> reducedLights;
  for (const auto& [name, parts] : without) {
    Light l = est_.lit;
    double sg = est_.sigma;
    refine(diffuse_.kept, l, sg, false, parts);
    res_.checks.push_back({name, std::clamp(shareOf(l, parts), 0.0, 1.0), true});
    reducedLights.push_back(l);
  }
  for (Light l : reducedLights) {
    if (l.falloff == 0) l.falloff = std::max(est_.lit.falloff, 1.0);
    double sg = est_.sigma;
    const bool ok = refine(diffuse_.kept, l, sg, false);
    const double share = std::clamp(shareOf(l, {}), 0.0, 1.0);
    if (share > res_.explained + 1e-6) res_.explained = share, est_.lit = l, est_.settled = ok;
  }
  for (auto& c : res_.checks) c.holds = res_.explained - c.explainedWithout >= 0.01;
}

}  // namespace rehearse::imaging::detail
