#pragma once
// Loads a case (the built-in phantom or a case folder) off the GUI thread and prepares what the
// view draws: the frame and the organ overlay, as QImages.
#include <rehearse/app/case.hpp>

#include <QImage>
#include <QPolygonF>
#include <QString>
#include <QStringList>

#include <atomic>
#include <functional>
#include <memory>

namespace rehearse::ui {

struct LoadedCase {
  std::shared_ptr<const app::Case> data;
  QImage frame;                  ///< RGB888 copy of the case frame
  QStringList notes;             ///< parts that could not be loaded, repairs made
  double seconds = 0;            ///< load time
  QString error;                 ///< non-empty when loading failed (one sentence); nothing else is set then
  bool cancelled = false;
};

/// Runs on a worker thread. `dir`: a case file (.rehearse), a case folder, or empty for the built-in phantom. Never throws: failures come back in `error`.
LoadedCase loadCase(const QString& dir, const std::function<void(double, const QString&)>& progress,
                    const std::atomic<bool>* cancel);

}  // namespace rehearse::ui
