#pragma once
// The main window: a workflow panel (steps of a case in order, what is done and what is next), the
// frame view with the organ over it, a panel for the current step, a case information panel and the
// status bar. Every edit of the case is an undoable command (a drag is one undo step). Long work
// (loading, meshing, decoding video, saving) runs on worker threads with progress and cancel.
#include "rehearse/ui/casedocument.hpp"
#include "rehearse/ui/frameview.hpp"

#include <rehearse/app/workflow.hpp>

#include <QFutureWatcher>
#include <QMainWindow>
#include <QTimer>
#include <QUndoStack>

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>

class QLabel;
class QPlainTextEdit;
class QProgressBar;
class QToolButton;
class QAction;
class QListWidget;
class QStackedWidget;
class QTreeWidget;
class QSlider;
class QDoubleSpinBox;
class QSpinBox;
class QComboBox;
class QCheckBox;
class QPushButton;
class QLineSeries;
class QValueAxis;

namespace cv {
class VideoCapture;
}

namespace rehearse::ui {

class OrganView;
class OrganGLView;
class GLOverlay;
class SimulationPanel;

using Step = app::Step;

class MainWindow : public QMainWindow {
  Q_OBJECT
 public:
  explicit MainWindow(QWidget* parent = nullptr);
  ~MainWindow() override;

  /// Loads a case file (.rehearse), a case folder, or the built-in phantom when `path` is empty, on a
  /// worker thread. The current case stays until the new one has loaded.
  void openCase(const QString& path);
  /// Saves the current case to `path` on a worker thread (atomic write); emits caseSaved.
  void saveCaseAs(const QString& path);
  QString currentPath() const { return doc_->path(); }
  bool isSaving() const { return doc_->isSaving(); }
  bool isLoading() const { return doc_->isLoading(); }
  bool isBusy() const;
  static QString autosavePath();
  static bool hasRecoverableAutosave();
  void autosaveNow();
  QStringList recentFiles() const;

  // Workflow steps (also reachable from menus and the keyboard).
  void importMesh(const QString& path);          ///< step 1: surface or volume; surfaces are tetrahedralised
  void openFrameSource(const QString& path);     ///< step 2: image or video file
  void openCameraDevice(int index);              ///< step 2: live camera
  void showVideoFrame(int index);                ///< step 2: decode and preview frame `index`
  void useShownFrame();                          ///< step 2: take the previewed frame for the case
  void loadCalibration(const QString& path);     ///< step 2: intrinsics and distortion
  void importContour(const QString& path);       ///< step 3
  void exportContour(const QString& path);       ///< step 3
  void solvePnP();                               ///< step 4: pose from landmark pairs
  void runElasticFit();                          ///< step 5: fit the organ onto the contour (worker thread; Esc cancels)
  void setStep(Step s);
  Step step() const { return step_; }

  CaseDocument* document() const { return doc_; }
  /// The organ over the frame as last drawn, and its outline (frame pixels).
  const QImage& organOverlay() const { return organOverlay_; }
  const QList<QPolygonF>& silhouette() const { return silhouette_; }
  /// The case as it is now (never null once a case has loaded).
  const std::shared_ptr<const app::Case>& caseData() const { return doc_->data(); }
  FrameView* frameView() const { return view_; }
  /// The 3D organ view: OpenGL when a context can be made (and --software was not given), else software.
  QWidget* organWidget() const;
  SimulationPanel* simulationPanel() const { return simulation_; }
  bool organViewUsesOpenGL() const { return organGLView_ != nullptr; }
  /// True when the frame view's organ overlay is drawn with OpenGL (off screen), false for the CPU rasteriser.
  bool overlayUsesOpenGL() const;
  /// Forces the software renderers (set before creating a window; `rehearse --software`).
  static void setSoftwareRendering(bool on);
  QUndoStack* undoStack() { return doc_->undoStack(); }
  QString infoText() const;
  int videoFrameCount() const { return videoFrames_; }
  int shownVideoFrame() const { return shownVideoFrame_; }
  const std::vector<LandmarkPair>& landmarks() const { return landmarks_; }
  double lastPnPReprojectionError() const { return pnpError_; }
  /// Contour to silhouette distance at the current pose (px); negative when it cannot be computed.
  double contourDistance() const { return contourDistance_; }
  bool stepDone(Step s) const;
  int labelsShown() const;  ///< rows in the label list of step 1
  int targetTets() const;
  void setTargetTets(int n);
  void setMeshUnit(const QString& unit);

  /// Applies an edit to a copy of the case and pushes it as an undoable command. Edits with the same
  /// non-negative mergeId (one drag) merge into one undo step.
  void editCase(const QString& text, const std::function<void(app::Case&)>& edit, int mergeId = -1) { doc_->edit(text, edit, mergeId); }

 signals:
  void caseLoaded(bool ok);
  void caseSaved(bool ok, const QString& message);
  void meshImported(bool ok, const QString& message);
  void videoFrameShown(int index);
  void frameSourceOpened(bool ok, const QString& message);

 public slots:
  void cancelLoading();
  void offerRecovery();

