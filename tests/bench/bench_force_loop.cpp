// Benchmark of the tool-force loop per deformable model (issue 37; not a test): the 1 kHz loop on its own thread while
// the session steps beside it in real time (paced at 10 ms), a hand moving the virtual device smoothly (a thread at
// 2 kHz) through a 1.5 cm pull of a grasped node over 2 s, on the liver preset (3,760 elements) and the patient liver's
// CT shape at its size (../shared/data/scikit-surgery, meshed to about 9k elements). For each model (the FEM with the
// interactive chord method and with the linearised one, the precomputed linear elasticity): the loop's achieved rate
// and its period's median, 99th percentile and worst; the session's step time (median, p99) and its outcomes; and how
// good the loop's force is between steps: at each step's new tip, the loop's extrapolation from the last step (f0 + K
// dp, what the hand felt) against the force that step then solves there (its relative error, median and worst; the
// precomputed model's K is exact, so only its cap and contact changes remain). Medians of the run. Writes
// force-loop.csv into the directory given (default ".").
#include "percentile.hpp"
#include "phantom/presets.hpp"
#include "realorgan.hpp"
#include "session_inputs.hpp"

#include <rehearse/simcore/paramesh.hpp>
#include <rehearse/simcore/session/forceloop.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string>
#include <memory>
#include <thread>
#include <vector>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

using testing::percentile;

struct Model {
  const char* name;
  BodyModel model;
  NewtonMethod method;
};

constexpr int kSteps = 200;      // 2 s of pulling at 10 ms
constexpr double kPull = 0.015;  // m, along -z (towards the camera; 2 cm slips the FEM's grasp at 15 N)

// The organ's body: the liver preset, or the patient's liver (false, said, when its file is absent).
bool organBody(const char* organ, BodySetup& base) {
  if (std::string(organ) == "liver preset") {
    base = testing::presetBody("liver", REHEARSE_SHARED_DATA);
  } else {
    // The patient's liver (its CT surface, scikit-surgery) at its own size, meshed to about 9k elements, hung by its
    // highest 8 % of surface nodes, the liver preset's tissue.
    const std::string path = std::string(REHEARSE_SHARED_DATA) + "/scikit-surgery/patient-liver/liver.vtk";
    if (!std::filesystem::exists(path)) {
      std::printf("%s is absent: skipped\n", path.c_str());
      return false;
    }
    TetrahedraliseOptions to;
    to.allowSelfIntersections = true;
    to.targetTets = 9000;
    base.mesh = tetrahedraliseSurface(testing::loadOrganSurface(path), to);
    const BodySetup preset = testing::presetBody("liver", REHEARSE_SHARED_DATA);
    base.material = preset.material;
    base.settings = preset.settings;
    base.tools = preset.tools;
    base.tools.trocar.reset();
    base.settings.gravity = Eigen::Vector3d(0, 9.81, 0);
    base.fixedNodes = testing::highestSurfaceNodes(base.mesh, 0.08);
  }
  return true;
}

