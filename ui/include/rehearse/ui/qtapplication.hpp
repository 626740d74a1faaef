#pragma once
// A Qt application for the command line's uses of the GUI library (a PDF report, the training database), when the
// process has none yet: offscreen without a display.
namespace rehearse::ui {

/// A QGuiApplication for headless use when the process has no Qt application yet (a report's fonts and painter need a
/// GUI application; the training database's Qt SQL works under it too, and a report may follow it in one process).
void ensureGuiApplication();

}  // namespace rehearse::ui
