// Issue 64: a step's error in physical units. Each step estimates, as it runs, how far its end lies from the converged
// answer of its own equations (StepReport::errorPosition, m; errorForce, N: the tool force's): the correction one more
// solve with the step's own factor gives for its last residual, the holds kept. Checked here against that answer
// itself: exact Newton to a relative residual of 1e-10 from the same start state, for every step of a grasp that pulls
// the liver preset's lobe 24 mm in 0.4 s and lets it go (the release is a step where something happens), with the
// linearised, chord and exact methods: the estimate is never below the true error by more than 2x, and not above it by
// more than 10x (20x for a step ended on the accuracy asked; plus 1 nm and 1 mN, below which nothing is resolved).
// With the accuracy asked and a lagged factor, the step's end is confirmed on the tangent at it (the Newton correction
// there): checked offline on a whole session, and on a bar torn and swung about, where the factor is not the tangent.
#include "box_mesh.hpp"
#include "session_inputs.hpp"
#include "static_checks.hpp"

#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/session/body.hpp>
#include <rehearse/simcore/session/step_truth.hpp>

#include <QtTest>

#include <algorithm>
#include <cmath>
#include <numeric>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

// Below this (1 nm) a step's error is round-off and the reference's own: ratios there are noise.
constexpr double kResolved = 1e-9;

double largestNodeDistance(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  double d = 0;
  for (Eigen::Index i = 0; i + 2 < a.size(); i += 3) d = std::max(d, (a.segment<3>(i) - b.segment<3>(i)).norm());
  return d;
}

// The free node lowest along gravity (the lobe's tip): where a grasp pulls.
int lowestFreeNode(const FemModel& m, const std::vector<int>& fixed, const Eigen::Vector3d& gravity) {
  int node = -1;
  for (std::size_t i = 0; i < m.nodeCount(); ++i) {
    if (std::find(fixed.begin(), fixed.end(), static_cast<int>(i)) != fixed.end()) continue;
    if (node < 0 || m.rest[i].dot(gravity) > m.rest[static_cast<std::size_t>(node)].dot(gravity))
      node = static_cast<int>(i);
  }
  return node;
}

}  // namespace

class TestStepError : public QObject {
  Q_OBJECT

