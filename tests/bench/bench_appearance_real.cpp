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
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

using namespace rehearse;

namespace {

// What a point light of any kind can explain on this frame (the ceiling the acceptance's 70 % is measured
// against): the organ's usable pixels (usablePixels) less the challenge's beads and anything bright (every
// channel above 120, grown 4 px: highlights, sheen), one pixel in three. Per channel, the frame (or the frame
// linearised with gamma 2.2) against k_d F cos(theta_i) / r^2 (+ an ambient term), k_d and the ambient solved in
// closed form for each light; the light searched on a grid and refined by coordinate steps. The share is the
// README's: 1 - squared residual over the squared deviation from the mean colour, all channels.
struct Sample {
  Eigen::Vector3d p, n;
  cv::Vec3d linear, gamma;
};

double pointLightShare(const std::vector<Sample>& px, const Eigen::Vector3d& light, double falloff, bool ambient,
                       bool gamma) {
  std::vector<double> m(px.size());
  for (std::size_t i = 0; i < px.size(); ++i) {
    const Eigen::Vector3d d = light - px[i].p;
    const double r = d.norm();
    m[i] = std::pow(std::max(0.0, px[i].p.z() / px[i].p.norm()), falloff) * std::max(0.0, px[i].n.dot(d) / r) / (r * r);
  }
  const double count = static_cast<double>(px.size());
  double residual = 0, variance = 0;
  for (int c = 0; c < 3; ++c) {
    double sm = 0, smm = 0, sy = 0, syy = 0, smy = 0;
    for (std::size_t i = 0; i < px.size(); ++i) {
      const double v = gamma ? px[i].gamma[c] : px[i].linear[c];
      sm += m[i], smm += m[i] * m[i], sy += v, syy += v * v, smy += m[i] * v;
    }
    if (ambient) {
      const double det = smm * count - sm * sm, kd = (smy * count - sm * sy) / det, a = (smm * sy - sm * smy) / det;
      residual += syy + kd * kd * smm + a * a * count - 2 * kd * smy - 2 * a * sy + 2 * kd * a * sm;
    } else {
      const double kd = smm > 0 ? smy / smm : 0;
      residual += syy - 2 * kd * smy + kd * kd * smm;
    }
    variance += syy - sy * sy / count;
  }
  return 1 - residual / variance;
}

struct BestLight {
  double share = -1e9;
  Eigen::Vector3d light = Eigen::Vector3d::Zero();
  double falloff = 0;
};

// The best light on a grid (millimetres: x, y in [-reach, reach] every step, z in [zLow, zHigh]; only points within
// `ball` of the lens when ball > 0), fall-off n in {0, 2, 4, 8}, then refined by halving coordinate steps.
BestLight bestPointLight(const std::vector<Sample>& px, double reach, double step, double zLow, double zHigh,
                         double ball, bool ambient, bool gamma) {
  BestLight best;
  const auto inside = [&](const Eigen::Vector3d& l) { return ball <= 0 || l.norm() <= ball * 1e-3 + 1e-12; };
  for (double x = -reach; x <= reach; x += step)
    for (double y = -reach; y <= reach; y += step)
      for (double z = zLow; z <= zHigh; z += step)
        for (const double n : {0.0, 2.0, 4.0, 8.0}) {
          const Eigen::Vector3d l(x * 1e-3, y * 1e-3, z * 1e-3);
          if (!inside(l)) continue;
          const double s = pointLightShare(px, l, n, ambient, gamma);
          if (s > best.share) best = {s, l, n};
        }
  for (double h = step / 2; h >= 0.5; h /= 2)
    for (bool better = true; better;) {
      better = false;
      for (int axis = 0; axis < 4; ++axis)
        for (const int sign : {-1, 1}) {
          Eigen::Vector3d l = best.light;
          double n = best.falloff;
          if (axis < 3)
            l[axis] += sign * h * 1e-3;
          else
            n = std::max(0.0, n + sign * h * 0.2);
          if (!inside(l)) continue;
          const double s = pointLightShare(px, l, n, ambient, gamma);
          if (s > best.share + 1e-6) best = {s, l, n}, better = true;
        }
    }
  return best;
}

// The fit's figures: its status, Theta, each stage, the share explained and each part switched off.
void reportFit(const app::AppearanceOutput& r, double medianMs, int repeat, std::ofstream& md) {
  const auto& f = r.fit;
  std::printf("%s\n", f.status.c_str());
  std::printf(
      "light (%.1f, %.1f, %.1f) mm, %.1f mm from the lens; fall-off cos^%.2f; kd (%.4g %.4g %.4g) ks (%.4g %.4g %.4g) "
      "sigma %.3f\n",
      1e3 * f.theta.lightPosition.x(), 1e3 * f.theta.lightPosition.y(), 1e3 * f.theta.lightPosition.z(),
      1e3 * f.theta.lightPosition.norm(), f.theta.falloff, f.theta.kd.x(), f.theta.kd.y(), f.theta.kd.z(),
      f.theta.ks.x(), f.theta.ks.y(), f.theta.ks.z(), f.theta.roughness);
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
}

// What the frame allows: the ceiling of any one-albedo model, and the best point light of any kind.
void frameAllows(const app::AppearanceInput& in, const imaging::SurfaceGeometry& g, const testdata::OpenCas& oc,
                 std::ofstream& md) {
  const cv::Mat1b usableAll = imaging::usablePixels(in.frame, g.mask());
  cv::Mat1b beads, bright(in.frame.size(), uchar(0));
  cv::dilate(oc.beads, beads, cv::Mat(), cv::Point(-1, -1), 4);
  for (int y = 0; y < bright.rows; ++y)
    for (int x = 0; x < bright.cols; ++x) {
      const cv::Vec3b v = in.frame(y, x);
      if (std::min({v[0], v[1], v[2]}) > 120) bright(y, x) = 255;
    }
  cv::dilate(bright, bright, cv::Mat(), cv::Point(-1, -1), 4);
  const cv::Mat1b use = usableAll & ~beads & ~bright;
  std::vector<Sample> px;
  cv::Vec3d mean(0, 0, 0);
  int counter = 0, used = 0;
  double nearest = 1e9, farthest = 0;
  for (int y = 0; y < use.rows; ++y)
    for (int x = 0; x < use.cols; ++x) {
      if (!use(y, x)) continue;
      const cv::Vec3b v = in.frame(y, x);
      mean += cv::Vec3d(v[0], v[1], v[2]);
      ++used;
      if (counter++ % 3) continue;
      const cv::Vec3f p = g.position(y, x), n = g.normal(y, x);
      Sample s;
      s.p = Eigen::Vector3d(p[0], p[1], p[2]);
      s.n = Eigen::Vector3d(n[0], n[1], n[2]).normalized();
      for (int c = 0; c < 3; ++c) s.linear[c] = v[c] / 255.0, s.gamma[c] = std::pow(v[c] / 255.0, 2.2);
      nearest = std::min(nearest, s.p.norm()), farthest = std::max(farthest, s.p.norm());
      px.push_back(s);
    }
  mean /= std::max(1, used);
  // One albedo and a perfect shading per pixel (the frame's colour projected on the mean colour): what no
  // shading of one albedo can exceed; the rest is the colour changing over the organ.
  double residual = 0, variance = 0;
  for (int y = 0; y < use.rows; ++y)
    for (int x = 0; x < use.cols; ++x)
      if (use(y, x)) {
        const cv::Vec3d v(in.frame(y, x)[0], in.frame(y, x)[1], in.frame(y, x)[2]);
        const cv::Vec3d r = v - (v.dot(mean) / mean.dot(mean)) * mean, d = v - mean;
        residual += r.dot(r), variance += d.dot(d);
      }
  const double ceiling = 1 - residual / variance;
  std::printf(
      "  what the frame allows (%d px, organ %.1f..%.1f mm from the lens): one albedo with a perfect shading "
      "per pixel explains %.3f\n",
      used, 1e3 * nearest, 1e3 * farthest, ceiling);
  md << "\nwhat the frame allows (" << used << " px, the organ " << 1e3 * nearest << " to " << 1e3 * farthest
     << " mm from the lens): one albedo with a perfect shading per pixel explains " << ceiling
     << "\n\n| point light | frame | ambient | explained | light (mm) | distance from the lens (mm) | n |\n"
        "|---|---|---|---:|---|---:|---:|\n";
  for (const bool tip : {true, false})
    for (const bool gamma : {false, true})
      for (const bool ambient : {false, true}) {
        const BestLight b = tip ? bestPointLight(px, 30, 10, -30, 30, 30, ambient, gamma)
                                : bestPointLight(px, 200, 20, -100, 40, 0, ambient, gamma);
        std::printf(
            "  best point light %s, %s frame%s: explains %.3f at (%.0f, %.0f, %.0f) mm (%.0f mm from the "
            "lens), n %.1f\n",
            tip ? "within 30 mm of the lens" : "anywhere", gamma ? "linearised (gamma 2.2)" : "raw",
            ambient ? ", with an ambient term" : "", b.share, 1e3 * b.light.x(), 1e3 * b.light.y(), 1e3 * b.light.z(),
            1e3 * b.light.norm(), b.falloff);
        md << "| " << (tip ? "within 30 mm of the lens" : "anywhere") << " | " << (gamma ? "gamma 2.2" : "raw")
           << " | " << (ambient ? "yes" : "no") << " | " << b.share << " | (" << std::lround(1e3 * b.light.x())
           << ", " << std::lround(1e3 * b.light.y()) << ", " << std::lround(1e3 * b.light.z()) << ") | "
           << std::lround(1e3 * b.light.norm()) << " | " << b.falloff << " |\n";
      }
}

// The honest check: fitted on half A, half B predicted.
void honestCheck(const app::AppearanceInput& in, const imaging::SurfaceGeometry& g, const std::string& out,
                 std::ofstream& md) {
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
}

}  // namespace

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
  std::ofstream md(out + "/appearance_real.md");
  reportFit(r, medianMs, repeat, md);

  // The composition at rest inside the organ (eroded 2 px, as the step measures it): re-shaded and texture-only.
  cv::Mat1b inner;
  cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  const cv::Mat3b reshaded = app::composeAppearance(in, r.fit.theta, r.background, r.albedo, imaging::Reshading{}, {}, 1);
  const cv::Mat3b texture = app::composeAppearance(in, r.fit.theta, r.background, r.albedo, imaging::Reshading{true, 0.0}, {}, 1);
  const double dbReshaded = imaging::psnr(in.frame, reshaded, inner),
               dbTexture = imaging::psnr(in.frame, texture, inner);
  std::printf("  composed at rest inside the organ: re-shaded %.1f dB, texture-only %.1f dB\n", dbReshaded, dbTexture);
  md << "\ncomposed at rest inside the organ: re-shaded " << dbReshaded << " dB, texture-only " << dbTexture << " dB\n";

  frameAllows(in, g, oc, md);
  honestCheck(in, g, out, md);
  cv::imwrite(out + "/open_cas_frame.png", in.frame);
  cv::imwrite(out + "/open_cas_reshaded.png", reshaded);
  std::printf("written: %s/appearance_real.md, .csv\n", out.c_str());
  return 0;
}
