#pragma once
// Step 6, the appearance: the organ's reflectance and the light fitted to the frame through the registered
// organ (app::runAppearance, the pipeline `rehearse appearance` runs) on a worker, with progress and Esc to
// cancel; the result is one undo step of the case. The page shows the fitted parameters as the paper's
// Table 1 does (light position in mm, k_d and k_s per channel, roughness), each stage's residual and time,
// the diffuse image I_D and the inpainted background I_B; the frame view turns to the composited view
// (View menu: composited / overlay / 3D).
#include "rehearse/ui/pages/steppage.hpp"

class QCheckBox;
class QComboBox;
class QLabel;
class QTableWidget;

namespace rehearse::ui {

class Composition;

class AppearancePage : public StepPage {
  Q_OBJECT
 public:
  AppearancePage(Workbench& wb, Composition* composition, QWidget* parent = nullptr);
  void refresh(const app::Case& c) override;
  /// Estimates the appearance on a worker (Esc cancels); emits estimated.
  void estimate();

 signals:
  void estimated(bool ok, const QString& status);

 private:
  void showLayers();
  Composition* composition_;
  QComboBox* inpaint_ = nullptr;
  QCheckBox* turn_ = nullptr;
  QLabel* status_ = nullptr;
  QTableWidget* table_ = nullptr;
  QLabel* report_ = nullptr;
  QLabel* diffuse_ = nullptr;
  QLabel* background_ = nullptr;
  QLabel* residual_ = nullptr;
};

}  // namespace rehearse::ui
