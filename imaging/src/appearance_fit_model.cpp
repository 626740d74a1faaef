// The shading model's fit (appearance_fit_model.hpp): sampling, the variable-projection solve, the bounded
// Levenberg-Marquardt search for the light, trimming, and the shares explained.
#include "appearance_fit_model.hpp"

#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

#include <array>
#include <utility>

namespace rehearse::imaging::detail {

std::vector<Sample> collect(const cv::Mat3b& image, const SurfaceGeometry& g, const cv::Mat1b& use, std::size_t maxSamples) {
  std::vector<cv::Point> where;
  cv::findNonZero(use, where);
  const std::size_t stride = std::max<std::size_t>(1, where.size() / std::max<std::size_t>(1, maxSamples));
  std::vector<Sample> out;
  out.reserve(where.size() / stride + 1);
  for (std::size_t i = 0; i < where.size(); i += stride) {
    const cv::Point& q = where[i];
    const cv::Vec3f p = g.position(q), n = g.normal(q);
    const cv::Vec3b c = image(q);
    out.push_back({Eigen::Vector3d(p[0], p[1], p[2]), Eigen::Vector3d(n[0], n[1], n[2]),
                   Eigen::Vector3d(c[2], c[1], c[0]) / 255.0, Eigen::Vector3d(c[2] < 235, c[1] < 235, c[0] < 235), q});
  }
  return out;
}

Projected solveLinear(const std::vector<Sample>& samples, const Light& light, double sigma, bool specular,
                      Eigen::VectorXd* residual, const Parts& parts) {
  std::array<Eigen::Matrix2d, 3> A;
  std::array<Eigen::Vector2d, 3> b;
  for (int c = 0; c < 3; ++c) A[c].setZero(), b[c].setZero();
  std::vector<std::pair<double, double>> terms(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    double d, s;
    basis(samples[i], light, sigma, d, s, parts);
    if (!specular) s = 0;
    terms[i] = {d, s};
    const Eigen::Vector2d phi(d, s);
    for (int c = 0; c < 3; ++c) {
      const double w = samples[i].weight[c];
      A[c] += w * phi * phi.transpose();
      b[c] += w * phi * samples[i].rgb[c];
    }
  }
  Projected out;
  for (int c = 0; c < 3; ++c) {
    const Eigen::Matrix2d& M = A[c];
    Eigen::Vector2d x = Eigen::Vector2d::Zero();
    if (specular && M.determinant() > 1e-18 * std::max(1.0, M(0, 0) * M(1, 1))) x = M.ldlt().solve(b[c]);
    else if (M(0, 0) > 0) x = Eigen::Vector2d(b[c](0) / M(0, 0), 0);
    // Non-negative: a negative coefficient is dropped and the other refitted alone.
    if (x.y() < 0) x = Eigen::Vector2d(M(0, 0) > 0 ? b[c](0) / M(0, 0) : 0, 0);
    if (x.x() < 0) x = Eigen::Vector2d(0, M(1, 1) > 0 ? std::max(0.0, b[c](1) / M(1, 1)) : 0);
    out.kd[c] = x.x();
    out.ks[c] = x.y();
  }
  if (residual) {
    residual->resize(3 * static_cast<Eigen::Index>(samples.size()));
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const Eigen::Vector3d model = out.kd * terms[i].first + out.ks * terms[i].second;
      residual->segment<3>(3 * static_cast<Eigen::Index>(i)) = (samples[i].rgb - model).cwiseProduct(samples[i].weight);
    }
  }
  return out;
}

namespace {

// The bounded search's coordinates: the light as u in R^3 with position = R u / sqrt(1 + |u|^2), inside the ball
// of radius R = kLightBound at every u; the fall-off as w with n = min(w^2, kMaxFalloff).
Eigen::Vector3d lightFromSearch(const Eigen::Vector3d& u) { return kLightBound * u / std::sqrt(1 + u.squaredNorm()); }
Eigen::Vector3d searchFromLight(const Eigen::Vector3d& position) {
  Eigen::Vector3d p = position;
  if (p.norm() > 0.98 * kLightBound) p *= 0.98 * kLightBound / p.norm();
  return p / std::sqrt(kLightBound * kLightBound - p.squaredNorm());
}

// Levenberg-Marquardt on the nonlinear unknowns: the light and the fall-off (in the search's coordinates) and,
// when `specular`, log(sigma).
struct VarProFunctor {
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  const std::vector<Sample>* samples;
  bool specular;
  Parts parts;
  int inputs() const { return specular ? 5 : 4; }
  int values() const { return 3 * static_cast<int>(samples->size()); }
  static Light light(const Eigen::VectorXd& x) {
    return {lightFromSearch(x.head<3>()), std::min(x[3] * x[3], kMaxFalloff)};
  }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& f) const {
    const double sigma = specular ? std::exp(x[4]) : 0.0;
    solveLinear(*samples, light(x), sigma, specular, &f, parts);
    return 0;
  }
};

}  // namespace

