// Hostile and absurd inputs to the command line (issue 60), each as a file a user or another machine could hand the
// program: JSON nested 100,000 deep, a FIFO where a file goes, settings inside the old ranges that never end, a
// recording whose step count says 10^12, a setup edited under its hash, a case folder's damaged ligaments, an
// appearance of 10^308, a contour of 400,000 points, a VTU whose blocks claim gigabytes. Each is refused with one
// sentence and an exit code in 1-123: no signal, no hang (every run here is bounded at 60 s), no memory past 8 GiB (each
// run's data is limited to that), never accepted silently.
#include "cli_run.hpp"
#include "gesture_args.hpp"
#include "test_support.hpp"

#include <rehearse/app/recording.hpp>
#include <rehearse/imaging/contour.hpp>

#include <QDir>
#include <QElapsedTimer>
#include <QFile>
#include <QTemporaryDir>
#include <QtTest>

#include <sqlite3.h>
#include <sys/stat.h>

#include <cmath>
#include <string>

using namespace rehearse;

namespace {
using ::testing::Run;

constexpr int kLimitMs = 60000;

// A refusal: an exit code in 1..123, a single line on stderr holding `fragment`, within the limit.
void expectRefused(const QStringList& args, const QString& fragment, const char* what) {
  QElapsedTimer t;
  t.start();
  const Run r = ::testing::run(args, kLimitMs, nullptr, /*boundMemory=*/true);
  const qint64 ms = t.elapsed();
  qInfo("%s: exit %d after %lld ms: %s", what, r.code, static_cast<long long>(ms), qPrintable(r.err.trimmed()));
  QVERIFY2(r.code >= 1 && r.code <= 123, qPrintable(QString("%1: exit %2 (-1: a signal or no end within 60 s) %3")
                                                        .arg(what)
                                                        .arg(r.code)
                                                        .arg(r.err.right(400))));
  QVERIFY2(ms < kLimitMs, what);
  QVERIFY2(r.err.trimmed().count('\n') == 0, qPrintable(QString("%1: %2").arg(what, r.err)));
  QVERIFY2(r.err.contains(fragment), qPrintable(QString("%1: %2").arg(what, r.err)));
}

void write(const QString& path, const QByteArray& bytes) {
  QFile f(path);
  QVERIFY(f.open(QIODevice::WriteOnly | QIODevice::Truncate));
  QCOMPARE(f.write(bytes), static_cast<qint64>(bytes.size()));
}

QByteArray nested(int depth, const QByteArray& inner = "1") {
  return QByteArray(depth, '[') + inner + QByteArray(depth, ']');
}

QByteArray scene(const QString& meshFile, const QByteArray& extra) {
  return "{\"components\": [{\"type\": \"mesh\", \"file\": \"" + meshFile.toUtf8() + "\"}" + extra + "]}";
}

int execSql(const QString& file, const std::string& sql) {
  sqlite3* db = nullptr;
  if (sqlite3_open(file.toUtf8().constData(), &db) != SQLITE_OK) return -1;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr);
  const int changed = sqlite3_changes(db);
  sqlite3_close(db);
  return rc == SQLITE_OK ? changed : -1;
}

}  // namespace

class TestHostileInputs : public QObject {
  Q_OBJECT
  QTemporaryDir dir_;
  QString caseDir_;

 private slots:
  void initTestCase() {
    QVERIFY(dir_.isValid());
    caseDir_ = dir_.path() + "/case";
    const Run r = ::testing::run({"phantom", "--out", caseDir_});
    QVERIFY2(r.code == 0, qPrintable(r.err));
  }

  // The memory bound the runs here are under holds in the child: the shell a QProcess starts under it reports 8 GiB
  // (`ulimit -d`, in KiB), and a child that asks for more than that is refused memory.
  void runsAreBoundedInMemory() {
    QProcess p;
    p.setChildProcessModifier(::testing::limitChildMemory);
    p.start("/bin/sh", {"-c", "ulimit -d"});
    QVERIFY(p.waitForFinished(10000));
    QCOMPARE(QString::fromUtf8(p.readAllStandardOutput()).trimmed(), QString::number(8 * 1024 * 1024));
    // dd with a 9 GiB block asks for it at once: without the bound it copies one block and exits 0.
    QProcess q;
    q.setChildProcessModifier(::testing::limitChildMemory);
    q.start("/bin/dd", {"if=/dev/zero", "of=/dev/null", "bs=9G", "count=1"});
    QVERIFY(q.waitForFinished(30000));
    const QString said = QString::fromUtf8(q.readAllStandardError());
    QVERIFY2(q.exitCode() != 0 && said.contains("memory"), qPrintable(said));
  }

