// Benchmark of the elastic fit (issue 5) with the protocol of Adagolodjo et al.: a ground truth made by
// the project without the inverse crime (a finer mesh of the phantom, another material law, loads the fit
// does not know: sideways gravity and a tool pushing on the front), its silhouette rendered through the
// camera, 40 visible surface markers; 12 starts (the true pose perturbed by +-2 cm along and +-20 degrees
// about each camera axis) x 4 contour fractions (100/90/80/70 %). Writes registration.csv and
// registration.png (marker error against wall time for each start at 100 %). Not a test.
//   bench_registration [OUT_DIR] [--quick] [--repeat N]
// --repeat N runs every start N times (the errors are the same each time: the fit is deterministic) and
// reports each run's mean wall time, so the spread a shared machine adds can be seen.
// Environment: REHEARSE_BENCH_DIAG=1 first analyses the error at the true pose (by stage and camera axis,
// the best rigid motion of the markers, the fit of undeformed outlines); REHEARSE_BENCH_VARIANTS=1 runs
// the rigid-only and elastic-only variants; REHEARSE_BENCH_TRACE=1 prints every iteration;
// REHEARSE_FIT_TETS=N builds the fit model with about N tets instead of the phantom's default.
#include "phantom/phantom.hpp"
#include "plot.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/registration.hpp>

#include <rehearse/imaging/contour.hpp>

#include <algorithm>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {
// The organ's outline in the frame: the longest border of its rendered mask.
std::vector<Eigen::Vector2d> outline(const phantom::Phantom& c, const Pose& pose, const SurfaceView& surface) {
  const auto borders = imaging::maskOutlines(imaging::renderMask(c.camera, pose, surface));
  return borders.empty() ? std::vector<Eigen::Vector2d>{} : borders.front();
}

// Turned about the camera axis through the organ's centre, then moved (camera frame).
Pose perturb(const Pose& p, const Eigen::Vector3d& move, int axis, double degrees, const Eigen::Vector3d& centre) {
  Pose q = p.turnedAbout(Eigen::AngleAxisd(degrees * M_PI / 180, Eigen::Vector3d::Unit(axis)).toRotationMatrix(), p.apply(centre));
  q.t += move;
  return q;
}

struct Start {
  std::string name;
  Eigen::Vector3d move;
  int axis;
  double degrees;
};

// The benchmark, phase by phase: the ground truth, the markers, the diagnostics, the starts, the variants, the fits
// and the summary.
struct RegistrationBench {
  std::string out = ".";
  bool quick = false;
  int repeat = 1;
  phantom::Phantom coarse, fine;
  FemModel model;
  Pose truth;
  SimulationSettings load;
  Eigen::VectorXd gtX;  // the ground truth's nodes
  std::vector<Eigen::Vector2d> fullContour;
  std::vector<Eigen::Vector3d> markerTruth;
  SurfaceEmbedding markerMap;
  std::ofstream csv;
  std::vector<PlotSeries> series;
  std::vector<Start> starts;
  std::vector<double> fractions;
  std::map<double, std::vector<double>> endErrors, times;
  std::map<double, std::vector<std::vector<double>>> runTimes;  // per fraction, per run: each start's wall time
  int worse = 0;

