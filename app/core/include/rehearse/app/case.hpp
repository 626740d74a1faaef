#pragma once
// The case document: everything the user made for one case, and nothing the program merely derived for
// drawing. It is a value (copied for each undo state), so that undo, autosave on a worker thread and the
// simulation session can all hold a consistent version of it without locks. Large immutable parts are
// shared between versions instead of copied: the organ (mesh, surfaces, quality), the frame (cv::Mat is
// reference-counted), the ground truth and the elastic fit's nodes. An edit therefore copies only what it
// changes: a pose edit on a 20k-tet organ copies a few kilobytes, not the mesh.
//
// Where things live (the "rooms", see README "Code layout"):
//   app::Case                 this file: the document's parts
//   app/workflow.hpp          the steps (what each needs, done, next), no hard-coded counts
//   app/elasticfit.hpp        step 5, the one elastic-fit pipeline (GUI and `rehearse register`)
//   app/casefolder.hpp        a case as a folder of ordinary files; the case file (SQLite) is ui/casefile
//   app/materials.hpp         the case's material -> simcore materials by label (fit and simulation)
//   app/appearancestep.hpp    step 6, the one appearance pipeline (GUI and `rehearse appearance`)
// Rehearsal recordings (step 7, replay) add a list of recorded sessions, a shared_ptr<const ...> part like
// `fit` and `appearance`.
// No Qt here (tests/check_layering.cmake).
#include <rehearse/imaging/appearance.hpp>
#include <rehearse/imaging/appearance_fit.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/mesh.hpp>
#include <rehearse/simcore/quality.hpp>

#include <opencv2/core.hpp>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace rehearse::phantom {
struct Phantom;
struct VesselSegment;
}  // namespace rehearse::phantom

namespace rehearse::app {

inline constexpr int kParenchymaLabel = 1;
inline constexpr int kVesselLabel = 2;

/// The organ's own surface as it was imported (tens of thousands of triangles, finer than the simulation
/// mesh's boundary; Courtecuisse et al. 2014, SOFA's visual models): the composited view draws it instead of
/// the elements' boundary, each vertex carried by the tetrahedron that holds it (barycentric weights at rest,
/// simcore::embedPoints), its normals recomputed from the deformed surface, the frame's texture following it.
struct VisualSurface {
  std::vector<Eigen::Vector3d> points;  ///< at rest, model frame, metres
  std::vector<std::array<int, 3>> triangles;
  simcore::SurfaceEmbedding embedding;  ///< each point in the volume's rest mesh

  /// Builds it for `volume` (metres), or returns null with a sentence in `why` when the surface is not that
  /// volume's (a vertex farther outside it than 5 % of the organ's size: a coarse mesh's boundary cuts
  /// corners by a few mm, 4.3 mm on the 220 mm patient liver at 3k tetrahedra) or has no triangles.
  static std::shared_ptr<const VisualSurface> make(const simcore::Mesh& volume, const simcore::Mesh& surface,
                                                   std::string* why = nullptr);
  /// Its points for the volume's nodes at `nodes` (volume node order, any frame); empty when `nodes` is not
  /// the volume it was made for (another node count, as after a cut).
  std::vector<Eigen::Vector3d> map(const std::vector<Eigen::Vector3d>& nodes) const;
  std::size_t nodeCount = 0;  ///< of the volume it was made for
  std::size_t bytes() const;
};

/// The organ: its volume mesh and what is derived from it once, where it is made (on a worker thread).
/// Immutable once built; shared between undo states.
struct Organ {
  simcore::Mesh volume;                          ///< tets with labels (1 parenchyma, others inner structures); model frame
  std::vector<std::array<int, 3>> surface;       ///< outer boundary triangles (indices into volume.points)
  std::vector<std::array<int, 3>> innerSurface;  ///< faces between labels, outward from the inner label
  std::vector<int> innerSurfaceLabels;           ///< the inner label of each of those faces
  simcore::QualityReport quality;
  Eigen::Vector3d centreOfGravity = Eigen::Vector3d::Zero();  ///< volume-weighted, model frame, mesh unit
  std::string source;                            ///< file it came from ("" for the built-in phantom)
  /// Metres per length unit of that file (the volume itself is in metres): a 4x4 pose matrix, which has no
  /// unit of its own, is read in it, as `rehearse register --unit` does.
  double sourceUnitToMetre = 1.0;
  /// The surface drawn in the composited view; null: the volume's boundary (`surface`) is drawn.
  std::shared_ptr<const VisualSurface> visual;

