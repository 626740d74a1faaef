#include "cli.hpp"

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

#ifndef REHEARSE_VERSION
#define REHEARSE_VERSION "0.0.0"
#endif

namespace rehearse::app {
namespace {

// A JSON report, written atomically (a reader never sees half of it).
void writeReport(const std::string& path, const nlohmann::json& report) { imaging::writeFileAtomically(path, report.dump(2) + "\n"); }

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Parses "--key value" pairs after the sub-command; flags listed in `flags` take no value.
std::map<std::string, std::string> parseOptions(const std::vector<std::string>& args, std::size_t from,
                                                const std::vector<std::string>& allowed,
                                                const std::vector<std::string>& flags = {}) {
  std::map<std::string, std::string> out;
  for (std::size_t i = from; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + a + "'; see 'rehearse --help'");
    std::string key = a.substr(2), value;
    if (auto eq = key.find('='); eq != std::string::npos) {
      value = key.substr(eq + 1);
      key = key.substr(0, eq);
    } else if (std::find(flags.begin(), flags.end(), key) == flags.end()) {
      if (i + 1 >= args.size()) throw UsageError("option --" + key + " needs a value");
      value = args[++i];
    }
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end() &&
        std::find(flags.begin(), flags.end(), key) == flags.end())
      throw UsageError("unknown option --" + key + "; see 'rehearse --help'");
    out[key] = value;
  }
  return out;
}

long parseCount(const std::string& s, const char* what, long lo, long hi) {
  try {
    std::size_t used = 0;
    long v = std::stol(s, &used);
    if (used != s.size() || v < lo || v > hi) throw std::out_of_range("");
    return v;
  } catch (const std::exception&) {
    throw UsageError(std::string(what) + " must be a whole number from " + std::to_string(lo) + " to " + std::to_string(hi));
  }
}

double parseNumber(const std::string& s, const char* what) {
  try {
    std::size_t used = 0;
    double v = std::stod(s, &used);
    if (used != s.size() || !std::isfinite(v) || v <= 0) throw std::out_of_range("");
    return v;
  } catch (const std::exception&) {
    throw UsageError(std::string(what) + " must be a positive number");
  }
}

int cmdPhantom(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, {"out", "tets", "seed"});
  if (!o.count("out")) throw UsageError("phantom needs --out DIR");
  phantom::PhantomOptions po;
  if (o.count("tets")) po.targetTets = parseCount(o["tets"], "--tets", 100, 2'000'000);
  if (o.count("seed")) po.seed = static_cast<unsigned>(parseCount(o["seed"], "--seed", 0, 1'000'000));
  auto t0 = std::chrono::steady_clock::now();
  const auto c = phantom::makePhantom(po);
  writeCaseDirectory(caseFromPhantom(c), o["out"]);
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("phantom written to %s: %zu nodes, %zu tets, %zu surface triangles, %zu attachment nodes, frame %dx%d (%.2f s)\n",
              o["out"].c_str(), c.volume.points.size(), c.volume.tets.size(), c.surface.size(), c.attachments.size(),
              c.frame.cols, c.frame.rows, s);
  return 0;
}

int cmdMesh(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, {"in", "out", "target-tets", "size", "unit"}, {"ascii", "allow-self-intersections"});
  if (!o.count("in") || !o.count("out")) throw UsageError("mesh needs --in SURFACE and --out VOLUME.msh|.vtk|.vtu");
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".msh" && ext != ".vtk" && ext != ".vtu" && ext != ".mesh")
    throw UsageError("--out must end in .msh, .vtk, .vtu or .mesh");
  simcore::LoadOptions lo;
  if (o.count("unit")) lo.unit = o["unit"];
  std::vector<std::string> notes;
  auto input = simcore::loadMesh(o["in"], lo, &notes);
  simcore::Mesh volume;
  auto t0 = std::chrono::steady_clock::now();
  if (input.isVolume()) {
    volume = std::move(input);
    volume.triangles.clear();
    volume.triangleLabels.clear();
    notes.push_back("The input is already a volume mesh; it was converted, not re-meshed.");
  } else {
    simcore::TetrahedraliseOptions to;
    if (o.count("target-tets")) to.targetTets = parseCount(o["target-tets"], "--target-tets", 10, 5'000'000);
    if (o.count("size")) to.cellSize = parseNumber(o["size"], "--size") * 1e-3;
    to.allowSelfIntersections = o.count("allow-self-intersections") > 0;
    if (isatty(fileno(stderr)))
      to.progress = [](double f, const std::string& stage) {
        if (f < 0) std::fprintf(stderr, "\r     %-64s", stage.c_str());  // a stage of unknown length: its counts
        else std::fprintf(stderr, "\r%3.0f%% %-64s", 100 * f, stage.c_str());
      };
    volume = simcore::tetrahedraliseSurface(input, to, &notes);
  }
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (isatty(fileno(stderr))) std::fprintf(stderr, "\r%50s\r", "");
  simcore::saveMesh(volume, o["out"], o.count("ascii") > 0);
  for (const auto& n : notes) std::fprintf(stderr, "note: %s\n", n.c_str());
  std::printf("%s", simcore::formatQuality(simcore::computeQuality(volume)).c_str());
  std::printf("meshing time: %.3f s\nwritten: %s\n", s, o["out"].c_str());
  return 0;
}

int cmdInfo(const std::vector<std::string>& args) {
  if (args.size() < 3 || args[2].rfind("--", 0) == 0) throw UsageError("info needs a FILE");
  auto o = parseOptions(args, 3, {"unit"});
  simcore::LoadOptions lo;
  if (o.count("unit")) lo.unit = o["unit"];
  std::vector<std::string> notes;
  auto m = simcore::loadMesh(args[2], lo, &notes);
  auto q = simcore::computeQuality(m);
  if (!m.isVolume()) q.selfIntersections = simcore::countSelfIntersections(m);
  std::printf("file: %s\nkind: %s\nunit: %s (coordinates shown in mm)\n", args[2].c_str(),
              m.isVolume() ? "volume" : "surface", lo.unit.c_str());
  std::printf("%s", simcore::formatQuality(q).c_str());
  for (const auto& n : notes) std::printf("repaired on load: %s\n", n.c_str());
  return 0;
}

Eigen::Vector3d parseVector(const std::string& s, const char* what) {
  Eigen::Vector3d v;
  char c1 = 0, c2 = 0;
  std::istringstream in(s);
  if (!(in >> v.x() >> c1 >> v.y() >> c2 >> v.z()) || c1 != ',' || c2 != ',' || !v.allFinite())
    throw UsageError(std::string(what) + " must be three numbers separated by commas, such as 0,-9.81,0");
  return v;
}

// --fixed-nodes: a list of node indices ("3 39 64" or "3,39,64") or a file holding one; decided by content
// (a list of digits is never taken for a file name). Every token must be an index: nothing is dropped.
std::vector<int> parseNodes(const std::string& s) {
  const bool isList = !s.empty() && s.find_first_not_of("0123456789, \t\r\n") == std::string::npos;
  std::string text = s;
  if (!isList) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(s, ec))
      throw UsageError("--fixed-nodes takes node indices (\"3 39 64\") or a file of them; '" + s.substr(0, 40) +
                       (s.size() > 40 ? "...'" : "'") + " is neither");
    std::ifstream in(s);
    std::stringstream ss;
    ss << in.rdbuf();
    text = ss.str();
    // A case folder's attachments.json ({"nodes": [...], "indexing": "0-based ..."}): its node list.
    if (text.find_first_not_of(" \t\r\n") != std::string::npos && text[text.find_first_not_of(" \t\r\n")] == '{') {
      const auto j = nlohmann::json::parse(text, nullptr, false);
      if (j.is_discarded() || !j.contains("nodes") || !j["nodes"].is_array())
        throw UsageError("--fixed-nodes: " + s + " is JSON but has no \"nodes\" list of node indices");
      std::vector<int> out;
      for (const auto& v : j["nodes"]) {
        if (!v.is_number_integer() || v.get<long long>() < 0)
          throw UsageError("--fixed-nodes: " + s + " lists something that is not a node index (0, 1, 2, ...)");
        out.push_back(v.get<int>());
      }
      return out;
    }
  }
  for (auto& ch : text)
    if (ch == ',') ch = ' ';
  std::vector<int> out;
  std::istringstream in(text);
  std::string tok;
  while (in >> tok) {
    if (tok.find_first_not_of("0123456789") != std::string::npos || tok.size() > 9)
      throw UsageError("--fixed-nodes holds '" + tok.substr(0, 20) + "', which is not a node index (0, 1, 2, ...)");
    out.push_back(std::stoi(tok));
  }
  return out;
}

