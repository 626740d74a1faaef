// Issue 61's path, as a new user takes it with the mouse and keys only: the patient liver
// (../shared/data/scikit-surgery/patient-liver/liver.vtk, meshed by step 1 to about 3,600 tets) imported over the
// scikit-surgery frame with its intrinsics, the silhouette drawn freehand in two segments, F9, H and attachment nodes
// picked with the mouse, F9 again, F10, step 7 with the panel's defaults (gravity into the scene, the tissue around the
// organ carrying it). Three assistants' picks: 22 nodes along the liver's top edge in the image, none at all (Release
// All), and the 8 % of its surface nodes highest against gravity (the front, nearest the camera). For each: the organ
// starts within 1 px of the registered shape, stays within 1 px over 10 s without an instrument with every step
// converged (counted on the stepping thread, whether drawn or not), and a grasp pulled 20 mm with the mouse gives a
// force of a few newtons. The median step of the shown frames is printed (BENCHMARKS.md; no timed assertion).
// Skipped (or failed, with REHEARSE_REQUIRE_SHARED=1) when the shared data is absent.
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QLabel>
#include <QPushButton>
#include <QRegularExpression>
#include <QScopeGuard>
#include <QSignalSpy>
#include <QtTest>
#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/session/session.hpp>
#include <set>

#include "rehearse/ui/composition.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/pages/appearancepage.hpp"
#include "rehearse/ui/pages/fitpage.hpp"
#include "rehearse/ui/pages/meshpage.hpp"
#include "rehearse/ui/simulationpanel.hpp"
#include "test_support.hpp"
#include "window_support.hpp"

using namespace rehearse;
using ui::MainWindow;

class TestPatientStart : public QObject {
  Q_OBJECT
  std::unique_ptr<MainWindow> w_;

  // The nodes of the registered shape in the camera frame, and their pixels.
  static std::vector<Eigen::Vector3d> registered(const app::Case& c) {
    std::vector<Eigen::Vector3d> out;
    for (const auto& p : c.shapeNodes()) out.push_back(c.pose.apply(p));
    return out;
  }
  static double farthestPx(const app::Case& c, const std::vector<Eigen::Vector3d>& positions) {
    const auto shape = registered(c);
    double px = 0;
    for (std::size_t i = 0; i < positions.size() && i < shape.size(); ++i)
      px = std::max(px, (c.camera.project(positions[i]) - c.camera.project(shape[i])).norm());
    return px;
  }
  static std::set<int> surfaceNodes(const app::Case& c) {
    std::set<int> s;
    for (const auto& t : c.organ->surface)
      for (int n : t) s.insert(n);
    return s;
  }

  // H, then one click per pick (frame pixels), on the mesh step; Release All first.
  void pick(const std::vector<Eigen::Vector2d>& at, double radiusMm) {
    auto* view = w_->frameView();
    QTest::keyClick(w_.get(), Qt::Key_1, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Mesh);
    QTest::mouseClick(w_->findChild<QPushButton*>("clearAttachments"), Qt::LeftButton);
    QVERIFY(discardTheRehearsalIfAsked(*w_));  // (the last case's pull may have torn it)
    QVERIFY(w_->caseData()->attachments.empty());
    if (at.empty()) return;
    view->setFocus();
    QTest::keyClick(w_.get(), Qt::Key_H);
    QCOMPARE(view->tool(), ui::Tool::Attachments);
    w_->findChild<QDoubleSpinBox*>("attachmentRadius")->setValue(radiusMm);
    for (const auto& p : at)
      QTest::mouseClick(view, Qt::LeftButton, {}, view->toWidget(QPointF(p.x(), p.y())).toPoint());
  }

