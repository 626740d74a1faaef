// The case file below the GUI (issue 63): what the GUI saves (.rehearse, one SQLite file) is read and written by the
// application core without Qt, and every command that takes a case folder takes a case file too, with the same
// answers. The GUI's own save and open under damage are test_casefile's (tests/ui); this suite needs no GUI.
#include "cli_run.hpp"
#include "test_support.hpp"

#include <rehearse/app/casefile.hpp>
#include <rehearse/app/casefolder.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <QCryptographicHash>
#include <QFile>
#include <QJsonDocument>
#include <QJsonObject>
#include <QTemporaryDir>
#include <QtTest>

#include <opencv2/core.hpp>
#include <sqlite3.h>

#include <map>

using namespace rehearse;
using ::testing::Run;
using ::testing::run;

namespace {

std::string readAll(const QString& path) {
  QFile f(path);
  if (!f.open(QIODevice::ReadOnly)) return {};
  const QByteArray b = f.readAll();
  return std::string(b.constData(), static_cast<std::size_t>(b.size()));
}

// Every part's data and stored checksum, read with SQLite directly (not through the code under test).
std::map<std::string, std::pair<QByteArray, QByteArray>> partsOf(const std::string& path) {
  std::map<std::string, std::pair<QByteArray, QByteArray>> parts;
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    sqlite3_close(db);
    return parts;
  }
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(db, "SELECT name, data, sha256 FROM parts", -1, &s, nullptr);
  while (s && sqlite3_step(s) == SQLITE_ROW) {
    auto blob = [&](int k) {
      return QByteArray(static_cast<const char*>(sqlite3_column_blob(s, k)), sqlite3_column_bytes(s, k));
    };
    parts[reinterpret_cast<const char*>(sqlite3_column_text(s, 0))] = {blob(1), blob(2)};
  }
  sqlite3_finalize(s);
  sqlite3_close(db);
  return parts;
}

}  // namespace

class TestCaseCommands : public QObject {
  Q_OBJECT
  QTemporaryDir dir_;
  QString file_, folder_;  // the built-in phantom as a case file and as a case folder

 private slots:
  void initTestCase() {
    file_ = dir_.path() + "/phantom.rehearse";
    folder_ = dir_.path() + "/phantom";
    for (const QString& out : {file_, folder_}) {
      const Run r = run({"phantom", "--out", out});
      QVERIFY2(r.code == 0, qPrintable(r.err));
    }
  }

  // `rehearse phantom --out CASE.rehearse` writes the case the folder holds, part for part, each part's SHA-256 as
  // Qt's own implementation computes it (the writer uses OpenSSL's).
  void aCaseFileHoldsWhatTheFolderHolds() {
    QVERIFY(app::isCaseFile(file_.toStdString()));
    QVERIFY(!app::isCaseFile(folder_.toStdString()));
    std::vector<std::string> notes;
    const app::Case c = app::loadCaseFile(file_.toStdString(), &notes);
    QVERIFY2(notes.empty(), notes.empty() ? "" : notes.front().c_str());
    const app::Case d = app::loadCaseDirectory(folder_.toStdString());
    QCOMPARE(c.organ->volume.points.size(), d.organ->volume.points.size());
    double largest = 0;
    for (std::size_t i = 0; i < c.organ->volume.points.size(); ++i)
      largest = std::max(largest, (c.organ->volume.points[i] - d.organ->volume.points[i]).norm());
    QCOMPARE(largest, 0.0);  // binary VTU in the file, the folder's organ.vtu: the same doubles
    QVERIFY(c.organ->volume.tets == d.organ->volume.tets);
    QVERIFY(c.attachments == d.attachments);
    QVERIFY(c.camera.K == d.camera.K);
    QCOMPARE(c.frame.size(), d.frame.size());
    QCOMPARE(cv::norm(c.frame, d.frame, cv::NORM_INF), 0.0);
    QVERIFY(c.groundTruth && d.groundTruth);
    QVERIFY(c.groundTruth->pose.R.isApprox(d.groundTruth->pose.R, 1e-12));
    QVERIFY(!c.poseAligned);  // the automatic first guess, as the GUI starts it
    const auto parts = partsOf(file_.toStdString());
    QVERIFY(parts.size() >= 7);
    for (const auto& [name, part] : parts)
      QVERIFY2(QCryptographicHash::hash(part.first, QCryptographicHash::Sha256) == part.second, name.c_str());
    for (const char* name : {"volume", "frame", "camera", "attachments", "material", "pose", "ground_truth"})
      QVERIFY2(parts.count(name), name);
  }

