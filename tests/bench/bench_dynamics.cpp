// Benchmarks of the physics core (not a test): step time against error for each Newton method, material
// and mesh resolution; step time and peak memory from 1k to 50k tetrahedra. Medians of repeated steps.
// Writes CSVs and PNG plots into the directory given (default "."), and prints the tables.
//   bench_dynamics [OUT_DIR] [--quick]
#include "box_mesh.hpp"
#include "phantom/phantom.hpp"
#include "phantom/presets.hpp"
#include "plot.hpp"

#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/integrator.hpp>

#include <dlfcn.h>
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

struct Run {
  std::vector<double> stepMs;
  Eigen::VectorXd x;
  int factorisations = 0, failed = 0, newton = 0;
  std::size_t integratorBytes = 0;
};

Run simulate(const FemModel& m, const std::vector<int>& fixed, SimulationSettings s, int steps) {
  s.reportEnergy = false;  // the step itself: assembly, solves, residuals
  Integrator in(m, fixed, s);
  auto state = in.initialState();
  Run r;
  for (int i = 0; i < steps; ++i) {
    const auto rep = in.step(state);
    r.stepMs.push_back(rep.wallMs);
    r.factorisations += rep.factorisations;
    r.newton += rep.newtonIterations;
    r.failed += !rep.ok;
  }
  r.x = state.x;
  r.integratorBytes = in.memoryBytes();
  return r;
}

// Resident memory, MiB, from /proc/self/status: "VmRSS" now, "VmHWM" the peak since the last reset
// (Linux: writing 5 to /proc/self/clear_refs resets the peak). -1 where unavailable.
double residentMiB(const char* field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind(field, 0) == 0) return std::atof(line.c_str() + std::strlen(field) + 1) / 1024.0;
  return -1;
}
void resetPeakResident() {
  malloc_trim(0);  // give freed memory back first, so that the next run's pages count
  std::ofstream("/proc/self/clear_refs") << "5";
}

const NewtonMethod kMethods[] = {NewtonMethod::Exact, NewtonMethod::LaggedPcg, NewtonMethod::Chord, NewtonMethod::Linearised};
const MaterialModel kMaterials[] = {MaterialModel::Linear, MaterialModel::Corotational, MaterialModel::StVK, MaterialModel::NeoHookean};