  // The fit's model and the ground truth, its outline the contour.
  void groundTruth() {
    // The model the fit uses: the built-in phantom, co-rotational, the DejaVu liver's parameters.
    phantom::PhantomOptions coarseOptions;
    if (const char* t = std::getenv("REHEARSE_FIT_TETS")) coarseOptions.targetTets = std::atoi(t);
    coarse = phantom::makePhantom(coarseOptions);
    model = FemModel::build(coarse.volume, {{phantom::kVesselLabel, {MaterialModel::Corotational, 620e3, 0.45, 1000}}},
                            {MaterialModel::Corotational, 27e3, 0.40, 1000});
    // The ground truth: a finer mesh of the same organ, the stable Neo-Hookean law, other loads.
    phantom::PhantomOptions fineOptions;
    fineOptions.targetTets = quick ? 8000 : 16000;
    fine = phantom::makePhantom(fineOptions);
    const FemModel fineModel = FemModel::build(fine.volume, {{phantom::kVesselLabel, {MaterialModel::NeoHookean, 620e3, 0.45, 1000}}},
                                               {MaterialModel::NeoHookean, 27e3, 0.45, 1000});
    truth = coarse.truePose;
    load.gravity = truth.R.transpose() * Eigen::Vector3d(9.81, 0, 0);  // 1 g sideways in the image
    Integrator gtIn(fineModel, fine.attachments, load);
    auto gt = gtIn.initialState();
    // A tool pushing the front surface near the organ's lower left: 0.3 N along the view direction.
    Eigen::VectorXd tool = Eigen::VectorXd::Zero(gt.x.size());
    {
      const Eigen::Vector3d cog = fine.centreOfGravity();
      int best = -1;
      double score = -1e300;
      for (const auto& t : fine.surface)
        for (int v : t) {
          const Eigen::Vector3d pc = truth.apply(fine.volume.points[v]);
          const double s = -pc.z() + 0.5 * (pc.x() - truth.apply(cog).x()) * -1;  // near, and to the left
          if (s > score) score = s, best = v;
        }
      tool.segment<3>(3 * best) = truth.R.transpose() * Eigen::Vector3d(0, 0, 0.3);
    }
    const auto gtRep = gtIn.solveStatic(gt, tool);
    std::printf("ground truth: %zu tets (fit model %zu), stable Neo-Hookean, 1 g sideways + 0.3 N tool: %s, largest displacement %.1f mm\n",
                fine.volume.tets.size(), coarse.volume.tets.size(), gtRep.status.c_str(), 1e3 * (gt.x - fineModel.restVector()).cwiseAbs().maxCoeff());
    gtX = gt.x;
    std::vector<double> gtVerts(gt.x.data(), gt.x.data() + gt.x.size());
    SurfaceView gtSurface = fine.surfaceView();
    gtSurface.vertices = gtVerts.data();
    fullContour = outline(fine, truth, gtSurface);
  }

  // Markers: 40 visible front-surface nodes of the fine mesh, spread by farthest-point sampling.
  void placeMarkers() {
    std::vector<int> candidates;
    {
      std::vector<char> seen(fine.volume.points.size(), 0);
      for (const auto& t : fine.surface) {
        const Eigen::Vector3d a = truth.apply(gtX.segment<3>(3 * t[0])), b = truth.apply(gtX.segment<3>(3 * t[1])),
                              c = truth.apply(gtX.segment<3>(3 * t[2]));
        if ((b - a).cross(c - a).dot(a) >= 0) continue;  // back face
        for (int v : t)
          if (!seen[v]) seen[v] = 1, candidates.push_back(v);
      }
    }
    std::vector<int> markers{candidates.front()};
    while (markers.size() < 40 && markers.size() < candidates.size()) {
      int best = -1;
      double far = -1;
      for (int v : candidates) {
        double d = 1e300;
        for (int m : markers) d = std::min(d, (fine.volume.points[v] - fine.volume.points[m]).norm());
        if (d > far) far = d, best = v;
      }
      markers.push_back(best);
    }
    std::vector<Eigen::Vector3d> markerRest;
    for (int v : markers) {
      markerRest.push_back(fine.volume.points[v] * fine.volume.unitToMetre);
      markerTruth.push_back(gtX.segment<3>(3 * v));
    }
    markerMap = embedPoints(model, markerRest);
    std::printf("%zu markers (%zu outside the fit model's volume), contour of %zu pixels; markers at the true pose, undeformed: %.2f mm\n",
                markers.size(), markerMap.outside, fullContour.size(), markerError(model.restVector(), truth));
  }

