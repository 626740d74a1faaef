// Benchmark of every deformable model against one reference (issue 37; not a test): the same scripted poke (5 mm into
// the organ) and pull (15 mm out of it) of the surface patch nearest the camera (the nodes within 10 mm of the front
// point, a grasper's jaws), on the liver preset's surface and on the patient liver's CT surface (../shared/data,
// scikit-surgery), each hung by its highest 8 % of surface nodes under gravity, the preset's tissue. Models: the FEM
// with the linear, co-rotational, StVK and Neo-Hookean laws (each solved to static equilibrium by Newton, CHOLMOD), the
// precomputed linear elasticity (superposition) and the parameterized mesh (81 x 81 geometry image, Gaussian FFD,
// Hertz's force) and the hybrid model (a 40 mm FEM region around the patch, the rest condensed through its responses;
// uncut), each at two or three resolutions. Reference: the Neo-Hookean law
// on the finest mesh. For each: the update's time (the FEM's static solve from the sagged organ to the new tool
// position: what its converged answer costs; the fast models' update, median of repeats), whether it converged, the
// tool-induced surface displacement's error against the reference at the reference's surface nodes (relative RMS; the
// displacement beyond the sag, interpolated in each model's elements, the FFD's from its nearest grid vertex) and the
// tool force's error (relative). Writes models.csv, a log-log plot of error against time per organ
// (models-<organ>.png), and prints the models no other beats on both axes (the Pareto front).
//   bench_models [OUT_DIR [ORGAN]]   (ORGAN: "liver preset" or "patient liver"; both by default)
#include "plot.hpp"
#include "realorgan.hpp"
#include "session_inputs.hpp"

#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/hybrid.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/paramesh.hpp>
#include <rehearse/simcore/precomputed.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

const Eigen::Vector3d kGravity(0, 9.81, 0);
const double kPatch = 0.010;  // m: the held patch's radius (a grasper's jaws on a fold; 6 mm held 2-4 nodes, whose
                              // count, changing with the mesh, decided the force more than the model did)
struct Action {
  const char* name;
  Eigen::Vector3d d;
};
// (8 mm turned an element of the patient liver's reference inside out under the patch: 5 mm keeps it a valid reference)
const Action kActions[] = {{"poke", Eigen::Vector3d(0, 0, 0.005)}, {"pull", Eigen::Vector3d(0, 0, -0.015)}};

// A model's answer to one action: the tool-induced displacement at the reference's sample points and the tool's force
// on the tissue.
struct Answer {
  std::vector<Eigen::Vector3d> du;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  double ms = 0;
  bool converged = false;
  std::string status;  ///< the static solve's sentence when it did not converge
};

struct Row {
  std::string organ, model;
  std::size_t tets = 0;
  double ms = 0, surfaceError = 0, forceError = 0;
  bool converged = true;
};

std::vector<int> patchNear(const Mesh& mesh, const std::vector<int>& surface, const std::vector<char>& fixed,
                           const Eigen::Vector3d& front) {
  std::vector<int> held;
  int nearest = -1;
  for (int v : surface) {
    if (fixed[static_cast<std::size_t>(v)]) continue;
    const double d = (mesh.points[static_cast<std::size_t>(v)] - front).norm();
    if (d <= kPatch) held.push_back(v);
    if (nearest < 0 || d < (mesh.points[static_cast<std::size_t>(nearest)] - front).norm()) nearest = v;
  }
  if (held.empty()) held.push_back(nearest);
  return held;
}

struct Meshed {
  Mesh mesh;
  std::vector<char> fixed;
  std::vector<int> fixedNodes, surface, held;
};

