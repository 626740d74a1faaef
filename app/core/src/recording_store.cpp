// The recordings' store in a case file (SQLite): its schema, listing and loading sessions, their checkpoints and
// thresholds, and copying them into another file (Save As). The recorder that writes them is recorder.cpp.
#include "rehearse/app/recording.hpp"

#include "recording_codec.hpp"
#include "recording_store.hpp"

#include <rehearse/simcore/input_ranges.hpp>

#include <nlohmann/json.hpp>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <ctime>
#include <set>
#include <stdexcept>

namespace rehearse::app {
namespace detail {

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

constexpr const char* kSchema =
    "CREATE TABLE IF NOT EXISTS rehearsal_sessions(id INTEGER PRIMARY KEY AUTOINCREMENT, trainee TEXT, started_utc "
    "TEXT, case_name TEXT, "
    "scene_version TEXT, app_version TEXT, notes TEXT, setup TEXT NOT NULL, time_step REAL, checksum_every INTEGER, "
    "steps INTEGER DEFAULT 0, "
    "complete INTEGER DEFAULT 0);"
    "CREATE TABLE IF NOT EXISTS rehearsal_events(session INTEGER NOT NULL, seq INTEGER NOT NULL, step INTEGER NOT "
    "NULL, event TEXT NOT NULL, "
    "PRIMARY KEY(session, seq));"
    "CREATE TABLE IF NOT EXISTS rehearsal_checksums(session INTEGER NOT NULL, step INTEGER NOT NULL, checksum TEXT NOT "
    "NULL, PRIMARY KEY(session, step));"
    "CREATE TABLE IF NOT EXISTS rehearsal_setups(session INTEGER NOT NULL, hash TEXT NOT NULL, setup TEXT NOT NULL, "
    "PRIMARY KEY(session, hash));"
    "CREATE TABLE IF NOT EXISTS rehearsal_checkpoints(session INTEGER NOT NULL, step INTEGER NOT NULL, setup_hash TEXT "
    "NOT NULL, state BLOB NOT NULL, "
    "PRIMARY KEY(session, step));";

int readingFlags(const std::string& path) {
  const std::string folder = std::filesystem::path(path).parent_path().string();
  const bool writable = ::access(path.c_str(), W_OK) == 0 && ::access(folder.empty() ? "." : folder.c_str(), W_OK) == 0;
  return writable ? SQLITE_OPEN_READWRITE : SQLITE_OPEN_READONLY;
}

sqlite3* openStore(const std::string& path, bool create) {
  // A FIFO or a device where the recording goes: SQLite's open and first read would block on it for ever (a replay of
  // a FIFO named .rehearse hung). Only a regular file (or none yet, to create) is opened.
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    throw std::runtime_error(path + " is not a regular file (a folder, a pipe or a device); a recording is a file");
  sqlite3* db = nullptr;
  const int flags = create ? SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE : readingFlags(path);
  if (sqlite3_open_v2(path.c_str(), &db, flags, nullptr) != SQLITE_OK) {
    const std::string why = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    throw std::runtime_error("cannot open " + path + " for recordings: " + why);
  }
  sqlite3_busy_timeout(db, 5000);
  return db;
}

// A session's checksum after `step` through `q` (INSERT, or INSERT OR IGNORE when written again).
void writeChecksum(sqlite3* db, Statement& q, std::int64_t session, long step, std::uint64_t sum) {
  sqlite3_reset(q.s);
  sqlite3_bind_int64(q.s, 1, session);
  sqlite3_bind_int64(q.s, 2, step);
  q.text(3, std::to_string(sum));
  if (sqlite3_step(q.s) != SQLITE_DONE)
    throw std::runtime_error(std::string("the recording store refused a checksum: ") + sqlite3_errmsg(db));
}

bool hasTable(sqlite3* db, const char* name) {
  Statement q(db, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?");
  q.text(1, name);
  return sqlite3_step(q.s) == SQLITE_ROW;
}

namespace {
bool hasColumn(sqlite3* db, const char* table, const char* column) {
  Statement q(db, (std::string("PRAGMA table_info(") + table + ")").c_str());
  while (sqlite3_step(q.s) == SQLITE_ROW)
    if (q.column(1) == column) return true;
  return false;
}
}  // namespace

void ensureSchema(sqlite3* db) {
  char* err = nullptr;
  auto run = [&](const char* sql) {
    if (sqlite3_exec(db, sql, nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string why = err ? err : "unknown error";
      sqlite3_free(err);
      throw std::runtime_error("the recording store refused a write: " + why);
    }
  };
  run(kSchema);
  if (!hasColumn(db, "rehearsal_sessions", "uuid")) run("ALTER TABLE rehearsal_sessions ADD COLUMN uuid TEXT");
  run("UPDATE rehearsal_sessions SET uuid = lower(hex(randomblob(16))) WHERE uuid IS NULL OR uuid = ''");
  if (!hasColumn(db, "rehearsal_sessions", "rules")) run("ALTER TABLE rehearsal_sessions ADD COLUMN rules TEXT");
  run("CREATE UNIQUE INDEX IF NOT EXISTS rehearsal_sessions_uuid ON rehearsal_sessions(uuid)");
}

}  // namespace detail

using nlohmann::json;
using namespace detail;

std::vector<RecordingSummary> listRecordings(const std::string& path) {
  sqlite3* db = openStore(path, false);
  std::vector<RecordingSummary> out;
  try {
    if (hasTable(db, "rehearsal_sessions")) {
      const bool uuid = hasColumn(db, "rehearsal_sessions", "uuid"),
                 rules = hasColumn(db, "rehearsal_sessions", "rules");
      const std::string sql =
          std::string(
              "SELECT id, trainee, started_utc, case_name, scene_version, app_version, notes, steps, "
              "complete, ") +
          (uuid ? "uuid" : "''") + ", " + (rules ? "rules" : "''") + " FROM rehearsal_sessions ORDER BY id";
      Statement q(db, sql.c_str());
      int rc;
      while ((rc = sqlite3_step(q.s)) == SQLITE_ROW) {
        RecordingSummary r;
        r.id = sqlite3_column_int64(q.s, 0);
        r.meta = {q.column(1), q.column(3), q.column(4), q.column(5), q.column(6), ""};
        r.startedUtc = q.column(2);
        r.steps = static_cast<long>(sqlite3_column_int64(q.s, 7));
        r.complete = sqlite3_column_int(q.s, 8) != 0;
        r.uuid = q.column(9);
        r.meta.rules = q.column(10);
        if (r.steps < 0)
          throw std::runtime_error("session " + std::to_string(r.id) + " in " + path + " has a negative step count");
        out.push_back(std::move(r));
      }
      if (rc != SQLITE_DONE)
        throw std::runtime_error(std::string("the recordings in ") + path + " cannot be read: " + sqlite3_errmsg(db));
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  return out;
}

Recording loadRecording(const std::string& path, std::int64_t id) {
  Recording r;
  int found = 0;
  for (auto& s : listRecordings(path))
    if (s.id == id) {
      r.summary = std::move(s);
      ++found;
    }
  if (!found) throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
  // A file written by another program can hold a sessions table without its key: two rows of one session would mix
  // one's setup with the other's summary.
  if (found > 1)
    throw std::runtime_error(path + " holds session " + std::to_string(id) + " " + std::to_string(found) +
                             " times (the file is damaged)");
  sqlite3* db = openStore(path, false);
  try {
    {
      Statement q(db, "SELECT setup, checksum_every FROM rehearsal_sessions WHERE id = ?");
      sqlite3_bind_int64(q.s, 1, id);
      if (sqlite3_step(q.s) != SQLITE_ROW)
        throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
      try {
        r.setup = decodeSetup(q.column(0), &r.numerics);
      } catch (const std::exception& e) {
        throw std::runtime_error("session " + std::to_string(id) + " in " + path + ": " + e.what());
      }
      r.checksumEvery = sqlite3_column_int(q.s, 1);
      if (r.checksumEvery < 1)
        throw std::runtime_error("session " + std::to_string(id) + " in " + path + " has no checksum interval");
    }
    {
      Statement q(db, "SELECT event, step FROM rehearsal_events WHERE session = ? ORDER BY seq");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) {
        r.events.push_back(decodeEvent(q.column(0)));
        // The events apply at step boundaries in order: a step going back or beyond the session cannot be replayed.
        const long step = r.events.back().step;
        if (step != sqlite3_column_int64(q.s, 1) || (r.events.size() > 1 && step < r.events[r.events.size() - 2].step))
          throw std::runtime_error("session " + std::to_string(id) + " in " + path +
                                   " has its events out of order (damaged)");
      }
    }
    {
      Statement q(db, "SELECT step, checksum FROM rehearsal_checksums WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) {
        const std::string text = q.column(1);
        char* end = nullptr;
        errno = 0;
        const unsigned long long sum = std::strtoull(text.c_str(), &end, 10);
        const long step = static_cast<long>(sqlite3_column_int64(q.s, 0));
        if (text.empty() || errno != 0 || *end != '\0' || step < 1)
          throw std::runtime_error("session " + std::to_string(id) + " in " + path + " has a damaged checksum (step " +
                                   std::to_string(step) + ")");
        r.checksums[step] = sum;
      }
    }
    if (hasTable(db, "rehearsal_checkpoints")) {
      Statement q(db, "SELECT step FROM rehearsal_checkpoints WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW)
        r.checkpointSteps.push_back(static_cast<long>(sqlite3_column_int64(q.s, 0)));
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  // A session cut short: its last checksum bounds what can be verified.
  if (!r.checksums.empty()) r.summary.steps = std::max(r.summary.steps, r.checksums.rbegin()->first);
  r.path = path;
  if (const std::string why = recordingLengthProblem(r); !why.empty())
    throw std::runtime_error("session " + std::to_string(id) + " in " + path + " " + why);
  return r;
}

RecordingRows loadRecordingRows(const std::string& path, std::int64_t id) {
  RecordingRows rows;
  sqlite3* db = openStore(path, false);
  try {
    {
      Statement q(db, "SELECT setup FROM rehearsal_sessions WHERE id = ?");
      sqlite3_bind_int64(q.s, 1, id);
      if (sqlite3_step(q.s) != SQLITE_ROW)
        throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
      rows.setup = q.column(0);
    }
    {
      Statement q(db, "SELECT seq, step, event FROM rehearsal_events WHERE session = ? ORDER BY seq");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW)
        rows.events.emplace_back(static_cast<long>(sqlite3_column_int64(q.s, 0)),
                                 static_cast<long>(sqlite3_column_int64(q.s, 1)), q.column(2));
    }
    {
      Statement q(db, "SELECT step, checksum FROM rehearsal_checksums WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW)
        rows.checksums.emplace_back(static_cast<long>(sqlite3_column_int64(q.s, 0)), q.column(1));
    }
    if (hasTable(db, "rehearsal_setups")) {
      Statement q(db, "SELECT hash, setup FROM rehearsal_setups WHERE session = ?");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) rows.setups.emplace_back(q.column(0), q.column(1));
    }
    if (hasTable(db, "rehearsal_checkpoints")) {
      Statement q(db, "SELECT step, setup_hash, state FROM rehearsal_checkpoints WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) {
        RecordingRows::CheckpointRow c;
        c.step = static_cast<long>(sqlite3_column_int64(q.s, 0));
        c.setupHash = q.column(1);
        const auto* blob = static_cast<const char*>(sqlite3_column_blob(q.s, 2));
        c.state.assign(blob ? blob : "", static_cast<std::size_t>(sqlite3_column_bytes(q.s, 2)));
        rows.checkpoints.push_back(std::move(c));
      }
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  return rows;
}

simcore::Checkpoint loadCheckpoint(const std::string& path, std::int64_t id, long step) {
  sqlite3* db = openStore(path, false);
  simcore::Checkpoint c;
  try {
    std::string bytes, namedHash;
    {
      Statement q(db, "SELECT state, setup_hash FROM rehearsal_checkpoints WHERE session = ? AND step = ?");
      sqlite3_bind_int64(q.s, 1, id);
      sqlite3_bind_int64(q.s, 2, step);
      if (sqlite3_step(q.s) != SQLITE_ROW)
        throw std::runtime_error(path + " has no checkpoint at step " + std::to_string(step) + " of session " +
                                 std::to_string(id));
      const auto* blob = static_cast<const char*>(sqlite3_column_blob(q.s, 0));
      bytes.assign(blob ? blob : "", static_cast<std::size_t>(sqlite3_column_bytes(q.s, 0)));
      namedHash = q.column(1);
    }
    // The row names the setup its bytes name (the first hash they hold): a row whose column was changed is damaged.
    if (bytes.size() >= 20) {
      std::uint64_t inBytes = 0;
      std::memcpy(&inBytes, bytes.data() + 12, sizeof inBytes);  // after the magic (4 bytes) and the step (8 bytes)
      if (namedHash != std::to_string(inBytes))
        throw std::runtime_error(path + ": the checkpoint at step " + std::to_string(step) +
                                 " names another setup in its row than in its bytes (damaged)");
    }
    c = decodeCheckpointState(bytes, [&](std::uint64_t hash) {
      Statement q(db, "SELECT setup FROM rehearsal_setups WHERE session = ? AND hash = ?");
      sqlite3_bind_int64(q.s, 1, id);
      q.text(2, std::to_string(hash));
      if (sqlite3_step(q.s) != SQLITE_ROW)
        throw std::runtime_error(path + ": the checkpoint at step " + std::to_string(step) +
                                 " names a setup that is missing");
      return decodeSharedSetup(q.column(0), hash);
    });
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  if (c.step != step)
    throw std::runtime_error(path + ": the checkpoint at step " + std::to_string(step) + " holds another step");
  return c;
}

std::string loadCaseThresholds(const std::string& path) {
  sqlite3* db = openStore(path, false);
  std::string out;
  if (hasTable(db, "rehearsal_thresholds")) {
    Statement q(db, "SELECT json FROM rehearsal_thresholds WHERE id = 1");
    if (sqlite3_step(q.s) == SQLITE_ROW) out = q.column(0);
  }
  sqlite3_close(db);
  return out;
}

void saveCaseThresholds(const std::string& path, const std::string& json) {
  sqlite3* db = openStore(path, true);
  char* err = nullptr;
  int rc = sqlite3_exec(
      db, "CREATE TABLE IF NOT EXISTS rehearsal_thresholds(id INTEGER PRIMARY KEY CHECK(id = 1), json TEXT NOT NULL)",
      nullptr, nullptr, &err);
  if (rc == SQLITE_OK) {
    Statement q(db, "INSERT OR REPLACE INTO rehearsal_thresholds(id, json) VALUES(1, ?)");
    q.text(1, json);
    rc = sqlite3_step(q.s) == SQLITE_DONE ? SQLITE_OK : SQLITE_ERROR;
  }
  const std::string why = err ? err : sqlite3_errmsg(db);
  sqlite3_free(err);
  sqlite3_close(db);
  if (rc != SQLITE_OK) throw std::runtime_error("the thresholds could not be kept in " + path + ": " + why);
}

int copyRecordings(const std::string& from, const std::string& to) {
  int sessions = 0;
  {
    sqlite3* src = openStore(from, false);
    const bool has = hasTable(src, "rehearsal_sessions");
    if (has) {
      Statement q(src, "SELECT COUNT(*) FROM rehearsal_sessions");
      if (sqlite3_step(q.s) == SQLITE_ROW) sessions = sqlite3_column_int(q.s, 0);
    }
    sqlite3_close(src);
    if (!has) return 0;
  }
  sqlite3* db = openStore(to, true);
  auto run = [&](const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string why = err ? err : "unknown error";
      sqlite3_free(err);
      sqlite3_close(db);
      throw std::runtime_error("the recorded sessions could not be carried into the saved case: " + why);
    }
  };
  std::string quoted;
  for (char ch : from) {
    quoted += ch;
    if (ch == '\'') quoted += '\'';
  }
  try {
    ensureSchema(db);
  } catch (const std::exception& e) {
    sqlite3_close(db);
    throw std::runtime_error(std::string("the recorded sessions could not be carried into the saved case: ") +
                             e.what());
  }
  bool prevUuid = false, prevRules = false;
  {
    sqlite3* src = openStore(from, false);
    prevUuid = hasColumn(src, "rehearsal_sessions", "uuid");
    prevRules = hasColumn(src, "rehearsal_sessions", "rules");
    sqlite3_close(src);
  }
  run("ATTACH DATABASE '" + quoted + "' AS prev");
  run("BEGIN");
  // Every session with its identity (one recorded before identities existed gets one here).
  run(std::string("INSERT INTO rehearsal_sessions(id, trainee, started_utc, case_name, scene_version, app_version, "
                  "notes, setup, time_step, "
                  "checksum_every, steps, complete, uuid, rules) SELECT id, trainee, started_utc, case_name, "
                  "scene_version, app_version, notes, setup, time_step, "
                  "checksum_every, steps, complete, ") +
      (prevUuid ? "CASE WHEN uuid IS NULL OR uuid = '' THEN lower(hex(randomblob(16))) ELSE uuid END"
                : "lower(hex(randomblob(16)))") +
      (prevRules ? ", rules" : ", NULL") + " FROM prev.rehearsal_sessions");
  run("INSERT INTO rehearsal_events SELECT * FROM prev.rehearsal_events");
  run("INSERT INTO rehearsal_checksums SELECT * FROM prev.rehearsal_checksums");
  {
    sqlite3* src = openStore(from, false);
    const bool has = hasTable(src, "rehearsal_checkpoints") && hasTable(src, "rehearsal_setups");
    const bool thresholds = hasTable(src, "rehearsal_thresholds");
    sqlite3_close(src);
    if (has) {
      run("INSERT INTO rehearsal_setups SELECT * FROM prev.rehearsal_setups");
      run("INSERT INTO rehearsal_checkpoints SELECT * FROM prev.rehearsal_checkpoints");
    }
    if (thresholds) {
      run("CREATE TABLE IF NOT EXISTS rehearsal_thresholds(id INTEGER PRIMARY KEY CHECK(id = 1), json TEXT NOT NULL)");
      run("INSERT OR REPLACE INTO rehearsal_thresholds SELECT * FROM prev.rehearsal_thresholds");
    }
  }
  run("COMMIT");
  run("DETACH DATABASE prev");
  sqlite3_close(db);
  return sessions;
}

simcore::BodySetup decodeSharedSetup(const std::string& text, std::uint64_t hash) {
  RecordedNumerics numerics;
  simcore::BodySetup s = decodeSetup(text, &numerics);
  // Setups written by a build that names what recorded them hash as this one does; older ones (their hash from an
  // older setupHash) are checked by --verify instead, which compares the state each checkpoint restores.
  if (!numerics.kernel.empty() && setupHash(s) != hash)
    throw std::runtime_error("a setup the checkpoints name is not the one its hash says (the file was edited or damaged)");
  return s;
}

std::string recordingLengthProblem(const Recording& r) {
  long last = r.summary.steps;
  if (!r.checksums.empty()) last = std::max(last, r.checksums.rbegin()->first);
  if (!r.events.empty()) last = std::max(last, r.events.back().step);
  for (long s : r.checkpointSteps) last = std::max(last, s);
  if (last < 1) return {};
  const std::string why = simcore::runLengthProblem(static_cast<double>(last), r.setup.settings.timeStep);
  return why.empty() ? why : "says it ran " + std::to_string(last) + " steps: " + why + " (the file is damaged)";
}

VerifyResult verifyRecording(const Recording& r) {
  return replayRecording(r).verify;
}

}  // namespace rehearse::app
