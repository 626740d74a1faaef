// The built-in phantom case: deterministic, the stated contents, a frame consistent with its ground truth,
// and case folders that round-trip and survive a damaged part.
#include "test_support.hpp"
#include "icosphere.hpp"

#include "phantom/phantom.hpp"
#include <rehearse/app/casefolder.hpp>

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>

#include <opencv2/imgcodecs.hpp>

#include <opencv2/imgproc.hpp>

#include <numbers>
#include <set>

using namespace rehearse;

class TestPhantom : public QObject {
  Q_OBJECT
  phantom::Phantom c_;

 private slots:
  void initTestCase() { c_ = phantom::makePhantom(); }

  void contents() {
    const auto q = simcore::computeQuality(c_.volume);
    qInfo("phantom: %zu nodes, %zu tets, %zu surface triangles, %zu attachments, volume %.1f cm^3, min dihedral %.1f deg",
          q.points, q.tets, c_.surface.size(), c_.attachments.size(), q.volume * 1e6, q.minDihedralDeg);
    QVERIFY(q.tets >= 2000 && q.tets <= 6000);  // "a few thousand tets"
    QCOMPARE(q.inverted, std::size_t(0));
    QCOMPARE(q.degenerate, std::size_t(0));
    QVERIFY(q.minDihedralDeg > 2.0);
    QCOMPARE(q.labels.size(), std::size_t(2));
    QCOMPARE(QString::fromStdString(c_.volume.labelName(phantom::kVesselLabel)), QString("vessels"));
    // Vessel tree volume against the analytic volume of its capsules (overlaps make the sum an upper bound).
    double capsules = 0;
    for (const auto& s : c_.vesselTree) capsules += std::numbers::pi * s.radius * s.radius * (s.b - s.a).norm();
    const double vessel = q.labels[1].volume;
    QVERIFY2(vessel > 0.5 * capsules && vessel < 1.6 * capsules, qPrintable(QString("%1 vs %2").arg(vessel).arg(capsules)));
    // The outer surface is closed and encloses the tet volume.
    simcore::Mesh surface = c_.volume;
    surface.tets.clear();
    surface.tetLabels.clear();
    surface.triangles = c_.surface;
    surface.triangleLabels.assign(c_.surface.size(), 0);
    const auto sq = simcore::computeQuality(surface);
    QVERIFY(sq.closed);
    QVERIFY(std::abs(sq.volume - q.volume) / q.volume < 1e-9);
    // Attachments: at least 10 surface nodes, all on the superior-posterior side.
    QVERIFY(c_.attachments.size() >= 10);
    std::set<int> onSurface;
    for (const auto& t : c_.surface) onSurface.insert(t.begin(), t.end());
    for (int a : c_.attachments) {
      QVERIFY(onSurface.count(a));
      QVERIFY(c_.volume.points[a].z() > 0 && c_.volume.points[a].y() < 0);
    }
  }

  void frameMatchesGroundTruth() {
    QCOMPARE(c_.frame.cols, 1280);
    QCOMPARE(c_.frame.rows, 720);
    QVERIFY(c_.camera.problem().empty());
    // The organ is in view and covers a plausible share of the frame.
    cv::Mat1b mask = imaging::renderMask(c_.camera, c_.truePose, c_.surfaceView());
    const double share = cv::countNonZero(mask) / double(mask.total());
    QVERIFY(share > 0.15 && share < 0.6);
    // Inside the organ (away from its edge and the vignette) the frame equals a re-render with the stored
    // ground truth, pixel for pixel: the frame really is Torrance-Sparrow with those parameters.
    cv::Mat3b rerender = imaging::renderShaded(c_.camera, c_.truePose, c_.surfaceView(), c_.trueAppearance,
                                               cv::Mat3b(720, 1280, cv::Vec3b(0, 0, 0)), 2);
    cv::Mat1b inner;
    cv::erode(mask, inner, cv::Mat(), {-1, -1}, 3);
    double maxDiff = 0;
    int n = 0;
    for (int y = 0; y < 720; ++y)
      for (int x = 0; x < 1280; ++x) {
        const double r = std::hypot(x - 639.5, y - 359.5);
        if (!inner(y, x) || r > 0.56 * 1280 - 20) continue;
        for (int k = 0; k < 3; ++k) maxDiff = std::max(maxDiff, std::abs(double(c_.frame(y, x)[k]) - rerender(y, x)[k]));
        ++n;
      }
    QVERIFY(n > 100000);
    QVERIFY2(maxDiff <= 1.0, qPrintable(QString::number(maxDiff)));
    // A specular highlight exists on the organ and the scope vignette blacks out the corners.
    double maxV = 0;
    cv::Mat gray;
    cv::cvtColor(c_.frame, gray, cv::COLOR_BGR2GRAY);
    cv::minMaxLoc(gray, nullptr, &maxV, nullptr, nullptr, inner);
    QVERIFY(maxV >= 230);
    QCOMPARE(c_.frame(0, 0), cv::Vec3b(0, 0, 0));
    QCOMPARE(c_.frame(719, 1279), cv::Vec3b(0, 0, 0));
  }

