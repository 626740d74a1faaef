#include "rehearse/ui/mainwindow.hpp"
#include "simulatedcase.hpp"
#include "rehearse/ui/crashreport.hpp"
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/labelimage.hpp>
#include "rehearse/ui/liveoverlay.hpp"
#include "rehearse/ui/recordingcontroller.hpp"

#include "rehearse/ui/caseinfo.hpp"
#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/organview.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <QAction>
#include <QActionGroup>
#include <QCoreApplication>
#include <QCursor>
#include <QGuiApplication>
#include <QMouseEvent>
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
#include <QScrollBar>
#include <QScreen>
#include <QLocale>
#include <QDir>
#include <QPainter>
#include <QProgressBar>
#include <QPushButton>
#include <QSettings>
#include <QStackedWidget>
#include <QStatusBar>
#include <QStyle>
#include <QTimer>
#include <QFutureWatcher>
#include <QtConcurrent/QtConcurrentRun>
#include <QToolBar>
#include <QToolButton>
#include <QUndoStack>
#include <QVBoxLayout>

#include "mainwindow_parts.hpp"
namespace rehearse::ui {

namespace {

MainWindow::Renderer& rendererChoice() {
  static MainWindow::Renderer choice = MainWindow::Renderer::Automatic;
  return choice;
}

}  // namespace

// The workflow's step titles (app::kSteps, which has no Qt) for translators: lupdate finds them here.
[[maybe_unused]] const char* const kStepTitlesToTranslate[] = {
    QT_TRANSLATE_NOOP("Step", "Organ mesh"),  QT_TRANSLATE_NOOP("Step", "Endoscope frame"),
    QT_TRANSLATE_NOOP("Step", "Contour"),     QT_TRANSLATE_NOOP("Step", "Rigid alignment"),
    QT_TRANSLATE_NOOP("Step", "Elastic fit"), QT_TRANSLATE_NOOP("Step", "Appearance"),
    QT_TRANSLATE_NOOP("Step", "Rehearse")};

QString stepName(int i) {
  return QStringLiteral("%1  %2").arg(i + 1).arg(
      QCoreApplication::translate("Step", app::kSteps[static_cast<std::size_t>(i)].title));
}

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
  wb_.log = [this](const QString& text) { logMessage(text); };
  wb_.goToStep = [this](Step s) { setStep(s); };
  wb_.endRehearsal = [this](const QString& doing, std::function<void()> then, std::function<void()> otherwise) {
    askToEndRehearsal(
        doing,
        [this, then = std::move(then)] {
          if (!simulation_->unkeptWork().isEmpty()) simulation_->reset();  // ended now: what follows does not ask again
          then();
        },
        std::move(otherwise));
  };
  wb_.currentStep = [this] { return step_; };
  keys_ = std::make_unique<StepKeys>(this, wb_.currentStep);
  wb_.keys = keys_.get();
  buildWorkflowPanel();
  buildMenus();