// The organ model of a command: --scene, --preset or --mesh, then the material flags, --fixed-nodes and
// --gravity over it (shared by simulate and register).
// When `surfaceIn` is given and the organ came as a surface that was tetrahedralised, it receives that
// surface (in metres), so indices into it can be mapped onto the volume.
simcore::Scene modelFromOptions(std::map<std::string, std::string>& o, const char* command, simcore::Mesh* surfaceIn = nullptr) {
  simcore::Scene p;
  p.defaultMaterial = {};
  if (o.count("scene")) {
    p = simcore::loadScene(o["scene"]);
    if (!p.mesh.isVolume()) p.mesh = simcore::tetrahedraliseSurface(p.mesh, {});
  } else if (o.count("preset")) {
    try {
      p = phantom::makePreset(o["preset"]);
    } catch (const simcore::MeshError& e) {
      throw UsageError(e.what());
    }
  } else if (o.count("mesh")) {
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    p.mesh = simcore::loadMesh(o["mesh"], lo);
    if (!p.mesh.isVolume()) {
      if (surfaceIn) {
        *surfaceIn = p.mesh;
        surfaceIn->convertToMetres();
      }
      simcore::TetrahedraliseOptions to;
      p.mesh = simcore::tetrahedraliseSurface(p.mesh, to);
    }
  } else {
    throw UsageError(std::string(command) + " needs --scene S.json, --preset NAME or --mesh FILE");
  }
  if (o.count("material")) p.defaultMaterial.model = simcore::materialModelFromString(o["material"]);
  if (o.count("young")) p.defaultMaterial.young = parseNumber(o["young"], "--young");
  if (o.count("poisson")) {
    try {
      p.defaultMaterial.poisson = std::stod(o["poisson"]);
    } catch (const std::exception&) {
      throw UsageError("--poisson must be a number in [0, 0.5)");
    }
  }
  if (o.count("density")) p.defaultMaterial.density = parseNumber(o["density"], "--density");
  if (o.count("vessel-young")) {
    // The case's vessel material as the GUI sets it (app::labelMaterials): the parenchyma's law and density.
    MaterialSettings m = materialFromScene(p);
    m.vesselYoung = parseNumber(o["vessel-young"], "--vessel-young");
    const LabelMaterials lm = labelMaterials(m);
    p.defaultMaterial = lm.fallback;
    p.materials = lm.byLabel;
  }
  if (o.count("fixed-nodes")) p.fixedNodes = parseNodes(o["fixed-nodes"]);
  if (o.count("gravity")) p.settings.gravity = parseVector(o["gravity"], "--gravity");
  return p;
}

constexpr simcore::StepStatus kStatuses[] = {simcore::StepStatus::Converged, simcore::StepStatus::Inexact, simcore::StepStatus::Inverted,
                                             simcore::StepStatus::Failed, simcore::StepStatus::Refused};

// {"converged": n, "inexact": n, ...}: the reports' "statuses".
nlohmann::json statusCounts(const std::vector<const simcore::StepReport*>& reports) {
  nlohmann::json counts = nlohmann::json::object();
  for (auto s : kStatuses) {
    std::size_t k = 0;
    for (const auto* r : reports) k += r->outcome == s;
    counts[toString(s)] = k;
  }
  return counts;
}

// The steps' outcomes counted, on stdout always ("statuses: ..."), on stderr when one did not converge, and the exit
// code: 0 when every step converged, 3 when a step failed (rolled back) or was refused, 5 when every step advanced but
// some ended inexact or with inverted elements.
int statusSummary(const std::vector<const simcore::StepReport*>& reports) {
  std::array<std::size_t, 5> n{};
  std::size_t mostInverted = 0;
  double largestResidual = 0, smallestJ = 1;
  for (const auto* r : reports) {
    ++n[static_cast<std::size_t>(r->outcome)];
    mostInverted = std::max(mostInverted, static_cast<std::size_t>(r->invertedElements));
    if (std::isfinite(r->residual)) largestResidual = std::max(largestResidual, r->residual);
    smallestJ = std::min(smallestJ, r->minVolumeRatio);
  }
  using S = simcore::StepStatus;
  std::string line = "statuses: ";
  for (S s : kStatuses)
    if (n[static_cast<std::size_t>(s)] || s == S::Converged)
      line += (line.size() > 10 ? ", " : "") + std::to_string(n[static_cast<std::size_t>(s)]) + " " + toString(s);
  char figures[160];
  std::snprintf(figures, sizeof figures, "; largest relative residual %.3g, at most %zu inverted elements, smallest volume ratio %.3g", largestResidual,
                mostInverted, smallestJ);
  line += figures;
  std::printf("%s\n", line.c_str());
  const std::size_t failed = n[static_cast<std::size_t>(S::Failed)] + n[static_cast<std::size_t>(S::Refused)];
  const std::size_t loose = n[static_cast<std::size_t>(S::Inexact)] + n[static_cast<std::size_t>(S::Inverted)];
  if (failed || loose) {
    const simcore::StepReport* first = nullptr;
    for (const auto* r : reports)
      if (r->outcome != S::Converged) {
        first = r;
        break;
      }
    std::fprintf(stderr, "rehearse: %zu of %zu steps did not converge (%s); the first: %s\n", failed + loose, reports.size(), line.c_str() + 10,
                 simcore::statusSentence(*first).c_str());
  }
  return failed ? 3 : loose ? 5 : 0;
}

