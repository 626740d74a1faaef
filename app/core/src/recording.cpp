#include "rehearse/app/recording.hpp"

#include "rehearse/app/review.hpp"

#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <algorithm>
#include <cctype>
#include <set>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <random>
#include <stdexcept>

#include "recording_codec.hpp"

namespace rehearse::app {
namespace {

using nlohmann::json;

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}


// One prepared statement, finalised on every path.
struct Statement {
  sqlite3_stmt* s = nullptr;
  Statement(sqlite3* db, const char* sql) {
    if (sqlite3_prepare_v2(db, sql, -1, &s, nullptr) != SQLITE_OK) throw std::runtime_error(std::string("the recording store cannot be read: ") + sqlite3_errmsg(db));
  }
  ~Statement() { sqlite3_finalize(s); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  void text(int i, const std::string& v) { sqlite3_bind_text(s, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT); }
  std::string column(int i) const {
    const auto* t = sqlite3_column_text(s, i);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
};

constexpr const char* kSchema =
    "CREATE TABLE IF NOT EXISTS rehearsal_sessions(id INTEGER PRIMARY KEY AUTOINCREMENT, trainee TEXT, started_utc TEXT, case_name TEXT, "
    "scene_version TEXT, app_version TEXT, notes TEXT, setup TEXT NOT NULL, time_step REAL, checksum_every INTEGER, steps INTEGER DEFAULT 0, "
    "complete INTEGER DEFAULT 0);"
    "CREATE TABLE IF NOT EXISTS rehearsal_events(session INTEGER NOT NULL, seq INTEGER NOT NULL, step INTEGER NOT NULL, event TEXT NOT NULL, "
    "PRIMARY KEY(session, seq));"
    "CREATE TABLE IF NOT EXISTS rehearsal_checksums(session INTEGER NOT NULL, step INTEGER NOT NULL, checksum TEXT NOT NULL, PRIMARY KEY(session, step));"
    "CREATE TABLE IF NOT EXISTS rehearsal_setups(session INTEGER NOT NULL, hash TEXT NOT NULL, setup TEXT NOT NULL, PRIMARY KEY(session, hash));"
    "CREATE TABLE IF NOT EXISTS rehearsal_checkpoints(session INTEGER NOT NULL, step INTEGER NOT NULL, setup_hash TEXT NOT NULL, state BLOB NOT NULL, "
    "PRIMARY KEY(session, step));";


sqlite3* openStore(const std::string& path, bool create) {
  sqlite3* db = nullptr;
  const int flags = create ? SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE : SQLITE_OPEN_READONLY;
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
  if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a checksum: ") + sqlite3_errmsg(db));
}

bool hasTable(sqlite3* db, const char* name) {
  Statement q(db, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?");
  q.text(1, name);
  return sqlite3_step(q.s) == SQLITE_ROW;
}

}  // namespace

struct Recorder::Statements {
  Statement event, checksum, checksumAgain, steps, setup, checkpoint;
  explicit Statements(sqlite3* db)
      : event(db, "INSERT INTO rehearsal_events(session, seq, step, event) VALUES(?, ?, ?, ?)"),
        // A step recorded twice is refused, never overwritten: a restarted step count (a reset) cannot replace the record.
        checksum(db, "INSERT INTO rehearsal_checksums(session, step, checksum) VALUES(?, ?, ?)"),
        checksumAgain(db, "INSERT OR IGNORE INTO rehearsal_checksums(session, step, checksum) VALUES(?, ?, ?)"),
        steps(db, "UPDATE rehearsal_sessions SET steps = ? WHERE id = ?"),
        setup(db, "INSERT OR IGNORE INTO rehearsal_setups(session, hash, setup) VALUES(?, ?, ?)"),
        checkpoint(db, "INSERT OR REPLACE INTO rehearsal_checkpoints(session, step, setup_hash, state) VALUES(?, ?, ?, ?)") {}
};

namespace {
bool hasColumn(sqlite3* db, const char* table, const char* column) {
  Statement q(db, (std::string("PRAGMA table_info(") + table + ")").c_str());
  while (sqlite3_step(q.s) == SQLITE_ROW)
    if (q.column(1) == column) return true;
  return false;
}
// The schema, and the uuid column added to a file recorded before it existed (its sessions get one).
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
  run("CREATE UNIQUE INDEX IF NOT EXISTS rehearsal_sessions_uuid ON rehearsal_sessions(uuid)");
}
}  // namespace

Recorder::Recorder(const std::string& path, const SessionMeta& meta, const simcore::BodySetup& setup, int checksumEvery, int checkpointEvery)
    : every_(std::max(1, checksumEvery)), checkpointEvery_(std::max(1, checkpointEvery)), lastCommit_(std::chrono::steady_clock::now()) {
  path_ = path;
  uuid_ = newSessionUuid();
  meta_ = meta;
  startedUtc_ = utcNow();
  setupText_ = encodeSetup(setup);
  timeStep_ = setup.settings.timeStep;
  open(path);
}

void Recorder::open(const std::string& path) {
  db_ = openStore(path, true);
  try {
    exec("PRAGMA journal_mode=WAL");
    exec("PRAGMA synchronous=NORMAL");
    ensureSchema(db_);
    exec("BEGIN");
    id_ = 0;
    {
      Statement q(db_, "SELECT id FROM rehearsal_sessions WHERE uuid = ?");
      q.text(1, uuid_);
      if (sqlite3_step(q.s) == SQLITE_ROW) id_ = sqlite3_column_int64(q.s, 0);
    }
    if (id_ == 0) {  // a new session, or a file that lost it: its row (what it held is written again)
      Statement q(db_, "INSERT INTO rehearsal_sessions(trainee, started_utc, case_name, scene_version, app_version, notes, setup, time_step, checksum_every, uuid) "
                       "VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
      q.text(1, meta_.trainee);
      q.text(2, startedUtc_);
      q.text(3, meta_.caseName);
      q.text(4, meta_.sceneVersion);
      q.text(5, meta_.appVersion);
      q.text(6, meta_.notes);
      q.text(7, setupText_);
      sqlite3_bind_double(q.s, 8, timeStep_);
      sqlite3_bind_int(q.s, 9, every_);
      q.text(10, uuid_);
      if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("cannot record into ") + path + ": " + sqlite3_errmsg(db_));
      id_ = sqlite3_last_insert_rowid(db_);
      written_ = 0;
    } else {
      Statement q(db_, "SELECT COUNT(*) FROM rehearsal_events WHERE session = ?");
      sqlite3_bind_int64(q.s, 1, id_);
      const long copied = sqlite3_step(q.s) == SQLITE_ROW ? static_cast<long>(sqlite3_column_int64(q.s, 0)) : 0;
      written_ = std::min(written_, static_cast<std::size_t>(copied));  // events are written in order: the copy holds a prefix
    }
    commitIfDue(true);  // the session is listed from the start
    statements_ = std::make_unique<Statements>(db_);
    path_ = path;
  } catch (...) {
    closeStore();
    throw;
  }
}

void Recorder::closeStore() {
  statements_.reset();  // finalised before the connection closes
  if (db_) sqlite3_close(db_);
  db_ = nullptr;
}

Recorder::~Recorder() {
  if (!db_) return;
  try {
    commitIfDue(true);
  } catch (...) {
  }
  sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr);
  closeStore();
}

void Recorder::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string why = err ? err : "unknown error";
    sqlite3_free(err);
    throw std::runtime_error("the recording store refused a write: " + why);
  }
}