  connect(view_, &FrameView::cursorMoved, this, [this](QPointF p) {
    status_.cursor->setText(tr("u %1  v %2 px").arg(p.x(), 0, 'f', 1).arg(p.y(), 0, 'f', 1));
  });
  // (a person's check found the last pixel still read out after the pointer had left the frame)
  connect(view_, &FrameView::cursorLeft, this, [this] { status_.cursor->clear(); });
  connect(view_, &FrameView::contourEdited, this, [this](const imaging::Contour& c, const QString& text, int merge) {
    // (the second frame's outline while it is shown)
    const bool second = view_->secondFrameShown();
    doc_->edit(
        text, [&c, second](app::Case& k) { (second ? k.contour2 : k.contour) = c; }, merge);
  });
  connect(view_, &FrameView::shownFrameChanged, this, [this] { refreshOverlay(); });
  connect(view_, &FrameView::poseEdited, this, [this](const Pose& p, const QString& text, int merge) {
    doc_->edit(
        text,
        [&p](app::Case& k) {
          k.pose = p;
          k.hasPose = true;
          k.poseAligned = true;
        },
        merge);
  });
  // A slip's sentence goes into the case's line (RehearsePage) and stayed there: under the next grasp's 10 s hint
  // while the jaws held again, and after Reset, as if the tissue had just slipped (a person's check). A new bite, or
  // Reset, replaces it. (The session's sentence, in simcore's words: not translated.)
  const auto forgetSlip = [this](const QString& now, Said what = Said::Other) {
    if (!status_.caseText->text().contains(QLatin1String("slipped out of the grasper"))) return;
    status_.caseText->setText(now);
    status_.caseText->setToolTip(now);
    said_ = what;
  };
  connect(view_, &FrameView::instrumentInput, this, [this, forgetSlip](const simcore::InputEvent& e) {
    if (!simulation_->post(e))
      say(tr("The simulation is not ready yet; the grasp did nothing (the organ needs a mesh and a pose)."));
    else if (e.kind == simcore::InputKind::Jaw && e.on)
      forgetSlip(tr("Grasped: drag to pull, release to let go."), Said::Grasped);
    // ... and the jaws opened end that line (a person read "Grasped: drag to pull" after letting go).
    else if (e.kind == simcore::InputKind::Jaw && said_ == Said::Grasped)
      say(QString());
    // Another instrument at work ends the slip's news too (a helper read "The tissue slipped out of..." 30 s after
    // placing a clip).
    else if (((e.kind == simcore::InputKind::Cut || e.kind == simcore::InputKind::Energy) && e.on) ||
             e.kind == simcore::InputKind::Clip)
      forgetSlip(QString());
  });
  connect(simulation_, &SimulationPanel::wasReset, view_, &FrameView::endGesture);
  // Play, Step and Reset clicked: the keys back to the frame, where the instruments work (Space closes the jaws).
  connect(simulation_, &SimulationPanel::keysBack, this, [this] {
    if (viewMode_ != ViewMode::ThreeD && view_->isVisible()) view_->setFocus();
  });
  // Play taken on the Simulation panel outside step 7 (a person pressed it in step 4 and the status bar still said the
  // rehearsal was paused): it plays there, in the panel's view.
  connect(simulation_, &SimulationPanel::playingChanged, this, [this](bool playing) {
    if (step_ == Step::Rehearse) {
      if (saysPausedOutside()) say(QString());  // (in step 7 Play and Pause show themselves)
    } else if (playing && said_ == Said::PausedOutside) {
      sayAs(Said::PlaysInPanel,
            tr("The rehearsal plays in the Simulation panel's view; the frame shows the case's organ until step 7."));
    } else if (!playing && said_ == Said::PlaysInPanel) {
      // ... and paused there again, it says so (the line had stayed "plays" under a paused clock).
      sayAs(Said::PausedInPanel, tr("The rehearsal is paused; step 7 plays it again."));
    }
  });
  // An instrument used on the paused rehearsal plays it (its input is applied at the next step): said, once per
  // pause (a person's check: a release while paused set the organ moving without a word).
  connect(simulation_, &SimulationPanel::playedByInput, this, [this] {
    if (step_ != Step::Rehearse) return;
    resumedByInput_.start();
    sayBriefly(tr("Playing again: an instrument used on the paused rehearsal plays it (F5 pauses it)."));
  });
  // Logged (a person's check found no Reset in the Messages panel; a recording's own sentence follows it), and said in
  // the status bar with what it waits for (Reset mid-grasp left the organ still, the drag after it moving nothing, and
  // nothing said so).
  // (Reset always leaves the organ paused: SimulationPanel::reset.)
  connect(simulation_, &SimulationPanel::wasReset, this, [this, forgetSlip] {
    // The organ is back at rest from now on: an instrument pressed at once bites it there (the case's shape), not where
    // the last frame before the Reset showed it. Frames of steps taken before the Reset, still on their way (the step
    // under way when Reset was pressed ends first: 0.2-0.4 s on a slow step), are not shown over it: they end at the
    // Reset's own frame, at step 0 (showSimulationFrame). A person pressed within that time and the jaws "closed on
    // nothing" where the tissue had been.
    view_->clearLive();
    view_->setProperty(kFramesBeforeReset, true);
    const QString said = tr("Reset: the organ is back at rest, as the frame shows it, and waits: press on it with an "
                            "instrument, or F5, to go on.");
    sayBriefly(said);
    forgetSlip(said);
  });
  // Another organ (a mesh imported, the organ moved, other attachments): the old session's organ, its cut, blood,
  // clips and warnings leave the frame view at once. (A helper imported the patient liver over the phantom's rehearsal:
  // the phantom's bleeding stayed drawn over the real frame, no session of the new organ to replace it.)
  connect(simulation_, &SimulationPanel::sessionReplaced, view_, &FrameView::clearLive);
  connect(view_, &FrameView::toolMessage, this, [this](const QString& text) {
    // The first hint after an instrument played the paused rehearsal says that too (helper-64: "Grasped: ..." took the
    // status bar at once, and the resume was said only in the Messages panel).
    const bool resumed = resumedByInput_.isValid() && resumedByInput_.elapsed() < 2000;
    resumedByInput_.invalidate();
    statusBar()->showMessage(resumed ? tr("Playing again (it was paused). %1").arg(text) : text, 10000);
  });
  connect(view_, &FrameView::attachmentsEdited, this, [this](const std::vector<int>& nodes, const QString& text) {
    doc_->edit(text, [&](app::Case& k) { k.attachments = nodes; });
  });
  connect(jobs_, &JobRunner::busyChanged, this, &MainWindow::setBusy);
  connect(jobs_, &JobRunner::refused, this, &MainWindow::say);
  connect(doc_, &CaseDocument::changed, this, &MainWindow::onCaseChanged);
  doc_->setGuard([this](const app::Case& before, const app::Case& after, const QString& what,
                        std::function<void()> proceed) {
    if (!simulation_ || simulation_->unkeptWork().isEmpty() || !simulation_->startsAnew(before, after)) return true;
    askToEndRehearsal(what, std::move(proceed));  // (asks: there is a rehearsal to end)
    return false;
  });
  connect(doc_, &CaseDocument::loaded, this, &MainWindow::onLoadFinished);
  connect(doc_, &CaseDocument::progress, this, &MainWindow::showProgress);
  connect(jobs_, &JobRunner::progress, this, &MainWindow::showProgress);
  connect(doc_, &CaseDocument::modifiedChanged, this, [this] { updateTitle(); });
  connect(doc_, &CaseDocument::autosaved, this, [this] {
    if (recoverAction_) recoverAction_->setEnabled(doc_->autosaveNewerThanCase());
  });
  connect(doc_, &CaseDocument::saved, this, [this](bool ok, const QString& message) {
    if (ok) updateTitle();
    // A recording goes on into the file as saved (or, when the save failed, into the file it was in).
    if (!doc_->isSaving()) simulation_->caseFileReplaced(doc_->path());
    say(message);
    emit caseSaved(ok, ok ? QString() : message);
  });
  connect(doc_, &CaseDocument::recentFilesChanged, this, &MainWindow::rebuildRecentMenu);
  // A save keeps the precomputed model's responses with the case (built again only when what they depend on changed).
  doc_->setResponseKeySource([this]() -> std::uint64_t { return simulation_ ? simulation_->responseKey() : 0; });
  setAcceptDrops(true);

