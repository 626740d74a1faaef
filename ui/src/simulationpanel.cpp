#include "rehearse/ui/simulationpanel.hpp"
#include "rehearse/ui/throttle.hpp"
#include "rehearse/ui/steadybox.hpp"
#include "simulationform.hpp"

#include <rehearse/app/materials.hpp>

#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/session/field.hpp>

#include <QFutureWatcher>
#include <QHBoxLayout>
#include <QLabel>
#include <QPainter>
#include <QPaintEvent>
#include <QPointer>
#include <QMessageBox>
#include <QPushButton>
#include <QStringList>
#include <QTimer>
#include <QtConcurrent/QtConcurrent>
#include <QVBoxLayout>

#include <algorithm>
#include <cmath>

Q_DECLARE_METATYPE(std::shared_ptr<const rehearse::ui::SimulationFrame>)

namespace rehearse::ui {

namespace {
simcore::InputEvent parameter(const std::string& name, double value, int label = 0) {
  simcore::InputEvent e;
  e.kind = simcore::InputKind::Parameter;
  e.name = name;
  e.value = value;
  e.label = label;
  return e;
}

// The same organ in the same shape, place and attachments (then a material or run edit keeps the state).
bool sameBody(const app::Case* a, const app::Case* b) {
  return a && b && a->organ == b->organ && a->shapeNodes() == b->shapeNodes() && a->attachments == b->attachments &&
         a->pose.R == b->pose.R && a->pose.t == b->pose.t;
}

}  // namespace

// ------------------------------------------------------------------------------------ session start

void SimulationPanel::startSession(const SimulationSetup& s, std::optional<RecordRequest> record) {
  const bool started = host_->start(s, record);  // the old session retired at once (its recording completed)
  if (!record && recordRequest_) {  // a new organ (or none) ends the recording: said, never silently
    recordRequest_.reset();
    emit recordingStopped(
        tr("The recording ended: the organ, its shape, pose or attachments changed (what was recorded is kept, "
           "complete)."));
  }
  startRefused_ = false;
  startWord_.clear();
  kept_.reset();
  // The frame on show is the ended session's until the new one's first arrives: what it shows is not this rehearsal's
  // (an undo right after a Discard asked again about the rehearsal just discarded).
  superseded_ = last_;
  resetPending_ = false;
  if (!started) {
    // The old session is over: its organ is not shown on (a new case without an organ kept showing it, greyed, and
    // its cut was asked about).
    const QString why = tr("No organ volume to simulate; load or tetrahedralise a mesh first.");
    last_.reset();
    view_->clearFrame(why);
    onFailed(why);
    return;
  }
  builtWith_ = s.organ->material;
}

void SimulationPanel::sessionStarted(const QString& words) {
  startWord_ = words;
  if (!words.isEmpty()) emit startSaid(words);
  // A refusal said before (nothing held it, no equilibrium) is over: the organ runs (it said so while paused too).
  if (!error_.isEmpty()) {
    error_.clear();
    statusThrottle_->request();
  }
  const auto& b = host_->session()->setup();
  asked_ = {b.settings.timeStep,
            b.tools.graspRadius,
            b.tools.clip.length,
            b.settings.accuracyPosition,
            b.settings.method,
            b.model,
            b.settings.gravity};
  // What was asked while the body was being built: edits first (they apply at the first step), then the run.
  if (organ_ && !(organ_->material == builtWith_)) postMaterial(builtWith_, organ_->material);
  postRunParameters();
}

void SimulationPanel::sessionRefused(const QString& why, bool wasRecorded) {
  startRefused_ = true;  // a setting changed on the panel tries again (postRunParameters)
  // The last session's organ is not what runs: no frame of it stays on show (it kept its time and attachments).
  last_.reset();
  view_->clearFrame(why);
  onFailed(why);
  if (wasRecorded) emit recordingStopped(tr("The recording did not start: %1").arg(why));
}

// ------------------------------------------------------------------------------------------- panel

SimulationPanel::SimulationPanel(QWidget* parent) : QWidget(parent) {
  qRegisterMetaType<std::shared_ptr<const SimulationFrame>>();
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(4, 4, 4, 4);
  view_ = new SimulationView(this);
  view_->setObjectName(QStringLiteral("simulationView"));
  layout->addWidget(view_, 1);
  form_ = new SimulationForm(this);
  host_ = new SessionHost(this);
  connect(host_, &SessionHost::started, this, &SimulationPanel::sessionStarted);
  connect(host_, &SessionHost::refused, this, &SimulationPanel::sessionRefused);
  connect(host_, &SessionHost::frame, this, &SimulationPanel::onFrame);
  connect(host_, &SessionHost::restProgress, this, [this](const QString& text) { status_->setText(text); });
  connect(host_, &SessionHost::recordingStopped, this, &SimulationPanel::recordingStopped);
  connect(host_, &SessionHost::recordingRetired, this, [this](qint64 id, long lastStep, bool discarded) {
    if (id <= 0 || id != resetEnded_) return;
    resetEnded_ = 0;
    // Stopped meanwhile (Reset then Stop at once): the stop has said what was kept, and the page is not recording (this
    // sentence set it to recording again, and the next Record click stopped instead).
    if (!recordRequest_ || !host_->recording()) return;
    // A session that took no step is not kept (StepRecording::finish drops it from the file).
    emit recordingRestarted(
        discarded
            ? tr("Reset: session %1 recorded no step and is not kept; the run from rest is recorded as a new session.")
                  .arg(id)
            : tr("Reset: recorded session %1 ended at step %2; the run from rest is recorded as a new session.")
                  .arg(id)
                  .arg(lastStep));
  });

  auto* buttons = new QHBoxLayout;
  playButton_ = new QPushButton(tr("Play"), this);
  playButton_->setObjectName(QStringLiteral("simPlay"));
  playButton_->setToolTip(tr("Play or pause the simulation (F5)"));
  stepButton_ = new QPushButton(tr("Step"), this);
  stepButton_->setObjectName(QStringLiteral("simStep"));
  stepButton_->setToolTip(tr("One time step (F6)"));
  resetButton_ = new QPushButton(tr("Reset"), this);
  resetButton_->setObjectName(QStringLiteral("simReset"));
  resetButton_->setToolTip(tr("Back to the rest shape (Shift+F5)"));
  buttons->addWidget(playButton_);
  buttons->addWidget(stepButton_);
  buttons->addWidget(resetButton_);
  layout->addLayout(buttons);
  status_ = new LinesLabel(6, this);
  statusThrottle_ = std::make_unique<Throttle>(this, [this] {
    const QString text = statusText();
    status_->setText(text);
    status_->setToolTip(text);
    emit statusChanged(text);
  });
  status_->setObjectName(QStringLiteral("simStatus"));
  status_->setWordWrap(true);
  // A fixed height of six lines, the text from the top: the controls below stay put whatever the sentence's length
  // (they moved with every message); a longer one ends in an ellipsis at the sixth line (it was cut off mid-line) and
  // is whole in the tooltip. (In a scroll area of its own it cost the GUI thread 50 ms at each new sentence.)
  status_->setAlignment(Qt::AlignTop | Qt::AlignLeft);
  layout->addWidget(new SteadyBox(status_, this));  // a new sentence is repainted, the panel not laid out again
  // The settings below the controls and the status: on a 900-px screen Play, Step, Reset and what the simulation says
  // stay in view without scrolling the panel (the settings, changed less often, scroll).
  layout->addWidget(form_);

  connect(playButton_, &QPushButton::clicked, this, &SimulationPanel::togglePlay);
  connect(stepButton_, &QPushButton::clicked, this, &SimulationPanel::stepOnce);
  connect(resetButton_, &QPushButton::clicked, this, &SimulationPanel::resetAsked);
  // Clicked (the field being typed in committed as the button took the keys), the keys go back to where the instruments
  // are (a person's Space after Reset and Cancel opened the Reset question again: the button had kept them). Reset's
  // question gives them back when it is answered.
  connect(playButton_, &QPushButton::clicked, this, &SimulationPanel::keysBack);
  connect(stepButton_, &QPushButton::clicked, this, &SimulationPanel::keysBack);
  connect(form_, &SimulationForm::presetChosen, this, &SimulationPanel::applyPreset);
  connect(form_, &SimulationForm::materialEdited, this, &SimulationPanel::materialFieldsEdited);
  connect(form_, &SimulationForm::runEdited, this, &SimulationPanel::postRunParameters);
  connect(form_, &SimulationForm::startToggled, this, &SimulationPanel::startToggled);
  connect(form_, &SimulationForm::colouringChosen, host_, &SessionHost::setColouring);
  updateButtons();
}

SimulationPanel::~SimulationPanel() = default;  // (the host, a child, joins the session and completes its recording)

void SimulationPanel::startToggled(bool on) {
  if (recordRequest_) {  // a recorded session's start is part of it: not changed under it
    form_->showStart(!on);
    const QString why = tr("Stop the recording first: how the organ starts is part of the recorded session.");
    status_->setText(why);
    emit statusChanged(why);
    return;
  }
  if (!organ_) return;
  playing_ = false;
  startSession(setup());  // a new session from the new start
  updateButtons();
}

QString SimulationPanel::startRecording(const QString& file, const app::SessionMeta& meta) {
  if (file.isEmpty()) return tr("Save the case to a file first (File > Save): the rehearsal is recorded into it.");
  if (!organ_ || organ_->organ->empty())
    return tr("No organ volume to rehearse on; load or tetrahedralise a mesh first.");
  // The recorder opens the file on the worker; a file it cannot write is said at once instead.
  try {
    (void)app::listRecordings(file.toStdString());
  } catch (const std::exception& e) {
    return QString::fromStdString(e.what());
  }
  const bool wasPlaying = playing_;
  recordRequest_ = RecordRequest{file.toStdString(), meta};
  startSession(setup(), recordRequest_);
  if (wasPlaying) play();
  return {};
}

bool SimulationPanel::stopRecording() {
  recordRequest_.reset();
  // The recording keeps the session as it is now (what the instruments do after it is not kept).
  if (last_ && recording()) kept_ = workOf(*last_);
  return host_->stopRecording();
}

qint64 SimulationPanel::recordingId() const { return host_->recordingId(); }

void SimulationPanel::suspendRecording() { host_->suspendRecording(); }

void SimulationPanel::caseFileReplaced(const QString& file) {
  if (recordRequest_) recordRequest_->file = file.toStdString();  // a reset goes on recording into the file as saved
  host_->recordingFileReplaced(file.toStdString());
}

SimulationSetup SimulationPanel::setup() const {
  SimulationSetup s;
  s.organ = organ_;
  if (organ_) {
    const auto& m = organ_->material;  // the case's material: what the fields show once the window applied them
    s.model = m.model;
    s.young = m.young;
    s.poisson = m.poisson;
    s.density = m.density;
    s.vesselYoung = m.vesselYoung;
    s.vesselPoisson = m.vesselPoisson;
    s.tearStrain = m.tearStrain;
    s.supportModulus = m.supportModulus;
  }
  form_->runSettings(s);
  return s;
}

void SimulationPanel::setCase(std::shared_ptr<const app::Case> c) {
  const auto previous = organ_;
  organ_ = std::move(c);
  form_->setOrganVolume(organ_ && !organ_->organ->empty() ? organ_->organ->quality.volume : 0.0);
  if (organ_) form_->showMaterial(organ_->material);
  const bool sameOrgan = sameBody(previous.get(), organ_.get());
  if (sameOrgan) {
    // The same organ in the same shape, place and attachments keeps running; a material edit is applied
    // at the next step boundary, keeping the state.
    // A new support is a new start (its springs are placed on the registered shape, the rest shape solved on them).
    if (previous->material.supportModulus == organ_->material.supportModulus) {
      if (!(previous->material == organ_->material)) postMaterial(previous->material, organ_->material);
      postRunParameters();  // the case's gravity (an undo, a redo): a new start or posted, as the panel's own change
      return;
    }
  }
  // A new support's start plays on if the organ was playing, as a new gravity's does (it stopped, a user's check); a
  // new organ starts paused.
  const bool playOn = sameOrgan && playing_;
  playing_ = false;
  if (!sameOrgan) emit sessionReplaced();
  startSession(setup());
  if (playOn) play();
  updateButtons();
}

void SimulationPanel::postMaterial(const app::MaterialSettings& before, const app::MaterialSettings& m) {
  simcore::Session* session = host_->session();
  if (!session) return;
  // As timestamped events through the session's mailbox (recorded with the run, like any input).
  if (m.model != before.model) session->post(parameter("model", static_cast<double>(m.model)));
  if (m.young != before.young) session->post(parameter("young", m.young));
  if (m.poisson != before.poisson) session->post(parameter("poisson", m.poisson));
  if (m.density != before.density) session->post(parameter("density", m.density));
  if (m.tearStrain != before.tearStrain) {
    session->post(parameter("tear_strain", m.tearStrain));
    if (m.vesselYoung > 0) session->post(parameter("tear_strain", m.tearStrain, app::kVesselLabel));
  }
  if (m.vesselYoung != before.vesselYoung || m.vesselPoisson != before.vesselPoisson) {
    session->post(parameter("young", m.vesselYoung, app::kVesselLabel));
    if (m.vesselYoung > 0) session->post(parameter("poisson", m.vesselPoisson, app::kVesselLabel));
  }
}

void SimulationPanel::applyPreset(const QString& name) {
  if (!organ_ || organ_->organ->empty()) return;
  try {
    emit materialEdited(app::presetMaterial(name.toStdString(), *organ_->organ));
  } catch (const std::exception& e) {
    onFailed(QString::fromStdString(e.what()));
  }
}

void SimulationPanel::materialFieldsEdited() {
  if (!organ_) return;
  // The material belongs to the case (the fit uses it too): an undoable edit, applied back through setCase.
  const app::MaterialSettings m = form_->material(organ_->material);
  if (!(m == organ_->material)) emit materialEdited(m);
}

void SimulationPanel::postRunParameters() {
  // Run parameters (time step, solver, gravity): events applied at the next step boundary, keeping the state; each
  // compared with what was last asked (the session's own setup lags until that boundary).
  simcore::Session* session = host_->session();
  if (!session) {
    // The organ was not started (no equilibrium where the frame shows it, nothing holding it): what the assistant
    // changes on the panel is tried at once.
    if (startRefused_ && organ_) {
      startSession(setup());
      updateButtons();
    }
    return;
  }
  const SimulationSetup s = setup();
  if (s.timeStep != asked_.timeStep) session->post(parameter("dt", asked_.timeStep = s.timeStep));
  if (s.graspRadius != asked_.graspRadius)
    session->post(parameter("grasp_radius", asked_.graspRadius = s.graspRadius));
  if (s.clipLength != asked_.clipLength) session->post(parameter("clip_length", asked_.clipLength = s.clipLength));
  if (s.accuracy != asked_.accuracy) session->post(parameter("accuracy", asked_.accuracy = s.accuracy));
  if (s.bodyModel != asked_.model) {
    asked_.model = s.bodyModel;
    host_->modelAsked(s.bodyModel);
    session->post(parameter("body_model", static_cast<double>(s.bodyModel)));  // the enum's order
  }
  if (s.bodyModel == simcore::BodyModel::Fem && s.method != asked_.method) {
    asked_.method = s.method;
    session->post(parameter("method", static_cast<double>(s.method)));
  }
  // (What the session ran is read from its last frame: its setup belongs to the stepping thread.)
  const bool cut = last_ && last_->surface;
  if (s.gravity != asked_.gravity && !recordRequest_ && s.startInEquilibrium && !cut) {
    // The start (and the supports) are solved for the gravity they were placed for: another gravity is a new start,
    // solved for it, as long as nothing was cut (then it acts on the running organ). Posted to the running organ, it
    // sagged 5 mm while the panel still said it started in equilibrium (a user's check).
    const bool wasPlaying = playing_;
    playing_ = false;
    startSession(s);
    if (wasPlaying) play();
    updateButtons();
    return;
  }
  if (s.gravity != asked_.gravity) {
    simcore::InputEvent g;
    g.kind = simcore::InputKind::Gravity;
    g.vector = asked_.gravity = s.gravity;
    session->post(g);
  }
}

bool SimulationPanel::post(simcore::InputEvent e) {
  if (!host_->post(std::move(e))) return false;
  if (!playing_) {
    play();
    if (playing_) emit playedByInput();
  }
  return true;
}

void SimulationPanel::play() {
  if (!organ_) return;
  if (!host_->session() && startRefused_) {  // nothing runs until a setting lets it start: Play does not pretend it plays
    updateButtons();
    return;
  }
  playing_ = true;
  error_.clear();
  rate_.clock.start();
  rate_.frames = 0;
  host_->play();
  updateButtons();
  emit playingChanged(true);
}

void SimulationPanel::pause() {
  playing_ = false;
  host_->pause();
  updateButtons();
  emit playingChanged(false);
}

void SimulationPanel::togglePlay() { playing_ ? pause() : play(); }

void SimulationPanel::stepOnce() {
  if (!organ_) return;
  playing_ = false;
  error_.clear();
  host_->stepOnce();  // (once the body is built, when it is being built)
  updateButtons();
}

void SimulationPanel::reset() {
  playing_ = false;
  error_.clear();
  if (recordRequest_ && host_->recording()) {
    // A recorded session's steps only go forwards: the run from rest is another session (the one recorded so far
    // ends complete where it was; both replay and verify).
    const qint64 ended = recordingId();
    startSession(setup(), recordRequest_);
    // Said once the ended session is complete in the file (recordingRetired): its last step is known then (read here,
    // the step under way was still to come: a person read 27298 where the file has 27299).
    resetEnded_ = ended;
    if (ended <= 0) emit recordingRestarted(tr("Reset: the run from rest is recorded as a new session."));
  } else if (organ_ && setup().startInEquilibrium && mechanicallyOther(organ_->material, builtWith_)) {
    // The start was solved for the material the session was built with: after an edit (a softer tissue) the same
    // rest shape hangs elsewhere, so Reset solves the start again for the material now (a person set Young's modulus
    // from 27 to 3 kPa and pressed Reset: the start's sentence was the 27 kPa one, and the organ sagged from it).
    startSession(setup());
  } else {
    host_->reset();
    resetPending_ = true;  // (the frames of steps before it are not the rehearsal's: unkeptWork)
  }
  updateButtons();
  emit wasReset();
}

bool SimulationPanel::startsAnew(const app::Case& before, const app::Case& after) const {
  if (!sameBody(&before, &after) || before.material.supportModulus != after.material.supportModulus) return true;
  const bool cut = last_ && last_->surface;
  return before.material.gravity != after.material.gravity && !recordRequest_ && setup().startInEquilibrium && !cut;
}

bool SimulationPanel::mechanicallyOther(app::MaterialSettings a, app::MaterialSettings b) {
  a.tearStrain = b.tearStrain = 0;  // (where the tissue tears does not move the start)
  return !(a == b);
}

void SimulationPanel::resetAsked() {
  const QString unkept = unkeptWork();
  if (unkept.isEmpty()) {
    reset();
    emit keysBack();
    return;
  }
  // Reset discarded an unrecorded cut without a word, where quitting or opening another case asked.
  auto* box = new QMessageBox(QMessageBox::Warning, tr("Rehearsal not kept"),
                              tr("Reset takes the organ back to rest and ends this rehearsal (%1), which is not "
                                 "recorded.")
                                  .arg(unkept),
                              QMessageBox::Reset | QMessageBox::Cancel, this);
  box->setObjectName(QStringLiteral("resetRehearsalBox"));
  box->setInformativeText(tr("Only a recording keeps a rehearsal (Ctrl+R). Reset ends it; Cancel goes back to it."));
  box->setDefaultButton(QMessageBox::Cancel);
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->setWindowModality(Qt::WindowModal);
  // The organ waits while the question is read (what it names would change); Cancel plays it on.
  const bool wasPlaying = isPlaying();
  if (wasPlaying) pause();
  connect(box, &QMessageBox::finished, this, [this, box, wasPlaying](int) {
    QTimer::singleShot(0, this, &SimulationPanel::keysBack);  // (after the box has given the focus back to the button)
    if (box->standardButton(box->clickedButton()) == QMessageBox::Reset) return reset();
    if (wasPlaying) play();
  });
  box->open();
}

SimulationPanel::ShownError SimulationPanel::shownError(const SimulationFrame& f, const ShownError& last) {
  // The session estimates its error every 10th step: the last estimate stays shown between them.
  // (The fast models estimate nothing: no estimate of an earlier body is shown for them.)
  // A step whose distance the check on the tangent found cannot be known says so (the estimate before it is not shown
  // as if it held), and so does a step that did not converge and estimated nothing.
  ShownError out;
  if (std::isfinite(f.report.errorPosition)) {
    out.position = f.report.errorPosition;
    out.force = std::isfinite(f.report.errorForce) ? f.report.errorForce : 0;
  } else if (f.steps == 0 || f.model != simcore::BodyModel::Fem) {
    // nothing shown
  } else if (f.report.errorUnknown || f.report.outcome == simcore::StepStatus::Inexact ||
             f.report.outcome == simcore::StepStatus::Failed) {
    out.unknown = true;
  } else {
    out = last;
  }
  return out;
}

void SimulationPanel::onFrame(std::shared_ptr<const SimulationFrame> f) {
  last_ = f;
  if (f->steps == 0) resetPending_ = false;  // the Reset's own frame: what comes after is the new rehearsal's
  shown_ = shownError(*f, shown_);
  if (asked_.model != f->model && f->message.contains(u"refused")) {
    // The model asked for was refused or its build cancelled: the list shows what runs.
    asked_.model = f->model;
    form_->showModel(f->model, asked_.method);
  }
  view_->setFrame(f);
  if (const QString why = host_->recordingFailure(); !why.isEmpty()) {
    recordRequest_.reset();
    emit recordingStopped(tr("The recording stopped (what was recorded is kept): %1").arg(why));
  }
  if (!f->report.ok && f->steps > 0) {
    playing_ = false;  // the worker stopped on a failed step
    updateButtons();
  }
  ++rate_.frames;
  if (rate_.clock.isValid() && rate_.clock.elapsed() > 500) {
    rate_.fps = 1e3 * rate_.frames / static_cast<double>(rate_.clock.elapsed());
    rate_.clock.restart();
    rate_.frames = 0;
  }
  statusThrottle_->request();  // the status line at most 15 times a second, the newest always shown
  emit frameShown(f->steps);
}

void SimulationPanel::onFailed(const QString& message) {
  playing_ = false;
  error_ = message;
  status_->setText(message);
  emit statusChanged(tr("Simulation: %1").arg(message));
  updateButtons();
}

SimulationPanel::Work SimulationPanel::workOf(const SimulationFrame& f) {
  Work w;
  w.cutFaces = f.surface ? f.surface->cutCount : 0;
  w.elements = f.elements;
  if (f.labels) w.burnt = static_cast<std::size_t>(std::count_if(f.labels->begin(), f.labels->end(), simcore::isBurnt));
  w.clips = f.field.clips.size();
  w.bloodLoss = f.field.bloodLoss;
  return w;
}

QString SimulationPanel::unkeptWork() const {
  // Nothing when the frame on show is not of the case's organ (a new case without one shows none).
  if (!last_ || last_ == superseded_ || resetPending_ || recording() || !organ_ || !last_->organ || last_->organ->organ != organ_->organ)
    return {};
  const Work now = workOf(*last_);
  // What a recording stopped since this session's start keeps: only what the instruments did after it is unkept, and
  // only that is named (a person read the recorded cut among what the question said was lost). Not the blood lost:
  // stumps the recording kept bleed on, with nothing done.
  const Work before = kept_.value_or(Work{0, last_->organ->organ->volume.tets.size(), 0, 0, 0});
  QStringList done;
  // A cut or a tear opens faces (and splits elements, unless the cut ran along their faces); a burn relabels them.
  if (now.cutFaces > before.cutFaces || (last_->surface && now.elements != before.elements)) done << tr("cut or torn");
  if (now.burnt > before.burnt) done << tr("burnt");
  if (const std::size_t clips = now.clips > before.clips ? now.clips - before.clips : 0; clips > 0)
    done << (clips == 1 ? tr("a clip") : tr("%1 clips").arg(clips));
  if (done.isEmpty()) return {};
  if (kept_) return tr("%1 since the recording stopped").arg(done.join(QStringLiteral(", ")));
  if (now.bloodLoss > 0) done << tr("%1 mL of blood lost").arg(1e6 * now.bloodLoss, 0, 'f', 1);
  return done.join(QStringLiteral(", "));
}

QString SimulationPanel::statusText() const {
  if (!error_.isEmpty()) return error_;
  if (!last_) return tr("Simulation ready");
  const auto& r = last_->report;
  // An imported organ has no ligament nodes: it falls only where nothing else carries it (no support, gravity on).
  const bool loose = organ_ && organ_->attachments.empty() && !(last_->supports && !last_->supports->empty()) &&
                     last_->gravity.norm() > 0;
  if (last_->steps == 0)
    return !startWord_.isEmpty() ? tr("t = 0. %1").arg(startWord_)
           : loose ? tr("Simulation at rest (t = 0). Nothing holds this organ (no attachment nodes, no support): it "
                        "will fall under gravity.")
                   : tr("Simulation at rest (t = 0)");
  if (!last_->message.isEmpty()) return last_->message;
  const QString rate = playing_ ? tr(" · %1 fps").arg(rate_.fps, 0, 'f', 0) : QString();
  // The fast models do no Newton iteration: their name instead (the model that ran the step).
  const QString solver = last_->model == simcore::BodyModel::Precomputed ? tr("precomputed linear")
                         : last_->model == simcore::BodyModel::Hybrid    ? tr("hybrid")
                         : last_->model == simcore::BodyModel::Ffd       ? tr("FFD")
                         : r.newtonIterations == 1                       ? tr("1 Newton iteration")
                                                                         : tr("%1 Newton iterations").arg(r.newtonIterations);
  // How far the step is from the converged answer, estimated as it ran (issue 64): in millimetres, and in newtons on
  // the tool while it holds or touches the tissue.
  QString error;
  // (In plain decimals: "±4.9e-10 mm" read as the program's jargon; below a thousandth, "within 0.001 mm".)
  const auto amount = [](double v, const QString& unit) {
    return v < 5e-4 ? tr("within 0.001 %1").arg(unit) : tr("±%1 %2").arg(QString::number(v, v < 1 ? 'f' : 'g', 3), unit);
  };
  if (std::isfinite(shown_.position)) {
    error = tr(" · %1").arg(amount(1e3 * shown_.position, tr("mm")));
    if (shown_.force > 0) error += tr(", %1").arg(amount(shown_.force, tr("N")));
  } else if (shown_.unknown) {
    error = tr(" · distance from the converged answer not known");
  }
  // (A step whose residual met the tolerance while its distance is not known read "... not known · converged" to a
  // person, as a contradiction: what converged is said.)
  QString status = QString::fromStdString(simcore::statusSentence(r));
  if (shown_.unknown && !std::isfinite(shown_.position) && status == QLatin1String("converged"))
    status = tr("converged by its residual");
  return tr("t = %1 s · step %2 ms%3 · %4%5 · %6")
      .arg(last_->time, 0, 'f', 2)
      .arg(r.wallMs, 0, 'f', 1)
      .arg(rate)
      .arg(solver)
      .arg(error)
      .arg(status);
}

void SimulationPanel::updateButtons() {
  playButton_->setText(playing_ ? tr("Pause") : tr("Play"));
  const bool have = organ_ && !organ_->organ->empty();
  playButton_->setEnabled(have);
  stepButton_->setEnabled(have);
  resetButton_->setEnabled(have);
}

}  // namespace rehearse::ui
