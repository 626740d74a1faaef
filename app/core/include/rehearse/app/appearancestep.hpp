#pragma once
// Step 6, the one appearance pipeline the GUI and the command line share: the registered organ's geometry
// through the camera, Theta fitted to the frame (imaging/appearance_fit.hpp), the background behind the
// organ inpainted, the albedo at rest; and composition of a deformed organ from them.
#include "rehearse/app/case.hpp"

#include <rehearse/imaging/appearance_fit.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <functional>
#include <memory>
#include <vector>

namespace rehearse::app {

struct AppearanceInput {
  imaging::Camera camera;
  Pose pose;                      ///< model -> camera, as registered
  std::vector<double> vertices;   ///< the organ's surface at rest (registered shape), model frame, metres, 3n
  std::vector<std::array<int, 3>> triangles;
  cv::Mat3b frame;                ///< undistorted, BGR
  imaging::InpaintMethod inpaint = imaging::InpaintMethod::Telea;  ///< the best measured on organ-sized holes (BENCHMARKS.md)
  std::function<bool(double, const std::string&)> progress;  ///< false cancels (imaging::AppearanceCancelled)
  /// The outline sketched in step 3 (undistorted pixels of the frame). With a silhouette in it and `turnByShading`,
  /// step 6 also settles the turn the outline leaves open (ShadingTurn); without one that turn is not searched.
  imaging::Contour contour;
  bool turnByShading = true;
  SurfaceView surface() const { return {vertices.data(), vertices.size() / 3, triangles.empty() ? nullptr : triangles.front().data(), triangles.size()}; }
};

/// Step 6's search of the turn an outline leaves open: a turn about the camera's X or Y axis through the organ's
/// centre moves its silhouette little but its shading much, so where the contour fit could not tell (its status says
/// "weakest: a turn about the camera's X axis") the shading can. Candidate turns up to 15 degrees (in up to three
/// rounds) that keep the silhouette on the outline (the outline's points on average no further from it than from the
/// registered pose's silhouette plus half a pixel and half that distance) are scored by the share of the shading a diffuse light explains through them (at
/// most 960 px wide); the best is refitted in full and adopted when it explains at least 3 points more than the
/// registered pose and at least enough to re-shade (AppearanceFitOptions::poorShare).
struct ShadingTurn {
  bool searched = false;
  bool adopted = false;
  Pose pose;                       ///< where Theta was fitted: the turned pose when adopted, else the input's
  double aboutXDeg = 0, aboutYDeg = 0;  ///< the turn found (camera axes, through the organ's centre)
  double explainedBefore = 0;      ///< the registered pose's full fit: what its scope's light alone explains
  double explainedAfter = 0;       ///< the same at the turned pose (when one was made)
  double outlineBeforePx = 0, outlineAfterPx = 0;  ///< the outline's points' mean distance to the silhouette (frame px)
  int candidates = 0;              ///< turns scored
  double scoredBefore = 0, scoredBest = 0;  ///< the working resolution's shares: the registered pose's, the best turn's
  double ms = 0;
  std::string sentence;            ///< what was done or why not; empty when not asked
};

struct AppearanceOutput {
  imaging::AppearanceFitResult fit;
  ShadingTurn turn;
  cv::Mat3b background;  ///< I_B
  cv::Mat3f albedo;      ///< albedo ratios at rest
  double inpaintMs = 0, totalMs = 0;
  double restPsnr = 0;   ///< the organ composed at rest against the frame, inside its mask (dB)
  cv::Mat3b residual;    ///< what Theta leaves of the frame on the organ (AppearanceLayers::residual)
};

/// The case's registered organ (its fitted shape once there is one, at its pose), camera and frame.
AppearanceInput appearanceInputFromCase(const Case& c);

/// What the case keeps of a run (Theta, what it could tell, its report) and what it was fitted on.
std::shared_ptr<const AppearanceEstimate> estimateFromRun(const AppearanceOutput& out, const Case& c, imaging::InpaintMethod inpaint);

/// The estimate as JSON (Theta in THETA.json's fields, README.md "File formats"; the report, what it was fitted on), and
/// back; the reader throws std::exception naming what is wrong.
std::string appearanceEstimateToJson(const AppearanceEstimate& e);
std::shared_ptr<const AppearanceEstimate> appearanceEstimateFromJson(const std::string& text);

/// What composition takes from the frame at rest, for a Theta: the specular-free image I_D, the background
/// behind the organ I_B, and the albedo ratios. Throws rehearse::InputError as runAppearance does.
struct AppearanceLayers {
  cv::Mat3b diffuse, background;
  cv::Mat3f albedo;
  cv::Mat3b residual;  ///< what Theta leaves: |frame - Theta's render (albedo 1)| x 3 on the organ, black elsewhere
};
AppearanceLayers appearanceLayers(const AppearanceInput& in, const imaging::Appearance& theta);

/// What composition takes for `in`'s organ at rest with those layers (its surface views point into `in`,
/// which must outlive it).
imaging::CompositionInput compositionInput(const AppearanceInput& in, const AppearanceLayers& layers, const imaging::Appearance& theta, imaging::Reshading how);

/// The compositor of `in`'s organ at rest (imaging::Compositor) with those layers.
std::unique_ptr<imaging::Compositor> makeCompositor(const AppearanceInput& in, const AppearanceLayers& layers, const imaging::Appearance& theta, imaging::Reshading how);

/// The composited view after cuts (issue 35): the cut organ's boundary (simcore::CutSurface, the cut mesh's
/// nodes: the organ's volume nodes first, then the cuts' new ones), each node placed where the frame showed it
/// (a new node by its barycentric weights in the uncut rest mesh, applied to the case's shape), drawn with `base`'s
/// frame, layers and Theta. The organ's own faces keep the frame's albedo; its cut faces take a preset interior
/// colour re-shaded by Theta: the parenchyma's, a vessel's blood, or another inner structure's (`said` names
/// them). Throws rehearse::InputError when `cut` is not of this case's organ.
struct CutComposition {
  std::unique_ptr<imaging::Compositor> compositor;
  std::vector<double> restVertices;  ///< the cut mesh's nodes where the frame showed them (model frame, 3n)
  std::string said;                  ///< one sentence: which colours the cut faces take
};
CutComposition makeCutCompositor(const imaging::Compositor& base, const Case& c, const simcore::CutSurface& cut);

/// Throws rehearse::InputError with one sentence for unusable input (organ behind the camera or off the
/// frame, a frame of another size, nothing usable to fit).
AppearanceOutput runAppearance(const AppearanceInput& in);

/// J for the organ's surface moved to `deformedVertices` (same vertex order, model frame, 3n; empty: at rest),
/// its edges anti-aliased by `supersampling`.
cv::Mat3b composeAppearance(const AppearanceInput& in, const imaging::Appearance& theta, const cv::Mat3b& background, const cv::Mat3f& albedo,
                            imaging::Reshading how, const std::vector<double>& deformedVertices = {}, int supersampling = 2);

/// J with a Theta given (no fitting): the background and albedo taken from the frame at rest, the organ moved
/// to `deformedVertices` (empty: at rest). Throws rehearse::InputError as runAppearance does.
/// `how`: re-shaded as far as the fit earned it, or texture only (the frame's own colours follow the tissue).
cv::Mat3b composeWithTheta(const AppearanceInput& in, const imaging::Appearance& theta,
                           const std::vector<double>& deformedVertices = {}, imaging::Reshading how = {});

/// A novel view with a Theta given (issue 35, imaging::composeNovelView): the layers taken from the frame at
/// rest, the organ (moved to `deformedVertices` when given) drawn through `viewCamera` at `viewPose` (model ->
/// that camera) over `viewImage` (or black), re-shaded with the view's own scope light (as far as `how` says), or
/// texture-only.
imaging::NovelView composeNovelViewWithTheta(const AppearanceInput& in, const imaging::Appearance& theta,
                                             const imaging::Camera& viewCamera, const Pose& viewPose,
                                             const cv::Mat3b& viewImage = {},
                                             const std::vector<double>& deformedVertices = {},
                                             imaging::Reshading how = {});

}  // namespace rehearse::app
