#pragma once
// Step 5, the one elastic-fit pipeline: a case's organ, attachments, material (by label), embedded
// surfaces and contour -> simcore::registerToContour. `rehearse register` and the GUI's fit page both
// build a FitInput and call runElasticFit, so the material, attachments and vessels the user set are
// the ones the fit uses, whichever door the fit came in by.
#include "rehearse/app/case.hpp"
#include "rehearse/app/materials.hpp"

#include <rehearse/imaging/motion.hpp>
#include <rehearse/simcore/registration.hpp>

#include <functional>
#include <memory>

namespace rehearse::app {

struct FitInput {
  std::shared_ptr<const Organ> organ;           ///< volume in metres, model frame
  std::vector<int> attachments;                 ///< held nodes
  LabelMaterials materials;
  std::vector<simcore::EmbeddedSurface> embedded;
  simcore::SimulationSettings settings;         ///< solver settings; gravity (model frame) off by default
  /// Which way is down, when known: gravity in the camera frame (m/s^2; zero: not known). The fit
  /// estimates the organ's sag with its pose either way; told this, also the sag along the view, which
  /// the outline cannot show (simcore::RegistrationOptions::gravityCamera).
  Eigen::Vector3d gravityCamera = Eigen::Vector3d::Zero();
  imaging::Contour contour;                     ///< undistorted pixels; anatomical segments' modelVertices are volume nodes
  Pinhole camera;
  Pose start;
  bool rigidPrepass = true;
  bool elastic = true;
  int maxIterations = 20;
  /// Further frames of the organ with their outlines and the features tracked into them
  /// (simcore::RegistrationOptions::frames).
  std::vector<simcore::RegistrationFrame> frames;
  /// The bound a determined fit stays within (mm; simcore::RegistrationOptions::toleranceMm).
  double toleranceMm = 5.0;
  FitInput() { settings.gravity.setZero(); }
};

/// Features tracked from `first` into `second` (undistorted frames of one size) on the organ as sketched on the first
/// frame: inside its silhouette segments, less a margin of 1 % of the width (imaging::trackFeatures).
std::vector<imaging::Track> tracksOnOrgan(const cv::Mat3b& first, const imaging::Contour& firstContour,
                                          const cv::Mat3b& second);

/// The case's second frame for the fit (Case::frame2): its outline, the camera's motion from the first frame estimated
/// from the features tracked on the organ (the move's length Case::baselineMm), with the motion's uncertainty and its
/// inlier tracks; `status` gets the estimate's sentence. Throws rehearse::InputError with one sentence when it cannot
/// be used (no outline on it, no baseline, frames of another size, too few features, barely moved, ...).
simcore::RegistrationFrame secondFrame(const Case& c, std::string* status = nullptr);

/// What the GUI fits: the case as it is (its organ, attachments, material, contour, camera and pose).
FitInput fitInputFromCase(const Case& c);

/// The FEM model the fit deforms (also what a test inspects to check the material reached the fit).
simcore::FemModel fitModel(const FitInput& in);

using FitProgress = std::function<bool(const simcore::RegistrationIteration&, const Eigen::VectorXd& x, const Pose& pose)>;

/// Runs the fit. Throws simcore::MeshError / rehearse::InputError with one sentence for unusable input
/// (no silhouette segment and no curve on the organ, a mesh behind the camera, ...). A fit whose shape cannot be used
/// (fittedShapeProblem) is not ok, its status the sentence.
simcore::RegistrationResult runElasticFit(const FitInput& in, const FitProgress& progress = {});

/// What makes a fit's shape (r.x, r.pose) unusable whatever its distance to the outline, in one sentence with what to do;
/// empty when usable: the organ's surface crossing the camera's image plane (a node of `surface` at or behind the
/// camera), or an element of `model` folded flat (as FemModel::build finds it, which a simulation started from that
/// shape then refuses).
std::string fittedShapeProblem(const simcore::FemModel& model, const std::vector<std::array<int, 3>>& surface,
                               const simcore::RegistrationResult& r);
/// The elements of the fit's shape turned inside out against the rest shape, in words (empty when none): said with a
/// kept fit (the simulation takes them as they are: FemModel::build accepts either sign).
std::string insideOutElements(const simcore::FemModel& model, const simcore::RegistrationResult& r);

/// One sentence for the fit's uncertainty (simcore::RegistrationUncertainty): "the surface may be up to 2.4 mm from
/// where the fit put it (inner targets 3.1 mm), weakest: a move along the view", or that the contour leaves a direction
/// undetermined, or that no bound was computed (no rigid stage).
std::string uncertaintySentence(const simcore::RegistrationUncertainty& u);

/// Where the organ may be after a fit: its outlines (undistorted frame pixels of the case's camera) at the fit's two
/// far ends (simcore::RegistrationUncertainty::ends), the outer outline of each. Empty when the fit has none (no bound,
/// or an unbounded one) or an end is behind the camera.
std::vector<std::vector<Eigen::Vector2d>> boundOutlines(const Case& c, const simcore::RegistrationResult& r);

/// The fit's result as the case part (model frame nodes and the status).
std::shared_ptr<const ElasticFit> toCasePart(const simcore::RegistrationResult& r);

}  // namespace rehearse::app