  // JSON nested deeper than any file of ours (the gesture script's incorrect actions 100,000 deep crashed the JSON
  // library's recursive printing with SIGSEGV), in every JSON input of the command line.
  void deeplyNestedJsonIsRefused() {
    const QString gesture = dir_.path() + "/deep-gesture.json";
    write(gesture, "{\"format\": \"rehearse-gesture\", \"duration\": 0.1, \"incorrect_actions\": " +
                       nested(100000, "{}") + "}");
    expectRefused({"gesture", "--preset", "liver", "--script", gesture, "--out", dir_.path() + "/o.vtu"},
                  "nested more than 64 levels deep", "gesture script 100,000 deep");
    const QString sceneFile = dir_.path() + "/deep-scene.json";
    write(sceneFile, scene(caseDir_ + "/organ.vtu", ", {\"type\": \"gravity\", \"vector\": " + nested(50000) + "}"));
    expectRefused({"simulate", "--scene", sceneFile, "--steps", "1", "--out", dir_.path() + "/o.vtu"},
                  "nested more than 64 levels deep", "scene 50,000 deep");
    const QString contour = dir_.path() + "/deep-contour.json";
    write(contour, "{\"segments\": " + nested(50000) + "}");
    expectRefused({"register", "--mesh", caseDir_ + "/organ.vtu", "--camera", caseDir_ + "/camera.yaml", "--contour",
                   contour, "--pose", caseDir_ + "/pose.json", "--out", dir_.path() + "/r.vtu"},
                  "nested more than 64 levels deep", "contour 50,000 deep");
  }

  // A FIFO where a file goes blocked the open forever: refused before it is opened.
  void pipesAreNotRead() {
    const QString fifo = dir_.path() + "/pipe.json";
    QCOMPARE(::mkfifo(fifo.toUtf8().constData(), 0600), 0);
    expectRefused({"gesture", "--preset", "liver", "--script", fifo, "--out", dir_.path() + "/o.vtu"},
                  "is not a regular file", "gesture script a FIFO");
    expectRefused({"simulate", "--scene", fifo, "--out", dir_.path() + "/o.vtu"}, "is not a regular file",
                  "scene a FIFO");
    expectRefused({"register", "--mesh", caseDir_ + "/organ.vtu", "--camera", caseDir_ + "/camera.yaml", "--contour",
                   fifo, "--pose", caseDir_ + "/pose.json", "--out", dir_.path() + "/r.vtu"},
                  "is not a regular file", "contour a FIFO");
    expectRefused({"compose", "--case", caseDir_, "--pose", caseDir_ + "/pose.json", "--theta", fifo, "--out",
                   dir_.path() + "/j.png"},
                  "is not a regular file", "appearance a FIFO");
    // A recording: SQLite's open blocked on it (a user's check found `replay` hung until killed).
    const QString recordingFifo = dir_.path() + "/pipe.rehearse";
    QCOMPARE(::mkfifo(recordingFifo.toUtf8().constData(), 0600), 0);
    expectRefused({"replay", recordingFifo, "--session", "1", "--verify"}, "is not a regular file",
                  "recording a FIFO");
    expectRefused({"replay", fifo}, "is not a regular file", "recording a FIFO named .json");
  }