int cmdSimulate(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2,
                        {"scene", "preset", "mesh", "unit", "material", "young", "poisson", "density", "vessel-young", "fixed-nodes", "gravity",
                         "steps", "dt", "out", "report", "solver", "method", "attachments", "factor"},
                        {"static", "list-components", "strict"});
  if (o.count("list-components")) {
    std::printf("%s", simcore::describeSceneComponents().c_str());
    return 0;
  }
  if (!o.count("out")) throw UsageError("simulate needs --out OUT.vtu|OUT.vtk");
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".vtu" && ext != ".vtk" && ext != ".msh") throw UsageError("--out must end in .vtu, .vtk or .msh");
  simcore::Scene p = modelFromOptions(o, "simulate");
  if (o.count("dt")) p.settings.timeStep = parseNumber(o["dt"], "--dt");
  if (o.count("strict")) p.settings.strict = true;
  // Names parsed by simcore's one set of parsers (as scenes are); their sentences become usage errors
  // (the Newton method's stays a model error, exit 1, as before).
  if (o.count("method")) p.settings.method = simcore::newtonMethodFromString(o["method"]);
  try {
    if (o.count("solver")) p.settings.solver = simcore::linearSolverFromString(o["solver"]);
    if (o.count("factor")) p.settings.simplicialFactor = simcore::simplicialFactorFromString(o["factor"]);
    if (o.count("attachments")) p.settings.attachments = simcore::attachmentModeFromString(o["attachments"]);
  } catch (const simcore::MeshError& e) {
    throw UsageError(e.what());
  }
  const long steps = o.count("steps") ? parseCount(o["steps"], "--steps", 1, 1'000'000) : p.steps;
  if (p.staticSolve) o["static"] = "";
  const simcore::FemModel model = simcore::FemModel::build(p.mesh, p.materials, p.defaultMaterial, p.embedded);
  for (const auto& e : model.embeddings)
    if (e.outside) std::fprintf(stderr, "rehearse: note: %zu vertices of the embedded surface '%s' lie outside the organ\n", e.outside, e.name.c_str());
  simcore::Integrator integrator(model, p.fixedNodes, p.settings);
  auto state = integrator.initialState();
  std::vector<simcore::StepReport> reports;
  if (o.count("static")) {
    reports.push_back(integrator.solveStatic(state));
  } else {
    for (long i = 0; i < steps; ++i) reports.push_back(integrator.step(state));
  }
  simcore::Mesh out = p.mesh;
  out.convertToMetres();
  out.triangles.clear();
  out.triangleLabels.clear();
  for (std::size_t i = 0; i < out.points.size(); ++i) out.points[i] = state.x.segment<3>(3 * i);
  simcore::saveMesh(out, o["out"]);
  // Embedded surfaces follow the organ: written beside the output as OUT.<name>.vtk.
  for (std::size_t k = 0; k < model.embeddings.size(); ++k) {
    simcore::Mesh surf;
    const auto pts = simcore::mapEmbedded(model, k, state.x);
    surf.points.assign(pts.begin(), pts.end());
    surf.triangles = model.embeddings[k].triangles;
    const auto path = std::filesystem::path(o["out"]).replace_extension("." + model.embeddings[k].name + ".vtk");
    simcore::saveMesh(surf, path.string());
  }
  if (o.count("report")) {
    nlohmann::json steps = nlohmann::json::array();
    for (std::size_t i = 0; i < reports.size(); ++i) {
      const auto& r = reports[i];
      steps.push_back({{"step", i}, {"wall_ms", r.wallMs}, {"newton_iterations", r.newtonIterations}, {"residual", r.residual},
                       {"energy", r.energy}, {"time_step", r.timeStepUsed}, {"retries", r.retries}, {"factorisations", r.factorisations},
                       {"ok", r.ok}, {"outcome", toString(r.outcome)}, {"status", simcore::statusSentence(r)}, {"inverted_elements", r.invertedElements},
                       {"min_volume_ratio", r.minVolumeRatio}, {"inversion_limited", r.inversionLimited}});
    }
    std::vector<const simcore::StepReport*> all;
    for (const auto& r : reports) all.push_back(&r);
    writeReport(o["report"], {{"steps", steps}, {"statuses", statusCounts(all)}});
  }
  std::size_t failed = 0;
  double wall = 0;
  for (const auto& r : reports) {
    failed += !r.ok;
    wall += r.wallMs;
  }
  std::printf("%s: %zu nodes, %zu tets, %zu %s, %zu failed, mean %.2f ms per %s, written %s\n",
              o.count("static") ? "static" : "dynamic", model.nodeCount(), model.tets.size(), reports.size(),
              o.count("static") ? "solve" : "steps", failed, wall / reports.size(), o.count("static") ? "solve" : "step",
              o["out"].c_str());
  std::vector<const simcore::StepReport*> all;
  for (const auto& r : reports) all.push_back(&r);
  return statusSummary(all);
}


