// fitAppearance's last stage (appearance_fit_stages.hpp): the light the frame shows when the scope's does not explain
// it (issue 65). A distant light (one direction everywhere: a room's lamp, a window) and an ambient term are tried
// beside the scope's light on the specular-free image's samples of the diffuse stage, with the reflectances in closed
// form (non-negative) and the distant light's direction searched over the sphere; a source is kept only where the frame
// bears it out (AppearanceFitResult::Source). The scope's light is refitted beside each where the highlights place it
// (fitSecondSource), and the specular lobe (k_s and the roughness) then refitted beside it (lobeBeside).
#include "appearance_fit_stages.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

namespace rehearse::imaging::detail {
namespace {

// The model's diffuse columns at each sample: the scope's term, the distant light's max(0, n . d), and 1.
struct Columns {
  std::vector<double> scope, distant;
};

Columns columnsOf(const std::vector<Sample>& samples, const Light& light, double sigma) {
  Columns c;
  c.scope.resize(samples.size());
  c.distant.assign(samples.size(), 0.0);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    double s;
    basis(samples[i], light, sigma, c.scope[i], s);
  }
  return c;
}

void distantColumn(const std::vector<Sample>& samples, const Eigen::Vector3d& d, std::vector<double>& out) {
  for (std::size_t i = 0; i < samples.size(); ++i) out[i] = std::max(0.0, samples[i].n.dot(d));
}

// Reflectances per channel (RGB) of the scope's term, the distant light and the ambient term.
struct Reflectances {
  Eigen::Vector3d kd = Eigen::Vector3d::Zero(), kr = Eigen::Vector3d::Zero(), ka = Eigen::Vector3d::Zero();
};

// Weighted least squares with every coefficient >= 0, per channel: every subset of the active columns solved, the
// best one whose coefficients are all non-negative kept (three columns at most: seven subsets).
Reflectances solveNonNegative(const std::vector<Sample>& samples, const Columns& c, bool distant, bool ambient) {
  Reflectances out;
  const int m = 3;
  const std::array<bool, 3> active{true, distant, ambient};
  for (int ch = 0; ch < 3; ++ch) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    double yy = 0;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const double w = samples[i].weight[ch];
      if (w == 0) continue;
      const Eigen::Vector3d phi(c.scope[i], c.distant[i], 1.0);
      A += w * phi * phi.transpose();
      b += w * phi * samples[i].rgb[ch];
      yy += w * samples[i].rgb[ch] * samples[i].rgb[ch];
    }
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector3d bestX = Eigen::Vector3d::Zero();
    for (int mask = 1; mask < (1 << m); ++mask) {
      bool allowed = true;
      std::vector<int> idx;
      for (int k = 0; k < m; ++k)
        if (mask & (1 << k)) {
          allowed &= active[static_cast<std::size_t>(k)];
          idx.push_back(k);
        }
      if (!allowed) continue;
      const auto n = static_cast<Eigen::Index>(idx.size());
      Eigen::MatrixXd As(n, n);
      Eigen::VectorXd bs(n);
      for (Eigen::Index r = 0; r < n; ++r) {
        bs[r] = b[idx[static_cast<std::size_t>(r)]];
        for (Eigen::Index q = 0; q < n; ++q) As(r, q) = A(idx[static_cast<std::size_t>(r)], idx[static_cast<std::size_t>(q)]);
      }
      const Eigen::LDLT<Eigen::MatrixXd> ldlt(As);
      if (ldlt.info() != Eigen::Success || !(As.diagonal().minCoeff() > 0)) continue;
      const Eigen::VectorXd xs = ldlt.solve(bs);
      if (!xs.allFinite() || xs.minCoeff() < 0) continue;
      const double cost = yy - 2 * xs.dot(bs) + xs.dot(As * xs);
      if (cost < best) {
        best = cost;
        bestX.setZero();
        for (Eigen::Index r = 0; r < n; ++r) bestX[idx[static_cast<std::size_t>(r)]] = xs[r];
      }
    }
    out.kd[ch] = bestX[0], out.kr[ch] = bestX[1], out.ka[ch] = bestX[2];
  }
  return out;
}

Eigen::VectorXd residualWith(const std::vector<Sample>& samples, const Columns& c, const Reflectances& f) {
  Eigen::VectorXd r(3 * static_cast<Eigen::Index>(samples.size()));
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const Eigen::Vector3d model = f.kd * c.scope[i] + f.kr * c.distant[i] + f.ka;
    r.segment<3>(3 * static_cast<Eigen::Index>(i)) = (samples[i].rgb - model).cwiseProduct(samples[i].weight);
  }
  return r;
}