  // Values the old ranges let through and that never end (or make no sense): each refused with its range.
  void settingsThatNeverEndAreRefused() {
    const QString mesh = caseDir_ + "/organ.vtu";
    struct Case {
      const char* what;
      QByteArray components;
      QString fragment;
    };
    const std::vector<Case> cases = {
        {"steps 1e12", ", {\"type\": \"implicit_euler\", \"steps\": 1e12}", "whole number in [1, 1000000]"},
        {"tolerance 1e-300, 10,000 iterations",
         ", {\"type\": \"implicit_euler\", \"tolerance\": 1e-300, \"newton_iterations\": 10000}",
         "whole number in [1, 200]"},
        {"tolerance 1e-300", ", {\"type\": \"implicit_euler\", \"tolerance\": 1e-300}", "the tolerance 1e-300"},
        {"tolerance -1", ", {\"type\": \"implicit_euler\", \"tolerance\": -1}", "the tolerance -1"},
        {"newton_iterations -5", ", {\"type\": \"implicit_euler\", \"newton_iterations\": -5}",
         "whole number in [1, 200]"},
        {"negative damping", ", {\"type\": \"damping\", \"rayleigh_mass\": -0.1}", "the damping"},
        {"Poisson 0.4999999999", ", {\"type\": \"material\", \"poisson\": 0.4999999999}", "Poisson ratio"},
        {"dt 1e-9 over an hour", ", {\"type\": \"implicit_euler\", \"dt\": 1e-9, \"steps\": 1000000}",
         "the time step 1e-09 s"},
    };
    for (const Case& c : cases) {
      const QString file = dir_.path() + "/scene-" + QString::number(qHash(QByteArray(c.what))) + ".json";
      write(file, scene(mesh, c.components));
      expectRefused({"simulate", "--scene", file, "--out", dir_.path() + "/o.vtu"}, c.fragment, c.what);
    }
    // The same through the command line's own flags.
    expectRefused({"simulate", "--preset", "liver", "--poisson", "0.4999999999", "--steps", "1", "--out",
                   dir_.path() + "/o.vtu"},
                  "Poisson ratio 0.4999999999 is outside [0, 0.4999]", "--poisson 0.4999999999");
    // A gesture script's time step: 1e-9 s over an hour (3.6e12 steps), 1e-300 s (lround overflowed to one step).
    for (const auto& [dt, fragment] : {std::pair{QByteArray("1e-9"), QString("below 1e-05 s")},
                                       std::pair{QByteArray("1e-300"), QString("below 1e-05 s")}}) {
      const QString file = dir_.path() + "/dt.json";
      write(file, "{\"format\": \"rehearse-gesture\", \"duration\": 3600, \"dt\": " + dt + ", \"events\": []}");
      expectRefused({"gesture", "--preset", "liver", "--script", file, "--out", dir_.path() + "/o.vtu"}, fragment,
                    qPrintable("gesture dt " + dt));
    }
  }

  // A recording's step count, or a checksum row, at step 10^12 made --verify run forever; a setup text edited under
  // its hash was used as if it were the recorded one.
  void recordingsBeyondTheirLimitsAreRefused() {
    const QString file = dir_.path() + "/rec.rehearse";
    QVERIFY(::testing::tookEveryStep(::testing::run(gestureArgs(dir_.path(), "grasp-pull.json", file))));
    // A copy of the recording with one change made in SQL (empty when the change did not apply).
    auto variant = [&](const char* name, const std::string& sql, int leastChanged = 1) -> QString {
      const QString copy = dir_.path() + "/" + name + ".rehearse";
      QFile::remove(copy);
      if (!QFile::copy(file, copy) || execSql(copy, sql) < leastChanged) return {};
      return copy;
    };
    const QString steps = variant("steps", "UPDATE rehearsal_sessions SET steps = 1000000000000");
    const QString checksum =
        variant("checksum", "INSERT INTO rehearsal_checksums(session, step, checksum) VALUES(1, 1000000000000, '7')");
    QVERIFY(!steps.isEmpty() && !checksum.isEmpty());
    expectRefused({"replay", steps, "--session", "1", "--verify"}, "says it ran 1000000000000 steps", "steps 1e12");
    expectRefused({"replay", checksum, "--session", "1", "--verify"}, "says it ran 1000000000000 steps",
                  "a checksum at step 1e12");
    // A setup text edited (its Young's modulus doubled) under the hash it is stored by: the checkpoints that name it
    // are damaged, said with their steps, exit 4.
    // Node 0 added to the ligaments of every stored setup: valid JSON, a valid node, another setup than its hash.
    const QString edited =
        variant("setup", "UPDATE rehearsal_setups SET setup = replace(setup, '\"fixedNodes\":[', '\"fixedNodes\":[0,')");
    QVERIFY(!edited.isEmpty());
    const Run v = ::testing::run({"replay", edited, "--session", "1", "--verify"}, kLimitMs);
    qInfo("edited setup: exit %d: %s", v.code, qPrintable(v.err.trimmed().split('\n').last()));
    QCOMPARE(v.code, 4);
    QVERIFY2(v.err.contains("is not the one its hash says"), qPrintable(v.err));
    // A sessions table without its key holding one session twice (another program's file): refused, not mixed.
    const QString twice = variant("twice",
                                  "CREATE TABLE copy AS SELECT * FROM rehearsal_sessions; DROP TABLE rehearsal_sessions; "
                                  "CREATE TABLE rehearsal_sessions AS SELECT * FROM copy UNION ALL SELECT * FROM copy; "
                                  "DROP TABLE copy",
                                  0);
    QVERIFY(!twice.isEmpty());
    expectRefused({"replay", twice, "--session", "1", "--verify"}, "holds session 1 2 times", "a session held twice");
    // A checkpoint row whose setup column was changed (its bytes untouched): named, exit 4.
    const QString column = variant("column",
                                   "UPDATE rehearsal_checkpoints SET setup_hash = '3735928559' WHERE step = (SELECT "
                                   "MIN(step) FROM rehearsal_checkpoints)");
    QVERIFY(!column.isEmpty());
    const Run c = ::testing::run({"replay", column, "--session", "1", "--verify"}, kLimitMs);
    qInfo("changed setup column: exit %d: %s", c.code, qPrintable(c.err.trimmed().split('\n').first()));
    QCOMPARE(c.code, 4);
    QVERIFY2(c.err.contains("names another setup in its row than in its bytes"), qPrintable(c.err));
  }

