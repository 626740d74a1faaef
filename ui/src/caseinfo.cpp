#include "rehearse/ui/caseinfo.hpp"

#include <QCoreApplication>

namespace rehearse::ui {
namespace {
QString tr(const char* s) { return QCoreApplication::translate("CaseInfo", s); }

QString poseText(const Pose& p) {
  QString s;
  for (int r = 0; r < 3; ++r)
    s += QStringLiteral("[%1 %2 %3]  t %4 mm\n")
             .arg(p.R(r, 0), 7, 'f', 4).arg(p.R(r, 1), 7, 'f', 4).arg(p.R(r, 2), 7, 'f', 4).arg(p.t[r] * 1e3, 8, 'f', 2);
  return s;
}
}  // namespace

QString caseInfoText(const app::Case& c, const QStringList& notes, const QString& qualityText) {
  QString t;
  t += tr("Case: %1\n").arg(QString::fromStdString(c.name));
  if (!c.organ->source.empty()) t += tr("Mesh from: %1\n").arg(QString::fromStdString(c.organ->source));
  t += QLatin1Char('\n');
  for (const auto& n : notes) t += tr("! %1\n").arg(n);
  if (!notes.isEmpty()) t += QLatin1Char('\n');
  t += tr("Organ mesh\n%1\n").arg(qualityText);
  t += tr("surface triangles: %1\nattachment nodes: %2\n\n").arg(c.organ->surface.size()).arg(c.attachments.size());
  const auto& cam = c.camera;
  t += tr("Camera\nimage: %1 x %2 px\nfx %3  fy %4 px\ncx %5  cy %6 px\ndistortion: %7 %8 %9 %10 %11\n\n")
           .arg(cam.width).arg(cam.height)
           .arg(cam.fx(), 0, 'f', 1).arg(cam.fy(), 0, 'f', 1).arg(cam.cx(), 0, 'f', 1).arg(cam.cy(), 0, 'f', 1)
           .arg(cam.distortion[0]).arg(cam.distortion[1]).arg(cam.distortion[2]).arg(cam.distortion[3]).arg(cam.distortion[4]);
  if (c.hasPose) t += tr("Pose (model to camera, %1)\n%2\n").arg(c.poseAligned ? tr("aligned") : c.hasFit() ? tr("placed by the elastic fit") : tr("automatic placement"), poseText(c.pose));
  if (c.hasFit()) t += tr("Elastic fit: %1\n\n").arg(QString::fromStdString(c.fit->status));
  if (c.appearance) {
    const auto& a = c.appearance->theta;
    t += tr("Appearance (estimated%1)\nlight: %2, %3, %4 mm\nkd: %5 %6 %7\nks: %8 %9 %10\nroughness: %11 rad\n%12\n\n")
             .arg(c.appearanceCurrent() ? QString() : tr(", STALE: the organ or the frame changed since"))
             .arg(a.lightPosition.x() * 1e3, 0, 'f', 1).arg(a.lightPosition.y() * 1e3, 0, 'f', 1).arg(a.lightPosition.z() * 1e3, 0, 'f', 1)
             .arg(a.kd.x()).arg(a.kd.y()).arg(a.kd.z()).arg(a.ks.x()).arg(a.ks.y()).arg(a.ks.z()).arg(a.roughness)
             .arg(QString::fromStdString(c.appearance->status));
  }
  if (c.groundTruth) {
    t += tr("Ground-truth pose\n%1").arg(poseText(c.groundTruth->pose));
    const auto& a = c.groundTruth->appearance;
    t += tr("\nLight (ground truth)\nposition: %1, %2, %3 mm\nkd: %4 %5 %6\nks: %7 %8 %9\nroughness: %10 rad\n")
             .arg(a.lightPosition.x() * 1e3).arg(a.lightPosition.y() * 1e3).arg(a.lightPosition.z() * 1e3)
             .arg(a.kd.x()).arg(a.kd.y()).arg(a.kd.z()).arg(a.ks.x()).arg(a.ks.y()).arg(a.ks.z()).arg(a.roughness);
  }
  return t;
}

}  // namespace rehearse::ui
