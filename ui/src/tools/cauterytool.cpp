// The cautery hook (step 7): press on the organ drawn over the frame to put the powered hook on the tissue there, drag
// to draw a burnt line along the surface, release to switch the power off. The tissue within the hook's radius burns
// after a fraction of a second (it whitens and stiffens; a cut along it does not bleed). Energy that reaches a vessel,
// a duct or a tumour is said, and counted for the trainer. Every input goes to the simulation session as a
// timestamped event (camera frame), so it is recorded with the run.
#include "tools.hpp"

#include <QMouseEvent>
#include <QPainter>
#include <QWheelEvent>

#include <algorithm>

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
    const auto hit = view_.liveSurfaceAt(f, FrameView::SurfacePick::Point);
    if (!hit) {
      emit view_.toolMessage(QObject::tr("Press on the organ to apply energy there."));
      return true;
    }
    pressed_ = view_.liveShape();
    press_ = kPress;
    on_ = true;
    off_ = false;
    path_.assign(1, f);
    tip_ = onSurface(*hit);
    postInstrument(view_, simcore::InputKind::ToolPose, tip_, false, kTool);
    postInstrument(view_, simcore::InputKind::Energy, tip_, true, kTool);
    emit view_.toolMessage(QObject::tr("Energy on: drag along the organ to burn a line, release to stop."));
    return true;
  }
  void move(const QPointF&, const Eigen::Vector2d& f) override {
    if (!on_) return;
    // The hook follows the surface under the cursor (off the organ, the cursor's ray in the air), the surface as it was when
    // the power came on: the one under the cursor now is the one the hook's own shaft pushed and dragged (a straight
    // drag across the phantom built up 18 N on the hook, the tissue carried along in front of the shaft).
    if (const auto hit = view_.liveSurfaceAt(f, FrameView::SurfacePick::Point, &pressed_)) {
      tip_ = onSurface(*hit);
      path_.push_back(f);
      off_ = false;
    } else {
      // Off the organ the hook leaves the tissue: it follows the cursor through the air at the depth it had (the ray
      // misses the organ, so no point of it is in the tissue). It stayed at the edge, burning there with the power
      // still on, while the cursor went on (a person's drag past the organ's outline).
      const Eigen::Vector3d ray = view_.caseData()->camera.K.inverse() * Eigen::Vector3d(f.x(), f.y(), 1.0);
      tip_ = ray * (tip_.z() / ray.z());
      if (!off_)
        emit view_.toolMessage(
            QObject::tr("The hook is off the organ: it burns nothing until it is back on the tissue."));
      off_ = true;
    }
    postInstrument(view_, simcore::InputKind::ToolPose, tip_, false, kTool);
  }
  void release(QMouseEvent*) override {
    if (!on_) return;
    on_ = false;
    postInstrument(view_, simcore::InputKind::Energy, tip_, false, kTool);
    retractInstrument(view_, tip_, kTool);
    emit view_.toolMessage(QObject::tr("Energy off."));
  }
  bool abandon() override {
    if (!on_) return false;
    release(nullptr);
    return true;
  }
  // The wheel presses the hook deeper into the tissue or lifts it (0-5 mm, half a millimetre a notch) while the power
  // is on, as the page's help says the wheel moves the tip; it zoomed the whole view out in the middle of a burn.
  bool wheel(QWheelEvent* e) override {
    if (!on_) {
      if (!(e->buttons() & Qt::LeftButton)) return false;
      emit view_.toolMessage(QObject::tr("The hook is not on the tissue: press on the organ to apply energy; the wheel "
                                         "then presses it deeper or lifts it."));
      return true;
    }
    press_ = std::clamp(press_ - 0.0005 * e->angleDelta().y() / 120.0, 0.0, kDeepest);
    if (!off_ && !path_.empty()) {
      if (const auto hit = view_.liveSurfaceAt(path_.back(), FrameView::SurfacePick::Point, &pressed_)) {
        tip_ = onSurface(*hit);
        postInstrument(view_, simcore::InputKind::ToolPose, tip_, false, kTool);
      }
    }
    emit view_.toolMessage(QObject::tr("The hook presses %1 mm into the tissue.").arg(1e3 * press_, 0, 'f', 1));
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
  /// The hook's tip for the surface point under the cursor: its shaft's end pressed 0.5 mm into it, the tip the shaft's
  /// radius less that back towards the trocar (along the view ray when no trocar is known). With the tip on the point
  /// itself the shaft pushed that surface in by its radius, the next point under the cursor lay on the pushed surface,
  /// and a drag dug the hook in deeper at every move (a person read 21.5 N on a straight drag); the burn reaches past
  /// the shaft's end (3 mm from the tip, the shaft 2.5 mm), into the tissue it presses.
  Eigen::Vector3d onSurface(const Eigen::Vector3d& hit) const {
    Eigen::Vector3d back = -hit.normalized();  // towards the camera
    if (const auto& trocar = view_.trocar()) {
      const Eigen::Vector3d shaft = *trocar - hit;
      if (shaft.norm() > 1e-6 && shaft.normalized().dot(back) > 0.1) back = shaft.normalized();
    }
    // (Pressed deeper with the wheel, past the shaft's radius the tip goes into the tissue.)
    const double r = view_.shaftRadius();
    return hit + (press_ <= kPress ? std::max(0.0, r - press_) : r - press_) * back;
  }
  static constexpr int kTool = 4;           ///< the cautery's instrument index (scripts' "cautery")
  static constexpr double kPress = 0.0005;   ///< m: how far the shaft's end presses into the surface to start with
  static constexpr double kDeepest = 0.005;  ///< m: the wheel presses it no deeper
  double press_ = kPress;                    ///< m: how far it presses now (the wheel)
  bool on_ = false;
  bool off_ = false;  ///< the drag has left the organ: the hook is in the air
  Eigen::Vector3d tip_ = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector2d> path_;
  std::vector<Eigen::Vector3d> pressed_;  ///< the live shape when the power came on (camera frame)
};

}  // namespace

std::unique_ptr<FrameTool> makeCauteryTool(FrameView& view) { return std::make_unique<CauteryTool>(view); }

}  // namespace rehearse::ui::tools
