// Under Xvfb (OpenGL through Mesa's llvmpipe): the main window uses its OpenGL organ view and that view
// draws the organ; with --software (or where no GL context can be made) the software view is used.
#include <QtTest>

#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/organview.hpp"

#include <QSignalSpy>
#include <QStandardPaths>

using namespace rehearse;

class TestGl : public QObject {
  Q_OBJECT
 private slots:
  void initTestCase() {
    QStandardPaths::setTestModeEnabled(true);
    if (QGuiApplication::platformName() != QLatin1String("xcb")) QSKIP("needs an X server with OpenGL (run under xvfb-run)");
  }

  void openGLOrganView() {
    QVERIFY2(ui::OrganGLView::openGLAvailable(), "no OpenGL 3.3 context under Xvfb");
    ui::MainWindow w;
    w.resize(1400, 900);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
    w.openCase({});
    QVERIFY(loaded.wait(60000));
    QVERIFY(w.organViewUsesOpenGL());
    auto* gl = qobject_cast<ui::OrganGLView*>(w.organWidget());
    QVERIFY(gl);
    QTRY_VERIFY_WITH_TIMEOUT(gl->glReady(), 10000);
    qInfo("OpenGL: %s", qPrintable(gl->glVersion()));
    const QImage img = gl->grabFramebuffer();
    QVERIFY(!img.isNull());
    // Organ pixels: reddish, unlike the dark background.
    int organ = 0;
    for (int y = 0; y < img.height(); ++y)
      for (int x = 0; x < img.width(); ++x) {
        const QColor c = img.pixelColor(x, y);
        organ += c.red() > 60 && c.red() > c.blue();
      }
    const double share = organ / double(img.width() * img.height());
    qInfo("organ covers %.1f %% of the OpenGL view", 100 * share);
    QVERIFY(share > 0.05 && share < 0.9);
    // Turning it with the mouse changes the picture.
    QTest::mousePress(gl, Qt::LeftButton, {}, gl->rect().center());
    QTest::mouseMove(gl, gl->rect().center() + QPoint(80, 0));
    QTest::mouseRelease(gl, Qt::LeftButton, {}, gl->rect().center() + QPoint(80, 0));
    const QImage turned = gl->grabFramebuffer();
    QVERIFY(turned != img);
  }

  void softwareFallback() {
    ui::MainWindow::setSoftwareRendering(true);
    ui::MainWindow w;
    QVERIFY(!w.organViewUsesOpenGL());
    QVERIFY(qobject_cast<ui::OrganView*>(w.organWidget()));
    ui::MainWindow::setSoftwareRendering(false);
  }
};

QTEST_MAIN(TestGl)
#include "test_gl.moc"
