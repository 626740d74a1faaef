// Benchmark of the starting equilibrium (issue 34; not a test): the rest shape that sags into the registered organ
// (simcore::solveRestShape) on real organ shapes from ../shared/data, meshed at the rehearsal's sizes (about 3.8k and
// 17k tets), held by the 8 % of their surface nodes highest against gravity, gravity down the image (+y). For each:
// the solve's wall time, static solves, the equilibrium's distance from the shape and the sag, then 200 steps of 10 ms
// with the GUI's method (linearised, asynchronous refresh) from the start: the largest move of a node, and the steps
// by outcome. Then (issue 61) the same organs carried by the tissue around them, gravity along the view, for the
// picks an assistant makes (none, one, 22 along the top, the 8 % highest): start error and drift over 10 s; and the
// BodyParts3D organs through `rehearse gesture --start equilibrium` with the picks as files. Writes start.csv,
// start_supported.csv and start_cli.csv into the directory given (default "."). With --pull only (issue 61's "a grasp and
// a 20 mm pull give a force of a few newtons"): the supported organs grasped and pulled 20 mm, start_pull.csv
// (REHEARSE_BENCH_ONLY="organ/picks" runs one case; REHEARSE_BENCH_DIAG=1 says the unconverged steps and the most
// compressed element; REHEARSE_BENCH_GRASP_MM the grasp radius).
//   bench_start [OUT_DIR] [--quick] [--cli] [--pull]   (--quick: the 3.8k meshes only; --cli: the command line's table)
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <rehearse/simcore/inverse_rest.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/session/session.hpp>
#include <rehearse/simcore/support.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>
#include <string>
#include <vector>

#include "realorgan.hpp"

using namespace rehearse;
using namespace rehearse::simcore;

