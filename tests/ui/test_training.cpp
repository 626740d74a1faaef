// The training centre's database (issue 16) against a real PostgreSQL server this test starts itself
// (initdb into a temporary folder, a Unix socket there, stopped at the end; as the postgres user when run
// as root). 50 sessions recorded into 5 case files (5 trainees; a grasp pulled by a known distance each):
//  - `rehearse publish` killed with SIGKILL mid-way leaves only whole sessions; run again, every session is
//    there exactly once and identical (checksums, events) to its case-file original;
//  - two publishers at once on the same files into a fresh database: no duplicate, no error, both exit 0;
//  - a session read back from the database replays and verifies (`rehearse replay postgresql:SERVICE`) and
//    seeks to its straight replay's states; its path length equals the scripted pull (to 1e-9 m);
//  - the cohort view lists the 5 trainees and plots each one's 10 attempts (the scripted distances).
// The connection goes through a libpq service file (PGSERVICEFILE), as a centre would configure it.
#include "fresh_start.hpp"
#include "window_support.hpp"
#include "replay_checks.hpp"
#include "test_support.hpp"

#include "box_mesh.hpp"
#include "session_inputs.hpp"

#include "rehearse/ui/cohortwindow.hpp"
#include "rehearse/ui/reviewwindow.hpp"
#include <rehearse/app/trainingdb.hpp>

#include <QDir>
#include <QJsonDocument>
#include <QJsonObject>
#include <QRegularExpression>
#include "cli_run.hpp"
#include <QFile>
#include <QProcess>
#include <QSqlDatabase>
#include <QSqlQuery>
#include <QStandardPaths>
#include <QTemporaryDir>

#include <unistd.h>

#include <random>
#include <set>

using namespace rehearse;

namespace {

struct PgServer {
  QString bin;
  QTemporaryDir dir{QDir::tempPath() + "/pgXXXXXX"};  // short: the socket's path has a length limit
  int port = 0;
  bool root = geteuid() == 0;
  bool started = false;
  QString log;

