// The rigid-alignment gizmo (step 4): X, Y, Z handles move the organ along the camera axes, rX, rY, rZ turn
// it about them through its centre of gravity (one undo step per drag); keys nudge (arrows, PgUp/PgDn:
// 1 mm; W/S, A/D, Q/E: 1 degree; Shift: 10 mm / 5 degrees). A press away from the handles pans.
#include "tools.hpp"

#include <QKeyEvent>
#include <QMouseEvent>
#include <QPainter>

#include <cmath>

namespace rehearse::ui::tools {
namespace {

constexpr double kHandleRadius = 13;         // widget px
constexpr double kRotationPerPixel = 0.005;  // rad per frame pixel for tilts about X and Y

Eigen::Matrix3d axisRotation(int axis, double angle) { return Eigen::AngleAxisd(angle, Eigen::Vector3d::Unit(axis)).toRotationMatrix(); }
QColor axisColour(int axis) {
  static const QColor c[3] = {QColor(235, 80, 80), QColor(90, 220, 90), QColor(90, 150, 255)};
  return c[axis];
}
Eigen::Vector3d cogCamera(const FrameView& v) {
  const auto& c = v.caseData();
  if (!c || !c->hasPose) return Eigen::Vector3d(0, 0, -1);
  return c->pose.apply(c->organ->centreOfGravity);
}

class GizmoTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF& w, const Eigen::Vector2d&) override {
    if (e->button() != Qt::LeftButton) return true;
    active_ = handleAt(w);
    if (active_ == GizmoHandle::None) return false;  // the view pans
    startPose_ = view_.caseData()->pose;
    startMouse_ = w;
    merge_ = view_.nextMergeId();
    view_.update();
    return true;
  }
  void move(const QPointF& w, const Eigen::Vector2d&) override {
    if (active_ != GizmoHandle::None) drag(w);
  }
  void release(QMouseEvent*) override {
    if (active_ == GizmoHandle::None) return;
    active_ = GizmoHandle::None;
    view_.update();
  }
  bool key(QKeyEvent* e) override {
    const auto& c = view_.caseData();
    if (!c) return false;
    const auto p = nudgedPose(*c, e->key(), e->modifiers() & Qt::ShiftModifier);
    if (!p) return false;
    emit view_.poseEdited(*p, QObject::tr("Nudge"), -1);
    return true;
  }
  void paint(QPainter& painter) override {
    const auto& c = view_.caseData();
    if (!c || !c->hasPose || cogCamera(view_).z() <= 0) return;
    const QPointF centre = gizmoHandlePosition(view_, GizmoHandle::None);
    struct H {
      GizmoHandle h;
      int axis;
      bool rotate;
      const char* label;
    };
    const H handles[] = {{GizmoHandle::TranslateX, 0, false, "X"}, {GizmoHandle::TranslateY, 1, false, "Y"},
                         {GizmoHandle::TranslateZ, 2, false, "Z"}, {GizmoHandle::RotateX, 0, true, "rX"},
                         {GizmoHandle::RotateY, 1, true, "rY"},    {GizmoHandle::RotateZ, 2, true, "rZ"}};
    painter.setPen(QPen(Qt::white, 1));
    painter.setBrush(Qt::white);
    painter.drawEllipse(centre, 4, 4);
    QFont f = view_.font();
    f.setBold(true);
    painter.setFont(f);
    for (const auto& h : handles) {
      const QPointF p = gizmoHandlePosition(view_, h.h);
      QColor col = axisColour(h.axis);
      if (active_ == h.h) col = col.lighter(140);
      painter.setPen(QPen(col, 2));
      painter.drawLine(centre, p);
      painter.setBrush(col.darker(h.rotate ? 200 : 120));
      const QRectF box(p - QPointF(kHandleRadius, kHandleRadius), QSizeF(2 * kHandleRadius, 2 * kHandleRadius));
      if (h.rotate) painter.drawEllipse(p, kHandleRadius, kHandleRadius);
      else painter.drawRect(box);
      painter.setPen(Qt::white);
      painter.drawText(box, Qt::AlignCenter, QString::fromLatin1(h.label));
    }
  }
  Qt::CursorShape cursor() const override { return Qt::ArrowCursor; }

