#pragma once
// The main window: docks, menus and the status bar, nothing else. The workflow panel stacks one page per
// step (ui/pages/: mesh, frame, contour, rigid, fit; a new step is a new StepPage), the frame view in the
// centre shows the organ over the frame (OrganOverlay), the Case panel, the 3D organ view and the
// Simulation panel are docks. The case lives in the CaseDocument (undo, open/save/autosave); every view
// and page redraws from its changed() signal. Long work goes through the JobRunner (progress, Esc cancels).
#include "rehearse/ui/casedocument.hpp"
#include "rehearse/ui/composition.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/organoverlay.hpp"
#include "rehearse/ui/pages/appearancepage.hpp"
#include "rehearse/ui/pages/contourpage.hpp"
#include "rehearse/ui/pages/fitpage.hpp"
#include "rehearse/ui/pages/framepage.hpp"
#include "rehearse/ui/pages/meshpage.hpp"
#include "rehearse/ui/pages/rehearsepage.hpp"
#include "rehearse/ui/pages/rigidpage.hpp"

#include <rehearse/app/workflow.hpp>

#include <QElapsedTimer>
#include <QMainWindow>
#include <QMessageBox>
#include <QPointer>
#include <QTimer>

#include <memory>
#include <optional>

class QAction;
class QDockWidget;
class QLabel;
class QListWidget;
class QMenu;
class QPlainTextEdit;
class QProgressBar;
class QStackedWidget;
class QTimer;
class QToolButton;

namespace rehearse::ui {

class OrganView;
class OrganGLView;
class SimulationPanel;

using Step = app::Step;

/// What the centre of the window shows: the frame with the organ composited into it (step 6 on), the
/// frame with the organ drawn over it, or the organ alone in 3D.
enum class ViewMode { Composited = 0, Overlay, ThreeD };

class MainWindow : public QMainWindow {
  Q_OBJECT
 public:
  /// ms a reply such as "Cancelled: ..." stays in the status bar (sayBriefly).
  static constexpr int kBriefMessageMs = 6000;
  explicit MainWindow(QWidget* parent = nullptr);
  ~MainWindow() override;

  /// Loads a case file (.rehearse), a case folder, or the built-in phantom when `path` is empty, on a
  /// worker thread. The current case stays until the new one has loaded.
  void openCase(const QString& path);
  /// What a person's File > Open, Open Recent, Built-in Phantom, New Case, Recover and a dropped case do: asks
  /// Save / Discard / Cancel first when the case has unsaved changes (askToKeepChanges), then opens.
  void openCaseAsked(const QString& path);
  void newCaseAsked();
  void recoverAutosaveAsked();
  /// Runs `then` at once when the case has no unsaved changes; otherwise asks (a window-modal box, objectName
  /// "unsavedChangesBox") whether to save them before `doing` ("opening another case"): Save runs `then` once the
  /// save has succeeded (Save As asks where when the case has no file), Discard runs it at once, Cancel not at all.
  void askToKeepChanges(const QString& doing, std::function<void()> then);
  /// Runs `then` at once when no rehearsal that nothing keeps is under way (SimulationPanel::unkeptWork); otherwise
  /// asks (a window-modal box, objectName "endRehearsalBox": Discard / Cancel) whether `doing` ("importing liver.vtk",
  /// "the edit \u201cAttach 4 nodes\u201d") may end it: Discard runs `then`, Cancel says so, plays the organ on and runs
  /// `otherwise`. True when `then` ran at once. Edits, undos and redos that start another session ask here (the
  /// document's guard), and so does an import once it has read its file.
  bool askToEndRehearsal(const QString& doing, std::function<void()> then, std::function<void()> otherwise = {});
  bool isModified() const { return doc_->isModified(); }
  bool autosaveNewerThanCase() const { return doc_->autosaveNewerThanCase(); }
  /// Records the rehearsal (step 7) into the current case file from rest, the trainee named; one sentence on
  /// error (the case not saved to a file yet, a file that cannot be written), empty when recording.
  QString startRecording(const QString& trainee);
  void stopRecording();
  bool recording() const;
  /// Opens the review window on the current case file's recorded sessions (null, with a message, when the
  /// case has no file yet).
  class ReviewWindow* openReview();
  /// Saves the current case to `path` on a worker thread (atomic write); emits caseSaved.
  void saveCaseAs(const QString& path);
  QString currentPath() const { return doc_->path(); }
  bool isSaving() const { return doc_->isSaving(); }
  bool isLoading() const { return doc_->isLoading(); }
  bool isBusy() const { return doc_->isLoading() || jobs_->isRunning() || doc_->isSaving(); }
  static QString autosavePath() { return CaseDocument::autosavePath(); }
  static bool hasRecoverableAutosave() { return CaseDocument::hasRecoverableAutosave(); }
  void autosaveNow() { doc_->autosaveNow(); }
  QStringList recentFiles() const { return doc_->recentFiles(); }