  bool empty() const { return volume.tets.empty(); }
  /// Derives surfaces, quality and centre from `volume` (the expensive part of making an organ).
  /// With `visualSurface` (metres), that surface is embedded as the visual one (VisualSurface::make); when it
  /// cannot be, `why` says so and the boundary is drawn.
  static std::shared_ptr<const Organ> fromVolume(simcore::Mesh volume, std::string source = {},
                                                 double sourceUnitToMetre = 1.0,
                                                 const simcore::Mesh* visualSurface = nullptr,
                                                 std::string* why = nullptr);
};

/// What a case knows independently of the user (the phantom's, or a study's): kept apart from the user's work.
struct GroundTruth {
  Pose pose;                                   ///< model -> camera
  imaging::Appearance appearance;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> vesselAxes;  ///< vessel centre-line segments (model frame, m)
  std::vector<double> vesselRadii;             ///< m, one per segment
};

/// Step 5's result: the organ's nodes after the fit (model frame, metres, volume node order) and its status.
struct ElasticFit {
  std::vector<Eigen::Vector3d> nodes;
  std::string status;
};

/// Step 6's result: Theta fitted to the frame through the registered organ, what the frame did and did not
/// determine, and what it was fitted on. A later change of the pose, the shape or the frame makes it stale
/// (Case::appearanceCurrent): it is kept, but not used to compose, until estimated again.
struct AppearanceEstimate {
  imaging::Appearance theta;
  bool highlightFound = false;
  bool textureOnly = false;                    ///< the model explained too little: the frame's texture is shown, not re-shaded
  std::array<bool, 3> ksMeasured{true, true, true};
  double explained = 0;                        ///< share of the organ's shading the diffuse model explains
  /// How the organ is drawn from this estimate: texture only, or re-shaded as far as its share explained earned
  /// (imaging::reshadeTrust).
  imaging::Reshading reshading() const { return imaging::Reshading::of(explained, textureOnly); }
  double smoothShare = 0;     ///< the same share for a smooth function of the image position (a reference)
  bool lightAtBound = false;  ///< the light ended on the search's bound: not placed by the frame
  std::vector<imaging::AppearanceFitResult::Check> checks;  ///< each part of the model switched off
  double scopeExplained = 0;  ///< the share the scope's light alone explains (AppearanceFitResult::scopeExplained)
  std::vector<imaging::AppearanceFitResult::Source> sources;  ///< the second sources tried, and the one used
  std::string status;                          ///< one sentence
  /// What step 6 did about the turn the outline leaves open (app::ShadingTurn::sentence; empty: not asked), and
  /// whether it turned the organ (the pose below is then the turned one, which the case took with the estimate).
  std::string turnSaid;
  bool turned = false;
  std::string inpaint = "telea";               ///< how I_B was filled (imaging::parseInpaintMethod)
  std::vector<imaging::AppearanceStage> stages;
  double restPsnr = 0;                         ///< dB, the organ composed at rest against the frame inside its mask
  double totalMs = 0;
  Pose pose;                                   ///< what it was fitted on: the pose ...
  double shapeDigest = 0;                      ///< ... the shape (Case::shapeDigest) ...
  int frameWidth = 0, frameHeight = 0;         ///< ... and the frame's size
  double frameDigest = 0;                      ///< ... and content (Case::frameDigest)
};

/// Where gravity points in the rehearsal, a stated choice of the case (the Simulation panel's Gravity): into the scene
/// (along the camera's view: a laparoscope looks down into a supine patient), down in the image (+y), or off.
enum class GravityChoice { DownInTheImage = 0, IntoTheScene = 1, Off = 2 };

/// The case's material, set in the Simulation panel and used by both the elastic fit and the simulation.
struct MaterialSettings {
  simcore::MaterialModel model = simcore::MaterialModel::Corotational;
  double young = 27e3;      ///< Pa, parenchyma (label 1 and unlisted labels)
  double poisson = 0.4;
  double density = 1000;    ///< kg/m^3
  double vesselYoung = 0;   ///< Pa for kVesselLabel (0: as the parenchyma)
  double vesselPoisson = 0.45;
  /// The engineering strain at which the tissue (and the vessels) tear in the rehearsal (MaterialParams::tearStrain);
  /// 0: they do not tear.
  double tearStrain = 0;
  /// Pa/m: the tissue around the organ carries it, an elastic foundation under the surface facing along gravity
  /// (simcore/support.hpp; its default, 1e5, is simcore::kDefaultSupportModulus); 0: only the held nodes hold it.
  double supportModulus = 1e5;
  /// Where gravity points in the rehearsal (cases saved before it: into the scene).
  GravityChoice gravity = GravityChoice::IntoTheScene;
  bool operator==(const MaterialSettings&) const = default;
};

/// Step 4's landmark pair: a point on the organ and where it is in the frame (the user's work: saved, undoable).
struct LandmarkPair {
  Eigen::Vector3d model = Eigen::Vector3d::Zero();  ///< point on the mesh, model frame (m)
  Eigen::Vector2d image = Eigen::Vector2d::Zero();  ///< where it is in the undistorted frame (px)
  bool hasImage = false;
  bool operator==(const LandmarkPair&) const = default;
};

struct Case {
  std::string name;
  std::shared_ptr<const Organ> organ = std::make_shared<Organ>();  ///< never null (an empty organ before step 1)
  std::vector<int> attachments;          ///< 0-based volume node indices held by ligaments (q(j) = 1)
  MaterialSettings material;
  imaging::Camera camera;
  /// Which way gravity points in the camera frame (a unit vector; zero: not known), as the user said on
  /// the fit page: the elastic fit then also finds the organ's sag along the view.
  Eigen::Vector3d down = Eigen::Vector3d::Zero();
  cv::Mat3b frame;                       ///< undistorted endoscope frame, BGR (what every step uses)
  cv::Mat3b rawFrame;                    ///< the frame as captured, when it had to be undistorted (else empty)
  imaging::Contour contour;              ///< sketched organ outline (pixels of the undistorted frame)
  /// A second frame of the same scene with the scope moved 1-2 cm (issue 38; undistorted with `camera` like `frame`;
  /// empty: none), the outline sketched on it, and how far the scope moved (mm: two frames give only the move's
  /// direction). The fit estimates the camera's motion from features tracked between the frames (app::secondFrame).
  cv::Mat3b frame2;
  imaging::Contour contour2;
  double baselineMm = 0;
  Pose pose;                             ///< current rigid alignment, model -> camera
  bool hasPose = false;                  ///< false until the organ has been placed (auto or by hand)
  bool poseAligned = false;              ///< true once the user aligned it (gizmos, fields or PnP)
  std::vector<LandmarkPair> landmarks;  ///< step 4's pairs (model points on the rest shape)
  std::shared_ptr<const ElasticFit> fit;           ///< null until step 5 ran
  std::shared_ptr<const GroundTruth> groundTruth;  ///< null unless the case came with one
  std::shared_ptr<const AppearanceEstimate> appearance;  ///< null until step 6 ran
  /// The trainer's incorrect-action rules for rehearsals of this case (incorrect_actions.hpp, JSON without a view:
  /// the case's camera is the view); empty: the defaults.
  std::string incorrectActions;

