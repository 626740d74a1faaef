#include <rehearse/imaging/appearance_fit.hpp>

#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>
#include <opencv2/xphoto/inpainting.hpp>

#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <numeric>

namespace rehearse::imaging {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// One fitting sample: the camera-frame point and normal at a pixel, and the pixel's value (RGB, 0..1).
struct Sample {
  Eigen::Vector3d p, n, rgb;
  Eigen::Vector3d weight = Eigen::Vector3d::Ones();  ///< 0 for a channel near clipping (>= 235: its true value is unknown, or averaged with clipped neighbours)
  cv::Point pixel{0, 0};
};

// The nonlinear unknowns: the light's position (camera frame, metres) and the scope's fall-off n (cos^n off
// its axis, appearance.hpp); the roughness travels beside them.
struct Light {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double falloff = 0;
};

// The model's parts that the checks switch off one at a time, to say which of them the frame bears out.
struct Parts {
  bool cosine = true;         ///< cos(theta_i): the surface's orientation to the light
  bool inverseSquare = true;  ///< 1 / r^2: the light's fall-off with distance
  bool falloff = true;        ///< cos^n off the scope's axis
};

// A laparoscope carries its light at its tip, beside the lens: the search keeps the light within this radius
// of the camera's centre (a bounded search; the fit says when the light ends on the bound).
constexpr double kLightBound = 0.030;
constexpr double kMaxFalloff = 60;
// A specular lobe wider than this (radians) is no highlight but a second diffuse term: not searched.
constexpr double kMaxRoughness = 0.6;

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

// The model's two basis terms at a sample for a light and a roughness: diffuse F cos(theta_i) / r^2 and
// specular F exp(-alpha^2 / 2 sigma^2) / (r^2 cos(theta_r)) (appearance.hpp), zero where the light is behind.
void basis(const Sample& s, const Light& light, double sigma, double& diffuse, double& specular,
           const Parts& parts = {}) {
  const Eigen::Vector3d toLight = light.position - s.p;
  const double r2 = std::max(toLight.squaredNorm(), 1e-12);
  const Eigen::Vector3d l = toLight / std::sqrt(r2);
  const double cosI = s.n.dot(l);
  if (cosI <= 0) {
    diffuse = specular = 0;
    return;
  }
  const Eigen::Vector3d v = (-s.p).normalized();
  const double cosR = std::max(s.n.dot(v), 1e-3);
  const double alpha = std::acos(std::clamp(s.n.dot((l + v).normalized()), -1.0, 1.0));
  const double f = parts.falloff && light.falloff > 0 ? std::pow(std::max(-v.z(), 0.0), light.falloff)
                                                      : 1.0;  // v points back to the lens
  const double distance = parts.inverseSquare ? r2 : 0.0025;  // without it: as if every point were 50 mm away
  diffuse = f * (parts.cosine ? cosI : 1.0) / distance;
  specular = sigma > 0 ? f * std::exp(-alpha * alpha / (2 * sigma * sigma)) / (distance * cosR) : 0.0;
}

// Variable projection: for a light position and a roughness, kd (and ks when `specular`) per channel are
// linear and solved in closed form (non-negative); the residuals are what is left.
struct Projected {
  Eigen::Vector3d kd = Eigen::Vector3d::Zero(), ks = Eigen::Vector3d::Zero();
};

Projected solveLinear(const std::vector<Sample>& samples, const Light& light, double sigma, bool specular,
                      Eigen::VectorXd* residual, const Parts& parts = {}) {
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

// Returns false when it did not settle (the evaluation budget ran out or the values went non-finite).
bool refine(const std::vector<Sample>& samples, Light& light, double& sigma, bool specular, const Parts& parts = {},
            int evaluations = 400) {
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

// Drops samples whose residual is far beyond the typical one (texture, vessels, a tool in the way).
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

// The share of the samples' variance (all channels, about their mean colour) that residual r leaves unexplained,
// subtracted from 1. (r is weighted per channel as solveLinear weights it: a channel near clipping counts in neither
// part.)
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

}  // namespace

cv::Mat1b usablePixels(const cv::Mat3b& frame, const cv::Mat1b& organ, int borderPx) {
  if (frame.size() != organ.size()) throw InputError("The frame and the organ's mask differ in size.");
  cv::Mat1b out;
  cv::erode(organ, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));  // the rim mixes organ and background
  std::vector<cv::Mat1b> ch;
  cv::split(frame, ch);
  cv::Mat1b saturated = (ch[0] >= 250) & (ch[1] >= 250) & (ch[2] >= 250);  // a clipped channel alone is dropped per sample
  out.setTo(0, saturated);
  // The scope's dark border: near-black pixels connected to the image's edge.
  cv::Mat1b grey;
  cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
  cv::Mat1b dark = grey < 10;
  cv::Mat1i labels;
  const int n = cv::connectedComponents(dark, labels, 8, CV_32S);
  std::vector<char> touches(static_cast<std::size_t>(n), 0);
  for (int x = 0; x < labels.cols; ++x) touches[labels(0, x)] = touches[labels(labels.rows - 1, x)] = 1;
  for (int y = 0; y < labels.rows; ++y) touches[labels(y, 0)] = touches[labels(y, labels.cols - 1)] = 1;
  cv::Mat1b border(frame.size(), uchar(0));
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x)
      if (labels(y, x) > 0 && touches[labels(y, x)]) border(y, x) = 255;
  if (borderPx > 0 && cv::countNonZero(border) > 0)
    cv::dilate(border, border, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * borderPx + 1, 2 * borderPx + 1)));
  out.setTo(0, border);
  return out;
}

