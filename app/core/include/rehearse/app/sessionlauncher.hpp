#pragma once
// A rehearsal launched and run from a window (issue 63): the case and the panel's settings -> the body, its start
// (sessionstart.hpp) -> the session, recorded when asked, and, when it is replaced, joined and its recording completed
// off the caller's thread. The GUI's Simulation panel only asks and words what happened; nothing here knows Qt.
#include <rehearse/app/recording.hpp>
#include <rehearse/app/sessionstart.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <atomic>
#include <cstdint>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

namespace rehearse::app {

/// Where and as what a launched session is recorded.
struct RecordTarget {
  std::string file;  ///< the case file (SQLite) the recording goes into
  SessionMeta meta;
};

/// The recording of a running session: written from the session's thread after every step (its step hook); a write
/// the file refuses stops the recording, not the simulation, and is kept as a sentence (failed(), error()).
class StepRecording {
 public:
  explicit StepRecording(std::shared_ptr<Recorder> recorder);
  /// Every step of `session` from now on is recorded.
  void attach(simcore::Session& session);
  bool failed() const { return failed_->load(); }
  std::string error() const;
  std::int64_t id() const { return recorder_->id(); }
  long lastStep() const { return recorder_->lastStep(); }
  /// Marks the recorded session complete at its last step (`session`'s hook removed first when given: it waits for
  /// the step in progress). Empty on success, else why it could not be.
  std::string finish(simcore::Session* session = nullptr);
  /// finish() found no step recorded and dropped the session from the file (Recorder::discardIfEmpty).
  bool discarded() const { return discarded_->load(); }
  /// Before the case file is copied and replaced (Recorder::suspend).
  void suspend() { recorder_->suspend(); }
  /// The case file was replaced: the recording goes on into `file` (a failure is kept as failed()).
  void reopen(const std::string& file);

 private:
  std::shared_ptr<Recorder> recorder_;
  std::shared_ptr<std::atomic<bool>> failed_ = std::make_shared<std::atomic<bool>>(false);
  std::shared_ptr<std::atomic<bool>> discarded_ = std::make_shared<std::atomic<bool>>(false);
  std::shared_ptr<std::string> error_ = std::make_shared<std::string>();
  mutable std::shared_ptr<std::mutex> mutex_ = std::make_shared<std::mutex>();
};

/// How a session is launched.
struct LaunchOptions {
  RestShapeCache* cache = nullptr;  ///< the rest shape solved for the same body before
  /// The rest shape's static solves as they go (their number, the distance from the shape in m); false cancels.
  std::function<bool(int, double)> restProgress;
  /// A long body build (the precomputed model's responses), 0..1; false cancels it.
  std::function<bool(double)> buildProgress;
  std::optional<RecordTarget> record;  ///< recorded into this case file from its first step
};

/// A session launched: how it starts (the start's outcome and the rest shape's solve; its body moved into the session:
/// read it there, Session::setup()) and, when it starts, the session and its recording.
struct Launch {
  SessionStart start;
  std::shared_ptr<simcore::Session> session;
  std::shared_ptr<StepRecording> recording;  ///< when LaunchOptions::record asked for one (not attached yet)
};

/// The case's organ and the run's settings to a session ready to play: the body (bodySetup), its start (prepareStart:
/// refused with an outcome when nothing holds it or no equilibrium exists), the recorder opened on the body as started
/// (throws std::runtime_error, in one sentence, when the file cannot be written), the session built. Runs for a while
/// (the rest shape's solves, the first factorisation): call it on a worker.
Launch launchSession(const SessionRequest& request, const LaunchOptions& options);

/// `session` joined and `recording` marked complete on a thread of their own, after `previous` (an older retirement)
/// is done; a recording that could not be completed is said through `onError` (on that thread); once it is complete,
/// `onFinished` (on that thread) is told its id, its last step (the session joined: no step comes after it) and
/// whether it was dropped for recording no step.
std::shared_future<void> retireSession(std::shared_ptr<simcore::Session> session,
                                       std::shared_ptr<StepRecording> recording, std::shared_future<void> previous,
                                       std::function<void(const std::string&)> onError,
                                       std::function<void(std::int64_t, long, bool)> onFinished = {});

}  // namespace rehearse::app
