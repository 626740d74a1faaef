// rehearse gesture: a scripted rehearsal without a window (issue 15), through the simulation session.
#include "support.hpp"

#include <rehearse/simcore/words.hpp>
#include <rehearse/text_input.hpp>

#include "phantom/phantom.hpp"
#include "phantom/presets.hpp"
#include "rehearse/app/casefile.hpp"
#include "rehearse/app/casefolder.hpp"
#include "rehearse/app/elasticfit.hpp"
#include "rehearse/app/appearancestep.hpp"
#include "rehearse/app/gesture.hpp"
#include "rehearse/app/recording.hpp"
#include "rehearse/app/sessionstart.hpp"
#include "rehearse/app/review.hpp"
#include "rehearse/app/materials.hpp"

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/input_ranges.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/inverse_rest.hpp>
#include <rehearse/simcore/support.hpp>
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
#include <limits>
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

// The options checked before anything is read.
Options checkGestureOptions(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, gestureCommand());
  if ((o.count("trainee") || o.count("notes")) && !o.count("record"))
    throw UsageError("--trainee and --notes go with --record CASE");
  if (!o.count("script")) throw UsageError("gesture needs --script G.json (README, File formats)");
  if (!o.count("out")) throw UsageError("gesture needs --out OUT.vtu|.vtk|.msh");
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".vtu" && ext != ".vtk" && ext != ".msh") throw UsageError("--out must end in .vtu, .vtk or .msh");
  return o;
}

GestureScript loadScript(Options& o) {
  std::string scriptText, unreadable;
  if (!readTextInput(o["script"], scriptText, unreadable)) throw UsageError("the gesture script " + unreadable);
  try {
    return parseGestureScript(scriptText);
  } catch (const std::runtime_error& e) {
    throw UsageError(std::string(o["script"]) + ": " + e.what());
  }
}

// --case: the case's organ, attachments and material; `caseSupport` gets its support (Pa/m, its material's).
simcore::BodySetup bodyFromCase(Options& o, simcore::Mesh& mesh, double& caseSupport) {
  for (const char* k :
       {"scene", "preset", "mesh", "material", "young", "poisson", "density", "vessel-young", "fixed-nodes"})
    if (o.count(k))
      throw UsageError(std::string("--case takes the case's organ, attachments and material; --") + k +
                       " cannot be combined with it");
  std::vector<std::string> notes;
  const Case c = loadCase(o["case"], &notes);
  // What the case could not give is said, and a rehearsal without its organ or its ligaments is refused: the organ
  // would hang from nothing (a damaged attachments.json was dropped without a word before).
  for (const auto& n : notes) {
    if (n.rfind("Attachments not loaded", 0) == 0 || n.rfind("Organ mesh not loaded", 0) == 0)
      throw UsageError(o["case"] + ": " + n);
    std::fprintf(stderr, "rehearse: note: %s\n", n.c_str());
  }
  if (c.organ->empty()) throw UsageError(o["case"] + " has no organ mesh");
  simcore::BodySetup setup;
  setup.settings.method = simcore::kInteractiveMethod;  // --method's default, as for scenes and presets without one
  mesh = c.organ->volume;
  setup.fixedNodes = c.attachments;
  caseSupport = c.material.supportModulus;
  const LabelMaterials lm = labelMaterials(c.material);
  setup.material = lm.fallback;
  setup.byLabel = lm.byLabel;
  if (o.count("gravity")) setup.settings.gravity = parseVector(o["gravity"], "--gravity");
  return setup;
}

// --scene, --preset or --mesh with the material flags.
simcore::BodySetup bodyFromModel(Options& o, simcore::Mesh& mesh) {
  simcore::Scene p = modelFromOptions(o, "gesture");
  if (!p.embedded.empty())
    throw UsageError("the scene embeds surfaces (" + p.embedded.front().name +
                     "), which the gesture session does not carry yet; remove them or use simulate");
  simcore::BodySetup setup;
  mesh = p.mesh;
  setup.fixedNodes = p.fixedNodes;
  setup.material = p.defaultMaterial;
  setup.byLabel = p.materials;
  setup.settings = p.settings;
  setup.model = simcore::bodyModelFromString(p.bodyModel);
  return setup;
}

