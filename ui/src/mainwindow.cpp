#include "rehearse/ui/mainwindow.hpp"

#include "rehearse/ui/caseinfo.hpp"
#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/organview.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <QAction>
#include <QActionGroup>
#include <QCoreApplication>
#include <QCloseEvent>
#include <QDockWidget>
#include <QDragEnterEvent>
#include <QDateTime>
#include <QDropEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QLabel>
#include <QListWidget>
#include <QMenuBar>
#include <QMessageBox>
#include "rehearse/ui/cohortwindow.hpp"
#include "rehearse/ui/reviewwindow.hpp"
#include <QInputDialog>
#include <QLineEdit>
#include <QMimeData>
#include <QPlainTextEdit>
#include <QPainter>
#include <QProgressBar>
#include <QSettings>
#include <QStackedWidget>
#include <QStatusBar>
#include <QTimer>
#include <QFutureWatcher>
#include <QtConcurrent/QtConcurrentRun>
#include <QToolBar>
#include <QToolButton>
#include <QUndoStack>
#include <QVBoxLayout>

namespace rehearse::ui {

// The simulated organ over the frame is redrawn at most every this many milliseconds (60 Hz).
constexpr qint64 kLiveOverlayMs = 16;
namespace {

MainWindow::Renderer& rendererChoice() {
  static MainWindow::Renderer choice = MainWindow::Renderer::Automatic;
  return choice;
}

// A status-bar label that never widens the bar: it shows as much of its sentence as fits, ending in an
// ellipsis, and the whole sentence in its tooltip (and in the Messages panel).
class SentenceLabel : public QLabel {
 public:
  using QLabel::QLabel;
  QSize minimumSizeHint() const override { return {200, QLabel::minimumSizeHint().height()}; }
  QSize sizeHint() const override { return {std::min(520, fontMetrics().horizontalAdvance(text()) + 8), QLabel::sizeHint().height()}; }

 protected:
  void paintEvent(QPaintEvent*) override {
    QPainter p(this);
    const QRect r = contentsRect();
    p.setPen(palette().color(QPalette::WindowText));
    p.drawText(r, Qt::AlignLeft | Qt::AlignVCenter, fontMetrics().elidedText(text(), Qt::ElideRight, r.width()));
  }
};

QString stepName(int i) { return QStringLiteral("%1  %2").arg(i + 1).arg(QCoreApplication::translate("Step", app::kSteps[static_cast<std::size_t>(i)].title)); }

}  // namespace

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle(tr("Rehearse"));
  setObjectName(QStringLiteral("MainWindow"));
  doc_ = new CaseDocument(this);
  jobs_ = new JobRunner(this);
  composition_ = new Composition(this);
  centre_ = new QStackedWidget(this);
  centre_->setObjectName(QStringLiteral("centre"));
  view_ = new FrameView(centre_);
  view_->setObjectName(QStringLiteral("frameView"));
  centre_->addWidget(view_);
  setCentralWidget(centre_);
  buildStatusBar();
  buildDocks();
  wb_.doc = doc_;
  wb_.view = view_;
  wb_.jobs = jobs_;
  wb_.window = this;
  wb_.status = [this](const QString& text) { say(text); };
  wb_.goToStep = [this](Step s) { setStep(s); };
  wb_.currentStep = [this] { return step_; };
  keys_ = std::make_unique<StepKeys>(this, wb_.currentStep);
  wb_.keys = keys_.get();
  buildWorkflowPanel();
  buildMenus();

