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
// The suite's class is in test_appearance_gui.hpp; the slots from clipCutAndCauterize on are in
// test_appearance_gui_tools.cpp.
#include "test_appearance_gui.hpp"
#include <algorithm>
#include <functional>
#include "rehearse/ui/organview.hpp"

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
double cell(QTableWidget* t, int r, int c) {
  return t->item(r, c)->text().section(QLatin1Char(' '), 0, 0).toDouble();
}
}  // namespace

// Step 7 over the frame, the simulation from rest and playing: true once its first steps on the organ are in.
bool TestAppearanceGui::rehearseFromRest() {
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
bool TestAppearanceGui::stepsOn(int n) {
  const long now = panel_->lastFrame()->steps;
  // Up to 4 s a step after a cut on the phantom, on a loaded machine (steps of 30-60 chord iterations with
  // refactorisations, issue 64; 4.2 s once, when 15 steps had a minute): this checks what the steps do, not their
  // speed, which bench_operative measures. 10 s a step, at least a minute.
  const bool on = waitFor([&] { return panel_->lastFrame()->steps >= now + n; }, std::max(60000, 10000 * n));
  if (!on) qWarning("%s", qPrintable(said()));
  return on;
}
// What the session and the panel say (for a failure's message: CI once saw the session stop stepping here).
QString TestAppearanceGui::said() const {
  const auto f = panel_->lastFrame();
  return QStringLiteral("step %1, %2 playing; status: %3; step: %4; message: %5")
      .arg(f ? f->steps : -1)
      .arg(panel_->isPlaying() ? "" : "not")
      .arg(panel_->statusText())
      .arg(f ? QString::fromStdString(f->report.status) : QString())
      .arg(f ? f->message : QString());
}

// F10 on the window, and the page's answer.
QList<QVariant> TestAppearanceGui::estimateWithF10() {
  QSignalSpy done(w_->appearancePage(), &ui::AppearancePage::estimated);
  QTest::keyClick(w_.get(), Qt::Key_F10);
  if (!done.wait(120000)) return {};
  return done.first();
}

void TestAppearanceGui::initTestCase() {
  QCoreApplication::setOrganizationName("RehearseAppearanceTest");
  MainWindow::setRenderer(MainWindow::Renderer::Software);
  QVERIFY(openPhantomCase(w_));
  panel_ = w_->simulationPanel();
  // Registered: the phantom at its true pose (steps 4-5 are tested elsewhere; here the appearance).
  const Pose truth = w_->caseData()->groundTruth->pose;
  w_->editCase("Register (test)", [&truth](app::Case& c) {
    c.pose = truth;
    c.hasPose = c.poseAligned = true;
  });
}

void TestAppearanceGui::estimateWithTheKeyboard() {
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
  qInfo("light (%.1f, %.1f, %.1f) mm, true (%.1f, %.1f, %.1f), %.0f mm from the organ; sigma %s (true %.3f)", light.x(),
        light.y(), light.z(), 1e3 * t.lightPosition.x(), 1e3 * t.lightPosition.y(), 1e3 * t.lightPosition.z(), distance,
        qPrintable(table->item(3, 0)->text()), t.roughness);
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
  // Issue 65: the page says which light the frame shows; the phantom's is its scope's alone, no second source used.
  const QString report = w_->appearancePage()->findChild<QLabel*>("appearanceReport")->text();
  QVERIFY2(report.contains(QStringLiteral("Light: the scope's light alone explains")) && report.contains(QStringLiteral("an ambient term")) &&
               !report.contains(QStringLiteral("(used)")) && !report.contains(QStringLiteral("Distant light towards")),
           qPrintable(report));
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
void TestAppearanceGui::waitForIdleShowsTheNewestComposition() {
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

// Issue 65: the window's composition honours a fit's verdict. An estimate marked texture only (what step 6 stores when
// the model explains too little of the frame's shading) is not re-shaded: at rest the organ shows the frame itself (as
// the re-shaded composition nearly does too), and turned 10 degrees it shows the frame's colours carried, not the
// re-shaded ones. The case's own estimate is put back afterwards. (At rest 203 of 287,603 inner pixels differ from the
// frame, along a fold near the organ's lower edge where it hides part of itself.)
void TestAppearanceGui::aTextureOnlyEstimateIsNotReshaded() {
  auto* composition = w_->composition();
  QVERIFY(composition->ready());
  const auto original = w_->caseData()->appearance;
  QVERIFY(original && !original->textureOnly);
  const auto restore = qScopeGuard([&] {
    w_->editCase("Estimate (test)", [&](app::Case& c) { c.appearance = original; });
    QVERIFY(waitFor([&] { return composition->ready(); }));
  });
  const app::Case& c = *w_->caseData();
  // The organ turned 10 degrees about the camera's X axis through its centre: its shading under the light changes.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : c.shapeNodes()) centre += c.pose.apply(p) / static_cast<double>(c.shapeNodes().size());
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::vector<Eigen::Vector3d> moved;
  for (const auto& p : c.shapeNodes()) moved.push_back(centre + turn * (c.pose.apply(p) - centre));
  composition->waitForIdle();
  const cv::Mat3b reshadedRest = toMat(composition->composeNow()), reshadedMoved = toMat(composition->composeNow(moved));
  auto textureOnly = std::make_shared<app::AppearanceEstimate>(*original);
  textureOnly->textureOnly = true;
  w_->editCase("Estimate (test)", [&](app::Case& k) { k.appearance = textureOnly; });
  QVERIFY(waitFor([&] { return composition->ready() && w_->caseData()->appearance == textureOnly; }));
  composition->waitForIdle();
  const cv::Mat3b rest = toMat(composition->composeNow()), shifted = toMat(composition->composeNow(moved));
  const app::Case& k = *w_->caseData();
  const cv::Mat1b organ = imaging::renderMask(k.camera, k.pose, k.surfaceView());
  cv::Mat1b inner;  // away from the rim, where the outline's pixels blend organ and background
  cv::erode(organ, inner, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  const double textureDb = imaging::psnr(k.frame, rest, inner), reshadedDb = imaging::psnr(k.frame, reshadedRest, inner);
  auto sameAsTheFrame = [&](const cv::Mat3b& j) {  // inner pixels equal to the frame's in every channel
    cv::Mat3b d;
    cv::absdiff(j, k.frame, d);
    cv::Mat1b any;
    cv::inRange(d, cv::Scalar(1, 1, 1), cv::Scalar(255, 255, 255), any);
    return cv::countNonZero(inner) - cv::countNonZero(any & inner);
  };
  const int textureSame = sameAsTheFrame(rest), reshadedSame = sameAsTheFrame(reshadedRest);
  cv::Mat3b diff;
  cv::absdiff(shifted, reshadedMoved, diff);
  cv::Mat1b differs;
  cv::inRange(diff, cv::Scalar(3, 3, 3), cv::Scalar(255, 255, 255), differs);
  qInfo("at rest inside the organ (%d px): texture only %d px equal to the frame's, %.1f dB; re-shaded %d px, %.1f dB; "
        "turned, %d px differ from the re-shaded composition by 3 levels or more",
        cv::countNonZero(inner), textureSame, textureDb, reshadedSame, reshadedDb, cv::countNonZero(differs));
  QVERIFY2(textureSame >= 0.995 * cv::countNonZero(inner), qPrintable(QString::number(textureSame)));
  QVERIFY(cv::countNonZero(differs) > 10000);
  composition->request();  // the view shows it too
  composition->waitForIdle();
  QVERIFY(w_->showingComposited());
  QVERIFY(toMat(w_->frameView()->shownFrame()).size() == rest.size());
  QVERIFY(cv::norm(toMat(w_->frameView()->shownFrame()), rest, cv::NORM_INF) == 0);

  // A fit that explained 70 % re-shades half way (imaging::reshadeTrust: nothing at 50 %, in full from 90 %): turned, the
  // organ's colours where the frame saw it are the mean of the full re-shade's and texture only's, and the appearance
  // page says how far the model's change is applied.
  auto withShare = [&](double explained) {
    auto e = std::make_shared<app::AppearanceEstimate>(*original);
    e->textureOnly = false;
    e->explained = explained;
    w_->editCase("Estimate (test)", [&](app::Case& k) { k.appearance = e; });
    [&] { QVERIFY(waitFor([&] { return composition->ready() && w_->caseData()->appearance == e; })); }();
    composition->waitForIdle();
    return toMat(composition->composeNow(moved));
  };
  const cv::Mat3b full = withShare(0.95);
  QTRY_VERIFY2(w_->findChild<QLabel*>(QStringLiteral("appearanceReport"))->text().contains(
                   QStringLiteral("Re-shading applies the model's change in full")),
               qPrintable(w_->findChild<QLabel*>(QStringLiteral("appearanceReport"))->text()));
  const cv::Mat3b half = withShare(0.7);
  cv::Mat3b mean;
  cv::addWeighted(full, 0.5, shifted, 0.5, 0.0, mean);
  // Inside the organ at rest, away from its rim (the turned organ covers nearly all of it).
  cv::Mat3b fromMean, fromFull;
  cv::absdiff(half, mean, fromMean);
  cv::absdiff(half, full, fromFull);
  int nearMean = 0, counted = 0, moves = 0;
  for (int y = 0; y < inner.rows; ++y)
    for (int x = 0; x < inner.cols; ++x) {
      if (!inner(y, x)) continue;
      const cv::Vec3b a = fromMean(y, x), b = fromFull(y, x);
      ++counted;
      nearMean += std::max({a[0], a[1], a[2]}) <= 1;
      moves += std::max({b[0], b[1], b[2]}) >= 2;
    }
  const QString said = w_->findChild<QLabel*>(QStringLiteral("appearanceReport"))->text();
  qInfo("explained 70 %%: %d of %d inner px within a level of the mean of the full re-shade and texture only, %d px "
        "2+ levels from the full re-shade; the page says: %s",
        nearMean, counted, moves, qPrintable(said.section(QLatin1Char('\n'), -2)));
  QVERIFY(nearMean >= 0.98 * counted);
  QVERIFY(moves > 5000);
  QVERIFY2(said.contains(QStringLiteral("Re-shading applies 50 % of the model's change")), qPrintable(said));
}

// Play deforms the organ in the frame: the view shows the composition of the simulation's snapshot, and
// where the organ was and is no more, I_B. (The organ starts where the frame shows it, in equilibrium: the tissue is
// made 4x softer on the Simulation panel first, a live edit, so that it sags from there.)
namespace {
// The tissue 4x softer (a live edit: the organ sags from its start) until the guard returned goes; then the tissue as
// it was (a live edit again), the run from rest and `after`, whatever the function's checks said: the functions after
// it cut and pull the organ at its own stiffness (CI once saw a failure leave it 4x softer, and the cut under traction
// then opened nothing).
[[nodiscard]] auto softenedTissue(ui::SimulationPanel* panel, std::function<void()> after = {}) {
  auto* young = panel->findChild<QDoubleSpinBox*>("simYoung");
  const double stiffness = young ? young->value() : 0;
  if (young) young->setValue(stiffness / 4);
  return qScopeGuard([=] {
    if (young) {
      young->setValue(stiffness);
      panel->reset();
    }
    if (after) after();
  });
}
}  // namespace

void TestAppearanceGui::compositedViewFollowsTheSimulation() {
  QVERIFY(w_->showingComposited());
  const cv::Mat3b rest = toMat(w_->frameView()->shownFrame());
  QVERIFY(panel_->findChild<QDoubleSpinBox*>("simYoung"));
  const auto restore = softenedTissue(panel_);
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
  QVERIFY2(worst == 0, qPrintable(QString("the view differs from the composition of the last snapshot (step %1) by up "
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

// Step 7, the organ softened (it sags from its start) and paused: the overlay (F3) and the 3D view (F4) show the organ
// the composited view shows, not the case at rest (a person's check: after the composited view had followed the
// simulation, F3 showed the overlay drawn before it, at rest, and F4 always showed the case at rest).
void TestAppearanceGui::everyViewShowsTheSimulatedOrgan() {
  QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
  QCOMPARE(w_->step(), ui::Step::Rehearse);
  QVERIFY(waitFor([&] { return w_->showingComposited(); }, 10000));
  const QImage restOverlay = w_->organOverlay();
  QVERIFY(panel_->findChild<QDoubleSpinBox*>("simYoung"));
  const auto restore = softenedTissue(panel_, [this] { QTest::keyClick(w_.get(), Qt::Key_F2); });
  if (!panel_->isPlaying()) QTest::keyClick(w_.get(), Qt::Key_F5);
  const long from = panel_->lastFrame() ? panel_->lastFrame()->steps : 0;
  QVERIFY(waitFor([&] { return panel_->lastFrame() && panel_->lastFrame()->steps > from + 30; }));
  QTest::keyClick(w_.get(), Qt::Key_F5);
  QVERIFY(waitFor([&] { return !panel_->isPlaying(); }, 10000));
  QTest::qWait(200);
  const auto f = panel_->lastFrame();
  const auto& c = *w_->caseData();
  double sag = 0;
  std::vector<double> now(3 * f->positions.size());
  for (std::size_t i = 0; i < f->positions.size(); ++i) {
    sag = std::max(sag, (f->positions[i] - c.pose.apply(c.shapeNodes()[i])).norm());
    const Eigen::Vector3d m = c.pose.R.transpose() * (f->positions[i] - c.pose.t);
    for (int k = 0; k < 3; ++k) now[3 * i + k] = m[k];
  }
  QVERIFY(sag > 1e-3);
  SurfaceView moved = c.surfaceView();
  moved.vertices = now.data();
  const cv::Mat1b was = imaging::renderMask(c.camera, c.pose, c.surfaceView()),
                  is = imaging::renderMask(c.camera, c.pose, moved);
  QTest::keyClick(w_.get(), Qt::Key_F3);
  QCOMPARE(w_->viewMode(), ui::ViewMode::Overlay);
  QVERIFY(waitFor([&] { return !(w_->organOverlay() == restOverlay); }, 10000));
  {
    const QImage o = w_->organOverlay().convertToFormat(QImage::Format_ARGB32);
    QCOMPARE(o.width(), c.camera.width);
    cv::Mat1b drawn(o.height(), o.width(), uchar(0));
    for (int y = 0; y < o.height(); ++y)
      for (int x = 0; x < o.width(); ++x) drawn(y, x) = qAlpha(o.pixel(x, y)) > 0 ? 255 : 0;
    cv::Mat1b offNow, offRest;
    cv::bitwise_xor(drawn, is, offNow);
    cv::bitwise_xor(drawn, was, offRest);
    qInfo("sagged %.1f mm: the overlay (F3) differs from the snapshot's silhouette on %d px, from the rest shape's on "
          "%d px",
          1e3 * sag, cv::countNonZero(offNow), cv::countNonZero(offRest));
    QVERIFY(cv::countNonZero(offNow) * 4 < cv::countNonZero(offRest));
  }
  auto* organ3d = w_->findChild<ui::OrganView*>("centreOrganView");
  QVERIFY(organ3d);
  const auto render3d = [&] {
    organ3d->repaint();
    return organ3d->rendered();
  };
  QTest::keyClick(w_.get(), Qt::Key_F4);
  QVERIFY(waitFor([&] { return organ3d->isVisible(); }));
  QCOMPARE(w_->viewModeText(), QStringLiteral("3D"));
  const QImage sagged3d = render3d();
  organ3d->setCase(w_->caseData());  // the case at rest, as the view drew it before
  const QImage rest3d = render3d();
  int differ = 0;
  for (int y = 0; y < std::min(rest3d.height(), sagged3d.height()); ++y)
    for (int x = 0; x < std::min(rest3d.width(), sagged3d.width()); ++x)
      differ += rest3d.pixel(x, y) != sagged3d.pixel(x, y);
  qInfo("the 3D view (F4) of the snapshot differs from the case at rest on %d of %d px", differ,
        rest3d.width() * rest3d.height());
  QVERIFY(differ > 500);
}

// A cut in step 7 keeps the composited view (issue 35; it gave way to the overlay before): the view shows the cut
// organ's composition (its cut faces in preset interior colours re-shaded by Theta), said in one sentence.
void TestAppearanceGui::cutOrganIsComposited() {
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
void TestAppearanceGui::graspPullCut() {
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
  ActionPauses pauses(QStringLiteral("the built-in phantom"));
  pauses.start();
  QTest::mouseMove(view, widget(0.5, 0.7));
  QTest::keyClick(view, Qt::Key_Space);
  QVERIFY2(waitFor([&] { return panel_->lastFrame()->tool.jawClosed && !panel_->lastFrame()->tool.held.empty(); }),
           qPrintable(said()));
  QVERIFY(stepsOn(3));
  pauses.stop("grasp");
  const auto bitten = panel_->lastFrame();
  const auto node = static_cast<std::size_t>(bitten->tool.held.front());
  const Eigen::Vector3d node0 = bitten->positions[node], tip0 = bitten->tool.tip;
  pauses.start();
  for (int i = 1; i <= 20; ++i) {
    QTest::mouseMove(view, widget(0.5, 0.7 + 0.15 * i / 20.0));
    QVERIFY(stepsOn(6));
  }
  QVERIFY(stepsOn(30));
  pauses.stop("pull");
  const auto pulled = panel_->lastFrame();
  QVERIFY(pulled->tool.jawClosed && !pulled->tool.held.empty());
  const Eigen::Vector3d tipMoved = pulled->tool.tip - tip0, nodeMoved = pulled->positions[node] - node0;
  qInfo("pulled: the jaws moved %.1f mm, the held node %.1f mm (%.3f mm apart), %.2f N", 1e3 * tipMoved.norm(),
        1e3 * nodeMoved.norm(), 1e3 * (tipMoved - nodeMoved).norm(), pulled->tool.force.norm());
  QVERIFY(tipMoved.norm() > 0.005);                                 // the mouse pulled more than 5 mm
  QVERIFY((tipMoved - nodeMoved).norm() < 0.02 * tipMoved.norm());  // and the tissue went with the jaws

  QTest::keyClick(w_.get(), Qt::Key_B);
  QCOMPARE(view->tool(), ui::Tool::Scissors);
  QVERIFY2(w_->statusBar()->currentMessage().contains("keeps its hold"), qPrintable(w_->statusBar()->currentMessage()));
  // A stroke across the stretched tissue above the jaws, from the middle leftwards.
  const QPoint a = widget(0.6, 0.62), b = widget(0.2, 0.62);
  pauses.start();
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
  pauses.stop("cut while grasping");
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

QTEST_MAIN(TestAppearanceGui)