SpecularSeparation separateSpecular(const cv::Mat3b& frame, const cv::Mat1b& organ) {
  SpecularSeparation s;
  s.highlights = cv::Mat1b(frame.size(), uchar(0));
  s.diffuse = frame.clone();
  // The organ's diffuse chromaticity: which channel is typically its largest, middle and smallest, and the
  // median ratios smallest / largest (r) and smallest / middle (q). A pixel c = D chroma + S (1, 1, 1) has
  // c_min - r c_max = S (1 - r): its specular part S; where the largest channel is clipped, the middle one
  // stands in (c_min - q c_mid = S (1 - q)).
  cv::Scalar meanColour = cv::mean(frame, organ);
  std::array<int, 3> order{0, 1, 2};  // BGR indices, largest first
  std::sort(order.begin(), order.end(), [&](int a, int b) { return meanColour[a] > meanColour[b]; });
  const int hiC = order[0], midC = order[1], loC = order[2];
  std::vector<double> ratios, midRatios;
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x)
      if (organ(y, x)) {
        const cv::Vec3b c = frame(y, x);
        if (c[hiC] >= 20 && c[hiC] < 250) ratios.push_back(static_cast<double>(c[loC]) / c[hiC]);
        if (c[midC] >= 20 && c[midC] < 250) midRatios.push_back(static_cast<double>(c[loC]) / c[midC]);
      }
  if (ratios.size() < 20) return s;
  const double r = std::min(median(ratios), 0.9), q = midRatios.size() >= 20 ? median(midRatios) : 1.0;
  cv::Mat1f spec(frame.size(), 0.0f);
  std::vector<double> values;
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x)
      if (organ(y, x)) {
        const cv::Vec3b c = frame(y, x);
        double v = 0;
        if (c[hiC] < 250) v = (c[loC] - r * c[hiC]) / (1 - r);
        else if (q < 0.9) v = (c[loC] - q * c[midC]) / (1 - q);
        else v = c[loC] >= 250 ? 255.0 : 0.0;  // a grey organ's clipped pixel: specular only when all channels clip
        v = std::max(0.0, v);
        spec(y, x) = static_cast<float>(v);
        values.push_back(v);
      }
  const double med = median(values);
  std::vector<double> dev(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) dev[i] = std::abs(values[i] - med);
  const double floor = med + std::max(10.0, 5 * 1.4826 * median(dev));
  cv::Mat1b peak = (spec > floor) & organ;
  cv::morphologyEx(peak, peak, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(3, 3)));  // isolated pixels are noise
  cv::Mat1i labels;
  s.blobs = std::max(0, cv::connectedComponents(peak, labels, 8, CV_32S) - 1);
  if (s.blobs == 0) return s;
  // The highlight: the peaks and the lobe around them where the specular part is above the noise.
  cv::Mat1b lobe = (spec > med + std::max(3.0, 2 * 1.4826 * median(dev))) & organ;
  cv::dilate(peak, s.highlights, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(15, 15)));
  s.highlights &= lobe;
  s.highlights |= peak;
  s.count = cv::countNonZero(s.highlights);
  // I_D: the specular part taken off every channel; clipped pixels (whose true value is unknown) filled.
  cv::Mat1b clipped(frame.size(), uchar(0));
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x) {
      if (!s.highlights(y, x)) continue;
      cv::Vec3b& d = s.diffuse(y, x);
      const cv::Vec3b c = frame(y, x);
      if (std::max({c[0], c[1], c[2]}) >= 250) clipped(y, x) = 255;
      for (int k = 0; k < 3; ++k) d[k] = cv::saturate_cast<uchar>(c[k] - spec(y, x));
    }
  if (cv::countNonZero(clipped) > 0) {
    cv::dilate(clipped, clipped, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
    cv::Mat3b filled;
    cv::inpaint(s.diffuse, clipped, filled, 5, cv::INPAINT_TELEA);
    s.diffuse = filled;
  }
  return s;
}