  // appearance, compose and gesture take the case file where they took the folder, and answer the same, bit for bit.
  void commandsTakeACaseFile() {
    const QString pose = folder_ + "/pose.json";
    const QString thetaFile = dir_.path() + "/from-file.json", thetaFolder = dir_.path() + "/from-folder.json";
    Run r = run({"appearance", "--case", file_, "--pose", pose, "--out", thetaFile});
    QVERIFY2(r.code == 0 || r.code == 4, qPrintable(r.err));
    r = run({"appearance", "--case", folder_, "--pose", pose, "--out", thetaFolder});
    QVERIFY2(r.code == 0 || r.code == 4, qPrintable(r.err));
    QVERIFY(!readAll(thetaFile).empty());
    QCOMPARE(readAll(thetaFile), readAll(thetaFolder));

    // A case whose pose was never aligned gives no pose: the automatic guess is not taken for one.
    r = run({"appearance", "--case", file_, "--out", dir_.path() + "/none.json"});
    QCOMPARE(r.code, 2);
    QVERIFY2(r.err.contains("neither aligned nor fitted"), qPrintable(r.err));
    QVERIFY(!QFile::exists(dir_.path() + "/none.json"));

    // Aligned (as step 4 leaves it), the case file's own pose is the one used: no --pose needed.
    app::Case aligned = app::loadCaseFile(file_.toStdString());
    aligned.pose = imaging::loadPose(pose.toStdString());
    aligned.poseAligned = true;
    const QString alignedFile = dir_.path() + "/aligned.rehearse";
    app::saveCaseFile(aligned, alignedFile.toStdString());
    const QString thetaAligned = dir_.path() + "/aligned.json";
    r = run({"appearance", "--case", alignedFile, "--out", thetaAligned});
    QVERIFY2(r.code == 0 || r.code == 4, qPrintable(r.err));
    QCOMPARE(readAll(thetaAligned), readAll(thetaFolder));

    // Placed by the elastic fit and never moved by hand (F9 then Keep Fit, as the GUI saves it): the fit found the
    // pose, so it is the one used (a helper's path: refused before as 'never aligned'). The fit's nodes here are the
    // rest shape, so the answer is the folder's at that pose.
    app::Case fitted = app::loadCaseFile(file_.toStdString());
    fitted.pose = imaging::loadPose(pose.toStdString());
    fitted.poseAligned = false;
    fitted.fit = std::make_shared<const app::ElasticFit>(app::ElasticFit{fitted.organ->volume.points, "fitted (test)"});
    QVERIFY(fitted.poseDetermined());
    const QString fittedFile = dir_.path() + "/fitted.rehearse", thetaFitted = dir_.path() + "/fitted.json";
    app::saveCaseFile(fitted, fittedFile.toStdString());
    r = run({"appearance", "--case", fittedFile, "--out", thetaFitted});
    QVERIFY2(r.code == 0 || r.code == 4, qPrintable(r.err));
    QCOMPARE(readAll(thetaFitted), readAll(thetaFolder));

    const QString jFile = dir_.path() + "/j-file.png", jFolder = dir_.path() + "/j-folder.png";
    r = run({"compose", "--case", alignedFile, "--theta", thetaAligned, "--out", jFile});
    QVERIFY2(r.code == 0, qPrintable(r.err));
    r = run({"compose", "--case", folder_, "--pose", pose, "--theta", thetaFolder, "--out", jFolder});
    QVERIFY2(r.code == 0, qPrintable(r.err));
    QVERIFY(!readAll(jFile).empty());
    QCOMPARE(readAll(jFile), readAll(jFolder));

    const QString script = QStringLiteral(REHEARSE_SOURCE_DIR) + "/resources/gestures/grasp-pull.json";
    const QString outFile = dir_.path() + "/pulled-file.vtu", outFolder = dir_.path() + "/pulled-folder.vtu";
    const QString reportFile = dir_.path() + "/pulled-file.json";
    r = run({"gesture", "--case", file_, "--script", script, "--out", outFile, "--report", reportFile});
    QVERIFY2(::testing::tookEveryStep(r), qPrintable(r.err + r.out));
    // The method --help names as the default (a case's run took the library's exact method instead: a helper saw it).
    const QJsonObject report = QJsonDocument::fromJson(QByteArray::fromStdString(readAll(reportFile))).object();
    QCOMPARE(report.value("method").toString(), QStringLiteral("chord"));
    r = run({"gesture", "--case", folder_, "--script", script, "--out", outFolder});
    QVERIFY2(::testing::tookEveryStep(r), qPrintable(r.err + r.out));
    const simcore::Mesh a = simcore::loadMesh(outFile.toStdString()), b = simcore::loadMesh(outFolder.toStdString());
    QCOMPARE(a.points.size(), b.points.size());
    double moved = 0;
    for (std::size_t i = 0; i < a.points.size(); ++i) {
      QCOMPARE(a.points[i], b.points[i]);
      moved = std::max(moved, (a.points[i] - aligned.organ->volume.points[i]).norm());
    }
    QVERIFY2(moved > 1e-3, qPrintable(QString("the pull moved the organ %1 m").arg(moved)));  // a pull happened
  }