// --model, --method and --refresh.
void applySolverOptions(Options& o, simcore::BodySetup& setup) {
  if (o.count("model")) setup.model = simcore::bodyModelFromString(o["model"]);
  if (o.count("method")) setup.settings.method = simcore::newtonMethodFromString(o["method"]);
  setup.settings.estimateErrorEvery = 1;  // the report's every row (a case's session estimates every 10th step live)
  if (o.count("accuracy")) {  // mm, as the window's Simulation panel asks it
    char* end = nullptr;
    const double mm = std::strtod(o["accuracy"].c_str(), &end);
    if (end == o["accuracy"].c_str() || *end || !(mm >= 0 && mm <= 1e3 * simcore::InputRanges::maxAccuracy))
      throw UsageError("--accuracy takes millimetres from 0 to " + std::to_string(static_cast<int>(
                           1e3 * simcore::InputRanges::maxAccuracy)) +
                       " (0: the relative residual alone), not '" + o["accuracy"] + "'");
    setup.settings.accuracyPosition = 1e-3 * mm;
  }
  if (o.count("refresh")) {
    if (o["refresh"] == "async")  // as the window runs it: no step waits for a factor
      setup.settings.factorRefresh = simcore::FactorRefresh::Asynchronous;
    else if (o["refresh"] != "sync")
      throw UsageError("--refresh takes sync or async, not '" + o["refresh"] + "'");
    if (setup.settings.factorRefresh == simcore::FactorRefresh::Asynchronous &&
        setup.settings.method == simcore::NewtonMethod::Exact)
      throw UsageError(
          "--refresh async rebuilds the lagged factorisation of the chord, lagged-pcg, linearised and newton-krylov "
          "methods; the exact method has none (choose --method)");
  }
}

// The body the script runs on, in metres, its settings and materials in range; `caseSupport` the case's support
// (Pa/m) when the organ comes from a case, else -1.
simcore::BodySetup loadBody(Options& o, double& caseSupport) {
  simcore::Mesh mesh;
  caseSupport = -1;
  simcore::BodySetup setup = o.count("case") ? bodyFromCase(o, mesh, caseSupport) : bodyFromModel(o, mesh);
  applySolverOptions(o, setup);
  refuseOutOfRange(setup.settings, setup.material, setup.byLabel);
  mesh.convertToMetres();
  setup.mesh = mesh;
  return setup;
}

// How the session starts, made as the GUI's Simulation panel makes it (app/sessionstart.hpp): at rest on the mesh as
// given (the default), or in equilibrium there (--start equilibrium: the mesh is where the organ hangs, as registered;
// its rest shape solved first); the tissue around it (--support; in equilibrium by default the case's, else 1e5 Pa/m)
// placed at that shape.
StartOptions startOptions(Options& o, double caseSupport) {
  if (o.count("start") && o["start"] != "rest" && o["start"] != "equilibrium")
    throw UsageError("--start takes rest or equilibrium, not '" + o["start"] + "'");
  StartOptions startAs;
  startAs.inEquilibrium = o.count("start") && o["start"] == "equilibrium";
  // A person's picks (a case's attachments, the window's clicks, or nodes given as a file with --fixed-nodes) hold a
  // lone one with its neighbours on the surface, as the window holds them. A scene's or preset's own held nodes hold
  // as they are written.
  startAs.attachmentPatches = o.count("case") || o.count("fixed-nodes");
  if (startAs.inEquilibrium) startAs.supportModulus = caseSupport >= 0 ? caseSupport : simcore::kDefaultSupportModulus;
  if (o.count("support")) {
    char* end = nullptr;
    const double m = std::strtod(o["support"].c_str(), &end);
    if (end == o["support"].c_str() || *end || !std::isfinite(m) || m < 0 || m > 1e9)
      throw UsageError("--support takes the support's modulus in Pa/m (0 to 1e9; 0: none), not '" + o["support"] + "'");
    startAs.supportModulus = m;
  }
  startAs.progress = [](int k, double error) {
    std::fprintf(stderr, "start: static solve %d, %.3g mm from the shape\n", k, 1e3 * error);
    return true;
  };
  return startAs;
}

