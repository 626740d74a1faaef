// Recorded rehearsals (issue 16), run as a user would: `rehearse gesture --record CASE` writes the session
// into a SQLite file as it runs; `rehearse replay CASE --session ID --verify` re-simulates it and compares
// every recorded state checksum; seeking, metrics and exports from the script. Damaged, hostile, tampered and killed
// recordings: test_recording_files. The suite's class is in test_recording.hpp; its later slots (checkpoints, settings,
// exports, sessions) are in test_recording_sessions.cpp.
#include "test_recording.hpp"

#include "box_mesh.hpp"
#include "cli_run.hpp"
#include "gesture_args.hpp"
#include "replay_checks.hpp"
#include "session_inputs.hpp"

#include <rehearse/app/recording.hpp>
#include <rehearse/simcore/numerics.hpp>

#include <QDir>
#include <QFile>
#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QElapsedTimer>
#include <QProcess>
#include <QTemporaryDir>
#include <QtTest>

#include <rehearse/app/review.hpp>

#include <QJsonArray>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <sqlite3.h>

#include <nlohmann/json.hpp>

#include <functional>
#include <random>

using namespace rehearse;

namespace {
using ::testing::Run;
using ::testing::run;
}  // namespace

void TestRecording::initTestCase() {
  QStandardPaths::setTestModeEnabled(true);
}

// Issue 33 (the house move, behaviour unchanged): a recording made before the move (grasp-pull-cut.json on the liver
// preset, linearised, by the build of commit cda3aaf, before instruments, contact and topology changes moved; kept as
// a test asset) replays after it with every checksum equal, its metrics from the replay.
void TestRecording::recordingFromBeforeTheMoveVerifies() {
  QTemporaryDir dir;
  const QString file = dir.path() + "/before.rehearse";
  QVERIFY(QFile::copy(
      QStringLiteral(REHEARSE_SOURCE_DIR) + "/tests/resources/recordings/grasp-pull-cut-before-house-move.rehearse",
      file));
  const Run r = run({"replay", file, "--session", "1", "--verify", "--metrics", dir.path() + "/m.json"});
  QVERIFY2(r.code == 0, qPrintable(r.out + r.err));
  QVERIFY2(r.out.contains("verified: 360 steps replayed, all 36 checksums match"), qPrintable(r.out));
  QFile mf(dir.path() + "/m.json");
  QVERIFY(mf.open(QIODevice::ReadOnly));
  const QJsonObject m = QJsonDocument::fromJson(mf.readAll()).object();
  QCOMPARE(m["grasps"].toInt(), 1);
  QVERIFY(m["cut_updates"].toInt() > 0);
  QCOMPARE(m["vessel_cuts"].toInt(), 1);
}

