// The grasper (step 7): press on the organ drawn over the frame to close the jaws there, drag to pull (the
// tip stays at the depth it bit at, under the cursor), release to open them. Every input goes to the
// simulation session as a timestamped event (camera frame), so it is recorded with the run.
#include "tools.hpp"

#include <rehearse/imaging/render.hpp>

#include <QElapsedTimer>
#include <QKeyEvent>
#include <QMouseEvent>
#include <QPainter>
#include <QWheelEvent>

#include <algorithm>

namespace rehearse::ui::tools {
namespace {

class GraspTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF&, const Eigen::Vector2d& f) override {
    if (e->button() != Qt::LeftButton) return false;
    bite(f);
    return true;
  }
  // Space closes the jaws at the cursor (and opens them again): the keyboard's way to grasp.
  bool key(QKeyEvent* e) override {
    if (e->key() != Qt::Key_Space) return false;
    if (holding_) release(nullptr);
    else bite(hover_, true);
    return true;
  }
  void move(const QPointF&, const Eigen::Vector2d& f) override {
    hover_ = f;
    if (!holding_) return;
    if (resume_) {  // the jaws stay where they are: the cursor's motion from here moves them
      offset_ = jaws_ - pointAtDepth(view_, f, depth_);
      resume_ = false;
    }
    last_ = f;
    send(simcore::InputKind::ToolPose, tipAt(f), false);
  }
  void release(QMouseEvent*) override { letGo(QObject::tr("Released.")); }
  bool abandon() override {
    if (!holding_) return false;
    release(nullptr);
    return true;
  }
  // The simulation's frame shows the jaws closed on nothing: the hold ends and the grasper is withdrawn, as when the
  // button comes up; the drag moves nothing until the next press. After a frame showed them holding tissue, it slipped
  // out; before any did, they closed on none (a person's 1 mm bite missed the tissue and read that it had slipped).
  // (Frames from before the bite's own step show the jaws open or empty: the first 0.3 s after a bite are not taken for
  // either.)
  void jawsSeen(bool closed, bool holding) override {
    if (!holding_ || !closed) return;
    if (holding) {
      heldTissue_ = true;
      return;
    }
    if (!bitten_.isValid() || bitten_.elapsed() < 300) return;
    slipped_ = true;  // (the wheel, meant for the jaws, does not zoom the view until the next bite)
    letGo(heldTissue_ ? QObject::tr("The tissue slipped out of the grasper: the jaws hold nothing and are withdrawn; "
                                    "press on the organ to grasp again.")
                      : QObject::tr("The jaws closed on nothing: no tissue they may hold lay within the jaw bite "
                                    "(Simulation panel) of where they closed; press on the organ again, or widen the "
                                    "bite."));
  }
  // Enter, or a tool other than the scissors taken while the jaws hold: they let go.
  void finish() override {
    if (holding_) release(nullptr);
  }
  // The scissors taken while the jaws hold (Space keeps them closed without a button): the jaws keep their hold where
  // they are while the blade cuts (the session keeps them apart: ToolSettings::jawsKeepTheirHold). Back with the
  // grasper, the drag goes on from where the jaws are, wherever the cursor is.
  void setActive(bool active) override {
    if (!holding_) return;
    if (active) {
      resume_ = true;
      emit view_.toolMessage(QObject::tr("The jaws still hold: drag to pull on, Space or a click lets go."));
    } else {
      emit view_.toolMessage(QObject::tr("The grasper keeps its hold while you cut (R, then Space, lets go)."));
    }
  }
  void paintIdle(QPainter& painter) override { paint(painter); }
  // The wheel while holding: the jaws towards (up) or away from the camera, 2 mm a notch.
  bool wheel(QWheelEvent* e) override {
    if (!holding_) {
      // A press that missed the organ is not a zoom either; nor is the wheel after the tissue slipped out (a person
      // pushing the jaws with the wheel saw the frame zoom once they had slipped): until the next bite it says why.
      if (!(e->buttons() & Qt::LeftButton) && !slipped_) return false;
      emit view_.toolMessage(
          QObject::tr("The jaws hold nothing: press on the organ to grasp it; the wheel then moves them towards or "
                      "away from the camera."));
      return true;
    }
    depth_ = std::max(1e-3, depth_ - 0.002 * e->angleDelta().y() / 120.0);
    send(simcore::InputKind::ToolPose, tipAt(last_), false);
    return true;
  }
  void paint(QPainter& painter) override {
    if (!holding_) return;
    painter.setPen(QPen(QColor(240, 240, 250), 2));
    painter.setBrush(Qt::NoBrush);
    const QPointF at = view_.toWidget(QPointF(last_.x(), last_.y()));
    painter.drawEllipse(at, 7, 7);
    painter.drawLine(at + QPointF(-11, 0), at + QPointF(-4, 0));
    painter.drawLine(at + QPointF(4, 0), at + QPointF(11, 0));
  }
  Qt::CursorShape cursor() const override { return holding_ ? Qt::ClosedHandCursor : Qt::OpenHandCursor; }