Meshed meshAt(const Mesh& surface, std::size_t tets, const Eigen::Vector3d& front) {
  TetrahedraliseOptions to;
  to.allowSelfIntersections = true;
  to.targetTets = tets;
  Meshed m;
  m.mesh = tetrahedraliseSurface(surface, to);
  m.fixed.assign(m.mesh.points.size(), 0);
  m.fixedNodes = testing::highestSurfaceNodes(m.mesh, 0.08);
  for (int v : m.fixedNodes) m.fixed[static_cast<std::size_t>(v)] = 1;
  m.surface = testing::surfaceNodes(m.mesh);
  m.held = patchNear(m.mesh, m.surface, m.fixed, front);
  return m;
}

// The FEM with `law`: static equilibrium under gravity (the sag), then with the held patch moved by each action.
std::vector<Answer> femAnswers(const Meshed& m, MaterialParams material, MaterialModel law,
                               const std::vector<Eigen::Vector3d>& samples) {
  material.model = law;
  const FemModel model = FemModel::build(m.mesh, {}, material);
  SimulationSettings settings;
  settings.gravity = kGravity;
  settings.tolerance = 1e-8;
  settings.maxNewtonIterations = 60;  // (10, the stepping's budget, left the reference's 8 mm poke unconverged)
  Integrator sagging(model, m.fixedNodes, settings);
  SimulationState sag = sagging.initialState();
  const StepReport sagReport = sagging.solveStatic(sag);
  const SurfaceEmbedding at = embedPoints(model, samples);
  const std::vector<Eigen::Vector3d> sagged = mapEmbedded(at, sag.x);
  std::vector<int> held = m.fixedNodes;
  held.insert(held.end(), m.held.begin(), m.held.end());
  std::vector<Answer> answers;
  for (const Action& a : kActions) {
    Integrator pulling(model, held, settings);
    SimulationState st = pulling.initialState();
    st.x = sag.x;
    for (int v : m.held) st.x.segment<3>(3 * v) += a.d;
    const auto t0 = Clock::now();
    const StepReport rep = pulling.solveStatic(st);
    Answer ans;
    ans.ms = msSince(t0);
    ans.converged = sagReport.outcome == StepStatus::Converged && rep.outcome == StepStatus::Converged;
    if (!ans.converged) ans.status = statusSentence(sagReport.outcome == StepStatus::Converged ? rep : sagReport);
    const std::vector<Eigen::Vector3d> now = mapEmbedded(at, st.x);
    for (std::size_t i = 0; i < samples.size(); ++i) ans.du.push_back(now[i] - sagged[i]);
    // The tool's force on the tissue: what balances the material and gravity at the held nodes.
    const Eigen::VectorXd f = elasticForces(model, st.x);
    for (int v : m.held) ans.force -= f.segment<3>(3 * v) + model.lumpedMass[v] * kGravity;
    answers.push_back(std::move(ans));
  }
  return answers;
}

// A superposed model's answers (precomputed, hybrid): `solve(held, displacement, u, forces)` gives the static
// displacement from rest (3n) with the held nodes displaced from rest and their forces; `held` are the nodes it holds
// (the patch, or what of it the model can hold: `wholePatch` says whether that is all of it). The sag is its answer
// with nothing held; each action moves the held nodes from their sagged places; the update is one solve (median of
// `repeat`).
using SuperposedSolve = std::function<bool(const std::vector<int>&, const std::vector<Eigen::Vector3d>&,
                                           Eigen::VectorXd&, std::vector<Eigen::Vector3d>*)>;
