// Recording files under damage (issue 16 onwards), run as a user would: damaged checkpoints and hostile recordings are
// refused with a sentence, a tampered checksum is caught by `rehearse replay --verify`, and a recording killed with
// SIGKILL at random moments leaves a file that opens whole and whose recorded part replays and verifies. Split from
// test_recording (recording, metrics, seeking) to keep each file readable.
#include "box_mesh.hpp"
#include "cli_run.hpp"
#include "gesture_args.hpp"
#include "replay_checks.hpp"
#include "session_inputs.hpp"

#include <rehearse/app/recording.hpp>

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

class TestRecordingFiles : public QObject {
  Q_OBJECT
 private slots:
  void initTestCase() { QStandardPaths::setTestModeEnabled(true); }

  // Damaged checkpoints (a corrupt or truncated case file): every truncation and 3,000 random byte changes of
  // a real checkpoint either decode or are refused with std::runtime_error (never a crash, never vectors of
  // disagreeing sizes); a replayer seeking onto a damaged one says so in one sentence.
  void damagedCheckpointsAreRefused() {
    QTemporaryDir dir;
    const QString file = dir.path() + "/case.rehearse";
    QVERIFY(::testing::tookEveryStep(run(gestureArgs(dir.path(), "grasp-pull-cut.json", file))));
    const auto rows = app::loadRecordingRows(file.toStdString(), 1);
    QVERIFY(rows.checkpoints.size() > 5);
    const auto& row = rows.checkpoints[rows.checkpoints.size() / 2];
    const std::string good = row.state;
    // The setups the checkpoints name, as the file stores them (a checkpoint after a cut names the cut body's).
    std::map<std::uint64_t, simcore::BodySetup> setups;
    for (const auto& [hash, text] : rows.setups) setups[std::stoull(hash)] = app::decodeSetup(text);
    auto setupOf = [&](std::uint64_t h) {
      const auto it = setups.find(h);
      if (it == setups.end()) throw std::runtime_error("names a setup that is missing");
      return it->second;
    };
    const app::Recording rec = app::loadRecording(file.toStdString(), 1);
    const simcore::Checkpoint original = app::decodeCheckpointState(good, setupOf);
    QCOMPARE(original.step, row.step);
    // What a decoded checkpoint must do: restore into a session and take steps, each advanced (with numbers) or
    // reported failed and rolled back — never a crash or a NaN state.
    simcore::Session session(simcore::replaySetup(rec.setup));
    auto restoreAndStep = [&](const simcore::Checkpoint& c) {
      simcore::Checkpoint d = c;
      d.setup = simcore::replaySetup(std::move(d.setup));
      if (d.pendingChange) d.pendingChange->setup = simcore::replaySetup(std::move(d.pendingChange->setup));
      session.discardPending();
      session.restore(d);
      for (int k = 0; k < 3; ++k) {
        session.advance();
        if (!session.state().x.allFinite() || !session.state().v.allFinite())
          return false;  // a failed step rolls back: numbers still
      }
      return true;
    };
    // Undamaged, it restores and steps.
    QVERIFY(restoreAndStep(original));
    int refused = 0, decoded = 0, stepped = 0;
    auto attempt = [&](const std::string& bytes) {
      simcore::Checkpoint c;
      try {
        c = app::decodeCheckpointState(bytes, setupOf);
        QCOMPARE(c.state.v.size(), c.state.x.size());
        ++decoded;
      } catch (const std::runtime_error&) {
        ++refused;
        return;
      }
      if (decoded % 10 == 1) {  // one in ten decoded variants restored and stepped
        if (!restoreAndStep(c)) QFAIL("a decoded checkpoint stepped to NaN");
        ++stepped;
      }
    };
    // Issue 60: a checkpoint carries the digest of its bytes, so every truncation and every change is refused before
    // any byte is read as a state. The decoder behind the digest is exercised as a forger would: each damaged body
    // sealed again with a digest of its own.
    const std::string body = good.substr(0, good.size() - 8);
    auto sealed = [](const std::string& b) {
      std::uint64_t h = 1469598103934665603ull;
      for (char ch : b) h = (h ^ static_cast<unsigned char>(ch)) * 1099511628211ull;
      return b + std::string(reinterpret_cast<const char*>(&h), 8);
    };
    QCOMPARE(sealed(body), good);  // the digest is FNV-1a 64 of the bytes before it
    int digestRefused = 0, changedAtAll = 0;
    auto refusedAsStored = [&](const std::string& bytes) {
      if (bytes == good) return;
      ++changedAtAll;
      try {
        app::decodeCheckpointState(bytes, setupOf);
      } catch (const std::runtime_error&) {
        ++digestRefused;
      }
    };
    for (std::size_t n = 0; n < body.size(); n += 1 + body.size() / 1500) {
      refusedAsStored(good.substr(0, n));
      attempt(sealed(body.substr(0, n)));
    }
    std::mt19937 rng(3);
    for (int k = 0; k < 3000; ++k) {
      std::string bad = body, badStored = good;
      const int changes = 1 + static_cast<int>(rng() % 4);
      for (int j = 0; j < changes; ++j) {
        // Mostly in the first 200 bytes (magic, step, lengths) where a change matters most.
        const std::size_t at = (rng() % 4 ? rng() % std::min<std::size_t>(200, bad.size()) : rng() % bad.size());
        const char value = static_cast<char>(rng());
        bad[at] = value;
        badStored[at] = value;
      }
      refusedAsStored(badStored);
      attempt(sealed(bad));
    }
    qInfo("as stored: %d of %d damaged checkpoints refused by their digest", digestRefused, changedAtAll);
    QCOMPARE(digestRefused, changedAtAll);
    QVERIFY2(decoded > 100, "random changes in the doubles decode (the test must reach the restore)");
    QVERIFY(stepped > 10);
    qInfo("damaged checkpoints: %d refused, %d decoded (changes in doubles), %d of these restored and stepped 3 steps",
          refused, decoded, stepped);
    QVERIFY(refused > 1000);
    // A replayer meeting one: one sentence.
    sqlite3* db = nullptr;
    QCOMPARE(sqlite3_open(file.toUtf8().constData(), &db), SQLITE_OK);
    QCOMPARE(sqlite3_exec(db, "UPDATE rehearsal_checkpoints SET state = x'00112233'", nullptr, nullptr, nullptr),
             SQLITE_OK);
    sqlite3_close(db);
    // Issue 60: it passes over every damaged one (with a sentence naming the nearest) and replays from the start,
    // landing on the recorded state.
    app::Replayer replayer(app::loadRecording(file.toStdString(), 1));
    replayer.seek(300);
    QCOMPARE(replayer.step(), 300L);
    QVERIFY(replayer.lastSeekFrom() <= 0);  // from the start (where the replayer was)
    const QString note = QString::fromStdString(replayer.lastSeekNote());
    long nearest = 0;  // the checkpoint a seek to 300 starts from when it is sound
    for (long st : rec.checkpointSteps)
      if (st <= 300) nearest = std::max(nearest, st);
    QVERIFY2(note.count('\n') == 0 && note.contains(QString("the checkpoint after step %1 is damaged").arg(nearest)),
             qPrintable(note));
    QVERIFY(rec.checksums.count(300));
    QCOMPARE(app::stateChecksum(replayer.state()), rec.checksums.at(300));
  }