  // The markers' mean distance from the truth (mm).
  double markerError(const Eigen::VectorXd& x, const Pose& pose) const {
    const auto pts = mapEmbedded(markerMap, x);
    double sum = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) sum += (pose.apply(pts[i]) - truth.apply(markerTruth[i])).norm();
    return 1e3 * sum / pts.size();
  }

  // The markers' mean error, across the view and along it, as one DIAG line.
  void parts(const char* what, const Eigen::VectorXd& x, const Pose& pose) const {
    const auto pts = mapEmbedded(markerMap, x);
    double xy = 0, z = 0, all = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector3d d = pose.apply(pts[i]) - truth.apply(markerTruth[i]);
      xy += d.head<2>().norm(), z += std::abs(d.z()), all += d.norm();
    }
    const double n = pts.size();
    std::printf("DIAG %-34s mean %.2f mm  |xy| %.2f  |z| %.2f\n", what, 1e3 * all / n, 1e3 * xy / n, 1e3 * z / n);
  }

  // REHEARSE_BENCH_DIAG: the error at the true pose by stage and camera axis, the best rigid motion of the markers,
  // the fit of undeformed outlines.
  void diagnose() const {
    parts("undeformed at truth", model.restVector(), truth);
    {
      // The best rigid motion of the undeformed markers onto the true ones (Umeyama, no scale).
      const auto pts = mapEmbedded(markerMap, model.restVector());
      Eigen::Matrix3Xd a(3, pts.size()), b(3, pts.size());
      for (std::size_t i = 0; i < pts.size(); ++i) a.col(i) = truth.apply(pts[i]), b.col(i) = truth.apply(markerTruth[i]);
      const Eigen::Matrix4d T = Eigen::umeyama(a, b, false);
      Pose p = truth;
      p.R = T.topLeftCorner<3, 3>() * truth.R;
      p.t = T.topLeftCorner<3, 3>() * truth.t + T.topRightCorner<3, 1>();
      parts("best rigid of the markers (oracle)", model.restVector(), p);
    }
    for (int which = 0; which < 2; ++which) {
      // Rigid fit from the truth onto the outline of an undeformed mesh: the coarse fit model itself, the fine one.
      const phantom::Phantom& c = which ? fine : coarse;
      const auto cont = outline(c, truth, c.surfaceView());
      RegistrationOptions o;
      o.elastic = false;
      SimulationSettings settings;
      settings.gravity.setZero();
      const auto r = registerToContour(model, coarse.attachments, settings, coarse.surface, {cont}, truth, coarse.camera.pinhole(), o);
      const Eigen::Vector3d c0 = truth.apply(coarse.centreOfGravity()), dc = r.pose.apply(coarse.centreOfGravity()) - c0;
      std::printf("DIAG undeformed %s outline: centre moved %.2f %.2f %.2f mm, %.2f deg, residual %.2f px (at truth %.2f px), centre depth %.0f mm\n",
                  which ? "fine" : "coarse", 1e3 * dc.x(), 1e3 * dc.y(), 1e3 * dc.z(), Eigen::AngleAxisd(r.pose.R * truth.R.transpose()).angle() * 180 / M_PI,
                  r.iterations.back().residual.mean, r.iterations.front().residual.mean, 1e3 * c0.z());
    }
    // The stages from the true pose; with the true gravity told to the fit, the elastic stage alone, and
    // after the rigid stage (which has already taken the sag for a move of the whole organ).
    struct Variant {
      const char* name;
      bool rigid, elastic, gravity;
    };
    for (const Variant& v : {Variant{"rigid only from truth", true, false, false}, Variant{"elastic only from truth", false, true, false},
                             Variant{"rigid+elastic from truth", true, true, false}, Variant{"elastic, true gravity", false, true, true},
                             Variant{"rigid+elastic, true gravity", true, true, true}}) {
      RegistrationOptions o;
      o.elastic = v.elastic;
      o.rigidPrepass = v.rigid;
      SimulationSettings settings;
      settings.gravity = v.gravity ? load.gravity : Eigen::Vector3d::Zero();
      const auto r = registerToContour(model, coarse.attachments, settings, coarse.surface, {fullContour}, truth, coarse.camera.pinhole(), o);
      parts(v.name, r.x, r.pose);
      const Eigen::Vector3d dc = r.pose.apply(coarse.centreOfGravity()) - truth.apply(coarse.centreOfGravity());
      std::printf("     centre moved %.2f %.2f %.2f mm, turned %.2f deg; residual %.2f px\n", 1e3 * dc.x(), 1e3 * dc.y(), 1e3 * dc.z(),
                  Eigen::AngleAxisd(r.pose.R * truth.R.transpose()).angle() * 180 / M_PI, r.iterations.back().residual.mean);
    }
  }

  // The 12 starts (+-2 cm along, +-20 degrees about each camera axis) and the contour shares.
  void makeStarts() {
    const double cm = 0.02, deg = 20;
    const char* axes = "XYZ";
    for (int a = 0; a < 3; ++a)
      for (int sgn : {1, -1}) {
        starts.push_back({std::string(sgn > 0 ? "+" : "-") + "2cm " + axes[a], sgn * cm * Eigen::Vector3d::Unit(a), a, 0});
        starts.push_back({std::string(sgn > 0 ? "+" : "-") + "20deg " + axes[a], Eigen::Vector3d::Zero(), a, sgn * deg});
      }
    if (quick) starts.resize(2);
    fractions = quick ? std::vector<double>{1.0} : std::vector<double>{1.0, 0.9, 0.8, 0.7};
  }

  // Variants at 100 %: rigid only, elastic without the pre-pass (what each stage contributes).
  void runVariants() {
    for (int variant = 0; variant < 2; ++variant) {
      double sum = 0;
      for (const auto& st : starts) {
        const Pose start = perturb(truth, st.move, st.axis, st.degrees, coarse.centreOfGravity());
        RegistrationOptions o;
        o.elastic = variant == 1;
        o.rigidPrepass = false;
        SimulationSettings settings;
        settings.gravity.setZero();
        RegistrationResult r;
        try {
          r = registerToContour(model, coarse.attachments, settings, coarse.surface, {fullContour}, start, coarse.camera.pinhole(), o);
        } catch (const std::exception& e) {
          r.status = e.what();
        }
        const double e1 = r.x.size() ? markerError(r.x, r.pose) : -1;
        sum += e1;
        std::printf("%-14s %-10s %8.2f mm -> %8.2f mm  %s\n", variant ? "elastic only" : "rigid only", st.name.c_str(),
                    markerError(model.restVector(), start), e1, r.status.c_str());
      }
      std::printf("%s: mean %.2f mm\n", variant ? "elastic only" : "rigid only", sum / starts.size());
    }
    fractions = {1.0};
  }

  // Every start at every contour share.
  void runFits() {
    std::printf("\n%-10s %5s %10s %10s %9s %9s %9s  %s\n", "start", "kept", "start mm", "end mm", "start px", "end px", "ms", "status");
    for (double fraction : fractions) {
      // Keep a contiguous part of the outline (the rest is as if the assistant had not drawn it).
      const std::size_t keep = static_cast<std::size_t>(fraction * fullContour.size());
      std::vector<Eigen::Vector2d> part(fullContour.begin(), fullContour.begin() + keep);
      for (const auto& s : starts) runStart(s, fraction, part);
    }
  }

  // One start on one share of the contour, `repeat` times: its line, its CSV row, its series at 100 %.
  void runStart(const Start& s, double fraction, const std::vector<Eigen::Vector2d>& part) {
    const Pose start = perturb(truth, s.move, s.axis, s.degrees, coarse.centreOfGravity());
    PlotSeries ps;
    ps.name = s.name;
    RegistrationOptions o;
    o.rigidPrepass = true;
    o.onIteration = [&](const RegistrationIteration& it, const Eigen::VectorXd& x, const Pose& pose) {
      ps.x.push_back(std::max(it.wallMs, 1.0));
      ps.y.push_back(markerError(x, pose));
      if (std::getenv("REHEARSE_BENCH_TRACE"))
        std::printf("  %s %.0f%% it %d %s %.0f ms %.2f px %.2f mm\n", s.name.c_str(), 100 * fraction, it.iteration, it.stage.c_str(), it.wallMs, it.score(), ps.y.back());
      return true;
    };
    SimulationSettings settings;
    settings.gravity.setZero();
    RegistrationResult r;
    for (int run = 0; run < repeat; ++run) {
      if (run > 0) o.onIteration = nullptr;  // the series is the first run's
      RegistrationResult again;
      try {
        again = registerToContour(model, coarse.attachments, settings, coarse.surface, {part}, start, coarse.camera.pinhole(), o);
      } catch (const std::exception& e) {
        again.status = std::string("error: ") + e.what();
      }
      runTimes[fraction].resize(static_cast<std::size_t>(repeat));
      runTimes[fraction][static_cast<std::size_t>(run)].push_back(again.iterations.empty() ? 0 : again.iterations.back().wallMs);
      if (run == 0) r = std::move(again);
    }
    const double e0 = markerError(model.restVector(), start);
    const double e1 = r.x.size() ? markerError(r.x, r.pose) : e0;
    const double px0 = r.iterations.empty() ? 0 : r.iterations.front().residual.mean;
    const double px1 = r.iterations.empty() ? 0 : r.iterations.back().residual.mean;
    const double ms = r.iterations.empty() ? 0 : r.iterations.back().wallMs;
    worse += e1 >= e0;
    endErrors[fraction].push_back(e1);
    times[fraction].push_back(ms);
    std::printf("%-10s %4.0f%% %10.2f %10.2f %9.2f %9.2f %9.0f  %s\n", s.name.c_str(), 100 * fraction, e0, e1, px0, px1, ms, r.status.c_str());
    csv << "\"" << s.name << "\"," << fraction << "," << e0 << "," << e1 << "," << px0 << "," << px1 << "," << ms << ","
        << r.iterations.size() << "," << r.ok << ",\"" << r.status << "\"\n";
    if (fraction == 1.0) series.push_back(ps);
  }

  // The means over the starts per share, the plot.
  void summary() {
    std::printf("\nsummary (mean over %zu starts):\n", starts.size());
    for (double f : fractions) {
      const auto& e = endErrors[f];
      const auto& t = times[f];
      std::printf("  contour %3.0f %%: marker error %.2f mm (worst %.2f), wall time %.0f ms (worst %.0f)", 100 * f,
                  std::accumulate(e.begin(), e.end(), 0.0) / e.size(), *std::max_element(e.begin(), e.end()),
                  std::accumulate(t.begin(), t.end(), 0.0) / t.size(), *std::max_element(t.begin(), t.end()));
      if (repeat > 1) {
        std::printf("; mean of each of %d runs:", repeat);
        double worstRun = 0;
        for (const auto& run : runTimes[f]) {
          std::printf(" %.0f", std::accumulate(run.begin(), run.end(), 0.0) / run.size());
          worstRun = std::max(worstRun, *std::max_element(run.begin(), run.end()));
        }
        std::printf(" ms (worst single start %.0f ms)", worstRun);
      }
      std::printf("\n");
    }
    std::printf("  starts that ended worse than they began: %d\n", worse);
    writeLogLogPlot(out + "/registration.png", "Elastic fit, 100 % contour: marker error against wall time per start", "wall time (ms)",
                    "mean marker error (mm)", series);
  }
};
}  // namespace

int main(int argc, char** argv) {
  RegistrationBench b;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") b.quick = true;
    else if (a == "--repeat" && i + 1 < argc) b.repeat = std::max(1, std::atoi(argv[++i]));
    else b.out = a;
  }
  std::filesystem::create_directories(b.out);
  b.groundTruth();
  b.placeMarkers();
  if (std::getenv("REHEARSE_BENCH_DIAG")) b.diagnose();
  b.csv.open(b.out + "/registration.csv");
  b.csv << "start,fraction,start_error_mm,end_error_mm,start_px,end_px,wall_ms,iterations,ok,status\n";
  b.makeStarts();
  if (std::getenv("REHEARSE_BENCH_VARIANTS")) b.runVariants();
  b.runFits();
  b.summary();
  std::printf("wrote %s/registration.csv and .png\n", b.out.c_str());
  return 0;
}
