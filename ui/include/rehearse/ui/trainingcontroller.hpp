#pragma once
// The training centre's database from the main window (the Simulation menu's Publish and Cohort): the connection from
// a libpq service name asked once and kept as a setting of this machine (never in the case file); publishing replays
// and verifies each session off the GUI thread; the cohort window opens on its own connection.
#include <QObject>
#include <QString>

#include <functional>

class QMenu;
class QWidget;

namespace rehearse::ui {

class CaseDocument;

class TrainingController : public QObject {
  Q_OBJECT
 public:
  /// `say`: a sentence for the status bar and the Messages panel; `window`: the dialogs' and windows' parent.
  TrainingController(CaseDocument* doc, QWidget* window, std::function<void(const QString&)> say);
  /// Adds "Publish Recorded Sessions..." and "Training Cohort..." to `menu`.
  void addActions(QMenu* menu);
  /// Publishes the case file's sessions into the database of `service` (on a worker; the result is said).
  void publish(const QString& service);
  /// Opens the cohort window on the database of `service` (said when it cannot be opened).
  void openCohort(const QString& service);

 private:
  /// The libpq service name, asked (empty: the environment's PGHOST, PGDATABASE, ...); false when cancelled.
  bool askService(QString& service);
  CaseDocument* doc_;
  QWidget* window_;
  std::function<void(const QString&)> say_;
};

}  // namespace rehearse::ui
