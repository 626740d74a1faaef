// The main window's menus and toolbar: File, Edit, Step, View, Simulate, Help (built once, by the constructor).
#include "rehearse/ui/devicesteering.hpp"
#include "rehearse_revision.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/pages/steppage.hpp"
#include "rehearse/ui/keyboardreference.hpp"
#include "rehearse/ui/liveoverlay.hpp"
#include "rehearse/ui/recordingcontroller.hpp"
#include "rehearse/ui/trainingcontroller.hpp"

#include "rehearse/ui/caseinfo.hpp"
#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/organview.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <QAction>
#include <QDesktopServices>
#include <QDialog>
#include <QDialogButtonBox>
#include <QHeaderView>
#include <QTableWidget>
#include <QUrl>
#include <QActionGroup>
#include <QCoreApplication>
#include <QCloseEvent>
#include <QDir>
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
#include "rehearse/ui/reviewwindow.hpp"
#include <QMimeData>
#include <QPlainTextEdit>
#include <QPainter>
#include <QProgressBar>
#include <QSettings>
#include <QStackedWidget>
#include <QStatusBar>
#include <QTimer>
#include <QToolBar>
#include <QToolButton>
#include <QUndoStack>
#include <QVBoxLayout>

#include "mainwindow_parts.hpp"

namespace rehearse::ui {

// -------------------------------------------------------------------------------------------- menus

void MainWindow::buildMenus() {
  const QList<QAction*> fileTools = buildFileMenu();
  const QList<QAction*> editTools = buildEditMenu();

  QMenu* stepMenu = menuBar()->addMenu(tr("&Step"));
  for (int i = 0; i < app::kStepCount; ++i) {
    if (!app::kSteps[static_cast<std::size_t>(i)].available) continue;
    QAction* a = stepMenu->addAction(stepName(i), this, [this, i] { setStep(static_cast<Step>(i)); });
    a->setShortcut(QKeySequence(Qt::ALT | static_cast<Qt::Key>(Qt::Key_1 + i)));
  }
  QToolBar* tools = addToolBar(tr("Main"));
  tools->setObjectName(QStringLiteral("mainToolbar"));
  tools->setIconSize(QSize(28, 28));
  for (QAction* a : fileTools) tools->addAction(a);
  tools->addSeparator();
  for (QAction* a : editTools) tools->addAction(a);
  buildViewMenu();
  buildSimulationMenu();

  QAction* cancel = new QAction(tr("Cancel"), this);
  cancel->setShortcut(QKeySequence(Qt::Key_Escape));
  connect(cancel, &QAction::triggered, this, &MainWindow::cancelLoading);
  addAction(cancel);

  buildHelpMenu();
}

QList<QAction*> MainWindow::buildFileMenu() {
  QMenu* file = menuBar()->addMenu(tr("&File"));
  QAction* newCase = file->addAction(tr("&New Case"), this, &MainWindow::newCaseAsked);
  newCase->setObjectName(QStringLiteral("newCaseAction"));
  newCase->setShortcut(QKeySequence::New);
  newCase->setStatusTip(tr("Start an empty case: its organ mesh first, then its frame"));
  QAction* openFile = file->addAction(tr("&Open Case..."), this, &MainWindow::openFileDialog);
  openFile->setShortcut(QKeySequence::Open);
  QAction* open = file->addAction(tr("Open Case &Folder..."), this, [this] {
    askToKeepChanges(tr("opening another case"), [this] {
      const QString dir = QFileDialog::getExistingDirectory(this, tr("Open Case Folder"), dialogFolder());
      if (dir.isEmpty()) return;
      rememberDialogFolder(QDir(dir).filePath(QStringLiteral(".")));  // (the folder itself, not its parent)
      openCase(dir);
    });
  });
  open->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_O));
  recentMenu_ = file->addMenu(tr("Open &Recent"));
  rebuildRecentMenu();
  file->addAction(tr("Open &Built-in Phantom"), this, [this] { openCaseAsked({}); })
      ->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_P));
  file->addSeparator();
  QAction* importAction = file->addAction(tr("&Import Mesh..."), pages_.mesh, &MeshPage::importMeshDialog);
  importAction->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_I));
  QAction* frameAction = file->addAction(tr("Open &Frame or Video..."), pages_.frame, &FramePage::openFrameDialog);
  frameAction->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_F));
  file->addSeparator();
  QAction* saveAction = file->addAction(tr("&Save"), this, &MainWindow::save);
  saveAction->setShortcut(QKeySequence::Save);
  file->addAction(tr("Save &As..."), this, &MainWindow::saveAs)
      ->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_S));
  recoverAction_ = file->addAction(tr("Recover &Autosaved Case"), this, &MainWindow::recoverAutosaveAsked);
  recoverAction_->setObjectName(QStringLiteral("recoverAutosaveAction"));
  recoverAction_->setStatusTip(tr("Open the work autosaved after the case's file was last saved"));
  recoverAction_->setEnabled(hasRecoverableAutosave());
  // Offered whenever an autosave newer than the case exists (one written a minute ago included).
  connect(file, &QMenu::aboutToShow, this,
          [this] { recoverAction_->setEnabled(doc_->autosaveNewerThanCase()); });
  file->addSeparator();
  file->addAction(tr("&Quit"), this, &QWidget::close)->setShortcut(QKeySequence::Quit);
  return {openFile, saveAction, importAction, frameAction};
}

