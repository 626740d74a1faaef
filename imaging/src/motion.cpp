// Features tracked between two frames and the camera's motion from them (motion.hpp).
#include <rehearse/imaging/motion.hpp>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>

namespace rehearse::imaging {

namespace {
cv::Mat1b grey(const cv::Mat& image) {
  cv::Mat1b g;
  if (image.channels() == 3)
    cv::cvtColor(image, g, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4)
    cv::cvtColor(image, g, cv::COLOR_BGRA2GRAY);
  else
    image.convertTo(g, CV_8U);
  return g;
}
}  // namespace

std::vector<Track> trackFeatures(const cv::Mat& first, const cv::Mat& second, const cv::Mat1b& mask, int maxFeatures) {
  if (first.empty() || second.empty()) throw InputError("A frame to track features in is empty.");
  if (first.size() != second.size()) throw InputError("The two frames are not the same size.");
  if (!mask.empty() && mask.size() != first.size()) throw InputError("The organ's mask is not the frame's size.");
  const cv::Mat1b a = grey(first), b = grey(second);
  std::vector<cv::Point2f> corners;
  // Corners at least 1 % of the frame's width apart, at least a thousandth as strong as the strongest (an organ has
  // little texture).
  const double spacing = std::max(4.0, 0.01 * first.cols);
  cv::goodFeaturesToTrack(a, corners, std::max(1, maxFeatures), 0.001, spacing, mask.empty() ? cv::noArray() : mask);
  if (corners.empty()) return {};
  cv::cornerSubPix(a, corners, cv::Size(5, 5), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01));
  std::vector<cv::Point2f> there, back;
  std::vector<unsigned char> okThere, okBack;
  std::vector<float> err;
  const cv::Size window(21, 21);
  cv::calcOpticalFlowPyrLK(a, b, corners, there, okThere, err, window, 3);
  cv::calcOpticalFlowPyrLK(b, a, there, back, okBack, err, window, 3);
  std::vector<Track> out;
  for (std::size_t i = 0; i < corners.size(); ++i) {
    if (!okThere[i] || !okBack[i]) continue;
    if (std::hypot(back[i].x - corners[i].x, back[i].y - corners[i].y) > 0.5) continue;
    if (there[i].x < 0 || there[i].y < 0 || there[i].x > b.cols - 1 || there[i].y > b.rows - 1) continue;
    out.push_back({{corners[i].x, corners[i].y}, {there[i].x, there[i].y}});
  }
  return out;
}

CameraMotion estimateCameraMotion(const Camera& camera, const std::vector<Track>& tracks, double baselineM) {
  CameraMotion m;
  if (auto p = camera.problem(); !p.empty()) {
    m.status = p;
    return m;
  }
  if (!(baselineM > 0) || !std::isfinite(baselineM)) {
    m.status =
        "the camera's move between the frames needs a length (a baseline in mm): two frames give only its "
        "direction";
    return m;
  }
  if (tracks.size() < 15) {
    m.status =
        "only " + std::to_string(tracks.size()) +
        " features could be tracked between the frames (at least 15 are needed); choose frames closer in time or "
        "with more texture on the organ";
    return m;
  }
  std::vector<cv::Point2d> a, b;
  for (const auto& [p, q] : tracks) {
    a.emplace_back(p.x(), p.y());
    b.emplace_back(q.x(), q.y());
  }
  cv::Mat K(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) K.at<double>(r, c) = camera.K(r, c);
  cv::Mat inlierMask;
  const cv::Mat E = cv::findEssentialMat(a, b, K, cv::RANSAC, 0.999, 1.0, inlierMask);
  if (E.rows != 3 || E.cols != 3) {
    m.status = "the tracked features do not agree on one camera motion (the organ may have moved between the frames)";
    return m;
  }
  cv::Mat R, t;
  const int front = cv::recoverPose(E, a, b, K, R, t, inlierMask);
  if (front < 15) {
    m.status = "only " + std::to_string(front) +
               " tracked features agree on the camera's motion (at least 15 are needed); the organ may have moved "
               "between the frames";
    return m;
  }
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.motion.R(r, c) = R.at<double>(r, c);
    m.motion.t[r] = t.at<double>(r);
  }
  m.motion.t = baselineM * m.motion.t.normalized();
  std::vector<double> angles;
  const Eigen::Matrix3d Kinv = camera.K.inverse();
  for (std::size_t i = 0; i < tracks.size(); ++i) {
    if (!inlierMask.at<unsigned char>(static_cast<int>(i))) continue;
    m.inliers.push_back(tracks[i]);
    const Eigen::Vector3d r1 = (Kinv * tracks[i].first.homogeneous()).normalized();
    const Eigen::Vector3d r2 = m.motion.R.transpose() * (Kinv * tracks[i].second.homogeneous()).normalized();
    angles.push_back(std::acos(std::clamp(r1.dot(r2), -1.0, 1.0)) * 180 / M_PI);
  }
  std::nth_element(angles.begin(), angles.begin() + angles.size() / 2, angles.end());
  m.parallaxDegrees = angles[angles.size() / 2];
  if (m.parallaxDegrees < 0.3) {
    m.status = "the camera barely moved between the frames (a median parallax of " +
               std::to_string(m.parallaxDegrees).substr(0, 4) +
               " degrees); choose a second frame with the scope moved 1-2 cm sideways";
    return m;
  }
  m.ok = true;
  char text[200];
  std::snprintf(text, sizeof text,
                "camera motion from %zu of %zu tracked features: turned %.1f degrees, moved %.1f mm "
                "(given), parallax %.1f degrees",
                m.inliers.size(), tracks.size(), Eigen::AngleAxisd(m.motion.R).angle() * 180 / M_PI, 1e3 * baselineM,
                m.parallaxDegrees);
  m.status = text;
  return m;
}

}  // namespace rehearse::imaging