// Returns false when it did not settle (the evaluation budget ran out or the values went non-finite).
bool refine(const std::vector<Sample>& samples, Light& light, double& sigma, bool specular, const Parts& parts,
            int evaluations) {
  VarProFunctor f{&samples, specular, parts};
  Eigen::VectorXd x(specular ? 5 : 4);
  x.head<3>() = searchFromLight(light.position);
  x[3] = parts.falloff ? std::sqrt(std::max(light.falloff, 0.0)) : 0.0;
  if (specular) x[4] = std::log(sigma);
  Eigen::NumericalDiff<VarProFunctor> nd(f, 1e-6);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<VarProFunctor>> lm(nd);
  lm.parameters.maxfev = evaluations;
  lm.parameters.xtol = 1e-10;
  lm.parameters.ftol = 1e-12;
  if (!parts.falloff) x[3] = 0;  // held at n = 0: its column is zero, which the solver treats as a fixed unknown
  const auto status = lm.minimize(x);
  if (!x.allFinite()) return false;
  light = VarProFunctor::light(x);
  if (!parts.falloff) light.falloff = 0;
  if (specular) sigma = std::clamp(std::exp(x[4]), 0.005, kMaxRoughness);
  return status != Eigen::LevenbergMarquardtSpace::TooManyFunctionEvaluation && status != Eigen::LevenbergMarquardtSpace::ImproperInputParameters;
}

std::vector<Sample> trimmed(const std::vector<Sample>& samples, const Light& light, double sigma, bool specular) {
  Eigen::VectorXd r;
  solveLinear(samples, light, sigma, specular, &r);
  std::vector<double> mag(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) mag[i] = r.segment<3>(3 * static_cast<Eigen::Index>(i)).norm();
  const double med = median(mag);
  std::vector<double> dev(mag.size());
  for (std::size_t i = 0; i < mag.size(); ++i) dev[i] = std::abs(mag[i] - med);
  const double limit = med + 3 * 1.4826 * std::max(median(dev), 1e-6);
  std::vector<Sample> out;
  for (std::size_t i = 0; i < samples.size(); ++i)
    if (mag[i] <= limit) out.push_back(samples[i]);
  return out.size() >= 50 ? out : samples;
}

double rmsLevels(const std::vector<Sample>& samples, const Light& light, double sigma, bool specular) {
  Eigen::VectorXd r;
  solveLinear(samples, light, sigma, specular, &r);
  return r.size() ? 255.0 * std::sqrt(r.squaredNorm() / static_cast<double>(r.size())) : 0.0;
}

double explainedShare(const std::vector<Sample>& samples, const Eigen::VectorXd& r) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), count = Eigen::Vector3d::Zero();
  for (const auto& s : samples) mean += s.rgb.cwiseProduct(s.weight), count += s.weight;
  mean = mean.cwiseQuotient(count.cwiseMax(1.0));
  double total = 0;
  for (const auto& s : samples) total += (s.rgb - mean).cwiseProduct(s.weight).squaredNorm();
  return total > 0 ? 1 - r.squaredNorm() / total : 0.0;
}

// What any smooth shading could explain: the share of the samples' variance that a polynomial of degree 5 in
// the pixel's position explains, per channel (21 terms; the organ's texture and noise are what it leaves).
double smoothShareOf(const std::vector<Sample>& samples) {
  if (samples.size() < 100) return 0;
  int x0 = samples.front().pixel.x, x1 = x0, y0 = samples.front().pixel.y, y1 = y0;
  for (const auto& s : samples)
    x0 = std::min(x0, s.pixel.x), x1 = std::max(x1, s.pixel.x), y0 = std::min(y0, s.pixel.y),
    y1 = std::max(y1, s.pixel.y);
  const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1), half = 0.5 * std::max({x1 - x0, y1 - y0, 1});
  constexpr int degree = 5, terms = (degree + 1) * (degree + 2) / 2;
  Eigen::MatrixXd A(static_cast<Eigen::Index>(samples.size()), terms);
  Eigen::MatrixXd b(static_cast<Eigen::Index>(samples.size()), 3);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double X = (samples[i].pixel.x - cx) / half, Y = (samples[i].pixel.y - cy) / half;
    int k = 0;
    for (int a = 0; a <= degree; ++a)
      for (int c = 0; a + c <= degree; ++c) A(static_cast<Eigen::Index>(i), k++) = std::pow(X, a) * std::pow(Y, c);
    b.row(static_cast<Eigen::Index>(i)) = samples[i].rgb.transpose();
  }
  const Eigen::MatrixXd fit = A * A.colPivHouseholderQr().solve(b);
  Eigen::VectorXd r(3 * static_cast<Eigen::Index>(samples.size()));
  for (std::size_t i = 0; i < samples.size(); ++i)
    r.segment<3>(3 * static_cast<Eigen::Index>(i)) =
        (b.row(static_cast<Eigen::Index>(i)) - fit.row(static_cast<Eigen::Index>(i))).transpose();
  return std::clamp(explainedShare(samples, r), 0.0, 1.0);
}

}  // namespace rehearse::imaging::detail
