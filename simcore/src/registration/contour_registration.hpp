#pragma once
// registerToContour's stages (issue 63): the fit as a class whose members are what the stages share and whose member
// functions are the stages. registration.cpp drives them in order, and the files hold them by stage:
// - registration_problem.cpp: the problem (frames, seen points, contours and curves checked and resampled) and how a
//   state (shape and pose) is measured against it;
// - registration_bindings.cpp: the correspondences (contour, curves and seen points onto the organ) and their rays;
// - registration_sag.cpp: the sag (the held model's responses to a load, its prior) and the sag's probe;
// - registration_rigid.cpp: the rigid stage (ICP on the pose and the sag, candidates, basin hopping);
// - registration_ambiguity.cpp: the probes for other poses, and the ambiguous fit's status;
// - registration_uncertainty.cpp: the bound (the cost's curvature, the hypotheses' spread, the motions') and its ends;
// - registration_elastic.cpp: the elastic stage and the final checks.
// Internal to simcore.
#include <rehearse/simcore/registration.hpp>

#include "registration_parts.hpp"

#include <Eigen/Core>

#include <array>
#include <chrono>
#include <string>
#include <utility>
#include <vector>

namespace rehearse::simcore::detail {

// A contour's segments (pixels).
using ContourSegments = std::vector<std::vector<Eigen::Vector2d>>;
// The organ's silhouette in every frame (View).
using Silhouettes = std::vector<std::vector<SilhouetteEdge>>;

// ---- The correspondences (registration_bindings.cpp) ----

struct Sample {
  Eigen::Vector2d pixel, normal;
};

// A surface point seen in two frames (triangulated, first camera frame) and how much a metre across the surface there
// is worth in the tracker's pixels (the depth's: f b / z^2, less when the motion is uncertain).
struct SeenPoint {
  Eigen::Vector3d target;
  double pxPerMetre;
};

// Contour points at uniform spacing with their 2D normals (perpendicular to the local tangent).
std::vector<Sample> contourSamples(const ContourSegments& contour, double spacing);
// Bindings further than `factor` times the median distance (and than `floorPx`) are outliers.
void dropOutliers(std::vector<Binding>& bindings, double factor, double floorPx);
// For the rigid pass: every contour point to the nearest compatible point of the silhouette edges, outliers dropped.
std::vector<Binding> bindForRigid(const std::vector<Sample>& samples, const std::vector<SilhouetteEdge>& sil,
                                  const RegistrationOptions& o);
// Binds the silhouette to the contour at the silhouette's vertices (see there).
std::vector<Binding> bindContour(const std::vector<Sample>& samples, const std::vector<std::size_t>& segmentStarts,
                                 const std::vector<SilhouetteEdge>& sil, const std::vector<char>& fixed,
                                 const RegistrationOptions& o, double floorPx);
// Every node of the anatomical curves to the nearest point of its image curve.
std::vector<Binding> bindCurves(const std::vector<AnatomicalCurve>& curves, const Eigen::VectorXd& x, const Pose& pose,
                                const Pinhole& cam, const std::vector<char>* fixed);
// The bound point on the ray through its contour point (or, sliding, on the plane through the contour's tangent).
void rayConstraints(const Binding& b, const Pose& pose, const Pinhole& cam, bool sliding,
                    std::vector<ScalarConstraint>& out);
// Each seen point to the nearest surface node facing the first camera, held across the surface there.
std::vector<Binding> bindPoints(const std::vector<SeenPoint>& points, const std::vector<std::array<int, 3>>& surface,
                                const Eigen::VectorXd& x, const Pose& pose, const Pinhole& cam);

// ---- The bound's parts that need no fit (registration_uncertainty.cpp) ----

// How many independent points residuals along a contour are worth (see there). `lagOne` gets rho_1.
double autocorrelationTime(const std::vector<double>& r, double* lagOne = nullptr);
// A direction of the fit's unknowns in words, from its parts in metres at the organ: a turn, a move, the sag.
std::string describeDirection(const Eigen::Vector3d& turn, const Eigen::Vector3d& move, double sag);
// The cost's curvature's share of RegistrationUncertainty (see there), at the rigid stage's end; `facing` and
// `onSurface` get which nodes are on the surface facing the camera and on the surface at all.
RegistrationUncertainty estimateUncertainty(const std::vector<Binding>& bindings, const Eigen::VectorXd& base,
                                            const Eigen::MatrixXd& U, const std::vector<View>& views, bool sliding,
                                            const Pose& pose, const Eigen::Vector3d& load,
                                            const Eigen::Matrix3d& prior, const FemModel& model,
                                            const std::vector<std::array<int, 3>>& surface, const Eigen::VectorXd& x,
                                            const Eigen::Vector3d& centre, std::vector<char>& facing,
                                            std::vector<char>& onSurface, Eigen::VectorXd& weakestDirection);

// ---- The fit ----

// The problem as set up from the inputs (setUpProblem): read by every stage (the motion share of the bound changes
// views and seen for a while, and puts them back).
struct RegistrationProblem {
  // The frames: the first's camera and contour, then the further ones'.
  std::vector<View> views;
  std::vector<const ContourSegments*> contours;
  // The further frames used (RegistrationOptions::frames less those set aside), and those set aside (said in the
  // status).
  std::vector<RegistrationFrame> frames;
  std::string setAside;
  std::vector<int> setAsideFrames;
  std::vector<SeenPoint> seen;  // the features tracked into further frames, triangulated
  std::size_t points = 0;       // the first frame's contour points
  std::vector<AnatomicalCurve> curves;  // checked, their image curves resampled
  std::vector<char> fixed;              // per node: held by the ligaments
  bool held = false;                    // any node held
  // Each frame's contour samples, its segments' starts among them.
  std::vector<std::vector<std::size_t>> segmentStarts;
  std::vector<std::vector<Sample>> samples;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // the organ's centre of mass (model frame)
  double diag = 0;                                   // the image's diagonal (px)
};

// The sag (see RegistrationOptions::estimateSag), set up by setUpSag: the shape is rest + U load.
struct RegistrationSag {
  Eigen::VectorXd rest;
  Eigen::MatrixXd U;  // empty: the shape stays the rest shape in the rigid stage
  // The prior's centre: the given gravity (model frame), usually none.
  Eigen::Vector3d givenLoad = Eigen::Vector3d::Zero();
  bool downKnown = false;    // told which way is down (RegistrationOptions::gravityCamera)
  double weight = 0;         // the prior's weight per bound point and (m/s^2)^2
  std::size_t fewest = 3;    // bindings an update needs
};

// Where the fit is, besides the result's pose and shape (RegistrationResult::pose, x).
struct RegistrationState {
  Eigen::Vector3d load = Eigen::Vector3d::Zero();  // the steady load (model frame, m/s^2)
  int iteration = 0;                               // the last one recorded
  RegistrationIteration first;                     // the start, as recorded
  double probedScore = 0;  // the rigid result's score, which the alternatives' are compared with
};

// The rigid stage's end: where the elastic stage starts, and what it must improve on.
struct RigidEnd {
  Pose pose;
  Eigen::VectorXd x;
  double mean = 0;
};

class ContourRegistration {
 public:
  ContourRegistration(const FemModel& model, const std::vector<int>& fixedNodes, const SimulationSettings& settings,
                      const std::vector<std::array<int, 3>>& surface, const ContourSegments& contour, const Pose& start,
                      const Pinhole& camera, const RegistrationOptions& o);
  // Not copied: problem.contours points into problem.frames.
  ContourRegistration(const ContourRegistration&) = delete;
  ContourRegistration& operator=(const ContourRegistration&) = delete;