// How the body started: its word in the report and its equilibrium's distance from the shape (m; -1 at rest), or the
// exit code when it could not.
struct GestureStart {
  int refused = 0;
  std::string word;
  double error = -1;
};

// `setup` made ready to start. A body nothing holds under gravity, or with no equilibrium at the shape, is not started
// (exit 4).
GestureStart startBody(simcore::BodySetup& setup, const StartOptions& startAs) {
  // A held node the mesh does not have is the input's fault, said in one line (it surfaced as "no rest shape was
  // found: rest shape 1 cannot be simulated (...)", twice).
  for (int n : setup.fixedNodes)
    if (n < 0 || static_cast<std::size_t>(n) >= setup.mesh.points.size()) {
      std::fprintf(stderr, "rehearse: the held nodes name node %d, but the mesh has %zu nodes (numbered from 0)\n", n,
                   setup.mesh.points.size());
      return {1, {}, -1};
    }
  SessionStart prepared = prepareStart(std::move(setup), startAs);
  if (prepared.rest) std::printf("start: %s\n", prepared.rest->status.c_str());
  switch (prepared.outcome) {
    case SessionStart::Outcome::NothingHolds:
      std::fprintf(stderr,
                   "The organ cannot start: nothing holds it under gravity; hold nodes (--fixed-nodes), let the "
                   "tissue around it carry it (--support, the FEM only), or turn gravity off (--gravity 0,0,0).\n");
      return {4, {}, -1};
    case SessionStart::Outcome::NoEquilibrium:
      std::fprintf(stderr, "The organ cannot start in equilibrium on this shape: %s\n", prepared.rest->status.c_str());
      return {4, {}, -1};
    case SessionStart::Outcome::Cancelled:  // (nothing cancels it here)
      return {4, {}, -1};
    case SessionStart::Outcome::Ready:
      break;
  }
  if (const std::string patches = prepared.patchesSentence(); !patches.empty())
    std::printf("held: %s\n", patches.c_str());
  if (prepared.supportNotInModel)
    std::fprintf(stderr, "rehearse: note: the %s model hangs the organ from its held nodes; --support acts in the FEM "
                 "only\n", simcore::bodyModelName(prepared.body.model).c_str());
  setup = std::move(prepared.body);
  const bool inEquilibrium = prepared.start == SessionStart::Start::InEquilibrium;
  GestureStart started;
  started.word = inEquilibrium ? "equilibrium" : "rest";
  started.error = inEquilibrium ? prepared.rest->error : -1;
  return started;
}

// --record: the session (setup, events, a state checksum every 10 steps) written into CASE as it runs, by `recorder`
// (made when the session starts).
GestureHooks recordingHooks(Options& o, const GestureScript& script, std::unique_ptr<Recorder>& recorder) {
  GestureHooks hooks;
  if (!o.count("record")) return hooks;
  SessionMeta meta;
  meta.trainee = o.count("trainee") ? o["trainee"] : "";
  meta.notes = o.count("notes") ? o["notes"] : "";
  meta.caseName = o.count("case")     ? o["case"]
                  : o.count("preset") ? "preset " + o["preset"]
                  : o.count("scene")  ? o["scene"]
                  : o.count("mesh")   ? o["mesh"]
                                      : "";
  meta.sceneVersion = o["script"];
  meta.appVersion = REHEARSE_VERSION;
  meta.rules = script.incorrectActions;
  hooks.start = [&recorder, meta, path = o["record"]](const simcore::BodySetup& s) {
    try {
      recorder = std::make_unique<Recorder>(path, meta, s);
    } catch (const std::runtime_error& e) {
      throw UsageError(e.what());
    }
  };
  hooks.step = [&recorder](const simcore::StepRecord& r) { recorder->afterStep(r); };
  return hooks;
}

// Over the steps: the tool's peak force (N), the wall time (ms) and the most nodes grasped at once.
struct StepTotals {
  double peak = 0, wall = 0;
  std::size_t grasped = 0;
};

