#include "rehearse/ui/pages/meshpage.hpp"

#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>
#include <rehearse/simcore/labelimage.hpp>

#include "phantom/phantom.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPushButton>
#include <QSettings>
#include <QSpinBox>
#include <QTreeWidget>
#include <QVBoxLayout>

#include <map>
#include <set>

namespace rehearse::ui {

QColor labelColour(int label) {
  static const QColor c[] = {QColor(200, 120, 100), QColor(80, 140, 255), QColor(250, 200, 60), QColor(170, 90, 220),
                             QColor(90, 220, 200), QColor(240, 120, 180)};
  return c[std::abs(label) % 6];
}

MeshPage::MeshPage(Workbench& wb, QWidget* parent) : StepPage(wb, app::Step::Mesh, parent) {
  auto* l = new QVBoxLayout(this);
  auto* importButton = new QPushButton(tr("Import Mesh... (Ctrl+I)"), this);
  importButton->setMinimumHeight(36);
  connect(importButton, &QPushButton::clicked, this, &MeshPage::importMeshDialog);
  l->addWidget(importButton);
  auto* form = new QFormLayout;
  targetTets_ = new QSpinBox(this);
  targetTets_->setRange(200, 500000);
  targetTets_->setSingleStep(500);
  targetTets_->setValue(QSettings().value(QStringLiteral("mesh/targetTets"), 4000).toInt());
  targetTets_->setToolTip(tr("Tetrahedra wanted when a surface is filled (size control)"));
  form->addRow(tr("Target tetrahedra"), targetTets_);
  meshUnit_ = new QComboBox(this);
  meshUnit_->addItems({"mm", "cm", "dm", "m"});
  meshUnit_->setToolTip(tr("Length unit of the file's coordinates"));
  form->addRow(tr("File unit"), meshUnit_);
  l->addLayout(form);
  l->addWidget(new QLabel(tr("Labels (tick to show inner structures)"), this));
  labels_ = new QTreeWidget(this);
  labels_->setAccessibleName(tr("Labels of the organ"));
  labels_->setObjectName(QStringLiteral("labelList"));
  labels_->setHeaderLabels({tr("Label"), tr("Kind"), tr("Elements")});
  labels_->setRootIsDecorated(false);
  labels_->header()->setStretchLastSection(false);
  labels_->header()->setSectionResizeMode(0, QHeaderView::Stretch);
  labels_->header()->setSectionResizeMode(1, QHeaderView::ResizeToContents);
  labels_->header()->setSectionResizeMode(2, QHeaderView::ResizeToContents);
  labels_->headerItem()->setToolTip(1,
                                    tr("What the label's name says it is (a vessel's kind, a bile duct, a tumour, its "
                                       "margin, a ligament): what a cut through it is called in the rehearsal"));
  connect(labels_, &QTreeWidget::itemChanged, this, [this](QTreeWidgetItem* item, int) {
    if (updating_) return;
    labelVisible_[item->data(0, Qt::UserRole).toInt()] = item->checkState(0) == Qt::Checked;
    emit shownLabelsChanged();
  });
  l->addWidget(labels_, 1);
  // Ligament attachments: the nodes that hold the organ in the simulation and the fit. An imported organ
  // has none until they are picked on it.
  attachmentsLabel_ = new QLabel(this);
  attachmentsLabel_->setObjectName(QStringLiteral("attachmentsLabel"));
  attachmentsLabel_->setWordWrap(true);
  l->addWidget(attachmentsLabel_);
  auto* attachRow = new QHBoxLayout;
  auto* pickAttach = toolButton(this, tr("Pick Attachments (H)"),
                                tr("Click on the organ drawn over the frame where a ligament holds it: the surface nodes within "
                                   "the patch radius are attached; a click on attached nodes releases them. Each click is one undo step."),
                                Tool::Attachments, Qt::Key_H);
  pickAttach->setObjectName(QStringLiteral("pickAttachments"));
  auto* clearAttach = new QPushButton(tr("Release All"), this);
  clearAttach->setObjectName(QStringLiteral("clearAttachments"));
  connect(clearAttach, &QPushButton::clicked, this, [this] {
    if (data() && !data()->attachments.empty())
      wb_.doc->edit(tr("Release all attachments"), [](app::Case& k) { k.attachments.clear(); });
  });
  attachRow->addWidget(pickAttach, 2);
  attachRow->addWidget(clearAttach, 1);
  l->addLayout(attachRow);
  auto* radiusForm = new QFormLayout;
  auto* radius = new QDoubleSpinBox(this);
  radius->setObjectName(QStringLiteral("attachmentRadius"));
  radius->setRange(1, 50);
  radius->setDecimals(0);
  radius->setSuffix(tr(" mm"));
  radius->setToolTip(tr("Surface nodes within this distance of a click are attached or released together"));
  connect(radius, &QDoubleSpinBox::valueChanged, this, [this](double mm) {
    wb_.view->setAttachmentRadius(mm * 1e-3);
    QSettings().setValue(QStringLiteral("mesh/attachmentRadiusMm"), mm);
  });
  radius->setValue(QSettings().value(QStringLiteral("mesh/attachmentRadiusMm"), 10.0).toDouble());
  wb_.view->setAttachmentRadius(radius->value() * 1e-3);
  radiusForm->addRow(tr("Attachment patch radius"), radius);
  l->addLayout(radiusForm);
}

int MeshPage::labelsShown() const { return labels_->topLevelItemCount(); }
int MeshPage::targetTets() const { return targetTets_->value(); }
void MeshPage::setTargetTets(int n) { targetTets_->setValue(n); }
void MeshPage::setMeshUnit(const QString& unit) { meshUnit_->setCurrentText(unit); }

std::vector<int> MeshPage::shownInnerLabels() const {
  std::vector<int> shown;
  for (const auto& [label, visible] : labelVisible_)
    if (visible && label != app::kParenchymaLabel) shown.push_back(label);
  return shown;
}

void MeshPage::caseLoaded() {
  importNotes_.clear();
  emit importNotesChanged();
}

void MeshPage::refresh(const app::Case& c) {
  updating_ = true;
  if (labelsFor_ != c.organ) {
    labelVisible_.clear();
    labelsFor_ = c.organ;
  }
  attachmentsLabel_->setText(c.attachments.empty()
                                 ? tr("No ligament attachments: in the simulation the tissue around the organ carries it (the Simulation "
                                      "panel's Support; with none, nothing holds it and it is not started).")
                                 : c.attachments.size() == 1 ? tr("Ligament attachments: 1 node.")
                                                                 : tr("Ligament attachments: %1 nodes.").arg(c.attachments.size()));
  labels_->clear();
  std::map<int, std::size_t> counts;
  for (int l : c.organ->volume.tetLabels) counts[l]++;
  for (const auto& [label, n] : counts) {
    auto* item = new QTreeWidgetItem(labels_);
    const std::string name = c.organ->volume.labelName(label);
    item->setText(0, QStringLiteral("%1 %2").arg(label).arg(QString::fromStdString(name)));
    item->setText(1, QString::fromUtf8(simcore::structureKindName(c.organ->volume.labelKind(label))));
    item->setText(2, QString::number(n));
    item->setData(0, Qt::UserRole, label);
    item->setFlags(item->flags() | Qt::ItemIsUserCheckable);
    if (!labelVisible_.count(label)) labelVisible_[label] = label == 1;
    item->setCheckState(0, labelVisible_[label] ? Qt::Checked : Qt::Unchecked);
    QPixmap swatch(14, 14);
    swatch.fill(labelColour(label));
    item->setIcon(0, QIcon(swatch));
  }
  updating_ = false;
}

void MeshPage::importMeshDialog() {
  const QString p = QFileDialog::getOpenFileName(
      wb_.window, tr("Import Organ Mesh"), dialogFolder(),
      tr("Meshes and segmentations (*.msh *.vtk *.vtu *.mesh *.obj *.stl *.ply *.off *.gltf *.glb "
         "*.nrrd *.nhdr *.nii *.nii.gz *.mha *.mhd *.inr *.inr.gz);;"
         "Meshes (*.msh *.vtk *.vtu *.mesh *.obj *.stl *.ply *.off *.gltf *.glb);;"
         "Segmentations: label images (*.nrrd *.nhdr *.nii *.nii.gz *.mha *.mhd *.inr *.inr.gz)"));
  if (!p.isEmpty()) {
    rememberDialogFolder(p);
    importMesh(p);
  }
}

void MeshPage::importMesh(const QString& path) {
  if (!data()) return;
  const int target = targetTets_->value();
  const std::string unit = meshUnit_->currentText().toStdString();
  QSettings().setValue(QStringLiteral("mesh/targetTets"), target);
  wb_.goToStep(app::Step::Mesh);
  wb_.jobs->run(tr("Importing %1...").arg(QFileInfo(path).fileName()), [this, path, target, unit](const std::atomic<bool>& cancel, const auto& progress) -> std::function<void()> {
    try {
      std::vector<std::string> notes;
      progress(0.02, QStringLiteral("reading"));
      const bool segmentation = simcore::isLabelImagePath(path.toStdString());
      QStringList unmeshed;  // a segmentation's labels too thin to get an element
      simcore::Mesh m;
      double fileUnit = 1e-3;    // kept with the organ (a 4x4 pose matrix is read in it)
      simcore::Mesh ownSurface;  // the surface as imported: drawn in the composited view, carried by the tetrahedra
      if (segmentation) {
        // A segmentation (NRRD, NIfTI, MetaImage, INR): meshed with each label a part, in the image's own frame
        // (LPS, or the image's axes for INR) and millimetres.
        const simcore::LabelImage image = simcore::readLabelImage(path.toStdString());
        notes = image.notes;
        simcore::LabelMeshOptions lo;
        lo.tetrahedralise.targetTets = static_cast<std::size_t>(target);
        lo.tetrahedralise.cancel = &cancel;
        lo.tetrahedralise.progress = [&progress](double f, const std::string& s) {
          progress(f < 0 ? f : 0.1 + 0.85 * f, QString::fromStdString(s));
        };
        progress(0.1, QStringLiteral("meshing %1 labels").arg(image.labelCounts().size()));
        m = simcore::meshLabelImage(image, lo, &notes);
        for (int l : simcore::unmeshedLabels(image, lo, m))
          unmeshed << QString::fromStdString(simcore::describeLabel(image, l));
      } else {
        m = simcore::loadMesh(path.toStdString(), {unit}, &notes);
        fileUnit = simcore::metresPerUnit(unit);
        // A size no organ has (under 1 cm or over 1 m across) is a wrong unit, not an organ: refused with the
        // likely unit, before anything is built (the case is unchanged).
        if (!m.points.empty()) {
          m.convertToMetres();
          const double size = m.bounds().sizes().maxCoeff();
          if (const simcore::OrganSize check = simcore::checkOrganSize(size, unit); !check.organSized) {
            const QString what =
                tr("With the file unit %1 this organ would measure %2 mm across; organs measure 10 to 1000 mm.")
                    .arg(QString::fromStdString(unit))
                    .arg(size * 1e3, 0, 'g', 3);
            throw simcore::MeshError(
                (check.likely.empty()
                     ? what + tr(" Check the file.")
                     : what + tr(" The file is probably in %1: choose that file unit and import again.")
                                  .arg(QString::fromStdString(check.likelyText())))
                    .toStdString());
          }
        }
        if (!m.isVolume()) {
          simcore::TetrahedraliseOptions o;
          o.outerSurface = &ownSurface;
          o.targetTets = static_cast<std::size_t>(target);
          o.cancel = &cancel;
          o.progress = [&progress](double f, const std::string& s) {
            progress(f < 0 ? f : 0.05 + 0.9 * f, QString::fromStdString(s));
          };
          m = simcore::tetrahedraliseSurface(m, o, &notes);
        }
      }
      m.triangles.clear();
      m.triangleLabels.clear();
      // Surfaces and quality of the new mesh are derived here, off the GUI thread.
      std::string visualNote;
      auto prepared = app::Organ::fromVolume(std::move(m), path.toStdString(), fileUnit,
                                             ownSurface.triangles.empty() ? nullptr : &ownSurface, &visualNote);
      if (!visualNote.empty()) notes.push_back(visualNote);
      QStringList qnotes;
      for (const auto& n : notes) qnotes << QString::fromStdString(n);
      // A new organ ends the rehearsal: one nothing keeps is asked about once the file has been read and meshed (asked
      // before, a Discard lost a burnt rehearsal to a file then refused for its unit: a person's check). Discard ends
      // it and the organ comes in; Cancel imports nothing.
      auto apply = [this, prepared, path, qnotes, segmentation, unmeshed] {
        importNotes_ = qnotes;
        // A case without a file that was the built-in phantom is named after the organ that replaces the phantom's
        // (the unsaved-changes question and Save As name it so); undone with the import.
        const bool renamed = wb_.doc->path().isEmpty() && data()->name == phantom::kBuiltInName;
        QString base = QFileInfo(path).completeBaseName();  // (liver.vtk: liver; a segmentation's .nii.gz: its name)
        if (base.endsWith(QStringLiteral(".nii"), Qt::CaseInsensitive)) base.chop(4);
        const std::string named = base.toStdString();
        // What belonged to the organ it replaces goes with it (Case::setOrgan), said (a person saw the fit and four
        // landmark pairs gone without a word).
        QStringList dropped;
        if (const app::Case& was = *data(); !was.organ->empty()) {
          if (was.hasFit()) dropped << tr("fit");
          if (const std::size_t n = was.landmarks.size(); n > 0)
            dropped << (n == 1 ? tr("landmark pair") : tr("%1 landmark pairs").arg(n));
          if (const std::size_t n = was.attachments.size(); n > 0)
            dropped << (n == 1 ? tr("attachment") : tr("%1 attachments").arg(n));
          if (was.poseAligned) dropped << tr("alignment");
        }
        if (!wb_.doc->edit(segmentation ? tr("Import segmentation") : tr("Import mesh"), [&](app::Case& k) {
              k.setOrgan(prepared);
              if (renamed && !named.empty()) k.name = named;
            })) {
          // (a rehearsal begun while the file was read: asked about, the organ comes in on Discard)
          wb_.status(tr("%1 comes in if the question about the rehearsal is answered Discard.")
                         .arg(QFileInfo(path).fileName()));
          return;
        }
        emit importNotesChanged();
        const auto& organ = *data()->organ;
        const std::set<int> labels(organ.volume.tetLabels.begin(), organ.volume.tetLabels.end());
        QString said =
            segmentation
                ? tr("Imported the segmentation %1: %2 tetrahedra in %3 labelled parts")
                          .arg(QFileInfo(path).fileName())
                          .arg(organ.volume.tets.size())
                          .arg(labels.size()) +
                      (unmeshed.isEmpty() ? QString()
                                          : tr("; %1 thinner than the elements, not meshed: raise the target count and "
                                               "import again")
                                                .arg(unmeshed.join(QStringLiteral(", "))))
            : organ.visual
                ? tr("Imported %1: %2 tetrahedra, drawn through its own surface (%3 triangles)")
                      .arg(QFileInfo(path).fileName())
                      .arg(organ.volume.tets.size())
                      .arg(organ.visual->triangles.size())
                : tr("Imported %1: %2 tetrahedra").arg(QFileInfo(path).fileName()).arg(organ.volume.tets.size());
        if (!dropped.isEmpty()) {
          const QString last = dropped.takeLast();
          said += tr(". The previous organ's %1 went with it (Ctrl+Z brings them back).")
                      .arg(dropped.isEmpty() ? last : tr("%1 and %2").arg(dropped.join(QStringLiteral(", ")), last));
        }
        wb_.status(said);
        emit meshImported(true, {});
      };
      return [this, apply, path] {
        if (!wb_.endRehearsal) return apply();
        wb_.endRehearsal(tr("importing %1").arg(QFileInfo(path).fileName()), apply, [this, path] {
          wb_.status(tr("%1 was not imported: the rehearsal stays as it is.").arg(QFileInfo(path).fileName()));
          emit meshImported(false, tr("cancelled"));
        });
      };
    } catch (const simcore::Cancelled&) {
      return [this] {
        wb_.status(tr("Import cancelled; the case is unchanged."));
        emit meshImported(false, tr("cancelled"));
      };
    } catch (const std::exception& e) {
      const QString msg = QString::fromUtf8(e.what());
      return [this, msg] {
        wb_.status(msg);
        emit meshImported(false, msg);
      };
    }
  });
}

}  // namespace rehearse::ui
