// Issue 34: the rehearsal on the patient's own organ, in the real main window: the patient liver
// (../shared/data/scikit-surgery/patient-liver/liver.vtk) imported over the real laparoscopic frame with its
// intrinsics, held by three patches of its upper rim picked with the mouse, a contour sketched freehand, the elastic
// fit onto it, then step 7. Without an instrument the organ
// stays where the frame shows it (to 1 px over 5 s), every step shown converged to the scene's tolerance (1e-6) with
// the default method, and a grasp pulled with the mouse moves the tissue with a force in the newton range that matches
// both the constraint multipliers and the force balance at the held nodes; the scissors taken while the jaws hold keep
// the traction, and a cut across the stretched tissue shows its faces in the composited view. Skipped (or failed, with
// REHEARSE_REQUIRE_SHARED=1) when the shared data is absent.
#include "test_support.hpp"
#include "window_support.hpp"

#include "rehearse/ui/composition.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/pages/appearancepage.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <rehearse/app/appearancestep.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QLabel>
#include <QPushButton>
#include <QSignalSpy>
#include <QStandardPaths>
#include <QtTest>

#include <QElapsedTimer>

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <set>

using namespace rehearse;
using ui::MainWindow;

namespace {
// The window's widest width while it lives (a status line's long sentence widened it from 1600 to 1833 px while the
// appearance was estimated; under load it had not yet, and the same drag pulled the tissue 9.7 mm instead of 7.2).
struct WidthWatch : QObject {
  explicit WidthWatch(QWidget* w) : watched(w), widest(w->width()) { w->installEventFilter(this); }
  bool eventFilter(QObject* o, QEvent* e) override {
    if (o == watched && e->type() == QEvent::Resize) widest = std::max(widest, watched->width());
    return false;
  }
  QWidget* watched;
  int widest;
};

// patientLiverOverTheRealFrame, one method per phase of the scenario (what a phase makes, the later ones use). A
// failed QVERIFY returns from its phase: the test checks QTest::currentTestFailed() after each.
struct PatientRehearsal {
  PatientRehearsal(std::unique_ptr<MainWindow>& w, QObject* test) : w_(w), test_(test) {}
  ~PatientRehearsal() { QObject::disconnect(watching); }
  PatientRehearsal(const PatientRehearsal&) = delete;
  PatientRehearsal& operator=(const PatientRehearsal&) = delete;

  std::unique_ptr<MainWindow>& w_;
  QObject* test_;  // the test object: the context of the connection that watches the frames
  ui::FrameView* view = nullptr;
  std::shared_ptr<const app::Case> kept;  // the fitted case
  ui::SimulationPanel* panel = nullptr;
  QLabel* status = nullptr;
  // The frames shown of the fitted organ from the rehearsal's start: how many, how many not converged, the worst
  // relative residual.
  int shown = 0, notConverged = 0;
  double worstResidual = 0;  // of the steps that ended on the relative residual
  double worstEstimate = 0;  // m: of the steps that ended on the accuracy asked (estimated every 10th step)
  int byAccuracy = 0;
  QMetaObject::Connection watching;
  Eigen::Vector2d centre;  // where the grasper bites (frame pixels)
  QPointF a, b;            // the pull, from and to (widget pixels)

  // The panel follows the case: its session for the fitted organ may have started before step 7 opened, and frames
  // of the sessions before it (the unfitted organ) may still be the last shown. Its frames, from here on.
  bool fitted(const std::shared_ptr<const ui::SimulationFrame>& f) const {
    const auto& c = *kept;
    return f && f->organ && f->organ->hasFit() && f->organ->shapeDigest() == c.shapeDigest() &&
           f->organ->pose.t == c.pose.t && f->positions.size() == c.organ->volume.points.size();
  }