StepTotals stepTotals(const GestureResult& r) {
  StepTotals t;
  for (const auto& s : r.steps) {
    t.peak = std::max(t.peak, s.toolForce.norm());
    t.wall += s.wallMs;
    t.grasped = std::max(t.grasped, s.grasped);
  }
  return t;
}

nlohmann::json finiteOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

// The steps' estimated distance from the converged answer (issue 64): the largest, and where.
struct LargestError {
  double position = std::numeric_limits<double>::quiet_NaN(), force = std::numeric_limits<double>::quiet_NaN();
  long step = -1;
  std::size_t notEstimated = 0;
  std::size_t unknown = 0;  // checked on the tangent and found not knowable there (StepReport::errorUnknown)
};
LargestError largestError(const GestureResult& r) {
  LargestError e;
  for (const auto& s : r.steps) {
    if (!std::isfinite(s.report.errorPosition)) {
      ++(s.report.errorUnknown ? e.unknown : e.notEstimated);
      continue;
    }
    if (!(s.report.errorPosition <= e.position)) {
      e.position = s.report.errorPosition;
      e.step = s.step;
    }
    if (std::isfinite(s.report.errorForce) && !(s.report.errorForce <= e.force)) e.force = s.report.errorForce;
  }
  return e;
}

// --report: a row per step, then the session's totals.
void writeGestureReport(const std::string& path, const GestureResult& r, const simcore::BodySetup& setup,
                        const GestureStart& start, double peak) {
  const simcore::Mesh& out = r.finalMesh;
  nlohmann::json rows = nlohmann::json::array();
  for (const auto& s : r.steps)
    rows.push_back({{"step", s.step},
                    {"time_s", s.time},
                    {"wall_ms", s.wallMs},
                    {"mass_kg", s.massKg},
                    {"elements", s.elements},
                    {"nodes", s.nodes},
                    {"grasped_nodes", s.grasped},
                    {"contacts", s.contacts},
                    {"tool_force_n", {s.toolForce.x(), s.toolForce.y(), s.toolForce.z()}},
                    {"tip_m", {s.tip.x(), s.tip.y(), s.tip.z()}},
                    {"events", s.events},
                    {"message", s.message},
                    {"ok", s.report.ok},
                    {"outcome", toString(s.report.outcome)},
                    {"status", simcore::statusSentence(s.report)},
                    {"residual", s.report.residual},
                    {"inverted_elements", s.report.invertedElements},
                    {"min_volume_ratio", s.report.minVolumeRatio},
                    {"factorisations", s.report.factorisations},
                    {"newton_iterations", s.report.newtonIterations},
                    {"retries", s.report.retries},
                    {"inversion_limited", s.report.inversionLimited},
                    {"constraint_violation_m", s.report.constraintViolation},
                    {"factor_requested", s.report.factorRequested},
                    {"factor_swapped", s.report.factorSwapped},
                    {"error_m", finiteOrNull(s.report.errorPosition)},
                    {"error_unknown", s.report.errorUnknown},
                    {"force_error_n", finiteOrNull(s.report.errorForce)}});
  std::vector<const simcore::StepReport*> all;
  for (const auto& s : r.steps) all.push_back(&s.report);
  const LargestError largest = largestError(r);
  writeReport(path,
              {{"steps", rows},
               {"model", simcore::bodyModelName(setup.model)},
               {"method", simcore::toString(setup.settings.method)},
               {"refresh", setup.settings.factorRefresh == simcore::FactorRefresh::Asynchronous ? "async" : "sync"},
               {"start", start.word},
               {"start_error_m", start.error >= 0 ? nlohmann::json(start.error) : nlohmann::json(nullptr)},
               {"supported_nodes", setup.supports.size()},
               {"statuses", statusCounts(all)},
               {"slips", r.events.slips},
               {"cuts", r.events.cuts},
               {"vessel_cuts", setup.mesh.namesAVessel() ? nlohmann::json(r.events.vesselCuts) : nlohmann::json(nullptr)},
               {"clips", r.events.clips},
               {"misplaced_clips", r.events.misplacedClips},
               {"bleedings", r.events.bleedings},
               {"blood_loss_ml", 1e6 * r.bloodLoss},
               {"burns", r.events.burns},
               {"energy_on_structures", r.events.energyOnStructures},
               {"tears", r.events.tears},
               {"attachments_torn", r.events.attachmentsTorn},
               {"failed_steps", r.failed},
               {"peak_tool_force_n", peak},
               {"elements", out.tets.size()},
               {"nodes", out.points.size()},
               {"contact_queries", r.contactQueries},
               {"largest_error_m", finiteOrNull(largest.position)},
               {"largest_force_error_n", finiteOrNull(largest.force)},
               {"steps_not_estimated", largest.notEstimated},
               {"steps_error_unknown", largest.unknown}});
}

