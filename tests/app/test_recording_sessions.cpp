// The recording suite's later slots (test_recording.hpp declares them, in their order): a checkpoint with a cut under
// way, stability settings, strain, exports and metrics from the script, reset and the sessions' identity across files.
#include "test_recording.hpp"

#include "box_mesh.hpp"
#include "cli_run.hpp"
#include "gesture_args.hpp"
#include "replay_checks.hpp"
#include "session_inputs.hpp"

#include <rehearse/app/recording.hpp>
#include <rehearse/app/sessionlauncher.hpp>
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
#include <optional>
#include <random>

using namespace rehearse;

namespace {
using ::testing::Run;
using ::testing::run;

// A 4 cm bar held at one end, linearised steps: the recorder's tests' small body.
simcore::BodySetup smallHeldBar() {
  simcore::BodySetup s;
  s.mesh = boxMesh(0.04, 0.01, 0.01, 6, 2, 2);
  s.fixedNodes = nodesAtX(s.mesh, 0.0);
  s.material.young = 5e3;
  s.settings.method = simcore::NewtonMethod::Linearised;
  return s;
}
}  // namespace

// Issue 61: a held-back step whose grasp force still came out past the limit is taken again with the jaws moved back
// (ToolSettings::slipResolved). Recorded live with the window's asynchronous refresh (factors swapped in when the second
// thread has them: recorded events), the session replays bit for bit: the second try swaps no factor in, so each swap
// stays at the boundary the replay installs it at. A hand's pull on the liver preset, 3 mm a move every 5 steps, up
// and away from the organ, until the tissue slips: at the limit within 2 %; the same pull held back to first order
// only (as recorded before) slips further past it (the test's own contrast: the step taken again is this pull's).
void TestRecording::aSlipTakenAgainReplays() {
  QTemporaryDir dir;
  const QString file = dir.path() + "/slip.rehearse";
  struct Pulled {
    double slipForce = -1;
    std::string said;
    long steps = 0;
    int swaps = 0;
  };
  auto pull = [&](bool resolved, bool record) {
    simcore::BodySetup s = rehearse::testing::presetBody("liver");
    s.settings.factorRefresh = simcore::FactorRefresh::Asynchronous;
    s.tools.slipResolved = resolved;
    Pulled out;
    simcore::Session session(s);
    app::SessionMeta meta;
    meta.trainee = "S. Lip";
    meta.appVersion = "0.1.0";
    std::optional<app::Recorder> recorder;
    if (record) {
      recorder.emplace(file.toStdString(), meta, session.setup());
      session.setStepHook([&](const simcore::StepRecord& r) { recorder->afterStep(r); });
    }
    auto step = [&] {
      const simcore::StepReport rep = session.advance();
      out.swaps += rep.factorSwapped ? 1 : 0;
      ++out.steps;
      const auto snap = session.snapshot();
      if (std::find(snap->events.begin(), snap->events.end(), "slip") != snap->events.end()) {
        out.said = snap->message;
        if (std::sscanf(out.said.c_str(), "The tissue slipped out of the grasper at %lf N", &out.slipForce) != 1)
          out.slipForce = 0;
      }
    };
    for (int k = 0; k < 50; ++k) step();
    Eigen::Vector3d tip = session.snapshot()->positions.front();
    for (const auto& p : session.snapshot()->positions)
      if ((p - Eigen::Vector3d(0, 0, -0.05)).norm() < (tip - Eigen::Vector3d(0, 0, -0.05)).norm()) tip = p;
    session.post(rehearse::testing::toolAt(tip));
    session.post(rehearse::testing::jaws(true));
    step();
    for (int move = 1; move <= 100 && out.slipForce < 0; ++move) {
      session.post(rehearse::testing::toolAt(tip + Eigen::Vector3d(0, 0, -0.003 * move)));
      for (int k = 0; k < 5 && out.slipForce < 0; ++k) step();
    }
    for (int k = 0; k < 20; ++k) step();  // and the tissue let go of
    if (recorder) recorder->finish(out.steps);
    return out;
  };
  const double max = rehearse::testing::presetBody("liver").tools.maxGraspForce;
  const Pulled before = pull(false, false), now = pull(true, true);
  qInfo("held back to first order: %s", before.said.c_str());
  qInfo("taken again: after %ld steps (%d factors swapped in): %s", now.steps, now.swaps, now.said.c_str());
  QVERIFY2(now.slipForce >= 0.95 * max && now.slipForce <= 1.02 * max, now.said.c_str());
  QVERIFY2(before.slipForce > 1.02 * max, "the first order's overshoot this test is about is no longer there");
  const auto rec = app::loadRecording(file.toStdString(), 1);
  QVERIFY(rec.setup.tools.slipResolved);
  const app::VerifyResult v = app::replayRecording(rec).verify;
  qInfo("%s", app::replayCheckSentence(v).c_str());
  QCOMPARE(v.mismatches, 0);
  QVERIFY(v.checked > 0);
}