  // `info` on a case (a helper expected it to take the case file the window saved): what each step holds, the
  // recorded sessions and the organ's counts, as the case's own reader finds them; --unit, which a case cannot
  // honour, is refused. (Runs after commandsTakeACaseFile, whose aligned and fitted cases it reads.)
  void infoDescribesACase() {
    const app::Case c = app::loadCaseFile(file_.toStdString());
    const QString organ = QStringLiteral("organ: %1 nodes, %2 tetrahedra\n")
                              .arg(c.organ->volume.points.size())
                              .arg(c.organ->volume.tets.size());
    Run r = run({"info", file_});
    QVERIFY2(r.code == 0, qPrintable(r.err));
    for (const QString& line :
         {QStringLiteral("kind: case (a case file, as the window saves it)"), organ,
          QStringLiteral("attachments: %1 %2").arg(c.attachments.size()).arg(c.attachments.size() == 1 ? "node" : "nodes"),
          QStringLiteral("frame: %1 x %2 px").arg(c.frame.cols).arg(c.frame.rows),
          QStringLiteral("pose: placed automatically, not aligned"), QStringLiteral("appearance: not estimated"),
          QStringLiteral("recordings: 0 sessions"), QStringLiteral("tetrahedra: %1").arg(c.organ->volume.tets.size())})
      QVERIFY2(r.out.contains(line), qPrintable(line + " not in:\n" + r.out));
    r = run({"info", folder_});
    QVERIFY2(r.code == 0 && r.out.contains("kind: case (a case folder)") && r.out.contains(organ), qPrintable(r.out));
    QVERIFY(!r.out.contains("recordings:"));  // a folder holds none
    r = run({"info", dir_.path() + "/aligned.rehearse"});
    QVERIFY2(r.out.contains("pose: aligned by hand (step 4)"), qPrintable(r.out));
    r = run({"info", dir_.path() + "/fitted.rehearse"});
    QVERIFY2(r.out.contains("pose: aligned and elastically fitted (step 5)"), qPrintable(r.out));
    // A fit that explained too little is said as texture only; a session recorded into the case is counted.
    app::Case estimated = c;
    auto e = std::make_shared<app::AppearanceEstimate>();
    e->explained = 0.12;
    e->textureOnly = true;
    estimated.appearance = e;
    const QString estimatedFile = dir_.path() + "/estimated.rehearse";
    app::saveCaseFile(estimated, estimatedFile.toStdString());
    r = run({"gesture", "--case", estimatedFile, "--script",
             QStringLiteral(REHEARSE_SOURCE_DIR) + "/resources/gestures/grasp-pull.json", "--out",
             dir_.path() + "/estimated.vtu", "--record", estimatedFile});
    QVERIFY2(::testing::tookEveryStep(r), qPrintable(r.err + r.out));
    r = run({"info", estimatedFile});
    QVERIFY2(r.out.contains("appearance: the model explains 12 % of the organ's shading; texture only"),
             qPrintable(r.out));
    QVERIFY2(r.out.contains("recordings: 1 session, 1 complete"), qPrintable(r.out));
    // Reading a case recorded into (a WAL database) leaves nothing beside it (a helper found -wal and -shm files).
    for (const char* suffix : {"-wal", "-shm"}) QVERIFY2(!QFile::exists(estimatedFile + suffix), suffix);
    expectOneLineError(run({"info", file_, "--unit", "mm"}), 2, "--unit is for mesh files");
  }

