#pragma once
// A Qt application for the command line's use of the GUI library (a PDF report), when the
// process has none yet: offscreen without a display.
namespace rehearse::ui {

/// A QGuiApplication for headless use when the process has no Qt application yet (a report's fonts and painter need a
/// GUI application).
void ensureGuiApplication();

}  // namespace rehearse::ui
