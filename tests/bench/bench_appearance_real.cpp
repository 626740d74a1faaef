// Appearance on a real frame (issue 35): the Open-CAS ex-vivo porcine liver (../shared/data/open-cas), whose CT
// surface is already in the left camera's frame. Theta fitted on the undistorted frame through that surface:
// each stage's figures, the share of the organ's shading explained (README, "Appearance") beside what a smooth
// function of the image position explains, each part of the model switched off, where the light lands against
// the scope, the composition at rest (re-shaded and texture-only), and the honest check: fitted on one half of
// the organ's pixels, the other half predicted by Theta (albedo 1) against the first half's mean colour (what a
// texture that does not know the shading predicts). Median time of repeated fits. Not a test.
//   bench_appearance_real [OUT_DIR] [--repeat N]
#include "opencas.hpp"

#include <rehearse/app/appearancestep.hpp>
#include <rehearse/imaging/render.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

using namespace rehearse;

int main(int argc, char** argv) {
  std::string out = ".";
  int repeat = 3;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc)
      repeat = std::max(1, std::atoi(argv[++i]));
    else
      out = a;
  }
  std::filesystem::create_directories(out);
  if (!testdata::OpenCas::available()) {
    std::printf("skipped: %s is absent\n", testdata::OpenCas::directory().c_str());
    return 0;
  }
  const testdata::OpenCas oc = testdata::OpenCas::load();
  app::AppearanceInput in;
  in.camera = oc.camera;
  in.frame = oc.frame;
  in.vertices = oc.vertices;
  in.triangles = oc.triangles;
  const auto g = imaging::surfaceGeometry(in.camera, in.pose, in.surface());
  std::printf("Open-CAS frame %dx%d, CT surface %zu triangles covering %d px\n", oc.frame.cols, oc.frame.rows,
              oc.triangles.size(), cv::countNonZero(g.mask()));

  std::vector<double> times;
  app::AppearanceOutput r;
  for (int k = 0; k < repeat; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    r = app::runAppearance(in);
    times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::nth_element(times.begin(), times.begin() + static_cast<std::ptrdiff_t>(times.size() / 2), times.end());
  const double medianMs = times[times.size() / 2];
  const auto& f = r.fit;
  std::printf("%s\n", f.status.c_str());
  std::printf(
      "light (%.1f, %.1f, %.1f) mm, %.1f mm from the lens; fall-off cos^%.2f; kd (%.4g %.4g %.4g) ks (%.4g %.4g %.4g) "
      "sigma %.3f\n",
      1e3 * f.theta.lightPosition.x(), 1e3 * f.theta.lightPosition.y(), 1e3 * f.theta.lightPosition.z(),
      1e3 * f.theta.lightPosition.norm(), f.theta.falloff, f.theta.kd.x(), f.theta.kd.y(), f.theta.kd.z(),
      f.theta.ks.x(), f.theta.ks.y(), f.theta.ks.z(), f.theta.roughness);
  std::ofstream md(out + "/appearance_real.md");
  md << "| stage | rms (levels) | pixels | ms |\n|---|---:|---:|---:|\n";
  for (const auto& s : f.stages) {
    std::printf("  %-28s rms %.2f levels over %zu px, %.0f ms\n", s.name.c_str(), s.rms, s.pixels, s.ms);
    md << "| " << s.name << " | " << s.rms << " | " << s.pixels << " | " << s.ms << " |\n";
  }
  std::printf("  explained %.3f; smooth function of the image position %.3f\n", f.explained, f.smoothShare);
  md << "\nexplained " << f.explained << ", smooth function of the image position " << f.smoothShare << "; light "
     << 1e3 * f.theta.lightPosition.norm() << " mm from the lens (at bound: " << f.lightAtBound << "), fall-off n "
     << f.theta.falloff << "; whole step median " << medianMs << " ms of " << repeat
     << "\n\n| without | explained | holds |\n|---|---:|---|\n";
  for (const auto& c : f.checks) {
    std::printf("  without %-36s %.3f (%s)\n", c.part.c_str(), c.explainedWithout, c.holds ? "holds" : "not seen");
    md << "| " << c.part << " | " << c.explainedWithout << " | " << (c.holds ? "yes" : "no") << " |\n";
  }

  // The composition at rest inside the organ (eroded 2 px, as the step measures it): re-shaded and texture-only.
  cv::Mat1b inner;
  cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  const cv::Mat3b reshaded = app::composeAppearance(in, f.theta, r.background, r.albedo, false, {}, 1);
  const cv::Mat3b texture = app::composeAppearance(in, f.theta, r.background, r.albedo, true, {}, 1);
  const double dbReshaded = imaging::psnr(in.frame, reshaded, inner),
               dbTexture = imaging::psnr(in.frame, texture, inner);
  std::printf("  composed at rest inside the organ: re-shaded %.1f dB, texture-only %.1f dB\n", dbReshaded, dbTexture);
  md << "\ncomposed at rest inside the organ: re-shaded " << dbReshaded << " dB, texture-only " << dbTexture << " dB\n";

  // The honest check: fitted on half A, half B predicted.
  std::ofstream csv(out + "/appearance_real.csv");
  csv << "split,half_fitted,explained_on_fitted,model_psnr_db,flat_psnr_db,gain_db\n";
  md << "\n| split | fitted on | explained there | Theta predicts the other half | its mean colour | gain "
        "|\n|---|---|---:|---:|---:|---:|\n";
  cv::Rect box = cv::boundingRect(g.mask());
  for (const std::string split : {"left/right", "checkerboard 24 px"})
    for (int half = 0; half < 2; ++half) {
      cv::Mat1b a(g.mask().size(), uchar(0));
      for (int y = 0; y < a.rows; ++y)
        for (int x = 0; x < a.cols; ++x) {
          const bool left = x < box.x + box.width / 2, cell = ((x / 24) + (y / 24)) % 2 == 0;
          a(y, x) = (split == "left/right" ? left : cell) == (half == 0) ? 255 : 0;
        }
      imaging::SurfaceGeometry ga = g;
      ga.triangle = g.triangle.clone();  // cv::Mat copies share their pixels
      ga.triangle.setTo(-1, ~a);
      const auto fa = imaging::fitAppearance(in.frame, ga);
      // Half B's usable pixels (the same rules as the fit's), not foreign, away from what is clipped.
      const cv::Mat1b usableAll = imaging::usablePixels(in.frame, g.mask());
      cv::Mat1b b = usableAll & ~a;
      cv::Mat1b ea;
      cv::erode(a, ea, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
      const cv::Mat3b model = imaging::renderShaded(in.camera, in.pose, in.surface(), fa.theta,
                                                    cv::Mat3b(in.frame.size(), cv::Vec3b(0, 0, 0)), 1);
      const cv::Scalar meanA = cv::mean(in.frame, usableAll & a);
      const cv::Mat3b flat(in.frame.size(),
                           cv::Vec3b(cv::saturate_cast<uchar>(meanA[0]), cv::saturate_cast<uchar>(meanA[1]),
                                     cv::saturate_cast<uchar>(meanA[2])));
      const double dbModel = imaging::psnr(in.frame, model, b), dbFlat = imaging::psnr(in.frame, flat, b);
      std::printf(
          "  %s, fitted on half %c: explains %.3f there; half %c predicted by Theta %.2f dB, by the mean colour %.2f "
          "dB (%+.2f dB)\n",
          split.c_str(), half == 0 ? 'A' : 'B', fa.explained, half == 0 ? 'B' : 'A', dbModel, dbFlat, dbModel - dbFlat);
      csv << split << "," << (half == 0 ? "A" : "B") << "," << fa.explained << "," << dbModel << "," << dbFlat << ","
          << dbModel - dbFlat << "\n";
      md << "| " << split << " | " << (half == 0 ? "A" : "B") << " | " << fa.explained << " | " << dbModel << " dB | "
         << dbFlat << " dB | " << dbModel - dbFlat << " dB |\n";
    }
  cv::imwrite(out + "/open_cas_frame.png", in.frame);
  cv::imwrite(out + "/open_cas_reshaded.png", reshaded);
  std::printf("written: %s/appearance_real.md, .csv\n", out.c_str());
  return 0;
}
