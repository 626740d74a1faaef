// The recorder: a rehearsal written into the case file's store as it runs (setup, events, checksums, checkpoints),
// suspended and reopened around a save, never half-open. The store itself: recording_store.cpp.
#include "rehearse/app/recording.hpp"

#include "recording_codec.hpp"
#include "recording_store.hpp"

#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/numerics.hpp>

#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <random>
#include <stdexcept>

namespace rehearse::app {

using nlohmann::json;
using namespace detail;

RecordedNumerics currentNumerics(const simcore::BodySetup& setup, const std::string& appVersion) {
  return {simcore::linearSolveKernel(setup.settings.simplicialFactor),
          "Rehearse " + (appVersion.empty() ? std::string("(version not given)") : appVersion) + ", " +
              simcore::numericalBuild()};
}

struct Recorder::Statements {
  Statement event, checksum, checksumAgain, steps, setup, checkpoint;
  explicit Statements(sqlite3* db)
      : event(db, "INSERT INTO rehearsal_events(session, seq, step, event) VALUES(?, ?, ?, ?)"),
        // A step recorded twice is refused, never overwritten: a restarted step count (a reset) cannot replace the
        // record.
        checksum(db, "INSERT INTO rehearsal_checksums(session, step, checksum) VALUES(?, ?, ?)"),
        checksumAgain(db, "INSERT OR IGNORE INTO rehearsal_checksums(session, step, checksum) VALUES(?, ?, ?)"),
        steps(db, "UPDATE rehearsal_sessions SET steps = ? WHERE id = ?"),
        setup(db, "INSERT OR IGNORE INTO rehearsal_setups(session, hash, setup) VALUES(?, ?, ?)"),
        checkpoint(
            db, "INSERT OR REPLACE INTO rehearsal_checkpoints(session, step, setup_hash, state) VALUES(?, ?, ?, ?)") {}
};

Recorder::Recorder(const std::string& path, const SessionMeta& meta, const simcore::BodySetup& setup, int checksumEvery,
                   int checkpointEvery)
    : every_(std::max(1, checksumEvery)),
      checkpointEvery_(std::max(1, checkpointEvery)),
      lastCommit_(std::chrono::steady_clock::now()) {
  path_ = path;
  uuid_ = newSessionUuid();
  meta_ = meta;
  startedUtc_ = utcNow();
  numerics_ = currentNumerics(setup, meta.appVersion);
  setupText_ = withRecordedNumerics(encodeSetup(setup), numerics_);
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
      Statement q(db_,
                  "INSERT INTO rehearsal_sessions(trainee, started_utc, case_name, scene_version, app_version, notes, "
                  "setup, time_step, checksum_every, uuid, rules) "
                  "VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
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
      q.text(11, meta_.rules);
      if (sqlite3_step(q.s) != SQLITE_DONE)
        throw std::runtime_error(std::string("cannot record into ") + path + ": " + sqlite3_errmsg(db_));
      id_ = sqlite3_last_insert_rowid(db_);
      written_ = 0;
    } else {
      Statement q(db_, "SELECT COUNT(*) FROM rehearsal_events WHERE session = ?");
      sqlite3_bind_int64(q.s, 1, id_);
      const long copied = sqlite3_step(q.s) == SQLITE_ROW ? static_cast<long>(sqlite3_column_int64(q.s, 0)) : 0;
      written_ =
          std::min(written_, static_cast<std::size_t>(copied));  // events are written in order: the copy holds a prefix
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
    setupsWritten_
        .clear();  // a checkpoint after this one writes its setup again when the copy missed it (INSERT OR IGNORE)
    for (const auto& [hash, text] : keptSetups_) writeSetup(hash, text);
    for (const auto& k : keptCheckpoints_) writeCheckpoint(k.step, k.hash, k.bytes);
    keptSetups_.clear();
    keptCheckpoints_.clear();
    {
      Statement q(db_, "UPDATE rehearsal_sessions SET steps = ?, complete = ? WHERE id = ?");
      sqlite3_bind_int64(q.s, 1, lastStep_);
      sqlite3_bind_int(q.s, 2, finished_ ? 1 : 0);
      sqlite3_bind_int64(q.s, 3, id_);
      if (sqlite3_step(q.s) != SQLITE_DONE)
        throw std::runtime_error(std::string("the recording store refused a step: ") + sqlite3_errmsg(db_));
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
  if (sqlite3_step(q.s) != SQLITE_DONE)
    throw std::runtime_error(std::string("the recording store refused a setup: ") + sqlite3_errmsg(db_));
  setupsWritten_.push_back(hash);
}

void Recorder::writeCheckpoint(long step, std::uint64_t hash, const std::string& bytes) {
  Statement& q = statements_->checkpoint;
  sqlite3_reset(q.s);
  sqlite3_bind_int64(q.s, 1, id_);
  sqlite3_bind_int64(q.s, 2, step);
  q.text(3, std::to_string(hash));
  sqlite3_bind_blob(q.s, 4, bytes.data(), static_cast<int>(bytes.size()), SQLITE_TRANSIENT);
  if (sqlite3_step(q.s) != SQLITE_DONE)
    throw std::runtime_error(std::string("the recording store refused a checkpoint: ") + sqlite3_errmsg(db_));
}

void Recorder::afterStep(long step, const std::vector<simcore::InputEvent>& recorded,
                         const simcore::SimulationState& state) {
  std::lock_guard<std::mutex> lock(mutex_);
  afterStepLocked(step, recorded, state);
}

void Recorder::afterStepLocked(long step, const std::vector<simcore::InputEvent>& recorded,
                               const simcore::SimulationState& state) {
  if (!broken_.empty()) throw std::runtime_error(broken_);
  if (finished_) throw std::runtime_error("the recorded session has ended; a new recording starts a new session");
  // The step count of a session only grows: one that starts again (a reset) is another run, never appended to this one.
  if (step <= lastStep_)
    throw std::runtime_error("the simulation started again (step " + std::to_string(step) + " after step " +
                             std::to_string(lastStep_) +
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
      if (sqlite3_step(q.s) != SQLITE_DONE)
        throw std::runtime_error(std::string("the recording store refused an event: ") + sqlite3_errmsg(db_));
    }
  }
  if (checksumDue) writeChecksum(db_, statements_->checksum, id_, step, sum);
  {
    Statement& q = statements_->steps;
    sqlite3_reset(q.s);
    sqlite3_bind_int64(q.s, 1, step);
    sqlite3_bind_int64(q.s, 2, id_);
    if (sqlite3_step(q.s) != SQLITE_DONE)
      throw std::runtime_error(std::string("the recording store refused a step: ") + sqlite3_errmsg(db_));
  }
  commitIfDue(false);
}

void Recorder::afterStep(const simcore::StepRecord& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  afterStepLocked(r.step, *r.recorded, *r.state);
  // Every `checkpointEvery` steps, and just after the body changed (a cut applied: seeking past it then starts
  // after it instead of building the cut body again).
  bool changed = false;
  for (const auto& e : r.snapshot->events) changed |= simcore::eventKind(e) == simcore::EventKind::Cut;
  if (r.step - lastCheckpoint_ >= checkpointEvery_ || changed) {
    const simcore::Checkpoint c = r.checkpoint();
    auto store = [this](const simcore::BodySetup& s) {
      const std::uint64_t h = setupHash(s);  // the mesh is copied and encoded only for a setup not written yet
      if (std::find(setupsWritten_.begin(), setupsWritten_.end(), h) != setupsWritten_.end()) return h;
      // Marked as written by a build that hashes setups as this one does: a reader checks it against its hash.
      std::string text = withRecordedNumerics(encodeSetup(sharedSetup(s)), numerics_);
      if (suspended_) {
        keptSetups_.emplace_back(h, std::move(text));
        setupsWritten_.push_back(h);
      } else {
        writeSetup(h, text);
      }
      return h;
    };
    const std::uint64_t h = store(c.setup);
    const std::uint64_t pending = c.pendingChange ? store(c.pendingChange->setup) : 0;
    std::string bytes = detail::encodeCheckpoint(c, h, pending);
    if (suspended_)
      keptCheckpoints_.push_back({r.step, h, std::move(bytes)});
    else
      writeCheckpoint(r.step, h, bytes);
    lastCheckpoint_ = r.step;
    ++checkpoints_;
  }
}

bool Recorder::discardIfEmpty() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_ || lastStep_ > 0 || !db_) return false;
  for (const char* sql : {"DELETE FROM rehearsal_events WHERE session = ?", "DELETE FROM rehearsal_checksums WHERE session = ?",
                          "DELETE FROM rehearsal_setups WHERE session = ?",
                          "DELETE FROM rehearsal_checkpoints WHERE session = ?", "DELETE FROM rehearsal_sessions WHERE id = ?"}) {
    Statement q(db_, sql);
    sqlite3_bind_int64(q.s, 1, id_);
    if (sqlite3_step(q.s) != SQLITE_DONE)
      throw std::runtime_error(std::string("the recording store refused to drop an empty session: ") +
                               sqlite3_errmsg(db_));
  }
  finished_ = true;
  commitIfDue(true);
  return true;
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
  if (sqlite3_step(q.s) != SQLITE_DONE)
    throw std::runtime_error(std::string("the recording store refused the session's end: ") + sqlite3_errmsg(db_));
  commitIfDue(true);
}

}  // namespace rehearse::app
