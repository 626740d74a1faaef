// The grasper through the simulation session (issue 15): a grasp-and-pull on a cantilever block against
// CalculiX with the same imposed displacement (the tool's force within 5 % of ccx's support reaction), the
// built-in phantom's liver grasped, pulled and released (the bite follows the tip within 1 mm, the
// ligament nodes stay, the organ relaxes, the mass is unchanged), a slip above the scene's maximum grasp
// force (an event and a sentence), and the gesture scripts' refusals.
#include "box_mesh.hpp"
#include "calculix.hpp"
#include "phantom/phantom.hpp"
#include "phantom/presets.hpp"
#include "session_inputs.hpp"

#include <rehearse/app/case.hpp>
#include <rehearse/app/gesture.hpp>
#include <rehearse/app/sessionstart.hpp>
#include <rehearse/simcore/session/forceloop.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <Eigen/Dense>

#include <fstream>
#include <limits>
#include <map>
#include <thread>
#include <sstream>

using namespace rehearse;
using simcore::InputEvent;
using simcore::InputKind;

namespace {
using testing::jaws;
using testing::toolAt;
simcore::BodySetup liverSetup() {
  simcore::BodySetup s = testing::presetBody("liver");
  s.settings.method = simcore::NewtonMethod::Exact;
  return s;
}
// The liver settled for 50 steps, then the jaws closed on the node nearest (0, 0, -5 cm), above the organ: returns
// where they closed.
Eigen::Vector3d settleAndGrasp(simcore::Session& session) {
  for (int k = 0; k < 50; ++k) session.advance();
  Eigen::Vector3d tip = session.snapshot()->positions.front();
  for (const auto& p : session.snapshot()->positions)
    if ((p - Eigen::Vector3d(0, 0, -0.05)).norm() < (tip - Eigen::Vector3d(0, 0, -0.05)).norm()) tip = p;
  session.post(toolAt(tip));
  session.post(jaws(true));
  session.advance();
  return tip;
}
}  // namespace

class TestGrasp : public QObject {
  Q_OBJECT
 private slots:
  // A 100 x 20 x 20 mm block held at x = 0; the grasper bites the middle of its free end and moves it 2 mm
  // sideways; after the block settles (large implicit steps, no gravity) the force the tool holds it with
  // is the support reaction CalculiX finds for the same nodes moved by the same displacements (NLGEOM: our
  // co-rotational law is geometrically nonlinear too; a linear ccx step misses the 0.7 mN axial part).
  void graspPullAgainstCalculix() {
    simcore::BodySetup s;
    s.mesh = boxMesh(0.1, 0.02, 0.02, 20, 4, 4);
    s.fixedNodes = nodesAtX(s.mesh, 0.0);
    s.material = {simcore::MaterialModel::Corotational, 10e3, 0.3, 1000};
    s.settings.gravity = Eigen::Vector3d::Zero();
    s.settings.timeStep = 0.5;
    s.settings.method = simcore::NewtonMethod::Exact;
    s.tools.graspRadius = 0.0055;  // nodes 5 mm apart: the bite holds the nearest six
    s.tools.maxGraspForce = 1e6;
    s.tools.toolRadius = 0;  // the grasp alone (CalculiX's run has no contact with the shaft)
    simcore::Session session(s);
    const Eigen::Vector3d end(0.1, 0.01, 0.01);
    session.post(toolAt(end));
    session.post(jaws(true));
    session.advance();
    const auto held = session.snapshot()->tool.held;
    QCOMPARE(held.size(),
             std::size_t(6));  // the end face's middle node, its four neighbours on the face and the one behind it
    const Eigen::Vector3d pull(0, 0, 0.002);
    session.post(toolAt(end + pull));
    for (int k = 0; k < 60; ++k) QVERIFY(session.advance().ok);
    const auto snap = session.snapshot();
    const Eigen::Vector3d ours = snap->tool.force;
    const double vmax = session.state().v.cwiseAbs().maxCoeff();
    QVERIFY2(vmax < 1e-9, qPrintable(QString::number(vmax)));  // settled: the force is the static one
    // The session reports the constraint solver's multipliers; the body's force balance at the held nodes
    // (an independent route through the elastic forces) says the same.
    const auto body = simcore::makeFemBody(s);
    const Eigen::Vector3d balance = body->appliedForce(held, session.state(), session.state().v, s.settings.timeStep);
    qInfo("multipliers (%.6f, %.6f, %.6f) N, force balance (%.6f, %.6f, %.6f) N", ours.x(), ours.y(), ours.z(),
          balance.x(), balance.y(), balance.z());
    QVERIFY((ours - balance).norm() < 1e-3 * ours.norm());
    std::map<int, Eigen::Vector3d> imposed;
    double follow = 0;
    for (int i : held) {
      imposed[i] = snap->positions[static_cast<std::size_t>(i)] - s.mesh.points[static_cast<std::size_t>(i)];
      follow = std::max(follow, (imposed[i] - pull).norm());
    }
    QVERIFY2(follow < 1e-6, qPrintable(QString::number(follow)));  // the bite moved with the tip
    Eigen::Vector3d reaction;
    const Eigen::VectorXd u =
        runCalculixStatic(s.mesh, {}, CcxMaterial{10e3, 0.3, 1000, false}, Eigen::Vector3d::Zero(), true, s.fixedNodes,
                          "grasp-pull", {}, imposed, &reaction);
    QVERIFY2(u.size() > 0, "CalculiX (ccx) did not run; scripts/install-deps.sh installs calculix-ccx");
    const double error = (ours - reaction).norm() / reaction.norm();
    qInfo("tool force (%.5f, %.5f, %.5f) N, CalculiX's reaction (%.5f, %.5f, %.5f) N: %.2f %% apart", ours.x(),
          ours.y(), ours.z(), reaction.x(), reaction.y(), reaction.z(), 100 * error);
    QVERIFY(reaction.norm() > 1e-4);
    QVERIFY(error < 0.05);
  }

  // Issue 32 (forces within the physics): the same grasp and pull on the same 60 x 12 x 12 mm cantilever meshed at
  // 6, 3 and 1.5 mm. The bite (4 mm) holds 1 node on the coarsest mesh and a patch on the finer ones, so the force
  // depends on the mesh; it must converge as the mesh refines (each refinement changes it less than the one before,
  // the last by under 15 %) and lie between the beam's free-end and guided-end stiffness (3 EI/L^3 and 12 EI/L^3: the
  // held patch translates without turning, which holds the end partly against rotation).
  void graspForceConvergesWithTheMesh() {
    const double L = 0.06, a = 0.012, E = 10e3, pull = 0.002;
    auto force = [&](int n) {
      simcore::BodySetup s;
      s.mesh = boxMesh(L, a, a, 5 * n, n, n);
      s.fixedNodes = nodesAtX(s.mesh, 0.0);
      s.material = {simcore::MaterialModel::Corotational, E, 0.3, 1000};
      s.settings.gravity = Eigen::Vector3d::Zero();
      s.settings.timeStep = 2.0;
      s.settings.method = simcore::NewtonMethod::Exact;
      s.tools.graspRadius = 0.004;
      s.tools.maxGraspForce = 1e6;
      s.tools.toolRadius = 0;
      simcore::Session session(s);
      const Eigen::Vector3d end(L, a / 2, a / 2);
      session.post(toolAt(end));
      session.post(jaws(true));
      session.advance();
      const std::size_t held = session.snapshot()->tool.held.size();
      session.post(toolAt(end + Eigen::Vector3d(0, 0, pull)));
      // Stepped until settled (at most 40 steps of 2 s): the force asked for is the static one.
      int steps = 0;
      double vmax = std::numeric_limits<double>::infinity();
      while (steps < 40 && !(vmax < 1e-9)) {
        session.advance();
        ++steps;
        vmax = session.state().v.cwiseAbs().maxCoeff();
      }
      const auto snap = session.snapshot();
      qInfo("%d elements across: %zu tets, %zu node(s) held, tool force %.4f mN (settled to %.1e m/s in %d steps)", n,
            s.mesh.tets.size(), held, 1e3 * snap->tool.force.norm(), vmax, steps);
      return std::make_pair(snap->tool.force.norm(), vmax);
    };
    const auto [f1, v1] = force(2);
    const auto [f2, v2] = force(4);
    const auto [f3, v3] = force(8);
    const double I = a * a * a * a / 12, free = 3 * E * I * pull / (L * L * L), guided = 4 * free;
    qInfo("changes with refinement: %.1f %% then %.1f %%; beam: free end %.4f mN, guided end %.4f mN",
          100 * std::abs(f2 - f1) / f2, 100 * std::abs(f3 - f2) / f3, 1e3 * free, 1e3 * guided);
    QVERIFY(std::max({v1, v2, v3}) < 1e-8);  // settled: static forces
    QVERIFY(std::abs(f3 - f2) < std::abs(f2 - f1));
    QVERIFY(std::abs(f3 - f2) < 0.15 * f3);
    QVERIFY(f3 > free && f3 < guided);
  }