  connect(view_, &FrameView::cursorMoved, this, [this](QPointF p) {
    status_.cursor->setText(tr("u %1  v %2 px").arg(p.x(), 0, 'f', 1).arg(p.y(), 0, 'f', 1));
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
  connect(view_, &FrameView::instrumentInput, this, [this](const simcore::InputEvent& e) {
    if (!simulation_->post(e)) say(tr("The simulation is not ready yet; the grasp did nothing (the organ needs a mesh and a pose)."));
  });
  connect(view_, &FrameView::toolMessage, this, [this](const QString& text) { statusBar()->showMessage(text, 10000); });
  connect(view_, &FrameView::attachmentsEdited, this, [this](const std::vector<int>& nodes, const QString& text) {
    doc_->edit(text, [&](app::Case& k) { k.attachments = nodes; });
  });
  connect(jobs_, &JobRunner::busyChanged, this, &MainWindow::setBusy);
  connect(jobs_, &JobRunner::refused, this, &MainWindow::say);
  connect(doc_, &CaseDocument::changed, this, &MainWindow::onCaseChanged);
  connect(doc_, &CaseDocument::loaded, this, &MainWindow::onLoadFinished);
  connect(doc_, &CaseDocument::progress, this, &MainWindow::showProgress);
  connect(jobs_, &JobRunner::progress, this, &MainWindow::showProgress);
  connect(doc_, &CaseDocument::saved, this, [this](bool ok, const QString& message) {
    if (ok) setWindowTitle(tr("%1 - Rehearse").arg(QFileInfo(doc_->path()).fileName()));
    // A recording goes on into the file as saved (or, when the save failed, into the file it was in).
    if (!doc_->isSaving()) simulation_->caseFileReplaced(doc_->path());
    say(message);
    emit caseSaved(ok, ok ? QString() : message);
  });
  connect(doc_, &CaseDocument::recentFilesChanged, this, &MainWindow::rebuildRecentMenu);
  setAcceptDrops(true);

  QSettings settings;
  if (!restoreGeometry(settings.value(QStringLiteral("window/geometry")).toByteArray())) resize(1600, 900);
  restoreState(settings.value(QStringLiteral("window/state")).toByteArray());
  setStep(Step::Mesh);
}

MainWindow::~MainWindow() {
  jobs_->cancel();
  pages_.frame->stopCamera();
  jobs_->waitForFinished();
}

void MainWindow::setRenderer(Renderer r) { rendererChoice() = r; }

MainWindow::Renderer MainWindow::renderer() { return rendererChoice(); }

QWidget* MainWindow::organWidget() const {
  if (organGLView_) return organGLView_;
  return organView_;
}

// ---------------------------------------------------------------------------------------------- docks

void MainWindow::buildDocks() {
  auto* infoDock = new QDockWidget(tr("Case"), this);
  infoDock->setObjectName(QStringLiteral("caseDock"));
  info_ = new QPlainTextEdit(infoDock);
  info_->setObjectName(QStringLiteral("caseInfo"));
  info_->setReadOnly(true);
  info_->setMinimumWidth(280);
  info_->setLineWrapMode(QPlainTextEdit::WidgetWidth);  // problem lines wrap instead of running off the side
  info_->setWordWrapMode(QTextOption::WrapAtWordBoundaryOrAnywhere);
  QFont mono(QStringLiteral("DejaVu Sans Mono"));
  mono.setStyleHint(QFont::Monospace);
  info_->setFont(mono);
  infoDock->setWidget(info_);
  addDockWidget(Qt::RightDockWidgetArea, infoDock);
  messagesDock_ = new QDockWidget(tr("Messages"), this);
  messagesDock_->setObjectName(QStringLiteral("messagesDock"));
  messages_ = new QPlainTextEdit(messagesDock_);
  messages_->setObjectName(QStringLiteral("messageLog"));
  messages_->setReadOnly(true);
  messages_->setMaximumBlockCount(5000);
  messagesDock_->setWidget(messages_);
  addDockWidget(Qt::RightDockWidgetArea, messagesDock_);
  tabifyDockWidget(infoDock, messagesDock_);
  infoDock->raise();
  auto* organDock = new QDockWidget(tr("Organ 3D"), this);
  organDock->setObjectName(QStringLiteral("organDock"));
  const QString glRenderer = rendererChoice() == Renderer::Software ? QString() : OrganGLView::openGLRenderer();
  bool openGL = !glRenderer.isEmpty();
  if (rendererChoice() == Renderer::Software) {
    rendererText_ = tr("Views drawn on the CPU (--software).");
  } else if (!openGL) {
    rendererText_ = tr("No OpenGL 3.3 here: the views are drawn on the CPU.");
  } else if (rendererChoice() == Renderer::Automatic && OrganGLView::isSoftwareRenderer(glRenderer)) {
    openGL = false;
    rendererText_ = tr("OpenGL here is a software rasteriser (%1): the views are drawn on the CPU, which is faster on it "
                       "('rehearse --opengl' uses OpenGL anyway).")
                        .arg(glRenderer);
  } else {
    rendererText_ = tr("Views drawn with OpenGL (%1).").arg(glRenderer);
  }
  messages_->appendPlainText(QDateTime::currentDateTime().toString(QStringLiteral("hh:mm:ss  ")) + rendererText_);
  overlay_ = std::make_unique<OrganOverlay>(openGL);
  composition_->useOpenGL(overlay_->usesOpenGL());  // the composited view as the overlay: OpenGL where it works
  if (openGL) {
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
  // The organ alone, large, in the centre (ViewMode::ThreeD): the same kind of view as the dock's.
  if (openGL) centreOrgan_ = new OrganGLView(centre_);
  else centreOrgan_ = new OrganView(centre_);
  centreOrgan_->setObjectName(QStringLiteral("centreOrganView"));
  centre_->addWidget(centreOrgan_);
  simulationDock_ = new QDockWidget(tr("Simulation"), this);
  simulationDock_->setObjectName(QStringLiteral("simulationDock"));
  simulation_ = new SimulationPanel(simulationDock_);
  simulation_->setObjectName(QStringLiteral("simulationPanel"));
  simulationDock_->setWidget(simulation_);
  addDockWidget(Qt::RightDockWidgetArea, simulationDock_);
  tabifyDockWidget(organDock, simulationDock_);
  organDock->raise();
  connect(simulation_, &SimulationPanel::statusChanged, this, [this](const QString& text) {
    status_.simulation->setText(text);
    status_.simulation->setToolTip(text);  // the whole sentence (the bar shows what fits)
  });
  liveDrawingTimer_.setSingleShot(true);
  liveDrawingTimer_.setInterval(static_cast<int>(kLiveOverlayMs));
  connect(&liveDrawingTimer_, &QTimer::timeout, this, &MainWindow::drawLiveIfDue);
  // The composited view follows the simulation: each snapshot shown is composed (on a worker, newest first).
  connect(simulation_, &SimulationPanel::frameShown, this, [this] {
    const auto f = simulation_->lastFrame();
    if (pages_.rehearse) pages_.rehearse->showFrame(f);
    // What happened in the rehearsal (a slip, a vessel cut, a refused edit) is kept in the Messages panel, once each.
    if (f && !f->message.isEmpty() && f->message != lastSimulationMessage_) {
      messages_->appendPlainText(QDateTime::currentDateTime().toString(QStringLiteral("hh:mm:ss  ")) + tr("Simulation (step %1): %2").arg(f->steps).arg(f->message));
    }
    if (f) lastSimulationMessage_ = f->message;
    if (f && f->organ && doc_->data() && f->organ->organ == doc_->data()->organ) {
      view_->setWarning(f->invertedAt, warningText(*f));
      view_->setLiveShape(f->positions);
      view_->setLiveSurface(f->surface);
      if (f->surface && showingComposited()) {
        // The composited view textures the organ's own surface; cut tissue it does not draw yet: the overlay
        // shows the cut instead of a picture that hides it.
        setViewMode(ViewMode::Overlay);
        statusBar()->showMessage(tr("The organ is cut: the composited view cannot show cut tissue yet, so the overlay is shown."), 8000);
      }
      // While rehearsing in the overlay view, the organ drawn over the frame follows the simulation: drawn on a
      // worker (newest first), at most 60 times a second and only once the last drawing was painted.
      if (step_ == Step::Rehearse && !showingComposited()) {
        LiveDrawing job;
        job.c = doc_->data();
        job.surface = f->surface;
        job.inner = pages_.mesh->shownInnerLabels();
        job.positions = f->positions;  // the case with these nodes is made on the worker (not at 100 Hz here)
        liveDrawingPending_ = std::move(job);
        drawLiveIfDue();
      }
    } else {
      view_->setWarning({}, {});  // another organ's frame (or none): its warning is not this organ's
    }
    if (showingComposited() && f && !f->surface && f->organ && doc_->data() && f->organ->organ == doc_->data()->organ) composition_->request(f->positions);
  });
  connect(composition_, &Composition::composed, this, [this] {
    if (showingComposited()) showFrameLayer();
  });
  connect(composition_, &Composition::readyChanged, this, [this](bool ready) {
    // The composited view is the case's view from the moment it can be made.
    if (ready) setViewMode(ViewMode::Composited);
    else showFrameLayer();
  });
  connect(simulation_, &SimulationPanel::materialEdited, this, [this](const app::MaterialSettings& m) {
    doc_->edit(tr("Edit material"), [m](app::Case& k) { k.material = m; });
  });
}

void MainWindow::buildStatusBar() {
  status_.progress = new QProgressBar(this);
  status_.progress->setRange(0, 100);
  status_.progress->setMaximumWidth(260);
  status_.progress->setVisible(false);
  status_.progress->setTextVisible(true);
  status_.progress->setFormat(QStringLiteral("%p%"));
  status_.stage = new QLabel(this);
  status_.stage->setObjectName(QStringLiteral("progressStage"));
  status_.stage->setVisible(false);
  status_.tick = new QTimer(this);
  status_.tick->setInterval(1000);
  connect(status_.tick, &QTimer::timeout, this, [this] { showProgress(status_.progress->maximum() == 0 ? -1 : status_.progress->value() / 100.0, {}); });
  status_.cancel = new QToolButton(this);
  status_.cancel->setText(tr("Cancel"));
  status_.cancel->setToolTip(tr("Cancel the running job (Esc)"));
  status_.cancel->setVisible(false);
  connect(status_.cancel, &QToolButton::clicked, this, &MainWindow::cancelLoading);
  status_.caseText = new SentenceLabel(this);
  status_.caseText->setObjectName(QStringLiteral("caseStatus"));
  auto* log = new QToolButton(this);
  log->setObjectName(QStringLiteral("showMessages"));
  log->setText(tr("Messages"));
  log->setToolTip(tr("Every message of this session, whole (Ctrl+L)"));
  log->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_L));
  connect(log, &QToolButton::clicked, this, [this] {
    messagesDock_->show();
    messagesDock_->raise();
  });
  status_.cursor = new QLabel(this);
  // The simulation's line is bounded (elided, whole in its tooltip) so that the case's sentence keeps its room.
  status_.simulation = new SentenceLabel(this);
  status_.simulation->setObjectName(QStringLiteral("statusSimulation"));
  status_.simulation->setMaximumWidth(520);
  status_.distance = new QLabel(this);
  status_.viewMode = new QLabel(this);
  status_.viewMode->setObjectName(QStringLiteral("statusViewMode"));
  statusBar()->addWidget(status_.caseText, 1);
  statusBar()->addWidget(log);
  statusBar()->addPermanentWidget(status_.simulation);
  statusBar()->addPermanentWidget(status_.distance);
  statusBar()->addPermanentWidget(status_.viewMode);
  statusBar()->addPermanentWidget(status_.cursor);
  statusBar()->addPermanentWidget(status_.stage);
  statusBar()->addPermanentWidget(status_.progress);
  statusBar()->addPermanentWidget(status_.cancel);
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
  stepStack_ = new QStackedWidget(host);
  pages_.mesh = new MeshPage(wb_);
  pages_.frame = new FramePage(wb_);
  pages_.contour = new ContourPage(wb_);
  pages_.rigid = new RigidPage(wb_);
  pages_.fit = new FitPage(wb_);
  pages_.appearance = new AppearancePage(wb_, composition_);
  pages_.rehearse = new RehearsePage(wb_);
  pages_.rehearse->setForceLoop([this] { return simulation_ ? simulation_->forceLoop() : nullptr; });
  pages_.all = {pages_.mesh, pages_.frame, pages_.contour, pages_.rigid, pages_.fit, pages_.appearance, pages_.rehearse};
  for (StepPage* p : pages_.all) stepStack_->addWidget(p);
  connect(pages_.mesh, &MeshPage::meshImported, this, &MainWindow::meshImported);
  connect(pages_.mesh, &MeshPage::shownLabelsChanged, this, &MainWindow::refreshOverlay);
  connect(pages_.mesh, &MeshPage::importNotesChanged, this, &MainWindow::showCaseInfo);
  connect(pages_.frame, &FramePage::frameSourceOpened, this, &MainWindow::frameSourceOpened);
  connect(pages_.frame, &FramePage::videoFrameShown, this, &MainWindow::videoFrameShown);
  layout->addWidget(stepStack_, 1);
  dock->setWidget(host);
  dock->setMinimumWidth(330);
  addDockWidget(Qt::LeftDockWidgetArea, dock);
}

// ------------------------------------------------------------------------------------------- workflow

void MainWindow::setStep(Step s) {
  step_ = s;
  keys_->stepShown(s);
  const int row = app::index(s);
  for (int i = 0; i < static_cast<int>(pages_.all.size()); ++i)
    if (pages_.all[static_cast<std::size_t>(i)]->step() == s) stepStack_->setCurrentIndex(i);
  if (workflow_->currentRow() != row) workflow_->setCurrentRow(row);
  // Each step's default tool (a tool of another step does not stay active on this one).
  const Tool t = view_->tool();
  if (s == Step::Contour && (t == Tool::Navigate || t == Tool::Align || t == Tool::Landmarks)) view_->setTool(Tool::Freehand);
  else if (s == Step::Rigid && t != Tool::Landmarks) view_->setTool(Tool::Align);
  else if (s == Step::Mesh || s == Step::Frame) view_->setTool(Tool::Navigate);
  else if ((s == Step::Elastic || s == Step::Appearance) && (t == Tool::Align || t == Tool::Landmarks)) view_->setTool(Tool::Navigate);  // no gizmo over the fit
  else if (s == Step::Rehearse) {
    if (t != Tool::Scissors) view_->setTool(Tool::Grasp);
    // The organ is rehearsed on live: it settles on its ligaments before the first grasp.
    if (doc_->hasCase() && doc_->data()->hasPose && !simulation_->isPlaying()) simulation_->play();
  }
  if (s != Step::Rehearse && (view_->tool() == Tool::Grasp || view_->tool() == Tool::Scissors)) view_->setTool(Tool::Navigate);
  if (s != Step::Rehearse && doc_->hasCase()) refreshOverlay();  // the case's organ again, not the simulation's
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

void MainWindow::onCaseChanged(CaseDocument::Parts parts) {
  const auto& data = doc_->data();
  view_->setCase(data);
  if (organView_) organView_->setCase(data);
  if (organGLView_) organGLView_->setCase(data);
  simulation_->setCase(data);
  if (auto* o = qobject_cast<OrganGLView*>(centreOrgan_)) o->setCase(data);
  else if (auto* o2 = qobject_cast<OrganView*>(centreOrgan_)) o2->setCase(data);
  composition_->setCase(data);
  if (data)
    for (StepPage* p : pages_.all) p->refresh(*data);
  refreshOverlay();
  showCaseInfo();
  updateWorkflow();
}

void MainWindow::drawLiveIfDue() {
  if (!liveDrawingPending_ || liveDrawingBusy_) return;
  if (!liveOverlayDue()) {
    if (!liveDrawingTimer_.isActive()) liveDrawingTimer_.start();  // the last frame is drawn even when the simulation stops
    return;
  }
  LiveDrawing job = std::move(*liveDrawingPending_);
  liveDrawingPending_.reset();
  liveDrawingBusy_ = true;
  liveOverlayClock_.start();
  liveOverlayPaints_ = view_->paints();
  auto* watcher = new QFutureWatcher<OverlayPicture>(this);
  connect(watcher, &QFutureWatcher<OverlayPicture>::finished, this, [this, watcher, organ = job.c->organ] {
    watcher->deleteLater();
    liveDrawingBusy_ = false;
    if (step_ == Step::Rehearse && !showingComposited() && doc_->data() && doc_->data()->organ == organ) {
      picture_ = watcher->result();
      showFrameLayer();
    }
    drawLiveIfDue();
  });
  watcher->setFuture(QtConcurrent::run([overlay = liveOverlay_, job = std::move(job)] {
    if (job.surface) return overlay->renderLive(*job.c, job.positions, *job.surface);
    // Uncut: the case with the simulated nodes as its shape (as an elastic fit's), drawn as the case is.
    app::Case live(*job.c);
    auto fit = std::make_shared<app::ElasticFit>();
    fit->nodes.reserve(job.positions.size());
    for (const auto& x : job.positions) fit->nodes.push_back(job.c->pose.R.transpose() * (x - job.c->pose.t));
    fit->status = "simulated";
    live.fit = fit;
    return overlay->render(live, job.inner);
  }));
}

bool MainWindow::liveOverlayDue() const {
  // Not before the last drawing reached the screen: drawings made faster than the view paints them only
  // delay its paints (measured in bench_rehearsal_view).
  return !liveOverlayClock_.isValid() || (liveOverlayClock_.elapsed() >= kLiveOverlayMs && view_->paints() != liveOverlayPaints_);
}

void MainWindow::showFrameLayer() {
  // Hiding the organ (O) in the composited view shows the frame as captured: the organ is drawn into that picture.
  const bool composited = showingComposited() && !composition_->lastComposed().isNull() && view_->overlayVisible();
  view_->setFrame(composited ? composition_->lastComposed() : doc_->frameImage());
  if (composited) {
    view_->setOverlay(QImage(), {});
    view_->setInnerOverlay(QImage());
  } else {
    view_->setOverlay(picture_.organ, picture_.silhouette);
    view_->setInnerOverlay(picture_.inner);
  }
  status_.viewMode->setText(viewModeText());
}

QString MainWindow::viewModeText() const {
  switch (viewMode_) {
    case ViewMode::Composited:
      return composition_->ready() ? (composition_->usesOpenGL() ? tr("Composited (OpenGL)") : tr("Composited"))
                                   : tr("Overlay (not composited: %1)").arg(composition_->whyNot());
    case ViewMode::Overlay: return tr("Overlay");
    case ViewMode::ThreeD: return tr("3D");
  }
  return {};
}

void MainWindow::setViewMode(ViewMode mode) {
  viewMode_ = mode;
  centre_->setCurrentIndex(mode == ViewMode::ThreeD ? 1 : 0);
  const auto i = static_cast<std::size_t>(mode);
  if (i < viewModeActions_.size() && !viewModeActions_[i]->isChecked()) viewModeActions_[i]->setChecked(true);
  if (mode == ViewMode::Composited && composition_->ready()) {
    // Follow the simulation from where it is now.
    const auto f = simulation_->lastFrame();
    composition_->request(f && f->organ && doc_->data() && f->organ->organ == doc_->data()->organ ? f->positions : std::vector<Eigen::Vector3d>{});
  }
  showFrameLayer();
  if (mode == ViewMode::Composited && !composition_->ready()) say(tr("The composited view needs the appearance: %1.").arg(composition_->whyNot()));
}

void MainWindow::refreshOverlay() {
  const auto& c = doc_->data();
  picture_ = c ? overlay_->render(*c, pages_.mesh->shownInnerLabels()) : OverlayPicture{};
  showFrameLayer();
  if (picture_.meanDistance >= 0) {
    const QString text = tr("Contour to silhouette: mean %1 px, RMS %2 px, max %3 px")
                             .arg(picture_.meanDistance, 0, 'f', 1)
                             .arg(picture_.rmsDistance, 0, 'f', 1)
                             .arg(picture_.maxDistance, 0, 'f', 1);
    status_.distance->setText(text);
    pages_.rigid->setDistanceText(text);
  } else {
    status_.distance->clear();
    pages_.rigid->setDistanceText(tr("Sketch a contour (step 3) to see its distance to the silhouette."));
  }
}

// ------------------------------------------------------------------------------------------- files

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
  const bool starts = doc_->hasCase() && !doc_->isSaving();
  if (starts) {
    say(tr("Saving %1...").arg(path));
    // The recorder lets go of the file (committed, WAL emptied) while it is copied and replaced; steps meanwhile
    // are kept and written into the saved file.
    simulation_->suspendRecording();
  }
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
  else if (QStringList{"msh", "vtk", "vtu", "mesh", "obj", "stl", "ply", "off", "gltf", "glb"}.contains(ext)) pages_.mesh->importMesh(path);
  else if (QStringList{"png", "jpg", "jpeg", "bmp", "tif", "tiff", "mp4", "avi", "mkv", "mov"}.contains(ext)) pages_.frame->openFrameSource(path);
  else if (ext == QLatin1String("json")) pages_.contour->importContour(path);
  else if (QStringList{"yaml", "yml", "xml"}.contains(ext)) pages_.frame->loadCalibration(path);
  else say(tr("%1: unknown file type.").arg(QFileInfo(path).fileName()));
}

// -------------------------------------------------------------------------------------------- menus

void MainWindow::buildMenus() {
  QMenu* file = menuBar()->addMenu(tr("&File"));
  QAction* openFile = file->addAction(tr("&Open Case..."), this, &MainWindow::openFileDialog);
  openFile->setShortcut(QKeySequence::Open);
  QAction* open = file->addAction(tr("Open Case &Folder..."), this, [this] {
    QSettings s;
    const QString dir = QFileDialog::getExistingDirectory(this, tr("Open Case Folder"), s.value(QStringLiteral("lastDir")).toString());
    if (dir.isEmpty()) return;
    s.setValue(QStringLiteral("lastDir"), dir);
    openCase(dir);
  });
  open->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_O));
  recentMenu_ = file->addMenu(tr("Open &Recent"));
  rebuildRecentMenu();
  file->addAction(tr("Open &Built-in Phantom"), this, [this] { openCase({}); })->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_P));
  file->addSeparator();
  QAction* importAction = file->addAction(tr("&Import Mesh..."), pages_.mesh, &MeshPage::importMeshDialog);
  importAction->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_I));
  QAction* frameAction = file->addAction(tr("Open &Frame or Video..."), pages_.frame, &FramePage::openFrameDialog);
  frameAction->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_F));
  file->addSeparator();
  QAction* saveAction = file->addAction(tr("&Save"), this, &MainWindow::save);
  saveAction->setShortcut(QKeySequence::Save);
  file->addAction(tr("Save &As..."), this, &MainWindow::saveAs)->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_S));
  recoverAction_ = file->addAction(tr("Recover &Autosaved Case"), this, [this] { openCase(autosavePath()); });
  recoverAction_->setEnabled(hasRecoverableAutosave());
  file->addSeparator();
  file->addAction(tr("&Quit"), this, &QWidget::close)->setShortcut(QKeySequence::Quit);

  QMenu* edit = menuBar()->addMenu(tr("&Edit"));
  QAction* undo = doc_->undoStack()->createUndoAction(this, tr("&Undo"));
  undo->setShortcut(QKeySequence::Undo);
  QAction* redo = doc_->undoStack()->createRedoAction(this, tr("&Redo"));
  redo->setShortcut(QKeySequence::Redo);
  edit->addAction(undo);
  edit->addAction(redo);
  // Undo and redo say what they did, so that no older sentence ("Imported ...") stays in the status bar.
  connect(undo, &QAction::triggered, this, [this] {
    const QUndoStack* stack = doc_->undoStack();
    say(tr("Undone: %1").arg(stack->text(stack->index())));
  });
  connect(redo, &QAction::triggered, this, [this] {
    const QUndoStack* stack = doc_->undoStack();
    if (stack->index() > 0) say(tr("Redone: %1").arg(stack->text(stack->index() - 1)));
  });

  QMenu* stepMenu = menuBar()->addMenu(tr("&Step"));
  for (int i = 0; i < app::kStepCount; ++i) {
    if (!app::kSteps[static_cast<std::size_t>(i)].available) continue;
    QAction* a = stepMenu->addAction(stepName(i), this, [this, i] { setStep(static_cast<Step>(i)); });
    a->setShortcut(QKeySequence(Qt::ALT | static_cast<Qt::Key>(Qt::Key_1 + i)));
  }
  QToolBar* tools = addToolBar(tr("Main"));
  tools->setObjectName(QStringLiteral("mainToolbar"));
  tools->setIconSize(QSize(28, 28));
  for (QAction* a : {openFile, saveAction, importAction, frameAction}) tools->addAction(a);
  tools->addSeparator();
  tools->addAction(undo);
  tools->addAction(redo);
  buildViewMenu();
  buildSimulationMenu();

  QAction* cancel = new QAction(tr("Cancel"), this);
  cancel->setShortcut(QKeySequence(Qt::Key_Escape));
  connect(cancel, &QAction::triggered, this, &MainWindow::cancelLoading);
  addAction(cancel);

  QMenu* help = menuBar()->addMenu(tr("&Help"));
  QAction* about = help->addAction(tr("&About Rehearse"), this, [this] {
    QMessageBox::about(this, tr("About Rehearse"),
                       tr("<b>Rehearse %1</b><p>Intra-operative surgical gesture rehearsal. This version registers the "
                          "pre-operative organ onto an endoscope frame (steps 1-5), estimates its appearance and the light from the frame "
                          "(step 6) and simulates it there, composited into the frame, where the grasper pulls it (step 7). Cutting, "
                          "contact, and the replay of rehearsals come in later versions.</p>")
                           .arg(QStringLiteral(REHEARSE_VERSION)));
  });
  about->setShortcut(QKeySequence::HelpContents);

}

