// Drawing a contour segment: freehand (press, drag, release) or click by click (Enter, a double click or
// another tool ends it; right click takes back the last point). Segments get the type set in step 3 and,
// when asked, snap to image edges: on a worker (intelligent scissors take seconds on a 4k frame), the
// stroke drawn dashed until its snapped segment joins the contour as one undo step.
#include "tools.hpp"

#include <QFutureWatcher>
#include <QMouseEvent>
#include <QPainter>
#include <QtConcurrent/QtConcurrent>

#include <list>

namespace rehearse::ui::tools {
namespace {

// The stroke's runs inside the frame ([-0.5, width - 0.5] x [-0.5, height - 0.5], pixel centres at integers), each
// ended where it crosses the frame's edge (Liang-Barsky on each stretch). What lies outside is not the organ's outline:
// where the organ reaches past the frame, the frame's edge cuts it, and a hand drawing round it strays there.
std::vector<std::vector<Eigen::Vector2d>> insideTheFrame(const std::vector<Eigen::Vector2d>& stroke, double width,
                                                         double height) {
  const Eigen::Vector2d lo(-0.5, -0.5), hi(width - 0.5, height - 0.5);
  auto onto = [&](const Eigen::Vector2d& p) -> Eigen::Vector2d { return p.cwiseMax(lo).cwiseMin(hi); };
  auto inside = [&](const Eigen::Vector2d& p) { return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all(); };
  std::vector<std::vector<Eigen::Vector2d>> runs;
  std::vector<Eigen::Vector2d> run;
  auto endRun = [&] {
    if (run.size() >= 2) runs.push_back(run);
    run.clear();
  };
  for (std::size_t i = 0; i < stroke.size(); ++i) {
    if (i == 0) {
      if (inside(stroke[0])) run.push_back(stroke[0]);
      continue;
    }
    const Eigen::Vector2d a = stroke[i - 1], d = stroke[i] - stroke[i - 1];
    double t0 = 0, t1 = 1;
    bool crosses = true;
    for (int k = 0; k < 2 && crosses; ++k) {
      for (const auto& [q, bound] : {std::pair{-d[k], a[k] - lo[k]}, std::pair{d[k], hi[k] - a[k]}}) {
        if (q == 0) {
          if (bound < 0) crosses = false;  // parallel to this edge, outside it
          continue;
        }
        const double t = bound / q;
        if (q < 0) t0 = std::max(t0, t);
        else t1 = std::min(t1, t);
      }
    }
    if (!crosses || t0 > t1) {  // wholly outside
      endRun();
      continue;
    }
    if (t0 > 0) {  // enters the frame here
      endRun();
      run.push_back(onto(a + t0 * d));
    } else if (run.empty()) {
      run.push_back(onto(a));
    }
    run.push_back(onto(a + t1 * d));
    if (t1 < 1) endRun();  // leaves it here
  }
  endRun();
  return runs;
}

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
      const auto& c = view_.caseData();
      // Only what lies inside the frame is kept, in as many pieces as the stroke had there (a person drew round an
      // organ that reaches past the frame's edge: the whole stroke was kept, and the fit then refused the contour).
      std::vector<std::vector<Eigen::Vector2d>> pieces{draft_};
      if (c && !c->frame.empty()) pieces = insideTheFrame(draft_, c->frame.cols, c->frame.rows);
      if (pieces.size() != 1 || pieces.front() != draft_) {
        emit view_.toolMessage(
            // (Short: the status bar's line is narrow. The frame's edge is not the organ's outline.)
            pieces.empty()       ? QObject::tr("Stroke outside the frame: nothing drawn.")
            : pieces.size() == 1 ? QObject::tr("Stroke past the frame's edge: the part inside kept.")
                                 : QObject::tr("Stroke past the frame's edge: %1 parts inside kept as segments.")
                                       .arg(pieces.size()));
      }
      if (view_.toolSettings().snapToEdges && c && !c->frame.empty())
        for (const auto& piece : pieces) snapOnWorker(c->frame, piece);
      else if (!pieces.empty())
        addSegments(pieces, freehand_ ? QObject::tr("Draw segment") : QObject::tr("Add segment"));
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
  bool busy() const override { return !snapping_.empty(); }
  void paint(QPainter& p) override {
    if (!freehand_) paintContourPoints(view_, p);
    for (const auto& s : snapping_) {  // strokes waiting for their snapped segment
      QPolygonF poly;
      for (const auto& q : s.stroke) poly << view_.toWidget(QPointF(q.x(), q.y()));
      p.setPen(QPen(QColor(60, 230, 255), 2.0, Qt::DashLine));
      p.setBrush(Qt::NoBrush);
      p.drawPolyline(poly);
    }
    if (draft_.empty()) return;
    QPolygonF poly;
    for (const auto& q : draft_) poly << view_.toWidget(QPointF(q.x(), q.y()));
    p.setPen(QPen(QColor(60, 230, 255), 2.5));
    p.setBrush(Qt::NoBrush);
    p.drawPolyline(poly);
  }

 private:
  struct Snapping {
    std::vector<Eigen::Vector2d> stroke;
    const uchar* frame = nullptr;  ///< which frame it snaps to (the segment is dropped if the frame changes)
    std::string type;
  };

  void addSegment(const std::vector<Eigen::Vector2d>& points, const QString& text, const std::string& type = {}) {
    addSegments({points}, text, type);
  }
  // The pieces join the contour as one undo step.
  void addSegments(const std::vector<std::vector<Eigen::Vector2d>>& pieces, const QString& text,
                   const std::string& type = {}) {
    imaging::Contour c = view_.currentContour();
    for (const auto& points : pieces)
      c.segments.push_back({points, false, type.empty() ? view_.toolSettings().newSegmentType : type, {}});
    emit view_.contourEdited(c, text, -1);
  }

  void snapOnWorker(const cv::Mat3b& frame, const std::vector<Eigen::Vector2d>& stroke) {
    imaging::ContourSegment s{stroke, false, view_.toolSettings().newSegmentType, {}};
    const auto anchors = imaging::resampleSegment(s, 30.0).points;
    auto it = snapping_.insert(snapping_.end(), Snapping{stroke, frame.data, s.type});
    auto* watcher = new QFutureWatcher<std::vector<Eigen::Vector2d>>(&guard_);
    QObject::connect(watcher, &QFutureWatcherBase::finished, &guard_, [this, watcher, it] {
      watcher->deleteLater();
      const Snapping job = *it;
      snapping_.erase(it);
      const auto& c = view_.caseData();
      std::vector<Eigen::Vector2d> points;
      try {
        points = watcher->result();
      } catch (const std::exception&) {
        points.clear();
      }
      if (!c || c->frame.data != job.frame) {
        emit view_.toolMessage(QObject::tr("The frame changed while the stroke was snapping to its edges; draw it again."));
      } else if (points.size() < 2) {
        addSegment(job.stroke, QObject::tr("Draw segment"), job.type);
        emit view_.toolMessage(QObject::tr("No image edge was found along the stroke; it was kept as drawn."));
      } else {
        addSegment(points, QObject::tr("Draw segment (snapped to edges)"), job.type);
      }
      view_.update();
    });
    cv::Mat3b image = frame;  // shares the pixels (reference counted); the case never writes a frame in place
    watcher->setFuture(QtConcurrent::run([image, anchors] { return imaging::snapToEdges(image, anchors); }));
    emit view_.toolMessage(QObject::tr("Snapping the stroke to image edges..."));
  }

  bool freehand_;
  QObject guard_;  ///< owns the snapping watchers: they go with the tool
  std::list<Snapping> snapping_;
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
