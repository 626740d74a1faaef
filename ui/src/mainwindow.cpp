#include "rehearse/ui/mainwindow.hpp"

#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/gloverlay.hpp"
#include "rehearse/ui/organview.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include "phantom/presets.hpp"

#include <rehearse/simcore/registration.hpp>

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <QAction>
#include <QApplication>
#include <QCheckBox>
#include <QCloseEvent>
#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QActionGroup>
#include <QHeaderView>
#include <QLabel>
#include <QListWidget>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QPushButton>
#include <QSettings>
#include <QSlider>
#include <QSpinBox>
#include <QStackedWidget>
#include <QStandardPaths>
#include <QStatusBar>
#include <QToolBar>
#include <QToolButton>
#include <QTreeWidget>
#include <QUndoCommand>
#include <QVBoxLayout>
#include <QtCharts/QChart>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QValueAxis>
#include <QtConcurrent/QtConcurrent>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

namespace rehearse::ui {
namespace {

// One undoable edit of the case: a snapshot before and after (cheap: frames are shared cv::Mats).
class CaseCommand : public QUndoCommand {
 public:
  CaseCommand(MainWindow* w, std::shared_ptr<const phantom::Case> before, std::shared_ptr<const phantom::Case> after,
              const QString& text, int mergeId)
      : QUndoCommand(text), w_(w), before_(std::move(before)), after_(std::move(after)), merge_(mergeId) {}
  void undo() override { w_->setCaseData(before_); }
  void redo() override { w_->setCaseData(after_); }
  int id() const override { return merge_ >= 0 ? 1 : -1; }
  bool mergeWith(const QUndoCommand* other) override {
    auto* o = dynamic_cast<const CaseCommand*>(other);
    if (!o || o->merge_ != merge_) return false;
    after_ = o->after_;
    return true;
  }

 private:
  MainWindow* w_;
  std::shared_ptr<const phantom::Case> before_, after_;
  int merge_;
};

QImage toQImage(const cv::Mat3b& bgr) {
  if (bgr.empty()) return {};
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return QImage(rgb.data, rgb.cols, rgb.rows, static_cast<int>(rgb.step), QImage::Format_RGB888).copy();
}

// The frame every step uses is the captured one undistorted with the case's camera (same K, so pixels
// keep the pinhole model of the camera). Without distortion it is the captured frame itself.
void undistortFrame(phantom::Case& k) {
  if (k.rawFrame.empty()) return;
  const auto& d = k.camera.distortion;
  if (d[0] == 0 && d[1] == 0 && d[2] == 0 && d[3] == 0 && d[4] == 0) {
    k.frame = k.rawFrame;
    return;
  }
  cv::Mat K(3, 3, CV_64F), D(1, 5, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) K.at<double>(r, c) = k.camera.K(r, c);
  for (int i = 0; i < 5; ++i) D.at<double>(0, i) = d[i];
  cv::Mat3b und;
  cv::undistort(k.rawFrame, und, K, D);
  k.frame = und;
}

QColor labelColour(int label) {
  static const QColor c[] = {QColor(200, 120, 100), QColor(80, 140, 255), QColor(250, 200, 60), QColor(170, 90, 220),
                             QColor(90, 220, 200), QColor(240, 120, 180)};
  return c[std::abs(label) % 6];
}

bool& softwareRenderingFlag() {
  static bool flag = false;
  return flag;
}
bool softwareRendering() { return softwareRenderingFlag(); }

const char* kStepNames[] = {"1  Organ mesh", "2  Endoscope frame", "3  Contour", "4  Rigid alignment",
                            "5  Elastic fit", "6  Appearance", "7  Rehearse"};

}  // namespace

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle(tr("Rehearse"));
  setObjectName(QStringLiteral("MainWindow"));
  view_ = new FrameView(this);
  view_->setObjectName(QStringLiteral("frameView"));
  setCentralWidget(view_);

  auto* infoDock = new QDockWidget(tr("Case"), this);
  infoDock->setObjectName(QStringLiteral("caseDock"));
  info_ = new QPlainTextEdit(infoDock);
  info_->setObjectName(QStringLiteral("caseInfo"));
  info_->setReadOnly(true);
  info_->setMinimumWidth(280);
  info_->setLineWrapMode(QPlainTextEdit::NoWrap);
  QFont mono(QStringLiteral("DejaVu Sans Mono"));
  mono.setStyleHint(QFont::Monospace);
  info_->setFont(mono);
  infoDock->setWidget(info_);
  addDockWidget(Qt::RightDockWidgetArea, infoDock);
  auto* organDock = new QDockWidget(tr("Organ 3D"), this);
  organDock->setObjectName(QStringLiteral("organDock"));
  if (!softwareRendering() && OrganGLView::openGLAvailable()) {
    glOverlay_ = std::make_unique<GLOverlay>();
    if (!glOverlay_->valid()) glOverlay_.reset();
    organGLView_ = new OrganGLView(organDock);
    organGLView_->setObjectName(QStringLiteral("organView"));
    organDock->setWidget(organGLView_);
  } else {
    organView_ = new OrganView(organDock);
    organView_->setObjectName(QStringLiteral("organView"));
    organDock->setWidget(organView_);
  }
  addDockWidget(Qt::RightDockWidgetArea, organDock);
  splitDockWidget(infoDock, organDock, Qt::Vertical);
  simulationDock_ = new QDockWidget(tr("Simulation"), this);
  simulationDock_->setObjectName(QStringLiteral("simulationDock"));
  simulation_ = new SimulationPanel(simulationDock_);
  simulation_->setObjectName(QStringLiteral("simulationPanel"));
  simulationDock_->setWidget(simulation_);
  addDockWidget(Qt::RightDockWidgetArea, simulationDock_);
  tabifyDockWidget(organDock, simulationDock_);
  organDock->raise();

  progress_ = new QProgressBar(this);
  progress_->setRange(0, 100);
  progress_->setMaximumWidth(260);
  progress_->setVisible(false);
  cancelButton_ = new QToolButton(this);
  cancelButton_->setText(tr("Cancel"));
  cancelButton_->setToolTip(tr("Cancel the running job (Esc)"));
  cancelButton_->setVisible(false);
  connect(cancelButton_, &QToolButton::clicked, this, &MainWindow::cancelLoading);
  statusCase_ = new QLabel(this);
  statusCase_->setObjectName(QStringLiteral("caseStatus"));
  statusCursor_ = new QLabel(this);
  statusSimulation_ = new QLabel(this);
  statusSimulation_->setObjectName(QStringLiteral("statusSimulation"));
  connect(simulation_, &SimulationPanel::statusChanged, statusSimulation_, &QLabel::setText);
  statusDistance_ = new QLabel(this);
  statusBar()->addWidget(statusCase_, 1);
  statusBar()->addPermanentWidget(statusSimulation_);
  statusBar()->addPermanentWidget(statusDistance_);
  statusBar()->addPermanentWidget(statusCursor_);
  statusBar()->addPermanentWidget(progress_);
  statusBar()->addPermanentWidget(cancelButton_);
  connect(view_, &FrameView::cursorMoved, this, [this](QPointF p) {
    statusCursor_->setText(tr("u %1  v %2 px").arg(p.x(), 0, 'f', 1).arg(p.y(), 0, 'f', 1));
  });
  connect(view_, &FrameView::contourEdited, this, [this](const imaging::Contour& c, const QString& text, int merge) {
    editCase(text, [&c](phantom::Case& k) { k.contour = c; }, merge);
  });
  connect(view_, &FrameView::poseEdited, this, [this](const Pose& p, const QString& text, int merge) {
    editCase(text, [&p](phantom::Case& k) {
      k.pose = p;
      k.hasPose = true;
      k.poseAligned = true;
    }, merge);
  });
  connect(view_, &FrameView::toolMessage, this, [this](const QString& text) { statusBar()->showMessage(text, 10000); });
  connect(view_, &FrameView::attachmentsEdited, this, [this](const std::vector<int>& nodes, const QString& text) {
    editCase(text, [&](phantom::Case& k) { k.attachments = nodes; });
  });
  connect(view_, &FrameView::landmarkModelPicked, this, [this](const Eigen::Vector3d& m) {
    landmarks_.push_back({m, Eigen::Vector2d::Zero(), false});
    view_->setLandmarks(landmarks_);
    refreshPanels();
    statusCase_->setText(tr("Landmark %1 on the organ; now click where it is in the frame.").arg(landmarks_.size()));
  });
  connect(view_, &FrameView::landmarkImagePicked, this, [this](const Eigen::Vector2d& p) {
    if (landmarks_.empty()) return;
    landmarks_.back().image = p;
    landmarks_.back().hasImage = true;
    view_->setLandmarks(landmarks_);
    refreshPanels();
    statusCase_->setText(tr("%1 landmark pairs; click the organ for the next, or solve (4 or more).").arg(landmarks_.size()));
  });