// rehearse register: the organ fitted onto a sketched silhouette (issue 5).
int cmdRegister(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2,
                        {"scene", "preset", "mesh", "unit", "material", "young", "poisson", "density", "vessel-young", "fixed-nodes", "gravity", "camera",
                         "contour", "pose", "out", "pose-out", "report", "ground-truth", "iterations", "image-size", "gravity-camera"},
                        {"rigid-prepass", "no-rigid-prepass", "rigid-only", "distorted-contour"});
  for (const char* need : {"camera", "contour", "pose", "out"})
    if (!o.count(need)) throw UsageError(std::string("register needs --") + need);
  if (o.count("rigid-prepass") && o.count("no-rigid-prepass")) throw UsageError("--rigid-prepass and --no-rigid-prepass contradict each other");
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".vtu" && ext != ".vtk" && ext != ".msh") throw UsageError("--out must end in .vtu, .vtk or .msh");
  const bool gravityGiven = o.count("gravity") > 0;
  simcore::Mesh surfaceIn;
  simcore::Scene p = modelFromOptions(o, "register", &surfaceIn);
  // A registration has no gravity unless the scene or --gravity asks for it (the pre-operative shape is
  // the organ as it lies).
  if (!gravityGiven && !o.count("scene")) p.settings.gravity.setZero();
  p.mesh.convertToMetres();
  imaging::Contour contour = imaging::loadContour(o["contour"]);
  int width = contour.width, height = contour.height;
  if (o.count("image-size")) {
    char x = 0;
    std::istringstream in(o["image-size"]);
    if (!(in >> width >> x >> height) || x != 'x' || width <= 0 || height <= 0) throw UsageError("--image-size must look like 1280x720");
  }
  const imaging::Camera camera = imaging::loadCamera(o["camera"], width, height);
  if (const std::string problem = camera.problem(); !problem.empty()) throw simcore::MeshError(problem);
  if (contour.width == 0) contour.width = camera.width;
  if (contour.height == 0) contour.height = camera.height;
  if (o.count("distorted-contour")) contour = imaging::undistortContour(contour, camera);
  if (const std::string problem = imaging::contourProblem(contour); !problem.empty()) throw simcore::MeshError(problem);
  const Pose start = imaging::loadPose(o["pose"]);
  // When the organ came as a surface, curve vertices index that surface: they go to the nearest surface
  // node of the volume made from it.
  std::vector<int> boundaryNodes;
  if (!surfaceIn.points.empty()) {
    for (const auto& t : simcore::boundaryTriangles(p.mesh, false)) boundaryNodes.insert(boundaryNodes.end(), t.begin(), t.end());
    std::sort(boundaryNodes.begin(), boundaryNodes.end());
    boundaryNodes.erase(std::unique(boundaryNodes.begin(), boundaryNodes.end()), boundaryNodes.end());
  }
  for (auto& seg : contour.segments) {
    if (seg.isSilhouette() || boundaryNodes.empty()) continue;
    for (int& v : seg.modelVertices) {
      if (v < 0 || static_cast<std::size_t>(v) >= surfaceIn.points.size())
        throw simcore::MeshError("The " + seg.type + " curve refers to vertex " + std::to_string(v) + ", which the surface does not have.");
      int best = boundaryNodes.front();
      for (int n : boundaryNodes)
        if ((p.mesh.points[n] - surfaceIn.points[v]).squaredNorm() < (p.mesh.points[best] - surfaceIn.points[v]).squaredNorm()) best = n;
      v = best;
    }
    seg.modelVertices.erase(std::unique(seg.modelVertices.begin(), seg.modelVertices.end()), seg.modelVertices.end());
  }
  simcore::Mesh truth;
  if (o.count("ground-truth")) {
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    truth = simcore::loadMesh(o["ground-truth"], lo);
    truth.convertToMetres();
    if (truth.points.size() != p.mesh.points.size())
      throw simcore::MeshError("The ground truth has " + std::to_string(truth.points.size()) + " nodes, the organ " +
                               std::to_string(p.mesh.points.size()) + "; they must be the same mesh in the same order.");
  }
  // The one fit pipeline the GUI uses too (app/elasticfit.hpp).
  FitInput in;
  in.organ = Organ::fromVolume(std::move(p.mesh));  // moved: the output below copies it from the organ
  in.attachments = p.fixedNodes;
  in.materials = {p.defaultMaterial, p.materials};
  in.embedded = p.embedded;
  in.settings = p.settings;
  in.contour = contour;
  in.camera = camera.pinhole();
  in.start = start;
  // The rigid stage runs first unless asked not to (as in the GUI): the elastic stage alone cannot recover
  // a pose that is centimetres off (BENCHMARKS.md).
  in.rigidPrepass = o.count("no-rigid-prepass") == 0;
  in.elastic = o.count("rigid-only") == 0;
  if (o.count("iterations")) in.maxIterations = static_cast<int>(parseCount(o["iterations"], "--iterations", 1, 1000));
  if (o.count("gravity-camera")) {
    if (gravityGiven) throw UsageError("--gravity (model frame) and --gravity-camera (camera frame) say the same thing twice; give one");
    in.gravityCamera = parseVector(o["gravity-camera"], "--gravity-camera");
    if (!(in.gravityCamera.norm() > 0)) throw UsageError("--gravity-camera must not be zero (leave it out when down is not known)");
  }
  struct Row {
    simcore::RegistrationIteration it;
    double errMean = -1, errMax = -1;
  };
  std::vector<Row> rows;
  const FitProgress record = [&](const simcore::RegistrationIteration& it, const Eigen::VectorXd& x, const Pose& pose) {
    Row r{it};
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
  const simcore::RegistrationResult res = runElasticFit(in, record);
  // Registered nodes in the camera frame, input order.
  simcore::Mesh out = in.organ->volume;
  out.triangles.clear();
  out.triangleLabels.clear();
  for (std::size_t i = 0; i < out.points.size(); ++i) out.points[i] = res.pose.apply(res.x.segment<3>(3 * i));
  if (res.ok) {
    simcore::saveMesh(out, o["out"]);
    if (o.count("pose-out")) imaging::savePose(res.pose, o["pose-out"]);
  }
  if (o.count("report")) {
    nlohmann::json iterations = nlohmann::json::array();
    for (const auto& r : rows) {
      nlohmann::json row = {{"iteration", r.it.iteration}, {"stage", r.it.stage}, {"wall_ms", r.it.wallMs}, {"mean_px", r.it.residual.mean},
                            {"rms_px", r.it.residual.rms}, {"hausdorff_px", r.it.residual.hausdorff}, {"bound", r.it.bound}};
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
    nlohmann::json alternatives = nlohmann::json::array();
    for (const auto& a : res.alternatives)
      alternatives.push_back({{"pose", nlohmann::json::parse(imaging::poseToJson(a.pose))}, {"mean_px", a.score}, {"apart_mm", a.apartMm}});
    writeReport(o["report"], {{"ok", res.ok},
                              {"converged", res.converged},
                              {"determined", res.ok && !res.ambiguous},
                              {"ambiguous", res.ambiguous},
                              {"alternatives", alternatives},
                              {"sag_determined", res.sagDetermined},
                              {"sag_share", res.sagShare},
                              {"sag_apart_mm", res.sagApartMm},
                              {"deeper_minima_taken", res.adopted},
                              {"load_model_m_s2", {res.load.x(), res.load.y(), res.load.z()}},
                              {"load_camera_m_s2", {(res.pose.R * res.load).x(), (res.pose.R * res.load).y(), (res.pose.R * res.load).z()}},
                              {"status", res.status},
                              {"iterations", iterations}});
  }
  const auto& last = rows.back().it;
  std::printf("register: %s; %zu iterations, %.0f ms; mean distance %.2f px (start %.2f px)%s\n", res.status.c_str(), rows.size(), last.wallMs,
              last.score(), rows.front().it.score(),
              rows.back().errMean >= 0 ? (", 3D error " + std::to_string(rows.back().errMean) + " mm").c_str() : "");
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

// Step 6's inputs: a case folder, or the organ, camera, pose and frame as files (each file overrides the
// case's part).
AppearanceInput appearanceInput(std::map<std::string, std::string>& o, const char* command) {
  AppearanceInput in;
  bool haveSurface = false, havePose = false;
  if (o.count("case")) {
    if (!std::filesystem::is_directory(o["case"]))
      throw UsageError(std::string(command) + " --case takes a case folder (as 'rehearse phantom --out DIR' writes); open a .rehearse file in the GUI");
    const Case c = loadCaseDirectory(o["case"]);
    in.camera = c.camera;
    in.frame = c.frame;
    if (c.hasPose) in.pose = c.pose, havePose = true;
    const SurfaceView v = c.surfaceView();
    in.vertices.assign(v.vertices, v.vertices + 3 * v.vertexCount);
    in.triangles.resize(v.triangleCount);
    for (std::size_t t = 0; t < v.triangleCount; ++t) in.triangles[t] = {v.triangles[3 * t], v.triangles[3 * t + 1], v.triangles[3 * t + 2]};
    haveSurface = true;
  }
  if (o.count("mesh")) {
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    simcore::Mesh m = simcore::loadMesh(o["mesh"], lo);
    m.convertToMetres();
    in.triangles = m.isVolume() ? simcore::boundaryTriangles(m, false) : m.triangles;
    in.vertices.clear();
    for (const auto& p : m.points) in.vertices.insert(in.vertices.end(), {p.x(), p.y(), p.z()});
    haveSurface = true;
  }
  if (o.count("image")) {
    in.frame = cv::imread(o["image"], cv::IMREAD_COLOR);
    if (in.frame.empty()) throw simcore::MeshError("The image " + o["image"] + " cannot be read; give a PNG or JPEG frame.");
  }
  if (o.count("camera")) in.camera = imaging::loadCamera(o["camera"], in.frame.cols, in.frame.rows);
  if (o.count("pose")) in.pose = imaging::loadPose(o["pose"]), havePose = true;
  if (!haveSurface) throw UsageError(std::string(command) + " needs --case or --mesh");
  if (in.frame.empty()) throw UsageError(std::string(command) + " needs --image (or a --case with a frame)");
  if (in.camera.width == 0) throw UsageError(std::string(command) + " needs --camera (or a --case with one)");
  if (!havePose) throw UsageError(std::string(command) + " needs --pose (the case has no alignment yet)");
  if (const std::string problem = in.camera.problem(); !problem.empty()) throw simcore::MeshError(problem);
  // A frame from a camera with lens distortion is undistorted first (every step works on the undistorted frame).
  if (o.count("image") && std::any_of(in.camera.distortion.begin(), in.camera.distortion.end(), [](double d) { return d != 0; })) {
    cv::Mat K(3, 3, CV_64F), D(1, 5, CV_64F), out;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) K.at<double>(r, c) = in.camera.K(r, c);
    for (int k = 0; k < 5; ++k) D.at<double>(0, k) = in.camera.distortion[static_cast<std::size_t>(k)];
    cv::undistort(in.frame, out, K, D, K);
    in.frame = out;
  }
  if (o.count("inpaint")) in.inpaint = imaging::parseInpaintMethod(o["inpaint"]);
  return in;
}

int cmdAppearance(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, {"case", "mesh", "unit", "camera", "pose", "image", "out", "report", "inpaint", "background", "diffuse"});
  if (!o.count("out")) throw UsageError("appearance needs --out THETA.json");
  const AppearanceInput in = appearanceInput(o, "appearance");
  const AppearanceOutput r = runAppearance(in);
  imaging::saveAppearance(r.fit.theta, o["out"]);
  if (o.count("background")) imaging::writeFileAtomically(o["background"], [&] {
      std::vector<uchar> buf;
      cv::imencode(".png", r.background, buf);
      return std::string(buf.begin(), buf.end());
    }());
  if (o.count("diffuse")) {
    std::vector<uchar> buf;
    cv::imencode(".png", r.fit.separation.diffuse, buf);
    imaging::writeFileAtomically(o["diffuse"], std::string(buf.begin(), buf.end()));
  }
  if (o.count("report")) {
    nlohmann::json stages = nlohmann::json::array();
    for (const auto& st : r.fit.stages) stages.push_back({{"stage", st.name}, {"rms_levels", st.rms}, {"ms", st.ms}, {"pixels", st.pixels}});
    stages.push_back({{"stage", std::string("background (") + imaging::inpaintMethodName(in.inpaint) + ")"}, {"ms", r.inpaintMs}});
    writeReport(o["report"], {{"status", r.fit.status},
                              {"highlight_found", r.fit.highlightFound},
                              {"texture_only", r.fit.textureOnly},
                              {"explained", r.fit.explained},
                              {"ks_measured", {r.fit.ksMeasured[0], r.fit.ksMeasured[1], r.fit.ksMeasured[2]}},
                              {"highlight_pixels", r.fit.separation.count},
                              {"rest_psnr_db", r.restPsnr},
                              {"total_ms", r.totalMs},
                              {"stages", stages}});
  }
  std::printf("%s\nlight (%.1f, %.1f, %.1f) mm, kd (%.4f, %.4f, %.4f), ks (%.4f, %.4f, %.4f), roughness %.3f; composed at rest: %.1f dB inside the organ; %.0f ms\n",
              r.fit.status.c_str(), 1e3 * r.fit.theta.lightPosition.x(), 1e3 * r.fit.theta.lightPosition.y(), 1e3 * r.fit.theta.lightPosition.z(),
              r.fit.theta.kd.x(), r.fit.theta.kd.y(), r.fit.theta.kd.z(), r.fit.theta.ks.x(), r.fit.theta.ks.y(), r.fit.theta.ks.z(), r.fit.theta.roughness,
              r.restPsnr, r.totalMs);
  // A fit too poor to re-shade is still written (texture mapping uses it), but says so with its own exit code.
  return r.fit.textureOnly ? 4 : 0;
}