 private slots:
  void estimateBoundsTheTrueErrorInMillimetresAndNewtons_data() {
    QTest::addColumn<int>("method");
    QTest::addColumn<bool>("async");
    QTest::newRow("linearised") << static_cast<int>(NewtonMethod::Linearised) << false;
    QTest::newRow("chord") << static_cast<int>(NewtonMethod::Chord) << false;
    QTest::newRow("exact") << static_cast<int>(NewtonMethod::Exact) << false;
    QTest::newRow("chord at a tolerance of 1e-3") << static_cast<int>(NewtonMethod::Chord) << false;
    // The GUI's: the factor rebuilt on the second thread, the steps meanwhile on the one they have.
    QTest::newRow("chord, asynchronous refresh") << static_cast<int>(NewtonMethod::Chord) << true;
    // The accuracy asked in millimetres and newtons (the window's 0.05 mm and 0.5 %): every step within it of exact
    // Newton's answer, as well as estimated within 2x.
    QTest::newRow("chord, 0.05 mm asked") << static_cast<int>(NewtonMethod::Chord) << false;
    QTest::newRow("chord, asynchronous refresh, 0.05 mm asked") << static_cast<int>(NewtonMethod::Chord) << true;
    QTest::newRow("chord, 0.005 mm asked") << static_cast<int>(NewtonMethod::Chord) << false;
    QTest::newRow("exact, 0.05 mm asked") << static_cast<int>(NewtonMethod::Exact) << false;
    QTest::newRow("newton-krylov, 0.05 mm asked") << static_cast<int>(NewtonMethod::NewtonKrylov) << false;
    // (The linearised method with the asynchronous refresh is not checked here: after the release its steps run on a
    // factor known to be stale and its estimate fell to 0.54-0.63 of the truth in three runs, too near the bound.)
  }
  void estimateBoundsTheTrueErrorInMillimetresAndNewtons() {
    QFETCH(int, method);
    QFETCH(bool, async);
    const BodySetup b = testing::presetBody("liver");
    const FemModel m = FemModel::build(b.mesh, b.byLabel, b.material);
    // The session's body (its tool force and the force's error estimate), and exact Newton's beside it.
    BodySetup bs = b, be = b;
    bs.settings.method = static_cast<NewtonMethod>(method);
    bs.settings.factorRefresh = async ? FactorRefresh::Asynchronous : FactorRefresh::Synchronous;
    const QString tag = QTest::currentDataTag();
    if (tag.contains("1e-3")) bs.settings.tolerance = 1e-3;
    if (tag.contains("0.05 mm asked")) bs.settings.accuracyPosition = 5e-5;
    if (tag.contains("0.005 mm asked")) bs.settings.accuracyPosition = 5e-6;
    const double asked = bs.settings.accuracyPosition;
    int endedOnAccuracy = 0;
    be.settings.method = NewtonMethod::Exact;
    be.settings.tolerance = 1e-10;
    be.settings.maxNewtonIterations = 60;
    be.settings.estimateError = false;
    const SimulationSettings& s = bs.settings;
    const auto stepper = makeFemBody(bs), exact = makeFemBody(be);
    SimulationState state = stepper->initialState();
    // The grasped node, pulled sideways and down.
    const int node = lowestFreeNode(m, b.fixedNodes, s.gravity);
    QVERIFY(node >= 0);
    const Eigen::Vector3d from = m.rest[static_cast<std::size_t>(node)], pull(0.02, 0, -0.0135);  // 24 mm
    const int pulling = static_cast<int>(std::lround(0.4 / s.timeStep)), free = 20;
    double worstTrue = 0, worstEstimate = 0, worstLow = 1e300, worstHigh = 0, worstForce = 0, worstForceTrue = 0;
    int steps = 0, estimated = 0, resolved = 0, lowAt = -1;
    for (int k = 0; k < pulling + free; ++k) {
      const bool held = k < pulling;
      const auto hold =
          held ? testing::holdAt(node, from + pull * double(k + 1) / pulling) : std::vector<ScalarConstraint>{};
      stepper->setToolConstraints(hold);
      exact->setToolConstraints(hold);
      SimulationState reference = state;
      const StepReport rep = stepper->step(state);
      QVERIFY2(rep.ok, rep.status.c_str());
      const StepReport ref = exact->step(reference);
      QVERIFY2(ref.ok && ref.outcome == StepStatus::Converged, ref.status.c_str());
      ++steps;
      const double truth = largestNodeDistance(state.x, reference.x);
      const double forceTruth = (stepper->toolForce() - exact->toolForce()).norm();
      QVERIFY2(std::isfinite(rep.errorPosition) && std::isfinite(rep.errorForce),
               qPrintable(QString("step %1: no estimate (%2; %3 m, %4 N)").arg(k).arg(QString::fromStdString(rep.status)).arg(rep.errorPosition).arg(rep.errorForce)));
      ++estimated;
      // The ratio where the truth itself is resolved (over 1 nm).
      if (truth > kResolved) {
        ++resolved;
        if (rep.errorPosition / truth < worstLow) lowAt = k;
        worstLow = std::min(worstLow, rep.errorPosition / truth);
        worstHigh = std::max(worstHigh, rep.errorPosition / truth);
      }
      worstTrue = std::max(worstTrue, truth);
      worstEstimate = std::max(worstEstimate, rep.errorPosition);
      worstForceTrue = std::max(worstForceTrue, forceTruth);
      worstForce = std::max(worstForce, rep.errorForce);
      if (k % 10 == 0 || k == pulling || (asked > 0 && truth > 0.8 * asked))
        qInfo("step %2d (%s): true error %.3g mm, estimated %.3g mm; tool force %.3f N, its error %.3g N, estimated "
              "%.3g N; %s; %d iterations%s",
              k, held ? "held" : "let go", 1e3 * truth, 1e3 * rep.errorPosition,
              exact->toolForce().norm(), forceTruth, rep.errorForce,
              statusSentence(rep).c_str(), rep.newtonIterations, rep.withinAccuracy ? ", ended on the accuracy" : "");
      QVERIFY2(truth <= kResolved || rep.errorPosition >= 0.5 * truth,
               qPrintable(QString("step %1: estimated %2 mm, the true error is %3 mm")
                              .arg(k)
                              .arg(1e3 * rep.errorPosition)
                              .arg(1e3 * truth)));
      // (A step ended on the accuracy divides its next correction by 1 - rho, rho up to 0.9: up to 10 times that
      // correction, itself about the truth; 20 times the truth allowed there. With an accuracy asked, an estimate a
      // hundredth of it costs nothing however pessimistic: the asynchronous run once estimated 16 nm for 0.3 nm.)
      QVERIFY2(rep.errorPosition <= (rep.withinAccuracy ? 20 : 10) * truth + std::max(kResolved, asked / 100),
               qPrintable(QString("step %1: estimated %2 mm, far above the true error %3 mm")
                              .arg(k)
                              .arg(1e3 * rep.errorPosition)
                              .arg(1e3 * truth)));
      QVERIFY2(forceTruth <= 1e-3 || rep.errorForce >= 0.5 * forceTruth,
               qPrintable(QString("step %1: tool force error estimated %2 N, true %3 N")
                              .arg(k)
                              .arg(rep.errorForce)
                              .arg(forceTruth)));
      if (asked > 0) {
        endedOnAccuracy += rep.withinAccuracy;
        QVERIFY2(truth <= asked, qPrintable(QString("step %1: %2 mm from exact Newton's answer, %3 mm asked (%4)")
                                                .arg(k)
                                                .arg(1e3 * truth)
                                                .arg(1e3 * asked)
                                                .arg(QString::fromStdString(statusSentence(rep)))));
        const double forceAsked = std::max(bs.settings.accuracyForce * exact->toolForce().norm(), 1e-3);
        QVERIFY2(forceTruth <= forceAsked, qPrintable(QString("step %1: the tool force %2 N from exact Newton's, %3 N "
                                                              "asked")
                                                          .arg(k)
                                                          .arg(forceTruth)
                                                          .arg(forceAsked)));
      }
      QVERIFY2(rep.errorForce <= 10 * forceTruth + 1e-3,
               qPrintable(QString("step %1: tool force error estimated %2 N, far above the true %3 N")
                              .arg(k)
                              .arg(rep.errorForce)
                              .arg(forceTruth)));
    }
    qInfo("%s%s: %d steps, all estimated; largest true error %.3g mm (estimated at most %.3g mm); estimate / truth "
          "in [%.2f (step %d), %.2f] over the %d steps whose error is over 1 nm; tool force error at most %.3g N (estimated at "
          "most %.3g N)",
          toString(s.method).c_str(), async ? " (asynchronous)" : "", steps, 1e3 * worstTrue, 1e3 * worstEstimate,
          resolved ? worstLow : 0.0, lowAt, worstHigh, resolved, worstForceTrue, worstForce);
    QCOMPARE(estimated, steps);
    if (asked > 0) {
      qInfo("%d of %d steps ended on the accuracy asked (%.3g mm), the others on the relative residual", endedOnAccuracy,
            steps, 1e3 * asked);
      QVERIFY(endedOnAccuracy > 0);  // the rule acted (else this row tests the residual's rule again)
    }
  }

