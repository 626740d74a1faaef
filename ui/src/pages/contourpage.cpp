#include "rehearse/ui/pages/contourpage.hpp"

#include "rehearse/ui/frameview.hpp"

#include <QCheckBox>
#include <QRegularExpression>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QSettings>
#include <QVBoxLayout>

namespace rehearse::ui {

ContourPage::ContourPage(Workbench& wb, QWidget* parent) : StepPage(wb, app::Step::Contour, parent) {
  auto* l = new QVBoxLayout(this);
  // Which frame the outline is sketched on: the first, or the second frame of step 2 (the scope moved).
  auto* onFrameRow = new QHBoxLayout;
  sketchOn_ = new QComboBox(this);
  sketchOn_->setObjectName(QStringLiteral("sketchOn"));
  sketchOn_->addItem(tr("First frame"));
  sketchOn_->addItem(tr("Second frame (the scope moved)"));
  sketchOn_->setToolTip(
      tr("Sketch the organ's outline on each frame: the fit uses both, and the camera's motion "
         "between them, to find the depth one outline cannot show."));
  auto* onFrameLabel = new QLabel(tr("Sketch &on"), this);
  onFrameLabel->setBuddy(sketchOn_);
  connect(sketchOn_, &QComboBox::currentIndexChanged, this, [this](int i) { wb_.view->setSecondFrameShown(i == 1); });
  connect(wb_.view, &FrameView::shownFrameChanged, this, [this](bool second) {
    const QSignalBlocker block(sketchOn_);
    sketchOn_->setCurrentIndex(second ? 1 : 0);
    if (data()) refresh(*data());
  });
  onFrameRow->addWidget(onFrameLabel);
  onFrameRow->addWidget(sketchOn_, 1);
  l->addLayout(onFrameRow);
  auto* grid = new QGridLayout;
  struct T {
    Tool tool;
    const char* name;
    Qt::Key key;
  };
  const T tools[] = {{Tool::Freehand, "Freehand (F)", Qt::Key_F}, {Tool::ClickPoints, "Click points (C)", Qt::Key_C},
                     {Tool::EditPoints, "Edit points (E)", Qt::Key_E}, {Tool::Erase, "Erase (X)", Qt::Key_X}};
  int i = 0;
  for (const auto& t : tools) {
    auto* b = new QPushButton(tr(t.name), this);
    b->setMinimumHeight(34);
    b->setToolTip(tr("Middle button pans and the wheel zooms while drawing; Enter ends a click-by-click segment; "
                     "in Edit, drag a point, Ctrl+click inserts, right-click deletes."));
    const Tool tool = t.tool;
    connect(b, &QPushButton::clicked, this, [this, tool] { wb_.view->setTool(tool); });
    stepKey(
        QKeySequence(t.key), [this, tool] { wb_.view->setTool(tool); },
        tr("Contour tool: %1").arg(QString(tr(t.name)).remove(QRegularExpression(QStringLiteral("\\s*\\(.*\\)$")))));
    grid->addWidget(b, i / 2, i % 2);
    ++i;
  }
  l->addLayout(grid);
  auto* snap = new QCheckBox(tr("Snap to image edges"), this);
  connect(snap, &QCheckBox::toggled, wb_.view, &FrameView::setSnapToEdges);
  l->addWidget(snap);
  // What new segments are: the organ's silhouette, or an anatomical curve (the ridge, the falciform
  // ligament) that step 5 can also hold onto its curve on the organ.
  auto* typeRow = new QHBoxLayout;
  segmentType_ = new QComboBox(this);
  segmentType_->setObjectName(QStringLiteral("segmentType"));
  segmentType_->addItem(tr("Silhouette"), QStringLiteral("silhouette"));
  segmentType_->addItem(tr("Ridge"), QStringLiteral("ridge"));
  segmentType_->addItem(tr("Ligament"), QStringLiteral("ligament"));
  segmentType_->setToolTip(tr("Silhouettes are drawn yellow, ridges orange, ligaments violet."));
  connect(segmentType_, &QComboBox::currentIndexChanged, this,
          [this](int i) { wb_.view->setNewSegmentType(segmentType_->itemData(i).toString()); });
  typeRow->addWidget(new QLabel(tr("New segments"), this));
  typeRow->addWidget(segmentType_, 1);
  l->addLayout(typeRow);
  auto* rs = new QHBoxLayout;
  spacing_ = new QDoubleSpinBox(this);
  spacing_->setAccessibleName(tr("Resampling spacing"));
  spacing_->setRange(1, 100);
  spacing_->setValue(8);
  spacing_->setSuffix(tr(" px"));
  auto* resample = new QPushButton(tr("Resample"), this);
  connect(resample, &QPushButton::clicked, this, [this] {
    const double s = spacing_->value();
    wb_.doc->edit(tr("Resample contour"), [this, s](app::Case& k) {
      for (auto& seg : shown(k).segments) seg = imaging::resampleSegment(seg, s);
    });
  });
  rs->addWidget(new QLabel(tr("Spacing"), this));
  rs->addWidget(spacing_);
  rs->addWidget(resample);
  l->addLayout(rs);
  auto* row = new QHBoxLayout;
  auto* smooth = new QPushButton(tr("Smooth"), this);
  connect(smooth, &QPushButton::clicked, this, [this] {
    wb_.doc->edit(tr("Smooth contour"), [this](app::Case& k) {
      for (auto& seg : shown(k).segments) seg = imaging::smoothSegment(seg, 5);
    });
  });
  auto* clear = new QPushButton(tr("Clear"), this);
  connect(clear, &QPushButton::clicked, this,
          [this] { wb_.doc->edit(tr("Clear contour"), [this](app::Case& k) { shown(k).segments.clear(); }); });
  row->addWidget(smooth);
  row->addWidget(clear);
  l->addLayout(row);
  auto* onRow = new QHBoxLayout;
  pointsOn_ = new QComboBox(this);
  pointsOn_->setObjectName(QStringLiteral("importedPointsOn"));
  pointsOn_->addItem(tr("as the file says (P2ILF: raw)"));
  pointsOn_->addItem(tr("the raw frame"));
  pointsOn_->addItem(tr("the undistorted frame"));
  pointsOn_->setToolTip(tr("Where an imported contour's points were drawn. Points on the raw (distorted) frame are "
                           "undistorted with the case's camera; P2ILF's contours are on the raw frame."));
  onRow->addWidget(new QLabel(tr("Imported points on"), this));
  onRow->addWidget(pointsOn_, 1);
  l->addLayout(onRow);
  auto* io = new QHBoxLayout;
  auto* imp = new QPushButton(tr("Import..."), this);
  connect(imp, &QPushButton::clicked, this, [this] {
    const QString p = QFileDialog::getOpenFileName(wb_.window, tr("Import Contour"), dialogFolder(), tr("Contours (*.json)"));
    if (!p.isEmpty()) {
      rememberDialogFolder(p);
      importContour(p);
    }
  });
  auto* exp = new QPushButton(tr("Export..."), this);
  connect(exp, &QPushButton::clicked, this, [this] {
    const QString ours = tr("Rehearse contour, undistorted frame (*.json)");
    const QString p2ilf = tr("P2ILF contour, raw frame (*.json)");
    QString filter = ours;
    const QString p = QFileDialog::getSaveFileName(wb_.window, tr("Export Contour"), dialogFolder(),
                                                   ours + QStringLiteral(";;") + p2ilf, &filter);
    if (!p.isEmpty()) {
      rememberDialogFolder(p);
      exportContour(p, filter == p2ilf ? imaging::ContourFormat::P2ILF : imaging::ContourFormat::Rehearse);
    }
  });
  io->addWidget(imp);
  io->addWidget(exp);
  l->addLayout(io);
  status_ = new QLabel(this);
  status_->setWordWrap(true);
  l->addWidget(status_);
  l->addStretch(1);
}

imaging::Contour& ContourPage::shown(app::Case& k) const {
  return wb_.view->secondFrameShown() && !k.frame2.empty() ? k.contour2 : k.contour;
}

void ContourPage::refresh(const app::Case& c) {
  sketchOn_->setEnabled(!c.frame2.empty());
  if (c.frame2.empty() && wb_.view->secondFrameShown()) wb_.view->setSecondFrameShown(false);  // (cleared or undone)
  const bool second = wb_.view->secondFrameShown();
  const imaging::Contour& k = second ? c.contour2 : c.contour;
  const std::string problem = imaging::contourProblem(k);
  const int segments = static_cast<int>(k.segments.size()), points = static_cast<int>(k.pointCount());
  status_->setText(tr("%1%2, %3. %4")
                       .arg(second ? tr("Second frame: ") : QString())
                       .arg(segments == 1 ? tr("1 segment") : tr("%1 segments").arg(segments))
                       .arg(points == 1 ? tr("1 point") : tr("%1 points").arg(points))
                       .arg(problem.empty()
                                ? (second ? tr("The fit uses it with the first.") : tr("Ready for fitting."))
                                : QString::fromStdString(problem)));
}

void ContourPage::setImportedPointsOn(PointsOn where) { pointsOn_->setCurrentIndex(static_cast<int>(where)); }

void ContourPage::importContour(const QString& path) {
  try {
    imaging::ContourFormat format = imaging::ContourFormat::Rehearse;
    imaging::Contour c = imaging::loadContour(path.toStdString(), &format);
    const auto where = static_cast<PointsOn>(pointsOn_->currentIndex());
    const bool raw = where == PointsOn::RawFrame || (where == PointsOn::FileConvention && format == imaging::ContourFormat::P2ILF);
    QString how;
    if (raw && data() && imaging::hasDistortion(data()->camera)) {
      c = imaging::undistortContour(c, data()->camera);
      how = tr(" Its points were on the raw frame and are undistorted with the case's camera.");
    } else if (raw) {
      how = tr(" Its points are on the raw frame; the camera has no distortion, so they are used as they are.");
    }
    if (data() && !data()->frame.empty() && c.width == 0) {
      c.width = data()->frame.cols;
      c.height = data()->frame.rows;
    }
    wb_.doc->edit(tr("Import contour"), [&c](app::Case& k) { k.contour = c; });
    wb_.goToStep(app::Step::Contour);
    wb_.status((c.segments.size() == 1 ? tr("Contour imported: 1 segment.")
                                       : tr("Contour imported: %1 segments.").arg(c.segments.size())) +
               how);
  } catch (const std::exception& e) {
    wb_.status(QString::fromUtf8(e.what()));
  }
}

void ContourPage::exportContour(const QString& path, imaging::ContourFormat format) {
  if (!data()) return;
  try {
    if (format == imaging::ContourFormat::P2ILF) {
      imaging::saveContourP2ILF(imaging::distortContour(data()->contour, data()->camera), path.toStdString());
      wb_.status(tr("Contour exported to %1 in P2ILF's layout, its points on the raw frame.").arg(path));
    } else {
      imaging::saveContour(data()->contour, path.toStdString());
      wb_.status(tr("Contour exported to %1.").arg(path));
    }
  } catch (const std::exception& e) {
    wb_.status(QString::fromUtf8(e.what()));
  }
}

}  // namespace rehearse::ui
