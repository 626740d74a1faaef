#include "rehearse/imaging/pnp.hpp"

#include <opencv2/calib3d.hpp>

#include <cmath>
#include <limits>

namespace rehearse::imaging {

std::optional<PnPResult> poseFromLandmarks(const Camera& camera, const std::vector<Eigen::Vector3d>& model,
                                           const std::vector<Eigen::Vector2d>& image, const Pose& start) {
  if (model.size() != image.size() || model.size() < 4) return std::nullopt;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> pixels;
  for (std::size_t i = 0; i < model.size(); ++i) {
    object.emplace_back(model[i].x(), model[i].y(), model[i].z());
    pixels.emplace_back(image[i].x(), image[i].y());
  }
  cv::Mat K(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) K.at<double>(r, c) = camera.K(r, c);
  // The frame is undistorted, so no distortion here.
  auto rms = [&](const cv::Mat& rv, const cv::Mat& tv) {
    std::vector<cv::Point2d> reproj;
    cv::projectPoints(object, rv, tv, K, cv::noArray(), reproj);
    double sum = 0;
    for (std::size_t i = 0; i < pixels.size(); ++i) sum += std::pow(cv::norm(reproj[i] - pixels[i]), 2);
    return std::sqrt(sum / static_cast<double>(pixels.size()));
  };
  cv::Mat rvec, tvec;
  double best = std::numeric_limits<double>::infinity();
  auto consider = [&](cv::Mat rv, cv::Mat tv) {
    if (rv.empty() || tv.empty() || tv.at<double>(2) <= 0) return;
    cv::solvePnPRefineLM(object, pixels, K, cv::noArray(), rv, tv);
    const double e = rms(rv, tv);
    if (e < best && tv.at<double>(2) > 0) {
      best = e;
      rvec = rv.clone();
      tvec = tv.clone();
    }
  };
  for (int method : {cv::SOLVEPNP_SQPNP, cv::SOLVEPNP_EPNP}) {
    cv::Mat rv, tv;
    try {
      if (cv::solvePnP(object, pixels, K, cv::noArray(), rv, tv, false, method)) consider(rv, tv);
    } catch (const cv::Exception&) {
      // a degenerate configuration for this solver: the others may still find the pose
    }
  }
  {
    cv::Mat R0(3, 3, CV_64F), rv, tv(3, 1, CV_64F);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) R0.at<double>(r, c) = start.R(r, c);
      tv.at<double>(r) = start.t[r];
    }
    cv::Rodrigues(R0, rv);
    try {
      if (cv::solvePnP(object, pixels, K, cv::noArray(), rv, tv, true, cv::SOLVEPNP_ITERATIVE)) consider(rv, tv);
    } catch (const cv::Exception&) {
    }
  }
  if (rvec.empty()) return std::nullopt;
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  PnPResult out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.pose.R(r, c) = R.at<double>(r, c);
    out.pose.t[r] = tvec.at<double>(r);
  }
  out.rmsPixels = best;
  return out;
}

}  // namespace rehearse::imaging