  // Waits until the tissue has come to rest (no node moved 0.01 mm in 50 steps, at most 3000 steps): what a pull or a
  // stroke leaves is looked at in its equilibrium, not after a count of steps (which a loaded machine overshoots: the
  // pull's bitten node read 7.22 mm 30 steps after the drag on an idle machine, 9.65 mm with the suite's core shared
  // four ways). Returns the steps it took; the last 50 steps' largest motion (m) in `moved`.
  long comeToRest(double& moved) {
    const long from = panel->lastFrame()->steps;
    moved = 1e9;
    while (moved > 1e-5 && panel->lastFrame()->steps < from + 3000) {
      const auto before = panel->lastFrame();
      if (!waitFor([&] { return panel->lastFrame()->steps >= before->steps + 50; }, 60000)) return -1;
      const auto after = panel->lastFrame();
      if (after->positions.size() != before->positions.size()) continue;  // a cut came in meanwhile
      moved = 0;
      for (std::size_t i = 0; i < after->positions.size(); ++i)
        moved = std::max(moved, (after->positions[i] - before->positions[i]).norm());
    }
    return panel->lastFrame()->steps - from;
  }

  void importTheLiver() {
    // Import, frame and intrinsics through the pages, as an assistant does.
    {
      const QString why = importPatientLiverOverItsFrame(*w_);
      QVERIFY2(why.isEmpty(), qPrintable(why));
    }
    // Drawn through its own surface (20,000 triangles), carried by the tetrahedra (issue 35).
    {
      const auto& organ = *w_->caseData()->organ;
      QVERIFY2(organ.visual, "the liver's own surface was not kept");
      QCOMPARE(organ.visual->triangles.size(), std::size_t(20000));
      QVERIFY(organ.visual->triangles.size() > 5 * organ.surface.size());
      QVERIFY2(w_->statusText().contains("drawn through its own surface (20000 triangles)"),
               qPrintable(w_->statusText()));
    }
  }

  void pickAttachments() {
    // Aligned where the import placed it (in view): the pose accepted as the rigid alignment.
    w_->editCase("Accept the import's placement (test)", [](app::Case& c) { c.hasPose = c.poseAligned = true; });
    view = w_->frameView();
    view->setFocus();
    // Attachments picked with the mouse (H, then a click on the organ over the frame): three patches of 20 mm along
    // the organ's upper rim in the image (against gravity: the smallest image y), where ligaments hold a liver.
    {
      QTest::keyClick(w_.get(), Qt::Key_1, Qt::AltModifier);
      QCOMPARE(w_->step(), ui::Step::Mesh);
      QTest::keyClick(w_.get(), Qt::Key_H);
      QCOMPARE(view->tool(), ui::Tool::Attachments);
      auto* radius = w_->findChild<QDoubleSpinBox*>("attachmentRadius");
      QVERIFY(radius);
      radius->setValue(20);
      const auto k = w_->caseData();
      const cv::Mat1b mask = imaging::renderMask(k->camera, k->pose, k->surfaceView());
      int left = mask.cols, right = -1;
      for (int y = 0; y < mask.rows; ++y)
        for (int x = 0; x < mask.cols; ++x)
          if (mask(y, x)) left = std::min(left, x), right = std::max(right, x);
      QVERIFY(right > left + 100);
      for (double at : {0.2, 0.5, 0.8}) {
        const int x = left + static_cast<int>(at * (right - left));
        int top = 0;
        while (top < mask.rows && !mask(top, x)) ++top;
        const std::size_t before = w_->caseData()->attachments.size();
        QTest::mouseClick(view, Qt::LeftButton, {}, view->toWidget(QPointF(x, top + 25)).toPoint());
        QVERIFY2(w_->caseData()->attachments.size() > before,
                 qPrintable(QStringLiteral("the click at (%1, %2) px attached nothing").arg(x).arg(top + 25)));
      }
    }
  }

