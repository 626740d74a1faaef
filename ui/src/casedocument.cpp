#include "rehearse/ui/casedocument.hpp"

#include "rehearse/ui/casefile.hpp"

#include <rehearse/simcore/quality.hpp>

#include <QDir>
#include <QFile>
#include <QFileInfo>
#include <QLockFile>
#include <QSettings>
#include <QStandardPaths>
#include <QUndoCommand>

#include <map>
#include <memory>
#include <QtConcurrent/QtConcurrent>

#include <opencv2/imgproc.hpp>

namespace rehearse::ui {
namespace {

// One undoable edit: the version before and after (cheap: large parts are shared).
class CaseCommand : public QUndoCommand {
 public:
  CaseCommand(CaseDocument* d, std::shared_ptr<const app::Case> before, std::shared_ptr<const app::Case> after, const QString& text, int mergeId)
      : QUndoCommand(text), d_(d), before_(std::move(before)), after_(std::move(after)), merge_(mergeId) {}
  void undo() override { d_->setVersion(before_); }
  void redo() override { d_->setVersion(after_); }
  const std::shared_ptr<const app::Case>& before() const { return before_; }
  const std::shared_ptr<const app::Case>& after() const { return after_; }
  int id() const override { return merge_ >= 0 ? 1 : -1; }
  bool mergeWith(const QUndoCommand* other) override {
    auto* o = dynamic_cast<const CaseCommand*>(other);
    if (!o || o->merge_ != merge_) return false;
    after_ = o->after_;
    return true;
  }

