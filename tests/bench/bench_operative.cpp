// Benchmark of a step with every instrument in use (issue 36; not a test): the cholecystectomy-like case on the
// patient liver (operative_case.hpp: two clips across a cystic artery, a cut between them, a burnt line, a pull until
// the liver tears), run through the gesture session as the command line runs it. Wall time per step in each phase
// (median, p99, worst over the phase's steps; each variant run `--repeat` times, the median of the runs' medians),
// with the statuses of those steps. (The grasp's pull alone, without the cut that parted the liver before it, pulls
// the whole organ from its attachments: steps of seconds, no baseline; measured once, not kept.) Variants: the script's
// own (chord, synchronous refresh, topology changes 5 steps after they are asked for: the same mesh every run) and the
// GUI's (chord with the asynchronous refresh, changes swapped in when built, steps ended at the accuracy of 0.05 mm and
// 0.5 % of the tool force), each accelerated (the default) and plain (SimulationSettings::chordAcceleration off, as
// before it existed), and each with and without the accuracy (SimulationSettings::accuracyPosition; 1e-6: the relative
// residual alone), the experiment of the nonlinear elimination of a torn flap's nodes
// (SimulationSettings::localElimination, synchronous and asynchronous), and the experiment of tears that part along faces (ToolSettings::tearRemovesElements: the
// over-stretched elements taken out, the nodes kept), synchronous, asynchronous, and asynchronous applied when built (ToolSettings::tearWhenBuilt; the window waits for a tear's body at its boundary). With --exact-check, each variant's last run is replayed and every step taken again by exact Newton
// from the same start (simcore::checkAgainstExact, as `rehearse replay --exact-check`): per phase the largest true
// error, the lowest estimate for its truth (where the truth is over 5 um), the steps past the accuracy asked, and those
// where exact Newton went to another solution of the step's equations. Writes operative-steps.csv into the directory
// given (default "."). --only TEXT runs the variants whose name contains TEXT (=NAME: that one). --record CASE records
// each variant's last run into CASE (a .rehearse file, as `rehearse gesture --record`): a run of the asynchronous
// variants is not repeatable, and `rehearse replay CASE --exact-check` checks a kept one again. --damping A,B sets the
// Rayleigh damping (alpha 1/s, beta s; the case's scene has 1, 0; the GUI's is 0.1, 0.02: app::bodySetup).
// --organ patient|bodyparts3d: the liver surface the case is meshed from (the scikit-surgery patient's, the default, or
// BodyParts3D's); --tets N: the meshing's target (default 10000: the patient liver at 9,265 elements; 17000 gives its
// 15,899 and BodyParts3D's 17,051, issue 64's sizes); --estimate-every N: SimulationSettings::estimateErrorEvery (the
// command line's 1, the default; the window's 10). --paced: the steps at real time, as the window plays them (a wait
// before a step while the organ is ahead of the wall clock, not counted in the step's time; more than 0.1 s behind,
// the time lost not made up): the second thread's builds then come in after as many steps as in the window.
// --tear-once: issue 61's "a pull past the threshold tears once and stops tearing when released" (below, where the
// script is changed): the pull's steps before the first tear ("pull") and from it on ("after the tear"), and the ratio
// of the steps' p99 from the tear on to their median from the grasp on.
//   bench_operative [OUT_DIR] [--repeat N] [--only TEXT] [--exact-check] [--record CASE] [--damping A,B]
//                   [--organ patient|bodyparts3d] [--tets N] [--estimate-every N] [--paced] [--tear-once]
#include "percentile.hpp"
#include "operative_case.hpp"
#include "session_inputs.hpp"

#include <rehearse/app/gesture.hpp>
#include <rehearse/app/recording.hpp>
#include <rehearse/simcore/scene.hpp>
#include <rehearse/simcore/session/step_truth.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace rehearse;

namespace {

using testing::percentile;

// The phase a step belongs to, by its time (the script's events: clips 0.1-0.4 s, the cut 0.4-0.9 s, the cautery
// 0.9-1.5 s, the pull and its tears from 1.5 s).
// --tear-once: the pull's steps before the first tear, and from it on (`tearAt`: the first tear's time, s).
const char* phaseOf(double t, double tearAt = -1) {
  if (t <= 0.1) return "settle";
  if (t <= 0.4) return "clips";
  if (t <= 0.9) return "cut";
  if (t <= 1.5) return "cautery";
  if (tearAt < 0) return "pull and tear";
  return t < tearAt - 1e-9 ? "pull" : "after the tear";
}

}  // namespace

