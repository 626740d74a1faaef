// The main window's docks, status bar and workflow panel (built once, by the constructor).
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/liveoverlay.hpp"
#include "rehearse/ui/recordingcontroller.hpp"

#include "rehearse/ui/caseinfo.hpp"
#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/organview.hpp"
#include "rehearse/ui/simulationpanel.hpp"
#include "rehearse/ui/steadybox.hpp"
#include "simulatedcase.hpp"

#include <QAction>
#include <QAbstractSlider>
#include <QComboBox>
#include <QAbstractSpinBox>
#include <QActionGroup>
#include <QCoreApplication>
#include <QCloseEvent>
#include <QDockWidget>
#include <QDragEnterEvent>
#include <QDateTime>
#include <QTextBlock>
#include <QTextDocument>
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
#include <QScrollArea>
#include <QScrollBar>
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

#include <algorithm>

#include "mainwindow_parts.hpp"

namespace rehearse::ui {

namespace {
// A status-bar label that never widens the bar: it shows as much of its sentence as fits, ending in an
// ellipsis, and the whole sentence in its tooltip (and in the Messages panel).
class SentenceLabel : public QLabel {
 public:
  explicit SentenceLabel(QWidget* parent = nullptr) : QLabel(parent) { setProperty("elidesItsText", true); }
  QSize minimumSizeHint() const override { return {200, QLabel::minimumSizeHint().height()}; }
  QSize sizeHint() const override {
    return {std::min(520, fontMetrics().horizontalAdvance(text()) + 8), QLabel::sizeHint().height()};
  }

 protected:
  void paintEvent(QPaintEvent*) override {
    QPainter p(this);
    const QRect r = contentsRect();
    p.setPen(palette().color(QPalette::WindowText));
    p.drawText(r, Qt::AlignLeft | Qt::AlignVCenter, fontMetrics().elidedText(text(), Qt::ElideRight, r.width()));
  }
};

// A status bar's short line: a short word as a QLabel asks for its whole width, a long sentence is elided and never
// asks more than `least` px of the window's least width; the whole sentence is its tooltip. The view mode (why the view
// is not composited: a stale estimate's sentence widened the window past the screen, MainWindow::setViewModeLine), the
// contour's distance and a job's stage (together they widened the window from 1600 to 1833 px on the patient liver
// while the appearance was estimated, and it stayed so: the same 12 px drag then pulled the tissue 7.2 mm, 9.7 mm on a
// loaded machine where the window had not widened yet).
class ShortLineLabel : public SentenceLabel {
 public:
  ShortLineLabel(int least, QWidget* parent) : SentenceLabel(parent), least_(least) {}
  QSize minimumSizeHint() const override {
    return {std::min(least_, fontMetrics().horizontalAdvance(text()) + 8), QLabel::minimumSizeHint().height()};
  }

