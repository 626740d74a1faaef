#pragma once
// Loads a case (the built-in phantom or a case folder) off the GUI thread and prepares what the
// view draws: the frame and the organ overlay, as QImages.
#include "phantom/phantom.hpp"

#include <QImage>
#include <QPolygonF>
#include <QString>
#include <QStringList>

#include <atomic>
#include <functional>
#include <memory>

namespace rehearse::ui {

struct LoadedCase {
  std::shared_ptr<const phantom::Case> data;
  QImage frame;                  ///< RGB888 copy of the case frame
  QImage organOverlay;           ///< ARGB32, shaded organ through the camera at the case pose
  QList<QPolygonF> silhouette;   ///< outline of the organ in frame pixels
  QString qualityText;           ///< mesh quality report
  QStringList notes;             ///< parts that could not be loaded, repairs made
  double seconds = 0;            ///< load time
  QString error;                 ///< non-empty when loading failed (one sentence); nothing else is set then
  bool cancelled = false;
};

/// Runs on a worker thread. `dir`: a case file (.rehearse), a case folder, or empty for the built-in phantom. Never throws: failures come back in `error`.
LoadedCase loadCase(const QString& dir, const std::function<void(double, const QString&)>& progress,
                    const std::atomic<bool>* cancel);

}  // namespace rehearse::ui
