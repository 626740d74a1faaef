// Step 6 through the real main window (offscreen, software rendering) with QTest key events: Alt+6 and
// F10 estimate the appearance of the built-in phantom (registered at its true pose) on a worker; the
// table holds Theta within the acceptance bounds of the phantom's known one; the frame view turns to the
// composited view, which reproduces the frame inside the organ; Play in the Simulation panel deforms the
// organ in the frame, re-shaded, with what it uncovers filled from I_B; a cut keeps it composited, and a grasp-pull-cut
// (the jaws holding while the scissors cut) shows the cut faces in their interior colour; F2/F3/F4 switch composited,
// overlay and 3D; a moved organ makes the estimate stale (said, composition off) and Undo brings it back;
// Esc cancels; a pose that puts the organ behind the camera is refused in one sentence; the estimate is
// saved in the case file and composited again after reopening.
// With REHEARSE_SCREENSHOT_DIR set, it saves a screenshot of the step there (for the README).
#include "test_support.hpp"
#include "window_support.hpp"

#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/composition.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <rehearse/imaging/appearance_fit.hpp>
#include <rehearse/imaging/render.hpp>

#include <QApplication>
#include <QLabel>
#include <QWheelEvent>
#include <QSignalSpy>
#include <QStackedWidget>
#include <QStandardPaths>
#include <QDoubleSpinBox>
#include <QTableWidget>
#include <QTemporaryDir>
#include <QThread>
#include <QStatusBar>
#include <QUndoStack>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

using namespace rehearse;
using ui::MainWindow;

namespace {
double cell(QTableWidget* t, int r, int c) { return t->item(r, c)->text().section(QLatin1Char(' '), 0, 0).toDouble(); }
}  // namespace

class TestAppearanceGui : public QObject {
  Q_OBJECT
  std::unique_ptr<MainWindow> w_;
  ui::SimulationPanel* panel_ = nullptr;

  // Step 7 over the frame, the simulation from rest and playing: true once its first steps on the organ are in.
  bool rehearseFromRest() {
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    if (!w_->showingComposited()) return false;
    panel_->reset();
    panel_->play();
    const std::size_t nodes = w_->caseData()->organ->volume.points.size();
    return waitFor([&] {
      return panel_->lastFrame() && panel_->lastFrame()->steps > 5 && panel_->lastFrame()->positions.size() == nodes;
    });
  }
  // True once the simulation has taken `n` more steps.
  bool stepsOn(int n) {
    const long now = panel_->lastFrame()->steps;
    const bool on = waitFor([&] { return panel_->lastFrame()->steps >= now + n; });
    if (!on) qWarning("%s", qPrintable(said()));
    return on;
  }
  // What the session and the panel say (for a failure's message: CI once saw the session stop stepping here).
  QString said() const {
    const auto f = panel_->lastFrame();
    return QStringLiteral("step %1, %2 playing; status: %3; step: %4; message: %5")
        .arg(f ? f->steps : -1)
        .arg(panel_->isPlaying() ? "" : "not")
        .arg(panel_->statusText())
        .arg(f ? QString::fromStdString(f->report.status) : QString())
        .arg(f ? f->message : QString());
  }

  // F10 on the window, and the page's answer.
  QList<QVariant> estimateWithF10() {
    QSignalSpy done(w_->appearancePage(), &ui::AppearancePage::estimated);
    QTest::keyClick(w_.get(), Qt::Key_F10);
    if (!done.wait(120000)) return {};
    return done.first();
  }

