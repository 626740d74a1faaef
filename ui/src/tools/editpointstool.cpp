// Editing contour points: drag a point (one undo step per drag), Ctrl+click inserts on the nearest edge,
// right click deletes (a segment left with one point goes).
#include "tools.hpp"

#include <QMouseEvent>
#include <QPainter>

#include <optional>

namespace rehearse::ui::tools {
namespace {

constexpr double kPickRadius = 9;  // widget px

class EditPointsTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF& w, const Eigen::Vector2d& f) override {
    const auto hit = pointNear(w);
    if (e->button() == Qt::RightButton && hit) {
      imaging::Contour c = view_.currentContour();
      auto& s = c.segments[hit->first];
      s.points.erase(s.points.begin() + hit->second);
      if (s.points.size() < 2) c.segments.erase(c.segments.begin() + hit->first);
      emit view_.contourEdited(c, QObject::tr("Delete point"), -1);
    } else if (e->button() == Qt::LeftButton && (e->modifiers() & Qt::ControlModifier)) {
      insertAt(w, f);
    } else if (e->button() == Qt::LeftButton && hit) {
      drag_ = hit;
      working_ = view_.currentContour();
      merge_ = view_.nextMergeId();
    }
    return true;
  }
  void move(const QPointF&, const Eigen::Vector2d& f) override {
    if (!drag_) return;
    working_.segments[drag_->first].points[drag_->second] = f;
    emit view_.contourEdited(working_, QObject::tr("Move point"), merge_);
  }
  void release(QMouseEvent*) override { drag_.reset(); }
  void paint(QPainter& p) override { paintContourPoints(view_, p); }

 private:
  std::optional<std::pair<int, int>> pointNear(const QPointF& w) const {
    const auto c = view_.currentContour();
    std::optional<std::pair<int, int>> best;
    double bestD = kPickRadius;
    for (int s = 0; s < static_cast<int>(c.segments.size()); ++s)
      for (int i = 0; i < static_cast<int>(c.segments[s].points.size()); ++i) {
        const auto& p = c.segments[s].points[i];
        const double d = QLineF(w, view_.toWidget(QPointF(p.x(), p.y()))).length();
        if (d <= bestD) {
          bestD = d;
          best = std::make_pair(s, i);
        }
      }
    return best;
  }
  void insertAt(const QPointF& w, const Eigen::Vector2d& f) {
    imaging::Contour c = view_.currentContour();
    double best = kPickRadius * 2;
    int bs = -1, bi = -1;
    for (int s = 0; s < static_cast<int>(c.segments.size()); ++s)
      for (int i = 0; i + 1 < static_cast<int>(c.segments[s].points.size()); ++i) {
        const auto& a = c.segments[s].points[i];
        const auto& b = c.segments[s].points[i + 1];
        const QPointF wa = view_.toWidget(QPointF(a.x(), a.y())), wb = view_.toWidget(QPointF(b.x(), b.y()));
        const QPointF ab = wb - wa;
        const double len2 = QPointF::dotProduct(ab, ab);
        const double t = len2 > 0 ? std::clamp(QPointF::dotProduct(w - wa, ab) / len2, 0.0, 1.0) : 0;
        const double d = QLineF(w, wa + t * ab).length();
        if (d < best) {
          best = d;
          bs = s;
          bi = i;
        }
      }
    if (bs < 0) return;
    c.segments[bs].points.insert(c.segments[bs].points.begin() + bi + 1, f);
    emit view_.contourEdited(c, QObject::tr("Insert point"), -1);
  }

  std::optional<std::pair<int, int>> drag_;
  imaging::Contour working_;  ///< the contour during a drag
  int merge_ = -1;
};

}  // namespace

std::unique_ptr<FrameTool> makeEditPointsTool(FrameView& view) { return std::make_unique<EditPointsTool>(view); }

}  // namespace rehearse::ui::tools