int cmdCompose(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, {"case", "mesh", "unit", "camera", "pose", "image", "theta", "deformed", "out", "inpaint"});
  for (const char* need : {"theta", "out"})
    if (!o.count(need)) throw UsageError(std::string("compose needs --") + need);
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".png" && ext != ".jpg" && ext != ".jpeg") throw UsageError("--out must end in .png or .jpg");
  const AppearanceInput in = appearanceInput(o, "compose");
  const imaging::Appearance theta = imaging::loadAppearance(o["theta"]);
  std::vector<double> deformed;
  if (o.count("deformed")) {
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    simcore::Mesh d = simcore::loadMesh(o["deformed"], lo);
    d.convertToMetres();
    for (const auto& p : d.points) deformed.insert(deformed.end(), {p.x(), p.y(), p.z()});
  }
  const cv::Mat3b j = composeWithTheta(in, theta, deformed);
  std::vector<uchar> buf;
  cv::imencode(ext, j, buf);
  imaging::writeFileAtomically(o["out"], std::string(buf.begin(), buf.end()));
  std::printf("written: %s\n", o["out"].c_str());
  return 0;
}

// rehearse gesture: a scripted rehearsal without a window (issue 15), through the simulation session.
int cmdGesture(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2,
                        {"case", "scene", "preset", "mesh", "unit", "material", "young", "poisson", "density", "vessel-young", "fixed-nodes", "gravity",
                         "script", "out", "report", "method", "refresh", "record", "trainee", "notes"},
                        {});
  if ((o.count("trainee") || o.count("notes")) && !o.count("record")) throw UsageError("--trainee and --notes go with --record CASE");
  if (!o.count("script")) throw UsageError("gesture needs --script G.json (README, File formats)");
  if (!o.count("out")) throw UsageError("gesture needs --out OUT.vtu|.vtk|.msh");
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".vtu" && ext != ".vtk" && ext != ".msh") throw UsageError("--out must end in .vtu, .vtk or .msh");
  std::ifstream in(o["script"]);
  if (!in) throw UsageError("cannot read the gesture script " + o["script"]);
  std::stringstream ss;
  ss << in.rdbuf();
  GestureScript script;
  try {
    script = parseGestureScript(ss.str());
  } catch (const std::runtime_error& e) {
    throw UsageError(std::string(o["script"]) + ": " + e.what());
  }
  simcore::BodySetup setup;
  simcore::Mesh mesh;
  if (o.count("case")) {
    for (const char* k : {"scene", "preset", "mesh", "material", "young", "poisson", "density", "vessel-young", "fixed-nodes"})
      if (o.count(k)) throw UsageError(std::string("--case takes the case's organ, attachments and material; --") + k + " cannot be combined with it");
    const Case c = loadCaseDirectory(o["case"]);
    if (c.organ->empty()) throw UsageError(o["case"] + " has no organ mesh");
    mesh = c.organ->volume;
    setup.fixedNodes = c.attachments;
    const LabelMaterials lm = labelMaterials(c.material);
    setup.material = lm.fallback;
    setup.byLabel = lm.byLabel;
    if (o.count("gravity")) setup.settings.gravity = parseVector(o["gravity"], "--gravity");
  } else {
    simcore::Scene p = modelFromOptions(o, "gesture");
    if (!p.embedded.empty())
      throw UsageError("the scene embeds surfaces (" + p.embedded.front().name + "), which the gesture session does not carry yet; remove them or use simulate");
    mesh = p.mesh;
    setup.fixedNodes = p.fixedNodes;
    setup.material = p.defaultMaterial;
    setup.byLabel = p.materials;
    setup.settings = p.settings;
  }
  if (o.count("method")) setup.settings.method = simcore::newtonMethodFromString(o["method"]);
  if (o.count("refresh")) {
    if (o["refresh"] == "async") setup.settings.factorRefresh = simcore::FactorRefresh::Asynchronous;
    else if (o["refresh"] != "sync") throw UsageError("--refresh takes sync or async, not '" + o["refresh"] + "'");
    if (setup.settings.factorRefresh == simcore::FactorRefresh::Asynchronous && setup.settings.method == simcore::NewtonMethod::Exact)
      throw UsageError("--refresh async rebuilds the lagged factorisation of the chord, lagged-pcg and linearised methods; the exact method has none (choose --method)");
  }
  mesh.convertToMetres();
  setup.mesh = mesh;
  // --record: the session (setup, events, a state checksum every 10 steps) written into CASE as it runs.
  std::unique_ptr<Recorder> recorder;
  GestureHooks hooks;
  if (o.count("record")) {
    SessionMeta meta;
    meta.trainee = o.count("trainee") ? o["trainee"] : "";
    meta.notes = o.count("notes") ? o["notes"] : "";
    meta.caseName = o.count("case") ? o["case"] : o.count("preset") ? "preset " + o["preset"] : o.count("scene") ? o["scene"] : o.count("mesh") ? o["mesh"] : "";
    meta.sceneVersion = o["script"];
    meta.appVersion = REHEARSE_VERSION;
    hooks.start = [&recorder, meta, path = o["record"]](const simcore::BodySetup& s) {
      try {
        recorder = std::make_unique<Recorder>(path, meta, s);
      } catch (const std::runtime_error& e) {
        throw UsageError(e.what());
      }
    };
    hooks.step = [&recorder](const simcore::StepRecord& r) { recorder->afterStep(r); };
  }
  const GestureResult r = runGesture(setup, script, hooks);
  if (recorder) {
    recorder->finish(static_cast<long>(r.steps.size()));
    std::printf("recorded: session %lld in %s (%zu steps)\n", static_cast<long long>(recorder->id()), o["record"].c_str(), r.steps.size());
  }
  const simcore::Mesh& out = r.finalMesh;
  simcore::saveMesh(out, o["out"]);
  double peak = 0, wall = 0;
  std::size_t grasped = 0;
  for (const auto& s : r.steps) {
    peak = std::max(peak, s.toolForce.norm());
    wall += s.wallMs;
    grasped = std::max(grasped, s.grasped);
  }
  if (o.count("report")) {
    nlohmann::json rows = nlohmann::json::array();
    for (const auto& s : r.steps)
      rows.push_back({{"step", s.step}, {"time_s", s.time}, {"wall_ms", s.wallMs}, {"mass_kg", s.massKg}, {"elements", s.elements}, {"nodes", s.nodes},
                      {"grasped_nodes", s.grasped}, {"contacts", s.contacts}, {"tool_force_n", {s.toolForce.x(), s.toolForce.y(), s.toolForce.z()}},
                      {"tip_m", {s.tip.x(), s.tip.y(), s.tip.z()}}, {"events", s.events}, {"message", s.message}, {"ok", s.report.ok},
                      {"outcome", toString(s.report.outcome)}, {"status", simcore::statusSentence(s.report)}, {"residual", s.report.residual},
                      {"inverted_elements", s.report.invertedElements}, {"min_volume_ratio", s.report.minVolumeRatio}, {"factorisations", s.report.factorisations},
                      {"factor_requested", s.report.factorRequested}, {"factor_swapped", s.report.factorSwapped}});
    std::vector<const simcore::StepReport*> all;
    for (const auto& s : r.steps) all.push_back(&s.report);
    writeReport(o["report"], {{"steps", rows}, {"statuses", statusCounts(all)}, {"slips", r.slips}, {"cuts", r.cuts}, {"vessel_cuts", setup.mesh.namesAVessel() ? nlohmann::json(r.vesselCuts) : nlohmann::json(nullptr)}, {"failed_steps", r.failed},
                              {"peak_tool_force_n", peak}, {"elements", out.tets.size()}, {"nodes", out.points.size()},
                              {"contact_queries", r.contactQueries}});
  }
  const std::string vessels = setup.mesh.namesAVessel() ? std::to_string(r.vesselCuts) + " vessel cut(s)" : "vessels unknown (the mesh names none)";
  std::printf("gesture: %zu steps (%.2f ms mean), up to %zu nodes grasped, peak tool force %.2f N, %zu slips, %zu cut updates, %s, %zu failed "
              "steps; %zu elements, %zu nodes written to %s\n",
              r.steps.size(), wall / static_cast<double>(r.steps.size()), grasped, peak, r.slips, r.cuts, vessels.c_str(), r.failed, out.tets.size(), out.points.size(),
              o["out"].c_str());
  std::vector<const simcore::StepReport*> all;
  for (const auto& s : r.steps) all.push_back(&s.report);
  const int code = statusSummary(all);
  // A cut refused or another input the session turned down is not a step's failure: r.failed counts steps not taken.
  return r.failed ? 3 : code;
}

