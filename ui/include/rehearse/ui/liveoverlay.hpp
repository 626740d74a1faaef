#pragma once
// The simulated organ drawn over the frame while rehearsing (step 7, the overlay view): each snapshot's drawing is
// made on a worker by its own CPU overlay, the newest replacing one not yet started, at most 60 times a second and
// only once the last drawing reached the screen (drawings made faster than the view paints them only delay its
// paints: bench_rehearsal_view).
#include "rehearse/ui/organoverlay.hpp"

#include <rehearse/app/case.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QElapsedTimer>
#include <QObject>
#include <QTimer>

#include <memory>
#include <optional>
#include <vector>

namespace rehearse::ui {

class FrameView;

class LiveOverlay : public QObject {
  Q_OBJECT
 public:
  /// One drawing: the case, the simulated nodes (camera frame), the cut surface after a cut, the inner labels shown.
  struct Job {
    std::shared_ptr<const app::Case> c;
    std::vector<Eigen::Vector3d> positions;
    std::shared_ptr<const simcore::CutSurface> surface;
    std::vector<int> inner;
    /// After a cut, the cut mesh's elements and labels (the inner structures are drawn on them).
    std::shared_ptr<const std::vector<std::array<int, 4>>> tets;
    std::shared_ptr<const std::vector<int>> labels;
  };
  LiveOverlay(FrameView* view, QObject* parent);
  /// Draws `job` when due (the newest request wins).
  void request(Job job);

 signals:
  /// A drawing of `organ` is ready (the window shows it if the organ and the view are still the same).
  void drawn(const OverlayPicture& picture, std::shared_ptr<const app::Organ> organ);

 private:
  void drawIfDue();
  bool due() const;
  FrameView* view_;
  std::shared_ptr<OrganOverlay> overlay_ = std::make_shared<OrganOverlay>(false);
  std::optional<Job> pending_;
  bool busy_ = false;
  QTimer timer_;
  QElapsedTimer clock_;  ///< since the last drawing began
  quint64 paints_ = 0;   ///< the frame view's paints when the last drawing began
};

}  // namespace rehearse::ui
