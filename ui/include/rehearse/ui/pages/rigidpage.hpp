#pragma once
// Step 4, the rigid alignment: the gizmo (G; translations along and rotations about the camera axes through
// the organ's centre), the pose typed in, a reset to the automatic placement, landmark pairs (L) solved by
// PnP, and the live contour-to-silhouette distance.
#include "rehearse/ui/pages/steppage.hpp"

class QDoubleSpinBox;
class QLabel;
class QListWidget;

namespace rehearse::ui {

class RigidPage : public StepPage {
  Q_OBJECT
 public:
  RigidPage(Workbench& wb, QWidget* parent = nullptr);
  void refresh(const app::Case& c) override;
  /// A pose file (JSON, or a 4x4 text matrix in the mesh's unit), one undoable edit; a bad file is one sentence.
  void loadPose(const QString& path);
  /// Pose from the landmark pairs (4 or more), one undoable edit.
  void solvePnP();
  const std::vector<LandmarkPair>& landmarks() const { return wb_.view->landmarks(); }
  double lastPnPReprojectionError() const { return pnpError_; }
  /// The distance line under the fields (the window computes it with the overlay).
  void setDistanceText(const QString& text);

 private:
  void refreshLandmarks(const app::Case& c);
  /// The case's pairs replaced by `l`, one undoable edit.
  void editLandmarks(std::vector<LandmarkPair> l, const QString& text);

  QDoubleSpinBox* poseFields_[6] = {};
  int fieldsMergeId_ = -1;    ///< the undo step that typed pose fields join
  int fieldsEditIndex_ = -1;  ///< the undo stack's index after the last field edit
  QLabel* distanceLabel_ = nullptr;
  QListWidget* landmarkList_ = nullptr;
  QPushButton* pnpButton_ = nullptr;
  double pnpError_ = -1;
};

}  // namespace rehearse::ui
