#pragma once
// Step 7, the rehearsal: the instruments the surgeon drives with the mouse in the frame view (the
// grasper now; contact and cutting come next), their live state from the simulation session (what the
// jaws hold, the force on the tissue, slips), in the composited view of step 6 or the overlay.
#include "rehearse/ui/pages/steppage.hpp"

#include <memory>

class QLabel;

namespace rehearse::ui {

struct SimulationFrame;

class RehearsePage : public StepPage {
  Q_OBJECT
 public:
  explicit RehearsePage(Workbench& wb, QWidget* parent = nullptr);
  void refresh(const app::Case& c) override;
  /// A simulation snapshot was shown: the instrument's state in words.
  void showFrame(const std::shared_ptr<const SimulationFrame>& f);

 private:
  QLabel* status_ = nullptr;
  QLabel* force_ = nullptr;
  int slips_ = 0, cuts_ = 0, vesselCuts_ = 0;
};

}  // namespace rehearse::ui