  // Issue 32: a steady grasp released without moving (grasp-pull.json with the GUI's 2.5 mm shaft). The bitten node
  // sits at the tip, on the shaft's axis, where the direction out of the shaft is noise: it was skipped at the release
  // and pushed out to the radius at the next step (one step of 5.74 N after a steady 17.3 N). Now it is pushed along
  // the surface's own inward normal, eased from where it is: the recoiling tissue leaves the instrument without a
  // spike.
  void releaseWithoutASpike() {
    std::ifstream in(std::string(REHEARSE_SOURCE_DIR) + "/resources/gestures/grasp-pull.json");
    std::stringstream ss;
    ss << in.rdbuf();
    app::GestureScript script = app::parseGestureScript(ss.str());
    script.toolRadius = 0.0025;
    script.duration = 2.6;
    simcore::BodySetup s = testing::presetBody("liver");
    s.settings.method = simcore::NewtonMethod::Linearised;
    const app::GestureResult r = app::runGesture(s, script);
    QCOMPARE(r.failed, std::size_t(0));
    std::size_t release = 0;
    for (std::size_t k = 0; k < r.steps.size() && !release; ++k)
      if (std::find(r.steps[k].events.begin(), r.steps[k].events.end(), "release") != r.steps[k].events.end())
        release = k;
    QVERIFY(release > 10);
    const double held = r.steps[release - 1].toolForce.norm();
    double after = 0;
    for (std::size_t k = release; k < std::min(r.steps.size(), release + 20); ++k)
      after = std::max(after, r.steps[k].toolForce.norm());
    qInfo("held %.2f N steadily; the 20 steps after the release peak at %.3f N", held, after);
    QVERIFY(held > 1);
    QVERIFY(after < 0.05 * held);
  }

  // The phantom's liver: settle, grasp the front, pull 2 cm towards the camera, release.
  void liverGraspPullRelease() {
    simcore::BodySetup s = liverSetup();
    s.tools.maxGraspForce = 1e6;
    simcore::Session session(s);
    for (int k = 0; k < 100; ++k) session.advance();  // settled on the ligaments
    const auto settled = session.snapshot();
    const double mass = settled->mass;
    // The tip on the front of the organ (the node nearest a point in front of it).
    Eigen::Vector3d tip = settled->positions.front();
    for (const auto& p : settled->positions)
      if ((p - Eigen::Vector3d(0, 0, -0.05)).norm() < (tip - Eigen::Vector3d(0, 0, -0.05)).norm()) tip = p;
    session.post(toolAt(tip));
    session.post(jaws(true));
    session.advance();
    const auto grasped = session.snapshot();
    QVERIFY(!grasped->tool.held.empty());
    QVERIFY(std::find(grasped->events.begin(), grasped->events.end(), "grasp") != grasped->events.end());
    const Eigen::Vector3d towardsCamera(0.208, 0.366, -0.907);
    for (int k = 1; k <= 100; ++k) {
      session.post(toolAt(tip + 0.02 * towardsCamera * (k / 100.0)));
      QVERIFY(session.advance().ok);
    }
    const auto pulled = session.snapshot();
    double worst = 0, fixedMoved = 0;
    for (std::size_t k = 0; k < pulled->tool.held.size(); ++k) {
      const auto i = static_cast<std::size_t>(pulled->tool.held[k]);
      worst = std::max(worst, (pulled->positions[i] - (pulled->tool.tip + pulled->tool.heldOffset[k])).norm());
    }
    for (int i : s.fixedNodes)
      fixedMoved = std::max(
          fixedMoved,
          (pulled->positions[static_cast<std::size_t>(i)] - s.mesh.points[static_cast<std::size_t>(i)]).norm());
    qInfo(
        "pulled 2 cm: %zu nodes held, worst %.4f mm from their place on the tool, tool force %.2f N, ligament nodes "
        "moved %.2e m",
        pulled->tool.held.size(), 1e3 * worst, pulled->tool.force.norm(), fixedMoved);
    QVERIFY(worst < 1e-3);
    QVERIFY(fixedMoved < 1e-12);
    QVERIFY(pulled->tool.force.norm() > 0.01);
    QVERIFY(pulled->tool.force.dot(towardsCamera) > 0);  // the tool pulls the tissue towards the camera
    const Eigen::Vector3d heldAt = pulled->positions[static_cast<std::size_t>(pulled->tool.held.front())];
    session.post(jaws(false));
    session.advance();
    QVERIFY(std::find(session.snapshot()->events.begin(), session.snapshot()->events.end(), "release") !=
            session.snapshot()->events.end());
    for (int k = 0; k < 150; ++k) session.advance();
    const auto relaxed = session.snapshot();
    const auto node = static_cast<std::size_t>(pulled->tool.held.front());
    const double before = (heldAt - settled->positions[node]).norm(),
                 after = (relaxed->positions[node] - settled->positions[node]).norm();
    qInfo("released: the bitten node %.1f mm from where it settled when let go, %.1f mm 1.5 s later", 1e3 * before,
          1e3 * after);
    QVERIFY(after < 0.5 * before);
    QCOMPARE(relaxed->mass, mass);
    QVERIFY(relaxed->tool.held.empty());
    QCOMPARE(relaxed->tool.force.norm(), 0.0);
  }

