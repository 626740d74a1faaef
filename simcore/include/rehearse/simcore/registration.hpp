#pragma once
// Elastic registration of the organ onto a sketched silhouette (Adagolodjo et al. 2017; the design brief ../shared/DESIGN.md):
// the visible silhouette of the deformed surface is projected through the camera, every contour point is
// bound to the nearest compatible silhouette point (2D normals, outliers rejected), and the bound points
// are held on the rays through their contour points (constraints in the image plane only; the elastic
// model alone decides depth) by the integrator's Lagrange-multiplier constraints, to static equilibrium.
// Rebinding and solving repeat until the 2D residual settles. Attachments and embedded structures of the
// model still apply. A rigid-only pre-pass (pose refined on the same bindings) is optional.
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/types.hpp>

#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::simcore {

/// A piece of the visible silhouette: the surface edge (nodes a, b) and its projection.
struct SilhouetteEdge {
  int a = -1, b = -1;
  Eigen::Vector2d pa, pb;    ///< pixels
  Eigen::Vector2d normal;    ///< unit 2D normal, pointing away from the visible face
  /// The smooth organ's outline is not the chord between two surface nodes: the edge bulges like the
  /// curve of a PN triangle (cubic from the nodes' normals), by `bulge` at its middle (model frame, m); the
  /// point at parameter s along the edge is lerp(a, b, s) + 4 s (1 - s) bulge, and `pm` is the middle's pixel.
  Eigen::Vector3d bulge = Eigen::Vector3d::Zero();
  Eigen::Vector2d pm = Eigen::Vector2d::Zero();
  /// The point of the curved edge nearest to p: its parameter along the edge (two straight halves through pm).
  double nearest(const Eigen::Vector2d& p, double* distance = nullptr) const;
};

/// The visible silhouette of a closed surface (triangles over the positions x, model frame, 3n) seen
/// through `pose` and `camera`: front faces whose three vertices pass a depth-buffer test, and the edges
/// between a visible face and a non-visible one (or the border of an open surface). Exact for non-convex
/// organs up to the depth buffer's resolution (the image's). Throws MeshError when a vertex is behind the
/// camera or the camera is unusable.
std::vector<SilhouetteEdge> visibleSilhouette(const std::vector<std::array<int, 3>>& triangles, const Eigen::VectorXd& x,
                                              const Pose& pose, const Pinhole& camera);

/// Distances from contour points to the silhouette (pixels): mean, RMS and Hausdorff (the largest of
/// the two directed distances, the silhouette side measured only near the contour's extent).
struct Residual2D {
  double mean = 0, rms = 0, hausdorff = 0;
  std::size_t points = 0;
};
Residual2D contourResidual(const std::vector<std::vector<Eigen::Vector2d>>& contour, const std::vector<SilhouetteEdge>& silhouette);

/// An anatomical curve: a 3D curve picked on the organ (surface nodes in order along it, such as the
/// liver's ridge or the falciform ligament) and the same curve drawn in the image (pixels, undistorted
/// frame). Each of its nodes is held on the ray through the nearest point of the image curve, so, like the
/// silhouette, it acts in the image plane only; nodes whose nearest point is an end of the image curve
/// (the 3D curve picked longer than the drawn one) are left free.
struct AnatomicalCurve {
  std::vector<int> nodes;
  std::vector<Eigen::Vector2d> image;
  std::string type = "ridge";
};

/// The shortest path along the surface's edges (lengths over `points`) from node `from` to node `to`, both
/// included: how a curve picked by a few clicks on the organ becomes a chain of surface nodes. Empty when
/// they are not connected.
std::vector<int> surfacePath(const std::vector<std::array<int, 3>>& triangles, const std::vector<Eigen::Vector3d>& points, int from, int to);

/// Distances (px) from the points of the image curves to the projected 3D curves (polylines through the
/// projected nodes), as contourResidual measures the silhouette.
Residual2D curveResidual(const std::vector<AnatomicalCurve>& curves, const Eigen::VectorXd& x, const Pose& pose, const Pinhole& camera);