  buildWorkflowPanel();
  buildMenus();
  connect(&watcher_, &QFutureWatcher<LoadedCase>::finished, this, &MainWindow::onLoadFinished);
  connect(&jobWatcher_, &QFutureWatcher<std::function<void()>>::finished, this, [this] {
    setBusy(false);
    auto finish = jobWatcher_.result();
    if (finish) finish();
  });
  connect(&saveWatcher_, &QFutureWatcher<QString>::finished, this, [this] {
    const QString error = saveWatcher_.result();
    if (error.isEmpty()) {
      currentPath_ = savingPath_;
      addRecent(savingPath_);
      undo_.setClean();
      setWindowTitle(tr("%1 - Rehearse").arg(QFileInfo(savingPath_).fileName()));
      statusCase_->setText(tr("Saved %1").arg(savingPath_));
    } else {
      statusCase_->setText(error);
    }
    emit caseSaved(error.isEmpty(), error);
  });
  connect(&cameraTimer_, &QTimer::timeout, this, [this] { showVideoFrame(-1); });
  setAcceptDrops(true);
  autosaveTimer_.setInterval(60'000);
  connect(&autosaveTimer_, &QTimer::timeout, this, [this] {
    if (case_.data && !saveWatcher_.isRunning()) {
      auto data = case_.data;
      (void)QtConcurrent::run([data] {
        try {
          QDir().mkpath(QFileInfo(autosavePath()).absolutePath());
          saveCaseFile(*data, autosavePath());
        } catch (const std::exception&) {
        }
      });
    }
  });
  autosaveTimer_.start();

  QSettings settings;
  if (!restoreGeometry(settings.value(QStringLiteral("window/geometry")).toByteArray())) resize(1600, 900);
  restoreState(settings.value(QStringLiteral("window/state")).toByteArray());
  setStep(Step::Mesh);
}

bool MainWindow::overlayUsesOpenGL() const { return glOverlay_ != nullptr; }

QImage MainWindow::organImage(const imaging::Camera& camera, const Pose& pose, const SurfaceView& surface, const QColor& colour) {
  QImage image;
  if (glOverlay_ && glOverlay_->render(camera, pose, surface, colour, image)) return image;
  const cv::Mat4b overlay = imaging::renderOverlay(camera, pose, surface, cv::Vec3b(colour.blue(), colour.green(), colour.red()));
  cv::Mat rgba;
  cv::cvtColor(overlay, rgba, cv::COLOR_BGRA2RGBA);
  return QImage(rgba.data, rgba.cols, rgba.rows, static_cast<int>(rgba.step), QImage::Format_RGBA8888).copy();
}

MainWindow::~MainWindow() {
  cancel_ = true;
  cameraTimer_.stop();
  watcher_.waitForFinished();
  jobWatcher_.waitForFinished();
  saveWatcher_.waitForFinished();
}

void MainWindow::setSoftwareRendering(bool on) { softwareRenderingFlag() = on; }

QWidget* MainWindow::organWidget() const {
  if (organGLView_) return organGLView_;
  return organView_;
}

bool MainWindow::isBusy() const { return watcher_.isRunning() || jobWatcher_.isRunning() || saveWatcher_.isRunning(); }

// ---------------------------------------------------------------------------------------------- panels

QPushButton* MainWindow::toolButton(QWidget* parent, const QString& text, const QString& tip, Step step, Tool tool, Qt::Key key) {
  // The button chooses the tool; its key also goes to the tool's step first (from anywhere in the window).
  auto* button = new QPushButton(text, parent);
  button->setToolTip(tip);
  connect(button, &QPushButton::clicked, this, [this, tool] { view_->setTool(tool); });
  auto* shortcut = new QAction(this);
  shortcut->setShortcut(QKeySequence(key));
  connect(shortcut, &QAction::triggered, this, [this, step, tool] {
    setStep(step);
    view_->setTool(tool);
  });
  addAction(shortcut);
  return button;
}

void MainWindow::buildWorkflowPanel() {
  auto* dock = new QDockWidget(tr("Workflow"), this);
  dock->setObjectName(QStringLiteral("workflowDock"));
  auto* host = new QWidget(dock);
  auto* layout = new QVBoxLayout(host);
  workflow_ = new QListWidget(host);
  workflow_->setObjectName(QStringLiteral("workflowList"));
  QFont big = workflow_->font();
  big.setPointSizeF(big.pointSizeF() * 1.15);
  workflow_->setFont(big);
  for (int i = 0; i < 7; ++i) {
    auto* item = new QListWidgetItem(tr(kStepNames[i]), workflow_);
    item->setSizeHint(QSize(0, 34));
    item->setToolTip(tr("Alt+%1").arg(i + 1));
    if (i >= 5) {
      item->setFlags(item->flags() & ~Qt::ItemIsEnabled);
      item->setToolTip(tr("Comes in a later version"));
    }
  }
  workflow_->setFixedHeight(7 * 34 + 8);
  workflow_->setVerticalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  connect(workflow_, &QListWidget::currentRowChanged, this, [this](int row) {
    if (row >= 0 && row < 5) setStep(static_cast<Step>(row));
  });
  layout->addWidget(workflow_);
  steps_ = new QStackedWidget(host);
  steps_->addWidget(buildMeshPage());
  steps_->addWidget(buildFramePage());
  steps_->addWidget(buildContourPage());
  steps_->addWidget(buildRigidPage());
  steps_->addWidget(buildFitPage());
  layout->addWidget(steps_, 1);
  dock->setWidget(host);
  dock->setMinimumWidth(330);
  addDockWidget(Qt::LeftDockWidgetArea, dock);
}

QWidget* MainWindow::buildMeshPage() {
  auto* page = new QWidget;
  auto* l = new QVBoxLayout(page);
  auto* importButton = new QPushButton(tr("Import Mesh... (Ctrl+I)"), page);
  importButton->setMinimumHeight(36);
  connect(importButton, &QPushButton::clicked, this, &MainWindow::importMeshDialog);
  l->addWidget(importButton);
  auto* form = new QFormLayout;
  targetTets_ = new QSpinBox(page);
  targetTets_->setRange(200, 500000);
  targetTets_->setSingleStep(500);
  targetTets_->setValue(QSettings().value(QStringLiteral("mesh/targetTets"), 4000).toInt());
  targetTets_->setToolTip(tr("Tetrahedra wanted when a surface is filled (size control)"));
  form->addRow(tr("Target tetrahedra"), targetTets_);
  meshUnit_ = new QComboBox(page);
  meshUnit_->addItems({"mm", "cm", "dm", "m"});
  meshUnit_->setToolTip(tr("Length unit of the file's coordinates"));
  form->addRow(tr("File unit"), meshUnit_);
  l->addLayout(form);
  l->addWidget(new QLabel(tr("Labels (tick to show inner structures)"), page));
  labels_ = new QTreeWidget(page);
  labels_->setObjectName(QStringLiteral("labelList"));
  labels_->setHeaderLabels({tr("Label"), tr("Elements")});
  labels_->setRootIsDecorated(false);
  labels_->header()->setStretchLastSection(false);
  labels_->header()->setSectionResizeMode(0, QHeaderView::Stretch);
  labels_->header()->setSectionResizeMode(1, QHeaderView::ResizeToContents);
  connect(labels_, &QTreeWidget::itemChanged, this, [this](QTreeWidgetItem* item, int) {
    if (updatingPanels_) return;
    labelVisible_[item->data(0, Qt::UserRole).toInt()] = item->checkState(0) == Qt::Checked;
    refreshOverlay();
  });
  l->addWidget(labels_, 1);
  // Ligament attachments: the nodes that hold the organ in the simulation and the fit. An imported organ
  // has none until they are picked on it.
  attachmentsLabel_ = new QLabel(page);
  attachmentsLabel_->setObjectName(QStringLiteral("attachmentsLabel"));
  attachmentsLabel_->setWordWrap(true);
  l->addWidget(attachmentsLabel_);
  auto* attachRow = new QHBoxLayout;
  auto* pickAttach = toolButton(page, tr("Pick Attachments (H)"),
                                tr("Click on the organ drawn over the frame where a ligament holds it: the surface nodes within "
                                   "the patch radius are attached; a click on attached nodes releases them. Each click is one undo step."),
                                Step::Mesh, Tool::Attachments, Qt::Key_H);
  pickAttach->setObjectName(QStringLiteral("pickAttachments"));
  auto* clearAttach = new QPushButton(tr("Release All"), page);
  clearAttach->setObjectName(QStringLiteral("clearAttachments"));
  connect(clearAttach, &QPushButton::clicked, this, [this] {
    if (case_.data && !case_.data->attachments.empty())
      editCase(tr("Release all attachments"), [](phantom::Case& k) { k.attachments.clear(); });
  });
  attachRow->addWidget(pickAttach, 2);
  attachRow->addWidget(clearAttach, 1);
  l->addLayout(attachRow);
  auto* radiusForm = new QFormLayout;
  auto* radius = new QDoubleSpinBox(page);
  radius->setObjectName(QStringLiteral("attachmentRadius"));
  radius->setRange(1, 50);
  radius->setDecimals(0);
  radius->setSuffix(tr(" mm"));
  radius->setToolTip(tr("Surface nodes within this distance of a click are attached or released together"));
  connect(radius, &QDoubleSpinBox::valueChanged, this, [this](double mm) {
    view_->setAttachmentRadius(mm * 1e-3);
    QSettings().setValue(QStringLiteral("mesh/attachmentRadiusMm"), mm);
  });
  radius->setValue(QSettings().value(QStringLiteral("mesh/attachmentRadiusMm"), 10.0).toDouble());
  view_->setAttachmentRadius(radius->value() * 1e-3);
  radiusForm->addRow(tr("Attachment patch radius"), radius);
  l->addLayout(radiusForm);
  return page;
}

QWidget* MainWindow::buildFramePage() {
  auto* page = new QWidget;
  auto* l = new QVBoxLayout(page);
  auto* open = new QPushButton(tr("Open Image or Video... (Ctrl+F)"), page);
  open->setMinimumHeight(36);
  connect(open, &QPushButton::clicked, this, &MainWindow::openFrameDialog);
  l->addWidget(open);
  auto* cam = new QHBoxLayout;
  auto* device = new QSpinBox(page);
  device->setRange(0, 9);
  auto* openDevice = new QPushButton(tr("Live Camera"), page);
  connect(openDevice, &QPushButton::clicked, this, [this, device] { openCameraDevice(device->value()); });
  cam->addWidget(new QLabel(tr("Device"), page));
  cam->addWidget(device);
  cam->addWidget(openDevice, 1);
  l->addLayout(cam);
  auto* videoBox = new QGroupBox(tr("Video"), page);
  auto* vl = new QVBoxLayout(videoBox);
  videoSlider_ = new QSlider(Qt::Horizontal, videoBox);
  videoSlider_->setObjectName(QStringLiteral("videoSlider"));
  videoSlider_->setEnabled(false);
  connect(videoSlider_, &QSlider::valueChanged, this, [this](int v) {
    if (!updatingPanels_) showVideoFrame(v);
  });
  vl->addWidget(videoSlider_);
  auto* row = new QHBoxLayout;
  auto* prev = new QToolButton(videoBox);
  prev->setText(QStringLiteral("<"));
  prev->setToolTip(tr("Previous frame (,)"));
  prev->setShortcut(QKeySequence(Qt::Key_Comma));
  connect(prev, &QToolButton::clicked, this, [this] { if (videoFrames_ > 0) showVideoFrame(std::max(0, shownVideoFrame_ - 1)); });
  auto* next = new QToolButton(videoBox);
  next->setText(QStringLiteral(">"));
  next->setToolTip(tr("Next frame (.)"));
  next->setShortcut(QKeySequence(Qt::Key_Period));
  connect(next, &QToolButton::clicked, this, [this] { if (videoFrames_ > 0) showVideoFrame(std::min(videoFrames_ - 1, shownVideoFrame_ + 1)); });
  videoLabel_ = new QLabel(tr("no video"), videoBox);
  row->addWidget(prev);
  row->addWidget(videoLabel_, 1);
  row->addWidget(next);
  vl->addLayout(row);
  useFrameButton_ = new QPushButton(tr("Use This Frame (Ctrl+Return)"), videoBox);
  useFrameButton_->setEnabled(false);
  useFrameButton_->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_Return));
  connect(useFrameButton_, &QPushButton::clicked, this, &MainWindow::useShownFrame);
  vl->addWidget(useFrameButton_);
  l->addWidget(videoBox);
  auto* camBox = new QGroupBox(tr("Camera intrinsics (px)"), page);
  auto* form = new QFormLayout(camBox);
  auto spin = [&](QDoubleSpinBox*& s, const QString& name) {
    s = new QDoubleSpinBox(camBox);
    s->setRange(name.startsWith('f') ? 1 : -100000, 100000);  // a focal length of 0 is a degenerate camera
    s->setDecimals(2);
    s->setKeyboardTracking(false);
    form->addRow(name, s);
    connect(s, &QDoubleSpinBox::valueChanged, this, [this] {
      if (updatingPanels_ || !case_.data) return;
      const double fx = fx_->value(), fy = fy_->value(), cx = cx_->value(), cy = cy_->value();
      editCase(tr("Edit intrinsics"), [=](phantom::Case& k) {
        k.camera.K(0, 0) = fx;
        k.camera.K(1, 1) = fy;
        k.camera.K(0, 2) = cx;
        k.camera.K(1, 2) = cy;
      });
    });
  };
  spin(fx_, tr("fx"));
  spin(fy_, tr("fy"));
  spin(cx_, tr("cx"));
  spin(cy_, tr("cy"));
  distortionLabel_ = new QLabel(camBox);
  distortionLabel_->setWordWrap(true);
  form->addRow(tr("Distortion"), distortionLabel_);
  auto* loadCal = new QPushButton(tr("Load Calibration..."), camBox);
  connect(loadCal, &QPushButton::clicked, this, [this] {
    const QString p = QFileDialog::getOpenFileName(this, tr("Load Camera Calibration"), QSettings().value("lastDir").toString(),
                                                   tr("Calibrations (*.yaml *.yml *.xml *.json *.txt)"));
    if (!p.isEmpty()) loadCalibration(p);
  });
  auto* defaults = new QPushButton(tr("Default From Image Size"), camBox);
  connect(defaults, &QPushButton::clicked, this, [this] {
    if (!case_.data || case_.data->frame.empty()) return;
    editCase(tr("Default intrinsics"), [](phantom::Case& k) { k.camera = imaging::Camera::defaultFor(k.frame.cols, k.frame.rows); });
  });
  form->addRow(loadCal);
  form->addRow(defaults);
  l->addWidget(camBox);
  l->addStretch(1);
  return page;
}