void MainWindow::buildViewMenu() {
  QMenu* viewMenu = menuBar()->addMenu(tr("&View"));
  QAction* overlay = viewMenu->addAction(tr("Show &Organ"));
  overlay->setCheckable(true);
  overlay->setChecked(true);
  overlay->setShortcut(QKeySequence(Qt::Key_O));
  connect(overlay, &QAction::toggled, view_, &FrameView::setOverlayVisible);
  connect(overlay, &QAction::toggled, this, [this] { showFrameLayer(); });  // the composited organ is part of the picture
  QAction* fit = viewMenu->addAction(tr("&Fit Frame"), view_, &FrameView::fitToWindow);
  fit->setShortcut(QKeySequence(Qt::Key_Home));
  viewMenu->addAction(tr("More Opaque Organ"), this, [this] { view_->setOverlayOpacity(view_->overlayOpacity() + 0.1); })
      ->setShortcut(QKeySequence(Qt::Key_BracketRight));
  viewMenu->addAction(tr("More Transparent Organ"), this, [this] { view_->setOverlayOpacity(view_->overlayOpacity() - 0.1); })
      ->setShortcut(QKeySequence(Qt::Key_BracketLeft));
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
    a->setChecked(static_cast<int>(style) == savedStyle);
    styles->addAction(a);
    connect(a, &QAction::triggered, this, [this, style = style] {
      view_->setOverlayStyle(style);
      QSettings().setValue(QStringLiteral("overlayStyle"), static_cast<int>(style));
    });
  }
  view_->setOverlayStyle(static_cast<OverlayStyle>(savedStyle));
  viewMenu->addAction(tr("Next Organ Style"), this, [this, styles] {
    styles->actions().at((static_cast<int>(view_->overlayStyle()) + 1) % 3)->trigger();
  })->setShortcut(QKeySequence(Qt::Key_V));
  QAction* legend = viewMenu->addAction(tr("&Legend"));
  legend->setCheckable(true);
  legend->setChecked(QSettings().value(QStringLiteral("legend"), true).toBool());
  view_->setLegendVisible(legend->isChecked());
  connect(legend, &QAction::toggled, this, [this](bool on) {
    view_->setLegendVisible(on);
    QSettings().setValue(QStringLiteral("legend"), on);
  });
  // Composited / overlay / 3D (F2, F3, F4).
  viewMenu->addSeparator();
  auto* modes = new QActionGroup(this);
  const std::tuple<QString, ViewMode, Qt::Key, QString> modeNames[] = {
      {tr("&Composited View"), ViewMode::Composited, Qt::Key_F2, tr("The organ re-shaded into the frame, as estimated in step 6")},
      {tr("O&verlay View"), ViewMode::Overlay, Qt::Key_F3, tr("The organ drawn over the frame")},
      {tr("&3D View"), ViewMode::ThreeD, Qt::Key_F4, tr("The organ alone, in 3D")}};
  for (const auto& [name, mode, key, tip] : modeNames) {
    QAction* a = viewMenu->addAction(name);
    a->setCheckable(true);
    a->setShortcut(QKeySequence(key));
    a->setToolTip(tip);
    a->setObjectName(QStringLiteral("viewMode%1").arg(static_cast<int>(mode)));
    modes->addAction(a);
    viewModeActions_.push_back(a);
    connect(a, &QAction::triggered, this, [this, mode = mode] { setViewMode(mode); });
  }
  viewModeActions_[static_cast<std::size_t>(viewMode_)]->setChecked(true);
  viewMenu->addSeparator();
  viewMenu->addAction(tr("&Navigate (pan and zoom)"), this, [this] { view_->setTool(Tool::Navigate); })->setShortcut(QKeySequence(Qt::Key_N));
  if (auto* bar = findChild<QToolBar*>(QStringLiteral("mainToolbar"))) {
    bar->addSeparator();
    bar->addAction(overlay);
    bar->addAction(fit);
    bar->addSeparator();
    for (QAction* a : viewModeActions_) bar->addAction(a);
  }
}