  // The accuracy asked in millimetres ends steps earlier than the relative residual of 1e-6 (nanometres): fewer Newton
  // iterations for the same grasp and pull (counts, not times), the same motion within the accuracy at every step.
  void askingForAccuracyTakesFewerIterations() {
    const BodySetup b = testing::presetBody("liver");
    const FemModel m = FemModel::build(b.mesh, b.byLabel, b.material);
    int iterations[2] = {0, 0};
    Eigen::VectorXd ends[2];
    for (const int run : {0, 1}) {
      BodySetup bs = b;
      bs.settings.method = NewtonMethod::Chord;
      bs.settings.accuracyPosition = run == 1 ? 5e-5 : 0;
      const auto body = makeFemBody(bs);
      SimulationState state = body->initialState();
      const int node = lowestFreeNode(m, b.fixedNodes, bs.settings.gravity);
      const Eigen::Vector3d from = m.rest[static_cast<std::size_t>(node)];
      for (int k = 0; k < 60; ++k) {
        body->setToolConstraints(k < 40 ? testing::holdAt(node, from + Eigen::Vector3d(0.0005 * k, 0, -0.0003 * k))
                                        : std::vector<ScalarConstraint>{});
        const StepReport rep = body->step(state);
        QVERIFY2(rep.ok && rep.outcome == StepStatus::Converged, rep.status.c_str());
        iterations[run] += rep.newtonIterations;
      }
      ends[run] = state.x;
    }
    const double apart = largestNodeDistance(ends[0], ends[1]);
    qInfo("60 steps of a pull and release: %d Newton iterations at a relative residual of 1e-6, %d at 0.05 mm; the "
          "ends %.3g mm apart",
          iterations[0], iterations[1], 1e3 * apart);
    QVERIFY(iterations[1] < iterations[0]);
    QVERIFY2(apart < 5e-4, "the two runs' motions parted by more than ten times the accuracy");
  }

