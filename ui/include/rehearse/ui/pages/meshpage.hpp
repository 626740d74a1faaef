#pragma once
// Step 1, the organ mesh: import a surface (tetrahedralised on a worker) or a volume, the length unit,
// the labels (ticked ones are drawn through the organ over the frame), and the ligament attachments
// picked on the organ (Attachments tool, H).
#include "rehearse/ui/pages/steppage.hpp"

#include <map>

class QComboBox;
class QLabel;
class QSpinBox;
class QTreeWidget;

namespace rehearse::ui {

class MeshPage : public StepPage {
  Q_OBJECT
 public:
  MeshPage(Workbench& wb, QWidget* parent = nullptr);
  void refresh(const app::Case& c) override;
  void caseLoaded() override;

  /// Imports a surface or volume mesh on a worker; emits meshImported. A rehearsal nothing keeps is asked about once
  /// the file is read (Workbench::endRehearsal: the new organ ends it); Cancel imports nothing.
  void importMesh(const QString& path);
  void importMeshDialog();
  int targetTets() const;
  void setTargetTets(int n);
  void setMeshUnit(const QString& unit);
  int labelsShown() const;
  /// The labels ticked to be drawn through the organ (the parenchyma excluded).
  std::vector<int> shownInnerLabels() const;
  /// Notes from the last import (the Case panel lists them).
  const QStringList& importNotes() const { return importNotes_; }

 signals:
  void meshImported(bool ok, const QString& message);
  void shownLabelsChanged();
  void importNotesChanged();

 private:
  QSpinBox* targetTets_ = nullptr;
  QComboBox* meshUnit_ = nullptr;
  QTreeWidget* labels_ = nullptr;
  QLabel* attachmentsLabel_ = nullptr;
  std::map<int, bool> labelVisible_;
  std::shared_ptr<const app::Organ> labelsFor_;  ///< the organ the ticks belong to (a new organ resets them)
  QStringList importNotes_;
};

/// The colour a label is drawn in (over the frame and in the list).
QColor labelColour(int label);

}  // namespace rehearse::ui