// rehearse publish CASE... [--service NAME]: the complete sessions of case files into the training database.
int cmdPublish(const std::vector<std::string>& args) {
  std::vector<std::string> files;
  std::size_t i = 2;
  for (; i < args.size() && args[i].rfind("--", 0) != 0; ++i) files.push_back(args[i]);
  if (files.empty()) throw UsageError("publish needs case files: rehearse publish CASE... [--service NAME]");
  auto o = parseOptions(args, i, {"service"}, {});
  for (const auto& f : files)
    if (!std::filesystem::exists(f)) throw UsageError(f + " does not exist");
  if (!trainingStore().publish)
    throw UsageError("publishing goes through Qt SQL's PostgreSQL driver, which this build has not (configured with REHEARSE_BUILD_GUI=OFF)");
  for (const auto& line : trainingStore().publish(files, o.count("service") ? o["service"] : std::string())) std::printf("%s\n", line.c_str());
  return 0;
}

// rehearse replay CASE: the recorded sessions of a case file (issue 16); --verify re-simulates one and compares
// every recorded state checksum (exit 4 on a mismatch).
int cmdReplay(const std::vector<std::string>& args) {
  if (args.size() < 3 || args[2].rfind("--", 0) == 0)
    throw UsageError("replay needs the case file (or postgresql:[SERVICE]): rehearse replay CASE [--session ID] [--verify]");
  const std::string file = args[2];
  auto o = parseOptions(args, 3, {"session", "metrics", "metrics-csv", "force-threshold", "thresholds", "planned-cut", "video", "report", "from", "to", "fps", "size"},
                        {"verify", "list"});
  // postgresql:[SERVICE]: the training centre's database (libpq service name, or the environment when empty).
  const bool fromDb = file.rfind("postgresql:", 0) == 0;
  const std::string service = fromDb ? file.substr(11) : std::string();
  if (fromDb && !trainingStore().load)
    throw UsageError("the training database is read through Qt SQL's PostgreSQL driver, which this build has not (configured with REHEARSE_BUILD_GUI=OFF)");
  if (!fromDb && !std::filesystem::exists(file)) throw UsageError(file + " does not exist");
  auto listSessions = [&] { return fromDb ? trainingStore().list(service) : listRecordings(file); };
  auto loadSession = [&](std::int64_t sid) { return fromDb ? trainingStore().load(service, sid) : loadRecording(file, sid); };
  const double threshold = o.count("force-threshold") ? parseNumber(o["force-threshold"], "--force-threshold") : 10.0;
  if (!(threshold >= 0)) throw UsageError("--force-threshold must be a force in N, 0 or more");
  ReplayOptions ro;
  ro.forceThresholdN = threshold;
  if (o.count("planned-cut")) {
    const std::string& p = o["planned-cut"];
    const auto colon = p.find(':');
    if (colon == std::string::npos) throw UsageError("--planned-cut takes two points X,Y,Z:X,Y,Z (m, the recording's frame)");
    ro.plannedCut = std::make_pair(parseVector(p.substr(0, colon), "--planned-cut"), parseVector(p.substr(colon + 1), "--planned-cut"));
  }
  std::vector<Threshold> thresholds;
  if (!o.count("thresholds") && !fromDb) {  // the trainer's thresholds kept in the case file
    const std::string kept = loadCaseThresholds(file);
    if (!kept.empty()) {
      try {
        thresholds = parseThresholds(kept);
      } catch (const std::runtime_error& e) {
        throw UsageError(file + ": its kept thresholds: " + e.what());
      }
    }
  }
  if (o.count("thresholds")) {
    std::ifstream in(o["thresholds"]);
    if (!in) throw UsageError("cannot read the thresholds " + o["thresholds"]);
    std::stringstream text;
    text << in.rdbuf();
    try {
      thresholds = parseThresholds(text.str());
    } catch (const std::runtime_error& e) {
      throw UsageError(o["thresholds"] + ": " + e.what());
    }
  }
  const bool oneSession = o.count("video") || o.count("report") || o.count("from") || o.count("to") || o.count("fps") || o.count("size");
  if (oneSession && !o.count("session")) throw UsageError("--video, --report, --from, --to, --fps and --size are for one session: give --session ID");
  if ((o.count("from") || o.count("to") || o.count("fps") || o.count("size")) && !o.count("video"))
    throw UsageError("--from, --to, --fps and --size set the video: give --video OUT.mp4");
  if (o.count("video") && std::filesystem::path(o["video"]).extension() != ".mp4") throw UsageError("--video must end in .mp4");
  if (o.count("report") && std::filesystem::path(o["report"]).extension() != ".pdf") throw UsageError("--report must end in .pdf");
  if (o.count("report") && !reportWriter())
    throw UsageError("--report needs the PDF writer of the GUI build (this build was configured with REHEARSE_BUILD_GUI=OFF)");
  if (o.count("metrics-csv")) {
    // Every session's metrics, one row each (a trainer's spreadsheet across attempts); each replay verified.
    if (o.count("session") || o.count("metrics") || o.count("verify"))
      throw UsageError("--metrics-csv covers every session; --session, --metrics and --verify are for one");
    std::ostringstream csv;
    csv.precision(17);
    csv << "session,trainee,started_utc,complete,steps,duration_s,path_length_m,economy_of_motion,grasps,slips,cut_updates,vessel_cuts,max_force_n,"
           "mean_force_n,force_threshold_n,time_over_threshold_s,max_strain,cut_length_m,cut_deviation_mean_m,cut_deviation_max_m,tumour_breaches,"
           "attachments_torn,checksums,checksums_differing\n";
    ro.strain = true;
    auto opt = [](const auto& v) { return v ? std::to_string(*v) : std::string(); };  // empty: not determined
    auto quoted = [](const std::string& s) {
      std::string q = "\"";
      for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
      return q + "\"";
    };
    long differing = 0;
    const auto sessions = listSessions();
    for (const auto& s : sessions) {
      const ReplayResult r = replayRecording(loadSession(s.id), ro);
      const SessionMetrics& m = r.metrics;
      differing += r.verify.mismatches;
      csv << s.id << ',' << quoted(s.meta.trainee) << ',' << s.startedUtc << ',' << (s.complete ? 1 : 0) << ',' << r.verify.steps << ',' << m.durationS << ','
          << m.pathLengthM << ',' << m.economy << ',' << m.grasps << ',' << m.slips << ',' << m.cuts << ',' << opt(m.vesselCuts) << ',' << m.maxForceN << ','
          << m.meanForceN << ',' << m.forceThresholdN << ',' << m.timeOverThresholdS << ',' << opt(m.maxStrain) << ',' << m.cutLengthM << ','
          << opt(m.cutDeviationMeanM) << ',' << opt(m.cutDeviationMaxM) << ',' << opt(m.tumourBreaches) << ',' << opt(m.attachmentsTorn) << ','
          << r.verify.checked << ',' << r.verify.mismatches << '\n';
    }
    imaging::writeFileAtomically(o["metrics-csv"], csv.str());
    std::printf("metrics of %zu sessions written to %s\n", sessions.size(), o["metrics-csv"].c_str());
    if (differing) {
      std::fprintf(stderr, "rehearse: %ld checksums differ on replay (column checksums_differing)\n", differing);
      return 4;
    }
    return 0;
  }
  if (!o.count("session")) {
    const auto sessions = listSessions();
    if (sessions.empty()) std::printf("%s holds no recorded session\n", file.c_str());
    for (const auto& s : sessions)
      std::printf("session %lld  %s  trainee '%s'  case '%s'  %ld steps%s\n", static_cast<long long>(s.id), s.startedUtc.c_str(), s.meta.trainee.c_str(),
                  s.meta.caseName.c_str(), s.steps, s.complete ? "" : "  (cut short)");
    if (o.count("verify")) throw UsageError("--verify needs --session ID (the list above)");
    return 0;
  }
  std::int64_t id = 0;
  try {
    std::size_t used = 0;
    id = std::stoll(o["session"], &used);
    if (used != o["session"].size()) throw std::invalid_argument("trailing");
  } catch (const std::exception&) {
    throw UsageError("--session takes a session number, not '" + o["session"] + "'");
  }
  const Recording rec = loadSession(id);
  std::printf("session %lld: %zu events, %zu checksums, %ld steps%s\n", static_cast<long long>(id), rec.events.size(), rec.checksums.size(), rec.summary.steps,
              rec.summary.complete ? "" : " (cut short: what was recorded is replayed)");
  if (!o.count("verify") && !o.count("metrics") && !o.count("video") && !o.count("report")) return 0;
  ro.strain = o.count("metrics") || o.count("report") || !thresholds.empty();
  ro.timeline = o.count("video") || o.count("report");
  const ReplayResult replayed = replayRecording(rec, ro);
  const auto verdicts = judge(replayed.metrics, thresholds);
  if (o.count("metrics")) {
    nlohmann::json j = {{"session", id}, {"trainee", rec.summary.meta.trainee}, {"started_utc", rec.summary.startedUtc},
                        {"force_threshold_n", replayed.metrics.forceThresholdN},
                        {"replay_verified", replayVerified(replayed.verify)},
                        {"replay_check", replayCheckSentence(replayed.verify)},
                        {"checksums", replayed.verify.checked},
                        {"checksums_differing", replayed.verify.mismatches}};
    for (const auto& v : metricValues(replayed.metrics)) {
      j[v.name] = !v.value ? nlohmann::json(nullptr) : v.count ? nlohmann::json(std::lround(*v.value)) : nlohmann::json(*v.value);
      if (!v.value) j[v.name + "_why"] = v.why;
    }
    nlohmann::json js = nlohmann::json::array();
    for (const auto& v : verdicts) {
      nlohmann::json row = {{"metric", v.metric.name}, {"result", resultWord(v.result)}};
      row["value"] = v.metric.value ? nlohmann::json(*v.metric.value) : nlohmann::json(nullptr);
      if (v.threshold.min) row["min"] = *v.threshold.min;
      if (v.threshold.max) row["max"] = *v.threshold.max;
      js.push_back(row);
    }
    j["verdicts"] = js;
    writeReport(o["metrics"], j);
    std::printf("metrics written to %s\n", o["metrics"].c_str());
  }
  if (!o.count("verify") && replayed.verify.mismatches == 0 && !replayVerified(replayed.verify))
    std::printf("replay check: %s\n", replayCheckSentence(replayed.verify).c_str());
  for (const auto& v : verdicts) {
    const auto& m = v.metric;  // counts as whole numbers ("grasps: pass (1)")
    const std::string value = !m.value ? m.why : m.count ? std::to_string(std::llround(*m.value)) : std::to_string(*m.value);
    std::printf("%s: %s (%s)\n", m.name.c_str(), resultWord(v.result), value.c_str());
  }
  if (o.count("video") || o.count("report")) {
    int width = 640, height = 480;
    if (o.count("size")) {
      char x = 0;
      std::istringstream in(o["size"]);
      if (!(in >> width >> x >> height) || x != 'x' || !in.eof()) throw UsageError("--size takes WIDTHxHEIGHT in pixels, e.g. 1280x720");
    }
    Replayer replayer(rec);
    ReviewRenderer renderer(rec.setup, width, height);
    if (o.count("video")) {
      const double fps = o.count("fps") ? parseNumber(o["fps"], "--fps") : 25.0;
      auto stepAt = [&](const std::string& key, long fallback) {
        if (!o.count(key)) return fallback;
        const double t = parseNumber(o[key], key == "from" ? "--from" : "--to");
        if (!(t >= 0)) throw UsageError("--" + key + " must be a time in seconds, 0 or more");
        long step = 0;
        for (const auto& s : replayed.timeline)
          if (s.time <= t + 1e-9) step = s.step;
        return step;
      };
      const long from = stepAt("from", 0), to = stepAt("to", replayer.steps());
      if (from >= to) throw UsageError("--from must come before --to within the session (" + std::to_string(replayed.metrics.durationS) + " s)");
      const int frames = writeReviewVideo(replayer, renderer, replayed.timeline, from, to, fps, o["video"]);
      std::printf("video: %d frames of %dx%d at %g fps (steps %ld to %ld) written to %s\n", frames, renderer.camera().width, renderer.camera().height, fps, from, to,
                  o["video"].c_str());
    }
    if (o.count("report")) {
      const ReviewReport report = makeReviewReport(rec, replayed, thresholds, replayer, renderer);
      reportWriter()(report, o["report"]);
      std::printf("report written to %s\n", o["report"].c_str());
    }
  }
  if (!o.count("verify")) {
    // Metrics, a video or a report of a replay that is not the recorded run are written (they say so) but not taken
    // as the trainee's: exit 4, as --verify and --metrics-csv do.
    if (replayed.verify.mismatches) {
      std::fprintf(stderr, "rehearse: session %lld %s\n", static_cast<long long>(id), replayCheckSentence(replayed.verify).c_str());
      return 4;
    }
    return 0;
  }
  const VerifyResult& v = replayed.verify;
  if (v.mismatches) {
    std::fprintf(stderr, "rehearse: session %lld does not replay: %ld of %ld checksums differ, the first after step %ld\n", static_cast<long long>(id), v.mismatches,
                 v.checked, v.firstMismatch);
    return 4;
  }
  if (v.checked == 0) {
    std::fprintf(stderr, "rehearse: session %lld has no checksum to verify against\n", static_cast<long long>(id));
    return 4;
  }
  std::printf("verified: %ld steps replayed, all %ld checksums match\n", v.steps, v.checked);
  return 0;
}

