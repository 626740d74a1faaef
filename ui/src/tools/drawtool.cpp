// Drawing a contour segment: freehand (press, drag, release) or click by click (Enter, a double click or
// another tool ends it; right click takes back the last point). Segments get the type set in step 3 and,
// when asked, snap to image edges.
#include "tools.hpp"

#include <QMouseEvent>
#include <QPainter>

namespace rehearse::ui::tools {
namespace {

class DrawTool final : public FrameTool {
 public:
  DrawTool(FrameView& v, bool freehand) : FrameTool(v), freehand_(freehand) {}

  bool press(QMouseEvent* e, const QPointF&, const Eigen::Vector2d& f) override {
    if (freehand_) {
      if (e->button() != Qt::LeftButton) return true;
      drawing_ = true;
      draft_ = {f};
    } else if (e->button() == Qt::LeftButton) {
      drawing_ = true;
      draft_.push_back(f);
    } else if (e->button() == Qt::RightButton && !draft_.empty()) {
      draft_.pop_back();
    }
    view_.update();
    return true;
  }
  void move(const QPointF&, const Eigen::Vector2d& f) override {
    if (!freehand_ || !drawing_) return;
    if ((f - draft_.back()).norm() * view_.scale() >= 2.0) {
      draft_.push_back(f);
      view_.update();
    }
  }
  void release(QMouseEvent* e) override {
    if (freehand_ && drawing_ && e->button() == Qt::LeftButton) finish();
  }
  bool doubleClick() override {
    if (freehand_ || !drawing_) return false;
    finish();
    return true;
  }
  void finish() override {
    if (draft_.size() >= 2) {
      imaging::Contour c = view_.currentContour();
      c.segments.push_back({snapped(draft_), false, view_.toolSettings().newSegmentType, {}});
      emit view_.contourEdited(c, freehand_ ? QObject::tr("Draw segment") : QObject::tr("Add segment"), -1);
    }
    draft_.clear();
    drawing_ = false;
    view_.update();
  }
  bool abandon() override {
    if (!drawing_) return false;
    draft_.clear();
    drawing_ = false;
    view_.update();
    return true;
  }
  void paint(QPainter& p) override {
    if (!freehand_) paintContourPoints(view_, p);
    if (draft_.empty()) return;
    QPolygonF poly;
    for (const auto& q : draft_) poly << view_.toWidget(QPointF(q.x(), q.y()));
    p.setPen(QPen(QColor(60, 230, 255), 2.5));
    p.setBrush(Qt::NoBrush);
    p.drawPolyline(poly);
  }

 private:
  std::vector<Eigen::Vector2d> snapped(const std::vector<Eigen::Vector2d>& pts) const {
    const auto& c = view_.caseData();
    if (!view_.toolSettings().snapToEdges || !c || c->frame.empty() || pts.size() < 2) return pts;
    imaging::ContourSegment s{pts, false, view_.toolSettings().newSegmentType, {}};
    return imaging::snapToEdges(c->frame, imaging::resampleSegment(s, 30.0).points);
  }

  bool freehand_;
  bool drawing_ = false;
  std::vector<Eigen::Vector2d> draft_;  ///< frame pixels
};

}  // namespace

std::unique_ptr<FrameTool> makeDrawTool(FrameView& view, bool freehand) { return std::make_unique<DrawTool>(view, freehand); }

QColor segmentColour(const std::string& type) {
  if (type == "ridge") return QColor(255, 130, 50);
  if (type == "ligament") return QColor(200, 130, 255);
  return QColor(255, 220, 40);
}

void paintContourPoints(const FrameView& view, QPainter& p) {
  p.setPen(QPen(QColor(30, 30, 30), 1));
  p.setBrush(QColor(255, 220, 40));
  for (const auto& s : view.currentContour().segments)
    for (const auto& q : s.points) p.drawEllipse(view.toWidget(QPointF(q.x(), q.y())), 3.5, 3.5);
}

}  // namespace rehearse::ui::tools