QList<QAction*> MainWindow::buildEditMenu() {
  QMenu* edit = menuBar()->addMenu(tr("&Edit"));
  QAction* undo = doc_->undoStack()->createUndoAction(this, tr("&Undo"));
  undo->setShortcut(QKeySequence::Undo);
  QAction* redo = doc_->undoStack()->createRedoAction(this, tr("&Redo"));
  // Ctrl+Shift+Z as on every desktop, and Ctrl+Y (the platform's standard key differs: Qt's offscreen one has only Y).
  redo->setShortcuts({QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_Z), QKeySequence(Qt::CTRL | Qt::Key_Y)});
  edit->addAction(undo);
  edit->addAction(redo);
  // On the toolbar a fixed word (the menu's text, "Undo Edit pose fields", had moved every button after it as it
  // changed); what it would undo is in its tooltip.
  undo->setIconText(tr("Undo"));
  redo->setIconText(tr("Redo"));
  auto tips = [this, undo, redo] {
    const QUndoStack* stack = doc_->undoStack();
    undo->setToolTip(stack->canUndo() ? tr("Undo %1 (Ctrl+Z)").arg(stack->undoText()) : tr("Nothing to undo"));
    redo->setToolTip(stack->canRedo() ? tr("Redo %1 (Ctrl+Shift+Z)").arg(stack->redoText()) : tr("Nothing to redo"));
  };
  tips();
  connect(doc_->undoStack(), &QUndoStack::indexChanged, this, tips);
  connect(doc_->undoStack(), &QUndoStack::cleanChanged, this, tips);
  // Undo and redo say what they did, so that no older sentence ("Imported ...") stays in the status bar; and a new edit
  // ends that sentence (a person read "Undone: Attach 4 nodes" after three new picks, and in step 7).
  connect(doc_, &CaseDocument::edited, this, [this] {
    if (said_ == Said::UndoneOrRedone) say(QString());
  });
  // An undo or a redo that would end an unrecorded rehearsal asks first (the document's guard): the stack's own
  // connections are replaced by ones that go through it.
  QObject::disconnect(undo, &QAction::triggered, doc_->undoStack(), nullptr);
  QObject::disconnect(redo, &QAction::triggered, doc_->undoStack(), nullptr);
  connect(undo, &QAction::triggered, this, [this] {
    doc_->undoAsked([this] {
      const QUndoStack* stack = doc_->undoStack();
      sayAs(Said::UndoneOrRedone, tr("Undone: %1").arg(stack->text(stack->index())));
    });
  });
  connect(redo, &QAction::triggered, this, [this] {
    doc_->redoAsked([this] {
      const QUndoStack* stack = doc_->undoStack();
      if (stack->index() > 0) sayAs(Said::UndoneOrRedone, tr("Redone: %1").arg(stack->text(stack->index() - 1)));
    });
  });
  return {undo, redo};
}