  void sketchTheContour() {
    // The assistant's contour, sketched freehand (F) on the frame: the outline of the organ sagged sideways (2 g in
    // the image's x, half of gravity, on these attachments), a deformation the elastic fit has to find.
    {
      const auto k = w_->caseData();
      const simcore::FemModel model =
          simcore::FemModel::build(k->organ->volume, {}, {simcore::MaterialModel::Corotational, 27e3, 0.4, 1000});
      simcore::SimulationSettings load;
      load.gravity = k->pose.R.transpose() * Eigen::Vector3d(0.5 * 9.81, 0, 0);
      simcore::Integrator sag(model, k->attachments, load);
      auto sagged = sag.initialState();
      QVERIFY(sag.solveStatic(sagged).ok);
      SurfaceView deformed = k->surfaceView();
      deformed.vertices = sagged.x.data();
      const auto borders = imaging::maskOutlines(imaging::renderMask(k->camera, k->pose, deformed));
      QVERIFY(!borders.empty());
      QTest::keyClick(w_.get(), Qt::Key_3, Qt::AltModifier);
      QCOMPARE(w_->step(), ui::Step::Contour);
      QTest::keyClick(w_.get(), Qt::Key_F);
      QCOMPARE(view->tool(), ui::Tool::Freehand);
      std::vector<QPoint> stroke;
      for (std::size_t i = 0; i < borders.front().size(); i += 4) {
        const QPoint p = view->toWidget(QPointF(borders.front()[i].x(), borders.front()[i].y())).toPoint();
        if (stroke.empty() || p != stroke.back()) stroke.push_back(p);
      }
      QTest::mousePress(view, Qt::LeftButton, {}, stroke.front());
      for (const QPoint& p : stroke) QTest::mouseMove(view, p);
      QTest::mouseRelease(view, Qt::LeftButton, {}, stroke.back());
      QCOMPARE(w_->caseData()->contour.segments.size(), std::size_t(1));
      QVERIFY(w_->caseData()->contour.segments.front().points.size() >= 20);
    }
  }

  void fitTheLiver() {
    // The elastic fit (Alt+5, F9) onto it.
    const auto aligned = w_->caseData();
    QTest::keyClick(w_.get(), Qt::Key_5, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Elastic);
    QTest::keyClick(w_.get(), Qt::Key_F9);
    QVERIFY(waitFor([&] { return w_->caseData()->hasFit(); }, 300000));
    qInfo("fit: %s", qPrintable(w_->findChild<QLabel*>("fitStatus")->text()));
    shot(*w_, "patient-fit");
    kept = w_->caseData();  // the case from here on (edits replace it)
    const auto& c = *kept;
    double fitMoved = 0;  // how far the fit moved the nodes, in the camera's frame
    for (std::size_t i = 0; i < c.fit->nodes.size(); ++i)
      fitMoved =
          std::max(fitMoved, (c.pose.apply(c.fit->nodes[i]) - aligned->pose.apply(aligned->shapeNodes()[i])).norm());
    qInfo(
        "patient liver: %zu tets, %zu attachment nodes (3 clicks), over the %dx%d frame; the fit moved nodes up to "
        "%.1f mm",
        c.organ->volume.tets.size(), c.attachments.size(), c.frame.cols, c.frame.rows, 1e3 * fitMoved);
    QVERIFY(c.organ->volume.tets.size() > 2500);
    QVERIFY(c.attachments.size() >= 6);
    QVERIFY(fitMoved > 1e-3);  // the fit deformed the organ (the start below is that shape, not the imported one)
  }

  void estimateTheAppearance() {
    // Step 6 on the real frame (Alt+6, F10): the composited view is made with the liver's own surface.
    QTest::keyClick(w_.get(), Qt::Key_6, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Appearance);
    {
      QSignalSpy estimated(w_->appearancePage(), &ui::AppearancePage::estimated);
      QTest::keyClick(w_.get(), Qt::Key_F10);
      QVERIFY(estimated.wait(120000));
      QVERIFY2(estimated.first().at(0).toBool(), qPrintable(estimated.first().at(1).toString()));
    }
    QVERIFY(waitFor([&] { return w_->composition()->ready(); }, 60000));
    QCOMPARE(app::appearanceInputFromCase(*w_->caseData()).triangles.size(), std::size_t(20000));
    qInfo("step 6 on the real frame: %s", w_->caseData()->appearance->status.c_str());
  }