  // The offline check a trainer runs on a recording (`rehearse replay --exact-check`): a session on the liver preset
  // with the window's chord and asynchronous refresh at 0.05 mm (a grasp that pulls 15 mm and lets go, then a hook
  // that cuts the left lobe off) is replayed and every step is taken again by exact Newton from the same start. Every
  // step is resolved, within the accuracy asked, its estimate never under half the truth; the same session run by
  // exact Newton itself (relative residual 1e-10) is found where the check's own exact Newton is (a check that took
  // another step's inputs or start would put it millimetres away).
  void aSessionCheckedAgainstExactNewtonOffline() {
    BodySetup b = testing::presetBody("liver");
    b.tools.graspRadius = 0.006;
    b.tools.maxGraspForce = 30;
    b.tools.bladeLength = 0.09;
    b.tools.trocar = Eigen::Vector3d(-0.06, -0.2, 0.0);
    Eigen::Vector3d grip = b.mesh.points.front();
    for (const auto& p : b.mesh.points)
      if ((p - Eigen::Vector3d(0, 0, -0.05)).norm() < (grip - Eigen::Vector3d(0, 0, -0.05)).norm()) grip = p;
    auto session = [&](const BodySetup& setup, int steps) {
      Session s(setup);
      for (int k = 0; k < steps; ++k) {
        if (k == 20) s.post(testing::toolAt(grip)), s.post(testing::jaws(true));
        if (k > 20 && k <= 60) s.post(testing::toolAt(grip + Eigen::Vector3d(0, 0, -0.015) * (k - 20) / 40.0));
        if (k == 75) s.post(testing::jaws(false));
        if (k == 90) {
          InputEvent hook = testing::toolAt({-0.06, 0.05, -0.04});
          hook.tool = 1;
          s.post(hook);
          s.post(testing::cutting(true));
        }
        if (k > 90 && k <= 150) {
          InputEvent hook = testing::toolAt({-0.06, 0.05, -0.04 + 0.09 * (k - 90) / 60.0});
          hook.tool = 1;
          s.post(hook);
        }
        if (k == 150) s.post(testing::cutting(false));
        s.advance();
      }
      return s.recorded();
    };
    BodySetup window = b;
    window.settings.method = NewtonMethod::Chord;
    window.settings.factorRefresh = FactorRefresh::Asynchronous;
    window.settings.accuracyPosition = 5e-5;
    const int steps = 170;
    const std::vector<InputEvent> events = session(window, steps);
    int checked = 0, cuts = 0, onAccuracy = 0, resolved = 0;
    double worst = 0, worstForce = 0, lowest = 1e300;
    QString lowestAt;
    ExactCheckOptions o;
    o.each = [&](const StepTruth& t) {
      ++checked;
      cuts += static_cast<int>(std::count(t.events.begin(), t.events.end(), "cut"));
      if (!t.resolved) return true;
      ++resolved;
      worst = std::max(worst, t.errorPosition);
      worstForce = std::max(worstForce, t.errorForce);
      if (t.report.withinAccuracy) {
        ++onAccuracy;
        [&] { QVERIFY2(t.errorPosition <= 5e-5, qPrintable(QString("step %1: %2 mm from exact Newton's answer").arg(t.step).arg(1e3 * t.errorPosition))); }();
      }
      // (judged as the command line judges it: where the truth is over a tenth of the accuracy asked; below, a step
      // ended on the relative residual after the cut estimated 0.16 um for 1.2 um)
      if (t.errorPosition > 5e-6 && t.report.errorPosition / t.errorPosition < lowest) {
        lowest = t.report.errorPosition / t.errorPosition;
        lowestAt = QString("step %1: %2 mm estimated, %3 mm true, %4").arg(t.step).arg(1e3 * t.report.errorPosition).arg(1e3 * t.errorPosition).arg(QString::fromStdString(t.report.status));
      }
      return true;
    };
    checkAgainstExact(window, events, steps, o);
    qInfo("the lowest estimate for its truth: %s", qPrintable(lowestAt));
    qInfo("%d steps checked against exact Newton (%d resolved, %d ended on the accuracy, %d cut updates): at most %.4f mm "
          "and %.4f N from its answer; estimate at least %.2f x the truth where it is over 0.005 mm",
          checked, resolved, onAccuracy, cuts, 1e3 * worst, worstForce, lowest);
    QCOMPARE(checked, steps);
    QCOMPARE(resolved, steps);
    QVERIFY(cuts > 0 && onAccuracy > steps / 2);
    QVERIFY2(worst <= 5e-5, qPrintable(QString::number(1e3 * worst)));
    QVERIFY2(lowest >= 0.5, qPrintable(QString::number(lowest)));

    BodySetup exact = b;
    exact.settings.method = NewtonMethod::Exact;
    exact.settings.tolerance = 1e-10;
    exact.settings.maxNewtonIterations = 60;
    const int exactSteps = 80;  // the grasp, its pull and the release
    const std::vector<InputEvent> exactEvents = session(exact, exactSteps);
    double apart = 0;
    int exactChecked = 0;
    o.each = [&](const StepTruth& t) {
      ++exactChecked;
      [&] { QVERIFY2(t.resolved, t.why.c_str()); }();
      if (t.resolved) apart = std::max(apart, t.errorPosition);
      return true;
    };
    checkAgainstExact(exact, exactEvents, exactSteps, o);
    qInfo("the session run by exact Newton itself: at most %.3g mm from the check's", 1e3 * apart);
    QCOMPARE(exactChecked, exactSteps);
    QVERIFY2(apart < 1e-9, qPrintable(QString::number(apart)));
  }

