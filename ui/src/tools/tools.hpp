#pragma once
// The frame view's tools, one class per file in this folder; the view makes them through these.
#include "rehearse/ui/frameview.hpp"

#include <QColor>

#include <memory>
#include <optional>
#include <string>

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

/// Posts an instrument's input (`tool`: 0 grasper, 1 scissors, 3 clip applier, 4 cautery;
/// scripts' 2 is the cutting hook) through the view
/// to the simulation session; `label`: the structure a clip was aimed at (0: none).
void postInstrument(FrameView& view, simcore::InputKind kind, const Eigen::Vector3d& tip, bool on, int tool,
                    int label = 0);
/// The point under frame pixel `f` at camera depth `depth` (m).
Eigen::Vector3d pointAtDepth(const FrameView& view, const Eigen::Vector2d& f, double depth);

/// A vessel or duct the view ray under frame pixel `f` crosses, as the view draws it (its labelled elements at the live
/// shape): the shallowest one entered between camera depths `from` and `to` (m).
struct StructureUnder {
  int label = 0;
  double entry = 0, exit = 0;  ///< m, camera depth where the ray enters it (not before `from`) and leaves it
  std::string name;            ///< in words (simcore::structureWords: "vessel", "portal vein", "artery (A4)")
};
std::optional<StructureUnder> structureUnder(const FrameView& view, const Eigen::Vector2d& f, double from, double to);

/// Widget position of a gizmo handle at the view's case pose; a null point when the organ is behind the camera.
QPointF gizmoHandlePosition(const FrameView& view, GizmoHandle h);
/// Contour segments by type: silhouettes yellow, ridges orange, ligaments violet.
QColor segmentColour(const std::string& type);
/// Draws the contour's points (while they can be clicked or edited).
void paintContourPoints(const FrameView& view, QPainter& p);

}  // namespace rehearse::ui::tools
