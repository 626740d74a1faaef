#pragma once
// Step 3, the contour: the drawing tools (freehand, click by click, edit points, erase), snapping to image
// edges, what new segments are (silhouette, ridge, ligament), resample, smooth, clear, import and export.
#include "rehearse/ui/pages/steppage.hpp"

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QLabel;

namespace rehearse::ui {

class ContourPage : public StepPage {
  Q_OBJECT
 public:
  ContourPage(Workbench& wb, QWidget* parent = nullptr);
  void refresh(const app::Case& c) override;
  /// Where the points of an imported file lie: as the file's layout says (P2ILF's are on the raw image,
  /// ours on the undistorted frame), or as the user chose. Points on the raw image are undistorted with the
  /// case's camera, as the command line's --distorted-contour does.
  enum class PointsOn { FileConvention, RawFrame, UndistortedFrame };
  void setImportedPointsOn(PointsOn where);
  void importContour(const QString& path);
  /// Ours (undistorted frame) or P2ILF's (points moved onto the raw image through the camera's distortion).
  void exportContour(const QString& path, imaging::ContourFormat format = imaging::ContourFormat::Rehearse);

 private:
  QLabel* status_ = nullptr;
  QDoubleSpinBox* spacing_ = nullptr;
  QComboBox* segmentType_ = nullptr;
  QComboBox* pointsOn_ = nullptr;
  QComboBox* sketchOn_ = nullptr;  ///< the first frame, or the second (Case::frame2)
  /// The contour the tools edit now: the second frame's while it is shown.
  imaging::Contour& shown(app::Case& k) const;
};

}  // namespace rehearse::ui
