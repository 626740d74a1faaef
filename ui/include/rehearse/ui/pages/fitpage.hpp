#pragma once
// Step 5, the elastic fit: the organ's silhouette slides onto the contour on a worker (the one pipeline,
// app::runElasticFit, with the case's organ, attachments and material), the organ deforms over the frame
// as it goes and a chart plots the distance against time; Esc cancels; the result is one undo step, kept
// or reverted. Ridges and ligaments hold once their curve on the organ is picked (K).
#include "rehearse/ui/pages/steppage.hpp"

class QCheckBox;
class QLabel;
class QLineSeries;
class QValueAxis;

namespace rehearse::ui {

class FitPage : public StepPage {
  Q_OBJECT
 public:
  FitPage(Workbench& wb, QWidget* parent = nullptr);
  void refresh(const app::Case& c) override;
  void caseLoaded() override { fitUndoIndex_ = -1; }
  /// Fits the organ onto the contour on a worker (Esc cancels); emits fitFinished.
  void runElasticFit();

 signals:
  void fitFinished(bool ok, const QString& status);

 private:
  QLabel* curves_ = nullptr;
  QCheckBox* rigid_ = nullptr;
  QLabel* status_ = nullptr;
  QPushButton* keep_ = nullptr;    ///< accept the fit just made ...
  QPushButton* revert_ = nullptr;  ///< ... or revert it (its undo step), while it is the last edit
  int fitUndoIndex_ = -1;          ///< the undo index right after the fit awaiting a decision, -1 for none
  QLineSeries* series_ = nullptr;
  QValueAxis* axisX_ = nullptr;
  QValueAxis* axisY_ = nullptr;
};

}  // namespace rehearse::ui