// Issue 60: a session recorded on one machine verifies on any other. The recording's process is told an OpenBLAS
// kernel set (OPENBLAS_CORETYPE, as some machines set it: this run's own, SkylakeX when unset; a processor's own choice
// is the same thing), and the replay
// runs under each of the kernel sets a machine here may choose or be told, unset, and with the reference BLAS as the
// machine's libblas.so.3 (what update-alternatives may select): every one verifies, since the program pins its
// kernels. The recording names what made it, and --verify says what replayed it.
namespace {
// Records grasp-pull under the kernel set this run was told and replays it under each named variant (all of them
// when `only` is empty): every one verifies and names the recording's kernel.
void recordHereAndReplayUnder(const QStringList& only) {
  QTemporaryDir dir;
  const QString file = dir.path() + "/case.rehearse";
  QProcessEnvironment recordEnv = QProcessEnvironment::systemEnvironment();
  // Recorded under the kernel set this run was told (ctest runs it under each), SkylakeX when none.
  recordEnv.insert("OPENBLAS_CORETYPE", qEnvironmentVariable("OPENBLAS_CORETYPE", "SkylakeX"));
  recordEnv.remove("GLIBC_TUNABLES");  // the recording process masks glibc's FMA itself
  recordEnv.remove("REHEARSE_LIBM_RESTARTED");
  const Run a = run(gestureArgs(dir.path(), "grasp-pull.json", file), 300000, &recordEnv);
  QVERIFY2(::testing::tookEveryStep(a), qPrintable(a.out + a.err));
  const auto rec = app::loadRecording(file.toStdString(), 1);
  const QString kernel = QString::fromStdString(rec.numerics.kernel);
  qInfo("recorded with: %s; built by: %s", qPrintable(kernel), rec.numerics.build.c_str());
  QVERIFY2(kernel.startsWith("CHOLMOD supernodal, OpenBLAS ") &&
               kernel.contains(QString(simcore::kPinnedBlasCore) + "; glibc ") && kernel.endsWith("libm without FMA"),
           qPrintable(kernel));
  QVERIFY2(QString::fromStdString(rec.numerics.build).contains("x86-64 baseline"), rec.numerics.build.c_str());
  const QString referenceBlas = "/usr/lib/x86_64-linux-gnu/blas", referenceLapack = "/usr/lib/x86_64-linux-gnu/lapack";
  QVERIFY2(QFile::exists(referenceBlas + "/libblas.so.3"),
           "the reference BLAS (Debian's libblas3, which scripts/install-deps.sh installs) is missing");
  struct Variant {
    QString name, core, libraryPath, tunables;
  };
  const std::vector<Variant> variants = {
      {"Prescott", "Prescott", "", ""},
      {"Haswell", "Haswell", "", ""},
      {"SkylakeX", "SkylakeX", "", ""},
      {"Zen", "Zen", "", ""},
      {"Cooperlake", "Cooperlake", "", ""},
      {"unset", "", "", ""},
      {"reference BLAS as libblas.so.3", "", referenceBlas + ":" + referenceLapack, ""},
      // A processor without AVX or FMA, as glibc sees it (its libm and string
      // functions choose their SSE2 versions).
      {"no AVX, no FMA", "Prescott", "", "glibc.cpu.hwcaps=-AVX2,-FMA,-FMA4,-AVX,-AVX512F,-AVX512VL"}};
  int replayed = 0;
  for (const Variant& v : variants) {
    if (!only.isEmpty() && !only.contains(v.name)) continue;
    ++replayed;
    QProcessEnvironment env = QProcessEnvironment::systemEnvironment();
    env.remove("OPENBLAS_CORETYPE");
    if (!v.core.isEmpty()) env.insert("OPENBLAS_CORETYPE", v.core);
    if (!v.libraryPath.isEmpty()) env.insert("LD_LIBRARY_PATH", v.libraryPath);
    env.remove("GLIBC_TUNABLES");  // what this test process was started with: each variant says its own
    env.remove("REHEARSE_LIBM_RESTARTED");
    if (!v.tunables.isEmpty()) env.insert("GLIBC_TUNABLES", v.tunables);
    const Run r = run({"replay", file, "--session", "1", "--verify"}, 300000, &env);
    qInfo("replayed under %s: exit %d, %s", qPrintable(v.name), r.code,
          qPrintable((r.out + r.err).trimmed().split('\n').mid(1).join(" | ")));
    QVERIFY2(r.code == 0, qPrintable(v.name + ": " + r.out + r.err));
    QVERIFY2(r.out.contains("kernel: " + kernel), qPrintable(v.name + ": " + r.out));
  }
  QCOMPARE(replayed, only.isEmpty() ? static_cast<int>(variants.size()) : static_cast<int>(only.size()));
}
}  // namespace

void TestRecording::aSessionVerifiesUnderEveryKernel() {
  recordHereAndReplayUnder({});
}

// The same under each kernel set ctest tells the suite (test_recording_<kernel>): recorded under it, replayed on the
// two machines least like it, a processor without AVX or FMA and the reference BLAS. (Every other pair is covered by
// the whole matrix above and by recordAndVerify, which records and replays under the told set. The suite's own entry,
// with no kernel set told, runs it too: about 7 s again of what the whole matrix covers.)
void TestRecording::aSessionRecordedUnderThisKernelVerifiesElsewhere() {
  recordHereAndReplayUnder({"no AVX, no FMA", "reference BLAS as libblas.so.3"});
}

// Issue 60: a replay that cannot reproduce its recording says which differs. A session recorded in-process on another
// kernel set (one this processor runs: selected for the test, as a benchmark does) does not verify on the pinned one,
// and the replay check names both kernels, in the API and on the command line.
void TestRecording::aReplayThatDiffersNamesTheKernels() {
  const char* other = nullptr;
  for (const char* core : {"SkylakeX", "Haswell", "Zen"})
    if (!other && simcore::selectBlasCore(core)) other = core;
  if (!other) {
    QVERIFY(simcore::pinBlasKernel());
    QSKIP("this processor has neither AVX2 nor AVX-512: no other OpenBLAS kernel set to record with");
  }
  const std::string otherKernel = simcore::linearSolveKernel(false);
  QTemporaryDir dir;
  const QString file = dir.path() + "/kernel.rehearse";
  {
    simcore::Session session(rehearse::testing::presetBody("liver"));
    app::SessionMeta meta;
    meta.trainee = "K. Ernel";
    meta.appVersion = "0.1.0";
    app::Recorder recorder(file.toStdString(), meta, session.setup());
    session.setStepHook([&](const simcore::StepRecord& r) { recorder.afterStep(r); });
    for (int k = 0; k < 40; ++k) session.advance();
    recorder.finish(40);
  }
  QVERIFY(simcore::pinBlasKernel());
  const auto rec = app::loadRecording(file.toStdString(), 1);
  QCOMPARE(rec.numerics.kernel, otherKernel);
  const app::VerifyResult v = app::replayRecording(rec).verify;
  const std::string pinnedKernel = simcore::linearSolveKernel(false);
  const QString sentence = QString::fromStdString(app::replayCheckSentence(v));
  qInfo("%s", qPrintable(sentence));
  QVERIFY2(v.mismatches > 0, "the kernel sets gave the same bits: this test shows nothing here");
  const QString both =
      QString::fromStdString("recorded with kernel " + otherKernel + ", replayed with " + pinnedKernel);
  QVERIFY2(sentence.startsWith("DOES NOT VERIFY") && sentence.contains(both), qPrintable(sentence));
  const Run r = run({"replay", file, "--session", "1", "--verify"});
  QCOMPARE(r.code, 4);
  QCOMPARE(r.err.trimmed().count('\n'), 0);
  QVERIFY2(r.err.contains(both), qPrintable(r.err));
}