  // After a tear the steps have a factor built for the torn body where the tear was launched (the factor refreshed on the
  // second thread): far stiffer than the torn piece's tangent as it swings free. The factor's own one-solve estimate and the relative residual then said 0.0001-0.001 mm where exact
  // Newton's answer was 0.04-2.25 mm away (bench_operative --exact-check on the patient liver). A bar grasped at its end
  // and pulled until it tears, the torn piece swung on the grasper and let go, checked offline: no step says it is
  // within 0.05 mm of the nearest answer of its equations and is not; every estimate at least half its truth (over 0.01 mm), or
  // saying it does not know. (Ending the steps on the check instead, the steps' own Newton correction driving them, kept
  // every step within 0.05 mm here but cost 2.5 times the median step on the patient liver, 0.8 s in its pull.)
  // When the factors built on the second thread come in: at every step boundary (an asynchronous run with the machine
  // idle: the bar's factor takes well under a step), or every second or third one (loaded). Until 2026-12-04 the first
  // two schedules fell under half the truth: at step 77, held by the grasp whose rows ran all their Gauss-Seidel sweeps
  // and took the dense solve, one move ended it on the accuracy with 0.0065 mm estimated, 0.018 mm from its answer (0.36
  // of it). A body that was cut or torn now has every step's estimate checked on the tangent at its end
  // (Integrator::setVerifyEveryEstimate): the lowest ratio is 0.98 in every schedule.
  void aTearCheckedAgainstExactNewtonOffline_data() {
    QTest::addColumn<int>("period");
    QTest::addColumn<int>("phase");
    QTest::addColumn<bool>("eliminate");  // SimulationSettings::localElimination (issue 61's experiment)
    QTest::addColumn<int>("estimateEvery");  // SimulationSettings::estimateErrorEvery (the window's: 10)
    QTest::newRow("factors in at every step") << 1 << 0 << false << 1;
    QTest::newRow("every second step") << 2 << 0 << false << 1;
    QTest::newRow("every third step") << 3 << 2 << false << 1;
    QTest::newRow("every third step, the flap's nodes eliminated") << 3 << 2 << true << 1;
    // The window's cadence: the torn body's steps checked on the tangent at every 10th step (and where their factor
    // looks suspect); the others say nothing of the accuracy.
    QTest::newRow("every third step, estimated every 10th") << 3 << 2 << false << 10;
  }

