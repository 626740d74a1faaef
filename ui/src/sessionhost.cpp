// The session the Simulation panel shows, run for the GUI (sessionhost.hpp).
#include "rehearse/ui/sessionhost.hpp"

#include <QFutureWatcher>
#include <QtConcurrent/QtConcurrent>

namespace rehearse::ui {

SessionHost::SessionHost(QWidget* dialogs) : QObject(dialogs), dialogs_(dialogs) {}

SessionHost::~SessionHost() {
  ++generation_;
  buildCancelled_->store(true);
  precomputeCancelled_->store(true);
  for (QFuture<void>& b : builds_) b.waitForFinished();  // a session being built uses the host's callbacks till done
  forceLoop_.reset();
  session_.reset();  // joins the session's thread before the host goes
  waitForRetired();
  if (recording_) (void)recording_->finish();
}

void SessionHost::retire() {
  forceLoop_.reset();  // it reads the session's snapshots
  // The old session's thread is joined (its step, a cut's build under way) and its recording marked complete on a
  // thread of their own (issue 62: Reset while recording froze the window 2 s); what records next waits for it.
  if (!session_ && !recording_) return;
  QPointer<SessionHost> self(this);
  retired_ = app::retireSession(
      std::move(session_), std::move(recording_), retired_,
      [self](const std::string& e) {
        const QString why = QString::fromStdString(e);
        QMetaObject::invokeMethod(
            self.data(),
            [self, why] {
              if (self) emit self->recordingStopped(tr("The recorded session could not be marked complete: %1").arg(why));
            },
            Qt::QueuedConnection);
      },
      [self](std::int64_t id, long lastStep, bool discarded) {
        QMetaObject::invokeMethod(
            self.data(),
            [self, id, lastStep, discarded] {
              if (self) emit self->recordingRetired(static_cast<qint64>(id), lastStep, discarded);
            },
            Qt::QueuedConnection);
      });
  session_.reset();
  recording_.reset();
}

bool SessionHost::start(const app::SessionRequest& s, std::optional<RecordRequest> record) {
  // Building the body (model, first factorisation) takes a while on a large organ: on a worker; the old
  // session keeps its thread until the new one is ready. Commands given meanwhile apply to the new one.
  retire();
  const long generation = ++generation_;
  buildCancelled_->store(true);  // the session being built (its rest-shape solve) is not wanted any more
  buildCancelled_ = std::make_shared<std::atomic<bool>>(false);
  recordPending_ = record.has_value();
  cancelRecord_ = false;
  pendingPlay_ = false;
  pendingSteps_ = 0;
  if (!s.organ || s.organ->organ->empty()) {
    recordPending_ = false;
    return false;
  }
  auto* watcher = new QFutureWatcher<void>(this);
  auto built = std::make_shared<Built>();
  connect(watcher, &QFutureWatcher<void>::finished, this, [this, watcher, built, generation] {
    watcher->deleteLater();
    if (generation == generation_) adopt(std::move(*built));  // else a newer organ arrived meanwhile
  });
  precomputeCancelled_->store(false);
  model_ = s.bodyModel;
  if (buildDialog_) buildDialog_->deleteLater();  // an older session's build: its progress will not come
  buildDialog_.clear();
  std::erase_if(builds_, [](const QFuture<void>& b) { return b.isFinished(); });
  QFuture<void> build = QtConcurrent::run([s, built, generation, record = record.has_value(),
                              options = launchOptions(generation, record), retiring = retired_,
                              cache = startCache_]() mutable {
    options.cache = cache.get();  // (kept alive by this task)
    try {
      if (record && retiring.valid()) retiring.wait();  // the last session's recording is complete in the file first
      app::Launch launch = app::launchSession(s, options);
      built->wasRecorded = record;
      built->outcome = launch.start.outcome;
      if (launch.start.outcome == app::SessionStart::Outcome::Cancelled) return;
      // (the body was moved into the session when it started: its setup there)
      built->words = startWords(s, launch.start, launch.session ? launch.session->setup() : launch.start.body);
      if (!launch.session) return;
      built->basis = std::make_shared<FrameBasis>(frameBasis(s.organ, launch.session->setup(), generation));
      built->session = std::move(launch.session);
      built->recording = std::move(launch.recording);
    } catch (const std::exception& e) {
      built->words = QString::fromStdString(e.what());
    }
  });
  watcher->setFuture(build);
  builds_.push_back(build);
  return true;
}

app::LaunchOptions SessionHost::launchOptions(long generation, const std::optional<RecordRequest>& record) {
  app::LaunchOptions options;
  QPointer<SessionHost> self(this);
  // A long body build (the precomputed model's responses, now or when chosen later in the Solver list) shows its
  // progress with a Cancel; it stops when a newer session is asked for too.
  options.buildProgress = [self, generation, cancelled = buildCancelled_, precompute = precomputeCancelled_](double d) {
    QMetaObject::invokeMethod(
        self,
        [self, d, generation] {
          if (self && self->generation_ == generation) self->showBuildProgress(d);
        },
        Qt::QueuedConnection);
    return !cancelled->load() && !precompute->load();
  };
  // The rest shape that sags into the registered one is solved in a few static solves: said on the status line as
  // they go, stopped when a newer session is asked for.
  options.restProgress = [self, cancelled = buildCancelled_, generation](int k, double error) {
    const QString text = tr("Solving the rest shape that sags into the registered one: static solve %1, %2 mm from it...")
                             .arg(k)
                             .arg(1e3 * error, 0, 'g', 3);
    QMetaObject::invokeMethod(
        self,
        [self, text, generation] {
          if (self && self->generation_ == generation) emit self->restProgress(text);
        },
        Qt::QueuedConnection);
    return !cancelled->load();
  };
  if (record) options.record = app::RecordTarget{record->file, record->meta};
  return options;
}

QString SessionHost::startWords(const app::SessionRequest& s, const app::SessionStart& start,
                                const simcore::BodySetup& b) {
  const QString model = QString::fromStdString(simcore::bodyModelName(b.model));
  switch (start.outcome) {
    case app::SessionStart::Outcome::Cancelled:
      return {};
    case app::SessionStart::Outcome::NothingHolds:  // a falling organ is not a rehearsal: said, with what to change
      return start.supportNotInModel
                 ? tr("The organ was not started: nothing holds it under gravity (the %1 model cannot stand it on "
                      "the tissue around it); hold nodes (H), choose the FEM, or turn gravity off.")
                       .arg(QString::fromStdString(simcore::bodyModelName(s.bodyModel)))
                 : tr("The organ was not started: nothing holds it under gravity; hold nodes (H), let the tissue "
                      "around it carry it (Support, on this panel), or turn gravity off.");
    case app::SessionStart::Outcome::NoEquilibrium:  // the organ would leave the frame at once: not started
      return tr("The organ was not started: %1").arg(QString::fromStdString(start.rest->status));
    case app::SessionStart::Outcome::Ready:
      break;
  }
  QString words;
  if (start.supportNotInModel)
    words = tr("The %1 model hangs the organ from its held nodes; the tissue around it carries it in the FEM only. ")
                .arg(model);
  if (start.start == app::SessionStart::Start::InEquilibrium)
    words += tr("The organ starts where the frame shows it, in equilibrium under gravity on %1: %2%3")
                 .arg(b.supports.empty()      ? tr("its attachments")
                      : b.fixedNodes.empty() ? tr("the tissue around it")
                                             : tr("its attachments and the tissue around it"))
                 .arg(QString::fromStdString(start.rest->status))
                 .arg(start.reused ? tr(" (solved for the last session, the same organ)") : QString());
  else if (start.start == app::SessionStart::Start::SagsFromShape)
    words += tr("The organ starts at rest on the registered shape and will sag from it under gravity.");
  if (const std::string patches = start.patchesSentence(); !patches.empty())
    words += QLatin1Char(' ') + QString::fromStdString(patches);
  return words;
}

void SessionHost::adopt(Built built) {
  const bool cancelled = cancelRecord_;
  recordPending_ = cancelRecord_ = false;
  if (built.outcome == app::SessionStart::Outcome::Cancelled && !built.session && built.words.isEmpty()) return;
  if (!built.session) {
    emit refused(built.words, built.wasRecorded);
    return;
  }
  session_ = std::move(built.session);
  if (built.recording && cancelled) {
    (void)built.recording->finish();
  } else if (built.recording) {
    recording_ = std::move(built.recording);
    recording_->attach(*session_);  // on the session's thread after every step
  }
  forceLoop_ = std::make_unique<simcore::ForceLoop>([s = session_.get()] { return s->toolForce(); }, &device_);
  forceLoop_->start();
  session_->setPublishedCallback([this, s = session_.get(), basis = built.basis]() {
    // On the session's thread: the frame is made here, the GUI thread only draws it.
    auto f = makeSimulationFrame(*basis, *s->snapshot(), colouring_.load());
    QMetaObject::invokeMethod(
        this,
        [this, f, generation = basis->generation] {
          if (generation == generation_) emit frame(f);
        },
        Qt::QueuedConnection);
  });
  session_->setPublishStress(colouring_ == 1);  // publishes the state at rest with the panel's colouring
  emit started(built.words);  // the panel posts what was asked while the body was being built (edits, the run)
  for (; pendingSteps_ > 0; --pendingSteps_) session_->stepOnce();
  if (pendingPlay_) session_->play();
  pendingPlay_ = false;
}

void SessionHost::setColouring(int colouring) {
  colouring_ = colouring;
  if (session_) session_->setPublishStress(colouring == 1);  // republishes the current state coloured this way
}

void SessionHost::modelAsked(simcore::BodyModel model) {
  model_ = model;
  precomputeCancelled_->store(false);
}

bool SessionHost::post(simcore::InputEvent e) {
  if (!session_) return false;
  if (e.kind == simcore::InputKind::ToolPose) device_.setPosition(e.position);
  session_->post(std::move(e));
  return true;
}

void SessionHost::play() {
  if (session_)
    session_->play();
  else
    pendingPlay_ = true;
}

void SessionHost::pause() {
  pendingPlay_ = false;
  if (session_) session_->pause();
}

void SessionHost::stepOnce() {
  if (session_)
    session_->stepOnce();
  else
    ++pendingSteps_;  // the body is still being built: the step runs when it is ready
}

void SessionHost::reset() {
  pendingPlay_ = false;
  pendingSteps_ = 0;
  if (session_) session_->reset();
}

bool SessionHost::stopRecording() {
  // A recorded session still being built (Stop right after Reset or Record) is not recorded: nothing is kept.
  const bool pending = recordPending_;
  if (recordPending_) cancelRecord_ = true;
  waitForRetired();
  if (!recording_) return !pending;
  (void)recording_->finish(session_.get());  // (a failure to mark it complete leaves it incomplete: replay says so)
  const bool kept = !recording_->discarded();
  recording_.reset();
  return kept;
}

QString SessionHost::recordingFailure() {
  if (!recording_ || !recording_->failed()) return {};
  const QString why = QString::fromStdString(recording_->error());
  stopRecording();
  return why;
}

void SessionHost::suspendRecording() {
  waitForRetired();  // (a session a reset ended is being marked complete in the file about to be copied)
  if (recording_) recording_->suspend();
}

void SessionHost::recordingFileReplaced(const std::string& file) {
  if (recording_) recording_->reopen(file);  // a failure stops the recording at the next frame
}

void SessionHost::waitForRetired() {
  if (retired_.valid()) retired_.wait();
}

void SessionHost::showBuildProgress(double done) {
  // Batches that ended after Cancel still report: the dialog does not come back for them.
  if (done >= 1 || precomputeCancelled_->load()) {
    if (buildDialog_) buildDialog_->deleteLater();
    buildDialog_.clear();
    return;
  }
  if (!buildDialog_) {
    const bool ffd = model_ == simcore::BodyModel::Ffd;
    buildDialog_ = new QProgressDialog(ffd ? tr("Mapping the organ's surface onto the FFD model's geometry image...")
                                           : tr("Computing the precomputed model's responses to each surface node..."),
                                       tr("Cancel"), 0, 1000, dialogs_);
    buildDialog_->setObjectName(QStringLiteral("precomputeProgress"));
    buildDialog_->setWindowTitle(ffd ? tr("FFD model") : tr("Precomputed model"));
    buildDialog_->setWindowModality(Qt::WindowModal);
    buildDialog_->setMinimumDuration(400);
    buildDialog_->setAutoClose(false);
    buildDialog_->setAutoReset(false);
    connect(buildDialog_, &QProgressDialog::canceled, this, [this, flag = precomputeCancelled_] {
      flag->store(true);  // the build stops after its current batch; the session says so and keeps the model it had
      if (buildDialog_) buildDialog_->deleteLater();
      buildDialog_.clear();
    });
  }
  buildDialog_->setValue(static_cast<int>(1000 * std::clamp(done, 0.0, 1.0)));
}

}  // namespace rehearse::ui
