#include "rehearse/ui/pages/rigidpage.hpp"

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/pnp.hpp>

#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QSettings>
#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QListWidget>
#include <QPushButton>
#include <QUndoStack>
#include <QVBoxLayout>

#include <cmath>

namespace rehearse::ui {
namespace {
// What a nudge key does (the keyboard reference): the camera's axes, 1 mm or 1 degree, Shift 10 mm or 5 degrees.
QString nudgeDescription(Qt::Key key, bool shift) {
  const QString mm = shift ? QStringLiteral("10 mm") : QStringLiteral("1 mm");
  const QString deg = shift ? QStringLiteral("5 degrees") : QStringLiteral("1 degree");
  switch (key) {
    case Qt::Key_Left:
      return QObject::tr("Move the organ left %1").arg(mm);
    case Qt::Key_Right:
      return QObject::tr("Move the organ right %1").arg(mm);
    case Qt::Key_Up:
      return QObject::tr("Move the organ up %1").arg(mm);
    case Qt::Key_Down:
      return QObject::tr("Move the organ down %1").arg(mm);
    case Qt::Key_PageUp:
      return QObject::tr("Move the organ away from the camera %1").arg(mm);
    case Qt::Key_PageDown:
      return QObject::tr("Move the organ towards the camera %1").arg(mm);
    case Qt::Key_W:
      return QObject::tr("Turn the organ about the camera's x axis %1").arg(deg);
    case Qt::Key_S:
      return QObject::tr("Turn the organ about the camera's x axis back %1").arg(deg);
    case Qt::Key_A:
      return QObject::tr("Turn the organ about the camera's y axis %1").arg(deg);
    case Qt::Key_D:
      return QObject::tr("Turn the organ about the camera's y axis back %1").arg(deg);
    case Qt::Key_Q:
      return QObject::tr("Turn the organ about the camera's z axis %1").arg(deg);
    case Qt::Key_E:
      return QObject::tr("Turn the organ about the camera's z axis back %1").arg(deg);
    default:
      return {};
  }
}
}  // namespace

RigidPage::RigidPage(Workbench& wb, QWidget* parent) : StepPage(wb, app::Step::Rigid, parent) {
  auto* l = new QVBoxLayout(this);
  auto* gizmo = toolButton(this, tr("Gizmo (G)"),
                           tr("Drag X, Y, Z to move along the camera axes, rX, rY, rZ to turn about them through the organ's centre. "
                              "Keys: arrows and PgUp/PgDn move 1 mm, W/S A/D Q/E turn 1 degree; Shift for 10 mm / 5 degrees."),
                           Tool::Align, Qt::Key_G);
  gizmo->setMinimumHeight(34);
  l->addWidget(gizmo);
  auto* box = new QGroupBox(tr("Pose (camera frame; R = Rz Ry Rx)"), this);
  box->setToolTip(tr("Model to camera: translation in mm; rotation as angles about the camera's Z, Y and X axes in degrees, "
                     "applied X first (R = Rz(rz) Ry(ry) Rx(rx)). Camera axes: x right, y down, z forward."));
  auto* form = new QFormLayout(box);
  const char* names[6] = {"tx (mm)", "ty (mm)", "tz (mm)", "rx (deg)", "ry (deg)", "rz (deg)"};
  for (int k = 0; k < 6; ++k) {
    auto* s = new QDoubleSpinBox(box);
    s->setRange(k < 3 ? -5000 : -180, k < 3 ? 5000 : 180);
    s->setDecimals(2);
    s->setSingleStep(1.0);
    s->setKeyboardTracking(false);
    poseFields_[k] = s;
    form->addRow(tr(names[k]), s);
    connect(s, &QDoubleSpinBox::valueChanged, this, [this] {
      if (updating_ || !data()) return;
      Pose p;
      p.t = Eigen::Vector3d(poseFields_[0]->value(), poseFields_[1]->value(), poseFields_[2]->value()) * 1e-3;
      const double d = M_PI / 180;
      p.R = (Eigen::AngleAxisd(poseFields_[5]->value() * d, Eigen::Vector3d::UnitZ()) *
             Eigen::AngleAxisd(poseFields_[4]->value() * d, Eigen::Vector3d::UnitY()) *
             Eigen::AngleAxisd(poseFields_[3]->value() * d, Eigen::Vector3d::UnitX()))
                .toRotationMatrix();
      // Typing one field after another is one undo step, until anything else is done in between.
      QUndoStack* stack = wb_.doc->undoStack();
      if (stack->index() != fieldsEditIndex_ || stack->index() != stack->count()) fieldsMergeId_ = wb_.view->nextMergeId();
      wb_.doc->edit(tr("Edit pose fields"), [p](app::Case& k) {
        k.pose = p;
        k.hasPose = true;
        k.poseAligned = true;
      }, fieldsMergeId_);
      fieldsEditIndex_ = stack->index();
    });
  }
  l->addWidget(box);
  auto* reset = new QPushButton(tr("Reset to Automatic Placement"), this);
  connect(reset, &QPushButton::clicked, this, [this] {
    wb_.doc->edit(tr("Reset pose"), [](app::Case& k) {
      k.pose = k.automaticPose();
      k.hasPose = true;
      k.poseAligned = false;
    });
  });
  l->addWidget(reset);
  auto* load = new QPushButton(tr("Load Pose..."), this);
  load->setObjectName(QStringLiteral("loadPose"));
  load->setToolTip(tr("A pose file: JSON {\"R\": [[...]], \"t\": [...], \"unit\": \"m\"} or a 4x4 text matrix in the mesh's unit"));
  connect(load, &QPushButton::clicked, this, [this] {
    const QString p = QFileDialog::getOpenFileName(wb_.window, tr("Load Pose"), dialogFolder(), tr("Poses (*.json *.txt)"));
    if (!p.isEmpty()) {
      rememberDialogFolder(p);
      loadPose(p);
    }
  });
  l->addWidget(load);
  auto* lmBox = new QGroupBox(tr("Landmark pairs (mesh point, then image point)"), this);
  auto* ll = new QVBoxLayout(lmBox);
  ll->addWidget(toolButton(lmBox, tr("Pick Landmarks (L)"), tr("Click a point on the organ, then where it is in the frame; 4 pairs or more"),
                           Tool::Landmarks, Qt::Key_L));
  landmarkList_ = new QListWidget(lmBox);
  landmarkList_->setAccessibleName(tr("Landmark pairs"));
  landmarkList_->setMaximumHeight(110);
  ll->addWidget(landmarkList_);
  auto* lrow = new QHBoxLayout;
  pnpButton_ = new QPushButton(tr("Solve Pose"), lmBox);
  pnpButton_->setEnabled(false);
  connect(pnpButton_, &QPushButton::clicked, this, &RigidPage::solvePnP);
  auto* clearLm = new QPushButton(tr("Clear"), lmBox);
  connect(clearLm, &QPushButton::clicked, this, [this] {
    if (data() && !data()->landmarks.empty()) editLandmarks({}, tr("Clear landmarks"));
  });
  lrow->addWidget(pnpButton_);
  lrow->addWidget(clearLm);
  ll->addLayout(lrow);
  l->addWidget(lmBox);
  distanceLabel_ = new QLabel(this);
  QFont f = distanceLabel_->font();
  f.setPointSizeF(f.pointSizeF() * 1.3);
  f.setBold(true);
  distanceLabel_->setFont(f);
  distanceLabel_->setWordWrap(true);
  l->addWidget(distanceLabel_);
  l->addStretch(1);

  // Keyboard nudges from anywhere in the window while step 4 is shown (each key one thing per step: E turns
  // the organ here and picks Edit points in step 3).
  for (const Qt::Key key : {Qt::Key_Left, Qt::Key_Right, Qt::Key_Up, Qt::Key_Down, Qt::Key_PageUp, Qt::Key_PageDown, Qt::Key_W, Qt::Key_S,
                            Qt::Key_A, Qt::Key_D, Qt::Key_Q, Qt::Key_E})
    for (const bool shift : {false, true})
      stepKey(
          QKeySequence(shift ? (Qt::SHIFT | key) : QKeyCombination(key)),
          [this, key, shift] {
            if (!data()) return;
            if (const auto p = nudgedPose(*data(), key, shift))
              wb_.doc->edit(tr("Nudge"), [&](app::Case& k) {
                k.pose = *p;
                k.hasPose = true;
                k.poseAligned = true;
              });
          },
          nudgeDescription(key, shift));

  // The Landmarks tool reports its clicks; the pairs live here until the pose is solved.
  connect(wb_.view, &FrameView::landmarkModelPicked, this, [this](const Eigen::Vector3d& m) {
    if (!data()) return;
    auto l = data()->landmarks;
    l.push_back({m, Eigen::Vector2d::Zero(), false});
    editLandmarks(std::move(l), tr("Landmark on the organ"));
    wb_.status(tr("Landmark %1 on the organ; now click where it is in the frame.").arg(landmarks().size()));
  });
  connect(wb_.view, &FrameView::landmarkImagePicked, this, [this](const Eigen::Vector2d& p) {
    if (!data() || data()->landmarks.empty()) return;
    auto l = data()->landmarks;
    l.back().image = p;
    l.back().hasImage = true;
    editLandmarks(std::move(l), tr("Landmark in the frame"));
    wb_.status(tr("%1 landmark pairs; click the organ for the next, or solve (4 or more).").arg(landmarks().size()));
  });
}

void RigidPage::editLandmarks(std::vector<LandmarkPair> l, const QString& text) {
  wb_.doc->edit(text, [&l](app::Case& k) { k.landmarks = std::move(l); });
}

void RigidPage::setDistanceText(const QString& text) { distanceLabel_->setText(text); }

void RigidPage::refreshLandmarks(const app::Case& c) {
  landmarkList_->clear();
  int complete = 0;
  for (std::size_t i = 0; i < c.landmarks.size(); ++i) {
    const auto& p = c.landmarks[i];
    complete += p.hasImage;
    landmarkList_->addItem(QStringLiteral("%1: (%2, %3, %4) mm -> %5")
                               .arg(i + 1)
                               .arg(p.model.x() * 1e3, 0, 'f', 1)
                               .arg(p.model.y() * 1e3, 0, 'f', 1)
                               .arg(p.model.z() * 1e3, 0, 'f', 1)
                               .arg(p.hasImage ? QStringLiteral("(%1, %2) px").arg(p.image.x(), 0, 'f', 1).arg(p.image.y(), 0, 'f', 1)
                                               : tr("click the frame")));
  }
  if (c.landmarks.empty()) {
    // Where the pairs are made is the frame view, not this list (a person looked for it here).
    auto* hint = new QListWidgetItem(tr("None yet: press Pick Landmarks (L), click a point on the organ in the frame "
                                        "view, then where that point is in the frame."),
                                     landmarkList_);
    hint->setFlags(Qt::NoItemFlags);
    hint->setForeground(palette().color(QPalette::Disabled, QPalette::Text));
  }
  landmarkList_->setWordWrap(true);
  pnpButton_->setEnabled(complete >= 4);
}

void RigidPage::refresh(const app::Case& c) {
  refreshLandmarks(c);
  if (!c.hasPose) return;
  updating_ = true;
  // Translation in mm, rotation as Z-Y-X Euler angles in degrees: R = Rz(rz) Ry(ry) Rx(rx), angles in
  // (-180, 180] with ry in [-90, 90] (the fields rebuild R the same way).
  const auto& R = c.pose.R;
  const double rz = std::atan2(R(1, 0), R(0, 0)), ry = std::asin(std::clamp(-R(2, 0), -1.0, 1.0)), rx = std::atan2(R(2, 1), R(2, 2));
  const double d = 180 / M_PI;
  const double vals[6] = {c.pose.t.x() * 1e3, c.pose.t.y() * 1e3, c.pose.t.z() * 1e3, rx * d, ry * d, rz * d};
  for (int k = 0; k < 6; ++k) poseFields_[k]->setValue(vals[k]);
  updating_ = false;
}

void RigidPage::loadPose(const QString& path) {
  if (!data()) return;
  try {
    // A 4x4 matrix has no unit: it is read in the organ file's (JSON poses say theirs).
    const double unit = data()->organ->sourceUnitToMetre;
    const Pose p = imaging::loadPose(path.toStdString(), unit);
    wb_.doc->edit(tr("Load pose"), [&p](app::Case& k) {
      k.pose = p;
      k.hasPose = true;
      k.poseAligned = true;
    });
    wb_.status(tr("Pose loaded from %1.").arg(QFileInfo(path).fileName()));
  } catch (const std::exception& e) {
    wb_.status(QString::fromUtf8(e.what()));
  }
}

void RigidPage::solvePnP() {
  if (!data()) return;
  std::vector<Eigen::Vector3d> model;
  std::vector<Eigen::Vector2d> image;
  for (const auto& l : data()->landmarks)
    if (l.hasImage) {
      model.push_back(l.model);
      image.push_back(l.image);
    }
  if (model.size() < 4) {
    wb_.status(tr("Pick at least 4 landmark pairs first."));
    return;
  }
  const auto result = imaging::poseFromLandmarks(data()->camera, model, image, data()->pose);
  if (!result) {
    wb_.status(tr("The landmarks do not determine a pose; spread them over the organ and try again."));
    return;
  }
  pnpError_ = result->rmsPixels;
  const Pose p = result->pose;
  wb_.doc->edit(tr("Pose from landmarks"), [p](app::Case& k) {
    k.pose = p;
    k.hasPose = true;
    k.poseAligned = true;
  });
  if (result->ambiguous)
    wb_.status(tr("Pose from %1 landmark pairs: reprojection RMS %2 px, but another pose fits nearly as well (%3 px): "
                  "the landmarks do not decide; add pairs away from the others.")
                   .arg(model.size()).arg(pnpError_, 0, 'f', 3).arg(result->alternativeRmsPixels, 0, 'f', 3));
  else
    wb_.status(tr("Pose from %1 landmark pairs: reprojection RMS %2 px.").arg(model.size()).arg(pnpError_, 0, 'f', 3));
}

}  // namespace rehearse::ui
