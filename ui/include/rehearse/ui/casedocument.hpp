#pragma once
// The open case as the GUI holds it: the current version of app::Case, its undo stack, where it lives on
// disk (open, save, save as, autosave, recent files) and a changed(parts) signal that every view and
// page observes instead of being pushed by hand. Each edit is a copy of the case with the change applied
// (large parts are shared, app/case.hpp), pushed as an undoable command; edits with the same mergeId
// (one drag) are one undo step. Loading and saving run on worker threads; the autosave writes only when
// something changed since the last one, and closing waits for it.
#include "rehearse/ui/caseloader.hpp"

#include <rehearse/app/case.hpp>

#include <QFutureWatcher>
#include <QImage>
#include <QObject>
#include <QStringList>
#include <QTimer>
#include <QUndoStack>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>

namespace rehearse::ui {

/// An RGB888 copy of a BGR frame (empty for an empty frame).
QImage frameToQImage(const cv::Mat3b& bgr);

class CaseDocument : public QObject {
  Q_OBJECT
 public:
  enum Part {
    OrganPart = 1,
    FramePart = 2,
    CameraPart = 4,
    ContourPart = 8,
    PosePart = 16,
    FitPart = 32,
    AttachmentsPart = 64,
    MaterialPart = 128,
    LandmarksPart = 256,
    AppearancePart = 512,
    SecondFramePart = 1024,  ///< the second frame, its outline, how far the scope moved
    AllParts = 2047
  };
  Q_DECLARE_FLAGS(Parts, Part)

  explicit CaseDocument(QObject* parent = nullptr);
  ~CaseDocument() override;

  /// The current version (null before the first case has loaded).
  const std::shared_ptr<const app::Case>& data() const { return case_; }
  bool hasCase() const { return case_ != nullptr; }
  QUndoStack* undoStack() { return &undo_; }

  /// Applies `edit` to a copy of the case and pushes it as one undoable command. False when the guard held it (the
  /// case unchanged for now: pushed later if the guard's question lets it, unless the case changed meanwhile).
  bool edit(const QString& text, const std::function<void(app::Case&)>& edit, int mergeId = -1);
  /// Asked before an edit, an undo or a redo replaces the case (`before` by `after`, `what` names it: "the edit
  /// \u201cAttach 4 nodes\u201d", "undoing \u201c...\u201d"): true goes ahead at once; false holds it, and the guard
  /// calls `proceed` later if it may go ahead after all (a question answered), or never. The window asks there before
  /// it ends a rehearsal nothing keeps.
  using Guard = std::function<bool(const app::Case& before, const app::Case& after, const QString& what,
                                   std::function<void()> proceed)>;
  void setGuard(Guard guard) { guard_ = std::move(guard); }
  /// Undo and redo as a person asks for them (Ctrl+Z, Ctrl+Shift+Z): the guard is asked first; `done` runs once undone
  /// (at once, or after the guard's question). False when not done now.
  bool undoAsked(std::function<void()> done = {}) { return stepAsked(true, std::move(done)); }
  bool redoAsked(std::function<void()> done = {}) { return stepAsked(false, std::move(done)); }
  /// Replaces the displayed version (undo/redo, the end of a preview).
  void setVersion(std::shared_ptr<const app::Case> version);

  /// Whether the case holds work that is in no file: edited since it was opened or saved (an undo back to that
  /// version is not a change), or recovered from an autosave. A new case or the built-in phantom, untouched, is not.
  bool isModified() const { return case_ && case_ != saved_; }
  /// Starts an empty case (no organ, no frame): its steps say what comes first. Emits loaded().
  void newCase();
  /// Loads a case file, a case folder, or the built-in phantom when `path` is empty, on a worker thread.
  /// The current case stays until the new one has loaded. Emits loaded().
  void open(const QString& path);
  void cancelLoading();
  bool isLoading() const { return loadWatcher_.isRunning(); }
  /// Saves to `path` on a worker thread (atomic write). Emits saved().
  void saveAs(const QString& path);
  /// What names the precomputed responses a save keeps with the case (the simulation's; autosaves leave them out).
  void setResponseKeySource(std::function<std::uint64_t()> source) { responseKey_ = std::move(source); }
  bool isSaving() const { return saveWatcher_.isRunning(); }
  QString path() const { return path_; }
  /// What the title and the questions call the case: its file's name, or its own name before it has a file.
  QString displayName() const;
  QStringList notes() const { return notes_; }
  double loadSeconds() const { return loadSeconds_; }
  QImage frameImage() const { return frameImage_; }
  QImage secondFrameImage() const { return secondFrameImage_; }  ///< Case::frame2, converted once per change
  QString qualityText() const { return qualityText_; }

