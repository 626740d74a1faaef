// Benchmark of the precomputed linear elasticity (issue 37; not a test): on real organ shapes from ../shared/data
// (the patient liver, BodyParts3D's liver and left kidney) meshed at two sizes, hung by their highest 8 % of surface
// nodes under gravity: the precomputation's time and memory (double and single precision; every node's rows or the
// surface's only, the inner nodes then by a back-solve per update), and the online update's time against the FEM's
// static solve of the same problem (CHOLMOD on the stiffness with the held nodes eliminated, factorised once: what the
// exact linear answer costs without the responses): one held node (the haptic loop's force alone, forceAt; the whole
// organ's displacement, solve) and a grasp's patch of 6; the answers' difference. Medians of repeated runs. Writes
// precomputed.csv into the directory given (default ".").
//   bench_precomputed [OUT_DIR]
#include "realorgan.hpp"

#include <rehearse/simcore/linear_solver.hpp>
#include <rehearse/simcore/precomputed.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

template <typename F>
double medianMs(int repeat, F&& f) {
  std::vector<double> t;
  for (int k = 0; k < repeat; ++k) {
    const auto a = Clock::now();
    f();
    t.push_back(msSince(a));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  const std::string out = argc > 1 ? argv[1] : ".";
  std::filesystem::create_directories(out);
  std::ofstream csv(out + "/precomputed.csv");
  csv << "organ,tets,nodes,driven,rows,precision,build_s,memory_mb,force_one_node_us,update_one_node_ms,update_patch6_"
         "ms,"
         "fem_factor_one_node_ms,fem_solve_one_node_ms,fem_factor_patch6_ms,fem_solve_patch6_ms,difference_relative\n";
  std::printf("%-20s %6s %6s %6s %7s %6s %7s %9s %8s %9s %9s %9s %9s %9s\n", "organ", "tets", "nodes", "driven", "rows",
              "prec", "build s", "memory MB", "force us", "update ms", "patch6 ms", "FEM fac", "FEM solve", "diff");
  const Eigen::Vector3d g(0, 9.81, 0);
  struct Organ {
    const char* name;
    const char* file;
  };
  for (const Organ organ : {Organ{"patient liver", "scikit-surgery/patient-liver/liver.vtk"},
                            Organ{"BodyParts3D liver", "bodyparts3d/FMA7197_Liver.obj"},
                            Organ{"BodyParts3D kidney", "bodyparts3d/FMA7205_Left_Kidney.obj"}}) {
    const std::string path = std::string(REHEARSE_SHARED_DATA) + "/" + organ.file;
    if (!std::filesystem::exists(path)) {
      std::printf("%s is absent: skipped\n", path.c_str());
      continue;
    }
    for (const std::size_t target : {4000u, 12000u}) {
      TetrahedraliseOptions to;
      to.allowSelfIntersections = true;
      to.targetTets = target;
      const Mesh mesh = tetrahedraliseSurface(testing::loadOrganSurface(path), to);
      const std::size_t n = mesh.points.size();
      std::vector<char> fixed(n, 0);
      for (int v : testing::highestSurfaceNodes(mesh, 0.08)) fixed[static_cast<std::size_t>(v)] = 1;
      std::vector<int> driven;
      for (int v : testing::surfaceNodes(mesh))
        if (!fixed[static_cast<std::size_t>(v)]) driven.push_back(v);
      MaterialParams m;
      m.model = MaterialModel::Linear;
      m.young = 27e3;
      m.poisson = 0.45;
      m.density = 1079;
      const FemModel model = FemModel::build(mesh, {}, m);
      // A grasp's patch: the 6 driven nodes nearest the one farthest from the attachments.
      Eigen::Vector3d hold = Eigen::Vector3d::Zero();
      int nh = 0;
      for (std::size_t i = 0; i < n; ++i)
        if (fixed[i]) hold += mesh.points[i], ++nh;
      hold /= nh;
      int far = driven.front();
      for (int v : driven)
        if ((mesh.points[static_cast<std::size_t>(v)] - hold).norm() >
            (mesh.points[static_cast<std::size_t>(far)] - hold).norm())
          far = v;
      std::vector<int> patch = driven;
      std::sort(patch.begin(), patch.end(), [&](int a, int b) {
        return (mesh.points[static_cast<std::size_t>(a)] - mesh.points[static_cast<std::size_t>(far)]).norm() <
               (mesh.points[static_cast<std::size_t>(b)] - mesh.points[static_cast<std::size_t>(far)]).norm();
      });
      patch.resize(6);
      const std::vector<Eigen::Vector3d> d6(6, Eigen::Vector3d(0.01, -0.005, 0.002));
      // The FEM's exact linear static answer without responses: K with the fixed and held nodes' rows and columns
      // replaced by the identity (right-hand side: f_g - K_:held d at the free rows, d at the held), one factorisation
      // per held set, one solve per update.
      auto femStatic = [&](const std::vector<int>& held, const std::vector<Eigen::Vector3d>& d, double& factorMs,
                           double& solveMs) {
        Eigen::SparseMatrix<double> K = elasticStiffness(model, model.restVector());
        const Eigen::SparseMatrix<double> K0 = K;
        std::vector<char> known(fixed);
        Eigen::VectorXd dk = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(n));
        for (std::size_t k = 0; k < held.size(); ++k) {
          known[static_cast<std::size_t>(held[k])] = 1;
          dk.segment<3>(3 * held[k]) = d[k];
        }
        for (int c = 0; c < K.outerSize(); ++c)
          for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it)
            if (known[static_cast<std::size_t>(it.row() / 3)] || known[static_cast<std::size_t>(it.col() / 3)])
              it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
        CholmodSolver chol;
        const auto a = Clock::now();
        chol.factorise(K);
        factorMs = msSince(a);
        Eigen::VectorXd rhs = -(K0 * dk), u;
        for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(n); ++i) {
          rhs.segment<3>(3 * i) += model.lumpedMass(i) * g;
          if (known[static_cast<std::size_t>(i)]) rhs.segment<3>(3 * i) = dk.segment<3>(3 * i);
        }
        solveMs = medianMs(21, [&] { chol.solve(rhs, u); });
        return u;
      };
      double f1 = 0, s1 = 0, f6 = 0, s6 = 0;
      const Eigen::VectorXd ref1 = femStatic({patch[0]}, {d6[0]}, f1, s1);
      const Eigen::VectorXd ref6 = femStatic(patch, d6, f6, s6);
      for (const int variant : {0, 1, 2, 3}) {
        const bool single = variant % 2 == 1, surfaceRows = variant >= 2;
        PrecomputeSettings s;
        s.singlePrecision = single;
        s.drivenRowsOnly = surfaceRows;  // the surface's rows, the inner nodes by a back-solve per update
        std::string why;
        const auto a = Clock::now();
        const auto p = PrecomputedElasticity::build(model, fixed, driven, g, s, why);
        const double buildS = msSince(a) / 1e3;
        if (!p) {
          std::printf("%s: %s\n", organ.name, why.c_str());
          continue;
        }
        const int j = p->drivenIndex(patch[0]);
        Eigen::Vector3d f = Eigen::Vector3d::Zero();
        const double forceUs = 1e3 *
                               medianMs(101,
                                        [&] {
                                          for (int k = 0; k < 1000; ++k)
                                            f += p->forceAt(j, d6[0] + 1e-6 * k * Eigen::Vector3d::UnitX());
                                        }) /
                               1000.0;
        Eigen::VectorXd u1, u6;
        const double update1 = medianMs(51, [&] { p->solve({patch[0]}, {d6[0]}, u1, nullptr, why); });
        const double update6 = medianMs(51, [&] { p->solve(patch, d6, u6, nullptr, why); });
        const double diff = std::max((u1 - ref1).norm() / ref1.norm(), (u6 - ref6).norm() / ref6.norm());
        std::printf("%-20s %6zu %6zu %6zu %7s %6s %7.2f %9.1f %8.3f %9.4f %9.4f %9.1f %9.2f %9.1e%s\n", organ.name,
                    mesh.tets.size(), n, driven.size(), surfaceRows ? "surface" : "all", single ? "float" : "double",
                    buildS, p->memoryBytes() / 1e6, forceUs, update1, update6, std::max(f1, f6), std::max(s1, s6), diff,
                    f.allFinite() ? "" : " (NaN)");
        csv << '"' << organ.name << "\"," << mesh.tets.size() << ',' << n << ',' << driven.size() << ','
            << (surfaceRows ? "surface" : "all") << ',' << (single ? "float" : "double") << ',' << buildS << ','
            << p->memoryBytes() / 1e6 << ',' << forceUs << ',' << update1 << ',' << update6 << ',' << f1 << ',' << s1
            << ',' << f6 << ',' << s6 << ',' << diff << '\n';
        std::fflush(stdout);
      }
    }
  }
  std::printf(
      "written %s/precomputed.csv (FEM columns: one factorisation with the held set eliminated, then a "
      "solve)\n",
      out.c_str());
  return 0;
}
