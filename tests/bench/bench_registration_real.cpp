// Benchmark of the elastic fit on real organ shapes (issue 13), with a ground truth that is not our own
// model: each organ's surface (a patient liver, the BodyParts3D and HuBMAP livers, a kidney) is meshed
// twice, finely for CalculiX (Neo-Hookean, NLGEOM: gravity on the organ held by its back, plus a tool
// pushing its front) and at the application's default size for the fit; the deformed fine surface is
// rendered through the scikit-surgery laparoscope's camera (1920x1080), and its outline, kept at
// 100/90/80/70/60/50 % with the missing part on four different sides, with +-2 px noise and a few outlier
// points, is the contour. The fit (app::runElasticFit, what the GUI and `rehearse register` run) starts
// from the paper's 12 perturbations (+-2 cm along, +-20 degrees about each camera axis) and 4 combined
// ones. Markers: 40 visible surface points and one inner target. Writes registration-real.csv (one row
// per fit) and registration-real-<organ>.png (marker error against wall time at 100 %). Not a test.
//   bench_registration_real [OUT_DIR] [--quick] [--organ NAME] [--no-attachments] [--fractions 1,0.7,0.5] [--ridge]
//                           [--second-frame MM [--estimate-motion]]
// --second-frame MM: a second frame (issue 38), the camera moved MM across the view (along its X) and turned to keep
// the organ's centre in the middle; its outline cut like the first's (the same share, the same side missing, its own
// noise) and 200 features tracked between the frames (0.5 px noise), the motion given; with --estimate-motion, the
// motion estimated from those features (imaging::estimateCameraMotion, the move's length given).
// --ridge: every contour also carries an anatomical curve (issue 38): the shortest path over the fit mesh's surface
// between the two visible front nodes farthest apart in the image (at least 40 px inside the outline), drawn where
// CalculiX's deformed organ puts it (each node moved as its nearest fine surface node), +-2 px noise.
// The fine meshes and CalculiX's answers are cached in OUT_DIR (delete them to recompute). REHEARSE_BENCH_TRACE=1
// prints every iteration's stage, time and distance (stderr); REHEARSE_BENCH_ONE_START=1 runs the first start only.
#include "calculix.hpp"
#include "plot.hpp"
#include "realorgan.hpp"

#include <rehearse/app/elasticfit.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/imaging/motion.hpp>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <QCoreApplication>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <sstream>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

struct OrganSpec {
  std::string name, path;
  std::string part;  ///< only this labelled part of the file (empty: all)
};

Mesh cachedVolume(const Mesh& surface, std::size_t tets, unsigned seed, const std::string& cache) {
  if (std::filesystem::exists(cache)) return loadMesh(cache);
  TetrahedraliseOptions o;
  o.targetTets = tets;
  o.seed = seed;
  o.allowSelfIntersections = true;  // the HuBMAP liver's outer surface touches itself in 38 places
  Mesh v = tetrahedraliseSurface(surface, o);
  saveMesh(v, cache);
  return v;
}

Pose perturb(const Pose& p, const Eigen::Vector3d& move, const Eigen::Vector3d& turnDegrees, const Eigen::Vector3d& centre) {
  Pose q = p;
  for (int a = 0; a < 3; ++a)
    if (turnDegrees[a] != 0)
      q = q.turnedAbout(Eigen::AngleAxisd(turnDegrees[a] * M_PI / 180, Eigen::Vector3d::Unit(a)).toRotationMatrix(), q.apply(centre));
  q.t += move;
  return q;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// Exit code of `rehearse register` for a result: 0 determined, 4 ambiguous, 3 failed.
int exitCode(const RegistrationResult& r) { return !r.ok ? 3 : r.ambiguous ? 4 : 0; }

// The command line.
struct Options {
  std::string out = ".";
  std::string only;
  bool quick = false, attachments = true, ridge = false;
  double secondFrameMm = 0;
  bool estimateMotion = false;
  std::vector<double> fractionsAsked;
};

Options parseOptions(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") o.quick = true;
    else if (a == "--organ" && i + 1 < argc) o.only = argv[++i];
    else if (a == "--no-attachments") o.attachments = false;
    else if (a == "--ridge")
      o.ridge = true;
    else if (a == "--second-frame" && i + 1 < argc)
      o.secondFrameMm = std::atof(argv[++i]);
    else if (a == "--estimate-motion")
      o.estimateMotion = true;
    else if (a == "--fractions" && i + 1 < argc) {
      std::stringstream list(argv[++i]);
      std::string item;
      while (std::getline(list, item, ',')) o.fractionsAsked.push_back(std::atof(item.c_str()));
    }
    else o.out = a;
  }
  return o;
}

// The fits of one organ and contour share: their errors, times and reports.
struct Cell {
  std::vector<double> err, target, ms, rigid;
  int silentWrong = 0, wrong = 0, flaggedGood = 0, good = 0, failed = 0, ambiguous = 0;
  // The reported bound against the true error (surface markers' mean; the inner target): covered (error <= bound)
  // and tight (bound <= 3x the error), over the fits that report one.
  int bounded = 0, covered = 0, tight = 0, targetCovered = 0;
};
using Cells = std::map<std::pair<std::string, double>, Cell>;