  // What is not a case is refused in one sentence, whatever the command; a case file saved by a newer build too.
  void notACaseIsRefused() {
    const QString text = dir_.path() + "/notes.rehearse";
    ::writeFile(text.toStdString(), "not a database\n");
    const QString truncated = dir_.path() + "/truncated.rehearse";
    const std::string whole = readAll(file_);
    ::writeFile(truncated.toStdString(), whole.substr(0, 4096));
    const QString newer = dir_.path() + "/newer.rehearse";
    QFile::copy(file_, newer);
    {
      sqlite3* db = nullptr;
      QCOMPARE(sqlite3_open(newer.toStdString().c_str(), &db), SQLITE_OK);
      QCOMPARE(sqlite3_exec(db, "UPDATE meta SET value = '99' WHERE key = 'schema_version'", nullptr, nullptr, nullptr),
               SQLITE_OK);
      sqlite3_close(db);
    }
    // What 'gesture --record' writes holds recorded sessions and no case: said as that, not as damaged.
    const QString recordings = dir_.path() + "/recordings.rehearse";
    const Run recorded = run({"gesture", "--preset", "liver", "--script",
                              QStringLiteral(REHEARSE_SOURCE_DIR) + "/resources/gestures/grasp-pull.json", "--out",
                              dir_.path() + "/recorded.vtu", "--record", recordings});
    QVERIFY2(::testing::tookEveryStep(recorded), qPrintable(recorded.err + recorded.out));
    const std::vector<std::pair<QString, QString>> cases = {{recordings, "holds recorded sessions but no case"},
                                                            {text, "is not a case"},
                                                            {truncated, "damaged"},
                                                            {newer, "saved by a newer Rehearse (schema 99"},
                                                            {dir_.path() + "/missing.rehearse", "does not exist"}};
    for (const auto& [path, words] : cases) {
      const Run r = run({"appearance", "--case", path, "--pose", folder_ + "/pose.json", "--out", dir_.path() + "/x.json"});
      QVERIFY2(r.code == 1, qPrintable(path + ": " + r.err));
      QCOMPARE(r.err.trimmed().count('\n'), 0);
      QVERIFY2(r.err.contains(words), qPrintable(path + ": " + r.err));
      QVERIFY(!QFile::exists(dir_.path() + "/x.json"));
    }
  }

  // A save that cannot be made says why and leaves the file that was there.
  void aFailedSaveLeavesThePreviousFile() {
    const app::Case c = app::loadCaseFile(file_.toStdString());
    const QString path = dir_.path() + "/kept.rehearse";
    app::saveCaseFile(c, path.toStdString());
    const std::string before = readAll(path);
    QVERIFY_THROWS_EXCEPTION(std::runtime_error, app::saveCaseFile(c, (dir_.path() + "/no/such/folder/x.rehearse").toStdString()));
    try {
      app::saveCaseFile(c, (dir_.path() + "/no/such/folder/x.rehearse").toStdString());
    } catch (const std::runtime_error& e) {
      QVERIFY2(QString(e.what()).contains("a folder missing or not writable"), e.what());
    }
    QCOMPARE(readAll(path), before);
  }
};

QTEST_GUILESS_MAIN(TestCaseCommands)
#include "test_case_commands.moc"
