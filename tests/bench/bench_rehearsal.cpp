// Benchmarks of rehearsal (issue 15; not a test): on the built-in liver preset (3,760 tets) and SOFA's
// liver (../shared/data/sofa/liver.msh, a real organ's shape), through the simulation session:
//  - a grasp pulled 2 cm over one second: the wall time of every step while pulling (median, 99th
//    percentile) for each Newton method, and the tip force and the bitten node's place at the end against
//    the exact method's (error against run time);
//  - a cut across the organ in sweeps: the re-meshing alone (cutTetrahedra) and the whole step that applies
//    it (body rebuild, first factorisation), median and 99th percentile.
// Writes rehearsal-pull.csv and rehearsal-cut.csv into the directory given (default ".").
//   bench_rehearsal [OUT_DIR] [--quick] [--cut-repeats N] [--only VARIANT]   (N runs of the cut scenario, their steps
//   pooled; only one pull variant on the built-in liver, no cut)
//   bench_rehearsal [OUT_DIR] --cut TEXT [--cut-repeats N]   (the cut table alone, its variants whose name contains
//   TEXT: "chord" is the window's default, chord with the asynchronous refresh and the 0.05 mm accuracy)
//   bench_rehearsal [OUT_DIR] --real [--organ NAME] [--only VARIANT]   (only the real organs: grasp-pull and
//   contact-pull at the patient's size, started in equilibrium; also part of a full run, not of --quick)
#include "phantom/presets.hpp"
#include "plot.hpp"
#include "realorgan.hpp"
#include "session_inputs.hpp"

#include <rehearse/simcore/cut.hpp>
#include <rehearse/simcore/inverse_rest.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>
#include <rehearse/simcore/session/forceloop.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double at = q * static_cast<double>(v.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(at);
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (at - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

BodySetup setupFor(const std::string& preset, const std::string& shared) {
  BodySetup s = testing::presetBody(preset, shared);
  s.settings.timeStep = 0.01;
  s.tools.maxGraspForce = 1e6;
  return s;
}

InputEvent event(InputKind kind, const Eigen::Vector3d& p = Eigen::Vector3d::Zero(), bool on = false) {
  InputEvent e;
  e.kind = kind;
  e.position = p;
  e.on = on;
  return e;
}

struct PullResult {
  std::vector<double> ms;
  double placeMaxMs =
      0;  // shaft on the surface: the slowest of the steps pushing the tissue out of it, before the pull
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), bitten = Eigen::Vector3d::Zero();
  int failed = 0, swaps = 0, contacts = 0, touchingSteps = 0;
  long newton = 0;                 // Newton iterations over the pull's steps
  long inner = 0;                  // CG iterations and Gauss-Seidel sweeps over the pull's steps
  int converged = 0, inexact = 0;  // steps by outcome (the others failed, were refused or inverted)
  double worstResidual = 0;        // the largest relative residual a pull step ended with
  int withinMicro = 0;  // steps that ended at a relative residual <= 1e-6 (issue 34's bar, whatever the method)
  std::vector<Eigen::Vector3d> end;  // every node's place after the pull
  ForceLoop::Timing loop;            // the 1 kHz tool-force loop's, run beside the pull on its own thread
};

struct Variant {
  NewtonMethod method;
  FactorRefresh refresh = FactorRefresh::Synchronous;
  double toolRadius = 0;  // m: contact with the instrument's shaft
  // The shaft laid along the organ's surface (its trocar 15 cm from the tip, through a point 2 mm under the surface
  // 3 cm away) instead of coming from the default trocar: it presses on the tissue beside the grasp while pulling.
  bool shaftOnSurface = false;
  double tolerance = 1e-6;  // relative residual (not the linearised method's: its one solve is its step)
  double accuracy = 0;      // m: SimulationSettings::accuracyPosition (the GUI's 0.05 mm; 0: the residual alone)
  std::string name() const {
    char tol[32] = "";
    if (tolerance != 1e-6) std::snprintf(tol, sizeof tol, "@%g", tolerance);
    if (accuracy > 0) std::snprintf(tol, sizeof tol, "@%g mm", 1e3 * accuracy);
    return toString(method) + (refresh == FactorRefresh::Asynchronous ? "+async" : "") +
           (toolRadius > 0 ? "+contact" : "") + (shaftOnSurface ? "+touching" : "") + tol;
  }
};