  // The tool's local stiffness (the haptic loop's extrapolation, from the last solve's compliance) against
  // finite differences: from one checkpoint mid-pull, the next step with the tip moved by 0.1 mm along each
  // axis; the force's change per metre is the published stiffness (the linearised step is linear in the tip,
  // so they agree to the constraint solver's tolerance). It is the one-step (instantaneous) stiffness, as
  // SOFA's LCP force feedback uses: while pulling steadily the tissue around the bite relaxes within each
  // step, so it over-predicts the next step's force (printed, not asserted: a fact about the model).
  void toolStiffnessIsTheForceDerivative() {
    simcore::BodySetup s = testing::presetBody("liver");
    s.settings.method = simcore::NewtonMethod::Linearised;
    s.tools.maxGraspForce = 1e6;
    simcore::Session session(s);
    const Eigen::Vector3d tip = settleAndGrasp(session);
    const Eigen::Vector3d pull(0.208, 0.366, -0.907);
    for (int k = 1; k <= 30; ++k) {
      session.post(toolAt(tip + 0.0002 * k * pull));
      session.advance();
    }
    QVERIFY(!session.snapshot()->tool.held.empty());
    const simcore::Checkpoint cp = session.checkpoint();
    const Eigen::Vector3d at = tip + 0.0002 * 31 * pull;
    auto stepTo = [&](const Eigen::Vector3d& p) {
      session.restore(cp);
      session.post(toolAt(p));
      session.advance();
      return session.snapshot();
    };
    const auto base = stepTo(at);
    const Eigen::Matrix3d K = base->tool.stiffness;
    Eigen::Matrix3d fd;
    const double d = 1e-4;
    for (int a = 0; a < 3; ++a)
      fd.col(a) = (stepTo(at + d * Eigen::Vector3d::Unit(a))->tool.force - base->tool.force) / d;
    const double rel = (fd - K).norm() / K.norm();
    qInfo(
        "tool stiffness: |K| %.1f N/m, eigenvalues of its symmetric part %.1f %.1f %.1f N/m; finite differences differ "
        "by %.2e relative",
        K.norm(), Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(K).eigenvalues()[0],
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(K).eigenvalues()[1],
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(K).eigenvalues()[2], rel);
    QVERIFY(K.norm() > 1.0);
    QVERIFY2(rel < 1e-4,
             qPrintable(QStringLiteral("finite differences %1 relative from the published stiffness").arg(rel)));
    QVERIFY(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(K).eigenvalues().minCoeff() >
            0);  // pulling further always pulls harder

    // Extrapolation between steps: the model of step k evaluated where the tool is at step k + 1.
    session.restore(cp);
    double extrapolated = 0, held = 0;
    auto previous = session.snapshot();
    for (int k = 32; k <= 60; ++k) {
      const Eigen::Vector3d p = tip + 0.0002 * k * pull;
      const simcore::ToolForceModel model = simcore::toolForceModel(*previous, s.tools.maxGraspForce);
      session.post(toolAt(p));
      session.advance();
      const auto now = session.snapshot();
      // The loop's lock-free source carries exactly the snapshot's model.
      const simcore::ToolForceModel lockFree = session.toolForce(),
                                    fromSnapshot = simcore::toolForceModel(*now, s.tools.maxGraspForce);
      QCOMPARE(lockFree.step, fromSnapshot.step);
      QVERIFY(lockFree.tip == fromSnapshot.tip && lockFree.force == fromSnapshot.force &&
              lockFree.stiffness == fromSnapshot.stiffness);
      QCOMPARE(lockFree.maxForce, fromSnapshot.maxForce);
      extrapolated = std::max(extrapolated, (simcore::extrapolateForce(model, p) - now->tool.force).norm());
      held = std::max(held, (previous->tool.force - now->tool.force).norm());
      previous = now;
    }
    qInfo(
        "next step's force while pulling 0.2 mm per step: extrapolated from the last step's model within %.4f N, the "
        "last force held within %.4f N "
        "(worst of 29 steps)",
        extrapolated, held);
    QVERIFY(std::isfinite(extrapolated) && held > 0);
  }

  // The shaft pressed into the tissue and swept across it (nothing held), a hand's pace (1 mm a step, 0.5 mm a step):
  // the force the loop renders between steps (the last step's model at the next step's tip) against the force that step
  // solves there. A person saw the chart spike to about 48 N at a touch that solved a few newtons.
  void theLoopExtrapolatesOnlyWhatStillActs() {
    // The loop's force between steps, f0 + K (p - p0), from a step's snapshot: K only from a step that solved its
    // equations with something held or touched. A person's chart (the patient liver) rose to 5-194 kN between steps
    // that solved 16-25 N: after a slip (nothing held, no cap) and on steps that did not converge.
    simcore::Snapshot s;
    s.tool.tip = Eigen::Vector3d(0, 0, 0.1);
    s.tool.force = Eigen::Vector3d(2, 0, 0);
    s.tool.stiffness = 1e6 * Eigen::Matrix3d::Identity();  // N/m
    s.tool.held = {7};
    s.report.outcome = simcore::StepStatus::Converged;
    const Eigen::Vector3d moved = s.tool.tip + Eigen::Vector3d(1e-6, 0, 0);  // 1 um: 1 N more along x
    auto at = [&](double cap) { return simcore::extrapolateForce(simcore::toolForceModel(s, cap, 0.0025), moved); };
    QVERIFY((at(15) - Eigen::Vector3d(3, 0, 0)).norm() < 1e-9);  // held, converged: f0 + K d
    s.tool.held.clear();  // slipped: nothing held, nothing touched
    QVERIFY((at(15) - s.tool.force).norm() < 1e-12);
    s.tool.contacts = 3;  // the shaft touches: its stiffness, uncapped
    QVERIFY((at(15) - Eigen::Vector3d(3, 0, 0)).norm() < 1e-9);
    for (const auto outcome : {simcore::StepStatus::Failed, simcore::StepStatus::Inverted}) {
      s.report.outcome = outcome;  // a step that did not solve: its force held
      QVERIFY((at(15) - s.tool.force).norm() < 1e-12);
    }
    s.report.outcome = simcore::StepStatus::Inexact;  // the linearised method's one solve: extrapolated
    QVERIFY((at(15) - Eigen::Vector3d(3, 0, 0)).norm() < 1e-9);
    s.report.keptBestOf = 4;  // no attempt converged, the best kept: held
    QVERIFY((at(15) - s.tool.force).norm() < 1e-12);
  }

  void shaftContactForceBetweenSteps() {
    for (const double mmPerStep : {0.5, 1.0}) {
      simcore::BodySetup s = liverSetup();
      s.settings.method = simcore::NewtonMethod::Chord;
      s.tools.toolRadius = 0.0025;
      simcore::Session session(s);
      for (int k = 0; k < 50; ++k) session.advance();
      Eigen::Vector3d top = session.snapshot()->positions.front();
      for (const auto& p : session.snapshot()->positions)
        if ((p - Eigen::Vector3d(0, 0, -0.05)).norm() < (top - Eigen::Vector3d(0, 0, -0.05)).norm()) top = p;
      // From 6 mm above the surface down 10 mm into it, then 20 mm sideways.
      std::vector<Eigen::Vector3d> path;
      for (double d = -6; d <= 4; d += mmPerStep) path.push_back(top + 0.001 * Eigen::Vector3d(0, 0, d));
      for (double x = mmPerStep; x <= 20; x += mmPerStep) path.push_back(path.back() + 0.001 * mmPerStep * Eigen::Vector3d::UnitX());
      auto previous = session.snapshot();
      double worst = 0, worstSolved = 0, worstRendered = 0, peakSolved = 0, peakRendered = 0;
      int touched = -1;
      for (std::size_t k = 0; k < path.size(); ++k) {
        const simcore::ToolForceModel model = simcore::toolForceModel(*previous, s.tools.maxGraspForce, s.tools.toolRadius);
        session.post(toolAt(path[k]));
        session.advance();
        const auto now = session.snapshot();
        if (touched < 0 && now->tool.contacts > 0) touched = static_cast<int>(k);
        const Eigen::Vector3d rendered = model.step >= 0 ? simcore::extrapolateForce(model, path[k]) : Eigen::Vector3d::Zero();
        const double off = (rendered - now->tool.force).norm();
        peakSolved = std::max(peakSolved, now->tool.force.norm());
        peakRendered = std::max(peakRendered, rendered.norm());
        if (off > worst) worst = off, worstSolved = now->tool.force.norm(), worstRendered = rendered.norm();
        previous = now;
      }
      qInfo("shaft pressed and swept at %.1f mm a step (touching from step %d of %zu): solved up to %.2f N, rendered "
            "between steps up to %.2f N; worst step %.2f N off (rendered %.2f N where the step solved %.2f N)",
            mmPerStep, touched, path.size(), peakSolved, peakRendered, worst, worstRendered, worstSolved);
      // The shaft touched, and what the loop rendered between steps stayed near what the steps solved (within twice
      // the largest solved force and a newton: measured 4.80 of 2.75 N and 7.28 of 3.87 N; a person's chart read 48 N).
      QVERIFY(touched >= 0 && peakSolved > 0.1);
      QVERIFY(std::isfinite(peakRendered) && peakRendered <= 2 * peakSolved + 1.0);
    }
  }