// 0. The parts of a step on the liver preset (corotational): medians of repeated calls.
void benchParts(const std::string& out) {
  std::ofstream csv(out + "/dynamics_parts.csv");
  csv << "part,tets,median_ms\n";
  Scene sc = phantom::makePreset("liver");
  phantom::setMaterialModel(sc, MaterialModel::Corotational);
  const FemModel m = FemModel::build(sc.mesh, sc.materials, sc.defaultMaterial);
  Integrator in(m, sc.fixedNodes, sc.settings);
  Eigen::VectorXd x = m.restVector(), f, y, v = Eigen::VectorXd::Ones(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += 1e-3 * std::sin(0.37 * i);
  Eigen::SparseMatrix<double> K = m.pattern;
  TangentState ts;
  auto time = [&](const char* name, const std::function<void()>& fn) {
    std::vector<double> t;
    for (int i = 0; i < 21; ++i) {
      const auto a = std::chrono::steady_clock::now();
      fn();
      t.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
    }
    std::printf("%-34s %8.3f ms\n", name, median(t));
    csv << name << "," << m.tets.size() << "," << median(t) << "\n";
  };
  std::printf("== parts of a step, liver preset, corotational, %zu tets, %zu nodes\n", m.tets.size(), m.nodeCount());
  time("elastic forces", [&] { elasticForces(m, x, f); });
  time("elastic energy", [&] { elasticEnergy(m, x); });
  time("stiffness assembly", [&] { assembleStiffness(m, x, K); });
  time("tangent state (polar per tet)", [&] { prepareTangentState(m, x, ts); });
  time("matrix-free K v", [&] { applyStiffness(m, ts, v, y); });
  time("sparse K v", [&] { y.noalias() = K * v; });
  // The Newton matrix of a 10 ms step at rest, (1 + h alpha) M + (h beta + h^2) K.
  const double h = sc.settings.timeStep;
  assembleStiffness(m, m.restVector(), K);
  Eigen::SparseMatrix<double> A = (h * sc.settings.rayleighStiffness + h * h) * K;
  for (Eigen::Index i = 0; i < A.rows(); ++i) A.coeffRef(i, i) += (1 + h * sc.settings.rayleighMass) * m.lumpedMass[i / 3];
  if (!in.solveLinear(A, v, y)) std::printf("the Newton matrix did not factorise\n");
  time("cholmod factorise + solve", [&] { in.solveLinear(A, v, y); });
  // The BLAS thread count, measured (the integrator sets OpenBLAS to one thread).
  using SetThreads = void (*)(int);
  auto setBlas = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  if (!setBlas)
    if (void* lib = dlopen("libopenblas.so.0", RTLD_NOLOAD | RTLD_LAZY)) setBlas = reinterpret_cast<SetThreads>(dlsym(lib, "openblas_set_num_threads"));
  if (setBlas) {
    setBlas(2);
    time("cholmod factorise + solve, 2 BLAS threads", [&] { in.solveLinear(A, v, y); });
    setBlas(1);
  }
}

// 1. The liver preset (corotational) with each Newton method: median step time, and the error of the
//    state after 1 s against the exact method at a tight tolerance.
void benchMethods(const std::string& out, bool quick) {
  std::ofstream csv(out + "/dynamics_methods.csv");
  csv << "method,tets,steps,median_step_ms,mean_step_ms,factorisations,newton_iterations,failed,rel_l2_error,max_error_mm\n";
  Scene sc = phantom::makePreset("liver");
  phantom::setMaterialModel(sc, MaterialModel::Corotational);
  const FemModel m = FemModel::build(sc.mesh, sc.materials, sc.defaultMaterial);
  const int steps = quick ? 30 : 100;
  SimulationSettings ref = sc.settings;
  ref.tolerance = 1e-10;
  ref.maxNewtonIterations = 30;
  const Run reference = simulate(m, sc.fixedNodes, ref, steps);
  const Eigen::VectorXd u = reference.x - m.restVector();
  std::printf("== liver preset, corotational, %zu tets, %d steps of %.0f ms (1 s)\n", m.tets.size(), steps, 1e3 * sc.settings.timeStep);
  std::printf("%-30s %10s %10s %8s %8s %12s %10s\n", "method", "median ms", "mean ms", "factors", "newton", "rel L2 err", "max mm");
  struct Variant {
    NewtonMethod method;
    double refresh;
    std::string name;
    bool simplicial = false;
  };
  std::vector<Variant> variants;
  for (NewtonMethod method : kMethods) variants.push_back({method, 1e-2, toString(method)});
  for (double r : {1e-3, 1e-1, 1.0}) variants.push_back({NewtonMethod::Linearised, r, "linearised, refresh at " + std::to_string(r).substr(0, 5)});
  // The allocation-free factor (simplicial LL' of the matrix permuted by us) beside the supernodal one.
  variants.push_back({NewtonMethod::Exact, 1e-2, "exact, simplicial factor", true});
  variants.push_back({NewtonMethod::Linearised, 1e-2, "linearised, simplicial factor", true});
  for (const Variant& var : variants) {
    const NewtonMethod method = var.method;
    SimulationSettings s = sc.settings;
    s.method = method;
    s.refreshResidual = var.refresh;
    s.simplicialFactor = var.simplicial;
    std::vector<double> medians;
    Run r;
    for (int rep = 0; rep < (quick ? 1 : 3); ++rep) {  // the median of three runs' medians
      r = simulate(m, sc.fixedNodes, s, steps);
      medians.push_back(median(r.stepMs));
    }
    double mean = 0;
    for (double t : r.stepMs) mean += t / r.stepMs.size();
    const double rel = (r.x - reference.x).norm() / u.norm();
    double worst = 0;
    for (Eigen::Index i = 0; i < r.x.size() / 3; ++i) worst = std::max(worst, (r.x - reference.x).segment<3>(3 * i).norm());
    std::printf("%-30s %10.2f %10.2f %8d %8d %12.2e %10.4f\n", var.name.c_str(), median(medians), mean, r.factorisations, r.newton,
                rel, 1e3 * worst);
    csv << "\"" << var.name << "\"," << m.tets.size() << "," << steps << "," << median(medians) << "," << mean << "," << r.factorisations
        << "," << r.newton << "," << r.failed << "," << rel << "," << 1e3 * worst << "\n";
  }
}

// 2. Error against run time: a soft cantilever (200 x 20 x 20 mm, E = 1 MPa, nu = 0.3) swinging down under
//    gravity for 0.3 s, per material x resolution x method; error of the tip displacement against the
//    finest mesh with the exact method (the same material).
void benchErrorAgainstTime(const std::string& out, bool quick) {
  std::ofstream csv(out + "/dynamics_error_vs_time.csv");
  csv << "material,method,k,tets,median_step_ms,tip_mm,tip_error\n";
  const double L = 0.2, b = 0.02, h = 0.02;
  const std::vector<int> ks = quick ? std::vector<int>{1, 2} : std::vector<int>{1, 2, 3, 4};
  const int finest = quick ? 3 : 6, steps = 30;
  std::vector<PlotSeries> series;
  std::printf("\n== cantilever under gravity, 0.3 s: median step time and tip error against the finest mesh (k = %d)\n", finest);
  for (MaterialModel mat : kMaterials) {
    auto tipOf = [&](const Mesh& box, const Eigen::VectorXd& x, const FemModel& m) {
      Eigen::Vector3d tip = Eigen::Vector3d::Zero();
      const auto end = nodesAtX(box, L);
      for (int n : end) tip += x.segment<3>(3 * n) - m.rest[n];
      return Eigen::Vector3d(tip / end.size());
    };
    SimulationSettings s;
    s.gravity = Eigen::Vector3d(0, 0, -9.81);
    s.timeStep = 0.01;
    const MaterialParams p{mat, 1e6, 0.3, 1000};
    Eigen::Vector3d refTip;
    {
      const Mesh box = boxMesh(L, b, h, 10 * finest, finest, finest);
      const FemModel m = FemModel::build(box, {}, p);
      SimulationSettings sr = s;
      sr.tolerance = 1e-9;
      refTip = tipOf(box, simulate(m, nodesAtX(box, 0), sr, steps).x, m);
    }
    for (NewtonMethod method : kMethods) {
      PlotSeries ps;
      ps.name = toString(mat) + " " + toString(method);
      for (int k : ks) {
        const Mesh box = boxMesh(L, b, h, 10 * k, k, k);
        const FemModel m = FemModel::build(box, {}, p);
        SimulationSettings sm = s;
        sm.method = method;
        const Run r = simulate(m, nodesAtX(box, 0), sm, steps);
        const Eigen::Vector3d tip = tipOf(box, r.x, m);
        const double err = (tip - refTip).norm() / refTip.norm();
        const double ms = median(r.stepMs);
        std::printf("%-13s %-11s k=%d %6zu tets %9.2f ms  tip %7.2f mm  error %6.2f %%%s\n", toString(mat).c_str(), toString(method).c_str(),
                    k, m.tets.size(), ms, 1e3 * tip.norm(), 100 * err, r.failed ? "  (failed steps)" : "");
        csv << toString(mat) << "," << toString(method) << "," << k << "," << m.tets.size() << "," << ms << "," << 1e3 * tip.norm() << ","
            << err << "\n";
        ps.x.push_back(ms);
        ps.y.push_back(std::max(err, 1e-6));
      }
      series.push_back(ps);
    }
  }
  writeLogLogPlot(out + "/dynamics_error_vs_time.png", "Cantilever under gravity (0.3 s): tip error vs step time, k = 1..4",
                  "median step time (ms)", "relative tip error", series);
}

// 3. Scaling from 1k to 50k tets (phantom re-meshed), corotational liver material: step time per
//    method and memory.
void benchScaling(const std::string& out, bool quick) {
  std::ofstream csv(out + "/dynamics_scaling.csv");
  csv << "target_tets,tets,nodes,method,median_step_ms,model_and_solver_mib,peak_rss_increase_mib\n";
  const std::vector<std::size_t> sizes =
      quick ? std::vector<std::size_t>{1000, 4000} : std::vector<std::size_t>{1000, 2000, 5000, 10000, 20000, 50000};
  std::map<NewtonMethod, PlotSeries> series;
  std::printf("\n== scaling: phantom liver, corotational (median step ms over 0.2-0.6 s; memory held by the model, the integrator and the factor, and the measured peak resident increase)\n");
  for (std::size_t target : sizes) {
    phantom::PhantomOptions po;
    po.targetTets = target;
    po.width = 320;
    po.height = 180;  // the frame is not used here
    const phantom::Phantom c = phantom::makePhantom(po);
    Scene sc = phantom::makePreset("liver", c.volume, c.attachments);
    phantom::setMaterialModel(sc, MaterialModel::Corotational);
    for (NewtonMethod method : kMethods) {
      if (method == NewtonMethod::Chord) continue;
      double ms = 0, mib = 0, peak = -1;
      resetPeakResident();
      const double before = residentMiB("VmRSS");
      {
        const FemModel m = FemModel::build(sc.mesh, sc.materials, sc.defaultMaterial);
        SimulationSettings s = sc.settings;
        s.method = method;
        // 0.6 s: the organ drops into its ligaments, then swings; the median of the last 0.4 s.
        const Run r = simulate(m, sc.fixedNodes, s, quick ? 10 : 60);
        ms = median(std::vector<double>(r.stepMs.begin() + r.stepMs.size() / 3, r.stepMs.end()));
        mib = static_cast<double>(m.memoryBytes() + r.integratorBytes) / (1 << 20);  // model, integrator, factor
        // Measured: the process's peak resident memory while building and running, above where it began.
        if (const double hwm = residentMiB("VmHWM"); hwm > 0 && before > 0) peak = hwm - before;
      }
      const std::size_t tets = sc.mesh.tets.size(), nodes = sc.mesh.points.size();
      std::printf("%6zu tets %5zu nodes %-11s %9.2f ms %8.1f MiB held %8.1f MiB peak\n", tets, nodes, toString(method).c_str(), ms, mib,
                  peak);
      csv << target << "," << tets << "," << nodes << "," << toString(method) << "," << ms << "," << mib << "," << peak << "\n";
      series[method].name = toString(method);
      series[method].x.push_back(static_cast<double>(tets));
      series[method].y.push_back(ms);
    }
  }
  std::vector<PlotSeries> list;
  for (auto& [k, v] : series) list.push_back(v);
  writeLogLogPlot(out + "/dynamics_scaling.png", "Step time against mesh size (phantom liver, corotational)", "tetrahedra",
                  "median step time (ms)", list);
}

}  // namespace

int main(int argc, char** argv) {
  std::string out = ".", only;
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--only" && i + 1 < argc) only = argv[++i];
    else out = a;
  }
  auto run = [&](const char* section) { return only.empty() || only == section; };
  std::filesystem::create_directories(out);

  if (run("parts")) benchParts(out);
  if (run("methods")) benchMethods(out, quick);
  if (run("error")) benchErrorAgainstTime(out, quick);
  if (run("scaling")) benchScaling(out, quick);
  std::printf("\nwrote %s/dynamics_*.csv and .png\n", out.c_str());
  return 0;
}
