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
//                      time_step, checksum_every, steps, complete, uuid)
//                      -- id: this file's row number (restarts at 1 in every file); uuid: the session's identity
//                      across files (a copy keeps it; a file recorded before it existed gets one when copied)
//   rehearsal_events(session, seq, step, event)        -- event: JSON, doubles to the last bit
//   rehearsal_checksums(session, step, checksum)       -- after step `step`, FNV-1a 64 of (x, v, time)
//   rehearsal_checkpoints(session, step, setup_hash, state) -- the complete state after `step` (binary: positions,
//                      velocities, the lagged factor's identity and a factor requested, the tools, a cut under way),
//                      every `checkpointEvery` steps and after each cut applied: seeking starts from the nearest
//   rehearsal_setups(session, hash, setup)             -- each body setup a checkpoint names, once (edits and cuts
//                      change it)
#include <rehearse/simcore/session/session.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

struct sqlite3;

namespace rehearse::app {

/// FNV-1a 64 over the bytes of the positions, velocities and time: equal only for bit-identical states.
std::uint64_t stateChecksum(const simcore::SimulationState& s);

/// What made a recording (issue 60): the numerical kernel of its linear solves (simcore::linearSolveKernel) and the
/// build (program version, compiler, floating-point flags). Kept in the session's setup text under "recorded_with",
/// so that every copy (another file, the training database) carries it; empty in a recording made before.
struct RecordedNumerics {
  std::string kernel, build;
};
/// The setup text (an object, as encodeSetup writes it) with `n` added; decodeSetup reads it back.
std::string withRecordedNumerics(const std::string& setupText, const RecordedNumerics& n);
/// The same for this process (what a recording made or replayed here says).
RecordedNumerics currentNumerics(const simcore::BodySetup& setup, const std::string& appVersion);

/// A body setup as JSON text (every field, doubles to the last bit) and back. Throws std::runtime_error
/// with one sentence for text that is not one. A setup with a cut in progress is refused (a recording
/// starts from a body at rest).
std::string encodeSetup(const simcore::BodySetup& s);
/// `numerics`, when given, receives what the text says made it (empty fields when it says nothing; each at most 512
/// characters).
simcore::BodySetup decodeSetup(const std::string& json, RecordedNumerics* numerics = nullptr);
std::string encodeEvent(const simcore::InputEvent& e);
simcore::InputEvent decodeEvent(const std::string& json);
/// What makes a decoded setup unusable (node indices out of range, sizes that disagree, an unknown enum, a
/// number that is not finite or outside its range), in one sentence; empty when it can be simulated. A
/// recording, a checkpoint or a database row is untrusted input: every decoder runs it.
std::string setupProblem(const simcore::BodySetup& s);
/// The same for a recorded event (an unknown kind or parameter, a value outside its range, no number).
std::string eventProblem(const simcore::InputEvent& e);
/// A new random identity for a recorded session (32 hex digits).
std::string newSessionUuid();

struct SessionMeta {
  std::string trainee;       ///< name or id
  std::string caseName;      ///< which case (name or path)
  std::string sceneVersion;  ///< e.g. the case file's parts' hash, or the preset's name
  std::string appVersion;
  std::string notes;
  /// The incorrect-action rules of the scene it was rehearsed in (incorrect_actions.hpp; JSON, empty: the defaults
  /// without a view). Stored with the session: a replay judges it by them.
  std::string rules;
};

/// Writes one session as it runs (from the stepping thread); reopen() from another thread is safe.
class Recorder {
 public:
  /// Opens (creates) `path`, its tables, and the session's row. Throws std::runtime_error with one
  /// sentence (a file that is not SQLite, a read-only file).
  Recorder(const std::string& path, const SessionMeta& meta, const simcore::BodySetup& setup, int checksumEvery = 10,
           int checkpointEvery = 20);
  ~Recorder();  ///< commits what is pending (a finish() not called leaves the session incomplete)
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;
  std::int64_t id() const { return id_; }
  /// After step `step` (1-based, as Session::advance counts): the events recorded so far (the session's
  /// whole record; the recorder keeps the ones it has not written) and the state's checksum every N steps.
  void afterStep(long step, const std::vector<simcore::InputEvent>& recorded, const simcore::SimulationState& state);
  /// The same from the session's step hook (Session::setStepHook), with a complete-state checkpoint every
  /// `checkpointEvery` steps and just after a cut was applied.
  void afterStep(const simcore::StepRecord& r);
  long checkpoints() const { return checkpoints_; }
  /// Marks the session complete with its step count and commits.
  void finish(long steps);
  /// A session that recorded no step (stopped, or reset, before its first): its rows are deleted, since there is
  /// nothing to replay or review (a person's check found an empty "Recorded session 3" listed after Reset then Stop).
  /// True when it was; false when it has steps, was finished or cannot be written now (suspended, broken). Throws
  /// std::runtime_error with one sentence when the store refuses the deletion.
  bool discardIfEmpty();
  /// Before the file is copied and replaced (a case saved anew, written beside and renamed over it): commits,
  /// checkpoints the WAL into the file and closes it, so that the copy holds everything written so far and no
  /// connection pairs the new file with the old WAL. Steps meanwhile are kept in memory (events, checksums,
  /// checkpoints) until reopen().
  void suspend();
  bool suspended() const;
  /// The file was replaced by a new one holding a copy of the recordings: writes go on into `path`, into the
  /// session with this recorder's uuid (its row number there may differ), and what the copy missed is written
  /// (what was kept while suspended; every event and checksum when the copy has not got the session at all).
  /// Throws std::runtime_error with one sentence; the recorder is then closed (nothing half-open) and refuses
  /// further steps with that sentence.
  void reopen(const std::string& path);
  std::string path() const;
  std::string uuid() const { return uuid_; }
  long lastStep() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return lastStep_;
  }

