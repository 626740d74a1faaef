#pragma once
// A second frame's camera motion (issue 38): features on the organ tracked from the first frame to the second
// (Shi-Tomasi corners, pyramidal Lucas-Kanade there and back), and the camera's motion between the frames from them
// (OpenCV's essential matrix with RANSAC, the rotation and the move's direction that put the points in front of both
// cameras, refined on all the tracks they explain with OpenCV's Levenberg-Marquardt). Two frames fix the move's
// direction, never its length: that is given (a stereo scope's baseline, a tracked or robot-held scope), or the fit
// cannot use the frame for depth.
#include <rehearse/imaging/camera.hpp>

#include <opencv2/core.hpp>

#include <string>
#include <utility>
#include <vector>

namespace rehearse::imaging {

using Track = std::pair<Eigen::Vector2d, Eigen::Vector2d>;  ///< a feature's pixel in the first frame and in the second

/// Up to `maxFeatures` features inside `mask` (255 where to look, e.g. the organ; empty: everywhere) of the first
/// frame, tracked into the second; kept when tracking back lands within 0.5 px of where it started. Both frames the
/// same size, undistorted (InputError otherwise).
std::vector<Track> trackFeatures(const cv::Mat& first, const cv::Mat& second, const cv::Mat1b& mask,
                                 int maxFeatures = 400);

struct CameraMotion {
  bool ok = false;
  Pose motion;                 ///< first camera frame -> second (a point q of the first is at motion.apply(q))
  std::vector<Track> inliers;  ///< the tracks the motion explains
  double parallaxDegrees = 0;  ///< the median angle between the two rays of the inliers
  /// The motion's uncertainty (1 sigma, from the tracks' misfit to it): the turn's and the move's direction's, and
  /// how far it moves the depth of the tracked points (their median, m; the length taken as given).
  double turnSigmaDegrees = 0, directionSigmaDegrees = 0, depthSigmaM = 0;
  /// The motion moved by its 1-sigma uncertainty the way that moves the tracked points' depth most (for a fit to see
  /// what that uncertainty does to its result: simcore::RegistrationFrame::motionAtOneSigma).
  Pose motionAtOneSigma;
  std::string status;          ///< one sentence
};

/// The motion from the tracks (both frames through `camera`), its move scaled to `baselineM` metres. Not ok, with
/// why, when fewer than 15 tracks agree or the camera barely moved (median parallax under 0.3 degrees: the move's
/// direction is then noise).
CameraMotion estimateCameraMotion(const Camera& camera, const std::vector<Track>& tracks, double baselineM);

}  // namespace rehearse::imaging
