#include "rehearse/ui/keyboardreference.hpp"

#include "rehearse/ui/frameview.hpp"
#include <rehearse/app/workflow.hpp>
#include "rehearse/ui/pages/steppage.hpp"

#include <QAbstractButton>
#include <QAction>
#include <QDir>
#include <QFile>
#include <QMenu>
#include <QPageSize>
#include <QPdfWriter>
#include <QRegularExpression>
#include <QTextBlock>
#include <QTextCursor>
#include <QTextDocument>
#include <QTextDocumentWriter>
#include <QTextFragment>
#include <QTextImageFormat>
#include <QWidget>

#include <algorithm>
#include <set>

namespace rehearse::ui {
namespace {

QString plain(QString text) {
  text.remove(QLatin1Char('&'));
  text.remove(QRegularExpression(QStringLiteral("\\s*\\([^()]*\\)\\s*$")));  // "Grasper (R)" -> "Grasper"
  text.remove(QRegularExpression(QStringLiteral("\\.\\.\\.$")));
  return text.trimmed();
}

QString menuOf(const QAction* a) {
  for (QObject* o : a->associatedObjects())
    if (auto* menu = qobject_cast<QMenu*>(o)) return plain(menu->title()) + QStringLiteral(" menu");
  return {};
}

}  // namespace

std::vector<KeyEntry> keyboardReference(const QWidget& window) {
  std::vector<KeyEntry> out;
  std::set<std::pair<QString, QString>> seen;  // (keys, what)
  auto add = [&](const QString& keys, const QString& what, const QString& where) {
    if (keys.isEmpty() || what.isEmpty()) return;
    if (!seen.insert({keys, what}).second) return;
    out.push_back({keys, what, where});
  };
  for (const QAction* a : window.findChildren<QAction*>()) {
    if (a->shortcuts().isEmpty()) continue;
    // A step page's key (StepKeys): what it does in each step that uses it (the same key, one thing per step).
    const QVariantMap perStep = a->property("rehearseStepKeys").toMap();
    if (!perStep.isEmpty()) {
      for (auto it = perStep.begin(); it != perStep.end(); ++it) {
        const int step = it.key().toInt();
        add(a->shortcut().toString(QKeySequence::PortableText), it.value().toString(),
            QStringLiteral("Step %1 %2")
                .arg(step + 1)
                .arg(QString::fromLatin1(app::kSteps[static_cast<std::size_t>(step)].title)));
      }
      continue;
    }
    QString where = menuOf(a);
    if (where.isEmpty()) where = a->property("rehearseWhere").toString();
    if (where.isEmpty()) where = QStringLiteral("Main window");
    QString what = plain(a->text());
    if (what.isEmpty()) what = a->toolTip() == a->text() ? QString() : a->toolTip();
    for (const QKeySequence& k : a->shortcuts()) add(k.toString(QKeySequence::PortableText), what, where);
  }
  for (const QAbstractButton* b : window.findChildren<QAbstractButton*>()) {
    if (b->shortcut().isEmpty()) continue;
    // Where: the step page the button is on.
    QString where = b->property("rehearseWhere").toString();
    for (const QWidget* p = b->parentWidget(); p && where.isEmpty(); p = p->parentWidget())
      if (const auto* page = qobject_cast<const StepPage*>(p)) {
        const int step = app::index(page->step());
        where = QStringLiteral("Step %1 %2")
                    .arg(step + 1)
                    .arg(QString::fromLatin1(app::kSteps[static_cast<std::size_t>(step)].title));
      }
    // What: its text, or its tool tip when the text is a sign ("<", ">").
    QString what = plain(b->text());
    if (!what.contains(QRegularExpression(QStringLiteral("[A-Za-z]")))) what = plain(b->toolTip());
    add(b->shortcut().toString(QKeySequence::PortableText), what,
        where.isEmpty() ? QStringLiteral("Main window") : where);
  }
  for (const auto& [key, what] : FrameView::viewKeys()) add(key, what, QStringLiteral("Frame view"));
  std::stable_sort(out.begin(), out.end(), [](const KeyEntry& a, const KeyEntry& b) {
    return a.where != b.where ? a.where < b.where : a.keys < b.keys;
  });
  return out;
}

QStringList referenceKeys(const std::vector<KeyEntry>& reference) {
  QStringList keys;
  for (const auto& e : reference)
    if (!keys.contains(e.keys)) keys << e.keys;
  return keys;
}

QString keyboardReferenceMarkdown(const std::vector<KeyEntry>& reference) {
  QString md = QStringLiteral("| Where | Keys | What |\n|---|---|---|\n");
  for (const auto& e : reference) {
    QString what = e.what;
    what.replace(QLatin1Char('|'), QStringLiteral("\\|"));
    md += QStringLiteral("| %1 | %2 | %3 |\n").arg(e.where, e.keys, what);
  }
  return md;
}

QString renderUserGuide(const QString& markdown, const QString& outDir, const std::vector<KeyEntry>& reference,
                        int imageWidth) {
  const QString marker = QStringLiteral("<!-- keyboard reference -->");
  if (!markdown.contains(marker))
    return QStringLiteral("The guide has no '%1' line for the keyboard reference.").arg(marker);
  QString md = markdown;
  md.replace(marker, keyboardReferenceMarkdown(reference));
  QDir dir(outDir);
  if (!dir.exists() && !QDir().mkpath(outDir)) return QStringLiteral("Cannot create %1.").arg(outDir);
  QTextDocument doc;
  doc.setBaseUrl(QUrl::fromLocalFile(dir.absolutePath() + QLatin1Char('/')));
  doc.setMarkdown(md, QTextDocument::MarkdownDialectGitHub);
  // Screenshots are 1600 pixels wide: drawn at most imageWidth wide, keeping their shape.
  QStringList missing;
  for (QTextBlock block = doc.begin(); block.isValid(); block = block.next())
    for (auto it = block.begin(); !it.atEnd(); ++it) {
      const QTextFragment f = it.fragment();
      if (!f.charFormat().isImageFormat()) continue;
      QTextImageFormat image = f.charFormat().toImageFormat();
      const QImage picture(dir.filePath(image.name()));
      if (picture.isNull()) {
        missing << image.name();
        continue;
      }
      // Given to the document itself: it does not read local files for a document without a viewer.
      doc.addResource(QTextDocument::ImageResource, QUrl(image.name()), QVariant(picture));
      const double w = std::min(imageWidth, picture.width());
      image.setWidth(w);
      image.setHeight(w * picture.height() / picture.width());
      QTextCursor c(&doc);
      c.setPosition(f.position());
      c.setPosition(f.position() + f.length(), QTextCursor::KeepAnchor);
      c.setCharFormat(image);
    }
  if (!missing.isEmpty())
    return QStringLiteral("The guide's images are missing: %1.").arg(missing.join(QStringLiteral(", ")));
  QFile html(dir.filePath(QStringLiteral("guide.html")));
  if (!html.open(QIODevice::WriteOnly | QIODevice::Truncate))
    return QStringLiteral("Cannot write %1.").arg(html.fileName());
  html.write(doc.toHtml().toUtf8());
  html.close();
  QPdfWriter pdf(dir.filePath(QStringLiteral("guide.pdf")));
  pdf.setPageSize(QPageSize(QPageSize::A4));
  pdf.setResolution(150);
  pdf.setTitle(QStringLiteral("Rehearse user guide"));
  pdf.setCreator(QStringLiteral("Rehearse"));
  doc.print(&pdf);
  return {};
}

}  // namespace rehearse::ui
