// The appearance suite's slots with the instruments and after (test_appearance_gui.hpp declares them, in their
// order): clips, a cut and the cautery; a tear; the view modes; a stale estimate; Esc; a refused pose; the estimate
// saved and composited again after reopening.
#include "test_appearance_gui.hpp"

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

#include <QMessageBox>
#include <QDir>
#include <QDropEvent>
#include <QTimer>
#include <QFile>
#include <QUrl>
#include <QMimeData>
#include <QPointer>
#include <QPushButton>
#include <QAction>
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

#include <functional>

using namespace rehearse;
using ui::MainWindow;

namespace {
// A point of the registered organ's box on the frame (fx, fy from 0 to 1 across it), in the frame view's pixels.
std::function<QPoint(double, double)> organBoxPoint(ui::FrameView* view, const app::Case& c) {
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (const auto& p : c.shapeNodes()) {
    const Eigen::Vector2d q = c.camera.project(c.pose.apply(p));
    x0 = std::min(x0, q.x()), x1 = std::max(x1, q.x()), y0 = std::min(y0, q.y()), y1 = std::max(y1, q.y());
  }
  return [=](double fx, double fy) {
    return view->toWidget(QPointF(x0 + fx * (x1 - x0), y0 + fy * (y1 - y0))).toPoint();
  };
}

// The cautery hook pressed at `from`, dragged to `to` and released, slowly: tissue burns after 0.2 s under the powered
// tip (at 4 steps a notch the hook's dwell was 0.18-0.2 s, and "The hook burnt nothing: no spot of tissue was heated
// more than 0.18 s ..." came whenever the window followed the mouse at once). False when its power did not come on, the
// simulation stalled or the power did not go off.
bool dragTheHook(QWidget* view, ui::SimulationPanel* panel, QPoint from, QPoint to,
                 const std::function<bool(int)>& stepsOn) {
  QTest::mousePress(view, Qt::LeftButton, {}, from);
  if (!waitFor([&] { return panel->lastFrame()->field.energy; })) return false;
  for (int i = 1; i <= 10; ++i) {
    QTest::mouseMove(view, from + (to - from) * (i / 10.0));
    if (!stepsOn(8)) return false;
  }
  QTest::mouseRelease(view, Qt::LeftButton, {}, to);
  return waitFor([&] { return !panel->lastFrame()->field.energy; });
}
// clipCutAndCauterize on the built-in case, one method per phase of the scenario (what a phase finds, the later ones
// use). A failed QVERIFY returns from its phase: the test checks QTest::currentTestFailed() after each.
struct ClipCutCauterize {
  ClipCutCauterize(std::unique_ptr<MainWindow>& w, ui::SimulationPanel* panel, ui::FrameView* frameView,
                   const app::Case& theCase, std::function<bool(int)> steps)
      : w_(w), panel_(panel), stepsOn(std::move(steps)), view(frameView), c(theCase), truth(*theCase.groundTruth) {}

  std::unique_ptr<MainWindow>& w_;
  ui::SimulationPanel* panel_;
  std::function<bool(int)> stepsOn;  // the test's: true once the simulation has taken `n` more steps
  ui::FrameView* view;
  const app::Case& c;
  const app::GroundTruth& truth;
  std::vector<std::pair<double, std::size_t>> branches;  // (depth under the surface, branch), shallowest first
  std::size_t first = 0, second = 0;                     // the branch clipped and cut, the one cut beyond its clip
  SessionHeard listening{panel_, 100000};  // what the session said and which events it raised during a stroke
  QStringList& heard = listening.lines;
  ActionPauses pauses{QStringLiteral("the built-in phantom")};  // the window's longest pause in each action

  // Where the model point a fraction `t` along branch `k`'s centre line shows, in the view's widget pixels.
  QPoint pixelOn(std::size_t k, double t) const {
    const auto& [a, b] = truth.vesselAxes[k];
    const Eigen::Vector2d q = c.camera.project(c.pose.apply(a + t * (b - a)));
    return view->toWidget(QPointF(q.x(), q.y())).toPoint();
  }

