#include "rehearse/ui/recordingcontroller.hpp"

#include "rehearse/ui/casedocument.hpp"
#include "rehearse/ui/pages/rehearsepage.hpp"
#include "rehearse/ui/reviewwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <rehearse/app/incorrect_actions.hpp>
#include <rehearse/app/recording.hpp>

#include <QCheckBox>
#include <QDateTime>
#include <QDialog>
#include <QDialogButtonBox>
#include <QDoubleSpinBox>
#include <QFileInfo>
#include <QFormLayout>
#include <QLabel>
#include <QMenu>
#include <QPushButton>
#include <QVBoxLayout>

#include <optional>

#ifndef REHEARSE_VERSION
#define REHEARSE_VERSION "0.0.0"
#endif

namespace rehearse::ui {

RecordingController::RecordingController(CaseDocument* doc, SimulationPanel* simulation, RehearsePage* page,
                                         QWidget* window, std::function<void(const QString&)> say)
    : QObject(window), doc_(doc), simulation_(simulation), page_(page), window_(window), say_(std::move(say)) {
  connect(simulation_, &SimulationPanel::recordingRestarted, this, [this](const QString& text) {
    say_(text);
    if (page_) page_->showRecording(true, text);
  });
  connect(simulation_, &SimulationPanel::recordingStopped, this, [this](const QString& why) {
    say_(why);
    if (page_) page_->showRecording(false, why);
  });
  if (page_)
    page_->setRecordHandlers(
        {[this](const QString& trainee) { return start(trainee); }, [this] { stop(); }, [this] { openReview(); }});
}

void RecordingController::addActions(QMenu* menu) {
  menu->addAction(tr("Start / Stop &Recording"), this,
                  [this] {
                    if (recording())
                      stop();
                    else if (const QString err = start(page_ ? page_->trainee() : QString()); !err.isEmpty())
                      say_(err);
                  })
      ->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_R));
  menu->addAction(tr("Re&view Recorded Rehearsals..."), this, [this] { openReview(); })
      ->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_R));
  auto* rules = menu->addAction(tr("&Incorrect-Action Rules..."), this, [this] { editRules(); });
  rules->setObjectName("incorrectActionRulesAction");
  rules->setStatusTip(tr("Which incorrect actions the trainer counts in this case's recorded rehearsals"));
}

bool RecordingController::recording() const { return simulation_->recording(); }

QString RecordingController::start(const QString& trainee) {
  const QString path = doc_->path();
  if (path.isEmpty() || !path.endsWith(QStringLiteral(".rehearse"), Qt::CaseInsensitive))
    return tr("Save the case as a case file first (File > Save As, .rehearse): the rehearsal is recorded into it.");
  if (!doc_->hasCase() || !doc_->data()->hasPose)
    return tr("Register the organ first (steps 4 and 5): the rehearsal runs on the registered organ.");
  app::SessionMeta meta;
  meta.trainee = trainee.toStdString();
  meta.caseName = QFileInfo(path).fileName().toStdString();
  meta.sceneVersion = ("saved " + QFileInfo(path).lastModified().toUTC().toString(Qt::ISODate)).toStdString();
  meta.appVersion = REHEARSE_VERSION;
  // The case's incorrect-action rules, with its camera as the view (the rehearsal's organ is in the camera frame).
  try {
    app::ActionRules rules = app::parseActionRules(doc_->data()->incorrectActions);
    const auto& camera = doc_->data()->camera;
    if (camera.problem().empty())
      rules.view = app::parseActionRules("{\"view\": " + app::cameraViewJson(camera) + "}").view;
    meta.rules = app::actionRulesJson(rules);
  } catch (const std::exception& e) {
    return tr("The case's incorrect-action rules cannot be used: %1").arg(QString::fromUtf8(e.what()));
  }
  const QString err = simulation_->startRecording(path, meta);
  if (!err.isEmpty()) return err;
  // Recording a paused simulation records nothing until Play: said (a person's check lost 3 s thinking it ran).
  const QString text = tr("Recording%1 into %2 (the simulation started again from rest%3).")
                           .arg(trainee.isEmpty() ? QString() : tr(" %1").arg(trainee))
                           .arg(QFileInfo(path).fileName())
                           .arg(simulation_->isPlaying() ? QString() : tr("; paused: nothing is recorded until Play, F5"));
  page_->showRecording(true, text);
  say_(text);
  return {};
}