QWidget* MainWindow::buildContourPage() {
  auto* page = new QWidget;
  auto* l = new QVBoxLayout(page);
  auto* grid = new QGridLayout;
  struct T {
    Tool tool;
    const char* name;
    Qt::Key key;
  };
  const T tools[] = {{Tool::Freehand, "Freehand (F)", Qt::Key_F}, {Tool::ClickPoints, "Click points (C)", Qt::Key_C},
                     {Tool::EditPoints, "Edit points (E)", Qt::Key_E}, {Tool::Erase, "Erase (X)", Qt::Key_X}};
  int i = 0;
  for (const auto& t : tools) {
    auto* b = new QPushButton(tr(t.name), page);
    b->setMinimumHeight(34);
    b->setToolTip(tr("Middle button pans and the wheel zooms while drawing; Enter ends a click-by-click segment; "
                     "in Edit, drag a point, Ctrl+click inserts, right-click deletes."));
    const Tool tool = t.tool;
    connect(b, &QPushButton::clicked, this, [this, tool] { view_->setTool(tool); });
    auto* a = new QAction(this);
    a->setShortcut(QKeySequence(t.key));
    connect(a, &QAction::triggered, this, [this, tool] {
      if (step_ == Step::Contour) view_->setTool(tool);
    });
    addAction(a);
    grid->addWidget(b, i / 2, i % 2);
    ++i;
  }
  l->addLayout(grid);
  snap_ = new QCheckBox(tr("Snap to image edges"), page);
  connect(snap_, &QCheckBox::toggled, view_, &FrameView::setSnapToEdges);
  l->addWidget(snap_);
  // What new segments are: the organ's silhouette, or an anatomical curve (the ridge, the falciform
  // ligament) that step 5 can also hold onto its curve on the organ.
  auto* typeRow = new QHBoxLayout;
  segmentType_ = new QComboBox(page);
  segmentType_->setObjectName(QStringLiteral("segmentType"));
  segmentType_->addItem(tr("Silhouette"), QStringLiteral("silhouette"));
  segmentType_->addItem(tr("Ridge"), QStringLiteral("ridge"));
  segmentType_->addItem(tr("Ligament"), QStringLiteral("ligament"));
  segmentType_->setToolTip(tr("Silhouettes are drawn yellow, ridges orange, ligaments violet."));
  connect(segmentType_, &QComboBox::currentIndexChanged, this,
          [this](int i) { view_->setNewSegmentType(segmentType_->itemData(i).toString()); });
  typeRow->addWidget(new QLabel(tr("New segments"), page));
  typeRow->addWidget(segmentType_, 1);
  l->addLayout(typeRow);
  auto* rs = new QHBoxLayout;
  spacing_ = new QDoubleSpinBox(page);
  spacing_->setRange(1, 100);
  spacing_->setValue(8);
  spacing_->setSuffix(tr(" px"));
  auto* resample = new QPushButton(tr("Resample"), page);
  connect(resample, &QPushButton::clicked, this, [this] {
    const double s = spacing_->value();
    editCase(tr("Resample contour"), [s](phantom::Case& k) {
      for (auto& seg : k.contour.segments) seg = imaging::resampleSegment(seg, s);
    });
  });
  rs->addWidget(new QLabel(tr("Spacing"), page));
  rs->addWidget(spacing_);
  rs->addWidget(resample);
  l->addLayout(rs);
  auto* row = new QHBoxLayout;
  auto* smooth = new QPushButton(tr("Smooth"), page);
  connect(smooth, &QPushButton::clicked, this, [this] {
    editCase(tr("Smooth contour"), [](phantom::Case& k) {
      for (auto& seg : k.contour.segments) seg = imaging::smoothSegment(seg, 5);
    });
  });
  auto* clear = new QPushButton(tr("Clear"), page);
  connect(clear, &QPushButton::clicked, this, [this] { editCase(tr("Clear contour"), [](phantom::Case& k) { k.contour.segments.clear(); }); });
  row->addWidget(smooth);
  row->addWidget(clear);
  l->addLayout(row);
  auto* io = new QHBoxLayout;
  auto* imp = new QPushButton(tr("Import..."), page);
  connect(imp, &QPushButton::clicked, this, [this] {
    const QString p = QFileDialog::getOpenFileName(this, tr("Import Contour"), QSettings().value("lastDir").toString(), tr("Contours (*.json)"));
    if (!p.isEmpty()) importContour(p);
  });
  auto* exp = new QPushButton(tr("Export..."), page);
  connect(exp, &QPushButton::clicked, this, [this] {
    const QString p = QFileDialog::getSaveFileName(this, tr("Export Contour"), QSettings().value("lastDir").toString(), tr("Contours (*.json)"));
    if (!p.isEmpty()) exportContour(p);
  });
  io->addWidget(imp);
  io->addWidget(exp);
  l->addLayout(io);
  contourStatus_ = new QLabel(page);
  contourStatus_->setWordWrap(true);
  l->addWidget(contourStatus_);
  l->addStretch(1);
  return page;
}

QWidget* MainWindow::buildFitPage() {
  auto* page = new QWidget;
  auto* layout = new QVBoxLayout(page);
  auto* intro = new QLabel(tr("Fit the organ onto the sketched contour: the silhouette is pulled onto it in the image plane and "
                              "the elastic model (the liver's parameters, held by its ligaments) decides the rest. "
                              "Afterwards keep the fit, or revert it (Ctrl+Z)."),
                           page);
  intro->setWordWrap(true);
  layout->addWidget(intro);
  fitRigid_ = new QCheckBox(tr("Rigid pre-pass (refine the pose first)"), page);
  fitRigid_->setObjectName(QStringLiteral("fitRigid"));
  fitRigid_->setChecked(true);
  layout->addWidget(fitRigid_);
  // Anatomical curves: a ridge or ligament sketched in step 3, and the same curve clicked on the organ.
  auto* pickCurve = toolButton(page, tr("Pick Curve on Organ (K)"),
                               tr("Click along the ridge or ligament on the organ drawn over the frame; the sketched ridge or "
                                  "ligament nearest to the first click gets the curve. Enter ends, Backspace takes back a click."),
                               Step::Elastic, Tool::OrganCurve, Qt::Key_K);
  pickCurve->setObjectName(QStringLiteral("pickCurve"));
  layout->addWidget(pickCurve);
  fitCurves_ = new QLabel(page);
  fitCurves_->setObjectName(QStringLiteral("fitCurves"));
  fitCurves_->setWordWrap(true);
  layout->addWidget(fitCurves_);
  auto* row = new QHBoxLayout;
  fitButton_ = new QPushButton(tr("Fit to Contour (F9)"), page);
  fitButton_->setObjectName(QStringLiteral("fitButton"));
  fitButton_->setShortcut(QKeySequence(Qt::Key_F9));
  connect(fitButton_, &QPushButton::clicked, this, &MainWindow::runElasticFit);
  auto* clear = new QPushButton(tr("Clear Fit"), page);
  clear->setObjectName(QStringLiteral("fitClear"));
  connect(clear, &QPushButton::clicked, this, [this] {
    if (case_.data && !case_.data->fitted.empty()) editCase(tr("Clear elastic fit"), [](phantom::Case& k) {
      k.fitted.clear();
      k.fitStatus.clear();
    });
  });
  row->addWidget(fitButton_);
  row->addWidget(clear);
  layout->addLayout(row);
  // After a fit: keep it, or revert it (its undo step) -- offered while it is the last edit.
  auto* decide = new QHBoxLayout;
  fitKeep_ = new QPushButton(tr("Keep Fit"), page);
  fitKeep_->setObjectName(QStringLiteral("fitKeep"));
  fitRevert_ = new QPushButton(tr("Revert Fit (Ctrl+Z)"), page);
  fitRevert_->setObjectName(QStringLiteral("fitRevert"));
  fitRevert_->setToolTip(tr("Back to the organ and pose before the fit; Redo brings the fit back."));
  connect(fitKeep_, &QPushButton::clicked, this, [this] {
    if (fitUndoIndex_ != undo_.index()) return;
    fitUndoIndex_ = -1;
    fitKeep_->setEnabled(false);
    fitRevert_->setEnabled(false);
    fitStatus_->setText(tr("Fit kept: %1").arg(QString::fromStdString(case_.data->fitStatus)));
  });
  connect(fitRevert_, &QPushButton::clicked, this, [this] {
    if (fitUndoIndex_ != undo_.index()) return;
    undo_.undo();  // Redo brings the fit back, and with it this choice
    fitStatus_->setText(tr("Fit reverted: the organ and the pose are as before it (Ctrl+Shift+Z brings it back)."));
  });
  connect(&undo_, &QUndoStack::indexChanged, this, [this](int index) {
    const bool open = fitUndoIndex_ >= 0 && index == fitUndoIndex_;
    fitKeep_->setEnabled(open);
    fitRevert_->setEnabled(open);
  });
  fitKeep_->setEnabled(false);
  fitRevert_->setEnabled(false);
  decide->addWidget(fitKeep_);
  decide->addWidget(fitRevert_);
  layout->addLayout(decide);
  fitStatus_ = new QLabel(page);
  fitStatus_->setObjectName(QStringLiteral("fitStatus"));
  fitStatus_->setWordWrap(true);
  layout->addWidget(fitStatus_);
  // Live chart: the contour-to-silhouette distance against run time.
  fitSeries_ = new QLineSeries;
  fitSeries_->setName(tr("mean distance (px)"));
  auto* chart = new QChart;
  chart->addSeries(fitSeries_);
  chart->legend()->hide();
  chart->setTitle(tr("Contour to silhouette (px) against time (s)"));
  chart->setTheme(QChart::ChartThemeDark);
  fitAxisX_ = new QValueAxis;
  fitAxisX_->setTitleText(tr("s"));
  fitAxisX_->setRange(0, 1);
  fitAxisY_ = new QValueAxis;
  fitAxisY_->setTitleText(tr("px"));
  fitAxisY_->setRange(0, 10);
  chart->addAxis(fitAxisX_, Qt::AlignBottom);
  chart->addAxis(fitAxisY_, Qt::AlignLeft);
  fitSeries_->attachAxis(fitAxisX_);
  fitSeries_->attachAxis(fitAxisY_);
  auto* chartView = new QChartView(chart, page);
  chartView->setObjectName(QStringLiteral("fitChart"));
  chartView->setRenderHint(QPainter::Antialiasing);
  chartView->setMinimumHeight(220);
  layout->addWidget(chartView, 1);
  return page;
}

