#pragma once
// Recorded rehearsals (issue 16): a session's complete setup, its timestamped input events with the step
// each applied at (the session's own record, including the factor swaps and cuts applied by its second
// thread) and a checksum of the complete state every N steps, written into a SQLite file (the case file,
// or any file) as the rehearsal runs. The file is in WAL mode and the open transaction is committed at
// least once a second, so a crash or kill -9 loses at most the last second; a session row is written
// first, so a session cut short is still listed (complete = 0) and what it holds replays.
//
// Tables (created when absent; a case file's own tables are untouched):
//   rehearsal_sessions(id, trainee, started_utc, case_name, scene_version, app_version, notes, setup,
//                      time_step, checksum_every, steps, complete)
//   rehearsal_events(session, seq, step, event)        -- event: JSON, doubles to the last bit
//   rehearsal_checksums(session, step, checksum)       -- after step `step`, FNV-1a 64 of (x, v, time)
#include <rehearse/simcore/session/session.hpp>

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

struct sqlite3;

namespace rehearse::app {

/// FNV-1a 64 over the bytes of the positions, velocities and time: equal only for bit-identical states.
std::uint64_t stateChecksum(const simcore::SimulationState& s);

/// A body setup as JSON text (every field, doubles to the last bit) and back. Throws std::runtime_error
/// with one sentence for text that is not one. A setup with a cut in progress is refused (a recording
/// starts from a body at rest).
std::string encodeSetup(const simcore::BodySetup& s);
simcore::BodySetup decodeSetup(const std::string& json);
std::string encodeEvent(const simcore::InputEvent& e);
simcore::InputEvent decodeEvent(const std::string& json);

struct SessionMeta {
  std::string trainee;       ///< name or id
  std::string caseName;      ///< which case (name or path)
  std::string sceneVersion;  ///< e.g. the case file's parts' hash, or the preset's name
  std::string appVersion;
  std::string notes;
};

/// Writes one session as it runs. Not thread-safe: call from the stepping thread (or after each step).
class Recorder {
 public:
  /// Opens (creates) `path`, its tables, and the session's row. Throws std::runtime_error with one
  /// sentence (a file that is not SQLite, a read-only file).
  Recorder(const std::string& path, const SessionMeta& meta, const simcore::BodySetup& setup, int checksumEvery = 10);
  ~Recorder();  ///< commits what is pending (a finish() not called leaves the session incomplete)
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;
  std::int64_t id() const { return id_; }
  /// After step `step` (1-based, as Session::advance counts): the events recorded so far (the session's
  /// whole record; the recorder keeps the ones it has not written) and the state's checksum every N steps.
  void afterStep(long step, const std::vector<simcore::InputEvent>& recorded, const simcore::SimulationState& state);
  /// Marks the session complete with its step count and commits.
  void finish(long steps);

 private:
  void exec(const char* sql);
  void commitIfDue(bool force);
  sqlite3* db_ = nullptr;
  struct Statements;
  std::unique_ptr<Statements> statements_;  // prepared once, used at every step
  std::int64_t id_ = 0;
  int every_;
  std::size_t written_ = 0;
  std::chrono::steady_clock::time_point lastCommit_;
};

struct RecordingSummary {
  std::int64_t id = 0;
  SessionMeta meta;
  std::string startedUtc;
  long steps = 0;  ///< the last step recorded
  bool complete = false;
};

struct Recording {
  RecordingSummary summary;
  simcore::BodySetup setup;
  int checksumEvery = 0;
  std::vector<simcore::InputEvent> events;
  std::map<long, std::uint64_t> checksums;  ///< after step -> checksum
};

/// The sessions recorded in `path` (none when it has no recording tables). Throws std::runtime_error with
/// one sentence when the file cannot be read as SQLite.
std::vector<RecordingSummary> listRecordings(const std::string& path);
/// One session; throws std::runtime_error with one sentence when it is absent or unreadable.
Recording loadRecording(const std::string& path, std::int64_t id);

/// Copies every recorded session from the SQLite file `from` into `to` (the tables created when absent):
/// a case saved anew (written beside the old file, then renamed over it) keeps its recordings. Nothing to do
/// when `from` has none. Returns the sessions copied; throws std::runtime_error with one sentence.
int copyRecordings(const std::string& from, const std::string& to);

struct VerifyResult {
  long steps = 0;       ///< replayed
  long checked = 0;     ///< checksums compared
  long mismatches = 0;
  long firstMismatch = -1;  ///< step, -1 when none
};
/// Re-simulates the recording from its setup and events (simcore::replay) and compares every recorded
/// checksum. Bit-identical on the same build.
VerifyResult verifyRecording(const Recording& r);

/// What a trainer reads about a session (computed from its replay, so a recording is all it needs).
struct SessionMetrics {
  double durationS = 0;          ///< simulated time
  double pathLengthM = 0;        ///< the instrument tip's path while an instrument is in the scene
  double economy = 0;            ///< straight distance from the tip's first to its last place / path length (1: straight; 0: no path)
  int grasps = 0, slips = 0, cuts = 0, vesselCuts = 0;  ///< events ("cut": cut updates applied)
  double maxForceN = 0;          ///< the tool's force on the tissue, largest
  double meanForceN = 0;         ///< mean over the steps with a force
  double forceThresholdN = 0;
  double timeOverThresholdS = 0; ///< simulated time with the force above the threshold
};
struct ReplayResult {
  VerifyResult verify;
  SessionMetrics metrics;
};
/// One replay: the checksums compared and the metrics computed (force threshold in N).
ReplayResult replayRecording(const Recording& r, double forceThresholdN = 10);

}  // namespace rehearse::app
