// The scissors (step 7): press on the organ drawn over the frame to open the cut there, drag to cut, release
// to stop. The blade lies on the shaft, from the tip back towards the trocar; the shaft goes through the surface
// under the cursor (at the pressed point's depth) and the tip lies beyond it by most of the blade's length (so the
// blade spans the tissue in front of it, and the incision opens under the cursor); the wheel moves the tip along the
// shaft, 2 mm a notch. (With the tip 20 mm behind the surface along the view ray, the shaft from an off-axis trocar
// crossed the surface 25-50 px beside the stroke on the phantom: the cut opened where the surgeon had not drawn.)
// Every input goes to the simulation session as a timestamped event (camera frame), so it is recorded with the run.
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
    const auto hit = view_.liveSurfaceAt(f, FrameView::SurfacePick::OuterPoint);
    if (!hit) {
      // A stroke may start beside the organ (a surgeon brings the open blades to the tissue): the cut opens where the
      // drag first reaches it. (A press just off the organ's edge said "Press on the organ" and the drag across it then
      // cut nothing: a person's check.)
      reaching_ = true;
      emit view_.toolMessage(QObject::tr("Not on the organ yet: drag onto it to start the cut there."));
      return true;
    }
    start(f, hit->z());
    return true;
  }
  void move(const QPointF&, const Eigen::Vector2d& f) override {
    if (reaching_) {
      if (const auto hit = view_.liveSurfaceAt(f, FrameView::SurfacePick::OuterPoint)) start(f, hit->z());
      return;
    }
    if (!cutting_) return;
    // The shaft through the organ's outer surface under the cursor as it is now (it bulges towards the camera and
    // falls away: at the pressed depth, the shaft crossed the surface 57 px above a stroke across the phantom's
    // middle); not deeper than 5 mm past the last (the ray through the opened incision meets its far wall, or the
    // organ's back), and kept off the organ.
    if (const auto hit = view_.liveSurfaceAt(f, FrameView::SurfacePick::OuterPoint); hit && hit->z() < surfaceDepth_ + 0.005) surfaceDepth_ = hit->z();
    path_.push_back(f);
    send(simcore::InputKind::ToolPose, tipAt(f), false);
    sayWhatLiesBeyond(f);
  }
  void release(QMouseEvent*) override {
    if (reaching_) {
      reaching_ = false;
      emit view_.toolMessage(QObject::tr("Nothing was cut: the stroke did not reach the organ."));
      return;
    }
    if (!cutting_) return;
    cutting_ = false;
    send(simcore::InputKind::Cut, tipAt(path_.back()), false);
    retractInstrument(view_, tipAt(path_.back()), 1);
    emit view_.toolMessage(QObject::tr("Cut ended."));
  }
  bool abandon() override {
    if (reaching_) {
      reaching_ = false;
      return true;
    }
    if (!cutting_) return false;
    release(nullptr);
    return true;
  }
  bool wheel(QWheelEvent* e) override {
    if (!cutting_) {
      // A press that missed the organ holds no blade: the wheel then is a person reaching for depth, not a zoom (the
      // view had shrunk to a corner under 15 notches).
      if (!reaching_ && !(e->buttons() & Qt::LeftButton)) return false;
      emit view_.toolMessage(
          QObject::tr("The scissors are not cutting yet: drag onto the organ to start the cut; the wheel then takes "
                      "the blade deeper or shallower."));
      return true;
    }
    depth_ = std::max(1e-3, depth_ - 0.002 * e->angleDelta().y() / 120.0);
    send(simcore::InputKind::ToolPose, tipAt(path_.back()), false);
    said_.clear();  // a structure still out of reach is said again at the new depth
    emit view_.toolMessage(QObject::tr("Cutting %1 mm deep.").arg(1e3 * depth_, 0, 'f', 0));
    sayWhatLiesBeyond(path_.back());
    view_.update();
    return true;
  }
  void paint(QPainter& painter) override {
    if (!cutting_ || path_.size() < 2) return;
    painter.setPen(QPen(QColor(230, 60, 60), 2, Qt::DashLine));
    QPolygonF line;
    for (const auto& f : path_) line << view_.toWidget(QPointF(f.x(), f.y()));
    painter.drawPolyline(line);
    // The blade's depth beside the cursor (a person cut six strokes over the drawn vessels at the default depth and
    // nothing said how deep the blade went).
    painter.setPen(QColor(255, 235, 235));
    painter.drawText(line.back() + QPointF(12, -10), QObject::tr("%1 mm deep").arg(1e3 * depth_, 0, 'f', 0));
  }
  Qt::CursorShape cursor() const override { return Qt::CrossCursor; }

 private:
  /// Opens the cut at frame pixel `f`, the organ's outer surface there at camera depth `z`.
  void start(const Eigen::Vector2d& f, double z) {
    reaching_ = false;
    surfaceDepth_ = z;
    depth_ = kBladeDepth;
    cutting_ = true;
    path_.clear();
    path_.push_back(f);
    send(simcore::InputKind::ToolPose, tipAt(f), false);
    send(simcore::InputKind::Cut, tipAt(f), true);
    said_.clear();
    emit view_.toolMessage(QObject::tr("Cutting %1 mm deep: drag across the organ, release to stop (wheel: deeper or "
                                       "shallower).")
                               .arg(1e3 * depth_, 0, 'f', 0));
    sayWhatLiesBeyond(f);
  }
  static constexpr double kBladeDepth = 0.02;  ///< m beyond the pressed surface point (the blade is 30 mm)
  static constexpr double kBeyond = 0.002;     ///< m past the tip before a structure is said to be out of its reach
  /// The tip for the cursor at frame pixel `f`: on the line from the trocar through the point under the cursor at the
  /// pressed surface's depth, depth_ beyond it (along the view ray when no trocar is known or it lies beyond the point).
  Eigen::Vector3d tipAt(const Eigen::Vector2d& f) const {
    return pointAtDepth(view_, f, surfaceDepth_) + depth_ * shaftAt(f);
  }
  /// The shaft's direction (unit, into the tissue) for the cursor at `f`.
  Eigen::Vector3d shaftAt(const Eigen::Vector2d& f) const {
    const Eigen::Vector3d at = pointAtDepth(view_, f, surfaceDepth_);
    Eigen::Vector3d along = at.normalized();
    if (const auto& trocar = view_.trocar()) {
      const Eigen::Vector3d shaft = at - *trocar;
      if (shaft.norm() > 1e-6 && shaft.normalized().dot(along) > 0.1) along = shaft.normalized();
    }
    return along;
  }
  /// Says once a stroke (and again after the wheel) a vessel or duct on the blade's line under the cursor that lies past
  /// its tip (by more than 2 mm: an element the tip reaches into is cut with its faces, and a person read "lies 17 mm,
  /// past the blade's 17 mm" over a vessel the stroke cut): the view draws the structures through the tissue, and a
  /// stroke over one at the default depth cut nothing and said nothing. Depths along the shaft from the surface, as the
  /// blade's own.
  void sayWhatLiesBeyond(const Eigen::Vector2d& f) {
    const auto s = structureAlong(view_, pointAtDepth(view_, f, surfaceDepth_), shaftAt(f), 0.0, 0.15);
    if (!s || s->entry <= depth_ + kBeyond || std::find(said_.begin(), said_.end(), s->label) != said_.end()) return;
    said_.push_back(s->label);
    emit view_.toolMessage(QObject::tr("The %1 here lies %2 mm deep along the shaft, past the blade's %3 mm: wheel down "
                                       "(towards you) to cut deeper.")
                               .arg(QString::fromStdString(s->name))
                               .arg(1e3 * s->entry, 0, 'f', 0)
                               .arg(1e3 * depth_, 0, 'f', 0));
  }
  void send(simcore::InputKind kind, const Eigen::Vector3d& tip, bool on) { postInstrument(view_, kind, tip, on, 1); }
  bool cutting_ = false;
  bool reaching_ = false;  ///< pressed beside the organ: the cut opens where the drag reaches it
  double surfaceDepth_ = 0;  ///< m: the pressed surface point's depth (camera z)
  double depth_ = 0;         ///< m: the tip beyond the surface along the shaft
  std::vector<Eigen::Vector2d> path_;
  std::vector<int> said_;  ///< the structures said to lie past the blade in this stroke at this depth
};

}  // namespace

std::unique_ptr<FrameTool> makeScissorsTool(FrameView& view) { return std::make_unique<ScissorsTool>(view); }

}  // namespace rehearse::ui::tools
