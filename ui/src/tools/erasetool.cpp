// Erasing contour points under the cursor while the button is held (one undo step per stroke); a segment
// cut in two becomes two segments, pieces of one point go.
#include "tools.hpp"

#include <QMouseEvent>

namespace rehearse::ui::tools {
namespace {

constexpr double kEraseRadius = 14;  // widget px

class EraseTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF& w, const Eigen::Vector2d&) override {
    if (e->button() != Qt::LeftButton) return true;
    erasing_ = true;
    working_ = view_.currentContour();
    merge_ = view_.nextMergeId();
    eraseAt(w);
    return true;
  }
  void move(const QPointF& w, const Eigen::Vector2d&) override {
    if (erasing_) eraseAt(w);
  }
  void release(QMouseEvent*) override { erasing_ = false; }

 private:
  void eraseAt(const QPointF& w) {
    std::vector<imaging::ContourSegment> out;
    bool changed = false;
    for (const auto& s : working_.segments) {
      imaging::ContourSegment piece = s;
      piece.points.clear();
      piece.closed = false;
      for (const auto& p : s.points) {
        if (QLineF(w, view_.toWidget(QPointF(p.x(), p.y()))).length() <= kEraseRadius) {
          changed = true;
          if (piece.points.size() >= 2) out.push_back(piece);
          piece.points.clear();
        } else {
          piece.points.push_back(p);
        }
      }
      if (piece.points.size() >= 2) out.push_back(piece);
      else if (!piece.points.empty()) changed = true;
    }
    if (!changed) return;
    working_.segments = out;
    emit view_.contourEdited(working_, QObject::tr("Erase"), merge_);
  }

  bool erasing_ = false;
  imaging::Contour working_;
  int merge_ = -1;
};

}  // namespace

std::unique_ptr<FrameTool> makeEraseTool(FrameView& view) { return std::make_unique<EraseTool>(view); }

}  // namespace rehearse::ui::tools