void MainWindow::buildSimulationMenu() {
  QMenu* simMenu = menuBar()->addMenu(tr("Si&mulate"));
  auto show = [this] {
    simulationDock_->show();
    simulationDock_->raise();
  };
  simMenu->addAction(tr("Show &Simulation"), this, show)->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_M));
  simMenu->addAction(tr("&Play / Pause"), this, [this, show] {
    show();
    simulation_->togglePlay();
  })->setShortcut(QKeySequence(Qt::Key_F5));
  simMenu->addAction(tr("Single S&tep"), this, [this, show] {
    show();
    simulation_->stepOnce();
  })->setShortcut(QKeySequence(Qt::Key_F6));
  simMenu->addAction(tr("&Reset"), this, [this] { simulation_->reset(); })->setShortcut(QKeySequence(Qt::SHIFT | Qt::Key_F5));
  simMenu->addSeparator();
  simMenu->addAction(tr("Start / Stop &Recording"), this, [this] {
    if (recording()) stopRecording();
    else if (const QString err = startRecording(pages_.rehearse ? pages_.rehearse->trainee() : QString()); !err.isEmpty()) say(err);
  })->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_R));
  simMenu->addAction(tr("Re&view Recorded Rehearsals..."), this, [this] { openReview(); })->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_R));
  // The training centre's database: the connection from a libpq service name (or the environment); never stored
  // in the case file (the service name is a setting of this machine).
  auto askService = [this](bool& ok) {
    QSettings settings;
    const QString service = QInputDialog::getText(this, tr("Training database"),
                                                   tr("libpq service name (pg_service.conf; empty: PGHOST, PGDATABASE, ... from the environment):"),
                                                   QLineEdit::Normal, settings.value(QStringLiteral("training/service")).toString(), &ok);
    if (ok) settings.setValue(QStringLiteral("training/service"), service);
    return service;
  };
  simMenu->addAction(tr("&Publish Recorded Sessions..."), this, [this, askService] {
    const QString path = doc_->path();
    if (path.isEmpty() || !QFileInfo::exists(path)) return say(tr("Save the case and record a rehearsal first: sessions are published from the case file."));
    bool ok = false;
    const QString service = askService(ok);
    if (!ok) return;
    say(tr("Publishing the sessions of %1 (each is replayed and verified first)...").arg(QFileInfo(path).fileName()));
    auto* watcher = new QFutureWatcher<QString>(this);
    connect(watcher, &QFutureWatcher<QString>::finished, this, [this, watcher] {
      say(watcher->result());
      watcher->deleteLater();
    });
    watcher->setFuture(QtConcurrent::run([path, service] {
      try {
        TrainingDatabase db(service);  // its own connection, on this thread
        const auto r = db.publish(path);
        QString text = tr("Published %1 sessions (%2 already there, %3 not published).").arg(r.published).arg(r.already).arg(r.skipped);
        if (!r.notes.isEmpty()) text += " " + r.notes.join(" ");
        return text;
      } catch (const std::exception& e) {
        return tr("Publishing failed: %1").arg(QString::fromStdString(e.what()));
      }
    }));
  });
  simMenu->addAction(tr("Training &Cohort..."), this, [this, askService] {
    bool ok = false;
    const QString service = askService(ok);
    if (!ok) return;
    try {
      auto* w = new CohortWindow(std::make_shared<TrainingDatabase>(service), this);
      w->setAttribute(Qt::WA_DeleteOnClose);
      w->setWindowFlag(Qt::Window);
      w->show();
    } catch (const std::exception& e) {
      say(tr("The training database cannot be opened: %1").arg(QString::fromStdString(e.what())));
    }
  });
  connect(simulation_, &SimulationPanel::recordingRestarted, this, [this](const QString& text) {
    say(text);
    if (pages_.rehearse) pages_.rehearse->showRecording(true, text);
  });
  connect(simulation_, &SimulationPanel::recordingStopped, this, [this](const QString& why) {
    say(why);
    if (pages_.rehearse) pages_.rehearse->showRecording(false, why);
  });
  pages_.rehearse->setRecordHandlers({[this](const QString& trainee) { return startRecording(trainee); }, [this] { stopRecording(); },
                                      [this] { openReview(); }});
}