 private:
  void exec(const char* sql);
  void commitIfDue(bool force);
  void open(const std::string& path);
  void closeStore();
  void writeCheckpoint(long step, std::uint64_t hash, const std::string& bytes);
  void writeSetup(std::uint64_t hash, const std::string& text);
  void afterStepLocked(long step, const std::vector<simcore::InputEvent>& recorded,
                       const simcore::SimulationState& state);
  mutable std::mutex mutex_;
  std::string path_;
  std::vector<std::pair<long, std::uint64_t>>
      checksumsWritten_;  // all of them (8 bytes per N steps): rewritten after a reopen
  long lastStep_ = 0;
  bool finished_ = false;
  std::string uuid_;
  SessionMeta meta_;
  std::string startedUtc_;
  std::string setupText_;  // the session's row again when a copy lost it
  RecordedNumerics numerics_;
  double timeStep_ = 0;
  bool suspended_ = false;
  std::string broken_;  // why the recorder cannot write any more (a reopen that failed)
  struct Kept {         // checkpoints (and their new setups) taken while suspended
    long step;
    std::uint64_t hash;
    std::string bytes;
  };
  std::vector<Kept> keptCheckpoints_;
  std::vector<std::pair<std::uint64_t, std::string>> keptSetups_;
  sqlite3* db_ = nullptr;
  struct Statements;
  std::unique_ptr<Statements> statements_;  // prepared once, used at every step
  std::int64_t id_ = 0;
  int every_;
  int checkpointEvery_;
  long lastCheckpoint_ = 0;
  long checkpoints_ = 0;
  std::vector<std::uint64_t> setupsWritten_;
  std::size_t written_ = 0;
  std::chrono::steady_clock::time_point lastCommit_;
};

struct RecordingSummary {
  std::int64_t id = 0;
  std::string uuid;  ///< the session's identity across files (empty in a file recorded before it existed)
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
  std::vector<long> checkpointSteps;        ///< the steps with a complete-state checkpoint (loadCheckpoint)
  RecordedNumerics numerics;                ///< what made it (empty fields: recorded before they were named)
  std::string path;                         ///< the file it was loaded from
  /// Where its checkpoints come from when not from `path` (a session read from the training database).
  std::function<simcore::Checkpoint(long step)> checkpointSource;
};

