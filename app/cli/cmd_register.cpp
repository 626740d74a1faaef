// rehearse register: the organ fitted onto a sketched silhouette (issue 5).
#include "support.hpp"

#include "phantom/phantom.hpp"
#include "phantom/presets.hpp"
#include "rehearse/app/casefolder.hpp"
#include "rehearse/app/elasticfit.hpp"
#include "rehearse/app/appearancestep.hpp"
#include "rehearse/app/gesture.hpp"
#include "rehearse/app/recording.hpp"
#include "rehearse/app/review.hpp"
#include "rehearse/app/materials.hpp"

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/imaging/motion.hpp>
#include <opencv2/imgproc.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/registration.hpp>
#include <rehearse/simcore/scene.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <nlohmann/json.hpp>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <unistd.h>

namespace rehearse::app::cli {

namespace {

nlohmann::json uncertaintyJson(const simcore::RegistrationUncertainty& u) {
  if (!u.computed) return nullptr;
  // Where the organ may be: the far ends' poses (their shapes: --ends-out).
  nlohmann::json ends = nlohmann::json::array();
  for (const auto& e : u.ends) ends.push_back({{"pose", nlohmann::json::parse(imaging::poseToJson(e.pose))}});
  auto mm = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };  // null: unbounded
  return {{"surface_mm", mm(u.surfaceMm)},
          {"target_mm", mm(u.targetMm)},
          {"curvature_mm", mm(u.curvatureMm)},
          {"spread_mm", u.spreadMm},
          {"motion_mm", u.motionMm},
          {"misfit_px", u.misfitPx},
          {"correlation", u.correlation},
          {"weakest", u.weakest},
          {"sentence", uncertaintySentence(u)},
          {"ends", ends}};
}

// The options checked before anything is read: the required ones, the second frame's, contradictions, file suffixes.
Options checkRegisterOptions(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, registerCommand());
  for (const char* need : {"camera", "contour", "pose", "out"})
    if (!o.count(need)) throw UsageError(std::string("register needs --") + need);
  for (const char* needsSecond : {"motion", "baseline-mm", "frame", "frame2"})
    if (o.count(needsSecond) && !o.count("contour2"))
      throw UsageError(std::string("--") + needsSecond + " is for a second frame: give its outline with --contour2");
  if (o.count("rigid-prepass") && o.count("no-rigid-prepass"))
    throw UsageError("--rigid-prepass and --no-rigid-prepass contradict each other");
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".vtu" && ext != ".vtk" && ext != ".msh") throw UsageError("--out must end in .vtu, .vtk or .msh");
  if (o.count("ends-out")) {
    const std::string endsExt = std::filesystem::path(o["ends-out"]).extension().string();
    if (endsExt != ".vtu" && endsExt != ".vtk" && endsExt != ".msh")
      throw UsageError("--ends-out must end in .vtu, .vtk or .msh");
  }
  return o;
}

// The organ model in metres; `surfaceIn` gets the surface it was made from, when it came as one.
simcore::Scene loadOrganModel(Options& o, bool gravityGiven, simcore::Mesh& surfaceIn) {
  simcore::Scene p = modelFromOptions(o, "register", &surfaceIn);
  // A registration has no gravity unless the scene or --gravity asks for it (the pre-operative shape is
  // the organ as it lies).
  if (!gravityGiven && !o.count("scene")) p.settings.gravity.setZero();
  p.mesh.convertToMetres();
  return p;
}

// The first frame's outline (sized by the camera, undistorted when drawn on the distorted frame) and the camera.
struct FirstFrame {
  imaging::Contour contour;
  imaging::Camera camera;
};

FirstFrame loadFirstFrame(Options& o) {
  imaging::Contour contour = imaging::loadContour(o["contour"]);
  int width = contour.width, height = contour.height;
  if (o.count("image-size")) {
    char x = 0;
    std::istringstream in(o["image-size"]);
    if (!(in >> width >> x >> height) || x != 'x' || width <= 0 || height <= 0)
      throw UsageError("--image-size must look like 1280x720");
  }
  const imaging::Camera camera = imaging::loadCamera(o["camera"], width, height);
  if (const std::string problem = camera.problem(); !problem.empty()) throw simcore::MeshError(problem);
  if (contour.width == 0) contour.width = camera.width;
  if (contour.height == 0) contour.height = camera.height;
  if (o.count("distorted-contour")) contour = imaging::undistortContour(contour, camera);
  if (const std::string problem = imaging::contourProblem(contour); !problem.empty()) throw simcore::MeshError(problem);
  return {std::move(contour), camera};
}

