#pragma once
// The review's PDF report (Qt's QPdfWriter): what app::makeReviewReport gathered, on A4 pages.
#include <rehearse/app/review.hpp>

#include <QColor>

#include <string>

namespace rehearse::ui {

/// Writes the report (through a save file: never half-written). Throws std::runtime_error with one sentence.
/// Starts an offscreen QGuiApplication when the process has none (the command line's `replay --report`).
void writeReviewPdf(const app::ReviewReport& report, const std::string& path);
/// The timeline's tick colour of a recorded event (the review window's and the report's; invalid: not ticked).
QColor reviewEventColour(const std::string& event);
/// The legend of those ticks, in words.
extern const char* const kReviewEventLegend;

}  // namespace rehearse::ui
