#pragma once
// Appearance estimation and composition (DejaVu's step 6; the design brief ../shared/DESIGN.md): the organ's reflectance and the
// scene's light (Theta of the simplified Torrance-Sparrow model, appearance.hpp) fitted to the frame
// through the registered organ's per-pixel geometry, in the paper's stages (light position from the
// specular peaks, then diffuse on the specular-free image, then specular and roughness on the frame); the
// background behind the organ filled by inpainting; and the composition J: the deformed organ re-shaded
// with Theta and its albedo over that background. CPU only (the reference the GUI's shader path is
// compared with).
#include <rehearse/imaging/appearance.hpp>
#include <rehearse/imaging/render.hpp>

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace rehearse::imaging {

/// Pixels that can be trusted for fitting: inside `organ` away from its 2 px rim (where organ and
/// background mix), not saturated in every channel (>= 250; a single clipped channel is left out of the fit
/// per pixel), and not in the dark border of a circular scope view (near-black pixels connected to the
/// image's edge) nor within `borderPx` of it.
cv::Mat1b usablePixels(const cv::Mat3b& frame, const cv::Mat1b& organ, int borderPx = 12);

/// Specular highlights and the specular-free (diffuse) image I_D, for a white light: a pixel is the
/// organ's diffuse colour scaled by its shading plus the same specular amount S in every channel. With the
/// organ's diffuse chromaticity taken as the median ratio r of its smallest to its largest channel,
/// S = (min - r max) / (1 - r) per pixel (the idea of Tan and Ikeuchi's specular-free image, for an organ of
/// one dominant colour); highlights are where S stands above the organ's noise (median + max(10 levels,
/// 5 MADs)) with the lobe around them; I_D is the frame minus S there, with clipped pixels inpainted.
struct SpecularSeparation {
  cv::Mat1b highlights;  ///< 255 on highlight pixels
  cv::Mat3b diffuse;     ///< I_D
  int count = 0;         ///< highlight pixels
  int blobs = 0;         ///< connected highlights
};
SpecularSeparation separateSpecular(const cv::Mat3b& frame, const cv::Mat1b& organ);

/// How the background behind the organ is filled: OpenCV's Telea and Navier-Stokes (cv::inpaint), and
/// xphoto's shift-map and fast frequency-selective reconstruction (cv::xphoto::inpaint).
enum class InpaintMethod { Telea, NavierStokes, ShiftMap, FsrFast };
/// "telea", "ns", "shiftmap", "fsr"; throws InputError naming the choices.
InpaintMethod parseInpaintMethod(const std::string& name);
const char* inpaintMethodName(InpaintMethod m);
/// The frame with `region` (grown by `growPx`) filled: the background I_B a moved organ uncovers. Holes over
/// 150,000 px are filled at half resolution by the diffusion methods (a quarter of the time).
cv::Mat3b inpaintRegion(const cv::Mat3b& frame, const cv::Mat1b& region, InpaintMethod method = InpaintMethod::Telea, int growPx = 4);

struct AppearanceStage {
  std::string name;
  /// Residual, grey levels (0..255) per channel: on I_D at the light the highlights gave (first stage), on
  /// I_D after the diffuse fit, on I after the specular fit (or of the diffuse model alone without a highlight).
  double rms = 0;
  double ms = 0;           ///< wall time
  std::size_t pixels = 0;  ///< samples the residual is over
};

struct AppearanceFitOptions {
  std::size_t maxSamples = 10000;  ///< pixels per stage (a regular subsample of the usable ones; 2,500-80,000 fit the phantom equally well, BENCHMARKS.md)
  double poorShare = 0.5;          ///< below this share of the organ's variance explained: texture mapping only
  /// Try a second light source beside the scope's (a distant light, an ambient term: AppearanceFitResult::sources);
  /// false: the scope's light alone, nothing else tried.
  bool secondSource = true;
  /// Called between stages (share done, stage name); false cancels (throws simcore-free Cancelled below).
  std::function<bool(double, const std::string&)> progress;
};

struct AppearanceFitResult {
  Appearance theta;
  bool highlightFound =
      false;  ///< false: the light started at the lens and the specular part is not determined (ks = 0)
  bool textureOnly = false;     ///< the model explains too little of the frame: show the frame's texture, not re-shaded
  /// The share explained (README, "Appearance"): 1 - the squared residual of Theta's diffuse part (as
  /// delivered) over the organ's squared deviation from its mean colour, all channels, on the specular-free
  /// image's pixels the diffuse stage samples (usable, of the organ's colour, away from highlights; the outliers
  /// its fit trims count here); a channel near clipping counts in neither part.
  double explained = 0;
  /// The same share for a polynomial of degree 5 in the pixel's position, fitted to the same pixels: a reference
  /// for what smooth shading of any kind explains, the rest being texture, specks and noise (not a bound: the
  /// polynomial misses rims and fissures that a shading model through the organ's normals follows).
  double smoothShare = 0;
  /// Each part of the model switched off in turn (the others refitted): the diffuse share without it, and
  /// whether the frame bears it out (its removal costs at least one point of the diffuse stage's share).
  struct Check {
    std::string part;
    double explainedWithout = 0;
    bool holds = true;
  };
  std::vector<Check> checks;
  /// The light the frame shows (issue 65): what the scope's light alone explains (the same share as `explained`), and
  /// each second source tried beside it (appearance.hpp: "an ambient term", "a distant light", "a distant light and an
  /// ambient term"), its share with the scope's light, and whether Theta carries it. A source is used only where the
  /// frame bears it out: each of its terms adds at least kSecondSourceGain to the share of the model without that term;
  /// of those, the one that explains most. `explained` is then the share of the model as delivered.
  struct Source {
    std::string name;
    double explainedWith = 0;
    bool used = false;
  };
  double scopeExplained = 0;
  Appearance scopeTheta;  ///< Theta of the scope's light alone, before a second source (what scopeExplained is of)
  std::vector<Source> sources;
  static constexpr double kSecondSourceGain = 0.02;
  bool highlightsDisagree =
      false;  ///< the specular stage's light would explain the shading worse: the diffuse stage's kept
  bool lightAtBound =
      false;          ///< the light ended on the bounded search's edge (30 mm from the lens): not placed by the frame
  cv::Mat1b foreign;  ///< organ pixels left out for not having the organ's colour (beads, dye, a tool)
  /// Per channel (RGB): false when the channel is clipped wherever its specular term matters, so its ks is
  /// not in the frame (it is then the measured channels' mean, and the status says so).
  std::array<bool, 3> ksMeasured{true, true, true};
  std::string status;           ///< one sentence
  std::vector<AppearanceStage> stages;
  SpecularSeparation separation;
  cv::Mat1b usable;
};

/// The fit was cancelled through AppearanceFitOptions::progress.
struct AppearanceCancelled : std::runtime_error {
  AppearanceCancelled() : std::runtime_error("cancelled") {}
};

/// Fits Theta to `frame` (8-bit BGR, camera size) through `geometry` (surfaceGeometry of the registered
/// organ at scale 1). Throws InputError when the organ covers too few usable pixels to fit anything.
AppearanceFitResult fitAppearance(const cv::Mat3b& frame, const SurfaceGeometry& geometry, const AppearanceFitOptions& options = {});

/// What a diffuse light explains of the organ's shading seen through `geometry`: the share
/// AppearanceFitResult::explained counts, on up to `maxSamples` of `use`'s organ pixels of `diffuse` (the
/// specular-free image, the geometry's size), with the light and fall-off refined from `start`'s in at most
/// `evaluations` evaluations (0: held where they are) and kd in closed form; `refined` receives them. Below 0
/// when the model does worse than the organ's mean colour; 0 with fewer than 50 pixels. Step 6 compares poses
/// with it (app::runAppearance's search of the turn an outline leaves open).
double diffuseShareAt(const cv::Mat3b& diffuse, const SurfaceGeometry& geometry, const cv::Mat1b& use, const Appearance& start,
                      std::size_t maxSamples = 2000, int evaluations = 120, Appearance* refined = nullptr);

/// Per-pixel albedo (RGB ratios to Theta's kd, float): the diffuse image over the fitted diffuse shading at
/// rest, so that a deformed organ keeps its texture while its shading follows its normals; 1 where the rest
/// shading is too dark to divide by or the pixel is not usable.
cv::Mat3f albedoRatio(const cv::Mat3b& diffuse, const SurfaceGeometry& rest, const Appearance& theta, const cv::Mat1b& usable);

/// What composition needs. `rest` and `deformed` are the same surface (same triangles, same vertex order;
/// model frame, metres); the texture is looked up where each point was at rest.
struct CompositionInput {
  Camera camera;
  Pose pose;
  SurfaceView rest, deformed;
  cv::Mat3b frame;       ///< the frame the texture comes from
  cv::Mat3b background;  ///< I_B (inpainted frame)
  cv::Mat3f albedo;      ///< albedoRatio at rest
  Appearance theta;
  bool textureOnly = false;  ///< no re-shading: the frame's own colours follow the tissue
  /// Re-shaded, a point the frame saw carries what Theta's model leaves of the frame there (Compositor::frameResidual):
  /// the frame's detail kept, at rest the frame itself. False: the model alone (its own tests).
  bool frameDetail = true;
  /// Re-shaded, how far the model's change moves the colours of tissue the frame saw (Reshading::trust): 1 the model's
  /// prediction (with the frame's detail), 0 the frame's own colours carried with the tissue, between a mix.
  double trust = 1;
  /// Per rest triangle (empty: all 0): 0, the organ's surface (the frame's albedo where it saw it); k >= 1, tissue
  /// the frame never showed (a cut's faces) drawn with `materials[k - 1]`, an albedo ratio (BGR, against k_d) that
  /// Theta re-shades, even when the surface is only texture-mapped.
  std::vector<int> triangleMaterial;
  std::vector<cv::Vec3f> materials;
};
/// The composited image J (8-bit BGR): I_B, the deformed organ re-shaded (or texture-mapped) over it, its
/// rim anti-aliased with `scale` x `scale` samples per rim pixel (1: none); what the deformation uncovers
/// shows I_B. One Compositor, used once.
cv::Mat3b compose(const CompositionInput& in, int scale = 2);

/// The organ's mean colour in the frame (BGR, 0..255) over the pixels where `triangleAtRest` (the rest's
/// rasterisation) shows it; the whole frame's mean where it shows none. Texture only, the compositors draw tissue the
/// frame never showed (an underside a pull turns into view) in it, not the background through the organ.
cv::Vec3f meanOrganColour(const cv::Mat3b& frame, const cv::Mat1i& triangleAtRest);

/// How much of the frame's own detail (its colours, and what the model leaves of them) a composite keeps at each vertex
/// of a deformed surface, seen through the frame's camera: 1 where the tissue around the vertex covers at most twice the
/// image area it covered in the frame at rest (1.4 times as wide), 0 from 5 times on (2.2 times as wide), linear
/// between. Tissue the frame saw obliquely (a fold's underside, a rim) that a pull turns towards the camera has a few
/// frame pixels to stretch over many: drawn from them, it was a smear of streaks (a person's check); the model is drawn
/// there instead. At rest every weight is 1. `rest` and `now`: the vertices in the camera's frame; the areas are those
/// of the triangles around each vertex, summed.
std::vector<float> frameDetailWeights(const Camera& camera, const std::vector<Eigen::Vector3d>& rest,
                                      const std::vector<Eigen::Vector3d>& now, const std::vector<int>& triangles);

/// Composition prepared once for a registered organ at rest, for a stream of deformed shapes (the viewport
/// following a simulation, a replay): the rest geometry through the camera, the frame's texture, the albedo
/// and the background are kept; each shape then costs its own rasterisation at the frame's resolution,
/// one shading per covered pixel, and scale x scale samples only on the pixels of its rim. Safe to call
/// compose() from several threads at once.
class Compositor {
 public:
  /// Everything in `in` but `deformed` (which may be left equal to `rest`). Throws InputError for a bad
  /// camera, images of another size, or an organ entirely behind the camera.
  explicit Compositor(const CompositionInput& in);
  ~Compositor();
  Compositor(const Compositor&) = delete;
  Compositor& operator=(const Compositor&) = delete;
  /// J for the surface moved to `deformed` (the rest's triangles and vertex order, model frame, metres).
  cv::Mat3b compose(const SurfaceView& deformed, int scale = 2) const;
  /// The same with the deformed vertices given as 3n model-frame coordinates (empty: the rest shape).
  cv::Mat3b compose(const std::vector<double>& deformedVertices, int scale = 2) const;
  const Camera& camera() const;
  /// What Theta's model leaves of the frame on the organ at rest (BGR, 0..255 units, float, frame size): the frame
  /// minus the model there, on the organ's pixels away from its rim (1 px), 0 elsewhere and when texture only. A
  /// re-shaded point the frame saw carries it from where the frame saw it (issue 65: the frame's detail is kept and
  /// the model changes the colours only by what changed; at rest the composite is the frame).
  const cv::Mat3f& frameResidual() const;
  /// The same frame, layers and Theta for another surface of the organ at rest (a cut organ's boundary: its
  /// vertices where the frame showed them, model frame), with its triangles' materials (CompositionInput).
  std::unique_ptr<Compositor> reshaped(const SurfaceView& rest, std::vector<int> triangleMaterial,
                                       std::vector<cv::Vec3f> materials) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> d_;
};

/// A novel view (issue 35): the organ of `fitted` (its rest surface, or moved to `deformedVertices`, the same
/// vertex order, model frame, metres) seen through another camera at another pose (model -> that camera). The
/// scope carries its light: Theta's light and fall-off are in the view camera's frame, so highlights move with
/// the view. Re-shaded, the albedo is the one the fitted frame saw where each point was at rest (1 where that
/// frame did not see it); texture-only, the fitted frame's own colours are pasted where it saw the point (bilinear at
/// its projection, hidden there when a surface lies over 2 mm nearer) and the organ's mean colour in that frame
/// elsewhere (meanOrganColour, as the compositor draws it). Undistorted view, over `background` (the view's
/// size) or black. Throws InputError for a bad camera, a background of another size, or an organ behind it.
struct NovelView {
  cv::Mat3b image;
  cv::Mat1b covered;  ///< 255 where the organ is drawn
  cv::Mat1b seen;     ///< 255 where the fitted frame saw that point of the organ
};
NovelView composeNovelView(const CompositionInput& fitted, const Camera& viewCamera, const Pose& viewPose,
                           const cv::Mat3b& background = {}, const std::vector<double>& deformedVertices = {});

/// Peak signal-to-noise ratio (dB) of b against a (8-bit, same size), over `mask` when given.
double psnr(const cv::Mat3b& a, const cv::Mat3b& b, const cv::Mat1b& mask = {});

}  // namespace rehearse::imaging