struct RegistrationIteration {
  int iteration = 0;
  double wallMs = 0;          ///< since the start
  Residual2D residual;        ///< silhouette contour to the organ's silhouette
  Residual2D curves;          ///< anatomical curves (when given)
  /// Features seen in two frames (RegistrationFrame::tracks), across the surface, in pixels of their depth's
  /// sensitivity (f b / z^2 per metre)
  Residual2D points;
  std::size_t bound = 0;      ///< contour and curve points bound
  std::string stage;          ///< "start", "rigid", "elastic"
  /// The mean distance over every silhouette, curve and seen point: what the fit minimises and compares.
  double score() const {
    const std::size_t n = residual.points + curves.points + points.points;
    return n ? (residual.mean * residual.points + curves.mean * curves.points + points.mean * points.points) / n : 0.0;
  }
};

/// Another frame of the same organ (RegistrationOptions::frames): the camera moved between the frames (the organ
/// did not), and the outline was sketched on this frame too. Its parallax fixes what one outline leaves to the
/// model: the depth, and the turns that keep the outline's shape.
struct RegistrationFrame {
  Pinhole camera;
  /// The camera's motion from the first frame's: a point q in the first frame's camera frame is at motion.apply(q)
  /// in this frame's (e.g. from features tracked between the frames, estimateCameraMotion).
  Pose motion;
  std::vector<std::vector<Eigen::Vector2d>> contour;  ///< pixels of this frame (undistorted)
  /// Features tracked from the first frame to this one (pixel in the first, pixel in this one; undistorted): each is
  /// triangulated through the motion and holds the organ's visible surface there (the rigid stage), weighted by how
  /// well the baseline fixes its depth. May be empty (the outlines alone).
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> tracks;
  /// How far the motion's own uncertainty moves the depth of what both frames see (1 sigma, m; e.g.
  /// imaging::CameraMotion::depthSigmaM): twice it is added to the fit's bound. 0: the motion is known (a stereo
  /// scope's calibration, a tracked or robot-held scope). Over RegistrationOptions::toleranceMm (1 sigma): the frame is
  /// set aside (RegistrationResult::setAsideFrames).
  double motionDepthSigmaM = 0;
  /// The estimated motion moved by its 1-sigma uncertainty the way that moves depth most (e.g.
  /// imaging::CameraMotion::motionAtOneSigma): the fit's pose is fitted again through it and twice how far that moves
  /// the surface is the bound's motion share (RegistrationUncertainty::motionMm); without it, twice motionDepthSigmaM.
  std::optional<Pose> motionAtOneSigma;
};

/// A point seen in two frames: the point of the first camera frame nearest to both rays (m), and how far apart the
/// rays pass there in pixels of the first frame (a mismatched track passes far apart). False when the rays are nearly
/// parallel (under 0.2 degrees) or meet behind either camera.
bool triangulateTrack(const Pinhole& first, const Pinhole& other, const Pose& motion, const Eigen::Vector2d& inFirst,
                      const Eigen::Vector2d& inOther, Eigen::Vector3d& point, double& gapPx);