InpaintMethod parseInpaintMethod(const std::string& name) {
  if (name == "telea") return InpaintMethod::Telea;
  if (name == "ns") return InpaintMethod::NavierStokes;
  if (name == "shiftmap") return InpaintMethod::ShiftMap;
  if (name == "fsr") return InpaintMethod::FsrFast;
  throw InputError("Unknown inpainting method '" + name + "'; choose telea, ns, shiftmap or fsr.");
}

const char* inpaintMethodName(InpaintMethod m) {
  switch (m) {
    case InpaintMethod::Telea: return "telea";
    case InpaintMethod::NavierStokes: return "ns";
    case InpaintMethod::ShiftMap: return "shiftmap";
    case InpaintMethod::FsrFast: return "fsr";
  }
  return "telea";
}

cv::Mat3b inpaintRegion(const cv::Mat3b& frame, const cv::Mat1b& region, InpaintMethod method, int growPx) {
  if (frame.size() != region.size()) throw InputError("The frame and the region to fill differ in size.");
  cv::Mat1b hole = region.clone();
  if (growPx > 0) cv::dilate(hole, hole, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * growPx + 1, 2 * growPx + 1)));
  const int holePixels = cv::countNonZero(hole);
  if (holePixels == 0) return frame.clone();
  // A large hole (an organ filling much of a full-HD frame) is filled at half resolution: what diffusion
  // puts there is smooth anyway, and it costs a quarter; the pixels outside the hole stay the frame's own.
  if (holePixels > 150000 && (method == InpaintMethod::Telea || method == InpaintMethod::NavierStokes)) {
    cv::Mat3b small, filled, up;
    cv::Mat1b smallHole;
    cv::resize(frame, small, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
    cv::resize(hole, smallHole, small.size(), 0, 0, cv::INTER_NEAREST);
    cv::dilate(smallHole, smallHole, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)));
    cv::inpaint(small, smallHole, filled, 3, method == InpaintMethod::Telea ? cv::INPAINT_TELEA : cv::INPAINT_NS);
    cv::resize(filled, up, frame.size(), 0, 0, cv::INTER_LINEAR);
    cv::Mat3b out = frame.clone();
    up.copyTo(out, hole);
    return out;
  }
  cv::Mat3b out;
  switch (method) {
    case InpaintMethod::Telea: cv::inpaint(frame, hole, out, 5, cv::INPAINT_TELEA); break;
    case InpaintMethod::NavierStokes: cv::inpaint(frame, hole, out, 5, cv::INPAINT_NS); break;
    case InpaintMethod::ShiftMap:
    case InpaintMethod::FsrFast: {
      // xphoto marks the known pixels (non-zero), not the hole.
      cv::Mat1b known = hole == 0;
      cv::Mat work = frame.clone(), result;
      if (method == InpaintMethod::ShiftMap) {
        cv::Mat lab;
        cv::cvtColor(frame, lab, cv::COLOR_BGR2Lab);  // shift-map works on Lab images
        cv::xphoto::inpaint(lab, known, result, cv::xphoto::INPAINT_SHIFTMAP);
        cv::cvtColor(result, result, cv::COLOR_Lab2BGR);
      } else {
        cv::xphoto::inpaint(work, known, result, cv::xphoto::INPAINT_FSR_FAST);
      }
      out = result;
      break;
    }
  }
  return out;
}

