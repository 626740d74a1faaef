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
  void importContour(const QString& path);
  void exportContour(const QString& path);

 private:
  QLabel* status_ = nullptr;
  QDoubleSpinBox* spacing_ = nullptr;
  QComboBox* segmentType_ = nullptr;
};

}  // namespace rehearse::ui
