#pragma once
// The frame view's tools, one class per file in this folder; the view makes them through these.
#include "rehearse/ui/frameview.hpp"

#include <QColor>

#include <memory>

namespace rehearse::ui::tools {

std::unique_ptr<FrameTool> makeDrawTool(FrameView& view, bool freehand);  ///< Freehand, ClickPoints
std::unique_ptr<FrameTool> makeEditPointsTool(FrameView& view);
std::unique_ptr<FrameTool> makeEraseTool(FrameView& view);
std::unique_ptr<FrameTool> makeGizmoTool(FrameView& view);                 ///< Align
std::unique_ptr<FrameTool> makeLandmarkTool(FrameView& view);
std::unique_ptr<FrameTool> makeOrganCurveTool(FrameView& view);
std::unique_ptr<FrameTool> makeAttachmentTool(FrameView& view);
std::unique_ptr<FrameTool> makeGraspTool(FrameView& view);

/// Widget position of a gizmo handle at the view's case pose; a null point when the organ is behind the camera.
QPointF gizmoHandlePosition(const FrameView& view, GizmoHandle h);
/// Contour segments by type: silhouettes yellow, ridges orange, ligaments violet.
QColor segmentColour(const std::string& type);
/// Draws the contour's points (while they can be clicked or edited).
void paintContourPoints(const FrameView& view, QPainter& p);

}  // namespace rehearse::ui::tools
