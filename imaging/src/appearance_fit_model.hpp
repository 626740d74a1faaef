#pragma once
// The shading model fitAppearance fits (appearance_fit.hpp): its samples, its basis terms, the variable-projection
// solve of the reflectances and the bounded search for the light, and the shares of the shading it explains.
#include <rehearse/imaging/appearance_fit.hpp>

#include <Eigen/Dense>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace rehearse::imaging::detail {

inline double median(std::vector<double> v) {
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

// A regular subsample (at most about maxSamples) of the pixels in `use`.
std::vector<Sample> collect(const cv::Mat3b& image, const SurfaceGeometry& g, const cv::Mat1b& use,
                            std::size_t maxSamples);

// The model's two basis terms at a sample for a light and a roughness: diffuse F cos(theta_i) / r^2 and
// specular F exp(-alpha^2 / 2 sigma^2) / (r^2 cos(theta_r)) (appearance.hpp), zero where the light is behind.
inline void basis(const Sample& s, const Light& light, double sigma, double& diffuse, double& specular,
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
                      Eigen::VectorXd* residual, const Parts& parts = {});

// Levenberg-Marquardt on the light and the fall-off (and, when `specular`, the roughness) in a search bounded to
// kLightBound. Returns false when it did not settle (the evaluation budget ran out or the values went non-finite).
bool refine(const std::vector<Sample>& samples, Light& light, double& sigma, bool specular, const Parts& parts = {},
            int evaluations = 400);

// Drops samples whose residual is far beyond the typical one (texture, vessels, a tool in the way).
std::vector<Sample> trimmed(const std::vector<Sample>& samples, const Light& light, double sigma, bool specular);

double rmsLevels(const std::vector<Sample>& samples, const Light& light, double sigma, bool specular);

// The share of the samples' variance (all channels, about their mean colour) that residual r leaves unexplained,
// subtracted from 1. (r is weighted per channel as solveLinear weights it: a channel near clipping counts in neither
// part.)
double explainedShare(const std::vector<Sample>& samples, const Eigen::VectorXd& r);

// What any smooth shading could explain: the share of the samples' variance that a polynomial of degree 5 in
// the pixel's position explains, per channel (21 terms; the organ's texture and noise are what it leaves).
double smoothShareOf(const std::vector<Sample>& samples);

}  // namespace rehearse::imaging::detail