void MainWindow::runElasticFit() {
  if (!case_.data) return;
  const auto c = case_.data;
  QString missing;
  if (!stepDone(Step::Mesh)) missing = tr("an organ mesh (step 1)");
  else if (!stepDone(Step::Frame)) missing = tr("a frame with its camera (step 2)");
  else if (!stepDone(Step::Contour)) missing = tr("a contour (step 3): %1").arg(QString::fromStdString(imaging::contourProblem(c->contour)));
  else if (!c->hasPose) missing = tr("a rigid alignment (step 4)");
  if (!missing.isEmpty()) {
    fitStatus_->setText(tr("The fit needs %1.").arg(missing));
    return;
  }
  setStep(Step::Elastic);
  fitSeries_->clear();
  fitAxisY_->setRange(0, 10);
  fitAxisX_->setRange(0, 1);
  const bool rigid = fitRigid_->isChecked();
  fitStatus_->setText(tr("Fitting... (Esc cancels)"));
  runJob(tr("Elastic fit..."), [this, c, rigid](const std::atomic<bool>& cancel, const auto& progress) -> std::function<void()> {
    try {
      simcore::Scene preset = phantom::makePreset("liver", c->volume, c->attachments);
      phantom::setMaterialModel(preset, simcore::MaterialModel::Corotational);
      const simcore::FemModel model = simcore::FemModel::build(preset.mesh, preset.materials, preset.defaultMaterial);
      simcore::SimulationSettings settings;
      settings.gravity.setZero();
      const auto segments = imaging::silhouetteSegments(c->contour);
      simcore::RegistrationOptions o;
      o.rigidPrepass = rigid;
      for (const auto& s : imaging::anatomicalSegments(c->contour)) o.curves.push_back({s.modelVertices, s.points, s.type});
      o.onIteration = [this, c, &cancel, &progress](const simcore::RegistrationIteration& it, const Eigen::VectorXd& x, const Pose& pose) {
        // Live: the organ deforms over the frame and the chart grows (on the GUI thread).
        auto preview = std::make_shared<phantom::Case>(*c);
        preview->fitted.resize(preview->volume.points.size());
        for (std::size_t i = 0; i < preview->fitted.size(); ++i) preview->fitted[i] = x.segment<3>(3 * i);
        preview->pose = pose;
        const double t = it.wallMs / 1000.0, px = it.score();
        QMetaObject::invokeMethod(this, [this, preview, t, px] {
          fitSeries_->append(t, px);
          fitAxisX_->setRange(0, std::max(1.0, 1.2 * t));
          fitAxisY_->setRange(0, std::max(fitAxisY_->max(), 1.1 * px));
          fitAxisY_->applyNiceNumbers();  // round ticks (0, 2, 4, ...)
          view_->setCase(preview);
        }, Qt::QueuedConnection);
        progress(std::min(0.95, 0.05 + 0.045 * it.iteration), QStringLiteral("%1 px").arg(px, 0, 'f', 2));
        return !cancel.load();
      };
      const simcore::RegistrationResult r =
          simcore::registerToContour(model, c->attachments, settings, c->surface, segments, c->pose, c->camera.pinhole(), o);
      const QString status = QString::fromStdString(r.status);
      if (r.cancelled || !r.ok) {
        return [this, status, cancelled = r.cancelled] {
          view_->setCase(case_.data);  // back to the case as it was
          fitStatus_->setText(cancelled ? tr("Cancelled; the case is unchanged.") : tr("The fit failed: %1").arg(status));
          statusCase_->setText(fitStatus_->text());
        };
      }
      std::vector<Eigen::Vector3d> fitted(static_cast<std::size_t>(r.x.size() / 3));
      for (std::size_t i = 0; i < fitted.size(); ++i) fitted[i] = r.x.segment<3>(3 * i);
      const Pose pose = r.pose;
      const double ms = r.iterations.back().wallMs;
      return [this, fitted, pose, status, ms] {
        editCase(tr("Elastic fit"), [&](phantom::Case& k) {
          k.fitted = fitted;
          k.fitStatus = status.toStdString();
          k.pose = pose;
        });
        fitUndoIndex_ = undo_.index();
        fitKeep_->setEnabled(true);
        fitRevert_->setEnabled(true);
        fitStatus_->setText(tr("%1 (%2 s). Keep it, or revert it (Ctrl+Z).").arg(status).arg(ms / 1000.0, 0, 'f', 1));
        statusCase_->setText(tr("Elastic fit: %1").arg(status));
      };
    } catch (const std::exception& e) {
      const QString message = QString::fromUtf8(e.what());
      return [this, message] {
        view_->setCase(case_.data);
        fitStatus_->setText(tr("The fit failed: %1").arg(message));
      };
    }
  });
}

QWidget* MainWindow::buildRigidPage() {
  auto* page = new QWidget;
  auto* l = new QVBoxLayout(page);
  auto* gizmo = toolButton(page, tr("Gizmo (G)"),
                           tr("Drag X, Y, Z to move along the camera axes, rX, rY, rZ to turn about them through the organ's centre. "
                              "Keys: arrows and PgUp/PgDn move 1 mm, W/S A/D Q/E turn 1 degree; Shift for 10 mm / 5 degrees."),
                           Step::Rigid, Tool::Align, Qt::Key_G);
  gizmo->setMinimumHeight(34);
  l->addWidget(gizmo);
  auto* box = new QGroupBox(tr("Pose (camera frame)"), page);
  auto* form = new QFormLayout(box);
  const char* names[6] = {"tx (mm)", "ty (mm)", "tz (mm)", "rx (deg)", "ry (deg)", "rz (deg)"};
  for (int k = 0; k < 6; ++k) {
    auto* s = new QDoubleSpinBox(box);
    s->setRange(k < 3 ? -5000 : -180, k < 3 ? 5000 : 180);
    s->setDecimals(k < 3 ? 2 : 2);
    s->setSingleStep(k < 3 ? 1.0 : 1.0);
    s->setKeyboardTracking(false);
    poseFields_[k] = s;
    form->addRow(tr(names[k]), s);
    connect(s, &QDoubleSpinBox::valueChanged, this, [this] {
      if (updatingPanels_ || !case_.data) return;
      Pose p;
      p.t = Eigen::Vector3d(poseFields_[0]->value(), poseFields_[1]->value(), poseFields_[2]->value()) * 1e-3;
      const double d = M_PI / 180;
      p.R = (Eigen::AngleAxisd(poseFields_[5]->value() * d, Eigen::Vector3d::UnitZ()) *
             Eigen::AngleAxisd(poseFields_[4]->value() * d, Eigen::Vector3d::UnitY()) *
             Eigen::AngleAxisd(poseFields_[3]->value() * d, Eigen::Vector3d::UnitX()))
                .toRotationMatrix();
      editCase(tr("Edit pose"), [p](phantom::Case& k) {
        k.pose = p;
        k.hasPose = true;
        k.poseAligned = true;
      });
    });
  }
  l->addWidget(box);
  auto* reset = new QPushButton(tr("Reset to Automatic Placement"), page);
  connect(reset, &QPushButton::clicked, this, [this] {
    editCase(tr("Reset pose"), [](phantom::Case& k) {
      k.pose = k.automaticPose();
      k.hasPose = true;
      k.poseAligned = false;
    });
  });
  l->addWidget(reset);
  auto* lmBox = new QGroupBox(tr("Landmark pairs (mesh point, then image point)"), page);
  auto* ll = new QVBoxLayout(lmBox);
  auto* pick = toolButton(lmBox, tr("Pick Landmarks (L)"), tr("Click a point on the organ, then where it is in the frame; 4 pairs or more"),
                          Step::Rigid, Tool::Landmarks, Qt::Key_L);
  ll->addWidget(pick);
  landmarkList_ = new QListWidget(lmBox);
  landmarkList_->setMaximumHeight(110);
  ll->addWidget(landmarkList_);
  auto* lrow = new QHBoxLayout;
  pnpButton_ = new QPushButton(tr("Solve Pose"), lmBox);
  pnpButton_->setEnabled(false);
  connect(pnpButton_, &QPushButton::clicked, this, &MainWindow::solvePnP);
  auto* clearLm = new QPushButton(tr("Clear"), lmBox);
  connect(clearLm, &QPushButton::clicked, this, [this] {
    landmarks_.clear();
    view_->setLandmarks(landmarks_);
    refreshPanels();
  });
  lrow->addWidget(pnpButton_);
  lrow->addWidget(clearLm);
  ll->addLayout(lrow);
  l->addWidget(lmBox);
  distanceLabel_ = new QLabel(page);
  QFont f = distanceLabel_->font();
  f.setPointSizeF(f.pointSizeF() * 1.3);
  f.setBold(true);
  distanceLabel_->setFont(f);
  distanceLabel_->setWordWrap(true);
  l->addWidget(distanceLabel_);
  l->addStretch(1);
  return page;
}

void MainWindow::setStep(Step s) {
  step_ = s;
  const int row = static_cast<int>(s);
  if (row < 5) {
    steps_->setCurrentIndex(row);
    if (workflow_->currentRow() != row) workflow_->setCurrentRow(row);
  }
  if (s == Step::Contour && (view_->tool() == Tool::Navigate || view_->tool() == Tool::Align || view_->tool() == Tool::Landmarks))
    view_->setTool(Tool::Freehand);
  else if (s == Step::Rigid && view_->tool() != Tool::Landmarks)
    view_->setTool(Tool::Align);
  else if (s == Step::Mesh || s == Step::Frame)
    view_->setTool(Tool::Navigate);
  updateWorkflow();
}

bool MainWindow::stepDone(Step s) const {
  const auto& c = case_.data;
  if (!c) return false;
  switch (s) {
    case Step::Mesh: return !c->volume.tets.empty();
    case Step::Frame: return !c->frame.empty() && c->camera.problem().empty();
    case Step::Contour: return imaging::contourProblem(c->contour).empty();
    case Step::Rigid: return c->hasPose && c->poseAligned;
    case Step::Elastic: return !c->fitted.empty();
    default: return false;
  }
}

