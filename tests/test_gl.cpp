// Under Xvfb (OpenGL through Mesa's llvmpipe): the main window uses its OpenGL organ view and that view
// draws the organ; the frame view's overlay drawn with OpenGL matches the CPU rasteriser's; with
// --software (or where no GL context can be made) the software view and the CPU overlay are used.
#include <QtTest>

#include "phantom/phantom.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/gloverlay.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/organview.hpp"

#include <QSignalSpy>
#include <QElapsedTimer>
#include <QStandardPaths>

#include <algorithm>
#include <functional>
#include <vector>

#include <rehearse/imaging/render.hpp>

#include <opencv2/imgproc.hpp>

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
    QVERIFY(w.overlayUsesOpenGL());  // the frame view's overlay too
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

  // The overlay through the frame's camera: OpenGL against the CPU rasteriser on the phantom at its true
  // pose (same coverage and shading up to edge pixels and rounding).
  void openGLOverlayMatchesTheCpuOne() {
    const phantom::Phantom c = phantom::makePhantom();
    ui::GLOverlay gl;
    QVERIFY2(gl.valid(), "no OpenGL 3.3 context under Xvfb");
    QImage image;
    QVERIFY(gl.render(c.camera, c.truePose, c.surfaceView(), QColor(120, 210, 150), image));
    QCOMPARE(image.size(), QSize(c.camera.width, c.camera.height));
    const cv::Mat4b cpu = imaging::renderOverlay(c.camera, c.truePose, c.surfaceView(), cv::Vec3b(150, 210, 120));
    int both = 0, either = 0;
    double colourDiff = 0;
    for (int y = 0; y < image.height(); ++y) {
      const uchar* g = image.constScanLine(y);
      for (int x = 0; x < image.width(); ++x) {
        const cv::Vec4b p = cpu(y, x);
        const bool inG = g[4 * x + 3] > 127, inC = p[3] > 127;
        either += inG || inC;
        if (inG && inC) {
          ++both;
          colourDiff += std::abs(g[4 * x] - p[2]) + std::abs(g[4 * x + 1] - p[1]) + std::abs(g[4 * x + 2] - p[0]);
        }
      }
    }
    const double iou = double(both) / either, meanDiff = colourDiff / (3.0 * both);
    qInfo("OpenGL overlay against the CPU one: IoU %.4f over %d pixels, mean colour difference %.4f levels (%.0f in total)", iou, either, meanDiff, colourDiff);
    QVERIFY(iou > 0.995);
    QVERIFY(meanDiff < 2.0);
    // How long each takes (reported, not asserted: this machine is shared): medians of 7.
    auto median = [](const std::function<void()>& f) {
      std::vector<double> ms;
      for (int i = 0; i < 7; ++i) {
        QElapsedTimer t;
        t.start();
        f();
        ms.push_back(t.nsecsElapsed() / 1e6);
      }
      std::sort(ms.begin(), ms.end());
      return ms[3];
    };
    const double glMs = median([&] { gl.render(c.camera, c.truePose, c.surfaceView(), QColor(120, 210, 150), image); });
    const double cpuMs = median([&] { imaging::renderOverlay(c.camera, c.truePose, c.surfaceView(), cv::Vec3b(150, 210, 120)); });
    qInfo("1280x720 overlay: OpenGL %.1f ms, CPU %.1f ms (medians of 7, including the read-back)", glMs, cpuMs);
  }

  void softwareFallback() {
    ui::MainWindow::setSoftwareRendering(true);
    ui::MainWindow w;
    QVERIFY(!w.organViewUsesOpenGL());
    QVERIFY(!w.overlayUsesOpenGL());
    QVERIFY(qobject_cast<ui::OrganView*>(w.organWidget()));
    ui::MainWindow::setSoftwareRendering(false);
  }
};

QTEST_MAIN(TestGl)
#include "test_gl.moc"