void RecordingController::stop() {
  if (!recording()) return;
  const qint64 id = simulation_->recordingId();
  const bool kept = simulation_->stopRecording();
  const QString text =
      kept ? tr("Recorded session %1 in %2; review it with Ctrl+Shift+R.").arg(id).arg(QFileInfo(doc_->path()).fileName())
      : id > 0 ? tr("Recording stopped before the first step: nothing to keep (session %1 is not in %2).")
                     .arg(id)
                     .arg(QFileInfo(doc_->path()).fileName())
               // (Stop right after Reset: the new session was still being set up and had no number yet.)
               : tr("Recording stopped before the first step: nothing to keep.");
  page_->showRecording(false, text);
  say_(text);
  for (auto* review : window_->findChildren<ReviewWindow*>())
    review->refreshSessions();  // open review windows list it at once
}

ReviewWindow* RecordingController::openReview() {
  const QString path = doc_->path();
  if (path.isEmpty() || !QFileInfo::exists(path)) {
    say_(tr("The case has no file yet: save it, record a rehearsal (step 7), then review it."));
    return nullptr;
  }
  std::optional<imaging::Camera> camera;
  cv::Mat3b frame;
  if (doc_->hasCase() && !doc_->data()->frame.empty() && doc_->data()->camera.problem().empty()) {
    camera = doc_->data()->camera;
    frame = doc_->data()->frame;
  }
  // The review replays its sessions on the machine's cores: the organ's simulation, playing beside it unrecorded,
  // pauses (said; Play goes on) so that a two-core machine gives them to the replay. A recording goes on.
  if (simulation_->isPlaying() && !simulation_->recording()) {
    simulation_->pause();
    say_(tr("The simulation is paused while the review replays its sessions; press Play (step 7) to go on."));
  }
  auto* w = new ReviewWindow(path, camera, frame, window_);
  w->setAttribute(Qt::WA_DeleteOnClose);
  w->setWindowFlag(Qt::Window);
  w->show();
  return w;
}