std::vector<Answer> superposedAnswers(const FemModel& model, const std::vector<int>& held, bool wholePatch,
                                      const SuperposedSolve& solve, int repeat,
                                      const std::vector<Eigen::Vector3d>& samples) {
  std::vector<Answer> answers;
  Eigen::VectorXd sag;
  if (!solve({}, {}, sag, nullptr)) return answers;
  const SurfaceEmbedding at = embedPoints(model, samples);
  const std::vector<Eigen::Vector3d> sagged = mapEmbedded(at, Eigen::VectorXd(model.restVector() + sag));
  for (const Action& a : kActions) {
    std::vector<Eigen::Vector3d> disp;
    for (int v : held) disp.push_back(sag.segment<3>(3 * v) + a.d);
    Eigen::VectorXd u;
    std::vector<Eigen::Vector3d> forces;
    std::vector<double> times;
    Answer ans;
    for (int k = 0; k < repeat; ++k) {
      const auto t0 = Clock::now();
      ans.converged = solve(held, disp, u, &forces) && wholePatch;
      times.push_back(msSince(t0));
    }
    std::sort(times.begin(), times.end());
    ans.ms = times[times.size() / 2];
    const std::vector<Eigen::Vector3d> now = mapEmbedded(at, Eigen::VectorXd(model.restVector() + u));
    for (std::size_t i = 0; i < samples.size(); ++i) ans.du.push_back(now[i] - sagged[i]);
    for (const auto& f : forces) ans.force += f;
    answers.push_back(std::move(ans));
  }
  return answers;
}

std::vector<Answer> precomputedAnswers(const Meshed& m, MaterialParams material,
                                       const std::vector<Eigen::Vector3d>& samples) {
  material.model = MaterialModel::Linear;
  const FemModel model = FemModel::build(m.mesh, {}, material);
  std::vector<int> driven;
  for (int v : m.surface)
    if (!m.fixed[static_cast<std::size_t>(v)]) driven.push_back(v);
  std::string why;
  const auto pc = PrecomputedElasticity::build(model, m.fixed, driven, kGravity, {}, why);
  if (!pc) {
    std::printf("precomputed: %s\n", why.c_str());
    return {};
  }
  return superposedAnswers(
      model, m.held, true,
      [&](const std::vector<int>& held, const std::vector<Eigen::Vector3d>& d, Eigen::VectorXd& u,
          std::vector<Eigen::Vector3d>* forces) { return pc->solve(held, d, u, forces, why); },
      21, samples);
}

// The hybrid model: a FEM region of the elements whose centre lies within 40 mm of the front, the rest condensed onto
// the interface through its precomputed responses (uncut: the linear FEM's answer); its update is the region's solve.
std::vector<Answer> hybridAnswers(const Meshed& m, MaterialParams material, const Eigen::Vector3d& front,
                                  const std::vector<Eigen::Vector3d>& samples) {
  material.model = MaterialModel::Linear;
  const FemModel model = FemModel::build(m.mesh, {}, material);
  std::vector<char> region(model.tets.size(), 0);
  for (std::size_t e = 0; e < model.tets.size(); ++e) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int v : model.tets[e]) c += model.rest[static_cast<std::size_t>(v)] / 4;
    region[e] = (c - front).norm() <= 0.040;
  }
  std::string why;
  const auto h = HybridElasticity::build(model, m.fixed, region, kGravity, why);
  if (!h) {
    std::printf("hybrid: %s\n", why.c_str());
    return {};
  }
  std::vector<int> held;
  for (int v : m.held)
    if (h->inRegion(v)) held.push_back(v);
  return superposedAnswers(
      model, held, held.size() == m.held.size(),
      [&](const std::vector<int>& nodes, const std::vector<Eigen::Vector3d>& d, Eigen::VectorXd& u,
          std::vector<Eigen::Vector3d>* forces) { return h->solve(nodes, d, u, forces, why); },
      11, samples);
}

