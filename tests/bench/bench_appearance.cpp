// Benchmark of the appearance step (issue 14): the built-in phantom generated at 1920x1080 (its frame
// rendered with a known light and reflectance, then sensor noise and JPEG at quality 85), Theta fitted
// from it at several sample budgets; parameter errors against the fit's time, and the whole step (fit,
// inpainting, albedo, the rest-pose composition) against the 2 s target. Median of repeated runs. Not a test.
//   bench_appearance [OUT_DIR] [--repeat N] [--compose-only]
// --compose-only: the viewport's compositions alone (compose.csv), the fits' sweeps and the turn search skipped.
#include "phantom/phantom.hpp"
#include "realorgan.hpp"
#include "traced_outline.hpp"

#include <rehearse/app/appearancestep.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/session/session.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

using namespace rehearse;

namespace {
// Issue 62: step 6's search of the turn an outline leaves open, on a frame rendered at `truth`: the organ registered
// turned off it about the camera's X (and Y) axis through its centre, the outline of the organ the frame shows traced in
// two pieces wavering 2 px; the whole step with the search (app::runAppearance). One CSV row and one line per turn.
void turnRows(std::ofstream& csv, const std::string& name, const imaging::Camera& cam, const Pose& truth, const SurfaceView& sv,
              const cv::Mat3b& frame, int repeat) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < sv.vertexCount; ++i)
    centre += truth.apply(Eigen::Vector3d(sv.vertices[3 * i], sv.vertices[3 * i + 1], sv.vertices[3 * i + 2]));
  centre /= static_cast<double>(sv.vertexCount);
  const imaging::Contour contour = handTracedOutline(cam, truth, sv);
  if (contour.empty()) return;
  for (const auto& [ax, ay] : std::vector<std::pair<double, double>>{{5, 0}, {-8, 3}, {0, 0}}) {
    app::AppearanceInput in;
    in.camera = cam;
    in.frame = frame;
    in.vertices.assign(sv.vertices, sv.vertices + 3 * sv.vertexCount);
    for (std::size_t t = 0; t < sv.triangleCount; ++t)
      in.triangles.push_back({sv.triangles[3 * t], sv.triangles[3 * t + 1], sv.triangles[3 * t + 2]});
    in.contour = contour;
    in.pose = truth.turnedAbout((Eigen::AngleAxisd(ax * M_PI / 180, Eigen::Vector3d::UnitX()) *
                                 Eigen::AngleAxisd(ay * M_PI / 180, Eigen::Vector3d::UnitY()))
                                    .toRotationMatrix(),
                                centre);
    std::vector<double> searchMs, totalMs;
    app::AppearanceOutput r;
    for (int k = 0; k < repeat; ++k) {
      r = app::runAppearance(in);
      searchMs.push_back(r.turn.ms);
      totalMs.push_back(r.totalMs);
    }
    std::sort(searchMs.begin(), searchMs.end());
    std::sort(totalMs.begin(), totalMs.end());
    auto offDeg = [&](const Pose& p) { return Eigen::AngleAxisd(p.R * truth.R.transpose()).angle() * 180 / M_PI; };
    std::printf("%-18s turned (%+.0f, %+.0f) deg: explains %5.1f %% -> %5.1f %%, %4.1f -> %4.1f deg off, %s, %d turns, "
                "search %.0f ms, whole step %.0f ms\n",
                name.c_str(), ax, ay, 100 * r.turn.explainedBefore, 100 * r.fit.explained, offDeg(in.pose),
                offDeg(r.turn.pose), r.turn.adopted ? "turned" : "left", r.turn.candidates, searchMs[searchMs.size() / 2],
                totalMs[totalMs.size() / 2]);
    csv << name << "," << ax << "," << ay << "," << r.turn.explainedBefore << "," << r.fit.explained << ","
        << offDeg(in.pose) << "," << offDeg(r.turn.pose) << "," << r.turn.adopted << "," << r.turn.candidates << ","
        << searchMs[searchMs.size() / 2] << "," << totalMs[totalMs.size() / 2] << "\n";
  }
}

