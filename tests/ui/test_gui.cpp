// The real main window, driven with QTest events offscreen: the built-in case loads on a worker thread
// and the frame shows the organ over it; keys toggle the overlay; a damaged case folder opens with a message.
#include "fresh_start.hpp"
#include "test_support.hpp"
#include "icosphere.hpp"

#include <QUndoStack>
#include <QFileInfo>
#include <QDir>

#include "phantom/phantom.hpp"
#include <rehearse/app/casefolder.hpp>
#include "rehearse/ui/casedocument.hpp"
#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/organview.hpp"
#include "rehearse/ui/organoverlay.hpp"
#include "rehearse/ui/pages/meshpage.hpp"
#include "rehearse/ui/pages/steppage.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/jobrunner.hpp"
#include "rehearse/ui/steadybox.hpp"
#include "window_support.hpp"
#include <QAbstractButton>
#include <QAbstractItemView>
#include <QAbstractSpinBox>
#include <QAccessible>
#include <QComboBox>
#include <QLineEdit>
#include <QListWidget>
#include <QMenuBar>
#include <QMessageBox>
#include <QSlider>
#include <rehearse/simcore/labelimage.hpp>

#include <algorithm>

#include <opencv2/imgproc.hpp>

#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QPlainTextEdit>
#include <QScrollBar>
#include <QStatusBar>
#include <QLabel>
#include <QHBoxLayout>
#include <QVBoxLayout>
#include <QSettings>
#include <QTimer>
#include <QTemporaryDir>
#include <QFileDialog>
#include <QSignalSpy>
#include <QThread>
#include <QStandardPaths>
#include <QLockFile>
#include <QScopeGuard>

using namespace rehearse;

class TestGui : public QObject {
  Q_OBJECT
  // A launch on the phantom that finds a crash's autosave: the recovery question it shows (null when none).
  // The window shown, active, with the built-in case open.
  static bool openBuiltInCase(ui::MainWindow& w) {
    w.show();
    if (!QTest::qWaitForWindowExposed(&w)) return false;
    w.activateWindow();
    if (!QTest::qWaitForWindowActive(&w)) return false;
    QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
    w.openCase({});
    return loaded.wait(60000);
  }

  static QMessageBox* launch(ui::MainWindow& w) {
    w.show();
    QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
    w.openCase({});
    if (!loaded.wait(60000) || !QTest::qWaitForWindowActive(&w)) return nullptr;
    w.offerRecovery();  // (what gui.cpp does at a start that finds the autosave)
    QMessageBox* box = nullptr;
    waitFor([&] {
      box = w.findChild<QMessageBox*>("recoverCaseBox");
      return box && box->isVisible();
    });
    return box;
  }

 private slots:
  // Several ticked inner structures are each drawn in their own colour: the phantom's vessel elements split
  // into two labels (2 and 3) give pixels of both label colours, where one colour was drawn before.
  void innerLabelsKeepTheirColours() {
    const auto p = phantom::makePhantom();
    app::Case c = app::caseFromPhantom(p);
    simcore::Mesh v = c.organ->volume;
    int relabelled = 0, vessels = 0;
    for (std::size_t e = 0; e < v.tets.size(); ++e)
      if (v.tetLabels[e] == app::kVesselLabel && (++vessels % 2 == 0)) {
        v.tetLabels[e] = 3;
        ++relabelled;
      }
    QVERIFY(relabelled > 10);
    c.organ = app::Organ::fromVolume(std::move(v));
    c.pose = p.truePose;
    c.hasPose = true;
    ui::OrganOverlay overlay(false);
    const ui::OverlayPicture pic = overlay.render(c, {2, 3});
    QVERIFY(!pic.inner.isNull());
    // Classify the drawn pixels by the nearer label colour (direction in RGB: the shading scales it).
    auto direction = [](const QColor& q) { return Eigen::Vector3d(q.red(), q.green(), q.blue()).normalized(); };
    const Eigen::Vector3d two = direction(ui::labelColour(2)), three = direction(ui::labelColour(3));
    int nearTwo = 0, nearThree = 0;
    const QImage img = pic.inner.convertToFormat(QImage::Format_RGBA8888);
    for (int y = 0; y < img.height(); ++y)
      for (int x = 0; x < img.width(); ++x) {
        const uchar* px = img.constScanLine(y) + 4 * x;
        if (px[3] < 128) continue;
        const Eigen::Vector3d d = Eigen::Vector3d(px[0], px[1], px[2]).normalized();
        (d.dot(two) > d.dot(three) ? nearTwo : nearThree)++;
      }
    qInfo("inner structures: %d pixels in label 2's colour, %d in label 3's", nearTwo, nearThree);
    QVERIFY(nearTwo > 100);
    QVERIFY(nearThree > 100);
    // The legend's key names each structure in the colour it is drawn in (a single red swatch stood for them before).
    QCOMPARE(pic.innerKey.size(), 2);
    QCOMPARE(pic.innerKey[0].first, ui::labelColour(2));
    QCOMPARE(pic.innerKey[1].first, ui::labelColour(3));
    ui::FrameView view;
    view.setFrame(QImage(320, 240, QImage::Format_RGB32));
    view.setInnerOverlay(pic.inner, pic.innerKey);
    QStringList inside;
    for (const auto& e : view.legend())
      if (e.text.startsWith("inside: ")) {
        inside << e.text;
        QVERIFY(e.colour == ui::labelColour(2) || e.colour == ui::labelColour(3));
      }
    QCOMPARE(inside.size(), 2);
  }

  // The frame view draws a frame that changes at each step (the composited view) through the painter's transform, and
  // scales and keeps it only once it has stayed the same a while (issue 64: scaling each new frame first paused the
  // window). Both drawings are the frame averaged down to the rectangle the view shows it in, as OpenCV's area
  // resampling makes it (an independent reference), within a few levels of 255: smooth gradients and a checker of
  // 16-pixel squares (edges, where the two filters differ most).
  void aChangingFrameIsDrawnAsTheFrameScaled() {
    cv::Mat3b bgr(720, 1280);
    for (int y = 0; y < bgr.rows; ++y)
      for (int x = 0; x < bgr.cols; ++x)
        bgr(y, x) = cv::Vec3b(static_cast<uchar>(x * 255 / 1279), static_cast<uchar>(y * 255 / 719),
                              ((x / 16 + y / 16) % 2) ? 200 : 60);
    ui::FrameView view;
    view.resize(700, 460);
    view.setFrame(ui::frameToQImage(bgr));
    view.fitToWindow();
    const QImage first = view.grab().toImage();  // its first repaint: through the transform
    QTest::qWait(400);                              // stayed 250 ms: kept scaled
    const QImage kept = view.grab().toImage();
    const QPointF a = view.toWidget(QPointF(0, 0)), b = view.toWidget(QPointF(1280, 720));
    const QRect target = QRectF(a, b).toAlignedRect();
    QVERIFY(target.width() > 300 && target.width() < 1280);  // scaled down
    cv::Mat3b reference;
    cv::resize(bgr, reference, cv::Size(target.width(), target.height()), 0, 0, cv::INTER_AREA);
    auto meanDifference = [&](const QImage& drawn) {
      const QImage rgb = drawn.convertToFormat(QImage::Format_RGB888);
      double sum = 0;
      long n = 0;
      for (int y = 2; y + 2 < target.height(); ++y)  // (the rectangle's edge pixels are partly the background)
        for (int x = 2; x + 2 < target.width(); ++x) {
          const int wx = target.x() + x, wy = target.y() + y;
          if (wx < 0 || wy < 0 || wx >= rgb.width() || wy >= rgb.height()) continue;
          const uchar* p = rgb.constScanLine(wy) + 3 * wx;
          const cv::Vec3b r = reference(y, x);
          sum += std::abs(p[0] - r[2]) + std::abs(p[1] - r[1]) + std::abs(p[2] - r[0]);
          n += 3;
        }
      return n > 0 ? sum / static_cast<double>(n) : 1e9;
    };
    const double drawnFirst = meanDifference(first), drawnKept = meanDifference(kept);
    qInfo("the frame drawn in %d x %d px: %.2f levels from the reference as first drawn, %.2f once kept scaled",
          target.width(), target.height(), drawnFirst, drawnKept);
    QVERIFY(drawnFirst < 4.0);
    QVERIFY(drawnKept < 4.0);
  }

