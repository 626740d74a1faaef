// Appearance estimation and composition (imaging/appearance_fit.hpp) against the built-in phantom's ground
// truth: the phantom's frame was rendered with a known light and reflectance (resources/phantom), so the
// fit must recover them from the frame alone (with sensor noise and JPEG compression added), say when it
// cannot, reproduce the frame at rest, and carry the frame's texture with the tissue when it deforms.
#include "test_support.hpp"

#include "calculix.hpp"
#include "opencas.hpp"
#include "phantom/phantom.hpp"
#include "realorgan.hpp"

#include <rehearse/imaging/appearance_fit.hpp>
#include <rehearse/imaging/render.hpp>

#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <fstream>
#include <thread>
#include <opencv2/imgproc.hpp>

using namespace rehearse;

namespace {

cv::Mat3b withNoiseAndJpeg(const cv::Mat3b& frame, double sigma, int quality) {
  cv::Mat noise(frame.size(), CV_32FC3);
  cv::RNG rng(14);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
  cv::Mat f;
  frame.convertTo(f, CV_32FC3);
  f += noise;
  cv::Mat3b noisy;
  f.convertTo(noisy, CV_8UC3);
  if (quality <= 0) return noisy;
  std::vector<uchar> buf;
  cv::imencode(".jpg", noisy, buf, {cv::IMWRITE_JPEG_QUALITY, quality});
  return cv::imdecode(buf, cv::IMREAD_COLOR);
}

double relative(const Eigen::Vector3d& a, const Eigen::Vector3d& b, int k) { return std::abs(a[k] - b[k]) / std::abs(b[k]); }

}  // namespace

class TestAppearance : public QObject {
  Q_OBJECT
  phantom::Phantom c_;

