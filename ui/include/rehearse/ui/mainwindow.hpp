#pragma once
// The main window. At this stage: the case's frame with the organ drawn over it, a case info panel,
// loading on a worker thread with progress and cancel. The workflow steps come next (issue 3).
#include "rehearse/ui/caseloader.hpp"

#include <QFutureWatcher>
#include <QMainWindow>

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

  /// Loads a case folder, or the built-in phantom when `dir` is empty, on a worker thread.
  void openCase(const QString& dir);
  bool isLoading() const { return watcher_.isRunning(); }
  const LoadedCase& currentCase() const { return case_; }
  FrameView* frameView() const { return view_; }
  QString infoText() const;

 signals:
  void caseLoaded(bool ok);

 public slots:
  void cancelLoading();

 protected:
  void closeEvent(QCloseEvent*) override;

 private:
  void buildMenus();
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
};

}  // namespace rehearse::ui
