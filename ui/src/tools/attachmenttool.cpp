// Ligament attachments (step 1): a click on the organ drawn over the frame holds the surface nodes within
// the patch radius; a click on a held node's dot releases the held nodes around it (one undo step each). Held nodes
// are drawn orange.
#include "tools.hpp"

#include <QLineF>
#include <QMouseEvent>
#include <QPainter>

#include <algorithm>
#include <iterator>

namespace rehearse::ui::tools {
namespace {

class AttachmentTool final : public FrameTool {
  static constexpr double kDotPickPixels = 6;  ///< a held node's dot is 3.5 px in radius: a click this near is on it

 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF&, const Eigen::Vector2d& f) override {
    if (e->button() == Qt::LeftButton) toggleAt(f);
    return true;
  }
  void paint(QPainter& painter) override {
    const auto& c = view_.caseData();
    if (!c || !c->hasPose) return;
    const SurfaceView sv = c->surfaceView();
    painter.setPen(QPen(QColor(30, 30, 30), 1));
    painter.setBrush(QColor(255, 150, 40));
    for (int a : c->attachments) {
      if (a < 0 || static_cast<std::size_t>(a) >= sv.vertexCount) continue;
      const Eigen::Vector3d xc = c->pose.apply(sv.vertex(static_cast<std::size_t>(a)));
      if (xc.z() <= 0) continue;
      const auto uv = c->camera.project(xc);
      painter.drawEllipse(view_.toWidget(QPointF(uv.x(), uv.y())), 3.5, 3.5);
    }
  }

 private:
  void toggleAt(const Eigen::Vector2d& f) {
    const auto& c = view_.caseData();
    if (!c || !c->hasPose) {
      emit view_.toolMessage(QObject::tr("Attachments are picked on the organ drawn over the frame: open a frame (step 2) first."));
      return;
    }
    const auto hit = view_.organAt(f);
    if (!hit) {
      emit view_.toolMessage(QObject::tr("Click on the organ drawn over the frame where a ligament holds it."));
      return;
    }
    // The surface nodes within the radius of the clicked point (the clicked node at least).
    const SurfaceView sv = c->surfaceView();
    const double radius = view_.toolSettings().attachmentRadius;
    std::vector<int> patch;
    std::vector<char> seen(sv.vertexCount, 0);
    for (const auto& t : c->organ->surface)
      for (int v : t) {
        if (seen[static_cast<std::size_t>(v)]) continue;
        seen[static_cast<std::size_t>(v)] = 1;
        if ((sv.vertex(static_cast<std::size_t>(v)) - hit->model).norm() <= radius) patch.push_back(v);
      }
    if (patch.empty()) patch.push_back(hit->node);
    std::vector<int> nodes = c->attachments;
    std::sort(nodes.begin(), nodes.end());
    std::sort(patch.begin(), patch.end());
    // A click on a held node's orange dot (within a few pixels of it on the screen) releases the held nodes within the
    // radius of the click, and that node; a click anywhere else adds its patch (clicks along an edge a few millimetres apart released each other's
    // nodes when any node of the patch, or the node nearest the click, was held).
    const QPointF clicked = view_.toWidget(QPointF(f.x(), f.y()));
    int onDot = -1;
    double nearest = kDotPickPixels;
    for (int a : nodes) {
      if (a < 0 || static_cast<std::size_t>(a) >= sv.vertexCount) continue;
      const Eigen::Vector3d xc = c->pose.apply(sv.vertex(static_cast<std::size_t>(a)));
      if (xc.z() <= 0) continue;
      const auto uv = c->camera.project(xc);
      const double d = QLineF(clicked, view_.toWidget(QPointF(uv.x(), uv.y()))).length();
      if (d <= nearest) nearest = d, onDot = a;
    }
    const bool release = onDot >= 0;
    if (release) {  // the held nodes of the clicked patch, and the dot's own
      patch.push_back(onDot);
      std::sort(patch.begin(), patch.end());
    }
    std::vector<int> result;
    if (release) std::set_difference(nodes.begin(), nodes.end(), patch.begin(), patch.end(), std::back_inserter(result));
    else std::set_union(nodes.begin(), nodes.end(), patch.begin(), patch.end(), std::back_inserter(result));
    const auto changed = static_cast<int>(std::max(result.size(), nodes.size()) - std::min(result.size(), nodes.size()));
    emit view_.attachmentsEdited(result, release ? (changed == 1 ? QObject::tr("Release 1 attachment node")
                                                                  : QObject::tr("Release %1 attachment nodes").arg(changed))
                                                 : (changed == 1 ? QObject::tr("Attach 1 node")
                                                                  : QObject::tr("Attach %1 nodes").arg(changed)));
  }
};

}  // namespace

std::unique_ptr<FrameTool> makeAttachmentTool(FrameView& view) { return std::make_unique<AttachmentTool>(view); }

}  // namespace rehearse::ui::tools
