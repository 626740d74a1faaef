#pragma once
// Small value types shared by simcore and imaging (the only thing they share).
// Units: metres unless a field says otherwise.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>

namespace rehearse {

/// Rigid model->camera transform: x_cam = R * x_model + t (t in metres).
struct Pose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return R * x + t; }
  /// The pose turned by the rotation Q (camera frame) about the camera-frame point `centre` (the gizmo's
  /// rotations about camera axes through the organ's centre).
  Pose turnedAbout(const Eigen::Matrix3d& Q, const Eigen::Vector3d& centre) const {
    Pose p;
    p.R = Q * R;
    p.t = Q * (t - centre) + centre;
    return p;
  }
};

/// An ideal pinhole camera (undistorted pixels): intrinsics K in pixels and the image size.
struct Pinhole {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  int width = 0, height = 0;
  /// Pixel of a camera-frame point (z > 0).
  Eigen::Vector2d project(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d h = K * x;
    return h.head<2>() / h.z();
  }
  /// Unit direction, in the camera frame, of the ray through a pixel.
  Eigen::Vector3d ray(const Eigen::Vector2d& pixel) const { return (K.inverse() * pixel.homogeneous()).normalized(); }
};

/// Non-owning view of a triangle surface: vertices (n x 3, metres, row-major xyz),
/// triangles (m x 3 vertex indices, counter-clockwise seen from outside).
struct SurfaceView {
  const double* vertices = nullptr;
  std::size_t vertexCount = 0;
  const int* triangles = nullptr;
  std::size_t triangleCount = 0;
  Eigen::Vector3d vertex(std::size_t i) const {
    return {vertices[3 * i], vertices[3 * i + 1], vertices[3 * i + 2]};
  }
};

}  // namespace rehearse