  void setStep(Step s);
  Step step() const { return step_; }
  bool stepDone(Step s) const;
  /// The step pages (each step's actions live there).
  MeshPage* meshPage() const { return pages_.mesh; }
  FramePage* framePage() const { return pages_.frame; }
  ContourPage* contourPage() const { return pages_.contour; }
  RigidPage* rigidPage() const { return pages_.rigid; }
  FitPage* fitPage() const { return pages_.fit; }
  AppearancePage* appearancePage() const { return pages_.appearance; }
  RehearsePage* rehearsePage() const { return pages_.rehearse; }
  /// The composited view's engine (layers of the appearance estimate, compositor).
  Composition* composition() const { return composition_; }
  /// Composited, overlay or 3D; a composited view asked for without a current appearance estimate shows
  /// the overlay and says why (viewModeText).
  void setViewMode(ViewMode mode);
  ViewMode viewMode() const { return viewMode_; }
  /// True while the frame view shows the composited picture (the mode is Composited and it can be made).
  bool showingComposited() const { return viewMode_ == ViewMode::Composited && composition_->ready(); }
  QString viewModeText() const;
  CaseDocument* document() const { return doc_; }
  /// The case as it is now (never null once a case has loaded).
  const std::shared_ptr<const app::Case>& caseData() const { return doc_->data(); }
  /// The case file the case lives in (opened from or last saved to); empty when it has none yet.
  QString caseFilePath() const;
  QUndoStack* undoStack() { return doc_->undoStack(); }
  /// Applies an edit to a copy of the case as one undoable command (same non-negative mergeId: one step).
  void editCase(const QString& text, const std::function<void(app::Case&)>& edit, int mergeId = -1) {
    doc_->edit(text, edit, mergeId);
  }
  /// The organ over the frame as last drawn, and its outline (frame pixels).
  const QImage& organOverlay() const { return picture_.organ; }
  const QList<QPolygonF>& silhouette() const { return picture_.silhouette; }
  /// The ticked inner structures (vessels, tumours) over the frame as last drawn (null when none is shown).
  const QImage& innerOverlay() const { return picture_.inner; }
  /// Contour to silhouette distance at the current pose (px); negative when it cannot be computed.
  double contourDistance() const { return picture_.meanDistance; }
  FrameView* frameView() const { return view_; }
  /// The 3D organ view: OpenGL or software, as renderer() chose.
  QWidget* organWidget() const;
  SimulationPanel* simulationPanel() const { return simulation_; }
  class DeviceSteering* deviceSteering() const {
    return steering_;
  }
  bool organViewUsesOpenGL() const { return organGLView_ != nullptr; }
  /// True when the frame view's organ overlay is drawn with OpenGL (off screen), false for the CPU rasteriser.
  bool overlayUsesOpenGL() const { return overlay_->usesOpenGL(); }
  /// Which renderers the views use (set before creating a window). Automatic: OpenGL where the machine has
  /// a hardware OpenGL 3.3, the CPU renderers where it has none or only a software rasteriser (Mesa's
  /// llvmpipe: there Qt composes the whole window through OpenGL at every repaint, and the views fall
  /// to 9-19 fps while the CPU views keep 31-39 fps; BENCHMARKS.md). Software: `rehearse --software`.
  /// OpenGL: `rehearse --opengl`, even through a software rasteriser.
  enum class Renderer { Automatic, Software, OpenGL };
  static void setRenderer(Renderer r);
  static Renderer renderer();
  /// The sentence saying which renderer the views use and why (also in the Messages panel).
  QString rendererText() const { return rendererText_; }
  QString infoText() const;
  /// The last sentence shown in the status bar, whole (the bar may show it shortened; its tooltip and the
  /// Messages panel hold all of it).
  QString statusText() const;
  /// Every sentence shown this session, oldest first, each with its time ("hh:mm:ss  sentence").
  QStringList messageLog() const;