std::vector<Answer> ffdAnswers(const Mesh& surface, int size, double radius, const MaterialParams& material,
                               const Eigen::Vector3d& front, const std::vector<Eigen::Vector3d>& samples) {
  GeometryImageSettings gs;
  gs.size = size;
  gs.maxSize = size;  // (the resolution asked for, never grown)
  std::string why;
  const auto gi = makeGeometryImage(surface.points, surface.triangles, gs, why);
  std::vector<Answer> answers;
  if (!gi) {
    std::printf("FFD %d x %d: %s\n", size, size, why.c_str());
    return answers;
  }
  FfdSettings fs;
  fs.youngModulus = material.young;
  fs.poisson = material.poisson;
  fs.toolRadius = kPatch;  // the jaws' patch
  fs.radius = radius;
  ParameterizedMesh pm(*gi, fs);
  const int v = pm.nearestVertex(front);
  // Each sample's nearest grid vertex (at rest).
  std::vector<int> nearest;
  for (const auto& s : samples) {
    int best = 0;
    for (std::size_t k = 1; k < gi->points.size(); ++k)
      if ((gi->points[k] - s).squaredNorm() < (gi->points[static_cast<std::size_t>(best)] - s).squaredNorm())
        best = static_cast<int>(k);
    nearest.push_back(best);
  }
  for (const Action& a : kActions) {
    Answer ans;
    std::vector<double> times;
    ParameterizedMesh::Contact c;
    for (int k = 0; k < 201; ++k) {
      const auto t0 = Clock::now();
      c = pm.hold(v, a.d);
      times.push_back(msSince(t0));
    }
    std::sort(times.begin(), times.end());
    ans.ms = times[times.size() / 2];
    ans.converged = !c.clamped;
    for (int k : nearest)
      ans.du.push_back(pm.positions()[static_cast<std::size_t>(k)] - gi->points[static_cast<std::size_t>(k)]);
    ans.force = -c.force;
    pm.release();
    answers.push_back(std::move(ans));
  }
  return answers;
}

double rms(const std::vector<Eigen::Vector3d>& v) {
  double s = 0;
  for (const auto& x : v) s += x.squaredNorm();
  return std::sqrt(s / std::max<std::size_t>(1, v.size()));
}

// An organ's surface, by name.
struct Organ {
  std::string name;
  Mesh surface;
};

// The organs: the liver preset's surface, and the patient's liver when ../shared/data has it.
std::vector<Organ> organsOf(const BodySetup& preset) {
  std::vector<Organ> organs;
  {
    Mesh s;
    s.points = preset.rest.empty() ? preset.mesh.points : preset.rest;
    s.triangles = boundaryTriangles(preset.mesh, false);
    s.triangleLabels.assign(s.triangles.size(), 1);
    s.compact();
    organs.push_back({"liver preset", s});
  }
  const std::string patient = std::string(REHEARSE_SHARED_DATA) + "/scikit-surgery/patient-liver/liver.vtk";
  if (std::filesystem::exists(patient))
    organs.push_back({"patient liver", testing::loadOrganSurface(patient)});
  else
    std::printf("%s is absent: skipped\n", patient.c_str());
  return organs;
}