 private:
  GizmoHandle handleAt(const QPointF& w) const {
    for (auto h : {GizmoHandle::TranslateX, GizmoHandle::TranslateY, GizmoHandle::TranslateZ, GizmoHandle::RotateX,
                   GizmoHandle::RotateY, GizmoHandle::RotateZ}) {
      const QPointF p = gizmoHandlePosition(view_, h);
      if (!p.isNull() && QLineF(w, p).length() <= kHandleRadius + 3) return h;
    }
    return GizmoHandle::None;
  }
  void drag(const QPointF& w) {
    const auto& c = view_.caseData();
    const Pose& p0 = startPose_;
    const Eigen::Vector3d g0 = p0.apply(c->organ->centreOfGravity);
    const QPointF a = view_.toFrame(startMouse_), b = view_.toFrame(w);
    const double du = b.x() - a.x(), dv = b.y() - a.y();
    const auto& cam = c->camera;
    Pose p = p0;
    QString text;
    auto rotate = [&](int axis, double angle) { p = p0.turnedAbout(axisRotation(axis, angle), g0); };  // the centre stays put
    switch (active_) {
      case GizmoHandle::TranslateX: p.t.x() += du * g0.z() / cam.fx(); text = QObject::tr("Move along camera X"); break;
      case GizmoHandle::TranslateY: p.t.y() += dv * g0.z() / cam.fy(); text = QObject::tr("Move along camera Y"); break;
      case GizmoHandle::TranslateZ: p.t.z() -= dv * g0.z() / cam.fy(); text = QObject::tr("Move along camera Z"); break;
      case GizmoHandle::RotateX: rotate(0, dv * kRotationPerPixel); text = QObject::tr("Rotate about camera X"); break;
      case GizmoHandle::RotateY: rotate(1, du * kRotationPerPixel); text = QObject::tr("Rotate about camera Y"); break;
      case GizmoHandle::RotateZ: {
        const Eigen::Vector2d o = cam.project(g0);
        const double a0 = std::atan2(a.y() - o.y(), a.x() - o.x()), a1 = std::atan2(b.y() - o.y(), b.x() - o.x());
        rotate(2, std::remainder(a1 - a0, 2 * M_PI));
        text = QObject::tr("Rotate about camera Z");
        break;
      }
      default: return;
    }
    emit view_.poseEdited(p, text, merge_);
  }

  GizmoHandle active_ = GizmoHandle::None;
  Pose startPose_;
  QPointF startMouse_;
  int merge_ = -1;
};

}  // namespace
}  // namespace rehearse::ui::tools

namespace rehearse::ui {

std::optional<Pose> nudgedPose(const app::Case& c, int key, bool shift) {
  if (!c.hasPose) return std::nullopt;
  const double step = shift ? 0.010 : 0.001, angle = (shift ? 5.0 : 1.0) * M_PI / 180;
  Pose p = c.pose;
  const Eigen::Vector3d g = p.apply(c.organ->centreOfGravity);
  auto rotate = [&](int axis, double a) { p = p.turnedAbout(tools::axisRotation(axis, a), g); };
  switch (key) {
    case Qt::Key_Left: p.t.x() -= step; break;
    case Qt::Key_Right: p.t.x() += step; break;
    case Qt::Key_Up: p.t.y() -= step; break;
    case Qt::Key_Down: p.t.y() += step; break;
    case Qt::Key_PageUp: p.t.z() += step; break;
    case Qt::Key_PageDown: p.t.z() -= step; break;
    case Qt::Key_W: rotate(0, -angle); break;
    case Qt::Key_S: rotate(0, angle); break;
    case Qt::Key_A: rotate(1, -angle); break;
    case Qt::Key_D: rotate(1, angle); break;
    case Qt::Key_Q: rotate(2, -angle); break;
    case Qt::Key_E: rotate(2, angle); break;
    default: return std::nullopt;
  }
  return p;
}

}  // namespace rehearse::ui

namespace rehearse::ui::tools {

std::unique_ptr<FrameTool> makeGizmoTool(FrameView& view) { return std::make_unique<GizmoTool>(view); }

QPointF gizmoHandlePosition(const FrameView& view, GizmoHandle h) {
  const Eigen::Vector3d g = cogCamera(view);
  if (g.z() <= 0 || !view.caseData()) return {};
  const Eigen::Vector2d uv = view.caseData()->camera.project(g);
  const QPointF p = view.toWidget(QPointF(uv.x(), uv.y()));
  switch (h) {
    case GizmoHandle::TranslateX: return p + QPointF(95, 0);
    case GizmoHandle::TranslateY: return p + QPointF(0, 95);
    case GizmoHandle::TranslateZ: return p + QPointF(-67, 67);
    case GizmoHandle::RotateX: return p + QPointF(0, -130);
    case GizmoHandle::RotateY: return p + QPointF(-130, 0);
    case GizmoHandle::RotateZ: return p + QPointF(92, -92);
    default: return p;
  }
}

}  // namespace rehearse::ui::tools