  void aTearCheckedAgainstExactNewtonOffline() {
    QFETCH(int, period);
    QFETCH(int, phase);
    QFETCH(bool, eliminate);
    QFETCH(int, estimateEvery);
    BodySetup b;
    b.mesh = boxMesh(0.04, 0.01, 0.01, 8, 2, 2);
    b.settings.estimateErrorEvery = estimateEvery;
    b.settings.localElimination = eliminate;
    b.fixedNodes = nodesAtX(b.mesh, 0.0);
    b.material = {MaterialModel::Corotational, 10e3, 0.3, 1000, 0.25};
    b.settings.method = NewtonMethod::Chord;
    // The factors built on the second thread come in at a fixed schedule (the row's), as a replay of an asynchronous run
    // has them: with the asynchronous refresh the run depends on when they arrived, and so did what the check found
    // (with the machine loaded, 4 runs in 105 had a step past the accuracy or an estimate under half its truth).
    b.settings.factorRefresh = FactorRefresh::Deferred;
    b.settings.accuracyPosition = 5e-5;
    b.settings.timeStep = 0.01;
    b.settings.rayleighMass = 2;
    b.settings.rayleighStiffness = 0.1;
    b.tools.graspRadius = 0.008;
    b.tools.maxGraspForce = 1e3;  // the tissue tears before the jaws let go
    b.tools.trocar = Eigen::Vector3d(0.2, 0.005, 0.005);
    const Eigen::Vector3d tip(0.04, 0.005, 0.005);
    const int steps = 110;
    int tears = 0, tornAt = -1;
    std::vector<InputEvent> events;
    {
      Session s(b);
      for (int k = 0; k < steps; ++k) {
        if (k == 0) s.post(testing::toolAt(tip)), s.post(testing::jaws(true));
        if (k > 0 && k <= 60) s.post(testing::toolAt(tip + Eigen::Vector3d(0.0003 * k, 0, 0)));
        if (k > 60 && k <= 90)  // the torn piece swung up and down on the grasper
          s.post(testing::toolAt(tip + Eigen::Vector3d(0.018, 0.01 * std::sin(0.2 * (k - 60)), 0)));
        if (k == 90) s.post(testing::jaws(false));
        if (k % period == phase) {
          InputEvent factor;
          factor.kind = InputKind::Factor;
          s.post(factor);
        }
        s.advance();
        const auto snap = s.snapshot();
        const int here = static_cast<int>(std::count(snap->events.begin(), snap->events.end(), "tear"));
        if (here > 0 && tornAt < 0) tornAt = k;
        tears += here;
      }
      events = s.recorded();
    }
    QVERIFY2(tears > 0 && tornAt < 60, qPrintable(QString("%1 tears, the first at step %2").arg(tears).arg(tornAt)));
    int eliminations = 0;
    int checked = 0, resolved = 0, onAccuracy = 0, unknown = 0, afterTear = 0, other = 0, claimedPast = 0, saidPast = 0, halved = 0;
    int notEstimated = 0, tornEstimated = 0;  // torn steps with no estimate (none claiming the accuracy); with one
    double worst = 0, lowest = 1e300;
    QString worstAt, lowestAt, pastAt;
    ExactCheckOptions o;
    o.each = [&](const StepTruth& t) {
      ++checked;
      eliminations += t.report.eliminations;
      if (!t.resolved) return true;
      ++resolved;
      if (t.step > tornAt) ++afterTear;
      if (!std::isfinite(t.report.errorPosition) && !t.report.errorUnknown && estimateEvery > 1) {
        // not estimated at this step (nor checked): the torn body's claims nothing (the whole body's may claim it on its
        // factor's contraction, as before the tear)
        if (t.step > tornAt)
          [&] { QVERIFY2(!t.report.withinAccuracy, qPrintable(QString("step %1: torn, within the accuracy, unchecked").arg(t.step))); }();
        notEstimated += t.step > tornAt;
        return true;
      }
      tornEstimated += t.step > tornAt;
      if (!std::isfinite(t.report.errorPosition)) {
        // said: the distance cannot be known there (the check on the tangent met an indefinite tangent or contacts
        // changing), not merely not estimated
        [&] { QVERIFY2(t.report.errorUnknown, qPrintable(QString("step %1: no estimate, not said unknown").arg(t.step))); }();
        ++unknown;
        return true;
      }
      // The run's method converged stays by the run, exact Newton's answer lies elsewhere (the torn piece let go: its
      // step's equations have two solutions there); counted apart, as the command line does.
      if (t.anotherSolution(5e-5)) {
        ++other;
        return true;
      }
      if (t.errorPosition > worst) {
        worst = t.errorPosition;
        worstAt = QString("step %1: %2 mm, estimated %3 mm, %4; the run's method converged %5 mm from it, %6 mm from exact Newton's").arg(t.step).arg(1e3 * t.errorPosition).arg(1e3 * t.report.errorPosition).arg(t.report.withinAccuracy ? "ended on the accuracy" : "ended otherwise").arg(1e3 * t.ownConverged).arg(1e3 * t.ownToExact) + QString("; events [%1], exact Newton's [%2]; %3 iterations, %4 inner, residual %5, %6").arg(QString::fromStdString(std::accumulate(t.events.begin(), t.events.end(), std::string(), [](std::string a, const std::string& b) { return a + b + " "; }))).arg(QString::fromStdString(std::accumulate(t.exactEvents.begin(), t.exactEvents.end(), std::string(), [](std::string a, const std::string& b) { return a + b + " "; }))).arg(t.report.newtonIterations).arg(t.report.innerIterations).arg(t.report.residual).arg(QString::fromStdString(statusSentence(t.report)));
      }
      // The estimate is of the distance to the answer of the step's equations nearest the run: where the run's own method
      // converged from the same start (taken where the run is off) lies nearer the run than exact Newton's answer, that
      // one (exact Newton went to another solution within the accuracy asked).
      const double truth = std::isfinite(t.ownConverged) ? std::min(t.ownConverged, t.errorPosition) : t.errorPosition;
      if (t.report.withinAccuracy) ++onAccuracy;
      // Past the accuracy, judged against that answer too: just after the torn piece is let go, exact Newton's answer lay
      // 0.050-0.054 mm from the run while the run's own method converged 0.001-0.022 mm from it, 0.050-0.054 mm from
      // exact Newton's (two answers of the step's equations, nearer each other than the rule above counts apart).
      if (truth > 5e-5) {
        ++(t.report.withinAccuracy ? claimedPast : saidPast);
        if (t.report.withinAccuracy && pastAt.isEmpty())
          pastAt = QString("step %1: %2 mm from exact Newton's answer, %3 mm from its own method's converged, estimated %4 mm; %5 iterations, %6 inner").arg(t.step).arg(1e3 * t.errorPosition).arg(1e3 * t.ownConverged).arg(1e3 * t.report.errorPosition).arg(t.report.newtonIterations).arg(t.report.innerIterations);
      }
      // Judged where the truth is over a fifth of the accuracy asked. The chord's first-move floor on its contraction
      // (NewtonLoop::rho) brought the lowest ratio from 0.40 (1 run in 30-100) to 0.60-0.68 over 100 runs.
      // (A step taken in halves after a failed attempt estimates its halves' distance from their answers: other
      // equations than the check's full step; it does not say it is within the accuracy, and is not judged here.)
      if (t.report.retries > 0) ++halved;
      if (truth > 1e-5 && t.report.retries == 0 && t.report.errorPosition / truth < lowest) {
        lowest = t.report.errorPosition / truth;
        lowestAt = QString("step %1: %2 mm estimated, %3 mm true; %4 iterations, %5 inner, residual %6, %7").arg(t.step).arg(1e3 * t.report.errorPosition).arg(1e3 * truth).arg(t.report.newtonIterations).arg(t.report.innerIterations).arg(t.report.residual).arg(t.report.withinAccuracy ? "ended on the accuracy" : "ended otherwise");
      }
      return true;
    };
    checkAgainstExact(b, events, steps, o);
    qInfo("%d tears (the first at step %d); %d steps checked, %d resolved, %d after the tear, %d ended on the accuracy, %d "
          "with the distance unknown, %d where exact Newton went to another solution, %d past the accuracy and saying "
          "so, %d past it and saying within, %d taken in halves; the farthest %s; the lowest estimate for its truth %s",
          tears, tornAt, checked, resolved, afterTear, onAccuracy, unknown, other, saidPast, claimedPast, halved,
          qPrintable(worstAt), qPrintable(lowestAt));
    qInfo("moves ended by an elimination: %d; after the tear %d steps estimated, %d not (estimated every %d)", eliminations,
          tornEstimated, notEstimated, estimateEvery);
    if (estimateEvery > 1) QVERIFY(notEstimated > 30 && tornEstimated >= 5);
    QCOMPARE(checked, steps);
    QVERIFY(eliminate ? eliminations > 0 : eliminations == 0);
    // (Where exact Newton goes to another answer depends on when the second thread's factors arrived: 0-13 steps in 100
    // runs with the machine loaded.)
    QVERIFY(resolved >= steps - 2 && afterTear > 30 && other <= steps / 5);
    QVERIFY2(claimedPast == 0, qPrintable(pastAt));  // never a step said within the accuracy and past it
    QVERIFY2(lowest >= 0.5, qPrintable(lowestAt));
  }