  // `gesture --case` with a damaged, missing or out-of-range attachments.json dropped the ligaments and exited 0 (an
  // index of 2^40 was truncated to a valid node): refused, naming what is wrong.
  void caseAttachmentsAreNeverDropped() {
    const QString script = QStringLiteral(REHEARSE_SOURCE_DIR) + "/resources/gestures/grasp-pull.json";
    struct Case {
      const char* what;
      QByteArray content;  // empty: the file removed
      QString fragment;
    };
    const std::vector<Case> cases = {
        {"missing", "", "does not exist"},
        {"damaged", "{\"nodes\": [1, 2", "is not a {\"nodes\": [...]} list"},
        {"out of range", "{\"nodes\": [1, 99999999]}", "names node 99999999"},
        {"2^40", "{\"nodes\": [1, 1099511627776]}", "names node 1099511627776"},
        {"not whole", "{\"nodes\": [1, 2.5]}", "not a whole number"},
    };
    for (const Case& c : cases) {
      const QString copy = dir_.path() + "/case-" + QString::number(qHash(QByteArray(c.what)));
      QDir().mkpath(copy);
      for (const QString& f : QDir(caseDir_).entryList(QDir::Files)) QFile::copy(caseDir_ + "/" + f, copy + "/" + f);
      QFile::remove(copy + "/attachments.json");
      if (!c.content.isEmpty()) write(copy + "/attachments.json", c.content);
      expectRefused({"gesture", "--case", copy, "--script", script, "--out", dir_.path() + "/o.vtu"},
                    "Attachments not loaded", c.what);
      const Run r = ::testing::run({"gesture", "--case", copy, "--script", script, "--out", dir_.path() + "/o.vtu"});
      QVERIFY2(r.err.contains(c.fragment), qPrintable(QString("%1: %2").arg(c.what, r.err)));
    }
  }

  // An appearance of k_d -1 or k_s 1e308 was accepted: refused with the ranges.
  void appearanceOutOfRangeIsRefused() {
    for (const auto& [what, body] :
         {std::pair{"kd -1", QByteArray("\"kd\": [-1, 0.5, 0.5], \"ks\": [0.1, 0.1, 0.1]")},
          std::pair{"ks 1e308", QByteArray("\"kd\": [0.5, 0.5, 0.5], \"ks\": [1e308, 0.1, 0.1]")}}) {
      const QString theta = dir_.path() + "/theta.json";
      write(theta, "{\"light_position\": [0, 0, 0], " + body + ", \"roughness\": 0.3}");
      expectRefused({"compose", "--case", caseDir_, "--pose", caseDir_ + "/pose.json", "--theta", theta, "--out",
                     dir_.path() + "/j.png"},
                    "k_d and k_s must be between 0 and 100", what);
    }
    // A fit's verdict out of range or of the wrong kind, and a file cut short (issue 65): each its own sentence.
    const QByteArray values = "\"light_position\": [0, 0, 0], \"kd\": [0.5, 0.5, 0.5], \"ks\": [0.1, 0.1, 0.1], "
                              "\"roughness\": 0.3";
    for (const auto& [what, text, said] :
         {std::tuple{"explained 2", "{" + values + ", \"fit\": {\"explained\": 2, \"reshade\": true}}",
                     "explained share must be between 0 and 1"},
          std::tuple{"reshade a word", "{" + values + ", \"fit\": {\"explained\": 0.4, \"reshade\": \"no\"}}",
                     "the fit's \"reshade\" must be true or false"},
          std::tuple{"explained a word", "{" + values + ", \"fit\": {\"explained\": \"abc\", \"reshade\": true}}",
                     "\"explained\" must be the share of the shading the fit explained"},
          std::tuple{"fit a number", "{" + values + ", \"fit\": 7}", "\"fit\" must be what a fit said of itself"},
          std::tuple{"kd two numbers", QByteArray("{\"light_position\": [0, 0, 0], \"kd\": [0.5, 0.5], \"ks\": [0.1, 0.1, 0.1], \"roughness\": 0.3}"),
                     "\"kd\" must be three numbers"},
          std::tuple{"no roughness", QByteArray("{\"light_position\": [0, 0, 0], \"kd\": [0.5, 0.5, 0.5], \"ks\": [0.1, 0.1, 0.1]}"),
                     "\"roughness\" must be a number"},
          std::tuple{"an array", QByteArray("[1, 2, 3]"), "is not an appearance file"},
          std::tuple{"cut short", "{" + values + ", \"fit\": {\"expl", "is not valid JSON"}}) {
      const QString theta = dir_.path() + "/theta.json";
      write(theta, text);
      expectRefused({"compose", "--case", caseDir_, "--pose", caseDir_ + "/pose.json", "--theta", theta, "--out",
                     dir_.path() + "/j.png"},
                    said, what);
    }
  }