void TestRecording::checkpointWithACutUnderWayIsComplete() {
  // Both ways a cut comes in: at the boundary the recording names (-1: sessions recorded before the latency), and
  // a fixed number of steps after its sweep (20 here, so that the checkpoint falls while it is being built).
  for (int latency : {-1, 20}) {
    simcore::BodySetup s;
    s.mesh = boxMesh(0.04, 0.01, 0.01, 8, 2, 2);
    s.fixedNodes = nodesAtX(s.mesh, 0.0);
    s.material.young = 2e4;
    s.settings.method = simcore::NewtonMethod::Linearised;
    s.settings.factorRefresh = simcore::FactorRefresh::Deferred;
    s.tools.bladeLength = 0.03;
    s.tools.trocar = Eigen::Vector3d(0.025, 0.005, -0.2);
    s.tools.cutLatencySteps = latency;
    std::vector<simcore::InputEvent> events;
    auto add = [&](simcore::InputEvent e, long step) {
      e.step = step;
      e.tool = 1;
      events.push_back(e);
    };
    // The blade stands through the block at x = 25 mm and is drawn across it in y.
    add(rehearse::testing::toolAt({0.025, -0.004, 0.012}), 5);
    add(rehearse::testing::cutting(true), 5);
    for (int k = 1; k <= 10; ++k) add(rehearse::testing::toolAt({0.025, -0.004 + 0.0018 * k, 0.012}), 5 + k);
    add(rehearse::testing::cutting(false), 16);
    simcore::InputEvent applied;
    applied.kind = simcore::InputKind::CutApplied;
    add(applied, 30);
    simcore::InputEvent factor;
    factor.kind = simcore::InputKind::Factor;
    add(factor, 26);  // before the cut comes in (which brings its own factor)
    constexpr long kAt = 22, kEnd = 45;
    std::vector<std::uint64_t> straight;
    simcore::Checkpoint cp;
    {
      simcore::Session session(s);
      for (const auto& e : events) session.post(e);
      for (long k = 1; k <= kEnd; ++k) {
        session.advance();
        straight.push_back(app::stateChecksum(session.state()));
        if (k == kAt) cp = session.checkpoint();
      }
      QVERIFY2(session.snapshot()->topologyVersion > 0, "the blade cut the block");
    }
    QVERIFY2(cp.pendingChange.has_value(), "the checkpoint falls while the cut's body is being built");
    qInfo("cut latency %d: checkpoint at step %ld, a cut under way (%zu new nodes, applied at %ld), a factor %s",
          latency, cp.step, cp.pendingChange->newNodes.size(), cp.pendingChange->applyAt,
          cp.state.lagged.requested ? "requested" : "not requested");
    // Through the bytes the recorder writes (setups by hash, without the cut's progress).
    std::map<std::uint64_t, simcore::BodySetup> setups;
    for (const auto* x : {&cp.setup, &cp.pendingChange->setup}) setups[app::setupHash(*x)] = app::sharedSetup(*x);
    const simcore::Checkpoint back =
        app::decodeCheckpointState(app::encodeCheckpointState(cp), [&](std::uint64_t h) { return setups.at(h); });
    QVERIFY(back.pendingChange.has_value());
    simcore::Session resumed(s);
    resumed.restore(back);
    for (const auto& e : events)
      if (e.step >= kAt) resumed.post(e);
    for (long k = kAt + 1; k <= kEnd; ++k) {
      resumed.advance();
      QVERIFY2(app::stateChecksum(resumed.state()) == straight[static_cast<std::size_t>(k - 1)],
               qPrintable(QString("step %1 after the checkpoint of step %2 differs").arg(k).arg(kAt)));
    }
    // Without the cut under way and the requested factor the continuation differs (so the comparison above
    // would see a checkpoint that lacks them).
    for (int strip = 0; strip < 2; ++strip) {
      simcore::Checkpoint partial = back;
      if (strip == 0)
        partial.pendingChange.reset();
      else
        partial.state.lagged.requested = false;
      simcore::Session other(s);
      other.restore(partial);
      for (const auto& e : events)
        if (e.step >= kAt) other.post(e);
      bool differs = false;
      for (long k = kAt + 1; k <= kEnd; ++k) {
        other.advance();
        differs |= app::stateChecksum(other.state()) != straight[static_cast<std::size_t>(k - 1)];
      }
      QVERIFY2(differs, strip == 0 ? "a checkpoint without its cut under way continued the same"
                                   : "a checkpoint without its requested factor continued the same");
    }
  }
}

