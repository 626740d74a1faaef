#pragma once
// A step page: the panel of one workflow step (app::kSteps), one class each (pages/meshpage.hpp ...).
// A page edits the case only through the CaseDocument (undoable), starts long work through the JobRunner,
// picks frame-view tools, and redraws itself from the case in refresh(). A new step (appearance,
// rehearsal) is one more StepPage subclass and one row of app::kSteps; the main window only stacks them.
#include "rehearse/ui/casedocument.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/jobrunner.hpp"

#include <rehearse/app/workflow.hpp>

#include <QWidget>

#include <QKeySequence>

#include <functional>
#include <map>

class QAction;
class QPushButton;

namespace rehearse::ui {

/// Keys that mean one thing per step (E edits points in step 3 and turns the organ in step 4): one
/// window-wide action per key, which calls the handler of the step shown, wherever the focus is.
class StepKeys {
 public:
  StepKeys(QWidget* window, std::function<app::Step()> currentStep) : window_(window), current_(std::move(currentStep)) {}
  /// `what` (what the key does in that step) goes to the keyboard reference (keyboardreference.hpp), kept on the
  /// key's action as its "rehearseStepKeys" property (step number -> what).
  void bind(const QKeySequence& key, app::Step step, std::function<void()> handler, const QString& what = {});
  /// A step is shown: only its keys are live (a key no step uses here goes to the focused widget: the
  /// arrows to a list or a combo box in step 3, to the pose nudges in step 4).
  void stepShown(app::Step step);

 private:
  QWidget* window_;
  std::function<app::Step()> current_;
  std::map<QString, std::map<app::Step, std::function<void()>>> handlers_;  ///< by key text
  std::map<QString, QAction*> actions_;
};

/// What every page works with (owned by the main window, which outlives the pages).
struct Workbench {
  CaseDocument* doc = nullptr;
  FrameView* view = nullptr;
  JobRunner* jobs = nullptr;
  QWidget* window = nullptr;                        ///< for dialogs and window-wide shortcuts
  std::function<void(const QString&)> status;       ///< a sentence for the status bar
  std::function<void(const QString&)> log;          ///< a sentence for the Messages panel only
  std::function<void(app::Step)> goToStep;          ///< shows a step's page (and its default tool)
  std::function<app::Step()> currentStep;
  /// Runs `then` once a rehearsal nothing keeps has ended: at once when there is none, else after asking whether
  /// `doing` may end it (MainWindow::askToEndRehearsal; Discard ends it, Cancel runs `otherwise`).
  std::function<void(const QString& doing, std::function<void()> then, std::function<void()> otherwise)> endRehearsal;
  StepKeys* keys = nullptr;
};

class StepPage : public QWidget {
  Q_OBJECT
 public:
  StepPage(Workbench& wb, app::Step step, QWidget* parent = nullptr);
  app::Step step() const { return step_; }
  /// Redraws the page's fields from the case (called on every change of the case; no edits from here).
  virtual void refresh(const app::Case& c) = 0;
  /// A new case was loaded (forget per-case transient state such as landmarks or a pending fit).
  virtual void caseLoaded() {}

 protected:
  /// A button that picks `tool` in the frame view; `key` does the same from anywhere, after going to
  /// this page's step.
  QPushButton* toolButton(QWidget* parent, const QString& text, const QString& tip, Tool tool, Qt::Key key);
  /// A key that does `handler` while this page's step is shown (StepKeys).
  void stepKey(const QKeySequence& key, std::function<void()> handler, const QString& what = {});
  const std::shared_ptr<const app::Case>& data() const { return wb_.doc->data(); }

  Workbench& wb_;
  bool updating_ = false;  ///< true while refresh() fills fields (their change signals are not edits)

 private:
  app::Step step_;
};

/// The folder a file dialog opens in: the last one any dialog took a file from or saved one to, else the user's home
/// (not the working directory the program happened to be started in, a person's check).
QString dialogFolder();
/// Remembers `file`'s folder for the next dialog (QSettings "lastDir").
void rememberDialogFolder(const QString& file);

}  // namespace rehearse::ui