  // The renderer that makes the phantom frame, against an independent reference: a sphere shaded in
  // closed form (ray-sphere intersection, the sphere's exact normal, ../shared/DESIGN.md's simplified Torrance-Sparrow
  // written out here, radiance 1 = level 255). The frame check above shows the frame is that renderer
  // with the stored truth; this shows the renderer is the model.
  void rendererMatchesAnalyticSphere() {
    simcore::Mesh sphere;
    const Eigen::Vector3d centre(0.006, -0.004, 0.15);
    const double R = 0.03;
    addIcosphere(sphere, centre, R, 5, 0);
    imaging::Camera cam = imaging::Camera::defaultFor(640, 480);
    imaging::Appearance a;
    a.lightPosition = Eigen::Vector3d(0.012, -0.01, 0.0);
    a.kd = Eigen::Vector3d(0.016, 0.009, 0.007);
    a.ks = Eigen::Vector3d(0.006, 0.006, 0.006);
    a.roughness = 0.22;
    const cv::Mat3b shown = imaging::renderShaded(cam, Pose{}, sphere.surfaceView(), a, cv::Mat3b(480, 640, cv::Vec3b(0, 0, 0)), 1);
    const Eigen::Matrix3d Kinv = cam.K.inverse();
    double worst = 0, sum = 0, peakSpecular = 0;
    int n = 0, coveredBoth = 0, coveredOne = 0;
    for (int y = 0; y < 480; ++y)
      for (int x = 0; x < 640; ++x) {
        const Eigen::Vector3d d = (Kinv * Eigen::Vector3d(x, y, 1)).normalized();
        const double b = d.dot(centre), disc = b * b - (centre.squaredNorm() - R * R);
        const bool hit = disc > 0;
        const bool drawn = shown(y, x) != cv::Vec3b(0, 0, 0);
        if (hit != drawn) ++coveredOne;
        if (!hit) continue;
        ++coveredBoth;
        if (disc < std::pow(0.004, 2)) continue;  // within about a pixel of the limb: facets decide there
        const Eigen::Vector3d p = (b - std::sqrt(disc)) * d;
        const Eigen::Vector3d nrm = (p - centre) / R;
        const Eigen::Vector3d toLight = a.lightPosition - p;
        const double r2 = toLight.squaredNorm();
        const Eigen::Vector3d l = toLight.normalized(), view = -p.normalized();
        const double cosI = nrm.dot(l), cosR = nrm.dot(view);
        if (cosI <= 0.05 || cosR <= 0.05) continue;
        const double alpha = std::acos(std::min(1.0, nrm.dot((l + view).normalized())));
        const double specular = std::exp(-alpha * alpha / (2 * a.roughness * a.roughness)) / (r2 * cosR);
        const Eigen::Vector3d J = a.kd * cosI / r2 + a.ks * specular;
        peakSpecular = std::max(peakSpecular, 255 * a.ks.x() * specular);
        for (int k = 0; k < 3; ++k) {
          const double expected = std::clamp(255 * J[2 - k], 0.0, 255.0);  // BGR
          const double diff = std::abs(expected - shown(y, x)[k]);
          worst = std::max(worst, diff);
          sum += diff;
        }
        ++n;
      }
    qInfo("analytic sphere: %d pixels compared, mean |difference| %.3f, worst %.1f levels (specular peak %.0f levels); "
          "coverage differs on %d of %d pixels", n, sum / (3 * n), worst, peakSpecular, coveredOne, coveredBoth);
    QVERIFY(n > 20000);
    QVERIFY(peakSpecular > 60);  // the specular lobe is there to be checked
    QVERIFY2(sum / (3 * n) < 0.5, qPrintable(QString::number(sum / (3 * n))));
    QVERIFY2(worst <= 2, qPrintable(QString::number(worst)));
    QVERIFY(coveredOne < 0.01 * coveredBoth);
  }