  // A stroke across branch `k` at `t`, `half` pixels each side of it.
  std::pair<QPoint, QPoint> across(std::size_t k, double t, double half) const {
    const QPointF a = pixelOn(k, t - 0.05), b = pixelOn(k, t + 0.05);
    QPointF n(-(b - a).y(), (b - a).x());
    n /= std::max(1e-9, std::hypot(n.x(), n.y()));
    const QPointF m = pixelOn(k, t);
    return std::make_pair((m - half * n).toPoint(), (m + half * n).toPoint());
  }

  // The scissors (B) across branch `k` at `t`, the blade `notches` wheel notches deeper, stepping as it goes.
  void cutAcross(std::size_t k, double t, int notches = 7) {
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
    const auto strokes = {std::make_pair(firstOnOrgan(a0), b0), std::make_pair(firstOnOrgan(b0), a0)};
    pauses.start();
    for (const auto& [from, to] : strokes) {
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
    pauses.stop("cut");
    for (const auto& line : heard) qInfo("  %s", qPrintable(line));
  }

  // The branches deep enough for the clip applier, shallowest first.
  void findTheBranches() {
    // How deep each branch lies under the surface the camera sees (its centre line's front, at its middle).
    const auto f0 = panel_->lastFrame();
    std::vector<double> xyz;
    for (const auto& p : f0->positions) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    const rehearse::SurfaceView sv{xyz.data(), f0->positions.size(), c.organ->surface.front().data(),
                                   c.organ->surface.size()};
    const auto g = imaging::surfaceGeometry(c.camera, rehearse::Pose{}, sv);
    auto depthBelow = [&](const Eigen::Vector3d& model, double radius) {
      const Eigen::Vector3d p = c.pose.apply(model);
      const Eigen::Vector2d q = c.camera.project(p);
      const int x = static_cast<int>(std::lround(q.x())), y = static_cast<int>(std::lround(q.y()));
      if (x < 0 || y < 0 || x >= g.triangle.cols || y >= g.triangle.rows || g.triangle(y, x) < 0) return 1e9;
      return p.z() - radius - g.position(y, x)[2];
    };
    branches.clear();
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
  }

  // Two clips (U) across the shallowest branch, each spanning it.
  void clipTheBranch() {
    // The shallowest branch: two clips on it, a cut between them, a burnt line, and a cut beyond the second clip (the
    // stump of the piece without a clip bleeds).
    first = second = branches[0].second;
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
      auto* status = w_->rehearsePage()->findChild<QLabel*>("rehearseStatus");
      const QPoint at = pixelOn(first, t);
      pauses.start();
      QTest::mouseClick(view, Qt::LeftButton, {}, at);
      QVERIFY(waitFor([&] { return panel_->lastFrame()->field.clips.size() == before + 1; }));
      waitFor([&] { return status->text().contains("clip") && status->text() != said; }, 3000);
      pauses.stop("clip");
      said = status->text();
      qInfo("clip at %.2f of the branch: %s", t, qPrintable(said));
    }
    for (const auto& clip : panel_->lastFrame()->field.clips) {
      qInfo("clip on label %d: %zu nodes, %s", clip.label, clip.nodes.size() + 1,
            clip.spans ? "spans" : "does not span");
      QVERIFY(clip.spans);
    }
    // Closed (0.1 s), the clips hold and the steps converge again: a clip the phantom's coarse elements could not
    // close as asked held every step after it back (the inversion guard), a second each, never converged; now it
    // stays as far as the tissue let it, and says so.
    // (A step may still end inexact now and then under load, its factor arriving late: one converged is asked for,
    // where before none did.)
    QVERIFY(stepsOn(10));
    QVERIFY2(waitFor([&] { return panel_->lastFrame()->report.outcome == simcore::StepStatus::Converged; }, 30000),
             simcore::statusSentence(panel_->lastFrame()->report).c_str());
  }

  void cutBetweenTheClips() {
    // The scissors across the branch between them.
    cutAcross(first, 0.57);
    pauses.start();
    QVERIFY(waitFor([&] { return !panel_->lastFrame()->field.bleeds.empty(); }, 60000));
    QVERIFY(stepsOn(5));  // (steps with clips are slow: 20 took over a minute under a parallel build)
    pauses.stop("cut");
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
  }

