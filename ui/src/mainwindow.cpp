#include "rehearse/ui/mainwindow.hpp"

#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/frameview.hpp"

#include <QAction>
#include <QApplication>
#include <QCloseEvent>
#include <QDir>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileInfo>
#include <QMimeData>
#include <QStandardPaths>
#include <QDockWidget>
#include <QFileDialog>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QSettings>
#include <QStatusBar>
#include <QToolBar>
#include <QToolButton>
#include <QtConcurrent/QtConcurrent>

namespace rehearse::ui {

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle(tr("Rehearse"));
  setObjectName(QStringLiteral("MainWindow"));
  view_ = new FrameView(this);
  view_->setObjectName(QStringLiteral("frameView"));
  setCentralWidget(view_);

  auto* dock = new QDockWidget(tr("Case"), this);
  dock->setObjectName(QStringLiteral("caseDock"));
  info_ = new QPlainTextEdit(dock);
  info_->setObjectName(QStringLiteral("caseInfo"));
  info_->setReadOnly(true);
  info_->setMinimumWidth(400);
  info_->setLineWrapMode(QPlainTextEdit::NoWrap);
  QFont mono(QStringLiteral("DejaVu Sans Mono"));
  mono.setStyleHint(QFont::Monospace);
  info_->setFont(mono);
  dock->setWidget(info_);
  addDockWidget(Qt::RightDockWidgetArea, dock);

  progress_ = new QProgressBar(this);
  progress_->setRange(0, 100);
  progress_->setMaximumWidth(220);
  progress_->setVisible(false);
  cancelButton_ = new QToolButton(this);
  cancelButton_->setText(tr("Cancel"));
  cancelButton_->setToolTip(tr("Cancel loading (Esc)"));
  cancelButton_->setVisible(false);
  connect(cancelButton_, &QToolButton::clicked, this, &MainWindow::cancelLoading);
  statusCase_ = new QLabel(this);
  statusCursor_ = new QLabel(this);
  statusBar()->addWidget(statusCase_, 1);
  statusBar()->addPermanentWidget(statusCursor_);
  statusBar()->addPermanentWidget(progress_);
  statusBar()->addPermanentWidget(cancelButton_);
  connect(view_, &FrameView::cursorMoved, this, [this](QPointF p) {
    statusCursor_->setText(tr("u %1  v %2 px").arg(p.x(), 0, 'f', 1).arg(p.y(), 0, 'f', 1));
  });

  buildMenus();
  connect(&watcher_, &QFutureWatcher<LoadedCase>::finished, this, &MainWindow::onLoadFinished);
  connect(&saveWatcher_, &QFutureWatcher<QString>::finished, this, [this] {
    const QString error = saveWatcher_.result();
    if (error.isEmpty()) {
      currentPath_ = savingPath_;
      addRecent(savingPath_);
      setWindowTitle(tr("%1 - Rehearse").arg(QFileInfo(savingPath_).fileName()));
      statusCase_->setText(tr("Saved %1").arg(savingPath_));
    } else {
      statusCase_->setText(error);
    }
    emit caseSaved(error.isEmpty(), error);
  });
  setAcceptDrops(true);
  autosaveTimer_.setInterval(60'000);
  connect(&autosaveTimer_, &QTimer::timeout, this, [this] {
    if (case_.data && !saveWatcher_.isRunning()) {
      auto data = case_.data;
      // Off the GUI thread; the autosave file is written atomically like any save.
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
  if (!restoreGeometry(settings.value(QStringLiteral("window/geometry")).toByteArray())) resize(1500, 860);
  restoreState(settings.value(QStringLiteral("window/state")).toByteArray());
}

MainWindow::~MainWindow() {
  cancel_ = true;
  watcher_.waitForFinished();
  saveWatcher_.waitForFinished();
}

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
  QString path = QFileDialog::getSaveFileName(this, tr("Save Case"), s.value(QStringLiteral("lastDir")).toString(),
                                              tr("Rehearse cases (*.rehearse)"));
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
  // Not modal: the view stays usable; the choice is also in the File menu.
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
  if (!urls.isEmpty() && urls.first().isLocalFile()) openCase(urls.first().toLocalFile());
}

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
  QAction* saveAction = file->addAction(tr("&Save"), this, &MainWindow::save);
  saveAction->setShortcut(QKeySequence::Save);
  QAction* saveAsAction = file->addAction(tr("Save &As..."), this, &MainWindow::saveAs);
  saveAsAction->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_S));
  recoverAction_ = file->addAction(tr("Recover &Autosaved Case"), this, [this] { openCase(autosavePath()); });
  recoverAction_->setEnabled(hasRecoverableAutosave());
  file->addSeparator();
  QAction* quit = file->addAction(tr("&Quit"), this, &QWidget::close);
  quit->setShortcut(QKeySequence::Quit);

  QMenu* viewMenu = menuBar()->addMenu(tr("&View"));
  overlayAction_ = viewMenu->addAction(tr("Show &Organ"));
  overlayAction_->setCheckable(true);
  overlayAction_->setChecked(true);
  overlayAction_->setShortcut(QKeySequence(Qt::Key_O));
  connect(overlayAction_, &QAction::toggled, view_, &FrameView::setOverlayVisible);
  QAction* fit = viewMenu->addAction(tr("&Fit Frame"), view_, &FrameView::fitToWindow);
  fit->setShortcut(QKeySequence(Qt::Key_Home));

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
  tools->addAction(openFile);
  tools->addAction(saveAction);
  tools->addAction(builtin);
  tools->addAction(overlayAction_);
  tools->addAction(fit);
}

