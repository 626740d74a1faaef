// The clip applier (step 7): click on the organ drawn over the frame to close a clip across the vessel (or duct) under
// the cursor (the shallowest within 25 mm below the surface, where the view draws it; the tissue there when there is none; the clip names the
// structure it was aimed at, and the session says where it closed); the clip stays on
// the tissue (drawn in titanium grey) and is recorded like any input. Its jaws close along the shaft's direction, made
// perpendicular to the clipped structure.
#include "tools.hpp"

#include <QMouseEvent>
#include <QPainter>

namespace rehearse::ui::tools {
namespace {

class ClipTool final : public FrameTool {
 public:
  using FrameTool::FrameTool;

  bool press(QMouseEvent* e, const QPointF&, const Eigen::Vector2d& f) override {
    if (e->button() != Qt::LeftButton) return false;
    const auto& c = view_.caseData();
    if (!c || !c->hasPose) {
      emit view_.toolMessage(
          QObject::tr("The clip applier works on the organ placed over the frame: place it first (step 4)."));
      return true;
    }
    const auto hit = view_.liveSurfaceAt(f);
    if (!hit) {
      emit view_.toolMessage(QObject::tr("Click on the organ, over the vessel to clip."));
      return true;
    }
    // The jaws close on the vessel (or duct) under the cursor, the shallowest within 25 mm below the surface point
    // clicked: the nearest of its nodes within 3 mm of the view ray; else where the ray crosses it as the view draws it
    // (its labelled elements: a vessel whose nodes lie farther apart than that), at the middle of its crossing (at most
    // 5 mm past where the ray enters it); without one, a little below that point (the tissue there).
    const simcore::Mesh& volume = c->organ->volume;
    Eigen::Vector3d tip = pointAtDepth(view_, f, hit->z() + kDepth);
    int aimed = 0;
    {
      const Eigen::Vector3d ray = pointAtDepth(view_, f, 1.0);
      const auto& live = view_.liveShape();
      std::vector<int> closable(volume.points.size(), 0);  // a vessel's or a duct's label at each node (0: none)
      for (std::size_t t = 0; t < volume.tets.size() && t < volume.tetLabels.size(); ++t) {
        const simcore::StructureKind k = volume.labelKind(volume.tetLabels[t]);
        if (simcore::isVessel(k) || k == simcore::StructureKind::BileDuct)
          for (int v : volume.tets[t]) closable[static_cast<std::size_t>(v)] = volume.tetLabels[t];
      }
      double shallowest = hit->z() + kSearchDepth;
      for (std::size_t i = 0; i < closable.size() && i < live.size(); ++i) {
        if (!closable[i]) continue;
        const Eigen::Vector3d& p = live[i];
        if (p.z() < hit->z() - 0.001 || p.z() > shallowest || (p - p.z() * ray).norm() > kLateral) continue;
        shallowest = p.z();
        tip = p;
        aimed = closable[i];
      }
    }
    if (!aimed)
      if (const auto s = structureUnder(view_, f, hit->z() - 0.001, hit->z() + kSearchDepth)) {
        aimed = s->label;
        tip = pointAtDepth(view_, f, std::min(0.5 * (s->entry + s->exit), s->entry + kPastEntry));
      }
    postInstrument(view_, simcore::InputKind::ToolPose, tip, false, 3);
    // The clip names the structure it was aimed at: the view shows the tissue a step or more behind the session, and
    // the session closes the jaws on it when it is still within their reach (its sentence follows in step 7's line).
    postInstrument(view_, simcore::InputKind::Clip, tip, true, 3, aimed);
    last_ = f;
    placedAt_ = tip;
    if (aimed) {
      // In words ("vessel", not the label's "vessels": a person read "Clip aimed at the vessels").
      const std::string name = simcore::structureWords(volume.labelKind(aimed), volume.labelName(aimed));
      emit view_.toolMessage(
          QObject::tr("Clip aimed at the %1 %2 mm below the surface (U: clip applier; R: grasper, B: scissors).")
              .arg(QString::fromStdString(name))
              .arg(1e3 * (tip.z() - hit->z()), 0, 'f', 0));
    } else if (const auto deeper = structureUnder(view_, f, hit->z() + kSearchDepth, hit->z() + 0.2)) {
      // A vessel drawn there, deeper than the applier reaches: said with its depth (a person read "No vessel under the
      // cursor" over a vessel the view drew).
      emit view_.toolMessage(QObject::tr("The %1 under the cursor lies %2 mm below the surface, deeper than the clip "
                                         "applier reaches (25 mm): the clip was aimed at the tissue there.")
                                 .arg(QString::fromStdString(deeper->name))
                                 .arg(1e3 * (deeper->entry - hit->z()), 0, 'f', 0));
    } else {
      emit view_.toolMessage(QObject::tr("No vessel under the cursor within 25 mm: the clip was aimed at the tissue there."));
    }
    return true;
  }
  // The applier leaves the clip and is withdrawn when the button comes up (its shaft kept pressing the tissue).
  void release(QMouseEvent*) override {
    if (!placedAt_) return;
    retractInstrument(view_, *placedAt_, 3);
    placedAt_.reset();
  }
  void paint(QPainter& painter) override {
    if (!last_) return;
    painter.setPen(QPen(QColor(200, 200, 215), 1.5, Qt::DotLine));
    painter.setBrush(Qt::NoBrush);
    painter.drawEllipse(view_.toWidget(QPointF(last_->x(), last_->y())), 9, 9);
  }
  Qt::CursorShape cursor() const override { return Qt::PointingHandCursor; }

 private:
  static constexpr double kDepth = 0.002;        ///< m below the clicked surface point (no vessel there)
  static constexpr double kSearchDepth = 0.025;  ///< m: how deep below it a vessel is looked for
  static constexpr double kLateral = 0.003;      ///< m from the view ray
  static constexpr double kPastEntry = 0.005;    ///< m: the jaws at most this far past where the ray enters the vessel
  std::optional<Eigen::Vector2d> last_;
  std::optional<Eigen::Vector3d> placedAt_;  ///< the tip a clip was just placed at, until the button comes up
};

}  // namespace

std::unique_ptr<FrameTool> makeClipTool(FrameView& view) { return std::make_unique<ClipTool>(view); }

}  // namespace rehearse::ui::tools