// When the organ came as a surface, curve vertices index that surface: they go to the nearest surface
// node of the volume made from it.
void mapCurvesToVolume(imaging::Contour& contour, const simcore::Mesh& surfaceIn, const simcore::Mesh& volume) {
  std::vector<int> boundaryNodes;
  if (!surfaceIn.points.empty()) {
    for (const auto& t : simcore::boundaryTriangles(volume, false))
      boundaryNodes.insert(boundaryNodes.end(), t.begin(), t.end());
    std::sort(boundaryNodes.begin(), boundaryNodes.end());
    boundaryNodes.erase(std::unique(boundaryNodes.begin(), boundaryNodes.end()), boundaryNodes.end());
  }
  for (auto& seg : contour.segments) {
    if (seg.isSilhouette() || boundaryNodes.empty()) continue;
    for (int& v : seg.modelVertices) {
      if (v < 0 || static_cast<std::size_t>(v) >= surfaceIn.points.size())
        throw simcore::MeshError("The " + seg.type + " curve refers to vertex " + std::to_string(v) +
                                 ", which the surface does not have.");
      int best = boundaryNodes.front();
      for (int n : boundaryNodes)
        if ((volume.points[n] - surfaceIn.points[v]).squaredNorm() <
            (volume.points[best] - surfaceIn.points[v]).squaredNorm())
          best = n;
      v = best;
    }
    seg.modelVertices.erase(std::unique(seg.modelVertices.begin(), seg.modelVertices.end()), seg.modelVertices.end());
  }
}

// --ground-truth: the organ's volume where it truly is (camera frame), node for node; empty without.
simcore::Mesh loadGroundTruth(Options& o, const simcore::Mesh& volume) {
  simcore::Mesh truth;
  if (o.count("ground-truth")) {
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    truth = simcore::loadMesh(o["ground-truth"], lo);
    truth.convertToMetres();
    if (truth.points.size() != volume.points.size())
      throw simcore::MeshError("The ground truth has " + std::to_string(truth.points.size()) + " nodes, the organ " +
                               std::to_string(volume.points.size()) +
                               "; they must be the same mesh in the same order.");
  }
  return truth;
}

// The input of the one fit pipeline the GUI uses too (app/elasticfit.hpp), with the fit's options.
FitInput fitInput(Options& o, simcore::Scene& p, const FirstFrame& frame, const Pose& start, bool gravityGiven) {
  FitInput in;
  in.organ = Organ::fromVolume(std::move(p.mesh));  // moved: the output copies it from the organ
  in.attachments = p.fixedNodes;
  in.materials = {p.defaultMaterial, p.materials};
  in.embedded = p.embedded;
  in.settings = p.settings;
  in.contour = frame.contour;
  in.camera = frame.camera.pinhole();
  in.start = start;
  // The rigid stage runs first unless asked not to (as in the GUI): the elastic stage alone cannot recover
  // a pose that is centimetres off (BENCHMARKS.md).
  in.rigidPrepass = o.count("no-rigid-prepass") == 0;
  in.elastic = o.count("rigid-only") == 0;
  if (o.count("iterations")) in.maxIterations = static_cast<int>(parseCount(o["iterations"], "--iterations", 1, 1000));
  if (o.count("gravity-camera")) {
    if (gravityGiven)
      throw UsageError(
          "--gravity (model frame) and --gravity-camera (camera frame) say the same thing twice; give one");
    in.gravityCamera = parseVector(o["gravity-camera"], "--gravity-camera");
    if (!(in.gravityCamera.norm() > 0))
      throw UsageError("--gravity-camera must not be zero (leave it out when down is not known)");
  }
  if (o.count("tolerance-mm")) {
    in.toleranceMm = parseNumber(o["tolerance-mm"], "--tolerance-mm");
    if (!(in.toleranceMm > 0)) throw UsageError("--tolerance-mm must be a positive number of millimetres");
  }
  return in;
}