// One organ: the Neo-Hookean reference, then every model at every resolution against it (a line, a row and a Row
// each); the self-checks' failures counted.
void benchOrgan(const Organ& organ, const MaterialParams& material, bool quick, std::ofstream& csv,
                std::vector<Row>& rows, int& failures) {
  // The front: the surface point nearest the camera (smallest z).
  Eigen::Vector3d front(0, 0, 1e9);
  for (const auto& t : organ.surface.triangles)
    for (int v : t)
      if (organ.surface.points[static_cast<std::size_t>(v)].z() < front.z())
        front = organ.surface.points[static_cast<std::size_t>(v)];
  const auto t0 = Clock::now();
  const Meshed ref = meshAt(organ.surface, quick ? 6000 : 24000, front);
  std::vector<Eigen::Vector3d> samples;
  for (int v : ref.surface)
    if (!ref.fixed[static_cast<std::size_t>(v)]) samples.push_back(ref.mesh.points[static_cast<std::size_t>(v)]);
  const std::vector<Answer> truth = femAnswers(ref, material, MaterialModel::NeoHookean, samples);
  std::printf(
      "%s: reference Neo-Hookean on %zu elements (%zu held nodes, %zu surface samples) in %.1f s: poke %.3f N "
      "%s, pull %.3f N %s\n",
      organ.name.c_str(), ref.mesh.tets.size(), ref.held.size(), samples.size(), 1e-3 * msSince(t0),
      truth[0].force.norm(), truth[0].converged ? "converged" : ("NOT converged: " + truth[0].status).c_str(),
      truth[1].force.norm(), truth[1].converged ? "converged" : ("NOT converged: " + truth[1].status).c_str());
  std::fflush(stdout);
  for (const Answer& a : truth)
    if (!a.converged) {
      std::printf("the reference did not converge: the errors below are against no solution\n");
      ++failures;
    }
  auto report = [&](const std::string& model, std::size_t tets, const std::vector<Answer>& answers) {
    if (answers.size() != std::size(kActions)) return;
    Row row{organ.name, model, tets, 0, 0, 0, true};
    for (std::size_t k = 0; k < answers.size(); ++k) {
      std::vector<Eigen::Vector3d> diff;
      for (std::size_t i = 0; i < samples.size(); ++i) diff.push_back(answers[k].du[i] - truth[k].du[i]);
      const double se = rms(diff) / rms(truth[k].du);
      const double fe = (answers[k].force - truth[k].force).norm() / truth[k].force.norm();
      csv << organ.name << ",\"" << model << "\"," << tets << ',' << kActions[k].name << ',' << answers[k].ms << ','
          << 1e3 / answers[k].ms << ',' << answers[k].converged << ',' << se << ',' << fe << ','
          << answers[k].force.norm() << ',' << truth[k].force.norm() << '\n';
      row.ms += answers[k].ms / static_cast<double>(answers.size());
      row.surfaceError += se / static_cast<double>(answers.size());
      row.forceError += fe / static_cast<double>(answers.size());
      row.converged = row.converged && answers[k].converged;
    }
    if (!std::isfinite(row.ms) || !std::isfinite(row.surfaceError) || !std::isfinite(row.forceError)) {
      std::printf("  %s: a result is not finite\n", model.c_str());
      ++failures;
    }
    std::printf("  %-28s %6zu tets: update %9.4f ms (%8.0f Hz), surface error %6.1f %%, force error %6.1f %%%s\n",
                model.c_str(), tets, row.ms, 1e3 / row.ms, 100 * row.surfaceError, 100 * row.forceError,
                row.converged ? "" : " (not converged)");
    std::fflush(stdout);
    rows.push_back(row);
  };
  for (const std::size_t target :
       quick ? std::vector<std::size_t>{2000} : std::vector<std::size_t>{2000, 6000, 12000}) {
    const Meshed m = meshAt(organ.surface, target, front);
    // The linear FEM once: reported, and what the precomputed and (uncut) hybrid models must equal to round-off on
    // the same mesh (a self-check: a difference over 1e-6 fails the run).
    const std::vector<Answer> linear = femAnswers(m, material, MaterialModel::Linear, samples);
    report("FEM linear", m.mesh.tets.size(), linear);
    for (const auto& [law, name] :
         std::vector<std::pair<MaterialModel, const char*>>{{MaterialModel::Corotational, "FEM co-rotational"},
                                                            {MaterialModel::StVK, "FEM StVK"},
                                                            {MaterialModel::NeoHookean, "FEM Neo-Hookean"}})
      report(name, m.mesh.tets.size(), femAnswers(m, material, law, samples));
    for (const auto& [name, answers] : std::vector<std::pair<std::string, std::vector<Answer>>>{
             {"precomputed linear", precomputedAnswers(m, material, samples)},
             {"hybrid (40 mm FEM region)", hybridAnswers(m, material, front, samples)}}) {
      report(name, m.mesh.tets.size(), answers);
      if (answers.size() != std::size(kActions)) ++failures;
      for (std::size_t k = 0; k < answers.size() && k < linear.size(); ++k) {
        std::vector<Eigen::Vector3d> diff;
        for (std::size_t i = 0; i < samples.size(); ++i) diff.push_back(answers[k].du[i] - linear[k].du[i]);
        const double d = rms(diff) / rms(linear[k].du);
        if (!(d < 1e-6)) {
          std::printf("%s and the linear FEM differ by %.2e on %zu elements (%s)\n", name.c_str(), d,
                      m.mesh.tets.size(), kActions[k].name);
          ++failures;
        }
      }
    }
  }
  for (const int size : quick ? std::vector<int>{41} : std::vector<int>{41, 81, 161})
    report("FFD " + std::to_string(size) + " x " + std::to_string(size), 0,
           ffdAnswers(organ.surface, size, 0.02, material, front, samples));
  report("FFD 81 x 81, radius 60 mm", 0, ffdAnswers(organ.surface, 81, 0.06, material, front, samples));
}

