#pragma once
// A frame-view tool: what a mouse press, drag, release, double click or key does on the frame, and what the
// tool draws over it. One class per tool (ui/src/tools/): drawing a contour (freehand or click by click),
// editing points, erasing, the rigid-alignment gizmo, landmarks, the organ curve of a ridge or ligament,
// attachment picking; the rehearsal's instruments (grasp, pull, cut) are tools too. A tool never edits
// the case: it emits the edited contour, pose or attachments through the view's signals and the window
// (CaseDocument) turns them into undoable commands. Panning (middle button) and zoom (wheel) are the view's.
#include <Eigen/Core>

#include <Qt>

class QKeyEvent;
class QMouseEvent;
class QWheelEvent;
class QPainter;
class QPointF;

namespace rehearse::ui {

class FrameView;

class FrameTool {
 public:
  explicit FrameTool(FrameView& view) : view_(view) {}
  virtual ~FrameTool() = default;
  FrameTool(const FrameTool&) = delete;
  FrameTool& operator=(const FrameTool&) = delete;

  /// A button pressed on the frame at widget position `w` (frame pixel `f`); false: the view pans instead.
  virtual bool press(QMouseEvent* e, const QPointF& w, const Eigen::Vector2d& f) = 0;
  virtual void move(const QPointF& /*w*/, const Eigen::Vector2d& /*f*/) {}
  virtual void release(QMouseEvent* /*e*/) {}
  /// True when the tool used the double click.
  virtual bool doubleClick() { return false; }
  /// True when the tool used the key.
  virtual bool key(QKeyEvent* /*e*/) { return false; }
  /// True when the tool used the wheel (the instruments: the tip along the view ray); else the view zooms.
  virtual bool wheel(QWheelEvent* /*e*/) { return false; }
  /// Ends the work in progress (a click-by-click segment, an organ curve): Enter, another tool, a new case.
  virtual void finish() {}
  /// Drops the work in progress without committing it (Esc); true when there was some.
  virtual bool abandon() { return false; }
  /// The simulation's jaws as its last frame has them: closed and holding tissue (`holding`), or closed on nothing
  /// (the tissue slipped out of them, or they closed where there was none): a grasp under way ends.
  virtual void jawsSeen(bool /*closed*/, bool /*holding*/) {}
  /// Draws over the frame, in widget coordinates.
  virtual void paint(QPainter& /*p*/) {}
  /// Draws what the tool leaves on the frame while another one is in use (the grasper's closed jaws).
  virtual void paintIdle(QPainter& /*p*/) {}
  /// The tool is taken (true) or another one is (false), after finish() when that was called.
  virtual void setActive(bool /*active*/) {}
  virtual Qt::CursorShape cursor() const { return Qt::CrossCursor; }
  /// True while work the tool started runs on a worker (a stroke snapping to image edges).
  virtual bool busy() const { return false; }

 protected:
  FrameView& view_;
};

}  // namespace rehearse::ui
