#pragma once
// The Case panel's text: where the mesh came from, problems found on opening or importing, mesh quality,
// camera, pose, and the ground truth when the case has one (kept apart from the user's work).
#include <rehearse/app/case.hpp>

#include <QString>
#include <QStringList>

namespace rehearse::ui {

QString caseInfoText(const app::Case& c, const QStringList& notes, const QString& qualityText);

}  // namespace rehearse::ui