// A second frame (--contour2): its outline, and the camera's motion to it (given, or from features tracked between the
// frames with the move's length given); the features are used by the fit too when both frames are there. Added to
// `in`; its part of the report (null without one).
nlohmann::json addSecondFrame(Options& o, const FirstFrame& frame, FitInput& in) {
  if (!o.count("contour2")) return nullptr;
  const imaging::Camera& camera = frame.camera;
  simcore::RegistrationFrame second;
  second.camera = camera.pinhole();
  imaging::Contour c2 = imaging::loadContour(o["contour2"]);
  if (c2.width == 0) c2.width = camera.width;
  if (c2.height == 0) c2.height = camera.height;
  if (o.count("distorted-contour")) c2 = imaging::undistortContour(c2, camera);
  if (const std::string problem = imaging::contourProblem(c2); !problem.empty())
    throw simcore::MeshError("The second frame's outline: " + problem);
  for (const auto& seg : c2.segments)
    if (seg.isSilhouette()) second.contour.push_back(seg.points);
  if (o.count("motion") && o.count("baseline-mm"))
    throw UsageError("--motion gives the move's length already; leave out --baseline-mm");
  if (!o.count("motion") && !o.count("baseline-mm"))
    throw UsageError(
        "--contour2 needs the camera's motion to the second frame: --motion M.json, or --frame, --frame2 and "
        "--baseline-mm (two frames give only the move's direction, not its length)");
  if (o.count("frame") != o.count("frame2")) throw UsageError("--frame and --frame2 go together");
  std::vector<imaging::Track> tracks;
  if (o.count("frame")) {
    auto read = [&](const std::string& path) {
      cv::Mat3b image = cv::imread(path, cv::IMREAD_COLOR);
      if (image.empty()) throw rehearse::InputError("Cannot read the frame " + path + " (not an image, or missing).");
      if (image.cols != camera.width || image.rows != camera.height)
        throw rehearse::InputError("The frame " + path + " is not the camera's size (" + std::to_string(camera.width) +
                                  "x" + std::to_string(camera.height) + ").");
      return imaging::undistortImage(image, camera);  // (the image itself without distortion)
    };
    const cv::Mat3b first = read(o["frame"]), image2 = read(o["frame2"]);
    // Features only on the organ as sketched on the first frame (its outline filled, less a margin).
    tracks = tracksOnOrgan(first, frame.contour, image2);
  }
  std::string motionStatus;
  if (o.count("motion")) {
    second.motion = imaging::loadPose(o["motion"]);
    motionStatus = "camera motion given (" + o["motion"] + ")";
  } else {
    if (!o.count("frame"))
      throw UsageError("--baseline-mm estimates the motion from the frames: give --frame and --frame2 too");
    const double baseline = 1e-3 * parseNumber(o["baseline-mm"], "--baseline-mm");
    if (!(baseline > 0)) throw UsageError("--baseline-mm must be a positive number of millimetres");
    const imaging::CameraMotion m = imaging::estimateCameraMotion(camera, tracks, baseline);
    if (!m.ok) throw rehearse::InputError("The second frame cannot be used: " + m.status + ".");
    second.motion = m.motion;
    second.motionDepthSigmaM = m.depthSigmaM;
    second.motionAtOneSigma = m.motionAtOneSigma;
    tracks = m.inliers;
    motionStatus = m.status;
  }
  second.tracks = tracks;
  std::printf("register: second frame: %s; %zu features tracked\n", motionStatus.c_str(), tracks.size());
  nlohmann::json frameReport = {{"motion", nlohmann::json::parse(imaging::poseToJson(second.motion))},
                                {"features", tracks.size()},
                                {"depth_sigma_mm", 1e3 * second.motionDepthSigmaM},
                                {"status", motionStatus}};
  in.frames = {second};
  return frameReport;
}

// The fit, with a row per iteration (and its 3D error, mm, against the ground truth when there is one).
struct FitRow {
  simcore::RegistrationIteration it;
  double errMean = -1, errMax = -1;
};
struct FitRun {
  simcore::RegistrationResult res;
  std::vector<FitRow> rows;
};

FitRun runFit(const FitInput& in, const simcore::Mesh& truth) {
  FitRun run;
  std::vector<FitRow>& rows = run.rows;
  const FitProgress record = [&](const simcore::RegistrationIteration& it, const Eigen::VectorXd& x, const Pose& pose) {
    FitRow r{it};
    if (!truth.points.empty()) {
      double sum = 0, worst = 0;
      for (std::size_t i = 0; i < truth.points.size(); ++i) {
        const double e = (pose.apply(x.segment<3>(3 * i)) - truth.points[i]).norm();
        sum += e;
        worst = std::max(worst, e);
      }
      r.errMean = 1e3 * sum / truth.points.size();
      r.errMax = 1e3 * worst;
    }
    rows.push_back(r);
    return true;
  };
  run.res = runElasticFit(in, record);
  return run;
}