// The session's line on stdout.
void printGestureSummary(const std::string& outPath, const GestureResult& r, const simcore::BodySetup& setup,
                         const StepTotals& t) {
  const simcore::Mesh& out = r.finalMesh;
  using simcore::quantity;
  const std::string vessels = setup.mesh.namesAVessel()
                                  ? quantity(static_cast<std::size_t>(r.events.vesselCuts), "vessel cut", "vessel cuts")
                                  : "vessels unknown (the mesh names none)";
  std::printf(
      "gesture (%s): %zu steps (%.2f ms mean), up to %s grasped, peak tool force %.2f N, %s, %s, %s, %s (%d "
      "misplaced), %.2f mL of blood lost, %s, %zu failed steps; %zu elements, %zu nodes written to %s\n",
      (setup.model == simcore::BodyModel::Fem ? simcore::toString(setup.settings.method)
                                              : simcore::bodyModelName(setup.model) + " model")
          .c_str(),
      r.steps.size(), t.wall / static_cast<double>(r.steps.size()), quantity(t.grasped, "node", "nodes").c_str(), t.peak,
      quantity(static_cast<std::size_t>(r.events.slips), "slip", "slips").c_str(),
      quantity(static_cast<std::size_t>(r.events.cuts), "cut update", "cut updates").c_str(), vessels.c_str(),
      quantity(static_cast<std::size_t>(r.events.clips), "clip", "clips").c_str(), r.events.misplacedClips,
      1e6 * r.bloodLoss, quantity(static_cast<std::size_t>(r.events.tears), "tear", "tears").c_str(), r.failed,
      out.tets.size(), out.points.size(),
      outPath.c_str());
  const LargestError e = largestError(r);
  if (std::isfinite(e.position))
    std::printf("estimated error against the converged answer: at most %.3g mm (step %ld), tool force within %.3g N%s%s\n",
                1e3 * e.position, e.step, std::isfinite(e.force) ? e.force : 0.0,
                e.notEstimated ? ("; " + std::to_string(e.notEstimated) + " steps not estimated").c_str() : "",
                e.unknown ? ("; " + std::to_string(e.unknown) +
                             " steps' distance not known (an indefinite tangent, or the contacts changing)")
                                .c_str()
                          : "");
  else if (e.unknown > 0)
    std::printf("estimated error against the converged answer: not known (%zu steps checked on the tangent: an "
                "indefinite tangent, or the contacts changing)\n",
                e.unknown);
  else
    std::printf("estimated error against the converged answer: not estimated (%s)\n",
                setup.model != simcore::BodyModel::Fem ? "a reduced model's steps have no residual to estimate it from"
                                                       : "no factor to estimate it with");
}

// The steps' outcomes (statusSummary prints them); exit 3 when a step failed.
int gestureExit(const GestureResult& r) {
  std::vector<const simcore::StepReport*> all;
  for (const auto& s : r.steps) all.push_back(&s.report);
  const int code = statusSummary(all);
  // A cut refused or another input the session turned down is not a step's failure: r.failed counts steps not taken.
  return r.failed ? 3 : code;
}

}  // namespace