  // A frame given with its copy already scaled to the view (the composited view's worker makes one for each frame it
  // composes, issue 64) is drawn from that copy as it is: the same pixels as the frame the view kept scaled itself
  // (checked against OpenCV above). A copy of another size is not used.
  void aFrameScaledOffTheGuiThreadIsDrawnAsGiven() {
    cv::Mat3b bgr(720, 1280);
    for (int y = 0; y < bgr.rows; ++y)
      for (int x = 0; x < bgr.cols; ++x)
        bgr(y, x) = cv::Vec3b(static_cast<uchar>(x * 255 / 1279), static_cast<uchar>(255 - y * 255 / 719),
                              ((x / 20 + y / 12) % 2) ? 220 : 30);
    ui::FrameView view;
    view.resize(700, 460);
    view.setFrame(ui::frameToQImage(bgr));
    view.fitToWindow();
    view.grab();        // drawn through the transform
    QTest::qWait(400);  // stayed 250 ms since: the view scaled it itself
    const quint64 before = view.paintsFromScaled();
    const QImage kept = view.grab().toImage();
    QCOMPARE(view.paintsFromScaled(), before + 1);
    const QPointF a = view.toWidget(QPointF(0, 0)), b = view.toWidget(QPointF(1280, 720));
    const QSize size = view.frameSizeInView();
    QCOMPARE(size, QRectF(a, b).size().toSize());
    QVERIFY(size.width() > 300 && size.width() < 1280);
    const QImage next = ui::frameToQImage(bgr);  // another image (another cache key), the same pixels
    view.setFrame(next, next.scaled(size, Qt::IgnoreAspectRatio, Qt::SmoothTransformation));
    const QImage given = view.grab().toImage();
    QCOMPARE(view.paintsFromScaled(), before + 2);
    QCOMPARE(given, kept);
    // A copy of another size (the view was resized since it was asked): drawn through the transform, within the
    // levels the first test allows of the scaled drawing.
    const QImage third = ui::frameToQImage(bgr);
    view.setFrame(third, third.scaled(size - QSize(40, 22), Qt::IgnoreAspectRatio, Qt::SmoothTransformation));
    const QImage transformed = view.grab().toImage();
    QCOMPARE(view.paintsFromScaled(), before + 2);
    QCOMPARE(transformed.size(), kept.size());
    double sum = 0;
    long n = 0;
    const QRect inner = QRectF(a, b).toAlignedRect().adjusted(2, 2, -2, -2);
    for (int y = inner.top(); y <= inner.bottom(); ++y)
      for (int x = inner.left(); x <= inner.right(); ++x) {
        const QRgb p = transformed.pixel(x, y), q = kept.pixel(x, y);
        sum += std::abs(qRed(p) - qRed(q)) + std::abs(qGreen(p) - qGreen(q)) + std::abs(qBlue(p) - qBlue(q));
        n += 3;
      }
    qInfo("drawn through the transform: %.2f levels from the scaled copy", sum / static_cast<double>(n));
    QVERIFY(sum / static_cast<double>(n) < 4.0);
    QVERIFY(transformed != kept);  // (the wrong-sized copy was not drawn: it would be placed at another size)
  }

  // A text that changes many times a second in a SteadyBox is repainted, not laid out (issue 64): the window above it
  // hears of it only when the text needs another line, or (one that does not wrap) more width than it has. Qt's own
  // label beside it is the reference: each of its new texts is a layout pass of the window.
  void aChangingTextLaysTheWindowOutOnlyWhenItNeedsMoreRoom() {
    QWidget window;
    auto* column = new QVBoxLayout(&window);
    auto* wrapped = new QLabel;
    wrapped->setWordWrap(true);
    column->addWidget(new ui::SteadyBox(wrapped, &window));
    auto* bare = new QLabel;  // the reference
    column->addWidget(bare);
    auto* row = new QHBoxLayout;
    auto* single = new QLabel(QStringLiteral("u 1.0  v 1.0 px"));
    auto* singleBox = new ui::SteadyBox(single, &window);
    row->addWidget(singleBox);
    row->addStretch(1);
    column->addLayout(row);
    auto* lines = new ui::LinesLabel(3, &window);
    column->addWidget(new ui::SteadyBox(lines, &window));
    column->addStretch(1);  // (each gets the height it asks for)
    window.resize(400, 300);
    wrapped->setText(QStringLiteral("Tool force 0.00 N"));
    window.show();
    QVERIFY(QTest::qWaitForWindowExposed(&window));
    QCoreApplication::processEvents();
    LayoutRequests layouts(&window);
    const int wrappedHeight = wrapped->height(), linesHeight = lines->height();
    auto settle = [] { QCoreApplication::processEvents(); };
    // The window's own layout pass for the reference's new texts, one per text.
    for (int i = 0; i < 20; ++i) {
      bare->setText(QStringLiteral("Tool force %1 N").arg(0.37 * i, 0, 'f', 2));
      settle();
    }
    const int byTheReference = layouts.count();
    // The same texts, and a long sentence over three lines, in the boxes: none.
    for (int i = 0; i < 20; ++i) {
      wrapped->setText(QStringLiteral("Tool force %1 N").arg(0.37 * i, 0, 'f', 2));
      single->setText(QStringLiteral("u %1  v %2 px").arg(1.0 + i * 0.1, 0, 'f', 1).arg(9.9 - i * 0.1, 0, 'f', 1));
      lines->setText(QString(QStringLiteral("A long sentence of the session, over its lines and more: %1. ")).arg(i).repeated(1 + i % 6));
      settle();
    }
    const int byTheBoxes = layouts.count() - byTheReference;
    QCOMPARE(wrapped->height(), wrappedHeight);
    QCOMPARE(lines->height(), linesHeight);  // a longer text ends in an ellipsis; the widgets below stay put
    QVERIFY(lines->text().endsWith(QStringLiteral(". ")));  // (the text itself whole)
    // Another line, and a longer single line: laid out, and each then has the room its text needs.
    wrapped->setText(QStringLiteral("Tool force 1.23 N (jaws 1.20 N, shaft 0.03 N) — step not converged (relative "
                                    "residual 0.0012): not the equilibrium force   slips: 1   cuts: 2"));
    single->setText(QStringLiteral("u 1234.5  v 6789.0 px, and a longer word"));
    settle();
    settle();
    const int forMoreRoom = layouts.count() - byTheReference - byTheBoxes;
    qInfo("layout passes: %d for Qt's label's 20 texts, %d for 20 texts in boxes, %d when they needed more room",
          byTheReference, byTheBoxes, forMoreRoom);
    QVERIFY(byTheReference >= 15);  // (the reference: Qt lays the window out at each new text)
    QCOMPARE(byTheBoxes, 0);
    QVERIFY(forMoreRoom >= 1);
    QCOMPARE(wrapped->height(), wrapped->heightForWidth(wrapped->width()));
    QVERIFY(wrapped->height() > wrappedHeight);
    QVERIFY(single->width() >= single->fontMetrics().horizontalAdvance(single->text()));
    // A shorter single line keeps the width it had (nothing beside it jitters), without a layout pass.
    const int singleWidth = single->width(), before = layouts.count();
    single->setText(QStringLiteral("u 1.0  v 2.0 px"));
    settle();
    QCOMPARE(layouts.count(), before);
    QCOMPARE(single->width(), singleWidth);
  }

