// The replayer (a recorded session re-simulated from its setup and events, seeking through its checkpoints).
#include "rehearse/app/recording.hpp"

#include <algorithm>
#include <stdexcept>

namespace rehearse::app {

Replayer::Replayer(Recording r) : rec_(std::move(r)) {
  steps_ = rec_.summary.complete || rec_.checksums.empty() ? rec_.summary.steps : rec_.checksums.rbegin()->first;
  startAt(nullptr);
  start_ = session_->checkpoint();
}

Replayer::~Replayer() = default;

long Replayer::step() const {
  return session_->snapshot()->step;
}

void Replayer::startAt(const simcore::Checkpoint* c) {
  if (!c) {
    session_ = std::make_unique<simcore::Session>(simcore::replaySetup(rec_.setup));
  } else {
    simcore::Checkpoint d = *c;
    d.setup = simcore::replaySetup(std::move(d.setup));
    if (d.pendingChange) d.pendingChange->setup = simcore::replaySetup(std::move(d.pendingChange->setup));
    session_->discardPending();
    session_->restore(d);
  }
  const long from = c ? c->step : 0;
  for (const auto& e : rec_.events)
    if (e.step >= from) session_->post(e);
}

void Replayer::avoidCheckpoints(const VerifyResult& v) {
  for (const auto& [step, why] : v.damagedCheckpoints) {
    damaged_.emplace(step, why);
    cache_.erase(step);
  }
  for (const auto& [step, why] : v.incompleteCheckpoints) {
    incomplete_.insert(step);
    cache_.erase(step);
  }
}

void Replayer::seek(long target) {
  target = std::clamp(target, 0L, steps_);
  lastSeekNote_.clear();
  const long now = step();
  bool atNow = true;  // the session is still where the seek began (not restored from a checkpoint found damaged)
  // The nearest sound checkpoint at or before the target (0: the start). One that does not decode, or whose state is
  // not the recorded one at its step (its checksum, where the recording has one there), is passed over with a note.
  for (;;) {
    long best = 0, nearest = 0;
    for (long s : rec_.checkpointSteps)
      if (s <= target && !incomplete_.count(s)) {
        nearest = std::max(nearest, s);
        if (s > best && !damaged_.count(s)) best = s;
      }
    if (nearest > best && lastSeekNote_.empty())  // the nearest is one found damaged before: said again
      lastSeekNote_ = "the checkpoint after step " + std::to_string(nearest) + " is damaged (" + damaged_[nearest] + ")";
    if (atNow && now <= target && now >= best) {
      lastSeekFrom_ = -1;  // onwards from here
      break;
    }
    if (best == 0) {
      startAt(&start_);
      lastSeekFrom_ = 0;
      break;
    }
    auto it = cache_.find(best);
    std::string why;
    if (it == cache_.end()) {
      try {
        it = cache_
                 .emplace(best, rec_.checkpointSource ? rec_.checkpointSource(best)
                                                      : loadCheckpoint(rec_.path, rec_.summary.id, best))
                 .first;
        if (it->second.step != best) why = "it says it was taken after step " + std::to_string(it->second.step);
      } catch (const std::exception& e) {
        why = e.what();
      }
    }
    if (why.empty()) {
      startAt(&it->second);
      atNow = false;
      const auto sum = rec_.checksums.find(best);
      if (sum != rec_.checksums.end() && stateChecksum(session_->state()) != sum->second)
        why = "its state is not the one recorded at that step";
    }
    if (why.empty()) {
      lastSeekFrom_ = best;
      break;
    }
    damaged_.emplace(best, why);
    cache_.erase(best);
    if (lastSeekNote_.empty())
      lastSeekNote_ = "the checkpoint after step " + std::to_string(best) + " is damaged (" + why + ")";
  }
  if (!lastSeekNote_.empty())
    lastSeekNote_ += lastSeekFrom_ > 0    ? "; the seek started from the checkpoint after step " +
                                                std::to_string(lastSeekFrom_) + " instead"
                     : lastSeekFrom_ == 0 ? "; the seek replayed from the start instead"
                                          : "; the seek went on from step " + std::to_string(now);
  while (step() < target) session_->advance();
}

void Replayer::advance() {
  if (step() < steps_) session_->advance();
}

std::shared_ptr<const simcore::Snapshot> Replayer::snapshot() const {
  return session_->snapshot();
}
simcore::SimulationState Replayer::state() const {
  return session_->state();
}

}  // namespace rehearse::app