  /// This program's autosave (a slot of its own, held while it runs: a second program on the machine has another).
  static QString autosavePath();
  /// Where the autosave a crash left in this slot is set aside while it is offered back, so that this run's own
  /// autosaves never overwrite it.
  static QString crashedAutosavePath();
  /// Sets the autosave a crash left (in this slot, found at start) aside to crashedAutosavePath(). An earlier crash's
  /// still there is kept under its time: returns that file's path (empty when none).
  static QString setAsideCrashedAutosave();
  /// A crash's work to offer back: set aside, or still in this slot's autosave.
  static bool hasRecoverableAutosave();
  /// An autosave written after the case's own file (or the case has no file): work that File > Recover brings back.
  bool autosaveNewerThanCase() const;
  /// The case file the autosave was made from (empty: a case without a file, or no autosave).
  static QString autosaveSource();
  /// Opens the autosave as the case it was made from (that file's path, so Save writes there; its changes unsaved).
  void recoverAutosave();
  /// Writes the autosave now, on this thread.
  void autosaveNow();
  /// Starts an autosave on a worker when something changed since the last one; false when none was needed.
  bool autosaveIfChanged();
  /// Waits for a running autosave (closing the window calls it before removing the file).
  void waitForAutosave();
  /// A clean exit: waits for the workers and removes this run's autosave (its presence at start means a crash), and
  /// the crash's set aside unless `keepAutosave` (it was offered back and not answered yet: offered again next time).
  void closeCleanly(bool keepAutosave = false);
  QStringList recentFiles() const;

 signals:
  void changed(rehearse::ui::CaseDocument::Parts parts);
  /// A new edit was made (pushed onto the undo stack: not an undo or redo).
  void edited(const QString& text);
  void loaded(bool ok, const QString& message);
  void saved(bool ok, const QString& message);
  void progress(double fraction, const QString& stage);
  void recentFilesChanged();
  void modifiedChanged(bool modified);
  void autosaved();  ///< an autosave was written (on the GUI thread, once it is on disk)

 private:
  std::function<std::uint64_t()> responseKey_;  ///< setResponseKeySource
  void addRecent(const QString& path);
  void onLoaded();

  std::shared_ptr<const app::Case> case_;
  std::shared_ptr<const app::Case> saved_;  ///< the version in the case's file (or as opened); isModified()
  void setSaved(std::shared_ptr<const app::Case> version);
  QString recoveredFrom_;  ///< the file the autosave being opened was made from (recoverAutosave)
  bool stepAsked(bool back, std::function<void()> done);
  QUndoStack undo_;
  Guard guard_;
  QString path_, loadingPath_, savingPath_;
  std::shared_ptr<const app::Case> savingVersion_;  ///< the version a running save writes
  QStringList notes_;
  double loadSeconds_ = 0;
  QImage frameImage_;
  QImage secondFrameImage_;
  QString qualityText_;
  std::atomic<bool> cancel_{false};
  QFutureWatcher<LoadedCase> loadWatcher_;
  QFutureWatcher<QString> saveWatcher_;
  QFutureWatcher<void> autosaveWatcher_;
  std::weak_ptr<const app::Case> autosaved_;  ///< the version last autosaved (or loaded): nothing to write while it is current
  QTimer autosaveTimer_;
};

}  // namespace rehearse::ui

Q_DECLARE_OPERATORS_FOR_FLAGS(rehearse::ui::CaseDocument::Parts)