void MainWindow::updateWorkflow() {
  if (!workflow_) return;
  int next = -1;
  for (int i = 0; i < 5; ++i)
    if (!stepDone(static_cast<Step>(i))) {
      next = i;
      break;
    }
  for (int i = 0; i < 7; ++i) {
    auto* item = workflow_->item(i);
    QString text = tr(kStepNames[i]);
    QFont f = item->font();
    f.setBold(i == next);
    item->setFont(f);
    if (i < 5 && stepDone(static_cast<Step>(i))) text += QStringLiteral("   \u2713");
    else if (i == next) text += tr("   (next)");
    item->setText(text);
  }
}

// ----------------------------------------------------------------------------------- case and commands

void MainWindow::editCase(const QString& text, const std::function<void(phantom::Case&)>& edit, int mergeId) {
  if (!case_.data) return;
  auto after = std::make_shared<phantom::Case>(*case_.data);
  edit(*after);
  undo_.push(new CaseCommand(this, case_.data, std::move(after), text, mergeId));
}

void MainWindow::setCaseData(std::shared_ptr<const phantom::Case> data) {
  const bool frameChanged = !case_.data || case_.data->frame.data != data->frame.data;
  const bool meshChanged = !case_.data || case_.data->volume.points.size() != data->volume.points.size() ||
                           case_.data->volume.tets != data->volume.tets;
  case_.data = std::move(data);
  if (frameChanged) case_.frame = toQImage(case_.data->frame);
  if (meshChanged) case_.qualityText = case_.data->volume.empty() ? QString() : QString::fromStdString(simcore::formatQuality(case_.data->quality));
  view_->setCase(case_.data);
  if (organView_) organView_->setCase(case_.data);
  if (organGLView_) organGLView_->setCase(case_.data);
  simulation_->setOrgan(case_.data);
  if (frameChanged) view_->setFrame(case_.frame);
  refreshOverlay();
  showCaseInfo();
  refreshPanels();
  updateWorkflow();
}

void MainWindow::refreshOverlay() {
  const auto& c = case_.data;
  contourDistance_ = -1;
  if (!c || c->surface.empty() || !c->hasPose || !c->camera.problem().empty()) {
    view_->setOverlay({}, {});
    view_->setInnerOverlay({});
    statusDistance_->clear();
    return;
  }
  // Large frames (4k) get the overlay at a reduced resolution, drawn scaled: the GUI thread stays responsive.
  const double s = std::min(1.0, 1600.0 / c->camera.width);
  imaging::Camera cam = c->camera;
  if (s < 1.0) {
    cam.width = static_cast<int>(std::lround(c->camera.width * s));
    cam.height = static_cast<int>(std::lround(c->camera.height * s));
    cam.K.row(0) *= s;
    cam.K.row(1) *= s;
    cam.K(0, 2) = s * (c->camera.cx() + 0.5) - 0.5;
    cam.K(1, 2) = s * (c->camera.cy() + 0.5) - 0.5;
  }
  case_.organOverlay = organImage(cam, c->pose, c->surfaceView(), QColor(120, 210, 150));
  const cv::Mat overlay(case_.organOverlay.height(), case_.organOverlay.width(), CV_8UC4, const_cast<uchar*>(case_.organOverlay.constBits()),
                        static_cast<std::size_t>(case_.organOverlay.bytesPerLine()));
  cv::Mat1b mask;
  cv::extractChannel(overlay, mask, 3);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  case_.silhouette.clear();
  for (const auto& ct : contours) {
    QPolygonF poly;
    for (const auto& p : ct) poly << QPointF((p.x + 0.5) / s, (p.y + 0.5) / s);
    case_.silhouette << poly;
  }
  view_->setOverlay(case_.organOverlay, case_.silhouette);
  // Inner structures the user ticked, drawn over the organ.
  std::vector<std::array<int, 3>> inner;
  int innerLabel = -1;
  for (std::size_t i = 0; i < c->innerSurface.size(); ++i) {
    const int l = c->innerSurfaceLabels[i];
    if (labelVisible_.count(l) && labelVisible_[l]) {
      inner.push_back(c->innerSurface[i]);
      innerLabel = l;
    }
  }
  if (!inner.empty()) {
    SurfaceView v = c->volume.surfaceView();
    v.triangles = inner.front().data();
    v.triangleCount = inner.size();
    view_->setInnerOverlay(organImage(cam, c->pose, v, labelColour(innerLabel)));
  } else {
    view_->setInnerOverlay({});
  }
  // The distance the elastic fit measures: the silhouette contour's points to the organ's visible
  // silhouette (its bent edges), in pixels of the frame.
  simcore::Residual2D d;
  if (const auto segments = imaging::silhouetteSegments(c->contour); !segments.empty()) {
    const SurfaceView sv = c->surfaceView();
    Eigen::VectorXd x(3 * static_cast<Eigen::Index>(sv.vertexCount));
    for (std::size_t i = 0; i < sv.vertexCount; ++i) x.segment<3>(3 * static_cast<Eigen::Index>(i)) = sv.vertex(i);
    try {
      d = simcore::contourResidual(segments, simcore::visibleSilhouette(c->surface, x, c->pose, c->camera.pinhole()));
    } catch (const std::exception&) {
      d = {};  // behind the camera: no distance to show
    }
  }
  if (d.points > 0 && std::isfinite(d.mean)) {
    contourDistance_ = d.mean;
    const QString text =
        tr("Contour to silhouette: mean %1 px, RMS %2 px, max %3 px").arg(d.mean, 0, 'f', 1).arg(d.rms, 0, 'f', 1).arg(d.hausdorff, 0, 'f', 1);
    statusDistance_->setText(text);
    if (distanceLabel_) distanceLabel_->setText(text);
  } else {
    statusDistance_->clear();
    if (distanceLabel_) distanceLabel_->setText(tr("Sketch a contour (step 3) to see its distance to the silhouette."));
  }
}

void MainWindow::refreshPanels() {
  const auto& c = case_.data;
  if (!c) return;
  updatingPanels_ = true;
  // Step 1: labels and attachments.
  attachmentsLabel_->setText(c->attachments.empty()
                                 ? tr("No ligament attachments: the organ is free (it falls in the simulation).")
                                 : tr("Ligament attachments: %n node(s).", nullptr, static_cast<int>(c->attachments.size())));
  labels_->clear();
  std::map<int, std::size_t> counts;
  for (int l : c->volume.tetLabels) counts[l]++;
  for (const auto& [label, n] : counts) {
    auto* item = new QTreeWidgetItem(labels_);
    const std::string name = c->volume.labelName(label);
    item->setText(0, QStringLiteral("%1 %2").arg(label).arg(QString::fromStdString(name)));
    item->setText(1, QString::number(n));
    item->setData(0, Qt::UserRole, label);
    item->setFlags(item->flags() | Qt::ItemIsUserCheckable);
    if (!labelVisible_.count(label)) labelVisible_[label] = label == 1;
    item->setCheckState(0, labelVisible_[label] ? Qt::Checked : Qt::Unchecked);
    QPixmap swatch(14, 14);
    swatch.fill(labelColour(label));
    item->setIcon(0, QIcon(swatch));
  }
  // Step 2: camera.
  fx_->setValue(c->camera.fx());
  fy_->setValue(c->camera.fy());
  cx_->setValue(c->camera.cx());
  cy_->setValue(c->camera.cy());
  const auto& d = c->camera.distortion;
  distortionLabel_->setText(QStringLiteral("k1 %1  k2 %2  p1 %3  p2 %4  k3 %5").arg(d[0]).arg(d[1]).arg(d[2]).arg(d[3]).arg(d[4]));
  // Step 3: contour status.
  const std::string problem = imaging::contourProblem(c->contour);
  contourStatus_->setText(tr("%1 segments, %2 points. %3")
                              .arg(c->contour.segments.size())
                              .arg(c->contour.pointCount())
                              .arg(problem.empty() ? tr("Ready for fitting.") : QString::fromStdString(problem)));
  // Step 5: the anatomical curves.
  {
    int sketched = 0, onOrgan = 0;
    for (const auto& s : c->contour.segments)
      if (!s.isSilhouette()) {
        ++sketched;
        onOrgan += !s.modelVertices.empty();
      }
    fitCurves_->setText(sketched == 0 ? tr("No ridge or ligament sketched: the fit uses the silhouette alone.")
                                      : tr("Ridges and ligaments: %1 sketched, %2 with their curve on the organ (held by the fit).")
                                            .arg(sketched)
                                            .arg(onOrgan));
  }
  // Step 4: pose fields (translation in mm, rotation as Z-Y-X Euler angles in degrees).
  if (c->hasPose) {
    // R = Rz(rz) Ry(ry) Rx(rx), angles in (-180, 180] with ry in [-90, 90] (the fields rebuild R the same way).
    const auto& R = c->pose.R;
    const double rz = std::atan2(R(1, 0), R(0, 0)), ry = std::asin(std::clamp(-R(2, 0), -1.0, 1.0)), rx = std::atan2(R(2, 1), R(2, 2));
    const double d = 180 / M_PI;
    const double vals[6] = {c->pose.t.x() * 1e3, c->pose.t.y() * 1e3, c->pose.t.z() * 1e3, rx * d, ry * d, rz * d};
    for (int k = 0; k < 6; ++k) poseFields_[k]->setValue(vals[k]);
  }
  landmarkList_->clear();
  int complete = 0;
  for (std::size_t i = 0; i < landmarks_.size(); ++i) {
    const auto& l = landmarks_[i];
    complete += l.hasImage;
    landmarkList_->addItem(QStringLiteral("%1: (%2, %3, %4) mm -> %5")
                               .arg(i + 1)
                               .arg(l.model.x() * 1e3, 0, 'f', 1)
                               .arg(l.model.y() * 1e3, 0, 'f', 1)
                               .arg(l.model.z() * 1e3, 0, 'f', 1)
                               .arg(l.hasImage ? QStringLiteral("(%1, %2) px").arg(l.image.x(), 0, 'f', 1).arg(l.image.y(), 0, 'f', 1)
                                               : tr("click the frame")));
  }
  pnpButton_->setEnabled(complete >= 4);
  updatingPanels_ = false;
}

// ----------------------------------------------------------------------------------------- workflow jobs

void MainWindow::runJob(const QString& message,
                        const std::function<std::function<void()>(const std::atomic<bool>&, const std::function<void(double, QString)>&)>& job) {
  if (jobWatcher_.isRunning()) {
    statusCase_->setText(tr("Another job is running; wait for it or cancel it (Esc)."));
    return;
  }
  cancel_ = false;
  setBusy(true, message);
  auto progress = [this](double f, QString stage) {
    QMetaObject::invokeMethod(this, [this, f, stage] {
      progress_->setValue(static_cast<int>(100 * f));
      progress_->setFormat(stage + QStringLiteral(" %p%"));
    }, Qt::QueuedConnection);
  };
  jobWatcher_.setFuture(QtConcurrent::run([this, job, progress]() -> std::function<void()> { return job(cancel_, progress); }));
}

int MainWindow::labelsShown() const { return labels_->topLevelItemCount(); }
int MainWindow::targetTets() const { return targetTets_->value(); }
void MainWindow::setTargetTets(int n) { targetTets_->setValue(n); }
void MainWindow::setMeshUnit(const QString& unit) { meshUnit_->setCurrentText(unit); }

