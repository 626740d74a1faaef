// Benchmark of the pinned BLAS kernels (issue 60; not a test). A recording replays bit for bit on any processor because
// the program pins OpenBLAS to one kernel set (Prescott: SSE3, runs on any x86-64 processor) instead of the one OpenBLAS
// would pick for the processor; the simplicial factor calls no BLAS at all. What that costs, side by side in one run,
// on the built-in liver and real organ shapes (SOFA's liver, the kidney and the uterus presets from ../shared/data):
//  - CHOLMOD's numeric factorisation and solve of the implicit-Euler matrix M/h^2 + K at rest (median of repeats);
//  - a whole step of the scripted grasp, pull and cut (resources/gestures/grasp-pull-cut.json, linearised method with
//    the asynchronous refresh the GUI uses): median and 95th percentile of the steps' wall time, and how far the
//    final shape is from the pinned kernel's (mm: other kernels round differently, the physics is the same).
// Each kernel set this processor can run is measured: Prescott (pinned), Haswell (AVX2), SkylakeX (AVX-512), and the
// simplicial factor. Writes blas-kernels.csv into the directory given (default ".").
//   bench_kernels [OUT_DIR] [--quick]
#include "bench_args.hpp"
#include "session_inputs.hpp"

#include <rehearse/app/gesture.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/linear_solver.hpp>
#include <rehearse/simcore/numerics.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

using namespace rehearse;

namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

struct Variant {
  std::string name, core;  // the OpenBLAS kernel set selected for the run
  bool simplicial = false;  // the simplicial factor (no BLAS at all)
};

}  // namespace

int main(int argc, char** argv) {
  const auto [out, quick] = testing::benchArgs(argc, argv);
  const std::string shared = REHEARSE_SHARED_DATA;
  const app::GestureScript script = testing::gestureScript("grasp-pull-cut.json");

  std::printf("OpenBLAS chose %s for this processor at start; pinned to %s (%s)\n",
              simcore::blasCoreChosenAtStart().c_str(), simcore::kPinnedBlasCore, simcore::blasKernel().c_str());
  std::vector<Variant> variants{{"supernodal Prescott (pinned)", simcore::kPinnedBlasCore, false}};
  for (const char* core : {"Haswell", "SkylakeX"}) {
    if (simcore::selectBlasCore(core)) variants.push_back({std::string("supernodal ") + core, core, false});
    else std::printf("%s: not run on this processor (its instructions are missing)\n", core);
  }
  variants.push_back({"simplicial (no BLAS)", simcore::kPinnedBlasCore, true});
  simcore::pinBlasKernel();

  std::ofstream csv(out + "/blas-kernels.csv");
  csv << "organ,elements,dofs,variant,factor_median_ms,solve_median_ms,step_median_ms,step_p95_ms,steps,final_shape_"
         "max_mm\n";
  std::vector<std::string> organs{"liver"};
  if (!quick)
    for (const char* o : {"sofa-liver", "kidney", "uterus"}) organs.push_back(o);
  const int repeats = quick ? 5 : 15;
  for (const auto& organ : organs) {
    simcore::BodySetup setup;
    try {
      setup = testing::presetBody(organ, shared);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "bench_kernels: the %s preset cannot be built: %s\n", organ.c_str(), e.what());
      return 1;
    }
    setup.settings.method = simcore::NewtonMethod::Linearised;
    setup.settings.factorRefresh = simcore::FactorRefresh::Asynchronous;
    // The implicit-Euler matrix at rest: what the step factorises.
    const simcore::FemModel fem = simcore::FemModel::build(setup.mesh, setup.byLabel, setup.material);
    Eigen::SparseMatrix<double> A = simcore::elasticStiffness(fem, fem.restVector());
    const double h = setup.settings.timeStep;
    for (Eigen::Index i = 0; i < A.rows(); ++i) A.coeffRef(i, i) += fem.lumpedMass[i / 3] / (h * h);
    A.makeCompressed();
    Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(A.rows(), -1.0, 1.0);
    std::vector<Eigen::Vector3d> pinnedFinal;
    for (const Variant& v : variants) {
      if (!simcore::selectBlasCore(v.core)) {
        std::fprintf(stderr, "bench_kernels: cannot select %s\n", v.core.c_str());
        return 1;
      }
      simcore::CholmodSolver solver;
      solver.setSimplicial(v.simplicial);
      std::vector<double> factorMs, solveMs;
      Eigen::VectorXd x;
      for (int k = 0; k < repeats; ++k) {
        auto t0 = std::chrono::steady_clock::now();
        if (!solver.factorise(A)) {
          std::fprintf(stderr, "bench_kernels: %s: the factorisation failed\n", organ.c_str());
          return 1;
        }
        factorMs.push_back(msSince(t0));
        t0 = std::chrono::steady_clock::now();
        solver.solve(b, x);
        solveMs.push_back(msSince(t0));
      }
      simcore::BodySetup s = setup;
      s.settings.simplicialFactor = v.simplicial;
      const app::GestureResult g = app::runGesture(s, script, {});
      std::vector<double> stepMs;
      for (const auto& row : g.steps) stepMs.push_back(row.wallMs);
      double maxMm = 0;
      if (pinnedFinal.empty()) pinnedFinal = g.finalMesh.points;
      if (g.finalMesh.points.size() == pinnedFinal.size())
        for (std::size_t i = 0; i < pinnedFinal.size(); ++i)
          maxMm = std::max(maxMm, 1e3 * (g.finalMesh.points[i] - pinnedFinal[i]).norm());
      else
        maxMm = -1;  // another topology (a cut that went otherwise): said as -1
      std::printf("%s (%zu tets, %ld dofs) %s: factor %.2f ms, solve %.3f ms (medians of %d); step median %.2f ms, "
                  "95th %.2f ms over %zu steps; final shape %.3g mm from the pinned kernel's\n",
                  organ.c_str(), setup.mesh.tets.size(), static_cast<long>(A.rows()), v.name.c_str(),
                  percentile(factorMs, 0.5), percentile(solveMs, 0.5), repeats, percentile(stepMs, 0.5),
                  percentile(stepMs, 0.95), stepMs.size(), maxMm);
      csv << organ << ',' << setup.mesh.tets.size() << ',' << A.rows() << ',' << v.name << ','
          << percentile(factorMs, 0.5) << ',' << percentile(solveMs, 0.5) << ',' << percentile(stepMs, 0.5) << ','
          << percentile(stepMs, 0.95) << ',' << stepMs.size() << ',' << maxMm << '\n';
    }
    simcore::pinBlasKernel();
  }
  return 0;
}