 signals:
  void caseLoaded(bool ok);
  void caseSaved(bool ok, const QString& message);
  void meshImported(bool ok, const QString& message);
  void videoFrameShown(int index);
  void frameSourceOpened(bool ok, const QString& message);

 public slots:
  void cancelLoading();
  void offerRecovery();
  /// Offers the newest crash report an earlier run left in `folder` (crashreport.hpp): a non-modal box that shows,
  /// deletes or keeps it (kept reports are not offered again).
  void offerCrashReports(const QString& folder);

 protected:
  void closeEvent(QCloseEvent*) override;
  void dragEnterEvent(QDragEnterEvent*) override;
  void dropEvent(QDropEvent*) override;

 private:
  void buildDocks();
  // buildDocks' parts (mainwindow_docks.cpp), in this order.
  QDockWidget* buildCaseDocks();  ///< the Case and Messages docks, tabbed; returns the Case dock
  QDockWidget* buildOrganDock(QDockWidget* infoDock);  ///< the organ in 3D, in its dock and the centre; returns the dock
  void buildSimulationDock(QDockWidget* organDock);
  void connectSimulation();    ///< what follows the simulation panel (the status bar, the views, the case's material)
  void showSimulationFrame();  ///< the views follow the simulation's frame just shown
  void buildStatusBar();
  void buildWorkflowPanel();
  void buildMenus();
  // buildMenus' parts (mainwindow_menus.cpp); the File and Edit menus return the actions the toolbar shows too.
  QList<QAction*> buildFileMenu();
  QList<QAction*> buildEditMenu();
  void buildHelpMenu();
  void showKeyboardReference();  ///< Help > Keyboard Shortcuts: the table of this window's keys, in a dialog
  void buildViewMenu();
  void buildSimulationMenu();
  void save();
  void saveAs();
  void openFileDialog();
  void rebuildRecentMenu();
  void onLoadFinished(bool ok, const QString& error);
  void onCaseChanged(CaseDocument::Parts parts);
  void showCaseInfo();
  void refreshOverlay();
  /// The frame view's picture for the view mode: the composited frame, or the frame under the overlay.
  void checkShownViewMode();
  void setViewModeLine(const QString& text);
  void showFrameLayer();
  void updateWorkflow();
  void setBusy(bool busy, const QString& message = {});
  void showProgress(double fraction, const QString& stage);
  /// Shows a sentence in the status bar and adds it to the Messages panel.
  void say(const QString& text);
  /// The sentences of the window's own the case's line may hold, which later events end or replace (said_).
  enum class Said { Other, Grasped, PausedOutside, PlaysInPanel, PausedInPanel, UndoneOrRedone, InstrumentsOnTheFrame };
  /// say() of one of those sentences, kept as what the line holds.
  void sayAs(Said what, const QString& text);
  /// say() for a reply that is not news of the case ("Cancelled: ..."): the status bar's temporary message for
  /// kBriefMessageMs (over a tool's hint), the case's line left as it was.
  void sayBriefly(const QString& text);
  /// Adds a sentence to the Messages panel, with the time.
  void logMessage(const QString& text);

