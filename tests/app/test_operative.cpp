// A cholecystectomy-like sequence on a real organ shape (issue 36, operative_case.hpp: the patient liver, a cystic
// artery through it, every instrument in one script), through the command line as a user runs it: recorded, replayed
// bit for bit, and its metrics: two clips, none misplaced, the artery cut and no blood lost, energy applied, tissue
// torn.
#include "cli_run.hpp"
#include "operative_case.hpp"
#include "session_inputs.hpp"
#include "test_support.hpp"

#include <rehearse/app/gesture.hpp>
#include <rehearse/simcore/scene.hpp>
#include <rehearse/simcore/session/step_truth.hpp>

#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QTemporaryDir>
#include <QtTest>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

using namespace rehearse;
using ::testing::run;
using ::testing::Run;

class TestOperative : public QObject {
  Q_OBJECT
 private slots:
  void cholecystectomyOnARealLiver() {
    REQUIRE_SHARED("scikit-surgery/patient-liver/liver.vtk");
    QTemporaryDir dir;
    if (qEnvironmentVariableIsSet("REHEARSE_KEEP")) {  // to run the case by hand
      dir.setAutoRemove(false);
      qInfo("kept in %s", qPrintable(dir.path()));
    }
    const rehearse::testing::OperativeCase oc = rehearse::testing::writeOperativeCase(
        sharedData("scikit-surgery/patient-liver/liver.vtk"), dir.path().toStdString());
    qInfo(
        "the patient liver: %zu elements, %zu nodes, %.0f x %.0f x %.0f mm; the cystic artery: %d elements, %.0f mm "
        "deep",
        oc.elements, oc.nodes, 1e3 * oc.size.x(), 1e3 * oc.size.y(), 1e3 * oc.size.z(), oc.artery, 1e3 * oc.depth);
    QVERIFY(oc.artery > 20);
    if (qEnvironmentVariableIsSet("REHEARSE_KEEP")) return;
    const QString file = dir.path() + "/case.rehearse";
    if (qEnvironmentVariableIsSet("REHEARSE_KEEP")) return;
    const Run g = run({"gesture", "--scene", dir.path() + "/scene.json", "--script", dir.path() + "/chole.json",
                       "--method", "chord", "--out", dir.path() + "/out.vtu", "--record", file, "--report",
                       dir.path() + "/report.json", "--trainee", "A. Trainee"});
    qInfo("%s", qPrintable(g.out.trimmed()));
    QVERIFY2(::testing::tookEveryStep(g), qPrintable(QString::number(g.code) + ": " + g.out + g.err));
    QFile rf(dir.path() + "/report.json");
    QVERIFY(rf.open(QIODevice::ReadOnly));
    const QJsonObject report = QJsonDocument::fromJson(rf.readAll()).object();
    QStringList said;
    for (const auto& row : report["steps"].toArray())
      if (!row.toObject()["message"].toString().isEmpty()) said << row.toObject()["message"].toString();
    qInfo("what the session said:\n  %s", qPrintable(said.join("\n  ")));
    QCOMPARE(report["clips"].toInt(), 2);
    QCOMPARE(report["misplaced_clips"].toInt(), 0);
    QVERIFY(report["vessel_cuts"].toInt() >= 1);
    QCOMPARE(report["blood_loss_ml"].toDouble(), 0.0);
    QVERIFY(report["burns"].toInt() >= 1);
    QVERIFY(report["tears"].toInt() >= 1);
    // Replayed bit for bit, with the trainer's metrics.
    const Run r = run({"replay", file, "--session", "1", "--verify", "--metrics", dir.path() + "/m.json"});
    QVERIFY2(r.code == 0, qPrintable(r.out + r.err));
    QFile mf(dir.path() + "/m.json");
    QVERIFY(mf.open(QIODevice::ReadOnly));
    const QJsonObject metrics = QJsonDocument::fromJson(mf.readAll()).object();
    qInfo(
        "metrics: clips %d (misplaced %d), vessel cuts %d, blood lost %.3f mL, energy %.2f s, tears %d, "
        "attachments torn %d",
        metrics["clips"].toInt(), metrics["misplaced_clips"].toInt(), metrics["vessel_cuts"].toInt(),
        metrics["blood_loss_ml"].toDouble(), metrics["energy_time_s"].toDouble(), metrics["tears"].toInt(),
        metrics["attachments_torn"].toInt());
    QCOMPARE(metrics["clips"].toInt(), 2);
    QCOMPARE(metrics["misplaced_clips"].toInt(), 0);
    QCOMPARE(metrics["vessel_cuts"].toInt(), report["vessel_cuts"].toInt());
    QCOMPARE(metrics["blood_loss_ml"].toDouble(), 0.0);
    QVERIFY(metrics["energy_time_s"].toDouble() > 0.3);
    QCOMPARE(metrics["tears"].toInt(), report["tears"].toInt());
    // The trainer's incorrect actions under the default rules: the artery was cut between its two clips (no vessel
    // cut without clips) and the clips sat on it, but pulling until it tore is one (tears in one over-pull are one).
    QStringList listed;
    for (const auto& a : metrics["incorrect_action_list"].toArray())
      listed << QString("%1 s %2").arg(a.toObject()["time_s"].toDouble()).arg(a.toObject()["rule"].toString());
    qInfo("incorrect actions: %d (%s)", metrics["incorrect_actions"].toInt(), qPrintable(listed.join(", ")));
    QCOMPARE(metrics["vessel_cuts_without_clips"].toInt(-1), 0);
    QCOMPARE(metrics["incorrect_action_list"].toArray().size(), metrics["incorrect_actions"].toInt(-1));
    QVERIFY(listed.filter(" tear").size() >= 1);
    QVERIFY(listed.filter("clip_misplaced").isEmpty());
    QVERIFY(metrics["instrument_outside_view"].isNull());  // the script declares no view: not determined
    // The GUI's way: the factor rebuilt on the second thread, taken in at a step's start when built or, where the
    // accelerated chord stalls after a tear, waited for within the step (issue 61); steps ended at 0.05 mm (issue 64).
    // Recorded and replayed bit for bit: the replay takes each factor where the run did, whatever its second thread's
    // timing.
    const QString asyncFile = dir.path() + "/async.rehearse";
    const Run a = run({"gesture", "--scene", dir.path() + "/scene.json", "--script", dir.path() + "/chole.json",
                       "--method", "chord", "--refresh", "async", "--accuracy", "0.05", "--out",
                       dir.path() + "/async.vtu", "--record",
                       asyncFile, "--report", dir.path() + "/async-report.json"});
    QVERIFY2(::testing::tookEveryStep(a), qPrintable(QString::number(a.code) + ": " + a.out + a.err));
    QFile af(dir.path() + "/async-report.json");
    QVERIFY(af.open(QIODevice::ReadOnly));
    const QJsonObject asyncReport = QJsonDocument::fromJson(af.readAll()).object();
    int notConverged = 0;
    for (const auto& row : asyncReport["steps"].toArray())
      notConverged += !row.toObject()["status"].toString().startsWith("converged");
    qInfo("asynchronous refresh: %d tears, %d of %lld steps not converged", asyncReport["tears"].toInt(),
          notConverged, static_cast<long long>(asyncReport["steps"].toArray().size()));
    QVERIFY(asyncReport["tears"].toInt() >= 1);  // (the steps' statuses depend on the second thread's timing: said)
    const Run ra = run({"replay", asyncFile, "--session", "1", "--verify"});
    QVERIFY2(ra.code == 0, qPrintable(ra.out + ra.err));
  }