// Two sessions into one file (grasp-pull, then cut-across, both with the asynchronous refresh the GUI
// uses: the factor swaps and cuts applied by the second thread are recorded events); both verify.
void TestRecording::recordAndVerify() {
  QTemporaryDir dir;
  const QString file = dir.path() + "/case.rehearse";
  const Run a = run(gestureArgs(dir.path(), "grasp-pull.json", file));
  QVERIFY2(::testing::tookEveryStep(a), qPrintable(a.out + a.err));
  QVERIFY2(a.out.contains("recorded: session 1"), qPrintable(a.out));
  const Run b = run(gestureArgs(dir.path(), "cut-across.json", file));
  QVERIFY2(::testing::tookEveryStep(b), qPrintable(b.out + b.err));
  QVERIFY2(b.out.contains("recorded: session 2"), qPrintable(b.out));
  const Run list = run({"replay", file});
  QCOMPARE(list.code, 0);
  QVERIFY2(list.out.contains("session 1") && list.out.contains("session 2") && list.out.contains("A. Trainee"),
           qPrintable(list.out));
  QVERIFY(!list.out.contains("cut short"));
  for (const char* id : {"1", "2"}) {
    const auto rec = app::loadRecording(file.toStdString(), std::stoll(id));
    long factors = 0, cuts = 0;
    for (const auto& e : rec.events) {
      factors += e.kind == simcore::InputKind::Factor;
      cuts += e.kind == simcore::InputKind::CutApplied;
    }
    const Run v = run({"replay", file, "--session", id, "--verify"});
    qInfo("session %s: %zu events (%ld factor swaps, %ld cuts applied), %zu checksums over %ld steps: %s", id,
          rec.events.size(), factors, cuts, rec.checksums.size(), rec.summary.steps,
          qPrintable(v.out.trimmed().split('\n').last()));
    QVERIFY2(v.code == 0, qPrintable(v.err));
    QCOMPARE(static_cast<long>(rec.checksums.size()), rec.summary.steps / 10);  // one every 10 steps
    QVERIFY(v.out.contains(QString("all %1 checksums match").arg(rec.checksums.size())));
    QVERIFY(rec.summary.complete);
    QCOMPARE(QString::fromStdString(rec.summary.meta.trainee), QStringLiteral("A. Trainee"));
  }
  // Issue 64: the pull's steps from 0.5 to 0.7 s against exact Newton's answer, one row each; the options it takes and
  // the ones it refuses, in one sentence each.
  const QString csv = dir.path() + "/exact.csv";
  const Run x = run({"replay", file, "--session", "1", "--exact-check", csv, "--from", "0.5", "--to", "0.7"});
  QVERIFY2(x.code == 0 || x.code == 4, qPrintable(x.out + x.err));
  QVERIFY2(x.out.contains("checked 21 of ") && x.out.contains("0 not resolved") &&
               x.out.contains("no accuracy asked"),
           qPrintable(x.out));
  QFile f(csv);
  QVERIFY(f.open(QIODevice::ReadOnly));
  const QStringList rows = QString::fromUtf8(f.readAll()).trimmed().split('\n');
  QCOMPARE(rows.size(), 22);  // the header and steps 50-70
  QVERIFY(rows[0].startsWith("step,time_s,events,outcome,ended_on_accuracy,residual,"));
  const int trueColumn = rows[0].split(',').indexOf("true_mm");
  QVERIFY(trueColumn > 0);
  for (int i = 1; i < rows.size(); ++i) {
    bool number = false;
    const double mm = rows[i].split(',').value(trueColumn).toDouble(&number);
    QVERIFY2(number && mm >= 0 && mm < 1, qPrintable(rows[i]));  // the linearised step: micrometres from the answer
  }
  for (const QStringList& refused :
       {QStringList{"--every", "5"}, QStringList{"--exact-check", csv, "--verify"},
        QStringList{"--exact-check", csv, "--every", "0"}, QStringList{"--exact-check", csv, "--from", "0.7", "--to", "0.5"}}) {
    const Run r = run(QStringList{"replay", file, "--session", "1"} + refused);
    QVERIFY2(r.code == 2 && r.err.trimmed().count('\n') == 0, qPrintable(refused.join(' ') + ": " + r.err));
  }
}