struct Error {
  double surface = 0, target = 0, worst = 0, depth = 0;  // depth: the mean of the markers' error along the view
};

struct Start {
  std::string name;
  Eigen::Vector3d move, turn;
};

// The paper's 12 perturbations (+-2 cm along, +-20 degrees about each camera axis) and 4 combined ones.
std::vector<Start> startsFor(bool quick) {
  std::vector<Start> starts;
  const char* axes = "XYZ";
  for (int a = 0; a < 3; ++a)
    for (int sgn : {1, -1}) {
      starts.push_back({std::string(sgn > 0 ? "+" : "-") + "2cm " + axes[a], sgn * 0.02 * Eigen::Vector3d::Unit(a), Eigen::Vector3d::Zero()});
      starts.push_back({std::string(sgn > 0 ? "+" : "-") + "20deg " + axes[a], Eigen::Vector3d::Zero(), sgn * 20.0 * Eigen::Vector3d::Unit(a)});
    }
  starts.push_back({"+1cm X +10deg Y", {0.01, 0, 0}, {0, 10, 0}});
  starts.push_back({"-1cm Y -10deg X", {0, -0.01, 0}, {-10, 0, 0}});
  starts.push_back({"+1cm Z +10deg Z", {0, 0, 0.01}, {0, 0, 10}});
  starts.push_back({"-1cm X +10deg X -10deg Y", {-0.01, 0, 0}, {10, -10, 0}});
  if (quick) starts = {starts[0], starts[3], starts[8], starts[12]};
  if (std::getenv("REHEARSE_BENCH_ONE_START")) starts.resize(1);
  return starts;
}

// The outline's topmost, rightmost, bottommost and leftmost points.
std::array<std::size_t, 4> sidesOf(const std::vector<Eigen::Vector2d>& line) {
  std::array<std::size_t, 4> at{0, 0, 0, 0};
  for (std::size_t i = 0; i < line.size(); ++i) {
    const auto& p = line[i];
    if (p.y() < line[at[0]].y()) at[0] = i;
    if (p.x() > line[at[1]].x()) at[1] = i;
    if (p.y() > line[at[2]].y()) at[2] = i;
    if (p.x() < line[at[3]].x()) at[3] = i;
  }
  return at;
}

const char* const sideNames[] = {"top", "right", "bottom", "left"};

// One organ, phase by phase: its meshes and loads, CalculiX's ground truth, the ridge, the fit's set-up, the
// diagnostics, the second frame and the fits. A phase that returns false has said why the organ is skipped.
struct OrganBench {
  const Options& opt;
  const OrganSpec& spec;
  const imaging::Camera& cam;
  std::chrono::steady_clock::time_point t0;
  Mesh fine;
  std::shared_ptr<const app::Organ> organ;
  Pose truth;
  std::vector<int> fineHeld, fitHeld, fineSurface;
  Eigen::Vector3d gCam, toolForce;
  int toolNode = 0;
  double heldShare = 0, toolNewton = 0;
  std::string gtCache;
  Eigen::VectorXd u;
  double loadScale = 1;
  Mesh deformed;
  std::vector<std::array<int, 3>> fineTris;
  std::vector<double> defVerts;
  SurfaceView view;
  std::vector<Eigen::Vector2d> outline;
  imaging::Rasterization ras;
  std::vector<int> markers;
  int target = -1;
  imaging::ContourSegment ridgeSegment;
  std::vector<Eigen::Vector3d> markerRest, markerTruth;
  app::FitInput in;
  FemModel model;
  SurfaceEmbedding markerMap;
  RegistrationFrame second;
  std::vector<Eigen::Vector2d> outline2;
  std::array<std::size_t, 4> sideAt2{};

  std::mt19937 rng{13};  // the contours' noise and outliers
  std::uniform_real_distribution<double> noise{-2.0, 2.0}, far{15.0, 40.0};

  OrganBench(const Options& o, const OrganSpec& s, const imaging::Camera& c) : opt(o), spec(s), cam(c) {}
  const Mesh& coarse() const { return organ->volume; }