// A fit that succeeded: the registered volume (nodes in the camera frame, input order), --pose-out and --ends-out.
void writeRegistered(Options& o, const FitInput& in, const simcore::RegistrationResult& res) {
  simcore::Mesh out = in.organ->volume;
  out.triangles.clear();
  out.triangleLabels.clear();
  for (std::size_t i = 0; i < out.points.size(); ++i) out.points[i] = res.pose.apply(res.x.segment<3>(3 * i));
  if (!res.ok) return;
  simcore::saveMesh(out, o["out"]);
  if (o.count("pose-out")) imaging::savePose(res.pose, o["pose-out"]);
  if (o.count("ends-out")) {
    // The bound's two far ends beside it: E-1.vtu and E-2.vtu for --ends-out E.vtu (nodes in the camera frame).
    if (res.uncertainty.ends.empty())
      std::printf("register: no far ends written: %s\n", uncertaintySentence(res.uncertainty).c_str());
    const std::filesystem::path stem = o["ends-out"];
    for (std::size_t e = 0; e < res.uncertainty.ends.size(); ++e) {
      const auto& end = res.uncertainty.ends[e];
      for (std::size_t i = 0; i < out.points.size(); ++i) out.points[i] = end.pose.apply(end.x.segment<3>(3 * i));
      const std::filesystem::path file =
          stem.parent_path() / (stem.stem().string() + "-" + std::to_string(e + 1) + stem.extension().string());
      simcore::saveMesh(out, file.string());
    }
  }
}

// --report: the outcome, the alternatives, the sag, the bound, the second frame and a row per iteration.
void writeRegisterReport(const std::string& path, const FitRun& fit, nlohmann::json frameReport, double toleranceMm) {
  const simcore::RegistrationResult& res = fit.res;
  nlohmann::json iterations = nlohmann::json::array();
  for (const auto& r : fit.rows) {
    nlohmann::json row = {{"iteration", r.it.iteration}, {"stage", r.it.stage},
                          {"wall_ms", r.it.wallMs},      {"mean_px", r.it.residual.mean},
                          {"rms_px", r.it.residual.rms}, {"hausdorff_px", r.it.residual.hausdorff},
                          {"bound", r.it.bound}};
    if (r.it.curves.points) {
      row["curve_mean_px"] = r.it.curves.mean;
      row["curve_hausdorff_px"] = r.it.curves.hausdorff;
    }
    if (r.errMean >= 0) {
      row["error_mean_mm"] = r.errMean;
      row["error_max_mm"] = r.errMax;
    }
    iterations.push_back(std::move(row));
  }
  if (frameReport.is_object()) frameReport["set_aside"] = !res.setAsideFrames.empty();
  nlohmann::json alternatives = nlohmann::json::array();
  for (const auto& a : res.alternatives)
    alternatives.push_back({{"pose", nlohmann::json::parse(imaging::poseToJson(a.pose))},
                            {"mean_px", a.score},
                            {"apart_mm", a.apartMm}});
  writeReport(path, {{"ok", res.ok},
                     {"converged", res.converged},
                     {"determined", res.ok && !res.ambiguous},
                     {"ambiguous", res.ambiguous},
                     {"alternatives", alternatives},
                     {"sag_determined", res.sagDetermined},
                     {"sag_share", res.sagShare},
                     {"sag_apart_mm", res.sagApartMm},
                     {"deeper_minima_taken", res.adopted},
                     {"uncertainty", uncertaintyJson(res.uncertainty)},
                     {"tolerance_mm", toleranceMm},
                     {"second_frame", frameReport},
                     {"load_model_m_s2", {res.load.x(), res.load.y(), res.load.z()}},
                     {"load_camera_m_s2",
                      {(res.pose.R * res.load).x(), (res.pose.R * res.load).y(), (res.pose.R * res.load).z()}},
                     {"status", res.status},
                     {"iterations", iterations}});
}

// The fit's line and its bound's sentence; the exit code: 0 a determined fit, 4 ambiguous, 3 failed.
int registerSummary(const FitRun& fit) {
  const simcore::RegistrationResult& res = fit.res;
  const std::vector<FitRow>& rows = fit.rows;
  const auto& last = rows.back().it;
  std::printf("register: %s; %zu iterations, %.0f ms; mean distance %.2f px (start %.2f px)%s\n", res.status.c_str(),
              rows.size(), last.wallMs, last.score(), rows.front().it.score(),
              rows.back().errMean >= 0 ? (", 3D error " + std::to_string(rows.back().errMean) + " mm").c_str() : "");
  if (res.ok) std::printf("register: %s\n", uncertaintySentence(res.uncertainty).c_str());
  if (!res.ok) {
    std::fprintf(stderr, "rehearse: %s\n", res.status.c_str());
    return 3;
  }
  if (res.ambiguous) {
    // The best fit is written, but the contour does not determine it: not a success.
    std::fprintf(stderr, "rehearse: %s\n", res.status.c_str());
    return 4;
  }
  return 0;
}

}  // namespace