double shareWith(const std::vector<Sample>& samples, const Columns& c, const Reflectances& f) {
  return explainedShare(samples, residualWith(samples, c, f));
}

Eigen::Vector3d fromAngles(double polar, double azimuth) {
  return {std::sin(polar) * std::cos(azimuth), std::sin(polar) * std::sin(azimuth), std::cos(polar)};
}

// A model with or without each second source, fitted and measured on the same samples.
struct Candidate {
  Light light;  ///< the scope's light, refitted beside the second source
  bool distant = false, ambient = false;
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();
  Reflectances f;
  double share = 0;
};

Candidate fitCandidate(const std::vector<Sample>& samples, Columns& c, bool distant, bool ambient,
                       const Eigen::Vector3d* from = nullptr) {
  Candidate best;
  best.distant = distant, best.ambient = ambient;
  best.share = -std::numeric_limits<double>::infinity();
  auto score = [&](const Eigen::Vector3d& d) {
    if (distant) distantColumn(samples, d, c.distant);
    const Reflectances f = solveNonNegative(samples, c, distant, ambient);
    const double s = shareWith(samples, c, f);
    if (s > best.share) best.share = s, best.f = f, best.direction = distant ? d : Eigen::Vector3d::Zero();
    return s;
  };
  if (!distant) {
    score(Eigen::Vector3d::Zero());
    return best;
  }
  // The sphere of directions (a Fibonacci lattice of 400) scored on a subsample of at most 2,000 samples, then the best
  // refined on all of them by a pattern search on its angles (from `from`, when given, with the pattern search alone).
  if (from) {
    score(*from);
  } else {
    const std::size_t stride = std::max<std::size_t>(1, samples.size() / 2000);
    std::vector<Sample> sub;
    Columns cs;
    for (std::size_t i = 0; i < samples.size(); i += stride) sub.push_back(samples[i]), cs.scope.push_back(c.scope[i]);
    cs.distant.assign(sub.size(), 0.0);
    constexpr int kDirections = 400;
    const double golden = M_PI * (3 - std::sqrt(5.0));
    double bestSub = -std::numeric_limits<double>::infinity();
    for (int k = 0; k < kDirections; ++k) {
      const double z = 1 - 2 * (k + 0.5) / kDirections;
      const double rho = std::sqrt(std::max(0.0, 1 - z * z));
      const Eigen::Vector3d d(rho * std::cos(golden * k), rho * std::sin(golden * k), z);
      distantColumn(sub, d, cs.distant);
      const double s = shareWith(sub, cs, solveNonNegative(sub, cs, distant, ambient));
      if (s > bestSub) bestSub = s, best.direction = d;
    }
    score(best.direction);
  }
  double polar = std::acos(std::clamp(best.direction.z(), -1.0, 1.0));
  double azimuth = std::atan2(best.direction.y(), best.direction.x());
  double current = best.share;
  for (double step = from ? 0.02 : 0.08; step > 0.002; step *= 0.5) {
    for (bool moved = true; moved;) {
      moved = false;
      for (const auto& [dp, da] : std::array<std::pair<double, double>, 4>{{{step, 0}, {-step, 0}, {0, step}, {0, -step}}}) {
        const double s = score(fromAngles(polar + dp, azimuth + da));
        if (s > current + 1e-9) current = s, polar += dp, azimuth += da, moved = true;
      }
    }
  }
  best.direction.normalize();
  return best;
}

// A candidate with the scope's light refitted beside it, in turns: the second source fitted at the light, then the light
// (and its fall-off) refined on what the second source leaves of the samples (a subsample of at most 1,500), three
// rounds. The scope's light stays within the search's bound.
constexpr int kRounds = 3;
Candidate jointly(const std::vector<Sample>& samples, Light light, double sigma, bool distant, bool ambient,
                  bool moveLight = true) {
  std::vector<Sample> sub;
  const std::size_t stride = std::max<std::size_t>(1, samples.size() / 1500);
  for (std::size_t i = 0; i < samples.size(); i += stride) sub.push_back(samples[i]);
  Candidate c;
  for (int round = 0; round < kRounds; ++round) {
    Columns columns = columnsOf(samples, light, sigma);
    const Eigen::Vector3d from = c.direction;
    c = fitCandidate(samples, columns, distant, ambient, round > 0 && distant ? &from : nullptr);
    c.light = light;
    if (round == kRounds - 1 || (!distant && !ambient) || !moveLight) break;
    std::vector<Sample> left = sub;
    for (auto& s : left) s.rgb -= c.f.kr * (distant ? std::max(0.0, s.n.dot(c.direction)) : 0.0) + c.f.ka;
    Light moved = light;
    double sg = sigma;
    refine(left, moved, sg, false, {}, 80);
    if (moved.position.allFinite() && std::isfinite(moved.falloff)) light = moved;
  }
  return c;
}