  QString run(const QString& program, const QStringList& args) {
    QProcess p;
    if (root) p.start("runuser", QStringList{"-u", "postgres", "--", bin + "/" + program} + args);
    else p.start(bin + "/" + program, args);
    p.waitForFinished(120000);
    const QString out = QString::fromUtf8(p.readAllStandardOutput() + p.readAllStandardError());
    return p.exitStatus() == QProcess::NormalExit && p.exitCode() == 0 ? QString() : program + ": " + out;
  }
  // One sentence on failure, empty when the server runs with databases `names`.
  QString start(const QStringList& names) {
    for (const QString& v : QDir("/usr/lib/postgresql").entryList(QDir::Dirs | QDir::NoDotAndDotDot, QDir::Name | QDir::Reversed))
      if (QFile::exists("/usr/lib/postgresql/" + v + "/bin/initdb")) {
        bin = "/usr/lib/postgresql/" + v + "/bin";
        break;
      }
    if (bin.isEmpty()) return "absent";
    if (root && QProcess::execute("chown", {"-R", "postgres:postgres", dir.path()}) != 0) return "cannot give the folder to the postgres user";
    if (QString e = run("initdb", {"-D", dir.path() + "/data", "-A", "trust", "-U", "rehearse", "-E", "UTF8", "--locale=C", "--no-sync"}); !e.isEmpty())
      return e;
    std::mt19937 rng(static_cast<unsigned>(getpid()));
    for (int attempt = 0; attempt < 5 && !started; ++attempt) {
      port = 20000 + static_cast<int>(rng() % 20000);
      const QString opts = QString("-k %1 -p %2 -c listen_addresses= -c fsync=off").arg(dir.path()).arg(port);
      log = run("pg_ctl", {"-D", dir.path() + "/data", "-l", dir.path() + "/server.log", "-w", "-t", "60", "-o", opts, "start"});
      started = log.isEmpty();
    }
    if (!started) return "the server did not start: " + log;
    for (const QString& n : names)
      if (QString e = run("createdb", {"-h", dir.path(), "-p", QString::number(port), "-U", "rehearse", n}); !e.isEmpty()) return e;
    // A libpq service file, as a training centre would write one: no password in it (trust on a private socket).
    QFile f(dir.path() + "/pg_service.conf");
    if (!f.open(QIODevice::WriteOnly)) return "cannot write the service file";
    for (const QString& n : names) f.write(QString("[%1]\nhost=%2\nport=%3\nuser=rehearse\ndbname=%1\n\n").arg(n, dir.path()).arg(port).toUtf8());
    f.close();
    if (root) QProcess::execute("chmod", {"a+r", f.fileName()});
    qputenv("PGSERVICEFILE", f.fileName().toUtf8());
    return {};
  }
  ~PgServer() {
    if (started) run("pg_ctl", {"-D", dir.path() + "/data", "-m", "immediate", "-w", "stop"});
  }
};

constexpr int kFiles = 5, kPerFile = 10, kSteps = 200;
const char* const kTrainees[kFiles] = {"Ada", "Ben", "Cleo", "Dev", "Eun"};

// The pull of session k (m): 4 to 13 mm, along -z.
Eigen::Vector3d pullOf(int k) { return Eigen::Vector3d(0, 0, -0.004 - 0.0001 * k); }

// Records one session in process: a 40 x 10 x 10 mm block fixed at x = 0, a grasp at its free end pulled by
// pullOf(k) over 30 steps, released; 200 steps.
void recordSession(const std::string& file, int k, const std::string& trainee) {
  simcore::BodySetup s;
  s.mesh = boxMesh(0.04, 0.01, 0.01, 8, 2, 2);
  s.fixedNodes = nodesAtX(s.mesh, 0.0);
  s.material.young = 5e4;
  s.material.poisson = 0.45;
  s.settings.gravity.setZero();
  s.tools.graspRadius = 0.003;
  s.tools.maxGraspForce = 1e6;
  app::Recorder rec(file, {trainee, "block", "v1", "test", "", ""}, s, 10, 20);
  simcore::Session session(s);
  session.setStepHook([&rec](const simcore::StepRecord& r) { rec.afterStep(r); });
  const Eigen::Vector3d tip(0.04, 0.005, 0.005);
  auto at = [](simcore::InputEvent e, long step) {
    e.step = step;
    return e;
  };
  session.post(at(rehearse::testing::toolAt(tip), 10));
  session.post(at(rehearse::testing::jaws(true), 10));
  for (int j = 1; j <= 30; ++j) session.post(at(rehearse::testing::toolAt(tip + pullOf(k) * (j / 30.0)), 10 + j));
  session.post(at(rehearse::testing::jaws(false), 60));
  for (int j = 0; j < kSteps; ++j) session.advance();
  rec.finish(kSteps);
}

}  // namespace

class TestTraining : public QObject {
  Q_OBJECT
  std::unique_ptr<PgServer> server_;
  QTemporaryDir dir_;
  QStringList files_;

  QStringList publishArgs(const QString& service) {
    QStringList a{"publish"};
    a << files_ << "--service" << service;
    return a;
  }
  // Every session of the case files is in the database exactly once, with the same events and checksums.
  void compareWithFiles(const QString& service) {
    app::TrainingDatabase db(service.toStdString());
    const auto published = db.sessions();
    QCOMPARE(static_cast<int>(published.size()), kFiles * kPerFile);
    std::set<std::string> uids;
    for (const auto& p : published) uids.insert(p.uid);
    QCOMPARE(static_cast<int>(uids.size()), kFiles * kPerFile);
    for (const QString& f : files_)
      for (const auto& s : app::listRecordings(f.toStdString())) {
        const std::string uid = app::sessionUid(app::loadRecordingRows(f.toStdString(), s.id), s);
        const auto it = std::find_if(published.begin(), published.end(), [&](const app::PublishedSession& p) { return p.uid == uid; });
        QVERIFY2(it != published.end(), qPrintable(f + " session " + QString::number(s.id) + " is missing"));
        const app::Recording fromFile = app::loadRecording(f.toStdString(), s.id), fromDb = db.load(it->id);
        QVERIFY(fromDb.checksums == fromFile.checksums);
        QVERIFY(fromDb.events == fromFile.events);
        QCOMPARE(fromDb.checkpointSteps, fromFile.checkpointSteps);
      }
  }

