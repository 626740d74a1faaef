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
/// The instrument `tool` withdrawn from the tissue when the hand lets go of it (the jaws opened, the blade or the power
/// off, the clip closed): its tip from `tip` back along the shaft to a fifth of the way from the trocar (the default
/// trocar lies an organ's radius off the organ). Left where it was, its shaft kept pressing the tissue: a force on the
/// page that no hand applied (0.3-1.9 N after a release), and after a pull the squeezed tissue under the shaft held the
/// steps back until Reset. Nothing is posted without a trocar (no shaft to touch with).
void retractInstrument(FrameView& view, const Eigen::Vector3d& tip, int tool);
/// The point under frame pixel `f` at camera depth `depth` (m).
Eigen::Vector3d pointAtDepth(const FrameView& view, const Eigen::Vector2d& f, double depth);

/// A vessel or duct the view ray under frame pixel `f` crosses, as the view draws it (its labelled elements at the live
/// shape): the shallowest one entered between camera depths `from` and `to` (m).
struct StructureUnder {
  int label = 0;
  double entry = 0, exit = 0;  ///< m along the line (camera depth for structureUnder): where it enters (not before `from`), leaves
  std::string name;            ///< in words (simcore::structureWords: "vessel", "portal vein", "artery (A4)")
};
std::optional<StructureUnder> structureUnder(const FrameView& view, const Eigen::Vector2d& f, double from, double to);
/// The same along the line `origin` + t `direction` (camera frame; entry and exit are values of t, from `from` on).
std::optional<StructureUnder> structureAlong(const FrameView& view, const Eigen::Vector3d& origin,
                                             const Eigen::Vector3d& direction, double from, double to);

/// Widget position of a gizmo handle at the view's case pose; a null point when the organ is behind the camera.
QPointF gizmoHandlePosition(const FrameView& view, GizmoHandle h);
/// Contour segments by type: silhouettes yellow, ridges orange, ligaments violet.
QColor segmentColour(const std::string& type);
/// Draws the contour's points (while they can be clicked or edited).
void paintContourPoints(const FrameView& view, QPainter& p);

}  // namespace rehearse::ui::tools
