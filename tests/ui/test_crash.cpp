// Crash reports (issue 39): the real program, killed with SIGSEGV while its window is up, writes a local report (its
// version and revision, the signal, what it was doing, its stack) and ends as the signal would; the next start offers
// the report (show, delete or keep; a kept one is not offered again). Nothing is sent anywhere.
#include "test_support.hpp"

#include "rehearse/ui/crashreport.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"

#include <QAbstractButton>
#include <QApplication>
#include <QDir>
#include <QMessageBox>
#include <QProcess>
#include <QTemporaryDir>

#include <csignal>

using rehearse::ui::MainWindow;
namespace crash = rehearse::ui::crash;

class TestCrash : public QObject {
  Q_OBJECT
  QTemporaryDir home_;
  QString folder() const { return home_.filePath("data/Rehearse/Rehearse/crash-reports"); }

  QMessageBox* offer() {
    for (QWidget* w : QApplication::topLevelWidgets())
      if (auto* box = qobject_cast<QMessageBox*>(w); box && box->objectName() == "crashReportOffer" && box->isVisible())
        return box;
    return nullptr;
  }

 private slots:
  void aCrashWritesALocalReport() {
    QProcess child;
    QProcessEnvironment env = QProcessEnvironment::systemEnvironment();
    env.insert("QT_QPA_PLATFORM", "offscreen");
    env.insert("HOME", home_.path());
    env.insert("XDG_DATA_HOME", home_.filePath("data"));
    env.insert("XDG_CONFIG_HOME", home_.filePath("config"));
    child.setProcessEnvironment(env);
    child.start(REHEARSE_BINARY, {"open", "--no-recover", "--software"});
    QVERIFY(child.waitForStarted(30000));
    // The handlers are installed before the folder is made; the window is up a few seconds later.
    QElapsedTimer t;
    t.start();
    while (!QDir(folder()).exists() && t.elapsed() < 60000 && child.state() == QProcess::Running) QTest::qWait(50);
    QVERIFY2(QDir(folder()).exists(), "the program made no crash-report folder");
    QTest::qWait(4000);
    QCOMPARE(child.state(), QProcess::Running);
    QVERIFY(crash::pendingReports(folder()).isEmpty());  // nothing is written unless it crashes
    ::kill(static_cast<pid_t>(child.processId()), SIGSEGV);
    QVERIFY(child.waitForFinished(30000));
    QCOMPARE(child.exitStatus(), QProcess::CrashExit);  // it ended as the signal would have
    const QStringList reports = crash::pendingReports(folder());
    QCOMPARE(reports.size(), 1);
    const QString report = QString::fromStdString(readFile(reports.front().toStdString()));
    qInfo("%s", qPrintable(report.left(900)));
    QVERIFY(report.startsWith("Rehearse crash report (kept on this machine; never sent anywhere)"));
    QVERIFY(report.contains("version: 0.1.0 (git ") || report.contains("version: 0.1.0 (revision unknown"));
    QVERIFY(report.contains("signal: SIGSEGV"));
    // The built-in case opens on its next step (3, the contour): the step shown when it crashed.
    QVERIFY2(report.contains("what was running: step 3 Contour"), qPrintable(report));
    const QStringList stack = report.mid(report.indexOf("stack (innermost first):")).split('\n', Qt::SkipEmptyParts);
    QVERIFY2(stack.size() >= 6, qPrintable(report));  // the header line and the frames down to main
    QVERIFY(report.contains("libQt6Core") || report.contains("rehearse"));
  }

  // The next start offers it: a non-modal box naming what was running and where the report is.
  void theNextStartOffersIt() {
    QStringList reports = crash::pendingReports(folder());
    QCOMPARE(reports.size(), 1);
    MainWindow w;
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    w.offerCrashReports(folder());
    QMessageBox* box = offer();
    QVERIFY(box);
    QVERIFY(box->text().contains(reports.front()));
    QVERIFY(box->text().contains("step 3 Contour"));
    QVERIFY(box->text().contains("never sent"));
    // Keep: not offered again, the report still on disk.
    auto* keep = box->findChild<QAbstractButton*>("keepCrashReport");
    QVERIFY(keep);
    QCOMPARE(keep->text(), QString("Keep"));
    QTest::mouseClick(keep, Qt::LeftButton);
    QTRY_VERIFY(offer() == nullptr);
    QVERIFY(crash::pendingReports(folder()).isEmpty());
    QVERIFY(QFileInfo::exists(QString(reports.front()).replace(".txt", ".shown.txt")));
    w.offerCrashReports(folder());
    QVERIFY(offer() == nullptr);
    QVERIFY(w.messageLog().join("\n").contains("Rehearse stopped unexpectedly last time"));
    // Delete: gone from the disk.
    const QString another = QDir(folder()).filePath("crash-20261128-120000-42.txt");
    writeFile(another.toStdString(), "Rehearse crash report\nwhat was running: step 5 Elastic fit; job: Fitting\n");
    w.offerCrashReports(folder());
    box = offer();
    QVERIFY(box);
    QVERIFY(box->text().contains("step 5 Elastic fit; job: Fitting"));
    QAbstractButton* remove = box->findChild<QAbstractButton*>("deleteCrashReport");
    QVERIFY(remove);
    QTest::mouseClick(remove, Qt::LeftButton);
    QTRY_VERIFY(offer() == nullptr);
    QVERIFY(!QFileInfo::exists(another));
  }
};

int main(int argc, char** argv) {
  QApplication app(argc, argv);
  rehearse::ui::applyDarkTheme(app);
  QStandardPaths::setTestModeEnabled(true);
  TestCrash t;
  return QTest::qExec(&t, argc, argv);
}
#include "test_crash.moc"