  void initTestCase() {
    // A second run of this program beside it (test_gui_hidpi) names its own instance: each keeps its own location.
    QCoreApplication::setOrganizationName("RehearseTest" + qEnvironmentVariable("REHEARSE_TEST_INSTANCE"));
    QStandardPaths::setTestModeEnabled(true);  // settings and autosave go to a test location
    forgetEarlierRuns();
  }

  // Save through the window, reopen in a new window, compare; autosave exists while open and is
  // removed by a clean close (its presence at start means a crash).
  void saveReopenAndAutosave() {
    const QString path = QString::fromStdString(tempPath("gui-saved.rehearse"));
    std::size_t tets = 0;
    {
      ui::MainWindow w;
      w.show();
      QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
      w.openCase({});
      QVERIFY(loaded.wait(60000));
      tets = w.caseData()->organ->volume.tets.size();
      QSignalSpy saved(&w, &ui::MainWindow::caseSaved);
      w.saveCaseAs(path);
      QVERIFY(w.isSaving() || saved.count() == 1);  // the save runs off the GUI thread
      QVERIFY(saved.count() == 1 || saved.wait(60000));
      QCOMPARE(saved.first().at(0).toBool(), true);
      QCOMPARE(w.currentPath(), path);
      QVERIFY(w.recentFiles().contains(path));
      QVERIFY(w.windowTitle().contains("gui-saved.rehearse"));
      w.autosaveNow();
      QVERIFY(ui::MainWindow::hasRecoverableAutosave());
      w.close();
      QVERIFY(!ui::MainWindow::hasRecoverableAutosave());
    }
    ui::MainWindow w2;
    w2.show();
    QSignalSpy loaded2(&w2, &ui::MainWindow::caseLoaded);
    w2.openCase(path);
    QVERIFY(loaded2.wait(60000));
    QCOMPARE(loaded2.first().at(0).toBool(), true);
    QCOMPARE(w2.caseData()->organ->volume.tets.size(), tets);
    QCOMPARE(w2.currentPath(), path);
    QCOMPARE(w2.document()->frameImage().size(), QSize(1280, 720));
    // Saving where it cannot be written keeps the case and says so.
    QSignalSpy saved2(&w2, &ui::MainWindow::caseSaved);
    w2.saveCaseAs("/proc/no-such-dir/x.rehearse");
    QVERIFY(saved2.count() == 1 || saved2.wait(60000));
    QCOMPARE(saved2.first().at(0).toBool(), false);
    QVERIFY(saved2.first().at(1).toString().startsWith("Cannot write"));
    QCOMPARE(w2.currentPath(), path);
  }

  void builtInCaseShowsFrameAndOrgan() {
    ui::MainWindow w;
    w.resize(1400, 800);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
    w.openCase({});
    QVERIFY(w.isLoading());  // the work runs off the GUI thread
    QVERIFY(loaded.wait(60000));
    QCOMPARE(loaded.takeFirst().at(0).toBool(), true);
    QCOMPARE(w.document()->frameImage().size(), QSize(1280, 720));
    QVERIFY(!w.organOverlay().isNull());
    QVERIFY(!w.silhouette().isEmpty());
    QVERIFY(w.infoText().contains("tetrahedra:"));
    QVERIFY(w.windowTitle().contains("phantom"));

    // The organ is drawn over the frame: the view's centre differs with and without the overlay.
    auto* view = w.frameView();
    const QImage withOrgan = view->grab().toImage();
    QTest::keyClick(&w, Qt::Key_O);
    QVERIFY(!view->overlayVisible());
    const QImage without = view->grab().toImage();
    const QPoint centre = view->rect().center();
    const QPoint centrePx = centre * view->devicePixelRatioF();  // grabs are in device pixels
    QVERIFY(withOrgan.pixel(centrePx) != without.pixel(centrePx));
    QTest::keyClick(&w, Qt::Key_O);
    QVERIFY(view->overlayVisible());

    // The legend names the colours drawn: its swatch for the organ outline is the colour the outline is
    // drawn in (found on the frame, outside the legend), and it lists each contour type present.
    const auto legend = view->legend();
    QVERIFY(!legend.isEmpty());
    QCOMPARE(legend.first().colour, ui::palette::organOutline());
    const QRect box = view->legendRect();
    QVERIFY(!box.isEmpty());
    const QImage shown = view->grab().toImage();
    const double dpr = view->devicePixelRatioF();
    const QFontMetrics fm(view->font());
    const QPoint swatch(box.left() + 16, box.top() + 5 + (fm.height() + 4) / 2);
    QCOMPARE(QColor(shown.pixel(swatch * dpr)), ui::palette::organOutline());
    int outlinePixels = 0;
    for (int y = 0; y < shown.height(); ++y)
      for (int x = 0; x < shown.width(); ++x)
        if (!box.contains(QPoint(x, y) / dpr) && QColor(shown.pixel(x, y)) == ui::palette::organOutline()) ++outlinePixels;
    QVERIFY2(outlinePixels > 50, qPrintable(QString::number(outlinePixels)));
    bool silhouetteListed = false;
    for (const auto& e : legend) silhouetteListed |= e.text.contains("silhouette");
    QCOMPARE(silhouetteListed, !w.caseData()->contour.segments.empty());

    // The organ alone, rendered in device pixels (test_gui_hidpi runs this at QT_SCALE_FACTOR=2).
    if (auto* organ = qobject_cast<ui::OrganView*>(w.organWidget())) {
      organ->grab();
      const double dpr = organ->devicePixelRatioF();
      qInfo("organ view: %d x %d widget, %d x %d rendered (device pixel ratio %.1f)", organ->width(), organ->height(),
            organ->rendered().width(), organ->rendered().height(), dpr);
      QCOMPARE(organ->rendered().size(), QSize(static_cast<int>(std::lround(organ->width() * dpr)),
                                               static_cast<int>(std::lround(organ->height() * dpr))));
      QCOMPARE(organ->rendered().devicePixelRatio(), dpr);
    }

    // Zoom about the cursor with the wheel, Home fits again.
    const QPointF before = view->toFrame(centre);
    QWheelEvent wheel(QPointF(centre), view->mapToGlobal(QPointF(centre)), QPoint(), QPoint(0, 480), Qt::NoButton, Qt::NoModifier,
                      Qt::NoScrollPhase, false);
    QApplication::sendEvent(view, &wheel);
    QVERIFY(view->zoom() > 1.5);
    QVERIFY((view->toFrame(centre) - before).manhattanLength() < 1.0);
    view->setFocus();
    QTest::keyClick(view, Qt::Key_Home);
    QCOMPARE(view->zoom(), 1.0);

    // The status bar reads out the frame's pixel under the pointer, and nothing once the pointer has left the frame.
    auto* cursor = w.findChild<QLabel*>("statusCursor");
    QVERIFY(cursor);
    const QPoint at = centre + QPoint(7, 5);
    QMouseEvent move(QEvent::MouseMove, QPointF(at), view->mapToGlobal(QPointF(at)), Qt::NoButton, Qt::NoButton,
                     Qt::NoModifier);
    QApplication::sendEvent(view, &move);
    const QPointF pixel = view->toFrame(at);
    QVERIFY2(cursor->text().startsWith(QStringLiteral("u %1").arg(pixel.x(), 0, 'f', 1)), qPrintable(cursor->text()));
    QEvent leave(QEvent::Leave);
    QApplication::sendEvent(view, &leave);
    QVERIFY2(cursor->text().isEmpty(), qPrintable(cursor->text()));
  }

