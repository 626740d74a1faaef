#pragma once
#include <QString>
class QApplication;

namespace rehearse::ui {
/// The dark theme used by default (operating rooms are dim): Fusion style, dark palette, 11 pt minimum.
void applyDarkTheme(QApplication& app);

/// Installs the interface's translation for `language` ("fr", "fr_FR"; "en" or "C": none, the interface's own
/// English; empty: the system's locale): Rehearse's own (built in, ui/translations/) and Qt's for its standard dialogs
/// when Debian's qt6-translations-l10n is there. Returns the language installed ("fr"), or an empty string when the
/// interface is in English (no translation for that language). Call before the windows are made.
QString installTranslation(const QString& language);
/// Starts the GUI: `rehearse [open CASE] [--screenshot PNG] [--software]`. Returns the exit code.
int runGui(int argc, char** argv);
}  // namespace rehearse::ui
