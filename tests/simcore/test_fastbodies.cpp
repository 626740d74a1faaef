// The fast models as the session's bodies (issue 37): the hybrid model (a FEM region where the instruments work, the
// rest's precomputed responses) and the parameterized mesh with free-form deformation, chosen by the scene, driven by
// the shipped gesture scripts on the liver preset.
//
// Checked against what does not come from the code under test: the linear law's stiffness assembled here (the hybrid
// model's answer is the whole organ's linear static equilibrium, before and after its cuts), the precomputed model's
// answer to the same script (a different algorithm for the same equations), Hertz's formula worked here, the jaws'
// recorded positions, and the recording's replay from its start and from checkpoints through the codec's bytes.
#include "session_inputs.hpp"
#include "static_checks.hpp"
#include "test_support.hpp"

#include <rehearse/app/gesture.hpp>
#include <rehearse/app/recording.hpp>
#include <rehearse/simcore/paramesh.hpp>
#include <rehearse/simcore/session/body.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QtTest>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

app::GestureScript script(const std::string& name, double duration = 0) {
  std::ifstream in(std::string(REHEARSE_SOURCE_DIR) + "/resources/gestures/" + name);
  std::stringstream ss;
  ss << in.rdbuf();
  app::GestureScript s = app::parseGestureScript(ss.str());
  if (duration > 0) s.duration = duration;
  return s;
}

// Nodes of pieces of the mesh that no fixed node holds (a cut took them off), 1 each.
std::vector<char> unheldPieces(const BodySetup& s) {
  const std::size_t n = s.mesh.points.size();
  std::vector<int> root(n);
  for (std::size_t v = 0; v < n; ++v) root[v] = static_cast<int>(v);
  auto find = [&](int v) {
    while (root[static_cast<std::size_t>(v)] != v) v = root[static_cast<std::size_t>(v)];
    return v;
  };
  for (const auto& t : s.mesh.tets)
    for (int k = 1; k < 4; ++k) root[static_cast<std::size_t>(find(t[static_cast<std::size_t>(k)]))] = find(t[0]);
  std::vector<char> anchored(n, 0), out(n, 0);
  for (int v : s.fixedNodes) anchored[static_cast<std::size_t>(find(v))] = 1;
  for (std::size_t v = 0; v < n; ++v) out[v] = !anchored[static_cast<std::size_t>(find(static_cast<int>(v)))];
  return out;
}

}  // namespace

class TestFastBodies : public QObject {
  Q_OBJECT

 private slots:
  // The shipped grasp-pull on the liver preset, ended while the jaws hold, with the hybrid model: every step converged;
  // the organ is in the linear law's static equilibrium at every free node the jaws do not hold (assembled here), what
  // remains at the held ones sums to the session's tool force, and the answer is the precomputed model's (another
  // algorithm for the same equations) to 1e-8 of the largest displacement.
  void theHybridModelGraspsAsTheLinearStaticAnswer() {
    BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Hybrid;
    const app::GestureScript pull = script("grasp-pull.json", 2.2);
    const app::GestureResult r = app::runGesture(s, pull);
    QCOMPARE(r.failed, std::size_t(0));
    std::vector<double> ms;
    std::size_t converged = 0;
    for (const auto& row : r.steps) converged += row.report.outcome == StepStatus::Converged, ms.push_back(row.wallMs);
    QCOMPARE(converged, r.steps.size());
    std::sort(ms.begin(), ms.end());
    const auto& last = r.steps.back();
    QVERIFY(last.grasped > 0);
    const testing::Balance b = testing::linearBalance(s, r.final.x);
    BodySetup p = s;
    p.model = BodyModel::Precomputed;
    const app::GestureResult q = app::runGesture(p, pull);
    Eigen::VectorXd rest(r.final.x.size());
    {
      Mesh mesh = s.mesh;
      mesh.convertToMetres();
      for (std::size_t i = 0; i < mesh.points.size(); ++i)
        rest.segment<3>(3 * static_cast<Eigen::Index>(i)) = mesh.points[i];
    }
    const double largest = (r.final.x - rest).cwiseAbs().maxCoeff();
    const double apart = (r.final.x - q.final.x).cwiseAbs().maxCoeff();
    qInfo(
        "hybrid grasp-pull (liver preset): %zu steps all converged, median %.3f ms, worst %.3f ms; %zu held, %zu free "
        "nodes off equilibrium, their force (%.4f, %.4f, %.4f) N, the session's (%.4f, %.4f, %.4f) N; the precomputed "
        "model's answer %.2e m away (largest displacement %.1f mm)",
        r.steps.size(), ms[ms.size() / 2], ms.back(), last.grasped, b.loaded, b.force.x(), b.force.y(), b.force.z(),
        last.toolForce.x(), last.toolForce.y(), last.toolForce.z(), apart, 1e3 * largest);
    QVERIFY(b.loaded <= last.grasped);
    QVERIFY(last.toolForce.norm() > 0.1);
    QVERIFY((b.force - last.toolForce).norm() <= 1e-6 * last.toolForce.norm());
    QVERIFY(apart <= 1e-8 * largest);
  }

