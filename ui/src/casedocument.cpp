#include "rehearse/ui/casedocument.hpp"

#include "rehearse/ui/casefile.hpp"

#include <rehearse/simcore/quality.hpp>

#include <QDir>
#include <QFileInfo>
#include <QSettings>
#include <QStandardPaths>
#include <QUndoCommand>
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
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return QImage(rgb.data, rgb.cols, rgb.rows, static_cast<int>(rgb.step), QImage::Format_RGB888).copy();
}

CaseDocument::CaseDocument(QObject* parent) : QObject(parent) {
  connect(&loadWatcher_, &QFutureWatcher<LoadedCase>::finished, this, &CaseDocument::onLoaded);
  connect(&saveWatcher_, &QFutureWatcher<QString>::finished, this, [this] {
    const QString error = saveWatcher_.result();
    if (error.isEmpty()) {
      path_ = savingPath_;
      addRecent(savingPath_);
      undo_.setClean();
    }
    emit saved(error.isEmpty(), error.isEmpty() ? tr("Saved %1").arg(savingPath_) : error);
  });
  autosaveTimer_.setInterval(60'000);
  connect(&autosaveTimer_, &QTimer::timeout, this, [this] { autosaveIfChanged(); });
  autosaveTimer_.start();
}

CaseDocument::~CaseDocument() {
  cancel_ = true;
  loadWatcher_.waitForFinished();
  saveWatcher_.waitForFinished();
  autosaveWatcher_.waitForFinished();
}

void CaseDocument::edit(const QString& text, const std::function<void(app::Case&)>& fn, int mergeId) {
  if (!case_) return;
  auto after = std::make_shared<app::Case>(*case_);
  fn(*after);
  undo_.push(new CaseCommand(this, case_, std::move(after), text, mergeId));
}

void CaseDocument::setVersion(std::shared_ptr<const app::Case> version) {
  if (!version) return;
  const Parts parts = difference(case_.get(), *version);
  if (parts & FramePart) frameImage_ = frameToQImage(version->frame);
  if ((parts & SecondFramePart) && version->frame2.data != (case_ ? case_->frame2.data : nullptr))
    secondFrameImage_ = frameToQImage(version->frame2);
  if (parts & OrganPart) qualityText_ = version->organ->empty() ? QString() : QString::fromStdString(simcore::formatQuality(version->organ->quality));
  case_ = std::move(version);
  if (parts) emit changed(parts);
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
  path_ = isCaseFile(loadingPath_) && loadingPath_ != autosavePath() ? loadingPath_ : QString();
  if (!path_.isEmpty()) addRecent(path_);
  case_.reset();  // everything changed
  setVersion(result.data);
  autosaved_ = case_;
  emit loaded(true, {});
}

void CaseDocument::saveAs(const QString& path) {
  if (!case_ || saveWatcher_.isRunning()) {
    emit saved(false, tr("Nothing to save yet."));
    return;
  }
  savingPath_ = path;
  auto data = case_;
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

QString CaseDocument::autosavePath() {
  return QStandardPaths::writableLocation(QStandardPaths::AppDataLocation) + QStringLiteral("/autosave.rehearse");
}

bool CaseDocument::hasRecoverableAutosave() { return isCaseFile(autosavePath()); }

void CaseDocument::autosaveNow() {
  if (!case_) return;
  waitForAutosave();
  QDir().mkpath(QFileInfo(autosavePath()).absolutePath());
  saveCaseFile(*case_, autosavePath());
  autosaved_ = case_;
}

bool CaseDocument::autosaveIfChanged() {
  if (!case_ || saveWatcher_.isRunning() || autosaveWatcher_.isRunning()) return false;
  if (autosaved_.lock() == case_) return false;  // nothing changed since the last autosave (or the load)
  auto data = case_;
  autosaved_ = case_;
  autosaveWatcher_.setFuture(QtConcurrent::run([data] {
    try {
      QDir().mkpath(QFileInfo(autosavePath()).absolutePath());
      saveCaseFile(*data, autosavePath());
    } catch (const std::exception&) {
      // The next change tries again; the user's work is in memory and in their own file.
    }
  }));
  return true;
}

void CaseDocument::waitForAutosave() { autosaveWatcher_.waitForFinished(); }

void CaseDocument::closeCleanly() {
  cancelLoading();
  loadWatcher_.waitForFinished();
  saveWatcher_.waitForFinished();
  waitForAutosave();
  QFile::remove(autosavePath());
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