  void startTheRehearsal() {
    // The grasp, pull and cut below were designed with the liver hung on its three rim patches alone, gravity down the
    // image (this frame's laparoscope looks across the liver): set so on the panel, as an assistant would. The
    // defaults (into the scene, carried by the tissue around it) are taken again for the last part, with no held node.
    w_->simulationPanel()->findChild<QComboBox*>("simGravity")->setCurrentIndex(0);
    w_->simulationPanel()->findChild<QDoubleSpinBox*>("simSupport")->setValue(0);
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Rehearse);
    panel = w_->simulationPanel();
    status = panel->findChild<QLabel*>("simStatus");
    // (The gravity chosen above is a new start: its session's frames.)
    QVERIFY2(waitFor(
                 [&] {
                   return panel->session() && panel->session()->setup().settings.gravity.y() > 9 &&
                          panel->session()->setup().supports.empty() && !panel->startSentence().isEmpty() &&
                          fitted(panel->lastFrame()) && panel->lastFrame()->gravity.y() > 9;
                 },
                 180000),
             qPrintable(status->text()));
    QVERIFY2(panel->startSentence().contains("starts where the frame shows it"), qPrintable(panel->startSentence()));
    qInfo("%s", qPrintable(panel->startSentence()));
    QVERIFY(panel->isPlaying());
  }

  void stayWithoutAnInstrument() {
    const auto& c = *kept;
    QString method;
    watching = QObject::connect(panel, &ui::SimulationPanel::frameShown, test_, [this] {
      const auto f = panel->lastFrame();
      if (!fitted(f) || f->steps == 0) return;
      ++shown;
      notConverged += f->report.outcome != simcore::StepStatus::Converged;
      // Converged: on the relative residual, or on the accuracy asked in millimetres (issue 64; the window's 0.05 mm).
      if (f->report.withinAccuracy) {
        ++byAccuracy;
        if (std::isfinite(f->report.errorPosition)) worstEstimate = std::max(worstEstimate, f->report.errorPosition);
      } else {
        worstResidual = std::max(worstResidual, f->report.residual);
      }
    });
    // 5 s without an instrument: the organ stays where the frame shows it.
    const long from = panel->lastFrame()->steps;
    double px = 0;
    QVERIFY(waitFor(
        [&] {
          const auto f = panel->lastFrame();
          const auto shape = c.shapeNodes();
          for (std::size_t i = 0; i < f->positions.size() && i < shape.size(); ++i)
            px = std::max(px, (c.camera.project(f->positions[i]) - c.camera.project(c.pose.apply(shape[i]))).norm());
          return f->steps >= from + 500;
        },
        300000));
    qInfo(
        "%ld steps without an instrument: the nodes at most %.3f px from the registered shape; %d frames shown, %d "
        "not converged, worst relative residual %.2e (tolerance %.0e)",
        panel->lastFrame()->steps - from, px, shown, notConverged, worstResidual, panel->lastFrame()->report.tolerance);
    QVERIFY(px <= 1.0);
    QVERIFY(shown > 20);
    QCOMPARE(notConverged, 0);
    qInfo("%d of the shown steps ended on the accuracy asked, their estimates at most %.3g mm", byAccuracy,
          1e3 * worstEstimate);
    QVERIFY(worstResidual <= 1e-6 * (1 + 1e-9));  // converged: residual <= tolerance x scale, within round-off
    QVERIFY(worstEstimate <= panel->session()->setup().settings.accuracyPosition);
  }