void MainWindow::buildHelpMenu() {
  QMenu* help = menuBar()->addMenu(tr("&Help"));
  // The keyboard reference, read from this window's own actions and keys (the user guide prints the same table).
  QAction* keysAction = help->addAction(tr("&Keyboard Shortcuts"), this, [this] { showKeyboardReference(); });
  keysAction->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_Slash));
  // The user guide, as installed with the package (HTML; a PDF beside it), or as the build made it; F1, where a
  // desktop application keeps its help (a helper pressed F1 and met the About box).
  QAction* guide = help->addAction(tr("User &Guide"), this, [this] {
    // Installed beside the program: PREFIX/bin/rehearse and PREFIX/share/doc/rehearse/guide/ (GNUInstallDirs); in
    // the build folder: build/app/rehearse and build/docs/guide/.
    const QString dir = QCoreApplication::applicationDirPath();
    const QString installed = QDir::cleanPath(dir + QStringLiteral("/../share/doc/rehearse/guide/guide.html")),
                  built = QDir::cleanPath(dir + QStringLiteral("/../docs/guide/guide.html"));
    const QString found = QFileInfo::exists(installed) ? installed : QFileInfo::exists(built) ? built : QString();
    if (found.isEmpty()) {
      say(tr("The user guide is not installed here (%1); build and install the package, or see the build folder's "
             "docs/guide/guide.html.")
              .arg(installed));
    } else if (QDesktopServices::openUrl(QUrl::fromLocalFile(found))) {
      say(tr("The user guide opens in the web browser: %1").arg(found));
    } else {
      say(tr("No web browser opened the user guide; open it yourself: %1 (a PDF beside it).").arg(found));
    }
  });
  guide->setShortcut(QKeySequence::HelpContents);
  help->addAction(tr("&About Rehearse"), this, [this] {
    QMessageBox::about(
        this, tr("About Rehearse"),
        tr("<b>Rehearse %1</b> (%2)<p>Intra-operative surgical gesture rehearsal. It registers the pre-operative "
           "organ onto an endoscope frame (steps 1-5, with how sure the elastic fit is), estimates the organ's "
           "appearance and the light from the frame (step 6) and simulates the organ there, composited into the "
           "frame, where the grasper, scissors, clip applier and cautery hook act on it (step 7). Sessions are "
           "recorded for replay and review.</p>")
            .arg(QStringLiteral(REHEARSE_VERSION), QStringLiteral(REHEARSE_REVISION)));
  });
}

void MainWindow::showKeyboardReference() {
  auto* dialog = new QDialog(this);
  dialog->setAttribute(Qt::WA_DeleteOnClose);
  dialog->setWindowTitle(tr("Keyboard Shortcuts"));
  auto* layout = new QVBoxLayout(dialog);
  auto* table = new QTableWidget(dialog);
  table->setObjectName(QStringLiteral("keyboardReference"));
  table->setAccessibleName(tr("Keyboard shortcuts"));
  const auto reference = keyboardReference(*this);
  table->setColumnCount(3);
  table->setRowCount(static_cast<int>(reference.size()));
  table->setHorizontalHeaderLabels({tr("Where"), tr("Keys"), tr("What")});
  for (int r = 0; r < static_cast<int>(reference.size()); ++r) {
    const auto& e = reference[static_cast<std::size_t>(r)];
    table->setItem(r, 0, new QTableWidgetItem(e.where));
    table->setItem(r, 1, new QTableWidgetItem(e.keys));
    table->setItem(r, 2, new QTableWidgetItem(e.what));
  }
  table->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table->resizeColumnsToContents();
  table->horizontalHeader()->setStretchLastSection(true);
  layout->addWidget(table);
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Close, dialog);
  connect(buttons, &QDialogButtonBox::rejected, dialog, &QDialog::close);
  layout->addWidget(buttons);
  dialog->resize(900, 640);
  dialog->show();
}

