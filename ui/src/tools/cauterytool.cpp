// The cautery hook (step 7): press on the organ drawn over the frame to put the powered hook on the tissue there, drag
// to draw a burnt line along the surface, release to switch the power off. The tissue within the hook's radius burns
// after a fraction of a second (it whitens and stiffens; a cut along it does not bleed). Energy that reaches a vessel,
// a duct or a tumour is said, and counted for the trainer. Every input goes to the simulation session as a
// timestamped event (camera frame), so it is recorded with the run.
#include "tools.hpp"

#include <QMouseEvent>
#include <QPainter>

namespace rehearse::ui::tools {
namespace {

class CauteryTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF&, const Eigen::Vector2d& f) override {
    if (e->button() != Qt::LeftButton) return false;
    const auto& c = view_.caseData();
    if (!c || !c->hasPose) {
      emit view_.toolMessage(
          QObject::tr("The cautery hook works on the organ placed over the frame: place it first (step 4)."));
      return true;
    }
    const auto hit = view_.liveSurfaceAt(f);
    if (!hit) {
      emit view_.toolMessage(QObject::tr("Press on the organ to apply energy there."));
      return true;
    }
    on_ = true;
    path_.assign(1, f);
    tip_ = *hit;  // on the surface point under the cursor
    postInstrument(view_, simcore::InputKind::ToolPose, tip_, false, kTool);
    postInstrument(view_, simcore::InputKind::Energy, tip_, true, kTool);
    emit view_.toolMessage(QObject::tr("Energy on: drag along the organ to burn a line, release to stop."));
    return true;
  }
  void move(const QPointF&, const Eigen::Vector2d& f) override {
    if (!on_) return;
    // The hook follows the surface under the cursor (it stays where it was off the organ).
    if (const auto hit = view_.liveSurfaceAt(f)) {
      tip_ = *hit;
      path_.push_back(f);
      postInstrument(view_, simcore::InputKind::ToolPose, tip_, false, kTool);
    }
  }
  void release(QMouseEvent*) override {
    if (!on_) return;
    on_ = false;
    postInstrument(view_, simcore::InputKind::Energy, tip_, false, kTool);
    emit view_.toolMessage(QObject::tr("Energy off."));
  }
  bool abandon() override {
    if (!on_) return false;
    release(nullptr);
    return true;
  }
  void paint(QPainter& painter) override {
    if (!on_ || path_.empty()) return;
    painter.setPen(QPen(QColor(255, 230, 120), 2, Qt::DotLine));
    QPolygonF line;
    for (const auto& f : path_) line << view_.toWidget(QPointF(f.x(), f.y()));
    painter.drawPolyline(line);
    painter.setBrush(QColor(255, 240, 160, 160));
    painter.setPen(Qt::NoPen);
    painter.drawEllipse(line.back(), 6, 6);
  }
  Qt::CursorShape cursor() const override { return Qt::CrossCursor; }

 private:
  static constexpr int kTool = 4;  ///< the cautery's instrument index (scripts' "cautery")
  bool on_ = false;
  Eigen::Vector3d tip_ = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector2d> path_;
};

}  // namespace

std::unique_ptr<FrameTool> makeCauteryTool(FrameView& view) { return std::make_unique<CauteryTool>(view); }

}  // namespace rehearse::ui::tools