constexpr int kPullSteps = 200;

// Settle, bite the node nearest the organ's front (smallest z), pull 2 cm towards -z over 200 steps of
// 10 ms, paced to real time as the session's thread plays (a step starts every 10 ms, or at once when the
// last one overran): the asynchronous refresh has the time the surgeon gives it, no more.
PullResult pull(BodySetup s, const Variant& v, int settle) {
  s.settings.method = v.method;
  s.settings.factorRefresh = v.refresh;
  s.settings.tolerance = v.tolerance;
  s.tools.toolRadius = v.toolRadius;
  auto settled = [&](Session& session) {
    for (int k = 0; k < settle; ++k) session.advance();
    const auto snap = session.snapshot();
    Eigen::Vector3d tip = snap->positions.front();
    for (const auto& p : snap->positions)
      if (p.z() < tip.z()) tip = p;
    return tip;
  };
  if (v.shaftOnSurface) {  // the settled shape (deterministic) tells where the surface is at the grasp
    Session probe(s);
    const Eigen::Vector3d at = settled(probe);
    const auto& placed = probe.snapshot()->positions;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& p : placed) centre += p;
    centre /= static_cast<double>(placed.size());
    // Along the surface: through the point 2 mm under the surface 3 cm from the bite (the node nearest there), so
    // that the shaft presses on the tissue beside the grasp whatever the surface's curvature (a tangent line lay off
    // the flatter real livers: it touched nothing there).
    const Eigen::Vector3d outward = (at - centre).normalized();
    const Eigen::Vector3d along = outward.cross(Eigen::Vector3d::UnitY()).normalized();
    Eigen::Vector3d beside = placed.front();
    for (const auto& p : placed)
      if ((p - (at + 0.03 * along)).norm() < (beside - (at + 0.03 * along)).norm()) beside = p;
    s.tools.trocar = at + 0.15 * (beside - 0.002 * outward - at).normalized();
  }
  Session session(s);
  const Eigen::Vector3d tip = settled(session);
  session.post(event(InputKind::ToolPose, tip));
  session.post(event(InputKind::Jaw, tip, true));
  session.advance();
  PullResult r;
  if (v.shaftOnSurface)  // the shaft appears lying on (partly in) the tissue: it is pushed out before the pull
    for (int k = 0; k < 10; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      session.advance();
      r.placeMaxMs = std::max(r.placeMaxMs,
                              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
  const int bitten = session.snapshot()->tool.held.empty() ? -1 : session.snapshot()->tool.held.front();
  VirtualDevice device;
  device.setPosition(tip);
  ForceLoop loop([&session] { return session.toolForce(); }, &device);
  loop.start();
  auto due = std::chrono::steady_clock::now();
  for (int k = 1; k <= kPullSteps; ++k) {
    std::this_thread::sleep_until(due);
    device.setPosition(tip + Eigen::Vector3d(0, 0, -0.02 * k / kPullSteps));
    session.post(event(InputKind::ToolPose, tip + Eigen::Vector3d(0, 0, -0.02 * k / kPullSteps)));
    const auto t0 = std::chrono::steady_clock::now();
    const StepReport rep = session.advance();
    const auto t1 = std::chrono::steady_clock::now();
    r.ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    r.failed += !rep.ok;
    r.newton += rep.newtonIterations;
    r.inner += rep.innerIterations;
    r.converged += rep.outcome == StepStatus::Converged;
    r.inexact += rep.outcome == StepStatus::Inexact;
    r.worstResidual = std::max(r.worstResidual, rep.residual);
    r.withinMicro += rep.ok && rep.residual <= 1e-6 && rep.outcome != StepStatus::Inverted;
    r.swaps += rep.factorSwapped;
    r.contacts = std::max(r.contacts, session.snapshot()->tool.contacts);
    r.touchingSteps += session.snapshot()->tool.contacts > 0;
    due = std::max(due + std::chrono::milliseconds(10), t1);
  }
  loop.stop();
  r.loop = loop.timing();
  r.force = session.snapshot()->tool.force;
  if (bitten >= 0) r.bitten = session.snapshot()->positions[static_cast<std::size_t>(bitten)];
  r.end = session.snapshot()->positions;
  return r;
}

void realOrgans(const std::string& out, const std::string& shared, const std::string& only, const std::string& organ) {
  // Issue 34: grasp-pull and contact-pull on real organs at the patient's size, started where the registered shape is
  // (the rest shape that sags into it solved first): per step while pulling, the Newton iterations and the outcomes;
  // every method at three tolerances, its tip force and every node's place after the pull against exact Newton's at
  // 1e-9 (error against run time, rehearsal-error-time.png).
  std::ofstream realCsv(out + "/rehearsal-real.csv");
  realCsv << "organ,tets,method,tolerance,median_ms,p99_ms,max_ms,newton_mean,inner_mean,converged,inexact,other,"
             "within_1e-6,worst_residual,force_n,force_error_rel,place_error_mm,start_solves,start_s\n";
  std::printf(
      "\nGrasp-pull (and with a 4 mm shaft touching) on real organs started in equilibrium, %d paced steps; errors "
      "against exact Newton at 1e-9\n",
      kPullSteps);
  std::printf("%-18s %6s %-38s %8s %8s %8s %6s %6s %14s %7s %9s %8s %9s %10s\n", "organ", "tets", "method", "median",
              "p99", "max ms", "Newton", "inner", "conv/inex/oth", "<=1e-6", "worst res", "force N", "force err",
              "place err");
  struct Real {
    std::string name, path;
    std::size_t tets;
  };
  std::vector<PlotSeries> forcePlot, placePlot;
  for (const Real& o :
       {Real{"liver preset", "", 0}, Real{"patient liver", "/scikit-surgery/patient-liver/liver.vtk", 17000},
        Real{"BodyParts3D liver", "/bodyparts3d/FMA7197_Liver.obj", 17000}}) {
    if (!organ.empty() && o.name.find(organ) == std::string::npos) continue;
    BodySetup s;
    if (o.path.empty()) {
      s = setupFor("liver", shared);
    } else {
      if (!std::filesystem::exists(shared + o.path)) {
        std::printf("%-18s absent: %s%s\n", o.name.c_str(), shared.c_str(), o.path.c_str());
        continue;
      }
      TetrahedraliseOptions to;
      to.allowSelfIntersections = true;
      to.targetTets = o.tets;
      s.mesh = tetrahedraliseSurface(testing::loadOrganSurface(shared + o.path), to);
      s.material = {MaterialModel::Corotational, 27e3, 0.4, 1079};
      s.settings.timeStep = 0.01;
      s.settings.gravity = Eigen::Vector3d(0, 9.81, 0);
      s.tools.maxGraspForce = 1e6;
      s.fixedNodes = testing::highestSurfaceNodes(s.mesh, 0.08);
    }
    const auto t0 = std::chrono::steady_clock::now();
    const InverseRestResult start = startInEquilibrium(s, s.mesh.points);
    const double startSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!start.converged()) {
      std::printf("%-18s %6zu no starting equilibrium: %s\n", o.name.c_str(), s.mesh.tets.size(), start.status.c_str());
      continue;
    }
    const auto async = FactorRefresh::Asynchronous;
    std::vector<Variant> variants = {{NewtonMethod::Exact}};
    for (double tol : {1e-4, 1e-6, 1e-8})
      for (NewtonMethod m : {NewtonMethod::Chord, NewtonMethod::NewtonKrylov})
        variants.push_back({m, async, 0, false, tol});
    variants.push_back({NewtonMethod::Linearised, async});
    for (NewtonMethod m : {NewtonMethod::Chord, NewtonMethod::NewtonKrylov, NewtonMethod::Linearised})
      variants.push_back({m, async, 0.004, true});
    // The reference: exact Newton at 1e-9, and the same pull with the shaft touching (contact changes the answer).
    Variant reference{NewtonMethod::Exact};
    reference.tolerance = 1e-9;
    const PullResult ref = pull(s, reference, 10);
    reference.toolRadius = 0.004;
    reference.shaftOnSurface = true;
    const PullResult refTouching = only.empty() ? pull(s, reference, 10) : ref;
    for (const Variant& v : variants) {
      if (!only.empty() && v.name() != only) continue;
      const PullResult r = pull(s, v, 10);
      const PullResult& e = v.shaftOnSurface ? refTouching : ref;
      const double fe = e.force.norm() > 0 ? (r.force - e.force).norm() / e.force.norm() : 0;
      double pe = 0;
      for (std::size_t i = 0; i < r.end.size() && i < e.end.size(); ++i)
        pe = std::max(pe, (r.end[i] - e.end[i]).norm());
      const int n = static_cast<int>(r.ms.size());
      std::printf("%-18s %6zu %-38s %8.2f %8.2f %8.2f %6.2f %6.2f %4d/%4d/%4d %7d %9.2e %8.3f %8.2e %8.2e mm\n",
                  o.name.c_str(), s.mesh.tets.size(), v.name().c_str(), percentile(r.ms, 0.5), percentile(r.ms, 0.99),
                  percentile(r.ms, 1.0), static_cast<double>(r.newton) / std::max(1, n),
                  static_cast<double>(r.inner) / std::max(1, n), r.converged, r.inexact, n - r.converged - r.inexact,
                  r.withinMicro, r.worstResidual, r.force.norm(), fe, 1e3 * pe);
      if (v.shaftOnSurface)
        std::printf("%-18s %6s   the shaft touched in %d of %d steps (up to %d triangles)\n", "", "", r.touchingSteps,
                    n, r.contacts);
      std::fflush(stdout);
      realCsv << '"' << o.name << "\"," << s.mesh.tets.size() << ',' << v.name() << ',' << v.tolerance << ','
              << percentile(r.ms, 0.5) << ',' << percentile(r.ms, 0.99) << ',' << percentile(r.ms, 1.0) << ','
              << static_cast<double>(r.newton) / std::max(1, n) << ',' << static_cast<double>(r.inner) / std::max(1, n)
              << ',' << r.converged << ',' << r.inexact << ',' << n - r.converged - r.inexact << ',' << r.withinMicro
              << ',' << r.worstResidual << ',' << r.force.norm() << ',' << fe << ',' << 1e3 * pe << ','
              << start.iterations << ',' << startSeconds << '\n';
      if (v.shaftOnSurface) continue;
      // One series per organ and method: its tolerances' points.
      const std::string series = o.name + ", " + toString(v.method);
      auto add = [&](std::vector<PlotSeries>& plot, double y) {
        auto it = std::find_if(plot.begin(), plot.end(), [&](const PlotSeries& p) { return p.name == series; });
        if (it == plot.end()) it = plot.insert(plot.end(), PlotSeries{series, {}, {}, true});
        it->x.push_back(percentile(r.ms, 0.5));
        it->y.push_back(std::max(y, 1e-12));  // exact to round-off shows at the floor
      };
      add(forcePlot, fe);
      add(placePlot, 1e3 * pe);
    }
  }
  if (!forcePlot.empty()) {
    writeLogLogPlot(out + "/rehearsal-error-time.png", "Grasp-pull on real organs: tip force error vs step time",
                    "median step (ms)", "tip force error (relative to exact Newton at 1e-9)", forcePlot);
    writeLogLogPlot(out + "/rehearsal-place-error-time.png",
                    "Grasp-pull on real organs: largest node place error vs step time", "median step (ms)",
                    "largest node place error (mm)", placePlot);
  }
}