void Recorder::commitIfDue(bool force) {
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - lastCommit_ < std::chrono::milliseconds(500)) return;
  exec("COMMIT");
  exec("BEGIN");
  lastCommit_ = now;
}

std::string Recorder::path() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return path_;
}

bool Recorder::suspended() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return suspended_;
}

void Recorder::suspend() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (suspended_ || !db_) return;
  sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr);
  statements_.reset();
  // Everything into the file itself, and the WAL emptied, before another connection copies or replaces it.
  sqlite3_wal_checkpoint_v2(db_, nullptr, SQLITE_CHECKPOINT_TRUNCATE, nullptr, nullptr);
  closeStore();
  suspended_ = true;
}

void Recorder::reopen(const std::string& path) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (db_) {  // not suspended: the old file was replaced under it; what it held uncommitted goes with it
    sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr);
    closeStore();
  }
  suspended_ = false;
  try {
    open(path);  // leaves a transaction open
    for (const auto& [step, sum] : checksumsWritten_) writeChecksum(db_, statements_->checksumAgain, id_, step, sum);
    setupsWritten_.clear();  // a checkpoint after this one writes its setup again when the copy missed it (INSERT OR IGNORE)
    for (const auto& [hash, text] : keptSetups_) writeSetup(hash, text);
    for (const auto& k : keptCheckpoints_) writeCheckpoint(k.step, k.hash, k.bytes);
    keptSetups_.clear();
    keptCheckpoints_.clear();
    {
      Statement q(db_, "UPDATE rehearsal_sessions SET steps = ?, complete = ? WHERE id = ?");
      sqlite3_bind_int64(q.s, 1, lastStep_);
      sqlite3_bind_int(q.s, 2, finished_ ? 1 : 0);
      sqlite3_bind_int64(q.s, 3, id_);
      if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a step: ") + sqlite3_errmsg(db_));
    }
    commitIfDue(true);
    broken_.clear();
  } catch (const std::exception& e) {
    closeStore();
    broken_ = "the recording cannot go on in " + path + ": " + e.what();
    throw std::runtime_error(broken_);
  }
}