 private:
  int least_;
};

// In a scrolled page the wheel scrolls the page: a spin box or a list box under the pointer takes it only once it has
// the keyboard focus (a click, Tab). A helper's scroll over the Simulation panel changed the jaw bite from 6 to 1 mm.
class WheelGuard : public QObject {
 public:
  using QObject::QObject;
  bool eventFilter(QObject* o, QEvent* e) override {
    if (e->type() != QEvent::Wheel) return false;
    auto* w = qobject_cast<QWidget*>(o);
    if (!w || w->hasFocus() || !w->parentWidget()) return false;
    QCoreApplication::sendEvent(w->parentWidget(), e);  // (passed up to the scroll area, as a wheel event is)
    return true;
  }
};
// A stack of pages whose height for a width is its shown page's: QStackedLayout answers the tallest page's, and a
// scroll area around it (which asks) scrolled step 3's page into 450 px of nothing.
class ShownPageStack : public QStackedWidget {
 public:
  using QStackedWidget::QStackedWidget;
  int heightForWidth(int w) const override {
    const QWidget* page = currentWidget();
    if (!page) return QStackedWidget::heightForWidth(w);
    const int h = page->hasHeightForWidth() ? page->heightForWidth(w) : page->minimumSizeHint().height();
    return std::max(h, minimumHeight());
  }
};

void guardWheel(QWidget* content) {
  auto* guard = new WheelGuard(content);
  for (QWidget* w : content->findChildren<QWidget*>())
    if (qobject_cast<QAbstractSpinBox*>(w) || qobject_cast<QComboBox*>(w) || qobject_cast<QAbstractSlider*>(w)) {
      w->setFocusPolicy(Qt::StrongFocus);  // (not the wheel's focus)
      w->installEventFilter(guard);
    }
}

// A dock's content in a scroll area (issue 62): on a laptop's screen (1280x800) a tall page scrolls instead of making
// the window taller than the screen or squeezing its widgets over each other. As wide as the content needs, so that only
// the height scrolls.
QScrollArea* scrolling(QWidget* content, QWidget* parent) {
  auto* area = new QScrollArea(parent);
  area->setObjectName(content->objectName() + QStringLiteral("Scroll"));
  area->setWidget(content);
  area->setWidgetResizable(true);
  area->setFrameShape(QFrame::NoFrame);
  area->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  area->setMinimumWidth(content->minimumSizeHint().width() + area->verticalScrollBar()->sizeHint().width());
  guardWheel(content);
  return area;
}
}  // namespace

// ---------------------------------------------------------------------------------------------- docks

void MainWindow::buildDocks() {
  QDockWidget* infoDock = buildCaseDocks();
  QDockWidget* organDock = buildOrganDock(infoDock);
  buildSimulationDock(organDock);
  connectSimulation();
}

QDockWidget* MainWindow::buildCaseDocks() {
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
  // Shown (its tab raised, Ctrl+L), the panel opens on the newest entry (it was laid out hidden, at the top).
  connect(messagesDock_, &QDockWidget::visibilityChanged, this, [this](bool visible) {
    if (visible)
      QTimer::singleShot(0, messages_, [this] {
        messages_->verticalScrollBar()->setValue(messages_->verticalScrollBar()->maximum());
      });
  });
  addDockWidget(Qt::RightDockWidgetArea, messagesDock_);
  tabifyDockWidget(infoDock, messagesDock_);
  infoDock->raise();
  return infoDock;
}

QDockWidget* MainWindow::buildOrganDock(QDockWidget* infoDock) {
  auto* organDock = new QDockWidget(tr("Organ 3D"), this);
  organDock->setObjectName(QStringLiteral("organDock"));
  const QString glRenderer = renderer() == Renderer::Software ? QString() : OrganGLView::openGLRenderer();
  bool openGL = !glRenderer.isEmpty();
  if (renderer() == Renderer::Software) {
    rendererText_ = tr("Views drawn on the CPU (--software).");
  } else if (!openGL) {
    rendererText_ = tr("No OpenGL 3.3 here: the views are drawn on the CPU.");
  } else if (renderer() == Renderer::Automatic && OrganGLView::isSoftwareRenderer(glRenderer)) {
    openGL = false;
    rendererText_ =
        tr("OpenGL here is a software rasteriser (%1): the views are drawn on the CPU, which is faster on it "
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
  if (openGL)
    centreOrgan_ = new OrganGLView(centre_);
  else
    centreOrgan_ = new OrganView(centre_);
  centreOrgan_->setObjectName(QStringLiteral("centreOrganView"));
  centre_->addWidget(centreOrgan_);
  return organDock;
}

void MainWindow::buildSimulationDock(QDockWidget* organDock) {
  simulationDock_ = new QDockWidget(tr("Simulation"), this);
  simulationDock_->setObjectName(QStringLiteral("simulationDock"));
  simulation_ = new SimulationPanel(simulationDock_);
  simulation_->setObjectName(QStringLiteral("simulationPanel"));
  simulationDock_->setWidget(scrolling(simulation_, simulationDock_));
  addDockWidget(Qt::RightDockWidgetArea, simulationDock_);
  tabifyDockWidget(organDock, simulationDock_);
  organDock->raise();
}

void MainWindow::connectSimulation() {
  connect(simulation_, &SimulationPanel::statusChanged, this, [this](const QString& text) {
    status_.simulation->setText(text);
    status_.simulation->setToolTip(text);  // the whole sentence (the bar shows what fits)
  });
  // (The panel shows the start's first lines and t = 0 only until the first step; a person read it cut off.)
  connect(simulation_, &SimulationPanel::startSaid, this, [this](const QString& words) { logMessage(words); });
  liveOverlay_ = new LiveOverlay(view_, this);
  connect(liveOverlay_, &LiveOverlay::drawn, this,
          [this](const OverlayPicture& picture, const std::shared_ptr<const app::Organ>& organ) {
            if (step_ == Step::Rehearse && !showingComposited() && doc_->data() && doc_->data()->organ == organ) {
              picture_ = picture;
              showFrameLayer();
            }
          });
  // The composited view follows the simulation: each snapshot shown is composed (on a worker, newest first).
  connect(simulation_, &SimulationPanel::frameShown, this, [this] { showSimulationFrame(); });
  connect(composition_, &Composition::composed, this, [this] {
    if (showingComposited()) showFrameLayer();
  });
  connect(composition_, &Composition::readyChanged, this, [this](bool ready) {
    // The composited view is the case's view from the moment it can be made.
    if (ready)
      setViewMode(ViewMode::Composited);
    else
      showFrameLayer();
  });
  connect(simulation_, &SimulationPanel::materialEdited, this, [this](const app::MaterialSettings& m) {
    // Named by what changed (the history and Undo's label read it).
    if (!doc_->data()) return;
    const app::MaterialSettings was = doc_->data()->material;
    app::MaterialSettings only = was;
    QString what = tr("Edit material");
    only.supportModulus = m.supportModulus;
    if (only == m && m.supportModulus != was.supportModulus) what = tr("Change support");
    only = was;
    only.gravity = m.gravity;
    if (only == m && m.gravity != was.gravity) what = tr("Change gravity");
    doc_->edit(what, [m](app::Case& k) { k.material = m; });
  });
}

void MainWindow::showSimulationFrame() {
  const auto f = simulation_->lastFrame();
  // After Reset, the frames of steps taken before it are not shown (the view holds the organ at rest); the Reset's own
  // frame, at step 0, ends them (every frame published reaches here, in order).
  if (f && view_->property(kFramesBeforeReset).toBool()) {
    if (f->steps > 0) return;
    view_->setProperty(kFramesBeforeReset, false);
  }
  if (pages_.rehearse) pages_.rehearse->showFrame(f);
  // What happened in the rehearsal (a slip, a vessel cut, a refused edit) is kept in the Messages panel, once each
  // (a slip's sentence the page has just said in the status bar is there already: it was logged twice).
  if (f && !f->message.isEmpty() && f->message != lastSimulationMessage_ &&
      !messages_->document()->lastBlock().text().endsWith(f->message)) {
    logMessage(tr("Simulation (step %1): %2").arg(f->steps).arg(f->message));  // (scrolled to: a person's check)
  }
  if (f) lastSimulationMessage_ = f->message;
  if (f && f->organ && doc_->data() && f->organ->organ == doc_->data()->organ) {
    view_->setWarning(f->invertedAt, warningText(*f));
    view_->setLiveShape(f->positions);
    view_->setShaftRadius(f->toolRadius);
    view_->setTrocar(f->trocar.allFinite() && f->trocar.norm() > 0 ? std::optional<Eigen::Vector3d>(f->trocar)
                                                                     : std::nullopt);
    view_->setLiveSurface(f->surface);
    view_->setLiveField(f->field, f->gravity, f->labels, f->tets);
    view_->setLiveJaws(f->tool.jawClosed, !f->tool.held.empty());
    view_->followHook(f->steps, f->tool.tip, f->tool.present, f->field.energy,
                      simcore::CauterySettings{}.radius,  // (the GUI's hook has the default radius)
                      f->field.energyTime);
    if (f->surface && showingComposited() && f->surface != lastCutComposited_) {
      // The composited view draws the cut organ (its cut faces in preset interior colours): said once per cut.
      lastCutComposited_ = f->surface;
      statusBar()->showMessage(
          tr("The organ is cut: the composited view draws its cut mesh's boundary; cut faces take preset interior "
             "colours (parenchyma, a vessel's blood, other structures), not colours estimated from this frame."),
          8000);
    }
    // While rehearsing in the overlay view, the organ drawn over the frame follows the simulation: drawn on a
    // worker (newest first), at most 60 times a second and only once the last drawing was painted.
    if (step_ == Step::Rehearse && !showingComposited()) {
      LiveOverlay::Job job;
      job.c = doc_->data();
      job.surface = f->surface;
      job.inner = pages_.mesh->shownInnerLabels();
      job.tets = f->tets;
      job.labels = f->labels;
      job.positions = f->positions;  // the case with these nodes is made on the worker (not at 100 Hz here)
      liveOverlay_->request(std::move(job));
    }
    // The 3D view (F4) while rehearsing shows the organ as simulated, not at rest (uncut: a cut organ's new nodes are
    // not the case's; the view then says it shows the organ at rest).
    if (step_ == Step::Rehearse && viewMode_ == ViewMode::ThreeD) {
      if (!f->surface && f->positions.size() == doc_->data()->organ->volume.points.size())
        showInOrganView(centreOrgan_, std::make_shared<const app::Case>(simulatedCase(*doc_->data(), f->positions)));
      else
        showInOrganView(centreOrgan_, doc_->data());
      setViewModeLine(viewModeText());
    }
  } else {
    view_->setWarning({}, {});  // another organ's frame (or none): its warning is not this organ's
  }
  if (showingComposited() && f && f->organ && doc_->data() && f->organ->organ == doc_->data()->organ)
    composition_->request(f->positions, f->surface);
}

void MainWindow::buildStatusBar() {
  setStatusBar(new ElidingStatusBar(this));  // a long message ends in an ellipsis, not cut against the simulation's line
  status_.progress = new QProgressBar(this);
  status_.progress->setRange(0, 100);
  status_.progress->setMaximumWidth(260);
  status_.progress->setVisible(false);
  status_.progress->setTextVisible(true);
  status_.progress->setFormat(QStringLiteral("%p%"));
  status_.stage = new ShortLineLabel(120, this);
  status_.stage->setObjectName(QStringLiteral("progressStage"));
  status_.stage->setMaximumWidth(400);
  status_.stage->setVisible(false);
  status_.tick = new QTimer(this);
  status_.tick->setInterval(1000);
  connect(status_.tick, &QTimer::timeout, this,
          [this] { showProgress(status_.progress->maximum() == 0 ? -1 : status_.progress->value() / 100.0, {}); });
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
  status_.cursor->setObjectName(QStringLiteral("statusCursor"));
  // The simulation's line is bounded (elided, whole in its tooltip) so that the case's sentence keeps its room.
  status_.simulation = new SentenceLabel(this);
  status_.simulation->setObjectName(QStringLiteral("statusSimulation"));
  status_.simulation->setMaximumWidth(520);
  status_.distance = new ShortLineLabel(120, this);
  status_.distance->setObjectName(QStringLiteral("statusDistance"));
  status_.distance->setMaximumWidth(460);
  status_.viewMode = new ShortLineLabel(90, this);
  status_.viewMode->setObjectName(QStringLiteral("statusViewMode"));
  status_.viewMode->setMaximumWidth(360);
  statusBar()->addWidget(status_.caseText, 1);
  statusBar()->addWidget(log);
  // The simulation's sentence (15 times a second), the distance and the cursor's pixel (at each mouse move, in every
  // drag) change often: in SteadyBoxes they lay out the window again only when they need more room.
  statusBar()->addPermanentWidget(new SteadyBox(status_.simulation, this));
  statusBar()->addPermanentWidget(new SteadyBox(status_.distance, this));
  statusBar()->addPermanentWidget(status_.viewMode);
  statusBar()->addPermanentWidget(new SteadyBox(status_.cursor, this));
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
  workflow_->setAccessibleName(tr("Workflow steps"));
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
    if (row >= 0 && row < app::kStepCount && app::kSteps[static_cast<std::size_t>(row)].available)
      setStep(static_cast<Step>(row));
  });
  layout->addWidget(workflow_);
  stepStack_ = new ShownPageStack(host);
  pages_.mesh = new MeshPage(wb_);
  pages_.frame = new FramePage(wb_);
  pages_.contour = new ContourPage(wb_);
  pages_.rigid = new RigidPage(wb_);
  pages_.fit = new FitPage(wb_);
  pages_.appearance = new AppearancePage(wb_, composition_);
  pages_.rehearse = new RehearsePage(wb_);
  pages_.rehearse->setForceLoop([this] { return simulation_ ? simulation_->forceLoop() : nullptr; });
  connect(simulation_, &SimulationPanel::wasReset, pages_.rehearse, &RehearsePage::forgetForceHistory);
  connect(simulation_, &SimulationPanel::sessionReplaced, pages_.rehearse, &RehearsePage::forgetForceHistory);
  pages_.all = {pages_.mesh, pages_.frame,      pages_.contour, pages_.rigid,
                pages_.fit,  pages_.appearance, pages_.rehearse};
  for (StepPage* p : pages_.all) stepStack_->addWidget(p);
  connect(pages_.mesh, &MeshPage::meshImported, this, &MainWindow::meshImported);
  connect(pages_.mesh, &MeshPage::shownLabelsChanged, this, &MainWindow::refreshOverlay);
  connect(pages_.mesh, &MeshPage::importNotesChanged, this, &MainWindow::showCaseInfo);
  connect(pages_.frame, &FramePage::frameSourceOpened, this, &MainWindow::frameSourceOpened);
  connect(pages_.frame, &FramePage::videoFrameShown, this, &MainWindow::videoFrameShown);
  // Only the page shown counts for the stack's size (a stack is as tall as its tallest page otherwise), and it scrolls.
  stepStack_->setObjectName(QStringLiteral("stepPages"));
  // The scroll area is as wide as the page shown needs (only the height scrolls: pages were cut off on the right).
  auto* pageScroll = scrolling(stepStack_, host);
  auto fitToPage = [this, pageScroll](int shown) {
    for (int i = 0; i < stepStack_->count(); ++i)
      stepStack_->widget(i)->setSizePolicy(i == shown ? QSizePolicy::Preferred : QSizePolicy::Ignored,
                                           i == shown ? QSizePolicy::Preferred : QSizePolicy::Ignored);
    stepStack_->adjustSize();
    pageScroll->verticalScrollBar()->setValue(0);  // a step's page opens at its top (not where the last one was scrolled)
    if (QWidget* page = stepStack_->widget(shown))
      pageScroll->setMinimumWidth(page->minimumSizeHint().width() + pageScroll->verticalScrollBar()->sizeHint().width());
  };
  connect(stepStack_, &QStackedWidget::currentChanged, this, fitToPage);
  fitToPage(stepStack_->currentIndex());
  layout->addWidget(pageScroll, 1);
  dock->setWidget(host);
  dock->setMinimumWidth(330);
  addDockWidget(Qt::LeftDockWidgetArea, dock);
}

}  // namespace rehearse::ui