bool MainWindow::recording() const { return simulation_->recording(); }

QString MainWindow::caseFilePath() const { return doc_->path(); }

QString MainWindow::startRecording(const QString& trainee) {
  const QString path = doc_->path();
  if (path.isEmpty() || !path.endsWith(QStringLiteral(".rehearse"), Qt::CaseInsensitive))
    return tr("Save the case as a case file first (File > Save As, .rehearse): the rehearsal is recorded into it.");
  if (!doc_->hasCase() || !doc_->data()->hasPose) return tr("Register the organ first (steps 4 and 5): the rehearsal runs on the registered organ.");
  app::SessionMeta meta;
  meta.trainee = trainee.toStdString();
  meta.caseName = QFileInfo(path).fileName().toStdString();
  meta.sceneVersion = ("saved " + QFileInfo(path).lastModified().toUTC().toString(Qt::ISODate)).toStdString();
  meta.appVersion = REHEARSE_VERSION;
  const QString err = simulation_->startRecording(path, meta);
  if (!err.isEmpty()) return err;
  const QString text = tr("Recording%1 into %2 (the simulation started again from rest).")
                           .arg(trainee.isEmpty() ? QString() : tr(" %1").arg(trainee))
                           .arg(QFileInfo(path).fileName());
  pages_.rehearse->showRecording(true, text);
  say(text);
  return {};
}