/// A session's rows as stored (to publish them elsewhere without decoding them).
struct RecordingRows {
  std::string setup;                                        ///< JSON
  std::vector<std::tuple<long, long, std::string>> events;  ///< seq, step, JSON
  std::vector<std::pair<long, std::string>> checksums;      ///< step, decimal
  std::vector<std::pair<std::string, std::string>> setups;  ///< hash (decimal), JSON
  struct CheckpointRow {
    long step = 0;
    std::string setupHash;
    std::string state;
  };
  std::vector<CheckpointRow> checkpoints;
};
/// Throws std::runtime_error with one sentence.
RecordingRows loadRecordingRows(const std::string& path, std::int64_t id);

/// The sessions recorded in `path` (none when it has no recording tables). Throws std::runtime_error with
/// one sentence when the file cannot be read as SQLite.
std::vector<RecordingSummary> listRecordings(const std::string& path);
/// One session; throws std::runtime_error with one sentence when it is absent or unreadable.
Recording loadRecording(const std::string& path, std::int64_t id);

/// A complete-state checkpoint of a session (after `step`). Throws std::runtime_error with one sentence.
simcore::Checkpoint loadCheckpoint(const std::string& path, std::int64_t id, long step);
/// A checkpoint as bytes and back (the state's doubles to the last bit; its setups by their hashes, stored
/// apart without their cut progress, which the bytes carry); decoding checks every length.
std::string encodeCheckpointState(const simcore::Checkpoint& c);
simcore::Checkpoint decodeCheckpointState(const std::string& bytes,
                                          const std::function<simcore::BodySetup(std::uint64_t hash)>& setupOf);
/// A setup a checkpoint names, decoded and checked against the hash it is stored under (an edited setup text is
/// refused; setups recorded before recordings named their kernels hashed otherwise and are not checked here: --verify
/// compares the state their checkpoints restore). Throws std::runtime_error with one sentence.
simcore::BodySetup decodeSharedSetup(const std::string& text, std::uint64_t hash);
/// Why a recording's length cannot be replayed (its steps, checksums, events or checkpoints beyond a run's limits:
/// a damaged step count made --verify run forever), or empty. Every loader runs it.
std::string recordingLengthProblem(const Recording& r);
/// A setup as a checkpoint stores it: without its cut progress.
simcore::BodySetup sharedSetup(const simcore::BodySetup& s);
/// A hash of a body setup (its mesh, attachments, materials, settings and tools; not the cut in progress, which
/// a checkpoint carries itself): equal setups, equal hashes. Hashes in place (no copy of the mesh).
std::uint64_t setupHash(const simcore::BodySetup& s);

/// A recording replayed with seeking: any step is reached from the nearest checkpoint at or before it
/// (or from the step it is at, when that is nearer), replaying the recorded events from there. The states
/// are those of a straight replay, bit for bit (the checkpoints are complete).
struct VerifyResult;

class Replayer {
 public:
  explicit Replayer(Recording r);
  ~Replayer();
  Replayer(const Replayer&) = delete;
  Replayer& operator=(const Replayer&) = delete;
  const Recording& recording() const { return rec_; }
  long steps() const { return steps_; }  ///< the last step that can be reached
  long step() const;                     ///< where it is
  /// Moves to after step `step` (0: at rest), clamped to [0, steps()].
  void seek(long step);
  /// One step forward (nothing at the end).
  void advance();
  std::shared_ptr<const simcore::Snapshot> snapshot() const;
  simcore::SimulationState state() const;
  /// How the last seek got there: from a checkpoint (its step), from the start (0) or onwards (-1).
  long lastSeekFrom() const { return lastSeekFrom_; }
  /// Checkpoints a seek must not start from, as a verify found them: damaged ones (a seek that would have started from
  /// one says so) and incomplete ones of an older build (passed over without a word).
  void avoidCheckpoints(const VerifyResult& v);
  /// Why the last seek did not start from the nearest checkpoint (one that does not decode, or whose state is not the
  /// recorded one at its step, or one a verify found damaged): a sentence naming it and where the seek started
  /// instead; empty when it did.
  const std::string& lastSeekNote() const { return lastSeekNote_; }