  // F9 (Fit to Contour) from another step's page, as F10 from any step: the fit's page shows, and what the fit does or
  // needs is said. A person's check found F9 on step 4's page did nothing (the key was its button's, on a hidden page).
  void f9FromAnotherStepOpensTheFit() {
    ui::MainWindow w;
    QVERIFY(openBuiltInCase(w));
    QTest::keyClick(&w, Qt::Key_4, Qt::AltModifier);
    QCOMPARE(w.step(), ui::Step::Rigid);
    QTest::keyClick(&w, Qt::Key_F9);
    QCOMPARE(w.step(), ui::Step::Elastic);
    // The built-in phantom has no contour yet: said where the person looks, not only on the page.
    QVERIFY2(w.statusText().startsWith("The fit needs") && w.statusText().contains("contour"), qPrintable(w.statusText()));
    QVERIFY(closeDiscardingChanges(w));
  }

  // Messages are read whole: a long error is shortened in the status bar, never pushes the widgets beside
  // it out, and is whole in the label's tooltip and in the Messages panel (Ctrl+L). The Case panel wraps
  // its lines instead of clipping them.
  void messagesAreReadWhole() {
    ui::MainWindow w;
    w.resize(1000, 700);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
    w.openCase({});
    QVERIFY(loaded.wait(60000));
    const std::string empty = tempPath("empty-contour-with-a-rather-long-name-as-people-give-them-exported-from-the-theatre-camera-on-2026-11-24-at-06-30.json");
    writeFile(empty, "");
    w.contourPage()->importContour(QString::fromStdString(empty));
    const QString sentence = w.statusText();
    QVERIFY2(sentence.contains("empty-contour-with") && sentence.endsWith("."), qPrintable(sentence));
    auto* status = w.findChild<QLabel*>("caseStatus");
    QCOMPARE(status->toolTip(), sentence);
    // The test shows a sentence longer than the whole window (the label's own width depends on what else the
    // status bar shows at that moment), so it must be shortened there.
    QVERIFY2(status->fontMetrics().horizontalAdvance(sentence) > w.width(),
             qPrintable(QStringLiteral("sentence %1 px, label %2 px, window %3 px: %4")
                            .arg(status->fontMetrics().horizontalAdvance(sentence))
                            .arg(status->width())
                            .arg(w.width())
                            .arg(sentence)));
    QVERIFY(w.statusBar()->minimumSizeHint().width() <= w.width());
    QVERIFY2(!w.messageLog().isEmpty() && w.messageLog().last().endsWith(sentence), qPrintable(w.messageLog().join("\n")));
    auto* dock = w.findChild<QDockWidget*>("messagesDock");
    QVERIFY(dock);
    QTest::keyClick(&w, Qt::Key_L, Qt::ControlModifier);
    QTRY_VERIFY(dock->isVisible() && !dock->visibleRegion().isEmpty());
    QVERIFY(w.findChild<QPlainTextEdit*>("messageLog")->toPlainText().contains(sentence));
    auto* info = w.findChild<QPlainTextEdit*>("caseInfo");
    info->parentWidget()->show();
    info->parentWidget()->raise();
    QTRY_VERIFY(info->isVisible());
    QCOMPARE(info->horizontalScrollBar()->maximum(), 0);
  }

  void damagedCaseFolderOpensWithMessage() {
    const std::string dir = tempPath("gui-case");
    auto c = phantom::makePhantom();
    app::writeCaseDirectory(app::caseFromPhantom(c), dir);
    QFile::remove(QString::fromStdString(dir + "/frame.png"));
    ui::MainWindow w;
    w.show();
    QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
    w.openCase(QString::fromStdString(dir));
    QVERIFY(loaded.wait(60000));
    QCOMPARE(loaded.takeFirst().at(0).toBool(), true);
    QVERIFY(w.infoText().contains("Frame not loaded"));
    QVERIFY(w.infoText().contains("tetrahedra:"));
    // A folder that is not a case: the current case stays.
    w.openCase(QString::fromStdString(tempPath("not-a-case")));
    QVERIFY(loaded.wait(60000));
    QCOMPARE(loaded.takeFirst().at(0).toBool(), false);
    QVERIFY(w.infoText().contains("Frame not loaded"));
    // A case file that is not there (a stale recent file): said so, and the current case stays.
    w.openCase(QString::fromStdString(tempPath("gone.rehearse")));
    QVERIFY(loaded.wait(60000));
    QCOMPARE(loaded.takeFirst().at(0).toBool(), false);
    auto* status = w.findChild<QLabel*>("caseStatus");
    QVERIFY(status);
    QVERIFY2(status->text().endsWith("gone.rehearse does not exist."), qPrintable(status->text()));
    QVERIFY(w.infoText().contains("Frame not loaded"));
  }

