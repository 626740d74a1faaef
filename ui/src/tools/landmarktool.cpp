// Landmark pairs (step 4): a click on the organ picks the model point, the next click on the frame picks
// where it is in the image; the rigid page keeps the pairs and solves the pose.
#include "tools.hpp"

#include <QMouseEvent>

namespace rehearse::ui::tools {
namespace {

class LandmarkTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;
  bool press(QMouseEvent* e, const QPointF&, const Eigen::Vector2d& f) override {
    if (e->button() != Qt::LeftButton) return true;
    const auto& l = view_.landmarks();
    if (!l.empty() && !l.back().hasImage) emit view_.landmarkImagePicked(f);
    else if (const auto hit = view_.organAt(f)) emit view_.landmarkModelPicked(hit->model);
    return true;
  }
};

}  // namespace

std::unique_ptr<FrameTool> makeLandmarkTool(FrameView& view) { return std::make_unique<LandmarkTool>(view); }

}  // namespace rehearse::ui::tools
