#include "rehearse/ui/mainwindow.hpp"

#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/gloverlay.hpp"
#include "rehearse/ui/organview.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <rehearse/app/elasticfit.hpp>
#include <rehearse/app/workflow.hpp>

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

QString stepName(int i) { return QStringLiteral("%1  %2").arg(i + 1).arg(QCoreApplication::translate("Step", app::kSteps[static_cast<std::size_t>(i)].title)); }

}  // namespace

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle(tr("Rehearse"));
  setObjectName(QStringLiteral("MainWindow"));
  doc_ = new CaseDocument(this);
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
  connect(simulation_, &SimulationPanel::materialEdited, this, [this](const app::MaterialSettings& m) {
    doc_->edit(tr("Edit material"), [m](app::Case& k) { k.material = m; });
  });
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
    doc_->edit(text, [&c](app::Case& k) { k.contour = c; }, merge);
  });
  connect(view_, &FrameView::poseEdited, this, [this](const Pose& p, const QString& text, int merge) {
    doc_->edit(text, [&p](app::Case& k) {
      k.pose = p;
      k.hasPose = true;
      k.poseAligned = true;
    }, merge);
  });
  connect(view_, &FrameView::toolMessage, this, [this](const QString& text) { statusBar()->showMessage(text, 10000); });
  connect(view_, &FrameView::attachmentsEdited, this, [this](const std::vector<int>& nodes, const QString& text) {
    doc_->edit(text, [&](app::Case& k) { k.attachments = nodes; });
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
  connect(&jobWatcher_, &QFutureWatcher<std::function<void()>>::finished, this, [this] {
    setBusy(false);
    auto finish = jobWatcher_.result();
    if (finish) finish();
  });
  connect(doc_, &CaseDocument::changed, this, &MainWindow::onCaseChanged);
  connect(doc_, &CaseDocument::loaded, this, &MainWindow::onLoadFinished);
  connect(doc_, &CaseDocument::progress, this, [this](double f, const QString& stage) {
    progress_->setValue(static_cast<int>(100 * f));
    progress_->setFormat(stage + QStringLiteral(" %p%"));
  });
  connect(doc_, &CaseDocument::saved, this, [this](bool ok, const QString& message) {
    if (ok) setWindowTitle(tr("%1 - Rehearse").arg(QFileInfo(doc_->path()).fileName()));
    statusCase_->setText(message);
    emit caseSaved(ok, ok ? QString() : message);
  });
  connect(doc_, &CaseDocument::recentFilesChanged, this, &MainWindow::rebuildRecentMenu);
  connect(&cameraTimer_, &QTimer::timeout, this, [this] { showVideoFrame(-1); });
  setAcceptDrops(true);

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
  jobWatcher_.waitForFinished();
}

void MainWindow::setSoftwareRendering(bool on) { softwareRenderingFlag() = on; }

QWidget* MainWindow::organWidget() const {
  if (organGLView_) return organGLView_;
  return organView_;
}

bool MainWindow::isBusy() const { return doc_->isLoading() || jobWatcher_.isRunning() || doc_->isSaving(); }

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
  for (int i = 0; i < app::kStepCount; ++i) {
    auto* item = new QListWidgetItem(stepName(i), workflow_);
    item->setSizeHint(QSize(0, 34));
    item->setToolTip(tr("Alt+%1").arg(i + 1));
    if (!app::kSteps[static_cast<std::size_t>(i)].available) {
      item->setFlags(item->flags() & ~Qt::ItemIsEnabled);
      item->setToolTip(tr("Comes in a later version"));
    }
  }
  workflow_->setFixedHeight(app::kStepCount * 34 + 8);
  workflow_->setVerticalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  connect(workflow_, &QListWidget::currentRowChanged, this, [this](int row) {
    if (row >= 0 && row < app::kStepCount && app::kSteps[static_cast<std::size_t>(row)].available) setStep(static_cast<Step>(row));
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
    if (doc_->data() && !doc_->data()->attachments.empty())
      doc_->edit(tr("Release all attachments"), [](app::Case& k) { k.attachments.clear(); });
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
      if (updatingPanels_ || !doc_->data()) return;
      const double fx = fx_->value(), fy = fy_->value(), cx = cx_->value(), cy = cy_->value();
      doc_->edit(tr("Edit intrinsics"), [=](app::Case& k) {
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
    if (!doc_->data() || doc_->data()->frame.empty()) return;
    doc_->edit(tr("Default intrinsics"), [](app::Case& k) { k.camera = imaging::Camera::defaultFor(k.frame.cols, k.frame.rows); });
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
    doc_->edit(tr("Resample contour"), [s](app::Case& k) {
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
    doc_->edit(tr("Smooth contour"), [](app::Case& k) {
      for (auto& seg : k.contour.segments) seg = imaging::smoothSegment(seg, 5);
    });
  });
  auto* clear = new QPushButton(tr("Clear"), page);
  connect(clear, &QPushButton::clicked, this, [this] { doc_->edit(tr("Clear contour"), [](app::Case& k) { k.contour.segments.clear(); }); });
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
    if (doc_->data() && doc_->data()->fit) doc_->edit(tr("Clear elastic fit"), [](app::Case& k) {
      k.fit.reset();
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
    if (fitUndoIndex_ != doc_->undoStack()->index()) return;
    fitUndoIndex_ = -1;
    fitKeep_->setEnabled(false);
    fitRevert_->setEnabled(false);
    fitStatus_->setText(tr("Fit kept: %1").arg(QString::fromStdString(doc_->data()->fit ? doc_->data()->fit->status : std::string())));
  });
  connect(fitRevert_, &QPushButton::clicked, this, [this] {
    if (fitUndoIndex_ != doc_->undoStack()->index()) return;
    doc_->undoStack()->undo();  // Redo brings the fit back, and with it this choice
    fitStatus_->setText(tr("Fit reverted: the organ and the pose are as before it (Ctrl+Shift+Z brings it back)."));
  });
  connect(doc_->undoStack(), &QUndoStack::indexChanged, this, [this](int index) {
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
  if (!doc_->hasCase()) return;
  const auto c = doc_->data();
  if (const std::string missing = app::missingFor(*c, Step::Elastic); !missing.empty()) {
    fitStatus_->setText(tr("The fit needs %1.").arg(QString::fromStdString(missing)));
    return;
  }
  setStep(Step::Elastic);
  fitSeries_->clear();
  fitAxisY_->setRange(0, 10);
  fitAxisX_->setRange(0, 1);
  // The case's organ, attachments and material (the Simulation panel's), through the one fit pipeline.
  app::FitInput input = app::fitInputFromCase(*c);
  input.rigidPrepass = fitRigid_->isChecked();
  fitStatus_->setText(tr("Fitting... (Esc cancels)"));
  runJob(tr("Elastic fit..."), [this, c, input](const std::atomic<bool>& cancel, const auto& progress) -> std::function<void()> {
    try {
      auto onIteration = [this, c, &cancel, &progress](const simcore::RegistrationIteration& it, const Eigen::VectorXd& x, const Pose& pose) {
        // Live: the organ deforms over the frame and the chart grows (on the GUI thread), as a preview.
        auto preview = std::make_shared<app::Case>(*c);
        simcore::RegistrationResult partial;
        partial.x = x;
        preview->fit = app::toCasePart(partial);
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
      const simcore::RegistrationResult r = app::runElasticFit(input, onIteration);
      const QString status = QString::fromStdString(r.status);
      if (r.cancelled || !r.ok) {
        return [this, status, cancelled = r.cancelled] {
          view_->setCase(doc_->data());  // back to the case as it was
          fitStatus_->setText(cancelled ? tr("Cancelled; the case is unchanged.") : tr("The fit failed: %1").arg(status));
          statusCase_->setText(fitStatus_->text());
        };
      }
      auto fit = app::toCasePart(r);
      const Pose pose = r.pose;
      const double ms = r.iterations.back().wallMs;
      return [this, fit, pose, status, ms] {
        doc_->edit(tr("Elastic fit"), [&](app::Case& k) {
          k.fit = fit;
          k.pose = pose;
        });
        fitUndoIndex_ = doc_->undoStack()->index();
        fitKeep_->setEnabled(true);
        fitRevert_->setEnabled(true);
        fitStatus_->setText(tr("%1 (%2 s). Keep it, or revert it (Ctrl+Z).").arg(status).arg(ms / 1000.0, 0, 'f', 1));
        statusCase_->setText(tr("Elastic fit: %1").arg(status));
      };
    } catch (const std::exception& e) {
      const QString message = QString::fromUtf8(e.what());
      return [this, message] {
        view_->setCase(doc_->data());
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
      if (updatingPanels_ || !doc_->data()) return;
      Pose p;
      p.t = Eigen::Vector3d(poseFields_[0]->value(), poseFields_[1]->value(), poseFields_[2]->value()) * 1e-3;
      const double d = M_PI / 180;
      p.R = (Eigen::AngleAxisd(poseFields_[5]->value() * d, Eigen::Vector3d::UnitZ()) *
             Eigen::AngleAxisd(poseFields_[4]->value() * d, Eigen::Vector3d::UnitY()) *
             Eigen::AngleAxisd(poseFields_[3]->value() * d, Eigen::Vector3d::UnitX()))
                .toRotationMatrix();
      doc_->edit(tr("Edit pose"), [p](app::Case& k) {
        k.pose = p;
        k.hasPose = true;
        k.poseAligned = true;
      });
    });
  }
  l->addWidget(box);
  auto* reset = new QPushButton(tr("Reset to Automatic Placement"), page);
  connect(reset, &QPushButton::clicked, this, [this] {
    doc_->edit(tr("Reset pose"), [](app::Case& k) {
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
  if (row < steps_->count()) {
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

bool MainWindow::stepDone(Step s) const { return doc_->hasCase() && app::stepDone(*doc_->data(), s); }

void MainWindow::updateWorkflow() {
  if (!workflow_ || !doc_->hasCase()) return;
  const int next = app::nextStep(*doc_->data());
  for (int i = 0; i < app::kStepCount; ++i) {
    auto* item = workflow_->item(i);
    const auto& info = app::kSteps[static_cast<std::size_t>(i)];
    QString text = stepName(i);
    QFont f = item->font();
    f.setBold(i == next);
    item->setFont(f);
    if (info.available && stepDone(info.step)) text += QStringLiteral("   \u2713");
    else if (i == next) text += tr("   (next)");
    item->setText(text);
  }
}

// ----------------------------------------------------------------------------------- case and commands

void MainWindow::onCaseChanged(CaseDocument::Parts parts) {
  const auto& data = doc_->data();
  if (parts & CaseDocument::OrganPart) labelVisible_.clear();
  view_->setCase(data);
  if (organView_) organView_->setCase(data);
  if (organGLView_) organGLView_->setCase(data);
  simulation_->setCase(data);
  if (parts & CaseDocument::FramePart) view_->setFrame(doc_->frameImage());
  refreshOverlay();
  showCaseInfo();
  refreshPanels();
  updateWorkflow();
}

void MainWindow::refreshOverlay() {
  const auto& c = doc_->data();
  contourDistance_ = -1;
  if (!c || c->organ->surface.empty() || !c->hasPose || !c->camera.problem().empty()) {
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
  organOverlay_ = organImage(cam, c->pose, c->surfaceView(), QColor(120, 210, 150));
  const cv::Mat overlay(organOverlay_.height(), organOverlay_.width(), CV_8UC4, const_cast<uchar*>(organOverlay_.constBits()),
                        static_cast<std::size_t>(organOverlay_.bytesPerLine()));
  cv::Mat1b mask;
  cv::extractChannel(overlay, mask, 3);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  silhouette_.clear();
  for (const auto& ct : contours) {
    QPolygonF poly;
    for (const auto& p : ct) poly << QPointF((p.x + 0.5) / s, (p.y + 0.5) / s);
    silhouette_ << poly;
  }
  view_->setOverlay(organOverlay_, silhouette_);
  // Inner structures the user ticked, drawn over the organ, on the organ's current shape (fitted or rest).
  std::vector<int> shown;
  for (const auto& [label, visible] : labelVisible_)
    if (visible && label != app::kParenchymaLabel) shown.push_back(label);
  std::vector<std::array<int, 3>> inner;
  const SurfaceView innerView = c->innerSurfaceView(shown, inner);
  if (!inner.empty()) view_->setInnerOverlay(organImage(cam, c->pose, innerView, labelColour(shown.back())));
  else view_->setInnerOverlay({});
  // The distance the elastic fit measures: the silhouette contour's points to the organ's visible
  // silhouette (its bent edges), in pixels of the frame.
  simcore::Residual2D d;
  if (const auto segments = imaging::silhouetteSegments(c->contour); !segments.empty()) {
    const SurfaceView sv = c->surfaceView();
    Eigen::VectorXd x(3 * static_cast<Eigen::Index>(sv.vertexCount));
    for (std::size_t i = 0; i < sv.vertexCount; ++i) x.segment<3>(3 * static_cast<Eigen::Index>(i)) = sv.vertex(i);
    try {
      d = simcore::contourResidual(segments, simcore::visibleSilhouette(c->organ->surface, x, c->pose, c->camera.pinhole()));
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
  const auto& c = doc_->data();
  if (!c) return;
  updatingPanels_ = true;
  // Step 1: labels and attachments.
  attachmentsLabel_->setText(c->attachments.empty()
                                 ? tr("No ligament attachments: the organ is free (it falls in the simulation).")
                                 : tr("Ligament attachments: %n node(s).", nullptr, static_cast<int>(c->attachments.size())));
  labels_->clear();
  std::map<int, std::size_t> counts;
  for (int l : c->organ->volume.tetLabels) counts[l]++;
  for (const auto& [label, n] : counts) {
    auto* item = new QTreeWidgetItem(labels_);
    const std::string name = c->organ->volume.labelName(label);
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
  if (!doc_->data()) return;
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
      auto prepared = app::Organ::fromVolume(std::move(m), path.toStdString());
      QStringList qnotes;
      for (const auto& n : notes) qnotes << QString::fromStdString(n);
      return [this, prepared, path, qnotes] {
        doc_->edit(tr("Import mesh"), [&](app::Case& k) { k.setOrgan(prepared); });
        importNotes_ = qnotes;
        showCaseInfo();
        statusCase_->setText(tr("Imported %1: %2 tetrahedra").arg(QFileInfo(path).fileName()).arg(doc_->data()->organ->volume.tets.size()));
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
      view_->setFrame(frameToQImage(frame));
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
  if (shownFrame_.empty() || !doc_->data()) return;
  cv::Mat3b frame = shownFrame_.clone();
  const int shown = shownVideoFrame_;
  const bool fromVideo = video_ != nullptr && videoFrames_ > 0;
  doc_->edit(fromVideo ? tr("Pick frame %1").arg(shown) : tr("Open frame"), [frame](app::Case& k) {
    if (k.camera.width != frame.cols || k.camera.height != frame.rows) {
      // A frame of another size keeps no stale calibration: the stated default, editable in the panel.
      k.camera = imaging::Camera::defaultFor(frame.cols, frame.rows);
    }
    k.rawFrame = frame;
    app::undistortFrame(k);
    k.contour.width = frame.cols;
    k.contour.height = frame.rows;
  });
  statusCase_->setText(fromVideo ? tr("Using frame %1 of the video.").arg(shown) : tr("Frame opened."));
}

void MainWindow::loadCalibration(const QString& path) {
  if (!doc_->data()) return;
  try {
    const int w = doc_->data()->frame.empty() ? 0 : doc_->data()->frame.cols, h = doc_->data()->frame.empty() ? 0 : doc_->data()->frame.rows;
    imaging::Camera cam = imaging::loadCamera(path.toStdString(), w, h);
    if (w > 0 && (cam.width != w || cam.height != h))
      throw imaging::InputError(tr("The calibration is for %1x%2 images but the frame is %3x%4; choose the matching calibration.")
                                    .arg(cam.width).arg(cam.height).arg(w).arg(h).toStdString());
    doc_->edit(tr("Load calibration"), [cam](app::Case& k) {
      if (k.rawFrame.empty()) k.rawFrame = k.frame;  // the frame so far was taken as captured
      k.camera = cam;
      app::undistortFrame(k);
    });
    statusCase_->setText(tr("Calibration loaded from %1.").arg(QFileInfo(path).fileName()));
  } catch (const std::exception& e) {
    statusCase_->setText(QString::fromUtf8(e.what()));
  }
}

void MainWindow::importContour(const QString& path) {
  try {
    imaging::Contour c = imaging::loadContour(path.toStdString());
    if (doc_->data() && !doc_->data()->frame.empty() && c.width == 0) {
      c.width = doc_->data()->frame.cols;
      c.height = doc_->data()->frame.rows;
    }
    doc_->edit(tr("Import contour"), [&c](app::Case& k) { k.contour = c; });
    setStep(Step::Contour);
    statusCase_->setText(tr("Contour imported: %1 segments.").arg(c.segments.size()));
  } catch (const std::exception& e) {
    statusCase_->setText(QString::fromUtf8(e.what()));
  }
}

void MainWindow::exportContour(const QString& path) {
  if (!doc_->data()) return;
  try {
    imaging::saveContour(doc_->data()->contour, path.toStdString());
    statusCase_->setText(tr("Contour exported to %1.").arg(path));
  } catch (const std::exception& e) {
    statusCase_->setText(QString::fromUtf8(e.what()));
  }
}

void MainWindow::solvePnP() {
  if (!doc_->data()) return;
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
  const auto& cam = doc_->data()->camera;
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
    const Pose& p0 = doc_->data()->pose;
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
  doc_->edit(tr("Pose from landmarks"), [p](app::Case& k) {
    k.pose = p;
    k.hasPose = true;
    k.poseAligned = true;
  });
  statusCase_->setText(tr("Pose from %1 landmark pairs: reprojection RMS %2 px.").arg(object.size()).arg(pnpError_, 0, 'f', 3));
}

// ------------------------------------------------------------------------------------------- files

QString MainWindow::autosavePath() { return CaseDocument::autosavePath(); }
bool MainWindow::hasRecoverableAutosave() { return CaseDocument::hasRecoverableAutosave(); }
void MainWindow::autosaveNow() { doc_->autosaveNow(); }
QStringList MainWindow::recentFiles() const { return doc_->recentFiles(); }

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
  if (doc_->hasCase() && !doc_->isSaving()) statusCase_->setText(tr("Saving %1...").arg(path));
  doc_->saveAs(path);
}

void MainWindow::save() {
  if (doc_->path().isEmpty() || !isCaseFile(doc_->path())) saveAs();
  else saveCaseAs(doc_->path());
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
  QAction* undo = doc_->undoStack()->createUndoAction(this, tr("&Undo"));
  undo->setShortcut(QKeySequence::Undo);
  QAction* redo = doc_->undoStack()->createRedoAction(this, tr("&Redo"));
  redo->setShortcut(QKeySequence::Redo);
  edit->addAction(undo);
  edit->addAction(redo);

  QMenu* stepMenu = menuBar()->addMenu(tr("&Step"));
  for (int i = 0; i < app::kStepCount; ++i) {
    if (!app::kSteps[static_cast<std::size_t>(i)].available) continue;
    QAction* a = stepMenu->addAction(stepName(i), this, [this, i] { setStep(static_cast<Step>(i)); });
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
  setBusy(true, path.isEmpty() ? tr("Generating the built-in phantom case...") : tr("Opening %1...").arg(path));
  doc_->open(path);
}

void MainWindow::cancelLoading() {
  doc_->cancelLoading();
  if (jobWatcher_.isRunning()) cancel_ = true;
}

void MainWindow::onLoadFinished(bool ok, const QString& error) {
  setBusy(false);
  if (!ok) {
    statusCase_->setText(error);  // the current case stays untouched
    emit caseLoaded(false);
    return;
  }
  fitUndoIndex_ = -1;
  importNotes_.clear();
  showCaseInfo();
  landmarks_.clear();
  view_->setLandmarks(landmarks_);
  view_->fitToWindow();
  const QString name = doc_->path().isEmpty() ? QString::fromStdString(doc_->data()->name) : QFileInfo(doc_->path()).fileName();
  setWindowTitle(tr("%1 - Rehearse").arg(name));
  statusCase_->setText(tr("%1 loaded in %2 s").arg(name).arg(doc_->loadSeconds(), 0, 'f', 2) +
                       (doc_->notes().isEmpty() ? QString() : tr(" (%1 problems, see the Case panel)").arg(doc_->notes().size())));
  // Go to the first step that is not done yet.
  const int next = app::nextStep(*doc_->data());
  if (next < app::index(Step::Elastic)) setStep(static_cast<Step>(next));
  emit caseLoaded(true);
}

QString MainWindow::infoText() const { return info_->toPlainText(); }

void MainWindow::showCaseInfo() {
  if (!doc_->data()) return;
  const auto& c = *doc_->data();
  QString t;
  t += tr("Case: %1\n").arg(QString::fromStdString(c.name));
  if (!c.organ->source.empty()) t += tr("Mesh from: %1\n").arg(QString::fromStdString(c.organ->source));
  t += QLatin1Char('\n');
  const QStringList notes = doc_->notes() + importNotes_;
  for (const auto& n : notes) t += tr("! %1\n").arg(n);
  if (!notes.isEmpty()) t += QLatin1Char('\n');
  t += tr("Organ mesh\n%1\n").arg(doc_->qualityText());
  t += tr("surface triangles: %1\nattachment nodes: %2\n\n").arg(c.organ->surface.size()).arg(c.attachments.size());
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
  if (c.groundTruth) {
    t += tr("Ground-truth pose\n%1").arg(poseText(c.groundTruth->pose));
    const auto& a = c.groundTruth->appearance;
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
  // A clean exit leaves no autosave behind (after waiting for one being written): its presence at start
  // means the last session crashed.
  doc_->closeCleanly();
  QSettings settings;
  settings.setValue(QStringLiteral("window/geometry"), saveGeometry());
  settings.setValue(QStringLiteral("window/state"), saveState());
  e->accept();
}

}  // namespace rehearse::ui