  // A job whose worker is done but whose result is not applied yet (its finished signal still queued behind other
  // events) is still the running job: the next one asked for is refused, said in a sentence, and the first one's
  // result is applied, never dropped. (A job started in that moment used to replace the watcher's future, and the
  // finished signal and the result went with it.)
  void aFinishedJobsResultIsAppliedBeforeTheNext() {
    ui::JobRunner jobs;
    QSignalSpy refused(&jobs, &ui::JobRunner::refused);
    int applied = 0;
    const auto job = [&](int n) {
      return [&applied, n](const std::atomic<bool>&, const ui::JobRunner::Progress&) {
        return std::function<void()>([&applied, n] { applied = n; });
      };
    };
    QVERIFY(jobs.run("first", job(1)));
    QThread::msleep(500);  // the worker is done (nothing to do); its finished signal waits in the event queue
    QVERIFY(jobs.isRunning());
    QVERIFY(!jobs.run("second", job(2)));
    QCOMPARE(refused.count(), 1);
    QVERIFY(refused.front().front().toString().contains("Another job is running"));
    QTRY_COMPARE(applied, 1);
    QVERIFY(!jobs.isRunning());
    QVERIFY(jobs.run("second", job(2)));
    QTRY_COMPARE(applied, 2);
    QVERIFY(!jobs.isRunning());
  }

  // Choices kept between runs: the organ's drawing style (V) and the attachment patch radius come back in
  // a new window. (Settings of their own: test_gui_hidpi may run beside this test.)
  void settingsKeptBetweenRuns() {
    const QString organisation = QCoreApplication::organizationName();
    QCoreApplication::setOrganizationName("RehearseSettingsTest");
    QSettings().clear();
    {
      ui::MainWindow w;
      w.show();
      QVERIFY(QTest::qWaitForWindowExposed(&w));
      const auto first = w.frameView()->overlayStyle();
      QTest::keyClick(&w, Qt::Key_V);
      QVERIFY(w.frameView()->overlayStyle() != first);
      QTest::keyClick(&w, Qt::Key_V);
      QCOMPARE(w.frameView()->overlayStyle(), ui::OverlayStyle::Silhouette);
      w.findChild<QDoubleSpinBox*>("attachmentRadius")->setValue(17);
    }
    {
      ui::MainWindow w;
      QCOMPARE(w.frameView()->overlayStyle(), ui::OverlayStyle::Silhouette);
      QCOMPARE(w.frameView()->attachmentRadius(), 0.017);
      QCOMPARE(w.findChild<QDoubleSpinBox*>("attachmentRadius")->value(), 17.0);
      w.show();
      QVERIFY(QTest::qWaitForWindowExposed(&w));
      QTest::keyClick(&w, Qt::Key_V);
      QCOMPARE(w.frameView()->overlayStyle(), ui::OverlayStyle::Shaded);
    }
    QSettings().clear();
    QCoreApplication::setOrganizationName(organisation);
  }

  // The file dialogs open in the folder a file was last taken from (any dialog's), else in the user's home: not in the
  // working directory the program was started from (a person's check), nor in a folder since removed. Ctrl+O, as a
  // person opens a case.
  void fileDialogsOpenInTheLastFolderOrHome() {
    const QString organisation = QCoreApplication::organizationName();
    QCoreApplication::setOrganizationName("RehearseDialogFolderTest");
    QSettings().clear();
    QTemporaryDir last;
    QVERIFY(QDir::currentPath() != QDir::homePath());  // (else this test could not tell them apart)
    {
      ui::MainWindow w;
      w.show();
      QVERIFY(QTest::qWaitForWindowExposed(&w));
      auto folderShown = [&] {
        QString seen;
        QTimer poll;
        poll.setInterval(50);
        connect(&poll, &QTimer::timeout, this, [&] {
          for (QWidget* top : QApplication::topLevelWidgets())
            if (auto* d = qobject_cast<QFileDialog*>(top); d && d->isVisible()) {
              seen = d->directory().absolutePath();
              d->reject();
            }
        });
        poll.start();
        w.activateWindow();  // (no window manager gives it back after a dialog)
        if (!QTest::qWaitForWindowActive(&w)) return QStringLiteral("(the window could not be made active)");
        QTest::keyClick(&w, Qt::Key_O, Qt::ControlModifier);
        return seen;
      };
      QCOMPARE(folderShown(), QDir::homePath());
      ui::rememberDialogFolder(last.path() + "/case.rehearse");
      QCOMPARE(folderShown(), QDir(last.path()).absolutePath());
      QSettings().setValue("lastDir", last.path() + "/gone");
      QCOMPARE(folderShown(), QDir::homePath());
    }
    QSettings().clear();
    QCoreApplication::setOrganizationName(organisation);
  }

  // Closing the window while an autosave is being written waits for it, then removes the autosave: no file
  // and no half-written temporary is left (five times); an autosave with nothing changed writes nothing.
  void closeDuringAutosave() {
    const QDir folder(QFileInfo(ui::MainWindow::autosavePath()).absolutePath());
    for (int i = 0; i < 5; ++i) {
      ui::MainWindow w;
      w.show();
      QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
      w.openCase({});
      QVERIFY(loaded.wait(60000));
      QVERIFY(!w.document()->autosaveIfChanged());  // just loaded: nothing to write
      w.editCase("test: move", [i](app::Case& k) { k.pose.t.x() += 1e-3 * (i + 1); });
      QVERIFY(w.document()->autosaveIfChanged());   // started on a worker ...
      QVERIFY(closeDiscardingChanges(w));           // ... and the window closes at once
      QVERIFY(!ui::MainWindow::hasRecoverableAutosave());
      QVERIFY2(folder.entryList({"*.saving-*"}, QDir::Files | QDir::Hidden).isEmpty(), "a temporary autosave was left behind");
    }
  }