struct RegistrationOptions {
  int maxIterations = 20;
  double tolerance = 0.05;     ///< px: stop when the mean residual changes less than this
  double normalDot = 0.5;      ///< |n_contour . n_silhouette| at least this to bind
  double outlierFactor = 3.0;  ///< drop bindings further than this times the median (and than 2 % of the image diagonal)
  double spacing = 6.0;        ///< px between the contour points used (the contour is resampled)
  bool rigidPrepass = false;   ///< refine the pose on the bindings before deforming
  bool elastic = true;         ///< false: rigid only
  int rigidIterations = 15;
  /// Rigid stage: after ICP, try short ICP runs from moves of hopDistance along and turns of hopDegrees
  /// about each camera axis, and continue from a clearly better one (up to three rounds).
  bool hops = true;
  double hopDistance = 0.003;  ///< m
  double hopDegrees = 3.0;
  /// Bound points slide along the contour (one constraint across it per point) instead of being held at the
  /// foot of their perpendicular (two, across the ray).
  bool sliding = true;
  /// After the rigid stage, short rigid fits from poses spread around its result (moves of probeDistance
  /// along and turns of probeDegrees about each camera axis): an end that fits the contour nearly as well
  /// (mean distance within ambiguityPx or ambiguityShare of the result's) with the organ's nodes more than
  /// ambiguityMm from the result's on average makes the fit ambiguous.
  bool probeAmbiguity = true;
  double probeDistance = 0.015;  ///< m
  double probeDegrees = 15.0;
  double ambiguityPx = 0.5;
  double ambiguityShare = 0.25;
  double ambiguityMm = 5.0;
  /// A probe's end that fits the contour more than adoptShare better than the rigid result is a deeper
  /// minimum the rigid stage missed: the fit continues from it, up to adoptRounds times.
  double adoptShare = 0.15;
  int adoptRounds = 2;
  /// After the rigid stage, when the organ is held (fixed nodes), the pose is refined together with the
  /// organ's sag under an unknown steady load (gravity, whose direction and size relative to the organ's
  /// stiffness the fit cannot know): three linear responses of the held model to a unit body acceleration
  /// along the model's axes, combined by the contour. The sag found is the load of the elastic stage. Without
  /// it a sagging organ's outline is explained by a wrong pose (moved and turned, mostly along the view).
  bool estimateSag = true;
  /// Prior on the sag: a load (away from the given gravity) whose sag moves the organ's nodes by this much
  /// on average (RMS, mm) costs as much as one pixel at every bound contour point, so a sag the contour
  /// does not show stays small.
  double sagScaleMm = 5.0;
  /// With probeAmbiguity and the sag estimated: the rigid fit is run again with the sag's prior
  /// sagProbeLoosen times weaker. When the sag found is less than sagDeterminedShare of the one the contour
  /// alone asks for (the prior decided most of it) and the two fits put the organ's nodes more than
  /// sagDecisiveMm apart on average, the contour does not show how far the organ sags: ambiguous.
  double sagProbeLoosen = 16.0;
  double sagDeterminedShare = 0.5;
  double sagDecisiveMm = 2.0;
  /// Which way is down, when known: gravity in the camera frame (m/s^2; zero: not known). It gives what the
  /// outline cannot show: the sag's part along the view relative to its part in the image (a sag across the
  /// direction, in the plane of the direction and the view, costs downAcross^2 times more; down along the view:
  /// every part across it). A sag across it within the image plane the outline shows, and loads other than
  /// gravity (an instrument, a retractor) put one there: it costs what it costs without the direction. Its size
  /// does not count: how far the organ sags depends on a stiffness the fit does not know, so that is the
  /// contour's to find as without it. For an organ the fit does not hold, it is the elastic stage's gravity.
  Eigen::Vector3d gravityCamera = Eigen::Vector3d::Zero();
  double downAcross = 4.0;
  /// Optional anatomical curve constraints, used by the rigid and the elastic stages.
  std::vector<AnatomicalCurve> curves;
  /// Further frames with their outlines (a second frame: the camera moved 1-2 cm): every stage fits all the
  /// outlines at once (the pose is the first frame's). Curves are the first frame's.
  std::vector<RegistrationFrame> frames;
  /// The tracker's noise (px, each frame) that a seen point's depth is weighed by.
  double trackNoisePx = 0.5;
  /// A fit is determined only when its own bound (RegistrationUncertainty::surfaceMm) is at most this (mm): one whose
  /// bound is larger is ambiguous, said so with the bound and what would decide it. Infinity: the bound is reported
  /// only.
  double toleranceMm = 5.0;
  /// Called after every iteration with the current positions (model frame) and pose; false cancels.
  std::function<bool(const RegistrationIteration&, const Eigen::VectorXd& x, const Pose& pose)> onIteration;
};

/// Another pose the contour allows nearly as well as the result's (an ambiguous fit's alternatives).
struct RegistrationAlternative {
  Pose pose;                ///< model -> camera (the shape is the rest shape)
  double score = 0;         ///< px, as RegistrationIteration::score, after a rigid fit from it
  double apartMm = 0;       ///< mean distance of the organ's nodes between this pose and the result's
};

/// One far end of where the fit may be (RegistrationUncertainty::ends): the organ's pose and nodes (model frame).
struct RegistrationEnd {
  Pose pose;
  Eigen::VectorXd x;
};