std::string usage() {
  return "Rehearse " REHEARSE_VERSION
         " - intra-operative surgical gesture rehearsal\n\n"
         "Usage:\n"
         "  rehearse                         start the GUI on the built-in phantom case\n"
         "  rehearse open CASE               start the GUI on a case folder\n"
         "  rehearse phantom --out DIR [--tets N] [--seed S]\n"
         "                                   write the built-in phantom case as ordinary files\n"
         "  rehearse mesh --in SURFACE --out VOLUME.msh|.vtk|.vtu [--target-tets N] [--size MM]\n"
         "                [--unit m|dm|cm|mm] [--ascii] [--allow-self-intersections]\n"
         "                                   tetrahedralise a closed surface (inner closed parts become labels)\n"
         "  rehearse info FILE [--unit m|dm|cm|mm]\n"
         "                                   node, element and label counts, bounds and quality\n"
         "  rehearse simulate --scene S.json | --preset eye|kidney|liver|uterus|sofa-liver | --mesh FILE [--unit u]\n"
         "                [--material linear|corotational|stvk|neohookean|neohookean-split] [--young PA] [--poisson NU]\n"
         "                [--density KG_M3] [--vessel-young PA]\n"
         "                [--fixed-nodes \"i j k\"|FILE] [--gravity X,Y,Z] [--steps N] [--dt H] [--static]\n"
         "                [--solver cholmod|cg|dense] [--method exact|lagged-pcg|chord|linearised]\n"
         "                [--factor supernodal|simplicial] [--attachments projection|lagrange]\n"
         "                --out OUT.vtu|.vtk [--report R.json]\n"
         "  rehearse simulate --list-components   the scene components and their parameters\n"
         "                                   FEM simulation (implicit Euler or static); nodes keep the input order\n"
         "  rehearse register --mesh VOLUME | --scene S.json | --preset NAME [--unit u] --camera CAM --contour C.json\n"
         "                --pose P0.json --out REGISTERED.vtu|.vtk [--pose-out P.json] [--report R.json]\n"
         "                [--ground-truth GT.vtu|.vtk] [--no-rigid-prepass] [--rigid-only] [--iterations N]\n"
         "                [--image-size WxH] [--distorted-contour] [--gravity-camera X,Y,Z] [material flags of simulate]\n"
         "                                   fit the organ onto a sketched silhouette (nodes written in the camera frame);\n"
         "                                   the organ's sag under a steady load is estimated with its pose (held organs;\n"
         "                                   --gravity-camera: which way is down in the camera frame, m/s^2, when known);\n"
         "                                   ridges and ligaments with their curve on the organ (P2ILF modelPoints, our\n"
         "                                   model_vertices: node indices, or surface vertices when --mesh is a surface)\n"
         "                                   are held onto their image curves too. Exit 0: a determined fit;\n"
         "                                   4: ambiguous (the best fit is written; the report names the other\n"
         "                                   poses that fit the contour nearly as well); 3: failed\n"
         "  rehearse appearance --case DIR | --mesh M [--unit u] --camera CAM --pose P.json --image FRAME --out THETA.json\n"
         "                [--report R.json] [--inpaint telea|ns|shiftmap|fsr] [--background IB.png] [--diffuse ID.png]\n"
         "                                   estimate the light and the organ's reflectance from the frame (step 6);\n"
         "                                   exit 4 when the model explains too little (texture mapping only)\n"
         "  rehearse compose --case DIR | --mesh M [--unit u] --camera CAM --pose P.json --image FRAME --theta THETA.json\n"
         "                [--deformed DEFORMED.vtu|.vtk] --out J.png [--inpaint telea|ns|shiftmap|fsr]\n"
         "                                   the organ (deformed: its nodes in the input order) re-shaded in the frame\n"
         "  rehearse gesture --case DIR | --scene S.json | --preset NAME | --mesh M [--unit u] [material flags of simulate]\n"
         "                --script G.json --out OUT.vtu|.vtk|.msh [--report R.json] [--method exact|lagged-pcg|chord|linearised]\n"
         "                [--refresh sync|async]  async: a drifted lagged factorisation is rebuilt on a second thread and\n"
         "                                   swapped in when ready (the steps never wait for it)\n"
         "                                   a scripted rehearsal (timed grasper events: tip, move, jaws) run through the\n"
         "                                   simulation session without a window; the report has a row per step (wall time,\n"
         "                                   mass, elements, nodes, grasped nodes, tool force, events); exit 3 when a step failed\n"
         "                [--record CASE [--trainee NAME] [--notes TEXT]]  the session (setup, events, a state checksum every\n"
         "                                   10 steps) written into CASE (a .rehearse file) as it runs\n"
         "  rehearse replay CASE [--session ID [--verify] [--metrics OUT.json] [--video OUT.mp4] [--report OUT.pdf]\n"
         "                [--from S] [--to S] [--fps N] [--size WxH] | --metrics-csv OUT.csv] [--force-threshold N]\n"
         "                [--thresholds T.json] [--planned-cut X,Y,Z:X,Y,Z]\n"
         "                                   the sessions recorded in CASE; --verify re-simulates one and compares every\n"
         "                                   recorded checksum (exit 4 when one differs); --metrics writes the session's\n"
         "                                   duration, path length, economy of motion, grasps, slips, cuts, forces, the\n"
         "                                   time over the force threshold (10 N by default), the largest tissue strain, the\n"
         "                                   cut's length and deviation from a planned line (m), structures damaged, and a\n"
         "                                   pass/fail per metric of T.json ({\"max_force_n\": {\"max\": 15}}); --video: the\n"
         "                                   span [--from, --to] s as MP4 (25 fps of simulated time, 640x480 unless given);\n"
         "                                   --report: a PDF with the metrics, their plots and key frames; --metrics-csv:\n"
         "                                   every session's metrics, one row each (exit 4 when a replay differs); CASE\n"
         "                                   postgresql:[SERVICE] reads the training database instead (below)\n"
         "  rehearse publish CASE... [--service NAME]\n"
         "                                   publish the complete sessions of case files into the training database\n"
         "                                   (PostgreSQL; the connection from the libpq service NAME or the environment:\n"
         "                                   PGHOST, PGPORT, PGDATABASE, PGUSER, PGPASSFILE, PGSSLMODE); idempotent: a\n"
         "                                   session already there is not written again; each is replayed and verified first\n"
         "  rehearse --help | --version\n\n"
         "GUI options: --screenshot PNG (save the window and quit), --software (no OpenGL), --opengl (OpenGL even\n"
         "  through a software rasteriser such as llvmpipe, which is otherwise not used)\n"
         "Mesh formats: .msh (Gmsh 1, 2.2, 4.1), .vtk (legacy), .vtu, .mesh (Medit), .obj .stl .ply .off .gltf .glb.\n"
         "Lengths are metres unless --unit says otherwise.\n";
}