  QSettings settings;
  if (!restoreGeometry(settings.value(QStringLiteral("window/geometry")).toByteArray())) {
    resize(1600, 900);
  } else if (screen()) {
    // Restored whole on the screen it is on (issue 62: a second launch came back 12 px below the screen's bottom,
    // the status bar out of sight).
    const QRect room = screen()->availableGeometry();
    QRect g = geometry();
    g.setSize(g.size().boundedTo(room.size()));
    if (g.bottom() > room.bottom()) g.moveBottom(room.bottom());
    if (g.right() > room.right()) g.moveRight(room.right());
    if (g.top() < room.top()) g.moveTop(room.top());
    if (g.left() < room.left()) g.moveLeft(room.left());
    setGeometry(g);
  }
  auto* workflow = findChild<QDockWidget*>(QStringLiteral("workflowDock"));
  auto* organ = findChild<QDockWidget*>(QStringLiteral("organDock"));
  if (!restoreState(settings.value(QStringLiteral("window/state")).toByteArray())) {
    // A first start: the frame gets the room. The docks are given their widths here, so that a long text in one of
    // them later (a status, a refusal) does not widen its area and squeeze the frame to its minimum.
    if (workflow && organ) resizeDocks({workflow, organ}, {470, 400}, Qt::Horizontal);
  } else if (workflow && organ) {
    // A later start keeps the layout the person left, but not a frame squeezed by a dock a long text widened in the
    // last session (issue 62: the left dock came back 580 px wide and the frame 490 px of 1600): the frame keeps at
    // least a third of the window (a first start gives it 45 %), the docks back to their first widths when it would
    // not. (Two fifths left a person 66 px to drag at 1600 px, the right dock at its least width: helper-65.)
    // The docks' widths as they were left are given again once the window is laid out at its size: restoreState
    // alone, applied before, brought a left dock dragged to 513 px back at 437 (helper-64). Whether the frame keeps its
    // third is judged from those widths (the frame's own width is the old one until the layout runs again: judged from
    // it, a frame left at 320 of 1600 px came back so at every launch, helper-65).
    const QList<int> left = {settings.value(QStringLiteral("window/workflowWidth"), 0).toInt(),
                             settings.value(QStringLiteral("window/organWidth"), 0).toInt()};
    QTimer::singleShot(0, this, [this, workflow, organ, left] {
      const bool docked = workflow->isVisible() && organ->isVisible() && !workflow->isFloating() && !organ->isFloating();
      const int separators = 2 * style()->pixelMetric(QStyle::PM_DockWidgetSeparatorExtent, nullptr, this);
      const int frame = docked && left[0] > 0 && left[1] > 0 ? width() - left[0] - left[1] - separators
                                                             : (centralWidget() ? centralWidget()->width() : width());
      if (frame < width() / 3) {
        const double share = std::min(1.0, width() / 1600.0);  // a first start's widths at 1600 px, narrower below
        resizeDocks({workflow, organ}, {static_cast<int>(470 * share), static_cast<int>(400 * share)}, Qt::Horizontal);
      } else if (docked && left[0] > 0 && left[1] > 0) {
        resizeDocks({workflow, organ}, left, Qt::Horizontal);
      }
    });
  }
  setStep(Step::Mesh);
}

MainWindow::~MainWindow() {
  jobs_->cancel();
  pages_.frame->stopCamera();
  jobs_->waitForFinished();
}

void MainWindow::setRenderer(Renderer r) {
  rendererChoice() = r;
}

MainWindow::Renderer MainWindow::renderer() {
  return rendererChoice();
}

QWidget* MainWindow::organWidget() const {
  if (organGLView_) return organGLView_;
  return organView_;
}

// ------------------------------------------------------------------------------------------- workflow

void MainWindow::setStep(Step s) {
  const Step left = step_;
  step_ = s;
  view_->setRehearsing(s == Step::Rehearse);
  if (left == Step::Rehearse && s != Step::Rehearse && isInstrument(view_->tool())) lastInstrument_ = view_->tool();
  crash::setActivity(activity());
  keys_->stepShown(s);
  if (s != Step::Contour) view_->setSecondFrameShown(false);  // (the second frame is sketched on in step 3 only)
  const int row = app::index(s);
  for (int i = 0; i < static_cast<int>(pages_.all.size()); ++i)
    if (pages_.all[static_cast<std::size_t>(i)]->step() == s) stepStack_->setCurrentIndex(i);
  if (workflow_->currentRow() != row) workflow_->setCurrentRow(row);
  // Each step's default tool (a tool of another step does not stay active on this one).
  const Tool t = view_->tool();
  if (s == Step::Contour && (t == Tool::Navigate || t == Tool::Align || t == Tool::Landmarks))
    view_->setTool(Tool::Freehand);
  else if (s == Step::Rigid && t != Tool::Landmarks)
    view_->setTool(Tool::Align);
  else if (s == Step::Mesh || s == Step::Frame)
    view_->setTool(Tool::Navigate);
  else if ((s == Step::Elastic || s == Step::Appearance) && (t == Tool::Align || t == Tool::Landmarks))
    view_->setTool(Tool::Navigate);  // no gizmo over the fit
  else if (s == Step::Rehearse) {
    // The instrument in hand when step 7 was left (a person came back from step 4 to the grasper, not the scissors).
    if (!isInstrument(t)) view_->setTool(lastInstrument_);
    // The organ is rehearsed on live: it settles on its ligaments before the first grasp.
    if (doc_->hasCase() && doc_->data()->hasPose && !simulation_->isPlaying()) simulation_->play();
  }
  if (s != Step::Rehearse && isInstrument(view_->tool())) view_->setTool(Tool::Navigate);
  // Leaving the rehearsal pauses it, as entering it plays it: the other steps show the case's organ, not the
  // simulation's, and its steps took a core from the mesher and the fits (a person saw its clock run in step 1).
  if (left == Step::Rehearse && s != Step::Rehearse && simulation_ && simulation_->isPlaying()) {
    simulation_->pause();
    // One step more, so that what leaving asked is applied before it stands still: the instrument taken from the hand
    // above let go (the jaws open, the blade lifts). Paused first, the jaws' opening had waited for step 7 again, the
    // organ held where the jaws had it (a race: test_appearance_gui graspPullCut failed once on it).
    simulation_->stepOnce();
    sayAs(Said::PausedOutside,
          tr("The rehearsal is paused outside step 7 (the other steps show the case's organ); step 7 plays it again."));
  }
  // Back in step 7 those sentences are over (a person read "paused outside step 7" there while it played); and an undo's
  // or redo's sentence is over on another step (a person read "Undone: Attach 2 nodes" in step 7).
  if ((s == Step::Rehearse && saysPausedOutside()) || (s != left && said_ == Said::UndoneOrRedone)) say(QString());
  if (s != Step::Rehearse && doc_->hasCase()) {
    refreshOverlay();  // the case's organ again, not the simulation's
    showInOrganView(centreOrgan_, doc_->data());
  }
  updateWorkflow();
}