namespace {
// An organ from ../shared/data and its material.
struct Organ {
  std::string name, path;
  MaterialParams material;
};

// The organs hung by the 8 % of their surface nodes highest against gravity, gravity down the image (+y), meshed
// at about 3.8k (and 17k) tets: the solve, then 200 steps from the start (start.csv).
void hangingStarts(const std::vector<Organ>& organs, const std::string& out, bool quick) {
  std::ofstream csv(out + "/start.csv");
  csv << "organ,tets,held,solve_s,static_solves,outcome,error_mm,sag_mm,drift_mm,steps,converged,inexact,failed,"
         "step_median_ms\n";
  std::printf("%-20s %6s %5s %8s %6s %-13s %9s %8s %9s %s\n", "organ", "tets", "held", "solve s", "solves", "outcome",
              "error mm", "sag mm", "drift mm", "200 steps (converged/inexact/failed), median ms");
  for (const Organ& o : organs) {
    if (!std::filesystem::exists(o.path)) {
      std::printf("%-20s absent: %s\n", o.name.c_str(), o.path.c_str());
      continue;
    }
    const Mesh surface = testing::loadOrganSurface(o.path);
    for (const std::size_t target : quick ? std::vector<std::size_t>{3800} : std::vector<std::size_t>{3800, 17000}) {
      BodySetup s;
      s.mesh = testing::meshedOrgan(surface, target);
      s.material = o.material;
      s.settings.gravity = Eigen::Vector3d(0, 9.81, 0);
      s.settings.method = NewtonMethod::Linearised;
      s.settings.factorRefresh = FactorRefresh::Asynchronous;
      s.fixedNodes = testing::highestSurfaceNodes(s.mesh, 0.08);
      const std::vector<Eigen::Vector3d> shape = s.mesh.points;
      const auto t0 = std::chrono::steady_clock::now();
      const InverseRestResult r = startInEquilibrium(s, shape);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      double drift = 0, median = 0;
      std::map<StepStatus, int> outcomes;
      if (r.converged()) {
        Session session(s);
        std::vector<double> ms;
        for (int k = 0; k < 200; ++k) {
          const auto a = std::chrono::steady_clock::now();
          const StepReport rep = session.advance();
          ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
          ++outcomes[rep.outcome];
          const auto& p = session.snapshot()->positions;
          for (std::size_t i = 0; i < p.size(); ++i) drift = std::max(drift, (p[i] - shape[i]).norm());
        }
        std::nth_element(ms.begin(), ms.begin() + 100, ms.end());
        median = ms[100];
      }
      const char* word = r.converged()                                      ? "converged"
                         : r.outcome == InverseRestResult::Outcome::Refused ? "refused"
                                                                            : "not converged";
      std::printf("%-20s %6zu %5zu %8.2f %6d %-13s %9.4f %8.1f %9.4f %d/%d/%d, %.2f\n", o.name.c_str(),
                  s.mesh.tets.size(), s.fixedNodes.size(), seconds, r.iterations, word, 1e3 * r.error, 1e3 * r.sag,
                  1e3 * drift, outcomes[StepStatus::Converged], outcomes[StepStatus::Inexact],
                  outcomes[StepStatus::Failed], median);
      if (!r.converged()) std::printf("    %s\n", r.status.c_str());
      csv << '"' << o.name << "\"," << s.mesh.tets.size() << ',' << s.fixedNodes.size() << ',' << seconds << ','
          << r.iterations << ',' << word << ',' << 1e3 * r.error << ',' << 1e3 * r.sag << ',' << 1e3 * drift
          << ",200," << outcomes[StepStatus::Converged] << ',' << outcomes[StepStatus::Inexact] << ','
          << outcomes[StepStatus::Failed] << ',' << median << '\n';
      std::fflush(stdout);
    }
  }
}

// The nodes that hold the organ for an assistant's picks, as `rehearse gesture --fixed-nodes` holds them (a lone pick
// holds its neighbours on the surface too, app::prepareStart); REHEARSE_BENCH_POINT_PICKS=1: the picks alone (as before
// that existed, and as the window still holds its clicks).
std::vector<int> heldFor(const Mesh& mesh, const std::vector<int>& picked) {
  if (std::getenv("REHEARSE_BENCH_POINT_PICKS")) return picked;
  return attachmentPatches(mesh, picked);
}

// Issue 61: the tissue around the organ carries it (support.hpp, the default modulus), gravity along the view (+z,
// into the scene), for the picks an assistant makes: none, one node, 22 along its top, the 8 % highest. The start's
// distance from the shape, then 10 s (1000 steps) with the GUI's method from it: the largest move of a node.
void supportedStarts(const std::vector<Organ>& organs, const std::string& out) {
  std::ofstream sup(out + "/start_supported.csv");
  sup << "organ,tets,picks,held,support_pa_per_m,solve_s,static_solves,outcome,error_mm,drift_10s_mm,steps,converged,"
         "step_median_ms\n";
  std::printf("\nsupported by the tissue around it (%g Pa/m), gravity along the view (+z):\n",
              kDefaultSupportModulus);
  std::printf("%-20s %6s %-16s %5s %8s %6s %-13s %9s %12s %s\n", "organ", "tets", "picks", "held", "solve s",
              "solves", "outcome", "error mm", "drift 10 s", "1000 steps converged, median ms");
  for (const Organ& o : organs) {
    if (!std::filesystem::exists(o.path)) continue;
    BodySetup base;
    base.mesh = testing::meshedOrgan(testing::loadOrganSurface(o.path), 3800);
    base.material = o.material;
    base.settings.gravity = Eigen::Vector3d(0, 0, 9.81);
    base.settings.method = NewtonMethod::Linearised;
    base.settings.factorRefresh = FactorRefresh::Asynchronous;
    const std::vector<Eigen::Vector3d> shape = base.mesh.points;
    for (const auto& [name, picked] : testing::assistantPicks(base.mesh)) {
      BodySetup s = base;
      s.fixedNodes = heldFor(s.mesh, picked);
      const std::vector<int>& held = s.fixedNodes;
      InverseRestOptions io;
      io.supportModulus = kDefaultSupportModulus;
      const auto t0 = std::chrono::steady_clock::now();
      const InverseRestResult r = startInEquilibrium(s, shape, io);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      double drift = 0, median = 0;
      int converged = 0;
      if (r.converged()) {
        Session session(s);
        std::vector<double> ms;
        for (int k = 0; k < 1000; ++k) {
          const auto a = std::chrono::steady_clock::now();
          const StepReport rep = session.advance();
          ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
          converged += rep.outcome == StepStatus::Converged;
          const auto& p = session.snapshot()->positions;
          for (std::size_t i = 0; i < p.size(); ++i) drift = std::max(drift, (p[i] - shape[i]).norm());
        }
        std::nth_element(ms.begin(), ms.begin() + 500, ms.end());
        median = ms[500];
      }
      const char* word = r.converged()                                      ? "converged"
                         : r.outcome == InverseRestResult::Outcome::Refused ? "refused"
                                                                            : "not converged";
      std::printf("%-20s %6zu %-16s %5zu %8.2f %6d %-13s %9.4f %9.4f mm %d, %.2f\n", o.name.c_str(),
                  s.mesh.tets.size(), name, held.size(), seconds, r.iterations, word, 1e3 * r.error, 1e3 * drift,
                  converged, median);
      if (!r.converged()) std::printf("    %s\n", r.status.c_str());
      sup << '"' << o.name << "\"," << s.mesh.tets.size() << ",\"" << name << "\"," << held.size() << ','
          << kDefaultSupportModulus << ',' << seconds << ',' << r.iterations << ',' << word << ',' << 1e3 * r.error
          << ',' << 1e3 * drift << ",1000," << converged << ',' << median << '\n';
      std::fflush(stdout);
    }
  }
}

// Issue 61, from the command line as a user runs it: each organ's meshed volume written to a file, each assistant's
// picks written as a file of node indices, then `rehearse gesture --mesh VOL --fixed-nodes PICKS --start equilibrium`
// (the default support) with a script of 10 s and no instrument. The start error is the report's, the drift the
// largest distance of the output's nodes (after 10 s) from the shape.
void commandLineStarts(const std::vector<Organ>& organs, const std::string& out) {
  std::ofstream cli(out + "/start_cli.csv");
  cli << "organ,tets,picks,held,support_pa_per_m,exit,start_error_mm,supported_nodes,drift_10s_mm,steps,converged\n";
  std::printf(
      "\nfrom the command line (rehearse gesture --start equilibrium --fixed-nodes FILE, 10 s, no instrument):\n");
  std::printf("%-20s %6s %-16s %5s %5s %9s %9s %12s %s\n", "organ", "tets", "picks", "held", "exit", "error mm",
              "supported", "drift 10 s", "steps converged");
  {
    std::ofstream still(out + "/still-10s.json");
    still << R"({"format": "rehearse-gesture", "duration": 10, "dt": 0.01, "events": []})";
  }
  for (const Organ& o : organs) {
    if (o.name == "patient liver" || !std::filesystem::exists(o.path)) continue;  // (the GUI test takes it)
    const Mesh volume = testing::meshedOrgan(testing::loadOrganSurface(o.path), 3800);
    const std::string slug = o.name == "BodyParts3D liver" ? "bp3d-liver" : "bp3d-kidney";
    const std::string vol = out + "/" + slug + ".vtu";
    saveMesh(volume, vol);
    for (const auto& [name, held] : testing::assistantPicks(volume)) {
      std::string pickSlug = name;
      std::replace(pickSlug.begin(), pickSlug.end(), ' ', '-');
      std::replace(pickSlug.begin(), pickSlug.end(), '%', 'p');
      const std::string picks = out + "/" + slug + "-" + pickSlug + ".txt", stem = out + "/" + slug + "-" + pickSlug;
      {
        std::ofstream f(picks);
        for (int n : held) f << n << '\n';
      }
      char law[160];
      std::snprintf(law, sizeof law, "--material corotational --young %.17g --poisson %.17g --density %.17g",
                    o.material.young, o.material.poisson, o.material.density);
      const std::string command = std::string("'") + REHEARSE_BINARY + "' gesture --mesh '" + vol + "' --unit m " +
                                  law + " --gravity 0,0,9.81 --start equilibrium --fixed-nodes '" + picks +
                                  "' --script '" + out + "/still-10s.json' --out '" + stem + "-end.vtu' --report '" +
                                  stem + "-report.json' > '" + stem + "-out.txt' 2>&1";
      const int status = std::system(command.c_str());
      const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      double error = -1, drift = -1;
      long supported = -1, steps = 0, converged = 0;
      if (code == 0) {
        std::ifstream rf(stem + "-report.json");
        const std::string text((std::istreambuf_iterator<char>(rf)), std::istreambuf_iterator<char>());
        auto number = [&](const char* key) {
          const auto at = text.find(std::string("\"") + key + "\":");
          return at == std::string::npos ? -1.0 : std::atof(text.c_str() + at + std::strlen(key) + 3);
        };
        error = number("start_error_m");
        supported = static_cast<long>(number("supported_nodes"));
        converged = static_cast<long>(number("converged"));
        for (std::size_t at = 0; (at = text.find("\"outcome\":", at)) != std::string::npos; ++at) ++steps;
        const Mesh end = loadMesh(stem + "-end.vtu");
        drift = 0;
        for (std::size_t i = 0; i < end.points.size() && i < volume.points.size(); ++i)
          drift = std::max(drift, (end.points[i] * end.unitToMetre - volume.points[i]).norm());
      }
      std::printf("%-20s %6zu %-16s %5zu %5d %9.4f %9ld %9.4f mm %ld of %ld\n", o.name.c_str(), volume.tets.size(),
                  name, held.size(), code, 1e3 * error, supported, 1e3 * drift, converged, steps);
      cli << '"' << o.name << "\"," << volume.tets.size() << ",\"" << name << "\"," << held.size() << ','
          << kDefaultSupportModulus << ',' << code << ',' << 1e3 * error << ',' << supported << ',' << 1e3 * drift
          << ',' << steps << ',' << converged << '\n';
      std::fflush(stdout);
    }
  }
}

// Issue 61's "a grasp and a 20 mm pull give a force of a few newtons": the same supported organs and picks, the
// grasper on free tissue (the front surface node nearest the organ's middle across the view, at least 15 mm from every
// held node), pulled 20 mm across the view away from the holds, two ways: as the mouse gives it (ten jumps of 2 mm, 5
// steps apart, as test_patient_start drags) and at a hand's speed (20 mm/s, 0.2 mm a step); then held 1 s. The jaws'
// force (no grasp limit: the tissue's own answer) at its peak, at the end of the pull and after the hold, for the
// damping given (Rayleigh beta, s).
void supportedPulls(const std::vector<Organ>& organs, const std::string& out, const std::vector<double>& betas) {
  std::ofstream csv(out + "/start_pull.csv");
  csv << "organ,tets,picks,held,beta_s,pull,held_by_jaws,peak_n,end_of_pull_n,after_1s_n,steps_not_converged\n";
  std::printf("\nthe grasper on free tissue pulled 20 mm across the view (no grasp limit), supported, gravity +z:\n");
  std::printf("%-20s %-16s %5s %7s %-6s %5s %8s %8s %8s %s\n", "organ", "picks", "held", "beta s", "pull", "jaws",
              "peak N", "end N", "1 s N", "not converged");
  const char* only = std::getenv("REHEARSE_BENCH_ONLY");  // "organ/picks" substrings, to look at one case
  for (const Organ& o : organs) {
    if (!std::filesystem::exists(o.path)) continue;
    if (only && o.name.find(std::string(only).substr(0, std::string(only).find('/'))) == std::string::npos) continue;
    BodySetup base;
    base.mesh = testing::meshedOrgan(testing::loadOrganSurface(o.path), 3800);
    base.material = o.material;
    base.settings.gravity = Eigen::Vector3d(0, 0, 9.81);
    base.settings.method = kInteractiveMethod;  // the GUI's
    base.settings.factorRefresh = FactorRefresh::Asynchronous;
    base.tools.maxGraspForce = 1e9;
    if (const char* r = std::getenv("REHEARSE_BENCH_GRASP_MM")) base.tools.graspRadius = 1e-3 * std::atof(r);
    const std::vector<Eigen::Vector3d> shape = base.mesh.points;
    for (const auto& [name, picked] : testing::assistantPicks(base.mesh)) {
      if (only && std::string(only).find('/') != std::string::npos &&
          std::string(name) != std::string(only).substr(std::string(only).find('/') + 1))
        continue;
      BodySetup s = base;
      s.fixedNodes = heldFor(s.mesh, picked);
      const std::vector<int>& held = s.fixedNodes;
      InverseRestOptions io;
      io.supportModulus = kDefaultSupportModulus;
      const InverseRestResult r = startInEquilibrium(s, shape, io);
      if (!r.converged()) {
        std::printf("%-20s %-16s no start: %s\n", o.name.c_str(), name, r.status.c_str());
        continue;
      }
      const testing::FreeBite free = testing::freeBite(s.mesh, shape, held);
      if (free.bite < 0) continue;
      const int bite = free.bite;
      const Eigen::Vector3d p = shape[static_cast<std::size_t>(bite)];
      const Eigen::Vector3d away = free.away;
      for (const double beta : betas)
        for (const bool jumps : {true, false}) {
          BodySetup d = s;
          d.settings.rayleighStiffness = beta;
          Session session(d);
          auto send = [&](InputKind kind, const Eigen::Vector3d& at, bool on) {
            InputEvent e;
            e.kind = kind;
            e.position = at;
            e.on = on;
            session.post(e);
          };
          for (int k = 0; k < 10; ++k) session.advance();
          send(InputKind::ToolPose, p, false);
          send(InputKind::Jaw, p, true);
          session.advance();
          const std::size_t jaws = session.snapshot()->tool.held.size();
          double peak = 0;
          long notConverged = 0;
          auto step = [&] {
            const StepReport rep = session.advance();
            if (rep.outcome != StepStatus::Converged && notConverged++ < 3 && std::getenv("REHEARSE_BENCH_DIAG"))
              std::printf("    step %ld: %s (%.3g N)\n", session.snapshot()->step, statusSentence(rep).c_str(),
                          session.snapshot()->tool.graspForce.norm());
            peak = std::max(peak, session.snapshot()->tool.graspForce.norm());
          };
          if (jumps)
            for (int k = 1; k <= 10; ++k) {
              send(InputKind::ToolPose, p + 0.002 * k * away, false);
              for (int i = 0; i < 5; ++i) step();
            }
          else
            for (int k = 1; k <= 100; ++k) {
              send(InputKind::ToolPose, p + 0.0002 * k * away, false);
              step();
            }
          const double endOfPull = session.snapshot()->tool.graspForce.norm();
          for (int k = 0; k < 100; ++k) step();
          const double after = session.snapshot()->tool.graspForce.norm();
          if (std::getenv("REHEARSE_BENCH_DIAG")) {  // the most compressed element: where, and how much
            const auto snap = session.snapshot();
            double worst = 1e300;
            std::size_t at = 0;
            for (std::size_t e = 0; e < s.mesh.tets.size(); ++e) {
              const auto& t = s.mesh.tets[e];
              auto vol = [&](const std::vector<Eigen::Vector3d>& x) {
                return (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]).dot(x[t[3]] - x[t[0]]);
              };
              const double ratio = vol(snap->positions) / vol(shape);
              if (ratio < worst) worst = ratio, at = e;
            }
            const auto& t = s.mesh.tets[at];
            double toHeld = 1e300;
            for (int hn : held)
              for (int k = 0; k < 4; ++k)
                toHeld = std::min(toHeld, (shape[static_cast<std::size_t>(hn)] - shape[t[k]]).norm());
            double toBite = 1e300;
            for (int k = 0; k < 4; ++k) toBite = std::min(toBite, (p - shape[t[k]]).norm());
            std::printf("    worst element %zu: volume x %.3f; %.1f mm from a held node, %.1f mm from the bite\n", at,
                        worst, 1e3 * toHeld, 1e3 * toBite);
          }
          const char* how = jumps ? "jumps" : "hand";
          std::printf("%-20s %-16s %5zu %7.3f %-6s %5zu %8.2f %8.2f %8.2f %ld\n", o.name.c_str(), name, held.size(),
                      beta, how, jaws, peak, endOfPull, after, notConverged);
          csv << '"' << o.name << "\"," << s.mesh.tets.size() << ",\"" << name << "\"," << held.size() << ',' << beta
              << ',' << how << ',' << jaws << ',' << peak << ',' << endOfPull << ',' << after << ',' << notConverged
              << '\n';
          std::fflush(stdout);
        }
    }
  }
}
}  // namespace