 protected:
  void closeEvent(QCloseEvent*) override;
  void dragEnterEvent(QDragEnterEvent*) override;
  void dropEvent(QDropEvent*) override;

 private:
  void buildMenus();
  void buildWorkflowPanel();
  QWidget* buildMeshPage();
  QWidget* buildFramePage();
  QWidget* buildContourPage();
  QWidget* buildRigidPage();
  QWidget* buildFitPage();
  /// A button that picks `tool` in the frame view; `key` does the same from anywhere, after going to `step`.
  QPushButton* toolButton(QWidget* parent, const QString& text, const QString& tip, Step step, Tool tool, Qt::Key key);
  void save();
  void saveAs();
  void openFileDialog();
  void importMeshDialog();
  void openFrameDialog();
  void rebuildRecentMenu();
  void onLoadFinished(bool ok, const QString& error);
  void onCaseChanged(CaseDocument::Parts parts);
  void showCaseInfo();
  void refreshOverlay();
  void refreshPanels();
  void updateWorkflow();
  void setBusy(bool busy, const QString& message = {});
  void runJob(const QString& message, const std::function<std::function<void()>(const std::atomic<bool>&,
                                                                                const std::function<void(double, QString)>&)>& job);

  FrameView* view_ = nullptr;
  OrganView* organView_ = nullptr;
  OrganGLView* organGLView_ = nullptr;
  std::unique_ptr<GLOverlay> glOverlay_;  // the frame view's overlay with OpenGL, when a context can be made
  QImage organImage(const imaging::Camera& camera, const Pose& pose, const SurfaceView& surface, const QColor& colour);
  SimulationPanel* simulation_ = nullptr;
  class QDockWidget* simulationDock_ = nullptr;
  QLabel* statusSimulation_ = nullptr;
  QPlainTextEdit* info_ = nullptr;
  QProgressBar* progress_ = nullptr;
  QToolButton* cancelButton_ = nullptr;
  QLabel* statusCase_ = nullptr;
  QLabel* statusCursor_ = nullptr;
  QLabel* statusDistance_ = nullptr;
  QAction* overlayAction_ = nullptr;
  QListWidget* workflow_ = nullptr;
  QStackedWidget* steps_ = nullptr;
  Step step_ = Step::Mesh;
  CaseDocument* doc_ = nullptr;
  QImage organOverlay_;
  QList<QPolygonF> silhouette_;
  QStringList importNotes_;

  // Step 1
  QSpinBox* targetTets_ = nullptr;
  QComboBox* meshUnit_ = nullptr;
  QTreeWidget* labels_ = nullptr;
  std::map<int, bool> labelVisible_;
  // Step 2
  QSlider* videoSlider_ = nullptr;
  QLabel* videoLabel_ = nullptr;
  QPushButton* useFrameButton_ = nullptr;
  QDoubleSpinBox* fx_ = nullptr;
  QDoubleSpinBox* fy_ = nullptr;
  QDoubleSpinBox* cx_ = nullptr;
  QDoubleSpinBox* cy_ = nullptr;
  QLabel* distortionLabel_ = nullptr;
  std::shared_ptr<cv::VideoCapture> video_;
  std::shared_ptr<std::mutex> videoMutex_ = std::make_shared<std::mutex>();
  int videoFrames_ = 0;
  int shownVideoFrame_ = -1;
  int pendingVideoFrame_ = -1;
  bool videoDecoding_ = false;
  cv::Mat shownFrame_;
  QTimer cameraTimer_;
  // Step 3
  QLabel* contourStatus_ = nullptr;
  QLabel* attachmentsLabel_ = nullptr;
  QDoubleSpinBox* spacing_ = nullptr;
  QCheckBox* snap_ = nullptr;
  QComboBox* segmentType_ = nullptr;
  // Step 5
  QLabel* fitCurves_ = nullptr;
  QCheckBox* fitRigid_ = nullptr;
  QPushButton* fitButton_ = nullptr;
  QLabel* fitStatus_ = nullptr;
  QPushButton* fitKeep_ = nullptr;    ///< accept the fit just made ...
  QPushButton* fitRevert_ = nullptr;  ///< ... or revert it (its undo step), while it is the last edit
  int fitUndoIndex_ = -1;             ///< the undo index right after the fit awaiting a decision, -1 for none
  QLineSeries* fitSeries_ = nullptr;
  QValueAxis* fitAxisX_ = nullptr;
  QValueAxis* fitAxisY_ = nullptr;
  // Step 4
  QDoubleSpinBox* poseFields_[6] = {};
  QLabel* distanceLabel_ = nullptr;
  QListWidget* landmarkList_ = nullptr;
  QPushButton* pnpButton_ = nullptr;
  std::vector<LandmarkPair> landmarks_;
  double pnpError_ = -1;
  double contourDistance_ = -1;
  bool updatingPanels_ = false;

  std::atomic<bool> cancel_{false};
  QFutureWatcher<std::function<void()>> jobWatcher_;
  QMenu* recentMenu_ = nullptr;
  QAction* recoverAction_ = nullptr;
};

}  // namespace rehearse::ui