// One setting of the fit: its time (median), worst parameter error (%) and the model's PSNR.
struct Point {
  std::string setting;
  double ms, error, db;
  bool resolution;
};

// The benchmark, phase by phase: the phantom's frame, the fit's sweep of sample budgets and resolutions and its
// plot, the whole step, the viewport's composition (the phantom, after a grasp-pull-cut, the real organs).
struct AppearanceBench {
  std::string out = ".";
  int repeat = 3;
  bool composeOnly = false;  ///< --compose-only
  phantom::Phantom c;
  cv::Mat3b frame;
  double distance = 0;
  imaging::SurfaceGeometry g;
  cv::RNG rng{14};
  std::ofstream csv, tcsv, ccsv;
  cv::Mat1b inner;
  std::vector<Point> points;

  // The phantom at 1920x1080, its frame with sensor noise and JPEG at quality 85; the CSV and the table's head.
  void makeFrame() {
    phantom::PhantomOptions po;
    po.width = 1920;
    po.height = 1080;
    c = phantom::makePhantom(po);
    cv::Mat noise(c.frame.size(), CV_32FC3), f;
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 2.0);
    c.frame.convertTo(f, CV_32FC3);
    f += noise;
    cv::Mat3b noisy;
    f.convertTo(noisy, CV_8UC3);
    std::vector<uchar> buf;
    cv::imencode(".jpg", noisy, buf, {cv::IMWRITE_JPEG_QUALITY, 85});
    frame = cv::imdecode(buf, cv::IMREAD_COLOR);
    const auto& t = c.trueAppearance;
    distance = (t.lightPosition - c.truePose.apply(phantom::centreOfGravity(c.volume))).norm();
    g = imaging::surfaceGeometry(c.camera, c.truePose, c.surfaceView());
    csv.open(out + "/appearance.csv");
    csv << "setting,samples,scale,fit_ms_median,light_error_pct_of_distance,kd_error_pct_max,ks_error_pct_max_measured,roughness_error_pct,model_psnr_db\n";
    std::printf("phantom at %dx%d, %zu tets; light %.0f mm from the organ\n", c.camera.width, c.camera.height, c.volume.tets.size(), 1e3 * distance);
    std::printf("%-22s %9s %9s %8s %8s %9s %11s\n", "setting", "fit ms", "light %", "kd %", "ks %", "sigma %", "model dB");
    // What Theta alone reproduces (albedo 1, no texture): the model rendered with it against the frame inside
    // the organ, at full resolution. The rest-pose composition would hide Theta's errors in the albedo.
    cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  }

  // Theta fitted with `samples` pixels per stage from the frame scaled by `scale`: one line, one row, one point.
  void sweep(const std::string& setting, std::size_t samples, double scale) {
    const auto& t = c.trueAppearance;
    imaging::Camera cam = c.camera;  // the frame and camera scaled (pixel centres kept)
    cv::Mat3b img = frame;
    if (scale != 1.0) {
      cam.K(0, 0) *= scale, cam.K(0, 1) *= scale, cam.K(1, 1) *= scale;
      cam.K(0, 2) = scale * (cam.K(0, 2) + 0.5) - 0.5;
      cam.K(1, 2) = scale * (cam.K(1, 2) + 0.5) - 0.5;
      cam.width = static_cast<int>(std::lround(cam.width * scale));
      cam.height = static_cast<int>(std::lround(cam.height * scale));
      cv::resize(frame, img, cv::Size(cam.width, cam.height), 0, 0, cv::INTER_AREA);
    }
    std::vector<double> ms;
    imaging::AppearanceFitResult r;
    for (int k = 0; k < repeat; ++k) {
      imaging::AppearanceFitOptions o;
      o.maxSamples = samples;
      const auto t0 = std::chrono::steady_clock::now();
      const auto geo = scale == 1.0 ? g : imaging::surfaceGeometry(cam, c.truePose, c.surfaceView());
      r = imaging::fitAppearance(img, geo, o);
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(ms.begin(), ms.end());
    double kd = 0, ks = 0;
    for (int ch = 0; ch < 3; ++ch) {
      kd = std::max(kd, 100 * std::abs(r.theta.kd[ch] - t.kd[ch]) / t.kd[ch]);
      if (r.ksMeasured[static_cast<std::size_t>(ch)]) ks = std::max(ks, 100 * std::abs(r.theta.ks[ch] - t.ks[ch]) / t.ks[ch]);
    }
    const double light = 100 * (r.theta.lightPosition - t.lightPosition).norm() / distance;
    const double sigma = 100 * std::abs(r.theta.roughness - t.roughness) / t.roughness;
    const double db = imaging::psnr(frame, imaging::renderShaded(c.camera, c.truePose, c.surfaceView(), r.theta, frame, 1), inner);
    std::printf("%-22s %9.0f %9.3f %8.2f %8.2f %9.2f %11.1f\n", setting.c_str(), ms[ms.size() / 2], light, kd, ks, sigma, db);
    csv << setting << "," << samples << "," << scale << "," << ms[ms.size() / 2] << "," << light << "," << kd << "," << ks << "," << sigma << "," << db << "\n";
    points.push_back({setting, ms[ms.size() / 2], std::max({light, kd, ks, sigma}), db, scale != 1.0});
  }

  // The plot: worst parameter error (%) and the model's PSNR against the fit's time, one point per setting.
  void plot() const {
    const int W = 900, H = 440, left = 70, right = 40, top = 40, bottom = 70;
    cv::Mat3b plot(H, W, cv::Vec3b(255, 255, 255));
    double tMax = 0, eMax = 0;
    for (const auto& q : points) tMax = std::max(tMax, q.ms), eMax = std::max(eMax, q.error);
    tMax *= 1.1;
    eMax = std::max(1.0, std::ceil(eMax * 1.2));
    const int pw = (W - left - right) / 2 - 30;
    for (int panel = 0; panel < 2; ++panel) {
      const int x0 = left + panel * (pw + 60), x1 = x0 + pw, y0 = top, y1 = H - bottom;
      const double lo = panel == 0 ? 0 : 30, hi = panel == 0 ? eMax : 60;
      cv::rectangle(plot, {x0, y0}, {x1, y1}, cv::Scalar(0, 0, 0));
      cv::putText(plot, panel == 0 ? "worst parameter error (%)" : "model PSNR inside the organ (dB)", {x0, y0 - 12}, cv::FONT_HERSHEY_SIMPLEX, 0.5,
                  cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      cv::putText(plot, "fit time (ms)", {x0 + pw / 2 - 50, H - 15}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      for (int i = 0; i <= 4; ++i) {
        const int yy = y1 - (y1 - y0) * i / 4, xx = x0 + (x1 - x0) * i / 4;
        cv::putText(plot, cv::format("%.3g", lo + (hi - lo) * i / 4), {x0 - 45, yy + 4}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
        cv::putText(plot, cv::format("%.0f", tMax * i / 4), {xx - 12, y1 + 18}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      }
      for (const auto& q : points) {
        const double v = panel == 0 ? q.error : q.db;
        const cv::Point at(x0 + static_cast<int>((x1 - x0) * q.ms / tMax), y1 - static_cast<int>((y1 - y0) * std::clamp((v - lo) / (hi - lo), 0.0, 1.0)));
        const cv::Scalar colour = q.resolution ? cv::Scalar(40, 40, 220) : cv::Scalar(200, 90, 20);
        cv::circle(plot, at, 4, colour, cv::FILLED, cv::LINE_AA);
        if (panel == 0) cv::putText(plot, q.setting, at + cv::Point(6, -4), cv::FONT_HERSHEY_SIMPLEX, 0.33, colour, 1, cv::LINE_AA);
      }
    }
    cv::putText(plot, "blue: pixels per stage at 1920x1080; red: 10,000 px at a lower resolution", {left, H - 35 + 30}, cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    cv::imwrite(out + "/appearance-error-vs-time.png", plot);
  }

  // The whole step as the GUI and `rehearse appearance` run it.
  void wholeStep() const {
    app::AppearanceInput in;
    in.camera = c.camera;
    in.pose = c.truePose;
    const SurfaceView v = c.surfaceView();
    in.vertices.assign(v.vertices, v.vertices + 3 * v.vertexCount);
    in.triangles = c.surface;
    in.frame = frame;
    std::vector<double> total, inpaint;
    app::AppearanceOutput o;
    for (int k = 0; k < repeat; ++k) {
      o = app::runAppearance(in);
      total.push_back(o.totalMs);
      inpaint.push_back(o.inpaintMs);
    }
    std::sort(total.begin(), total.end());
    std::sort(inpaint.begin(), inpaint.end());
    std::printf("whole step at 1920x1080: %.0f ms median (inpainting %.0f ms); composed at rest %.1f dB inside the organ; %s\n", total[total.size() / 2],
                inpaint[inpaint.size() / 2], o.restPsnr, o.fit.status.c_str());
  }

  // `carried`: the surface is the organ's own, carried by a simulation mesh's tetrahedra (app::VisualSurface):
  // the bend moves the mesh's nodes, and each frame maps them onto the surface before composing (timed with it).
  void viewport(const std::string& name, const imaging::Camera& cam720, const Pose& pose, const SurfaceView& sv,
                const cv::Mat3b& frame720, const imaging::Appearance& theta, const app::Organ* carried = nullptr) {
    imaging::CompositionInput ci;
    ci.camera = cam720;
    ci.pose = pose;
    ci.rest = ci.deformed = sv;
    ci.frame = frame720;
    const auto geo = imaging::surfaceGeometry(cam720, pose, sv);
    ci.background = imaging::inpaintRegion(frame720, geo.mask());
    ci.albedo = cv::Mat3f(frame720.size(), cv::Vec3f(1, 1, 1));
    ci.theta = theta;
    const imaging::Compositor compositor(ci);
    double lo = 1e30, hi = -1e30;
    for (std::size_t i = 0; i < sv.vertexCount; ++i)
      lo = std::min(lo, sv.vertex(i).x()), hi = std::max(hi, sv.vertex(i).x());
    std::vector<double> moved(sv.vertices, sv.vertices + 3 * sv.vertexCount);
    for (std::size_t i = 0; i < sv.vertexCount; ++i) {
      const double u = (moved[3 * i] - lo) / std::max(hi - lo, 1e-9);
      moved[3 * i + 1] += 0.003 + 0.01 * u * u;
    }
    std::vector<Eigen::Vector3d> nodes;  // the simulation mesh's nodes, bent the same way
    if (carried) {
      nodes = carried->volume.points;
      for (auto& x : nodes) x.y() += 0.003 + 0.01 * std::pow((x.x() - lo) / std::max(hi - lo, 1e-9), 2);
    }
    const int covered = cv::countNonZero(geo.mask());
    double mapped = 0;  // how far the carried surface is from the bent one (mm): the bend is not affine
    for (int rim : {1, 2, 4}) {
      std::vector<double> cms;
      for (int k = 0; k < std::max(repeat, 15); ++k) {
        const auto t0 = std::chrono::steady_clock::now();
        if (carried) {
          const std::vector<Eigen::Vector3d> surface = carried->visual->map(nodes);
          for (std::size_t i = 0; i < surface.size(); ++i)
            moved[3 * i] = surface[i].x(), moved[3 * i + 1] = surface[i].y(), moved[3 * i + 2] = surface[i].z();
        }
        const cv::Mat3b j = compositor.compose(moved, rim);
        cms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      }
      if (carried)
        for (std::size_t i = 0; i < sv.vertexCount; ++i) {
          const double u = (sv.vertex(i).x() - lo) / std::max(hi - lo, 1e-9);
          mapped = std::max(mapped, 1e3 * std::abs(moved[3 * i + 1] - (sv.vertex(i).y() + 0.003 + 0.01 * u * u)));
        }
      std::sort(cms.begin(), cms.end());
      const std::string what = carried ? std::to_string(carried->volume.tets.size()) +
                                             " tetrahedra carrying it (mapped within " +
                                             std::to_string(mapped).substr(0, 5) + " mm of the bend)"
                                       : std::string("moved directly");
      std::printf("viewport compose, %s, %zu triangles, %s, %dx%d, %d px of organ, rim %dx%d: %.1f ms median\n",
                  name.c_str(), sv.triangleCount, what.c_str(), cam720.width, cam720.height, covered, rim, rim,
                  cms[cms.size() / 2]);
      ccsv << name << "," << sv.triangleCount << "," << (carried ? carried->volume.tets.size() : 0) << ","
           << cam720.width << "," << cam720.height << "," << rim * rim << "," << covered << "," << cms[cms.size() / 2]
           << "\n";
    }
  }

  // The built-in case's organ simulated headless as step 7 drives it (the jaws close on a surface node of its lower
  // part and pull it 15 % of its height down in the image; the scissors, the jaws holding, cut across the stretched
  // tissue above them, the blade 20 mm behind the surface): its last snapshot.
  static std::shared_ptr<const simcore::Snapshot> graspPullCut(const app::Case& c) {
    simcore::BodySetup b;
    b.mesh = c.organ->volume;
    b.mesh.convertToMetres();
    const auto& shape = c.shapeNodes();
    for (const auto& x : shape) b.rest.push_back(c.pose.apply(x));  // the camera frame, as the GUI's session
    b.fixedNodes = c.attachments;
    b.material = {simcore::MaterialModel::Corotational, 27e3, 0.4, 1079};
    b.settings.timeStep = 0.01;
    b.settings.method = simcore::kInteractiveMethod;
    b.tools.cutLatencySteps = 0;
    double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
    for (const auto& p : b.rest) {
      const Eigen::Vector2d q = c.camera.project(p);
      x0 = std::min(x0, q.x()), x1 = std::max(x1, q.x()), y0 = std::min(y0, q.y()), y1 = std::max(y1, q.y());
    }
    std::vector<double> posed;
    for (const auto& p : b.rest) posed.insert(posed.end(), {p.x(), p.y(), p.z()});
    const SurfaceView posedView{posed.data(), b.rest.size(), c.organ->surface.front().data(), c.organ->surface.size()};
    const auto geo = imaging::surfaceGeometry(c.camera, Pose{}, posedView);
    const auto surfaceAt = [&](double fx, double fy) {  // the organ's surface under a point of its box in the image
      const int u = static_cast<int>(std::lround(x0 + fx * (x1 - x0))),
                v = static_cast<int>(std::lround(y0 + fy * (y1 - y0)));
      const cv::Vec3f p = geo.position(v, u);
      return Eigen::Vector3d(p[0], p[1], p[2]);
    };
    const auto ray = [&](double fx, double fy, double depth) {
      const Eigen::Vector3d r = c.camera.K.inverse() * Eigen::Vector3d(x0 + fx * (x1 - x0), y0 + fy * (y1 - y0), 1.0);
      return Eigen::Vector3d(r * (depth / r.z()));
    };
    std::vector<simcore::InputEvent> events;
    const auto add = [&](simcore::InputKind kind, const Eigen::Vector3d& at, bool on, int tool, long step) {
      simcore::InputEvent e;
      e.kind = kind;
      e.position = at;
      e.on = on;
      e.tool = tool;
      e.step = step;
      events.push_back(e);
    };
    const Eigen::Vector3d bite = surfaceAt(0.5, 0.7);
    add(simcore::InputKind::ToolPose, bite, false, 0, 2);
    add(simcore::InputKind::Jaw, bite, true, 0, 2);
    for (int i = 1; i <= 20; ++i)
      add(simcore::InputKind::ToolPose, ray(0.5, 0.7 + 0.15 * i / 20, bite.z()), false, 0, 2 + 3 * i);
    const double bladeDepth = surfaceAt(0.6, 0.62).z() + 0.02;
    add(simcore::InputKind::ToolPose, ray(0.6, 0.62, bladeDepth), false, 1, 80);
    add(simcore::InputKind::Cut, ray(0.6, 0.62, bladeDepth), true, 1, 80);
    for (int i = 1; i <= 20; ++i)
      add(simcore::InputKind::ToolPose, ray(0.6 - 0.4 * i / 20, 0.62, bladeDepth), false, 1, 80 + 2 * i);
    add(simcore::InputKind::Cut, ray(0.2, 0.62, bladeDepth), false, 1, 121);
    simcore::Session session(b);
    for (const auto& e : events) session.post(e);
    for (int k = 0; k < 180; ++k) session.advance();
    return session.snapshot();
  }

  // After a grasp-pull-cut (issue 35): the cut organ's composition (app::makeCutCompositor: the cut mesh's boundary,
  // its cut faces in the parenchyma's colour) timed per frame at 1280x720 with the GUI's 2x2 rim.
  void cutViewport() {
    phantom::PhantomOptions p720;
    p720.width = 1280;
    p720.height = 720;
    const phantom::Phantom ph = phantom::makePhantom(p720);
    app::Case kase = app::caseFromPhantom(ph);
    kase.pose = ph.truePose;
    kase.hasPose = true;
    const app::AppearanceInput in = app::appearanceInputFromCase(kase);
    const auto base = app::makeCompositor(in, app::appearanceLayers(in, ph.trueAppearance), ph.trueAppearance, imaging::Reshading{});
    const auto snap = graspPullCut(kase);
    if (!snap->surface || snap->surface->cutCount == 0) {
      std::printf("grasp-pull-cut on the phantom: the blade cut nothing (%s)\n", snap->message.c_str());
      return;
    }
    const app::CutComposition cut = app::makeCutCompositor(*base, kase, *snap->surface);
    std::vector<double> model;  // the cut mesh's nodes in the model frame (the compositor's)
    const Eigen::Matrix3d Rt = kase.pose.R.transpose();
    for (const auto& p : snap->positions) {
      const Eigen::Vector3d m = Rt * (p - kase.pose.t);
      model.insert(model.end(), {m.x(), m.y(), m.z()});
    }
    std::vector<double> cms;
    cv::Mat3b j;
    for (int k = 0; k < std::max(repeat, 15); ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      j = cut.compositor->compose(model, 2);
      cms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(cms.begin(), cms.end());
    const SurfaceView cutView{model.data(), snap->positions.size(), snap->surface->triangles.front().data(),
                              snap->surface->triangles.size()};
    const auto cutGeo = imaging::surfaceGeometry(kase.camera, kase.pose, cutView);
    int seen = 0;
    for (int y = 0; y < cutGeo.triangle.rows; ++y)
      for (int x = 0; x < cutGeo.triangle.cols; ++x)
        if (const int t = cutGeo.triangle(y, x); t >= 0 && snap->surface->cut[static_cast<std::size_t>(t)]) ++seen;
    std::printf(
        "viewport compose, phantom after a grasp-pull-cut, %zu triangles (%zu cut faces, seen on %d px), "
        "1280x720, rim 2x2: %.1f ms median (step %.1f ms Newton %d, %s)\n",
        snap->surface->triangles.size(), snap->surface->cutCount, seen, cms[cms.size() / 2], snap->report.wallMs,
        snap->report.newtonIterations, snap->report.status.c_str());
    ccsv << "phantom cut," << snap->surface->triangles.size() << "," << snap->elements << ",1280,720,4," << seen
         << "," << cms[cms.size() / 2] << "\n";
    cv::imwrite(out + "/compose_cut.png", j);
  }

  // A real organ shape (not our smooth phantom): its surface seen broadside through the scikit-surgery
  // laparoscope (1920x1080), rendered with the phantom's light beside the lens and its reflectance (kd
  // scaled by the square of the distance so the organ is as bright), the scope's vignette, noise and JPEG 85.
  void realOrgan(const std::string& name, const std::string& file) {
    const auto& t = c.trueAppearance;
    const std::string path = std::string(REHEARSE_SHARED_DATA) + file;
    if (!std::filesystem::exists(path)) {
      std::printf("%s: %s is absent; skipped\n", name.c_str(), path.c_str());
      return;
    }
    const simcore::Mesh organ = testing::loadOrganSurface(path);
    const imaging::Camera cam = testing::scikitSurgeryCamera();
    const Pose pose = testing::broadsideView(organ, cam);
    const SurfaceView sv = organ.surfaceView();
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& p : organ.points) centre += pose.apply(p);
    centre /= static_cast<double>(organ.points.size());
    imaging::Appearance truth = t;
    truth.kd *= std::pow(centre.z() / 0.195, 2);
    truth.ks *= std::pow(centre.z() / 0.195, 2);
    cv::Mat3b img = imaging::renderShaded(cam, pose, sv, truth, imaging::makeTissueBackground(cam.width, cam.height, 9), 2);
    imaging::applyScopeVignette(img);
    cv::Mat fo, nz(img.size(), CV_32FC3);
    rng.fill(nz, cv::RNG::NORMAL, 0.0, 2.0);
    img.convertTo(fo, CV_32FC3);
    fo += nz;
    cv::Mat3b noisyOrgan;
    fo.convertTo(noisyOrgan, CV_8UC3);
    std::vector<uchar> jb;
    cv::imencode(".jpg", noisyOrgan, jb, {cv::IMWRITE_JPEG_QUALITY, 85});
    const cv::Mat3b seen = cv::imdecode(jb, cv::IMREAD_COLOR);
    const auto geo = imaging::surfaceGeometry(cam, pose, sv);
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = imaging::fitAppearance(seen, geo);
    const double fitMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    double kd = 0, ks = 0;
    for (int ch = 0; ch < 3; ++ch) {
      kd = std::max(kd, 100 * std::abs(r.theta.kd[ch] - truth.kd[ch]) / truth.kd[ch]);
      if (r.ksMeasured[static_cast<std::size_t>(ch)]) ks = std::max(ks, 100 * std::abs(r.theta.ks[ch] - truth.ks[ch]) / truth.ks[ch]);
    }
    std::printf("%s (%zu triangles, %.0f mm away): light %.2f %% of its distance off, kd %.2f %%, ks %.2f %% (measured channels %d%d%d), roughness %.2f %%; "
                "%.0f ms; %s\n",
                name.c_str(), organ.triangles.size(), 1e3 * centre.z(), 100 * (r.theta.lightPosition - truth.lightPosition).norm() / (truth.lightPosition - centre).norm(),
                kd, ks, r.ksMeasured[0], r.ksMeasured[1], r.ksMeasured[2], 100 * std::abs(r.theta.roughness - truth.roughness) / truth.roughness, fitMs,
                r.status.c_str());
    imaging::Camera cam720 = cam;  // the same view at 1280x720
    const double k = 1280.0 / cam.width;
    cam720.K.row(0) *= k;
    cam720.K.row(1) *= k;
    cam720.width = 1280;
    cam720.height = static_cast<int>(std::lround(cam.height * k));
    cv::Mat3b seen720;
    cv::resize(seen, seen720, cv::Size(cam720.width, cam720.height), 0, 0, cv::INTER_AREA);
    viewport(name, cam720, pose, sv, seen720, r.theta);
    if (!composeOnly) turnRows(tcsv, name, cam, pose, sv, seen, repeat);
    carriedViewport(name, organ, cam720, pose, seen720, r.theta);
  }

  // The same surface as the organ's own, drawn over a simulation mesh of about 3,500 tetrahedra (issue 35).
  void carriedViewport(const std::string& name, const simcore::Mesh& organ, const imaging::Camera& cam720,
                       const Pose& pose, const cv::Mat3b& seen720, const imaging::Appearance& theta) {
    simcore::Mesh own;
    simcore::TetrahedraliseOptions to;
    to.targetTets = 3500;
    to.outerSurface = &own;
    std::string why;
    std::shared_ptr<const app::Organ> carried;
    try {
      carried = app::Organ::fromVolume(simcore::tetrahedraliseSurface(organ, to), {}, 1.0, &own, &why);
    } catch (const std::exception& e) {
      std::printf("%s: not tetrahedralised (%s)\n", name.c_str(), e.what());
      return;
    }
    if (!carried->visual) {
      std::printf("%s: its own surface could not be carried: %s\n", name.c_str(), why.c_str());
      return;
    }
    std::vector<double> ownVertices;
    for (const auto& p : carried->visual->points) ownVertices.insert(ownVertices.end(), {p.x(), p.y(), p.z()});
    const SurfaceView ownView{ownVertices.data(), carried->visual->points.size(),
                              carried->visual->triangles.front().data(), carried->visual->triangles.size()};
    viewport(name, cam720, pose, ownView, seen720, theta, carried.get());
  }
};
}  // namespace

int main(int argc, char** argv) {
  AppearanceBench b;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc) b.repeat = std::max(1, std::atoi(argv[++i]));
    else if (a == "--compose-only") b.composeOnly = true;
    else b.out = a;
  }
  std::filesystem::create_directories(b.out);
  b.makeFrame();
  if (!b.composeOnly) {
    for (std::size_t samples : {2500, 5000, 10000, 20000, 40000, 80000}) b.sweep(std::to_string(samples) + " px/stage", samples, 1.0);
    for (double scale : {0.5, 0.25, 0.125}) b.sweep("1/" + std::to_string(static_cast<int>(std::lround(1 / scale))) + " resolution", 10000, scale);
    b.plot();
    b.wholeStep();
  }
  b.tcsv.open(b.out + "/appearance_turn.csv");
  b.tcsv << "organ,about_x_deg,about_y_deg,explained_before,explained_after,off_deg_before,off_deg_after,turned,turns_scored,search_ms_median,step_ms_median\n";
  if (!b.composeOnly) turnRows(b.tcsv, "phantom", b.c.camera, b.c.truePose, b.c.surfaceView(), b.frame, b.repeat);
  // The CPU composition as the viewport uses it (imaging::Compositor, prepared once per registered organ,
  // then one deformed shape per frame) at 1280x720: the phantom and each real organ shape below, moved
  // 3 mm and bent, with no anti-aliasing and with 2x2 and 4x4 samples on the rim.
  b.ccsv.open(b.out + "/compose.csv");
  b.ccsv << "organ,triangles,tetrahedra,width,height,rim_samples,organ_pixels,compose_ms_median\n";
  {
    phantom::PhantomOptions p720;
    p720.width = 1280;
    p720.height = 720;
    const phantom::Phantom c720 = phantom::makePhantom(p720);
    b.viewport("phantom", c720.camera, c720.truePose, c720.surfaceView(), c720.frame, c720.trueAppearance);
  }
  b.cutViewport();
  for (const auto& [name, file] : std::vector<std::pair<std::string, std::string>>{
           {"patient liver", "/scikit-surgery/patient-liver/liver.vtk"}, {"BodyParts3D liver", "/bodyparts3d/FMA7197_Liver.obj"},
           {"kidney", "/scikit-surgery/kidney/kidney.vtk"}})
    b.realOrgan(name, file);
  std::printf("wrote %s/appearance.csv, %s/appearance_turn.csv and %s/compose.csv\n", b.out.c_str(), b.out.c_str(), b.out.c_str());
  return 0;
}