  // A contour of 400,000 points (the self-intersection test was quadratic: it never ended): refused at once. The
  // bucketed test gives the pairwise test's answers (a circle does not cross itself; a figure eight does).
  void contoursAreBounded() {
    QByteArray points;
    points.reserve(400000 * 24);
    for (int i = 0; i < 400000; ++i) {
      const double a = 2 * M_PI * i / 400000.0;
      points += (i ? ", [" : "[") + QByteArray::number(500 + 300 * std::cos(a), 'f', 3) + ", " +
                QByteArray::number(400 + 300 * std::sin(a), 'f', 3) + "]";
    }
    const QString contour = dir_.path() + "/huge-contour.json";
    write(contour, "{\"image_size\": [1280, 1024], \"segments\": [{\"points\": [" + points + "], \"closed\": true}]}");
    expectRefused({"register", "--mesh", caseDir_ + "/organ.vtu", "--camera", caseDir_ + "/camera.yaml", "--contour",
                   contour, "--pose", caseDir_ + "/pose.json", "--out", dir_.path() + "/r.vtu"},
                  "an outline needs at most 20000", "contour of 400,000 points");
    for (const int n : {100, 20000}) {
      imaging::ContourSegment circle, eight;
      circle.closed = eight.closed = true;
      for (int i = 0; i < n; ++i) {
        const double a = 2 * M_PI * i / n;
        circle.points.emplace_back(std::cos(a), std::sin(a));
        eight.points.emplace_back(std::sin(a), std::sin(2 * a) / 2);  // crosses itself at the origin
      }
      QVERIFY(!imaging::segmentSelfIntersects(circle));
      QVERIFY(imaging::segmentSelfIntersects(eight));
    }
  }

  // A VTU whose compressed blocks claim 8 GB for 4 points (the blocks were decompressed whatever NumberOfPoints
  // said): refused before anything is expanded.
  void vtuBlocksBeyondThePieceAreRefused() {
    // Header (UInt64): 4 blocks of 2^31 - 1 bytes, each "compressed" into 2.1 MB (zlib's 1032:1 allows it).
    const std::uint64_t blocks = 4, blockSize = (std::uint64_t{1} << 31) - 1, csize = 2100000;
    QByteArray header;
    auto put = [&](std::uint64_t v) { header.append(reinterpret_cast<const char*>(&v), 8); };
    put(blocks);
    put(blockSize);
    put(blockSize);
    for (std::uint64_t b = 0; b < blocks; ++b) put(csize);
    const QByteArray data(static_cast<int>(blocks * csize), 'x');
    const QByteArray vtu =
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
        "header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\"><UnstructuredGrid><Piece NumberOfPoints=\"4\" "
        "NumberOfCells=\"1\"><Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"appended\" "
        "offset=\"0\"/></Points><Cells><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2 3"
        "</DataArray><DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">4</DataArray><DataArray "
        "type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray></Cells></Piece></UnstructuredGrid>"
        "<AppendedData encoding=\"raw\">_" +
        header + data + "</AppendedData></VTKFile>\n";
    const QString file = dir_.path() + "/bomb.vtu";
    write(file, vtu);
    expectRefused({"info", file}, "claims more data than the piece's points and cells declare", "VTU blocks of 8 GB");
  }
};

QTEST_GUILESS_MAIN(TestHostileInputs)
#include "test_hostile_inputs.moc"
