#pragma once
// A second frame of a scene (issue 38), made from the first: each pixel on the organ takes the first frame's colour
// where the organ's surface point there is seen in the first (depth-tested), the rest of the scene as if it were a
// plane 2 cm behind the organ's back. The surface is given in the first camera's frame; `motion` takes a point of the
// first camera frame into the second's. Also the organ's mask in the first frame (eroded by 15 px), where features are
// worth tracking. For test_motion (the real Open-CAS frame) and the GUI's second frame (test_simulation_gui).
#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/render.hpp>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace rehearse::testing {

// The motion of a camera moved `move` (first camera frame, m) and turned to look at `centre`.
inline Pose lookingAt(const Eigen::Vector3d& move, const Eigen::Vector3d& centre) {
  const Eigen::Vector3d z = (centre - move).normalized(), x = Eigen::Vector3d::UnitY().cross(z).normalized();
  Pose m;
  m.R.row(0) = x.transpose();
  m.R.row(1) = z.cross(x).transpose();
  m.R.row(2) = z.transpose();
  m.t = -m.R * move;
  return m;
}

inline cv::Mat3b secondView(const imaging::Camera& camera, const cv::Mat3b& frame, const SurfaceView& s,
                            const Pose& motion, cv::Mat1b& firstMask) {
  const imaging::Rasterization r1 = imaging::rasterize(camera, Pose{}, s), r2 = imaging::rasterize(camera, motion, s);
  cv::Mat1f mapX(frame.size(), -1.f), mapY(frame.size(), -1.f);
  const Eigen::Matrix3d Kinv = camera.K.inverse();
  double back = 0;
  for (std::size_t i = 0; i < s.vertexCount; ++i) back = std::max(back, s.vertex(i).z());
  back += 0.02;
  const Eigen::Vector3d eye = -motion.R.transpose() * motion.t;
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x) {
      if (r2.triangle(y, x) < 0) {  // the plane behind
        const Eigen::Vector3d d = motion.R.transpose() * (Kinv * Eigen::Vector3d(x, y, 1));
        const Eigen::Vector2d px = camera.pinhole().project(eye + (back - eye.z()) / d.z() * d);
        mapX(y, x) = static_cast<float>(px.x());
        mapY(y, x) = static_cast<float>(px.y());
        continue;
      }
      const Eigen::Vector3d p2 = r2.depth(y, x) * (Kinv * Eigen::Vector3d(x, y, 1));
      const Eigen::Vector3d p1 = motion.R.transpose() * (p2 - motion.t);
      const Eigen::Vector2d px = camera.pinhole().project(p1);
      const int u = static_cast<int>(std::lround(px.x())), v = static_cast<int>(std::lround(px.y()));
      if (u < 0 || v < 0 || u >= frame.cols || v >= frame.rows || r1.triangle(v, u) < 0) continue;
      if (std::abs(r1.depth(v, u) - p1.z()) > 0.002) continue;  // hidden in the first frame
      mapX(y, x) = static_cast<float>(px.x());
      mapY(y, x) = static_cast<float>(px.y());
    }
  cv::Mat3b out;
  cv::remap(frame, out, mapX, mapY, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0));
  firstMask = cv::Mat1b(frame.size(), 0);
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x) firstMask(y, x) = r1.triangle(y, x) >= 0 ? 255 : 0;
  cv::erode(firstMask, firstMask, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(31, 31)));
  return out;
}

}  // namespace rehearse::testing