// Issue 36: two clips across the left lobe's vessel branch and the hook's cut between them (clip-clip-cut.json, with
// the chord method: the linearised one is refused under clips, and refused with a sentence), then
// the same cut without clips (cut-across.json), recorded the GUI's way: both verify bit for bit; the first cuts the
// vessel and loses no blood (its thresholds pass), the second loses blood at the stumps' rate (its threshold fails).
void TestRecording::clipsStopTheBleedingInARecordedSession() {
  QTemporaryDir dir;
  const QString file = dir.path() + "/case.rehearse";
  QStringList clipArgs = gestureArgs(dir.path(), "clip-clip-cut.json", file);
  clipArgs[clipArgs.indexOf("linearised")] = "chord";  // the clip applier refuses the linearised method
  const Run a = run(clipArgs);
  QVERIFY2(::testing::tookEveryStep(a), qPrintable(a.out + a.err));
  QVERIFY2(a.out.contains("2 clips (0 misplaced), 0.00 mL of blood lost"), qPrintable(a.out));
  const Run b = run(gestureArgs(dir.path(), "cut-across.json", file));
  QVERIFY2(::testing::tookEveryStep(b), qPrintable(b.out + b.err));
  {  // Under the linearised method the clips are refused, each with its sentence: no clip, the vessel cut, bleeding.
    QTemporaryDir other;
    QStringList args = gestureArgs(other.path(), "clip-clip-cut.json", other.path() + "/c.rehearse");
    args << "--report" << other.path() + "/r.json";
    const Run refused = run(args);
    QVERIFY2(refused.out.contains("0 clips"), qPrintable(refused.out));
    QFile rf(other.path() + "/r.json");
    QVERIFY(rf.open(QIODevice::ReadOnly));
    QVERIFY(QString::fromUtf8(rf.readAll()).contains("The clip was refused: the linearised method"));
  }
  QFile th(dir.path() + "/t.json");
  QVERIFY(th.open(QIODevice::WriteOnly));
  th.write(R"({"blood_loss_ml": {"max": 0}, "misplaced_clips": {"max": 0}})");
  th.close();
  QMap<QString, QJsonObject> metrics;
  for (const char* id : {"1", "2"}) {
    const QString out = dir.path() + "/m" + id + ".json";
    const Run r =
        run({"replay", file, "--session", id, "--verify", "--metrics", out, "--thresholds", dir.path() + "/t.json"});
    QVERIFY2(r.code == 0, qPrintable(r.out + r.err));
    QFile mf(out);
    QVERIFY(mf.open(QIODevice::ReadOnly));
    metrics[id] = QJsonDocument::fromJson(mf.readAll()).object();
  }
  const QJsonObject clipped = metrics["1"], open = metrics["2"];
  qInfo("clipped: %d clips, %d vessel cut(s), %.3f mL lost; unclipped: %d vessel cut(s), %.3f mL lost",
        clipped["clips"].toInt(), clipped["vessel_cuts"].toInt(), clipped["blood_loss_ml"].toDouble(),
        open["vessel_cuts"].toInt(), open["blood_loss_ml"].toDouble());
  QCOMPARE(clipped["clips"].toInt(), 2);
  QCOMPARE(clipped["misplaced_clips"].toInt(), 0);
  QVERIFY(clipped["vessel_cuts"].toInt() >= 1);
  QCOMPARE(clipped["blood_loss_ml"].toDouble(), 0.0);
  QCOMPARE(open["clips"].toInt(), 0);
  QVERIFY(open["vessel_cuts"].toInt() >= 1);
  QVERIFY(open["blood_loss_ml"].toDouble() > 0);
  auto verdicts = [](const QJsonObject& m) {
    QMap<QString, QString> v;
    for (const auto& x : m["verdicts"].toArray())
      v[x.toObject()["metric"].toString()] = x.toObject()["result"].toString();
    return v;
  };
  QCOMPARE(verdicts(clipped)["blood_loss_ml"], QStringLiteral("pass"));
  QCOMPARE(verdicts(open)["blood_loss_ml"], QStringLiteral("fail"));
  QCOMPARE(verdicts(clipped)["misplaced_clips"], QStringLiteral("pass"));
}

