#pragma once
// The review's PDF report (Qt's QPdfWriter): what app::makeReviewReport gathered, on A4 pages.
#include <rehearse/app/review.hpp>

#include <string>

namespace rehearse::ui {

/// Writes the report (through a save file: never half-written). Throws std::runtime_error with one sentence.
/// Starts an offscreen QGuiApplication when the process has none (the command line's `replay --report`).
void writeReviewPdf(const app::ReviewReport& report, const std::string& path);

}  // namespace rehearse::ui