  // The shipped cut-across script with the hybrid model (the blade's cuts on the second thread with the scene's
  // latency): the organ is cut (elements added, mass kept), every step converged, and at the end the cut organ is in
  // the linear law's static equilibrium (assembled here on the cut mesh) at every free node except those of pieces the
  // cut took off (the static model holds them where they are, said). The recording replays bit for bit from its start
  // and from checkpoints taken through the codec's bytes (the region as it had grown is part of their setup).
  void theHybridModelCutsAndReplays() {
    BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Hybrid;
    BodySetup started;
    std::vector<InputEvent> recorded;
    std::vector<std::pair<long, std::string>> taken;
    std::map<std::uint64_t, BodySetup> setups;
    Checkpoint end;
    app::GestureHooks hooks;
    hooks.start = [&](const BodySetup& b) { started = b; };
    hooks.step = [&](const StepRecord& r) {
      recorded = *r.recorded;
      end = r.checkpoint();
      if (r.step % 40 != 0) return;
      const Checkpoint c = r.checkpoint();
      taken.emplace_back(r.step, app::encodeCheckpointState(c));
      setups[app::setupHash(c.setup)] = c.setup;
      if (c.pendingChange) setups[app::setupHash(c.pendingChange->setup)] = c.pendingChange->setup;
    };
    const app::GestureResult r = app::runGesture(s, script("cut-across.json"), hooks);
    std::size_t converged = 0;
    std::vector<double> ms;
    for (const auto& row : r.steps) converged += row.report.outcome == StepStatus::Converged, ms.push_back(row.wallMs);
    std::sort(ms.begin(), ms.end());
    const std::vector<char> off = unheldPieces(end.setup);
    const testing::Balance b = testing::linearBalance(end.setup, end.state.x, off);
    const auto offNodes = std::count(off.begin(), off.end(), 1);
    qInfo(
        "hybrid cut-across (liver preset): %d cuts, %zu -> %zu elements, %zu of %zu steps converged (median %.3f ms, "
        "worst %.1f ms); %zu free nodes off equilibrium (the pieces cut off: %ld nodes, held)",
        r.events.cuts, s.mesh.tets.size(), r.finalMesh.tets.size(), converged, r.steps.size(), ms[ms.size() / 2], ms.back(),
        b.loaded, static_cast<long>(offNodes));
    QCOMPARE(r.failed, std::size_t(0));
    QVERIFY(r.events.cuts > 0);
    QVERIFY(r.finalMesh.tets.size() > s.mesh.tets.size());
    QCOMPARE(converged, r.steps.size());
    QVERIFY(r.final.x.allFinite());
    QCOMPARE(b.loaded, std::size_t(0));
    // Replays: from the start, and from each checkpoint (its bytes decoded).
    const long steps = static_cast<long>(r.steps.size());
    Session again(replaySetup(started));
    for (const auto& e : recorded) again.post(e);
    while (again.snapshot()->step < steps) again.advance();
    QVERIFY(again.state().x == end.state.x);
    for (const auto& [step, bytes] : taken) {
      const Checkpoint c = app::decodeCheckpointState(bytes, [&](std::uint64_t h) { return setups.at(h); });
      Session resumed(replaySetup(started));
      resumed.restore(c);
      for (const auto& e : recorded)
        if (e.step >= step) resumed.post(e);
      while (resumed.snapshot()->step < steps) resumed.advance();
      QVERIFY2(resumed.state().x == end.state.x, qPrintable(QString("from step %1").arg(step)));
    }
    qInfo("replayed from the start and from %zu checkpoints: bit for bit", taken.size());
    const BodySetup decoded = app::decodeSetup(app::encodeSetup(end.setup));
    QVERIFY(decoded.model == BodyModel::Hybrid);
    QVERIFY(decoded.regionCentres == end.setup.regionCentres);
    QVERIFY(!end.setup.regionCentres.empty());
  }