  // The offline check's second start (checkAgainstExact, StepTruth::exactFromEnd): SimulationState::firstIterate moves
  // only where a step's Newton iterations start, not its equations. Started at its own answer, exact Newton stays there
  // (no iteration, the same positions to its tolerance); started twice as far out as the answer's move, it comes back to
  // the same answer (this pull has one); the field is cleared by the step.
  void aStepStartedElsewhereSolvesTheSameEquations() {
    const BodySetup b = testing::presetBody("liver");
    const FemModel m = FemModel::build(b.mesh, b.byLabel, b.material);
    SimulationSettings s = b.settings;
    s.method = NewtonMethod::Exact;
    s.tolerance = 1e-10;
    s.maxNewtonIterations = 60;
    Integrator in(m, b.fixedNodes, s);
    SimulationState state = in.initialState();
    const int node = lowestFreeNode(m, b.fixedNodes, s.gravity);
    for (int k = 0; k < 5; ++k) {  // a pull under way: the step below starts moving
      in.setConstraints(testing::holdAt(node, m.rest[static_cast<std::size_t>(node)] + Eigen::Vector3d(0, 0.002 * k, 0)));
      QVERIFY(in.step(state).ok);
    }
    in.setConstraints(testing::holdAt(node, m.rest[static_cast<std::size_t>(node)] + Eigen::Vector3d(0, 0.012, 0)));
    const SimulationState start = state;
    SimulationState plain = start;
    const StepReport ref = in.step(plain);
    QVERIFY2(ref.ok && ref.outcome == StepStatus::Converged, ref.status.c_str());
    const double moved = largestNodeDistance(plain.x, start.x);
    QVERIFY(moved > 1e-4);  // the step moves the organ (m)
    const Eigen::VectorXd answer = (plain.x - start.x) / s.timeStep;
    for (const double far : {1.0, 2.0}) {
      SimulationState again = start;
      again.firstIterate = far * answer;
      const StepReport rep = in.step(again);
      QVERIFY2(rep.ok && rep.outcome == StepStatus::Converged, rep.status.c_str());
      QCOMPARE(again.firstIterate.size(), Eigen::Index(0));
      const double apart = largestNodeDistance(again.x, plain.x);
      qInfo("started %.0fx the answer's move (%.3f mm): %d iterations (from the step's start %d), %.2e mm from its answer",
            far, 1e3 * far * moved, rep.newtonIterations, ref.newtonIterations, 1e3 * apart);
      QVERIFY2(apart < 1e-3 * moved, qPrintable(QString::number(1e3 * apart) + " mm apart"));
      if (far == 1.0) QVERIFY(rep.newtonIterations <= 1);
    }
  }