 private:
  void startAt(const simcore::Checkpoint* c);
  Recording rec_;
  long steps_ = 0;
  long lastSeekFrom_ = -1;
  std::unique_ptr<simcore::Session> session_;
  std::map<long, simcore::Checkpoint> cache_;  // checkpoints read so far
  std::map<long, std::string> damaged_;        // checkpoints found damaged, and why
  std::set<long> incomplete_;                  // an older build's checkpoints that hold less than the state
  std::string lastSeekNote_;
  simcore::Checkpoint start_;                  // at rest (restoring it is cheaper than building the session)
};

/// The trainer's thresholds for this case's sessions (the JSON `parseThresholds` reads), kept in the case file
/// (table rehearsal_thresholds); empty when none was set. Throws std::runtime_error with one sentence.
std::string loadCaseThresholds(const std::string& path);
void saveCaseThresholds(const std::string& path, const std::string& json);

/// Copies every recorded session from the SQLite file `from` into `to` (the tables created when absent):
/// a case saved anew (written beside the old file, then renamed over it) keeps its recordings. Nothing to do
/// when `from` has none. Returns the sessions copied; throws std::runtime_error with one sentence.
int copyRecordings(const std::string& from, const std::string& to);

struct VerifyResult {
  long steps = 0;    ///< replayed
  long checked = 0;  ///< checksums compared
  long mismatches = 0;
  long firstMismatch = -1;  ///< step, -1 when none
  /// Checkpoints compared with the straight replay (decoded, and the state they restore equal to the replay's at their
  /// step); each one that is not, with its step and why.
  long checkpointsChecked = 0;
  std::vector<std::pair<long, std::string>> damagedCheckpoints;
  /// Checkpoints of a recording made by an older build (one that did not name its kernels) that hold less than a
  /// checkpoint holds now (the instruments' or the field's whole state): sound for what they hold, not damaged, but a
  /// seek must not start from them (Replayer::avoidCheckpoints).
  std::vector<std::pair<long, std::string>> incompleteCheckpoints;
  RecordedNumerics recorded, replayed;  ///< what made the recording, and what replayed it here
};
/// Re-simulates the recording from its setup and events (simcore::replay) and compares every recorded
/// checksum. Bit-identical on the same build.
VerifyResult verifyRecording(const Recording& r);

/// What a trainer reads about a session (computed from its replay, so a recording is all it needs).
/// One incorrect action a replay found under the session's rules (incorrect_actions.hpp): which rule, when, in words.
struct IncorrectAction {
  std::string rule;  ///< "vessel_cut_without_clips", "energy_on_structure", "force_over_limit", "tear",
                     ///< "clip_misplaced", "outside_view"
  long step = 0;
  double time = 0;  ///< s, simulated
  std::string what;
};