// Metrics of a scripted session against values computed by hand from the script (the grasper bites once
// and is moved by (4.16, 7.32, -18.14) mm in a straight line; 350 steps of 10 ms) and from the live run's own
// per-step report (forces: the same steps, replayed bit for bit, computed by other code).
void TestRecording::metricsMatchTheScriptAndTheLiveRun() {
  QTemporaryDir dir;
  const QString file = dir.path() + "/case.rehearse";
  QStringList args = gestureArgs(dir.path(), "grasp-pull.json", file);
  args << "--report" << dir.path() + "/live.json";
  QVERIFY(::testing::tookEveryStep(run(args)));
  const Run m =
      run({"replay", file, "--session", "1", "--metrics", dir.path() + "/metrics.json", "--force-threshold", "2"});
  QVERIFY2(m.code == 0, qPrintable(m.err));
  QFile mf(dir.path() + "/metrics.json"), lf(dir.path() + "/live.json");
  QVERIFY(mf.open(QIODevice::ReadOnly) && lf.open(QIODevice::ReadOnly));
  const QJsonObject metrics = QJsonDocument::fromJson(mf.readAll()).object();
  const QJsonArray rows = QJsonDocument::fromJson(lf.readAll()).object().value("steps").toArray();
  QCOMPARE(rows.size(), 350);
  double maxF = 0, sumF = 0, over = 0;
  int withForce = 0;
  for (const auto& row : rows) {
    const QJsonArray f = row.toObject().value("tool_force_n").toArray();
    const double n = std::sqrt(f[0].toDouble() * f[0].toDouble() + f[1].toDouble() * f[1].toDouble() +
                               f[2].toDouble() * f[2].toDouble());
    maxF = std::max(maxF, n);
    if (n > 0) {
      sumF += n;
      ++withForce;
    }
    if (n > 2.0) over += 0.01;
  }
  // The move is spread evenly over its 100 steps, the first of them the step the tip appears at (already
  // 1/100 along): from where it appears the tip travels 99/100 of the move.
  const double path = 0.99 * std::sqrt(0.00416 * 0.00416 + 0.00732 * 0.00732 + 0.01814 * 0.01814);
  qInfo(
      "metrics: duration %.3f s, path %.6f m (script %.6f), economy %.9f, grasps %d, slips %d, max force %.4f N "
      "(live %.4f), mean %.4f N (live %.4f), "
      "over 2 N %.2f s (live %.2f)",
      metrics["duration_s"].toDouble(), metrics["path_length_m"].toDouble(), path,
      metrics["economy_of_motion"].toDouble(), metrics["grasps"].toInt(), metrics["slips"].toInt(),
      metrics["max_force_n"].toDouble(), maxF, metrics["mean_force_n"].toDouble(), sumF / withForce,
      metrics["time_over_threshold_s"].toDouble(), over);
  QVERIFY(std::abs(metrics["duration_s"].toDouble() - 3.5) < 1e-12);
  QVERIFY(std::abs(metrics["path_length_m"].toDouble() - path) < 1e-9);
  QVERIFY(std::abs(metrics["economy_of_motion"].toDouble() - 1.0) < 1e-9);
  QCOMPARE(metrics["grasps"].toInt(), 1);
  QCOMPARE(metrics["slips"].toInt(), 0);
  QCOMPARE(metrics["cut_updates"].toInt(), 0);
  QVERIFY(maxF > 2.0 && over > 0);  // the threshold is crossed: the time over it is a real figure
  QVERIFY(std::abs(metrics["max_force_n"].toDouble() - maxF) <= 1e-9 * maxF);
  QVERIFY(std::abs(metrics["mean_force_n"].toDouble() - sumF / withForce) <= 1e-9 * maxF);
  QVERIFY(std::abs(metrics["time_over_threshold_s"].toDouble() - over) < 1e-9);
  // Across sessions: a second attempt (cut-across), then one CSV row per session, the first row the same
  // figures as the JSON above.
  QStringList cutArgs = gestureArgs(dir.path(), "cut-across.json", file);
  cutArgs << "--report" << dir.path() + "/live-cut.json";
  QVERIFY(::testing::tookEveryStep(run(cutArgs)));
  const Run c = run({"replay", file, "--metrics-csv", dir.path() + "/cohort.csv", "--force-threshold", "2"});
  QVERIFY2(c.code == 0, qPrintable(c.err));
  QFile cf(dir.path() + "/cohort.csv");
  QVERIFY(cf.open(QIODevice::ReadOnly));
  const QStringList lines = QString::fromUtf8(cf.readAll()).trimmed().split('\n');
  QCOMPARE(lines.size(), 3);
  const QStringList head = lines[0].split(','), first = lines[1].split(','), second = lines[2].split(',');
  auto col = [&](const QStringList& row, const char* name) { return row[head.indexOf(QLatin1String(name))]; };
  QCOMPARE(col(first, "session"), QStringLiteral("1"));
  QCOMPARE(col(first, "trainee"), QStringLiteral("\"A. Trainee\""));
  QCOMPARE(col(first, "path_length_m").toDouble(), metrics["path_length_m"].toDouble());
  QCOMPARE(col(first, "max_force_n").toDouble(), metrics["max_force_n"].toDouble());
  QCOMPARE(col(first, "time_over_threshold_s").toDouble(), metrics["time_over_threshold_s"].toDouble());
  QCOMPARE(col(first, "checksums").toInt(), 35);
  QCOMPARE(col(first, "checksums_differing").toInt(), 0);
  // How many cut updates the live run applied depends on when its second thread finished each (a loaded
  // machine may finish none before the session ends): the replay counts what the live run reported.
  QFile lc(dir.path() + "/live-cut.json");
  QVERIFY(lc.open(QIODevice::ReadOnly));
  QCOMPARE(col(second, "cut_updates").toInt(), QJsonDocument::fromJson(lc.readAll()).object()["cuts"].toInt());
  QCOMPARE(col(second, "checksums").toInt(), 25);
  QCOMPARE(col(second, "checksums_differing").toInt(), 0);
}

