#include "rehearse/ui/recordingcontroller.hpp"

#include "rehearse/ui/casedocument.hpp"
#include "rehearse/ui/pages/rehearsepage.hpp"
#include "rehearse/ui/reviewwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <rehearse/app/recording.hpp>

#include <QDateTime>
#include <QMenu>
#include <QFileInfo>

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
  const QString text = tr("Recording%1 into %2 (the simulation started again from rest).")
                           .arg(trainee.isEmpty() ? QString() : tr(" %1").arg(trainee))
                           .arg(QFileInfo(path).fileName());
  page_->showRecording(true, text);
  say_(text);
  return {};
}

void RecordingController::stop() {
  if (!recording()) return;
  const qint64 id = simulation_->recordingId();
  simulation_->stopRecording();
  const QString text =
      tr("Recorded session %1 in %2; review it with Ctrl+Shift+R.").arg(id).arg(QFileInfo(doc_->path()).fileName());
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
  auto* w = new ReviewWindow(path, camera, frame, window_);
  w->setAttribute(Qt::WA_DeleteOnClose);
  w->setWindowFlag(Qt::Window);
  w->show();
  return w;
}

}  // namespace rehearse::ui
