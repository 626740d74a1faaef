// A cholecystectomy-like sequence on a real organ shape (issue 36, operative_case.hpp: the patient liver, a cystic
// artery through it, every instrument in one script), through the command line as a user runs it: recorded, replayed
// bit for bit, and its metrics: two clips, none misplaced, the artery cut and no blood lost, energy applied, tissue
// torn.
#include "cli_run.hpp"
#include "operative_case.hpp"
#include "test_support.hpp"

#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QTemporaryDir>
#include <QtTest>

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
};

QTEST_GUILESS_MAIN(TestOperative)
#include "test_operative.moc"