int cmdGesture(const std::vector<std::string>& args) {
  Options o = checkGestureOptions(args);
  const GestureScript script = loadScript(o);
  double caseSupport = -1;  // Pa/m: the case's support (its material), when the organ comes from a case
  simcore::BodySetup setup = loadBody(o, caseSupport);
  const GestureStart start = startBody(setup, startOptions(o, caseSupport));
  if (start.refused) return start.refused;
  std::unique_ptr<Recorder> recorder;
  const GestureHooks hooks = recordingHooks(o, script, recorder);
  const GestureResult r = runGesture(setup, script, hooks);
  if (recorder) {
    recorder->finish(static_cast<long>(r.steps.size()));
    std::printf("recorded: session %lld in %s (%zu steps)\n", static_cast<long long>(recorder->id()),
                o["record"].c_str(), r.steps.size());
  }
  simcore::saveMesh(r.finalMesh, o["out"]);
  const StepTotals totals = stepTotals(r);
  if (o.count("report")) writeGestureReport(o["report"], r, setup, start, totals.peak);
  printGestureSummary(o["out"], r, setup, totals);
  return gestureExit(r);
}

const Command& gestureCommand() {
  static const Command command{
      "gesture",
      "  rehearse gesture --case CASE | --scene S.json | --preset NAME | --mesh M [--unit u] [material flags of "
      "simulate]\n"
      "                --script G.json --out OUT.vtu|.vtk|.msh [--report R.json] [--method "
      "chord|exact|lagged-pcg|linearised|newton-krylov]\n"
      "                [--model fem|precomputed|hybrid|ffd]\n"
      "                [--start rest|equilibrium] [--refresh sync|async]  async: a drifted lagged factorisation is "
      "rebuilt on a second thread "
      "and\n"
      "                                   swapped in when ready (the steps never wait for it)\n"
      "                                   a scripted rehearsal (timed grasper events: tip, move, jaws) run through "
      "the\n"
      "                                   simulation session without a window; the report has a row per step (wall "
      "time,\n"
      "                                   mass, elements, nodes, grasped nodes, tool force, events); exit 3 when a "
      "step failed\n"
      "                [--record CASE [--trainee NAME] [--notes TEXT]]  the session (setup, events, a state checksum "
      "every\n"
      "                                   10 steps) written into CASE (a .rehearse file) as it runs\n",
      joined(joined({{"case", "CASE", "a case file's (.rehearse) or case folder's organ, attachments and material"}}, modelOptions()),
             {{"script", "G.json", "the timed instrument events (README, File formats)"},
              {"out", "OUT", "the volume at the end: .vtu, .vtk or .msh"},
              {"report", "R.json", "a row per step: wall time, mass, elements, tool force, events, outcome"},
              {"method", "M", "chord (default: converged every step), exact, lagged-pcg, linearised or newton-krylov"},
              {"model", "M",
               "fem (default); precomputed: Cotin's precomputed linear elasticity (quasi-static, exact for the "
               "linear law; it cannot cut, tear, clip or burn: said); hybrid: a FEM region where the instruments work "
               "and the rest's precomputed responses (quasi-static, linear; it cuts); ffd: the surface's geometry "
               "image with free-form deformation and Hertz's force (geometric; it cannot cut: said)"},
              {"refresh", "R", "sync or async: how a drifted lagged factorisation is rebuilt"},
              {"accuracy", "MM",
               "each step ends once every node is estimated within MM of the converged answer and the tool force "
               "within 0.5 %; default: the scene's, else the relative residual alone"},
              {"start", "S",
               "rest (the mesh is the rest shape; default) or equilibrium (the mesh is where the organ hangs under "
               "gravity on its attachments, as registered: its rest shape is solved first; exit 4 when none is found)"},
              {"support", "PA_PER_M",
               "the tissue around the organ carries it, an elastic foundation under the surface facing along gravity "
               "with this modulus, placed at the starting shape (with --start equilibrium default the case's or 1e5 "
               "Pa/m, support.hpp; with --start rest default 0; 0: only the held nodes hold it)"},
              {"record", "CASE", "record the session into CASE (a .rehearse file) as it runs"},
              {"trainee", "NAME", "the trainee the recording names (with --record)"},
              {"notes", "TEXT", "notes kept with the recording (with --record)"}}),
      cmdGesture};
  return command;
}

}  // namespace rehearse::app::cli