// The grasp pulled on each organ with each Newton method (or the one named by --only): one line and one row each.
void pullTable(const std::vector<std::string>& organs, const std::string& shared, const std::string& out,
               const std::string& only, bool quick) {
  std::ofstream pullCsv(out + "/rehearsal-pull.csv");
  pullCsv << "organ,tets,method,median_ms,p99_ms,max_ms,place_max_ms,failed,swaps,contacts,touching_steps,force_error_"
             "rel,bitten_error_mm,loop_hz,loop_period_median_ms,loop_period_p99_ms,loop_period_max_ms,loop_jitter_p99_"
             "ms,loop_realtime\n";
  std::printf(
      "Grasp pulled 2 cm over %d steps of 10 ms, paced to real time (wall time per step while pulling); the force loop "
      "beside it\n",
      kPullSteps);
  std::printf("%-11s %6s %-35s %9s %9s %9s %6s %5s %8s %8s %12s %12s %8s %9s\n", "organ", "tets", "method", "median ms",
              "p99 ms", "max ms", "failed", "swaps", "contacts", "touching", "force err", "bitten err", "loop Hz",
              "jitter ms");
  const std::vector<Variant> variants = {{NewtonMethod::Exact},
                                         {NewtonMethod::LaggedPcg},
                                         {NewtonMethod::Chord},
                                         {NewtonMethod::Linearised},
                                         {NewtonMethod::Chord, FactorRefresh::Asynchronous},
                                         {NewtonMethod::Linearised, FactorRefresh::Asynchronous},
                                         {NewtonMethod::Linearised, FactorRefresh::Asynchronous, 0.004},
                                         {NewtonMethod::Linearised, FactorRefresh::Asynchronous, 0.006, true},
                                         {NewtonMethod::NewtonKrylov, FactorRefresh::Asynchronous},
                                         {NewtonMethod::NewtonKrylov, FactorRefresh::Asynchronous, 0.006, true}};
  for (const auto& organ : organs) {
    const BodySetup s = setupFor(organ, shared);
    const PullResult exact = pull(s, variants.front(), quick ? 20 : 50);
    for (const Variant& v : variants) {
      if (!only.empty() && v.name() != only) continue;
      const PullResult r = &v == &variants.front() ? exact : pull(s, v, quick ? 20 : 50);
      const double fe = exact.force.norm() > 0 ? (r.force - exact.force).norm() / exact.force.norm() : 0;
      const double de = 1e3 * (r.bitten - exact.bitten).norm();
      std::printf("%-11s %6zu %-35s %9.2f %9.2f %9.2f %6d %5d %8d %8d %11.2f%% %9.3f mm %8.0f %9.3f\n", organ.c_str(),
                  s.mesh.tets.size(), v.name().c_str(), percentile(r.ms, 0.5), percentile(r.ms, 0.99),
                  percentile(r.ms, 1.0), r.failed, r.swaps, r.contacts, r.touchingSteps, 100 * fe, de, r.loop.rateHz,
                  r.loop.jitterMs);
      pullCsv << organ << ',' << s.mesh.tets.size() << ',' << v.name() << ',' << percentile(r.ms, 0.5) << ','
              << percentile(r.ms, 0.99) << ',' << percentile(r.ms, 1.0) << ',' << r.placeMaxMs << ',' << r.failed << ','
              << r.swaps << ',' << r.contacts << ',' << r.touchingSteps << ',' << fe << ',' << de << ','
              << r.loop.rateHz << ',' << r.loop.medianPeriodMs << ',' << r.loop.p99PeriodMs << ',' << r.loop.maxPeriodMs
              << ',' << r.loop.jitterMs << ',' << r.loop.realtime << '\n';
    }
  }
}

