// rehearse simulate: a FEM simulation of a scene, a preset or a mesh, without a window.
#include "support.hpp"

#include <rehearse/simcore/input_ranges.hpp>

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

namespace rehearse::app::cli {

int cmdSimulate(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, simulateCommand());
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
    // --solver cg or dense without a method (here or in the scene): that solver's default, not a refusal.
    if (o.count("solver") && !o.count("method") && !p.methodNamed)
      p.settings.method = simcore::defaultMethodFor(p.settings.solver);
  } catch (const simcore::MeshError& e) {
    throw UsageError(e.what());
  }
  const long steps = o.count("steps") ? parseCount(o["steps"], "--steps", 1, 1'000'000) : p.steps;
  refuseOutOfRange(p.settings, p.defaultMaterial, p.materials);
  if (!p.staticSolve && !o.count("static"))
    if (const std::string why = simcore::runLengthProblem(static_cast<double>(steps), p.settings.timeStep);
        !why.empty())
      throw UsageError(why);
  if (p.staticSolve) o["static"] = "";
  simcore::FemModel model = simcore::FemModel::build(p.mesh, p.materials, p.defaultMaterial, p.embedded);
  simcore::setVolumeBarrier(model, p.settings.volumeBarrier);
  for (const auto& e : model.embeddings)
    if (e.outside)
      std::fprintf(stderr, "rehearse: note: %zu vertices of the embedded surface '%s' lie outside the organ\n",
                   e.outside, e.name.c_str());
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
      steps.push_back({{"step", i},
                       {"wall_ms", r.wallMs},
                       {"newton_iterations", r.newtonIterations},
                       {"residual", r.residual},
                       {"energy", r.energy},
                       {"time_step", r.timeStepUsed},
                       {"retries", r.retries},
                       {"factorisations", r.factorisations},
                       {"ok", r.ok},
                       {"outcome", toString(r.outcome)},
                       {"status", simcore::statusSentence(r)},
                       {"inverted_elements", r.invertedElements},
                       {"min_volume_ratio", r.minVolumeRatio},
                       {"inversion_limited", r.inversionLimited}});
    }
    std::vector<const simcore::StepReport*> all;
    for (const auto& r : reports) all.push_back(&r);
    writeReport(o["report"], {{"steps", steps},
                              {"method", o.count("static") ? "static" : simcore::toString(p.settings.method)},
                              {"statuses", statusCounts(all)}});
  }
  std::size_t failed = 0;
  double wall = 0;
  for (const auto& r : reports) {
    failed += !r.ok;
    wall += r.wallMs;
  }
  std::printf("%s (%s): %zu nodes, %zu tets, %zu %s, %zu failed, mean %.2f ms per %s, written %s\n",
              o.count("static") ? "static" : "dynamic",
              o.count("static") ? "Newton" : simcore::toString(p.settings.method).c_str(), model.nodeCount(),
              model.tets.size(), reports.size(), o.count("static") ? "solve" : "steps", failed, wall / reports.size(),
              o.count("static") ? "solve" : "step", o["out"].c_str());
  std::vector<const simcore::StepReport*> all;
  for (const auto& r : reports) all.push_back(&r);
  return statusSummary(all);
}

const Command& simulateCommand() {
  static const Command command{
      "simulate",
      "  rehearse simulate --scene S.json | --preset eye|kidney|liver|uterus|sofa-liver | --mesh FILE [--unit u]\n"
      "                [--material linear|corotational|stvk|neohookean|neohookean-split] [--young PA] [--poisson "
      "NU]\n"
      "                [--density KG_M3] [--vessel-young PA]\n"
      "                [--fixed-nodes \"i j k\"|FILE] [--gravity X,Y,Z] [--steps N] [--dt H] [--static]\n"
      "                [--solver cholmod|cg|dense] [--method chord|exact|lagged-pcg|linearised|newton-krylov]\n"
      "                [--factor supernodal|simplicial] [--attachments projection|lagrange]\n"
      "                --out OUT.vtu|.vtk [--report R.json]\n"
      "  rehearse simulate --list-components   the scene components and their parameters\n"
      "                                   FEM simulation (implicit Euler or static); nodes keep the input order\n",
      joined(modelOptions(),
             {{"steps", "N", "implicit Euler steps (default 100)"},
              {"dt", "H", "the time step, s"},
              {"static", "", "solve the static equilibrium instead of stepping"},
              {"out", "OUT", "the deformed volume: .vtu, .vtk or .msh"},
              {"report", "R.json", "per-step outcomes, residuals and timings"},
              {"solver", "S", "cholmod, cg or dense"},
              {"method", "M", "chord (default: converged every step), exact, lagged-pcg, linearised or newton-krylov"},
              {"factor", "F", "supernodal or simplicial (CHOLMOD)"},
              {"attachments", "A", "projection or lagrange"},
              {"strict", "", "a step that does not converge fails (rolled back) instead of being kept inexact"},
              {"list-components", "", "print the scene components and their parameters, then stop"}}),
      cmdSimulate};
  return command;
}

}  // namespace rehearse::app::cli