int main(int argc, char** argv) {
  std::string out = ".";
  int repeat = 3;
  std::string only;  // run only the variants whose name contains this
  bool exactCheck = false;
  std::string record;  // --record CASE
  double dampingAlpha = -1, dampingBeta = -1;  // --damping A,B (negative: the scene's)
  std::string organ = "patient";               // --organ patient|bodyparts3d
  std::size_t tets = 10000;                    // --tets N: the meshing's target
  int estimateEvery = 1;                       // --estimate-every N (the window's: 10)
  bool tearOnce = false;                       // --tear-once
  bool paced = false;                          // --paced
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--exact-check") == 0)
      exactCheck = true;
    else if (std::strcmp(argv[i], "--tear-once") == 0)
      tearOnce = true;
    else if (std::strcmp(argv[i], "--paced") == 0)
      paced = true;
    else if (std::strcmp(argv[i], "--damping") == 0 && i + 1 < argc) {
      if (std::sscanf(argv[++i], "%lf,%lf", &dampingAlpha, &dampingBeta) != 2 || !(dampingAlpha >= 0) ||
          !(dampingBeta >= 0)) {
        std::fprintf(stderr, "--damping takes ALPHA,BETA (two numbers, at least 0)\n");
        return 2;
      }
    }
    else if (std::strcmp(argv[i], "--repeat") == 0 && i + 1 < argc)
      repeat = std::max(1, std::atoi(argv[++i]));
    else if (std::strcmp(argv[i], "--only") == 0 && i + 1 < argc)
      only = argv[++i];
    else if (std::strcmp(argv[i], "--record") == 0 && i + 1 < argc)
      record = argv[++i];
    else if (std::strcmp(argv[i], "--organ") == 0 && i + 1 < argc) {
      organ = argv[++i];
      if (organ != "patient" && organ != "bodyparts3d") {
        std::fprintf(stderr, "--organ takes patient or bodyparts3d\n");
        return 2;
      }
    }
    else if (std::strcmp(argv[i], "--tets") == 0 && i + 1 < argc) {
      const long n = std::atol(argv[++i]);
      if (n < 500 || n > 200000) {
        std::fprintf(stderr, "--tets takes a meshing target from 500 to 200000\n");
        return 2;
      }
      tets = static_cast<std::size_t>(n);
    }
    else if (std::strcmp(argv[i], "--estimate-every") == 0 && i + 1 < argc) {
      estimateEvery = std::atoi(argv[++i]);
      if (estimateEvery < 1) {
        std::fprintf(stderr, "--estimate-every takes a whole number of steps, at least 1\n");
        return 2;
      }
    }
    else if (argv[i][0] == '-') {
      std::fprintf(stderr, "unknown option %s (see the comment at the top of bench_operative.cpp)\n", argv[i]);
      return 2;
    }
    else
      out = argv[i];
  }
  std::filesystem::create_directories(out);
  const char* organName = organ == "patient" ? "patient liver" : "BodyParts3D liver";
  const std::string liver = std::string(REHEARSE_SHARED_DATA) +
                            (organ == "patient" ? "/scikit-surgery/patient-liver/liver.vtk" : "/bodyparts3d/FMA7197_Liver.obj");
  if (!std::filesystem::exists(liver)) {
    std::printf("the %s is absent (%s): nothing to measure\n", organName, liver.c_str());
    return 0;
  }
  const std::string dir = out + "/operative-case";
  std::filesystem::create_directories(dir);
  const testing::OperativeCase oc = testing::writeOperativeCase(liver, dir, tets);
  std::printf("%s: %zu elements, %zu nodes; cystic artery %d elements\n", organName, oc.elements, oc.nodes, oc.artery);
  simcore::BodySetup base = testing::sceneBody(simcore::loadScene(dir + "/scene.json"));
  base.settings.method = simcore::NewtonMethod::Chord;
  if (dampingAlpha >= 0) {
    base.settings.rayleighMass = dampingAlpha;
    base.settings.rayleighStiffness = dampingBeta;
  }
  base.settings.estimateErrorEvery = estimateEvery;
  std::printf("damping: alpha %g 1/s, beta %g s; error estimated every %d step(s)\n", base.settings.rayleighMass,
              base.settings.rayleighStiffness, estimateEvery);
  std::ifstream in(dir + "/chole.json");
  std::stringstream ss;
  ss << in.rdbuf();
  app::GestureScript all = app::parseGestureScript(ss.str());
  // --tear-once: issue 61's tear as a person makes it in the window (test_patient_start tearOnce): the grasper alone on
  // the intact liver (the operation's clips, cut and burn left out: at 15 % the liver beside the clipped artery tears
  // with no pull, 0.9 s after the cut), tearing at the recommended 15 % (the artery at its 60 %); the jaws hold the
  // window's 6 mm and let go at its 15 N; they pull 20 mm/s (a millimetre every five steps, as the test's mouse does)
  // and open 20 steps (0.2 s, a person's reaction) after the first tear is shown; then the organ is watched to 7.6 s.
  constexpr long kReactionSteps = 20;
  if (tearOnce) {
    all.tearStrainByLabel[1] = 0.15;
    all.maxGraspForce = 15;
    all.graspRadius = 0.006;
    all.events.back().over = 4.0;
    all.events.erase(all.events.begin(), std::find_if(all.events.begin(), all.events.end(),
                                                        [](const app::GestureEvent& e) { return e.t >= 1.5; }));
    all.duration = 7.6;
    std::printf("tear once: the liver tears at 15 %%, the jaws hold 6 mm and let go at 15 N, a 20 mm/s pull, released "
                "%ld steps after the first tear\n",
                kReactionSteps);
  }
  std::ofstream csv(out + "/operative-steps.csv");
  csv << "variant,script,phase,steps,median_ms,p99_ms,max_ms,converged,inexact,other,largest_error_mm,events,"
         "largest_true_error_mm,lowest_estimate_over_truth,past_accuracy,other_solution\n";
  // Every step of each variant's last run: what a slow step did (its Newton iterations, retries, factorisations).
  std::ofstream perStep(out + "/operative-each-step.csv");
  perStep << "variant,step,time_s,phase,wall_ms,outcome,newton_iterations,retries,factorisations,inversion_limited,"
             "residual,elements,events\n";
  // --exact-check: every step of each variant's last run against exact Newton's answer.
  std::ofstream exactRows;
  if (exactCheck) {
    exactRows.open(out + "/operative-exact.csv");
    exactRows << "variant,step,time_s,events,ended_on_accuracy,residual,iterations,factorisations,estimate_mm,true_mm,"
                 "force_error_n,resolved,own_converged_mm,own_to_exact_mm,exact_from_end_mm,why\n";
  }
  std::printf("%-22s %-14s %-14s %6s %9s %9s %9s %s\n", "variant", "script", "phase", "steps", "median ms", "p99",
              "worst", "converged/inexact/other  largest error estimate  events");
  struct Variant {
    const char* name;
    simcore::FactorRefresh refresh;
    int latency;
    bool accelerated;  // SimulationSettings::chordAcceleration
    double accuracy;   // SimulationSettings::accuracyPosition (m; 0: the relative residual alone)
    bool tearWhenBuilt = false;  // ToolSettings::tearWhenBuilt (the GUI's)
    bool tearRemovesElements = false;  // ToolSettings::tearRemovesElements (an experiment; the GUI's re-meshes)
    bool localElimination = false;  // SimulationSettings::localElimination (an experiment, issue 61)
  };
  for (const Variant v :
       {Variant{"chord, sync, latency 5", simcore::FactorRefresh::Synchronous, 5, true, 0},
        Variant{"chord, async, 0.05 mm", simcore::FactorRefresh::Asynchronous, -1, true, 5e-5},
        Variant{"chord, async, 0.05 mm, tears when built", simcore::FactorRefresh::Asynchronous, -1, true, 5e-5, true},
        Variant{"chord, async, 0.05 mm, tears part along faces", simcore::FactorRefresh::Asynchronous, -1, true, 5e-5,
                false, true},
        Variant{"chord, async, 0.05 mm, tears when built, part along faces", simcore::FactorRefresh::Asynchronous, -1,
                true, 5e-5, true, true},
        Variant{"chord, sync, 0.05 mm, tears part along faces", simcore::FactorRefresh::Synchronous, 5, true, 5e-5,
                false, true},
        Variant{"chord, sync, 0.05 mm, local elimination", simcore::FactorRefresh::Synchronous, 5, true, 5e-5, false,
                false, true},
        Variant{"chord, async, 0.05 mm, tears when built, local elimination", simcore::FactorRefresh::Asynchronous, -1,
                true, 5e-5, true, false, true},
        Variant{"chord, async (GUI), 1e-6", simcore::FactorRefresh::Asynchronous, -1, true, 0},
        Variant{"chord, sync, 0.05 mm", simcore::FactorRefresh::Synchronous, 5, true, 5e-5},
        Variant{"plain chord, sync, latency 5", simcore::FactorRefresh::Synchronous, 5, false, 0},
        Variant{"plain chord, async", simcore::FactorRefresh::Asynchronous, -1, false, 0}}) {
    if (!only.empty() && (only[0] == '=' ? only.substr(1) != v.name : std::string(v.name).find(only) == std::string::npos))
      continue;
    {
      simcore::BodySetup s = base;
      s.settings.factorRefresh = v.refresh;
      s.settings.chordAcceleration = v.accelerated;
      s.settings.accuracyPosition = v.accuracy;
      s.tools.tearWhenBuilt = v.tearWhenBuilt;
      s.tools.tearRemovesElements = v.tearRemovesElements;
      s.settings.localElimination = v.localElimination;
      app::GestureScript script = all;
      script.cutLatencySteps = v.latency;
      // phase -> per run: the step times; and the last run's statuses and events
      std::map<std::string, std::vector<double>> medians, p99s, worsts;
      std::map<std::string, std::array<int, 3>> statuses;
      std::map<std::string, std::map<std::string, int>> events;
      std::map<std::string, double> largestError;  // m: the last run's largest error estimate per phase
      simcore::BodySetup ran;  // the last run's setup and events (for --exact-check)
      std::vector<simcore::InputEvent> recorded;
      long stepsRun = 0;
      std::unique_ptr<app::Recorder> recorder;  // --record: the last run
      bool last = false;
      long tearStep = -1, releasedAt = -1;  // --tear-once: the first tear's step, the step the jaws opened at
      app::GestureHooks hooks;
      hooks.start = [&](const simcore::BodySetup& b) {
        ran = b;
        if (last && !record.empty()) {
          app::SessionMeta meta;
          meta.caseName = dir + "/scene.json";
          meta.sceneVersion = dir + "/chole.json";
          meta.appVersion = REHEARSE_VERSION;
          meta.notes = std::string("bench_operative, ") + v.name;
          recorder = std::make_unique<app::Recorder>(record, meta, b);
        }
      };
      hooks.step = [&](const simcore::StepRecord& r) {
        stepsRun = r.step;
        if (tearOnce && tearStep < 0 && r.snapshot &&
            std::count(r.snapshot->events.begin(), r.snapshot->events.end(), std::string("tear")) > 0)
          tearStep = r.step;
        if (r.recorded) recorded = *r.recorded;
        if (recorder) recorder->afterStep(r);
      };
      // --paced: the steps at real time, as the window plays them (Session::run): before each step, a wait while the
      // organ is ahead of the wall clock; more than 0.1 s behind it, the time lost is not made up.
      using Clock = std::chrono::steady_clock;
      Clock::time_point playStart;
      const double h = all.dt > 0 ? all.dt : base.settings.timeStep;
      hooks.boundary = [&](long k, simcore::Session& session) {
        if (paced) {
          if (k == 0) playStart = Clock::now();
          const double ahead = k * h - std::chrono::duration<double>(Clock::now() - playStart).count();
          if (ahead > 0) std::this_thread::sleep_for(std::chrono::duration<double>(ahead));
          if (ahead < -0.1)
            playStart += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(-ahead - 0.1));
        }
        if (!tearOnce || tearStep < 0 || releasedAt >= 0 || k < tearStep + kReactionSteps) return;
        simcore::InputEvent open;
        open.kind = simcore::InputKind::Jaw;
        open.on = false;
        session.post(open);
        releasedAt = k;
      };
      std::vector<double> ratios;  // --tear-once: each run's p99 from the tear on over the median from the grasp on
      std::vector<int> tearsHeld, tearsAfter;  // --tear-once: each run's tears before the release and after it
      double tearAt = -1;                      // s, the last run's first tear (--tear-once; 1e9: none)
      for (int r = 0; r < repeat; ++r) {
        last = r + 1 == repeat;
        tearStep = releasedAt = -1;
        const app::GestureResult g = app::runGesture(s, script, hooks);
        if (recorder) {
          recorder->finish(stepsRun);
          std::printf("recorded: session %lld in %s (%ld steps)\n", static_cast<long long>(recorder->id()),
                      record.c_str(), stepsRun);
          recorder.reset();
        }
        std::map<std::string, std::vector<double>> ms;
        tearAt = -1;
        if (tearOnce) {
          tearAt = 1e9;
          int held = 0, after = 0;
          std::vector<double> fromGrasp, fromTear;
          for (const auto& step : g.steps) {
            const int n = static_cast<int>(std::count(step.events.begin(), step.events.end(), std::string("tear")));
            if (n > 0 && tearAt > 1e8) tearAt = step.time;
            (releasedAt >= 0 && step.step > releasedAt ? after : held) += n;
            if (step.time > 1.5) fromGrasp.push_back(step.wallMs);
            if (step.time >= tearAt - 1e-9) fromTear.push_back(step.wallMs);
          }
          tearsHeld.push_back(held);
          tearsAfter.push_back(after);
          if (!fromTear.empty()) ratios.push_back(percentile(fromTear, 0.99) / percentile(fromGrasp, 0.5));
          std::printf("%-22s run %d: %s; %d tear(s) before the jaws opened, %d after; p99 from the tear on %.1f ms, "
                      "median from the grasp on %.1f ms\n",
                      v.name, r + 1,
                      tearAt > 1e8 ? "no tear"
                                   : ("first tear at " + std::to_string(tearAt) + " s, released at step " +
                                      std::to_string(releasedAt))
                                         .c_str(),
                      held, after, fromTear.empty() ? 0.0 : percentile(fromTear, 0.99), percentile(fromGrasp, 0.5));
        }
        statuses.clear();
        events.clear();
        largestError.clear();
        for (const auto& step : g.steps) {
          const std::string phase = phaseOf(step.time, tearAt);
          ms[phase].push_back(step.wallMs);
          if (std::isfinite(step.report.errorPosition))
            largestError[phase] = std::max(largestError[phase], step.report.errorPosition);
          auto& st = statuses[phase];
          ++st[step.report.outcome == simcore::StepStatus::Converged ? 0
               : step.report.outcome == simcore::StepStatus::Inexact ? 1
                                                                     : 2];
          for (const auto& e : step.events)
            if (e == "clip" || e == "cut" || e == "burn" || e == "tear" || e == "vessel cut") ++events[phase][e];
        }
        if (r + 1 == repeat)
          for (std::size_t i = 0; i < g.steps.size(); ++i) {
            const auto& step = g.steps[i];
            std::string said;
            for (const auto& e : step.events) said += (said.empty() ? "" : " ") + e;
            perStep << '"' << v.name << "\"," << i + 1 << ',' << step.time << ',' << phaseOf(step.time, tearAt) << ','
                    << step.wallMs << ',' << static_cast<int>(step.report.outcome) << ','
                    << step.report.newtonIterations << ',' << step.report.retries << ','
                    << step.report.factorisations << ',' << step.report.inversionLimited << ','
                    << step.report.residual << ',' << step.elements << ",\"" << said << "\"\n";
          }
        for (const auto& [phase, t] : ms) {
          medians[phase].push_back(percentile(t, 0.5));
          p99s[phase].push_back(percentile(t, 0.99));
          worsts[phase].push_back(percentile(t, 1.0));
        }
      }
      // The last run against exact Newton, per phase: the largest true error (m), the lowest estimate / truth, the steps
      // ended on the accuracy and past it, the steps where exact Newton went to another solution.
      struct Truth {
        double worst = 0, lowest = std::numeric_limits<double>::infinity();
        int past = 0, other = 0, unresolved = 0;
      };
      std::map<std::string, Truth> truths;
      if (exactCheck) {
        simcore::ExactCheckOptions o;
        const double asked = ran.settings.accuracyPosition;
        o.each = [&](const simcore::StepTruth& t) {
          std::string said;
          for (const auto& e : t.events) said += (said.empty() ? "" : " ") + e;
          exactRows << '"' << v.name << "\"," << t.step << ',' << t.time << ",\"" << said << "\"," << t.report.withinAccuracy
                    << ',' << t.report.residual << ',' << t.report.newtonIterations << ',' << t.report.factorisations << ','
                    << 1e3 * t.report.errorPosition << ',' << 1e3 * t.errorPosition << ',' << t.errorForce << ','
                    << t.resolved << ',' << 1e3 * t.ownConverged << ',' << 1e3 * t.ownToExact << ','
                    << 1e3 * t.exactFromEnd << ",\"" << t.why << "\"\n";
          Truth& p = truths[phaseOf(t.time, tearAt)];
          if (!t.resolved) return ++p.unresolved, true;
          if (t.anotherSolution(asked)) return ++p.other, true;
          p.worst = std::max(p.worst, t.errorPosition);
          if (t.errorPosition > 5e-6) p.lowest = std::min(p.lowest, t.report.errorPosition / t.errorPosition);
          p.past += t.report.withinAccuracy && asked > 0 && t.errorPosition > asked;
          return true;
        };
        simcore::checkAgainstExact(ran, recorded, stepsRun, o);
      }
      if (tearOnce && !ratios.empty())
        std::printf("%-22s tear once: p99 from the tear on / median from the grasp on %.2f (median of %zu runs: %s); "
                    "tears before the release %d, after it %d (the last run)\n",
                    v.name, percentile(ratios, 0.5), ratios.size(),
                    [&] {
                      std::string all;
                      for (double x : ratios) all += (all.empty() ? "" : " ") + std::to_string(x).substr(0, 4);
                      return all;
                    }()
                        .c_str(),
                    tearsHeld.back(), tearsAfter.back());
      for (const char* phase : {"settle", "clips", "cut", "cautery", "pull and tear", "pull", "after the tear"}) {
        if (!medians.count(phase)) continue;
        std::string said;
        for (const auto& [e, n] : events[phase]) said += (said.empty() ? "" : " ") + e + " x" + std::to_string(n);
        const auto& st = statuses[phase];
        const int n = st[0] + st[1] + st[2];
        std::printf("%-22s %-14s %-14s %6d %9.2f %9.2f %9.2f %d/%d/%d  %.3g mm  %s\n", v.name, "every instrument",
                    phase, n, percentile(medians[phase], 0.5), percentile(p99s[phase], 0.5),
                    percentile(worsts[phase], 0.5), st[0], st[1], st[2], 1e3 * largestError[phase], said.c_str());
        const Truth& tr = truths[phase];
        if (exactCheck)
          std::printf("%-22s %-14s %-14s against exact Newton: at most %.4f mm, estimate >= %.2f x the truth (over 5 um), "
                      "%d past the accuracy, %d to another solution, %d unresolved\n",
                      "", "", phase, 1e3 * tr.worst, std::isfinite(tr.lowest) ? tr.lowest : 0.0, tr.past, tr.other,
                      tr.unresolved);
        csv << '"' << v.name << "\"," << ("every instrument") << ',' << phase << ',' << n << ','
            << percentile(medians[phase], 0.5) << ',' << percentile(p99s[phase], 0.5) << ','
            << percentile(worsts[phase], 0.5) << ',' << st[0] << ',' << st[1] << ',' << st[2] << ','
            << 1e3 * largestError[phase] << ",\"" << said << "\",";
        if (exactCheck)
          csv << 1e3 * tr.worst << ',' << (std::isfinite(tr.lowest) ? tr.lowest : 0.0) << ',' << tr.past << ',' << tr.other;
        else
          csv << ",,,";
        csv << "\n";
      }
      std::fflush(stdout);
    }
  }
  std::printf("written %s/operative-steps.csv\n", out.c_str());
  return 0;
}
