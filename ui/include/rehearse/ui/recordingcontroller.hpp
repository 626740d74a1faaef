#pragma once
// Recording step 7 into the case file and opening its review (the main window's Record, Stop and Review, and the
// Simulation menu's): the case must be a saved .rehearse file and registered; the session is named by the trainee.
#include <QObject>
#include <QString>

#include <functional>

class QDialog;
class QMenu;

namespace rehearse::ui {

class CaseDocument;
class SimulationPanel;
class RehearsePage;
class ReviewWindow;

class RecordingController : public QObject {
  Q_OBJECT
 public:
  /// `say`: a sentence for the status bar and the Messages panel; `window`: the review windows' parent. The page's
  /// Record, Stop and Review buttons and the panel's restarts and stops of a recording are wired here.
  RecordingController(CaseDocument* doc, SimulationPanel* simulation, RehearsePage* page, QWidget* window,
                      std::function<void(const QString&)> say);
  /// Adds "Start / Stop Recording" (Ctrl+R), "Review Recorded Rehearsals..." (Ctrl+Shift+R) and "Incorrect-Action
  /// Rules..." to `menu`.
  void addActions(QMenu* menu);
  /// Starts recording; an empty string when it started, else why not (one sentence).
  QString start(const QString& trainee);
  void stop();
  bool recording() const;
  /// The review window of the case file's sessions (null, said, when the case has no file yet).
  ReviewWindow* openReview();
  /// The trainer's incorrect-action rules of the case (incorrect_actions.hpp), in a dialog (object name
  /// "incorrectActionRulesDialog"; shown, not modal): OK stores them in the case as one undoable edit; the sessions
  /// recorded from then on carry them, with the case's camera as the view. Null (said) without a case.
  QDialog* editRules();

 private:
  CaseDocument* doc_;
  SimulationPanel* simulation_;
  RehearsePage* page_;
  QWidget* window_;
  std::function<void(const QString&)> say_;
};

}  // namespace rehearse::ui