void MainWindow::setBusy(bool busy, const QString& message) {
  progress_->setVisible(busy);
  cancelButton_->setVisible(busy);
  if (busy) progress_->setValue(0);
  if (!message.isEmpty()) statusCase_->setText(message);
}

void MainWindow::openCase(const QString& dir) {
  if (watcher_.isRunning()) {
    cancel_ = true;
    watcher_.waitForFinished();
  }
  cancel_ = false;
  loadingDir_ = dir;
  setBusy(true, dir.isEmpty() ? tr("Generating the built-in phantom case...") : tr("Opening %1...").arg(dir));
  auto progress = [this](double f, const QString& stage) {
    QMetaObject::invokeMethod(this, [this, f, stage] {
      progress_->setValue(static_cast<int>(100 * f));
      progress_->setFormat(stage + QStringLiteral(" %p%"));
    }, Qt::QueuedConnection);
  };
  watcher_.setFuture(QtConcurrent::run([dir, progress, this] { return loadCase(dir, progress, &cancel_); }));
}

void MainWindow::cancelLoading() {
  if (watcher_.isRunning()) cancel_ = true;
}

void MainWindow::onLoadFinished() {
  setBusy(false);
  LoadedCase loaded = watcher_.result();
  if (!loaded.error.isEmpty()) {
    // A failed or cancelled load leaves the current case untouched.
    statusCase_->setText(loaded.error);
    emit caseLoaded(false);
    return;
  }
  case_ = std::move(loaded);
  currentPath_ = isCaseFile(loadingDir_) && loadingDir_ != autosavePath() ? loadingDir_ : QString();
  if (!currentPath_.isEmpty()) addRecent(currentPath_);
  view_->setFrame(case_.frame);
  view_->setOverlay(case_.organOverlay, case_.silhouette);
  showCaseInfo();
  const QString name = QString::fromStdString(case_.data->name);
  setWindowTitle(tr("%1 - Rehearse").arg(name));
  statusCase_->setText(tr("%1 loaded in %2 s").arg(name).arg(case_.seconds, 0, 'f', 2) +
                       (case_.notes.isEmpty() ? QString() : tr(" (%1 problems, see the Case panel)").arg(case_.notes.size())));
  emit caseLoaded(true);
}

QString MainWindow::infoText() const { return info_->toPlainText(); }

void MainWindow::showCaseInfo() {
  const auto& c = *case_.data;
  QString t;
  t += tr("Case: %1\n\n").arg(QString::fromStdString(c.name));
  for (const auto& n : case_.notes) t += tr("! %1\n").arg(n);
  if (!case_.notes.isEmpty()) t += QLatin1Char('\n');
  t += tr("Organ mesh\n%1\n").arg(case_.qualityText);
  t += tr("surface triangles: %1\nattachment nodes: %2\n\n").arg(c.surface.size()).arg(c.attachments.size());
  const auto& cam = c.camera;
  t += tr("Camera\nimage: %1 x %2 px\nfx %3  fy %4 px\ncx %5  cy %6 px\ndistortion: %7 %8 %9 %10 %11\n\n")
           .arg(cam.width).arg(cam.height)
           .arg(cam.fx(), 0, 'f', 1).arg(cam.fy(), 0, 'f', 1).arg(cam.cx(), 0, 'f', 1).arg(cam.cy(), 0, 'f', 1)
           .arg(cam.distortion[0]).arg(cam.distortion[1]).arg(cam.distortion[2]).arg(cam.distortion[3]).arg(cam.distortion[4]);
  if (c.hasGroundTruth) {
    const auto& p = c.truePose;
    t += tr("Pose (model to camera, ground truth)\n");
    for (int r = 0; r < 3; ++r)
      t += QStringLiteral("[%1 %2 %3]  t %4 mm\n")
               .arg(p.R(r, 0), 7, 'f', 4).arg(p.R(r, 1), 7, 'f', 4).arg(p.R(r, 2), 7, 'f', 4).arg(p.t[r] * 1e3, 8, 'f', 2);
    const auto& a = c.trueAppearance;
    t += tr("\nLight (ground truth)\nposition: %1, %2, %3 mm\nkd: %4 %5 %6\nks: %7 %8 %9\nroughness: %10 rad\n")
             .arg(a.lightPosition.x() * 1e3).arg(a.lightPosition.y() * 1e3).arg(a.lightPosition.z() * 1e3)
             .arg(a.kd.x()).arg(a.kd.y()).arg(a.kd.z()).arg(a.ks.x()).arg(a.ks.y()).arg(a.ks.z()).arg(a.roughness);
  }
  info_->setPlainText(t);
}

void MainWindow::closeEvent(QCloseEvent* e) {
  cancelLoading();
  saveWatcher_.waitForFinished();
  // A clean exit leaves no autosave behind: its presence at start means the last session crashed.
  QFile::remove(autosavePath());
  QSettings settings;
  settings.setValue(QStringLiteral("window/geometry"), saveGeometry());
  settings.setValue(QStringLiteral("window/state"), saveState());
  e->accept();
}

}  // namespace rehearse::ui