/// How far the fit's 3D result may be from the truth, from the fit itself (never a fixed threshold):
/// - the cost's curvature: Gauss-Newton's information matrix of the rigid stage's contour cost in the pose (and the
///   sag's load, with its prior loosened as the sag probe loosens it) at its end, scaled by that stage's own misfit
///   (the residuals' variance, times their integrated autocorrelation time along the contour: a smooth misfit, the
///   deformation the pose cannot explain, is worth fewer independent points than it has), propagated to the organ's
///   nodes (two standard deviations);
/// - the spread of the hypotheses that fit as well: the alternatives' and the loosened sag's distance from the result.
/// The two add (the truth may lie at the far end of the hypotheses and off by the curvature's share from there). A
/// direction the contour does not constrain at all (a singular information matrix) makes the bound infinite, with the
/// direction named in `weakest`. Computed after the rigid stage (not when it does not run: `computed` false).
struct RegistrationUncertainty {
  bool computed = false;
  double surfaceMm = -1;    ///< mean over the surface nodes facing the camera
  double targetMm = -1;     ///< the largest over the inner nodes (any inner target)
  double curvatureMm = -1;  ///< the cost's curvature's share (surface, mean)
  double spreadMm = 0;      ///< the hypotheses' share (the farthest alternative or sag probe)
  double motionMm = 0;      ///< the estimated camera motions' share (2 sigma of the depth they move; 0: given)
  double misfitPx = 0;      ///< the rigid stage's residual (RMS, px) the curvature is scaled by
  double correlation = 0;   ///< the residuals' lag-one correlation along the contour
  double autocorrelationTime = 1;  ///< their integrated autocorrelation time (points): the variance's inflation
  /// e.g. "a move along the view", "a turn about the camera's X axis", "the organ's sag": the curvature's largest
  /// direction, or, where the hypotheses spread further, the farthest one's.
  std::string weakest;
  /// Where the organ may be: the result moved each way along the direction the bound's largest share comes from (the
  /// curvature's weakest direction, the farthest hypothesis, or an estimated motion's refit), so far that the surface
  /// facing the camera moves by surfaceMm on average. Two ends, or none (no bound computed, or an infinite one). The
  /// fit page draws their outlines.
  std::vector<RegistrationEnd> ends;
};

struct RegistrationResult {
  /// RegistrationOptions::frames not used (their indices): an estimated motion (motionDepthSigmaM) leaving the depth
  /// more uncertain than toleranceMm; the status says so. The fit is then the other frames'.
  std::vector<int> setAsideFrames;
  bool ok = false;          ///< a usable result (possibly not converged; see status)
  /// Usable, but the contour does not determine the pose: `alternatives` fit it nearly as well far from
  /// the result (or the pose has a direction the contour does not constrain, or the fit's own bound exceeds
  /// RegistrationOptions::toleranceMm); `status` says which and what would decide it. `rehearse register` exits 4.
  bool ambiguous = false;
  std::vector<RegistrationAlternative> alternatives;
  bool converged = false;
  bool cancelled = false;
  std::string status;       ///< one sentence
  Eigen::VectorXd x;        ///< node positions, model frame (3n)
  Pose pose;                ///< model -> camera
  std::vector<RegistrationIteration> iterations;
  /// The steady load the fit settled on (model frame, m/s^2): the given gravity, or the one estimated with
  /// the sag (RegistrationOptions::estimateSag).
  Eigen::Vector3d load = Eigen::Vector3d::Zero();
  /// Whether the contour shows the sag (RegistrationOptions::sagDeterminedShare; true when not probed), the
  /// share of the sag the contour alone asks for that the fit found, and how far apart the two put the organ.
  bool sagDetermined = true;
  /// How many times a probe found a clearly deeper minimum and the fit continued from it.
  int adopted = 0;
  double sagShare = 1.0;
  double sagApartMm = 0.0;
  RegistrationUncertainty uncertainty;
};

/// Registers `model` (rest shape at the start) onto the contour (segments of pixels in the undistorted
/// frame). `fixedNodes` and `settings` as for the Integrator (the solve is static; gravity as given).
/// The contour may be empty when anatomical curves are given. Throws MeshError for unusable input (empty or
/// single-point contour without curves, a curve with fewer than two nodes or image points or with a node the
/// model does not have, mesh behind the camera).
RegistrationResult registerToContour(const FemModel& model, const std::vector<int>& fixedNodes, SimulationSettings settings,
                                     const std::vector<std::array<int, 3>>& surface,
                                     const std::vector<std::vector<Eigen::Vector2d>>& contour, const Pose& start,
                                     const Pinhole& camera, const RegistrationOptions& options = {});

}  // namespace rehearse::simcore