void Recorder::writeSetup(std::uint64_t hash, const std::string& text) {
  Statement& q = statements_->setup;
  sqlite3_reset(q.s);
  sqlite3_bind_int64(q.s, 1, id_);
  q.text(2, std::to_string(hash));
  q.text(3, text);
  if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a setup: ") + sqlite3_errmsg(db_));
  setupsWritten_.push_back(hash);
}

void Recorder::writeCheckpoint(long step, std::uint64_t hash, const std::string& bytes) {
  Statement& q = statements_->checkpoint;
  sqlite3_reset(q.s);
  sqlite3_bind_int64(q.s, 1, id_);
  sqlite3_bind_int64(q.s, 2, step);
  q.text(3, std::to_string(hash));
  sqlite3_bind_blob(q.s, 4, bytes.data(), static_cast<int>(bytes.size()), SQLITE_TRANSIENT);
  if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a checkpoint: ") + sqlite3_errmsg(db_));
}

void Recorder::afterStep(long step, const std::vector<simcore::InputEvent>& recorded, const simcore::SimulationState& state) {
  std::lock_guard<std::mutex> lock(mutex_);
  afterStepLocked(step, recorded, state);
}

void Recorder::afterStepLocked(long step, const std::vector<simcore::InputEvent>& recorded, const simcore::SimulationState& state) {
  if (!broken_.empty()) throw std::runtime_error(broken_);
  if (finished_) throw std::runtime_error("the recorded session has ended; a new recording starts a new session");
  // The step count of a session only grows: one that starts again (a reset) is another run, never appended to this one.
  if (step <= lastStep_)
    throw std::runtime_error("the simulation started again (step " + std::to_string(step) + " after step " + std::to_string(lastStep_) +
                             "): the recorded session ends here; record again to record the new run");
  lastStep_ = step;
  const bool checksumDue = step % every_ == 0;
  const std::uint64_t sum = checksumDue ? stateChecksum(state) : 0;
  if (checksumDue) checksumsWritten_.emplace_back(step, sum);
  if (suspended_) return;  // kept: the events are in the session's record, the checksums above, written at reopen()
  if (recorded.size() > written_) {
    Statement& q = statements_->event;
    for (; written_ < recorded.size(); ++written_) {
      sqlite3_reset(q.s);
      sqlite3_bind_int64(q.s, 1, id_);
      sqlite3_bind_int64(q.s, 2, static_cast<sqlite3_int64>(written_));
      sqlite3_bind_int64(q.s, 3, recorded[written_].step);
      q.text(4, encodeEvent(recorded[written_]));
      if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused an event: ") + sqlite3_errmsg(db_));
    }
  }
  if (checksumDue) writeChecksum(db_, statements_->checksum, id_, step, sum);
  {
    Statement& q = statements_->steps;
    sqlite3_reset(q.s);
    sqlite3_bind_int64(q.s, 1, step);
    sqlite3_bind_int64(q.s, 2, id_);
    if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a step: ") + sqlite3_errmsg(db_));
  }
  commitIfDue(false);
}