  // The meshes (cached in OUT_DIR), the view, the held region and the loads.
  bool load() {
    t0 = std::chrono::steady_clock::now();
    try {
      const Mesh surface = testing::loadOrganSurface(spec.path, spec.part);
      fine = cachedVolume(surface, 20000, 7, opt.out + "/gt-" + spec.name + "-fine.vtu");
      organ = app::Organ::fromVolume(cachedVolume(surface, 5000, 0, opt.out + "/gt-" + spec.name + "-fit.vtu"), spec.path);
    } catch (const std::exception& e) {
      std::printf("%s: %s; skipped\n", spec.name.c_str(), e.what());
      return false;
    }
    if (fine.tets.size() > 3 * 20000) {
      // (The HuBMAP liver's capsule: its small features force 376,417 tets, which CalculiX cannot hold.)
      std::printf("%s: meshes to %zu tets instead of about 20,000 (its surface's small features); skipped\n", spec.name.c_str(), fine.tets.size());
      return false;
    }
    truth = testing::broadsideView(fine, cam);
    // Held by its back: the 12 % of its surface nodes farthest from the camera (as the diaphragm,
    // ligaments and retroperitoneum hold a liver or a kidney); the fit is given the same region of its own
    // mesh (its surface nodes beyond the same depth).
    heldShare = std::getenv("REHEARSE_BENCH_HELD") ? std::atof(std::getenv("REHEARSE_BENCH_HELD")) : 0.12;
    toolNewton = std::getenv("REHEARSE_BENCH_TOOL_N") ? std::atof(std::getenv("REHEARSE_BENCH_TOOL_N")) : 0.5;
    const double heldDepth = testing::farthestShareDepth(fine, truth, heldShare);
    fineHeld = testing::surfaceNodesBeyond(fine, truth, heldDepth);
    fitHeld = testing::surfaceNodesBeyond(coarse(), truth, heldDepth);
    // Gravity down the image and a little away from the camera; a tool pushing 0.4 N into the front,
    // lower left.
    gCam = 9.81 * Eigen::Vector3d(0.2, 1.0, 0.3).normalized();
    fineSurface = testing::surfaceNodes(fine);
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& p : fine.points) centre += p;
    centre /= static_cast<double>(fine.points.size());
    toolNode = fineSurface.front();
    {
      double best = -1e300;
      const Eigen::Vector3d cc = truth.apply(centre);
      for (int n : fineSurface) {
        const Eigen::Vector3d q = truth.apply(fine.points[n]);
        const double s = -(q.z() - cc.z()) - 0.5 * (q.x() - cc.x()) + 0.3 * (q.y() - cc.y());
        if (s > best) best = s, toolNode = n;
      }
    }
    // The tool: 0.5 N pushing the organ sideways and up (a retractor at its lower left edge), or into the
    // organ along the view (what a silhouette cannot see).
    const bool depthTool = std::getenv("REHEARSE_BENCH_DEPTH_TOOL") != nullptr;
    toolForce = toolNewton * (depthTool ? Eigen::Vector3d(0, 0, 1) : Eigen::Vector3d(Eigen::Vector3d(1, -0.5, 0.3).normalized()));
    gtCache = opt.out + "/gt-" + spec.name + (depthTool ? "-depthtool" : "") + "-" + std::to_string(heldShare) + "-" + std::to_string(toolNewton) + "-u20.txt";
    return true;
  }

  // CalculiX's answer (or the cache's), its deformed surface, outline and render, the markers and the target.
  bool groundTruth() {
    // The loads are scaled so that the largest displacement is about 20 mm (the patient liver sagged
    // 21 mm): the organs differ in shape and size, and a realistic deformation is what is measured. The
    // cache holds the scale, then the displacements.
    if (std::filesystem::exists(gtCache)) {
      std::ifstream cached(gtCache);
      cached >> loadScale;
      u.resize(3 * static_cast<Eigen::Index>(fine.points.size()));
      for (Eigen::Index i = 0; i < u.size(); ++i) cached >> u[i];
      if (!cached) u.resize(0);
    }
    if (u.size() == 0) {
      const CcxMaterial nh{40e3, 0.45, 1060, true};  // liver-like parenchyma, real tissue's density
      auto solve = [&](double scale) {
        return runCalculixStatic(fine, {}, nh, scale * truth.R.transpose() * gCam, true, fineHeld, spec.name,
                                 {{toolNode, scale * truth.R.transpose() * toolForce}});
      };
      auto peakOf = [](const Eigen::VectorXd& v) {
        double p = 0;
        for (Eigen::Index i = 0; i < v.size() / 3; ++i) p = std::max(p, v.segment<3>(3 * i).norm());
        return p;
      };
      u = solve(loadScale = 1);
      if (u.size() == 0) u = solve(loadScale = 0.25);  // too soft to take the whole load in CalculiX's increments
      for (int tries = 0; tries < 4 && u.size() && (peakOf(u) < 0.017 || peakOf(u) > 0.023); ++tries) u = solve(loadScale *= 0.020 / peakOf(u));
      if (u.size() == 0) {
        std::printf("%s: CalculiX failed; skipped\n", spec.name.c_str());
        return false;
      }
      std::ofstream o(gtCache);
      o.precision(17);
      o << loadScale << '\n';
      for (Eigen::Index i = 0; i < u.size(); ++i) o << u[i] << '\n';
    }
    gCam *= loadScale;
    toolForce *= loadScale;
    deformed = fine;
    for (std::size_t i = 0; i < deformed.points.size(); ++i) deformed.points[i] += u.segment<3>(3 * static_cast<Eigen::Index>(i));
    fineTris = boundaryTriangles(fine, false);
    for (const auto& p : deformed.points) defVerts.insert(defVerts.end(), {p.x(), p.y(), p.z()});
    view = SurfaceView{defVerts.data(), deformed.points.size(), fineTris.front().data(), fineTris.size()};
    const auto borders = imaging::maskOutlines(imaging::renderMask(cam, truth, view));
    if (borders.empty()) {
      std::printf("%s: the organ is not in the image; skipped\n", spec.name.c_str());
      return false;
    }
    outline = borders.front();
    // Markers: 40 surface nodes the camera sees (depth test against the render), spread by farthest-point
    // sampling; and an inner target: the node nearest the camera among those at least 10 mm inside.
    ras = imaging::rasterize(cam, truth, view);
    markers = testing::visibleMarkers(fine, deformed.points, truth, cam, 40);
    {
      std::vector<char> onSurface(fine.points.size(), 0);
      for (int n : fineSurface) onSurface[n] = 1;
      double bestZ = 1e300, deepest = 0;
      int deepestNode = -1;
      for (std::size_t i = 0; i < fine.points.size(); ++i) {
        if (onSurface[i]) continue;
        double d = 1e300;
        for (int n : fineSurface) d = std::min(d, (fine.points[i] - fine.points[n]).norm());
        if (d > deepest) deepest = d, deepestNode = static_cast<int>(i);
        if (d < 0.010) continue;
        const double z = truth.apply(deformed.points[i]).z();
        if (z < bestZ) bestZ = z, target = static_cast<int>(i);
      }
      if (target < 0) target = deepestNode;  // a small organ: its deepest point
    }
    return true;
  }

  // The ridge (--ridge): a curve on the fit mesh's visible front and where the truth puts it in the image.
  void makeRidge() {
    const Mesh& coarse = this->coarse();
    auto truthOf = [&](int node) {  // a fit-mesh node where CalculiX's organ has it (camera frame)
      const Eigen::Vector3d& p = coarse.points[static_cast<std::size_t>(node)];
      int nearest = fineSurface.front();
      for (int n : fineSurface)
        if ((fine.points[n] - p).squaredNorm() < (fine.points[nearest] - p).squaredNorm()) nearest = n;
      return truth.apply(p + u.segment<3>(3 * static_cast<Eigen::Index>(nearest)));
    };
    auto seen = [&](const Eigen::Vector3d& q, Eigen::Vector2d& px) {
      px = cam.project(q);
      const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
      if (x < 0 || y < 0 || x >= ras.depth.cols || y >= ras.depth.rows || ras.triangle(y, x) < 0) return false;
      return q.z() <= ras.depth(y, x) + 1e-3;
    };
    auto insideBy = [&](const Eigen::Vector2d& px) {  // distance to the outline (px)
      double d = 1e300;
      for (std::size_t i = 0; i < outline.size(); ++i) {
        const Eigen::Vector2d a = outline[i], b = outline[(i + 1) % outline.size()];
        const double t = std::clamp((px - a).dot(b - a) / std::max(1e-12, (b - a).squaredNorm()), 0.0, 1.0);
        d = std::min(d, (a + t * (b - a) - px).norm());
      }
      return d;
    };
    std::vector<int> front;
    std::vector<Eigen::Vector2d> frontPx;
    std::vector<char> onSurface(coarse.points.size(), 0);
    for (const auto& t : organ->surface)
      for (int v : t) onSurface[static_cast<std::size_t>(v)] = 1;
    for (std::size_t v = 0; v < coarse.points.size(); v += 3) {
      Eigen::Vector2d px;
      if (onSurface[v] && seen(truthOf(static_cast<int>(v)), px) && insideBy(px) > 40)
        front.push_back(static_cast<int>(v)), frontPx.push_back(px);
    }
    std::size_t ia = 0, ib = 0;
    for (std::size_t i = 0; i < front.size(); ++i)
      for (std::size_t j = i + 1; j < front.size(); ++j)
        if ((frontPx[i] - frontPx[j]).squaredNorm() > (frontPx[ia] - frontPx[ib]).squaredNorm()) ia = i, ib = j;
    const std::vector<int> path =
        front.size() > 1 ? surfacePath(organ->surface, coarse.points, front[ia], front[ib]) : std::vector<int>{};
    std::mt19937 ridgeRng(29);
    std::uniform_real_distribution<double> jitter(-2.0, 2.0);
    for (int v : path) {
      Eigen::Vector2d px;
      if (!seen(truthOf(v), px)) continue;  // (hidden stretches of the path are not drawn)
      ridgeSegment.modelVertices.push_back(v);
      ridgeSegment.points.push_back(px + Eigen::Vector2d(jitter(ridgeRng), jitter(ridgeRng)));
    }
    ridgeSegment.type = "ridge";
    std::printf(
        "ridge: %zu of %zu path nodes visible, %.0f px long in the image\n", ridgeSegment.points.size(), path.size(),
        ridgeSegment.points.size() > 1 ? (ridgeSegment.points.front() - ridgeSegment.points.back()).norm() : 0.0);
    // The image curve, densified (the fit binds each node to the nearest point of the drawn curve).
    std::vector<Eigen::Vector2d> dense;
    for (std::size_t i = 0; i + 1 < ridgeSegment.points.size(); ++i)
      for (int k = 0; k < 4; ++k)
        dense.push_back(ridgeSegment.points[i] + k / 4.0 * (ridgeSegment.points[i + 1] - ridgeSegment.points[i]));
    if (!ridgeSegment.points.empty()) dense.push_back(ridgeSegment.points.back());
    ridgeSegment.points = dense;
  }

  // The fit's input and model, the markers embedded in it; the organ's line.
  void setUpFit() {
    for (int v : markers) markerRest.push_back(fine.points[v]), markerTruth.push_back(truth.apply(deformed.points[v]));
    markerRest.push_back(fine.points[target]);
    markerTruth.push_back(truth.apply(deformed.points[target]));
    in.organ = organ;
    in.attachments = opt.attachments ? fitHeld : std::vector<int>{};
    in.materials = app::labelMaterials(app::defaultMaterial(*organ));
    in.camera = cam.pinhole();
    // The fit told the true gravity (the OR knows which way is down in the camera's frame), as a variant.
    if (std::getenv("REHEARSE_BENCH_FIT_GRAVITY")) in.settings.gravity = truth.R.transpose() * gCam;
    // Or told only which way is down (gravity in the camera frame, as the fit page's Down list gives it).
    if (std::getenv("REHEARSE_BENCH_TOLD_DOWN")) in.gravityCamera = gCam;
    model = app::fitModel(in);
    markerMap = embedPoints(model, markerRest);
    double sag = 0;
    for (Eigen::Index i = 0; i < u.size() / 3; ++i) sag = std::max(sag, u.segment<3>(3 * i).norm());
    const Error atTruth = markerError(model.restVector(), truth);
    std::printf("\n== %s: fine %zu tets (CalculiX), fit %zu tets, %zu/%zu held; loads x%.2f, largest displacement %.1f mm; outline %zu px; "
                "%zu markers + target %.0f mm deep; undeformed at the true pose %.2f mm (along the view %.2f, target %.2f); set-up %.0f s\n",
                spec.name.c_str(), fine.tets.size(), coarse().tets.size(), fineHeld.size(), fitHeld.size(), loadScale, 1e3 * sag, outline.size(), markers.size(),
                1e3 * truth.apply(deformed.points[target]).z() - 1e3 * ras.depth(static_cast<int>(cam.project(truth.apply(deformed.points[target])).y()),
                                                                                   static_cast<int>(cam.project(truth.apply(deformed.points[target])).x())),
                atTruth.surface, atTruth.depth, atTruth.target, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }

  // The markers' error (mm) of a fit in the camera frame: the surface's mean, worst, along the view; the target.
  Error markerError(const Eigen::VectorXd& x, const Pose& pose) const {
    const auto pts = mapEmbedded(markerMap, x);
    Error e;
    for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
      const double d = 1e3 * (pose.apply(pts[i]) - markerTruth[i]).norm();
      e.surface += d;
      e.depth += 1e3 * std::abs((pose.apply(pts[i]) - markerTruth[i]).z());
      e.worst = std::max(e.worst, d);
    }
    e.surface /= static_cast<double>(pts.size() - 1);
    e.depth /= static_cast<double>(pts.size() - 1);
    e.target = 1e3 * (pose.apply(pts.back()) - markerTruth.back()).norm();
    e.worst = std::max(e.worst, e.target);
    return e;
  }

  // REHEARSE_BENCH_DIAG: what each stage does from the true pose with the whole outline, without noise.
  void diagnose() const {
    const Mesh& coarse = this->coarse();
    imaging::Contour clean;
    clean.width = cam.width;
    clean.height = cam.height;
    clean.segments.push_back({outline, true});
    struct Variant {
      const char* name;
      bool rigid, elastic, held, gravity;
    };
    {
      // The fit model itself simulating the true loads (gravity, the tool at its nearest surface node),
      // held as the fit holds it: how near the model alone can come (no contour).
      SimulationSettings st;
      st.gravity = truth.R.transpose() * gCam;
      Integrator sim(model, in.attachments, st);
      auto state = sim.initialState();
      Eigen::VectorXd f = Eigen::VectorXd::Zero(state.x.size());
      int near = 0;
      for (std::size_t i = 0; i < coarse.points.size(); ++i)
        if ((coarse.points[i] - fine.points[toolNode]).norm() < (coarse.points[near] - fine.points[toolNode]).norm()) near = static_cast<int>(i);
      f.segment<3>(3 * near) = truth.R.transpose() * toolForce;
      const auto rep = sim.solveStatic(state, f);
      const Error e = markerError(state.x, truth);
      std::printf("DIAG fit model under the true loads at the true pose %6.2f mm (along the view %5.2f, target %5.2f); %s\n", e.surface, e.depth,
                  e.target, rep.status.c_str());
    }
    for (const Variant& v : {Variant{"rigid only", true, false, true, false}, Variant{"elastic only", false, true, true, false},
                             Variant{"rigid + elastic", true, true, true, false}, Variant{"elastic only, gravity", false, true, true, true},
                             Variant{"elastic only, not held", false, true, false, false}, Variant{"rigid + elastic, not held", true, true, false, false}}) {
      app::FitInput d = in;
      d.contour = clean;
      d.start = truth;
      d.rigidPrepass = v.rigid;
      d.elastic = v.elastic;
      if (!v.held) d.attachments.clear();
      d.settings.gravity = v.gravity ? Eigen::Vector3d(truth.R.transpose() * gCam) : Eigen::Vector3d::Zero();
      const auto r = app::runElasticFit(d);
      const Error e = markerError(r.x, r.pose);
      const Eigen::Vector3d dc = r.pose.apply(organ->centreOfGravity) - truth.apply(organ->centreOfGravity);
      std::printf("DIAG from the truth, %-28s %6.2f mm (along the view %5.2f, target %5.2f); centre moved %.1f %.1f %.1f mm, turned %.2f deg; %s\n", v.name,
                  e.surface, e.depth, e.target, 1e3 * dc.x(), 1e3 * dc.y(), 1e3 * dc.z(),
                  Eigen::AngleAxisd(r.pose.R * truth.R.transpose()).angle() * 180 / M_PI, r.status.c_str());
    }
  }

  // The second frame (--second-frame): its camera, outline and tracked features (the motion estimated from them with
  // --estimate-motion).
  bool makeSecondFrame() {
    const Eigen::Vector3d centre = truth.apply(organ->centreOfGravity), eye(1e-3 * opt.secondFrameMm, 0, 0);
    const Eigen::Vector3d z = (centre - eye).normalized(), x = Eigen::Vector3d::UnitY().cross(z).normalized();
    second.camera = cam.pinhole();
    second.motion.R.row(0) = x.transpose();
    second.motion.R.row(1) = z.cross(x).transpose();
    second.motion.R.row(2) = z.transpose();
    second.motion.t = -second.motion.R * eye;
    Pose seen;
    seen.R = second.motion.R * truth.R;
    seen.t = second.motion.R * truth.t + second.motion.t;
    const auto borders2 = imaging::maskOutlines(imaging::renderMask(cam, seen, view));
    if (borders2.empty()) {
      std::printf("%s: the organ is not in the second frame; skipped\n", spec.name.c_str());
      return false;
    }
    outline2 = borders2.front();
    sideAt2 = sidesOf(outline2);
    second.tracks = testing::trackedFeatures(view, truth, second.motion, cam, 200, 0.5, 5);
    if (opt.estimateMotion && !estimateSecondMotion()) return false;
    std::printf("second frame %.0f mm across: outline %zu px, %zu features tracked\n", opt.secondFrameMm, outline2.size(),
                second.tracks.size());
    return true;
  }

  // --estimate-motion: the second frame's motion estimated from its tracks, compared with the true one.
  bool estimateSecondMotion() {
    std::vector<imaging::Track> tracks(second.tracks.begin(), second.tracks.end());
    const imaging::CameraMotion m = imaging::estimateCameraMotion(cam, tracks, second.motion.t.norm());
    std::printf(
        "estimated motion: %s; turn off by %.3f degrees, the move's direction by %.2f degrees\n", m.status.c_str(),
        Eigen::AngleAxisd(m.motion.R * second.motion.R.transpose()).angle() * 180 / M_PI,
        std::acos(std::clamp(m.motion.t.normalized().dot(second.motion.t.normalized()), -1.0, 1.0)) * 180 / M_PI);
    {  // how well each motion explains the tracks (RMS Sampson distance): the estimate should be the better
      auto rms = [&](const Pose& M) {
        const Eigen::Vector3d t = M.t.normalized();
        Eigen::Matrix3d tx;
        tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
        const Eigen::Matrix3d E = tx * M.R, Ki = cam.pinhole().K.inverse();
        double s2 = 0;
        for (const auto& [p, q] : tracks) {
          const Eigen::Vector3d a = Ki * p.homogeneous(), b = Ki * q.homogeneous();
          const Eigen::Vector3d Ea = E * a, Eb = E.transpose() * b;
          const double r = cam.pinhole().K(0, 0) * b.dot(Ea) /
                           std::sqrt(Ea.head<2>().squaredNorm() + Eb.head<2>().squaredNorm());
          s2 += r * r;
        }
        return std::sqrt(s2 / tracks.size());
      };
      std::printf("the tracks' RMS Sampson distance: %.4f px to the true motion, %.4f px to the estimate\n",
                  rms(second.motion), rms(m.motion));
    }
    if (!m.ok) {
      std::printf("%s: the motion could not be estimated; skipped\n", spec.name.c_str());
      return false;
    }
    second.motion = m.motion;
    second.motionDepthSigmaM = m.depthSigmaM;
    second.motionAtOneSigma = m.motionAtOneSigma;
    second.tracks = m.inliers;
    return true;
  }

  // The share kept of an outline, the missing arc centred on the side, with noise and outliers.
  imaging::ContourSegment cut(const std::vector<Eigen::Vector2d>& line, std::size_t sidePoint, double fraction) {
    imaging::ContourSegment seg;
    const std::size_t n = line.size(), drop = static_cast<std::size_t>((1 - fraction) * static_cast<double>(n));
    const std::size_t first = (sidePoint + drop / 2 + 1) % n;  // just past the missing arc
    for (std::size_t k = 0; k < n - drop; ++k) seg.points.push_back(line[(first + k) % n]);
    seg.closed = drop == 0;
    for (auto& p : seg.points) p += Eigen::Vector2d(noise(rng), noise(rng));
    const std::size_t outliers = std::max<std::size_t>(3, seg.points.size() / 100);
    for (std::size_t k = 0; k < outliers; ++k) {
      auto& p = seg.points[(k * 7919 + 31) % seg.points.size()];
      const double angle = 2 * M_PI * (noise(rng) + 2) / 4;
      p += far(rng) * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    }
    return seg;
  }

  // Contours: the outline kept at each share, the missing arc centred on the top, right, bottom or left
  // of the organ; +-2 px noise; 1 % of the points (at least 3) thrown 15-40 px off. Each fitted from every start.
  void runFits(Cells& cells, std::ofstream& csv) {
    std::vector<double> fractions = opt.quick ? std::vector<double>{1.0, 0.7} : std::vector<double>{1.0, 0.9, 0.8, 0.7, 0.6, 0.5};
    if (!opt.fractionsAsked.empty()) fractions = opt.fractionsAsked;
    const auto sideAt = sidesOf(outline);
    const std::vector<Start> starts = startsFor(opt.quick);
    std::vector<PlotSeries> series;
    std::printf("%-26s %5s %-6s %9s %9s %7s %9s %8s %7s %4s  %s\n", "start", "kept", "side", "start mm", "end mm", "(z)", "target", "end px", "ms", "exit", "status");
    for (double fraction : fractions) {
      for (int side = 0; side < (fraction < 1 ? 4 : 1); ++side) {
        imaging::Contour contour;
        contour.width = cam.width;
        contour.height = cam.height;
        contour.segments.push_back(cut(outline, sideAt[side], fraction));
        in.frames.clear();
        if (opt.secondFrameMm > 0) {
          second.contour = {cut(outline2, sideAt2[side], fraction).points};
          in.frames = {second};
        }
        if (opt.ridge && ridgeSegment.modelVertices.size() >= 2) contour.segments.push_back(ridgeSegment);
        for (const auto& s : starts) {
          in.contour = contour;
          in.start = perturb(truth, s.move, s.turn, organ->centreOfGravity);
          const PlotSeries ps = runStart(s, fraction, side, cells[{spec.name, fraction}], csv);
          if (fraction == 1.0) series.push_back(ps);
        }
      }
    }
    writeLogLogPlot(opt.out + "/registration-real-" + spec.name + ".png", spec.name + ", 100 % contour: marker error against wall time per start",
                    "wall time (ms)", "mean surface marker error (mm)", series);
  }

  // One fit (in, from its start): its line and CSV row, counted in its cell; returns its error against time.
  PlotSeries runStart(const Start& s, double fraction, int side, Cell& cell, std::ofstream& csv) {
    PlotSeries ps;
    ps.name = s.name;
    RegistrationResult r;
    double rigidError = -1;
    const auto fitStart = std::chrono::steady_clock::now();
    static const bool trace = std::getenv("REHEARSE_BENCH_TRACE") != nullptr;  // each iteration's stage and time
    try {
      r = app::runElasticFit(in, [&](const RegistrationIteration& it, const Eigen::VectorXd& x, const Pose& pose) {
        if (it.stage != "elastic") rigidError = markerError(x, pose).surface;  // the last before the elastic stage
        if (trace)
          std::fprintf(stderr, "  %-8s %3d %8.1f ms %6.2f px\n", it.stage.c_str(), it.iteration, it.wallMs,
                       it.score());
        if (fraction == 1.0) {
          ps.x.push_back(std::max(it.wallMs, 1.0));
          ps.y.push_back(markerError(x, pose).surface);
        }
        return true;
      });
    } catch (const std::exception& e) {
      r.status = std::string("error: ") + e.what();
    }
    const Error e0 = markerError(model.restVector(), in.start);
    const Error e1 = r.x.size() ? markerError(r.x, r.pose) : e0;
    // The whole call (a failed elastic solve's time is in no iteration's record).
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - fitStart).count();
    const double px = r.iterations.empty() ? 0 : r.iterations.back().score();
    const int code = exitCode(r);
    cell.err.push_back(e1.surface);
    cell.rigid.push_back(rigidError);
    cell.target.push_back(e1.target);
    cell.ms.push_back(ms);
    if (e1.surface > 5) {
      ++cell.wrong;
      cell.silentWrong += code == 0;
    }
    if (e1.surface < 3) {
      ++cell.good;
      cell.flaggedGood += code != 0;
    }
    cell.failed += code == 3;
    const auto& un = r.uncertainty;
    if (un.computed) {
      ++cell.bounded;
      cell.covered += e1.surface <= un.surfaceMm;
      cell.tight += un.surfaceMm <= 3 * e1.surface;
      cell.targetCovered += e1.target <= un.targetMm;
    }
    cell.ambiguous += code == 4;
    std::printf(
        "%-26s %4.0f%% %-6s %9.2f %9.2f %7.2f %9.2f %8.2f %7.0f %4d  bound %.2f (target %.2f; curvature %.2f, "
        "spread %.2f, misfit %.2f px, rho %.2f, weakest %s)  %s\n",
        s.name.c_str(), 100 * fraction, fraction < 1 ? sideNames[side] : "-", e0.surface, e1.surface, e1.depth,
        e1.target, px, ms, code, un.surfaceMm, un.targetMm, un.curvatureMm, un.spreadMm, un.misfitPx,
        un.correlation, un.weakest.c_str(), r.status.c_str());
    std::fflush(stdout);
    csv << spec.name << "," << fraction << "," << (fraction < 1 ? sideNames[side] : "-") << ",\"" << s.name
        << "\"," << e0.surface << "," << rigidError << "," << e1.surface << "," << e1.target << "," << e1.worst
        << "," << (r.iterations.empty() ? 0 : r.iterations.front().score()) << "," << px << "," << ms << ","
        << code << "," << r.sagShare << "," << r.sagApartMm << "," << un.surfaceMm << "," << un.targetMm << ","
        << un.curvatureMm << "," << un.spreadMm << "," << un.misfitPx << "," << un.correlation << ","
        << un.autocorrelationTime << ",\"" << un.weakest << "\",\"" << r.status << "\"\n";
    return ps;
  }
};

