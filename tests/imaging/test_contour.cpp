// Contours: files (ours and P2ILF), resampling and smoothing against geometry, self-intersection,
// outlines of masks, the silhouette segments, and edge snapping on a synthetic image with a known edge.
#include "test_support.hpp"

#include <rehearse/imaging/contour.hpp>

#include <opencv2/imgproc.hpp>

#include <numbers>
#include <random>

using namespace rehearse::imaging;
using rehearse::InputError;

namespace {
ContourSegment circle(double cx, double cy, double r, int n, bool closed = true) {
  ContourSegment s;
  s.closed = closed;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * std::numbers::pi * i / n;
    s.points.emplace_back(cx + r * std::cos(a), cy + r * std::sin(a));
  }
  return s;
}
}  // namespace

class TestContour : public QObject {
  Q_OBJECT
 private slots:
  void filesRoundTripAndP2ilf() {
    Contour c;
    c.width = 1280;
    c.height = 720;
    c.segments.push_back(circle(600, 300, 100, 50, false));
    c.segments.push_back({{{10, 10}, {20, 15.5}}, false, "ridge", {4, 9}});
    const std::string p = tempPath("contour.json");
    saveContour(c, p);
    auto r = loadContour(p);
    QCOMPARE(r.width, 1280);
    QCOMPARE(r.segments.size(), std::size_t(2));
    QCOMPARE(r.segments[1].type, std::string("ridge"));
    QVERIFY(r.segments[1].modelVertices == std::vector<int>({4, 9}));
    QCOMPARE(anatomicalSegments(r).size(), std::size_t(1));  // the ridge with its curve on the organ
    for (std::size_t i = 0; i < c.segments[0].points.size(); ++i) QCOMPARE(r.segments[0].points[i], c.segments[0].points[i]);
    const std::string p2 = tempPath("p2ilf.json");
    writeFile(p2, R"({"numOfContours":2,"contour":[{"contourType":"Silhouette","imagePoints":{"x":[1,2,3],"y":[4,5,6]}},
                    {"contourType":"Ligament","imagePoints":{"x":["7.5"],"y":["8"]},"modelPoints":{"vertices":[12,"13",14]}}]})");
    auto q = loadContour(p2);
    QCOMPARE(q.segments.size(), std::size_t(2));
    QCOMPARE(q.segments[0].points[2], Eigen::Vector2d(3, 6));
    QCOMPARE(q.segments[1].type, std::string("ligament"));
    QCOMPARE(q.segments[1].points[0], Eigen::Vector2d(7.5, 8));
    QVERIFY(q.segments[1].modelVertices == std::vector<int>({12, 13, 14}));
    QVERIFY(q.segments[0].modelVertices.empty());
    writeFile(p2, R"({"contour":[{"contourType":"Ridge","imagePoints":{"x":[1,2],"y":[4,5]},"modelPoints":{"vertices":[1,-2]}}]})");
    try {
      loadContour(p2);
      QFAIL("a negative vertex index was accepted");
    } catch (const InputError& e) {
      QVERIFY2(QString(e.what()).contains("p2ilf.json") && QString(e.what()).contains("vertex"), e.what());
    }
    writeFile(p2, R"({"contour":[{"imagePoints":{"x":[1,2],"y":[4]}}]})");
    QVERIFY_THROWS_EXCEPTION(InputError, loadContour(p2));
    writeFile(p2, "{not json");
    QVERIFY_THROWS_EXCEPTION(InputError, loadContour(p2));
  }

  void problems() {
    Contour c;
    c.width = 100;
    c.height = 100;
    QVERIFY(QString::fromStdString(contourProblem(c)).contains("empty"));
    c.segments.push_back({{{5, 5}}, false, "silhouette", {}});
    QVERIFY(QString::fromStdString(contourProblem(c)).contains("single point"));
    c.segments[0].points = {{10, 10}, {90, 90}, {90, 10}, {10, 90}};  // a bow tie crosses itself
    QVERIFY(QString::fromStdString(contourProblem(c)).contains("crosses itself"));
    c.segments[0].points = {{10, 10}, {90, 10}, {90, 90}, {10, 90}};
    QVERIFY(contourProblem(c).empty());
    c.segments[0].closed = true;
    QVERIFY(contourProblem(c).empty());
    c.segments[0].points.push_back({150, 50});
    QVERIFY(QString::fromStdString(contourProblem(c)).contains("outside the image"));
  }

  void resampleAndSmooth() {
    // A straight polyline with uneven points resamples to exact uniform spacing.
    ContourSegment line{{{0, 0}, {3, 0}, {3.5, 0}, {10, 0}}, false, "silhouette", {}};
    auto r = resampleSegment(line, 1.0);
    QCOMPARE(r.points.size(), std::size_t(11));
    for (std::size_t i = 0; i < r.points.size(); ++i) QVERIFY((r.points[i] - Eigen::Vector2d(double(i), 0)).norm() < 1e-12);
    // Absurd coordinates come back unchanged instead of as a trillion points.
    ContourSegment huge{{{0, 0}, {1e12, 0}}, false, "silhouette", {}};
    QCOMPARE(resampleSegment(huge, 1.0).points.size(), std::size_t(2));
    // A closed circle: spacing equal to the chord of the target spacing.
    auto c = resampleSegment(circle(0, 0, 50, 37), 5.0);
    const double perimeter = 2 * std::numbers::pi * 50;
    QVERIFY(std::abs(int(c.points.size()) - int(std::round(perimeter / 5.0))) <= 2);
    // Smoothing a noisy circle moves points towards the circle without shrinking it (Taubin).
    ContourSegment noisy = circle(0, 0, 50, 200);
    std::mt19937 rng(1);
    std::normal_distribution<double> n(0, 1.0);
    for (auto& p : noisy.points) p += Eigen::Vector2d(n(rng), n(rng));
    auto radialError = [](const ContourSegment& s) {
      double e = 0, mean = 0;
      for (const auto& p : s.points) {
        e += std::pow(p.norm() - 50, 2);
        mean += p.norm();
      }
      return std::make_pair(std::sqrt(e / s.points.size()), mean / s.points.size());
    };
    auto [before, r0] = radialError(noisy);
    auto [after, r1] = radialError(smoothSegment(noisy, 25));
    qInfo("noise RMS %.3f px -> %.3f px; mean radius %.2f -> %.2f px", before, after, r0, r1);
    QVERIFY(after < 0.6 * before);
    QVERIFY(std::abs(r1 - 50) < 0.5);
  }

  // What the fit and the live readout measure: the silhouette segments only (ridges and ligaments lie
  // inside the outline), closed ones closed.
  void silhouetteSegmentsOnly() {
    Contour c;
    c.segments.push_back({{{45, 100}, {100, 40}, {160, 100}}, true, "silhouette", {}});
    c.segments.push_back({{{100, 100}, {110, 100}}, false, "ridge", {}});
    c.segments.push_back({{{1, 2}, {3, 4}}, false, "", {}});
    c.segments.push_back({{{5, 6}, {7, 8}}, false, "ligament", {3, 4}});
    const auto s = silhouetteSegments(c);
    QCOMPARE(s.size(), std::size_t(2));
    QCOMPARE(s[0].size(), std::size_t(4));  // closed: the first point again at the end
    QCOMPARE(s[0].back(), s[0].front());
    QCOMPARE(s[1].size(), std::size_t(2));
    QCOMPARE(anatomicalSegments(c).size(), std::size_t(1));  // the ligament with its curve on the organ
  }

  // A mask's outline lies on its boundary with the background: a square of pixels 50..150 is bounded by
  // 49.5 and 150.5, and a disc of the pixels whose centres lie within R of its centre by the circle R.
  void maskOutlineOnTheBoundary() {
    cv::Mat1b square(200, 200, uchar(0));
    cv::rectangle(square, cv::Rect(50, 50, 101, 101), cv::Scalar(255), cv::FILLED);
    const auto sq = maskOutlines(square);
    QCOMPARE(sq.size(), std::size_t(1));
    double minX = 1e9, maxX = -1e9, sideError = 0;
    int sidePoints = 0;
    for (const auto& p : sq.front()) {
      minX = std::min(minX, p.x()), maxX = std::max(maxX, p.x());
      if (p.y() > 60 && p.y() < 140) sideError = std::max(sideError, std::min(std::abs(p.x() - 49.5), std::abs(p.x() - 150.5))), ++sidePoints;
    }
    QVERIFY(sidePoints > 100);
    QVERIFY2(sideError < 1e-9, qPrintable(QString::number(sideError)));
    const double R = 60.3, c = 100;
    cv::Mat1b disc(200, 200, uchar(0));
    for (int y = 0; y < 200; ++y)
      for (int x = 0; x < 200; ++x) disc(y, x) = std::hypot(x - c, y - c) <= R ? 255 : 0;
    const auto dl = maskOutlines(disc);
    QCOMPARE(dl.size(), std::size_t(1));
    double mean = 0;
    for (const auto& p : dl.front()) mean += std::hypot(p.x() - c, p.y() - c) / dl.front().size();
    qInfo("square's sides at %.2f and %.2f; disc of radius %.1f: outline at %.3f px from its centre on average", minX, maxX, R, mean);
    QVERIFY(std::abs(mean - R) < 0.15);
  }

  // A dark disc on a bright background: anchors placed 6 px off the edge snap onto it.
  void snapFollowsTheEdge() {
    cv::Mat3b img(240, 320, cv::Vec3b(200, 200, 200));
    cv::circle(img, {160, 120}, 80, cv::Scalar(40, 40, 120), cv::FILLED, cv::LINE_AA);
    std::vector<Eigen::Vector2d> anchors;
    for (double a : {-0.6, 0.0, 0.6}) anchors.emplace_back(160 + 86 * std::cos(a), 120 + 86 * std::sin(a));
    auto path = snapToEdges(img, anchors);
    QVERIFY(path.size() > 20);
    double worst = 0;
    for (const auto& p : path) worst = std::max(worst, std::abs((p - Eigen::Vector2d(160, 120)).norm() - 80));
    qInfo("snapped %zu points; worst distance to the true edge %.2f px", path.size(), worst);
    QVERIFY(worst < 2.5);
  }
};

QTEST_GUILESS_MAIN(TestContour)
#include "test_contour.moc"