// Seeking: a session with a grasp, a pull and a cut (asynchronous refresh: factors requested and a cut body
// built on the second thread while it steps on) is recorded with checkpoints; ten seeks to random steps, in
// random order (backwards too), each land on the state of a straight replay, bit for bit (checksums of every
// step of the straight run, computed here).
// The review's replay reports as it goes (issue 62): after every step, in order, the samples so far (the whole
// replay's, sample for sample) and the checksums compared up to that step; a progress that returns false stops it.
void TestRecording::aReplayReportsItsProgressAndStops() {
  QTemporaryDir dir;
  const QString file = dir.path() + "/case.rehearse";
  QVERIFY(::testing::tookEveryStep(run(gestureArgs(dir.path(), "grasp-pull.json", file))));
  const app::Recording rec = app::loadRecording(file.toStdString(), 1);
  app::ReplayOptions plain;
  plain.timeline = true;
  const app::ReplayResult whole = app::replayRecording(rec, plain);
  QCOMPARE(static_cast<long>(whole.timeline.size()), rec.summary.steps);
  long calls = 0;
  bool inOrder = true, prefix = true, checkedSoFar = true;
  app::ReplayOptions watched = plain;
  watched.progress = [&](long step, long steps, const app::ReplayResult& soFar) {
    inOrder =
        inOrder && step == ++calls && steps == rec.summary.steps && static_cast<long>(soFar.timeline.size()) == step;
    const auto& s = soFar.timeline.back();
    const auto& w = whole.timeline[static_cast<std::size_t>(step - 1)];
    prefix = prefix && s.step == w.step && s.time == w.time && s.force == w.force && s.tip == w.tip;
    const long due = static_cast<long>(
        std::count_if(rec.checksums.begin(), rec.checksums.end(), [&](const auto& c) { return c.first <= step; }));
    checkedSoFar = checkedSoFar && soFar.verify.checked == due && soFar.verify.mismatches == 0;
    return true;
  };
  const app::ReplayResult reported = app::replayRecording(rec, watched);
  QCOMPARE(calls, rec.summary.steps);
  QVERIFY(inOrder && prefix && checkedSoFar);
  QCOMPARE(reported.verify.checked, whole.verify.checked);
  long stoppedAt = 0;
  app::ReplayOptions stopping = plain;
  stopping.progress = [&](long step, long, const app::ReplayResult&) {
    stoppedAt = step;
    return step < 100;
  };
  QVERIFY_THROWS_EXCEPTION(app::ReplayStopped, app::replayRecording(rec, stopping));
  QCOMPARE(stoppedAt, 100L);
}