// The loop beside the session stepping in real time, the hand pulling the grasped node: one line, one row.
void runModel(const char* organ, const BodySetup& base, const Model& m, std::ofstream& csv) {
  BodySetup s = base;
  s.model = m.model;
  s.settings.method = m.method;
  std::unique_ptr<Session> built;
  try {
    built = std::make_unique<Session>(s);
  } catch (const std::exception& e) {  // a model this organ refuses (said, as the GUI says it)
    std::printf("%-14s %6zu %-26s refused: %s\n", organ, s.mesh.tets.size(), m.name, e.what());
    return;
  }
  Session& session = *built;
  for (int k = 0; k < 20; ++k) session.advance();  // settled under gravity
  const auto snap = session.snapshot();
  std::vector<char> fixed(snap->positions.size(), 0);
  for (int v : s.fixedNodes) fixed[static_cast<std::size_t>(v)] = 1;
  Eigen::Vector3d tip(0, 0, 1e9);
  for (std::size_t i = 0; i < snap->positions.size(); ++i)
    if (!fixed[i] && snap->positions[i].z() < tip.z())
      tip = snap->positions[i];  // the free node nearest the camera
  session.post(testing::toolAt(tip));
  InputEvent jaw = testing::jaws(true);
  jaw.position = tip;
  session.post(jaw);
  session.advance();
  VirtualDevice device;
  device.setPosition(tip);
  ForceLoop loop([&session] { return session.toolForce(); }, &device);
  loop.start();
  // The hand: the device moves continuously (2 kHz), the session gets the pose at each step.
  const auto began = std::chrono::steady_clock::now();
  const double duration = kSteps * s.settings.timeStep;
  auto handAt = [&](double t) {
    return Eigen::Vector3d(tip + Eigen::Vector3d(0, 0, -kPull * std::min(1.0, t / duration)));
  };
  std::atomic<bool> done{false};
  std::thread hand([&] {
    while (!done) {
      device.setPosition(handAt(std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count()));
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
  });
  std::vector<double> stepMs, errors;
  int converged = 0, other = 0;
  auto due = began;
  for (int k = 1; k <= kSteps; ++k) {
    std::this_thread::sleep_until(due);
    const Eigen::Vector3d p =
        handAt(std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count());
    const Eigen::Vector3d felt = extrapolateForce(session.toolForce(), p);  // what the loop renders at p now
    session.post(testing::toolAt(p));
    const auto t0 = std::chrono::steady_clock::now();
    const StepReport rep = session.advance();
    const auto t1 = std::chrono::steady_clock::now();
    stepMs.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    (rep.outcome == StepStatus::Converged ? converged : other)++;
    const Eigen::Vector3d solved = extrapolateForce(session.toolForce(), p);  // the step's own force at p
    if (solved.norm() > 1e-3) errors.push_back((felt - solved).norm() / solved.norm());
    due = std::max(due + std::chrono::milliseconds(10), t1);
  }
  done = true;
  hand.join();
  loop.stop();
  const ForceLoop::Timing t = loop.timing();
  const double fEnd = session.snapshot()->tool.force.norm();
  const double errMed = percentile(errors, 0.5), errMax = percentile(errors, 1.0);
  std::printf("%-14s %6zu %-26s %8.0f %7.3f %7.3f %7.2f %8.3f %8.3f %5d/%-3d %9.2e %9.2e %7.2f%s\n", organ,
              s.mesh.tets.size(), m.name, t.rateHz, t.medianPeriodMs, t.p99PeriodMs, t.maxPeriodMs,
              percentile(stepMs, 0.5), percentile(stepMs, 0.99), converged, other, errMed, errMax, fEnd,
              t.realtime ? "" : " (no real-time priority)");
  std::fflush(stdout);
  csv << organ << ',' << s.mesh.tets.size() << ",\"" << m.name << "\"," << t.rateHz << ',' << t.medianPeriodMs
      << ',' << t.p99PeriodMs << ',' << t.maxPeriodMs << ',' << t.realtime << ',' << percentile(stepMs, 0.5) << ','
      << percentile(stepMs, 0.99) << ',' << converged << ',' << other << ',' << errMed << ',' << errMax << ','
      << fEnd << '\n';
}

  // The parameterized mesh (FFD and Hertz's law): the loop computes the force itself at the device's position each
  // tick (no step behind it: the deformation is the loop's own), the same pull of the surface vertex nearest the
  // grasped node. Its update time is the hold's (median of 2,000 along the pull).
void runParameterizedMesh(const char* organ, const BodySetup& base, std::ofstream& csv) {
  std::vector<Eigen::Vector3d> points = base.mesh.points;
  std::vector<std::array<int, 3>> triangles = boundaryTriangles(base.mesh, false);
  if (std::string(organ) == "patient liver") {  // its file's surface (the mesh's has a non-manifold edge)
    const Mesh file =
        testing::loadOrganSurface(std::string(REHEARSE_SHARED_DATA) + "/scikit-surgery/patient-liver/liver.vtk");
    points = file.points, triangles = file.triangles;
  }
  std::string why;
  GeometryImageSettings gs;
  gs.maxSize = gs.size;  // the paper's 81 x 81, as the row says
  const auto gi = makeGeometryImage(points, triangles, gs, why);
  if (!gi) {
    std::printf("%-14s %6s %-26s the geometry image failed: %s\n", organ, "", "FFD, 81 x 81", why.c_str());
    return;
  }
  FfdSettings fs;
  fs.youngModulus = base.material.young;
  fs.poisson = base.material.poisson;
  ParameterizedMesh pm(*gi, fs);
  Eigen::Vector3d tip(0, 0, 1e9);
  for (const auto& p : gi->points)
    if (p.z() < tip.z()) tip = p;
  const int held = pm.nearestVertex(tip);
  std::vector<double> updateUs;
  for (int k = 1; k <= 2000; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    pm.hold(held, Eigen::Vector3d(0, 0, -kPull * k / 2000.0));
    updateUs.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  VirtualDevice device;
  device.setPosition(tip);
  ForceLoop loop([&](const Eigen::Vector3d& p) { return Eigen::Vector3d(-pm.hold(held, p - tip).force); }, &device);
  loop.start();
  const auto began = std::chrono::steady_clock::now();
  const double duration = kSteps * base.settings.timeStep;
  for (;;) {
    const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count();
    if (t > duration) break;
    device.setPosition(tip + Eigen::Vector3d(0, 0, -kPull * t / duration));
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  loop.stop();
  const ForceLoop::Timing t = loop.timing();
  const double fEnd = device.rendered().norm();
  std::printf("%-14s %6s %-26s %8.0f %7.3f %7.3f %7.2f %8.4f %8.4f %9s %9s %9s %7.2f%s\n", organ, "-",
              "FFD, 81 x 81", t.rateHz, t.medianPeriodMs, t.p99PeriodMs, t.maxPeriodMs,
              1e-3 * percentile(updateUs, 0.5), 1e-3 * percentile(updateUs, 0.99), "(no step)", "-", "-", fEnd,
              t.realtime ? "" : " (no real-time priority)");
  std::fflush(stdout);
  csv << organ << ",0,\"FFD, 81 x 81\"," << t.rateHz << ',' << t.medianPeriodMs << ',' << t.p99PeriodMs << ','
      << t.maxPeriodMs << ',' << t.realtime << ',' << 1e-3 * percentile(updateUs, 0.5) << ','
      << 1e-3 * percentile(updateUs, 0.99) << ",0,0,,," << fEnd << '\n';
}

}  // namespace

int main(int argc, char** argv) {
  const std::string out = argc > 1 ? argv[1] : ".";
  std::filesystem::create_directories(out);
  std::ofstream csv(out + "/force-loop.csv");
  csv << "organ,tets,model,loop_rate_hz,period_median_ms,period_p99_ms,period_max_ms,realtime,step_median_ms,"
         "step_p99_ms,converged,other,force_error_median_rel,force_error_max_rel,force_end_n\n";
  std::printf("%-14s %6s %-26s %8s %7s %7s %7s %8s %8s %9s %9s %9s %7s\n", "organ", "tets", "model", "loop Hz",
              "med ms", "p99 ms", "max ms", "step med", "step p99", "conv/oth", "f err med", "f err max", "f N");
  for (const char* organ : {"liver preset", "patient liver"}) {
    BodySetup base;
    if (!organBody(organ, base)) continue;
    for (const Model& m : {Model{"FEM, chord (interactive)", BodyModel::Fem, NewtonMethod::Chord},
                           Model{"FEM, linearised", BodyModel::Fem, NewtonMethod::Linearised},
                           Model{"precomputed linear", BodyModel::Precomputed, NewtonMethod::Chord},
                           Model{"hybrid (30 mm FEM region)", BodyModel::Hybrid, NewtonMethod::Chord},
                           Model{"FFD body (session)", BodyModel::Ffd, NewtonMethod::Chord}}) {
      runModel(organ, base, m, csv);
    }
    runParameterizedMesh(organ, base, csv);
  }
  std::printf("written %s/force-loop.csv\n", out.c_str());
  return 0;
}