void printSummary(const Cells& cells) {
  std::printf("\nsummary: surface marker error (mm) per organ and contour share (rigid mean: after the rigid stage); wrong = mean marker error > 5 mm; silent = wrong "
              "and exit 0; alarms = fits under 3 mm flagged ambiguous or failed\n");
  std::printf("%-18s %5s %5s %7s %7s %7s %6s %10s %13s %8s %8s %11s %11s %5s %5s %9s %7s %9s\n", "organ", "kept",
              "fits", "mean", "median", "worst", ">5mm", "rigid mean", "target med/max", "med ms", "worst ms", "silent",
              "alarms", "amb", "fail", "covered", "tight", "target cov");
  for (const auto& [key, c] : cells) {
    const double mean = std::accumulate(c.err.begin(), c.err.end(), 0.0) / static_cast<double>(c.err.size());
    const auto over = std::count_if(c.err.begin(), c.err.end(), [](double e) { return e > 5; });
    std::printf(
        "%-18s %4.0f%% %5zu %7.2f %7.2f %7.2f %5.0f%% %10.2f %6.2f/%6.2f %8.0f %8.0f %5d of %3d %5d of %3d %5d %5d "
        "%8.0f%% %6.0f%% %8.0f%%\n",
        key.first.c_str(), 100 * key.second, c.err.size(), mean, median(c.err),
        *std::max_element(c.err.begin(), c.err.end()), 100.0 * over / c.err.size(),
        std::accumulate(c.rigid.begin(), c.rigid.end(), 0.0) / static_cast<double>(c.rigid.size()), median(c.target),
        *std::max_element(c.target.begin(), c.target.end()), median(c.ms), *std::max_element(c.ms.begin(), c.ms.end()),
        c.silentWrong, c.wrong, c.flaggedGood, c.good, c.ambiguous, c.failed,
        c.bounded ? 100.0 * c.covered / c.bounded : 0.0, c.bounded ? 100.0 * c.tight / c.bounded : 0.0,
        c.bounded ? 100.0 * c.targetCovered / c.bounded : 0.0);
  }
}

}  // namespace