void TestRecording::seekingLandsOnTheStraightRun() {
  QTemporaryDir dir;
  const QString file = dir.path() + "/case.rehearse";
  const Run a = run(gestureArgs(dir.path(), "grasp-pull-cut.json", file));
  QVERIFY2(::testing::tookEveryStep(a), qPrintable(a.out + a.err));
  const auto rec = app::loadRecording(file.toStdString(), 1);
  QVERIFY2(rec.checkpointSteps.size() >= 18, "a checkpoint every 20 steps of 360 and after each cut");
  // Some checkpoints hold a cut being built or a factor requested: what makes them complete is exercised.
  int withPendingCut = 0, withRequest = 0;
  for (long s : rec.checkpointSteps) {
    const simcore::Checkpoint c = app::loadCheckpoint(file.toStdString(), 1, s);
    QCOMPARE(c.step, s);
    withPendingCut += c.pendingChange.has_value();
    withRequest += c.state.lagged.requested;
  }
  const std::vector<std::uint64_t> straight = rehearse::testing::straightChecksums(rec);
  QCOMPARE(static_cast<long>(straight.size()), rec.summary.steps + 1);
  for (const auto& [step, sum] : rec.checksums)
    QCOMPARE(straight[static_cast<std::size_t>(step)], sum);  // the straight run is the recorded one
  app::Replayer replayer(rec);
  std::mt19937 rng(16);
  std::uniform_int_distribution<long> at(1, rec.summary.steps);
  int fromCheckpoints = 0;
  QString times;
  for (int k = 0; k < 10; ++k) {
    const long target = at(rng);
    QElapsedTimer t;
    t.start();
    replayer.seek(target);
    times += QString(" %1@%2").arg(t.elapsed()).arg(target);
    QCOMPARE(replayer.step(), target);
    fromCheckpoints += replayer.lastSeekFrom() > 0;
    QVERIFY2(app::stateChecksum(replayer.state()) == straight[static_cast<std::size_t>(target)],
             qPrintable(QString("seeking to step %1 (from %2) differs from the straight run")
                            .arg(target)
                            .arg(replayer.lastSeekFrom())));
  }
  qInfo(
      "%zu checkpoints (%d with a cut being built, %d with a factor requested); 10 seeks, %d from a checkpoint, "
      "ms@step:%s",
      rec.checkpointSteps.size(), withPendingCut, withRequest, fromCheckpoints, qPrintable(times));
  QVERIFY(fromCheckpoints >= 5);
  // Whether a checkpoint falls while a cut is built or a factor is requested depends on the live run's timing;
  // checkpointWithACutUnderWayIsComplete below makes both happen deterministically.
}