  void graspAndPull() {
    const auto& c = *kept;
    // The grasper, pulled upwards with the mouse by 12 px of the view (48 px of the frame: 13 mm at the organ).
    QTest::keyClick(w_.get(), Qt::Key_R);
    QCOMPARE(view->tool(), ui::Tool::Grasp);
    // On a surface node facing the camera near the organ's centre in the image (the grasp holds the nodes within 6 mm
    // of the tip, and this mesh's surface nodes are about 1 cm apart: between them the jaws close on nothing).
    const Eigen::Vector2d middle = c.camera.project(c.pose.apply(c.organ->centreOfGravity));
    centre = middle;
    {
      const auto shape = c.shapeNodes();
      std::set<int> surface;
      for (const auto& t : c.organ->surface)
        for (int n : t) surface.insert(n);
      double best = 1e300;
      for (int n : surface) {
        const Eigen::Vector3d p = c.pose.apply(shape[static_cast<std::size_t>(n)]);
        const Eigen::Vector2d q = c.camera.project(p);
        if ((q - middle).norm() > 60) continue;
        // Nearest the camera among those near the middle: on the visible side.
        const double score = p.z() + 1e-4 * (q - middle).norm();
        if (score < best) best = score, centre = q;
      }
    }
    a = view->toWidget(QPointF(centre.x(), centre.y()));
    // 25 px of the frame up (7 mm at the bite's depth), whatever the view's scale: the stroke below is placed in the
    // frame's pixels too. (Once 12 px of the view: 24.9 px of the frame in a window a status line had widened to 1833
    // px, 33.3 px in one of 1600.)
    b = view->toWidget(QPointF(centre.x(), centre.y() - 25));
    QCOMPARE(w_->width(), 1600);  // nothing said so far made the window wider
    qInfo("the pull: %.1f px of the view, 25 px of the frame; the view %dx%d, the window %dx%d", (b - a).manhattanLength(),
          view->width(), view->height(), w_->width(), w_->height());
    QTest::mousePress(view, Qt::LeftButton, {}, a.toPoint());
    const bool bit = waitFor([&] { return !panel->lastFrame()->tool.held.empty(); }, 30000);
    QVERIFY2(bit, qPrintable(QStringLiteral("pressed at (%1, %2) px of the frame").arg(centre.x()).arg(centre.y())));
    const std::vector<Eigen::Vector3d> before = panel->lastFrame()->positions;
    const int held = panel->lastFrame()->tool.held.front();
    for (int i = 1; i <= 8; ++i) {
      QTest::mouseMove(view, (a + (b - a) * (i / 8.0)).toPoint());
      const long at = panel->lastFrame()->steps;
      QVERIFY(waitFor([&] { return panel->lastFrame()->steps >= at + 4; }, 60000));
    }
    {
      double still = 0;
      const long took = comeToRest(still);
      qInfo("the tissue came to rest %ld steps after the pull (%.4f mm in the last 50 steps)", took, 1e3 * still);
      QVERIFY2(took >= 0 && still <= 1e-5, qPrintable(QString::number(1e3 * still)));
    }
    QVERIFY2(!panel->lastFrame()->tool.held.empty(), qPrintable(panel->lastFrame()->message));
    const double moved =
        1e3 *
        (panel->lastFrame()->positions[static_cast<std::size_t>(held)] - before[static_cast<std::size_t>(held)]).norm();
    // The force the page shows is the step's constraint multipliers; their jaws' share is the force balance at the
    // held nodes (the elastic forces of the state, another route).
    shot(*w_, "patient-pulled");
    panel->pause();
    QTest::qWait(300);
    const auto* session = panel->session();
    const auto snap = session->snapshot();
    const simcore::SimulationState state = session->state();
    const auto body = simcore::makeFemBody(session->setup());
    const Eigen::Vector3d balance =
        body->appliedForce(snap->tool.held, state, state.v, session->setup().settings.timeStep);
    qInfo(
        "pulled: the bitten node moved %.2f mm; %zu nodes held; tool force %.3f N (jaws %.3f N), force balance at "
        "the held nodes %.3f N; %s; every shown step converged: %d of %d",
        moved, snap->tool.held.size(), snap->tool.force.norm(), snap->tool.graspForce.norm(), balance.norm(),
        simcore::toString(session->setup().settings.method).c_str(), shown - notConverged, shown);
    QVERIFY(moved > 2.0);
    QVERIFY(snap->tool.graspForce.norm() > 0.05 && snap->tool.graspForce.norm() < 50);  // the newton range
    QVERIFY((balance - snap->tool.graspForce).norm() < 0.05 * snap->tool.graspForce.norm());
    QVERIFY(session->setup().settings.method == simcore::kInteractiveMethod);
    QCOMPARE(notConverged, 0);
    QVERIFY(worstResidual <= 1e-6 * (1 + 1e-9));
    QVERIFY(worstEstimate <= session->setup().settings.accuracyPosition);
    // The composited view follows the pull through the liver's own surface: the view shows the composition of the
    // last snapshot, and the organ's pixels changed around the bitten node.
    QVERIFY(w_->showingComposited());
    QTest::qWait(200);  // the last snapshot reaches the view
    w_->composition()->waitForIdle();
    const QImage pulledView = w_->composition()->composeNow(panel->lastFrame()->positions);
    QVERIFY(!pulledView.isNull());
    QCOMPARE(w_->frameView()->shownFrame(), pulledView);
    {
      const cv::Mat3b now = toMat(pulledView), atRest = toMat(w_->composition()->composeNow());
      cv::Mat diff, changed;
      cv::absdiff(now, atRest, diff);
      cv::inRange(diff, cv::Scalar(10, 10, 10), cv::Scalar(255, 255, 255), changed);
      qInfo("composited view after the pull: %d px changed by 10 levels or more", cv::countNonZero(changed));
      QVERIFY(cv::countNonZero(changed) > 200);
    }
    shot(*w_, "patient-pulled-composited");
    panel->play();
  }