  void burnALine() {
    // The cautery hook: a line burnt along the organ below the clipped branch.
    QTest::keyClick(w_.get(), Qt::Key_J);
    QCOMPARE(view->tool(), ui::Tool::Cautery);
    {
      const QPoint from = pixelOn(first, 0.68), to = across(first, 0.68, 30).second;  // from over the vessel sideways
      pauses.start();
      QVERIFY(dragTheHook(view, panel_, from, to, stepsOn));
      QVERIFY(stepsOn(10));
      // The burnt elements' body is built on the second thread and comes in when built (one change at a time: after a
      // cut still being built, later): under a loaded CI machine that took longer than the 10 steps above.
      auto burntNow = [&] {
        const auto f = panel_->lastFrame();
        return f->labels ? std::count_if(f->labels->begin(), f->labels->end(), simcore::isBurnt) : 0L;
      };
      QVERIFY2(waitFor([&] { return burntNow() > 0; }, 30000), qPrintable(heard.join(" | ")));
      QVERIFY(stepsOn(5));
      pauses.stop("cautery");
      const auto f = panel_->lastFrame();
      const long burnt = burntNow();
      qInfo("cautery: %ld elements burnt, energy on tissue %.2f s", burnt, f->field.energyTime);
      QVERIFY(burnt > 0);
    }
  }

  void cutBeyondTheClips() {
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
    pauses.start();
    QVERIFY2(waitFor([&] { return panel_->lastFrame()->surface->cutCount > cutFacesBefore; }, 60000),
             qPrintable(heard.join(" | ")));
    QVERIFY(stepsOn(5));
    pauses.stop("cut");
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
  }

  // Paused, the screenshots; Esc and a reset.
  void pauseAndShoot() {
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
  }

  // Closing the window over this rehearsal: its cuts, its burn and its clips are not the case's (saving does not keep
  // them, a recording would), so the window asks before it ends them and says what would be lost; Cancel keeps them.
  // (Ctrl+Q after a cut quit without a word.) After Reset there is nothing left to ask about.
  void closingAsksAboutTheRehearsal() {
    const QString unkept = panel_->unkeptWork();
    QVERIFY2(unkept.contains("cut or torn") && unkept.contains("burnt") && unkept.contains("clip"), qPrintable(unkept));
    w_->close();
    QMessageBox* box = nullptr;
    QVERIFY(waitFor(
        [&] {
          box = w_->findChild<QMessageBox*>("unkeptRehearsalBox");
          if (!box) box = w_->findChild<QMessageBox*>("unsavedChangesBox");  // (the case has unsaved edits too)
          return box && box->isVisible();
        },
        10000));
    const QString said = box->text() + " " + box->informativeText(), name = box->objectName();
    qInfo("asked (%s): %s", qPrintable(name), qPrintable(said));
    QVERIFY2(said.contains(unkept) && said.contains("recording"), qPrintable(said));
    QTest::mouseClick(box->button(QMessageBox::Cancel), Qt::LeftButton);
    QVERIFY(waitFor([&] { return !w_->findChild<QMessageBox*>(name); }, 10000));
    QVERIFY(w_->isVisible());
    w_->activateWindow();  // (the window manager gives it back after a box; offscreen has none)
    QVERIFY(QTest::qWaitForWindowActive(w_.get()));
    QCOMPARE(panel_->unkeptWork(), unkept);
    // The reply to Cancel leaves the status bar after a while (it stayed there until the next message); the Messages
    // panel keeps it.
    const QString cancelled = name == "unsavedChangesBox"
                                  ? QStringLiteral("Cancelled: the case and its unsaved changes stay open.")
                                  : QStringLiteral("Cancelled: the rehearsal stays as it is.");
    // It is the status bar's message over whatever hint showed (said into the case's line, a tool's hint hid it).
    QCOMPARE(w_->statusBar()->currentMessage(), cancelled);
    QVERIFY(waitFor([&] { return w_->statusBar()->currentMessage() != cancelled; },
                    ui::MainWindow::kBriefMessageMs + 10000));
    QVERIFY(w_->statusText() != cancelled);
    QVERIFY(w_->messageLog().join('\n').contains(cancelled));
    // Reset ends the rehearsal too: Shift+F5 asks first (it discarded the cuts without a word); Cancel keeps them, and
    // the panel's Reset button, answered Reset, takes the organ back to rest. Then nothing is left to ask about.
    auto resetBox = [&] {
      QMessageBox* b = nullptr;
      waitFor(
          [&] {
            b = w_->findChild<QMessageBox*>("resetRehearsalBox");
            return b && b->isVisible();
          },
          10000);
      return b && b->isVisible() ? b : nullptr;
    };
    QTest::keyClick(w_.get(), Qt::Key_F5, Qt::ShiftModifier);
    box = resetBox();
    QVERIFY(box);
    QVERIFY2(box->text().contains(unkept) && box->informativeText().contains("recording"), qPrintable(box->text()));
    QTest::mouseClick(box->button(QMessageBox::Cancel), Qt::LeftButton);
    QVERIFY(waitFor([&] { return !w_->findChild<QMessageBox*>("resetRehearsalBox"); }, 10000));
    QCOMPARE(panel_->unkeptWork(), unkept);
    auto* resetButton = panel_->findChild<QPushButton*>("simReset");
    QVERIFY(resetButton && resetButton->isEnabled());
    QTest::mouseClick(resetButton, Qt::LeftButton);
    box = resetBox();
    QVERIFY(box);
    QTest::mouseClick(box->button(QMessageBox::Reset), Qt::LeftButton);
    QVERIFY(waitFor([&] { return panel_->lastFrame() && panel_->unkeptWork().isEmpty(); }, 20000));
    w_->activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(w_.get()));
    QTest::keyClick(w_.get(), Qt::Key_F5, Qt::ShiftModifier);  // nothing to ask about now
    QTest::qWait(300);
    QVERIFY(!w_->findChild<QMessageBox*>("resetRehearsalBox"));
  }
};
}  // namespace

