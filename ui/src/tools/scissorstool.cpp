// The scissors (step 7): press on the organ drawn over the frame to open the cut there, drag to cut, release
// to stop. The blade lies on the shaft, from the tip back towards the trocar; the tip goes in behind the
// pressed surface point by most of the blade's length (so the blade spans the tissue in front of it), and
// the wheel moves it along the view ray, 2 mm a notch. Every input goes to the simulation session as a
// timestamped event (camera frame), so it is recorded with the run.
#include "tools.hpp"

#include <QMouseEvent>
#include <QPainter>
#include <QWheelEvent>

#include <algorithm>

namespace rehearse::ui::tools {
namespace {

class ScissorsTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF&, const Eigen::Vector2d& f) override {
    if (e->button() != Qt::LeftButton) return false;
    const auto& c = view_.caseData();
    if (!c || !c->hasPose) {
      emit view_.toolMessage(QObject::tr("The scissors work on the organ placed over the frame: place it first (step 4)."));
      return true;
    }
    const auto hit = view_.liveSurfaceAt(f);
    if (!hit) {
      emit view_.toolMessage(QObject::tr("Press on the organ to start the cut."));
      return true;
    }
    depth_ = hit->z() + kBladeDepth;
    cutting_ = true;
    path_.clear();
    path_.push_back(f);
    send(simcore::InputKind::ToolPose, pointAtDepth(view_, f, depth_), false);
    send(simcore::InputKind::Cut, pointAtDepth(view_, f, depth_), true);
    emit view_.toolMessage(QObject::tr("Cutting: drag across the organ, release to stop (wheel: deeper or shallower)."));
    return true;
  }
  void move(const QPointF&, const Eigen::Vector2d& f) override {
    if (!cutting_) return;
    path_.push_back(f);
    send(simcore::InputKind::ToolPose, pointAtDepth(view_, f, depth_), false);
  }
  void release(QMouseEvent*) override {
    if (!cutting_) return;
    cutting_ = false;
    send(simcore::InputKind::Cut, pointAtDepth(view_, path_.back(), depth_), false);
    emit view_.toolMessage(QObject::tr("Cut ended."));
  }
  bool abandon() override {
    if (!cutting_) return false;
    release(nullptr);
    return true;
  }
  bool wheel(QWheelEvent* e) override {
    if (!cutting_) {
      // A press that missed the organ holds no blade: the wheel then is a person reaching for depth, not a zoom (the
      // view had shrunk to a corner under 15 notches).
      if (!(e->buttons() & Qt::LeftButton)) return false;
      emit view_.toolMessage(
          QObject::tr("The scissors are not cutting: press on the organ to start the cut; the wheel then takes the "
                      "blade deeper or shallower."));
      return true;
    }
    depth_ = std::max(1e-3, depth_ - 0.002 * e->angleDelta().y() / 120.0);
    send(simcore::InputKind::ToolPose, pointAtDepth(view_, path_.back(), depth_), false);
    return true;
  }
  void paint(QPainter& painter) override {
    if (!cutting_ || path_.size() < 2) return;
    painter.setPen(QPen(QColor(230, 60, 60), 2, Qt::DashLine));
    QPolygonF line;
    for (const auto& f : path_) line << view_.toWidget(QPointF(f.x(), f.y()));
    painter.drawPolyline(line);
  }
  Qt::CursorShape cursor() const override { return Qt::CrossCursor; }

 private:
  static constexpr double kBladeDepth = 0.02;  ///< m behind the pressed surface point (the blade is 30 mm)
  void send(simcore::InputKind kind, const Eigen::Vector3d& tip, bool on) { postInstrument(view_, kind, tip, on, 1); }
  bool cutting_ = false;
  double depth_ = 0;
  std::vector<Eigen::Vector2d> path_;
};

}  // namespace

std::unique_ptr<FrameTool> makeScissorsTool(FrameView& view) { return std::make_unique<ScissorsTool>(view); }

}  // namespace rehearse::ui::tools