int runCli(const std::vector<std::string>& args, bool& handled) {
  handled = true;
  if (args.size() < 2 || args[1] == "open" || (args[1].rfind("--", 0) == 0 && args[1] != "--help" && args[1] != "--version" &&
                                               args[1] != "-h")) {
    handled = false;
    return 0;
  }
  const std::string& cmd = args[1];
  try {
    if (cmd == "--help" || cmd == "-h" || cmd == "help") {
      std::printf("%s", usage().c_str());
      return 0;
    }
    if (cmd == "--version") {
      std::printf("rehearse %s\n", REHEARSE_VERSION);
      return 0;
    }
    if (cmd == "phantom") return cmdPhantom(args);
    if (cmd == "mesh") return cmdMesh(args);
    if (cmd == "info") return cmdInfo(args);
    if (cmd == "simulate") return cmdSimulate(args);
    if (cmd == "register") return cmdRegister(args);
    if (cmd == "appearance") return cmdAppearance(args);
    if (cmd == "compose") return cmdCompose(args);
    if (cmd == "gesture") return cmdGesture(args);
    if (cmd == "replay") return cmdReplay(args);
    if (cmd == "publish") return cmdPublish(args);
    throw UsageError("unknown command '" + cmd + "'; see 'rehearse --help'");
  } catch (const UsageError& e) {
    std::fprintf(stderr, "rehearse: %s\n", e.what());
    return 2;
  } catch (const imaging::AppearanceCancelled&) {
    std::fprintf(stderr, "rehearse: cancelled\n");
    return 130;
  } catch (const simcore::Cancelled&) {
    std::fprintf(stderr, "rehearse: cancelled\n");
    return 130;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "rehearse: error: out of memory; try a smaller mesh or target\n");
    return 1;
  } catch (const std::filesystem::filesystem_error& e) {
    // In our words, not the library's ("filesystem error: status: ... [path]").
    std::fprintf(stderr, "rehearse: error: cannot access %s: %s\n", e.path1().string().c_str(), e.code().message().c_str());
    return 1;
  } catch (const nlohmann::json::exception& e) {
    std::fprintf(stderr, "rehearse: error: a JSON input is not in the expected form (%s); see \"File formats\" in the README\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::string msg = e.what();
    for (auto& ch : msg)
      if (ch == '\n') ch = ' ';
    std::fprintf(stderr, "rehearse: error: %s\n", msg.c_str());
    return 1;
  }
}

}  // namespace rehearse::app