 private:
  // The jaws open where they are and the grasper is withdrawn, with the sentence that says why.
  void letGo(const QString& said) {
    if (!holding_) return;
    holding_ = false;
    send(simcore::InputKind::Jaw, tipAt(last_), false);
    retractInstrument(view_, tipAt(last_), 0);
    emit view_.toolMessage(said);
  }
  // `byKey`: Space closed them (no button is held: Space again lets go).
  void bite(const Eigen::Vector2d& f, bool byKey = false) {
    slipped_ = false;  // (a press, on the organ or not, gives the wheel back to the view)
    const auto& c = view_.caseData();
    if (!c || !c->hasPose) {
      emit view_.toolMessage(QObject::tr("The grasper works on the organ placed over the frame: place it first (step 4)."));
      return;
    }
    // Pressed on the organ as the simulation has it now (the case's shape before it runs); the jaws bite at
    // the surface node nearest the pressed point (a coarse mesh's triangle can be wider than the grasp
    // radius: the point itself might hold nothing).
    const auto hit = view_.liveSurfaceAt(f);
    if (!hit) {
      emit view_.toolMessage(QObject::tr("Press on the organ to grasp it."));
      return;
    }
    const Eigen::Vector3d tip = *hit;
    depth_ = tip.z();
    offset_.setZero();
    offset_ = tip - tipAt(f);  // the bite's node need not be under the cursor: the drag moves it by the cursor's motion
    holding_ = true;
    heldTissue_ = false;
    resume_ = false;
    bitten_.start();
    send(simcore::InputKind::ToolPose, tip, false);
    send(simcore::InputKind::Jaw, tip, true);
    last_ = f;
    // (Closed by Space, "release to let go" named a button no one held: a person's check.)
    emit view_.toolMessage(byKey ? QObject::tr("Grasped: move the mouse to pull, Space again to let go.")
                                 : QObject::tr("Grasped: drag to pull, release to let go."));
    return;
  }
  // The tip for frame pixel `f`: the point under it at the depth the jaws bit at (camera frame, m), plus the
  // bite's offset from the pressed point.
  Eigen::Vector3d tipAt(const Eigen::Vector2d& f) const { return pointAtDepth(view_, f, depth_) + offset_; }
  void send(simcore::InputKind kind, const Eigen::Vector3d& tip, bool on) {
    jaws_ = tip;
    postInstrument(view_, kind, tip, on, 0);
  }
  bool holding_ = false;
  bool heldTissue_ = false;  ///< a frame since the bite showed the jaws holding tissue
  bool slipped_ = false;     ///< the jaws let go on their own (a slip, a bite on nothing) since the last bite
  QElapsedTimer bitten_;  ///< since the jaws last closed
  bool resume_ = false;                             ///< taken again while holding: the next drag starts at `jaws_`
  Eigen::Vector3d jaws_ = Eigen::Vector3d::Zero();  ///< where the grasper last put its tip (camera frame, m)
  double depth_ = 0;
  Eigen::Vector3d offset_ = Eigen::Vector3d::Zero();
  Eigen::Vector2d last_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d hover_ = Eigen::Vector2d::Zero();  ///< the cursor's last frame pixel (for Space)
};

}  // namespace

std::unique_ptr<FrameTool> makeGraspTool(FrameView& view) { return std::make_unique<GraspTool>(view); }

void postInstrument(FrameView& view, simcore::InputKind kind, const Eigen::Vector3d& tip, bool on, int tool,
                    int label) {
  simcore::InputEvent e;
  e.kind = kind;
  e.tool = tool;
  e.position = tip;
  e.on = on;
  e.label = label;
  emit view.instrumentInput(e);
}

void retractInstrument(FrameView& view, const Eigen::Vector3d& tip, int tool) {
  const auto& trocar = view.trocar();
  if (!trocar || !tip.allFinite() || (tip - *trocar).norm() < 1e-3) return;
  postInstrument(view, simcore::InputKind::ToolPose, *trocar + 0.2 * (tip - *trocar), false, tool);
}

Eigen::Vector3d pointAtDepth(const FrameView& view, const Eigen::Vector2d& f, double depth) {
  const Eigen::Vector3d ray = view.caseData()->camera.K.inverse() * Eigen::Vector3d(f.x(), f.y(), 1.0);
  return ray * (depth / ray.z());
}

}  // namespace rehearse::ui::tools