  // Issue 60: --verify checks every checkpoint (decoded, and the state it restores the straight replay's at its step).
  // One truncated to a third and one with a single byte changed are each named with their step (exit 4); the run
  // itself still verifies, and a seek onto either starts from the nearest sound one with a sentence, landing on the
  // recorded state.
  void damagedCheckpointsAreNamedByVerify() {
    QTemporaryDir dir;
    const QString file = dir.path() + "/case.rehearse";
    QVERIFY(::testing::tookEveryStep(run(gestureArgs(dir.path(), "grasp-pull.json", file))));
    const auto rows = app::loadRecordingRows(file.toStdString(), 1);
    QVERIFY(rows.checkpoints.size() >= 6);
    const Run sound = run({"replay", file, "--session", "1", "--verify"});
    QVERIFY2(sound.code == 0, qPrintable(sound.err));
    QVERIFY2(sound.out.contains(QString("all %1 checkpoints restore the replay's state").arg(rows.checkpoints.size())),
             qPrintable(sound.out));
    const long truncated = rows.checkpoints[1].step, flipped = rows.checkpoints[4].step;
    sqlite3* db = nullptr;
    QCOMPARE(sqlite3_open(file.toUtf8().constData(), &db), SQLITE_OK);
    QCOMPARE(sqlite3_exec(db,
                          ("UPDATE rehearsal_checkpoints SET state = substr(state, 1, length(state) / 3) WHERE step = " +
                           std::to_string(truncated))
                              .c_str(),
                          nullptr, nullptr, nullptr),
             SQLITE_OK);
    QCOMPARE(sqlite3_changes(db), 1);
    std::string bytes = rows.checkpoints[4].state;
    bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 0x10);  // one byte, in the state's doubles
    sqlite3_stmt* q = nullptr;
    QCOMPARE(sqlite3_prepare_v2(db, "UPDATE rehearsal_checkpoints SET state = ? WHERE step = ?", -1, &q, nullptr),
             SQLITE_OK);
    sqlite3_bind_blob(q, 1, bytes.data(), static_cast<int>(bytes.size()), SQLITE_TRANSIENT);
    sqlite3_bind_int64(q, 2, flipped);
    QCOMPARE(sqlite3_step(q), SQLITE_DONE);
    sqlite3_finalize(q);
    // Two rows deleted, one between sound ones and the last: nothing in the file says they were there but the recorder's
    // rule (every N steps and after each cut), which the replay follows.
    const long deleted = rows.checkpoints[2].step, deletedLast = rows.checkpoints.back().step;
    for (const long step : {deleted, deletedLast}) {
      QCOMPARE(sqlite3_exec(db, ("DELETE FROM rehearsal_checkpoints WHERE step = " + std::to_string(step)).c_str(),
                            nullptr, nullptr, nullptr),
               SQLITE_OK);
      QCOMPARE(sqlite3_changes(db), 1);
    }
    sqlite3_close(db);
    const Run v = run({"replay", file, "--session", "1", "--verify"});
    qInfo("%s", qPrintable(v.err.trimmed()));
    QCOMPARE(v.code, 4);
    QVERIFY2(v.err.contains(QString("the checkpoint after step %1 is damaged").arg(truncated)), qPrintable(v.err));
    QVERIFY2(v.err.contains(QString("the checkpoint after step %1 is damaged").arg(flipped)), qPrintable(v.err));
    for (const long step : {deleted, deletedLast})
      QVERIFY2(v.err.contains(QString("the checkpoint after step %1 is damaged: its row is missing").arg(step)),
               qPrintable(v.err));
    QVERIFY2(v.err.contains(QString("4 of %1 checkpoints are damaged").arg(rows.checkpoints.size())),
             qPrintable(v.err));
    QVERIFY2(v.err.contains("all 35 checksums match"), qPrintable(v.err));
    // The metrics say so too (the replay check), exit 4.
    const Run m = run({"replay", file, "--session", "1", "--metrics", dir.path() + "/m.json"});
    QCOMPARE(m.code, 4);  // written, and saying why they are not taken as verified
    QCOMPARE(m.err.trimmed().count('\n'), 0);
    QVERIFY2(m.err.contains(QString("the checkpoint after step %1 is damaged").arg(truncated)), qPrintable(m.err));
    QFile mj(dir.path() + "/m.json");
    QVERIFY(mj.open(QIODevice::ReadOnly));
    const QJsonObject metrics = QJsonDocument::fromJson(mj.readAll()).object();
    QCOMPARE(metrics["replay_verified"].toBool(true), false);
    QVERIFY2(metrics["replay_check"].toString().contains(QString("the checkpoint after step %1 is damaged").arg(truncated)),
             qPrintable(metrics["replay_check"].toString()));
    // Seeking without a verify first: each damaged one is found when met, passed over with a sentence.
    const app::Recording rec = app::loadRecording(file.toStdString(), 1);
    for (const long damaged : {flipped, truncated}) {
      app::Replayer replayer(rec);
      const long target = damaged + 10;
      replayer.seek(target);
      const QString note = QString::fromStdString(replayer.lastSeekNote());
      qInfo("seek to %ld: %s", target, qPrintable(note));
      QVERIFY2(note.contains(QString("the checkpoint after step %1 is damaged").arg(damaged)), qPrintable(note));
      QVERIFY(replayer.lastSeekFrom() < damaged);
      QVERIFY(rec.checksums.count(target));
      QCOMPARE(app::stateChecksum(replayer.state()), rec.checksums.at(target));
    }
  }

  // Hostile recordings (issue 32): a setup or an event changed in the file — an index out of range or negative,
  // a float where an index goes, an unknown law, method or event kind, a number that is not one, events out of
  // order, a damaged checksum — is refused by `rehearse replay --verify` with one sentence and exit 1, never a
  // signal (an out-of-range tet index made it die with SIGSEGV before).
  void hostileRecordingsAreRefused() {
    QTemporaryDir dir;
    const QString file = dir.path() + "/case.rehearse";
    QVERIFY(::testing::tookEveryStep(run(gestureArgs(dir.path(), "grasp-pull.json", file))));
    const auto rec = app::loadRecording(file.toStdString(), 1);
    const int nodes = static_cast<int>(rec.setup.mesh.points.size());
    QVERIFY(nodes > 100 && !rec.events.empty());
    using J = nlohmann::json;
    struct Change {
      const char* what;
      std::function<void(J&)> setup;                // on the session's setup JSON
      std::function<void(std::vector<J>&)> events;  // on its events
      const char* sql = nullptr;
    };
    const std::vector<Change> changes = {
        {"a tet index past the last node", [&](J& j) { j["mesh"]["tets"][5][2] = nodes + 7; }, nullptr},
        {"a negative tet index", [&](J& j) { j["mesh"]["tets"][0][0] = -3; }, nullptr},
        {"a float as a tet index", [&](J& j) { j["mesh"]["tets"][1][1] = 2.5; }, nullptr},
        {"a huge tet index", [&](J& j) { j["mesh"]["tets"][1][1] = 1e300; }, nullptr},
        {"a triangle index out of range",
         [&](J& j) {
           j["mesh"]["triangles"].push_back({0, 1, nodes});
         },
         nullptr},
        {"an attachment out of range", [&](J& j) { j["fixedNodes"].push_back(1 << 30); }, nullptr},
        {"fewer element labels than elements", [&](J& j) { j["mesh"]["tetLabels"].erase(0); }, nullptr},
        {"an unknown material law", [&](J& j) { j["material"]["model"] = 9; }, nullptr},
        {"no density (NaN is written as null)", [&](J& j) { j["material"]["density"] = nullptr; }, nullptr},
        {"a negative Young's modulus", [&](J& j) { j["material"]["young"] = -5.0; }, nullptr},
        {"a Poisson ratio of 0.5", [&](J& j) { j["material"]["poisson"] = 0.5; }, nullptr},
        {"an unknown method", [&](J& j) { j["settings"]["method"] = 7; }, nullptr},
        {"an unknown solver", [&](J& j) { j["settings"]["solver"] = -1; }, nullptr},
        {"a zero time step", [&](J& j) { j["settings"]["timeStep"] = 0.0; }, nullptr},
        {"a rest position list of another length",
         [&](J& j) {
           j["rest"] = j["mesh"]["points"];
           j["rest"].erase(0);
         },
         nullptr},
        {"an unknown event kind", nullptr, [](std::vector<J>& e) { e[0]["kind"] = 42; }},
        {"an event position that is no number", nullptr, [](std::vector<J>& e) { e[0]["position"][1] = nullptr; }},
        {"an unknown material law as a parameter event", nullptr,
         [](std::vector<J>& e) {
           e[0] = J{{"kind", 3},       {"wallTime", 0.0},       {"step", e[0]["step"]}, {"tool", 0},
                    {"label", 0},      {"position", {0, 0, 0}}, {"vector", {0, 0, 0}},  {"on", false},
                    {"name", "model"}, {"value", 99.0}};
         }},
        {"an unknown parameter event", nullptr,
         [](std::vector<J>& e) { e[0]["kind"] = 3, e[0]["name"] = "viscosity"; }},
        {"events out of order", nullptr, [](std::vector<J>& e) { e.back()["step"] = 0; }},
        {"a damaged checksum", nullptr, nullptr, "UPDATE rehearsal_checksums SET checksum = 'x12' WHERE step = 100"},
    };
    int refused = 0;
    for (const auto& c : changes) {
      const QString copy = dir.path() + "/hostile.rehearse";
      QFile::remove(copy);
      QVERIFY(QFile::copy(file, copy));
      sqlite3* db = nullptr;
      QCOMPARE(sqlite3_open(copy.toUtf8().constData(), &db), SQLITE_OK);
      if (c.setup) {
        J j = J::parse(app::loadRecordingRows(copy.toStdString(), 1).setup);
        c.setup(j);
        sqlite3_stmt* q = nullptr;
        sqlite3_prepare_v2(db, "UPDATE rehearsal_sessions SET setup = ? WHERE id = 1", -1, &q, nullptr);
        const std::string text = j.dump();
        sqlite3_bind_text(q, 1, text.c_str(), -1, SQLITE_TRANSIENT);
        QCOMPARE(sqlite3_step(q), SQLITE_DONE);
        sqlite3_finalize(q);
      }
      if (c.events) {
        const auto rows = app::loadRecordingRows(copy.toStdString(), 1);
        std::vector<J> events;
        for (const auto& [seq, step, text] : rows.events) events.push_back(J::parse(text));
        c.events(events);
        for (std::size_t k = 0; k < events.size(); ++k) {
          sqlite3_stmt* q = nullptr;
          sqlite3_prepare_v2(db, "UPDATE rehearsal_events SET event = ?, step = ? WHERE session = 1 AND seq = ?", -1,
                             &q, nullptr);
          const std::string text = events[k].dump();
          sqlite3_bind_text(q, 1, text.c_str(), -1, SQLITE_TRANSIENT);
          sqlite3_bind_int64(q, 2, events[k]["step"].is_number_integer() ? events[k]["step"].get<long long>() : -1);
          sqlite3_bind_int64(q, 3, static_cast<sqlite3_int64>(k));
          QCOMPARE(sqlite3_step(q), SQLITE_DONE);
          sqlite3_finalize(q);
        }
      }
      if (c.sql) QCOMPARE(sqlite3_exec(db, c.sql, nullptr, nullptr, nullptr), SQLITE_OK);
      sqlite3_close(db);
      const Run v = run({"replay", copy, "--session", "1", "--verify"});
      QVERIFY2(v.code != -1, qPrintable(QString("%1: the replay crashed").arg(c.what)));
      QVERIFY2(v.code == 1,
               qPrintable(QString("%1: exit %2, %3 %4").arg(c.what).arg(v.code).arg(v.out.right(300), v.err)));
      QVERIFY2(v.err.trimmed().count('\n') == 0 && !v.err.trimmed().isEmpty(),
               qPrintable(QString("%1: %2").arg(c.what, v.err)));
      qInfo("%s: %s", c.what, qPrintable(v.err.trimmed()));
      ++refused;
    }
    QCOMPARE(refused, static_cast<int>(changes.size()));
    // The original still verifies (the changes above were each made on a copy).
    QCOMPARE(run({"replay", file, "--session", "1", "--verify"}).code, 0);
  }

  // A checksum changed in the file: --verify says where and exits 4; a missing session is one line, exit 1.
  void tamperedChecksumIsCaught() {
    QTemporaryDir dir;
    const QString file = dir.path() + "/case.rehearse";
    QVERIFY(::testing::tookEveryStep(run(gestureArgs(dir.path(), "grasp-pull.json", file))));
    sqlite3* db = nullptr;
    QCOMPARE(sqlite3_open(file.toUtf8().constData(), &db), SQLITE_OK);
    QCOMPARE(sqlite3_exec(db, "UPDATE rehearsal_checksums SET checksum = '12345' WHERE step = 200", nullptr, nullptr,
                          nullptr),
             SQLITE_OK);
    QCOMPARE(sqlite3_changes(db), 1);
    sqlite3_close(db);
    const Run v = run({"replay", file, "--session", "1", "--verify"});
    QCOMPARE(v.code, 4);
    QCOMPARE(v.err.trimmed().count('\n'), 0);
    QVERIFY2(v.err.contains("1 of 35 checksums differ, the first after step 200"), qPrintable(v.err));
    // Its metrics are written, saying so, and the command exits 4 as --verify does (not 0, as if they were the
    // trainee's).
    const Run m = run({"replay", file, "--session", "1", "--metrics", dir.path() + "/m.json"});
    QCOMPARE(m.code, 4);
    QCOMPARE(m.err.trimmed().count('\n'), 0);
    QVERIFY2(m.err.contains("DOES NOT VERIFY: 1 of 35"), qPrintable(m.err));
    QFile mj(dir.path() + "/m.json");
    QVERIFY(mj.open(QIODevice::ReadOnly));
    const QJsonObject metrics = QJsonDocument::fromJson(mj.readAll()).object();
    QCOMPARE(metrics["replay_verified"].toBool(true), false);
    QCOMPARE(metrics["checksums_differing"].toInt(), 1);
    const Run missing = run({"replay", file, "--session", "7", "--verify"});
    QCOMPARE(missing.code, 1);
    QVERIFY2(missing.err.contains("no recorded session 7"), qPrintable(missing.err));
    const Run notSqlite =
        run({"replay", QStringLiteral(REHEARSE_SOURCE_DIR) + "/resources/gestures/grasp-pull.json", "--session", "1"});
    QCOMPARE(notSqlite.code, 1);
    QCOMPARE(notSqlite.err.trimmed().count('\n'), 0);
  }

  // SIGKILL at random moments of a recording: the file opens whole every time, the session is listed (cut
  // short), and what it holds replays and verifies.
  void killedRecordingsOpenAndVerify() {
    QTemporaryDir dir;
    const QString file = dir.path() + "/case.rehearse";
    // How long a whole recording takes here: the kills fall anywhere in it (from the start of the process).
    QElapsedTimer whole;
    whole.start();
    QVERIFY(::testing::tookEveryStep(run(gestureArgs(dir.path(), "grasp-pull.json", file))));
    const int fullMs = static_cast<int>(whole.elapsed());
    // 12 kills (20 before: 54 s of the CI; the ones before a session began prove nothing, about a tenth).
    constexpr int kKills = 12;
    std::mt19937 rng(20261125);
    std::uniform_int_distribution<int> when(fullMs / 10, fullMs - 50);
    int verifiedSessions = 0, killedBeforeARow = 0;
    long verifiedChecksums = 0;
    std::size_t listed = app::listRecordings(file.toStdString()).size();
    for (int k = 0; k < kKills; ++k) {
      QProcess p;
      p.start(QStringLiteral(REHEARSE_BINARY), gestureArgs(dir.path(), "grasp-pull.json", file));
      QVERIFY(p.waitForStarted());
      const int ms = when(rng);
      p.waitForFinished(ms);
      if (p.state() != QProcess::NotRunning) p.kill();  // SIGKILL
      p.waitForFinished();
      const auto sessions = app::listRecordings(file.toStdString());  // opens whole
      QVERIFY(sessions.size() >= listed);
      if (sessions.size() == listed) {  // killed before the session began (the body was being built)
        ++killedBeforeARow;
        continue;
      }
      listed = sessions.size();
      const auto& last = sessions.back();
      const auto rec = app::loadRecording(file.toStdString(), last.id);
      const auto v = app::verifyRecording(rec);
      QCOMPARE(v.mismatches, 0L);
      verifiedChecksums += v.checked;
      ++verifiedSessions;
    }
    const auto sessions = app::listRecordings(file.toStdString());
    int cutShort = 0;
    for (const auto& s : sessions) cutShort += !s.complete;
    qInfo(
        "a whole recording %d ms; %d killed at random moments: %d before their session began, %zu sessions in the file "
        "(%d cut short), %d verified "
        "(%ld checksums), none differs",
        fullMs, kKills, killedBeforeARow, sessions.size(), cutShort, verifiedSessions, verifiedChecksums);
    QVERIFY(cutShort > 0);
    QVERIFY(verifiedChecksums > 0);
  }
};

QTEST_MAIN(TestRecordingFiles)
#include "test_recording_files.moc"