void MainWindow::stopRecording() {
  if (!recording()) return;
  const qint64 id = simulation_->recordingId();
  simulation_->stopRecording();
  const QString text = tr("Recorded session %1 in %2; review it with Ctrl+Shift+R.").arg(id).arg(QFileInfo(doc_->path()).fileName());
  pages_.rehearse->showRecording(false, text);
  say(text);
  for (auto* review : findChildren<ReviewWindow*>()) review->refreshSessions();  // open review windows list it at once
}

ReviewWindow* MainWindow::openReview() {
  const QString path = doc_->path();
  if (path.isEmpty() || !QFileInfo::exists(path)) {
    say(tr("The case has no file yet: save it, record a rehearsal (step 7), then review it."));
    return nullptr;
  }
  std::optional<imaging::Camera> camera;
  cv::Mat3b frame;
  if (doc_->hasCase() && !doc_->data()->frame.empty() && doc_->data()->camera.problem().empty()) {
    camera = doc_->data()->camera;
    frame = doc_->data()->frame;
  }
  auto* w = new ReviewWindow(path, camera, frame, this);
  w->setAttribute(Qt::WA_DeleteOnClose);
  w->setWindowFlag(Qt::Window);
  w->show();
  return w;
}

// ------------------------------------------------------------------------------------------ messages