  // The loop itself: a tick renders minus the extrapolated force to the device, capped at the model's maximum;
  // the thread ticks, keeps its samples and its periods, and stops.
  void forceLoopRendersTheExtrapolatedForce() {
    simcore::ToolForceModel m;
    m.step = 7;
    m.tip = Eigen::Vector3d(0.01, 0.02, 0.03);
    m.force = Eigen::Vector3d(1, 2, -1);
    m.stiffness << 300, 10, 0, 10, 200, 5, 0, 5, 100;
    m.maxForce = 4.0;
    simcore::VirtualDevice device;
    simcore::ForceLoop loop([&] { return m; }, &device);
    device.setPosition(m.tip + Eigen::Vector3d(0.001, -0.002, 0.004));
    const Eigen::Vector3d expected(
        1.28, 1.63, -0.61);  // N, f0 + K dp worked by hand: (1 + 0.3 - 0.02, 2 + 0.01 - 0.4 + 0.02, -1 - 0.01 + 0.4)
    QVERIFY(expected.norm() < m.maxForce);
    QVERIFY((loop.tick() - expected).norm() < 1e-12);
    QVERIFY((device.rendered() + expected).norm() < 1e-12);
    device.setPosition(m.tip + Eigen::Vector3d(0.02, 0, 0));  // 1 + 6 N along x: capped at 4 N
    const Eigen::Vector3d capped = loop.tick();
    QVERIFY(std::abs(capped.norm() - 4.0) < 1e-12);
    QVERIFY(capped.normalized().dot(Eigen::Vector3d(7, 2.2, -1).normalized()) >
            1 - 1e-12);  // (1 + 6, 2 + 0.2, -1) by hand
    // Contact (no cap) and a device far from the step's tip (the instrument jumped; on the patient liver, whose CT
    // coordinates are 0.3 m from the origin, the chart read 18 kN): the model is used no further than its reach.
    m.maxForce = 0;
    m.reach = 0.003;
    device.setPosition(m.tip + Eigen::Vector3d(0.3, 0, 0));
    QVERIFY((loop.tick() - Eigen::Vector3d(1.9, 2.03, -1.0)).norm() <
            1e-12);  // f0 + K (3 mm, 0, 0), not f0 + K (300 mm, 0, 0) = (91, 5, -1)
    m.reach = 0;
    QVERIFY((loop.tick() - Eigen::Vector3d(91, 5, -1)).norm() < 1e-9);  // unbounded, as it was
    loop.start();
    QVERIFY(loop.running());
    while (loop.timing().ticks < 50) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    loop.stop();
    QVERIFY(!loop.running());
    const auto t = loop.timing();
    QVERIFY(t.ticks >= 50 && t.medianPeriodMs > 0 && t.rateHz > 0);
    QVERIFY(loop.samples(10).size() >= 50);
    qInfo("force loop here: %.0f Hz, period median %.3f ms, p99 %.3f ms (measured in bench_rehearsal, not asserted)",
          t.rateHz, t.medianPeriodMs, t.p99PeriodMs);
  }

  // The lock-free cell the loop reads: a writer storing (i, i, ..., i) as fast as it can, a reader never
  // sees a mixture of two stores (a torn read would give unequal entries).
  void lockFreeCellNeverTears() {
    simcore::SeqCell<17> cell;
    std::atomic<bool> done{false};
    std::thread writer([&] {
      std::array<double, 17> v{};
      for (int i = 1; i <= 2000000; ++i) {
        v.fill(static_cast<double>(i));
        cell.store(v);
      }
      done = true;
    });
    long reads = 0, torn = 0;
    double last = 0;
    bool monotone = true;
    while (!done) {
      const auto v = cell.load();
      ++reads;
      for (double x : v) torn += x != v[0];
      monotone &= v[0] >= last;
      last = v[0];
    }
    writer.join();
    qInfo("%ld reads during 2,000,000 stores: %ld torn entries", reads, torn);
    QVERIFY(reads > 0);
    QCOMPARE(torn, 0L);
    QVERIFY(monotone);
    QCOMPARE(cell.load()[16], 2000000.0);
  }

  // Issue 32: surface that is inside the shaft when it becomes free to touch it — here the blade switched off halfway
  // through the lobe (cut-across stopped at 0.9 s), which also applies the last cut at once — was pushed to the shaft's
  // radius in one step: a one-step spike (7.5 N against a steady 3 N on the liver preset). It is now eased out at the
  // scene's depenetration speed (20 mm/s): no step after the blade stops exceeds the force the tissue then rests on the
  // shaft with by 40 % (it swings on it), and that resting force (the physics) is the same either way within 5 %.
  void contactFreedInsideTheShaftIsEased() {
    std::ifstream in(std::string(REHEARSE_SOURCE_DIR) + "/resources/gestures/cut-across.json");
    std::stringstream ss;
    ss << in.rdbuf();
    auto run = [&](double speedMmS) {
      app::GestureScript script = app::parseGestureScript(ss.str());
      script.toolRadius = 0.0025;
      script.depenetrationSpeed = 1e-3 * speedMmS;
      script.duration = 1.5;
      for (auto& e : script.events)
        if (e.cut && !*e.cut) e.t = 0.9;  // the blade off with the shaft inside the lobe
      simcore::BodySetup s = testing::presetBody("liver");
      s.settings.method = simcore::NewtonMethod::Linearised;
      s.tools.cutLatencySteps = -1;  // the last cut applied at the switch-off itself, the shaft inside the lobe then
      return app::runGesture(s, script);
    };
    const app::GestureResult atOnce = run(0), eased = run(20);
    const std::size_t off = 90;  // the step that applies the blade's switch-off (t = 0.9 s)
    auto force = [](const app::GestureResult& r, std::size_t k) { return r.steps[k].toolForce.norm(); };
    double peakAtOnce = 0, peakEased = 0;
    for (std::size_t k = off; k < off + 10; ++k) {
      peakAtOnce = std::max(peakAtOnce, force(atOnce, k));
      peakEased = std::max(peakEased, force(eased, k));
    }
    const double restingAtOnce = force(atOnce, off + 20), restingEased = force(eased, off + 20);
    qInfo(
        "blade off inside the lobe: at once, the first 10 steps peak at %.2f N (resting %.2f N 20 steps later); eased "
        "at 20 mm/s, %.2f N "
        "(resting %.2f N)",
        peakAtOnce, restingAtOnce, peakEased, restingEased);
    QVERIFY(restingAtOnce > 0.5 && restingEased > 0.5);  // the shaft is inside the organ: it holds part of it
    QVERIFY2(peakAtOnce > 1.8 * restingAtOnce, "the spike this test is about is no longer there to remove");
    QVERIFY(peakEased < 1.4 * restingEased);
    QVERIFY(std::abs(restingEased - restingAtOnce) < 0.05 * restingAtOnce);
    QCOMPARE(atOnce.failed + eased.failed, std::size_t(0));
  }