int cmdRegister(const std::vector<std::string>& args) {
  Options o = checkRegisterOptions(args);
  const bool gravityGiven = o.count("gravity") > 0;
  simcore::Mesh surfaceIn;
  simcore::Scene p = loadOrganModel(o, gravityGiven, surfaceIn);
  FirstFrame frame = loadFirstFrame(o);
  const Pose start = imaging::loadPose(o["pose"]);
  mapCurvesToVolume(frame.contour, surfaceIn, p.mesh);
  const simcore::Mesh truth = loadGroundTruth(o, p.mesh);
  FitInput in = fitInput(o, p, frame, start, gravityGiven);
  const nlohmann::json frameReport = addSecondFrame(o, frame, in);
  const FitRun fit = runFit(in, truth);
  writeRegistered(o, in, fit.res);
  if (o.count("report")) writeRegisterReport(o["report"], fit, frameReport, in.toleranceMm);
  return registerSummary(fit);
}

const Command& registerCommand() {
  static const Command command{
      "register",
      "  rehearse register --mesh VOLUME | --scene S.json | --preset NAME [--unit u] --camera CAM --contour C.json\n"
      "                --pose P0.json --out REGISTERED.vtu|.vtk [--pose-out P.json] [--report R.json]\n"
      "                [--ends-out E.vtu]\n"
      "                [--ground-truth GT.vtu|.vtk] [--no-rigid-prepass] [--rigid-only] [--iterations N]\n"
      "                [--image-size WxH] [--distorted-contour] [--gravity-camera X,Y,Z] [material flags of "
      "simulate]\n"
      "                                   fit the organ onto a sketched silhouette (nodes written in the camera "
      "frame);\n"
      "                                   the organ's sag under a steady load is estimated with its pose (held "
      "organs;\n"
      "                                   --gravity-camera: which way is down in the camera frame, m/s^2, when "
      "known);\n"
      "                                   ridges and ligaments with their curve on the organ (P2ILF modelPoints, "
      "our\n"
      "                                   model_vertices: node indices, or surface vertices when --mesh is a "
      "surface)\n"
      "                                   are held onto their image curves too. Exit 0: a determined fit;\n"
      "                                   4: ambiguous (the best fit is written; the report names the other\n"
      "                                   poses that fit the contour nearly as well, or the fit's own bound\n"
      "                                   exceeds --tolerance-mm, 5 by default); 3: failed\n"
      "                [--contour2 C2.json (--motion M.json | --baseline-mm MM) [--frame F1 --frame2 F2]]\n"
      "                                   a second frame (the scope moved 1-2 cm): its outline, the camera's\n"
      "                                   motion to it (given, or from features tracked between the frames,\n"
      "                                   the move's length given), and the features, fitted with the first\n",
      joined(modelOptions(), {{"camera", "CAM", "the camera (OpenCV YAML or JSON intrinsics)"},
                              {"contour", "C.json", "the sketched silhouette (and curves) in pixels"},
                              {"pose", "P0.json", "the starting pose (model to camera)"},
                              {"out", "OUT", "the registered volume, nodes in the camera frame: .vtu or .vtk"},
                              {"pose-out", "P.json", "the fitted pose"},
                              {"ends-out", "E.vtu",
                               "where the organ may be: the bound's two far ends as E-1.vtu and E-2.vtu (camera "
                               "frame)"},
                              {"report", "R.json", "residuals, status, alternatives"},
                              {"ground-truth", "GT", "a volume in the camera frame to measure the fit against"},
                              {"iterations", "N", "the elastic fit's iterations"},
                              {"image-size", "WxH", "the frame's size when the camera file has none"},
                              {"gravity-camera", "X,Y,Z", "which way is down in the camera frame, m/s^2, when known"},
                              {"rigid-prepass", "", "run the rigid stage first (the default)"},
                              {"no-rigid-prepass", "", "start the elastic fit from the given pose"},
                              {"rigid-only", "", "stop after the rigid stage"},
                              {"distorted-contour", "", "the contour was drawn on the distorted frame"},
                              {"tolerance-mm", "MM", "the bound a determined fit stays within (default 5)"},
                              {"contour2", "C2.json", "the outline sketched on a second frame"},
                              {"motion", "M.json", "the camera's motion from the first frame to the second"},
                              {"baseline-mm", "MM", "how far the camera moved between the frames"},
                              {"frame", "F1", "the first frame (to track features from)"},
                              {"frame2", "F2", "the second frame (to track features into)"}}),
      cmdRegister};
  return command;
}

}  // namespace rehearse::app::cli
