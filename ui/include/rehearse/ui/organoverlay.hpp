#pragma once
// The organ over the frame, as the frame view shows it: the organ drawn through the case's camera at its
// pose and current shape (fitted or rest), with OpenGL off screen when a context can be made and by the
// CPU rasteriser otherwise; its outline; the inner structures the user ticked, each label in its own
// colour; and the contour-to-silhouette distance the elastic fit measures.
#include <rehearse/app/case.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QImage>
#include <QList>
#include <QPolygonF>

#include <memory>
#include <vector>

namespace rehearse::ui {

class GLOverlay;

struct OverlayPicture {
  QImage organ;                  ///< RGBA, possibly at a reduced resolution (drawn scaled onto the frame)
  QList<QPolygonF> silhouette;   ///< frame pixels
  QImage inner;                  ///< inner structures, same size as `organ` (null when none is shown)
  /// Each inner structure drawn in `inner`: its colour (labelColour, as in step 1) and its name, in label order.
  QList<QPair<QColor, QString>> innerKey;
  double meanDistance = -1;      ///< px; negative when it cannot be computed (no contour, behind the camera)
  double rmsDistance = -1, maxDistance = -1;
};

class OrganOverlay {
 public:
  /// `openGL`: try an off-screen OpenGL context (falls back to the CPU rasteriser when none can be made).
  explicit OrganOverlay(bool openGL);
  ~OrganOverlay();
  bool usesOpenGL() const { return gl_ != nullptr; }
  /// Empty picture when the case has no organ, no pose or an unusable camera.
  OverlayPicture render(const app::Case& c, const std::vector<int>& innerLabels);
  /// The simulated organ after a cut: its boundary at `cameraPositions` (camera frame, m), cut tissue in
  /// dark red where it is seen (by the CPU rasteriser: one pass for the shading, one for which triangle each
  /// pixel sees).
  /// With the cut mesh's elements and their labels (`tets`, `labels`: the simulation's), the inner structures
  /// `innerLabels` are drawn too, as the boundaries of their elements on the cut mesh (they went missing after a cut, a
  /// person's check).
  OverlayPicture renderLive(const app::Case& c, const std::vector<Eigen::Vector3d>& cameraPositions, const simcore::CutSurface& surface,
                            std::shared_ptr<const std::vector<std::array<int, 4>>> tets = {},
                            std::shared_ptr<const std::vector<int>> labels = {}, const std::vector<int>& innerLabels = {});

 private:
  QImage organImage(const imaging::Camera& camera, const Pose& pose, const SurfaceView& surface, const QColor& colour);
  /// The inner structures `innerLabels` into out.inner and out.innerKey: the faces `faces` (labelled `faceLabels`) over
  /// the vertices of `view`, each label in its own colour, composed in label order; names from `names`.
  void drawInner(OverlayPicture& out, const imaging::Camera& camera, const Pose& pose, SurfaceView view,
                 const std::vector<std::array<int, 3>>& faces, const std::vector<int>& faceLabels,
                 const std::vector<int>& innerLabels, const simcore::Mesh& names);
  std::unique_ptr<GLOverlay> gl_;
  // The cut mesh's inner faces, kept while its elements and labels are the same ones (the session shares them between
  // its snapshots until they change; renderLive runs at every frame shown). Held: a new mesh is never taken for this
  // one at its address.
  std::shared_ptr<const std::vector<std::array<int, 4>>> innerTets_;
  std::shared_ptr<const std::vector<int>> innerTetLabels_;
  std::vector<std::array<int, 3>> innerFaces_;
  std::vector<int> innerFaceLabels_;
};

}  // namespace rehearse::ui