void MainWindow::importMesh(const QString& path) {
  if (!case_.data) return;
  const int target = targetTets_->value();
  const std::string unit = meshUnit_->currentText().toStdString();
  QSettings().setValue(QStringLiteral("mesh/targetTets"), target);
  setStep(Step::Mesh);
  runJob(tr("Importing %1...").arg(QFileInfo(path).fileName()), [this, path, target, unit](const std::atomic<bool>& cancel, const auto& progress) -> std::function<void()> {
    try {
      std::vector<std::string> notes;
      progress(0.02, QStringLiteral("reading"));
      simcore::Mesh m = simcore::loadMesh(path.toStdString(), {unit}, &notes);
      if (!m.isVolume()) {
        simcore::TetrahedraliseOptions o;
        o.targetTets = static_cast<std::size_t>(target);
        o.cancel = &cancel;
        o.progress = [&progress](double f, const std::string& s) { progress(0.05 + 0.9 * f, QString::fromStdString(s)); };
        m = simcore::tetrahedraliseSurface(m, o, &notes);
      }
      m.triangles.clear();
      m.triangleLabels.clear();
      // Surfaces and quality of the new mesh are derived here, off the GUI thread.
      auto prepared = std::make_shared<phantom::Case>();
      prepared->volume = std::move(m);
      prepared->deriveFromVolume();
      QStringList qnotes;
      for (const auto& n : notes) qnotes << QString::fromStdString(n);
      return [this, prepared, path, qnotes] {
        editCase(tr("Import mesh"), [&](phantom::Case& k) {
          k.volume = prepared->volume;
          k.surface = prepared->surface;
          k.innerSurface = prepared->innerSurface;
          k.innerSurfaceLabels = prepared->innerSurfaceLabels;
          k.quality = prepared->quality;
          k.attachments.clear();
          k.fitted.clear();
          k.fitStatus.clear();
          k.hasGroundTruth = false;
          k.vesselTree.clear();
          k.meshSource = path.toStdString();
          k.pose = k.automaticPose();
          k.hasPose = true;
          k.poseAligned = false;
        });
        case_.notes = qnotes;
        showCaseInfo();
        statusCase_->setText(tr("Imported %1: %2 tetrahedra").arg(QFileInfo(path).fileName()).arg(case_.data->volume.tets.size()));
        emit meshImported(true, {});
      };
    } catch (const simcore::Cancelled&) {
      return [this] {
        statusCase_->setText(tr("Import cancelled; the case is unchanged."));
        emit meshImported(false, tr("cancelled"));
      };
    } catch (const std::exception& e) {
      const QString msg = QString::fromUtf8(e.what());
      return [this, msg] {
        statusCase_->setText(msg);
        emit meshImported(false, msg);
      };
    }
  });
}

void MainWindow::openFrameSource(const QString& path) {
  setStep(Step::Frame);
  const QString ext = QFileInfo(path).suffix().toLower();
  const bool isVideo = QStringList{"mp4", "avi", "mkv", "mov", "m4v", "mpg", "webm"}.contains(ext);
  if (!isVideo) {
    cv::Mat3b img = cv::imread(path.toStdString(), cv::IMREAD_COLOR);
    if (img.empty()) {
      const QString msg = tr("%1 is not a readable image; use PNG, JPEG, BMP or TIFF.").arg(QFileInfo(path).fileName());
      statusCase_->setText(msg);
      emit frameSourceOpened(false, msg);
      return;
    }
    video_.reset();
    videoFrames_ = 0;
    videoSlider_->setEnabled(false);
    videoLabel_->setText(tr("no video"));
    shownFrame_ = img;
    useShownFrame();
    emit frameSourceOpened(true, {});
    return;
  }
  // Opening a video probes the container and decoder: off the GUI thread.
  auto mutex = videoMutex_;
  runJob(tr("Opening video %1...").arg(QFileInfo(path).fileName()), [this, path, mutex](const std::atomic<bool>&, const auto&) -> std::function<void()> {
    auto cap = std::make_shared<cv::VideoCapture>();
    std::lock_guard<std::mutex> lock(*mutex);
    if (!cap->open(path.toStdString()) || !cap->isOpened()) {
      const QString msg = tr("%1 cannot be decoded as a video; check the file or convert it to MP4 (H.264).").arg(QFileInfo(path).fileName());
      return [this, msg] {
        statusCase_->setText(msg);
        emit frameSourceOpened(false, msg);
      };
    }
    const int frames = static_cast<int>(cap->get(cv::CAP_PROP_FRAME_COUNT));
    return [this, cap, frames, path] {
      cameraTimer_.stop();
      video_ = cap;
      videoFrames_ = std::max(0, frames);
      updatingPanels_ = true;
      videoSlider_->setRange(0, std::max(0, videoFrames_ - 1));
      videoSlider_->setValue(0);
      videoSlider_->setEnabled(videoFrames_ > 1);
      updatingPanels_ = false;
      useFrameButton_->setEnabled(true);
      statusCase_->setText(tr("Video %1: %2 frames; scrub to pick the frame to work on.").arg(QFileInfo(path).fileName()).arg(videoFrames_));
      emit frameSourceOpened(true, {});
      showVideoFrame(0);
    };
  });
}

void MainWindow::openCameraDevice(int index) {
  auto cap = std::make_shared<cv::VideoCapture>();
  if (!cap->open(index) || !cap->isOpened()) {
    statusCase_->setText(tr("Camera device %1 cannot be opened; check that it is connected and not in use.").arg(index));
    emit frameSourceOpened(false, statusCase_->text());
    return;
  }
  video_ = cap;
  videoFrames_ = 0;
  videoSlider_->setEnabled(false);
  useFrameButton_->setEnabled(true);
  videoLabel_->setText(tr("live camera %1").arg(index));
  cameraTimer_.start(66);
  emit frameSourceOpened(true, {});
}

void MainWindow::showVideoFrame(int index) {
  if (!video_) return;
  if (videoDecoding_) {
    pendingVideoFrame_ = index;  // the latest request wins
    return;
  }
  videoDecoding_ = true;
  auto cap = video_;
  auto mutex = videoMutex_;
  auto watcher = new QFutureWatcher<cv::Mat>(this);
  connect(watcher, &QFutureWatcher<cv::Mat>::finished, this, [this, watcher, index] {
    cv::Mat frame = watcher->result();
    watcher->deleteLater();
    videoDecoding_ = false;
    if (!frame.empty()) {
      shownFrame_ = frame;
      if (index >= 0) shownVideoFrame_ = index;
      view_->setFrame(toQImage(frame));
      videoLabel_->setText(index >= 0 ? tr("frame %1 of %2").arg(index).arg(videoFrames_) : videoLabel_->text());
      updatingPanels_ = true;
      if (index >= 0) videoSlider_->setValue(index);
      updatingPanels_ = false;
      if (index >= 0) emit videoFrameShown(index);
    } else if (index >= 0) {
      statusCase_->setText(tr("Frame %1 could not be decoded.").arg(index));
    }
    if (pendingVideoFrame_ >= 0 && pendingVideoFrame_ != index) {
      const int next = pendingVideoFrame_;
      pendingVideoFrame_ = -1;
      showVideoFrame(next);
    }
  });
  watcher->setFuture(QtConcurrent::run([cap, mutex, index]() -> cv::Mat {
    std::lock_guard<std::mutex> lock(*mutex);
    cv::Mat frame;
    if (index >= 0) cap->set(cv::CAP_PROP_POS_FRAMES, index);
    cap->read(frame);
    if (!frame.empty() && frame.channels() != 3) cv::cvtColor(frame, frame, frame.channels() == 1 ? cv::COLOR_GRAY2BGR : cv::COLOR_BGRA2BGR);
    return frame;
  }));
}

void MainWindow::useShownFrame() {
  if (shownFrame_.empty() || !case_.data) return;
  cv::Mat3b frame = shownFrame_.clone();
  const int shown = shownVideoFrame_;
  const bool fromVideo = video_ != nullptr && videoFrames_ > 0;
  editCase(fromVideo ? tr("Pick frame %1").arg(shown) : tr("Open frame"), [frame](phantom::Case& k) {
    if (k.camera.width != frame.cols || k.camera.height != frame.rows) {
      // A frame of another size keeps no stale calibration: the stated default, editable in the panel.
      k.camera = imaging::Camera::defaultFor(frame.cols, frame.rows);
    }
    k.rawFrame = frame;
    undistortFrame(k);
    k.contour.width = frame.cols;
    k.contour.height = frame.rows;
  });
  statusCase_->setText(fromVideo ? tr("Using frame %1 of the video.").arg(shown) : tr("Frame opened."));
}

void MainWindow::loadCalibration(const QString& path) {
  if (!case_.data) return;
  try {
    const int w = case_.data->frame.empty() ? 0 : case_.data->frame.cols, h = case_.data->frame.empty() ? 0 : case_.data->frame.rows;
    imaging::Camera cam = imaging::loadCamera(path.toStdString(), w, h);
    if (w > 0 && (cam.width != w || cam.height != h))
      throw imaging::InputError(tr("The calibration is for %1x%2 images but the frame is %3x%4; choose the matching calibration.")
                                    .arg(cam.width).arg(cam.height).arg(w).arg(h).toStdString());
    editCase(tr("Load calibration"), [cam](phantom::Case& k) {
      if (k.rawFrame.empty()) k.rawFrame = k.frame;  // the frame so far was taken as captured
      k.camera = cam;
      undistortFrame(k);
    });
    statusCase_->setText(tr("Calibration loaded from %1.").arg(QFileInfo(path).fileName()));
  } catch (const std::exception& e) {
    statusCase_->setText(QString::fromUtf8(e.what()));
  }
}

void MainWindow::importContour(const QString& path) {
  try {
    imaging::Contour c = imaging::loadContour(path.toStdString());
    if (case_.data && !case_.data->frame.empty() && c.width == 0) {
      c.width = case_.data->frame.cols;
      c.height = case_.data->frame.rows;
    }
    editCase(tr("Import contour"), [&c](phantom::Case& k) { k.contour = c; });
    setStep(Step::Contour);
    statusCase_->setText(tr("Contour imported: %1 segments.").arg(c.segments.size()));
  } catch (const std::exception& e) {
    statusCase_->setText(QString::fromUtf8(e.what()));
  }
}

void MainWindow::exportContour(const QString& path) {
  if (!case_.data) return;
  try {
    imaging::saveContour(case_.data->contour, path.toStdString());
    statusCase_->setText(tr("Contour exported to %1.").arg(path));
  } catch (const std::exception& e) {
    statusCase_->setText(QString::fromUtf8(e.what()));
  }
}