bool MainWindow::saysPausedOutside() const {
  return said_ == Said::PausedOutside || said_ == Said::PlaysInPanel || said_ == Said::PausedInPanel;
}

bool MainWindow::stepDone(Step s) const {
  return doc_->hasCase() && app::stepDone(*doc_->data(), s);
}

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
    if (info.available && stepDone(info.step))
      text += QStringLiteral("   \u2713");
    else if (i == next)
      text += tr("   (next)");
    item->setText(text);
  }
}

void MainWindow::onCaseChanged(CaseDocument::Parts parts) {
  const auto& data = doc_->data();
  view_->setCase(data);
  if (organView_) organView_->setCase(data);
  if (organGLView_) organGLView_->setCase(data);
  simulation_->setCase(data);
  showInOrganView(centreOrgan_, data);
  composition_->setCase(data);
  if (data)
    for (StepPage* p : pages_.all) p->refresh(*data);
  refreshOverlay();
  showCaseInfo();
  updateTitle();  // (the name may change with an edit: an organ imported into the built-in case names it)
  updateWorkflow();
}

void MainWindow::showFrameLayer() {
  // Hiding the organ (O) in the composited view shows the frame as captured: the organ is drawn into that picture.
  if (view_->secondFrameShown() && doc_->hasCase() && !doc_->data()->frame2.empty()) {
    // The second frame, its outline sketched over it; the organ is not drawn (the motion to it is the fit's).
    view_->setFrame(doc_->secondFrameImage());
    view_->setOverlay(QImage(), {});
    view_->setInnerOverlay(QImage());
    setViewModeLine(tr("Second frame"));
    return;
  }
  const bool composited = showingComposited() && !composition_->lastComposed().isNull() && view_->overlayVisible();
  if (composited)
    view_->setFrame(composition_->lastComposed(), composition_->lastScaled());
  else
    view_->setFrame(doc_->frameImage());
  // The composition's worker scales the frames it makes to the view's size (the GUI thread then only draws them).
  composition_->setViewScale(showingComposited() ? view_->frameSizeInView() : QSize());
  if (composited) {
    view_->setOverlay(QImage(), {});
    view_->setInnerOverlay(QImage());
  } else {
    view_->setOverlay(picture_.organ, picture_.silhouette);
    view_->setInnerOverlay(picture_.inner, picture_.innerKey);
  }
  setViewModeLine(viewModeText());
  checkShownViewMode();
}

void MainWindow::setViewModeLine(const QString& text) {
  // Elided where it is longer than its room (a person's check saw a stale estimate's sentence widen the window past the
  // screen), whole in its tooltip.
  status_.viewMode->setText(text);
  status_.viewMode->setToolTip(text);
}

void MainWindow::checkShownViewMode() {
  // The button pressed is the view shown: the composited view asked for while it cannot be made (no appearance yet,
  // or its estimate undone) shows the overlay, and the Overlay button says so; it comes back when the composition can
  // be made (Composition::readyChanged). (Checking an action does not trigger it: the mode asked for stays.)
  const ViewMode shown = viewMode_ == ViewMode::Composited && !composition_->ready() ? ViewMode::Overlay : viewMode_;
  const auto i = static_cast<std::size_t>(shown);
  if (i < viewModeActions_.size() && !viewModeActions_[i]->isChecked()) viewModeActions_[i]->setChecked(true);
}

QString MainWindow::viewModeText() const {
  switch (viewMode_) {
    case ViewMode::Composited:
      return composition_->ready() ? (composition_->usesOpenGL() ? tr("Composited (OpenGL)") : tr("Composited"))
                                   : tr("Overlay, not composited: %1").arg(composition_->whyNot());
    case ViewMode::Overlay:
      return tr("Overlay");
    case ViewMode::ThreeD:
      if (step_ == Step::Rehearse)
        if (const auto f = simulation_->lastFrame(); f && f->surface)
          return tr("3D: the organ at rest (the cut organ is drawn in the composited and overlay views, F2 and F3)");
      return tr("3D");
  }
  return {};
}