 private slots:
  void initTestCase() {
    forgetEarlierRuns();
    server_ = std::make_unique<PgServer>();
    const QString e = server_->start({"training", "twin"});
    // The set-up installs the server: its absence is a failure of the run, never a suite that quietly shrinks.
    if (e == "absent") QFAIL("PostgreSQL's server binaries are absent (/usr/lib/postgresql/*/bin); run scripts/install-deps.sh, which installs postgresql");
    QVERIFY2(e.isEmpty(), qPrintable(e));
    for (int f = 0; f < kFiles; ++f) {
      files_ << dir_.path() + QString("/case%1.rehearse").arg(f);
      for (int k = 0; k < kPerFile; ++k) recordSession(files_.back().toStdString(), f * kPerFile + k, kTrainees[(f + k) % kFiles]);
    }
  }

  // Killed mid-way, then run again: whole sessions only, each exactly once, identical to the files.
  void killedPublishResumes() {
    QProcess p;
    p.start(QStringLiteral(REHEARSE_BINARY), publishArgs("training"));
    QVERIFY(p.waitForStarted());
    int seen = 0;
    QElapsedTimer t;
    t.start();
    while (p.state() != QProcess::NotRunning && t.elapsed() < 120000) {
      QSqlDatabase db = QSqlDatabase::addDatabase("QPSQL", "probe");
      db.setConnectOptions("service=training");
      if (db.open()) {
        QSqlQuery q("SELECT COUNT(*) FROM rehearse_sessions", db);
        if (q.next()) seen = q.value(0).toInt();
        db.close();
      }
      db = QSqlDatabase();
      QSqlDatabase::removeDatabase("probe");
      if (seen >= 8) break;
      QTest::qWait(5);
    }
    QVERIFY2(p.state() != QProcess::NotRunning, qPrintable(QString("the publisher finished before it could be killed (%1 sessions seen): ").arg(seen) +
                                                            QString::fromUtf8(p.readAllStandardError())));
    p.kill();  // SIGKILL
    p.waitForFinished();
    {
      app::TrainingDatabase db("training");
      const auto published = db.sessions();
      QVERIFY(!published.empty() && static_cast<int>(published.size()) < kFiles * kPerFile);
      // Whole sessions only: each has all its events and checksums (200 steps: 20 checksums; 33 events posted:
      // the tool placed, the jaws closed, 30 moves, the jaws opened; the synchronous refresh records no others).
      for (const auto& s : published) {
        const app::Recording r = db.load(s.id);
        QCOMPARE(static_cast<int>(r.checksums.size()), kSteps / 10);
        QCOMPARE(static_cast<int>(r.events.size()), 33);
      }
      qInfo("killed after %d sessions were seen; %zu whole sessions in the database", seen, published.size());
    }
    const ::testing::Run again = ::testing::run(publishArgs("training"));
    QVERIFY2(again.code == 0, qPrintable(again.err));
    QVERIFY2(again.err.isEmpty(), qPrintable(again.err));
    qInfo("%s", qPrintable(again.out.trimmed().replace('\n', " / ")));
    compareWithFiles("training");
    // And once more: nothing new.
    const ::testing::Run third = ::testing::run(publishArgs("training"));
    QCOMPARE(third.code, 0);
    QCOMPARE(third.out.count(" 0 published, 10 already there"), kFiles);
  }

  // Two publishers at once on the same sessions: no duplicate, no error.
  void twoPublishersAtOnce() {
    QProcess a, b;
    a.start(QStringLiteral(REHEARSE_BINARY), publishArgs("twin"));
    b.start(QStringLiteral(REHEARSE_BINARY), publishArgs("twin"));
    QVERIFY(a.waitForFinished(300000) && b.waitForFinished(300000));
    const QString outA = QString::fromUtf8(a.readAllStandardOutput()), outB = QString::fromUtf8(b.readAllStandardOutput());
    QVERIFY2(a.exitCode() == 0 && b.exitCode() == 0, qPrintable(QString::fromUtf8(a.readAllStandardError() + b.readAllStandardError())));
    QVERIFY(a.readAllStandardError().isEmpty() && b.readAllStandardError().isEmpty());
    int published = 0, already = 0;
    for (const QString& out : {outA, outB})
      for (const QString& line : out.split('\n')) {
        const QRegularExpressionMatch m = QRegularExpression(R"(: (\d+) published, (\d+) already there)").match(line);
        if (m.hasMatch()) published += m.captured(1).toInt(), already += m.captured(2).toInt();
      }
    qInfo("two publishers: %d sessions written, %d found written by the other", published, already);
    QCOMPARE(published, kFiles * kPerFile);
    QCOMPARE(already, kFiles * kPerFile);
    compareWithFiles("twin");
  }