int main(int argc, char** argv) {
  std::string out = ".";
  bool quick = false, cliOnly = false, pullOnly = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick"))
      quick = true;
    else if (!std::strcmp(argv[i], "--cli"))
      cliOnly = true;
    else if (!std::strcmp(argv[i], "--pull"))
      pullOnly = true;
    else
      out = argv[i];
  }
  std::filesystem::create_directories(out);
  const std::string shared = REHEARSE_SHARED_DATA;
  const std::vector<Organ> organs = {
      {"patient liver",
       shared + "/scikit-surgery/patient-liver/liver.vtk",
       {MaterialModel::Corotational, 27e3, 0.4, 1079}},
      {"BodyParts3D liver", shared + "/bodyparts3d/FMA7197_Liver.obj", {MaterialModel::Corotational, 27e3, 0.4, 1079}},
      {"BodyParts3D kidney",
       shared + "/bodyparts3d/FMA7205_Left_Kidney.obj",
       {MaterialModel::Corotational, 250e3, 0.4, 1066}}};
  if (pullOnly) {
    supportedPulls(organs, out, {0.1, 0.02, 0.01});
    return 0;
  }
  if (!cliOnly) {
    hangingStarts(organs, out, quick);
    supportedStarts(organs, out);
  }
  commandLineStarts(organs, out);
  return 0;
}
