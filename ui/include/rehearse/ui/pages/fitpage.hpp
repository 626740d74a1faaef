#pragma once
// Step 5, the elastic fit: the organ's silhouette slides onto the contour on a worker (the one pipeline,
// app::runElasticFit, with the case's organ, attachments and material), the organ deforms over the frame
// as it goes and a chart plots the distance against time; Esc cancels; the result is one undo step, kept
// or reverted. Ridges and ligaments hold once their curve on the organ is picked (K). An ambiguous fit (the
// contour does not determine the pose) says so and lists the other poses: choosing one shows the organ
// there over the frame, and *Fit from It* continues from it.
#include "rehearse/ui/pages/steppage.hpp"

#include <rehearse/simcore/registration.hpp>

#include <QList>
#include <QPolygonF>

#include <memory>
#include <vector>

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QLineSeries;
class QValueAxis;
class QVBoxLayout;

namespace rehearse::ui {

class FitPage : public StepPage {
  Q_OBJECT
 public:
  FitPage(Workbench& wb, QWidget* parent = nullptr);
  void refresh(const app::Case& c) override;
  void caseLoaded() override { fitUndoIndex_ = -1; }
  /// Fits the organ onto the contour on a worker (Esc cancels); emits fitFinished.
  void runElasticFit();
  /// After an ambiguous fit: the other poses that fit the contour nearly as well (rest shape, rigid).
  const std::vector<Pose>& alternatives() const { return alternativePoses_; }
  /// Puts the organ at alternative `index` (one undo step) and fits from there without the rigid stage.
  void useAlternative(int index);

 signals:
  void fitFinished(bool ok, const QString& status);

 private:
  QLabel* curves_ = nullptr;
  QCheckBox* rigid_ = nullptr;
  QComboBox* down_ = nullptr;  ///< which way is down in the image (the case's `down`)
  QDoubleSpinBox* tolerance_ = nullptr;  ///< the bound a determined fit stays within (mm)
  QLabel* status_ = nullptr;
  QPushButton* keep_ = nullptr;    ///< accept the fit just made ...
  QPushButton* revert_ = nullptr;  ///< ... or revert it (its undo step), while it is the last edit
  int fitUndoIndex_ = -1;          ///< the undo index right after the fit awaiting a decision, -1 for none
  QString uncertainty_;            ///< that fit's bound, in a sentence (kept on the status when the fit is kept)
  QCheckBox* showBound_ = nullptr;  ///< draw where the organ may be
  /// The last fit's far ends' outlines (app::boundOutlines), drawn over the frame while it is the case's fit (and
  /// pose) and *Show where the organ may be* is ticked.
  QList<QPolygonF> boundOutlines_;
  QString boundText_;
  std::shared_ptr<const app::ElasticFit> boundFit_;  ///< the fit they belong to (others: not drawn)
  Pose boundPose_;
  // The constructor's parts, each adding its widgets to the page's layout, in this order.
  void addDownRow(QVBoxLayout* layout);
  void addToleranceRow(QVBoxLayout* layout);
  void addCurvePicking(QVBoxLayout* layout);
  void addFitButtons(QVBoxLayout* layout);  ///< fit and clear; keep or revert
  void addBoundAndStatus(QVBoxLayout* layout);
  void addAlternatives(QVBoxLayout* layout);
  void addChart(QVBoxLayout* layout);
  void showBound();
  void runFit(bool rigidPrepass);
  /// The alternatives list (hidden when empty); the status stands out while the fit is ambiguous.
  void showAlternatives(const std::vector<simcore::RegistrationAlternative>& alternatives, bool ambiguous);
  QWidget* alternativesBox_ = nullptr;
  QComboBox* alternativesList_ = nullptr;
  std::vector<Pose> alternativePoses_;
  QLineSeries* series_ = nullptr;
  QValueAxis* axisX_ = nullptr;
  QValueAxis* axisY_ = nullptr;
};

}  // namespace rehearse::ui