// A checkpoint taken while a cut's body is being built and a factor is requested (the deferred refresh, as a
// replay runs: both stay pending until the recorded CutApplied and Factor events) goes through its bytes and
// a new session continues from it exactly as the uninterrupted one, step for step.
// Traction held while the blade cuts (ToolSettings::jawsKeepTheirHold): the jaws (instrument 0) close on the block's
// free end and pull it 5 mm along its length; the blade (instrument 1) then stands through the block at x = 25 mm
// and is drawn across it, severing it, while the jaws hold. What the jaws hold stays where they put it (the
// constraint's targets do not follow the blade's tip); with the setting off (sessions recorded before it existed),
// the held nodes follow the blade as they used to. A checkpoint taken while the blade is away from the jaws
// continues bit for bit through the codec's bytes, and reading it as an older checkpoint (the jaws wherever the tip
// is) continues differently: the jaws' place is part of the state. The setting is in the recorded setup; a setup
// recorded before it existed reads as off.
void TestRecording::jawsKeepTheirHoldWhileTheBladeCuts() {
  const auto setupWith = [](bool keep) {
    simcore::BodySetup s;
    s.mesh = boxMesh(0.04, 0.01, 0.01, 8, 2, 2);
    s.fixedNodes = nodesAtX(s.mesh, 0.0);
    s.material.young = 2e4;
    s.settings.method = simcore::NewtonMethod::Exact;
    s.tools.bladeLength = 0.03;
    s.tools.trocar = Eigen::Vector3d(0.025, 0.005, -0.2);
    s.tools.cutLatencySteps = 0;
    s.tools.maxGraspForce = 1e3;  // no slip: where the jaws' targets are is the question
    s.tools.jawsKeepTheirHold = keep;
    return s;
  };
  std::vector<simcore::InputEvent> events;
  auto add = [&](simcore::InputEvent e, long step, int tool) {
    e.step = step;
    e.tool = tool;
    events.push_back(e);
  };
  const Eigen::Vector3d end(0.04, 0.005, 0.005);  // the free end's centre: the jaws hold the nodes within 6 mm
  add(rehearse::testing::toolAt(end), 2, 0);
  add(rehearse::testing::jaws(true), 2, 0);
  for (int k = 1; k <= 5; ++k) add(rehearse::testing::toolAt(end + Eigen::Vector3d(0.001 * k, 0, 0)), 2 + k, 0);
  add(rehearse::testing::toolAt({0.025, -0.004, 0.012}), 10, 1);
  add(rehearse::testing::cutting(true), 10, 1);
  for (int k = 1; k <= 10; ++k) add(rehearse::testing::toolAt({0.025, -0.004 + 0.0018 * k, 0.012}), 10 + k, 1);
  add(rehearse::testing::cutting(false), 21, 1);
  constexpr long kAt = 16, kEnd = 40;
  const Eigen::Vector3d jawsAt = end + Eigen::Vector3d(0.005, 0, 0);

  std::map<bool, double> heldOff;  // the held nodes' largest distance from their place at the jaws, at the end
  std::vector<std::uint64_t> straight;
  simcore::Checkpoint cp;
  std::vector<int> held;
  std::vector<Eigen::Vector3d> heldAt;
  for (const bool keep : {true, false}) {
    simcore::Session session(setupWith(keep));
    for (const auto& e : events) session.post(e);
    for (long k = 1; k <= kEnd; ++k) {
      session.advance();
      if (keep) straight.push_back(app::stateChecksum(session.state()));
      if (keep && k == kAt) cp = session.checkpoint();
      if (k == 8) {  // pulled: where the held nodes are relative to the jaws
        held = session.snapshot()->tool.held;
        heldAt.clear();
        for (int n : held) heldAt.push_back(session.state().x.segment<3>(3 * n) - jawsAt);
      }
    }
    const auto snap = session.snapshot();
    QVERIFY2(snap->topologyVersion > 0, "the blade cut the block");
    if (keep) {  // the review draws the jaws where they hold, apart from the blade's tip
      const app::ReviewRenderer renderer(session.setup(), 640, 480);
      const cv::Mat3b drawn = renderer.render(*snap, {}, "");
      simcore::Snapshot open = *snap;
      open.tool.jawClosed = false;
      cv::Mat diff;
      cv::absdiff(drawn, renderer.render(open, {}, ""), diff);
      cv::Mat1b changed;
      cv::inRange(diff, cv::Scalar(1, 1, 1), cv::Scalar(255, 255, 255), changed);
      const cv::Rect ring = cv::boundingRect(changed);
      qInfo("the jaws' ring in the review: %d px changed, %dx%d", cv::countNonZero(changed), ring.width, ring.height);
      QVERIFY(cv::countNonZero(changed) > 10 && ring.width < 40 && ring.height < 40);
    }
    QVERIFY(!held.empty() && snap->tool.jawClosed && snap->tool.held == held);
    double off = 0;
    for (std::size_t i = 0; i < held.size(); ++i)
      off = std::max(off, (session.state().x.segment<3>(3 * held[i]) - (jawsAt + heldAt[i])).norm());
    heldOff[keep] = off;
    qInfo(
        "jaws keep their hold %d: %zu nodes held, at most %.4f mm from where the jaws put them after the cut; tip "
        "%.1f mm from the jaws",
        int(keep), held.size(), 1e3 * off, 1e3 * (snap->tool.tip - jawsAt).norm());
  }
  QVERIFY(heldOff[true] < 1e-6);   // the constraint's targets stayed at the jaws
  QVERIFY(heldOff[false] > 0.01);  // they followed the blade's tip, more than 10 mm away
  QVERIFY((cp.tool.jawTip - jawsAt).norm() < 1e-12 && (cp.tool.tip - jawsAt).norm() > 0.01);
  QCOMPARE(cp.tool.jawTool, 0);

  std::map<std::uint64_t, simcore::BodySetup> setups;
  setups[app::setupHash(cp.setup)] = app::sharedSetup(cp.setup);
  const simcore::Checkpoint back =
      app::decodeCheckpointState(app::encodeCheckpointState(cp), [&](std::uint64_t h) { return setups.at(h); });
  QCOMPARE(back.tool.jawTip, cp.tool.jawTip);
  QCOMPARE(back.tool.jawTool, 0);
  const auto continues = [&](const simcore::Checkpoint& c) {
    simcore::Session resumed(setupWith(true));
    resumed.restore(c);
    for (const auto& e : events)
      if (e.step >= kAt) resumed.post(e);
    for (long k = kAt + 1; k <= kEnd; ++k) {
      resumed.advance();
      if (app::stateChecksum(resumed.state()) != straight[static_cast<std::size_t>(k - 1)]) return false;
    }
    return true;
  };
  QVERIFY(continues(back));
  simcore::Checkpoint older = back;
  older.tool.jawTip = older.tool.tip;
  QVERIFY2(!continues(older), "the jaws' place must matter to the continuation, or the comparison above sees nothing");

  QVERIFY(app::decodeSetup(app::encodeSetup(setupWith(true))).tools.jawsKeepTheirHold);
  QVERIFY(!app::decodeSetup(app::encodeSetup(setupWith(false))).tools.jawsKeepTheirHold);
  auto recordedBefore = nlohmann::json::parse(app::encodeSetup(setupWith(true)));
  recordedBefore["tools"].erase("jawsKeepTheirHold");
  QVERIFY(!app::decodeSetup(recordedBefore.dump()).tools.jawsKeepTheirHold);
}

QTEST_MAIN(TestRecording)