QDialog* RecordingController::editRules() {
  if (!doc_->hasCase()) {
    say_(tr("Open a case first: the incorrect-action rules are the case's."));
    return nullptr;
  }
  if (auto* open = window_->findChild<QDialog*>("incorrectActionRulesDialog")) {  // one at a time
    open->raise();
    open->activateWindow();
    return open;
  }
  app::ActionRules rules;
  try {
    rules = app::parseActionRules(doc_->data()->incorrectActions);
  } catch (const std::exception&) {  // (checked when the case was read: the defaults otherwise)
  }
  auto* d = new QDialog(window_);
  d->setObjectName("incorrectActionRulesDialog");
  d->setWindowTitle(tr("Incorrect-Action Rules - Rehearse"));
  d->setAttribute(Qt::WA_DeleteOnClose);
  auto* layout = new QVBoxLayout(d);
  auto* intro =
      new QLabel(tr("What the trainer counts as an incorrect action in this case's rehearsals, each with "
                    "its time on the review's timeline. Sessions keep the rules they were recorded with."));
  intro->setWordWrap(true);
  layout->addWidget(intro);
  auto box = [&](const char* name, const QString& text, bool on) {
    auto* b = new QCheckBox(text);
    b->setObjectName(name);
    b->setChecked(on);
    layout->addWidget(b);
    return b;
  };
  auto* vessel =
      box("ruleVesselCut", tr("A vessel cut where no clip closes it (it bleeds)"), rules.vesselCutWithoutClips);
  auto* energy =
      box("ruleEnergy", tr("Energy on a named structure (vessel, duct, tumour, ligament)"), rules.energyOnStructure);
  auto* force = box("ruleForce", tr("The tool's force over the limit for too long"), rules.forceOverLimit);
  auto* form = new QFormLayout;
  auto spin = [](const char* name, double lo, double hi, int decimals, const QString& suffix, double value) {
    auto* b = new QDoubleSpinBox;
    b->setObjectName(name);
    b->setRange(lo, hi);
    b->setDecimals(decimals);
    b->setSuffix(suffix);
    b->setValue(value);
    return b;
  };
  auto* limit = spin("ruleForceLimit", 0.1, 100, 3, tr(" N"), rules.forceLimitN);
  auto* longer = spin("ruleForceTime", 0, 60, 3, tr(" s"), rules.forceLongerThanS);
  form->addRow(tr("    limit"), limit);
  form->addRow(tr("    for at least"), longer);
  layout->addLayout(form);
  connect(force, &QCheckBox::toggled, limit, &QWidget::setEnabled);
  connect(force, &QCheckBox::toggled, longer, &QWidget::setEnabled);
  limit->setEnabled(rules.forceOverLimit);
  longer->setEnabled(rules.forceOverLimit);
  auto* tear = box("ruleTear", tr("Tissue torn (pulled past its material's tear strain)"), rules.tear);
  auto* clip = box("ruleClip", tr("A clip misplaced (on no vessel or duct, or not across it)"), rules.clipMisplaced);
  const auto& camera = doc_->data()->camera;
  auto* outside = box("ruleOutsideView",
                      camera.problem().empty()
                          ? tr("An instrument used outside the view (the case's camera, %1 x %2 px)")
                                .arg(camera.width)
                                .arg(camera.height)
                          : tr("An instrument used outside the view (the case has no usable camera: not determined)"),
                      rules.outsideView);
  auto* buttons =
      new QDialogButtonBox(QDialogButtonBox::Ok | QDialogButtonBox::Cancel | QDialogButtonBox::RestoreDefaults);
  buttons->setObjectName("ruleButtons");
  layout->addWidget(buttons);
  connect(buttons, &QDialogButtonBox::rejected, d, &QDialog::reject);
  connect(buttons->button(QDialogButtonBox::RestoreDefaults), &QPushButton::clicked, d, [=] {
    const app::ActionRules defaults;
    vessel->setChecked(defaults.vesselCutWithoutClips);
    energy->setChecked(defaults.energyOnStructure);
    force->setChecked(defaults.forceOverLimit);
    limit->setValue(defaults.forceLimitN);
    longer->setValue(defaults.forceLongerThanS);
    tear->setChecked(defaults.tear);
    clip->setChecked(defaults.clipMisplaced);
    outside->setChecked(defaults.outsideView);
  });
  connect(buttons, &QDialogButtonBox::accepted, d, [=, this] {
    app::ActionRules r;  // the view is not the case's to keep: the camera is added when a session is recorded
    r.vesselCutWithoutClips = vessel->isChecked();
    r.energyOnStructure = energy->isChecked();
    r.forceOverLimit = force->isChecked();
    r.forceLimitN = limit->value();
    r.forceLongerThanS = longer->value();
    r.tear = tear->isChecked();
    r.clipMisplaced = clip->isChecked();
    r.outsideView = outside->isChecked();
    const std::string json = app::actionRulesJson(r);
    if (doc_->hasCase() && json != doc_->data()->incorrectActions) {
      doc_->edit(tr("Incorrect-action rules"), [json](app::Case& c) { c.incorrectActions = json; });
      say_(tr("The incorrect-action rules are set for the sessions recorded from now on."));
    }
    d->accept();
  });
  d->open();
  return d;
}

}  // namespace rehearse::ui
