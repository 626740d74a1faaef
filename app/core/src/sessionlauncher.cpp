// A rehearsal launched from a window, recorded, and retired (sessionlauncher.hpp).
#include "rehearse/app/sessionlauncher.hpp"

#include <utility>

namespace rehearse::app {

StepRecording::StepRecording(std::shared_ptr<Recorder> recorder) : recorder_(std::move(recorder)) {}

void StepRecording::attach(simcore::Session& session) {
  failed_->store(false);
  session.setStepHook([rec = recorder_, failed = failed_, why = error_, mutex = mutex_](const simcore::StepRecord& r) {
    if (failed->load()) return;
    try {
      rec->afterStep(r);
    } catch (const std::exception& e) {
      const std::lock_guard<std::mutex> lock(*mutex);
      *why = e.what();
      failed->store(true);
    }
  });
}

std::string StepRecording::error() const {
  const std::lock_guard<std::mutex> lock(*mutex_);
  return *error_;
}

std::string StepRecording::finish(simcore::Session* session) {
  if (session) session->setStepHook({});  // waits for the step in progress
  try {
    if (recorder_->discardIfEmpty()) {
      discarded_->store(true);
      return {};
    }
    recorder_->finish(recorder_->lastStep());
  } catch (const std::exception& e) {
    return e.what();
  }
  return {};
}

void StepRecording::reopen(const std::string& file) {
  try {
    recorder_->reopen(file);
  } catch (const std::exception& e) {
    const std::lock_guard<std::mutex> lock(*mutex_);
    *error_ = e.what();
    failed_->store(true);
  }
}

Launch launchSession(const SessionRequest& request, const LaunchOptions& options) {
  simcore::BodySetup body = bodySetup(request);
  body.buildProgress = options.buildProgress;
  StartOptions startAs;
  startAs.inEquilibrium = request.startInEquilibrium;
  // The window's clicks hold what the radius caught; a click that caught one node alone (a coarse mesh, a small
  // radius) holds its neighbours on the surface too, as a file of picks does: one pinned node is crushed by a pull.
  startAs.attachmentPatches = true;
  startAs.supportModulus = request.supportModulus;
  startAs.cache = options.cache;
  startAs.progress = options.restProgress;
  Launch launch;
  launch.start = prepareStart(std::move(body), startAs);
  if (launch.start.outcome != SessionStart::Outcome::Ready) return launch;
  simcore::BodySetup& b = launch.start.body;
  if (options.record)
    launch.recording =
        std::make_shared<StepRecording>(std::make_shared<Recorder>(options.record->file, options.record->meta, b));
  launch.session = std::make_shared<simcore::Session>(std::move(b));
  return launch;
}

std::shared_future<void> retireSession(std::shared_ptr<simcore::Session> session,
                                       std::shared_ptr<StepRecording> recording, std::shared_future<void> previous,
                                       std::function<void(const std::string&)> onError,
                                       std::function<void(std::int64_t, long, bool)> onFinished) {
  return std::async(std::launch::async, [session = std::move(session), recording = std::move(recording),
                                         previous = std::move(previous), onError = std::move(onError),
                                         onFinished = std::move(onFinished)]() mutable {
           if (previous.valid()) previous.wait();
           session.reset();  // joins its thread (its step, a cut's build under way)
           if (!recording) return;
           const std::string why = recording->finish();  // a new session is a new recording (or none)
           if (!why.empty() && onError) onError(why);
           if (onFinished) onFinished(recording->id(), recording->lastStep(), recording->discarded());
         })
      .share();
}

}  // namespace rehearse::app
