#pragma once
// Step 4's pose from landmark pairs (a point on the organ, model frame; where it is in the undistorted
// frame, pixels): several PnP solvers (SQPnP, EPnP, and Levenberg-Marquardt started from the current
// pose), each refined, and the one with the smallest reprojection error in front of the camera wins; a few
// landmarks on an organ's front are nearly coplanar, where a single solver can land on the mirror pose.
#include <rehearse/imaging/camera.hpp>

#include <optional>
#include <vector>

namespace rehearse::imaging {

struct PnPResult {
  Pose pose;                 ///< model -> camera
  double rmsPixels = 0;      ///< reprojection error (px)
  /// Another pose, turned more than 10 degrees from this one, reprojects nearly as well (within 1 px RMS or
  /// twice this one's): the landmarks do not decide between them (few, close to a plane); add landmarks.
  bool ambiguous = false;
  double alternativeRmsPixels = -1;  ///< that pose's RMS (px), when ambiguous
};

/// Needs 4 pairs or more; nullopt when no solver finds a pose in front of the camera (the landmarks do not
/// determine one). `model` in the mesh's unit, `image` in pixels of the undistorted frame.
std::optional<PnPResult> poseFromLandmarks(const Camera& camera, const std::vector<Eigen::Vector3d>& model,
                                           const std::vector<Eigen::Vector2d>& image, const Pose& start);

}  // namespace rehearse::imaging
