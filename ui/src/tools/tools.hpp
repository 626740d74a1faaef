#pragma once
// The frame view's tools, one class per file in this folder; the view makes them through these.
#include "rehearse/ui/frameview.hpp"

#include <QColor>

#include <memory>
#include <optional>

namespace rehearse::ui::tools {

std::unique_ptr<FrameTool> makeDrawTool(FrameView& view, bool freehand);  ///< Freehand, ClickPoints
std::unique_ptr<FrameTool> makeEditPointsTool(FrameView& view);
std::unique_ptr<FrameTool> makeEraseTool(FrameView& view);
std::unique_ptr<FrameTool> makeGizmoTool(FrameView& view);                 ///< Align
std::unique_ptr<FrameTool> makeLandmarkTool(FrameView& view);
std::unique_ptr<FrameTool> makeOrganCurveTool(FrameView& view);
std::unique_ptr<FrameTool> makeAttachmentTool(FrameView& view);
std::unique_ptr<FrameTool> makeGraspTool(FrameView& view);
std::unique_ptr<FrameTool> makeScissorsTool(FrameView& view);
std::unique_ptr<FrameTool> makeClipTool(FrameView& view);
std::unique_ptr<FrameTool> makeCauteryTool(FrameView& view);

/// The instruments' pick: the organ's surface point under frame pixel `f` as the simulation has it now (its
/// cut boundary after a cut), snapped to the nearest surface node; camera frame (m). Nothing off the organ.
std::optional<Eigen::Vector3d> pickLiveSurface(const FrameView& view, const Eigen::Vector2d& f);
/// Posts an instrument's input (`tool`: 0 grasper, 1 scissors, 3 clip applier, 4 cautery;
/// scripts' 2 is the cutting hook) through the view
/// to the simulation session.
void postInstrument(FrameView& view, simcore::InputKind kind, const Eigen::Vector3d& tip, bool on, int tool);
/// The point under frame pixel `f` at camera depth `depth` (m).
Eigen::Vector3d pointAtDepth(const FrameView& view, const Eigen::Vector2d& f, double depth);

/// Widget position of a gizmo handle at the view's case pose; a null point when the organ is behind the camera.
QPointF gizmoHandlePosition(const FrameView& view, GizmoHandle h);
/// Contour segments by type: silhouettes yellow, ridges orange, ligaments violet.
QColor segmentColour(const std::string& type);
/// Draws the contour's points (while they can be clicked or edited).
void paintContourPoints(const FrameView& view, QPainter& p);

}  // namespace rehearse::ui::tools
