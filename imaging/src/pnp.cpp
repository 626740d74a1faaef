#include "rehearse/imaging/pnp.hpp"

#include <opencv2/calib3d.hpp>

#include <Eigen/Geometry>

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
  std::vector<std::pair<double, Eigen::Matrix3d>> candidates;  // every refined solution in front of the camera
  auto rotation = [](const cv::Mat& rv) {
    cv::Mat R;
    cv::Rodrigues(rv, R);
    Eigen::Matrix3d out;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) out(r, c) = R.at<double>(r, c);
    return out;
  };
  auto consider = [&](cv::Mat rv, cv::Mat tv) {
    if (rv.empty() || tv.empty() || tv.at<double>(2) <= 0) return;
    cv::solvePnPRefineLM(object, pixels, K, cv::noArray(), rv, tv);
    if (tv.at<double>(2) <= 0) return;
    const double e = rms(rv, tv);
    if (!std::isfinite(e)) return;
    candidates.emplace_back(e, rotation(rv));
    if (e < best) {
      best = e;
      rvec = rv.clone();
      tvec = tv.clone();
    }
  };
  // Every solver that takes this many points: with four nearly coplanar landmarks and a pixel of click
  // noise, SQPnP and EPnP alone were seen to miss the pose (19.7 px RMS, 119 degrees off) that P3P finds.
  std::vector<int> methods = {cv::SOLVEPNP_SQPNP, cv::SOLVEPNP_EPNP, cv::SOLVEPNP_IPPE};
  if (object.size() == 4) methods.insert(methods.end(), {cv::SOLVEPNP_P3P, cv::SOLVEPNP_AP3P});
  for (int method : methods) {
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
  PnPResult out;
  {
    const Eigen::Matrix3d Rbest = rotation(rvec);
    for (const auto& [e, R] : candidates)
      if (e < std::max(best + 1.0, 2 * best) && Eigen::AngleAxisd(R * Rbest.transpose()).angle() > 10 * M_PI / 180) {
        out.ambiguous = true;
        out.alternativeRmsPixels = out.alternativeRmsPixels < 0 ? e : std::min(out.alternativeRmsPixels, e);
      }
  }
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.pose.R(r, c) = R.at<double>(r, c);
    out.pose.t[r] = tvec.at<double>(r);
  }
  out.rmsPixels = best;
  return out;
}

}  // namespace rehearse::imaging
