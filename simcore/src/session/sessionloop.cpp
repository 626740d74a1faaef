#include <rehearse/simcore/session/sessionloop.hpp>

#include <algorithm>
#include <chrono>

namespace rehearse::simcore {

void SessionLoop::start(std::function<void()> body) {
  thread_ = std::thread(std::move(body));
}

void SessionLoop::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    quit_ = true;
    playing_ = false;
  }
  wake_.notify_all();
  thread_.join();
}

void SessionLoop::post(InputEvent e) {
  std::lock_guard<std::mutex> lock(mutex_);
  mailbox_.push_back(std::move(e));
}

std::vector<InputEvent> SessionLoop::takeDue(long steps) {
  std::vector<InputEvent> due;
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = mailbox_.begin(); it != mailbox_.end();) {
    if (it->step < 0 || it->step <= steps) {
      due.push_back(std::move(*it));
      it = mailbox_.erase(it);
    } else {
      ++it;
    }
  }
  return due;
}

void SessionLoop::discard() {
  std::lock_guard<std::mutex> lock(mutex_);
  mailbox_.clear();
}

void SessionLoop::play() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    playing_ = true;
  }
  wake_.notify_all();
}

void SessionLoop::pause() {
  playing_ = false;
  wake_.notify_all();
}

void SessionLoop::stepOnce() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    playing_ = false;
    ++pendingSteps_;
  }
  wake_.notify_all();
}

void SessionLoop::reset() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    playing_ = false;
    pendingReset_ = true;
    // What the instruments did before the Reset and no step applied (given while paused) is not done to the organ
    // from rest: 20 clips clicked on a paused organ closed on it after Reset and Play. Edits (material, gravity,
    // parameters) stay, as the session keeps them over a reset; what is posted after this call is kept.
    std::erase_if(mailbox_, [](const InputEvent& e) {
      return e.step < 0 && (e.kind == InputKind::ToolPose || e.kind == InputKind::Jaw || e.kind == InputKind::Cut ||
                            e.kind == InputKind::Clip || e.kind == InputKind::Energy);
    });
  }
  wake_.notify_all();
}

void SessionLoop::setPublishStress(bool on) {
  publishStress_ = on;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    republish_ = true;
  }
  wake_.notify_all();
}

SessionLoop::Order SessionLoop::next() {
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait(lock, [this] { return quit_ || playing_ || pendingSteps_ > 0 || pendingReset_ || republish_; });
  if (quit_) return Order::Quit;
  if (republish_ && !playing_ && pendingSteps_ == 0 && !pendingReset_) {
    republish_ = false;
    return Order::Republish;
  }
  republish_ = false;
  const bool doReset = pendingReset_;
  pendingReset_ = false;
  if (doReset) return Order::Reset;
  if (pendingSteps_ > 0) {
    --pendingSteps_;
    return Order::Step;
  }
  return Order::Advance;
}

void SessionLoop::waitWhileAhead(double ahead) {
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait_for(lock, std::chrono::duration<double>(std::min(ahead, 1.0)),
                 [this] { return quit_ || !playing_ || pendingReset_; });
}

void SessionLoop::publish(std::shared_ptr<const Snapshot> s) {
  std::function<void()> callback;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    snapshot_ = std::move(s);
    callback = published_;
  }
  if (callback) callback();
}

std::shared_ptr<const Snapshot> SessionLoop::snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return snapshot_;
}

void SessionLoop::setPublishedCallback(std::function<void()> f) {
  std::lock_guard<std::mutex> lock(mutex_);
  published_ = std::move(f);
}

}  // namespace rehearse::simcore