AppearanceFitResult fitAppearance(const cv::Mat3b& frame, const SurfaceGeometry& g, const AppearanceFitOptions& o) {
  if (frame.empty() || frame.size() != g.triangle.size()) throw InputError("The frame and the organ's geometry differ in size; use the camera of this frame.");
  auto tick = [] { return std::chrono::steady_clock::now(); };
  auto ms = [](auto a, auto b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
  auto report = [&](double share, const std::string& what) {
    if (o.progress && !o.progress(share, what)) throw AppearanceCancelled();
  };
  AppearanceFitResult res;
  const cv::Mat1b organ = g.mask();
  res.usable = usablePixels(frame, organ);
  if (cv::countNonZero(res.usable) < 200)
    throw InputError("The organ covers fewer than 200 usable pixels of the frame (outside the scope's view, saturated or too small); check the pose and the frame.");

  // Stage 1: the light from the specular peaks. At each highlight's brightest pixel the light lies on the
  // view ray mirrored about the normal; a scope carries its light beside the lens, so the point of that
  // ray nearest the camera (or the point nearest all such rays) is the start.
  auto t0 = tick();
  report(0.0, "finding specular highlights");
  res.separation = separateSpecular(frame, res.usable);
  Eigen::Vector3d light(0, 0, 0);
  res.highlightFound = res.separation.count > 0;
  if (res.highlightFound) {
    cv::Mat1i labels;
    const int n = cv::connectedComponents(res.separation.highlights, labels, 8, CV_32S);
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
    // Each highlight's mirrored view ray (a speck of a pixel or two is noise or a rim glint: left out). The
    // scope carries its light beside the lens, so each ray says "the light is about where I pass the
    // camera": the point of each ray nearest the camera, averaged weighted by the highlight's size, after
    // dropping the points far from their median (a highlight seen through a wrong normal). Nearly parallel
    // rays (one smooth highlight) determine no crossing point, but this one.
    struct Guess {
      Eigen::Vector3d x;
      double w;
    };
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
    if (!guesses.empty()) {
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
      light = w > 0 ? Eigen::Vector3d(sum / w) : mid;
    }
    if (!light.allFinite()) light = Eigen::Vector3d(0, 0, 0);
  }
  // The scope's light is at its tip: the highlights' point is kept within the search's bound.
  if (light.norm() > kLightBound) light *= kLightBound / light.norm();
  res.stages.push_back({"light from highlights", 0, ms(t0, tick()), 0});  // its residual: at the start of the next stage

  // Stage 2: the light, the scope's fall-off and kd on the specular-free image, away from the highlights and
  // from what is not the organ's colour (beads, dye, a tool).
  t0 = tick();
  report(0.3, "fitting the light and the diffuse reflectance");
  res.foreign = foreignColour(res.separation.diffuse, res.usable);
  if (res.highlightFound) {  // a highlight is the light's colour, not a foreign object's: its own stage takes it
    cv::Mat1b grown;
    cv::dilate(res.separation.highlights, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
    res.foreign.setTo(0, grown);
  }
  cv::Mat1b away = res.usable & ~res.foreign;
  if (res.highlightFound) {
    cv::Mat1b grown;
    cv::dilate(res.separation.highlights, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
    away.setTo(0, grown);
  }
  std::vector<Sample> diffuseSamples = collect(res.separation.diffuse, g, away, o.maxSamples);
  if (diffuseSamples.size() < 50) throw InputError("Too few organ pixels away from the highlights to fit the diffuse reflectance.");
  double sigma = 0.1;
  Light lit{light, 0.0};
  res.stages.front().rms = rmsLevels(diffuseSamples, lit, sigma, false);  // what the start light leaves on I_D
  res.stages.front().pixels = diffuseSamples.size();
  // The highlights' light, and the scope's usual place for it (at the lens), with and without a fall-off:
  // each refined, the one that explains I_D best kept (a wrong highlight, or a model that is not the frame's
  // mesh, can put the first start in another valley).
  bool settled = false;
  {
    std::vector<Light> starts{lit, {Eigen::Vector3d::Zero(), 4.0}};
    if (light.norm() > 0.005) starts.push_back({Eigen::Vector3d::Zero(), 0.0});
    double best = std::numeric_limits<double>::infinity();
    for (const auto& start : starts) {
      Light l = start;
      double sg = sigma;
      const bool ok = refine(diffuseSamples, l, sg, false);
      const double cost = rmsLevels(diffuseSamples, l, sg, false);
      if (cost < best) best = cost, lit = l, settled = ok;
    }
  }
  const std::vector<Sample> allDiffuse = diffuseSamples;  // the shares are over all of them, outliers included
  diffuseSamples = trimmed(diffuseSamples, lit, sigma, false);
  settled = refine(diffuseSamples, lit, sigma, false) && settled;
  // The share a light explains: kd projected on the trimmed samples, the residual over all of them.
  auto shareOf = [&](const Light& l, const Parts& parts) {
    const Projected p = solveLinear(diffuseSamples, l, sigma, false, nullptr, parts);
    Eigen::VectorXd r(3 * static_cast<Eigen::Index>(allDiffuse.size()));
    for (std::size_t i = 0; i < allDiffuse.size(); ++i) {
      double d, sp;
      basis(allDiffuse[i], l, sigma, d, sp, parts);
      r.segment<3>(3 * static_cast<Eigen::Index>(i)) =
          (allDiffuse[i].rgb - p.kd * d).cwiseProduct(allDiffuse[i].weight);
    }
    return explainedShare(allDiffuse, r);  // below 0 when the model does worse than the organ's mean colour
  };
  res.explained = std::clamp(shareOf(lit, {}), 0.0, 1.0);
  // Which parts of the model the frame bears out: each switched off in turn and the rest refitted; a part
  // whose removal costs less than one point of the share explained is not seen in this frame. Each reduced
  // model's light also restarts the whole model (the cost has several valleys on real tissue).
  {
    const std::array<std::pair<const char*, Parts>, 3> without{{{"cosine of incidence", {false, true, true}},
                                                                {"inverse square of distance", {true, false, true}},
                                                                {"off-axis fall-off", {true, true, false}}}};
    std::vector<Light> reducedLights;
    for (const auto& [name, parts] : without) {
      Light l = lit;
      double sg = sigma;
      refine(diffuseSamples, l, sg, false, parts);
      res.checks.push_back({name, std::clamp(shareOf(l, parts), 0.0, 1.0), true});
      reducedLights.push_back(l);
    }
    for (Light l : reducedLights) {
      if (l.falloff == 0) l.falloff = std::max(lit.falloff, 1.0);
      double sg = sigma;
      const bool ok = refine(diffuseSamples, l, sg, false);
      const double share = std::clamp(shareOf(l, {}), 0.0, 1.0);
      if (share > res.explained + 1e-6) res.explained = share, lit = l, settled = ok;
    }
    for (auto& c : res.checks) c.holds = res.explained - c.explainedWithout >= 0.01;
  }
  res.stages.push_back(
      {"light and diffuse (I_D)", rmsLevels(diffuseSamples, lit, sigma, false), ms(t0, tick()), diffuseSamples.size()});

  // Stage 3: ks and the roughness on the frame itself, the light and kd refined with them; the highlights
  // and their surroundings all count, the rest of the organ subsampled.
  t0 = tick();
  report(0.7, "fitting the specular reflectance and roughness");
  Projected lin;
  const cv::Mat1b clean = res.usable & ~res.foreign;
  if (res.highlightFound) {
    cv::Mat1b near;
    cv::dilate(res.separation.highlights, near, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(61, 61)));
    near &= clean;
    std::vector<Sample> specSamples = collect(frame, g, near, o.maxSamples / 2);
    const std::vector<Sample> rest = collect(frame, g, clean & ~near, o.maxSamples / 2);
    specSamples.insert(specSamples.end(), rest.begin(), rest.end());
    // The roughness first on a log grid (the cost is not convex in it), then everything together: the
    // highlights pin the light better than the diffuse shading does.
    double bestCost = std::numeric_limits<double>::infinity();
    for (double sg = 0.02; sg <= kMaxRoughness; sg *= 1.25) {
      Eigen::VectorXd r;
      solveLinear(specSamples, lit, sg, true, &r);
      if (r.squaredNorm() < bestCost) bestCost = r.squaredNorm(), sigma = sg;
    }
    // Kept only when it still explains the shading (the diffuse stage's share, within 2 points): on real tissue
    // the glints of wet facets far finer than the mesh can pull the light where the shading says it is not.
    {
      auto diffuseShare = [&](const Light& l) { return shareOf(l, {}); };
      const Light before = lit;
      const double sigmaBefore = sigma, shareBefore = diffuseShare(before);
      const bool ok = refine(specSamples, lit, sigma, true);
      if (diffuseShare(lit) < shareBefore - 0.02) {
        lit = before;
        sigma = sigmaBefore;
        res.highlightsDisagree = true;
      } else {
        settled = ok && settled;
      }
    }
    lin = solveLinear(specSamples, lit, sigma, true, nullptr);
    if (res.highlightsDisagree) {
      // kd stays the shading's (the diffuse stage's); ks and the roughness are fitted on top of it.
      const Eigen::Vector3d kd = solveLinear(diffuseSamples, lit, sigma, false, nullptr).kd;
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
        if (c < best) best = c, sigma = sg;
      }
      lin.kd = kd;
      lin.ks = ksFor(sigma, nullptr);
    }
    // A channel clipped at the highlight (left out of the solve above) still says something: the model must
    // reach at least the clipped value there. Its ks is refitted with that as a one-sided (censored) term.
    for (int c = 0; c < 3; ++c) {
      std::vector<std::array<double, 4>> terms;  // diffuse, specular, value, clipped
      std::size_t clipped = 0;
      for (const auto& smp : specSamples) {
        double d, sp;
        basis(smp, lit, sigma, d, sp);
        terms.push_back({d, sp, smp.rgb[c], smp.weight[c] == 0 ? 1.0 : 0.0});
        clipped += smp.weight[c] == 0 && sp > 0;
      }
      if (clipped < 20) continue;
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
        res.ksMeasured[static_cast<std::size_t>(c)] = false;
        continue;
      }
      double lo = 0, hi = 4 * std::max({lin.ks.maxCoeff(), lin.ks[c], 1e-4});
      for (int it = 0; it < 80; ++it) {  // golden section: the cost is convex in ks
        const double a = hi - 0.618 * (hi - lo), b = lo + 0.618 * (hi - lo);
        if (cost(a) < cost(b)) hi = b;
        else lo = a;
      }
      lin.ks[c] = 0.5 * (lo + hi);
    }
    res.stages.push_back(
        {"specular and roughness (I)", rmsLevels(specSamples, lit, sigma, true), ms(t0, tick()), specSamples.size()});
  } else {
    lin = solveLinear(diffuseSamples, lit, sigma, false, nullptr);
    // No specular part to fit: the residual is the diffuse model's on the frame itself.
    const std::vector<Sample> onFrame = collect(frame, g, clean, o.maxSamples);
    res.stages.push_back(
        {"specular and roughness (I)", rmsLevels(onFrame, lit, sigma, false), ms(t0, tick()), onFrame.size()});
  }
  // A channel clipped all over its highlight: its ks is not in the frame. A highlight has the light's
  // colour (the specular reflection of tissue does not tint it much), so it takes the measured channels'
  // mean, and the status says so.
  std::string unmeasured;
  if (res.highlightFound) {
    double sum = 0;
    int n = 0;
    for (int c = 0; c < 3; ++c)
      if (res.ksMeasured[static_cast<std::size_t>(c)]) sum += lin.ks[c], ++n;
    const char* names[] = {"red", "green", "blue"};
    for (int c = 0; c < 3; ++c)
      if (!res.ksMeasured[static_cast<std::size_t>(c)]) {
        lin.ks[c] = n ? sum / n : 0.0;
        unmeasured += std::string(unmeasured.empty() ? "" : " and ") + names[c];
      }
  }
  res.theta.lightPosition = lit.position;
  res.theta.falloff = lit.falloff;
  res.theta.kd = lin.kd;
  res.theta.ks = res.highlightFound ? lin.ks : Eigen::Vector3d::Zero();
  res.theta.roughness = sigma;
  res.lightAtBound = lit.position.norm() > 0.97 * kLightBound;
  // The share Theta as delivered explains of the organ's shading: its diffuse part (light, fall-off and kd after
  // the specular stage) on the specular-free image's samples of the diffuse stage; and what any smooth function
  // of the image position explains of the same samples.
  {
    Eigen::VectorXd r(3 * static_cast<Eigen::Index>(allDiffuse.size()));
    for (std::size_t i = 0; i < allDiffuse.size(); ++i) {
      double d, sp;
      basis(allDiffuse[i], lit, sigma, d, sp);
      r.segment<3>(3 * static_cast<Eigen::Index>(i)) =
          (allDiffuse[i].rgb - res.theta.kd * d).cwiseProduct(allDiffuse[i].weight);
    }
    res.explained = std::clamp(explainedShare(allDiffuse, r), 0.0, 1.0);
    res.smoothShare = smoothShareOf(allDiffuse);
  }
  res.textureOnly = res.explained < o.poorShare;
  char text[600];
  std::snprintf(
      text, sizeof text,
      "%s; the diffuse model explains %.0f %% of the organ's shading (a smooth function of the image position: %.0f "
      "%%)%s",
      res.highlightFound ? "fitted"
                         : "no specular highlight found: the light started at the lens and the specular part is not "
                           "determined (ks = 0)",
      100 * res.explained, 100 * res.smoothShare,
      res.textureOnly ? ": too little, so the organ is shown with the frame's own texture, not re-shaded" : "");
  res.status = text;
  std::string notSeen;
  for (const auto& c : res.checks)
    if (!c.holds) notSeen += std::string(notSeen.empty() ? "" : ", ") + c.part;
  if (!notSeen.empty())
    res.status += "; the frame does not bear out the model's " + notSeen + " (without it the model explains as much)";
  if (res.lightAtBound)
    res.status += "; the light ends on the search's bound (" + std::to_string(static_cast<int>(kLightBound * 1e3)) +
                  " mm from the lens): the frame does not place it";
  if (res.highlightsDisagree)
    res.status +=
        "; the highlights would move the light where the shading says it is not (glints of facets finer than the "
        "mesh): the shading's light is kept";
  if (!settled) res.status += "; the fit did not settle within its evaluation budget: the values are the last it reached";
  if (!unmeasured.empty())
    res.status += "; the " + unmeasured + " channel is clipped all over the highlight, so its specular reflectance is not measured: taken as the other channels' mean";
  report(1.0, "done");
  return res;
}