  // The hybrid region grows where an instrument acts outside it: a hold of the free surface node farthest from the
  // first region (around the surface nearest the trocar) is honoured at once, and the answer is the precomputed
  // model's for the same rows (1e-9 of the displacement); the note counts the region's centres; the growth's step time
  // is measured.
  void theHybridRegionGrows() {
    BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Hybrid;
    const auto hybrid = makeBody(s);
    BodySetup p = s;
    p.model = BodyModel::Precomputed;
    const auto precomputed = makeBody(p);
    SimulationState a = hybrid->initialState(), b = precomputed->initialState();
    const std::string before = hybrid->buildNote();
    const Eigen::Vector3d trocar = defaultTrocar(hybrid->restPositions());
    int far = -1;
    for (const auto& t : boundaryTriangles(s.mesh, false))
      for (int v : t)
        if (!hybrid->fixedMask()[static_cast<std::size_t>(v)] &&
            (far < 0 || (hybrid->restPositions()[static_cast<std::size_t>(v)] - trocar).norm() >
                            (hybrid->restPositions()[static_cast<std::size_t>(far)] - trocar).norm()))
          far = v;
    const std::vector<ScalarConstraint> rows =
        testing::holdAt(far, a.x.segment<3>(3 * far) + Eigen::Vector3d(0, -0.005, 0));
    const auto t0 = std::chrono::steady_clock::now();
    hybrid->setToolConstraints(rows);
    const StepReport ra = hybrid->step(a);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    precomputed->setToolConstraints(rows);
    const StepReport rb = precomputed->step(b);
    const double moved = (b.x - precomputed->initialState().x).cwiseAbs().maxCoeff();
    const double apart = (a.x - b.x).cwiseAbs().maxCoeff();
    qInfo("before: %s | after: %s | the growing step %.1f ms; the precomputed answer %.1e m away (moved %.2f mm)",
          before.c_str(), hybrid->buildNote().c_str(), ms, apart, 1e3 * moved);
    QVERIFY(ra.ok && rb.ok);
    QVERIFY(ra.outcome == StepStatus::Converged);
    QVERIFY(apart <= 1e-9 * moved);
    QVERIFY(before.find("around 1 point,") != std::string::npos);
    QVERIFY(hybrid->buildNote().find("around 2 points") != std::string::npos);
  }