  void deterministic() {
    auto again = phantom::makePhantom();
    QCOMPARE(again.volume.points.size(), c_.volume.points.size());
    for (std::size_t i = 0; i < c_.volume.points.size(); ++i) QCOMPARE(again.volume.points[i], c_.volume.points[i]);
    QVERIFY(again.volume.tets == c_.volume.tets);
    QVERIFY(again.attachments == c_.attachments);
    QCOMPARE(cv::norm(again.frame, c_.frame, cv::NORM_INF), 0.0);
  }

  void caseFolderRoundTrip() {
    const std::string dir = tempPath("phantom-case");
    app::writeCaseDirectory(app::caseFromPhantom(c_), dir);
    std::vector<std::string> notes;
    auto r = app::loadCaseDirectory(dir, &notes);
    QVERIFY(notes.empty());
    QCOMPARE(r.organ->volume.points.size(), c_.volume.points.size());
    QVERIFY(r.organ->volume.tets == c_.volume.tets);
    QVERIFY(r.organ->volume.tetLabels == c_.volume.tetLabels);
    QCOMPARE(r.organ->surface.size(), c_.surface.size());
    QCOMPARE(r.attachments.size(), c_.attachments.size());
    QVERIFY(r.attachments == c_.attachments);
    QVERIFY((r.camera.K - c_.camera.K).norm() < 1e-12);
    QVERIFY((r.groundTruth->pose.R - c_.truePose.R).norm() < 1e-12 && (r.groundTruth->pose.t - c_.truePose.t).norm() < 1e-15);
    QCOMPARE(r.groundTruth->appearance.roughness, c_.trueAppearance.roughness);
    QCOMPARE(cv::norm(r.frame, c_.frame, cv::NORM_INF), 0.0);  // PNG is lossless
    QCOMPARE(r.groundTruth->vesselAxes.size(), c_.vesselTree.size());
    // The surface file written beside it is the same closed surface.
    auto obj = simcore::loadMesh(dir + "/organ_surface.obj");
    QCOMPARE(obj.triangles.size(), c_.surface.size());
    QVERIFY(simcore::computeQuality(obj).closed);
  }

  void damagedPartLeavesTheRestIntact() {
    const std::string dir = tempPath("damaged-case");
    app::writeCaseDirectory(app::caseFromPhantom(c_), dir);
    writeFile(dir + "/camera.yaml", "%YAML:1.0\ncamera_matrix: [this is not a matrix\n");
    std::vector<std::string> notes;
    auto r = app::loadCaseDirectory(dir, &notes);
    QCOMPARE(notes.size(), std::size_t(1));
    QVERIFY(QString::fromStdString(notes[0]).startsWith("Camera not loaded"));
    QCOMPARE(r.organ->volume.tets.size(), c_.volume.tets.size());
    QCOMPARE(r.frame.cols, 1280);
    QCOMPARE(r.camera.width, 1280);  // default camera from the frame size
    // No manifest at all: a clear error.
    QVERIFY_THROWS_EXCEPTION(rehearse::InputError, app::loadCaseDirectory(tempPath("no-such-case")));
  }
};

QTEST_GUILESS_MAIN(TestPhantom)
#include "test_phantom.moc"
