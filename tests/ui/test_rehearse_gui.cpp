// Step 7 through the real main window (offscreen, software rendering) with QTest mouse and key events:
// Alt+7 picks the grasper; a press on the organ closes the jaws there, a drag pulls it (the simulation
// plays), and the bitten tissue follows the tip within 1 mm while the ligament nodes stay; the release
// opens the jaws and the tissue is let go. With REHEARSE_SCREENSHOT_DIR set, it saves a screenshot.
#include "test_support.hpp"

#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <QLabel>

#include <optional>
#include <QSignalSpy>
#include <QStandardPaths>

using namespace rehearse;
using ui::MainWindow;

class TestRehearseGui : public QObject {
  Q_OBJECT
  std::unique_ptr<MainWindow> w_;

  bool waitFor(const std::function<bool()>& done, int ms = 60000) {
    QElapsedTimer t;
    t.start();
    while (t.elapsed() < ms) {
      if (done()) return true;
      QTest::qWait(10);
    }
    return done();
  }

 private slots:
  void initTestCase() {
    QCoreApplication::setOrganizationName("RehearseRehearseTest");
    QStandardPaths::setTestModeEnabled(true);
    ui::applyDarkTheme(*qApp);
    MainWindow::setSoftwareRendering(true);
    w_ = std::make_unique<MainWindow>();
    w_->resize(1600, 900);
    w_->show();
    QVERIFY(QTest::qWaitForWindowExposed(w_.get()));
    w_->activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(w_.get()));
    QSignalSpy loaded(w_.get(), &MainWindow::caseLoaded);
    w_->openCase({});
    QVERIFY(loaded.wait(60000));
    const Pose truth = w_->caseData()->groundTruth->pose;
    w_->editCase("Register (test)", [&truth](app::Case& c) {
      c.pose = truth;
      c.hasPose = c.poseAligned = true;
    });
    // The simulation's session is built for this organ (at rest).
    QVERIFY(waitFor([&] { return w_->simulationPanel()->lastFrame() != nullptr; }));
  }

  void graspPullRelease() {
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Rehearse);
    QCOMPARE(w_->frameView()->tool(), ui::Tool::Grasp);
    auto* panel = w_->simulationPanel();
    QVERIFY(panel->isPlaying());  // the step plays the simulation: the organ settles on its ligaments first
    const QImage restOverlay = w_->organOverlay();
    QVERIFY(waitFor([&] { return panel->lastFrame()->steps > 150; }));
    const auto& c = *w_->caseData();
    const Eigen::Vector2d centre = c.camera.project(c.pose.apply(c.organ->centreOfGravity));
    auto* view = w_->frameView();
    const QPointF a = view->toWidget(QPointF(centre.x(), centre.y()));
    const QPointF b = a + QPointF(0, -45);  // about 2 cm at the organ (checked below)
    double peak = 0;
    std::optional<Eigen::Vector3d> tipAtGrasp;
    QString slipMessage;
    connect(panel, &ui::SimulationPanel::frameShown, this, [&] {
      const auto fr = panel->lastFrame();
      peak = std::max(peak, fr->tool.force.norm());
      if (!fr->tool.held.empty() && !tipAtGrasp) tipAtGrasp = fr->tool.tip;
      if (!fr->message.isEmpty()) slipMessage = fr->message;
    });
    QTest::mousePress(view, Qt::LeftButton, {}, a.toPoint());
    const bool grasped = waitFor([&] { return panel->lastFrame() && !panel->lastFrame()->tool.held.empty(); }, 20000);
    QVERIFY2(grasped, qPrintable(w_->messageLog().join(" | ") + " // " + w_->statusText() + " // " + QString::fromStdString(panel->lastFrame()->report.status) +
                                   QString(" steps %1 jaw %2").arg(panel->lastFrame()->steps).arg(panel->lastFrame()->tool.jawClosed)));
    for (int i = 1; i <= 12; ++i) {
      QTest::mouseMove(view, (a + (b - a) * (i / 12.0)).toPoint());
      // The organ follows each move for a few steps before the next (a hand moves over many steps; a slow
      // machine must not turn the drag into jumps).
      const long now = panel->lastFrame()->steps;
      QVERIFY(waitFor([&] { return panel->lastFrame()->steps >= now + 5; }));
    }
    // The tip reached the cursor's last place; after the organ followed for a while, compare.
    const long at = panel->lastFrame()->steps;
    QVERIFY(waitFor([&] { return panel->lastFrame()->steps > at + 40; }));
    const auto f = panel->lastFrame();
    QVERIFY2(!f->tool.held.empty(), qPrintable(QString("peak %1 N; %2").arg(peak).arg(slipMessage)));
    double worst = 0;
    for (std::size_t k = 0; k < f->tool.held.size(); ++k)
      worst = std::max(worst, (f->positions[static_cast<std::size_t>(f->tool.held[k])] - (f->tool.tip + f->tool.heldOffset[k])).norm());
    double fixedMoved = 0;
    for (int i : c.attachments)
      fixedMoved = std::max(fixedMoved, (f->positions[static_cast<std::size_t>(i)] - c.pose.apply(c.shapeNodes()[static_cast<std::size_t>(i)])).norm());
    // The tip moved with the cursor (the bite's node need not be under it: the nearest surface node is).
    QVERIFY(tipAtGrasp.has_value());
    const Eigen::Vector2d tipMoved = c.camera.project(f->tool.tip) - c.camera.project(*tipAtGrasp);
    const QPointF cursorMoved = view->toFrame(b) - view->toFrame(a);
    qInfo("pulled: %zu nodes held, worst %.4f mm from their place on the tool; the tip moved (%.1f, %.1f) px, the cursor (%.1f, %.1f) px; tool force %.2f N "
          "(peak %.2f N); ligament nodes moved %.1e m",
          f->tool.held.size(), 1e3 * worst, tipMoved.x(), tipMoved.y(), cursorMoved.x(), cursorMoved.y(), f->tool.force.norm(), peak, fixedMoved);
    const double pulledMm = 1e3 * (f->tool.tip - *tipAtGrasp).norm();
    qInfo("the tip moved %.1f mm", pulledMm);
    QVERIFY(pulledMm > 15 && pulledMm < 30);
    QVERIFY(worst < 1e-3);
    QVERIFY((tipMoved - Eigen::Vector2d(cursorMoved.x(), cursorMoved.y())).norm() < 1.0);
    QVERIFY(fixedMoved < 1e-9);
    QVERIFY(f->tool.force.norm() > 0.01);
    QVERIFY(!(w_->organOverlay() == restOverlay));  // the organ over the frame follows the simulation in this step
    QVERIFY(w_->findChild<QLabel*>("rehearseForce")->text().startsWith("Tool force"));
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty()) w_->grab().save(QString::fromLocal8Bit(dir) + "/step7-grasp.png");
    QTest::mouseRelease(view, Qt::LeftButton, {}, b.toPoint());
    QVERIFY(waitFor([&] { return panel->lastFrame()->tool.held.empty() && !panel->lastFrame()->tool.jawClosed; }));
    QVERIFY(waitFor([&] { return w_->findChild<QLabel*>("rehearseStatus")->text().startsWith("Released"); }, 10000));
    QCOMPARE(panel->lastFrame()->tool.force.norm(), 0.0);
    panel->pause();
  }

  void cleanupTestCase() {
    w_->close();
    w_.reset();
  }
};

QTEST_MAIN(TestRehearseGui)
#include "test_rehearse_gui.moc"
