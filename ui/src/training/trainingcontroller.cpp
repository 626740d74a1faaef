#include "rehearse/ui/trainingcontroller.hpp"

#include "rehearse/ui/casedocument.hpp"
#include "rehearse/ui/cohortwindow.hpp"

#include <QFileInfo>
#include <QFutureWatcher>
#include <QInputDialog>
#include <QLineEdit>
#include <QMenu>
#include <QSettings>
#include <QtConcurrent/QtConcurrentRun>

namespace rehearse::ui {

TrainingController::TrainingController(CaseDocument* doc, QWidget* window, std::function<void(const QString&)> say)
    : QObject(window), doc_(doc), window_(window), say_(std::move(say)) {}

void TrainingController::addActions(QMenu* menu) {
  menu->addAction(tr("&Publish Recorded Sessions..."), this, [this] {
    const QString path = doc_->path();
    if (path.isEmpty() || !QFileInfo::exists(path))
      return say_(tr("Save the case and record a rehearsal first: sessions are published from the case file."));
    if (QString service; askService(service)) publish(service);
  });
  menu->addAction(tr("Training &Cohort..."), this, [this] {
    if (QString service; askService(service)) openCohort(service);
  });
}

bool TrainingController::askService(QString& service) {
  QSettings settings;
  bool ok = false;
  service = QInputDialog::getText(
      window_, tr("Training database"),
      tr("libpq service name (pg_service.conf; empty: PGHOST, PGDATABASE, ... from the environment):"),
      QLineEdit::Normal, settings.value(QStringLiteral("training/service")).toString(), &ok);
  if (ok) settings.setValue(QStringLiteral("training/service"), service);
  return ok;
}

void TrainingController::publish(const QString& service) {
  const QString path = doc_->path();
  say_(tr("Publishing the sessions of %1 (each is replayed and verified first)...").arg(QFileInfo(path).fileName()));
  auto* watcher = new QFutureWatcher<QString>(this);
  connect(watcher, &QFutureWatcher<QString>::finished, this, [this, watcher] {
    say_(watcher->result());
    watcher->deleteLater();
  });
  watcher->setFuture(QtConcurrent::run([path, service] {
    try {
      app::TrainingDatabase db(service.toStdString());  // its own connection, on this thread
      const auto r = db.publish(path.toStdString());
      QString text = tr("Published %1 sessions (%2 already there, %3 not published).")
                         .arg(r.published)
                         .arg(r.already)
                         .arg(r.skipped);
      for (const std::string& note : r.notes) text += " " + QString::fromStdString(note);
      return text;
    } catch (const std::exception& e) {
      return tr("Publishing failed: %1").arg(QString::fromStdString(e.what()));
    }
  }));
}

void TrainingController::openCohort(const QString& service) {
  try {
    auto* w = new CohortWindow(std::make_shared<app::TrainingDatabase>(service.toStdString()), window_);
    w->setAttribute(Qt::WA_DeleteOnClose);
    w->setWindowFlag(Qt::Window);
    w->show();
  } catch (const std::exception& e) {
    say_(tr("The training database cannot be opened: %1").arg(QString::fromStdString(e.what())));
  }
}

}  // namespace rehearse::ui