void Recorder::afterStep(const simcore::StepRecord& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  afterStepLocked(r.step, *r.recorded, *r.state);
  // Every `checkpointEvery` steps, and just after the body changed (a cut applied: seeking past it then starts
  // after it instead of building the cut body again).
  bool changed = false;
  for (const auto& e : r.snapshot->events) changed |= e == "cut";
  if (r.step - lastCheckpoint_ >= checkpointEvery_ || changed) {
    const simcore::Checkpoint c = r.checkpoint();
    auto store = [this](const simcore::BodySetup& s) {
      const std::uint64_t h = setupHash(s);  // the mesh is copied and encoded only for a setup not written yet
      if (std::find(setupsWritten_.begin(), setupsWritten_.end(), h) != setupsWritten_.end()) return h;
      std::string text = encodeSetup(sharedSetup(s));
      if (suspended_) {
        keptSetups_.emplace_back(h, std::move(text));
        setupsWritten_.push_back(h);
      } else {
        writeSetup(h, text);
      }
      return h;
    };
    const std::uint64_t h = store(c.setup);
    const std::uint64_t pending = c.pendingCut ? store(c.pendingCut->setup) : 0;
    std::string bytes = detail::encodeCheckpoint(c, h, pending);
    if (suspended_) keptCheckpoints_.push_back({r.step, h, std::move(bytes)});
    else writeCheckpoint(r.step, h, bytes);
    lastCheckpoint_ = r.step;
    ++checkpoints_;
  }
}

void Recorder::finish(long steps) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  finished_ = true;
  lastStep_ = std::max(lastStep_, steps);
  if (!db_) return;  // suspended: reopen() marks it complete; broken: nothing more can be written
  Statement q(db_, "UPDATE rehearsal_sessions SET steps = ?, complete = 1 WHERE id = ?");
  sqlite3_bind_int64(q.s, 1, lastStep_);
  sqlite3_bind_int64(q.s, 2, id_);
  if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused the session's end: ") + sqlite3_errmsg(db_));
  commitIfDue(true);
}

