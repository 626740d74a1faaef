#pragma once
class QApplication;

namespace rehearse::ui {
/// The dark theme used by default (operating rooms are dim): Fusion style, dark palette, 11 pt minimum.
void applyDarkTheme(QApplication& app);
/// Starts the GUI: `rehearse [open CASE] [--screenshot PNG] [--software]`. Returns the exit code.
int runGui(int argc, char** argv);
}  // namespace rehearse::ui
