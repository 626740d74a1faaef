#pragma once
// Recording step 7 into the case file and opening its review (the main window's Record, Stop and Review, and the
// Simulation menu's): the case must be a saved .rehearse file and registered; the session is named by the trainee.
#include <QObject>
#include <QString>

#include <functional>

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
  /// Adds "Start / Stop Recording" (Ctrl+R) and "Review Recorded Rehearsals..." (Ctrl+Shift+R) to `menu`.
  void addActions(QMenu* menu);
  /// Starts recording; an empty string when it started, else why not (one sentence).
  QString start(const QString& trainee);
  void stop();
  bool recording() const;
  /// The review window of the case file's sessions (null, said, when the case has no file yet).
  ReviewWindow* openReview();

 private:
  CaseDocument* doc_;
  SimulationPanel* simulation_;
  RehearsePage* page_;
  QWidget* window_;
  std::function<void(const QString&)> say_;
};

}  // namespace rehearse::ui