  // The work a crash left is offered back at the next start; a person who clicks beside the question and presses
  // Ctrl+Q has not answered it: the question keeps the window (window-modal: the click and the key reach nothing
  // behind it), and a close that happens anyway keeps the autosave for the launch after, which offers it again. Before,
  // the question was not modal: the click went to the window, Ctrl+Q quit cleanly, and the clean exit removed the
  // autosave (the work lost). No discards it.
  void anUnansweredRecoveryKeepsTheWork() {
    const QString autosave = ui::MainWindow::autosavePath();
    const QString kept = QString::fromStdString(tempPath("gui-crash-left.rehearse"));
    double moved = 0;
    {
      ui::MainWindow w;
      w.show();
      QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
      w.openCase({});
      QVERIFY(loaded.wait(60000));
      w.editCase("test: move", [](app::Case& k) { k.pose.t.x() += 7e-3; });
      moved = w.caseData()->pose.t.x();
      w.autosaveNow();
      QFile::remove(kept);
      QVERIFY(QFile::copy(autosave, kept));  // what a crash would leave: the autosave, not removed
      QVERIFY(closeDiscardingChanges(w));
      QVERIFY(!ui::MainWindow::hasRecoverableAutosave());
      QVERIFY(QFile::copy(kept, autosave));
    }
    {
      ui::MainWindow w;
      QMessageBox* box = launch(w);
      QVERIFY(box);
      const Qt::WindowModality modality = box->windowModality();  // (the box is gone once the window closes)
      QTest::mouseClick(w.centralWidget(), Qt::LeftButton, Qt::NoModifier, QPoint(40, 40));  // beside the question
      // Ctrl+Q (File > Quit closes the window; the offscreen platform binds no key to it): however the window closes
      // with the question unanswered, the work stays for the next launch.
      w.close();
      QVERIFY2(ui::MainWindow::hasRecoverableAutosave(), "the work a crash left was removed before it was answered");
      QCOMPARE(modality, Qt::WindowModal);  // (and under X the click and the key reach nothing behind it)
    }
    {
      // The question's own window closed (no button: a person without a window manager's title bar did so), then the
      // window: the work stays too (it was removed at that clean exit before).
      ui::MainWindow w;
      QMessageBox* box = launch(w);
      QVERIFY2(box, "the second launch did not offer the work again");
      box->close();
      QVERIFY(waitFor([&] { return !w.findChild<QMessageBox*>("recoverCaseBox"); }));
      w.close();
      QVERIFY2(ui::MainWindow::hasRecoverableAutosave(), "the work a crash left was removed: its question was closed");
    }
    {
      ui::MainWindow w;
      QMessageBox* box = launch(w);
      QVERIFY2(box, "the next launch did not offer the work again");
      // Closed unanswered again, then File > Recover Autosaved Case: the work is back, and a Discard at the end
      // leaves no autosave to offer (the menu answered the question).
      box->close();
      QVERIFY(waitFor([&] { return !w.findChild<QMessageBox*>("recoverCaseBox"); }));
      QAction* recover = nullptr;
      for (auto* a : w.findChildren<QAction*>())
        if (a->text().remove('&') == QLatin1String("Recover Autosaved Case")) recover = a;
      QVERIFY(recover);
      recover->trigger();
      QVERIFY(waitFor([&] { return w.isWindowModified(); }, 60000));  // recovered: unsaved changes of the phantom
      QCOMPARE(w.caseData()->pose.t.x(), moved);  // the work the crash left
      QVERIFY(closeDiscardingChanges(w));
      QVERIFY(!ui::MainWindow::hasRecoverableAutosave());
    }
    QVERIFY(QFile::copy(kept, autosave));  // the crash again: this time Yes
    {
      ui::MainWindow w;
      QMessageBox* box = launch(w);
      QVERIFY2(box, "the launch after a crash did not offer its work");
      QTest::mouseClick(box->button(QMessageBox::Yes), Qt::LeftButton);
      QVERIFY(waitFor([&] { return w.isWindowModified(); }, 60000));
      QCOMPARE(w.caseData()->pose.t.x(), moved);
      QVERIFY(closeDiscardingChanges(w));
      QVERIFY(!ui::MainWindow::hasRecoverableAutosave());
    }
    QFile::remove(kept);
  }

  // The work a crash left outlives the next run's autosaves: the question closed unanswered, the next run works on (its
  // own autosave written), then quits; the launch after offers the crash's work, not the next run's. Before, the two
  // were one file: the next run's autosave overwrote the crash's (its work lost), and that was offered back instead.
  // A crash during that run too: both are kept, the older one under its time.
  void aCrashsWorkOutlivesTheNextRunsAutosave() {
    const QString autosave = ui::MainWindow::autosavePath();
    double crashed = 0;
    {
      ui::MainWindow w;
      w.show();
      QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
      w.openCase({});
      QVERIFY(loaded.wait(60000));
      w.editCase("test: move", [](app::Case& k) { k.pose.t.x() += 11e-3; });
      crashed = w.caseData()->pose.t.x();
      w.autosaveNow();
      const QString kept = autosave + ".test-copy";
      QFile::remove(kept);
      QVERIFY(QFile::copy(autosave, kept));
      QVERIFY(closeDiscardingChanges(w));
      QFile::remove(autosave);
      QVERIFY(QFile::rename(kept, autosave));  // what a crash leaves: the autosave, not removed
    }
    double worked = 0;
    {
      ui::MainWindow w;
      QMessageBox* box = launch(w);
      QVERIFY(box);
      box->close();  // unanswered
      QVERIFY(waitFor([&] { return !w.findChild<QMessageBox*>("recoverCaseBox"); }));
      w.editCase("test: other work", [](app::Case& k) { k.pose.t.y() += 5e-3; });
      worked = w.caseData()->pose.t.y();
      w.autosaveNow();  // this run's own autosave (the timer's, a minute on)
      // ... and this run crashes too: its autosave stays beside the first crash's.
      const QString kept = autosave + ".test-copy";
      QFile::remove(kept);
      QVERIFY(QFile::copy(autosave, kept));
      QVERIFY(closeDiscardingChanges(w));
      QVERIFY2(ui::MainWindow::hasRecoverableAutosave(), "the crash's work was removed");
      QFile::remove(autosave);  // (this run's own autosave: what its crash leaves instead is the copy)
      QVERIFY(QFile::rename(kept, autosave));
    }
    {
      ui::MainWindow w;
      QMessageBox* box = launch(w);
      QVERIFY2(box, "the next launch did not offer the work back");
      qInfo("%s", qPrintable(box->text()));
      QVERIFY2(box->text().contains("earlier crash"), qPrintable(box->text()));
      QTest::mouseClick(box->button(QMessageBox::Yes), Qt::LeftButton);
      QVERIFY(waitFor([&] { return w.isWindowModified(); }, 60000));
      QCOMPARE(w.caseData()->pose.t.y(), worked);  // the newest crash's work
      // The earlier crash's work is kept under its time, whole.
      const QDir folder(QFileInfo(autosave).absolutePath());
      const QStringList earlier = folder.entryList({QFileInfo(autosave).completeBaseName() + ".crashed-*.rehearse"});
      QCOMPARE(earlier.size(), 1);
      const auto back = ui::loadCaseFile(folder.filePath(earlier.front()));
      QCOMPARE(back.pose.t.x(), crashed);
      QVERIFY(QFile::remove(folder.filePath(earlier.front())));
      QVERIFY(closeDiscardingChanges(w));
      QVERIFY(!ui::MainWindow::hasRecoverableAutosave());
    }
  }