  /// The organ's node positions as the user sees them (model frame): the fitted ones after step 5,
  /// the rest shape before. Sized like organ->volume.points.
  const std::vector<Eigen::Vector3d>& shapeNodes() const;
  bool hasFit() const { return fit && fit->nodes.size() == organ->volume.points.size(); }
  /// The pose is the organ's in the frame: aligned by the user, or placed by a completed elastic fit (which finds the
  /// pose with the shape). Otherwise it is at most the automatic first guess, which nothing should take for one.
  bool poseDetermined() const { return hasPose && (poseAligned || hasFit()); }
  /// A number that changes when the shape (shapeNodes) changes, and one for the frame's pixels.
  double shapeDigest() const;
  double frameDigest() const;
  /// True when step 6's estimate was made on this pose, shape and frame (composition may use it).
  bool appearanceCurrent() const;
  /// The organ's outer surface as drawn (the fitted shape once there is one).
  SurfaceView surfaceView() const;
  /// A first placement: the organ's centre on the optical axis, unrotated, at the distance where it
  /// spans about 60 % of the image width, or farther when that would take it out of the middle 90 % of
  /// the image either way (a large, deep or tall organ).
  Pose automaticPose() const;
  /// Replaces the organ: clears everything that referred to the old one (attachments, fit) and places it.
  void setOrgan(std::shared_ptr<const Organ> organ);
  /// Bytes this version holds on its own (not counting parts it shares with other versions).
  std::size_t ownBytes() const;
  /// Bytes of the shared parts (organ, fit, frames).
  std::size_t sharedBytes() const;
};

/// A case from the built-in phantom: the organ, its attachments, camera, frame and ground truth;
/// the organ placed automatically.
Case caseFromPhantom(const phantom::Phantom& p);

/// The frame every step uses: the captured one undistorted with the case's camera (same K, so pixels keep
/// the pinhole model). Without distortion it is the captured frame itself. Needs rawFrame.
void undistortFrame(Case& c);

}  // namespace rehearse::app