  // Pulled harder than the scene's maximum grasp force: the tissue slips out, said, and nothing is held.
  void slipAboveTheMaximumForce() {
    simcore::BodySetup s = liverSetup();
    s.tools.maxGraspForce = 0.5;
    simcore::Session session(s);
    const Eigen::Vector3d tip = settleAndGrasp(session);
    QVERIFY(!session.snapshot()->tool.held.empty());
    bool slipped = false;
    for (int k = 1; k <= 200 && !slipped; ++k) {
      session.post(toolAt(tip + Eigen::Vector3d(0, 0, -0.0005 * k)));
      session.advance();
      const auto snap = session.snapshot();
      if (std::find(snap->events.begin(), snap->events.end(), "slip") != snap->events.end()) {
        slipped = true;
        qInfo("%s", snap->message.c_str());
        QVERIFY(QString::fromStdString(snap->message).contains("slipped"));
        QVERIFY(snap->tool.held.empty());
        QVERIFY(snap->tool.jawClosed);  // the jaws stay closed, on nothing
      }
    }
    QVERIFY(slipped);
  }

  // Issue 61: a quick 20 mm pull let go at 34.9 N with a maximum of 15 N (the chart peaked at 39 N): the slip came
  // after a whole step's pull. The jaws now let go at the limit, to first order: on the liver preset, grasped and
  // pulled away from the organ at 0.5, 2 and 5 mm per step and in one 20 mm jump, the grasp force is never above
  // the limit by more than 10 % and the tissue slips at it within 15 % (measured: 15.3, 16.0, 15.3, 15.3 N of 15); the
  // same pulls as recorded before (slipAtLimit false) went past it: 21.5 N at 5 mm per step, 99.1 N for the jump
  // (the test's own contrast: the jump at least 1.5x the limit). Held-back steps whose force still came out more than
  // 2 % past the limit are now taken again (slipResolved): every pull slips within 95-102 % of it (measured 15.3, 14.6,
  // 14.6, 14.6 N), where the first order alone let the 2 mm steps go at 16.0 N (the contrast: more than 102 %).
  void letsGoAtTheMaximumForce() {
    struct Pull {
      double mmPerStep;
      int steps;
    };
    enum Kind { Resolved, FirstOrder, AsBefore };
    for (const Kind kind : {Resolved, FirstOrder, AsBefore})
      for (const Pull pull : {Pull{0.5, 200}, Pull{2, 60}, Pull{5, 30}, Pull{20, 3}}) {
        const bool atLimit = kind != AsBefore;
        simcore::BodySetup s = liverSetup();
        s.tools.slipAtLimit = atLimit;
        s.tools.slipResolved = kind == Resolved;
        const double max = s.tools.maxGraspForce;
        simcore::Session session(s);
        const Eigen::Vector3d tip = settleAndGrasp(session);
        QVERIFY(!session.snapshot()->tool.held.empty());
        double peak = 0, slipForce = -1;
        for (int k = 1; k <= pull.steps && slipForce < 0; ++k) {
          // Up and away from the organ (its attachments are on top: the pull stretches it).
          session.post(toolAt(tip + Eigen::Vector3d(0, 0, -0.001 * pull.mmPerStep * k)));
          session.advance();
          const auto snap = session.snapshot();
          peak = std::max(peak, snap->tool.graspForce.norm());
          if (std::find(snap->events.begin(), snap->events.end(), "slip") != snap->events.end()) {
            std::sscanf(snap->message.c_str(), "The tissue slipped out of the grasper at %lf N", &slipForce);
            peak = std::max(peak, slipForce);  // (the snapshot's force is the hold's after it let go: none)
            QVERIFY2(snap->tool.held.empty(), snap->message.c_str());
          }
        }
        qInfo("%s, %.1f mm per step: peak grasp force %.2f N, slipped at %.2f N (limit %.0f N)",
              kind == Resolved ? "at the limit" : kind == FirstOrder ? "to first order" : "as recorded before",
              pull.mmPerStep, peak, slipForce, max);
        QVERIFY2(slipForce > 0, "the pull never slipped");
        if (kind == Resolved) {
          QVERIFY(peak <= 1.02 * max);
          QVERIFY(slipForce >= 0.95 * max && slipForce <= 1.02 * max);
        } else if (kind == FirstOrder) {
          QVERIFY(peak <= 1.10 * max);
          QVERIFY(std::abs(slipForce - max) <= 0.15 * max);
          if (pull.mmPerStep == 2)
            QVERIFY2(slipForce > 1.02 * max, "the first order's overshoot the step taken again is for is no longer there");
        } else if (pull.mmPerStep == 20) {
          QVERIFY2(slipForce > 1.5 * max, "the overshoot this test is about is no longer there to remove");
        }
      }
  }