// Issue 36: the other instruments with the mouse on the built-in case, composited. The clip applier (U) closes two
// clips across the shallowest vessel branch under the surface, the scissors (B) cut between them (the vessel's
// stumps are found and neither bleeds), the cautery hook (J) burns a line along the organ (its elements relabelled
// burnt, drawn whitened), and the scissors cut another branch without clips: it bleeds, the loss grows, and the blood
// is drawn over the composited view.
void TestAppearanceGui::clipCutAndCauterize() {
  QVERIFY(rehearseFromRest());
  auto* view = w_->frameView();
  const auto& c = *w_->caseData();
  QVERIFY(c.groundTruth);
  ClipCutCauterize s(w_, panel_, view, c, [this](int n) { return stepsOn(n); });
  s.findTheBranches();
  if (QTest::currentTestFailed()) return;
  s.clipTheBranch();
  if (QTest::currentTestFailed()) return;
  s.cutBetweenTheClips();
  if (QTest::currentTestFailed()) return;
  s.burnALine();
  if (QTest::currentTestFailed()) return;
  s.cutBeyondTheClips();
  if (QTest::currentTestFailed()) return;
  s.pauseAndShoot();
  if (QTest::currentTestFailed()) return;
  s.closingAsksAboutTheRehearsal();
}

