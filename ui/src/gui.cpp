#include "rehearse/ui/gui.hpp"

#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/crashreport.hpp"
#include "rehearse_revision.hpp"

#include <QApplication>
#include <QCommandLineParser>
#include <QLibraryInfo>
#include <QLocale>
#include <QTranslator>
#include <QPalette>
#include <QStyleFactory>
#include <QTimer>

#include <cstdio>
#include <cstdlib>

namespace rehearse::ui {
// Operating rooms are dim: a dark theme by default.
QString installTranslation(const QString& language) {
  static QTranslator* ours = nullptr;
  static QTranslator* qts = nullptr;
  for (QTranslator** t : {&ours, &qts})
    if (*t) {
      QCoreApplication::removeTranslator(*t);
      delete *t;
      *t = nullptr;
    }
  const QLocale locale = language.isEmpty() ? QLocale::system() : QLocale(language);
  if (language == QLatin1String("en") || language == QLatin1String("C") || locale.language() == QLocale::English)
    return {};
  auto* own = new QTranslator;
  if (!own->load(locale, QStringLiteral("rehearse"), QStringLiteral("_"), QStringLiteral(":/i18n"))) {
    delete own;
    return {};
  }
  QCoreApplication::installTranslator(own);
  ours = own;
  auto* base = new QTranslator;
  if (base->load(locale, QStringLiteral("qtbase"), QStringLiteral("_"),
                 QLibraryInfo::path(QLibraryInfo::TranslationsPath))) {
    QCoreApplication::installTranslator(base);
    qts = base;
  } else {
    delete base;
  }
  return QLocale::languageToCode(locale.language());
}

void applyDarkTheme(QApplication& app) {
  app.setStyle(QStyleFactory::create(QStringLiteral("Fusion")));
  QPalette p;
  p.setColor(QPalette::Window, QColor(37, 38, 41));
  p.setColor(QPalette::WindowText, QColor(225, 225, 225));
  p.setColor(QPalette::Base, QColor(26, 27, 30));
  p.setColor(QPalette::AlternateBase, QColor(44, 45, 48));
  p.setColor(QPalette::Text, QColor(225, 225, 225));
  p.setColor(QPalette::Button, QColor(48, 49, 53));
  p.setColor(QPalette::ButtonText, QColor(225, 225, 225));
  p.setColor(QPalette::Highlight, QColor(46, 140, 90));
  p.setColor(QPalette::HighlightedText, Qt::white);
  p.setColor(QPalette::ToolTipBase, QColor(50, 50, 50));
  p.setColor(QPalette::ToolTipText, Qt::white);
  p.setColor(QPalette::PlaceholderText, QColor(150, 150, 150));  // (Fusion's dark grey was nearly invisible on Base)
  p.setColor(QPalette::Disabled, QPalette::Text, QColor(110, 110, 110));
  p.setColor(QPalette::Disabled, QPalette::ButtonText, QColor(110, 110, 110));
  p.setColor(QPalette::Disabled, QPalette::WindowText, QColor(110, 110, 110));
  app.setPalette(p);
  QFont f = app.font();
  f.setPointSizeF(std::max(11.0, f.pointSizeF()));
  app.setFont(f);
}

int runGui(int argc, char** argv) {
#if defined(__linux__)
  // Without a display Qt aborts with a page about platform plugins; say it in one line instead.
  const auto unset = [](const char* name) {
    const char* v = std::getenv(name);
    return !v || !*v;
  };
  if (unset("DISPLAY") && unset("WAYLAND_DISPLAY") && unset("QT_QPA_PLATFORM")) {
    std::fprintf(stderr, "rehearse: no display to open the window on (DISPLAY is not set); run it under xvfb-run, or "
                         "use scripts/run.sh, which does\n");
    return 1;
  }
#endif
  QApplication app(argc, argv);
  QApplication::setOrganizationName(QStringLiteral("Rehearse"));
  QApplication::setApplicationName(QStringLiteral("Rehearse"));
  QApplication::setApplicationVersion(QStringLiteral(REHEARSE_VERSION));
  applyDarkTheme(app);
  // Crash reports: written locally on a crash, offered at the next start (crashreport.hpp).
  crash::install(crash::defaultFolder(), QStringLiteral(REHEARSE_VERSION " (" REHEARSE_REVISION ")"));

  QCommandLineParser parser;
  parser.addPositionalArgument(QStringLiteral("open"), QStringLiteral("open CASE"));
  QCommandLineOption screenshot(QStringLiteral("screenshot"), QStringLiteral("Save the window to PNG and quit."), QStringLiteral("png"));
  QCommandLineOption software(QStringLiteral("software"), QStringLiteral("Draw the views on the CPU, without OpenGL."));
  QCommandLineOption opengl(QStringLiteral("opengl"),
                            QStringLiteral("Draw the views with OpenGL even through a software rasteriser (by default a software "
                                           "OpenGL such as Mesa's llvmpipe is not used: the CPU views are faster there)."));
  QCommandLineOption language(QStringLiteral("language"),
                              QStringLiteral("The interface's language (fr; en: English); by default the system's."),
                              QStringLiteral("code"));
  QCommandLineOption noRecover(QStringLiteral("no-recover"), QStringLiteral("Do not offer to recover an autosaved case."));
  parser.addOption(screenshot);
  parser.addOption(software);
  parser.addOption(opengl);
  parser.addOption(noRecover);
  parser.addOption(language);
  if (!parser.parse(app.arguments())) {
    std::fprintf(stderr, "rehearse: %s; see 'rehearse --help'\n", qPrintable(parser.errorText()));
    return 2;
  }
  installTranslation(parser.value(language));
  const QStringList pos = parser.positionalArguments();
  QString caseDir;
  if (!pos.isEmpty()) {
    // (`open` alone: the built-in case, as a desktop launcher with no file to give runs it)
    if (pos.size() > 2 || pos[0] != QLatin1String("open")) {
      std::fprintf(stderr, "rehearse: expected 'open CASE'; see 'rehearse --help'\n");
      return 2;
    }
    if (pos.size() == 2) caseDir = pos[1];
  }
  if (parser.isSet(software) && parser.isSet(opengl)) {
    std::fprintf(stderr, "rehearse: --software and --opengl contradict each other; give one\n");
    return 2;
  }
  MainWindow::setRenderer(parser.isSet(software) ? MainWindow::Renderer::Software
                          : parser.isSet(opengl) ? MainWindow::Renderer::OpenGL
                                                 : MainWindow::Renderer::Automatic);
  MainWindow window;
  const QString shot = parser.value(screenshot);
  int exitCode = 0;
  if (!shot.isEmpty()) {
    QObject::connect(&window, &MainWindow::caseLoaded, &window, [&window, shot, &exitCode](bool ok) {
      QTimer::singleShot(300, &window, [&window, shot, ok, &exitCode] {
        const bool saved = window.grab().save(shot);
        if (!saved) std::fprintf(stderr, "rehearse: error: cannot write %s\n", qPrintable(shot));
        exitCode = ok && saved ? 0 : 1;
        QMetaObject::invokeMethod(qApp, &QCoreApplication::quit, Qt::QueuedConnection);
      });
    });
  }
  // This program's autosave slot is held from the start (a second program launched beside it takes another), and a
  // crash's autosave found in it is set aside at once: this run's autosaves never overwrite it, asked or not.
  CaseDocument::setAsideCrashedAutosave();
  window.show();
  const bool recover = shot.isEmpty() && !parser.isSet(noRecover) && MainWindow::hasRecoverableAutosave();
  window.openCase(caseDir);
  if (recover) QTimer::singleShot(0, &window, &MainWindow::offerRecovery);
  if (shot.isEmpty()) QTimer::singleShot(0, &window, [&window] { window.offerCrashReports(crash::defaultFolder()); });
  const int code = app.exec();
  return shot.isEmpty() ? code : exitCode;
}

}  // namespace rehearse::ui
