#pragma once
// Pinhole camera with OpenCV conventions (x right, y down, z forward; pixel centres at integers),
// and the camera / pose file formats (README.md, "File formats").
#include <rehearse/files.hpp>  // InputError (what the readers here throw), writeFileAtomically
#include <rehearse/types.hpp>

#include <opencv2/core.hpp>

#include <array>
#include <stdexcept>
#include <string>

namespace rehearse::imaging {

struct Camera {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();  ///< intrinsics in pixels
  std::array<double, 5> distortion{};               ///< k1 k2 p1 p2 k3
  int width = 0, height = 0;                        ///< image size in pixels

  double fx() const { return K(0, 0); }
  double fy() const { return K(1, 1); }
  double cx() const { return K(0, 2); }
  double cy() const { return K(1, 2); }
  /// Ideal (undistorted) pixel of a camera-frame point; z must be > 0.
  Eigen::Vector2d project(const Eigen::Vector3d& xCam) const {
    return {fx() * xCam.x() / xCam.z() + K(0, 1) * xCam.y() / xCam.z() + cx(), fy() * xCam.y() / xCam.z() + cy()};
  }
  /// Empty when usable; otherwise one sentence saying what is wrong.
  std::string problem() const;
  bool distorted() const {
    for (double d : distortion)
      if (d != 0) return true;
    return false;
  }
  /// The ideal pinhole of the undistorted frame (what simcore's registration projects through).
  Pinhole pinhole() const {
    Pinhole p;
    p.K = K;
    p.width = width;
    p.height = height;
    return p;
  }
  /// The stated default when no calibration is given: principal point at the image centre,
  /// fx = fy = 0.8 * width (about a 64 degree horizontal field of view, typical of laparoscopes), no distortion.
  static Camera defaultFor(int width, int height);
};

/// `image` (this camera's) undistorted with the same K, so its pixels keep the pinhole model: what every step
/// works on. Without distortion, the image itself.
cv::Mat3b undistortImage(const cv::Mat3b& image, const Camera& camera);

/// Reads a camera: OpenCV calibration YAML/XML (camera_matrix, distortion_coefficients, image_width,
/// image_height), JSON ({"K": [[...]], "distortion": [...], "width": w, "height": h}, or the P2ILF
/// form with fx fy cx cy k1 k2 k3 p1 p2), or a 3x3 text matrix (then width/height must be given).
/// Throws InputError.
Camera loadCamera(const std::string& path, int width = 0, int height = 0);
/// Writes an OpenCV calibration file (.yaml/.yml/.xml) or our JSON (.json). Throws InputError.
void saveCamera(const Camera& camera, const std::string& path);

/// Reads a pose: JSON {"R": [[..],[..],[..]], "t": [..], "unit": "m"} or a 4x4 text matrix in
/// `matrixUnit` (metres per unit). Returns metres. Throws InputError (also for a non-rotation R).
Pose loadPose(const std::string& path, double matrixUnitToMetre = 1.0);
void savePose(const Pose& pose, const std::string& path);
/// The pose as savePose writes it (JSON text, metres).
std::string poseToJson(const Pose& pose);


}  // namespace rehearse::imaging