  // The scikit-surgery frame with its intrinsics, and the patient liver imported over it (meshed to about 3,600
  // elements), its placement accepted; the frame view focused.
  void importPatientLiver() {
    const QString why = importPatientLiverOverItsFrame(*w_);
    QVERIFY2(why.isEmpty(), qPrintable(why));
    w_->editCase("Accept the import's placement (test)", [](app::Case& c) { c.hasPose = c.poseAligned = true; });
    w_->frameView()->setFocus();
  }
  // The outline (frame pixels) drawn freehand (F, step 3) in two segments that meet: the first over 55 % of it, the
  // second over the rest and back over the first's end.
  void drawInTwoPieces(const std::vector<Eigen::Vector2d>& outline) {
    auto* view = w_->frameView();
    QTest::keyClick(w_.get(), Qt::Key_3, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Contour);
    QTest::keyClick(w_.get(), Qt::Key_F);
    QCOMPARE(view->tool(), ui::Tool::Freehand);
    const std::size_t n = outline.size();
    for (const auto& [first, last] : {std::pair{std::size_t(0), 55 * n / 100}, std::pair{50 * n / 100, n + n / 50}}) {
      std::vector<QPoint> stroke;
      for (std::size_t i = first; i <= last; i += 4) {
        const auto& q = outline[i % n];
        const QPoint p = view->toWidget(QPointF(q.x(), q.y())).toPoint();
        if (stroke.empty() || p != stroke.back()) stroke.push_back(p);
      }
      QTest::mousePress(view, Qt::LeftButton, {}, stroke.front());
      for (const QPoint& p : stroke) QTest::mouseMove(view, p);
      QTest::mouseRelease(view, Qt::LeftButton, {}, stroke.back());
    }
    qInfo("contour: %zu segments, %zu outline pixels", w_->caseData()->contour.segments.size(), n);
    QCOMPARE(w_->caseData()->contour.segments.size(), std::size_t(2));
  }

  // F9 on the elastic step, until the case has a fit of its current attachments.
  void fit(QString* said = nullptr) {
    QTest::keyClick(w_.get(), Qt::Key_5, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Elastic);
    QSignalSpy finished(w_->fitPage(), &ui::FitPage::fitFinished);
    QTest::keyClick(w_.get(), Qt::Key_F9);
    QVERIFY(finished.wait(300000));
    if (said) *said = finished.first().at(1).toString();
    qInfo("  fit (%zu held nodes): %s", w_->caseData()->attachments.size(),
          qPrintable(finished.first().at(1).toString()));
    QVERIFY2(finished.first().at(0).toBool(), qPrintable(finished.first().at(1).toString()));
    QVERIFY(w_->caseData()->hasFit());
    // F10: the appearance estimated on the fitted shape (the composited view of step 7).
    QTest::keyClick(w_.get(), Qt::Key_6, Qt::AltModifier);
    QSignalSpy estimated(w_->appearancePage(), &ui::AppearancePage::estimated);
    QTest::keyClick(w_.get(), Qt::Key_F10);
    QVERIFY(estimated.wait(120000));
    QVERIFY2(estimated.first().at(0).toBool(), qPrintable(estimated.first().at(1).toString()));
  }

  // The grasper's node on a visible surface near the organ's middle in the image, free of the held nodes (-1 if
  // none): the node a surgeon grasps.
  static int nodeToGrasp(const app::Case& c, const std::vector<Eigen::Vector3d>& shape) {
    const Eigen::Vector2d middle = c.camera.project(c.pose.apply(c.organ->centreOfGravity));
    int bite = -1;
    double best = 1e300;
    // Free tissue, as a surgeon grasps it: at least 15 mm from every held node (beside one, the jaws would pull
    // against the ligament itself), nearest the middle among the visible ones.
    auto free = [&](int n) {
      for (int h : c.attachments)
        if ((shape[static_cast<std::size_t>(h)] - shape[static_cast<std::size_t>(n)]).norm() < 0.015) return false;
      return true;
    };
    for (int n : surfaceNodes(c)) {
      if (!free(n)) continue;
      const Eigen::Vector3d& p = shape[static_cast<std::size_t>(n)];
      const Eigen::Vector2d q = c.camera.project(p);
      if ((q - middle).norm() > 150) continue;
      const double score = p.z() + 1e-4 * (q - middle).norm();  // nearest the camera: on the visible side
      if (score < best) best = score, bite = n;
    }
    return bite;
  }