  // ---- The stages, in registerToContour's order ----

  // The problem (registration_problem.cpp): the frames, the seen points, the contours and curves checked (MeshError
  // when unusable) and resampled.
  void setUpProblem();
  // The sag's responses and prior (registration_sag.cpp), the start's shape.
  void setUpSag();
  // The start recorded (iteration 0).
  void recordStart();
  // Rigid stage (registration_rigid.cpp): candidates, ICP with the sag, basin hopping.
  void rigidStage();
  // Does the contour determine the pose? (registration_ambiguity.cpp; the alternatives, a deeper minimum adopted)
  void probePoses();
  // Does the contour determine the sag? (registration_sag.cpp)
  void probeSag();
  // How far the result may be from the truth (registration_uncertainty.cpp).
  void estimateBound();
  // The load the elastic stage uses, and the rigid stage's end (registration.cpp).
  RigidEnd endRigidStage();
  // Elastic stage (registration_elastic.cpp): static equilibrium with the bound points on their rays, rebinding.
  void elasticStage(const RigidEnd& rigid);
  // A fit that leaves the contour far from the organ, or most of it off the silhouette, fails.
  void checkFinalFit();
  // The far ends of where the organ may be (RegistrationUncertainty::ends).
  void computeEnds();
  // An ambiguous fit said so in the status, with what would decide it.
  void sayAmbiguity();