 private:
  CaseDocument* d_;
  std::shared_ptr<const app::Case> before_, after_;
  int merge_;
};

CaseDocument::Parts difference(const app::Case* a, const app::Case& b) {
  if (!a) return CaseDocument::AllParts;
  CaseDocument::Parts p;
  if (a->organ != b.organ) p |= CaseDocument::OrganPart;
  if (a->frame.data != b.frame.data || a->rawFrame.data != b.rawFrame.data) p |= CaseDocument::FramePart;
  if (a->camera.K != b.camera.K || a->camera.width != b.camera.width || a->camera.height != b.camera.height ||
      a->camera.distortion != b.camera.distortion || a->down != b.down)
    p |= CaseDocument::CameraPart;
  if (!(a->contour == b.contour)) p |= CaseDocument::ContourPart;
  if (a->pose.R != b.pose.R || a->pose.t != b.pose.t || a->hasPose != b.hasPose || a->poseAligned != b.poseAligned) p |= CaseDocument::PosePart;
  if (a->fit != b.fit) p |= CaseDocument::FitPart;
  if (a->attachments != b.attachments) p |= CaseDocument::AttachmentsPart;
  if (!(a->material == b.material)) p |= CaseDocument::MaterialPart;
  if (a->landmarks != b.landmarks) p |= CaseDocument::LandmarksPart;
  if (a->appearance != b.appearance) p |= CaseDocument::AppearancePart;
  if (a->frame2.data != b.frame2.data || !(a->contour2 == b.contour2) || a->baselineMm != b.baselineMm)
    p |= CaseDocument::SecondFramePart;
  return p;
}

}  // namespace

QImage frameToQImage(const cv::Mat3b& bgr) {
  if (bgr.empty()) return {};
  // As 32-bit pixels (B, G, R, 255 in memory: QImage::Format_RGB32): the format QPainter draws without converting
  // (a 24-bit image was converted at each repaint of the composited view, on the GUI thread).
  cv::Mat bgra;
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  return QImage(bgra.data, bgra.cols, bgra.rows, static_cast<int>(bgra.step), QImage::Format_RGB32).copy();
}

CaseDocument::CaseDocument(QObject* parent) : QObject(parent) {
  connect(&loadWatcher_, &QFutureWatcher<LoadedCase>::finished, this, &CaseDocument::onLoaded);
  connect(&saveWatcher_, &QFutureWatcher<QString>::finished, this, [this] {
    const QString error = saveWatcher_.result();
    if (error.isEmpty()) {
      path_ = savingPath_;
      addRecent(savingPath_);
      undo_.setClean();
      setSaved(savingVersion_);  // (edits made while it was written stay unsaved)
    }
    savingVersion_.reset();
    emit saved(error.isEmpty(), error.isEmpty() ? tr("Saved %1").arg(savingPath_) : error);
  });
  autosaveTimer_.setInterval(60'000);
  connect(&autosaveTimer_, &QTimer::timeout, this, [this] { autosaveIfChanged(); });
  connect(&autosaveWatcher_, &QFutureWatcher<void>::finished, this, &CaseDocument::autosaved);
  autosaveTimer_.start();
}

CaseDocument::~CaseDocument() {
  cancel_ = true;
  loadWatcher_.waitForFinished();
  saveWatcher_.waitForFinished();
  autosaveWatcher_.waitForFinished();
}

bool CaseDocument::edit(const QString& text, const std::function<void(app::Case&)>& fn, int mergeId) {
  if (!case_) return false;
  auto copy = std::make_shared<app::Case>(*case_);
  fn(*copy);
  std::shared_ptr<const app::Case> after = std::move(copy);
  auto push = [this, before = case_, after, text, mergeId] {
    if (case_ != before) return;  // (another version came in while the guard asked: this edit was made on the old one)
    undo_.push(new CaseCommand(this, case_, after, text, mergeId));
    emit edited(text);
  };
  if (guard_ && !guard_(*case_, *after, tr("the edit \u201c%1\u201d").arg(text), push)) return false;
  push();
  return true;
}

bool CaseDocument::stepAsked(bool back, std::function<void()> done) {
  if (!(back ? undo_.canUndo() : undo_.canRedo()) || !case_) return false;
  const auto* command = dynamic_cast<const CaseCommand*>(undo_.command(undo_.index() - (back ? 1 : 0)));
  auto step = [this, back, index = undo_.index(), done] {
    if (undo_.index() != index) return;  // (the history moved while the guard asked)
    back ? undo_.undo() : undo_.redo();
    if (done) done();
  };
  const std::shared_ptr<const app::Case> target = command ? (back ? command->before() : command->after()) : nullptr;
  const QString what = back ? tr("undoing \u201c%1\u201d").arg(undo_.undoText())
                            : tr("redoing \u201c%1\u201d").arg(undo_.redoText());
  if (target && guard_ && !guard_(*case_, *target, what, step)) return false;
  step();
  return true;
}

void CaseDocument::setVersion(std::shared_ptr<const app::Case> version) {
  if (!version) return;
  const Parts parts = difference(case_.get(), *version);
  if (parts & FramePart) frameImage_ = frameToQImage(version->frame);
  if ((parts & SecondFramePart) && version->frame2.data != (case_ ? case_->frame2.data : nullptr))
    secondFrameImage_ = frameToQImage(version->frame2);
  if (parts & OrganPart) qualityText_ = version->organ->empty() ? QString() : QString::fromStdString(simcore::formatQuality(version->organ->quality));
  const bool was = isModified();
  case_ = std::move(version);
  if (parts) emit changed(parts);
  if (isModified() != was) emit modifiedChanged(isModified());
}

void CaseDocument::setSaved(std::shared_ptr<const app::Case> version) {
  const bool was = isModified();
  saved_ = std::move(version);
  if (isModified() != was) emit modifiedChanged(isModified());
}

void CaseDocument::newCase() {
  if (loadWatcher_.isRunning()) {
    cancel_ = true;
    loadWatcher_.waitForFinished();
  }
  undo_.clear();
  notes_.clear();
  loadSeconds_ = 0;
  path_.clear();
  auto empty = std::make_shared<app::Case>();
  empty->name = tr("Untitled case").toStdString();
  case_.reset();  // everything changed
  setVersion(empty);
  autosaved_ = case_;
  setSaved(case_);  // nothing in it to lose
  emit loaded(true, {});
}

void CaseDocument::open(const QString& path) {
  if (loadWatcher_.isRunning()) {
    cancel_ = true;
    loadWatcher_.waitForFinished();
  }
  cancel_ = false;
  loadingPath_ = path;
  auto report = [this](double f, const QString& stage) {
    QMetaObject::invokeMethod(this, [this, f, stage] { emit progress(f, stage); }, Qt::QueuedConnection);
  };
  loadWatcher_.setFuture(QtConcurrent::run([path, report, this] { return loadCase(path, report, &cancel_); }));
}

void CaseDocument::cancelLoading() {
  if (loadWatcher_.isRunning()) cancel_ = true;
}

void CaseDocument::onLoaded() {
  LoadedCase result = loadWatcher_.result();
  if (!result.error.isEmpty()) {
    emit loaded(false, result.error);  // the current case stays untouched
    return;
  }
  undo_.clear();
  notes_ = result.notes;
  loadSeconds_ = result.seconds;
  const bool recovered = loadingPath_ == autosavePath() || loadingPath_ == crashedAutosavePath();
  path_ = isCaseFile(loadingPath_) && !recovered ? loadingPath_ : QString();
  // A recovered autosave is the work of the file it was made from: saved there, not into the autosave.
  if (recovered && isCaseFile(recoveredFrom_)) path_ = recoveredFrom_;
  recoveredFrom_.clear();
  if (!path_.isEmpty() && !recovered) addRecent(path_);
  case_.reset();  // everything changed
  setVersion(result.data);
  autosaved_ = case_;
  setSaved(recovered ? nullptr : case_);  // recovered work is in no file of the user's until saved
  emit loaded(true, {});
}

void CaseDocument::saveAs(const QString& path) {
  if (!case_ || saveWatcher_.isRunning()) {
    emit saved(false, tr("Nothing to save yet."));
    return;
  }
  savingPath_ = path;
  auto data = case_;
  savingVersion_ = case_;
  // The recordings come from the file the case lives in now (a Save As carries them to the new one).
  const QString from = path_.isEmpty() ? QString() : path_;
  const std::uint64_t responses = responseKey_ ? responseKey_() : 0;
  saveWatcher_.setFuture(QtConcurrent::run([data, path, from, responses]() -> QString {
    try {
      saveCaseFile(*data, path, from, responses);
      return {};
    } catch (const std::exception& e) {
      return QString::fromUtf8(e.what());
    }
  }));
}

namespace {
// Each running program autosaves into a slot of its own: autosave.rehearse, or autosave-2.rehearse ... for a second
// one launched on the same machine, each held by a lock file while the program runs (QLockFile: a lock whose program is
// no longer running is stale and taken over). A second launch had shared the first's file: it offered the running
// program's work back as a crash's, wrote its own autosaves over it, and its clean exit removed it.
QString slotName(int k) { return k == 0 ? QStringLiteral("autosave") : QStringLiteral("autosave-%1").arg(k + 1); }
QString claimSlot(const QString& dir) {
  static std::map<QString, std::pair<QString, std::unique_ptr<QLockFile>>> held;  // by folder (tests change it)
  if (auto it = held.find(dir); it != held.end()) return it->second.first;
  QDir().mkpath(dir);
  for (int k = 0; k < 16; ++k) {
    const QString base = dir + '/' + slotName(k);
    auto lock = std::make_unique<QLockFile>(base + QStringLiteral(".lock"));
    lock->setStaleLockTime(0);  // held as long as the program runs; stale only once it is gone
    if (lock->tryLock(0)) return held.emplace(dir, std::make_pair(base, std::move(lock))).first->second.first;
  }
  // Sixteen programs running (or a folder that takes no lock): the first slot, as before the slots existed.
  return held.emplace(dir, std::make_pair(dir + '/' + slotName(0), nullptr)).first->second.first;
}
QString slotBase() { return claimSlot(QStandardPaths::writableLocation(QStandardPaths::AppDataLocation)); }
// Where an autosave's case lives (its file, or empty): kept beside it so that a recovery saves back there.
QString sourcePathOf(const QString& autosave) { return autosave + QStringLiteral(".source"); }
QString autosaveSourcePath() { return sourcePathOf(CaseDocument::autosavePath()); }
void writeAutosaveSource(const QString& path) {
  QFile f(autosaveSourcePath());
  if (f.open(QIODevice::WriteOnly | QIODevice::Truncate)) f.write(path.toUtf8());
}
bool moveWithSource(const QString& from, const QString& to) {
  QFile::remove(to);
  QFile::remove(sourcePathOf(to));
  if (!QFile::rename(from, to)) return false;
  if (QFile::exists(sourcePathOf(from))) QFile::rename(sourcePathOf(from), sourcePathOf(to));
  return true;
}
}  // namespace

QString CaseDocument::autosavePath() { return slotBase() + QStringLiteral(".rehearse"); }

QString CaseDocument::crashedAutosavePath() { return slotBase() + QStringLiteral(".crashed.rehearse"); }

QString CaseDocument::setAsideCrashedAutosave() {
  const QString autosave = autosavePath(), crashed = crashedAutosavePath();
  if (!isCaseFile(autosave)) return {};
  QString kept;
  if (isCaseFile(crashed)) {
    // An earlier crash's work, still not answered: kept beside it under its time, never overwritten.
    kept = slotBase() + QStringLiteral(".crashed-%1.rehearse")
                            .arg(QFileInfo(crashed).lastModified().toString(QStringLiteral("yyyyMMdd-HHmmss")));
    if (!moveWithSource(crashed, kept)) kept.clear();
  }
  moveWithSource(autosave, crashed);
  return kept;
}

bool CaseDocument::hasRecoverableAutosave() { return isCaseFile(crashedAutosavePath()) || isCaseFile(autosavePath()); }

QString CaseDocument::autosaveSource() {
  QFile f(sourcePathOf(isCaseFile(crashedAutosavePath()) ? crashedAutosavePath() : autosavePath()));
  return f.open(QIODevice::ReadOnly) ? QString::fromUtf8(f.readAll()).trimmed() : QString();
}

QString CaseDocument::displayName() const {
  if (!path_.isEmpty()) return QFileInfo(path_).fileName();
  return case_ ? QString::fromStdString(case_->name) : QString();
}

bool CaseDocument::autosaveNewerThanCase() const {
  if (!hasRecoverableAutosave()) return false;
  if (isCaseFile(crashedAutosavePath())) return true;  // a crash's work, not yet recovered or discarded
  const QFileInfo autosave(autosavePath());
  // The case's own file, or the one the autosave was made from when the case open now has none.
  const QString file = path_.isEmpty() ? autosaveSource() : path_;
  if (file.isEmpty() || !QFileInfo::exists(file)) return true;
  return autosave.lastModified() > QFileInfo(file).lastModified();
}

void CaseDocument::recoverAutosave() {
  recoveredFrom_ = autosaveSource();
  open(isCaseFile(crashedAutosavePath()) ? crashedAutosavePath() : autosavePath());
}

void CaseDocument::autosaveNow() {
  if (!case_) return;
  waitForAutosave();
  QDir().mkpath(QFileInfo(autosavePath()).absolutePath());
  writeAutosaveSource(path_);
  saveCaseFile(*case_, autosavePath());
  autosaved_ = case_;
  emit autosaved();
}

bool CaseDocument::autosaveIfChanged() {
  if (!case_ || saveWatcher_.isRunning() || autosaveWatcher_.isRunning()) return false;
  if (autosaved_.lock() == case_) return false;  // nothing changed since the last autosave (or the load)
  auto data = case_;
  autosaved_ = case_;
  QDir().mkpath(QFileInfo(autosavePath()).absolutePath());
  writeAutosaveSource(path_);
  autosaveWatcher_.setFuture(QtConcurrent::run([data] {
    try {
      saveCaseFile(*data, autosavePath());
    } catch (const std::exception&) {
      // The next change tries again; the user's work is in memory and in their own file.
    }
  }));
  return true;
}

void CaseDocument::waitForAutosave() { autosaveWatcher_.waitForFinished(); }

void CaseDocument::closeCleanly(bool keepAutosave) {
  cancelLoading();
  loadWatcher_.waitForFinished();
  saveWatcher_.waitForFinished();
  waitForAutosave();
  // This run's own autosave goes (its work was saved or discarded); a crash's set aside goes too once answered.
  QFile::remove(autosavePath());
  QFile::remove(autosaveSourcePath());
  if (keepAutosave) return;
  QFile::remove(crashedAutosavePath());
  QFile::remove(sourcePathOf(crashedAutosavePath()));
}

QStringList CaseDocument::recentFiles() const { return QSettings().value(QStringLiteral("recentFiles")).toStringList(); }

void CaseDocument::addRecent(const QString& path) {
  QSettings s;
  QStringList list = s.value(QStringLiteral("recentFiles")).toStringList();
  list.removeAll(path);
  list.prepend(path);
  while (list.size() > 8) list.removeLast();
  s.setValue(QStringLiteral("recentFiles"), list);
  emit recentFilesChanged();
}

}  // namespace rehearse::ui