  // The same pulls as a hand makes them in the window: a move every 5 steps (the mouse's events come at about 20 Hz, the
  // steps at 100), the jaws still between moves, the GUI's 5 mm shaft, up, sideways and along the surface. The hold
  // back predicts the force to first order; the tissue slips when the force the step solved is within 5 % of the
  // limit, and the step before it was within the limit (the slip within one step's change of it). Before, the slip came
  // after the held-back step whatever it solved: 13.4 N of 15 sideways at 1 mm a move here, "at 7.2 N" in a person's
  // pull on the phantom; then 17.0 N there, on a move's step after 9.3 N on the step before (one step's change). Now a
  // held-back step whose force still comes out more than 2 % past the limit is taken again with the jaws moved back
  // (ToolSettings::slipResolved): here every slip between 14.3 and 15.2 N, within 95-102 % of the limit.
  void aHandsPullLetsGoAtTheMaximumForce() {
    for (const Eigen::Vector3d& dir :
         {Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0.3).normalized()})
      for (const double mmPerMove : {1.0, 3.0, 8.0})
        for (const auto method : {simcore::NewtonMethod::Exact, simcore::NewtonMethod::Chord}) {
        simcore::BodySetup s = liverSetup();
        QVERIFY(s.tools.slipResolved);
        s.settings.method = method;
        s.tools.toolRadius = 0.0025;
        const double max = s.tools.maxGraspForce;
        simcore::Session session(s);
        const Eigen::Vector3d tip = settleAndGrasp(session);
        QVERIFY(!session.snapshot()->tool.held.empty());
        double peak = 0, slipForce = -1, before = 0;  // (before: the grasp force on the step before the slip)
        int steps = 0;
        for (int move = 1; move <= 400 && slipForce < 0; ++move) {
          session.post(toolAt(tip + 0.001 * mmPerMove * move * dir));
          for (int k = 0; k < 5 && slipForce < 0; ++k, ++steps) {
            session.advance();
            const auto snap = session.snapshot();
            peak = std::max(peak, snap->tool.graspForce.norm());
            if (std::find(snap->events.begin(), snap->events.end(), "slip") != snap->events.end()) {
              QVERIFY2(std::sscanf(snap->message.c_str(), "The tissue slipped out of the grasper at %lf N", &slipForce) == 1,
                       snap->message.c_str());
              peak = std::max(peak, slipForce);
            } else {
              before = snap->tool.graspForce.norm();
            }
          }
        }
        qInfo("%s, %.0f mm per move along (%.1f, %.1f, %.1f) (a move every 5 steps): %.2f N, then slipped at %.2f N "
              "after %d steps (limit %.0f N)",
              method == simcore::NewtonMethod::Exact ? "exact Newton" : "chord", mmPerMove, dir.x(), dir.y(), dir.z(),
              before, slipForce, steps, max);
        QVERIFY2(slipForce > 0, "the pull never slipped");
        QVERIFY(slipForce >= 0.95 * max);
        QVERIFY(slipForce <= 1.02 * max);
        QVERIFY(before <= max);
      }
  }

  // The rehearsal's tissue (app::bodySetup: the window's and `rehearse gesture`'s) is viscous as liver is, not ten
  // times stiffer for a moment: the built-in phantom's case started in equilibrium on its supports, the jaws on a free
  // front node, the tool jumped 1 mm within one step (a mouse move between two steps). The reference is the same jump
  // in the same tissue without damping (its mass alone makes the jump read 1.6 times the force after 2 s held there).
  // A Kelvin-Voigt solid meets a jump with at most (1 + beta / h) times the undamped force (exactly, without mass);
  // liver's instantaneous stiffness is a small multiple of its relaxed one (about 3, sessionstart.cpp). With the
  // generic beta = 0.1 s the damping multiplied the jump's force by 7.7 (12.2 times the relaxed force), and on the
  // patient liver a mouse drag of 2 mm jumps read 2.2-2.8 times its force at rest: the grasp slipped at a few pixels.
  // Then a hand's pull, 10 mm at 20 mm/s: its force within 5 % of the relaxed one.
  void theRehearsalsTissueMeetsAJumpAsLiverDoes() {
    auto c = std::make_shared<app::Case>(app::caseFromPhantom(phantom::makePhantom()));
    app::SessionRequest r;
    r.organ = c;
    app::StartOptions so;
    so.supportModulus = c->material.supportModulus;
    const app::SessionStart start = app::prepareStart(app::bodySetup(r), so);
    QVERIFY(start.outcome == app::SessionStart::Outcome::Ready);
    simcore::BodySetup s = start.body;
    s.tools.maxGraspForce = 1e9;  // the tissue's own answer, not a slip
    const double h = s.settings.timeStep;
    // The free front node nearest the organ's middle across the view, at least 15 mm from every held node.
    const auto& x0 = s.rest.empty() ? s.mesh.points : s.rest;
    Eigen::Vector3d mid = Eigen::Vector3d::Zero();
    for (const auto& p : x0) mid += p;
    mid /= static_cast<double>(x0.size());
    int bite = -1;
    for (std::size_t i = 0; i < x0.size(); ++i) {
      bool free = (x0[i] - mid).head<2>().norm() < 0.03;
      for (int f : s.fixedNodes) free = free && (x0[static_cast<std::size_t>(f)] - x0[i]).norm() >= 0.015;
      if (free && (bite < 0 || x0[i].z() < x0[static_cast<std::size_t>(bite)].z())) bite = static_cast<int>(i);
    }
    QVERIFY(bite >= 0);
    std::map<int, double> ratio;  // 0: the jump undamped, 1: the jump, 2: the hand's pull
    for (const int run : {0, 1, 2}) {
      const bool jump = run < 2;
      simcore::BodySetup d = s;
      if (run == 0) d.settings.rayleighStiffness = 0;
      simcore::Session session(d);
      for (int k = 0; k < 5; ++k) session.advance();
      const Eigen::Vector3d tip = session.snapshot()->positions[static_cast<std::size_t>(bite)];
      session.post(toolAt(tip));
      session.post(jaws(true));
      for (int k = 0; k < 20; ++k) session.advance();
      QVERIFY(!session.snapshot()->tool.held.empty());
      const Eigen::Vector3d f0 = session.snapshot()->tool.graspForce, dir(0, -1, 0);
      Eigen::Vector3d moving = Eigen::Vector3d::Zero();
      if (jump) {
        session.post(toolAt(tip + 0.001 * dir));
        session.advance();
        moving = session.snapshot()->tool.graspForce;
      } else {
        for (int k = 1; k <= 50; ++k) {  // 0.2 mm a step
          session.post(toolAt(tip + 0.0002 * k * dir));
          session.advance();
        }
        moving = session.snapshot()->tool.graspForce;
      }
      for (int k = 0; k < 200; ++k) session.advance();
      QVERIFY(session.snapshot()->report.outcome == simcore::StepStatus::Converged);
      const Eigen::Vector3d relaxed = session.snapshot()->tool.graspForce;
      ratio[run] = (moving - f0).norm() / (relaxed - f0).norm();
      qInfo("%s: %.4f N while moving, %.4f N relaxed (from %.4f N): %.2f times (h %.3g s, beta %.3g s)",
            jump ? "1 mm within a step" : "10 mm at 20 mm/s", (moving - f0).norm(), (relaxed - f0).norm(), f0.norm(),
            ratio[run], h, d.settings.rayleighStiffness);
      QVERIFY((relaxed - f0).norm() > 1e-3);
    }
    const double byDamping = ratio[1] / ratio[0];
    qInfo("the damping multiplies the jump's force by %.2f", byDamping);
    QVERIFY2(ratio[0] >= 1.0, "a jump meets at least the relaxed force");
    QVERIFY2(byDamping > 1.3, "the tissue is viscous: its damping adds to a jump's force");
    QVERIFY2(byDamping <= 3.0, "the damping multiplies a jump's force by at most 3, as liver's stiffness rises");
    QVERIFY2(ratio[2] > 1.0 && ratio[2] < 1.05, "a hand's pull reads the tissue's force at rest, within 5 %");
  }

  // A slip on a step that did not converge: the force read there is not the tissue's at equilibrium, and the sentence
  // says so instead of naming it as the force the tissue slipped at (a user's pull on the patient liver let go "at
  // 39.1 N" of 15 on a step the inversion guard held back, relative residual 18). Steps made inexact on purpose (one
  // exact Newton iteration to a tolerance no step meets), the 20 mm jump of the test above as recorded before.
  void aSlipOnAnInexactStepSaysItsForceIsNotEquilibrium() {
    for (const bool inexact : {true, false}) {
      simcore::BodySetup s = liverSetup();
      s.tools.slipAtLimit = false;
      s.tools.slipResolved = false;
      simcore::Session session(s);
      const Eigen::Vector3d tip = settleAndGrasp(session);
      QVERIFY(!session.snapshot()->tool.held.empty());
      if (inexact) {  // settled and grasped on converged steps; the pull's steps are then made inexact
        simcore::Checkpoint c = session.checkpoint();
        c.setup.settings.method = simcore::NewtonMethod::Exact;
        c.setup.settings.maxNewtonIterations = 1;
        c.setup.settings.tolerance = 1e-14;
        session.restore(c);
        QVERIFY(!session.snapshot()->tool.held.empty());
      }
      std::string said;
      int outcome = -1;
      for (int k = 1; k <= 3 && said.empty(); ++k) {
        session.post(toolAt(tip + Eigen::Vector3d(0, 0, -0.02 * k)));
        session.advance();
        const auto snap = session.snapshot();
        if (std::find(snap->events.begin(), snap->events.end(), "slip") != snap->events.end()) {
          said = snap->message;
          outcome = static_cast<int>(snap->report.outcome);
        }
      }
      qInfo("%s: %s", inexact ? "inexact steps" : "converged steps", said.c_str());
      QVERIFY2(!said.empty(), "the pull never slipped");
      QCOMPARE(outcome == static_cast<int>(simcore::StepStatus::Converged), !inexact);
      QCOMPARE(QString::fromStdString(said).contains("on a step that did not converge"), inexact);
      QCOMPARE(QString::fromStdString(said).startsWith("The tissue slipped out of the grasper at "), !inexact);
    }
    // Held back and taken again at the limit (slipResolved) on steps held to one Newton iteration, the slip reads near
    // the limit (17.9 N of 15 here: a step that cannot converge reads no force exactly), and its sentence names that
    // force and says the step did not converge (below 1.25x the limit it named it as the tissue's before).
    simcore::BodySetup s = liverSetup();
    simcore::Session session(s);
    const Eigen::Vector3d tip = settleAndGrasp(session);
    simcore::Checkpoint c = session.checkpoint();
    c.setup.settings.method = simcore::NewtonMethod::Exact;
    c.setup.settings.maxNewtonIterations = 1;
    c.setup.settings.tolerance = 1e-14;
    session.restore(c);
    std::string said;
    for (int k = 1; k <= 20 && said.empty(); ++k) {
      session.post(toolAt(tip + Eigen::Vector3d(0, 0, -0.002 * k)));
      session.advance();
      const auto snap = session.snapshot();
      if (std::find(snap->events.begin(), snap->events.end(), "slip") != snap->events.end()) said = snap->message;
    }
    qInfo("inexact steps taken again at the limit: %s", said.c_str());
    double at = 0;
    QVERIFY2(std::sscanf(said.c_str(), "The tissue slipped out of the grasper at %lf N", &at) == 1, said.c_str());
    QVERIFY2(at >= 0.95 * s.tools.maxGraspForce && at <= 1.25 * s.tools.maxGraspForce, said.c_str());
    QVERIFY2(QString::fromStdString(said).contains("on a step that did not converge"), said.c_str());
  }

  // Contact (triangle-based, off by default: README): a 40 x 20 x 20 mm block (5 mm elements) on a fixed base;
  // a vertical instrument of 6 mm radius (wider than an element) and one of 1 mm (thinner: it meets the face
  // between nodes) comes down on the middle of its top face, its tip 2 mm below where the face was. Every
  // contact constraint holds at the end of every step to 1 micrometre (projected Gauss-Seidel on the nearly
  // parallel constraints of neighbouring triangles: 0.1 micrometre seen with the thin instrument); the surface, sampled
  // between the nodes on a 24 x 24 grid per triangle, stays out of the instrument within 0.1 mm (the constraints are
  // linearised at the step's start); the contact only pushes and its force is the base's support reaction (an
  // independent route through the elastic forces); withdrawn, the tissue lets go and springs back; without an
  // instrument no contact detection runs.
  void contactPushesNotPenetrates_data() {
    QTest::addColumn<double>("radius");
    QTest::newRow("6 mm") << 0.006;
    QTest::newRow("1 mm") << 0.001;
  }
  void contactPushesNotPenetrates() {
    QFETCH(double, radius);
    simcore::BodySetup s;
    s.mesh = boxMesh(0.04, 0.02, 0.02, 8, 4, 4);
    for (std::size_t i = 0; i < s.mesh.points.size(); ++i)
      if (s.mesh.points[i].z() < 1e-12) s.fixedNodes.push_back(static_cast<int>(i));
    s.material = {simcore::MaterialModel::Corotational, 20e3, 0.3, 1000};
    s.settings.gravity = Eigen::Vector3d::Zero();
    s.settings.timeStep = 0.05;
    s.settings.method = simcore::NewtonMethod::Exact;
    s.tools.trocar = Eigen::Vector3d(0.02, 0.01, 0.3);
    s.tools.toolRadius = radius;
    simcore::Session session(s);
    for (int k = 0; k < 5; ++k) session.advance();
    QCOMPARE(session.contactQueries(), 0L);  // no instrument, no detection
    const Eigen::Vector3d above(0.02, 0.01, 0.029);
    double worstInside = 0;
    // The surface's gap to the instrument: every boundary triangle sampled on a 24 x 24 barycentric grid
    // (between the nodes too), its points' distance to the shaft's axis less the radius.
    const auto boundary = simcore::boundaryTriangles(s.mesh, false);
    auto capsuleGap = [&](const simcore::Snapshot& snap) {
      double worst = 1;
      const Eigen::Vector3d a = snap.tool.tip, b = *session.setup().tools.trocar, d = b - a;
      for (const auto& tri : boundary)
        for (int i = 0; i <= 24; ++i)
          for (int j = 0; i + j <= 24; ++j) {
            const Eigen::Vector3d p = ((24 - i - j) * snap.positions[static_cast<std::size_t>(tri[0])] +
                                       i * snap.positions[static_cast<std::size_t>(tri[1])] +
                                       j * snap.positions[static_cast<std::size_t>(tri[2])]) /
                                      24.0;
            const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
            worst = std::min(worst, (p - (a + t * d)).norm() - radius);
          }
      return worst;
    };
    for (int k = 0; k <= 20; ++k) {
      session.post(toolAt(above - Eigen::Vector3d(0, 0, 0.011 * k / 20.0)));  // down to 18 mm: 2 mm below the face
      QVERIFY(session.advance().ok);
      QVERIFY2(session.snapshot()->report.constraintViolation < 1e-6,
               qPrintable(QString::number(session.snapshot()->report.constraintViolation)));
      worstInside = std::min(worstInside, capsuleGap(*session.snapshot()));
    }
    for (int k = 0; k < 40; ++k) {
      QVERIFY(session.advance().ok);
      QVERIFY(session.snapshot()->report.constraintViolation < 1e-6);
      worstInside = std::min(worstInside, capsuleGap(*session.snapshot()));
    }
    const auto pressed = session.snapshot();
    QVERIFY(session.contactQueries() > 0);
    QVERIFY(pressed->tool.contacts > 0);
    const Eigen::Vector3d force = pressed->tool.force;
    const double vmax = session.state().v.cwiseAbs().maxCoeff();
    const auto body = simcore::makeFemBody(s);
    const Eigen::Vector3d reaction =
        body->appliedForce(s.fixedNodes, session.state(), session.state().v, s.settings.timeStep);
    qInfo(
        "pressed: %d contact triangles, the surface at most %.2e m inside the instrument, contact force (%.4f, %.4f, "
        "%.4f) N, base reaction (%.4f, %.4f, %.4f) N, "
        "max speed %.1e m/s",
        pressed->tool.contacts, -worstInside, force.x(), force.y(), force.z(), reaction.x(), reaction.y(), reaction.z(),
        vmax);
    QVERIFY(force.norm() > 1e-3);
    QVERIFY(-worstInside < 1e-4);
    QVERIFY((force + reaction).norm() < 0.05 * force.norm());  // the base holds what the instrument pushes
    // Withdrawn: no contact, no force, the face springs back.
    session.post(toolAt(above + Eigen::Vector3d(0, 0, 0.02)));
    for (int k = 0; k < 60; ++k) QVERIFY(session.advance().ok);
    const auto after = session.snapshot();
    double back = 0;
    for (std::size_t i = 0; i < after->positions.size(); ++i)
      back = std::max(back, (after->positions[i] - s.mesh.points[i]).norm());
    qInfo("withdrawn: %d contacts, force %.2e N, furthest node %.2e m from rest", after->tool.contacts,
          after->tool.force.norm(), back);
    QCOMPARE(after->tool.contacts, 0);
    QCOMPARE(after->tool.force.norm(), 0.0);
    QVERIFY(back < 1e-4);
  }

  // Issue 34: the Newton-Krylov method (exact tangent matrix-free, CG preconditioned by the lagged factor, constraint
  // preconditioner for the contact and grasp rows) and chord solve the same equations as exact Newton: on each of the
  // five laws a shaft presses a block's top face, the jaws close on it while it presses, then pull it up. Every step
  // converges to 1e-8 with every method, and the states and the tool forces agree to what that tolerance allows.
  void newtonKrylovMatchesExactNewton_data() {
    QTest::addColumn<int>("law");
    for (auto law : {simcore::MaterialModel::Linear, simcore::MaterialModel::Corotational, simcore::MaterialModel::StVK,
                     simcore::MaterialModel::NeoHookean, simcore::MaterialModel::NeoHookeanSplit})
      QTest::newRow(simcore::toString(law).c_str()) << static_cast<int>(law);
  }
  void newtonKrylovMatchesExactNewton() {
    QFETCH(int, law);
    struct Run {
      std::vector<std::vector<Eigen::Vector3d>> positions;
      std::vector<Eigen::Vector3d> forces;
      int maxContacts = 0, heldSteps = 0, notConverged = 0;
      long newton = 0;
    };
    auto run = [&](simcore::NewtonMethod method) {
      simcore::BodySetup s;
      s.mesh = boxMesh(0.04, 0.02, 0.02, 8, 4, 4);
      for (std::size_t i = 0; i < s.mesh.points.size(); ++i)
        if (s.mesh.points[i].z() < 1e-12) s.fixedNodes.push_back(static_cast<int>(i));
      s.material = {static_cast<simcore::MaterialModel>(law), 20e3, 0.3, 1000};
      s.settings.gravity = Eigen::Vector3d(0, 0, -9.81);
      s.settings.timeStep = 0.02;
      s.settings.tolerance = 1e-8;
      s.settings.method = method;
      s.settings.factorRefresh = simcore::FactorRefresh::Synchronous;
      s.tools.trocar = Eigen::Vector3d(0.02, 0.01, 0.3);
      s.tools.toolRadius = 0.002;
      s.tools.graspRadius = 0.0055;
      s.tools.maxGraspForce = 1e6;
      simcore::Session session(s);
      Run r;
      auto step = [&] {
        const simcore::StepReport rep = session.advance();
        r.notConverged += rep.outcome != simcore::StepStatus::Converged;
        r.newton += rep.newtonIterations;
        r.positions.push_back(session.snapshot()->positions);
        r.forces.push_back(session.snapshot()->tool.force);
        r.maxContacts = std::max(r.maxContacts, session.snapshot()->tool.contacts);
        r.heldSteps += !session.snapshot()->tool.held.empty();
      };
      const Eigen::Vector3d above(0.02, 0.01, 0.024);
      for (int k = 0; k <= 10; ++k) {  // the shaft's tip down to 1 mm below the face: contact
        session.post(toolAt(above - Eigen::Vector3d(0, 0, 0.005 * k / 10.0)));
        step();
      }
      session.post(jaws(true));  // bites while it presses
      for (int k = 0; k < 5; ++k) step();
      for (int k = 1; k <= 15; ++k) {  // and pulls the face 4 mm up and 2 mm sideways
        session.post(toolAt(above + Eigen::Vector3d(0.002 * k / 15.0, 0, -0.005 + 0.009 * k / 15.0)));
        step();
      }
      return r;
    };
    const Run exact = run(simcore::NewtonMethod::Exact);
    QCOMPARE(exact.notConverged, 0);
    QVERIFY(exact.maxContacts > 0);
    QVERIFY(exact.heldSteps >= 15);
    // Newton-Krylov, and chord (the interactive default) which iterates with the lagged factor to the same tolerance.
    for (const auto method : {simcore::NewtonMethod::NewtonKrylov, simcore::NewtonMethod::Chord}) {
      const Run other = run(method);
      QCOMPARE(other.notConverged, 0);
      QVERIFY(other.maxContacts > 0);
      QCOMPARE(other.heldSteps, exact.heldSteps);
      double worstPlace = 0, largestMove = 0, worstForce = 0, largestForce = 0;
      for (std::size_t k = 0; k < exact.positions.size(); ++k) {
        for (std::size_t i = 0; i < exact.positions[k].size(); ++i) {
          worstPlace = std::max(worstPlace, (other.positions[k][i] - exact.positions[k][i]).norm());
          largestMove = std::max(largestMove, (exact.positions[k][i] - exact.positions.front()[i]).norm());
        }
        worstForce = std::max(worstForce, (other.forces[k] - exact.forces[k]).norm());
        largestForce = std::max(largestForce, exact.forces[k].norm());
      }
      qInfo(
          "%s: largest move %.2f mm, force up to %.3f N; %s vs exact: %.2e of the move, %.2e of the force; Newton "
          "iterations %ld vs %ld",
          simcore::toString(static_cast<simcore::MaterialModel>(law)).c_str(), 1e3 * largestMove, largestForce,
          simcore::toString(method).c_str(), worstPlace / largestMove, worstForce / largestForce, other.newton,
          exact.newton);
      QVERIFY(largestMove > 1e-3 && largestForce > 1e-3);
      QVERIFY2(worstPlace < 1e-5 * largestMove, qPrintable(QString::number(worstPlace / largestMove)));
      QVERIFY2(worstForce < 1e-4 * largestForce, qPrintable(QString::number(worstForce / largestForce)));
    }
  }

  void gestureScriptsSayWhatTheyCannotDo() {
    auto refused = [](const std::string& text, const char* words) {
      try {
        app::parseGestureScript(text);
      } catch (const std::runtime_error& e) {
        return QString::fromUtf8(e.what()).contains(QString::fromUtf8(words));
      }
      return false;
    };
    QVERIFY(refused(R"({"format": "rehearse-gesture", "events": [{"t": 0, "cut": "on"}]})", "cuts with the grasper"));
    QVERIFY(refused(R"({"format": "rehearse-gesture", "events": [{"t": 0, "tool": "scissors", "cut": true}]})",
                    "must be \"on\" or \"off\""));
    QVERIFY(
        refused(R"({"format": "rehearse-gesture", "events": [{"t": 0, "tool": "hook"}, {"t": 1, "jaws": "close"}]})",
                "while holding the hook"));
    QVERIFY(refused(R"({"format": "rehearse-gesture", "events": [{"t": 0, "tool": "laser"}]})", "unknown tool"));
    QVERIFY(
        refused(R"({"format": "rehearse-gesture", "events": [{"t": 1, "jaws": "close"}, {"t": 0.5, "jaws": "open"}]})",
                "time order"));
    QVERIFY(refused(R"({"format": "rehearse-gesture", "events": [{"t": 0, "tip": [0, "a", 0]}]})", "not a number"));
    QVERIFY(refused(R"({"events": []})", "rehearse-gesture"));
    QVERIFY(refused("{", "not valid JSON"));
    // The shipped script parses and grasps the liver preset.
    std::ifstream in(std::string(REHEARSE_SOURCE_DIR) + "/resources/gestures/grasp-pull.json");
    std::stringstream ss;
    ss << in.rdbuf();
    const app::GestureScript script = app::parseGestureScript(ss.str());
    simcore::BodySetup s = liverSetup();
    s.settings.method = simcore::NewtonMethod::Linearised;
    const app::GestureResult r = app::runGesture(s, script);
    std::size_t most = 0;
    for (const auto& row : r.steps) most = std::max(most, row.grasped);
    qInfo("grasp-pull.json on the liver preset: %zu steps, up to %zu nodes grasped, %d slips, %zu failed",
          r.steps.size(), most, r.events.slips, r.failed);
    QCOMPARE(r.steps.size(), std::size_t(350));
    QVERIFY(most > 0);
    QCOMPARE(r.failed, std::size_t(0));
  }
};

QTEST_GUILESS_MAIN(TestGrasp)
#include "test_grasp.moc"