  // The FFD model through the session: the grasp-pull moves the held patch with the jaws (its centre's nearest grid
  // point exactly, up to the largest displacement), the tool force is Hertz's law on that displacement (worked here),
  // every step says it is inexact (geometric, no equilibrium) with a sentence; a cut, a clip and a tear are refused
  // with sentences, the mesh unchanged.
  void theFfdModelThroughTheSession() {
    BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Ffd;
    const app::GestureResult r = app::runGesture(s, script("grasp-pull.json", 2.2));
    QCOMPARE(r.failed, std::size_t(0));
    std::size_t inexact = 0, inverted = 0, said = 0;
    for (const auto& row : r.steps) {
      inexact += row.report.outcome == StepStatus::Inexact;
      inverted += row.report.outcome == StepStatus::Inverted;
      said += row.report.status.find("geometric (no equilibrium)") != std::string::npos;
    }
    qInfo("FFD grasp-pull: %zu steps inexact, %zu inverted", inexact, inverted);
    QCOMPARE(inexact + inverted, r.steps.size());
    QCOMPARE(said, r.steps.size());
    const auto& last = r.steps.back();
    QVERIFY(last.grasped > 0);
    QVERIFY(r.final.x.allFinite());
    // The surface moved by the hold's displacement d (at most the FFD's largest, 20 mm) times the weight of the held
    // centre's grid point at the nearest node (below 1 by their distance): the largest node displacement is at most d,
    // so the tool force lies between Hertz's law at it and at 20 mm, along the pull.
    const double E = s.material.young / (1 - s.material.poisson * s.material.poisson);
    auto hertz = [&](double d) { return 4.0 / 3.0 * std::sqrt(0.005) * E * std::pow(d, 1.5); };
    Mesh mesh = s.mesh;
    mesh.convertToMetres();
    double moved = 0;
    Eigen::Vector3d along = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < mesh.points.size(); ++i) {
      const Eigen::Vector3d u = r.final.x.segment<3>(3 * static_cast<Eigen::Index>(i)) - mesh.points[i];
      if (u.norm() > moved) moved = u.norm(), along = u.normalized();
    }
    qInfo(
        "FFD grasp-pull: %zu steps, all with the sentence (%s); the surface moved %.2f mm; tool force %.4f N (Hertz "
        "%.4f N there, %.4f N at 20 mm), off the pull by %.1e",
        r.steps.size(), last.report.status.c_str(), 1e3 * moved, last.toolForce.norm(), hertz(moved), hertz(0.02),
        1 - last.toolForce.normalized().dot(along));
    QVERIFY(moved > 0.002 && moved <= 0.02);
    QVERIFY(last.toolForce.norm() >= hertz(moved) * (1 - 1e-12) && last.toolForce.norm() <= hertz(0.02) * (1 + 1e-12));
    QVERIFY(last.toolForce.normalized().dot(along) > 1 - 1e-9);
    // The same script again: the same bits (the geometry image's choice of map is deterministic).
    {
      const app::GestureResult again = app::runGesture(s, script("grasp-pull.json", 2.2));
      QVERIFY(again.final.x == r.final.x);
    }
    const app::GestureResult c = app::runGesture(s, script("cut-across.json"));
    std::string refused;
    for (const auto& row : c.steps)
      if (row.message.find("cannot cut") != std::string::npos) refused = row.message;
    qInfo("cut: %s", refused.c_str());
    QVERIFY(refused.find("The FFD model cannot cut") != std::string::npos);
    QCOMPARE(c.events.cuts, 0);
    QCOMPARE(c.finalMesh.tets.size(), s.mesh.tets.size());
    QVERIFY(app::decodeSetup(app::encodeSetup(s)).model == BodyModel::Ffd);
  }

  // The FFD body alone: one surface node held 8 mm off along the outward normal-ish direction (+z and -y mixed): the
  // tool force is Hertz's law at 8 mm exactly (worked here), along the hold; the node's displacement is 8 mm times
  // the Gaussian weight of its distance to its grid point (in (0.9, 1]); past 20 mm the force stops growing.
  void theFfdBodysHertzForce() {
    BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Ffd;
    const auto body = makeBody(s);
    SimulationState st = body->initialState();
    const int node = testing::firstFreeSurfaceNode(s, *body);
    const Eigen::Vector3d x0 = st.x.segment<3>(3 * node);
    const double E = s.material.young / (1 - s.material.poisson * s.material.poisson);
    auto hertz = [&](double d) { return 4.0 / 3.0 * std::sqrt(0.005) * E * std::pow(d, 1.5); };
    auto hold = [&](const Eigen::Vector3d& d) {
      body->setToolConstraints(testing::holdAt(node, x0 + d));
      return body->step(st);
    };
    const Eigen::Vector3d d = 0.008 * Eigen::Vector3d(0.3, -0.6, -0.74).normalized();
    const StepReport rep = hold(d);
    const Eigen::Vector3d moved = st.x.segment<3>(3 * node) - x0;
    const Eigen::Matrix3d K = body->toolStiffness();
    qInfo("held 8 mm: %s; force %.6f N (Hertz %.6f N), the node moved %.3f mm, stiffness along the hold %.1f N/m",
          statusSentence(rep).c_str(), body->toolForce().norm(), hertz(0.008), 1e3 * moved.norm(),
          d.normalized().dot(K * d.normalized()));
    QVERIFY(rep.ok);
    QVERIFY(std::abs(body->toolForce().norm() - hertz(0.008)) <= 1e-9 * hertz(0.008));
    QVERIFY(body->toolForce().normalized().dot(d.normalized()) > 1 - 1e-9);
    QVERIFY(moved.norm() > 0.9 * 0.008 && moved.norm() <= 0.008 * (1 + 1e-12));
    QVERIFY(moved.normalized().dot(d.normalized()) > 1 - 1e-9);
    // The stiffness is Hertz's derivative (finite difference of the force over 0.1 mm more, 1e-3).
    const double k = d.normalized().dot(K * d.normalized());
    const double fd = (hertz(0.0081) - hertz(0.0079)) / 0.0002;
    QVERIFY(std::abs(k - fd) <= 1e-3 * fd);
    hold(0.025 * d.normalized());
    QVERIFY(std::abs(body->toolForce().norm() - hertz(0.02)) <= 1e-9 * hertz(0.02));
    QVERIFY(body->toolStiffness().isZero(0));
  }

  // The FFD body's build tells its progress (rising to 1) and stops when told to, with a sentence (the GUI's dialog
  // and its Cancel).
  void theFfdBuildTellsProgressAndCancels() {
    BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Ffd;
    std::vector<double> told;
    s.buildProgress = [&](double d) {
      told.push_back(d);
      return true;
    };
    makeBody(s);
    qInfo("told %zu times, last %.2f", told.size(), told.empty() ? -1.0 : told.back());
    QVERIFY(told.size() >= 3);
    QVERIFY(std::is_sorted(told.begin(), told.end()));
    QCOMPARE(told.back(), 1.0);
    int calls = 0;
    s.buildProgress = [&](double) { return ++calls < 3; };
    try {
      makeBody(s);
      QFAIL("a cancelled FFD build made a body");
    } catch (const MeshError& e) {
      qInfo("%s", e.what());
      QVERIFY(std::string(e.what()).find("cancelled") != std::string::npos);
    }
    QCOMPARE(calls, 3);
  }

  // Extreme and bad cases: a pull of 0.3 m (the FFD stops at its largest displacement and says so; the hybrid model's
  // linear answer turns elements inside out, counted), an organ held by nothing (both refused in a sentence), an
  // unknown model's name (refused naming the four).
  void extremeAndBadCases() {
    BodySetup s = testing::presetBody("liver");
    for (BodyModel m : {BodyModel::Hybrid, BodyModel::Ffd}) {
      s.model = m;
      const auto body = makeBody(s);
      SimulationState st = body->initialState();
      const int node = testing::firstFreeSurfaceNode(s, *body);
      body->setToolConstraints(testing::holdAt(node, st.x.segment<3>(3 * node) + Eigen::Vector3d(0, 0, -0.3)));
      const StepReport rep = body->step(st);
      qInfo("%s pulled 0.3 m: %s; tool force %.1f N", bodyModelName(m).c_str(), statusSentence(rep).c_str(),
            body->toolForce().norm());
      QVERIFY(rep.ok);
      QVERIFY(st.x.allFinite() && st.v.allFinite());
      if (m == BodyModel::Ffd)
        QVERIFY(rep.status.find("went past the largest displacement") != std::string::npos);
      else
        QVERIFY(rep.outcome == StepStatus::Inverted && rep.invertedElements > 0);
    }
    BodySetup loose = s;
    loose.fixedNodes.clear();
    loose.model = BodyModel::Hybrid;
    try {
      makeBody(loose);
      QFAIL("a hybrid body held by nothing was built");
    } catch (const MeshError& e) {
      qInfo("%s", e.what());
      QVERIFY(std::string(e.what()).find("Nothing holds the organ") != std::string::npos);
    }
    try {
      bodyModelFromString("sph");
      QFAIL("an unknown model was accepted");
    } catch (const MeshError& e) {
      QVERIFY(std::string(e.what()).find("fem, precomputed, hybrid or ffd") != std::string::npos);
    }
  }
};

QTEST_GUILESS_MAIN(TestFastBodies)
#include "test_fastbodies.moc"