// The specular lobe again once the scope's light has moved beside a second source: its roughness and, per measured
// channel, k_s in closed form (non-negative) at each roughness tried, on the frame's samples around the highlights less
// both sources' diffuse parts there. The roughness as stage 3 finds it (a log grid, the cost not convex in it), then a
// golden section in its logarithm between the grid's neighbours. A channel not measured takes the measured ones' mean,
// as before (`ks` and `sigma` kept where nothing is measured).
struct Lobe {
  Eigen::Vector3d ks;
  double sigma;
};
Lobe lobeBeside(const std::vector<Sample>& spec, const Candidate& chosen, const std::array<bool, 3>& measured,
                Lobe lobe) {
  // What the specular lobe is left to explain at each sample (the same at every roughness).
  std::vector<Eigen::Vector3d> rest(spec.size());
  for (std::size_t i = 0; i < spec.size(); ++i) {
    double d, sp;
    basis(spec[i], chosen.light, lobe.sigma, d, sp);
    const double room = chosen.distant ? std::max(0.0, spec[i].n.dot(chosen.direction)) : 0.0;
    rest[i] = spec[i].rgb - chosen.f.kd * d - chosen.f.kr * room - chosen.f.ka;
  }
  auto at = [&](double sigma, Eigen::Vector3d& ks) {
    Eigen::Vector3d num = Eigen::Vector3d::Zero(), den = Eigen::Vector3d::Zero(), rr = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < spec.size(); ++i) {
      double d, sp;
      basis(spec[i], chosen.light, sigma, d, sp);
      num += sp * rest[i].cwiseProduct(spec[i].weight);
      den += sp * sp * spec[i].weight;
      rr += rest[i].cwiseProduct(rest[i]).cwiseProduct(spec[i].weight);
    }
    double cost = 0;
    for (int c = 0; c < 3; ++c) {
      if (!measured[static_cast<std::size_t>(c)] || !(den[c] > 0)) continue;
      ks[c] = std::max(0.0, num[c] / den[c]);
      cost += rr[c] - 2 * ks[c] * num[c] + ks[c] * ks[c] * den[c];  // sum w (rest - ks sp)^2
    }
    return cost;
  };
  bool any = false;
  for (int c = 0; c < 3; ++c) any = any || measured[static_cast<std::size_t>(c)];
  if (!any || spec.empty()) return lobe;
  Eigen::Vector3d ks = lobe.ks;
  double best = std::numeric_limits<double>::infinity(), bestSigma = lobe.sigma;
  for (double sg = 0.02; sg <= kMaxRoughness; sg *= 1.25)
    if (const double c = at(sg, ks); c < best) best = c, bestSigma = sg;
  // (Each iteration evaluates one new point: the other is the last one's, at the golden ratio. 24 iterations leave
  // the logarithm within 5e-6.)
  const double golden = 0.5 * (std::sqrt(5.0) - 1.0);
  double lo = std::log(bestSigma / 1.25), hi = std::log(std::min(bestSigma * 1.25, kMaxRoughness));
  double a = hi - golden * (hi - lo), b = lo + golden * (hi - lo);
  double fa = at(std::exp(a), ks), fb = at(std::exp(b), ks);
  for (int it = 0; it < 24; ++it) {
    if (fa < fb) {
      hi = b, b = a, fb = fa;
      a = hi - golden * (hi - lo);
      fa = at(std::exp(a), ks);
    } else {
      lo = a, a = b, fa = fb;
      b = lo + golden * (hi - lo);
      fb = at(std::exp(b), ks);
    }
  }
  // (Never worse than the roughness found before, k_s refitted at it.)
  Eigen::Vector3d ksBefore = lobe.ks;
  const double sigma = std::exp(0.5 * (lo + hi));
  if (at(sigma, ks) <= at(lobe.sigma, ksBefore)) lobe.sigma = sigma;
  at(lobe.sigma, ks);
  double sum = 0;
  int n = 0;
  for (int c = 0; c < 3; ++c)
    if (measured[static_cast<std::size_t>(c)]) sum += ks[c], ++n;
  for (int c = 0; c < 3; ++c)
    if (!measured[static_cast<std::size_t>(c)] && n > 0) ks[c] = sum / n;
  lobe.ks = ks;
  return lobe;
}

}  // namespace

