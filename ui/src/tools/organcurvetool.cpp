// The organ curve of a sketched ridge or ligament (step 5): clicks on the organ drawn over the frame, joined
// by shortest paths along the surface, give the nearest sketched ridge or ligament its 3D curve (volume
// nodes), which the elastic fit then holds onto the sketch. Backspace takes back a click; Enter, a double
// click, a right click or another tool end it; all clicks of one curve are one undo step.
#include "tools.hpp"

#include <rehearse/simcore/registration.hpp>

#include <QKeyEvent>
#include <QMouseEvent>

#include <limits>

namespace rehearse::ui::tools {
namespace {

class OrganCurveTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF&, const Eigen::Vector2d& f) override {
    if (e->button() == Qt::LeftButton) pick(f);
    else if (e->button() == Qt::RightButton) finish();
    return true;
  }
  bool doubleClick() override {
    finish();
    return true;
  }
  bool key(QKeyEvent* e) override {
    if (e->key() != Qt::Key_Backspace || segment_ < 0) return false;
    // Take back the last click's stretch of the organ curve.
    imaging::Contour c = view_.currentContour();
    if (segment_ < static_cast<int>(c.segments.size()) && !c.segments[segment_].modelVertices.empty()) {
      auto& mv = c.segments[segment_].modelVertices;
      mv.resize(stops_.size() > 1 ? stops_[stops_.size() - 2] : 0);
      if (!stops_.empty()) stops_.pop_back();
      emit view_.contourEdited(c, QObject::tr("Pick organ curve"), merge_);
    }
    return true;
  }
  void finish() override {
    if (segment_ >= 0) emit view_.toolMessage(QObject::tr("Organ curve done; the fit (F9) holds it onto the sketched curve."));
    segment_ = -1;
    merge_ = -1;
    stops_.clear();
  }
  bool abandon() override {
    if (segment_ < 0) return false;
    finish();  // what was clicked stays (Ctrl+Z takes it back)
    return true;
  }

 private:
  void pick(const Eigen::Vector2d& f) {
    const auto hit = view_.organAt(f);
    if (!hit) {
      emit view_.toolMessage(QObject::tr("Click on the organ drawn over the frame, along the ridge or ligament."));
      return;
    }
    imaging::Contour c = view_.currentContour();
    if (segment_ < 0 || segment_ >= static_cast<int>(c.segments.size())) {
      // The first click chooses the sketched ridge or ligament nearest to it; its organ curve starts anew.
      double best = std::numeric_limits<double>::infinity();
      int target = -1;
      for (int i = 0; i < static_cast<int>(c.segments.size()); ++i) {
        if (c.segments[i].isSilhouette()) continue;
        for (const auto& p : c.segments[i].points)
          if ((p - f).norm() < best) {
            best = (p - f).norm();
            target = i;
          }
      }
      if (target < 0) {
        emit view_.toolMessage(QObject::tr("Sketch the ridge or ligament on the frame first (step 3, new segments: Ridge or Ligament)."));
        return;
      }
      segment_ = target;
      merge_ = view_.nextMergeId();
      stops_.clear();
      c.segments[target].modelVertices.clear();
    }
    auto& seg = c.segments[segment_];
    auto& mv = seg.modelVertices;
    if (mv.empty()) {
      mv.push_back(hit->node);
    } else {
      // Joined to the previous click by the shortest path along the surface (rest shape).
      const auto& organ = *view_.caseData()->organ;
      const auto path = simcore::surfacePath(organ.surface, organ.volume.points, mv.back(), hit->node);
      if (path.size() > 1) mv.insert(mv.end(), path.begin() + 1, path.end());
    }
    stops_.push_back(mv.size());
    emit view_.contourEdited(c, QObject::tr("Pick organ curve"), merge_);
    emit view_.toolMessage(QObject::tr("%1: %2 nodes on the organ. Click on along it; Backspace takes back a click, Enter or a double click ends.")
                               .arg(QString::fromStdString(seg.type))
                               .arg(mv.size()));
  }

  int segment_ = -1;  ///< the ridge or ligament whose organ curve is being picked
  int merge_ = -1;
  std::vector<std::size_t> stops_;  ///< the curve's length after each click (for Backspace)
};

}  // namespace

std::unique_ptr<FrameTool> makeOrganCurveTool(FrameView& view) { return std::make_unique<OrganCurveTool>(view); }

}  // namespace rehearse::ui::tools