std::vector<RecordingSummary> listRecordings(const std::string& path) {
  sqlite3* db = openStore(path, false);
  std::vector<RecordingSummary> out;
  try {
    if (hasTable(db, "rehearsal_sessions")) {
      const bool uuid = hasColumn(db, "rehearsal_sessions", "uuid");
      Statement q(db, uuid ? "SELECT id, trainee, started_utc, case_name, scene_version, app_version, notes, steps, complete, uuid FROM rehearsal_sessions ORDER BY id"
                           : "SELECT id, trainee, started_utc, case_name, scene_version, app_version, notes, steps, complete FROM rehearsal_sessions ORDER BY id");
      int rc;
      while ((rc = sqlite3_step(q.s)) == SQLITE_ROW) {
        RecordingSummary r;
        r.id = sqlite3_column_int64(q.s, 0);
        r.meta = {q.column(1), q.column(3), q.column(4), q.column(5), q.column(6)};
        r.startedUtc = q.column(2);
        r.steps = static_cast<long>(sqlite3_column_int64(q.s, 7));
        r.complete = sqlite3_column_int(q.s, 8) != 0;
        if (uuid) r.uuid = q.column(9);
        if (r.steps < 0) throw std::runtime_error("session " + std::to_string(r.id) + " in " + path + " has a negative step count");
        out.push_back(std::move(r));
      }
      if (rc != SQLITE_DONE) throw std::runtime_error(std::string("the recordings in ") + path + " cannot be read: " + sqlite3_errmsg(db));
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
  bool found = false;
  for (auto& s : listRecordings(path))
    if (s.id == id) {
      r.summary = std::move(s);
      found = true;
    }
  if (!found) throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
  sqlite3* db = openStore(path, false);
  try {
    {
      Statement q(db, "SELECT setup, checksum_every FROM rehearsal_sessions WHERE id = ?");
      sqlite3_bind_int64(q.s, 1, id);
      if (sqlite3_step(q.s) != SQLITE_ROW) throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
      r.setup = decodeSetup(q.column(0));
      r.checksumEvery = sqlite3_column_int(q.s, 1);
      if (r.checksumEvery < 1) throw std::runtime_error("session " + std::to_string(id) + " in " + path + " has no checksum interval");
    }
    {
      Statement q(db, "SELECT event, step FROM rehearsal_events WHERE session = ? ORDER BY seq");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) {
        r.events.push_back(decodeEvent(q.column(0)));
        // The events apply at step boundaries in order: a step going back or beyond the session cannot be replayed.
        const long step = r.events.back().step;
        if (step != sqlite3_column_int64(q.s, 1) || (r.events.size() > 1 && step < r.events[r.events.size() - 2].step))
          throw std::runtime_error("session " + std::to_string(id) + " in " + path + " has its events out of order (damaged)");
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
          throw std::runtime_error("session " + std::to_string(id) + " in " + path + " has a damaged checksum (step " + std::to_string(step) + ")");
        r.checksums[step] = sum;
      }
    }
    if (hasTable(db, "rehearsal_checkpoints")) {
      Statement q(db, "SELECT step FROM rehearsal_checkpoints WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) r.checkpointSteps.push_back(static_cast<long>(sqlite3_column_int64(q.s, 0)));
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  // A session cut short: its last checksum bounds what can be verified.
  if (!r.checksums.empty()) r.summary.steps = std::max(r.summary.steps, r.checksums.rbegin()->first);
  r.path = path;
  return r;
}

RecordingRows loadRecordingRows(const std::string& path, std::int64_t id) {
  RecordingRows rows;
  sqlite3* db = openStore(path, false);
  try {
    {
      Statement q(db, "SELECT setup FROM rehearsal_sessions WHERE id = ?");
      sqlite3_bind_int64(q.s, 1, id);
      if (sqlite3_step(q.s) != SQLITE_ROW) throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
      rows.setup = q.column(0);
    }
    {
      Statement q(db, "SELECT seq, step, event FROM rehearsal_events WHERE session = ? ORDER BY seq");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW)
        rows.events.emplace_back(static_cast<long>(sqlite3_column_int64(q.s, 0)), static_cast<long>(sqlite3_column_int64(q.s, 1)), q.column(2));
    }
    {
      Statement q(db, "SELECT step, checksum FROM rehearsal_checksums WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) rows.checksums.emplace_back(static_cast<long>(sqlite3_column_int64(q.s, 0)), q.column(1));
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
    std::string bytes;
    {
      Statement q(db, "SELECT state FROM rehearsal_checkpoints WHERE session = ? AND step = ?");
      sqlite3_bind_int64(q.s, 1, id);
      sqlite3_bind_int64(q.s, 2, step);
      if (sqlite3_step(q.s) != SQLITE_ROW)
        throw std::runtime_error(path + " has no checkpoint at step " + std::to_string(step) + " of session " + std::to_string(id));
      const auto* blob = static_cast<const char*>(sqlite3_column_blob(q.s, 0));
      bytes.assign(blob ? blob : "", static_cast<std::size_t>(sqlite3_column_bytes(q.s, 0)));
    }
    c = decodeCheckpointState(bytes, [&](std::uint64_t hash) {
      Statement q(db, "SELECT setup FROM rehearsal_setups WHERE session = ? AND hash = ?");
      sqlite3_bind_int64(q.s, 1, id);
      q.text(2, std::to_string(hash));
      if (sqlite3_step(q.s) != SQLITE_ROW)
        throw std::runtime_error(path + ": the checkpoint at step " + std::to_string(step) + " names a setup that is missing");
      return decodeSetup(q.column(0));
    });
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  if (c.step != step) throw std::runtime_error(path + ": the checkpoint at step " + std::to_string(step) + " holds another step");
  return c;
}

Replayer::Replayer(Recording r) : rec_(std::move(r)) {
  steps_ = rec_.summary.complete || rec_.checksums.empty() ? rec_.summary.steps : rec_.checksums.rbegin()->first;
  startAt(nullptr);
  start_ = session_->checkpoint();
}

Replayer::~Replayer() = default;

long Replayer::step() const { return session_->snapshot()->step; }

void Replayer::startAt(const simcore::Checkpoint* c) {
  if (!c) {
    session_ = std::make_unique<simcore::Session>(simcore::replaySetup(rec_.setup));
  } else {
    simcore::Checkpoint d = *c;
    d.setup = simcore::replaySetup(std::move(d.setup));
    if (d.pendingCut) d.pendingCut->setup = simcore::replaySetup(std::move(d.pendingCut->setup));
    session_->discardPending();
    session_->restore(d);
  }
  const long from = c ? c->step : 0;
  for (const auto& e : rec_.events)
    if (e.step >= from) session_->post(e);
}

void Replayer::seek(long target) {
  target = std::clamp(target, 0L, steps_);
  const long now = step();
  long best = 0;  // the nearest checkpoint at or before the target (0: the start)
  for (long s : rec_.checkpointSteps)
    if (s <= target && s > best) best = s;
  if (now <= target && now >= best) {
    lastSeekFrom_ = -1;  // onwards from here
  } else if (best > 0) {
    auto it = cache_.find(best);
    if (it == cache_.end())
      it = cache_.emplace(best, rec_.checkpointSource ? rec_.checkpointSource(best) : loadCheckpoint(rec_.path, rec_.summary.id, best)).first;
    startAt(&it->second);
    lastSeekFrom_ = best;
  } else {
    startAt(&start_);
    lastSeekFrom_ = 0;
  }
  while (step() < target) session_->advance();
}

void Replayer::advance() {
  if (step() < steps_) session_->advance();
}

std::shared_ptr<const simcore::Snapshot> Replayer::snapshot() const { return session_->snapshot(); }
simcore::SimulationState Replayer::state() const { return session_->state(); }

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
  int rc = sqlite3_exec(db, "CREATE TABLE IF NOT EXISTS rehearsal_thresholds(id INTEGER PRIMARY KEY CHECK(id = 1), json TEXT NOT NULL)", nullptr, nullptr, &err);
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
    throw std::runtime_error(std::string("the recorded sessions could not be carried into the saved case: ") + e.what());
  }
  bool prevUuid = false;
  {
    sqlite3* src = openStore(from, false);
    prevUuid = hasColumn(src, "rehearsal_sessions", "uuid");
    sqlite3_close(src);
  }
  run("ATTACH DATABASE '" + quoted + "' AS prev");
  run("BEGIN");
  // Every session with its identity (one recorded before identities existed gets one here).
  run(std::string("INSERT INTO rehearsal_sessions(id, trainee, started_utc, case_name, scene_version, app_version, notes, setup, time_step, "
                  "checksum_every, steps, complete, uuid) SELECT id, trainee, started_utc, case_name, scene_version, app_version, notes, setup, time_step, "
                  "checksum_every, steps, complete, ") +
      (prevUuid ? "CASE WHEN uuid IS NULL OR uuid = '' THEN lower(hex(randomblob(16))) ELSE uuid END" : "lower(hex(randomblob(16)))") +
      " FROM prev.rehearsal_sessions");
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

VerifyResult verifyRecording(const Recording& r) { return replayRecording(r).verify; }

ReplayResult replayRecording(const Recording& r, double forceThresholdN) {
  ReplayOptions o;
  o.forceThresholdN = forceThresholdN;
  return replayRecording(r, o);
}

namespace {
double distanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double len2 = d.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * d)).norm();
}
}  // namespace

ReplayResult replayRecording(const Recording& r, const ReplayOptions& options) {
  const double forceThresholdN = options.forceThresholdN;
  ReplayResult out;
  VerifyResult& v = out.verify;
  SessionMetrics& m = out.metrics;
  m.forceThresholdN = forceThresholdN;
  // What this session cannot say, in words.
  int tumourLabel = 0;
  for (const auto& [label, name] : r.setup.mesh.labelNames) {
    std::string lower = name;
    for (auto& ch : lower) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (lower.find("tumour") != std::string::npos || lower.find("tumor") != std::string::npos) tumourLabel = label;
  }
  if (r.setup.mesh.namesAVessel()) m.vesselCuts = 0;
  else m.vesselWhy = "the case names no vessel (no element label named vessel, vein or artery)";
  if (tumourLabel) m.tumourBreaches = 0;
  else m.tumourWhy = "the case marks no tumour (no element label named tumour)";
  m.attachmentsWhy = "the model's attachments cannot tear (they are fixed nodes)";
  if (!options.plannedCut) m.cutDeviationWhy = "the case has no planned cut line";
  double deviationSum = 0;
  long cuttingSteps = 0;
  std::vector<Eigen::Vector3d> rest = r.setup.rest.empty() ? r.setup.mesh.points : r.setup.rest;
  bool wasCutting = false;
  double previousForce = 0;
  Eigen::Vector3d lastCut = Eigen::Vector3d::Zero();
  const long steps = r.summary.complete || r.checksums.empty() ? r.summary.steps : r.checksums.rbegin()->first;
  double time = 0;  // simulated (the time step may be edited during the session: each step's own length counts)
  bool seen = false;
  Eigen::Vector3d first = Eigen::Vector3d::Zero(), last = Eigen::Vector3d::Zero();
  double forceSum = 0;
  long forceSteps = 0;
  // An instrument swapped for another (grasper -> hook): the tip's jump between them is not a path travelled.
  std::set<long> swapped;  // steps whose snapshot shows the new instrument's first pose
  double straight = 0;     // the straight distances of the instruments swapped out
  {
    int lastTool = -1;
    for (const auto& e : r.events)
      if (e.kind == simcore::InputKind::ToolPose) {
        if (lastTool >= 0 && e.tool != lastTool) swapped.insert(e.step + 1);
        lastTool = e.tool;
      }
  }
  simcore::replaySession(r.setup, r.events, steps, [&](long step, const simcore::Session& session) {
    ++v.steps;
    if (const auto it = r.checksums.find(step); it != r.checksums.end()) {
      ++v.checked;
      if (stateChecksum(session.state()) != it->second) {
        ++v.mismatches;
        if (v.firstMismatch < 0) v.firstMismatch = step;
      }
    }
    const auto snap = session.snapshot();
    const auto& tool = snap->tool;
    if (tool.present) {
      if (!seen) first = last = tool.tip;
      if (swapped.count(step)) {  // economy per instrument: its own straight distance
        straight += (last - first).norm();
        first = last = tool.tip;
      }
      m.pathLengthM += (tool.tip - last).norm();
      last = tool.tip;
      seen = true;
    }
    const double f = tool.force.norm();
    m.maxForceN = std::max(m.maxForceN, f);
    if (f > 0) {
      forceSum += f;
      ++forceSteps;
    }
    const bool over = f > forceThresholdN;
    if (over) m.timeOverThresholdS += snap->time - time;
    const bool overBefore = previousForce > forceThresholdN;
    previousForce = f;
    time = snap->time;
    for (const auto& e : snap->events) {
      m.grasps += e == "grasp";
      m.slips += e == "slip";
      m.cuts += e == "cut";
      if (m.vesselCuts && e == "vessel cut") ++*m.vesselCuts;
      if (tumourLabel && e == "cut through label " + std::to_string(tumourLabel)) ++*m.tumourBreaches;
    }
    if (tool.present && tool.cutting) {
      if (wasCutting) m.cutLengthM += (tool.tip - lastCut).norm();
      lastCut = tool.tip;
      if (options.plannedCut) {
        const double d = distanceToSegment(tool.tip, options.plannedCut->first, options.plannedCut->second);
        deviationSum += d;
        ++cuttingSteps;
        m.cutDeviationMaxM = std::max(m.cutDeviationMaxM.value_or(0.0), d);
      }
    }
    wasCutting = tool.present && tool.cutting;
    double strain = 0;
    if (options.strain) {
      const auto& restNow = snap->surface ? snap->surface->rest : rest;
      strain = snap->tets ? maxGreenStrain(restNow, snap->positions, *snap->tets) : 0;
      m.maxStrain = std::max(m.maxStrain.value_or(0.0), strain);
    }
    if (options.timeline) {
      TimelineSample t;
      t.step = step;
      t.time = snap->time;
      t.toolPresent = tool.present;
      t.tip = tool.tip;
      t.force = f;
      t.strain = strain;
      t.holding = !tool.held.empty();
      t.cutting = tool.cutting;
      t.newInstrument = swapped.count(step) > 0;
      t.events = snap->events;
      if (over && !overBefore) t.events.push_back("force over threshold");
      out.timeline.push_back(std::move(t));
    }
  });
  if (options.plannedCut) {
    if (cuttingSteps) m.cutDeviationMeanM = deviationSum / static_cast<double>(cuttingSteps);
    else m.cutDeviationWhy = "the blade never cut";
  }
  m.durationS = time;
  m.meanForceN = forceSteps ? forceSum / static_cast<double>(forceSteps) : 0;
  m.economy = m.pathLengthM > 0 ? (straight + (last - first).norm()) / m.pathLengthM : 0;
  return out;
}

}  // namespace rehearse::app