// The plots and the Pareto front per organ (surface error against time; a row beaten on both by another is out).
void plotOrgans(const std::vector<Organ>& organs, const std::vector<Row>& rows, const std::string& out) {
  for (const Organ& organ : organs) {
    if (std::none_of(rows.begin(), rows.end(), [&](const Row& r) { return r.organ == organ.name; })) continue;
    std::map<std::string, PlotSeries> series;
    for (const Row& r : rows)
      if (r.organ == organ.name) {
        std::string family = r.model.substr(0, r.model.find(" x ") == std::string::npos ? r.model.size() : 3);
        auto& s = series[family];
        s.name = family;
        s.x.push_back(r.ms);
        s.y.push_back(r.surfaceError);
      }
    std::vector<PlotSeries> list;
    for (auto& [k, s] : series) list.push_back(s);
    std::string file = organ.name;
    std::replace(file.begin(), file.end(), ' ', '-');
    writeLogLogPlot(out + "/models-" + file + ".png", organ.name + ": surface error against update time",
                    "update time (ms)", "surface displacement error (relative RMS)", list);
    std::printf("%s, not beaten on both time and surface error:", organ.name.c_str());
    for (const Row& r : rows) {
      if (r.organ != organ.name) continue;
      bool beaten = false;
      for (const Row& o : rows)
        if (o.organ == organ.name && &o != &r && o.ms <= r.ms && o.surfaceError <= r.surfaceError * (1 + 1e-6) &&
            (o.ms < r.ms || o.surfaceError < r.surfaceError * (1 - 1e-6)))  // (equal to round-off: the same answer)
          beaten = true;
      if (!beaten)
        std::printf(" %s (%zu tets: %.3f ms, %.1f %%);", r.model.c_str(), r.tets, r.ms, 100 * r.surfaceError);
    }
    std::printf("\n");
  }
}

}  // namespace

int main(int argc, char** argv) {
  // Arguments: OUT_DIR, then an organ's name, and --quick (the liver preset, a 6k-element reference, one resolution:
  // the test suite's smoke run, which fails when the reference does not converge, an error is not finite, or the
  // precomputed model's answer differs from the linear FEM's on the same mesh by more than 1e-6).
  std::vector<std::string> args;
  bool quick = false;
  for (int k = 1; k < argc; ++k) {
    if (std::string(argv[k]) == "--quick")
      quick = true;
    else
      args.push_back(argv[k]);
  }
  const std::string out = !args.empty() ? args[0] : ".";
  int failures = 0;
  std::filesystem::create_directories(out);
  std::ofstream csv(out + "/models.csv");
  csv << "organ,model,tets,action,update_ms,update_hz,converged,surface_error_rel,force_error_rel,force_n,"
         "reference_force_n\n";
  const BodySetup preset = testing::presetBody("liver", REHEARSE_SHARED_DATA);
  const std::vector<Organ> organs = organsOf(preset);
  std::vector<Row> rows;
  const std::string only = args.size() > 1 ? args[1] : quick ? "liver preset" : "";  // one organ by name
  for (const Organ& organ : organs) {
    if (!only.empty() && organ.name != only) continue;
    benchOrgan(organ, preset.material, quick, csv, rows, failures);
  }
  plotOrgans(organs, rows, out);
  std::printf("written %s/models.csv%s\n", out.c_str(), failures ? "; FAILED (see above)" : "");
  return failures ? 1 : 0;
}