  // A session from the database replays and verifies like one from a case file; its metrics are the script's.
  void sessionFromTheDatabaseReplays() {
    app::TrainingDatabase db("training");
    const auto published = db.sessions();
    QVERIFY(!published.empty());
    const auto& s = published[published.size() / 2];
    const ::testing::Run v = ::testing::run({"replay", "postgresql:training", "--session", QString::number(s.id), "--verify", "--metrics", dir_.path() + "/m.json"});
    QVERIFY2(v.code == 0, qPrintable(v.out + v.err));
    QVERIFY2(v.out.contains("all 20 checksums match"), qPrintable(v.out));
    const ::testing::Run list = ::testing::run({"replay", "postgresql:training"});
    QCOMPARE(list.code, 0);
    QCOMPARE(list.out.count("session "), kFiles * kPerFile);
    // Which pull it was: the session's place in its file (trainee (f + k) % 5 of file f, k-th).
    QFile m(dir_.path() + "/m.json");
    QVERIFY(m.open(QIODevice::ReadOnly));
    const double path = QJsonDocument::fromJson(m.readAll()).object().value("path_length_m").toDouble();
    bool matched = false;
    for (int k = 0; k < kFiles * kPerFile; ++k) matched |= std::abs(path - pullOf(k).norm()) < 1e-9;
    QVERIFY2(matched, qPrintable(QString("path %1 m is none of the scripted pulls").arg(path, 0, 'g', 12)));
    // Seeking through the database's checkpoints lands on the straight replay.
    const app::Recording r = db.load(s.id);
    const std::vector<std::uint64_t> straight = rehearse::testing::straightChecksums(r);
    app::Replayer replayer(r);
    for (long target : {150L, 45L, 199L, 3L, 120L}) {
      replayer.seek(target);
      QVERIFY(app::stateChecksum(replayer.state()) == straight[static_cast<std::size_t>(target)]);
    }
    QVERIFY(replayer.lastSeekFrom() > 0);
  }

  // The cohort view: 5 trainees, 10 attempts each, the path length of each attempt plotted.
  void cohortView() {
    auto db = std::make_shared<app::TrainingDatabase>("training");
    ui::CohortWindow w(db);
    w.resize(1400, 850);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    QStringList names = w.trainees();
    names.sort();
    QCOMPARE(names, QStringList({"Ada", "Ben", "Cleo", "Dev", "Eun"}));
    QCOMPARE(w.sessionRows(), kFiles * kPerFile);
    w.setMetric("path_length_m");
    std::multiset<long> plotted, scripted;
    for (const auto& [name, values] : w.curves()) {
      QCOMPARE(static_cast<int>(values.size()), kPerFile);
      for (double v : values) plotted.insert(std::lround(v * 1e7));
    }
    for (int k = 0; k < kFiles * kPerFile; ++k) scripted.insert(std::lround(pullOf(k).norm() * 1e7));
    QVERIFY(plotted == scripted);
    // The incorrect actions are published with each session: the scripted pulls break none of the default rules.
    w.setMetric("incorrect_actions");
    int sessions = 0;
    for (const auto& [name, values] : w.curves())
      for (double v : values) {
        QCOMPARE(v, 0.0);
        ++sessions;
      }
    QCOMPARE(sessions, kFiles * kPerFile);
    w.setMetric("path_length_m");
    w.selectTrainee("Cleo");
    QCOMPARE(w.sessionRows(), kPerFile);
    QCOMPARE(static_cast<int>(w.curves().size()), 1);
    w.selectTrainee({});
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty()) {
      QTest::qWait(100);
      w.grab().save(QString::fromLocal8Bit(dir) + "/cohort.png");
    }
    // A session opens in the review window from the database.
    ui::ReviewWindow* review = w.openSession(db->sessions().front().id);
    QVERIFY(review);
    QElapsedTimer t;
    t.start();
    while (!review->ready(0) && t.elapsed() < 60000) QTest::qWait(10);
    QVERIFY(review->ready(0));
    review->seekTime(0.5);
    QVERIFY(landsOn(review, 0, 50L));
    review->close();
  }

  void cleanupTestCase() { server_.reset(); }
};

QTEST_MAIN(TestTraining)
#include "test_training.moc"