struct SessionMetrics {
  double durationS = 0;    ///< simulated time
  double pathLengthM = 0;  ///< the instrument tip's path while an instrument is in the scene (not the jump when one is
                           ///< swapped for another)
  double economy = 0;      ///< straight distance from the tip's first to its last place (per instrument, summed) / path
                           ///< length (1: straight; 0: no path)
  int grasps = 0, slips = 0, cuts = 0;  ///< events ("cut": cut updates applied)
  /// Vessels cut (once per vessel and stroke): labels the organ's mesh names as vessels (Mesh::labelIsVessel);
  /// nullopt when it names none (vesselWhy says so): a cut through an unnamed inner structure is not counted as one.
  std::optional<int> vesselCuts;
  std::string vesselWhy;
  double maxForceN = 0;   ///< the tool's force on the tissue, largest
  double meanForceN = 0;  ///< mean over the steps with a force
  double forceThresholdN = 0;
  double timeOverThresholdS = 0;  ///< simulated time with the force above the threshold
  std::optional<double>
      maxStrain;          ///< largest principal Green strain of any element at any step (ReplayOptions::strain)
  double cutLengthM = 0;  ///< the blade tip's path while cutting
  /// The blade tip's distance from the planned cut line while cutting (mean over the cutting steps, largest);
  /// nullopt without a planned line (cutDeviationWhy says so) or without cutting.
  std::optional<double> cutDeviationMeanM, cutDeviationMaxM;
  std::string cutDeviationWhy;
  std::optional<int> tumourBreaches;  ///< cuts through an element labelled "tumour"; nullopt when the case marks none
  std::string tumourWhy;
  int clips = 0;           ///< clips the clip applier left (events "clip")
  int misplacedClips = 0;  ///< of them, on something not a vessel or a duct, or not across all of it ("clip misplaced")
  /// mL of blood lost from cut vessels' open stumps by the session's end; nullopt when the case names no vessel
  /// (vesselWhy says so: nothing can bleed).
  std::optional<double> bloodLossMl;
  int energyOnStructures = 0;          ///< named structures the cautery's energy reached ("energy on structure")
  double energyTimeS = 0;              ///< s of energy applied to tissue
  /// Tears ("tear": tissue pulled past its material's tear strain), and of them those at an attachment (a ligament's
  /// fixed node or a ligament label: "attachment torn"); nullopt when no material of the case declares a tear strain
  /// (attachmentsWhy says so: nothing can tear).
  std::optional<int> tears, attachmentsTorn;
  std::string attachmentsWhy;
  /// The incorrect actions under the session's rules (SessionMeta::rules), in time order; rulesError says why there
  /// are none to show when its rules cannot be read; ruleNotCounted: the rules off or not determined, with why.
  std::vector<IncorrectAction> incorrectActions;
  std::string rulesError;
  std::map<std::string, std::string> ruleNotCounted;
  /// How many of a rule's incorrect actions (nullopt, with why, when the rule is not counted or the rules unreadable).
  std::optional<int> incorrectCount(const std::string& rule, std::string* why = nullptr) const;
};
/// One step of a replay, for the review's timeline and plots.
struct TimelineSample {
  long step = 0;
  double time = 0;  ///< s, simulated
  bool toolPresent = false;
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();  ///< m, body frame
  double force = 0;                               ///< N
  double strain = 0;                              ///< largest principal Green strain (0 unless computed)
  bool holding = false, cutting = false;
  bool newInstrument = false;  ///< another instrument than at the last step (its tip did not travel from there)
  std::vector<std::string> events;  ///< "grasp", "release", "slip", "cut", "vessel cut", "cut through label N", "force
                                    ///< over threshold", "clip", "clip misplaced", "bleeding", "bleeding stopped",
                                    ///< "tear", "attachment torn"
};
struct ReplayResult {
  VerifyResult verify;
  SessionMetrics metrics;
  std::vector<TimelineSample> timeline;  ///< with ReplayOptions::timeline; steps 1..n
};
struct ReplayOptions {
  double forceThresholdN = 10;
  /// A planned cut line (two points, m, body frame): the cut's deviation from it is measured.
  std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> plannedCut;
  bool strain = false;    ///< compute the tissue's largest strain at every step (one pass over the elements)
  bool timeline = false;  ///< keep the per-step samples
  /// Compare every checkpoint with the straight replay (VerifyResult::damagedCheckpoints). Off where the checkpoints'
  /// source cannot be read from the replaying thread (a training database's connection belongs to its thread).
  bool checkpoints = true;
  /// Called on the replaying thread after every step with what is known so far (the samples kept, the checksums and
  /// checkpoints compared up to `step`, the metrics so far), `steps` being how many the replay makes: the review draws
  /// its timeline and seeks as far as the replay has checked while it runs. Returning false stops the replay:
  /// replayRecording then throws ReplayStopped.
  std::function<bool(long step, long steps, const ReplayResult& soFar)> progress;
};
/// A replay its progress callback stopped (a review closed, or another session chosen, while it ran).
struct ReplayStopped : std::runtime_error {
  ReplayStopped() : std::runtime_error("the replay was stopped before its end") {}
};
/// One replay: the checksums compared and the metrics computed.
ReplayResult replayRecording(const Recording& r, const ReplayOptions& options);
/// The same with only a force threshold (N).
ReplayResult replayRecording(const Recording& r, double forceThresholdN = 10);

}  // namespace rehearse::app