  void cutWhileHolding() {
    const auto& c = *kept;
    // Grasp, pull, cut (issue 35): the scissors taken while the button still holds the jaws closed; the button comes up
    // on the scissors, so the jaws keep the traction. A stroke across the stretched tissue below the jaws opens an
    // incision whose cut faces the composited view shows (the cut mesh's boundary, faces in the parenchyma's colour).
    QTest::keyClick(w_.get(), Qt::Key_B);
    QCOMPARE(view->tool(), ui::Tool::Scissors);
    QTest::mouseRelease(view, Qt::LeftButton, {}, b.toPoint());
    QVERIFY(panel->lastFrame()->tool.jawClosed && !panel->lastFrame()->tool.held.empty());
    // 16 px of the frame (4 mm) above the jaws, 90 px (25 mm) either side: the blade must cross two of this mesh's
    // elements (about 1 cm) before it cuts. The jaws hold one node, so the traction opens the incision a little.
    const QPointF strokeFrom = view->toWidget(QPointF(centre.x() + 90, centre.y() - 16)),
                  strokeTo = view->toWidget(QPointF(centre.x() - 90, centre.y() - 16));
    SessionHeard heard(panel, 2000);  // every frame's sentence and events, none missed between the waits
    QTest::mousePress(view, Qt::LeftButton, {}, strokeFrom.toPoint());
    QVERIFY(waitFor([&] { return panel->lastFrame()->tool.cutting; }, 30000));
    for (int i = 1; i <= 20; ++i) {
      QTest::mouseMove(view, (strokeFrom + (strokeTo - strokeFrom) * (i / 20.0)).toPoint());
      const long at = panel->lastFrame()->steps;
      QVERIFY(waitFor([&] { return panel->lastFrame()->steps >= at + 3; }, 60000));
    }
    QTest::mouseRelease(view, Qt::LeftButton, {}, strokeTo.toPoint());
    // The stroke's sentence is said once all of it is in: the cut the blade made while an earlier cut's body was being
    // built comes in after that one (when depends on the machine's load; CI once looked 40 steps after the first cut
    // came in and saw 8 cut faces of the stroke's 12).
    const auto said = [&] { return heard.lines.join(" | "); };
    QVERIFY2(waitFor([&] { return said().contains("The cut is done") || said().contains("Nothing was cut"); }, 180000),
             qPrintable(said()));
    QVERIFY2(!said().contains("Nothing was cut") && panel->lastFrame()->surface &&
                 panel->lastFrame()->surface->cutCount > 0,
             qPrintable(said()));
    for (const QString& line : heard.lines)
      if (line.contains("The cut is done")) qInfo("the stroke: %s", qPrintable(line));
    {
      double moved = 0;
      const long took = comeToRest(moved);
      qInfo("the tissue came to rest %ld steps after the stroke's sentence (%.4f mm in the last 50 steps)", took,
            1e3 * moved);
      QVERIFY2(took >= 0 && moved <= 1e-5, qPrintable(QString::number(1e3 * moved)));
    }
    QVERIFY(panel->lastFrame()->tool.jawClosed && !panel->lastFrame()->tool.held.empty());
    panel->pause();
    QTest::qWait(300);
    w_->composition()->waitForIdle();
    QVERIFY2(w_->showingComposited(), qPrintable(w_->viewModeText()));
    {
      const auto f = panel->lastFrame();
      const cv::Mat1b cutSeen = cutFacesSeen(c.camera, f->positions, *f->surface).cut;
      const int seen = cv::countNonZero(cutSeen);
      qInfo("grasp-pull-cut: %zu cut faces of %zu, seen on %d px of the frame; %s", f->surface->cutCount,
            f->surface->triangles.size(), seen, qPrintable(w_->composition()->cutSentence()));
      // The incision opens under the stroke (the shaft goes through the surface under the cursor): the cut faces seen
      // lie along the drawn line, in frame pixels (the line 16 px above the jaws, 90 px either side).
      std::vector<double> off;
      for (int y = 0; y < cutSeen.rows; ++y)
        for (int x = 0; x < cutSeen.cols; ++x)
          if (cutSeen(y, x)) {
            const double along = std::clamp(static_cast<double>(x) + 0.5, centre.x() - 90, centre.x() + 90);
            off.push_back(std::hypot(x + 0.5 - along, y + 0.5 - (centre.y() - 16)));
          }
      std::sort(off.begin(), off.end());
      const double median = off.empty() ? 1e9 : off[off.size() / 2], worst = off.empty() ? 1e9 : off.back();
      qInfo("the cut faces seen lie a median %.1f px from the drawn line, at most %.1f px", median, worst);
      // (The line crosses the lobe's lower edge, where the surface the camera sees steps 50 mm nearer: the shaft
      // follows the near surface there, and the incision opens in it, 60 px of cut faces on this frame.)
      QVERIFY2(seen >= 30, qPrintable(QString::number(seen)));
      QVERIFY2(median <= 12, qPrintable(QString::number(median)));
      const QImage composed = w_->composition()->composeNow(f->positions, f->surface);
      QCOMPARE(w_->frameView()->shownFrame(), composed);
      // The composited view around the incision (the frame's pixels, 3x), for the README.
      if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty()) {
        const cv::Rect box = (cv::boundingRect(cutSeen) + cv::Size(160, 100)) - cv::Point(80, 50);
        cv::Mat3b detail;
        cv::resize(toMat(composed)(box & cv::Rect(0, 0, cutSeen.cols, cutSeen.rows)), detail, {}, 3, 3,
                   cv::INTER_CUBIC);
        cv::imwrite((dir + "/patient-grasp-pull-cut-detail.png").toStdString(), detail);
      }
    }
    shot(*w_, "patient-grasp-pull-cut");
    QTest::keyClick(w_.get(), Qt::Key_R);
    QTest::keyClick(view, Qt::Key_Space);  // the jaws let go
    panel->play();
    QVERIFY(waitFor([&] { return !panel->lastFrame()->tool.jawClosed; }));
  }

  void nothingHeld() {
    const auto& c = *kept;
    // Issue 61: no held node at all (Release All on the mesh step, then back to step 7): the tissue around the organ
    // carries it (the default support, gravity into the scene), so it starts where the frame shows it and stays.
    // (Each of these starts the organ again: the cut rehearsal before is asked about, and discarded.)
    panel->findChild<QComboBox*>("simGravity")->setCurrentIndex(1);
    QVERIFY(discardTheRehearsalIfAsked(*w_));
    panel->findChild<QDoubleSpinBox*>("simSupport")->setValue(100);  // Pa/mm, the default
    QVERIFY(discardTheRehearsalIfAsked(*w_));
    // Gravity is the case's stated choice (saved with it, undoable under its own name).
    QCOMPARE(w_->caseData()->material.gravity, app::GravityChoice::IntoTheScene);
    QTest::keyClick(w_.get(), Qt::Key_1, Qt::AltModifier);
    auto* release = w_->findChild<QPushButton*>("clearAttachments");
    QVERIFY(release);
    QTest::mouseClick(release, Qt::LeftButton);
    QVERIFY(discardTheRehearsalIfAsked(*w_));  // (the pull before may have torn it)
    QVERIFY(w_->caseData()->attachments.empty());
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    auto unheld = [&](const std::shared_ptr<const ui::SimulationFrame>& f) {
      return fitted(f) && f->organ->attachments.empty() && f->steps > 0;
    };
    panel->play();
    QVERIFY2(waitFor([&] { return unheld(panel->lastFrame()); }, 180000), qPrintable(status->text()));
    qInfo("no held node: %s", qPrintable(panel->startSentence()));
    QVERIFY2(panel->startSentence().contains("starts where the frame shows it") &&
                 panel->startSentence().contains("the tissue around it"),
             qPrintable(panel->startSentence()));
    QVERIFY(panel->lastFrame()->supports && panel->lastFrame()->supports->size() > 50);  // drawn in the 3D view
    qInfo("carried by the tissue around it at %zu nodes", panel->lastFrame()->supports->size());
    {
      const long at = panel->lastFrame()->steps;
      double far = 0;
      int unconverged = 0;
      const auto shape = c.shapeNodes();
      QVERIFY(waitFor(
          [&] {
            const auto f = panel->lastFrame();
            unconverged += f->report.outcome != simcore::StepStatus::Converged;
            for (std::size_t i = 0; i < f->positions.size() && i < shape.size(); ++i)
              far =
                  std::max(far, (c.camera.project(f->positions[i]) - c.camera.project(c.pose.apply(shape[i]))).norm());
            return f->steps >= at + 300;
          },
          300000));
      qInfo(
          "no held node, %ld steps: the nodes at most %.3f px from the registered shape; %d shown steps not converged",
          panel->lastFrame()->steps - at, far, unconverged);
      QVERIFY(far <= 1.0);
      QCOMPARE(unconverged, 0);
    }
    shot(*w_, "patient-unheld");
  }
};
}  // namespace