  // What the check counts as another solution rather than the run's error: a converged answer by the run (its own
  // method's, or exact Newton's started where it ended) within what it asked, exact Newton's from the start beyond it.
  void anotherSolutionNeedsAnAnswerByTheRun() {
    StepTruth t;
    t.report.errorPosition = 1e-5;  // estimated 0.01 mm; 0.05 mm asked
    t.errorPosition = 4e-4;         // exact Newton's answer 0.4 mm away
    QVERIFY(!t.anotherSolution(5e-5));  // nothing found by the run: its error
    t.exactFromEnd = 3e-4;              // Newton from the run's end went as far: no answer by it either
    QVERIFY(!t.anotherSolution(5e-5));
    t.exactFromEnd = 2e-5;  // an answer 0.02 mm from the run
    QVERIFY(t.anotherSolution(5e-5));
    t.errorPosition = 3e-5;  // exact Newton's own answer is within the accuracy too: the same one, no other
    QVERIFY(!t.anotherSolution(5e-5));
    StepTruth own;
    own.report.errorPosition = 1e-5;
    own.errorPosition = 4e-4;
    own.ownConverged = 1e-5, own.ownToExact = 3.9e-4;  // the run's method converged by the run, far from exact Newton's
    QVERIFY(own.anotherSolution(5e-5));
  }

  // The estimate changes nothing a step computes: the same run with it off gives the same bits.
  void estimatingChangesNothing() {
    const BodySetup b = testing::presetBody("liver");
    const FemModel m = FemModel::build(b.mesh, b.byLabel, b.material);
    for (NewtonMethod method : {NewtonMethod::Linearised, NewtonMethod::Chord}) {
      Eigen::VectorXd ends[2];
      for (const bool estimate : {true, false}) {
        SimulationSettings s = b.settings;
        s.method = method;
        s.estimateError = estimate;
        Integrator in(m, b.fixedNodes, s);
        SimulationState state = in.initialState();
        const int node = lowestFreeNode(m, b.fixedNodes, s.gravity);
        for (int k = 0; k < 30; ++k) {
          in.setConstraints(testing::holdAt(node, m.rest[static_cast<std::size_t>(node)] +
                                                      Eigen::Vector3d(0, 0.0005 * k, 0)));
          const StepReport rep = in.step(state);
          QVERIFY(rep.ok);
          QCOMPARE(std::isfinite(rep.errorPosition), estimate);
        }
        ends[estimate ? 0 : 1] = state.x;
      }
      QVERIFY2(ends[0] == ends[1], toString(method).c_str());
    }
  }
};

QTEST_GUILESS_MAIN(TestStepError)
#include "test_step_error.moc"