void MainWindow::solvePnP() {
  if (!case_.data) return;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (const auto& l : landmarks_)
    if (l.hasImage) {
      object.emplace_back(l.model.x(), l.model.y(), l.model.z());
      image.emplace_back(l.image.x(), l.image.y());
    }
  if (object.size() < 4) {
    statusCase_->setText(tr("Pick at least 4 landmark pairs first."));
    return;
  }
  const auto& cam = case_.data->camera;
  cv::Mat K(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) K.at<double>(r, c) = cam.K(r, c);
  // The frame is undistorted, so no distortion here. Several solvers (SQPnP, EPnP, and Levenberg-Marquardt
  // started from the current pose), each refined, and the one with the smallest reprojection error wins:
  // a few landmarks on an organ's front are nearly coplanar, where single solvers can land on the mirror pose.
  auto rms = [&](const cv::Mat& rv, const cv::Mat& tv) {
    std::vector<cv::Point2d> reproj;
    cv::projectPoints(object, rv, tv, K, cv::noArray(), reproj);
    double sum = 0;
    for (std::size_t i = 0; i < image.size(); ++i) sum += std::pow(cv::norm(reproj[i] - image[i]), 2);
    return std::sqrt(sum / image.size());
  };
  cv::Mat rvec, tvec;
  double best = std::numeric_limits<double>::infinity();
  auto consider = [&](cv::Mat rv, cv::Mat tv) {
    if (rv.empty() || tv.empty() || tv.at<double>(2) <= 0) return;
    cv::solvePnPRefineLM(object, image, K, cv::noArray(), rv, tv);
    const double e = rms(rv, tv);
    if (e < best && tv.at<double>(2) > 0) {
      best = e;
      rvec = rv.clone();
      tvec = tv.clone();
    }
  };
  for (int method : {cv::SOLVEPNP_SQPNP, cv::SOLVEPNP_EPNP}) {
    cv::Mat rv, tv;
    try {
      if (cv::solvePnP(object, image, K, cv::noArray(), rv, tv, false, method)) consider(rv, tv);
    } catch (const cv::Exception&) {
    }
  }
  {
    cv::Mat R0(3, 3, CV_64F), rv, tv(3, 1, CV_64F);
    const Pose& p0 = case_.data->pose;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) R0.at<double>(r, c) = p0.R(r, c);
      tv.at<double>(r) = p0.t[r];
    }
    cv::Rodrigues(R0, rv);
    try {
      if (cv::solvePnP(object, image, K, cv::noArray(), rv, tv, true, cv::SOLVEPNP_ITERATIVE)) consider(rv, tv);
    } catch (const cv::Exception&) {
    }
  }
  if (rvec.empty()) {
    statusCase_->setText(tr("The landmarks do not determine a pose; spread them over the organ and try again."));
    return;
  }
  pnpError_ = best;
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Pose p;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p.R(r, c) = R.at<double>(r, c);
    p.t[r] = tvec.at<double>(r);
  }
  editCase(tr("Pose from landmarks"), [p](phantom::Case& k) {
    k.pose = p;
    k.hasPose = true;
    k.poseAligned = true;
  });
  statusCase_->setText(tr("Pose from %1 landmark pairs: reprojection RMS %2 px.").arg(object.size()).arg(pnpError_, 0, 'f', 3));
}

// ------------------------------------------------------------------------------------------- files

QString MainWindow::autosavePath() {
  return QStandardPaths::writableLocation(QStandardPaths::AppDataLocation) + QStringLiteral("/autosave.rehearse");
}

bool MainWindow::hasRecoverableAutosave() { return isCaseFile(autosavePath()); }

void MainWindow::autosaveNow() {
  if (!case_.data) return;
  QDir().mkpath(QFileInfo(autosavePath()).absolutePath());
  saveCaseFile(*case_.data, autosavePath());
}

QStringList MainWindow::recentFiles() const { return QSettings().value(QStringLiteral("recentFiles")).toStringList(); }

void MainWindow::addRecent(const QString& path) {
  QSettings s;
  QStringList list = s.value(QStringLiteral("recentFiles")).toStringList();
  list.removeAll(path);
  list.prepend(path);
  while (list.size() > 8) list.removeLast();
  s.setValue(QStringLiteral("recentFiles"), list);
  rebuildRecentMenu();
}

void MainWindow::rebuildRecentMenu() {
  if (!recentMenu_) return;
  recentMenu_->clear();
  const QStringList list = recentFiles();
  for (int i = 0; i < list.size(); ++i) {
    QAction* a = recentMenu_->addAction(QStringLiteral("&%1 %2").arg(i + 1).arg(list[i]));
    const QString path = list[i];
    connect(a, &QAction::triggered, this, [this, path] { openCase(path); });
  }
  recentMenu_->setEnabled(!list.isEmpty());
}

void MainWindow::saveCaseAs(const QString& path) {
  if (!case_.data || saveWatcher_.isRunning()) {
    emit caseSaved(false, tr("Nothing to save yet."));
    return;
  }
  savingPath_ = path;
  statusCase_->setText(tr("Saving %1...").arg(path));
  auto data = case_.data;
  saveWatcher_.setFuture(QtConcurrent::run([data, path]() -> QString {
    try {
      saveCaseFile(*data, path);
      return {};
    } catch (const std::exception& e) {
      return QString::fromUtf8(e.what());
    }
  }));
}

void MainWindow::save() {
  if (currentPath_.isEmpty() || !isCaseFile(currentPath_)) saveAs();
  else saveCaseAs(currentPath_);
}

void MainWindow::saveAs() {
  QSettings s;
  QString path = QFileDialog::getSaveFileName(this, tr("Save Case"), s.value(QStringLiteral("lastDir")).toString(), tr("Rehearse cases (*.rehearse)"));
  if (path.isEmpty()) return;
  if (!path.endsWith(QStringLiteral(".rehearse"))) path += QStringLiteral(".rehearse");
  s.setValue(QStringLiteral("lastDir"), QFileInfo(path).absolutePath());
  saveCaseAs(path);
}

void MainWindow::importMeshDialog() {
  const QString p = QFileDialog::getOpenFileName(this, tr("Import Organ Mesh"), QSettings().value("lastDir").toString(),
                                                 tr("Meshes (*.msh *.vtk *.vtu *.mesh *.obj *.stl *.ply *.off *.gltf *.glb)"));
  if (!p.isEmpty()) importMesh(p);
}

void MainWindow::openFrameDialog() {
  const QString p = QFileDialog::getOpenFileName(this, tr("Open Endoscope Image or Video"), QSettings().value("lastDir").toString(),
                                                 tr("Images and videos (*.png *.jpg *.jpeg *.bmp *.tif *.mp4 *.avi *.mkv *.mov)"));
  if (!p.isEmpty()) openFrameSource(p);
}

void MainWindow::openFileDialog() {
  QSettings s;
  const QString path = QFileDialog::getOpenFileName(this, tr("Open Case"), s.value(QStringLiteral("lastDir")).toString(),
                                                    tr("Rehearse cases (*.rehearse);;All files (*)"));
  if (path.isEmpty()) return;
  s.setValue(QStringLiteral("lastDir"), QFileInfo(path).absolutePath());
  openCase(path);
}

void MainWindow::offerRecovery() {
  if (!hasRecoverableAutosave()) return;
  auto* box = new QMessageBox(QMessageBox::Question, tr("Recover case"),
                              tr("Rehearse did not close cleanly last time. Recover the case that was open then?"),
                              QMessageBox::Yes | QMessageBox::No, this);
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->setWindowModality(Qt::NonModal);
  connect(box, &QMessageBox::finished, this, [this](int r) {
    if (r == QMessageBox::Yes) openCase(autosavePath());
  });
  box->show();
}

void MainWindow::dragEnterEvent(QDragEnterEvent* e) {
  if (e->mimeData()->hasUrls()) e->acceptProposedAction();
}

void MainWindow::dropEvent(QDropEvent* e) {
  const auto urls = e->mimeData()->urls();
  if (urls.isEmpty() || !urls.first().isLocalFile()) return;
  const QString path = urls.first().toLocalFile();
  const QString ext = QFileInfo(path).suffix().toLower();
  // The dropped file's kind decides the step it belongs to.
  if (QFileInfo(path).isDir() || ext == QLatin1String("rehearse")) openCase(path);
  else if (QStringList{"msh", "vtk", "vtu", "mesh", "obj", "stl", "ply", "off", "gltf", "glb"}.contains(ext)) importMesh(path);
  else if (QStringList{"png", "jpg", "jpeg", "bmp", "tif", "tiff", "mp4", "avi", "mkv", "mov"}.contains(ext)) openFrameSource(path);
  else if (ext == QLatin1String("json")) importContour(path);
  else if (QStringList{"yaml", "yml", "xml"}.contains(ext)) loadCalibration(path);
  else statusCase_->setText(tr("%1: unknown file type.").arg(QFileInfo(path).fileName()));
}

// -------------------------------------------------------------------------------------------- menus

