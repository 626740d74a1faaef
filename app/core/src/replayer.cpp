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
      it = cache_
               .emplace(best, rec_.checkpointSource ? rec_.checkpointSource(best)
                                                    : loadCheckpoint(rec_.path, rec_.summary.id, best))
               .first;
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

std::shared_ptr<const simcore::Snapshot> Replayer::snapshot() const {
  return session_->snapshot();
}
simcore::SimulationState Replayer::state() const {
  return session_->state();
}

}  // namespace rehearse::app