  // Pulled away from what holds it, in the image plane (up the image when nothing is held).
  static Eigen::Vector3d awayFromTheHolds(const app::Case& c, const std::vector<Eigen::Vector3d>& shape,
                                          const Eigen::Vector3d& p) {
    Eigen::Vector3d away(0, -1, 0);
    if (!c.attachments.empty()) {
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int h : c.attachments) mean += shape[static_cast<std::size_t>(h)];
      mean /= static_cast<double>(c.attachments.size());
      away = p - mean;
      away.z() = 0;
      away = away.norm() > 1e-6 ? Eigen::Vector3d(away.normalized()) : Eigen::Vector3d(0, -1, 0);
    }
    return away;
  }

  // Step 7 with the panel's defaults; 10 s untouched; a grasp pulled 20 mm. Returns nothing: it checks.
  void rehearse(const char* picks) {
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Rehearse);
    auto* panel = w_->simulationPanel();
    auto* status = panel->findChild<QLabel*>("simStatus");
    QCOMPARE(panel->findChild<QComboBox*>("simGravity")->currentText(), QStringLiteral("into the scene"));
    QCOMPARE(panel->findChild<QDoubleSpinBox*>("simSupport")->value(), 100.0);
    const auto kept = w_->caseData();
    const app::Case& c = *kept;
    auto ours = [&](const std::shared_ptr<const ui::SimulationFrame>& f) {
      return f && f->organ && f->organ->hasFit() && f->organ->shapeDigest() == c.shapeDigest() &&
             f->organ->attachments == c.attachments && f->positions.size() == c.organ->volume.points.size();
    };
    panel->play();
    QVERIFY2(waitFor([&] { return ours(panel->lastFrame()) && !panel->startSentence().isEmpty(); }, 300000),
             qPrintable(status->text()));
    qInfo("  %s: %s", picks, qPrintable(panel->startSentence()));
    QVERIFY2(panel->startSentence().contains("starts where the frame shows it"), qPrintable(panel->startSentence()));
    // A click whose radius caught one node alone holds its neighbours on the surface too, and the start says how many
    // nodes the body holds: the session's own count, more than the clicks held (the top edge's 2 mm clicks on this
    // 3.3k-tet mesh leave some nodes lone).
    if (std::string(picks) == "top-edge") {
      const QRegularExpressionMatch m =
          QRegularExpression("lone attachments? holds? (its|their) [0-9]+ neighbours too \\(([0-9]+) nodes held\\)")
              .match(panel->startSentence());
      QVERIFY2(m.hasMatch(), qPrintable(panel->startSentence()));
      const auto held = panel->session()->setup().fixedNodes.size();
      QCOMPARE(m.captured(2).toULongLong(), static_cast<qulonglong>(held));
      QVERIFY(held > c.attachments.size());
      // The frames carry them (the simulation view draws the held neighbours beside the picks) ...
      QVERIFY(panel->lastFrame()->held);
      QCOMPARE(panel->lastFrame()->held->size(), held);
      // ... and the start's whole sentence stays in the Messages panel (the panel's lines cut it off, a person read).
      QVERIFY2(w_->messageLog().join(QLatin1Char('\n')).contains(m.captured(0)), qPrintable(w_->messageLog().join(" | ")));
    }
    // Where it starts: the first frame of this session.
    const double startPx = farthestPx(c, panel->lastFrame()->positions);
    std::vector<double> wall;
    double drift = 0;
    const auto watching = connect(panel, &ui::SimulationPanel::frameShown, this, [&] {
      const auto f = panel->lastFrame();
      if (!ours(f) || f->steps == 0) return;
      wall.push_back(f->report.wallMs);
      drift = std::max(drift, farthestPx(c, f->positions));
    });
    auto unwatch = qScopeGuard([&] { disconnect(watching); });
    const long steps = std::lround(10.0 / panel->setup().timeStep);
    QVERIFY(waitFor([&] { return ours(panel->lastFrame()) && panel->lastFrame()->steps >= steps; }, 600000));
    const auto f = panel->lastFrame();
    std::sort(wall.begin(), wall.end());
    const double median = wall.empty() ? 0 : wall[wall.size() / 2];
    qInfo(
        "  %s: %zu tets, %zu held nodes, %zu supported; starts %.3f px from the registered shape, at most %.3f px "
        "over %ld steps (%.1f s); %ld steps not converged; median step %.2f ms (%zu frames shown)",
        picks, c.organ->volume.tets.size(), c.attachments.size(), f->supports ? f->supports->size() : 0, startPx, drift,
        f->steps, f->time, f->stepsNotConverged, median, wall.size());
    QVERIFY(startPx <= 1.0);
    QVERIFY(drift <= 1.0);
    QCOMPARE(f->stepsNotConverged, 0L);
    QVERIFY(wall.size() > 20);
    QVERIFY2(w_->showingComposited(), qPrintable(w_->viewModeText()));
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty())
      w_->findChild<ui::SimulationView*>()->grab().save(QString::fromLocal8Bit(dir) + "/patient-start-" + picks +
                                                        "-3d.png");

    // The grasper (R) on a visible surface node near the organ's middle in the image (not a held one), pulled 20 mm up
    // the image by the mouse, in ten moves.
    auto* view = w_->frameView();
    view->setFocus();
    QTest::keyClick(w_.get(), Qt::Key_R);
    QCOMPARE(view->tool(), ui::Tool::Grasp);
    const auto shape = registered(c);
    const int bite = nodeToGrasp(c, shape);
    QVERIFY(bite >= 0);
    const Eigen::Vector3d p = f->positions[static_cast<std::size_t>(bite)];
    // Pulled away from what holds it, in the image plane (up the image when nothing is held): a surgeon retracts the
    // tissue against its ligaments, not into them (pulled 20 mm towards the top edge's picks 15 mm away, the tissue
    // between is crushed: steps held back to keep elements from inverting, 83 inexact, up to 1.3 s).
    const Eigen::Vector3d away = awayFromTheHolds(c, shape, p);
    const Eigen::Vector2d from = c.camera.project(p), to = c.camera.project(p + 0.02 * away);
    const QPointF a = view->toWidget(QPointF(from.x(), from.y())), b = view->toWidget(QPointF(to.x(), to.y()));
    QTest::mousePress(view, Qt::LeftButton, {}, a.toPoint());
    QVERIFY(waitFor([&] { return !panel->lastFrame()->tool.held.empty(); }, 30000));
    qInfo("  %s: grasped node %d (%zu held by the jaws: %s)", picks, bite, panel->lastFrame()->tool.held.size(),
          qPrintable(panel->lastFrame()->message));
    double peak = 0, held = 0;  // N: the largest grasp force; the last one while the jaws held (before a slip)
    QStringList said, trace;
    const auto forces = connect(panel, &ui::SimulationPanel::frameShown, this, [&] {
      const auto f = panel->lastFrame();
      peak = std::max(peak, f->tool.graspForce.norm());
      if (!f->tool.held.empty()) held = f->tool.graspForce.norm();
      if (trace.size() < 12)
        trace << QStringLiteral("%1:%2n/%3N/%4mm")
                     .arg(f->steps)
                     .arg(f->tool.held.size())
                     .arg(f->tool.graspForce.norm(), 0, 'f', 2)
                     .arg(1e3 * (f->tool.tip - p).norm(), 0, 'f', 1);
      if (f->report.outcome != simcore::StepStatus::Converged) {
        const QString why = QString::fromStdString(simcore::statusSentence(f->report));
        if (!said.contains(why)) said << why;
      }
      for (const auto& e : f->events) said << QString::fromStdString(e);
      if (!f->message.isEmpty() && !said.contains(f->message)) said << f->message;
    });
    auto unforce = qScopeGuard([&] { disconnect(forces); });
    double slowest = 0;
    const auto timing = connect(panel, &ui::SimulationPanel::frameShown, this,
                                [&] { slowest = std::max(slowest, panel->lastFrame()->report.wallMs); });
    auto untime = qScopeGuard([&] { disconnect(timing); });
    auto stepsOn = [&](long by) {
      const long at = panel->lastFrame()->steps;
      const bool on = waitFor([&] { return panel->lastFrame()->steps >= at + by; }, 60000);
      if (!on)
        qWarning("  %s: %ld steps in 60 s (playing: %d; slowest shown step %.0f ms): %s", picks,
                 panel->lastFrame()->steps - at, panel->isPlaying(), slowest, qPrintable(status->text()));
      return on;
    };
    for (int i = 1; i <= 10; ++i) {
      QTest::mouseMove(view, (a + (b - a) * (i / 10.0)).toPoint());
      QVERIFY(stepsOn(5));
    }
    QVERIFY(stepsOn(50));
    const auto g = panel->lastFrame();
    const double moved = 1e3 * (g->tool.tip - p).norm();
    qInfo(
        "  %s: the jaws pulled %.1f mm; %zu nodes held; force %.2f N (peak %.2f N); slowest shown step %.1f ms; "
        "%ld steps not converged since the start; said: %s",
        picks, moved, g->tool.held.size(), g->tool.graspForce.norm(), peak, slowest, g->stepsNotConverged,
        qPrintable(said.join(" | ")));
    QVERIFY(moved > 12);  // the mouse's 20 mm at the organ, seen along the shaft
    // A few newtons, never kN: held, or let go at the scene's maximum grasp force (tissue pinned all round by the
    // front's picks is that stiff: a 2 mm jump of the mouse asks for more), within one step's change of it.
    int slipAt = -1;
    for (int i = 0; i < said.size() && slipAt < 0; ++i)
      if (said[i].contains(QStringLiteral("slipped out of the grasper at"))) slipAt = i;
    if (slipAt >= 0) {
      const QRegularExpressionMatch m = QRegularExpression("at ([0-9.]+) N").match(said[slipAt]);
      // The jaws are held back where the force, to first order, reaches the limit (Session::limitJawsAtGraspForce). A
      // 2 mm jump on this pinned tissue takes the force from 8.8 N to 15.7-16.9 N in one step: what the first order
      // missed, 10-24 % of the step's change past the limit (which, depended on how far the tissue settled between the
      // jumps, the machine's timing). Now such a step is taken again with the jaws moved back by regula falsi on the
      // force (ToolSettings::slipResolved): the slip within 2 % of the limit, whatever the timing.
      const double at = m.hasMatch() ? m.captured(1).toDouble() : 1e9,
                   limit = panel->session()->setup().tools.maxGraspForce;
      qInfo("  %s: %.2f N on the last step the jaws held, %.1f N at the slip (limit %.0f N)", picks, held, at, limit);
      QVERIFY2(at <= 1.02 * limit, qPrintable(said[slipAt]));
    } else {
      QVERIFY2(peak > 0.05 && peak < 15.5, qPrintable(trace.join(' ')));
    }
    letGo(b.toPoint());
    if (std::string(picks) == "top-edge") tearOnce(view, a, b);
    shot(*w_, (std::string("patient-start-") + picks).c_str());
    panel->pause();
  }

  // The button released over the view: the jaws open (Space opens them if they stay closed).
  void letGo(QPoint at) {
    auto* view = w_->frameView();
    auto* panel = w_->simulationPanel();
    QTest::mouseRelease(view, Qt::LeftButton, {}, at);
    if (!waitFor([&] { return !panel->lastFrame()->tool.jawClosed; }, 10000)) QTest::keyClick(view, Qt::Key_Space);
    QVERIFY(waitFor([&] { return !panel->lastFrame()->tool.jawClosed && panel->lastFrame()->tool.held.empty(); }, 30000));
  }

  // Issue 61, tearing at the README's recommended threshold (15 %, measured from where the organ started): the organ
  // let go after the 20 mm pull, the tears-at field set to 15, it does not tear at rest over 100 steps; grasped again
  // where it was and pulled along the same line a millimetre a move, it tears; released at once, it tears no more over
  // 100 steps.
  void tearOnce(ui::FrameView* view, QPointF a, QPointF b) {
    auto* panel = w_->simulationPanel();
    // Tears counted by whether the jaws held tissue at the step each was made at (the frames shown lag the session: a
    // tear made just before the release can be shown after it).
    int tears = 0, whileHeld = 0;
    QStringList said;
    const auto counting = connect(panel, &ui::SimulationPanel::frameShown, this, [&] {
      const auto f = panel->lastFrame();
      for (const auto& e : f->events)
        if (e == "tear") ++tears, whileHeld += !f->tool.held.empty();
      if (!f->message.isEmpty() && !said.contains(f->message)) said << f->message;
    });
    auto uncount = qScopeGuard([&] { disconnect(counting); });
    auto stepsOn = [&](long by, int ms) {
      const long from = panel->lastFrame()->steps;
      return waitFor([&] { return panel->lastFrame()->steps >= from + by; }, ms);
    };
    QVERIFY(stepsOn(100, 120000));  // let go: it relaxes
    auto* tearsAt = panel->findChild<QDoubleSpinBox*>("simTearStrain");
    tearsAt->setFocus();
    typeInto(tearsAt, QStringLiteral("15"));
    QVERIFY(waitFor([&] { return std::abs(w_->caseData()->material.tearStrain - 0.15) < 1e-9; }));
    view->setFocus();
    QVERIFY(stepsOn(100, 120000));
    const int atRest = tears;
    QTest::mousePress(view, Qt::LeftButton, {}, a.toPoint());
    QVERIFY(waitFor([&] { return !panel->lastFrame()->tool.held.empty(); }, 30000));
    QPoint at = a.toPoint();
    int moves = 0;
    for (int i = 1; i <= 40 && tears == atRest && !panel->lastFrame()->tool.held.empty(); ++i, ++moves) {
      at = (a + (b - a) * (i / 20.0)).toPoint();
      QTest::mouseMove(view, at);
      QVERIFY(stepsOn(5, 60000));
    }
    QVERIFY(stepsOn(10, 120000));  // (a tear opens 5 steps after the tissue passed its limit)
    shot(*w_, "patient-tear");
    letGo(at);
    QVERIFY(stepsOn(100, 240000));
    const int pulling = whileHeld;
    const QStringList tore = said.filter(QStringLiteral(" tore"));
    qInfo("  top-edge, tears at 15 %%: %d tears at rest over 100 steps; pulled %d mm again: %d tear(s); %d more over the "
          "100 steps after the release; %s",
          atRest, moves, pulling, tears - atRest - pulling, qPrintable(tore.join(" | ")));
    QCOMPARE(atRest, 0);
    QVERIFY2(pulling >= 1, qPrintable(said.join(" | ")));
    QVERIFY2(pulling <= 3, qPrintable(said.join(" | ")));  // a tear, not a cascade
    QCOMPARE(tears, atRest + pulling);                       // released, it tears no more
    // The next picks' measurements are the organ's without tearing, as before.
    tearsAt->setFocus();
    typeInto(tearsAt, QStringLiteral("0"));
    QVERIFY(waitFor([&] { return w_->caseData()->material.tearStrain == 0; }));
    view->setFocus();
  }

 private slots:
  void initTestCase() {
    QCoreApplication::setOrganizationName("RehearsePatientStartTest");
    MainWindow::setRenderer(MainWindow::Renderer::Software);
    QVERIFY(openPhantomCase(w_));
  }

  void anAssistantsPicksOnThePatientLiver() {
    REQUIRE_SHARED("scikit-surgery/laparoscopy-liver-frame.jpg");
    REQUIRE_SHARED("scikit-surgery/patient-liver/liver.vtk");
    importPatientLiver();
    if (QTest::currentTestFailed()) return;
    // The silhouette, freehand (F) in two segments that meet: the organ's outline in the frame, 6 px wider all round
    // (the fit has something to do), the first segment over 55 % of it, the second over the rest and back over the
    // first's end.
    {
      const auto k = w_->caseData();
      cv::Mat1b mask = imaging::renderMask(k->camera, k->pose, k->surfaceView());
      cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, {13, 13}));
      const auto borders = imaging::maskOutlines(mask);
      QVERIFY(!borders.empty());
      const auto& outline = borders.front();
      drawInTwoPieces(outline);
      if (QTest::currentTestFailed()) return;
    }
    fit();  // F9 (and F10) on the contour alone

    // 22 picks along the top edge in the image, 2 mm each (a node or two per click).
    {
      const auto k = w_->caseData();
      const cv::Mat1b mask = imaging::renderMask(k->camera, k->pose, k->surfaceView());
      int left = mask.cols, right = -1;
      for (int y = 0; y < mask.rows; ++y)
        for (int x = 0; x < mask.cols; ++x)
          if (mask(y, x)) left = std::min(left, x), right = std::max(right, x);
      std::vector<Eigen::Vector2d> top;
      for (int i = 0; i < 22; ++i) {
        const int x = left + static_cast<int>((0.08 + 0.84 * i / 21.0) * (right - left));
        int y = 0;
        while (y < mask.rows && !mask(y, x)) ++y;
        top.emplace_back(x, y + 6);
      }
      pick(top, 2);
      qInfo("22 picks along the top edge: %zu nodes held", w_->caseData()->attachments.size());
      // (Two clicks nearer each other than the mesh's nodes, about 8 mm apart here, may hold the same node.)
      QVERIFY(w_->caseData()->attachments.size() >= 16);
    }
    fit();
    rehearse("top-edge");

    // None: Release All.
    pick({}, 2);
    fit();
    rehearse("none");

    // The 8 % of the surface nodes highest against gravity (into the scene: nearest the camera), each clicked.
    {
      const auto k = w_->caseData();
      const auto shape = registered(*k);
      std::vector<std::pair<double, int>> byDepth;
      for (int n : surfaceNodes(*k)) byDepth.emplace_back(shape[static_cast<std::size_t>(n)].z(), n);
      std::sort(byDepth.begin(), byDepth.end());
      const std::size_t count = std::max<std::size_t>(3, byDepth.size() * 8 / 100);
      std::vector<Eigen::Vector2d> at;
      for (std::size_t i = 0; i < count; ++i)
        at.push_back(k->camera.project(shape[static_cast<std::size_t>(byDepth[i].second)]));
      pick(at, 1);
      qInfo("the 8 %% highest: %zu clicks, %zu nodes held", count, w_->caseData()->attachments.size());
      QVERIFY(w_->caseData()->attachments.size() >= count / 2);
    }
    fit();
    rehearse("highest-8pc");
  }

  // A person's own contour, not the organ's placed outline: where the assistant traced the liver in the frame, the
  // import's placement lies off it (here its outline moved 30 px right and 20 px up, turned 8 degrees and stretched
  // 1.1 x 0.92), drawn freehand in two pieces, F9 with no node held. The fit is kept and crushes no element: none of
  // the fitted shape's elements, their volumes computed here from its nodes, is below 1 % of its rest volume (the
  // simulation's floor) or inside out. Before, the fit's bindings pulled surface nodes through their neighbours: 2
  // elements inside out in this case, and in a person's case under Xvfb 2 flat ones, so the fit was refused. Then step 7
  // as for the assistants' picks above: it starts within 1 px, stays within 1 px over 10 s, and a grasp pulls it 20 mm.
  void aPersonsContourWithoutAttachmentsCrushesNothing() {
    REQUIRE_SHARED("scikit-surgery/laparoscopy-liver-frame.jpg");
    REQUIRE_SHARED("scikit-surgery/patient-liver/liver.vtk");
    closeDiscardingChanges(*w_);  // a new window on the built-in case: the picks above are not this case's
    w_.reset();
    QVERIFY(openPhantomCase(w_));
    importPatientLiver();
    if (QTest::currentTestFailed()) return;
    QVERIFY(w_->caseData()->attachments.empty());
    {
      const auto k = w_->caseData();
      const cv::Mat1b mask = imaging::renderMask(k->camera, k->pose, k->surfaceView());
      const cv::Moments m = cv::moments(mask, true);
      const cv::Point2f centre(static_cast<float>(m.m10 / m.m00), static_cast<float>(m.m01 / m.m00));
      cv::Mat A = cv::getRotationMatrix2D(centre, 8, 1.0);
      A.row(0) *= 1.1;
      A.row(1) *= 0.92;
      A.at<double>(0, 2) = centre.x - (A.at<double>(0, 0) * centre.x + A.at<double>(0, 1) * centre.y) + 30;
      A.at<double>(1, 2) = centre.y - (A.at<double>(1, 0) * centre.x + A.at<double>(1, 1) * centre.y) - 20;
      cv::Mat1b traced;
      cv::warpAffine(mask, traced, A, mask.size(), cv::INTER_NEAREST);
      const auto borders = imaging::maskOutlines(traced);
      QVERIFY(!borders.empty());
      drawInTwoPieces(borders.front());
      if (QTest::currentTestFailed()) return;
    }
    QString said;
    fit(&said);  // F9 (and F10)
    if (QTest::currentTestFailed()) return;
    const auto k = w_->caseData();
    const auto shape = k->shapeNodes();
    const auto& rest = k->organ->volume.points;
    const auto& tets = k->organ->volume.tets;
    QCOMPARE(shape.size(), rest.size());
    double smallest = 1e300;
    int below = 0;
    for (const auto& t : tets) {
      Eigen::Matrix3d now, was;
      for (int c = 0; c < 3; ++c)
        now.col(c) = shape[static_cast<std::size_t>(t[c + 1])] - shape[static_cast<std::size_t>(t[0])],
        was.col(c) = rest[static_cast<std::size_t>(t[c + 1])] - rest[static_cast<std::size_t>(t[0])];
      const double J = now.determinant() / was.determinant();
      smallest = std::min(smallest, J);
      below += !(J >= 0.01);
    }
    qInfo("the fitted shape's %zu elements: the smallest at %.3g of its rest volume; %d below 1 %%", tets.size(),
          smallest, below);
    QCOMPARE(below, 0);
    QVERIFY2(!said.contains("inside out") && !said.contains("flat"), qPrintable(said));
    rehearse("a person's contour, none");  // step 7 starts there, stays, and a grasp pulls it 20 mm
  }

  void cleanupTestCase() {
    closeDiscardingChanges(*w_);
    w_.reset();
  }
};

QTEST_MAIN(TestPatientStart)
#include "test_patient_start.moc"
