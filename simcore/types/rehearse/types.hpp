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