// Tearing with the mouse: the Simulation panel's "Tears at" set to 15 % strain, the grasper bites the organ and drags
// it far down the frame until the tissue tears (the mesh changes without a blade; the status says what tore and at
// what strain, the page counts it), then lets go. Screenshot docs/step7-tear.png.
void TestAppearanceGui::graspPullUntilItTears() {
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
  const auto widget = organBoxPoint(view, c);
  QTest::keyClick(w_.get(), Qt::Key_R);
  QCOMPARE(view->tool(), ui::Tool::Grasp);
  const std::size_t nodes = panel_->lastFrame()->positions.size();
  const QPoint from = widget(0.3, 0.6);
  ActionPauses pauses(QStringLiteral("the built-in phantom"));
  pauses.start();
  QTest::mousePress(view, Qt::LeftButton, {}, from);
  QVERIFY(waitFor([&] { return !panel_->lastFrame()->tool.held.empty(); }));
  QVERIFY(stepsOn(3));
  pauses.stop("grasp");
  auto* status = w_->rehearsePage()->findChild<QLabel*>("rehearseStatus");
  QString tore;
  // What tore, as the page says it: seen on every frame shown (under load a later frame's status replaced the
  // tear's before a poll of the label saw it).
  const auto watching = connect(panel_, &ui::SimulationPanel::frameShown, this, [&] {
    if (tore.isEmpty() && status->text().contains("tore")) tore = status->text();
  });
  const auto unwatch = qScopeGuard([&] { disconnect(watching); });
  QPoint last = from;
  pauses.start();
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
  QVERIFY(
      waitFor([&] { return w_->rehearsePage()->findChild<QLabel*>("rehearseForce")->text().contains("TORN"); }, 10000));
  QVERIFY(stepsOn(10));
  pauses.stop("pull and tear");
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

void TestAppearanceGui::viewModesWithTheKeyboard() {
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
void TestAppearanceGui::movedOrganMakesItStale() {
  const int width = w_->width(), least = w_->minimumSizeHint().width();
  // The tear before (graspPullUntilItTears) is not kept: moving the organ ends that rehearsal, asked first (Discard).
  QVERIFY(!panel_->unkeptWork().isEmpty());
  w_->editCase("Move (test)", [](app::Case& c) { c.pose.t.x() += 0.005; });
  QMessageBox* box = nullptr;
  QVERIFY(waitFor([&] { return (box = w_->findChild<QMessageBox*>("endRehearsalBox")) && box->isVisible(); }, 10000));
  QVERIFY2(box->text().contains("Move (test)"), qPrintable(box->text()));
  QTest::mouseClick(box->button(QMessageBox::Discard), Qt::LeftButton);
  QVERIFY(waitFor([&] { return !w_->findChild<QMessageBox*>("endRehearsalBox"); }, 10000));
  w_->activateWindow();  // (the window manager gives it back after a box; offscreen has none)
  QVERIFY(QTest::qWaitForWindowActive(w_.get()));
  QVERIFY(!w_->caseData()->appearanceCurrent());
  // The status bar's long sentence does not widen the window (a person's check saw it grow from 1600 to 1622 px here,
  // and past the screen's 1920 px on another case): it is elided, whole in its tooltip.
  QTest::qWait(100);
  qInfo("the window's least width %d px before the stale estimate's sentence, %d px with it", least,
        w_->minimumSizeHint().width());
  QCOMPARE(w_->minimumSizeHint().width(), least);
  QCOMPARE(w_->width(), width);
  auto* modeLine = w_->findChild<QLabel*>("statusViewMode");
  QVERIFY(modeLine);
  QCOMPARE(modeLine->toolTip(), w_->viewModeText());
  QVERIFY(!w_->showingComposited());
  QVERIFY2(w_->viewModeText().contains("another pose"), qPrintable(w_->viewModeText()));
  QVERIFY(w_->findChild<QLabel*>("appearanceStatus")->text().startsWith("STALE"));
  QVERIFY(!w_->stepDone(ui::Step::Appearance));
  QVERIFY(w_->infoText().contains("STALE"));
  // The toolbar's button pressed is the view shown: the overlay (a person's check found Composited View still
  // pressed after an undo while the view and the status bar said it showed the overlay); F2 there says why and leaves
  // it so.
  auto* composited = w_->findChild<QAction*>("viewMode0");
  auto* overlay = w_->findChild<QAction*>("viewMode1");
  QVERIFY(composited && overlay);
  QVERIFY(!composited->isChecked() && overlay->isChecked());
  QTest::keyClick(w_.get(), Qt::Key_F2);
  QVERIFY(!w_->showingComposited());
  QVERIFY(!composited->isChecked() && overlay->isChecked());
  QVERIFY2(w_->viewModeText().startsWith("Overlay, not composited:"), qPrintable(w_->viewModeText()));
  w_->undoStack()->undo();
  QVERIFY(w_->caseData()->appearanceCurrent());
  QVERIFY(waitFor([&] { return w_->showingComposited(); }, 30000));
  QVERIFY(composited->isChecked() && !overlay->isChecked());
}

void TestAppearanceGui::escCancels() {
  const auto before = w_->caseData()->appearance;
  QSignalSpy done(w_->appearancePage(), &ui::AppearancePage::estimated);
  QTest::keyClick(w_.get(), Qt::Key_F10);
  QTest::keyClick(w_.get(), Qt::Key_Escape);
  QVERIFY(done.wait(120000));
  QVERIFY(!done.first().at(0).toBool());
  QCOMPARE(done.first().at(1).toString(), QStringLiteral("Cancelled; the case is unchanged."));
  QVERIFY(w_->caseData()->appearance == before);
}

void TestAppearanceGui::organBehindTheCameraIsRefused() {
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

void TestAppearanceGui::savedAndComposedAgainAfterReopening() {
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

// New Case over a rehearsal that burnt the organ asks first (Discard / Cancel), naming only what a stopped recording
// did not keep; Discard starts the empty case, which shows no simulated organ and asks nothing more about the old
// one's rehearsal. (A person's check found the old organ
// kept on show, greyed at t = 20.59 s, and its cut asked about again at every Ctrl+Q, Ctrl+N and Ctrl+O.)
// An edit, an undo or an import that would start another session ends a rehearsal nothing keeps: it asks first ("a
// person imported a mesh over a cut rehearsal and it was gone without a word", where quitting and Reset asked). Cancel
// keeps the rehearsal and the case as they were; Discard ends the rehearsal and the import goes ahead, undoable.
void TestAppearanceGui::editsThatEndTheRehearsalAsk(const QString& unkept, const QString& folder) {
  // The question (window-modal), answered with the mouse; what it asked kept.
  QString asked;
  auto answer = [&](QMessageBox::StandardButton button) {
    QMessageBox* box = nullptr;
    if (!waitFor(
            [&] {
              box = w_->findChild<QMessageBox*>("endRehearsalBox");
              return box && box->isVisible();
            },
            10000)) {
      qWarning("no question came: %s", qPrintable(w_->statusText()));
      return false;
    }
    asked = box->text() + " " + box->informativeText();
    QTest::mouseClick(box->button(button), Qt::LeftButton);
    return waitFor([&] { return !w_->findChild<QMessageBox*>("endRehearsalBox"); }, 10000);
  };
  const auto before = w_->caseData();
  // The support's stiffness (a new start), Cancel: the field shows the case's value again.
  auto* support = panel_->findChild<QDoubleSpinBox*>("simSupport");
  QVERIFY(support);
  const double shown = support->value();
  support->setValue(shown + 100);
  QVERIFY(answer(QMessageBox::Cancel));
  QVERIFY2(asked.contains(unkept) && asked.contains("Change support") && asked.contains("recording"), qPrintable(asked));
  QCOMPARE(w_->caseData(), before);
  QCOMPARE(panel_->unkeptWork(), unkept);
  QVERIFY(waitFor([&] { return support->value() == shown; }, 10000));
  QCOMPARE(w_->caseData(), before);
  QCOMPARE(w_->statusBar()->currentMessage(), QStringLiteral("Cancelled: the rehearsal stays as it is."));
  // A mesh dropped on the window (the same as File > Import Mesh), Cancel: nothing read, the organ as it was.
  const QString cube = QDir(folder).filePath("cube.vtk");
  {
    QFile f(cube);
    QVERIFY(f.open(QIODevice::WriteOnly));
    // A 60 mm cube in five tetrahedra (legacy VTK, millimetres).
    f.write("# vtk DataFile Version 3.0\ncube\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 double\n"
            "0 0 0\n60 0 0\n60 60 0\n0 60 0\n0 0 60\n60 0 60\n60 60 60\n0 60 60\n"
            "CELLS 5 25\n4 0 1 3 4\n4 1 2 3 6\n4 1 4 5 6\n4 3 6 7 4\n4 1 3 4 6\n"
            "CELL_TYPES 5\n10\n10\n10\n10\n10\n");
  }
  auto drop = [&](const QString& file) {  // as a user drags it from the file manager
    QMimeData mime;
    mime.setUrls({QUrl::fromLocalFile(file)});
    QDragEnterEvent enter(QPoint(600, 400), Qt::CopyAction, &mime, Qt::LeftButton, Qt::NoModifier);
    QApplication::sendEvent(w_.get(), &enter);
    QDropEvent event(QPointF(600, 400), Qt::CopyAction, &mime, Qt::LeftButton, Qt::NoModifier);
    QApplication::sendEvent(w_.get(), &event);
  };
  // A file refused (a 6 mm "organ": a wrong unit) costs the rehearsal nothing: it is asked about only once a file is
  // read (asked before, a person's Discard lost a burn to a file then refused).
  const QString tiny = QDir(folder).filePath("tiny.vtk");
  {
    QFile f(tiny);
    QVERIFY(f.open(QIODevice::WriteOnly));
    f.write("# vtk DataFile Version 3.0\ntiny\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n"
            "0 0 0\n6 0 0\n0 6 0\n0 0 6\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n");
  }
  drop(tiny);
  QVERIFY2(waitFor([&] { return w_->statusText().contains("organs measure 10 to 1000 mm"); }, 30000),
           qPrintable(w_->statusText()));
  QVERIFY(!w_->findChild<QMessageBox*>("endRehearsalBox"));
  QCOMPARE(w_->caseData(), before);
  QCOMPARE(panel_->unkeptWork(), unkept);
  // The cube, Cancel: nothing imported, the organ and the rehearsal as they were.
  drop(cube);
  QVERIFY(answer(QMessageBox::Cancel));
  QVERIFY2(asked.contains(unkept) && asked.contains("importing cube.vtk"), qPrintable(asked));
  QTest::qWait(500);
  QCOMPARE(w_->caseData(), before);
  QCOMPARE(panel_->unkeptWork(), unkept);
  QVERIFY2(w_->statusText().contains("cube.vtk was not imported"), qPrintable(w_->statusText()));
  // Discard: the rehearsal ends at once, the cube comes in, and Ctrl+Z brings the organ back (nothing to ask then).
  drop(cube);
  QVERIFY(answer(QMessageBox::Discard));
  QVERIFY2(asked.contains("importing cube.vtk"), qPrintable(asked));
  QCOMPARE(panel_->unkeptWork(), QString());
  QVERIFY(waitFor([&] { return w_->caseData()->organ->volume.tets.size() == 5; }, 60000));
  w_->activateWindow();
  QVERIFY(QTest::qWaitForWindowActive(w_.get()));
  QTest::keyClick(w_.get(), Qt::Key_Z, Qt::ControlModifier);
  QVERIFY(waitFor([&] { return w_->caseData()->organ == before->organ; }, 10000));
  QVERIFY(!w_->findChild<QMessageBox*>("endRehearsalBox"));
}

void TestAppearanceGui::aNewCaseEndsTheRehearsal() {
  QVERIFY(rehearseFromRest());
  auto* view = w_->frameView();
  const auto& c = *w_->caseData();
  const auto widget = organBoxPoint(view, c);
  QCOMPARE(panel_->unkeptWork(), QString());
  auto burnt = [&] { return ui::SimulationPanel::workOf(*panel_->lastFrame()).burnt; };
  // Recorded (saved to a file first: the rehearsal is recorded into it), a line burnt across the organ with the
  // cautery hook, the recording stopped: the recording keeps that burn, nothing is asked about it.
  QTemporaryDir dir;
  QSignalSpy saved(w_.get(), &MainWindow::caseSaved);
  w_->saveCaseAs(dir.filePath("burnt.rehearse"));
  QVERIFY(saved.wait(60000));
  QVERIFY(saved.first().at(0).toBool());
  auto* record = w_->findChild<QPushButton*>("recordButton");
  QVERIFY(record);
  QTest::mouseClick(record, Qt::LeftButton);
  QVERIFY2(w_->recording(), qPrintable(w_->messageLog().join(" | ")));
  QVERIFY(stepsOn(5));
  QTest::keyClick(w_.get(), Qt::Key_J);
  QCOMPARE(view->tool(), ui::Tool::Cautery);
  QVERIFY(dragTheHook(view, panel_, widget(0.35, 0.4), widget(0.6, 0.4), [this](int n) { return stepsOn(n); }));
  QVERIFY(waitFor([&] { return burnt() > 0; }, 30000));
  const std::size_t recorded = burnt();
  QTest::mouseClick(record, Qt::LeftButton);  // stop
  QVERIFY(!w_->recording());
  QCOMPARE(panel_->unkeptWork(), QString());
  // A second line, after the recording: only that one is named, as such.
  QVERIFY(dragTheHook(view, panel_, widget(0.35, 0.6), widget(0.6, 0.6), [this](int n) { return stepsOn(n); }));
  QVERIFY2(waitFor([&] { return burnt() > recorded; }, 30000), qPrintable(panel_->unkeptWork()));
  QString unkept = panel_->unkeptWork();
  QCOMPARE(unkept, QStringLiteral("burnt since the recording stopped"));
  editsThatEndTheRehearsalAsk(unkept, dir.path());
  if (QTest::currentTestFailed()) return;
  // That ended the rehearsal (an import, discarded, then undone): back in step 7, another line for New Case to ask about.
  const auto ended = panel_->lastFrame();
  QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
  if (!panel_->isPlaying()) QTest::keyClick(w_.get(), Qt::Key_F5);  // (a new organ starts paused)
  QVERIFY(waitFor([&] {
    const auto f = panel_->lastFrame();
    return f && f != ended && f->steps > 5 && f->positions.size() == c.organ->volume.points.size();
  }, 60000));
  QTest::keyClick(w_.get(), Qt::Key_J);
  QCOMPARE(view->tool(), ui::Tool::Cautery);
  QVERIFY(dragTheHook(view, panel_, widget(0.35, 0.5), widget(0.6, 0.5), [this](int n) { return stepsOn(n); }));
  QVERIFY2(waitFor([&] { return burnt() > 0; }, 30000), qPrintable(panel_->unkeptWork()));
  unkept = panel_->unkeptWork();
  QCOMPARE(unkept, QStringLiteral("burnt"));
  {  // Redo (Ctrl+Shift+Z) of the import would end this one too: asked, and Cancel keeps it and the organ.
    QCOMPARE(w_->undoStack()->redoText(), QStringLiteral("Import mesh"));
    const auto organ = w_->caseData()->organ;
    QTest::keyClick(w_.get(), Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
    QMessageBox* box = nullptr;
    QVERIFY(waitFor([&] { return (box = w_->findChild<QMessageBox*>("endRehearsalBox")) && box->isVisible(); }, 10000));
    QVERIFY2(box->text().contains("redoing \u201cImport mesh\u201d") && box->text().contains(unkept),
             qPrintable(box->text()));
    QTest::mouseClick(box->button(QMessageBox::Cancel), Qt::LeftButton);
    QVERIFY(waitFor([&] { return !w_->findChild<QMessageBox*>("endRehearsalBox"); }, 10000));
    QCOMPARE(w_->caseData()->organ, organ);
    QCOMPARE(panel_->unkeptWork(), unkept);
    w_->activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(w_.get()));
  }
  QTest::keyClick(w_.get(), Qt::Key_N, Qt::ControlModifier);
  QMessageBox* box = nullptr;
  QVERIFY(waitFor(
      [&] {
        box = w_->findChild<QMessageBox*>("unkeptRehearsalBox");
        return box && box->isVisible();
      },
      10000));
  qInfo("asked: %s", qPrintable(box->text()));
  QVERIFY2(box->text().contains(unkept) && box->text().contains("starting a new case"), qPrintable(box->text()));
  QTest::mouseClick(box->button(QMessageBox::Discard), Qt::LeftButton);
  QVERIFY(waitFor([&] { return w_->caseData() && w_->caseData()->organ->empty(); }, 10000));
  QVERIFY(waitFor([&] { return !panel_->lastFrame(); }, 10000));  // the old organ is not shown on
  QCOMPARE(panel_->unkeptWork(), QString());
  w_->activateWindow();  // (the window manager gives it back after a box; offscreen has none)
  QVERIFY(QTest::qWaitForWindowActive(w_.get()));
  // Nothing more to ask: New Case again goes ahead at once.
  QTest::keyClick(w_.get(), Qt::Key_N, Qt::ControlModifier);
  QTest::qWait(300);
  QVERIFY(!w_->findChild<QMessageBox*>("unkeptRehearsalBox"));
  QVERIFY(!w_->findChild<QMessageBox*>("unsavedChangesBox"));
}

void TestAppearanceGui::cleanupTestCase() {
  w_->close();
  w_.reset();
}
