// A second frame's camera motion (issue 38): features tracked on the real Open-CAS liver frame between it and a second
// frame made from it (the frame's pixels carried by the organ's CT surface, which the data set gives in the camera's
// frame, into a camera moved 12 mm sideways and turned to keep the organ in view), and the motion estimated from them
// against the motion that made the second frame. And the refusals: no length for the move, too few features, a camera
// that did not move.
#include "test_support.hpp"
#include "opencas.hpp"
#include "second_view.hpp"

#include <rehearse/imaging/motion.hpp>
#include <rehearse/imaging/render.hpp>

#include <opencv2/imgproc.hpp>

using namespace rehearse;
using namespace rehearse::imaging;

using testing::lookingAt;

namespace {
// The second frame made from the real one through its CT surface (testing::secondView).
cv::Mat3b secondFrame(const testdata::OpenCas& c, const Pose& motion, cv::Mat1b& firstMask) {
  return testing::secondView(c.camera, c.frame, c.surface(), motion, firstMask);
}
}  // namespace

class TestMotion : public QObject {
  Q_OBJECT
 private slots:
  void motionFromTheRealFrame() {
    if (!testdata::OpenCas::available()) {
      if (sharedDataRequired()) QFAIL("../shared/data/open-cas is absent");
      QSKIP("../shared/data/open-cas is absent");
    }
    const auto c = testdata::OpenCas::load();
    const SurfaceView s = c.surface();
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < s.vertexCount; ++i) centre += s.vertex(i) / static_cast<double>(s.vertexCount);
    const Pose truth = lookingAt(Eigen::Vector3d(0.012, 0, 0), centre);
    cv::Mat1b mask;
    const cv::Mat3b second = secondFrame(c, truth, mask);
    const auto tracks = trackFeatures(c.frame, second, mask);
    QVERIFY(tracks.size() >= 50);
    // Each track against where the CT surface puts its feature in the second frame.
    const Rasterization r1 = rasterize(c.camera, Pose{}, s);
    const Eigen::Matrix3d Kinv = c.camera.K.inverse();
    std::vector<double> trackError;
    for (const auto& [a, b] : tracks) {
      const int x = static_cast<int>(std::lround(a.x())), y = static_cast<int>(std::lround(a.y()));
      const Eigen::Vector3d p1 = r1.depth(y, x) * (Kinv * Eigen::Vector3d(a.x(), a.y(), 1));
      trackError.push_back((c.camera.pinhole().project(truth.apply(p1)) - b).norm());
    }
    std::sort(trackError.begin(), trackError.end());
    const auto m = estimateCameraMotion(c.camera, tracks, truth.t.norm());
    const double turnError = Eigen::AngleAxisd(m.motion.R * truth.R.transpose()).angle() * 180 / M_PI;
    const double moveError =
        std::acos(std::clamp(m.motion.t.normalized().dot(truth.t.normalized()), -1.0, 1.0)) * 180 / M_PI;
    qInfo(
        "%zu tracks (median error %.2f px, 90th percentile %.2f px); %s; turn off by %.3f degrees, the move's "
        "direction by %.2f degrees (true turn %.2f degrees)",
        tracks.size(), trackError[trackError.size() / 2], trackError[trackError.size() * 9 / 10], m.status.c_str(),
        turnError, moveError, Eigen::AngleAxisd(truth.R).angle() * 180 / M_PI);
    QVERIFY(trackError[trackError.size() / 2] < 1.0);
    QVERIFY2(m.ok, m.status.c_str());
    // (A few tracks slide along their epipolar line, at the specular highlights the second frame carries with the
    // surface: the motion cannot see them, the fit's check of how far a track's rays pass apart cannot either.)
    // (RANSAC's best minimal sample alone: 0.59 and 0.85 degrees; refined on all the tracks: 0.18 and 0.28.)
    QVERIFY(turnError < 0.4);
    QVERIFY(moveError < 0.6);
    QVERIFY(m.directionSigmaDegrees > 0 && moveError < 3 * m.directionSigmaDegrees);
    QVERIFY(m.depthSigmaM > 0 && m.depthSigmaM < 0.01);
    QCOMPARE(m.motion.t.norm(), truth.t.norm());
    QVERIFY(m.inliers.size() >= tracks.size() / 2);
    // Refused: the move without its length; the same frame twice (no parallax); too few features (a tiny mask).
    QVERIFY(!estimateCameraMotion(c.camera, tracks, 0).ok);
    QVERIFY(estimateCameraMotion(c.camera, tracks, 0).status.find("length") != std::string::npos);
    const auto same = estimateCameraMotion(c.camera, trackFeatures(c.frame, c.frame, mask), 0.012);
    QVERIFY2(!same.ok && same.status.find("barely moved") != std::string::npos, same.status.c_str());
    cv::Mat1b tiny(mask.size(), 0);
    tiny(cv::Rect(mask.cols / 2, mask.rows / 2, 6, 6)) = 255;
    const auto few = estimateCameraMotion(c.camera, trackFeatures(c.frame, second, tiny), 0.012);
    QVERIFY2(!few.ok && few.status.find("features") != std::string::npos, few.status.c_str());
    // Frames of different sizes: one sentence.
    try {
      trackFeatures(c.frame, second(cv::Rect(0, 0, 100, 100)), cv::Mat1b());
      QFAIL("frames of different sizes were accepted");
    } catch (const InputError& e) {
      QVERIFY(std::string(e.what()).find("same size") != std::string::npos);
    }
  }

  // A liver's front seen 15 mm apart from 35 cm (a sphere cap of 10 cm radius, 10 x 8 cm across, 200 points, 0.5 px
  // of Gaussian noise in each frame; the scikit-surgery laparoscope's 1920x1080 intrinsics): nearly flat, about 2
  // degrees of parallax, where the essential matrix is badly conditioned. Over 20 draws: the estimate explains the
  // tracks within 0.01 px RMS as well as the true motion does (no shallow minimum: RANSAC's start alone ended 8-9
  // degrees off, explaining them 0.08-0.12 px worse, in bench_registration_real; here without the homography's starts
  // one draw ended on a turn-only motion), and the stated uncertainty nearly holds: the move's direction within 2 sigma
  // in >= 70 % of the draws (15 of 20 measured; an honest 2D Gaussian would give 86 %) and beyond 3 sigma in at most 2
  // (2 measured, 3.3 and 5.2 sigma: the cost's valley is curved, its curvature understates the tail).
  void flatFrontCalibratedUncertainty() {
    Camera cam;
    cam.K << 2012, 0, 960, 0, 2012, 540, 0, 0, 1;
    cam.width = 1920;
    cam.height = 1080;
    const Eigen::Vector3d centre(0, 0, 0.35);
    const Pose truth = lookingAt(Eigen::Vector3d(0.015, 0, 0), centre);
    auto sampson = [&](const Pose& M, const std::vector<Track>& tracks) {
      const Eigen::Vector3d t = M.t.normalized();
      Eigen::Matrix3d tx;
      tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
      const Eigen::Matrix3d E = tx * M.R, Ki = cam.K.inverse();
      double s2 = 0;
      for (const auto& [p, q] : tracks) {
        const Eigen::Vector3d a = Ki * p.homogeneous(), b = Ki * q.homogeneous(), Ea = E * a, Eb = E.transpose() * b;
        s2 += std::pow(cam.fx() * b.dot(Ea), 2) / (Ea.head<2>().squaredNorm() + Eb.head<2>().squaredNorm());
      }
      return std::sqrt(s2 / static_cast<double>(tracks.size()));
    };
    int within2 = 0, beyond3 = 0;
    const int draws = 20;
    for (int draw = 0; draw < draws; ++draw) {
      std::mt19937 rng(static_cast<unsigned>(100 + draw));
      std::uniform_real_distribution<double> across(-0.05, 0.05), down(-0.04, 0.04);
      std::normal_distribution<double> noise(0.0, 0.5);
      std::vector<Track> tracks;
      while (tracks.size() < 200) {
        const double x = across(rng), y = down(rng), radius = 0.1;
        const Eigen::Vector3d p(x, y, centre.z() - std::sqrt(radius * radius - x * x - y * y) + radius);
        const Eigen::Vector2d a = cam.project(p), b = cam.project(truth.apply(p));
        tracks.push_back({a + Eigen::Vector2d(noise(rng), noise(rng)), b + Eigen::Vector2d(noise(rng), noise(rng))});
      }
      const CameraMotion m = estimateCameraMotion(cam, tracks, 0.015);
      QVERIFY2(m.ok, m.status.c_str());
      const double direction =
          std::acos(std::clamp(m.motion.t.normalized().dot(truth.t.normalized()), -1.0, 1.0)) * 180 / M_PI;
      const double mine = sampson(m.motion, m.inliers), theirs = sampson(truth, m.inliers);
      qInfo(
          "draw %d: the move's direction %.2f degrees off (sigma %.2f), the turn %.3f; RMS Sampson %.4f px (the "
          "true motion's %.4f); depth sigma %.1f mm",
          draw, direction, m.directionSigmaDegrees,
          Eigen::AngleAxisd(m.motion.R * truth.R.transpose()).angle() * 180 / M_PI, mine, theirs, 1e3 * m.depthSigmaM);
      QVERIFY(mine <= theirs + 0.01);
      within2 += direction <= 2 * m.directionSigmaDegrees;
      beyond3 += direction > 3 * m.directionSigmaDegrees;
    }
    qInfo("the move's direction within 2 sigma in %d of %d draws, beyond 3 sigma in %d", within2, draws, beyond3);
    QVERIFY(within2 >= 14);
    QVERIFY(beyond3 <= 2);
  }
};

QTEST_GUILESS_MAIN(TestMotion)
#include "test_motion.moc"
