#pragma once
// The keyboard reference (issue 39): every key the main window answers, read from the window itself (its actions'
// shortcuts with their names, the step pages' keys with what each does in its step, the frame view's own keys), so
// the Help menu's table and the user guide's can never list a key that does not exist or miss one that does.
#include <QString>
#include <QStringList>

#include <vector>

class QWidget;

namespace rehearse::ui {

struct KeyEntry {
  QString keys;   ///< as Qt writes them, portable: "Ctrl+Shift+O", "F9", "Alt+1"
  QString what;   ///< what the key does
  QString where;  ///< the menu it is in, or the step it works in ("Step 4 Rigid alignment"), or "Frame view"
};

/// Every key of the window, sorted by where, then keys; duplicates (the same key doing the same thing from a menu
/// and a button) once.
std::vector<KeyEntry> keyboardReference(const QWidget& window);

/// The keys of a reference, each once ("F9", "Ctrl+Z", ...).
QStringList referenceKeys(const std::vector<KeyEntry>& reference);

/// The reference as a Markdown table (where | keys | what).
QString keyboardReferenceMarkdown(const std::vector<KeyEntry>& reference);

/// The user guide (docs/guide.md): its `<!-- keyboard reference -->` line replaced by the reference, rendered to
/// OUT_DIR/guide.html and OUT_DIR/guide.pdf (A4) with Qt's own Markdown and PDF support; its images are read from
/// OUT_DIR (relative names) and drawn at most `imageWidth` pixels wide. Returns an empty string, or why not.
QString renderUserGuide(const QString& markdown, const QString& outDir, const std::vector<KeyEntry>& reference,
                        int imageWidth = 720);

}  // namespace rehearse::ui