void AppearanceFitter::fitSecondSource() {
  const auto t0 = tick();
  report(0.95, "trying a second light source");
  res_.scopeExplained = res_.explained;
  res_.scopeTheta = res_.theta;
  const std::vector<Sample>& all = diffuse_.all;
  if (!in_.o.secondSource || all.size() < 50) return;
  // Where the scope's light goes beside a second source. The stages before fitted it without one, so a second source
  // in the frame pulls it away (on the phantom lit from outside too, to the search's bound). The highlights are the
  // scope's light's own (the second source has no lobe): where they were found and agree with the shading, the light is
  // refitted beside each second source from where they put it. Otherwise it is held: refitted from the shading alone
  // it follows whatever the second source leaves (on the Open-CAS frame fitted on its left half, the right half was then
  // predicted 6.4 dB worse than with the light held).
  const bool move = res_.highlightFound && !res_.highlightsDisagree && est_.highlightLight.norm() > 0;
  const Light start = move ? Light{est_.highlightLight, est_.lit.falloff} : est_.lit;
  // Fitted on all the diffuse stage's samples, the scope's light alone too (the rule compares like with like): those
  // the stage trimmed as outliers of the scope's light alone are where a second source shows most.
  const Candidate scope = jointly(all, est_.lit, est_.sigma, false, false);
  const Candidate ambient = jointly(all, start, est_.sigma, false, true, move);
  const Candidate distant = jointly(all, start, est_.sigma, true, false, move);
  // Both: the distant light's direction searched again with the ambient term beside it.
  const Candidate both = jointly(all, start, est_.sigma, true, true, move);
  constexpr double gain = AppearanceFitResult::kSecondSourceGain;
  const bool ambientHolds = ambient.share - scope.share >= gain;
  const bool distantHolds = distant.share - scope.share >= gain;
  const bool bothHold = both.share - ambient.share >= gain && both.share - distant.share >= gain;
  const Candidate* chosen = nullptr;
  for (const auto& [c, holds] : std::array<std::pair<const Candidate*, bool>, 3>{{{&ambient, ambientHolds},
                                                                                {&distant, distantHolds},
                                                                                {&both, bothHold}}})
    if (holds && (!chosen || c->share > chosen->share)) chosen = c;
  res_.sources = {{"an ambient term", std::clamp(ambient.share, 0.0, 1.0), chosen == &ambient},
                  {"a distant light", std::clamp(distant.share, 0.0, 1.0), chosen == &distant},
                  {"a distant light and an ambient term", std::clamp(both.share, 0.0, 1.0), chosen == &both}};
  if (chosen) {
    res_.theta.lightPosition = chosen->light.position;
    res_.theta.falloff = chosen->light.falloff;
    res_.lightAtBound = chosen->light.position.norm() > 0.97 * kLightBound;
    res_.theta.kd = chosen->f.kd;
    res_.theta.kr = chosen->distant ? chosen->f.kr : Eigen::Vector3d::Zero();
    res_.theta.roomDirection = chosen->distant && chosen->f.kr.maxCoeff() > 0 ? chosen->direction : Eigen::Vector3d::Zero();
    if (res_.theta.roomDirection.squaredNorm() == 0) res_.theta.kr.setZero();
    res_.theta.ka = chosen->ambient ? chosen->f.ka : Eigen::Vector3d::Zero();
    res_.explained = std::clamp(chosen->share, 0.0, 1.0);
    res_.textureOnly = res_.explained < in_.o.poorShare;
    if (move && res_.highlightFound) {
      const Lobe lobe = lobeBeside(specularSamples(res_.usable & ~res_.foreign), *chosen, res_.ksMeasured,
                                   Lobe{res_.theta.ks, res_.theta.roughness});
      res_.theta.ks = lobe.ks;
      res_.theta.roughness = lobe.sigma;
    }
  }
  const Candidate& delivered = chosen ? *chosen : scope;
  Columns ca = columnsOf(all, delivered.light, est_.sigma);
  if (delivered.distant) distantColumn(all, delivered.direction, ca.distant);
  const Eigen::VectorXd r = residualWith(all, ca, delivered.f);
  res_.stages.push_back({"second source", r.size() ? 255.0 * std::sqrt(r.squaredNorm() / static_cast<double>(r.size())) : 0.0,
                         ms(t0, tick()), all.size()});
}

}  // namespace rehearse::imaging::detail