  // A second program launched on the same machine while the first runs (its autosave's slot held by a lock file, with
  // work autosaved in it): the second offers nothing back (the first did not crash), autosaves into a slot of its own,
  // and its clean exit leaves the first's autosave as it was. Before, one file served both: the second launch offered
  // the running program's work back as a crash's, wrote over it, and removed it at its exit.
  void aSecondLaunchKeepsToItsOwnAutosave() {
    const QString organisation = QCoreApplication::organizationName();
    QCoreApplication::setOrganizationName(organisation + "SecondLaunch");
    const auto restore = qScopeGuard([&] { QCoreApplication::setOrganizationName(organisation); });
    const QDir folder(QStandardPaths::writableLocation(QStandardPaths::AppDataLocation));
    QVERIFY(QDir().mkpath(folder.path()));
    for (const QString& f : folder.entryList(QDir::Files | QDir::Hidden)) QFile::remove(folder.filePath(f));
    // The first program: its lock, and its work autosaved.
    QLockFile first(folder.filePath("autosave.lock"));
    first.setStaleLockTime(0);
    QVERIFY(first.tryLock(0));
    app::Case work = app::caseFromPhantom(phantom::makePhantom());
    work.pose.t.x() += 13e-3;
    ui::saveCaseFile(work, folder.filePath("autosave.rehearse"));
    const QDateTime written = QFileInfo(folder.filePath("autosave.rehearse")).lastModified();
    {
      ui::MainWindow w;  // the second program
      w.show();
      QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
      w.openCase({});
      QVERIFY(loaded.wait(60000));
      qInfo("the second program's autosave: %s", qPrintable(ui::MainWindow::autosavePath()));
      QVERIFY2(!ui::MainWindow::hasRecoverableAutosave(), "the running program's work was taken for a crash's");
      w.offerRecovery();
      QTest::qWait(200);
      QVERIFY(!w.findChild<QMessageBox*>("recoverCaseBox"));
      QVERIFY(ui::MainWindow::autosavePath() != folder.filePath("autosave.rehearse"));
      w.editCase("test: move", [](app::Case& k) { k.pose.t.y() += 3e-3; });
      w.autosaveNow();
      QVERIFY(QFile::exists(ui::MainWindow::autosavePath()));
      QVERIFY(closeDiscardingChanges(w));
      QVERIFY(!QFile::exists(ui::MainWindow::autosavePath()));  // its own, removed at its clean exit
    }
    QVERIFY2(QFile::exists(folder.filePath("autosave.rehearse")), "the first program's autosave was removed");
    QCOMPARE(QFileInfo(folder.filePath("autosave.rehearse")).lastModified(), written);
    QCOMPARE(ui::loadCaseFile(folder.filePath("autosave.rehearse")).pose.t.x(), work.pose.t.x());
    first.unlock();
    QFile::remove(folder.filePath("autosave.rehearse"));
  }

