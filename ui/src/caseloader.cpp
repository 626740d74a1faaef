#include "rehearse/ui/caseloader.hpp"

#include "rehearse/ui/casefile.hpp"

#include "phantom/phantom.hpp"
#include <rehearse/app/casefolder.hpp>

#include <QFileInfo>

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/quality.hpp>

#include <opencv2/imgproc.hpp>

#include <chrono>

namespace rehearse::ui {

namespace {
LoadedCase loadCaseOrThrow(const QString& dir, const std::function<void(double, const QString&)>& progress,
                           const std::atomic<bool>* cancel) {
  const auto t0 = std::chrono::steady_clock::now();
  LoadedCase out;
  auto c = std::make_shared<app::Case>();
  if (dir.isEmpty()) {
    phantom::PhantomOptions po;
    po.meshing.cancel = cancel;
    po.meshing.progress = [&](double f, const std::string& stage) {
      if (progress) progress(f < 0 ? f : 0.9 * f, QString::fromStdString(stage));
    };
    *c = app::caseFromPhantom(phantom::makePhantom(po));
  } else if (!QFileInfo::exists(dir)) {
    throw rehearse::InputError(QStringLiteral("%1 does not exist.").arg(dir).toStdString());
  } else if (QFileInfo(dir).isFile()) {
    *c = loadCaseFile(dir, &out.notes);
  } else {
    std::vector<std::string> notes;
    *c = app::loadCaseDirectory(dir.toStdString(), &notes);
    for (const auto& n : notes) out.notes << QString::fromStdString(n);
  }
  if (progress) progress(0.92, QStringLiteral("drawing the organ"));
  if (!c->frame.empty()) {
    cv::Mat rgb;
    cv::cvtColor(c->frame, rgb, cv::COLOR_BGR2RGB);
    out.frame = QImage(rgb.data, rgb.cols, rgb.rows, static_cast<int>(rgb.step), QImage::Format_RGB888).copy();
  }
  out.data = std::move(c);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (progress) progress(1.0, QStringLiteral("done"));
  return out;
}
}  // namespace

LoadedCase loadCase(const QString& dir, const std::function<void(double, const QString&)>& progress,
                    const std::atomic<bool>* cancel) {
  LoadedCase failed;
  try {
    return loadCaseOrThrow(dir, progress, cancel);
  } catch (const simcore::Cancelled&) {
    failed.cancelled = true;
    failed.error = QStringLiteral("Loading was cancelled; the previous case is unchanged.");
  } catch (const std::bad_alloc&) {
    failed.error = QStringLiteral("There is not enough memory to open this case.");
  } catch (const std::exception& e) {
    failed.error = QString::fromUtf8(e.what());
  }
  return failed;
}

}  // namespace rehearse::ui