void MainWindow::say(const QString& text) {
  status_.caseText->setText(text);
  status_.caseText->setToolTip(text);
  if (!text.isEmpty()) messages_->appendPlainText(QDateTime::currentDateTime().toString(QStringLiteral("hh:mm:ss  ")) + text);
}

QString MainWindow::statusText() const { return status_.caseText->text(); }

QStringList MainWindow::messageLog() const { return messages_->toPlainText().split(QLatin1Char('\n'), Qt::SkipEmptyParts); }

// ------------------------------------------------------------------------------------------ loading

void MainWindow::setBusy(bool busy, const QString& message) {
  status_.progress->setVisible(busy);
  status_.stage->setVisible(busy);
  status_.cancel->setVisible(busy);
  if (busy) {
    status_.progress->setRange(0, 100);
    status_.progress->setValue(0);
    status_.stageText.clear();
    status_.clock.start();
    status_.tick->start();
    showProgress(0, {});
  } else {
    status_.tick->stop();
  }
  if (!message.isEmpty()) say(message);
}

void MainWindow::showProgress(double fraction, const QString& stage) {
  if (fraction < 0) {
    status_.progress->setRange(0, 0);  // busy: this stage's length is not known, its words say how far it got
  } else {
    status_.progress->setRange(0, 100);
    status_.progress->setValue(static_cast<int>(100 * fraction));
  }
  if (!stage.isEmpty()) status_.stageText = stage;
  const qint64 seconds = status_.clock.isValid() ? status_.clock.elapsed() / 1000 : 0;
  status_.stage->setText(status_.stageText.isEmpty() ? tr("%1 s").arg(seconds) : tr("%1 · %2 s").arg(status_.stageText).arg(seconds));
}