// The largest principal Green strain against closed forms: a uniform stretch s gives (s^2 - 1) / 2, a
// rotation adds nothing, a simple shear g gives (g^2 + g sqrt(g^2 + 4)) / 4.
// Issue 17's settings are recorded: strict, the inversion guard and the linearised tolerance go through a
// setup's JSON unchanged; a setup recorded before they existed (its JSON without them) decodes as that version
// ran — strict (a step that did not converge was rolled back) and unguarded — so its replay takes the same steps.
void TestRecording::stabilitySettingsAreRecorded() {
  simcore::BodySetup s;
  s.mesh = boxMesh(0.02, 0.01, 0.01, 2, 1, 1);
  s.settings.strict = false;
  s.settings.inversionGuard = true;
  s.settings.linearisedTolerance = 0.05;
  const simcore::BodySetup back = app::decodeSetup(app::encodeSetup(s));
  QCOMPARE(back.settings.strict, false);
  QCOMPARE(back.settings.inversionGuard, true);
  QCOMPARE(back.settings.linearisedTolerance, 0.05);
  s.settings.strict = true;
  s.settings.inversionGuard = false;
  QCOMPARE(app::decodeSetup(app::encodeSetup(s)).settings.strict, true);
  QCOMPARE(app::decodeSetup(app::encodeSetup(s)).settings.inversionGuard, false);
  QJsonObject j = QJsonDocument::fromJson(QByteArray::fromStdString(app::encodeSetup(s))).object();
  QJsonObject settings = j["settings"].toObject();
  for (const char* key :
       {"strict", "inversionGuard", "linearisedTolerance", "chordAcceleration", "checkedProjection", "heldBackStop",
        "volumeBarrier"}) {
    QVERIFY2(settings.contains(key), key);
    settings.remove(key);
  }
  j["settings"] = settings;
  const simcore::BodySetup old = app::decodeSetup(QJsonDocument(j).toJson(QJsonDocument::Compact).toStdString());
  QCOMPARE(old.settings.strict, true);
  QCOMPARE(old.settings.inversionGuard, false);
  QCOMPARE(old.settings.linearisedTolerance, simcore::SimulationSettings{}.linearisedTolerance);
  // The chord's acceleration: written only when on (a setup without it keeps its text and hash), and a setup recorded
  // before it existed replays the plain chord it ran.
  QVERIFY(simcore::SimulationSettings{}.chordAcceleration);
  QVERIFY(app::decodeSetup(app::encodeSetup(s)).settings.chordAcceleration);
  QVERIFY(QString::fromStdString(app::encodeSetup(s)).contains("\"chordAcceleration\":true"));
  s.settings.chordAcceleration = false;
  QVERIFY(!QString::fromStdString(app::encodeSetup(s)).contains("chordAcceleration"));
  QVERIFY(!app::decodeSetup(app::encodeSetup(s)).settings.chordAcceleration);
  QVERIFY(!old.settings.chordAcceleration);
  // The same for the projection of an indefinite tangent and the end of a step the inversion guard holds back.
  for (bool simcore::SimulationSettings::*flag :
       {&simcore::SimulationSettings::checkedProjection, &simcore::SimulationSettings::heldBackStop}) {
    s.settings = simcore::SimulationSettings{};
    QVERIFY(s.settings.*flag);
    QVERIFY(app::decodeSetup(app::encodeSetup(s)).settings.*flag);
    s.settings.*flag = false;
    QVERIFY(!(app::decodeSetup(app::encodeSetup(s)).settings.*flag));
    QVERIFY(!(old.settings.*flag));
  }
  // The corotational law's volume barrier: on by default (at kVolumeBarrierJ), written with its J, and off in a setup
  // recorded before it existed.
  s.settings = simcore::SimulationSettings{};
  QCOMPARE(s.settings.volumeBarrier, simcore::kVolumeBarrierJ);
  QCOMPARE(app::decodeSetup(app::encodeSetup(s)).settings.volumeBarrier, simcore::kVolumeBarrierJ);
  s.settings.volumeBarrier = 0;
  QVERIFY(!QString::fromStdString(app::encodeSetup(s)).contains("volumeBarrier"));
  QCOMPARE(app::decodeSetup(app::encodeSetup(s)).settings.volumeBarrier, 0.0);
  QCOMPARE(old.settings.volumeBarrier, 0.0);
  {  // a setup another version or machine wrote with a barrier out of range: refused with a sentence, at read
    s.settings.volumeBarrier = simcore::kVolumeBarrierJ;
    QJsonObject bad = QJsonDocument::fromJson(QByteArray::fromStdString(app::encodeSetup(s))).object();
    QJsonObject badSettings = bad["settings"].toObject();
    badSettings["volumeBarrier"] = 1.5;
    bad["settings"] = badSettings;
    try {
      app::decodeSetup(QJsonDocument(bad).toJson(QJsonDocument::Compact).toStdString());
      QFAIL("a volume barrier of 1.5 was read");
    } catch (const std::exception& e) {
      QVERIFY2(QString(e.what()).contains("volume barrier"), e.what());
    }
  }
  // The accuracy asked in millimetres (issue 64): off by default, written only when on (with its force share), and
  // off in a setup recorded before it existed.
  s.settings = simcore::SimulationSettings{};
  QCOMPARE(s.settings.accuracyPosition, 0.0);
  QVERIFY(!QString::fromStdString(app::encodeSetup(s)).contains("accuracy"));
  s.settings.accuracyPosition = 5e-5;
  s.settings.accuracyForce = 0.01;
  QCOMPARE(app::decodeSetup(app::encodeSetup(s)).settings.accuracyPosition, 5e-5);
  QCOMPARE(app::decodeSetup(app::encodeSetup(s)).settings.accuracyForce, 0.01);
  QCOMPARE(old.settings.accuracyPosition, 0.0);
  // A tear's body taken in when built (the window's): written only when on, off in a setup from before it existed.
  QVERIFY(!simcore::ToolSettings{}.tearWhenBuilt);
  QVERIFY(!QString::fromStdString(app::encodeSetup(s)).contains("tearWhenBuilt"));
  s.tools.tearWhenBuilt = true;
  QVERIFY(app::decodeSetup(app::encodeSetup(s)).tools.tearWhenBuilt);
  QVERIFY(!old.tools.tearWhenBuilt);
}