int main(int argc, char** argv) {
  QCoreApplication app(argc, argv);  // QProcess (ccx) needs an event loop's thread data
  const Options opt = parseOptions(argc, argv);
  std::filesystem::create_directories(opt.out);
  const std::string data = REHEARSE_SHARED_DATA;
  std::vector<OrganSpec> organs{{"patient-liver", data + "/scikit-surgery/patient-liver/liver.vtk"},
                                {"bodyparts3d-liver", data + "/bodyparts3d/FMA7197_Liver.obj"},
                                {"hubmap-liver", data + "/hubmap/VH_M_Liver.glb", "VH_M_liver_capsule"},
                                {"kidney", data + "/scikit-surgery/kidney/kidney.vtk"}};
  if (!opt.only.empty()) organs.erase(std::remove_if(organs.begin(), organs.end(), [&](const OrganSpec& o) { return o.name != opt.only; }), organs.end());
  // The scikit-surgery laparoscope (its calibration of the 1920x1080 frame in ../shared/data).
  const imaging::Camera cam = testing::scikitSurgeryCamera();

  std::ofstream csv(opt.out + "/registration-real.csv");
  csv << "organ,fraction,side,start,start_error_mm,rigid_stage_error_mm,surface_error_mm,target_error_mm,worst_marker_"
         "mm,start_px,end_px,wall_ms,exit,sag_share,sag_apart_mm,bound_mm,target_bound_mm,curvature_mm,spread_mm,"
         "misfit_px,correlation,autocorrelation_time,weakest,status\n";
  Cells cells;
  for (const auto& spec : organs) {
    if (!std::filesystem::exists(spec.path)) {
      std::printf("%s: %s is absent; skipped\n", spec.name.c_str(), spec.path.c_str());
      continue;
    }
    OrganBench b(opt, spec, cam);
    if (!b.load() || !b.groundTruth()) continue;
    if (opt.ridge) b.makeRidge();
    b.setUpFit();
    if (std::getenv("REHEARSE_BENCH_DIAG")) b.diagnose();
    if (opt.secondFrameMm > 0 && !b.makeSecondFrame()) continue;
    b.runFits(cells, csv);
  }
  printSummary(cells);
  std::printf("wrote %s/registration-real.csv and registration-real-<organ>.png\n", opt.out.c_str());
  return 0;
}