void MainWindow::setViewMode(ViewMode mode) {
  if (mode == ViewMode::ThreeD && viewMode_ != ViewMode::ThreeD && (QGuiApplication::mouseButtons() & Qt::LeftButton)) {
    // A drag on the frame ends where the frame view goes out of sight (the button's release would reach the 3D view,
    // and the grasper kept holding, pulling the tissue with the next moves of the mouse without a button): ended as
    // its release ends it.
    const QPoint at = view_->mapFromGlobal(QCursor::pos());
    QMouseEvent release(QEvent::MouseButtonRelease, QPointF(at), QPointF(QCursor::pos()), Qt::LeftButton,
                        QGuiApplication::mouseButtons() & ~Qt::LeftButton, QGuiApplication::keyboardModifiers());
    QCoreApplication::sendEvent(view_, &release);
  }
  viewMode_ = mode;
  centre_->setCurrentIndex(mode == ViewMode::ThreeD ? 1 : 0);
  if (mode == ViewMode::Composited && composition_->ready()) {
    // Follow the simulation from where it is now.
    const auto f = simulation_->lastFrame();
    composition_->request(f && f->organ && doc_->data() && f->organ->organ == doc_->data()->organ
                              ? f->positions
                              : std::vector<Eigen::Vector3d>{});
  }
  // While rehearsing, the view shown follows the simulation from where it is now (the overlay and the 3D view too: they
  // showed the last shape drawn in them, at rest when they had not been shown since the start).
  if (step_ == Step::Rehearse && simulation_->lastFrame()) showSimulationFrame();
  showFrameLayer();
  checkShownViewMode();
  if (mode == ViewMode::Composited && !composition_->ready())
    say(tr("The composited view needs the appearance: %1.").arg(composition_->whyNot()));
  // The 3D view takes no instrument: said when it is taken with one in hand in step 7 (a person pressed on the organ
  // there with the grasper and nothing happened, nothing said).
  // (Short, so that the status bar shows it whole; ended when the frame is back.)
  if (mode == ViewMode::ThreeD && step_ == Step::Rehearse && isInstrument(view_->tool()))
    sayAs(Said::InstrumentsOnTheFrame, tr("The 3D view turns the organ; the instruments work on the frame (F2, F3)."));
  else if (mode != ViewMode::ThreeD && said_ == Said::InstrumentsOnTheFrame)
    say(QString());
}