void TestRecording::strainMatchesClosedForms() {
  const std::vector<Eigen::Vector3d> rest = {{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}, {0, 0, 0.01}};
  const std::vector<std::array<int, 4>> tets = {{0, 1, 2, 3}};
  auto deformed = [&](const Eigen::Matrix3d& F) {
    std::vector<Eigen::Vector3d> x;
    for (const auto& p : rest) x.push_back(F * p + Eigen::Vector3d(0.3, -0.1, 0.2));
    return x;
  };
  QVERIFY(std::abs(app::maxGreenStrain(rest, deformed(1.1 * Eigen::Matrix3d::Identity()), tets) - 0.105) < 1e-12);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(1.2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  QVERIFY(std::abs(app::maxGreenStrain(rest, deformed(R * 1.1), tets) - 0.105) < 1e-12);
  QVERIFY(app::maxGreenStrain(rest, deformed(R), tets) < 1e-12);
  const double g = 0.3;
  Eigen::Matrix3d shear = Eigen::Matrix3d::Identity();
  shear(0, 1) = g;
  QVERIFY(std::abs(app::maxGreenStrain(rest, deformed(shear), tets) - (g * g + g * std::sqrt(g * g + 4)) / 4) < 1e-12);
}

// The review's exports and the metrics of a session with a grasp, a pull and a cut, against values worked
// out from the script: the hook is drawn 90 mm along +z in 100 steps while it cuts (the runner's first
// cutting pose is already 1/100 along), so the blade tip's cut path is 99 x 0.9 mm; a planned line 5 mm to
// its side is 5 mm from every cutting pose. The video of the whole 3.6 s at 25 fps has 91 frames of 640x480
// (read back through OpenCV's decoder); the PDF report has four pages, each rendered by pdftoppm.
void TestRecording::exportsAndMetricsFromTheScript() {
  QTemporaryDir dir;
  const QString file = dir.path() + "/case.rehearse";
  QStringList args = gestureArgs(dir.path(), "grasp-pull-cut.json", file);
  args << "--report" << dir.path() + "/live.json";
  const Run a = run(args);
  QVERIFY2(::testing::tookEveryStep(a), qPrintable(a.out + a.err));
  QFile th(dir.path() + "/t.json");
  QVERIFY(th.open(QIODevice::WriteOnly));
  th.write(R"({"max_force_n": {"max": 1000}, "vessel_cuts": {"max": 0}, "tumour_breaches": {"max": 0}})");
  th.close();
  const QStringList judged = {"replay", file, "--session", "1", "--verify", "--thresholds", dir.path() + "/t.json",
                              "--planned-cut", "-0.055,0.05,-0.04:-0.055,0.05,0.05"};
  const Run r = run(judged + QStringList{"--metrics", dir.path() + "/m.json", "--video", dir.path() + "/v.mp4",
                                         "--report", dir.path() + "/r.pdf"});
  QVERIFY2(r.code == 0, qPrintable(r.out + r.err));
  QVERIFY2(r.out.contains("video: 91 frames of 640x480"), qPrintable(r.out));
  QFile mf(dir.path() + "/m.json");
  QVERIFY(mf.open(QIODevice::ReadOnly));
  const QJsonObject m = QJsonDocument::fromJson(mf.readAll()).object();
  qInfo("cut length %.9f m, deviation mean %.9f max %.9f m, strain %.4f, max force %.3f N",
        m["cut_length_m"].toDouble(), m["cut_deviation_mean_m"].toDouble(), m["cut_deviation_max_m"].toDouble(),
        m["max_strain"].toDouble(), m["max_force_n"].toDouble());
  QVERIFY(std::abs(m["cut_length_m"].toDouble() - 99 * 0.0009) < 1e-9);
  // The path: the grasper's 15 mm pull over 60 steps (its first pose 1/60 along) and the hook's 90 mm (1/100
  // along), not the jump from one instrument to the other; both straight.
  QVERIFY(std::abs(m["path_length_m"].toDouble() - (59 * 0.015 / 60 + 99 * 0.0009)) < 1e-9);
  QVERIFY(std::abs(m["economy_of_motion"].toDouble() - 1.0) < 1e-9);
  QVERIFY(std::abs(m["cut_deviation_mean_m"].toDouble() - 0.005) < 1e-9);
  QVERIFY(std::abs(m["cut_deviation_max_m"].toDouble() - 0.005) < 1e-9);
  QVERIFY(m["max_strain"].toDouble() > 0);
  QVERIFY(m["tumour_breaches"].isNull() && m["tumour_breaches_why"].toString().contains("no tumour"));
  QVERIFY(m["attachments_torn"].isNull());
  // The largest force and the vessel cuts: the live run's own report (how the blade's sweep is split into cut
  // updates depends on when the second thread finishes each, so whether one goes through a vessel may vary).
  QFile lf(dir.path() + "/live.json");
  QVERIFY(lf.open(QIODevice::ReadOnly));
  const QJsonObject live = QJsonDocument::fromJson(lf.readAll()).object();
  QVERIFY(std::abs(live["peak_tool_force_n"].toDouble() - m["max_force_n"].toDouble()) < 1e-9);
  QCOMPARE(m["vessel_cuts"].toInt(), live["vessel_cuts"].toInt());
  QVERIFY(!m["vessel_cuts"].isNull() &&
          m["vessel_cuts"].toInt() >= 1);  // the phantom names label 2 "vessels"; the hook goes through them
  {  // Issue 32: a mesh that names no vessel cannot say whether one was cut: no number, a sentence.
    app::Recording unnamed = app::loadRecording(file.toStdString(), 1);
    unnamed.setup.mesh.labelNames.clear();
    app::ReplayOptions o;
    const app::ReplayResult rr = app::replayRecording(unnamed, o);
    QVERIFY(!rr.metrics.vesselCuts.has_value());
    QVERIFY(QString::fromStdString(rr.metrics.vesselWhy).contains("names no vessel"));
    QVERIFY(rr.metrics.cuts > 0);
  }
  // Verdicts: under 1000 N passes, a vessel cut fails, the tumour is not determined.
  QMap<QString, QString> verdict;
  for (const auto& v : m["verdicts"].toArray())
    verdict[v.toObject()["metric"].toString()] = v.toObject()["result"].toString();
  QCOMPARE(verdict["max_force_n"], QStringLiteral("pass"));
  QCOMPARE(verdict["vessel_cuts"], live["vessel_cuts"].toInt() > 0 ? QStringLiteral("fail") : QStringLiteral("pass"));
  QCOMPARE(verdict["tumour_breaches"], QStringLiteral("not determined"));
  // The video, read back.
  cv::VideoCapture cap((dir.path() + "/v.mp4").toStdString());
  QVERIFY(cap.isOpened());
  int frames = 0;
  cv::Mat f, first;
  while (cap.read(f)) {
    if (frames++ == 0) first = f.clone();
    QCOMPARE(f.cols, 640);
    QCOMPARE(f.rows, 480);
  }
  QCOMPARE(frames, 91);
  cv::Scalar mean, sd;
  cv::meanStdDev(first, mean, sd);
  QVERIFY(sd[2] > 10);  // the organ over the background, not a blank frame
  // The report: four pages, rendered.
  QProcess pdf;
  pdf.start("pdftoppm", {"-r", "30", "-png", dir.path() + "/r.pdf", dir.path() + "/page"});
  QVERIFY2(pdf.waitForStarted(), "pdftoppm (poppler-utils) is installed by scripts/install-deps.sh");
  QVERIFY(pdf.waitForFinished(60000) && pdf.exitCode() == 0);
  // Metrics, over time, incorrect actions (here: none, and the rules not determined: a page of short lines), key
  // frames.
  for (int k = 1; k <= 4; ++k) {
    const cv::Mat page = cv::imread((dir.path() + QString("/page-%1.png").arg(k)).toStdString(), cv::IMREAD_GRAYSCALE);
    QVERIFY2(!page.empty(), qPrintable(QString("page %1").arg(k)));
    const int dark = cv::countNonZero(page < 128);
    QVERIFY2(dark > (k == 3 ? 60 : 200), qPrintable(QString("page %1 is blank (%2 dark pixels)").arg(k).arg(dark)));
  }
  QVERIFY(!QFile::exists(dir.path() + "/page-5.png"));
  {
    // Issue 63: the report is written below the GUI, so the build without Qt writes it too, the same words on the
    // same pages (scripts/test.sh builds that program before the suites run and asks for it).
    const QString nogui = QStringLiteral(REHEARSE_SOURCE_DIR "/build-nogui/app/rehearse");
    if (!QFile::exists(nogui)) {
      QVERIFY2(qgetenv("REHEARSE_REQUIRE_NOGUI") != "1", qPrintable(nogui + " is missing (scripts/test.sh builds it)"));
      qInfo("the GUI-less build's report not checked: %s is not built", qPrintable(nogui));
    } else {
      QProcess p;
      p.start(nogui, judged + QStringList{"--report", dir.path() + "/r-nogui.pdf"});
      QVERIFY(p.waitForFinished(300000));
      QVERIFY2(p.exitCode() == 0 || p.exitCode() == 4, p.readAllStandardError().constData());
      auto words = [](const QString& pdf) {
        QProcess t;
        t.start("pdftotext", {"-layout", pdf, "-"});
        return t.waitForFinished(60000) && t.exitCode() == 0 ? t.readAllStandardOutput() : QByteArray();
      };
      const QByteArray gui = words(dir.path() + "/r.pdf"), headless = words(dir.path() + "/r-nogui.pdf");
      QVERIFY(gui.size() > 1000);
      QCOMPARE(headless, gui);
      QVERIFY2(gui.contains("Metrics") && gui.contains("Over time") && gui.contains("Key frames"), gui.constData());
    }
  }
  // Bad requests say so in one line.
  const Run bad = run({"replay", file, "--session", "1", "--video", dir.path() + "/v.avi"});
  QCOMPARE(bad.code, 2);
  QCOMPARE(bad.err.trimmed().count('\n'), 0);
  // A report into a folder that is not there is refused before the replay, in one sentence.
  const Run nowhere = run({"replay", file, "--session", "1", "--report", dir.path() + "/missing/r.pdf"});
  QCOMPARE(nowhere.code, 2);
  QVERIFY2(nowhere.err.trimmed().count('\n') == 0 && nowhere.err.contains("missing does not exist") &&
               !nowhere.out.contains("verified"),
           qPrintable(nowhere.out + nowhere.err));
  const Run badThresholds = run({"replay", file, "--session", "1", "--metrics", dir.path() + "/m2.json", "--thresholds",
                                 script("grasp-pull.json")});
  QCOMPARE(badThresholds.code, 2);
  QVERIFY2(badThresholds.err.contains("unknown metric"), qPrintable(badThresholds.err));
}

// A reset while recording (issue 32): the step count starts again. The recorder ends the session there instead of
// writing the new run's checksums over the old ones (which made the session fail to verify); what it recorded
// before the reset is intact and verifies.
void TestRecording::resetEndsTheRecordedSession() {
  QTemporaryDir dir;
  const std::string file = (dir.path() + "/case.rehearse").toStdString();
  const simcore::BodySetup s = smallHeldBar();
  auto recorder = std::make_shared<app::Recorder>(file, app::SessionMeta{"R. Eset", {}, {}, {}, {}, {}}, s, 5, 10);
  std::string stopped;
  {
    simcore::Session session(s);
    session.setStepHook([&](const simcore::StepRecord& r) {
      if (!stopped.empty()) return;
      try {
        recorder->afterStep(r);
      } catch (const std::exception& e) {
        stopped = e.what();
      }
    });
    session.post(rehearse::testing::toolAt({0.04, 0.005, 0.005}));
    for (int k = 0; k < 40; ++k) session.advance();
    session.reset();  // what Shift+F5 did while recording (applied by the session's thread)
    for (int k = 0; k < 500 && session.snapshot()->step != 0; ++k) QTest::qWait(10);
    QCOMPARE(session.snapshot()->step, 0L);
    session.post(rehearse::testing::toolAt({0.03, 0.0, 0.02}));
    for (int k = 0; k < 25; ++k) session.advance();
    session.setStepHook({});
  }
  QVERIFY2(!stopped.empty(), "the recorder took the steps of the run after the reset");
  QVERIFY2(QString::fromStdString(stopped).contains("started again"), stopped.c_str());
  QCOMPARE(recorder->lastStep(), 40L);
  recorder->finish(recorder->lastStep());
  recorder.reset();
  const auto rec = app::loadRecording(file, 1);
  QCOMPARE(rec.summary.steps, 40L);
  QCOMPARE(static_cast<long>(rec.checksums.size()), 8L);
  const auto v = app::verifyRecording(rec);
  QCOMPARE(v.checked, 8L);
  QCOMPARE(v.mismatches, 0L);
  qInfo("reset at step 40: '%s'; the session keeps 40 steps and verifies (%ld checksums)", stopped.c_str(), v.checked);
}

// A recording stopped (or reset) before its first step keeps nothing: a person's check found an empty "Recorded session
// 3" listed after Reset then Stop. The session with steps beside it stays, with its events, and verifies; the empty
// one's rows are gone from every table; a session with steps is never dropped.
void TestRecording::aSessionWithoutStepsIsNotKept() {
  QTemporaryDir dir;
  const std::string file = (dir.path() + "/case.rehearse").toStdString();
  const simcore::BodySetup s = smallHeldBar();
  std::int64_t keptId = 0, emptyId = 0;
  {
    auto first = std::make_shared<app::StepRecording>(
        std::make_shared<app::Recorder>(file, app::SessionMeta{"A. Trainee", {}, {}, {}, {}, {}}, s, 5, 10));
    simcore::Session session(s);
    first->attach(session);
    session.post(rehearse::testing::toolAt({0.04, 0.005, 0.005}));
    for (int k = 0; k < 12; ++k) session.advance();
    QCOMPARE(first->finish(&session), std::string());
    QVERIFY(!first->discarded());
    keptId = first->id();
  }
  {
    auto second = std::make_shared<app::StepRecording>(
        std::make_shared<app::Recorder>(file, app::SessionMeta{"A. Trainee", {}, {}, {}, {}, {}}, s, 5, 10));
    simcore::Session session(s);
    second->attach(session);
    session.post(rehearse::testing::toolAt({0.03, 0.0, 0.02}));  // a tool moved while paused: an event, no step
    QCOMPARE(app::listRecordings(file).size(), std::size_t{2});  // listed while it records
    QCOMPARE(second->finish(&session), std::string());
    QVERIFY(second->discarded());
    emptyId = second->id();
  }
  const auto listed = app::listRecordings(file);
  QCOMPARE(listed.size(), std::size_t{1});
  QCOMPARE(listed.front().id, keptId);
  QCOMPARE(listed.front().steps, 12L);
  QVERIFY(listed.front().complete);
  const auto v = app::verifyRecording(app::loadRecording(file, keptId));
  QVERIFY(v.checked > 0 && v.mismatches == 0);
  QVERIFY_THROWS_EXCEPTION(std::exception, app::loadRecording(file, emptyId));
  // No row of the dropped session is left in any table.
  {
    sqlite3* db = nullptr;
    QCOMPARE(sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
    for (const char* table : {"rehearsal_events", "rehearsal_checksums", "rehearsal_setups", "rehearsal_checkpoints"}) {
      sqlite3_stmt* q = nullptr;
      const std::string sql = std::string("SELECT COUNT(*) FROM ") + table + " WHERE session = ?";
      QCOMPARE(sqlite3_prepare_v2(db, sql.c_str(), -1, &q, nullptr), SQLITE_OK);
      sqlite3_bind_int64(q, 1, emptyId);
      QCOMPARE(sqlite3_step(q), SQLITE_ROW);
      QCOMPARE(sqlite3_column_int64(q, 0), sqlite3_int64{0});
      sqlite3_finalize(q);
    }
    sqlite3_close(db);
  }
  qInfo("session %lld (12 steps) kept and verifies; session %lld (no step, one event) dropped from every table",
        static_cast<long long>(keptId), static_cast<long long>(emptyId));
}

// Sessions have an identity across files (issue 32): a recorder whose file is replaced by a copy goes on in its
// own session (found by uuid, whatever its row number there); a file whose session 1 is someone else's gets ours
// as a new session, never appended to theirs; steps taken while the recorder was suspended (the save) reach the
// new file; a failed reopen leaves nothing half-open and refuses further steps with a sentence.
void TestRecording::sessionsKeepTheirIdentityAcrossFiles() {
  QTemporaryDir dir;
  const std::string a = (dir.path() + "/a.rehearse").toStdString(),
                    other = (dir.path() + "/other.rehearse").toStdString();
  const simcore::BodySetup s = smallHeldBar();
  auto record = [&](const std::string& file, const char* who, int steps, double y,
                    const std::function<void(int, app::Recorder&)>& during = {}) {
    auto r = std::make_unique<app::Recorder>(file, app::SessionMeta{who, {}, {}, {}, {}, {}}, s, 5, 10);
    simcore::Session session(s);
    session.setStepHook([&](const simcore::StepRecord& rec) { r->afterStep(rec); });
    session.post(rehearse::testing::toolAt({0.04, y, 0.005}));
    for (int k = 0; k < steps; ++k) {
      session.advance();
      if (during) during(k + 1, *r);
    }
    session.setStepHook({});
    r->finish(r->lastStep());
    return r;
  };
  record(other, "Someone Else", 30, 0.0);  // other.rehearse: session 1, someone else's
  const std::string firstUuid = record(a, "Trainee A", 20, 0.004)->uuid();
  // A second session in a.rehearse (row 2): at step 15 the recorder lets go of the file (a save begins), a copy is
  // made (saved.rehearse) and at step 25 it goes on there; at step 40 it is moved into other.rehearse, where row 2
  // does not exist and row 1 is someone else's.
  std::string secondUuid;
  const std::string saved = (dir.path() + "/saved.rehearse").toStdString();
  record(a, "Trainee A", 60, 0.008, [&](int step, app::Recorder& r) {
    secondUuid = r.uuid();
    if (step == 15) r.suspend();
    if (step == 25) {  // steps 16-25 were kept in memory; the copy holds steps up to 15
      QCOMPARE(app::copyRecordings(a, saved), 2);
      r.reopen(saved);
    }
    if (step == 40) r.reopen(other);  // not suspended: the file simply changed
  });
  QVERIFY(secondUuid != firstUuid && secondUuid.size() == 32);
  // saved.rehearse: both sessions with their identities; ours up to the move at step 40, checkpoints included.
  const auto inSaved = app::listRecordings(saved);
  QCOMPARE(inSaved.size(), std::size_t(2));
  QCOMPARE(inSaved[0].uuid, firstUuid);
  QCOMPARE(inSaved[1].uuid, secondUuid);
  for (const auto& x : inSaved) {
    const auto v = app::verifyRecording(app::loadRecording(saved, x.id));
    QVERIFY(v.checked > 0);
    QCOMPARE(v.mismatches, 0L);
  }
  const app::Recording ours = app::loadRecording(saved, 2);
  QCOMPARE(ours.summary.steps, 40L);
  QVERIFY2(std::count(ours.checkpointSteps.begin(), ours.checkpointSteps.end(), 20L) == 1,
           "the checkpoint taken while suspended reached the saved file");
  QCOMPARE(app::listRecordings(a).back().steps, 15L);  // the file it left: up to the save
  // other.rehearse: someone else's session 1 untouched, ours a new row with its uuid, complete, verifying.
  const auto inOther = app::listRecordings(other);
  QCOMPARE(inOther.size(), std::size_t(2));
  QCOMPARE(QString::fromStdString(inOther[0].meta.trainee), QStringLiteral("Someone Else"));
  QCOMPARE(inOther[0].steps, 30L);
  QCOMPARE(inOther[1].uuid, secondUuid);
  QVERIFY(inOther[1].complete);
  QCOMPARE(inOther[1].steps, 60L);
  for (const auto& x : inOther) {
    const auto rec = app::loadRecording(other, x.id);
    const auto v = app::verifyRecording(rec);
    QCOMPARE(v.checked, x.steps / 5);
    QCOMPARE(v.mismatches, 0L);
  }
  // A reopen that cannot open the file: one sentence, closed, and further steps are refused with it.
  auto third = std::make_unique<app::Recorder>(a, app::SessionMeta{"T", {}, {}, {}, {}, {}}, s, 5, 10);
  third->suspend();
  try {
    third->reopen((dir.path() + "/no/such/folder/x.rehearse").toStdString());
    QFAIL("a reopen into a folder that does not exist succeeded");
  } catch (const std::runtime_error& e) {
    QVERIFY2(QString(e.what()).contains("cannot go on"), e.what());
  }
  simcore::Session session(s);
  session.advance();
  try {
    third->afterStep(1, {}, session.state());
    QFAIL("a broken recorder took a step");
  } catch (const std::runtime_error& e) {
    QVERIFY2(QString(e.what()).contains("cannot go on"), e.what());
  }
}