void MainWindow::buildMenus() {
  QMenu* file = menuBar()->addMenu(tr("&File"));
  QAction* openFile = file->addAction(tr("&Open Case..."), this, &MainWindow::openFileDialog);
  openFile->setShortcut(QKeySequence::Open);
  QAction* open = file->addAction(tr("Open Case &Folder..."), this, [this] {
    QSettings s;
    const QString dir = QFileDialog::getExistingDirectory(this, tr("Open Case Folder"), s.value(QStringLiteral("lastDir")).toString());
    if (!dir.isEmpty()) {
      s.setValue(QStringLiteral("lastDir"), dir);
      openCase(dir);
    }
  });
  open->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_O));
  recentMenu_ = file->addMenu(tr("Open &Recent"));
  rebuildRecentMenu();
  QAction* builtin = file->addAction(tr("Open &Built-in Phantom"), this, [this] { openCase({}); });
  builtin->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_P));
  file->addSeparator();
  QAction* importAction = file->addAction(tr("&Import Mesh..."), this, &MainWindow::importMeshDialog);
  importAction->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_I));
  QAction* frameAction = file->addAction(tr("Open &Frame or Video..."), this, &MainWindow::openFrameDialog);
  frameAction->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_F));
  file->addSeparator();
  QAction* saveAction = file->addAction(tr("&Save"), this, &MainWindow::save);
  saveAction->setShortcut(QKeySequence::Save);
  QAction* saveAsAction = file->addAction(tr("Save &As..."), this, &MainWindow::saveAs);
  saveAsAction->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_S));
  recoverAction_ = file->addAction(tr("Recover &Autosaved Case"), this, [this] { openCase(autosavePath()); });
  recoverAction_->setEnabled(hasRecoverableAutosave());
  file->addSeparator();
  QAction* quit = file->addAction(tr("&Quit"), this, &QWidget::close);
  quit->setShortcut(QKeySequence::Quit);

  QMenu* edit = menuBar()->addMenu(tr("&Edit"));
  QAction* undo = undo_.createUndoAction(this, tr("&Undo"));
  undo->setShortcut(QKeySequence::Undo);
  QAction* redo = undo_.createRedoAction(this, tr("&Redo"));
  redo->setShortcut(QKeySequence::Redo);
  edit->addAction(undo);
  edit->addAction(redo);

  QMenu* stepMenu = menuBar()->addMenu(tr("&Step"));
  for (int i = 0; i < 5; ++i) {
    QAction* a = stepMenu->addAction(tr(kStepNames[i]), this, [this, i] { setStep(static_cast<Step>(i)); });
    a->setShortcut(QKeySequence(Qt::ALT | static_cast<Qt::Key>(Qt::Key_1 + i)));
  }

  QMenu* viewMenu = menuBar()->addMenu(tr("&View"));
  overlayAction_ = viewMenu->addAction(tr("Show &Organ"));
  overlayAction_->setCheckable(true);
  overlayAction_->setChecked(true);
  overlayAction_->setShortcut(QKeySequence(Qt::Key_O));
  connect(overlayAction_, &QAction::toggled, view_, &FrameView::setOverlayVisible);
  QAction* fit = viewMenu->addAction(tr("&Fit Frame"), view_, &FrameView::fitToWindow);
  fit->setShortcut(QKeySequence(Qt::Key_Home));
  QAction* more = viewMenu->addAction(tr("More Opaque Organ"), this, [this] { view_->setOverlayOpacity(view_->overlayOpacity() + 0.1); });
  more->setShortcut(QKeySequence(Qt::Key_BracketRight));
  QAction* less = viewMenu->addAction(tr("More Transparent Organ"), this, [this] { view_->setOverlayOpacity(view_->overlayOpacity() - 0.1); });
  less->setShortcut(QKeySequence(Qt::Key_BracketLeft));
  // Shaded, wireframe or outline only; V cycles, the choice is kept between runs.
  viewMenu->addSeparator();
  auto* styles = new QActionGroup(this);
  const std::pair<QString, OverlayStyle> styleNames[] = {{tr("Organ &Shaded"), OverlayStyle::Shaded},
                                                         {tr("Organ &Wireframe"), OverlayStyle::Wireframe},
                                                         {tr("Organ Silhouette &Only"), OverlayStyle::Silhouette}};
  const int savedStyle = std::clamp(QSettings().value(QStringLiteral("overlayStyle"), 0).toInt(), 0, 2);
  for (const auto& [name, style] : styleNames) {
    QAction* a = viewMenu->addAction(name);
    a->setCheckable(true);
    a->setData(static_cast<int>(style));
    a->setChecked(static_cast<int>(style) == savedStyle);
    styles->addAction(a);
    connect(a, &QAction::triggered, this, [this, style = style] {
      view_->setOverlayStyle(style);
      QSettings().setValue(QStringLiteral("overlayStyle"), static_cast<int>(style));
    });
  }
  view_->setOverlayStyle(static_cast<OverlayStyle>(savedStyle));
  QAction* cycle = viewMenu->addAction(tr("Next Organ Style"), this, [this, styles] {
    const int next = (static_cast<int>(view_->overlayStyle()) + 1) % 3;
    styles->actions().at(next)->trigger();
  });
  cycle->setShortcut(QKeySequence(Qt::Key_V));
  viewMenu->addSeparator();
  QAction* navigate = viewMenu->addAction(tr("&Navigate (pan and zoom)"), this, [this] { view_->setTool(Tool::Navigate); });
  navigate->setShortcut(QKeySequence(Qt::Key_N));

  QMenu* simMenu = menuBar()->addMenu(tr("Si&mulate"));
  QAction* showSim = simMenu->addAction(tr("Show &Simulation"), this, [this] {
    simulationDock_->show();
    simulationDock_->raise();
  });
  showSim->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_M));
  QAction* playSim = simMenu->addAction(tr("&Play / Pause"), this, [this] {
    simulationDock_->show();
    simulationDock_->raise();
    simulation_->togglePlay();
  });
  playSim->setShortcut(QKeySequence(Qt::Key_F5));
  QAction* stepSim = simMenu->addAction(tr("Single S&tep"), this, [this] {
    simulationDock_->show();
    simulationDock_->raise();
    simulation_->stepOnce();
  });
  stepSim->setShortcut(QKeySequence(Qt::Key_F6));
  QAction* resetSim = simMenu->addAction(tr("&Reset"), this, [this] { simulation_->reset(); });
  resetSim->setShortcut(QKeySequence(Qt::SHIFT | Qt::Key_F5));

  QAction* cancel = new QAction(tr("Cancel"), this);
  cancel->setShortcut(QKeySequence(Qt::Key_Escape));
  connect(cancel, &QAction::triggered, this, &MainWindow::cancelLoading);
  addAction(cancel);

  QMenu* help = menuBar()->addMenu(tr("&Help"));
  QAction* about = help->addAction(tr("&About Rehearse"), this, [this] {
    QMessageBox::about(this, tr("About Rehearse"),
                       tr("<b>Rehearse %1</b><p>Intra-operative surgical gesture rehearsal: register the pre-operative "
                          "organ onto an endoscope frame, then grasp, pull and cut it in a view that looks like the frame.</p>")
                           .arg(QStringLiteral(REHEARSE_VERSION)));
  });
  about->setShortcut(QKeySequence::HelpContents);

  QToolBar* tools = addToolBar(tr("Main"));
  tools->setObjectName(QStringLiteral("mainToolbar"));
  tools->setIconSize(QSize(28, 28));
  tools->addAction(openFile);
  tools->addAction(saveAction);
  tools->addAction(importAction);
  tools->addAction(frameAction);
  tools->addSeparator();
  tools->addAction(undo);
  tools->addAction(redo);
  tools->addSeparator();
  tools->addAction(overlayAction_);
  tools->addAction(fit);
}

// ------------------------------------------------------------------------------------------ loading

void MainWindow::setBusy(bool busy, const QString& message) {
  progress_->setVisible(busy);
  cancelButton_->setVisible(busy);
  if (busy) progress_->setValue(0);
  if (!message.isEmpty()) statusCase_->setText(message);
}

void MainWindow::openCase(const QString& path) {
  if (watcher_.isRunning()) {
    cancel_ = true;
    watcher_.waitForFinished();
  }
  cancel_ = false;
  loadingDir_ = path;
  setBusy(true, path.isEmpty() ? tr("Generating the built-in phantom case...") : tr("Opening %1...").arg(path));
  auto progress = [this](double f, const QString& stage) {
    QMetaObject::invokeMethod(this, [this, f, stage] {
      progress_->setValue(static_cast<int>(100 * f));
      progress_->setFormat(stage + QStringLiteral(" %p%"));
    }, Qt::QueuedConnection);
  };
  watcher_.setFuture(QtConcurrent::run([path, progress, this] { return loadCase(path, progress, &cancel_); }));
}

void MainWindow::cancelLoading() {
  if (watcher_.isRunning() || jobWatcher_.isRunning()) cancel_ = true;
}

void MainWindow::onLoadFinished() {
  setBusy(false);
  LoadedCase loaded = watcher_.result();
  if (!loaded.error.isEmpty()) {
    statusCase_->setText(loaded.error);  // the current case stays untouched
    emit caseLoaded(false);
    return;
  }
  auto data = loaded.data;
  case_ = std::move(loaded);
  case_.data = nullptr;  // setCaseData compares with the previous data
  undo_.clear();
  fitUndoIndex_ = -1;
  landmarks_.clear();
  view_->setLandmarks(landmarks_);
  labelVisible_.clear();
  currentPath_ = isCaseFile(loadingDir_) && loadingDir_ != autosavePath() ? loadingDir_ : QString();
  if (!currentPath_.isEmpty()) addRecent(currentPath_);
  setCaseData(data);
  view_->fitToWindow();
  const QString name = currentPath_.isEmpty() ? QString::fromStdString(case_.data->name) : QFileInfo(currentPath_).fileName();
  setWindowTitle(tr("%1 - Rehearse").arg(name));
  statusCase_->setText(tr("%1 loaded in %2 s").arg(name).arg(case_.seconds, 0, 'f', 2) +
                       (case_.notes.isEmpty() ? QString() : tr(" (%1 problems, see the Case panel)").arg(case_.notes.size())));
  // Go to the first step that is not done yet.
  for (int i = 0; i < 4; ++i)
    if (!stepDone(static_cast<Step>(i))) {
      setStep(static_cast<Step>(i));
      break;
    }
  emit caseLoaded(true);
}

QString MainWindow::infoText() const { return info_->toPlainText(); }

void MainWindow::showCaseInfo() {
  if (!case_.data) return;
  const auto& c = *case_.data;
  QString t;
  t += tr("Case: %1\n").arg(QString::fromStdString(c.name));
  if (!c.meshSource.empty()) t += tr("Mesh from: %1\n").arg(QString::fromStdString(c.meshSource));
  t += QLatin1Char('\n');
  for (const auto& n : case_.notes) t += tr("! %1\n").arg(n);
  if (!case_.notes.isEmpty()) t += QLatin1Char('\n');
  t += tr("Organ mesh\n%1\n").arg(case_.qualityText);
  t += tr("surface triangles: %1\nattachment nodes: %2\n\n").arg(c.surface.size()).arg(c.attachments.size());
  const auto& cam = c.camera;
  t += tr("Camera\nimage: %1 x %2 px\nfx %3  fy %4 px\ncx %5  cy %6 px\ndistortion: %7 %8 %9 %10 %11\n\n")
           .arg(cam.width).arg(cam.height)
           .arg(cam.fx(), 0, 'f', 1).arg(cam.fy(), 0, 'f', 1).arg(cam.cx(), 0, 'f', 1).arg(cam.cy(), 0, 'f', 1)
           .arg(cam.distortion[0]).arg(cam.distortion[1]).arg(cam.distortion[2]).arg(cam.distortion[3]).arg(cam.distortion[4]);
  auto poseText = [](const Pose& p) {
    QString s;
    for (int r = 0; r < 3; ++r)
      s += QStringLiteral("[%1 %2 %3]  t %4 mm\n")
               .arg(p.R(r, 0), 7, 'f', 4).arg(p.R(r, 1), 7, 'f', 4).arg(p.R(r, 2), 7, 'f', 4).arg(p.t[r] * 1e3, 8, 'f', 2);
    return s;
  };
  if (c.hasPose) t += tr("Pose (model to camera, %1)\n%2\n").arg(c.poseAligned ? tr("aligned") : tr("automatic placement"), poseText(c.pose));
  if (c.hasGroundTruth) {
    t += tr("Ground-truth pose\n%1").arg(poseText(c.truePose));
    const auto& a = c.trueAppearance;
    t += tr("\nLight (ground truth)\nposition: %1, %2, %3 mm\nkd: %4 %5 %6\nks: %7 %8 %9\nroughness: %10 rad\n")
             .arg(a.lightPosition.x() * 1e3).arg(a.lightPosition.y() * 1e3).arg(a.lightPosition.z() * 1e3)
             .arg(a.kd.x()).arg(a.kd.y()).arg(a.kd.z()).arg(a.ks.x()).arg(a.ks.y()).arg(a.ks.z()).arg(a.roughness);
  }
  info_->setPlainText(t);
}

void MainWindow::closeEvent(QCloseEvent* e) {
  cancelLoading();
  cameraTimer_.stop();
  jobWatcher_.waitForFinished();
  saveWatcher_.waitForFinished();
  // A clean exit leaves no autosave behind: its presence at start means the last session crashed.
  QFile::remove(autosavePath());
  QSettings settings;
  settings.setValue(QStringLiteral("window/geometry"), saveGeometry());
  settings.setValue(QStringLiteral("window/state"), saveState());
  e->accept();
}

}  // namespace rehearse::ui