  // ---- The stages' parts ----

  // registration_problem.cpp
  void setUpFrames();
  std::vector<SeenPoint> triangulateSeen() const;
  void checkContours();
  void sampleContours();
  double elapsedMs() const;
  Silhouettes silhouettesOf(const Eigen::VectorXd& x, const Pose& pose) const;
  const Silhouettes& silhouette(const Eigen::VectorXd& x, const Pose& pose);
  RegistrationIteration measure(const Silhouettes& sil, const Eigen::VectorXd& x, const Pose& pose) const;
  RegistrationIteration record(int it, const char* stage, std::size_t bound);
  double score(const Eigen::VectorXd& x, const Pose& pose);

  // registration_sag.cpp
  Eigen::MatrixXd sagResponses() const;
  Eigen::Matrix3d downAcrossCamera() const;
  Eigen::Matrix3d priorMatrix(const Pose& pose, std::size_t bound) const;
  Eigen::VectorXd shapeOf(const Eigen::Vector3d& a) const;

  // registration_rigid.cpp
  // A short ICP run's end and score.
  struct IcpEnd {
    Pose pose;
    Eigen::Vector3d load;
    double score;
  };
  std::vector<Binding> rigidBindings(const Silhouettes& sil, const Eigen::VectorXd& x, const Pose& pose) const;
  void refine(const Eigen::VectorXd& x, const std::vector<Binding>& bindings, Pose& pose, Eigen::Vector3d& a) const;
  std::pair<Pose, double> shortIcpHeld(Pose pose, int iterations) const;
  IcpEnd shortIcp(Pose pose, Eigen::Vector3d a, int iterations) const;
  IcpEnd bestOf(const std::vector<Pose>& starts, const Eigen::Vector3d& a, int iterations) const;
  std::vector<Pose> posesAround(const Pose& pose, double distance, double degrees) const;
  std::vector<Pose> startCandidates();
  void polish(double previous, double bestMean);

  // registration_ambiguity.cpp
  std::string ambiguityText() const;
  std::string whatWouldDecide();

  // registration_uncertainty.cpp
  void curvatureBound();
  std::pair<double, double> spreadOf(const Pose& pose, const Eigen::VectorXd& x) const;
  void nameFarthest(const RegistrationAlternative* farthest);
  void addMotionShare(double spread, bool measured);

  // registration_elastic.cpp
  std::vector<Binding> elasticBindings(const Eigen::VectorXd& x, double outlierFloor, double cap);
  void elasticStatus(const RigidEnd& rigid, double bestMean, const std::string& failure);

  // ---- What the stages share ----

  const std::chrono::steady_clock::time_point t0;
  // The inputs, as registerToContour got them (settings: a copy, the fit sets its gravity and solver's tolerance).
  const FemModel& model;
  const std::vector<int>& fixedNodes;
  SimulationSettings settings;
  const std::vector<std::array<int, 3>>& surface;
  const ContourSegments& contour;
  const Pose& start;
  const Pinhole& camera;
  const RegistrationOptions& o;

  RegistrationProblem problem;
  RegistrationSag sag;
  RegistrationState current;
  // The silhouettes of the last state asked for: recording an iteration and binding the next one look at
  // the same state, and the depth buffer is the costly part.
  struct {
    Eigen::VectorXd x;
    Pose pose;
    Silhouettes edges;
    bool valid = false;
  } last;
  // Does the contour determine the sag (probeSag)? Where the loosened sag puts the organ (x empty: not probed).
  struct {
    bool undetermined = false;
    double share = 1, apartMm = 0;
    Pose pose;
    Eigen::VectorXd x;
  } sagProbe;
  // The bound's direction as a hypothesis the fit's far ends lie towards (RegistrationUncertainty::ends): the pose and
  // shape it moves the result (`from`) to.
  struct {
    Pose pose, fromPose;
    Eigen::VectorXd x, fromX;  // empty: none
  } toward;
  // Which nodes are on the surface facing the camera, and on the surface at all (empty: the bound not computed).
  std::vector<char> facing, onSurface;
  // The result being built.
  RegistrationResult res;
};

}  // namespace rehearse::simcore::detail