// One cut across the organ with one method, run cutRepeats times: its line and row.
void cutRun(const std::string& organ, const Variant& v, const std::string& shared, bool quick, int cutRepeats,
            std::ofstream& cutCsv) {
  BodySetup s = setupFor(organ, shared);
  s.settings.method = v.method;
  s.settings.factorRefresh = v.refresh;
  s.settings.accuracyPosition = v.accuracy;
  Eigen::AlignedBox3d box;
  for (const auto& p : s.mesh.points) box.extend(p);
  const Eigen::Vector3d size = box.sizes();
  const double x = box.min().x() + 0.25 * size.x();
  // The trocar above the cut's plane; the blade (1.5x the organ's height) sweeps from front to back.
  s.tools.trocar = Eigen::Vector3d(x, box.min().y() - 2 * size.y(), box.center().z());
  s.tools.bladeLength = 1.5 * size.y() + 0.02;
  std::vector<double> remesh, step, all;
  std::size_t before = 0, after = 0;
  for (int repeat = 0; repeat < cutRepeats; ++repeat) {
    Session session(s);
    for (int k = 0; k < (quick ? 10 : 30); ++k) session.advance();
    before = session.snapshot()->elements;
    const Eigen::Vector3d from(x, box.max().y() + 0.01, box.min().z() - 0.01);
    session.post(event(InputKind::ToolPose, from));
    session.post(event(InputKind::Cut, from, true));
    const int sweeps = 12;
    auto due = std::chrono::steady_clock::now();
    auto timedStep = [&] {
      std::this_thread::sleep_until(due);
      const auto t0 = std::chrono::steady_clock::now();
      session.advance();
      const auto t1 = std::chrono::steady_clock::now();
      due = std::max(due + std::chrono::milliseconds(10), t1);
      const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
      all.push_back(ms);
      const auto& ev = session.snapshot()->events;
      if (std::find(ev.begin(), ev.end(), "cut") != ev.end()) step.push_back(ms);
    };
    for (int k = 1; k <= sweeps; ++k) {
      const Eigen::Vector3d to = from + Eigen::Vector3d(0, 0, (size.z() + 0.02) * k / sweeps);
      // The re-meshing alone, on a copy of the session's mesh at its current shape.
      {
        const auto snap = session.snapshot();
        std::vector<Eigen::Vector3d> rest = session.setup().mesh.points, current = snap->positions;
        auto tets = session.setup().mesh.tets;
        auto labels = session.setup().mesh.tetLabels;
        const Eigen::Vector3d prev = from + Eigen::Vector3d(0, 0, (size.z() + 0.02) * (k - 1) / sweeps);
        auto end = [&](const Eigen::Vector3d& t) {
          return Eigen::Vector3d(t + s.tools.bladeLength * (*s.tools.trocar - t).normalized());
        };
        CutProgress progress = session.setup().cut;
        if (current.size() == rest.size()) {
          const auto t0 = std::chrono::steady_clock::now();
          const CutResult r =
              cutTetrahedra(rest, current, tets, labels, {prev, end(prev), to, end(to)}, s.tools.cut, &progress);
          if (r.changed)
            remesh.push_back(
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        }
      }
      session.post(event(InputKind::ToolPose, to));
      for (int j = 0; j < 3; ++j) timedStep();
    }
    session.post(event(InputKind::Cut, from, false));  // withdrawn: a cut still being built is applied here
    timedStep();
    for (int j = 0; j < 5; ++j) timedStep();
    after = session.snapshot()->elements;
  }
  const double slowest = all.empty() ? 0 : *std::max_element(all.begin(), all.end());
  std::printf("%-11s %-18s %7zu %15.2f %13.2f %17.2f %15.2f %14.2f %7zu -> %zu\n", organ.c_str(), v.name().c_str(),
              step.size(), percentile(remesh, 0.5), percentile(remesh, 0.99), percentile(step, 0.5),
              percentile(step, 0.99), slowest, before, after);
  cutCsv << organ << ',' << v.name() << ',' << step.size() << ',' << percentile(remesh, 0.5) << ','
         << percentile(remesh, 0.99) << ',' << percentile(step, 0.5) << ',' << percentile(step, 0.99) << ','
         << slowest << ',' << before << ',' << after << '\n';
}

// A cut across each organ with three methods (rehearsal-cut.csv).
void cutTable(const std::vector<std::string>& organs, const std::string& shared, const std::string& out, bool quick,
              int cutRepeats, const std::string& cutOnly) {
  std::ofstream cutCsv(out + "/rehearsal-cut.csv");
  std::printf(
      "\nA cut across the organ (plane a quarter of its width from its left end, the blade in 12 poses, 3 steps of 10 "
      "ms each, paced)\n");
  std::printf("%-11s %-18s %7s %15s %13s %17s %15s %14s %16s\n", "organ", "method", "updates", "remesh med ms",
              "remesh p99", "step+cut med ms", "step+cut p99", "slowest step", "elements");
  cutCsv << "organ,method,updates,remesh_median_ms,remesh_p99_ms,step_with_cut_median_ms,step_with_cut_p99_ms,slowest_"
            "step_ms,elements_before,elements_after\n";
  for (const auto& organ : organs) {
    Variant gui{NewtonMethod::Chord, FactorRefresh::Asynchronous};  // the window's default
    gui.accuracy = 5e-5;
    for (const Variant& v : {Variant{NewtonMethod::Exact}, Variant{NewtonMethod::Linearised},
                             Variant{NewtonMethod::Linearised, FactorRefresh::Asynchronous}, gui}) {
      if (!cutOnly.empty() && v.name().find(cutOnly) == std::string::npos) continue;
      cutRun(organ, v, shared, quick, cutRepeats, cutCsv);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string out = ".";
  bool quick = false;
  std::string only;    // one pull variant by name (e.g. "linearised"), on the built-in liver only, and no cut: A/B runs
  bool real = false;   // only the real organs' section
  std::string organ;   // --real: only the organs whose name contains this (e.g. "patient"); with --only, one variant
  std::string cutOnly;  // --cut VARIANT: only the cut table, its variants whose name contains this
  int cutRepeats = 1;  // the cut scenario run this many times, its steps pooled (a comparison of builds wants more
                       // than the 3 updates of one run: each waits for a body built on the other core)
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick"))
      quick = true;
    else if (!std::strcmp(argv[i], "--cut-repeats") && i + 1 < argc)
      cutRepeats = std::max(1, std::atoi(argv[++i]));
    else if (!std::strcmp(argv[i], "--only") && i + 1 < argc)
      only = argv[++i];
    else if (!std::strcmp(argv[i], "--cut") && i + 1 < argc)
      cutOnly = argv[++i];
    else if (!std::strcmp(argv[i], "--real"))
      real = true;
    else if (!std::strcmp(argv[i], "--organ") && i + 1 < argc)
      organ = argv[++i];
    else
      out = argv[i];
  }
  std::filesystem::create_directories(out);

  const std::string shared = std::string(REHEARSE_SHARED_DATA);
  if (real) {
    realOrgans(out, shared, only, organ);
    return 0;
  }
  std::vector<std::string> organs = {"liver"};
  if (only.empty() && std::filesystem::exists(shared + "/sofa/liver.msh"))
    organs.push_back("sofa-liver");
  else if (only.empty())
    std::printf("(sofa-liver skipped: %s/sofa/liver.msh is absent)\n", shared.c_str());

  if (cutOnly.empty()) pullTable(organs, shared, out, only, quick);

  if (!only.empty()) return 0;
  cutTable(organs, shared, out, quick, cutRepeats, cutOnly);
  if (!cutOnly.empty()) return 0;
  if (quick) return 0;

  realOrgans(out, shared, "", "");
  return 0;
}
