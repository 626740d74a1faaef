#pragma once
// Simplified Torrance-Sparrow reflectance (the project's design brief, ../shared/DESIGN.md, beside the repository), per colour channel c (values in [0,1], no gamma), lit by
// a laparoscope's light:
//   J_c = F(p) [kd_c cos(theta_i) / r^2 + ks_c / (r^2 cos(theta_r)) * exp(-alpha^2 / (2 sigma^2))]
// with F = cos^n(psi), psi the angle between the scope's axis (camera z) and the ray to the point: the light
// cone's fall-off and the lens vignetting together (both depend on that angle alone, so one frame cannot tell
// them apart). n = 0 is an isotropic point light seen through an ideal lens.
// A second source (issue 65), kept only where the frame bears it out (fitAppearance): light from outside the scope,
// the same at every point of the organ and fixed to the scene, not to the scope, so without the scope's fall-off:
//   + kr_c max(0, n . d) + ka_c
// a distant light from direction d (a room's lamp, a window: an ex-vivo set-up's light) and an ambient term (light
// scattered from everything around). Both are diffuse reflection, so a pixel's albedo scales them as it scales kd.
#include <rehearse/imaging/camera.hpp>

namespace rehearse::imaging {

struct Appearance {
  Eigen::Vector3d lightPosition = Eigen::Vector3d::Zero();  ///< metres, camera frame
  Eigen::Vector3d kd = Eigen::Vector3d::Zero();             ///< diffuse, RGB (W m^2 units folded in)
  Eigen::Vector3d ks = Eigen::Vector3d::Zero();             ///< specular, RGB
  double roughness = 0.1;                                   ///< sigma, radians
  double falloff = 0;                                       ///< n of F = cos^n(psi), >= 0
  Eigen::Vector3d roomDirection = Eigen::Vector3d::Zero();  ///< the distant light's: unit, camera frame, towards it; 0: none
  Eigen::Vector3d kr = Eigen::Vector3d::Zero();             ///< the distant light's diffuse reflection, RGB
  Eigen::Vector3d ka = Eigen::Vector3d::Zero();             ///< the ambient term, RGB

  /// Whether a distant light is part of the model (a direction and some reflection), and an ambient term.
  bool hasDistantLight() const { return roomDirection.squaredNorm() > 0 && kr.maxCoeff() > 0; }
  bool hasAmbient() const { return ka.maxCoeff() > 0; }
  /// The second source's part of the radiance (RGB) at unit normal `n` (camera frame): kr max(0, n . d) + ka.
  Eigen::Vector3d secondSource(const Eigen::Vector3d& n) const;

  /// F at camera-frame point `p`: cos^n of its angle off the scope's axis (1 on the axis; 0 behind).
  double falloffAt(const Eigen::Vector3d& p) const;

  /// Radiance (RGB) at camera-frame point `p` (m) with unit normal `n`, seen from the camera at the origin.
  Eigen::Vector3d shade(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const;
  /// The scope light's two scalar terms there, fall-off included: shade = kd * diffuse + ks * specular + secondSource(n).
  void terms(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double& diffuse, double& specular) const;
};

/// Issue 65: how far a fit has earned re-shading the organ: the share of the model's change (the organ moved, deformed or
/// seen from elsewhere) applied to the colours the frame showed. 0 up to the share explained below which a fit is texture
/// only (0.5, AppearanceFitOptions::poorShare), 1 from 0.9 on (the model then predicts the frame's shading to within its
/// noise and texture: the phantom's 99 %), linear between; so a fit just over the line changes the frame's colours little.
double reshadeTrust(double explained);

/// A trust as a whole percentage for a sentence: 0 and 100 only at the ends, so that a fit just inside the range never
/// reads as none or as full (0.9987 is 99 %, 0.002 is 1 %).
int trustPercent(double trust);
/// A share explained as a whole percentage beside a trust (floored: 0.8995, re-shaded at 99 %, reads 89 %, not 90 %).
int explainedPercent(double explained);

/// How an organ is drawn from a fit: texture only (the frame's colours follow the tissue, what the frame never saw is
/// not drawn), or re-shaded with the model's change applied at `trust` (0..1) of its size.
struct Reshading {
  bool textureOnly = false;
  double trust = 1;
  /// From a fit's share explained and its verdict (texture only: trust 0).
  static Reshading of(double explained, bool textureOnly);
};

/// What a fit said of itself, kept in THETA.json beside the values (issue 65: a fit's verdict travels with it): how
/// much of the organ's shading it explained, whether it may re-shade the organ, and its sentence. A THETA written by
/// hand (a known light) or before the verdict was kept carries none (`known` false).
struct AppearanceVerdict {
  bool known = false;
  double explained = 0;  ///< share of the organ's shading the fit explained (AppearanceFitResult::explained)
  bool reshade = true;   ///< false: the fit explained too little, show the frame's texture instead (texture only)
  std::string said;      ///< the fit's status sentence
  /// How the fit may draw the organ: its share explained made a trust (reshadeTrust); none known, re-shaded in full (a
  /// light given by hand is taken as known).
  Reshading reshading() const { return known ? Reshading::of(explained, !reshade) : Reshading{}; }
};

/// THETA.json (README.md, "File formats"); throws InputError. `verdict` receives what the fit said of itself.
Appearance loadAppearance(const std::string& path, AppearanceVerdict* verdict = nullptr);
/// Why these values cannot be an organ's appearance (one sentence without a full stop), or empty: k_d and k_s in
/// [0, 100] per channel (a pixel's value at 1 cm from the light is then at most 10^6: any brighter is no organ), the
/// light within 10 m of the camera, the roughness in (0, 10] rad ([0, 10] with `zeroRoughness`: an estimate that found
/// no highlight), the fall-off in [0, 200].
std::string appearanceProblem(const Appearance& a, bool zeroRoughness = false);
/// Writes THETA.json, with the fit's verdict when `verdict.known`.
void saveAppearance(const Appearance& a, const std::string& path, const AppearanceVerdict& verdict = {});

}  // namespace rehearse::imaging
