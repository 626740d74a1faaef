#pragma once
// The session's thread and what it shares with the other threads (session.hpp): the mailbox of inputs posted for the
// next step boundary, the control flags (play, pause, one step, reset, republish, quit) the thread waits on, and what
// the session publishes after every step (the snapshot, and the tool force the force loop reads without a lock).
// It decides nothing about the simulation: the session's run() asks it what to do next and does it.
//
// Locking: the mailbox, the snapshot, the published callback and the control flags are guarded by the loop's own
// mutex (the session's "mailbox" mutex); playing and publishStress are atomics also read without it; the tool force is
// a SeqCell (one writer, lock-free readers). The loop never takes the session's step mutex: when both are held, the
// step mutex is taken first (Session::advance) or the loop's mutex is released before it is (Session::run).
#include <rehearse/simcore/session/input.hpp>
#include <rehearse/simcore/session/seqcell.hpp>

#include <array>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace rehearse::simcore {

struct Snapshot;

class SessionLoop {
 public:
  SessionLoop() = default;
  SessionLoop(const SessionLoop&) = delete;
  SessionLoop& operator=(const SessionLoop&) = delete;

  /// Starts the thread running `body` (Session::run). Once.
  void start(std::function<void()> body);
  /// Tells the thread to quit (it stops playing) and waits for it (the step in progress ends first).
  void stop();

  // Any thread: the inputs for the next step boundary.
  void post(InputEvent e);
  /// The events due at a boundary after `steps` steps (those without a step, and those whose step has come), in the
  /// order they were posted; the rest stay.
  std::vector<InputEvent> takeDue(long steps);
  void discard();  ///< drops the inputs posted and not taken yet

  // Any thread: the controls.
  void play();
  void pause();
  void stepOnce();
  void reset();
  bool playing() const { return playing_; }
  /// Stops playing without waking the thread (the thread itself, after a failed step).
  void stopPlaying() { playing_ = false; }
  void setPublishStress(bool on);  ///< and the thread republishes at once
  bool publishStress() const { return publishStress_; }

  /// What the thread does next (waited for): Quit; Republish the last snapshot (paused, nothing else asked for);
  /// Reset; Step (one step asked for); Advance (playing; whether it still plays is read after this returns).
  enum class Order { Quit, Republish, Reset, Step, Advance };
  Order next();
  /// While playing, ahead of the wall clock: waits up to min(ahead, 1) s, woken early by pause, reset or quit.
  void waitWhileAhead(double ahead);

  // What the session publishes.
  /// The snapshot in (under the loop's mutex), then the published callback called (outside it).
  void publish(std::shared_ptr<const Snapshot> s);
  std::shared_ptr<const Snapshot> snapshot() const;
  void setPublishedCallback(std::function<void()> f);
  /// Written at each publish (one writer: the publishing thread), read by the force loop without a lock.
  void publishToolForce(const std::array<double, 18>& v) { toolForce_.store(v); }
  std::array<double, 18> toolForce() const { return toolForce_.load(); }

 private:
  mutable std::mutex mutex_;  // mailbox, snapshot, callback, control flags (the session's mailbox mutex)
  SeqCell<18> toolForce_;     // written at each publish, read by the force loop without a lock
  std::deque<InputEvent> mailbox_;
  std::shared_ptr<const Snapshot> snapshot_;
  std::function<void()> published_;
  std::condition_variable wake_;
  std::atomic<bool> playing_{false};
  std::atomic<bool> publishStress_{false};
  bool republish_ = false;
  int pendingSteps_ = 0;
  bool pendingReset_ = false;
  bool quit_ = false;
  std::thread thread_;
};

}  // namespace rehearse::simcore