  // Cancel (Esc) of a long job: an import whose meshing is cancelled leaves the case exactly as it was, says
  // so, and the window goes on working (a second import of the same file completes).
  void cancelKeepsTheWindowUsable() {
    ui::MainWindow w;
    QVERIFY(openBuiltInCase(w));
    const auto before = w.caseData();
    const int undoIndex = w.undoStack()->index();
    // A sphere surface (20480 triangles) to fill with 20k tetrahedra: seconds of meshing, cancellable.
    simcore::Mesh sphere;
    addIcosphere(sphere, Eigen::Vector3d::Zero(), 0.05, 5, 1);
    const std::string path = tempPath("sphere.obj");
    {
      std::string obj;
      for (const auto& p : sphere.points) obj += "v " + std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
      for (const auto& t : sphere.triangles) obj += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + "\n";
      writeFile(path, obj);
    }
    w.meshPage()->setMeshUnit("m");
    w.meshPage()->setTargetTets(20000);
    QSignalSpy imported(&w, &ui::MainWindow::meshImported);
    w.meshPage()->importMesh(QString::fromStdString(path));
    QTest::keyClick(&w, Qt::Key_Escape);  // the job has just started: its meshing sees the cancel
    QVERIFY(imported.wait(60000));
    QCOMPARE(imported.first().at(0).toBool(), false);
    QCOMPARE(imported.first().at(1).toString(), QStringLiteral("cancelled"));
    QVERIFY(w.caseData() == before);  // the very same version: nothing changed
    QCOMPARE(w.undoStack()->index(), undoIndex);
    // An edit first: the case is modified before the import (a person's check found the title then kept the old name,
    // the title being written only when the case's modified state changed).
    w.editCase("Move (test)", [](app::Case& c) { c.pose.t.x() += 0.002; });
    QVERIFY(w.isWindowModified());
    imported.clear();
    w.meshPage()->importMesh(QString::fromStdString(path));
    QVERIFY(imported.wait(120000));
    QVERIFY2(imported.first().at(0).toBool(), qPrintable(imported.first().at(1).toString()));
    QVERIFY(w.caseData()->organ->volume.tets.size() > 5000);
    // The built-in case, its phantom replaced by the user's organ, is named after it: the title, the question before
    // Ctrl+N throws it away (a person's check found "Built-in liver phantom" asked about the imported liver), and
    // Ctrl+Z gives the phantom and its name back.
    QCOMPARE(before->name, std::string("Built-in liver phantom"));
    QCOMPARE(w.caseData()->name, std::string("sphere"));
    QVERIFY2(w.windowTitle().startsWith(QStringLiteral("sphere")), qPrintable(w.windowTitle()));
    QTest::keyClick(&w, Qt::Key_N, Qt::ControlModifier);
    QMessageBox* box = nullptr;
    QVERIFY(waitFor(
        [&] {
          box = w.findChild<QMessageBox*>("unsavedChangesBox");
          return box && box->isVisible();
        },
        10000));
    QVERIFY2(box->text().contains(QStringLiteral("\u201csphere\u201d")), qPrintable(box->text()));
    QTest::mouseClick(box->button(QMessageBox::Cancel), Qt::LeftButton);
    QVERIFY(waitFor([&] { return !w.findChild<QMessageBox*>("unsavedChangesBox"); }, 10000));
    QCOMPARE(w.caseData()->name, std::string("sphere"));  // cancelled: the case stays
    w.activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(&w));
    QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier);
    QCOMPARE(w.caseData()->name, std::string("Built-in liver phantom"));
    QCOMPARE(w.caseData()->organ->volume.tets.size(), before->organ->volume.tets.size());
  }

  // A segmentation in step 1 (issue 39): a NIfTI label image with a colour table beside it imports through the
  // same job as a mesh (progress, cancel), each label a part named from the table, placed where the image's origin
  // puts it; Ctrl+Z gives the previous organ back; a damaged image says one sentence and changes nothing.
  void importsASegmentation() {
    ui::MainWindow w;
    QVERIFY(openBuiltInCase(w));
    const auto before = w.caseData();
    // A 60 x 50 x 40 mm block of 1 mm x 1 mm x 2 mm voxels: an ellipsoid "liver" (label 1) holding a ball (label 4).
    simcore::LabelImage image;
    image.size = {64, 56, 24};
    image.spacing = Eigen::Vector3d(1e-3, 1e-3, 2e-3);
    image.origin = Eigen::Vector3d(0.010, -0.020, 0.030);
    image.labels.assign(static_cast<std::size_t>(64 * 56 * 24), 0);
    long organVoxels = 0, tumourVoxels = 0;
    for (long k = 0; k < 24; ++k)
      for (long j = 0; j < 56; ++j)
        for (long i = 0; i < 64; ++i) {
          const Eigen::Vector3d p(i - 31.5, j - 27.5, 2.0 * (k - 11.5));  // mm from the block's centre
          auto& l = image.labels[static_cast<std::size_t>(i + 64 * (j + 56 * k))];
          if ((p - Eigen::Vector3d(8, 0, 0)).norm() < 8)
            l = 4, ++tumourVoxels;
          else if (std::pow(p.x() / 30, 2) + std::pow(p.y() / 25, 2) + std::pow(p.z() / 20, 2) < 1)
            l = 1, ++organVoxels;
        }
    image.labels[static_cast<std::size_t>(2 + 64 * (2 + 56 * 2))] = 9;  // one voxel (1 x 1 x 2 mm) far from the organ
    const std::string path = tempPath("segmentation.nii.gz");
    simcore::writeLabelImage(image, path);
    writeFile(tempPath("segmentation.ctbl"), "1 liver 200 100 100 255\n4 tumour 250 250 0 255\n9 clip 0 0 255 255\n");
    w.meshPage()->setTargetTets(6000);
    QSignalSpy imported(&w, &ui::MainWindow::meshImported);
    w.meshPage()->importMesh(QString::fromStdString(path));
    QVERIFY(imported.wait(120000));
    QVERIFY2(imported.first().at(0).toBool(), qPrintable(imported.first().at(1).toString()));
    QCOMPARE(w.caseData()->name, std::string("segmentation"));  // (segmentation.nii.gz into the built-in case)
    const auto& volume = w.caseData()->organ->volume;
    QCOMPARE(volume.labelName(1), std::string("liver"));
    QCOMPARE(volume.labelName(4), std::string("tumour"));
    QCOMPARE(volume.labelKind(4), simcore::StructureKind::Tumour);
    std::map<int, double> meshed;
    Eigen::AlignedBox3d box;
    for (std::size_t t = 0; t < volume.tets.size(); ++t) {
      const auto& e = volume.tets[t];
      meshed[volume.tetLabels[t]] +=
          simcore::tetVolume(volume.points[e[0]], volume.points[e[1]], volume.points[e[2]], volume.points[e[3]]);
    }
    for (const auto& p : volume.points) box.extend(p);
    const double voxel = 2e-9;
    qInfo("segmentation: %zu tets; liver %.2f of %.2f mL, tumour %.2f of %.2f mL", volume.tets.size(), meshed[1] * 1e6,
          organVoxels * voxel * 1e6, meshed[4] * 1e6, tumourVoxels * voxel * 1e6);
    QVERIFY(std::abs(meshed[1] - organVoxels * voxel) < 0.03 * organVoxels * voxel);
    QVERIFY(std::abs(meshed[4] - tumourVoxels * voxel) < 0.10 * tumourVoxels * voxel);
    // The ellipsoid's centre: origin + spacing x (31.5, 27.5, 11.5) voxels.
    const Eigen::Vector3d centre = image.origin + Eigen::Vector3d(31.5e-3, 27.5e-3, 23e-3);
    QVERIFY((box.center() - centre).norm() < 1.5e-3);
    QVERIFY(std::abs(box.sizes().x() - 0.060) < 2.5e-3);
    QVERIFY2(w.statusText().contains(QStringLiteral("2 labelled parts")), qPrintable(w.statusText()));
    // The one-voxel label is too thin for 6000 elements: none of it is in the mesh, and the status says so.
    QCOMPARE(std::count(volume.tetLabels.begin(), volume.tetLabels.end(), 9), 0);
    QVERIFY2(w.statusText().contains(QStringLiteral("label 9 (clip) thinner than the elements, not meshed")),
             qPrintable(w.statusText()));
    // Undo (the key, as a user presses it) gives the built-in organ back.
    QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier);
    QTRY_VERIFY(w.caseData()->organ->volume.tets.size() == before->organ->volume.tets.size());
    // A damaged image: one sentence, the case unchanged.
    const auto kept = w.caseData();
    writeFile(tempPath("damaged.nii.gz"), std::string(3000, 'x'));
    imported.clear();
    w.meshPage()->importMesh(QString::fromStdString(tempPath("damaged.nii.gz")));
    QVERIFY(imported.wait(60000));
    QCOMPARE(imported.first().at(0).toBool(), false);
    const QString why = imported.first().at(1).toString();
    QVERIFY2(why.startsWith(QStringLiteral("Cannot read damaged.nii.gz")) && !why.contains('\n'), qPrintable(why));
    QVERIFY(w.caseData() == kept);
  }

  // The interface in French (issue 39): the translation built into the program (ui/translations/rehearse_fr.ts), as
  // `rehearse --language fr` or a French system installs it; strings it does not translate stay in English.
  void frenchInterface() {
    QCOMPARE(ui::installTranslation("fr"), QStringLiteral("fr"));
    {
      ui::MainWindow w;
      QStringList menus;
      for (QAction* a : w.menuBar()->actions()) menus << a->text();
      qInfo("menus in French: %s", qPrintable(menus.join(" | ")));
      for (const char* m : {"&Fichier", "É&dition", "&Affichage", "Si&mulation", "&Aide"})
        QVERIFY2(menus.contains(QString::fromUtf8(m)), m);
      auto* steps = w.findChild<QListWidget*>("workflowList");
      QVERIFY(steps);
      QVERIFY2(steps->item(0)->text().contains(QString::fromUtf8("Maillage de l'organe")),
               qPrintable(steps->item(0)->text()));
      QVERIFY(steps->item(6)->text().contains(QString::fromUtf8("Répétition")));
    }
    QCOMPARE(ui::installTranslation("en"), QString());
    ui::MainWindow english;
    QCOMPARE(english.menuBar()->actions().front()->text(), QStringLiteral("&File"));
  }

  // Accessible names (issue 39): every control a screen reader reaches on each step's page and in the window has a
  // name (its text, its label's, or one set for it), read through Qt's accessibility interface as a reader would.
  void controlsHaveAccessibleNames() {
    ui::MainWindow w;
    w.resize(1600, 900);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    w.activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(&w));
    QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
    w.openCase({});
    QVERIFY(loaded.wait(60000));
    QStringList unnamed;  // each control once, whichever steps show it
    int checked = 0;
    for (int step = 1; step <= 7; ++step) {
      QTest::keyClick(&w, static_cast<Qt::Key>(Qt::Key_0 + step), Qt::AltModifier);
      QTest::qWait(50);
      for (QWidget* c : w.findChildren<QWidget*>()) {
        if (!c->isVisible()) continue;
        const bool control = qobject_cast<QAbstractButton*>(c) || qobject_cast<QAbstractSpinBox*>(c) ||
                             qobject_cast<QComboBox*>(c) || qobject_cast<QSlider*>(c) ||
                             (qobject_cast<QLineEdit*>(c) && !qobject_cast<QAbstractSpinBox*>(c->parentWidget()) &&
                              !qobject_cast<QComboBox*>(c->parentWidget())) ||
                             qobject_cast<QAbstractItemView*>(c);
        if (!control || c->focusPolicy() == Qt::NoFocus) continue;
        QAccessibleInterface* a = QAccessible::queryAccessibleInterface(c);
        QVERIFY(a);
        ++checked;
        if (a->text(QAccessible::Name).trimmed().isEmpty()) {
          const QString what =
              QStringLiteral("%1 '%2' in %3 (tip: %4)")
                  .arg(QString::fromLatin1(c->metaObject()->className()), c->objectName(),
                       QString::fromLatin1(c->parentWidget()->metaObject()->className()), c->toolTip().left(60));
          if (!unnamed.contains(what)) unnamed << what;
        }
      }
    }
    qInfo("%d controls checked over the seven steps", checked);
    QVERIFY2(unnamed.isEmpty(),
             qPrintable(QStringLiteral("%1 controls without an accessible name:\n").arg(unnamed.size()) +
                        unnamed.join("\n")));
  }
};

QTEST_MAIN(TestGui)
#include "test_gui.moc"