void MainWindow::refreshOverlay() {
  const auto& c = doc_->data();
  // (not drawn over the second frame: not rendered while it is shown; shown again, the first frame renders it)
  picture_ = c && !view_->secondFrameShown() ? overlay_->render(*c, pages_.mesh->shownInnerLabels()) : OverlayPicture{};
  showFrameLayer();
  if (view_->secondFrameShown()) {
    // (the first frame's distance does not describe the second frame's outline: no organ is placed there yet)
    status_.distance->setText(tr("Second frame: the fit places the organ in it"));
    status_.distance->setToolTip(status_.distance->text());
  } else if (picture_.meanDistance >= 0) {
    const QString text = tr("Contour to silhouette: mean %1 px, RMS %2 px, max %3 px")
                             .arg(picture_.meanDistance, 0, 'f', 1)
                             .arg(picture_.rmsDistance, 0, 'f', 1)
                             .arg(picture_.maxDistance, 0, 'f', 1);
    status_.distance->setText(text);
    status_.distance->setToolTip(text);
    pages_.rigid->setDistanceText(text);
  } else {
    status_.distance->clear();
    status_.distance->setToolTip({});
    // Why there is no distance, as the case has it (a two-segment contour is not "no contour").
    const bool anyContour = c && !c->contour.segments.empty();
    const bool silhouette = c && !imaging::silhouetteSegments(c->contour).empty();
    pages_.rigid->setDistanceText(
        !anyContour   ? tr("Sketch a contour (step 3) to see its distance to the silhouette.")
        : !silhouette ? tr("The contour has no silhouette segment (step 3's segment type): the distance is measured "
                           "from silhouette segments only.")
                      : tr("The organ's silhouette is not in the frame (behind or outside the camera's view): place "
                           "the organ over the frame to see the contour's distance to it."));
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
    connect(a, &QAction::triggered, this, [this, path] { openCaseAsked(path); });
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
  if (doc_->path().isEmpty() || !isCaseFile(doc_->path()))
    saveAs();
  else
    saveCaseAs(doc_->path());
}

void MainWindow::saveAs() {
  // A name to start from: the case's file, or its name in the folder last used ("Built-in liver phantom.rehearse").
  QString suggested = doc_->path();
  if (suggested.isEmpty() && doc_->hasCase()) {
    suggested = QDir(dialogFolder()).filePath(QString::fromStdString(doc_->data()->name).replace('/', '-') + ".rehearse");
  }
  QString path = QFileDialog::getSaveFileName(this, tr("Save Case"), suggested, tr("Rehearse cases (*.rehearse)"));
  if (path.isEmpty()) return;
  if (!path.endsWith(QStringLiteral(".rehearse"))) path += QStringLiteral(".rehearse");
  rememberDialogFolder(path);
  saveCaseAs(path);
}

void MainWindow::openFileDialog() {
  askToKeepChanges(tr("opening another case"), [this] {
    const QString path =
        QFileDialog::getOpenFileName(this, tr("Open Case"), dialogFolder(),
                                     tr("Rehearse cases (*.rehearse);;All files (*)"));
    if (path.isEmpty()) return;
    rememberDialogFolder(path);
    openCase(path);
  });
}

void MainWindow::offerRecovery() {
  if (!hasRecoverableAutosave()) return;
  // Set aside first: this run's own autosaves go to the slot's file and never overwrite the crash's work (they had,
  // while the question waited unanswered: the next launch then offered this run's work, the crash's lost).
  const QString earlier = CaseDocument::setAsideCrashedAutosave();
  if (!QFileInfo::exists(CaseDocument::crashedAutosavePath())) return;
  // Which work and from when: the file it was made from (or the case's name) and the autosave's time.
  const QFileInfo autosave(CaseDocument::crashedAutosavePath());
  const QString source = CaseDocument::autosaveSource();
  const QString what = source.isEmpty() ? tr("a case not saved to a file") : QFileInfo(source).fileName();
  QString text = tr("Rehearse did not close cleanly last time. Recover the work autosaved at %1 (%2)?")
                     .arg(QLocale().toString(autosave.lastModified(), QLocale::ShortFormat), what);
  if (!earlier.isEmpty())
    text += ' ' + tr("The work an earlier crash left, not recovered then, is kept in %1 (File > Open).")
                      .arg(QDir::toNativeSeparators(earlier));
  auto* box = new QMessageBox(QMessageBox::Question, tr("Recover case"), text, QMessageBox::Yes | QMessageBox::No, this);
  box->setObjectName(QStringLiteral("recoverCaseBox"));
  box->setAttribute(Qt::WA_DeleteOnClose);
  // Answered before anything else (a stray click and Ctrl+Q quit past it, and the clean exit removed the autosave:
  // the work the crash left was lost). Yes opens it; No discards it at the next clean exit.
  box->setWindowModality(Qt::WindowModal);
  recoveryBox_ = box;
  // Only a button answers it (clicked, or Escape for No): the question's window closed without one (a person did so
  // with no window manager's buttons: the clean exit after it removed the autosave) leaves the work for the next launch.
  auto answered = std::make_shared<bool>(false);
  connect(box, &QMessageBox::buttonClicked, this, [answered](QAbstractButton*) { *answered = true; });
  connect(box, &QMessageBox::finished, this, [this, answered](int r) {
    recoveryBox_.clear();
    recoveryAnswered_ = recoveryAnswered_ || *answered;
    if (*answered && r == QMessageBox::Yes) recoverAutosaveAsked();
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
  if (QFileInfo(path).isDir() || ext == QLatin1String("rehearse"))
    openCaseAsked(path);
  else if (QStringList{"msh", "vtk", "vtu", "mesh", "obj", "stl", "ply", "off", "gltf", "glb"}.contains(ext) ||
           simcore::isLabelImagePath(path.toStdString()))
    pages_.mesh->importMesh(path);
  else if (QStringList{"png", "jpg", "jpeg", "bmp", "tif", "tiff", "mp4", "avi", "mkv", "mov"}.contains(ext))
    pages_.frame->openFrameSource(path);
  else if (ext == QLatin1String("json"))
    pages_.contour->importContour(path);
  else if (QStringList{"yaml", "yml", "xml"}.contains(ext))
    pages_.frame->loadCalibration(path);
  else
    say(tr("%1: unknown file type.").arg(QFileInfo(path).fileName()));
}

// ------------------------------------------------------------------------------------------ messages

void MainWindow::say(const QString& text) { sayAs(Said::Other, text); }

void MainWindow::sayAs(Said what, const QString& text) {
  status_.caseText->setText(text);
  status_.caseText->setToolTip(text);
  said_ = text.isEmpty() ? Said::Other : what;
  if (!text.isEmpty()) logMessage(text);
}

void MainWindow::logMessage(const QString& text) {
  messages_->appendPlainText(QDateTime::currentDateTime().toString(QStringLiteral("hh:mm:ss  ")) + text);
  // The newest entry in sight (appendPlainText scrolls only when the panel is laid out and already at its end).
  messages_->verticalScrollBar()->setValue(messages_->verticalScrollBar()->maximum());
}

void MainWindow::sayBriefly(const QString& text) {
  // A reply to the person, not news of the case: the status bar's temporary message, over whatever hint is showing
  // (said into the case's line, a tool's hint shown over it hid it), gone after a while; the Messages panel keeps it.
  logMessage(text);
  statusBar()->showMessage(text, kBriefMessageMs);
}

QString MainWindow::statusText() const {
  return status_.caseText->text();
}

QStringList MainWindow::messageLog() const {
  return messages_->toPlainText().split(QLatin1Char('\n'), Qt::SkipEmptyParts);
}

// ------------------------------------------------------------------------------------------ loading

QString MainWindow::activity() const {
  const int i = app::index(step_);
  QString what =
      QStringLiteral("step %1 %2").arg(i + 1).arg(QString::fromLatin1(app::kSteps[static_cast<std::size_t>(i)].title));
  if (!busyMessage_.isEmpty()) what += QStringLiteral("; job: ") + busyMessage_;
  return what;
}

void MainWindow::offerCrashReports(const QString& folder) {
  const QStringList reports = crash::pendingReports(folder);
  if (reports.isEmpty()) return;
  const QString newest = reports.back();
  QString doing;
  {
    QFile f(newest);
    if (f.open(QIODevice::ReadOnly))
      for (const QString& line : QString::fromUtf8(f.read(1 << 16)).split(QLatin1Char('\n')))
        if (line.startsWith(QStringLiteral("what was running: "))) doing = line.mid(18);
  }
  say(tr("Rehearse stopped unexpectedly last time%1; its report is kept on this machine, never sent: %2")
          .arg(doing.isEmpty() ? QString() : tr(" (%1)").arg(doing), newest));
  auto* box =
      new QMessageBox(QMessageBox::Warning, tr("Rehearse stopped unexpectedly"),
                      tr("Rehearse stopped unexpectedly last time%1. The case open then was autosaved at most a "
                         "minute before%2.\n\nA report (version, what was running, the program's stack) is kept "
                         "on this machine and never sent anywhere:\n%3")
                          .arg(doing.isEmpty() ? QString() : tr(", during %1").arg(doing),
                               hasRecoverableAutosave() ? tr(" and is offered back") : QString(), newest),
                      QMessageBox::NoButton, this);
  box->setObjectName(QStringLiteral("crashReportOffer"));
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->setWindowModality(Qt::NonModal);
  QPushButton* show = box->addButton(tr("Show Report"), QMessageBox::ActionRole);
  QPushButton* remove = box->addButton(tr("Delete Report"), QMessageBox::DestructiveRole);
  box->addButton(tr("Keep"), QMessageBox::AcceptRole)->setObjectName(QStringLiteral("keepCrashReport"));
  show->setObjectName(QStringLiteral("showCrashReport"));
  remove->setObjectName(QStringLiteral("deleteCrashReport"));
  connect(box, &QMessageBox::buttonClicked, this, [this, show, remove, reports, newest](QAbstractButton* b) {
    if (b == show) {
      auto* text = new QPlainTextEdit;
      text->setAttribute(Qt::WA_DeleteOnClose);
      text->setReadOnly(true);
      text->setWindowTitle(QFileInfo(newest).fileName());
      QFile f(newest);
      if (f.open(QIODevice::ReadOnly)) text->setPlainText(QString::fromUtf8(f.readAll()));
      text->resize(900, 600);
      text->show();
    }
    for (const QString& r : reports) {
      if (b == remove)
        QFile::remove(r);
      else
        crash::markShown(r);
    }
    say(b == remove ? tr("Crash report deleted.") : tr("Crash report kept: %1").arg(newest));
  });
  box->show();
}

void MainWindow::setBusy(bool busy, const QString& message) {
  busyMessage_ = busy ? message : QString();
  crash::setActivity(activity());
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
  status_.stage->setText(status_.stageText.isEmpty() ? tr("%1 s").arg(seconds)
                                                     : tr("%1 · %2 s").arg(status_.stageText).arg(seconds));
  status_.stage->setToolTip(status_.stage->text());
}

void MainWindow::openCase(const QString& path) {
  setBusy(true, path.isEmpty() ? tr("Generating the built-in phantom case...") : tr("Opening %1...").arg(path));
  doc_->open(path);
}

void MainWindow::openCaseAsked(const QString& path) {
  askToKeepChanges(tr("opening another case"), [this, path] { openCase(path); });
}

void MainWindow::newCaseAsked() {
  askToKeepChanges(tr("starting a new case"), [this] {
    if (doc_->isLoading()) cancelLoading();
    doc_->newCase();
  });
}

void MainWindow::recoverAutosaveAsked() {
  askToKeepChanges(tr("recovering the autosaved case"), [this] {
    recoveryAnswered_ = true;  // (File > Recover answers the question closed unanswered: the work is open again)
    setBusy(true, tr("Recovering the autosaved case..."));
    doc_->recoverAutosave();
  });
}

void MainWindow::updateTitle() {
  if (!doc_->hasCase()) return setWindowTitle(tr("Rehearse"));
  setWindowTitle(tr("%1[*] - Rehearse").arg(doc_->displayName()));
  setWindowModified(doc_->isModified());
}

void MainWindow::askToKeepChanges(const QString& doing, std::function<void()> then) {
  // The rehearsal's cuts, burns and clips (step 7) are not the case's: saving does not keep them, only a recording
  // does. Ending a rehearsal that changed the organ is asked about too (Ctrl+Q after a cut quit without a word).
  const QString unkept = simulation_ ? simulation_->unkeptWork() : QString();
  const bool unsaved = doc_->isModified();
  if (!unsaved && unkept.isEmpty()) return then();
  const QString rehearsal = tr("Only a recording keeps a rehearsal (Ctrl+R, into the case's file once it is saved).");
  auto* box =
      unsaved ? new QMessageBox(QMessageBox::Warning, tr("Unsaved changes"),
                                tr("The case \u201c%1\u201d has changes that are not saved. Save them before %2?")
                                    .arg(doc_->displayName(), doing),
                                QMessageBox::Save | QMessageBox::Discard | QMessageBox::Cancel, this)
              : new QMessageBox(QMessageBox::Warning, tr("Rehearsal not kept"),
                                tr("The rehearsal on \u201c%1\u201d (%2) is not kept: %3 ends it.")
                                    .arg(doc_->displayName(), unkept, doing),
                                QMessageBox::Discard | QMessageBox::Cancel, this);
  box->setObjectName(unsaved ? QStringLiteral("unsavedChangesBox") : QStringLiteral("unkeptRehearsalBox"));
  if (unsaved)
    box->setInformativeText(unkept.isEmpty() ? tr("Discard loses them; Cancel goes back to the case.")
                                             : tr("Discard loses them and the rehearsal; Cancel goes back to the case. "
                                                  "Saving keeps the case, not the rehearsal (%1). %2")
                                                   .arg(unkept, rehearsal));
  else
    box->setInformativeText(rehearsal + QStringLiteral(" ") + tr("Discard ends it; Cancel goes back to it."));
  box->setDefaultButton(unsaved ? QMessageBox::Save : QMessageBox::Cancel);
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->setWindowModality(Qt::WindowModal);
  // The organ does not go on moving behind the question (what it is asked about would change while it is read);
  // Cancel plays it on from where it stopped.
  const bool wasPlaying = simulation_ && simulation_->isPlaying();
  if (wasPlaying) simulation_->pause();
  auto resume = [this, wasPlaying] {
    if (wasPlaying && simulation_) simulation_->play();
  };
  connect(box, &QMessageBox::finished, this, [this, box, resume, unsaved, then = std::move(then)](int) {
    const auto button = box->standardButton(box->clickedButton());
    if (button == QMessageBox::Discard) {
      // When what was asked for did not happen (its file dialog cancelled: the same case, nothing loading, the window
      // open), the organ plays on as it was (it stayed paused, unsaid).
      const auto before = doc_->data();
      then();
      if (isVisible() && !closeAsked_ && !doc_->isLoading() && doc_->data() == before) resume();
      return;
    }
    if (button != QMessageBox::Save) {
      resume();
      return sayBriefly(unsaved ? tr("Cancelled: the case and its unsaved changes stay open.")
                                : tr("Cancelled: the rehearsal stays as it is."));
    }
    save();  // (Save As asks where for a case without a file)
    if (!doc_->isSaving()) return resume();  // Save As cancelled: nothing saved, nothing replaced
    auto once = std::make_shared<QMetaObject::Connection>();
    *once = connect(doc_, &CaseDocument::saved, this, [this, once, then, resume](bool ok, const QString&) {
      disconnect(*once);
      if (!ok) return resume();  // (a failed save said why; the case stays)
      then();
    });
  });
  box->open();
}

bool MainWindow::askToEndRehearsal(const QString& doing, std::function<void()> then, std::function<void()> otherwise) {
  // An edit, an undo or an import that starts another session ended an unrecorded cut without a word (a person
  // imported a mesh over a cut rehearsal), where quitting, opening another case and Reset ask.
  const QString unkept = simulation_ ? simulation_->unkeptWork() : QString();
  if (unkept.isEmpty()) {
    then();
    return true;
  }
  auto* box = new QMessageBox(
      QMessageBox::Warning, tr("Rehearsal not kept"),
      tr("The rehearsal on \u201c%1\u201d (%2) is not kept: %3 ends it.").arg(doc_->displayName(), unkept, doing),
      QMessageBox::Discard | QMessageBox::Cancel, this);
  box->setObjectName(QStringLiteral("endRehearsalBox"));
  box->setInformativeText(tr("Only a recording keeps a rehearsal (Ctrl+R). Discard ends it; Cancel goes back to it."));
  box->setDefaultButton(QMessageBox::Cancel);
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->setWindowModality(Qt::WindowModal);
  // The organ waits while the question is read (what it names would change); Cancel plays it on.
  const bool wasPlaying = simulation_->isPlaying();
  if (wasPlaying) simulation_->pause();
  connect(box, &QMessageBox::finished, this,
          [this, box, wasPlaying, then = std::move(then), otherwise = std::move(otherwise)](int) {
    if (box->standardButton(box->clickedButton()) == QMessageBox::Discard) return then();
    if (wasPlaying) simulation_->play();
    sayBriefly(tr("Cancelled: the rehearsal stays as it is."));
    if (otherwise) otherwise();
    // A field that was changed (the support's stiffness) shows the case's value again: the fields alone are shown
    // again (the views and the composition have not changed).
    if (const auto& data = doc_->data()) {
      simulation_->setCase(data);  // (the same case: the panel's fields refilled, the session untouched)
      for (StepPage* p : pages_.all) p->refresh(*data);
    }
  });
  box->open();
  return false;
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
  const QString name = doc_->displayName();
  updateTitle();
  if (recoverAction_) recoverAction_->setEnabled(doc_->autosaveNewerThanCase());
  if (doc_->data()->organ->empty() && doc_->data()->frame.empty())
    say(tr("New case: import the organ's mesh first (step 1, Ctrl+I), then open the endoscope frame (step 2, Ctrl+F)."));
  else if (doc_->isModified())
    say(tr("%1 recovered from its autosave: save it (Ctrl+S) to keep it.").arg(name));
  else
    say(tr("%1 loaded in %2 s").arg(name).arg(doc_->loadSeconds(), 0, 'f', 2) +
        (doc_->notes().isEmpty() ? QString() : tr(" (%1 problems, see the Case panel)").arg(doc_->notes().size())));
  // Go to the first step that is not done yet.
  const int next = app::nextStep(*doc_->data());
  if (next < app::index(Step::Elastic)) setStep(static_cast<Step>(next));
  emit caseLoaded(true);
}

QString MainWindow::infoText() const {
  return info_->toPlainText();
}

void MainWindow::showCaseInfo() {
  if (doc_->data())
    info_->setPlainText(caseInfoText(*doc_->data(), doc_->notes() + pages_.mesh->importNotes(), doc_->qualityText()));
}

void MainWindow::closeEvent(QCloseEvent* e) {
  if (!closeAsked_ && (doc_->isModified() || (simulation_ && !simulation_->unkeptWork().isEmpty()))) {
    e->ignore();
    askToKeepChanges(tr("closing Rehearse"), [this] {
      closeAsked_ = true;
      close();
    });
    return;
  }
  closeAsked_ = false;
  cancelLoading();
  pages_.frame->stopCamera();
  jobs_->waitForFinished();
  // A clean exit leaves no autosave behind (after waiting for one being written): its presence at start
  // means the last session crashed. Unless the work a crash left is still being offered back: it stays, and the next
  // launch offers it again.
  // (A crash's work set aside at start and never asked about, --no-recover, stays too.)
  const bool unanswered = !recoveryBox_.isNull() || !recoveryAnswered_;
  if (recoveryBox_) recoveryBox_->close();
  doc_->closeCleanly(unanswered);
  QSettings settings;
  settings.setValue(QStringLiteral("window/geometry"), saveGeometry());
  settings.setValue(QStringLiteral("window/state"), saveState());
  auto* workflow = findChild<QDockWidget*>(QStringLiteral("workflowDock"));
  auto* organ = findChild<QDockWidget*>(QStringLiteral("organDock"));
  if (workflow && organ) {
    settings.setValue(QStringLiteral("window/workflowWidth"), workflow->width());
    settings.setValue(QStringLiteral("window/organWidth"), organ->width());
  }
  e->accept();
}

}  // namespace rehearse::ui