void MainWindow::buildViewMenu() {
  QMenu* viewMenu = menuBar()->addMenu(tr("&View"));
  QAction* overlay = viewMenu->addAction(tr("Show &Organ"));
  overlay->setCheckable(true);
  overlay->setChecked(true);
  overlay->setShortcut(QKeySequence(Qt::Key_O));
  connect(overlay, &QAction::toggled, view_, &FrameView::setOverlayVisible);
  connect(overlay, &QAction::toggled, this,
          [this] { showFrameLayer(); });  // the composited organ is part of the picture
  QAction* fit = viewMenu->addAction(tr("&Fit Frame"), view_, &FrameView::fitToWindow);
  fit->setShortcut(QKeySequence(Qt::Key_Home));
  viewMenu
      ->addAction(tr("More Opaque Organ"), this, [this] { view_->setOverlayOpacity(view_->overlayOpacity() + 0.1); })
      ->setShortcut(QKeySequence(Qt::Key_BracketRight));
  viewMenu
      ->addAction(tr("More Transparent Organ"), this,
                  [this] { view_->setOverlayOpacity(view_->overlayOpacity() - 0.1); })
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
  viewMenu
      ->addAction(
          tr("Next Organ Style"), this,
          [this, styles] { styles->actions().at((static_cast<int>(view_->overlayStyle()) + 1) % 3)->trigger(); })
      ->setShortcut(QKeySequence(Qt::Key_V));
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
      {tr("&Composited View"), ViewMode::Composited, Qt::Key_F2,
       tr("The organ re-shaded into the frame, as estimated in step 6")},
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
  viewMenu->addAction(tr("&Navigate (pan and zoom)"), this, [this] { view_->setTool(Tool::Navigate); })
      ->setShortcut(QKeySequence(Qt::Key_N));
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
  simMenu
      ->addAction(tr("&Play / Pause"), this,
                  [this, show] {
                    show();
                    simulation_->togglePlay();
                  })
      ->setShortcut(QKeySequence(Qt::Key_F5));
  simMenu
      ->addAction(tr("Single S&tep"), this,
                  [this, show] {
                    show();
                    simulation_->stepOnce();
                  })
      ->setShortcut(QKeySequence(Qt::Key_F6));
  simMenu->addAction(tr("&Reset"), this, [this] { simulation_->resetAsked(); })
      ->setShortcut(QKeySequence(Qt::SHIFT | Qt::Key_F5));
  simMenu->addSeparator();
  recorder_ =
      new RecordingController(doc_, simulation_, pages_.rehearse, this, [this](const QString& text) { say(text); });
  recorder_->addActions(simMenu);
  (new TrainingController(doc_, this, [this](const QString& text) { say(text); }))->addActions(simMenu);
  simMenu->addSeparator();
  steering_ = new DeviceSteering(
      view_, simulation_, [this](const QString& text) { say(text); }, this);
  steering_->addActions(simMenu);
}

bool MainWindow::recording() const { return recorder_->recording(); }

QString MainWindow::caseFilePath() const { return doc_->path(); }

QString MainWindow::startRecording(const QString& trainee) { return recorder_->start(trainee); }

void MainWindow::stopRecording() { recorder_->stop(); }

ReviewWindow* MainWindow::openReview() { return recorder_->openReview(); }

}  // namespace rehearse::ui