  struct Pages {
    MeshPage* mesh = nullptr;
    FramePage* frame = nullptr;
    ContourPage* contour = nullptr;
    RigidPage* rigid = nullptr;
    FitPage* fit = nullptr;
    AppearancePage* appearance = nullptr;
    RehearsePage* rehearse = nullptr;
    std::vector<StepPage*> all;  ///< in app::kSteps order (steps without a page yet are greyed)
  };
  /// The status bar's parts: the case's last sentence, the simulation, the distance, the cursor, progress.
  struct StatusParts {
    QLabel* caseText = nullptr;
    QLabel* simulation = nullptr;
    QLabel* distance = nullptr;
    QLabel* viewMode = nullptr;  ///< composited / overlay / 3D, and why not composited
    QLabel* cursor = nullptr;
    QProgressBar* progress = nullptr;  ///< a fraction, or busy (no fraction) while a stage of unknown length runs
    QLabel* stage = nullptr;           ///< the running stage in words and the time since the job began
    QString stageText;
    QElapsedTimer clock;
    QTimer* tick = nullptr;  ///< refreshes the elapsed time once a second while busy
    QToolButton* cancel = nullptr;
  };

  CaseDocument* doc_ = nullptr;
  JobRunner* jobs_ = nullptr;
  FrameView* view_ = nullptr;
  std::unique_ptr<OrganOverlay> overlay_;
  OverlayPicture picture_;
  Composition* composition_ = nullptr;
  std::shared_ptr<const simcore::CutSurface> lastCutComposited_;  ///< the cut surface the status bar spoke of last
  ViewMode viewMode_ = ViewMode::Overlay;
  QStackedWidget* centre_ = nullptr;  ///< the frame view, or the 3D organ (ViewMode::ThreeD)
  QWidget* centreOrgan_ = nullptr;
  std::vector<QAction*> viewModeActions_;
  class LiveOverlay* liveOverlay_ = nullptr;       ///< the simulated organ over the frame in step 7 (liveoverlay.hpp)
  class DeviceSteering* steering_ = nullptr;       ///< a 3D mouse moving the instrument (Simulate > Connect 3D Mouse)
  class RecordingController* recorder_ = nullptr;  ///< recording step 7 into the case file, and its review
  OrganView* organView_ = nullptr;
  QString rendererText_;
  OrganGLView* organGLView_ = nullptr;
  SimulationPanel* simulation_ = nullptr;
  QDockWidget* simulationDock_ = nullptr;
  QPlainTextEdit* info_ = nullptr;
  QPlainTextEdit* messages_ = nullptr;
  QString lastSimulationMessage_;  ///< the simulation's last sentence logged (each is logged once)
  QDockWidget* messagesDock_ = nullptr;
  StatusParts status_;
  QListWidget* workflow_ = nullptr;
  QStackedWidget* stepStack_ = nullptr;
  /// The status bar says the rehearsal is paused outside step 7, or plays or is paused there (setStep, F5).
  bool saysPausedOutside() const;
  Said said_ = Said::Other;  ///< which of the window's sentences the case's line holds (Other: none of them)
  /// Started when an instrument played the paused rehearsal: the tool's next hint says so too (it took the status bar).
  QElapsedTimer resumedByInput_;
  Step step_ = Step::Mesh;
  Tool lastInstrument_ = Tool::Grasp;  ///< the instrument in hand when step 7 was last left (taken again there)
  Workbench wb_;
  QString busyMessage_;  ///< the running job's message (crash reports say what was running)
  QString activity() const;
  std::unique_ptr<StepKeys> keys_;
  Pages pages_;
  QMenu* recentMenu_ = nullptr;
  QAction* recoverAction_ = nullptr;
  void updateTitle();
  /// The question offering back the work a crash left, while it is not answered (a close keeps that work then).
  QPointer<QMessageBox> recoveryBox_;
  bool recoveryAnswered_ = false;  ///< a button of the recovery question or File > Recover answered it
  bool closeAsked_ = false;  ///< the unsaved changes were settled: the next close goes through
};

}  // namespace rehearse::ui