void MainWindow::openCase(const QString& path) {
  setBusy(true, path.isEmpty() ? tr("Generating the built-in phantom case...") : tr("Opening %1...").arg(path));
  doc_->open(path);
}

void MainWindow::cancelLoading() {
  doc_->cancelLoading();
  jobs_->cancel();
}

void MainWindow::onLoadFinished(bool ok, const QString& error) {
  setBusy(false);
  if (!ok) {
    say(error);  // the current case stays untouched
    emit caseLoaded(false);
    return;
  }
  for (StepPage* p : pages_.all) p->caseLoaded();
  showCaseInfo();
  view_->fitToWindow();
  const QString name = doc_->path().isEmpty() ? QString::fromStdString(doc_->data()->name) : QFileInfo(doc_->path()).fileName();
  setWindowTitle(tr("%1 - Rehearse").arg(name));
  say(tr("%1 loaded in %2 s").arg(name).arg(doc_->loadSeconds(), 0, 'f', 2) +
                            (doc_->notes().isEmpty() ? QString() : tr(" (%1 problems, see the Case panel)").arg(doc_->notes().size())));
  // Go to the first step that is not done yet.
  const int next = app::nextStep(*doc_->data());
  if (next < app::index(Step::Elastic)) setStep(static_cast<Step>(next));
  emit caseLoaded(true);
}

QString MainWindow::infoText() const { return info_->toPlainText(); }

void MainWindow::showCaseInfo() {
  if (doc_->data()) info_->setPlainText(caseInfoText(*doc_->data(), doc_->notes() + pages_.mesh->importNotes(), doc_->qualityText()));
}

void MainWindow::closeEvent(QCloseEvent* e) {
  cancelLoading();
  pages_.frame->stopCamera();
  jobs_->waitForFinished();
  // A clean exit leaves no autosave behind (after waiting for one being written): its presence at start
  // means the last session crashed.
  doc_->closeCleanly();
  QSettings settings;
  settings.setValue(QStringLiteral("window/geometry"), saveGeometry());
  settings.setValue(QStringLiteral("window/state"), saveState());
  e->accept();
}

}  // namespace rehearse::ui