  // Issue 64, never a confident wrong answer: the window's variant (chord, the factor refreshed on the second thread,
  // steps ended at 0.05 mm) on the operative case after the liver tore, with its topology changes at the boundaries a
  // run of `bench_operative --record` took them (2026-12-04, a run of the kind whose steps after the tear go astray:
  // the cuts' bodies swapped in at 64, 80, 96 and 124, the tears' at 181-217 every 6 steps, no factor from the second
  // thread before 236), taken in by a deferred session as a replay takes them: the same trajectory on any machine.
  // Steps 205-224 checked against exact Newton. Before Newton's second correction was checked (NewtonLoop::
  // secondCorrection) steps 209 and 224 said they were within 0.05 mm and were 0.097 and 0.060 mm from exact Newton's
  // answer (their first corrections 0.004 and 0.017 mm, the second 25 and 1.5 times as large).
  void aStepAfterATearNeverSaysWithinAndIsFarther() {
    REQUIRE_SHARED("scikit-surgery/patient-liver/liver.vtk");
    QTemporaryDir dir;
    rehearse::testing::writeOperativeCase(sharedData("scikit-surgery/patient-liver/liver.vtk"), dir.path().toStdString());
    simcore::BodySetup base =
        rehearse::testing::sceneBody(simcore::loadScene(dir.path().toStdString() + "/scene.json"));
    base.settings.method = simcore::NewtonMethod::Chord;
    base.settings.chordAcceleration = true;
    base.settings.factorRefresh = simcore::FactorRefresh::Deferred;
    base.settings.accuracyPosition = 5e-5;
    std::ifstream in(dir.path().toStdString() + "/chole.json");
    std::stringstream ss;
    ss << in.rdbuf();
    app::GestureScript script = app::parseGestureScript(ss.str());
    script.cutLatencySteps = -1;  // swapped in when built: here, at the boundaries below
    const long steps = 224;
    script.duration = steps * 0.01;
    const std::set<long> swapped = {64, 80, 96, 124, 181, 187, 193, 199, 205, 211, 217};
    simcore::BodySetup ran;
    std::vector<simcore::InputEvent> recorded;
    int tears = 0;
    app::GestureHooks hooks;
    hooks.start = [&](const simcore::BodySetup& b) { ran = b; };
    hooks.step = [&](const simcore::StepRecord& r) {
      if (r.recorded) recorded = *r.recorded;
    };
    hooks.boundary = [&](long k, simcore::Session& s) {
      if (!swapped.count(k)) return;
      simcore::InputEvent e;
      e.kind = simcore::InputKind::CutApplied;
      s.post(e);
    };
    const app::GestureResult g = app::runGesture(base, script, hooks);
    for (const auto& st : g.steps) tears += static_cast<int>(std::count(st.events.begin(), st.events.end(), "tear"));
    QCOMPARE(static_cast<long>(g.steps.size()), steps);
    QVERIFY2(tears >= 6, qPrintable(QString("%1 tears").arg(tears)));
    const double asked = 5e-5;
    int checked = 0, resolved = 0, within = 0, claimedPast = 0, unknown = 0, other = 0;
    double farthestWithin = 0;
    QString past;
    simcore::ExactCheckOptions o;
    o.from = 205;
    o.to = steps;
    o.each = [&](const simcore::StepTruth& t) {
      ++checked;
      if (!t.resolved) return true;
      ++resolved;
      if (!std::isfinite(t.report.errorPosition)) ++unknown;
      if (t.anotherSolution(asked)) return ++other, true;
      if (!t.report.withinAccuracy) return true;
      ++within;
      farthestWithin = std::max(farthestWithin, t.errorPosition);
      if (t.errorPosition > asked) {
        ++claimedPast;
        past += QString(" step %1: %2 mm from exact Newton's answer, estimated %3 mm;").arg(t.step).arg(1e3 * t.errorPosition).arg(1e3 * t.report.errorPosition);
      }
      return true;
    };
    simcore::checkAgainstExact(ran, recorded, steps, o);
    qInfo("%d tears; steps 205-%ld: %d checked, %d resolved by exact Newton, %d with the distance not known, %d where "
          "exact Newton went to another solution, %d said within 0.05 mm (the farthest %.4f mm from exact Newton's "
          "answer), %d of them farther",
          tears, steps, checked, resolved, unknown, other, within, 1e3 * farthestWithin, claimedPast);
    QCOMPARE(checked, static_cast<int>(steps - 204));
    QVERIFY(resolved >= checked - 3);
    QVERIFY2(claimedPast == 0, qPrintable(past));
  }