  // The phantom's organ rendered with `truth` over a tissue background (`seed`) at `supersampling`, the scope's
  // border, noise and JPEG 90, and fitted.
  imaging::AppearanceFitResult fitRendered(const imaging::Appearance& truth, unsigned seed, int supersampling) const {
    const cv::Mat3b bg = imaging::makeTissueBackground(c_.camera.width, c_.camera.height, seed);
    cv::Mat3b frame = imaging::renderShaded(c_.camera, c_.truePose, c_.surfaceView(), truth, bg, supersampling);
    imaging::applyScopeVignette(frame);
    frame = withNoiseAndJpeg(frame, 2.0, 90);
    return imaging::fitAppearance(frame, imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView()));
  }

  // What composition takes for the phantom's organ at rest, Theta and the albedo fitted to `frame` (`fit` receives the
  // fit), the background inpainted behind the organ.
  imaging::CompositionInput fittedInput(const cv::Mat3b& frame, imaging::AppearanceFitResult& fit) const {
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    fit = imaging::fitAppearance(frame, g);
    imaging::CompositionInput in;
    in.camera = c_.camera;
    in.pose = c_.truePose;
    in.rest = in.deformed = c_.surfaceView();
    in.frame = frame;
    in.background = imaging::inpaintRegion(frame, g.mask());
    in.albedo = imaging::albedoRatio(fit.separation.diffuse, g, fit.theta, fit.usable);
    in.theta = fit.theta;
    return in;
  }

  // Checks a fit against the phantom's truth: the light within 5 % of its distance to the organ, kd and ks
  // within 5 % per channel, the roughness within 10 %.
  void checkTheta(const imaging::AppearanceFitResult& r, const imaging::Appearance* truth = nullptr) {
    const auto& t = truth ? *truth : c_.trueAppearance;
    const auto& f = r.theta;
    const Eigen::Vector3d organ = c_.truePose.apply(c_.centreOfGravity());
    const double distance = (t.lightPosition - organ).norm();
    qInfo("light (%.1f, %.1f, %.1f) mm, true (%.1f, %.1f, %.1f) mm: off by %.2f mm of %.0f mm", 1e3 * f.lightPosition.x(), 1e3 * f.lightPosition.y(),
          1e3 * f.lightPosition.z(), 1e3 * t.lightPosition.x(), 1e3 * t.lightPosition.y(), 1e3 * t.lightPosition.z(),
          1e3 * (f.lightPosition - t.lightPosition).norm(), 1e3 * distance);
    qInfo("kd (%.5f %.5f %.5f) true (%.5f %.5f %.5f); ks (%.5f %.5f %.5f) true (%.5f %.5f %.5f); sigma %.4f true %.4f", f.kd.x(), f.kd.y(), f.kd.z(),
          t.kd.x(), t.kd.y(), t.kd.z(), f.ks.x(), f.ks.y(), f.ks.z(), t.ks.x(), t.ks.y(), t.ks.z(), f.roughness, t.roughness);
    for (const auto& s : r.stages) qInfo("  stage %-28s rms %.2f levels, %zu px, %.0f ms", s.name.c_str(), s.rms, s.pixels, s.ms);
    QVERIFY2(r.highlightFound, r.status.c_str());
    QVERIFY(!r.textureOnly);
    QVERIFY((f.lightPosition - t.lightPosition).norm() < 0.05 * distance);
    int measured = 0;
    for (int k = 0; k < 3; ++k) {
      QVERIFY2(relative(f.kd, t.kd, k) < 0.05, qPrintable(QString("kd channel %1").arg(k)));
      if (r.ksMeasured[static_cast<std::size_t>(k)]) {
        QVERIFY2(relative(f.ks, t.ks, k) < 0.05, qPrintable(QString("ks channel %1").arg(k)));
        ++measured;
      } else {
        // A channel clipped over its whole highlight is not in the frame: said, not guessed silently. (The
        // phantom's red: its diffuse part alone clips around the highlight.)
        QVERIFY2(r.status.find("is clipped all over the highlight") != std::string::npos, r.status.c_str());
        QVERIFY(relative(f.ks, t.ks, k) < 0.10);  // the light's colour stands in: the phantom's highlight is nearly white
      }
    }
    QVERIFY(measured >= 2);
    QVERIFY(std::abs(f.roughness - t.roughness) < 0.10 * t.roughness);
    // A frame lit by the scope alone bears out no second source (issue 65): every one tried, none used.
    if (!t.hasDistantLight() && !t.hasAmbient()) {
      QCOMPARE(r.sources.size(), std::size_t(3));
      for (const auto& s : r.sources) QVERIFY2(!s.used, r.status.c_str());
      QVERIFY(!f.hasDistantLight() && !f.hasAmbient());
      QVERIFY2(r.status.find("no second light source is borne out") != std::string::npos, r.status.c_str());
    }
  }

 // The phantom seen through its own camera and true pose, its surface at rest and as `deformed`.
  imaging::CompositionInput phantomInput(const SurfaceView& deformed) const {
    imaging::CompositionInput in;
    in.camera = c_.camera;
    in.pose = c_.truePose;
    in.rest = c_.surfaceView();
    in.deformed = deformed;
    return in;
  }

  // The organ drawn with `truth` and a texture of its own: the diffuse reflectance modulated by a pattern fixed to the
  // tissue (two crossed waves of 11 and 17 mm, 20 % deep, a little different per channel), the specular one not,
  // clipped at white; per pixel centre (no rim supersampling), over `background`.
  static cv::Mat3b texturedTruth(const imaging::Camera& cam, const Pose& pose, const SurfaceView& sv,
                                 const imaging::Appearance& truth, const cv::Mat3b& background) {
    const auto g = imaging::surfaceGeometry(cam, pose, sv);
    cv::Mat3b out = background.clone();
    for (int y = 0; y < out.rows; ++y)
      for (int x = 0; x < out.cols; ++x) {
        if (g.triangle(y, x) < 0) continue;
        const cv::Vec3f pf = g.position(y, x), nf = g.normal(y, x);
        const Eigen::Vector3d p(pf[0], pf[1], pf[2]), n(nf[0], nf[1], nf[2]);
        const Eigen::Vector3d q = pose.R.transpose() * (p - pose.t);  // on the tissue
        double diffuse, specular;
        truth.terms(p, n, diffuse, specular);
        for (int k = 0; k < 3; ++k) {  // BGR
          const double a = 1 + (0.2 - 0.03 * k) * std::sin(2 * M_PI * (q.x() + 0.4 * q.z()) / 0.011) *
                                   std::sin(2 * M_PI * (q.y() - 0.3 * q.z()) / 0.017);
          out(y, x)[k] = cv::saturate_cast<uchar>(255.0 * (a * truth.kd[2 - k] * diffuse + truth.ks[2 - k] * specular));
        }
      }
    return out;
  }

  // A reference z-buffer written here, independent of imaging's rasteriser: per pixel centre (integers), the nearest
  // triangle's point in the camera's frame (barycentric over the projected triangle), its depth (infinity: none).
  struct ZBuffer {
    cv::Mat1f depth;
    cv::Mat3f point;
  };
  static ZBuffer zBuffer(const imaging::Camera& cam, const Pose& pose, const SurfaceView& s) {
    ZBuffer z{cv::Mat1f(cam.height, cam.width, std::numeric_limits<float>::infinity()), cv::Mat3f(cam.height, cam.width)};
    for (std::size_t t = 0; t < s.triangleCount; ++t) {
      Eigen::Vector3d c[3];
      Eigen::Vector2d q[3];
      bool front = true;
      for (int i = 0; i < 3; ++i) {
        c[i] = pose.apply(s.vertex(static_cast<std::size_t>(s.triangles[3 * t + static_cast<std::size_t>(i)])));
        front &= c[i].z() > 1e-3;
        q[i] = Eigen::Vector2d(cam.K(0, 0) * c[i].x() / c[i].z() + cam.K(0, 1) * c[i].y() / c[i].z() + cam.K(0, 2),
                               cam.K(1, 1) * c[i].y() / c[i].z() + cam.K(1, 2));
      }
      if (!front) continue;
      const double area = (q[1] - q[0]).x() * (q[2] - q[0]).y() - (q[1] - q[0]).y() * (q[2] - q[0]).x();
      if (std::abs(area) < 1e-12) continue;
      const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({q[0].x(), q[1].x(), q[2].x()})))),
                x1 = std::min(cam.width - 1, static_cast<int>(std::floor(std::max({q[0].x(), q[1].x(), q[2].x()})))),
                y0 = std::max(0, static_cast<int>(std::ceil(std::min({q[0].y(), q[1].y(), q[2].y()})))),
                y1 = std::min(cam.height - 1, static_cast<int>(std::floor(std::max({q[0].y(), q[1].y(), q[2].y()}))));
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
          // Screen-space barycentrics, corrected for perspective (1/z interpolated).
          double w[3];
          for (int i = 0; i < 3; ++i) {
            const Eigen::Vector2d& a = q[(i + 1) % 3];
            const Eigen::Vector2d& b = q[(i + 2) % 3];
            w[i] = ((b - a).x() * (y - a.y()) - (b - a).y() * (x - a.x())) / area;
          }
          if (w[0] < 0 || w[1] < 0 || w[2] < 0) continue;
          const double inv = w[0] / c[0].z() + w[1] / c[1].z() + w[2] / c[2].z();
          const Eigen::Vector3d p = (w[0] / c[0].z() * c[0] + w[1] / c[1].z() * c[1] + w[2] / c[2].z() * c[2]) / inv;
          if (p.z() < z.depth(y, x)) {
            z.depth(y, x) = static_cast<float>(p.z());
            z.point(y, x) = cv::Vec3f(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
          }
        }
    }
    return z;
  }

 private slots:
  void initTestCase() { c_ = phantom::makePhantom(); }

  void thetaRecoveredFromTheFrame() {
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const cv::Mat3b frame = withNoiseAndJpeg(c_.frame, 2.0, 0);
    const auto r = imaging::fitAppearance(frame, g);
    qInfo("%s", r.status.c_str());
    checkTheta(r);
  }

  // Frames are not our renderer's: sensor noise, JPEG at quality 85, highlights clipped at 255 (the
  // phantom's red channel saturates at its highlight), the scope's dark border.
  void thetaRecoveredThroughNoiseAndJpeg() {
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const cv::Mat3b frame = withNoiseAndJpeg(c_.frame, 3.0, 85);
    const auto r = imaging::fitAppearance(frame, g);
    qInfo("%s", r.status.c_str());
    checkTheta(r);
  }

  // A frame the registered mesh did not make: the phantom meshed about four times finer (its own surface
  // and renderer), with the scope's vignette, noise and JPEG, fitted through the coarse mesh placed where the
  // fine one is (the same shape in the same model frame, discretised differently).
  void thetaRecoveredFromAFinerMeshsFrame() {
    phantom::PhantomOptions o;
    o.targetTets = 16000;
    const phantom::Phantom fine = phantom::makePhantom(o);
    QVERIFY(fine.volume.tets.size() > 3 * c_.volume.tets.size());
    cv::Mat3b frame = fine.frame.clone();
    if (!std::getenv("T_NOVIG")) imaging::applyScopeVignette(frame);
    if (!std::getenv("T_NONOISE")) frame = withNoiseAndJpeg(frame, 2.0, 85);
    if (std::getenv("T_DUMP")) cv::imwrite("/tmp/fineframe.png", frame);
    const auto g = imaging::surfaceGeometry(c_.camera, fine.truePose, c_.surfaceView());
    const auto r = imaging::fitAppearance(frame, g);
    qInfo("frame from %zu surface triangles, fitted through %zu: %s", fine.surface.size(), c_.surface.size(), r.status.c_str());
    checkTheta(r);
  }

  // A dimmer organ whose red does not clip around the highlight: every channel's ks is measured. The frame
  // is rendered at another supersampling (3x, not the phantom's 2x) over another background.
  void thetaRecoveredWhenNothingClips() {
    imaging::Appearance dim = c_.trueAppearance;
    dim.kd *= 0.6;
    const auto r = fitRendered(dim, 5, 3);
    qInfo("%s", r.status.c_str());
    QVERIFY(r.ksMeasured[0] && r.ksMeasured[1] && r.ksMeasured[2]);
    checkTheta(r, &dim);
  }

  // A laparoscope's light (appearance.hpp): at the scope's tip, 9 mm off the lens on the other side, with a
  // cone and vignetting falling as cos^8 off the axis. The frame rendered with it (noise, JPEG, the scope's
  // border) gives back the light, n and the reflectance, and every part of the model shows in the checks.
  void laparoscopeLightAndFalloffRecovered() {
    imaging::Appearance scope = c_.trueAppearance;
    scope.lightPosition = Eigen::Vector3d(-0.004, 0.008, 0.002);
    scope.falloff = 8;
    scope.kd *=
        1.6;  // the cone darkens the organ's edges: brighter at the centre, as a real scope's gain would make it
    scope.ks *= 1.6;
    const auto r = fitRendered(scope, 9, 2);
    qInfo("%s", r.status.c_str());
    qInfo("fall-off n %.3f (true %.1f)", r.theta.falloff, scope.falloff);
    for (const auto& c : r.checks) qInfo("  without %s: %.3f of %.3f", c.part.c_str(), c.explainedWithout, r.explained);
    checkTheta(r, &scope);
    QVERIFY(std::abs(r.theta.falloff - scope.falloff) < 0.10 * scope.falloff);
    QCOMPARE(r.checks.size(), std::size_t(3));
    for (const auto& c : r.checks) QVERIFY2(c.holds, c.part.c_str());
    QVERIFY(!r.lightAtBound);
  }

  // A frame lit by the scope and from outside it (issue 65, "the light the frame shows"): the phantom rendered with
  // the scope's light plus a distant light from above-left on the camera's side and an ambient term, through noise and
  // JPEG. The fit uses both, says so, and recovers them: the distant light's direction within 10 degrees, k_r within
  // 20 % and k_a within 10 % per channel (measured 8.7 degrees, k_r 13-14 % low, k_a 5-6 % high: the scope's light, the
  // distant one and the ambient term trade against each other over the phantom's normals; with the scope's light held
  // where the fit without a second source put it, the direction was 25-31 degrees off and k_a 0). With an ambient term
  // alone, only that is used.
  void secondSourceRecoveredWhereTheFrameShowsIt() {
    const Eigen::Vector3d colour = c_.trueAppearance.kd / c_.trueAppearance.kd.maxCoeff();
    imaging::Appearance truth = c_.trueAppearance;
    truth.kd *= 0.5, truth.ks *= 0.5;  // room for the other light below white
    truth.roomDirection = Eigen::Vector3d(-0.45, -0.55, -0.70).normalized();
    truth.kr = 0.25 * colour;
    truth.ka = 0.20 * colour;
    const auto r = fitRendered(truth, 5, 2);
    qInfo("%s", r.status.c_str());
    const auto& f = r.theta;
    const double angle = std::acos(std::clamp(f.roomDirection.dot(truth.roomDirection), -1.0, 1.0)) * 180 / M_PI;
    qInfo("direction (%.3f %.3f %.3f), true (%.3f %.3f %.3f): %.2f degrees off", f.roomDirection.x(), f.roomDirection.y(),
          f.roomDirection.z(), truth.roomDirection.x(), truth.roomDirection.y(), truth.roomDirection.z(), angle);
    qInfo("kr (%.4f %.4f %.4f) true (%.4f %.4f %.4f); ka (%.4f %.4f %.4f) true (%.4f %.4f %.4f)", f.kr.x(), f.kr.y(),
          f.kr.z(), truth.kr.x(), truth.kr.y(), truth.kr.z(), f.ka.x(), f.ka.y(), f.ka.z(), truth.ka.x(), truth.ka.y(),
          truth.ka.z());
    QCOMPARE(r.sources.size(), std::size_t(3));
    QVERIFY2(r.sources[2].used, r.status.c_str());  // a distant light and an ambient term
    QVERIFY2(r.status.find("with a distant light and an ambient term") != std::string::npos, r.status.c_str());
    // What the frame cannot tell apart is said: a second source can stand in for an organ registered off the frame's.
    QVERIFY2(r.status.find("check the registration") != std::string::npos, r.status.c_str());
    QVERIFY(angle < 10.0);
    for (int k = 0; k < 3; ++k) {
      QVERIFY2(relative(f.kr, truth.kr, k) < 0.20, qPrintable(QString("kr channel %1").arg(k)));
      QVERIFY2(relative(f.ka, truth.ka, k) < 0.10, qPrintable(QString("ka channel %1").arg(k)));
    }
    QVERIFY(r.explained >= 0.95);
    QVERIFY(r.explained >= r.scopeExplained + imaging::AppearanceFitResult::kSecondSourceGain);
    checkScopeLight(r, truth);

    imaging::Appearance ambientOnly = c_.trueAppearance;
    ambientOnly.kd *= 0.7, ambientOnly.ks *= 0.7;
    ambientOnly.ka = 0.15 * colour;
    const auto a = fitRendered(ambientOnly, 6, 2);
    qInfo("%s", a.status.c_str());
    qInfo("ka (%.4f %.4f %.4f) true (%.4f %.4f %.4f)", a.theta.ka.x(), a.theta.ka.y(), a.theta.ka.z(), ambientOnly.ka.x(),
          ambientOnly.ka.y(), ambientOnly.ka.z());
    QVERIFY2(a.sources[0].used, a.status.c_str());  // an ambient term
    QVERIFY(!a.theta.hasDistantLight());
    for (int k = 0; k < 3; ++k) QVERIFY(relative(a.theta.ka, ambientOnly.ka, k) < 0.10);
    checkScopeLight(a, ambientOnly);
  }

 private:
  // Beside a second source, the scope's light within 5 % of its distance to the organ, k_d within 5 % per channel, k_s
  // within 15 % on the channels the frame measures and the roughness within 5 %, both refitted after the light moved
  // (measured: k_s 2.3-7.8 % and the roughness 0.0-1.6 %; with k_s alone refitted at the roughness fitted before, k_s
  // 8.6-11 % and the roughness 5.9-15 %; without any refit k_s 5.5-9 % with both sources, 24 % with the ambient term
  // alone).
  void checkScopeLight(const imaging::AppearanceFitResult& r, const imaging::Appearance& truth) {
    qInfo("ks (%.5f %.5f %.5f) true (%.5f %.5f %.5f), measured %d%d%d; before the second source (%.5f %.5f %.5f)",
          r.theta.ks.x(), r.theta.ks.y(), r.theta.ks.z(), truth.ks.x(), truth.ks.y(), truth.ks.z(), int(r.ksMeasured[0]),
          int(r.ksMeasured[1]), int(r.ksMeasured[2]), r.scopeTheta.ks.x(), r.scopeTheta.ks.y(), r.scopeTheta.ks.z());
    for (int k = 0; k < 3; ++k)
      if (r.ksMeasured[static_cast<std::size_t>(k)])
        QVERIFY2(relative(r.theta.ks, truth.ks, k) < 0.15, qPrintable(QString("ks channel %1").arg(k)));
    qInfo("roughness %.4f true %.4f (%.1f %% off); before the second source %.4f", r.theta.roughness, truth.roughness,
          100 * std::abs(r.theta.roughness / truth.roughness - 1), r.scopeTheta.roughness);
    QVERIFY(std::abs(r.theta.roughness / truth.roughness - 1) < 0.05);
    const double distance = (truth.lightPosition - c_.truePose.apply(c_.centreOfGravity())).norm();
    qInfo("scope's light %.2f mm off of %.0f mm; kd (%.5f %.5f %.5f) true (%.5f %.5f %.5f)",
          1e3 * (r.theta.lightPosition - truth.lightPosition).norm(), 1e3 * distance, r.theta.kd.x(), r.theta.kd.y(),
          r.theta.kd.z(), truth.kd.x(), truth.kd.y(), truth.kd.z());
    QVERIFY((r.theta.lightPosition - truth.lightPosition).norm() < 0.05 * distance);
    for (int k = 0; k < 3; ++k) QVERIFY2(relative(r.theta.kd, truth.kd, k) < 0.05, qPrintable(QString("kd channel %1").arg(k)));
  }

 private slots:

  // The second source on the real ex-vivo frame (Open-CAS, lit from outside the scope): fitted on one half of the
  // organ, it predicts the other half (pixels no fit saw) better than the scope's light alone fitted on the same half,
  // by at least 1 dB each way; the frame bears it out beyond the pixels it was fitted on.
  void secondSourcePredictsTheHalfItWasNotFittedOn() {
    if (!testdata::OpenCas::available()) QSKIP("../shared/data/open-cas is absent");
    const auto oc = testdata::OpenCas::load();
    const auto g = imaging::surfaceGeometry(oc.camera, Pose{}, oc.surface());
    const cv::Rect box = cv::boundingRect(g.mask());
    const cv::Mat1b usableAll = imaging::usablePixels(oc.frame, g.mask());
    for (int half = 0; half < 2; ++half) {
      cv::Mat1b a(g.mask().size(), uchar(0));
      a.colRange(half == 0 ? 0 : box.x + box.width / 2, half == 0 ? box.x + box.width / 2 : a.cols).setTo(255);
      imaging::SurfaceGeometry ga = g;
      ga.triangle = g.triangle.clone();
      ga.triangle.setTo(-1, ~a);
      imaging::AppearanceFitOptions scopeOnly;
      scopeOnly.secondSource = false;
      const auto both = imaging::fitAppearance(oc.frame, ga), scope = imaging::fitAppearance(oc.frame, ga, scopeOnly);
      QVERIFY(scope.sources.empty() && !scope.theta.hasDistantLight() && !scope.theta.hasAmbient());
      QVERIFY2(both.theta.hasDistantLight() || both.theta.hasAmbient(), both.status.c_str());
      auto predicted = [&](const imaging::Appearance& theta) {
        const cv::Mat3b model = imaging::renderShaded(oc.camera, Pose{}, oc.surface(), theta,
                                                      cv::Mat3b(oc.frame.size(), cv::Vec3b(0, 0, 0)), 1);
        return imaging::psnr(oc.frame, model, usableAll & ~a);
      };
      const double withSecond = predicted(both.theta), alone = predicted(scope.theta);
      qInfo("fitted on the %s half: the other half predicted %.2f dB with %s, %.2f dB by the scope's light alone",
            half == 0 ? "left" : "right", withSecond,
            both.theta.hasDistantLight() ? (both.theta.hasAmbient() ? "a distant light and an ambient term" : "a distant light")
                                         : "an ambient term",
            alone);
      QVERIFY(withSecond >= alone + 1.0);
    }
  }

  // The real ex-vivo frame (Open-CAS): the light stays at the scope (within the search's 30 mm), the share
  // explained that the status reports is what the fitted model, rendered by the independent renderer
  // (renderShaded), leaves of the organ's pixels, and the challenge's fiducial beads are left out of the fit.
  void realFrameIsFittedWithinTheScopeAndSaysWhatItExplains() {
    if (!testdata::OpenCas::available()) QSKIP("../shared/data/open-cas is absent");
    const auto oc = testdata::OpenCas::load();
    const auto g = imaging::surfaceGeometry(oc.camera, Pose{}, oc.surface());
    const auto r = imaging::fitAppearance(oc.frame, g);
    qInfo("%s", r.status.c_str());
    qInfo("light (%.1f, %.1f, %.1f) mm, n %.2f; explained %.3f, smooth share %.3f", 1e3 * r.theta.lightPosition.x(),
          1e3 * r.theta.lightPosition.y(), 1e3 * r.theta.lightPosition.z(), r.theta.falloff, r.explained,
          r.smoothShare);
    QVERIFY(r.theta.lightPosition.norm() <= 0.0301);
    QVERIFY(r.theta.kd.allFinite() && r.theta.ks.allFinite());
    QVERIFY(r.status.find("explains " + std::to_string(imaging::explainedPercent(r.explained)) + " %") != std::string::npos);
    // The share recomputed: the specular-free image against Theta's diffuse part rendered by renderShaded,
    // over the pixels the diffuse stage could use (usable, not foreign, away from highlights, no channel near
    // clipping); the fit samples a regular subset of them.
    imaging::Appearance diffuseOnly = r.theta;
    diffuseOnly.ks.setZero();
    const cv::Mat3b model = imaging::renderShaded(oc.camera, Pose{}, oc.surface(), diffuseOnly,
                                                  cv::Mat3b(oc.frame.size(), cv::Vec3b(0, 0, 0)), 1);
    cv::Mat1b used = r.usable & ~r.foreign, grown;
    cv::dilate(r.separation.highlights, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
    used.setTo(0, grown);
    std::vector<cv::Mat1b> ch;
    cv::split(r.separation.diffuse, ch);
    used.setTo(0, (ch[0] >= 235) | (ch[1] >= 235) | (ch[2] >= 235));
    const cv::Scalar mean = cv::mean(r.separation.diffuse, used);
    double sse = 0, sst = 0;
    std::vector<double> errors;
    for (int y = 0; y < used.rows; ++y)
      for (int x = 0; x < used.cols; ++x)
        if (used(y, x))
          for (int k = 0; k < 3; ++k) {
            const double v = r.separation.diffuse(y, x)[k];
            sse += (v - model(y, x)[k]) * (v - model(y, x)[k]);
            sst += (v - mean[k]) * (v - mean[k]);
          }
    const double share = 1 - sse / sst;
    qInfo("recomputed over %d px: %.3f", cv::countNonZero(used), share);
    QVERIFY(std::abs(std::max(share, 0.0) - r.explained) < 0.03);
    // The beads inside the organ (the challenge's own mask): left out as foreign colour or as highlights.
    const cv::Mat1b beadsOnOrgan = oc.beads & r.usable;
    const cv::Mat1b caught = beadsOnOrgan & (r.foreign | r.separation.highlights);
    qInfo("bead pixels on the organ: %d, left out: %d", cv::countNonZero(beadsOnOrgan), cv::countNonZero(caught));
    QVERIFY(cv::countNonZero(beadsOnOrgan) > 50);
    QVERIFY(cv::countNonZero(caught) >= 0.8 * cv::countNonZero(beadsOnOrgan));
  }

  // A novel view on synthetic truth: the phantom rendered from a second view (the scope turned 14 degrees about
  // the organ, its light with it) with the true Theta; that view predicted from the first view's fit lands
  // within 1 dB of the same prediction made with the true Theta, and beats pasting the first frame's texture by
  // at least 3 dB where the highlights are (they move with the view; the texture's stay where they were).
  void novelViewPredictsAnotherView() {
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const cv::Mat3b frame = withNoiseAndJpeg(c_.frame, 2.0, 90);
    const auto r = imaging::fitAppearance(frame, g);
    const Eigen::Vector3d centre = c_.truePose.apply(c_.centreOfGravity());
    const Pose view2 = c_.truePose.turnedAbout(
        Eigen::AngleAxisd(14 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix(), centre);
    const cv::Mat3b truth = imaging::renderShaded(c_.camera, view2, c_.surfaceView(), c_.trueAppearance,
                                                  cv::Mat3b(frame.size(), cv::Vec3b(0, 0, 0)), 2);
    auto predict = [&](const imaging::Appearance& theta, bool textureOnly, bool detail = true) {
      imaging::CompositionInput in;
      in.camera = c_.camera;
      in.pose = c_.truePose;
      in.rest = in.deformed = c_.surfaceView();
      in.frame = frame;
      in.background = frame;
      in.albedo = imaging::albedoRatio(r.separation.diffuse, g, theta, r.usable);
      in.theta = theta;
      in.textureOnly = textureOnly;
      in.frameDetail = detail;
      return imaging::composeNovelView(in, c_.camera, view2);
    };
    const auto fitted = predict(r.theta, false), withTruth = predict(c_.trueAppearance, false),
               texture = predict(r.theta, true), modelAlone = predict(r.theta, false, false);
    // Compared where both views see the organ, away from its rim; the highlights: where the second view's
    // true specular term stands above the noise.
    cv::Mat1b both = fitted.covered & fitted.seen;
    cv::erode(both, both, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
    imaging::Appearance specularOnly = c_.trueAppearance;
    specularOnly.kd.setZero();
    const cv::Mat3b spec = imaging::renderShaded(c_.camera, view2, c_.surfaceView(), specularOnly,
                                                 cv::Mat3b(frame.size(), cv::Vec3b(0, 0, 0)), 1);
    cv::Mat1b highlights;
    cv::cvtColor(spec, highlights, cv::COLOR_BGR2GRAY);
    highlights = (highlights > 20) & both;
    // The first view's highlights too: where the texture carries them to the wrong place.
    imaging::Appearance specular1 = specularOnly;
    const cv::Mat3b spec1 = imaging::renderShaded(c_.camera, c_.truePose, c_.surfaceView(), specular1,
                                                  cv::Mat3b(frame.size(), cv::Vec3b(0, 0, 0)), 1);
    const double dbFit = imaging::psnr(truth, fitted.image, both), dbTrue = imaging::psnr(truth, withTruth.image, both);
    const double hiFit = imaging::psnr(truth, fitted.image, highlights),
                 hiTexture = imaging::psnr(truth, texture.image, highlights);
    qInfo(
        "second view: %d px seen by both, %d highlight px; fitted Theta %.2f dB, true Theta %.2f dB; at the highlights "
        "%.2f dB against texture-only %.2f dB",
        cv::countNonZero(both), cv::countNonZero(highlights), dbFit, dbTrue, hiFit, hiTexture);
    if (std::getenv("REHEARSE_SCREENSHOT_DIR")) {
      const std::string dir = std::getenv("REHEARSE_SCREENSHOT_DIR");
      cv::Mat3b row;
      cv::hconcat(std::vector<cv::Mat>{frame, truth, fitted.image, texture.image}, row);
      cv::imwrite(dir + "/novel-view.png", row);
    }
    QVERIFY(cv::countNonZero(both) > 20000);
    QVERIFY(cv::countNonZero(highlights) > 300);
    QVERIFY(dbFit >= dbTrue - 1.0);
    QVERIFY(hiFit >= hiTexture + 3.0);
    // The frame's detail carried (issue 65) against the model alone: no worse where both views see the organ, nor
    // at the moved highlights.
    const double dbModel = imaging::psnr(truth, modelAlone.image, both), hiModel = imaging::psnr(truth, modelAlone.image, highlights);
    qInfo("the model alone: %.2f dB, at the highlights %.2f dB", dbModel, hiModel);
    QVERIFY(dbFit >= dbModel - 0.5);
    QVERIFY(hiFit >= hiModel - 0.5);
    // An organ behind the view, and a background of another size: one sentence each.
    Pose behind = view2;
    behind.t.z() = -0.5;
    imaging::CompositionInput in;
    in.camera = c_.camera;
    in.pose = c_.truePose;
    in.rest = in.deformed = c_.surfaceView();
    in.frame = in.background = frame;
    in.textureOnly = true;
    QVERIFY_THROWS_EXCEPTION(rehearse::InputError, imaging::composeNovelView(in, c_.camera, behind));
    QVERIFY_THROWS_EXCEPTION(rehearse::InputError, imaging::composeNovelView(in, c_.camera, view2, cv::Mat3b(10, 10)));
  }

  // Issue 65 on the real organ shapes (synthetic truth with a known light): each organ's surface, seen broadside
  // through the scikit-surgery laparoscope at 1920x1080, is drawn with
  // the phantom's light and reflectance and a texture of its own (texturedTruth), fitted through noise and JPEG 90, and
  // seen again through the scope turned 14 degrees about the organ (its light with it). Where the second view's
  // highlights are, the re-shaded novel view comes at least 3 dB nearer the truth than the frame's texture carried
  // over; where both views see the organ it is no worse; at rest the composite is the frame.
  void novelViewOnRealOrganShapes_data() {
    QTest::addColumn<QString>("file");
    QTest::newRow("patient liver") << "scikit-surgery/patient-liver/liver.vtk";
    QTest::newRow("BodyParts3D liver") << "bodyparts3d/FMA7197_Liver.obj";
    QTest::newRow("kidney") << "scikit-surgery/kidney/kidney.vtk";
    QTest::newRow("uterus") << "hubmap/VH_F_Uterus.glb";
  }
  void novelViewOnRealOrganShapes() {
    QFETCH(QString, file);
    REQUIRE_SHARED(file.toStdString());
    const simcore::Mesh organ = testing::loadOrganSurface(sharedData(file.toStdString()));
    const imaging::Camera cam = testing::scikitSurgeryCamera();
    const Pose pose = testing::broadsideView(organ, cam);
    const SurfaceView sv = organ.surfaceView();
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& p : organ.points) centre += pose.apply(p) / static_cast<double>(organ.points.size());
    imaging::Appearance truth = c_.trueAppearance;  // as bright at the organ's distance as the phantom at its own
    truth.kd *= std::pow(centre.z() / 0.195, 2);
    truth.ks *= std::pow(centre.z() / 0.195, 2);
    const cv::Mat3b bg = imaging::makeTissueBackground(cam.width, cam.height, 9);
    const cv::Mat3b frame = withNoiseAndJpeg(texturedTruth(cam, pose, sv, truth, bg), 2.0, 90);
    const auto g = imaging::surfaceGeometry(cam, pose, sv);
    const auto r = imaging::fitAppearance(frame, g);
    qInfo("%s: %s", qPrintable(file), r.status.c_str());
    QVERIFY2(!r.textureOnly, r.status.c_str());
    imaging::CompositionInput in;
    in.camera = cam;
    in.pose = pose;
    in.rest = in.deformed = sv;
    in.frame = frame;
    in.background = imaging::inpaintRegion(frame, g.mask());
    in.albedo = imaging::albedoRatio(r.separation.diffuse, g, r.theta, r.usable);
    in.theta = r.theta;
    in.trust = imaging::Reshading::of(r.explained, r.textureOnly).trust;
    // At rest: the frame.
    cv::Mat1b inner;
    cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
    const cv::Mat3b atRest = imaging::compose(in);
    cv::Mat3b diff;
    cv::absdiff(atRest, frame, diff);
    int same = 0;
    for (int y = 0; y < diff.rows; ++y)
      for (int x = 0; x < diff.cols; ++x)
        if (inner(y, x)) same += std::max({diff(y, x)[0], diff(y, x)[1], diff(y, x)[2]}) <= 3;
    // The second view.
    const Pose view2 = pose.turnedAbout(Eigen::AngleAxisd(14 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix(), centre);
    const cv::Mat3b black(frame.size(), cv::Vec3b(0, 0, 0));
    const cv::Mat3b trueView = texturedTruth(cam, view2, sv, truth, black);
    const auto fitted = imaging::composeNovelView(in, cam, view2);
    imaging::CompositionInput asTexture = in;
    asTexture.textureOnly = true;
    const auto texture = imaging::composeNovelView(asTexture, cam, view2);
    cv::Mat1b both = fitted.covered & fitted.seen;
    cv::erode(both, both, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
    imaging::Appearance specularOnly = truth;
    specularOnly.kd.setZero();
    cv::Mat1b highlights;
    cv::cvtColor(imaging::renderShaded(cam, view2, sv, specularOnly, black, 1), highlights, cv::COLOR_BGR2GRAY);
    highlights = (highlights > 20) & both;
    const double db = imaging::psnr(trueView, fitted.image, both), dbTexture = imaging::psnr(trueView, texture.image, both),
                 hi = imaging::psnr(trueView, fitted.image, highlights),
                 hiTexture = imaging::psnr(trueView, texture.image, highlights);
    qInfo("%s: explained %.0f %% (trust %.2f); at rest %d of %d inner px the frame's within 3 levels; the second view, %d px "
          "seen by both: re-shaded %.2f dB, texture carried over %.2f dB; at its %d highlight px %.2f against %.2f dB",
          qPrintable(file), 100 * r.explained, in.trust, same, cv::countNonZero(inner), cv::countNonZero(both), db,
          dbTexture, cv::countNonZero(highlights), hi, hiTexture);
    if (const char* dir = std::getenv("REHEARSE_SCREENSHOT_DIR")) {
      cv::Mat3b row;
      cv::hconcat(std::vector<cv::Mat>{frame, trueView, fitted.image, texture.image}, row);
      cv::resize(row, row, cv::Size(), 0.25, 0.25, cv::INTER_AREA);
      cv::imwrite(std::string(dir) + "/novel-" + QString(QTest::currentDataTag()).replace(' ', '-').toStdString() + ".png", row);
    }
    QVERIFY(same >= 0.99 * cv::countNonZero(inner));
    QVERIFY(cv::countNonZero(both) > 20000);
    QVERIFY(cv::countNonZero(highlights) > 300);
    QVERIFY(hi >= hiTexture + 3.0);
    QVERIFY(db >= dbTexture);
  }

  // Issue 65, the Open-CAS frame (left view only): its fit is marked texture only, and the novel view then is the
  // frame's texture carried over pixel by pixel, checked against a reference written here (its own z-buffers of the CT
  // surface in both views, the frame sampled bilinearly where each point of the view projects, a point hidden in the
  // frame when a surface lies over 2 mm nearer there): through a stereo partner 5 mm to the right and through the scope
  // turned 10 degrees. The tissue the frame did not see is drawn in the organ's mean colour in the frame, not left empty,
  // and so is the back of the open surface seen from behind.
  void openCasNovelViewIsTheTextureCarriedOver() {
    REQUIRE_SHARED(std::string("open-cas/Stereo_SD_d_complete_22_IMG_left.bmp"));
    const auto oc = testdata::OpenCas::load();
    const auto g = imaging::surfaceGeometry(oc.camera, Pose{}, oc.surface());
    const auto r = imaging::fitAppearance(oc.frame, g);
    QVERIFY2(r.textureOnly, r.status.c_str());
    imaging::CompositionInput in;
    in.camera = oc.camera;
    in.rest = in.deformed = oc.surface();
    in.frame = in.background = oc.frame;
    in.theta = r.theta;
    in.textureOnly = imaging::Reshading::of(r.explained, r.textureOnly).textureOnly;
    QVERIFY(in.textureOnly);
    const ZBuffer fitted = zBuffer(oc.camera, Pose{}, oc.surface());
    const cv::Scalar organMean = cv::mean(oc.frame, fitted.depth < std::numeric_limits<float>::infinity());
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < oc.surface().vertexCount; ++i) centre += oc.surface().vertex(i) / static_cast<double>(oc.surface().vertexCount);
    Pose stereo;
    stereo.t = Eigen::Vector3d(-0.005, 0, 0);
    const Pose turned = Pose{}.turnedAbout(Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix(), centre);
    for (const auto& [name, view] : {std::pair<const char*, Pose>{"5 mm to the right", stereo}, {"turned 10 degrees", turned}}) {
      const auto novel = imaging::composeNovelView(in, oc.camera, view);
      const ZBuffer seenThere = zBuffer(oc.camera, view, oc.surface());
      cv::Mat1b drawn = seenThere.depth < std::numeric_limits<float>::infinity(), inner;
      cv::erode(drawn, inner, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)));
      int carried = 0, carriedSame = 0, unseen = 0, unseenMean = 0, empty = 0;
      for (int y = 0; y < inner.rows; ++y)
        for (int x = 0; x < inner.cols; ++x) {
          if (!inner(y, x)) continue;
          const cv::Vec3b got = novel.image(y, x);
          empty += !novel.covered(y, x);
          // The point in the frame's camera (the organ's frame here: its pose is the identity).
          const cv::Vec3f pv = seenThere.point(y, x);
          const Eigen::Vector3d p = view.R.transpose() * (Eigen::Vector3d(pv[0], pv[1], pv[2]) - view.t);
          const double u = oc.camera.K(0, 0) * p.x() / p.z() + oc.camera.K(0, 1) * p.y() / p.z() + oc.camera.K(0, 2),
                       v = oc.camera.K(1, 1) * p.y() / p.z() + oc.camera.K(1, 2);
          const int iu = static_cast<int>(std::lround(u)), iv = static_cast<int>(std::lround(v));
          const bool seen = iu >= 0 && iv >= 0 && iu < oc.camera.width - 1 && iv < oc.camera.height - 1 &&
                            fitted.depth(iv, iu) > p.z() - 0.002;
          int off = 0;
          if (seen) {
            const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
            const double fx = u - x0, fy = v - y0;
            for (int k = 0; k < 3; ++k) {
              const double want = (1 - fy) * ((1 - fx) * oc.frame(y0, x0)[k] + fx * oc.frame(y0, x0 + 1)[k]) +
                                  fy * ((1 - fx) * oc.frame(y0 + 1, x0)[k] + fx * oc.frame(y0 + 1, x0 + 1)[k]);
              off = std::max(off, static_cast<int>(std::abs(want - got[k]) + 0.5));
            }
            ++carried;
            carriedSame += off <= 1;
          } else {
            for (int k = 0; k < 3; ++k) off = std::max(off, static_cast<int>(std::abs(organMean[k] - got[k]) + 0.5));
            ++unseen;
            unseenMean += off <= 1;
          }
        }
      qInfo("Open-CAS, the view %s: of %d inner px, %d carried from the frame (%d within a level of the reference's "
            "colour), %d the frame did not see (%d in the organ's mean colour); %d not drawn",
            name, cv::countNonZero(inner), carried, carriedSame,
            unseen, unseenMean, empty);
      QVERIFY(carried > 20000);
      QVERIFY(carriedSame >= 0.995 * carried);
      QVERIFY(unseenMean >= 0.9 * unseen);
      QVERIFY(empty <= 0.001 * cv::countNonZero(inner));
    }
    // Its back (the scope turned 150 degrees about the organ): the CT surface is open, and the frame saw none of its
    // back, whatever the depths say: the organ's mean colour, not the front's texture mirrored.
    const Pose back = Pose{}.turnedAbout(Eigen::AngleAxisd(150 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix(), centre);
    const auto behind = imaging::composeNovelView(in, oc.camera, back);
    cv::Mat1b inner;
    cv::erode(behind.covered, inner, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)));
    int plain = 0;
    for (int y = 0; y < inner.rows; ++y)
      for (int x = 0; x < inner.cols; ++x) {
        if (!inner(y, x)) continue;
        int off = 0;
        for (int k = 0; k < 3; ++k) off = std::max(off, static_cast<int>(std::abs(organMean[k] - behind.image(y, x)[k]) + 0.5));
        plain += off <= 1;
      }
    qInfo("Open-CAS from behind: %d of %d inner px in the organ's mean colour, %d seen", plain, cv::countNonZero(inner),
          cv::countNonZero(behind.seen & inner));
    QVERIFY(cv::countNonZero(inner) > 10000);
    QVERIFY(plain >= 0.99 * cv::countNonZero(inner));
  }

  // Tissue the frame saw obliquely and a move turns towards the camera (here the phantom's underside, the organ tilted 25
  // degrees about the camera's horizontal axis through its centre) has a few frame pixels to stretch over many: drawn
  // from them it was a smear of streaks (helper-62, a pull in step 7). Where frameDetailWeights keeps less than half of
  // the frame's detail, the composite is the model, and so within reach of the truth (the phantom's own model at the
  // tilted pose); where the tissue is not stretched, it is the frame's, as before.
  void stretchedTissueIsDrawnByTheModel() {
    const cv::Mat3b frame = withNoiseAndJpeg(c_.frame, 2.0, 0);
    imaging::AppearanceFitResult r;
    const imaging::CompositionInput in = fittedInput(frame, r);
    const imaging::Compositor compositor(in);
    const SurfaceView rest = c_.surfaceView();
    const Eigen::Vector3d centre = c_.centreOfGravity();
    const Eigen::Matrix3d turn = c_.truePose.R.transpose() *
                                 Eigen::AngleAxisd(-25 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix() * c_.truePose.R;
    std::vector<double> tilted(3 * rest.vertexCount);
    std::vector<Eigen::Vector3d> restCam(rest.vertexCount), nowCam(rest.vertexCount);
    for (std::size_t i = 0; i < rest.vertexCount; ++i) {
      const Eigen::Vector3d p = centre + turn * (rest.vertex(i) - centre);
      for (int k = 0; k < 3; ++k) tilted[3 * i + static_cast<std::size_t>(k)] = p[k];
      restCam[i] = c_.truePose.apply(rest.vertex(i));
      nowCam[i] = c_.truePose.apply(p);
    }
    const std::vector<int> triangles(rest.triangles, rest.triangles + 3 * rest.triangleCount);
    const std::vector<float> keep = imaging::frameDetailWeights(c_.camera, restCam, nowCam, triangles);
    QCOMPARE(imaging::frameDetailWeights(c_.camera, restCam, restCam, triangles), std::vector<float>(keep.size(), 1.0f));
    const SurfaceView moved{tilted.data(), rest.vertexCount, rest.triangles, rest.triangleCount};
    const cv::Mat3b j = compositor.compose(tilted, 2);
    const cv::Mat3b truth = imaging::renderShaded(c_.camera, c_.truePose, moved, c_.trueAppearance, in.background, 2);
    // The pixels on triangles whose vertices keep less than half of the frame's detail, and on those that keep all of
    // it, away from the organ's rim.
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, moved);
    cv::Mat1b inner, stretched(g.triangle.size(), uchar(0)), kept(g.triangle.size(), uchar(0));
    cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
    for (int y = 0; y < inner.rows; ++y)
      for (int x = 0; x < inner.cols; ++x) {
        const int t = g.triangle(y, x);
        if (!inner(y, x) || t < 0) continue;
        const int* v = rest.triangles + 3 * t;
        const float w = (keep[static_cast<std::size_t>(v[0])] + keep[static_cast<std::size_t>(v[1])] + keep[static_cast<std::size_t>(v[2])]) / 3;
        stretched(y, x) = w < 0.5f ? 255 : 0;
        kept(y, x) = w >= 1.0f ? 255 : 0;
      }
    const int nStretched = cv::countNonZero(stretched), nKept = cv::countNonZero(kept);
    const double dbStretched = imaging::psnr(truth, j, stretched), dbKept = imaging::psnr(truth, j, kept);
    int fewer = 0;
    for (float w : keep) fewer += w < 1;
    qInfo("tilted 25 degrees: %d of %zu vertices keep less than all of the frame's detail; against the truth %.2f dB on "
          "the %d px of stretched tissue, %.2f dB on the %d px that keep it all",
          fewer, keep.size(), dbStretched, nStretched, dbKept, nKept);
    if (const char* dir = std::getenv("REHEARSE_SCREENSHOT_DIR")) {
      cv::Mat3b row;
      cv::hconcat(std::vector<cv::Mat>{truth, j}, row);
      cv::imwrite(std::string(dir) + "/stretched.png", row);
    }
    QVERIFY(nStretched > 5000);
    QVERIFY(nKept > 100000);
    // Measured 39.56 dB on the stretched tissue (29.39 dB with every weight 1, the frame's pixels stretched as before)
    // and 31.80 dB elsewhere either way.
    QVERIFY(dbStretched >= 35.0);
    QVERIFY(dbKept >= 30.0);
  }

  // A second source in a novel view (issue 65): the scope's light moves with the view, the distant light stays with the
  // scene. The phantom lit by both (secondSourceRecoveredWhereTheFrameShowsIt's light) is fitted through noise and JPEG
  // and seen through the scope turned 30 degrees about the organ; the true second view is rendered with the distant
  // light's direction turned into that camera (R_view R_frame^T d). The prediction from the fit lands within 30 dB of it
  // where both views see the organ, and at least 3 dB nearer it than to the same view with the direction left in the
  // camera's frame (as if the room's lamp turned with the scope).
  void novelViewKeepsASecondSourceWithTheScene() {
    const Eigen::Vector3d colour = c_.trueAppearance.kd / c_.trueAppearance.kd.maxCoeff();
    imaging::Appearance truth = c_.trueAppearance;
    truth.kd *= 0.5, truth.ks *= 0.5;
    truth.roomDirection = Eigen::Vector3d(-0.45, -0.55, -0.70).normalized();
    truth.kr = 0.25 * colour;
    truth.ka = 0.20 * colour;
    const cv::Mat3b bg = imaging::makeTissueBackground(c_.camera.width, c_.camera.height, 5);
    cv::Mat3b frame = imaging::renderShaded(c_.camera, c_.truePose, c_.surfaceView(), truth, bg, 2);
    frame = withNoiseAndJpeg(frame, 2.0, 90);
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const auto r = imaging::fitAppearance(frame, g);
    QVERIFY2(r.theta.hasDistantLight(), r.status.c_str());
    const Eigen::Vector3d centre = c_.truePose.apply(c_.centreOfGravity());
    const Pose view2 = c_.truePose.turnedAbout(Eigen::AngleAxisd(30 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix(), centre);
    imaging::Appearance inView = truth, turnedWithScope = truth;
    inView.roomDirection = view2.R * (c_.truePose.R.transpose() * truth.roomDirection);
    const cv::Mat3b black(frame.size(), cv::Vec3b(0, 0, 0));
    const cv::Mat3b trueView = imaging::renderShaded(c_.camera, view2, c_.surfaceView(), inView, black, 2),
                    wrongView = imaging::renderShaded(c_.camera, view2, c_.surfaceView(), turnedWithScope, black, 2);
    imaging::CompositionInput in;
    in.camera = c_.camera;
    in.pose = c_.truePose;
    in.rest = in.deformed = c_.surfaceView();
    in.frame = in.background = frame;
    in.albedo = imaging::albedoRatio(r.separation.diffuse, g, r.theta, r.usable);
    in.theta = r.theta;
    const auto predicted = imaging::composeNovelView(in, c_.camera, view2);
    cv::Mat1b both = predicted.covered & predicted.seen;
    cv::erode(both, both, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
    const double right = imaging::psnr(trueView, predicted.image, both), wrong = imaging::psnr(wrongView, predicted.image, both);
    qInfo("the second view (%d px seen by both): %.2f dB against the truth, %.2f dB against the lamp turned with the scope",
          cv::countNonZero(both), right, wrong);
    QVERIFY(cv::countNonZero(both) > 20000);
    QVERIFY(right >= 30.0);
    QVERIFY(right >= wrong + 3.0);
  }

  // A deformed organ in the novel view: moved by d in its own frame, it is drawn as the organ at rest seen from a
  // pose moved by R d (the texture stays where the tissue was at rest, the light with the scope).
  void novelViewOfAMovedOrgan() {
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const auto r = imaging::fitAppearance(c_.frame, g);
    imaging::CompositionInput in;
    in.camera = c_.camera;
    in.pose = c_.truePose;
    in.rest = in.deformed = c_.surfaceView();
    in.frame = in.background = c_.frame;
    in.albedo = imaging::albedoRatio(r.separation.diffuse, g, r.theta, r.usable);
    in.theta = r.theta;
    const Eigen::Vector3d centre = c_.truePose.apply(c_.centreOfGravity());
    const Pose view = c_.truePose.turnedAbout(
        Eigen::AngleAxisd(-10 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix(), centre);
    const Eigen::Vector3d d(0.004, -0.003, 0.002);
    std::vector<double> moved(c_.surfaceView().vertices, c_.surfaceView().vertices + 3 * c_.surfaceView().vertexCount);
    for (std::size_t i = 0; i < moved.size(); ++i) moved[i] += d[static_cast<Eigen::Index>(i % 3)];
    Pose shifted = view;
    shifted.t += view.R * d;
    const auto a = imaging::composeNovelView(in, c_.camera, view, {}, moved),
               b = imaging::composeNovelView(in, c_.camera, shifted);
    const double db = imaging::psnr(a.image, b.image);
    qInfo("moved organ against a moved view: %.1f dB over the whole view; %d and %d px drawn", db,
          cv::countNonZero(a.covered), cv::countNonZero(b.covered));
    QVERIFY(cv::countNonZero(a.covered) > 100000);
    QVERIFY(db >= 45);
    QVERIFY_THROWS_EXCEPTION(rehearse::InputError,
                             imaging::composeNovelView(in, c_.camera, view, {}, std::vector<double>(9, 0.0)));
  }

  // Issue 65: the model changes the frame's colours only as far as the fit earned it (imaging::reshadeTrust): not at all
  // at or below the texture-only line (50 % explained), in full from 90 %, in proportion between. Checked against the
  // two ends drawn on their own paths: where the frame saw the tissue, trust 0 draws what texture only draws and half
  // trust the mean of texture only and the full re-shade, in the novel view and in the compositor on a moved organ; at
  // rest every trust gives the frame; the moved highlights come nearer the truth as the trust rises.
  void reshadingFollowsWhatTheFitEarned() {
    QCOMPARE(imaging::reshadeTrust(0.3), 0.0);
    QCOMPARE(imaging::reshadeTrust(0.5), 0.0);
    QVERIFY(std::abs(imaging::reshadeTrust(0.7) - 0.5) < 1e-12);
    QCOMPARE(imaging::reshadeTrust(0.9), 1.0);
    QCOMPARE(imaging::reshadeTrust(0.999), 1.0);
    QCOMPARE(imaging::reshadeTrust(std::nan("")), 0.0);
    QVERIFY(imaging::Reshading::of(0.95, true).textureOnly && imaging::Reshading::of(0.95, true).trust == 0);
    // As sentences say them: 0 and 100 only at the ends, the share floored beside them.
    QCOMPARE(imaging::trustPercent(imaging::reshadeTrust(0.8995)), 99);
    QCOMPARE(imaging::explainedPercent(0.8995), 89);
    QCOMPARE(imaging::trustPercent(imaging::reshadeTrust(0.501)), 1);
    QCOMPARE(imaging::trustPercent(0.0), 0);
    QCOMPARE(imaging::trustPercent(1.0), 100);
    QCOMPARE(imaging::trustPercent(0.5), 50);
    QCOMPARE(imaging::explainedPercent(0.29), 29);
    QCOMPARE(imaging::explainedPercent(0.7), 70);
    imaging::AppearanceVerdict verdict;
    QCOMPARE(verdict.reshading().trust, 1.0);  // no fit's verdict: a light given by hand, taken as known
    verdict.known = true;
    verdict.explained = 0.8;
    QVERIFY(!verdict.reshading().textureOnly && std::abs(verdict.reshading().trust - 0.75) < 1e-12);
    verdict.reshade = false;
    QVERIFY(verdict.reshading().textureOnly);

    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const cv::Mat3b frame = withNoiseAndJpeg(c_.frame, 2.0, 90);
    imaging::AppearanceFitResult r;
    const imaging::CompositionInput in = fittedInput(frame, r);
    // The share of pixels of `where` on which `a` is within `levels` of `b` in every channel.
    auto within = [](const cv::Mat3b& a, const cv::Mat3b& b, const cv::Mat1b& where, int levels) {
      cv::Mat3b d;
      cv::absdiff(a, b, d);
      cv::Mat1b anyOff = cv::Mat1b::zeros(d.size());
      for (int y = 0; y < d.rows; ++y)
        for (int x = 0; x < d.cols; ++x) {
          const cv::Vec3b v = d(y, x);
          anyOff(y, x) = std::max({v[0], v[1], v[2]}) > levels ? 255 : 0;
        }
      return 1.0 - static_cast<double>(cv::countNonZero(anyOff & where)) / std::max(1, cv::countNonZero(where));
    };
    auto mean = [](const cv::Mat3b& a, const cv::Mat3b& b) {
      cv::Mat3b m;
      cv::addWeighted(a, 0.5, b, 0.5, 0.0, m);
      return m;
    };

    // The novel view, turned 14 degrees.
    const Eigen::Vector3d centre = c_.truePose.apply(c_.centreOfGravity());
    const Pose view2 = c_.truePose.turnedAbout(
        Eigen::AngleAxisd(14 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix(), centre);
    auto novel = [&](double trust, bool textureOnly) {
      imaging::CompositionInput k = in;
      k.trust = trust;
      k.textureOnly = textureOnly;
      return imaging::composeNovelView(k, c_.camera, view2);
    };
    const auto full = novel(1, false), half = novel(0.5, false), none = novel(0, false), texture = novel(0, true);
    cv::Mat1b both = full.covered & full.seen;
    cv::erode(both, both, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
    const double noneIsTexture = within(none.image, texture.image, both, 1),
                 halfIsMean = within(half.image, mean(full.image, texture.image), both, 1);
    const cv::Mat3b truth = imaging::renderShaded(c_.camera, view2, c_.surfaceView(), c_.trueAppearance,
                                                  cv::Mat3b(frame.size(), cv::Vec3b(0, 0, 0)), 2);
    imaging::Appearance specularOnly = c_.trueAppearance;
    specularOnly.kd.setZero();
    cv::Mat1b highlights;
    cv::cvtColor(imaging::renderShaded(c_.camera, view2, c_.surfaceView(), specularOnly,
                                       cv::Mat3b(frame.size(), cv::Vec3b(0, 0, 0)), 1),
                 highlights, cv::COLOR_BGR2GRAY);
    highlights = (highlights > 20) & both;
    const double hiTexture = imaging::psnr(truth, texture.image, highlights),
                 hiHalf = imaging::psnr(truth, half.image, highlights), hiFull = imaging::psnr(truth, full.image, highlights);
    qInfo("novel view, %d px seen by both: trust 0 draws texture only's colours on %.3f %% (within 1 level), half trust "
          "their mean with the full re-shade's on %.3f %%; at the %d moved highlight px texture %.2f dB, half %.2f, full %.2f",
          cv::countNonZero(both), 100 * noneIsTexture, 100 * halfIsMean, cv::countNonZero(highlights), hiTexture, hiHalf,
          hiFull);
    QVERIFY(cv::countNonZero(both) > 20000 && cv::countNonZero(highlights) > 300);
    QVERIFY(noneIsTexture >= 0.999);
    QVERIFY(halfIsMean >= 0.99);
    QVERIFY(hiHalf > hiTexture + 1.0 && hiFull > hiHalf + 1.0);

    // The compositor: the organ moved 3 mm across the view and turned 6 degrees (nearly all of it still seen).
    std::vector<double> moved(c_.surfaceView().vertices, c_.surfaceView().vertices + 3 * c_.surfaceView().vertexCount);
    const Eigen::Vector3d cog = c_.centreOfGravity();
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(6 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
    for (std::size_t i = 0; i < moved.size(); i += 3) {
      const Eigen::Vector3d p(moved[i], moved[i + 1], moved[i + 2]);
      const Eigen::Vector3d q = cog + turn * (p - cog) + Eigen::Vector3d(0.003, 0, 0);
      for (int k = 0; k < 3; ++k) moved[i + static_cast<std::size_t>(k)] = q[k];
    }
    auto composed = [&](double trust, bool textureOnly, bool atRest) {
      imaging::CompositionInput k = in;
      k.trust = trust;
      k.textureOnly = textureOnly;
      return imaging::Compositor(k).compose(atRest ? std::vector<double>{} : moved, 1);
    };
    const cv::Mat3b cFull = composed(1, false, false), cHalf = composed(0.5, false, false),
                    cNone = composed(0, false, false), cTexture = composed(0, true, false);
    // Where the moved organ is drawn, away from its rim (nearly all of it tissue the frame saw).
    SurfaceView movedView = c_.surfaceView();
    movedView.vertices = moved.data();
    cv::Mat1b drawn = imaging::renderMask(c_.camera, c_.truePose, movedView);
    cv::erode(drawn, drawn, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
    const double cNoneIsTexture = within(cNone, cTexture, drawn, 1),
                 cHalfIsMean = within(cHalf, mean(cFull, cTexture), drawn, 1);
    cv::Mat3b moveDiff;
    cv::absdiff(cFull, cTexture, moveDiff);
    cv::Mat1b changed;
    cv::inRange(moveDiff, cv::Scalar(4, 4, 4), cv::Scalar(255, 255, 255), changed);
    qInfo("compositor, organ moved (%d inner px, %d where the full re-shade differs from texture only by 4+ levels): trust 0 "
          "is texture only's on %.3f %%, half trust their mean on %.3f %%",
          cv::countNonZero(drawn), cv::countNonZero(changed & drawn), 100 * cNoneIsTexture, 100 * cHalfIsMean);
    QVERIFY(cv::countNonZero(changed & drawn) > 2000);  // the move changed the shading: the mix is not trivial
    QVERIFY(cNoneIsTexture >= 0.99);
    QVERIFY(cHalfIsMean >= 0.99);
    // At rest every trust draws the frame.
    cv::Mat1b inner;
    cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
    for (double trust : {0.0, 0.5}) {
      const double same = within(composed(trust, false, true), frame, inner, 3);
      qInfo("at rest, trust %.1f: %.3f %% of the inner pixels the frame's within 3 levels", trust, 100 * same);
      QVERIFY(same >= 0.995);
    }
    // A trust outside [0, 1] is refused with a sentence, not clamped.
    for (double bad : {1.5, -0.1, std::nan("")}) {
      imaging::CompositionInput k = in;
      k.trust = bad;
      QVERIFY_THROWS_EXCEPTION(rehearse::InputError, imaging::Compositor{k});
      QVERIFY_THROWS_EXCEPTION(rehearse::InputError, imaging::composeNovelView(k, c_.camera, view2));
    }
  }

  // Tissue the frame never showed (a cut's faces, issue 35) takes its material's albedo ratio, re-shaded by Theta,
  // also when the organ's surface is only texture-mapped: with no specular term, its colour is the ratio times the
  // colour of the same surface with albedo 1, channel by channel (to the 8-bit rounding). A material list that does
  // not fit the triangles is refused.
  void cutFacesTakeTheirMaterial() {
    imaging::CompositionInput in;
    in.camera = c_.camera;
    in.pose = c_.truePose;
    in.rest = in.deformed = c_.surfaceView();
    in.frame = in.background = c_.frame;
    in.albedo = cv::Mat3f(c_.frame.size(), cv::Vec3f(1, 1, 1));
    in.theta = c_.trueAppearance;
    in.theta.ks = Eigen::Vector3d::Zero();
    in.frameDetail = false;  // the model's shading (a cut face carries nothing of the frame)
    const imaging::Compositor plain(in);
    const cv::Mat3b reference = plain.compose(std::vector<double>{}, 1);
    const cv::Vec3f ratio(0.5f, 0.25f, 0.8f);  // BGR
    for (const bool texture : {false, true}) {
      in.textureOnly = texture;
      const imaging::Compositor textured(in);
      const auto cut =
          textured.reshaped(c_.surfaceView(), std::vector<int>(c_.surfaceView().triangleCount, 1), {ratio});
      const cv::Mat3b j = cut->compose(std::vector<double>{}, 1);
      const cv::Mat1b organ = imaging::renderMask(c_.camera, c_.truePose, c_.surfaceView());
      int checked = 0;
      double worst = 0;
      for (int y = 0; y < j.rows; ++y)
        for (int x = 0; x < j.cols; ++x) {
          if (!organ(y, x)) continue;
          for (int k = 0; k < 3; ++k) {
            const double ref = reference(y, x)[k];
            if (ref < 20 || ref > 250) continue;  // too dark to tell, or clipped
            worst = std::max(worst, std::abs(j(y, x)[k] - ratio[k] * ref));
            ++checked;
          }
        }
      qInfo(
          "%s: %d channel values of the organ, the material's colour within %.2f levels of its ratio times albedo 1's",
          texture ? "texture-only" : "re-shaded", checked, worst);
      QVERIFY(checked > 100000);
      QVERIFY(worst <= 1.0);
    }
    QVERIFY_THROWS_EXCEPTION(rehearse::InputError, plain.reshaped(c_.surfaceView(), {1, 1}, {ratio}));
    QVERIFY_THROWS_EXCEPTION(
        rehearse::InputError,
        plain.reshaped(c_.surfaceView(), std::vector<int>(c_.surfaceView().triangleCount, 2), {ratio}));
  }

  // The frame never showed a surface that faced away from it at rest: the organ turned half a turn about the camera's
  // vertical axis through its centre brings its back to the front, and with the frame's texture only, no pixel on a
  // triangle that faced away at rest may take the frame's colours: it takes the organ's mean colour in the frame, and no
  // pixel of the organ shows the background (black here) through it (before, the unseen showed it). Before, the
  // back's points by the rest's silhouette passed as seen (within 2 mm in depth of the front there, or on a triangle
  // sharing a vertex with the front one shown there): the lit front's colours were carried onto the back (a bright
  // tick at each shared vertex where a pull turned an underside into view).
  void backAtRestIsNeverTheFramesTexture() {
    const SurfaceView rest = c_.surfaceView();
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& p : c_.volume.points) centre += p;
    centre /= static_cast<double>(c_.volume.points.size());
    const Eigen::AngleAxisd turn(M_PI, c_.truePose.R.transpose() * Eigen::Vector3d::UnitY());
    std::vector<double> moved(3 * c_.volume.points.size());
    for (std::size_t i = 0; i < c_.volume.points.size(); ++i) {
      const Eigen::Vector3d q = centre + turn * (c_.volume.points[i] - centre);
      for (int k = 0; k < 3; ++k) moved[3 * i + k] = q[k];
    }
    SurfaceView deformed = rest;
    deformed.vertices = moved.data();
    imaging::CompositionInput in = phantomInput(deformed);
    in.frame = c_.frame;
    in.background = cv::Mat3b(c_.frame.size(), cv::Vec3b(0, 0, 0));
    in.theta = c_.trueAppearance;
    in.textureOnly = true;
    const cv::Mat3b j = imaging::Compositor(in).compose(moved, 1);
    // Which triangles faced away from the camera at rest (camera frame: a . ((b - a) x (c - a)) > 0 for a closed
    // surface wound outward, as the phantom's is), and which one each pixel of the turned organ shows.
    std::vector<char> backAtRest(rest.triangleCount);
    for (std::size_t t = 0; t < rest.triangleCount; ++t) {
      const int* tri = rest.triangles + 3 * t;
      const Eigen::Vector3d a = c_.truePose.apply(rest.vertex(static_cast<std::size_t>(tri[0]))),
                            b = c_.truePose.apply(rest.vertex(static_cast<std::size_t>(tri[1]))),
                            c = c_.truePose.apply(rest.vertex(static_cast<std::size_t>(tri[2])));
      backAtRest[t] = a.dot((b - a).cross(c - a)) > 0;
    }
    const auto turned = imaging::surfaceGeometry(c_.camera, c_.truePose, deformed);
    // The organ's mean colour in the frame, from the phantom's own rasterisation at rest (not the compositor's): what
    // tissue the frame never showed is drawn in (within 1 of each 8-bit channel).
    const auto atRest = imaging::surfaceGeometry(c_.camera, c_.truePose, rest);
    const cv::Scalar mean = cv::mean(c_.frame, atRest.triangle >= 0);
    const cv::Vec3b fill(cv::saturate_cast<uchar>(mean[0]), cv::saturate_cast<uchar>(mean[1]),
                         cv::saturate_cast<uchar>(mean[2]));
    auto isFill = [&](const cv::Vec3b& v) {
      for (int k = 0; k < 3; ++k)
        if (std::abs(int(v[k]) - int(fill[k])) > 1) return false;
      return true;
    };
    int onBack = 0, wrong = 0, background = 0, inner = 0;
    for (int y = 1; y + 1 < j.rows; ++y)
      for (int x = 1; x + 1 < j.cols; ++x) {
        const int t = turned.triangle(y, x);
        // Inner pixels only: a rim pixel's triangle in the reference rasterisation may be its neighbour's.
        if (t < 0 || turned.triangle(y - 1, x) != t || turned.triangle(y + 1, x) != t || turned.triangle(y, x - 1) != t ||
            turned.triangle(y, x + 1) != t)
          continue;
        ++inner;
        background += j(y, x) == cv::Vec3b(0, 0, 0);
        if (!backAtRest[static_cast<std::size_t>(t)]) continue;
        ++onBack;
        wrong += !isFill(j(y, x));
      }
    qInfo("the organ turned half a turn: %d inner px, %d on triangles that faced away at rest, %d of those not in the "
          "organ's mean colour (%d %d %d); %d showing the background",
          inner, onBack, wrong, fill[0], fill[1], fill[2], background);
    QVERIFY(onBack > 100000);
    QCOMPARE(wrong, 0);
    QCOMPARE(background, 0);
  }

  // The appearance file carries the scope's fall-off; a file without it is an isotropic light (n = 0); an
  // impossible n is refused in one sentence.
  void appearanceFileCarriesTheFalloff() {
    const std::string dir = tempPath("appearance-file");
    std::filesystem::create_directories(dir);
    imaging::Appearance a = c_.trueAppearance;
    a.falloff = 6.5;
    imaging::saveAppearance(a, dir + "/theta.json");
    QCOMPARE(imaging::loadAppearance(dir + "/theta.json").falloff, 6.5);
    auto write = [&](const std::string& name, const std::string& text) {
      std::ofstream(dir + "/" + name) << text;
      return dir + "/" + name;
    };
    QCOMPARE(imaging::loadAppearance(
                 write("old.json",
                       R"({"light_position": [0, 0, 0], "kd": [0.1, 0.1, 0.1], "ks": [0, 0, 0], "roughness": 0.1})"))
                 .falloff,
             0.0);
    try {
      imaging::loadAppearance(write(
          "bad.json",
          R"({"light_position": [0, 0, 0], "kd": [0.1, 0.1, 0.1], "ks": [0, 0, 0], "roughness": 0.1, "falloff": -2})"));
      QFAIL("a negative fall-off was accepted");
    } catch (const rehearse::InputError& e) {
      QVERIFY(std::string(e.what()).find("falloff") != std::string::npos);
    }
    // A second source travels with THETA, and a file without one has none.
    a.roomDirection = Eigen::Vector3d(0.6, 0, -0.8);
    a.kr = Eigen::Vector3d(0.2, 0.1, 0.05);
    a.ka = Eigen::Vector3d(0.03, 0.02, 0.01);
    imaging::saveAppearance(a, dir + "/theta2.json");
    const imaging::Appearance back = imaging::loadAppearance(dir + "/theta2.json");
    QVERIFY(back.roomDirection.isApprox(a.roomDirection) && back.kr.isApprox(a.kr) && back.ka.isApprox(a.ka));
    const imaging::Appearance none = imaging::loadAppearance(dir + "/old.json");
    QVERIFY(!none.hasDistantLight() && !none.hasAmbient());
    for (const char* bad :
         {R"({"light_position": [0, 0, 0], "kd": [0.1, 0.1, 0.1], "ks": [0, 0, 0], "roughness": 0.1, "distant_light": {"direction": [1, 1, 0], "kr": [0.1, 0.1, 0.1]}})",
          R"({"light_position": [0, 0, 0], "kd": [0.1, 0.1, 0.1], "ks": [0, 0, 0], "roughness": 0.1, "distant_light": {"direction": [1, 0, 0]}})",
          R"({"light_position": [0, 0, 0], "kd": [0.1, 0.1, 0.1], "ks": [0, 0, 0], "roughness": 0.1, "ambient": [-0.1, 0, 0]})"}) {
      try {
        imaging::loadAppearance(write("bad2.json", bad));
        QFAIL(bad);
      } catch (const rehearse::InputError& e) {
        qInfo("%s", e.what());
        QVERIFY(std::string(e.what()).find("distant") != std::string::npos ||
                std::string(e.what()).find("k_a") != std::string::npos);
      }
    }
  }

  // Without a highlight the light starts at the lens, the specular part is not determined, and the
  // status says both.
  void noHighlightIsSaid() {
    imaging::Appearance matte = c_.trueAppearance;
    matte.ks.setZero();
    const cv::Mat3b bg = imaging::makeTissueBackground(c_.camera.width, c_.camera.height, 3);
    const cv::Mat3b frame = imaging::renderShaded(c_.camera, c_.truePose, c_.surfaceView(), matte, bg, 2);
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const auto r = imaging::fitAppearance(frame, g);
    qInfo("%s; kd (%.5f %.5f %.5f); %d highlight px in %d blobs", r.status.c_str(), r.theta.kd.x(), r.theta.kd.y(), r.theta.kd.z(), r.separation.count,
          r.separation.blobs);
    QVERIFY(!r.highlightFound);
    QVERIFY(r.status.find("no specular highlight") != std::string::npos);
    QCOMPARE(r.theta.ks.norm(), 0.0);
  }

  // Composed at rest with what was fitted, the organ reproduces the frame inside its mask (PSNR >= 30 dB).
  void restPoseReproducesTheFrame() {
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const cv::Mat3b frame = withNoiseAndJpeg(c_.frame, 2.0, 0);
    imaging::AppearanceFitResult r;
    imaging::CompositionInput in = fittedInput(frame, r);
    const cv::Mat3b j = imaging::compose(in);
    cv::Mat1b inner;
    cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));  // the anti-aliased rim mixes with I_B
    const double db = imaging::psnr(frame, j, inner);
    // Re-shaded with the frame's detail (issue 65), at rest the composite is the frame: measured 99.93 % of the inner
    // pixels within 3 levels, the rest where the organ folds over itself inside its outline (a depth step whose rim
    // samples mix the two surfaces; up to 96 levels); 51.1 dB against the model alone's 44.9 dB.
    cv::Mat3b diff;
    cv::absdiff(frame, j, diff);
    int same = 0, inside = 0;
    double worst = 0;
    for (int y = 0; y < diff.rows; ++y)
      for (int x = 0; x < diff.cols; ++x)
        if (inner(y, x)) {
          const cv::Vec3b d = diff(y, x);
          const int m = std::max({d[0], d[1], d[2]});
          ++inside;
          same += m <= 3;
          worst = std::max(worst, static_cast<double>(m));
        }
    in.frameDetail = false;
    const double modelDb = imaging::psnr(frame, imaging::compose(in), inner);
    qInfo("rest pose, re-shaded with the frame's detail: %d of %d inner pixels the frame's within 3 levels (worst %.0f "
          "levels), %.1f dB; the model alone %.1f dB",
          same, inside, worst, db, modelDb);
    QVERIFY(same >= 0.995 * inside);
    QVERIFY(modelDb >= 30.0 && db >= modelDb + 3.0);
    if (std::getenv("T_DUMP")) {
      cv::Mat3b diff;
      cv::absdiff(frame, j, diff);
      cv::Mat3b vis = diff * 4;
      cv::imwrite("/tmp/restdiff.png", vis);
      cv::imwrite("/tmp/restj.png", j);
    }
    qInfo("rest pose: PSNR %.1f dB inside the organ (%d px)", db, cv::countNonZero(inner));
    QVERIFY(db >= 30.0);
  }

  // The compositor's shading (a lobe table, planes made once per shape, rim-only supersampling) against
  // the reference renderer (Appearance::shade per pixel, whole-image supersampling) on a moved organ with
  // albedo 1: the same picture inside the organ (1x: within 1 level, every pixel), and on its rim the 4x4
  // rim samples come within 35 dB of a whole 4x supersampled render.
  void compositorAgreesWithTheReferenceRenderer() { compositorAgrees(c_.trueAppearance); }

  // The same with a second source (a distant light and an ambient term): the compositor's shading of it against
  // Appearance::shade's.
  void compositorAgreesWithASecondSource() {
    imaging::Appearance theta = c_.trueAppearance;
    theta.kd *= 0.6, theta.ks *= 0.6;
    theta.roomDirection = Eigen::Vector3d(0.3, -0.5, -0.8).normalized();
    theta.kr = Eigen::Vector3d(0.25, 0.12, 0.1);
    theta.ka = Eigen::Vector3d(0.06, 0.03, 0.02);
    compositorAgrees(theta);
  }

private:
  void compositorAgrees(const imaging::Appearance& theta) {
    std::vector<double> moved(3 * c_.volume.points.size());
    for (std::size_t i = 0; i < c_.volume.points.size(); ++i) {
      const Eigen::Vector3d q = c_.volume.points[i] + Eigen::Vector3d(0.004, 0.002 + 0.1 * c_.volume.points[i].x() * c_.volume.points[i].x(), 0.003);
      for (int k = 0; k < 3; ++k) moved[3 * i + k] = q[k];
    }
    SurfaceView deformed = c_.surfaceView();
    deformed.vertices = moved.data();
    const cv::Mat3b bg = imaging::makeTissueBackground(c_.camera.width, c_.camera.height, 11);
    imaging::CompositionInput in = phantomInput(deformed);
    in.frame = c_.frame;
    in.background = bg;
    in.albedo = cv::Mat3f(bg.size(), cv::Vec3f(1, 1, 1));
    in.theta = theta;
    in.frameDetail = false;  // the model alone, as the reference renders it
    const imaging::Compositor compositor(in);
    const cv::Mat3b one = compositor.compose(moved, 1);
    const cv::Mat3b reference1 = imaging::renderShaded(c_.camera, c_.truePose, deformed, theta, bg, 1);
    cv::Mat3b diff;
    cv::absdiff(one, reference1, diff);
    double worst = 0;
    cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
    qInfo("1x: worst difference %.0f levels over the whole frame", worst);
    QVERIFY(worst <= 1.0);
    const cv::Mat1b mask = imaging::renderMask(c_.camera, c_.truePose, deformed);
    cv::Mat1b rim;
    cv::morphologyEx(mask, rim, cv::MORPH_GRADIENT, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)));
    const cv::Mat3b four = compositor.compose(moved, 4);
    const cv::Mat3b reference4 = imaging::renderShaded(c_.camera, c_.truePose, deformed, theta, bg, 4);
    const double rimDb = imaging::psnr(reference4, four, rim), plainDb = imaging::psnr(reference4, one, rim);
    qInfo("rim (%d px): %.1f dB with 4x4 rim samples, %.1f dB without", cv::countNonZero(rim), rimDb, plainDb);
    QVERIFY(rimDb >= 35.0);
    QVERIFY(rimDb > plainDb + 6);
    // The rasterisation's buffers are kept from one shape to the next (and a compose on another thread allocates its
    // own): a shape drawn after others, or beside another on a second thread, is drawn as when it was the first.
    const cv::Mat3b rest = compositor.compose(std::vector<double>{}, 1);
    QVERIFY(cv::norm(rest, one, cv::NORM_INF) > 0);  // two different pictures
    QCOMPARE(cv::norm(compositor.compose(moved, 1), one, cv::NORM_INF), 0.0);
    for (int round = 0; round < 3; ++round) {
      cv::Mat3b a, b;
      std::thread other([&] { a = compositor.compose(std::vector<double>{}, 1); });
      b = compositor.compose(moved, 1);
      other.join();
      QCOMPARE(cv::norm(a, rest, cv::NORM_INF), 0.0);
      QCOMPARE(cv::norm(b, one, cv::NORM_INF), 0.0);
    }
    // A shape of another mesh is refused in one sentence.
    QVERIFY_THROWS_EXCEPTION(rehearse::InputError, compositor.compose(std::vector<double>(9, 0.0), 1));
  }

 private slots:

  // The texture follows the tissue: dots painted on the organ in the frame land, after the organ moves,
  // where the moved surface points under them project (within 1 px); the shading follows the new normals.
  // Dots painted on the organ in the frame, the organ's nodes moved to `movedNodes` (model frame): returns
  // the worst distance (px) from a dot in the composition to where its tissue went, and how far the dots moved.
  void checkTextureFollows(const std::vector<Eigen::Vector3d>& movedNodes, const char* what, double minMovePx) {
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const auto r = imaging::fitAppearance(c_.frame, g);
    cv::Mat3b frame = c_.frame.clone();
    std::vector<cv::Point> dots;
    std::vector<int> dotTriangle;  // the surface point under each dot: its triangle and barycentric coordinates
    std::vector<cv::Vec3f> dotWeights;
    for (int y = 200; y < 560; y += 60)
      for (int x = 400; x < 900; x += 60) {
        cv::Mat1b inner;
        if (g.triangle(y, x) < 0) continue;
        bool whole = true;  // the dot and its ring where the frame's texture is known (usable pixels of the organ)
        for (int dy = -8; dy <= 8; ++dy)
          for (int dx = -8; dx <= 8; ++dx) whole &= r.usable(y + dy, x + dx) != 0;
        if (!whole) continue;
        cv::circle(frame, {x, y}, 3, cv::Scalar(0, 0, 0), cv::FILLED, cv::LINE_AA);
        dots.push_back({x, y});
        dotTriangle.push_back(g.triangle(y, x));
        dotWeights.push_back(g.barycentric(y, x));
      }
    QVERIFY(dots.size() >= 12);
    std::vector<double> moved(c_.volume.points.size() * 3);
    for (std::size_t i = 0; i < c_.volume.points.size(); ++i)
      for (int k = 0; k < 3; ++k) moved[3 * i + k] = movedNodes[i][k];
    const SurfaceView rest = c_.surfaceView();
    SurfaceView deformed = rest;
    deformed.vertices = moved.data();
    imaging::CompositionInput in = phantomInput(deformed);
    in.frame = frame;
    in.background = imaging::inpaintRegion(frame, g.mask());
    in.albedo = imaging::albedoRatio(frame, g, r.theta, r.usable);
    in.theta = r.theta;
    const cv::Mat3b j = imaging::compose(in, 1);
    in.frame = c_.frame;  // the same without the dots: their difference holds only the dots
    in.albedo = imaging::albedoRatio(c_.frame, g, r.theta, r.usable);
    const cv::Mat3b plain = imaging::compose(in, 1);
    const auto moved3 = imaging::surfaceGeometry(c_.camera, c_.truePose, deformed);
    if (std::getenv("T_DUMP")) {
      cv::imwrite("/tmp/j.png", j);
      cv::imwrite("/tmp/plain.png", plain);
      cv::imwrite("/tmp/dotted.png", frame);
      cv::Mat3b a8;
      in.albedo.convertTo(a8, CV_8UC3, 100);
      cv::imwrite("/tmp/albedo.png", a8);
    }
    double worst = 0, moveMax = 0;
    int found = 0;
    for (std::size_t i = 0; i < dots.size(); ++i) {
      // Where the surface point under the dot went: the mesh deforms piecewise linearly, so the point keeps
      // its barycentric coordinates in its moved triangle.
      const int* tri = c_.surface[static_cast<std::size_t>(dotTriangle[i])].data();
      Eigen::Vector3d movedPoint = Eigen::Vector3d::Zero();
      Eigen::Vector3d restPoint = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k) movedPoint += dotWeights[i][k] * movedNodes[static_cast<std::size_t>(tri[k])];
      for (int k = 0; k < 3; ++k) restPoint += dotWeights[i][k] * c_.volume.points[static_cast<std::size_t>(tri[k])];
      moveMax = std::max(moveMax, (c_.camera.project(c_.truePose.apply(movedPoint)) - c_.camera.project(c_.truePose.apply(restPoint))).norm());
      const Eigen::Vector3d q = c_.truePose.apply(movedPoint);
      const Eigen::Vector2d expect(c_.camera.K(0, 0) * q.x() / q.z() + c_.camera.K(0, 2), c_.camera.K(1, 1) * q.y() / q.z() + c_.camera.K(1, 2));
      const int cx = static_cast<int>(std::lround(expect.x())), cy = static_cast<int>(std::lround(expect.y()));
      if (cx < 12 || cy < 12 || cx >= j.cols - 12 || cy >= j.rows - 12) continue;
      bool onOrgan = true;  // the whole window on the moved organ (the outline would pull the centroid)
      for (int dy = -10; dy <= 10; ++dy)
        for (int dx = -10; dx <= 10; ++dx) onOrgan &= moved3.triangle(cy + dy, cx + dx) >= 0;
      if (!onOrgan) continue;
      double sw = 0, sx = 0, sy = 0;
      for (int dy = -10; dy <= 10; ++dy)
        for (int dx = -10; dx <= 10; ++dx) {
          // Green and blue: the organ's red clips at 255 where it is brightly lit, which would hide part of a dot.
          const double w = std::max(0.0, static_cast<double>(plain(cy + dy, cx + dx)[0]) + plain(cy + dy, cx + dx)[1] - j(cy + dy, cx + dx)[0] -
                                             j(cy + dy, cx + dx)[1]);
          sw += w, sx += w * (cx + dx), sy += w * (cy + dy);
        }
      if (sw <= 0) continue;
      const double err = (Eigen::Vector2d(sx / sw, sy / sw) - expect).norm();
      worst = std::max(worst, err);
      if (err > 1.0) qInfo("  dot at (%d, %d): expected (%.1f, %.1f), found (%.1f, %.1f)", dots[i].x, dots[i].y, expect.x(), expect.y(), sx / sw, sy / sw);
      ++found;
    }
    qInfo("texture: %d of %zu dots found after %s (dots moved up to %.1f px), worst %.2f px from where their tissue went", found, dots.size(), what, moveMax,
          worst);
    QVERIFY(found >= static_cast<int>(dots.size()) * 3 / 4);
    QVERIFY(moveMax >= minMovePx);  // the deformation moved the texture visibly
    QVERIFY(worst <= 1.0);
  }

  // A known analytic deformation: the organ's nodes bent sideways, more the further along its x they lie.
  void textureFollowsTheTissue() {
    std::vector<Eigen::Vector3d> bent;
    for (const auto& p : c_.volume.points) bent.emplace_back(p.x(), p.y() + 0.15 * p.x() * p.x() / 0.05, p.z() + 0.002);
    checkTextureFollows(bent, "the bend", 5.0);
  }

  // An independent deformation: CalculiX (ccx) sags the phantom under gravity from its ligament nodes
  // (soft tissue, 3 kPa, nu 0.45, large deformation).
  void textureFollowsACalculixSag() {
    const Eigen::Vector3d gravity = c_.truePose.R.transpose() * Eigen::Vector3d(0, 9.81, 0);  // down in the image
    const Eigen::VectorXd u = runCalculixStatic(c_.volume, {}, CcxMaterial{3000, 0.45, 1000, false}, gravity, true, c_.attachments, "appearance-sag");
    QVERIFY2(u.size() == static_cast<Eigen::Index>(3 * c_.volume.points.size()), "CalculiX (ccx) did not run; scripts/install-deps.sh installs calculix-ccx");
    std::vector<Eigen::Vector3d> sagged;
    double most = 0;
    for (std::size_t i = 0; i < c_.volume.points.size(); ++i) {
      const Eigen::Vector3d d = u.segment<3>(static_cast<Eigen::Index>(3 * i));
      sagged.push_back(c_.volume.points[i] + d);
      most = std::max(most, d.norm());
    }
    qInfo("CalculiX sag: nodes moved up to %.1f mm", 1e3 * most);
    checkTextureFollows(sagged, "the CalculiX sag", 3.0);
  }

  // A mesh whose triangles are wound the other way (normals pointing in): the same Theta, since the normal
  // seen is the one facing the camera.
  void flippedNormalsGiveTheSameTheta() {
    std::vector<std::array<int, 3>> flipped = c_.surface;
    for (auto& t : flipped) std::swap(t[1], t[2]);
    SurfaceView v = c_.surfaceView();
    v.triangles = flipped.front().data();
    const auto g0 = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    const auto g1 = imaging::surfaceGeometry(c_.camera, c_.truePose, v);
    const auto a = imaging::fitAppearance(c_.frame, g0), b = imaging::fitAppearance(c_.frame, g1);
    qInfo("light %.3f mm apart, kd %.2e apart", 1e3 * (a.theta.lightPosition - b.theta.lightPosition).norm(), (a.theta.kd - b.theta.kd).norm());
    QVERIFY((a.theta.lightPosition - b.theta.lightPosition).norm() < 1e-4);
    QVERIFY((a.theta.kd - b.theta.kd).norm() < 1e-3 * a.theta.kd.norm());
  }

  // An organ so far away that it covers a few pixels: one sentence, no fit.
  void tinyOrganSaysSo() {
    Pose far = c_.truePose;
    far.t.z() += 20.0;
    const auto g = imaging::surfaceGeometry(c_.camera, far, c_.surfaceView());
    QVERIFY(cv::countNonZero(g.mask()) < 200);
    try {
      imaging::fitAppearance(c_.frame, g);
      QFAIL("a few pixels were fitted");
    } catch (const rehearse::InputError& e) {
      QVERIFY(std::string(e.what()).find("fewer than 200 usable pixels") != std::string::npos);
    }
  }

  void badInputSaysSo() {
    // Behind the camera.
    Pose behind = c_.truePose;
    behind.t.z() = -0.5;
    try {
      imaging::surfaceGeometry(c_.camera, behind, c_.surfaceView());
      QFAIL("an organ behind the camera was accepted");
    } catch (const rehearse::InputError& e) {
      QVERIFY(std::string(e.what()).find("behind the camera") != std::string::npos);
    }
    const auto g = imaging::surfaceGeometry(c_.camera, c_.truePose, c_.surfaceView());
    // An all-black and a saturated frame: nothing usable to fit, one sentence.
    for (const cv::Scalar& value : {cv::Scalar(0, 0, 0), cv::Scalar(255, 255, 255)}) {
      const cv::Mat3b flat(c_.frame.size(), cv::Vec3b(static_cast<uchar>(value[0]), static_cast<uchar>(value[1]), static_cast<uchar>(value[2])));
      try {
        imaging::fitAppearance(flat, g);
        QFAIL("a flat frame was fitted");
      } catch (const rehearse::InputError& e) {
        QVERIFY(std::string(e.what()).find("usable pixels") != std::string::npos);
      }
    }
    // Off-screen: no pixel of the organ in the frame.
    Pose away = c_.truePose;
    away.t.x() += 5.0;
    const auto off = imaging::surfaceGeometry(c_.camera, away, c_.surfaceView());
    QCOMPARE(cv::countNonZero(off.mask()), 0);
    QVERIFY_THROWS_EXCEPTION(rehearse::InputError, imaging::fitAppearance(c_.frame, off));
  }
};

QTEST_GUILESS_MAIN(TestAppearance)
#include "test_appearance.moc"