 private slots:
  void initTestCase() {
    QCoreApplication::setOrganizationName("RehearseAppearanceTest");
    forgetEarlierRuns();
    ui::applyDarkTheme(*qApp);
    MainWindow::setRenderer(MainWindow::Renderer::Software);
    w_ = std::make_unique<MainWindow>();
    w_->resize(1600, 900);
    w_->show();
    QVERIFY(QTest::qWaitForWindowExposed(w_.get()));
    w_->activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(w_.get()));
    QSignalSpy loaded(w_.get(), &MainWindow::caseLoaded);
    w_->openCase({});
    QVERIFY(loaded.wait(60000));
    panel_ = w_->simulationPanel();
    // Registered: the phantom at its true pose (steps 4-5 are tested elsewhere; here the appearance).
    const Pose truth = w_->caseData()->groundTruth->pose;
    w_->editCase("Register (test)", [&truth](app::Case& c) {
      c.pose = truth;
      c.hasPose = c.poseAligned = true;
    });
  }

  void estimateWithTheKeyboard() {
    QVERIFY(!w_->composition()->ready());
    QVERIFY2(w_->composition()->whyNot().contains("no appearance"), qPrintable(w_->composition()->whyNot()));
    QTest::keyClick(w_.get(), Qt::Key_6, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Appearance);
    const QList<QVariant> answer = estimateWithF10();
    QVERIFY(!answer.isEmpty());
    QVERIFY2(answer.at(0).toBool(), qPrintable(answer.at(1).toString()));
    const auto& c = *w_->caseData();
    QVERIFY(c.appearance && c.appearanceCurrent());
    QVERIFY(w_->stepDone(ui::Step::Appearance));
    QVERIFY(w_->infoText().contains("Appearance (estimated)"));
    // The table against the phantom's Theta (issue 14's bounds: light within 5 % of its distance, kd and ks
    // within 5 %, sigma within 10 %), read from the widget as the user reads it.
    auto* table = w_->findChild<QTableWidget*>("appearanceTable");
    QVERIFY(table);
    const auto& t = c.groundTruth->appearance;
    const Eigen::Vector3d light(cell(table, 0, 0), cell(table, 0, 1), cell(table, 0, 2));
    const double distance = 1e3 * (t.lightPosition - c.pose.apply(c.organ->centreOfGravity)).norm();
    qInfo("light (%.1f, %.1f, %.1f) mm, true (%.1f, %.1f, %.1f), %.0f mm from the organ; sigma %s (true %.3f)",
          light.x(), light.y(), light.z(), 1e3 * t.lightPosition.x(), 1e3 * t.lightPosition.y(),
          1e3 * t.lightPosition.z(), distance, qPrintable(table->item(3, 0)->text()), t.roughness);
    QVERIFY((light - 1e3 * t.lightPosition).norm() <= 0.05 * distance);
    for (int k = 0; k < 3; ++k) {
      QVERIFY2(std::abs(cell(table, 1, k) - t.kd[k]) <= 0.05 * t.kd[k], qPrintable(table->item(1, k)->text()));
      if (c.appearance->ksMeasured[static_cast<std::size_t>(k)])
        QVERIFY2(std::abs(cell(table, 2, k) - t.ks[k]) <= 0.05 * t.ks[k], qPrintable(table->item(2, k)->text()));
      else
        QVERIFY(table->item(2, k)->text().endsWith(" *"));
    }
    QVERIFY(std::abs(cell(table, 3, 0) - t.roughness) <= 0.10 * t.roughness);
    // The frame view now shows the composited frame: it reproduces the frame inside the organ.
    QVERIFY(waitFor([&] { return w_->showingComposited(); }, 10000));
    QCOMPARE(w_->viewModeText(), QStringLiteral("Composited"));
    const cv::Mat3b shown = toMat(w_->frameView()->shownFrame());
    QCOMPARE(shown.cols, c.frame.cols);
    cv::Mat1b inner;
    cv::erode(imaging::renderMask(c.camera, c.pose, c.surfaceView()), inner,
              cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
    const double db = imaging::psnr(c.frame, shown, inner);
    qInfo("composited view at rest: %.1f dB inside the organ (%d px); %s", db, cv::countNonZero(inner),
          qPrintable(w_->appearancePage()->findChild<QLabel*>("appearanceReport")->text()));
    QVERIFY(db >= 30.0);
    QVERIFY(!w_->composition()->diffuseImage().isNull() && !w_->composition()->backgroundImage().isNull());
    // What the model leaves (x 3): on the phantom, rendered with the model, little but noise; the scope's
    // fall-off and the light's distance from the lens, as the table shows them.
    const QImage residual = w_->composition()->residualImage();
    QVERIFY(!residual.isNull());
    const cv::Mat3b left = toMat(residual);
    const double leftMean = cv::mean(left, inner)[0] + cv::mean(left, inner)[1] + cv::mean(left, inner)[2];
    qInfo("left unexplained (x 3): %.1f levels summed over the channels; %s, %s", leftMean,
          qPrintable(table->item(3, 1)->text()), qPrintable(table->item(3, 2)->text()));
    QVERIFY(leftMean < 30);
    QVERIFY(table->item(3, 1)->text().startsWith("n "));
    QVERIFY(std::abs(table->item(3, 1)->text().mid(2).toDouble() - c.appearance->theta.falloff) < 0.01);
    QVERIFY(table->item(3, 2)->text().endsWith(" mm"));  // the light's distance from the lens, whole in its cell
    QVERIFY(std::abs(table->item(3, 2)->text().split(' ')[0].toDouble() -
                     1e3 * c.appearance->theta.lightPosition.norm()) < 0.1);
    QVERIFY(table->item(3, 2)->toolTip().contains("from the lens"));
    QVERIFY2(table->visualItemRect(table->item(3, 2)).width() >=
                 table->fontMetrics().horizontalAdvance(table->item(3, 2)->text()) + 4,
             "the light's distance is cut in its cell");
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty()) {
      QTest::qWait(50);
      w_->grab().save(QString::fromLocal8Bit(dir) + "/step6-appearance.png");
    }
  }

  // A composition that finished while nothing handled events (its watcher's finished signal still queued) is shown
  // once waitForIdle returns: the view then shows the newest request's composition (CI once compared the view with
  // the last snapshot while the composition before it was still shown: waitForIdle asked the watcher whether it ran,
  // which says no before the finished signal is delivered).
  void waitForIdleShowsTheNewestComposition() {
    auto* composition = w_->composition();
    QVERIFY(composition->ready());
    QVERIFY(w_->showingComposited());
    QTest::qWait(200);
    composition->waitForIdle();  // nothing composing or waiting to be handled
    const auto& c = *w_->caseData();
    std::vector<Eigen::Vector3d> moved;  // the organ 4 mm to the right in the camera frame
    for (const auto& p : c.shapeNodes()) moved.push_back(c.pose.apply(p) + Eigen::Vector3d(0.004, 0, 0));
    const QImage before = w_->frameView()->shownFrame();
    composition->request(moved);
    QThread::msleep(3000);  // the worker composes (about 0.1 s) and its finished signal waits in the event queue
    composition->waitForIdle();
    const QImage expected = composition->composeNow(moved);
    QVERIFY(!expected.isNull());
    QVERIFY(expected != before);
    QVERIFY(composition->lastComposed() == expected);
    QVERIFY(w_->frameView()->shownFrame() == expected);
    composition->request();  // the organ at rest again
    composition->waitForIdle();
    QVERIFY(w_->frameView()->shownFrame() == composition->composeNow());
  }

  // Play deforms the organ in the frame: the view shows the composition of the simulation's snapshot, and
  // where the organ was and is no more, I_B. (The organ starts where the frame shows it, in equilibrium: the tissue is
  // made 4x softer on the Simulation panel first, a live edit, so that it sags from there.)
  void compositedViewFollowsTheSimulation() {
    QVERIFY(w_->showingComposited());
    const cv::Mat3b rest = toMat(w_->frameView()->shownFrame());
    auto* young = panel_->findChild<QDoubleSpinBox*>("simYoung");
    QVERIFY(young);
    // The tissue as it was (a live edit again) and the run from rest, whatever this function's checks say: the
    // functions after it cut and pull the organ at its own stiffness (CI once saw a failure here leave it 4x softer,
    // and the cut under traction then opened nothing).
    const double stiffness = young->value();
    const auto restore = qScopeGuard([&] {
      young->setValue(stiffness);
      panel_->reset();
    });
    young->setValue(stiffness / 4);
    QTest::keyClick(w_.get(), Qt::Key_F5);
    QVERIFY(waitFor([&] { return panel_->lastFrame() && panel_->lastFrame()->steps > 30; }));
    QTest::keyClick(w_.get(), Qt::Key_F5);
    QVERIFY(waitFor([&] { return !panel_->isPlaying(); }, 10000));
    QTest::qWait(200);  // the last snapshot reaches the view
    w_->composition()->waitForIdle();
    const auto f = panel_->lastFrame();
    const cv::Mat3b shown = toMat(w_->frameView()->shownFrame());
    const cv::Mat3b expected = toMat(w_->composition()->composeNow(f->positions));
    cv::Mat3b diff;
    cv::absdiff(shown, expected, diff);
    double worst = 0;
    cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
    std::vector<cv::Mat1b> channels;
    cv::split(diff, channels);
    const cv::Mat1b differs = (channels[0] | channels[1] | channels[2]) > 0;
    // the view shows the last snapshot's composition
    QVERIFY2(worst == 0,
             qPrintable(QString("the view differs from the composition of the last snapshot (step %1) by up "
                                "to %2 levels on %3 px")
                            .arg(f->steps)
                            .arg(worst)
                            .arg(cv::countNonZero(differs))));
    cv::absdiff(shown, rest, diff);
    cv::Mat1b changed;
    cv::inRange(diff, cv::Scalar(10, 10, 10), cv::Scalar(255, 255, 255), changed);
    const auto& c = *w_->caseData();
    double sag = 0;
    for (std::size_t i = 0; i < f->positions.size(); ++i)
      sag = std::max(sag, (f->positions[i] - c.pose.apply(c.shapeNodes()[i])).norm());
    qInfo("after %ld steps (largest displacement %.1f mm): %d px of the view changed by 10 levels or more", f->steps,
          1e3 * sag, cv::countNonZero(changed));
    QVERIFY(sag > 1e-3);
    QVERIFY(cv::countNonZero(changed) > 500);
    // Uncovered: organ at rest, not in the snapshot (away from both rims) -> the background I_B.
    std::vector<double> now(3 * f->positions.size());
    for (std::size_t i = 0; i < f->positions.size(); ++i) {
      const Eigen::Vector3d m = c.pose.R.transpose() * (f->positions[i] - c.pose.t);
      for (int k = 0; k < 3; ++k) now[3 * i + k] = m[k];
    }
    SurfaceView moved = c.surfaceView();
    moved.vertices = now.data();
    const cv::Mat1b was = imaging::renderMask(c.camera, c.pose, c.surfaceView()),
                    is = imaging::renderMask(c.camera, c.pose, moved);
    cv::Mat1b isGrown, uncovered;
    cv::dilate(is, isGrown, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
    cv::bitwise_and(was, ~isGrown, uncovered);
    const cv::Mat3b background = toMat(w_->composition()->backgroundImage());
    if (cv::countNonZero(uncovered) > 0) {
      const double db = imaging::psnr(background, shown, uncovered);
      qInfo("uncovered: %d px show I_B (%.1f dB)", cv::countNonZero(uncovered), db);
      QVERIFY(db >= 45.0);
    } else {
      qInfo("the organ sagged within its own outline: nothing uncovered");
    }
  }

  // A cut in step 7 keeps the composited view (issue 35; it gave way to the overlay before): the view shows the cut
  // organ's composition (its cut faces in preset interior colours re-shaded by Theta), said in one sentence.
  void cutOrganIsComposited() {
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Rehearse);
    QVERIFY(w_->showingComposited());
    QTest::keyClick(w_.get(), Qt::Key_B);
    QCOMPARE(w_->frameView()->tool(), ui::Tool::Scissors);
    panel_->play();
    auto* view = w_->frameView();
    const auto& c = *w_->caseData();
    QVERIFY(waitFor(
        [&] { return panel_->lastFrame() && panel_->lastFrame()->positions.size() == c.organ->volume.points.size(); }));
    // A stroke down the organ at 35 % of its width, from above it to below it (as test_rehearse_gui's), where the
    // frame shows it (the simulation starts there).
    std::vector<Eigen::Vector3d> inFrame;
    for (const auto& p : c.shapeNodes()) inFrame.push_back(c.pose.apply(p));
    const auto [from, to] = strokeDownTheOrgan(c.camera, inFrame, 0.35);
    const QPointF a = view->toWidget(QPointF(from.x(), from.y())), b = view->toWidget(QPointF(to.x(), to.y()));
    QTest::mousePress(view, Qt::LeftButton, {}, a.toPoint());
    QVERIFY(waitFor([&] { return panel_->lastFrame()->tool.cutting; }, 20000));
    QStringList said;  // what the session said during the stroke (each sentence once), for the log
    for (int i = 1; i <= 20; ++i) {
      QTest::mouseMove(view, (a + (b - a) * (i / 20.0)).toPoint());
      const long now = panel_->lastFrame()->steps;
      QVERIFY(waitFor([&] { return panel_->lastFrame()->steps >= now + 3; }));
      if (const QString m = panel_->lastFrame()->message; !m.isEmpty() && !said.contains(m)) said << m;
    }
    QTest::mouseRelease(view, Qt::LeftButton, {}, b.toPoint());
    qInfo("stroke from (%.0f, %.0f) to (%.0f, %.0f) px; said: %s", from.x(), from.y(), to.x(), to.y(),
          qPrintable(said.join(" | ")));
    QVERIFY2(waitFor([&] { return panel_->lastFrame()->surface && panel_->lastFrame()->surface->cutCount > 0; }, 60000),
             qPrintable(said.join(" | ")));
    {
      const long at = panel_->lastFrame()->steps;
      QVERIFY(waitFor([&] { return panel_->lastFrame()->steps > at + 30; }));
    }
    QTest::keyClick(w_.get(), Qt::Key_F5);  // pause
    QVERIFY(waitFor([&] { return !panel_->isPlaying(); }, 10000));
    QTest::qWait(200);
    w_->composition()->waitForIdle();
    QVERIFY2(w_->showingComposited(), qPrintable(w_->viewModeText()));
    const auto f = panel_->lastFrame();
    const cv::Mat3b shown = toMat(w_->frameView()->shownFrame());
    const QImage expected = w_->composition()->composeNow(f->positions, f->surface);
    QVERIFY(!expected.isNull());
    cv::Mat3b diff;
    cv::absdiff(shown, toMat(expected), diff);
    double worst = 0;
    cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
    QCOMPARE(worst, 0.0);  // the view shows the cut organ's composition of the last snapshot
    QVERIFY2(w_->composition()->cutSentence().contains("preset interior colours"),
             qPrintable(w_->composition()->cutSentence()));
    // The composition of the cut organ is not the uncut organ's at the same nodes (the cut mesh's boundary is
    // drawn); the colour of its cut faces is test_appearance's cutFacesTakeTheirMaterial. How much of them shows is
    // logged: the organ hangs on its attachments under gravity, and the incision parts a little as the stress it
    // carried is released (graspPullCut checks what traction shows).
    {
      const int seen = cv::countNonZero(cutFacesSeen(c.camera, f->positions, *f->surface).cut);
      qInfo("cut: %zu cut faces of %zu, seen on %d px of the frame (nothing holds the incision open); %s",
            f->surface->cutCount, f->surface->triangles.size(), seen, qPrintable(w_->composition()->cutSentence()));
    }
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty()) {
      QTest::qWait(50);
      w_->grab().save(QString::fromLocal8Bit(dir) + "/step7-cut-composited.png");
    }
    panel_->reset();
    QTest::keyClick(w_.get(), Qt::Key_Escape);
  }

  // Grasp, pull, cut (issue 35): Space closes the jaws on the organ's lower part and the mouse pulls it (the held node
  // follows the jaws); taking the scissors (B) leaves the jaws holding where they are, said in a sentence, as an
  // assistant keeps the traction; the blade's stroke across the stretched tissue above them moves the instrument's tip
  // far away without dragging what the jaws hold; the incision opens under the traction and its cut faces, re-shaded
  // in their interior colour, are seen in the composited view (redder than the capsule around them: the parenchyma's
  // preset ratio). Back with the grasper (R) the drag goes on from where the jaws are, and Space lets go.
  void graspPullCut() {
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    QVERIFY(w_->showingComposited());
    panel_->play();
    auto* view = w_->frameView();
    const auto& c = *w_->caseData();
    QVERIFY(waitFor(
        [&] { return panel_->lastFrame() && panel_->lastFrame()->positions.size() == c.organ->volume.points.size(); }));
    double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
    for (const auto& p : c.shapeNodes()) {
      const Eigen::Vector2d q = c.camera.project(c.pose.apply(p));
      x0 = std::min(x0, q.x()), x1 = std::max(x1, q.x()), y0 = std::min(y0, q.y()), y1 = std::max(y1, q.y());
    }
    const auto widget = [&](double fx, double fy) {  // a point of the organ's box in the image
      return view->toWidget(QPointF(x0 + fx * (x1 - x0), y0 + fy * (y1 - y0))).toPoint();
    };
    QTest::keyClick(w_.get(), Qt::Key_R);
    QCOMPARE(view->tool(), ui::Tool::Grasp);
    QTest::mouseMove(view, widget(0.5, 0.7));
    QTest::keyClick(view, Qt::Key_Space);
    QVERIFY2(waitFor([&] { return panel_->lastFrame()->tool.jawClosed && !panel_->lastFrame()->tool.held.empty(); }),
             qPrintable(said()));
    const auto bitten = panel_->lastFrame();
    const auto node = static_cast<std::size_t>(bitten->tool.held.front());
    const Eigen::Vector3d node0 = bitten->positions[node], tip0 = bitten->tool.tip;
    for (int i = 1; i <= 20; ++i) {
      QTest::mouseMove(view, widget(0.5, 0.7 + 0.15 * i / 20.0));
      QVERIFY(stepsOn(6));
    }
    QVERIFY(stepsOn(30));
    const auto pulled = panel_->lastFrame();
    QVERIFY(pulled->tool.jawClosed && !pulled->tool.held.empty());
    const Eigen::Vector3d tipMoved = pulled->tool.tip - tip0, nodeMoved = pulled->positions[node] - node0;
    qInfo("pulled: the jaws moved %.1f mm, the held node %.1f mm (%.3f mm apart), %.2f N", 1e3 * tipMoved.norm(),
          1e3 * nodeMoved.norm(), 1e3 * (tipMoved - nodeMoved).norm(), pulled->tool.force.norm());
    QVERIFY(tipMoved.norm() > 0.005);                                 // the mouse pulled more than 5 mm
    QVERIFY((tipMoved - nodeMoved).norm() < 0.02 * tipMoved.norm());  // and the tissue went with the jaws

    QTest::keyClick(w_.get(), Qt::Key_B);
    QCOMPARE(view->tool(), ui::Tool::Scissors);
    QVERIFY2(w_->statusBar()->currentMessage().contains("keeps its hold"),
             qPrintable(w_->statusBar()->currentMessage()));
    // A stroke across the stretched tissue above the jaws, from the middle leftwards.
    const QPoint a = widget(0.6, 0.62), b = widget(0.2, 0.62);
    QTest::mousePress(view, Qt::LeftButton, {}, a);
    QVERIFY(waitFor([&] { return panel_->lastFrame()->tool.cutting; }, 20000));
    bool slipped = false;
    for (int i = 1; i <= 20; ++i) {
      QTest::mouseMove(view, a + (b - a) * (i / 20.0));
      QVERIFY(stepsOn(3));
      for (const auto& e : panel_->lastFrame()->events) slipped |= e == "slip";
    }
    QTest::mouseRelease(view, Qt::LeftButton, {}, b);
    QVERIFY(waitFor([&] { return panel_->lastFrame()->surface && panel_->lastFrame()->surface->cutCount > 0; }, 60000));
    QVERIFY(stepsOn(60));
    const auto cut = panel_->lastFrame();
    QVERIFY(!slipped);
    QVERIFY(cut->tool.jawClosed && !cut->tool.held.empty());
    const double bladeAway = (cut->tool.tip - pulled->tool.tip).norm(),
                 nodeDrift = (cut->positions[node] - pulled->positions[node]).norm();
    qInfo("the blade's tip %.1f mm from the jaws' hold; the held node moved %.2f mm meanwhile; %.2f N", 1e3 * bladeAway,
          1e3 * nodeDrift, cut->tool.force.norm());
    QVERIFY(bladeAway > 0.02);   // the instrument's tip went far from the jaws
    QVERIFY(nodeDrift < 0.001);  // and what they hold stayed with them
    QTest::keyClick(w_.get(), Qt::Key_F5);
    QVERIFY(waitFor([&] { return !panel_->isPlaying(); }, 10000));
    QTest::qWait(200);
    w_->composition()->waitForIdle();
    QVERIFY2(w_->showingComposited(), qPrintable(w_->viewModeText()));
    const auto f = panel_->lastFrame();
    const auto seenNow = cutFacesSeen(c.camera, f->positions, *f->surface);
    const cv::Mat1b& cutSeen = seenNow.cut;
    const int seen = cv::countNonZero(cutSeen);
    // Where they are seen, the view shows the cut faces' colour: the parenchyma's preset ratio (0.80, 0.60, 0.60 of the
    // surface's red, green, blue) makes them redder than the organ's surface around them (green over red lower).
    const cv::Mat3b shown = toMat(w_->frameView()->shownFrame());
    cv::Mat3b frameSize;
    cv::resize(shown, frameSize, cutSeen.size(), 0, 0, cv::INTER_NEAREST);
    cv::Mat1b inner, ring;
    cv::erode(cutSeen, inner, cv::Mat(), cv::Point(-1, -1), 2);
    cv::dilate(cutSeen, ring, cv::Mat(), cv::Point(-1, -1), 6);
    ring &= ~cutSeen & seenNow.organ;
    const auto greenOverRed = [&](const cv::Mat1b& m) {
      const cv::Scalar mean = cv::mean(frameSize, m);
      return mean[1] / std::max(1.0, mean[2]);
    };
    qInfo("cut: %zu cut faces of %zu, seen on %d px of the frame; green/red %.3f on them, %.3f on the surface around",
          f->surface->cutCount, f->surface->triangles.size(), seen, greenOverRed(inner), greenOverRed(ring));
    QVERIFY2(seen >= 200, qPrintable(QString::number(seen)));
    QVERIFY(cv::countNonZero(inner) > 0);
    QVERIFY(greenOverRed(inner) < 0.9 * greenOverRed(ring));
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty()) {
      QTest::qWait(50);
      w_->grab().save(QString::fromLocal8Bit(dir) + "/step7-grasp-pull-cut.png");
      // The composited view around the incision (the frame's pixels, 2x).
      const cv::Rect box = (cv::boundingRect(cutSeen) + cv::Size(240, 160)) - cv::Point(120, 80);
      cv::Mat3b detail;
      cv::resize(shown(box & cv::Rect(0, 0, shown.cols, shown.rows)), detail, {}, 2, 2, cv::INTER_CUBIC);
      cv::imwrite((dir + "/step7-grasp-pull-cut-detail.png").toStdString(), detail);
    }
    // Back with the grasper: the jaws still hold, and a drag moves them from where they are.
    QTest::keyClick(w_.get(), Qt::Key_R);
    QVERIFY2(w_->statusBar()->currentMessage().contains("still hold"), qPrintable(w_->statusBar()->currentMessage()));
    panel_->play();
    QVERIFY(stepsOn(2));
    const Eigen::Vector3d jaws = panel_->lastFrame()->tool.jawTip;
    QTest::mouseMove(view, widget(0.8, 0.3));  // far from the jaws: the first move only takes them up
    QVERIFY(stepsOn(10));
    QVERIFY((panel_->lastFrame()->tool.tip - jaws).norm() < 1e-9);
    QTest::keyClick(view, Qt::Key_Space);
    QVERIFY(waitFor([&] { return !panel_->lastFrame()->tool.jawClosed; }));
    // Leaving the instruments lets go: the jaws closed again, the scissors taken, then step 3's tool.
    QTest::mouseMove(view, widget(0.5, 0.7));
    QTest::keyClick(view, Qt::Key_Space);
    QVERIFY(waitFor([&] { return panel_->lastFrame()->tool.jawClosed && !panel_->lastFrame()->tool.held.empty(); }));
    QTest::keyClick(w_.get(), Qt::Key_B);
    QTest::keyClick(w_.get(), Qt::Key_3, Qt::AltModifier);
    QVERIFY(view->tool() != ui::Tool::Grasp && view->tool() != ui::Tool::Scissors);
    QVERIFY(waitFor([&] { return !panel_->lastFrame()->tool.jawClosed; }));
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    panel_->reset();
    QTest::keyClick(w_.get(), Qt::Key_Escape);
  }

  // Issue 36: the other instruments with the mouse on the built-in case, composited. The clip applier (U) closes two
  // clips across the shallowest vessel branch under the surface, the scissors (B) cut between them (the vessel's
  // stumps are found and neither bleeds), the cautery hook (J) burns a line along the organ (its elements relabelled
  // burnt, drawn whitened), and the scissors cut another branch without clips: it bleeds, the loss grows, and the blood
  // is drawn over the composited view.
  void clipCutAndCauterize() {
    QVERIFY(rehearseFromRest());
    auto* view = w_->frameView();
    const auto& c = *w_->caseData();
    QVERIFY(c.groundTruth);
    // How deep each branch lies under the surface the camera sees (its centre line's front, at its middle).
    const auto f0 = panel_->lastFrame();
    std::vector<double> xyz;
    for (const auto& p : f0->positions) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    const rehearse::SurfaceView sv{xyz.data(), f0->positions.size(), c.organ->surface.front().data(),
                                   c.organ->surface.size()};
    const auto g = imaging::surfaceGeometry(c.camera, rehearse::Pose{}, sv);
    const auto& truth = *c.groundTruth;
    auto depthBelow = [&](const Eigen::Vector3d& model, double radius) {
      const Eigen::Vector3d p = c.pose.apply(model);
      const Eigen::Vector2d q = c.camera.project(p);
      const int x = static_cast<int>(std::lround(q.x())), y = static_cast<int>(std::lround(q.y()));
      if (x < 0 || y < 0 || x >= g.triangle.cols || y >= g.triangle.rows || g.triangle(y, x) < 0) return 1e9;
      return p.z() - radius - g.position(y, x)[2];
    };
    std::vector<std::pair<double, std::size_t>> branches;
    for (std::size_t k = 1; k < truth.vesselAxes.size(); ++k) {
      const auto& [a, b] = truth.vesselAxes[k];
      if ((b - a).norm() < 0.02) continue;
      double worst = 0;
      for (double t : {0.3, 0.5, 0.7}) worst = std::max(worst, depthBelow(a + t * (b - a), truth.vesselRadii[k]));
      branches.emplace_back(worst, k);
    }
    std::sort(branches.begin(), branches.end());
    for (const auto& [d, k] : branches) qInfo("branch %zu: %.1f mm under the surface", k, 1e3 * d);
    QVERIFY(!branches.empty() && branches[0].first < 0.02);  // the clip applier looks 25 mm deep
    auto pixelOn = [&](std::size_t k, double t) {
      const auto& [a, b] = truth.vesselAxes[k];
      const Eigen::Vector2d q = c.camera.project(c.pose.apply(a + t * (b - a)));
      return view->toWidget(QPointF(q.x(), q.y())).toPoint();
    };
    // The shallowest branch: two clips on it, a cut between them, a burnt line, and a cut beyond the second clip (the
    // stump of the piece without a clip bleeds).
    const std::size_t first = branches[0].second, second = first;
    // The built-in case's mesh makes its 6.4 mm vessels up to 17 mm wide: clips of 18 mm (the Simulation panel).
    auto* clipLength = panel_->findChild<QDoubleSpinBox*>("simClipLength");
    QVERIFY(clipLength);
    clipLength->setFocus();
    typeInto(clipLength, QStringLiteral("18"));
    QCOMPARE(clipLength->value(), 18.0);
    QVERIFY(stepsOn(2));
    QVERIFY(waitFor([&] { return true; }, 100));
    QTest::keyClick(w_.get(), Qt::Key_U);
    QCOMPARE(view->tool(), ui::Tool::Clip);
    QString said;
    for (double t : {0.35, 0.8}) {
      const std::size_t before = panel_->lastFrame()->field.clips.size();
      QTest::mouseClick(view, Qt::LeftButton, {}, pixelOn(first, t));
      QVERIFY(waitFor([&] { return panel_->lastFrame()->field.clips.size() == before + 1; }));
      auto* status = w_->rehearsePage()->findChild<QLabel*>("rehearseStatus");
      waitFor([&] { return status->text().contains("clip") && status->text() != said; }, 3000);
      said = status->text();
      qInfo("clip at %.2f of the branch: %s", t, qPrintable(said));
    }
    for (const auto& clip : panel_->lastFrame()->field.clips) {
      qInfo("clip on label %d: %zu nodes, %s", clip.label, clip.nodes.size() + 1,
            clip.spans ? "spans" : "does not span");
      QVERIFY(clip.spans);
    }
    // The scissors across the branch between them.
    auto across = [&](std::size_t k, double t, double half) {
      const QPointF a = pixelOn(k, t - 0.05), b = pixelOn(k, t + 0.05);
      QPointF n(-(b - a).y(), (b - a).x());
      n /= std::max(1e-9, std::hypot(n.x(), n.y()));
      const QPointF m = pixelOn(k, t);
      return std::make_pair((m - half * n).toPoint(), (m + half * n).toPoint());
    };
    SessionHeard listening(panel_, 100000);  // what the session said and which events it raised during a stroke
    QStringList& heard = listening.lines;
    auto cutAcross = [&](std::size_t k, double t, int notches = 7) {
      heard.clear();
      QTest::keyClick(w_.get(), Qt::Key_B);
      QCOMPARE(view->tool(), ui::Tool::Scissors);
      const auto [a0, b0] = across(k, t, 18);  // across this branch only (another runs 8 mm beside it)
      const QPoint m = pixelOn(k, t);
      // Near the organ's edge the stroke's end can fall beside the organ as the simulation has deformed it ("Press on
      // the organ to start the cut."): as a surgeon does, the press goes where the organ is, the first point from
      // each end towards the vessel over the live shape the view draws (the stroke still crosses the vessel).
      auto onOrgan = [&](const QPoint& w) {
        const QPointF f = view->toFrame(QPointF(w));
        return view->liveSurfaceAt(Eigen::Vector2d(f.x(), f.y())).has_value();
      };
      auto firstOnOrgan = [&](const QPoint& from) {
        for (int i = 0; i <= 8; ++i) {
          const QPoint q = from + (m - from) * (i / 10.0);
          if (onOrgan(q)) return q;
        }
        return from;
      };
      QPoint a, b;
      bool started = false;
      for (const auto& [from, to] : {std::make_pair(firstOnOrgan(a0), b0), std::make_pair(firstOnOrgan(b0), a0)}) {
        a = from, b = to;
        QTest::mousePress(view, Qt::LeftButton, {}, a);
        if ((started = waitFor([&] { return panel_->lastFrame()->tool.cutting; }, 10000))) break;
        qInfo("the press at (%d, %d) did not start a cut: %s", a.x(), a.y(),
              qPrintable(w_->statusBar()->currentMessage()));
        QTest::mouseRelease(view, Qt::LeftButton, {}, a);
      }
      QVERIFY(started);
      // The blade 14 mm deeper (it spans 4-34 mm under the pressed surface): the branch lies 18-25 mm deep, in elements
      // that reach 35 mm, and only the faces wholly inside the sweep open (with 3 notches the cut missed the vessel).
      wheelDeeper(view, a, notches);
      for (int i = 1; i <= 8; ++i) {
        QTest::mouseMove(view, a + (b - a) * (i / 8.0));
        QVERIFY(stepsOn(3));
      }
      QTest::mouseRelease(view, Qt::LeftButton, {}, b);
      QVERIFY(waitFor([&] { return !panel_->lastFrame()->tool.cutting; }));
      QVERIFY(stepsOn(10));
      for (const auto& line : heard) qInfo("  %s", qPrintable(line));
    };
    cutAcross(first, 0.57);
    QVERIFY(waitFor([&] { return !panel_->lastFrame()->field.bleeds.empty(); }, 60000));
    QVERIFY(stepsOn(5));  // (steps with clips are slow: 20 took over a minute under a parallel build)
    {
      const auto f = panel_->lastFrame();
      int stopped = 0;
      for (const auto& b : f->field.bleeds) stopped += b.stoppedBy >= 0;
      qInfo("cut between the clips: %zu stumps, %d stopped by a clip; %.3f mL lost", f->field.bleeds.size(), stopped,
            1e6 * f->field.bloodLoss);
      for (const auto& b : f->field.bleeds) {
        QString behind;
        for (const auto& clip : f->field.clips)
          behind += QString(" %1").arg(
              1e3 * (f->surface->rest[static_cast<std::size_t>(clip.anchor)] - b.at).dot(b.normal), 0, 'f', 1);
        qInfo("  stump: %.1f mm^2, %.2f mL/s, stopped by %d; clips along its normal (mm):%s", 1e6 * b.area,
              1e6 * b.rate, b.stoppedBy, qPrintable(behind));
      }
      QCOMPARE(stopped, static_cast<int>(f->field.bleeds.size()));
      QCOMPARE(f->field.bloodLoss, 0.0);
    }
    // The cautery hook: a line burnt along the organ below the clipped branch.
    QTest::keyClick(w_.get(), Qt::Key_J);
    QCOMPARE(view->tool(), ui::Tool::Cautery);
    {
      const QPoint from = pixelOn(first, 0.68), to = across(first, 0.68, 30).second;  // from over the vessel sideways
      QTest::mousePress(view, Qt::LeftButton, {}, from);
      QVERIFY(waitFor([&] { return panel_->lastFrame()->field.energy; }));
      for (int i = 1; i <= 10; ++i) {
        QTest::mouseMove(view, from + (to - from) * (i / 10.0));
        QVERIFY(stepsOn(4));
      }
      QTest::mouseRelease(view, Qt::LeftButton, {}, to);
      QVERIFY(waitFor([&] { return !panel_->lastFrame()->field.energy; }));
      QVERIFY(stepsOn(10));
      const auto f = panel_->lastFrame();
      const long burnt = f->labels ? std::count_if(f->labels->begin(), f->labels->end(), simcore::isBurnt) : 0;
      qInfo("cautery: %ld elements burnt, energy on tissue %.2f s", burnt, f->field.energyTime);
      QVERIFY(burnt > 0);
    }
    // The branch cut beyond the second clip: new stumps; the piece without a clip bleeds, more and more.
    const std::size_t cutFacesBefore = panel_->lastFrame()->surface->cutCount;
    cutAcross(second, 0.92);
    // A stroke that opened nothing says so ("Nothing was cut: the blade crossed no tissue ... take it deeper"; CI,
    // under load, once: the organ had deformed under the clips and the hook); as a surgeon does, the stroke again,
    // deeper.
    auto saidNothingCut = [&] { return waitFor([&] { return heard.join(" ").contains("Nothing was cut"); }, 5000); };
    if (panel_->lastFrame()->surface->cutCount == cutFacesBefore && saidNothingCut()) {
      qInfo("the second stroke cut nothing (said); again, 4 notches deeper");
      cutAcross(second, 0.92, 11);
    }
    QVERIFY2(waitFor([&] { return panel_->lastFrame()->surface->cutCount > cutFacesBefore; }, 60000),
             qPrintable(heard.join(" | ")));
    QVERIFY(stepsOn(5));
    const std::size_t stumpsBefore = 2;
    for (const auto& b : panel_->lastFrame()->field.bleeds)
      qInfo("  stump after the second cut: %.1f mm^2, stopped by %d", 1e6 * b.area, b.stoppedBy);
    // The cut opened new stumps. Whether one of them has a clip behind it depends on whether the blade went through the
    // vessel or only into it (the mouse's stroke over a coarse mesh): an open one bleeds more and more, a stopped one
    // loses nothing (test_field and test_recording check the rule itself against the analytic loss).
    // (On the coarse mesh the mouse's stroke may also pass beside the vessel: then nothing new bleeds, said here.)
    if (panel_->lastFrame()->field.bleeds.size() <= stumpsBefore) qInfo("the second stroke did not reach the vessel");
    const auto cut2 = panel_->lastFrame();
    double rate = 0;
    for (const auto& b : cut2->field.bleeds)
      if (b.stoppedBy < 0) rate += b.rate;
    const double lost0 = cut2->field.bloodLoss;
    QVERIFY(stepsOn(15));
    const auto bled = panel_->lastFrame();
    qInfo("cut beyond the clips: bleeding %.2f mL/s, %.3f mL lost, then %.3f mL", 1e6 * rate, 1e6 * lost0,
          1e6 * bled->field.bloodLoss);
    if (rate > 0) {
      QVERIFY(bled->field.bloodLoss > lost0);
      QVERIFY(waitFor(
          [&] { return w_->rehearsePage()->findChild<QLabel*>("rehearseForce")->text().contains("blood lost"); }));
    } else {
      QCOMPARE(bled->field.bloodLoss, lost0);
    }
    QTest::keyClick(w_.get(), Qt::Key_F5);
    QVERIFY(waitFor([&] { return !panel_->isPlaying(); }, 10000));
    QTest::qWait(300);
    w_->composition()->waitForIdle();
    QTest::qWait(100);
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty()) {
      w_->grab().save(QString::fromLocal8Bit(dir) + "/step7-clip-cut-cautery.png");
      // The view around both branches (widget pixels, 2x).
      QRect box;
      for (std::size_t k : {first, second})
        for (double t : {0.0, 1.0}) box |= QRect(pixelOn(k, t), QSize(1, 1));
      box.adjust(-120, -90, 120, 90);
      view->grab(box & view->rect())
          .scaled(2 * (box & view->rect()).size(), Qt::KeepAspectRatio, Qt::SmoothTransformation)
          .save(QString::fromLocal8Bit(dir) + "/step7-clip-cut-cautery-detail.png");
    }
    QTest::keyClick(w_.get(), Qt::Key_Escape);
    panel_->reset();
  }

  // Tearing with the mouse: the Simulation panel's "Tears at" set to 15 % strain, the grasper bites the organ and drags
  // it far down the frame until the tissue tears (the mesh changes without a blade; the status says what tore and at
  // what strain, the page counts it), then lets go. Screenshot docs/step7-tear.png.
  void graspPullUntilItTears() {
    QVERIFY(rehearseFromRest());
    auto* view = w_->frameView();
    const auto& c = *w_->caseData();
    auto* tears = panel_->findChild<QDoubleSpinBox*>("simTearStrain");
    QVERIFY(tears);
    QCOMPARE(tears->value(), 0.0);  // by default nothing tears ("never")
    tears->setFocus();
    typeInto(tears, QStringLiteral("15"));
    QVERIFY(waitFor([&] { return w_->caseData()->material.tearStrain == 0.15; }));
    QVERIFY(stepsOn(3));
    double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
    for (const auto& p : c.shapeNodes()) {
      const Eigen::Vector2d q = c.camera.project(c.pose.apply(p));
      x0 = std::min(x0, q.x()), x1 = std::max(x1, q.x()), y0 = std::min(y0, q.y()), y1 = std::max(y1, q.y());
    }
    const auto widget = [&](double fx, double fy) {
      return view->toWidget(QPointF(x0 + fx * (x1 - x0), y0 + fy * (y1 - y0))).toPoint();
    };
    QTest::keyClick(w_.get(), Qt::Key_R);
    QCOMPARE(view->tool(), ui::Tool::Grasp);
    const std::size_t nodes = panel_->lastFrame()->positions.size();
    const QPoint from = widget(0.3, 0.6);
    QTest::mousePress(view, Qt::LeftButton, {}, from);
    QVERIFY(waitFor([&] { return !panel_->lastFrame()->tool.held.empty(); }));
    auto* status = w_->rehearsePage()->findChild<QLabel*>("rehearseStatus");
    QString tore;
    // What tore, as the page says it: seen on every frame shown (under load a later frame's status replaced the
    // tear's before a poll of the label saw it).
    const auto watching = connect(panel_, &ui::SimulationPanel::frameShown, this, [&] {
      if (tore.isEmpty() && status->text().contains("tore")) tore = status->text();
    });
    const auto unwatch = qScopeGuard([&] { disconnect(watching); });
    QPoint last = from;
    for (int i = 1; i <= 40 && tore.isEmpty(); ++i) {
      last = widget(0.3 - 0.3 * i / 40.0, 0.6 + 0.6 * i / 40.0);
      QTest::mouseMove(view, last);
      QVERIFY(stepsOn(4));
      if (status->text().contains("tore")) tore = status->text();
      if (panel_->lastFrame()->tool.held.empty()) break;  // slipped first
    }
    QVERIFY(waitFor([&] { return panel_->lastFrame()->positions.size() > nodes; },
                    30000));  // torn: the tear's faces get their own nodes
    QVERIFY(waitFor([&] { return status->text().contains("tore") || !tore.isEmpty(); }, 10000));
    if (tore.isEmpty()) tore = status->text();
    qInfo("%s", qPrintable(tore));
    QVERIFY(tore.contains("where its material tears at 15 %"));
    QVERIFY(waitFor([&] { return w_->rehearsePage()->findChild<QLabel*>("rehearseForce")->text().contains("TORN"); },
                    10000));
    QVERIFY(stepsOn(10));
    QTest::keyClick(w_.get(), Qt::Key_F5);
    QVERIFY(waitFor([&] { return !panel_->isPlaying(); }, 10000));
    QTest::qWait(300);
    w_->composition()->waitForIdle();
    QTest::qWait(100);
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty())
      w_->grab().save(QString::fromLocal8Bit(dir) + "/step7-tear.png");
    QTest::mouseRelease(view, Qt::LeftButton, {}, last);
    // Back to "never" for the suites after this one.
    tears->setFocus();
    typeInto(tears, QStringLiteral("0"));
    QVERIFY(waitFor([&] { return w_->caseData()->material.tearStrain == 0; }));
    QTest::keyClick(w_.get(), Qt::Key_Escape);
  }

  void viewModesWithTheKeyboard() {
    auto* centre = w_->findChild<QStackedWidget*>("centre");
    QVERIFY(centre);
    QTest::keyClick(w_.get(), Qt::Key_F3);
    QCOMPARE(w_->viewMode(), ui::ViewMode::Overlay);
    QVERIFY(w_->frameView()->shownFrame() == w_->document()->frameImage());
    QTest::keyClick(w_.get(), Qt::Key_F4);
    QCOMPARE(w_->viewMode(), ui::ViewMode::ThreeD);
    QCOMPARE(centre->currentIndex(), 1);
    QTest::keyClick(w_.get(), Qt::Key_F2);
    QCOMPARE(centre->currentIndex(), 0);
    QVERIFY(waitFor(
        [&] { return w_->showingComposited() && !(w_->frameView()->shownFrame() == w_->document()->frameImage()); },
        10000));
    // O hides the organ in the composited view too (issue 32: it did nothing there): the frame as captured, then back.
    QTest::keyClick(w_.get(), Qt::Key_O);
    QVERIFY(w_->frameView()->shownFrame() == w_->document()->frameImage());
    QTest::keyClick(w_.get(), Qt::Key_O);
    QVERIFY(waitFor([&] { return !(w_->frameView()->shownFrame() == w_->document()->frameImage()); }, 10000));
  }

  // Moving the organ after the estimate: said stale, not composited; Undo makes it current again.
  void movedOrganMakesItStale() {
    w_->editCase("Move (test)", [](app::Case& c) { c.pose.t.x() += 0.005; });
    QVERIFY(!w_->caseData()->appearanceCurrent());
    QVERIFY(!w_->showingComposited());
    QVERIFY2(w_->viewModeText().contains("another pose"), qPrintable(w_->viewModeText()));
    QVERIFY(w_->findChild<QLabel*>("appearanceStatus")->text().startsWith("STALE"));
    QVERIFY(!w_->stepDone(ui::Step::Appearance));
    QVERIFY(w_->infoText().contains("STALE"));
    w_->undoStack()->undo();
    QVERIFY(w_->caseData()->appearanceCurrent());
    QVERIFY(waitFor([&] { return w_->showingComposited(); }, 30000));
  }

  void escCancels() {
    const auto before = w_->caseData()->appearance;
    QSignalSpy done(w_->appearancePage(), &ui::AppearancePage::estimated);
    QTest::keyClick(w_.get(), Qt::Key_F10);
    QTest::keyClick(w_.get(), Qt::Key_Escape);
    QVERIFY(done.wait(120000));
    QVERIFY(!done.first().at(0).toBool());
    QCOMPARE(done.first().at(1).toString(), QStringLiteral("Cancelled; the case is unchanged."));
    QVERIFY(w_->caseData()->appearance == before);
  }

  void organBehindTheCameraIsRefused() {
    const auto before = w_->caseData()->appearance;
    w_->editCase("Behind (test)", [](app::Case& c) { c.pose.t.z() = -0.2; });
    const QList<QVariant> answer = estimateWithF10();
    QVERIFY(!answer.isEmpty());
    QVERIFY(!answer.at(0).toBool());
    qInfo("%s", qPrintable(answer.at(1).toString()));
    QVERIFY(answer.at(1).toString().contains("behind the camera"));
    QVERIFY(w_->caseData()->appearance == before);
    w_->undoStack()->undo();
    QVERIFY(w_->caseData()->appearanceCurrent());
  }

  void savedAndComposedAgainAfterReopening() {
    QTemporaryDir dir;
    const QString path = dir.filePath("appearance.rehearse");
    QSignalSpy saved(w_.get(), &MainWindow::caseSaved);
    w_->saveCaseAs(path);
    QVERIFY(saved.wait(60000));
    QVERIFY(saved.first().at(0).toBool());
    QVERIFY(w_->caseData()->appearance);
    const auto theta = w_->caseData()->appearance->theta;
    QSignalSpy loaded(w_.get(), &MainWindow::caseLoaded);
    w_->openCase(path);
    QVERIFY(loaded.wait(60000));
    const auto& c = *w_->caseData();
    QVERIFY(c.appearance);
    QVERIFY(c.appearanceCurrent());
    QCOMPARE(c.appearance->theta.lightPosition, theta.lightPosition);
    QCOMPARE(c.appearance->theta.kd, theta.kd);
    QVERIFY(waitFor([&] { return w_->showingComposited(); }, 30000));
  }

  void cleanupTestCase() {
    w_->close();
    w_.reset();
  }
};

QTEST_MAIN(TestAppearanceGui)
#include "test_appearance_gui.moc"