double diffuseShareAt(const cv::Mat3b& diffuse, const SurfaceGeometry& geometry, const cv::Mat1b& use, const Appearance& start,
                      std::size_t maxSamples, int evaluations, Appearance* refined) {
  if (diffuse.size() != geometry.triangle.size() || use.size() != geometry.triangle.size())
    throw InputError("The image, the pixels to use and the organ's geometry differ in size.");
  const std::vector<Sample> samples = collect(diffuse, geometry, use & geometry.mask(), maxSamples);
  if (samples.size() < 50) return 0;
  Light light{start.lightPosition, start.falloff};
  double sigma = 0.1;
  if (evaluations > 0) refine(samples, light, sigma, false, {}, evaluations);  // keeps the start unless it ends finite
  Eigen::VectorXd r;
  const Projected p = solveLinear(samples, light, sigma, false, &r);
  if (refined) {
    *refined = start;
    refined->lightPosition = light.position;
    refined->falloff = light.falloff;
    refined->kd = p.kd;
  }
  return std::clamp(explainedShare(samples, r), -1.0, 1.0);
}

cv::Mat3f albedoRatio(const cv::Mat3b& diffuse, const SurfaceGeometry& rest, const Appearance& theta, const cv::Mat1b& usable) {
  cv::Mat3f out(diffuse.size(), cv::Vec3f(1, 1, 1));
  double peak = 0;
  for (int y = 0; y < diffuse.rows; ++y)
    for (int x = 0; x < diffuse.cols; ++x) {
      if (rest.triangle(y, x) < 0) continue;
      const cv::Vec3f p = rest.position(y, x), n = rest.normal(y, x);
      Sample s{Eigen::Vector3d(p[0], p[1], p[2]), Eigen::Vector3d(n[0], n[1], n[2]), Eigen::Vector3d::Zero()};
      double d, sp;
      basis(s, Light{theta.lightPosition, theta.falloff}, theta.roughness, d, sp);
      peak = std::max(peak, d);
    }
  for (int y = 0; y < diffuse.rows; ++y)
    for (int x = 0; x < diffuse.cols; ++x) {
      if (rest.triangle(y, x) < 0 || !usable(y, x)) continue;
      const cv::Vec3f p = rest.position(y, x), n = rest.normal(y, x);
      Sample s{Eigen::Vector3d(p[0], p[1], p[2]), Eigen::Vector3d(n[0], n[1], n[2]), Eigen::Vector3d::Zero()};
      double d, sp;
      basis(s, Light{theta.lightPosition, theta.falloff}, theta.roughness, d, sp);
      if (d < 0.05 * peak) continue;
      const cv::Vec3b c = diffuse(y, x);
      for (int k = 0; k < 3; ++k) {
        const double kd = theta.kd[2 - k];  // BGR pixel, RGB kd
        if (kd > 0) out(y, x)[k] = static_cast<float>(std::clamp(c[k] / 255.0 / (kd * d), 0.0, 5.0));
      }
    }
  return out;
}

cv::Mat3b compose(const CompositionInput& in, int scale) { return Compositor(in).compose(in.deformed, scale); }

double psnr(const cv::Mat3b& a, const cv::Mat3b& b, const cv::Mat1b& mask) {
  if (a.size() != b.size()) throw InputError("Images of different sizes cannot be compared.");
  double sum = 0;
  std::size_t n = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      if (!mask.empty() && !mask(y, x)) continue;
      for (int k = 0; k < 3; ++k) {
        const double d = static_cast<double>(a(y, x)[k]) - b(y, x)[k];
        sum += d * d;
      }
      n += 3;
    }
  if (n == 0) return 0;
  const double mse = sum / static_cast<double>(n);
  return mse > 0 ? 10 * std::log10(255.0 * 255.0 / mse) : 99.0;
}

}  // namespace rehearse::imaging