  // The cut between two clips on the liver preset (clip-clip-cut.json: StVK, the chord method, its factor rebuilt at
  // once, the relative residual to 1e-6), each step from 100 to 130 checked against exact Newton's answer from the
  // same start; the hook cuts through the clipped vessel at step 112. With the clips' constraints the chord's
  // correction there is not a descent direction for the residual's norm, and backtracking on that norm took a 64th of
  // each correction while the residual rose: step 112 ended at a relative residual of 0.0232 (exact Newton does not
  // resolve that step either), step 115 at 0.00026 after two retries, and step 116 0.156 mm from exact Newton's answer.
  // Backtracking on the incremental potential plus the constraints' violation (NewtonLoop::lineSearch): at most 3.8e-6
  // and 0.057 mm (step 113; the steps converged to 1e-6 after the cut are 0.03-0.06 mm from it either way, a soft mode).
  void theCutBetweenTheClipsEndsNearExactNewton() {
    simcore::BodySetup base = rehearse::testing::sceneBody(phantom::makePreset("liver"));
    base.settings.method = simcore::NewtonMethod::Chord;
    base.settings.factorRefresh = simcore::FactorRefresh::Synchronous;
    base.settings.accuracyPosition = 0;
    std::ifstream in(std::string(REHEARSE_SOURCE_DIR) + "/resources/gestures/clip-clip-cut.json");
    std::stringstream ss;
    ss << in.rdbuf();
    app::GestureScript script = app::parseGestureScript(ss.str());
    const long steps = 130;
    script.duration = steps * 0.01;
    simcore::BodySetup ran;
    std::vector<simcore::InputEvent> recorded;
    app::GestureHooks hooks;
    hooks.start = [&](const simcore::BodySetup& b) { ran = b; };
    hooks.step = [&](const simcore::StepRecord& r) {
      if (r.recorded) recorded = *r.recorded;
    };
    const app::GestureResult g = app::runGesture(base, script, hooks);
    QCOMPARE(static_cast<long>(g.steps.size()), steps);
    int clips = 0, vesselCuts = 0;
    for (const auto& st : g.steps) {
      clips += static_cast<int>(std::count(st.events.begin(), st.events.end(), "clip"));
      vesselCuts += static_cast<int>(std::count(st.events.begin(), st.events.end(), "vessel cut"));
    }
    QCOMPARE(clips, 2);
    QVERIFY(vesselCuts >= 1);
    int checked = 0, resolved = 0;
    double farthest = 0, largestResidual = 0;
    long farthestStep = -1;
    simcore::ExactCheckOptions o;
    o.from = 100;
    o.to = steps;
    o.each = [&](const simcore::StepTruth& t) {
      ++checked;
      largestResidual = std::max(largestResidual, t.report.residual);
      if (!t.resolved) return true;
      ++resolved;
      if (t.errorPosition > farthest) farthest = t.errorPosition, farthestStep = t.step;
      return true;
    };
    simcore::checkAgainstExact(ran, recorded, steps, o);
    qInfo("clip, clip, cut on the liver preset: steps 100-%ld, %d checked, %d resolved by exact Newton; the farthest "
          "%.4f mm from exact Newton's answer (step %ld); the largest relative residual %.3g",
          steps, checked, resolved, 1e3 * farthest, farthestStep, largestResidual);
    QCOMPARE(checked, static_cast<int>(steps - 99));
    QVERIFY(resolved >= checked - 1);
    QVERIFY2(farthest < 0.1e-3, qPrintable(QString("%1 mm at step %2").arg(1e3 * farthest).arg(farthestStep)));
    QVERIFY2(largestResidual < 1e-4, qPrintable(QString::number(largestResidual)));
  }
};

QTEST_GUILESS_MAIN(TestOperative)
#include "test_operative.moc"