class TestPatientRehearsal : public QObject {
  Q_OBJECT
  std::unique_ptr<MainWindow> w_;
  std::unique_ptr<WidthWatch> widths;

 private slots:
  void initTestCase() {
    QCoreApplication::setOrganizationName("RehearsePatientRehearsalTest");
    MainWindow::setRenderer(MainWindow::Renderer::Software);
    QVERIFY(openPhantomCase(w_));
    widths = std::make_unique<WidthWatch>(w_.get());
  }

  void patientLiverOverTheRealFrame() {
    REQUIRE_SHARED("scikit-surgery/laparoscopy-liver-frame.jpg");
    REQUIRE_SHARED("scikit-surgery/patient-liver/liver.vtk");
    PatientRehearsal s(w_, this);
    s.importTheLiver();
    if (QTest::currentTestFailed()) return;
    s.pickAttachments();
    if (QTest::currentTestFailed()) return;
    s.sketchTheContour();
    if (QTest::currentTestFailed()) return;
    s.fitTheLiver();
    if (QTest::currentTestFailed()) return;
    s.estimateTheAppearance();
    if (QTest::currentTestFailed()) return;
    s.startTheRehearsal();
    if (QTest::currentTestFailed()) return;
    s.stayWithoutAnInstrument();
    if (QTest::currentTestFailed()) return;
    s.graspAndPull();
    if (QTest::currentTestFailed()) return;
    s.cutWhileHolding();
    if (QTest::currentTestFailed()) return;
    s.nothingHeld();
    if (QTest::currentTestFailed()) return;
    // Nothing the window said made it wider than the person made it.
    qInfo("the window: %d px wide, at most %d px", w_->width(), widths->widest);
    QCOMPARE(widths->widest, 1600);
  }

  void cleanupTestCase() {
    closeDiscardingChanges(*w_);
    w_.reset();
  }
};

QTEST_MAIN(TestPatientRehearsal)
#include "test_patient_rehearsal.moc"
