#pragma once
// The main window. At this stage: the case's frame with the organ drawn over it, a case info panel,
// loading on a worker thread with progress and cancel. The workflow steps come next (issue 3).
#include "rehearse/ui/caseloader.hpp"

#include <QFutureWatcher>
#include <QMainWindow>
#include <QTimer>

#include <atomic>

class QLabel;
class QPlainTextEdit;
class QProgressBar;
class QToolButton;
class QAction;

namespace rehearse::ui {

class FrameView;

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
  QString currentPath() const { return currentPath_; }
  bool isSaving() const { return saveWatcher_.isRunning(); }
  /// Where the periodic autosave goes, and whether one was left by a session that did not close cleanly.
  static QString autosavePath();
  static bool hasRecoverableAutosave();
  /// Writes the autosave now (normally every minute while a case is open). Blocks until done.
  void autosaveNow();
  void setAutosaveInterval(int ms) { autosaveTimer_.setInterval(ms); }
  QStringList recentFiles() const;
  bool isLoading() const { return watcher_.isRunning(); }
  const LoadedCase& currentCase() const { return case_; }
  FrameView* frameView() const { return view_; }
  QString infoText() const;

 signals:
  void caseLoaded(bool ok);
  void caseSaved(bool ok, const QString& message);

 public slots:
  void cancelLoading();
  /// Offers (without blocking) to reopen the autosave left by a session that did not close cleanly.
  void offerRecovery();

 protected:
  void closeEvent(QCloseEvent*) override;

 private:
  void buildMenus();
  void save();
  void saveAs();
  void openFileDialog();
  void addRecent(const QString& path);
  void rebuildRecentMenu();
  void dragEnterEvent(QDragEnterEvent*) override;
  void dropEvent(QDropEvent*) override;
  void onLoadFinished();
  void showCaseInfo();
  void setBusy(bool busy, const QString& message = {});

  FrameView* view_ = nullptr;
  QPlainTextEdit* info_ = nullptr;
  QProgressBar* progress_ = nullptr;
  QToolButton* cancelButton_ = nullptr;
  QLabel* statusCase_ = nullptr;
  QLabel* statusCursor_ = nullptr;
  QAction* overlayAction_ = nullptr;
  QFutureWatcher<LoadedCase> watcher_;
  std::atomic<bool> cancel_{false};
  LoadedCase case_;
  QString loadingDir_;
  QString currentPath_;
  QFutureWatcher<QString> saveWatcher_;
  QString savingPath_;
  QTimer autosaveTimer_;
  QMenu* recentMenu_ = nullptr;
  QAction* recoverAction_ = nullptr;
};

}  // namespace rehearse::ui
