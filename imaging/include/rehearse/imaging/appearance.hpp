#pragma once
// Simplified Torrance-Sparrow reflectance of DESIGN.md, per colour channel c (values in [0,1], no gamma):
//   J_c = kd_c cos(theta_i) / r^2 + ks_c / (r^2 cos(theta_r)) * exp(-alpha^2 / (2 sigma^2))
#include <rehearse/imaging/camera.hpp>

namespace rehearse::imaging {

struct Appearance {
  Eigen::Vector3d lightPosition = Eigen::Vector3d::Zero();  ///< metres, camera frame
  Eigen::Vector3d kd = Eigen::Vector3d::Zero();             ///< diffuse, RGB (W m^2 units folded in)
  Eigen::Vector3d ks = Eigen::Vector3d::Zero();             ///< specular, RGB
  double roughness = 0.1;                                   ///< sigma, radians

  /// Radiance (RGB) at camera-frame point `p` (m) with unit normal `n`, seen from the camera at the origin.
  Eigen::Vector3d shade(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const;
};

Appearance loadAppearance(const std::string& path);  ///< JSON of DESIGN.md; throws InputError
void saveAppearance(const Appearance& a, const std::string& path);

}  // namespace rehearse::imaging
