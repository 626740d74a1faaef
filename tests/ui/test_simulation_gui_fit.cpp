// The simulation panel suite's fit slots (test_simulation_gui.hpp declares them, in their order): the elastic fit of
// step 5 from the GUI, an anatomical curve, the GUI's fit against `rehearse register`, a second frame (issue 38) and an
// ambiguous fit's alternatives.
#include "test_simulation_gui.hpp"

#include "sagged_outline.hpp"
#include "second_view.hpp"
#include "test_support.hpp"
#include "window_support.hpp"

#include "rehearse/ui/casefile.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/pages/framepage.hpp"

#include <opencv2/imgcodecs.hpp>

#include <QCheckBox>
#include <QComboBox>
#include <QUndoStack>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <set>

#include <rehearse/app/elasticfit.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <QProcess>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <QDoubleSpinBox>
#include <QLabel>
#include <QPushButton>
#include <QRegularExpression>
#include <QSignalSpy>

using namespace rehearse;
using ui::MainWindow;

// Step 5: the elastic fit from the GUI: F9 runs it on a worker thread, the chart grows, the result
// is one undo step and is saved in the case file.
void TestSimulationGui::elasticFitStep() {
  const auto& c = *w_->caseData();
  // The assistant's contour: the outline at the true pose of the organ sagging 2 g sideways (a
  // deformation the fit must find); the rigid alignment: the true pose moved 3 mm sideways.
  const imaging::ContourSegment seg = saggedOutline(c);
  QVERIFY(!seg.points.empty());
  w_->editCase("test: contour and pose", [&](app::Case& k) {
    k.contour.width = k.camera.width;
    k.contour.height = k.camera.height;
    k.contour.segments = {seg};
    k.pose = k.groundTruth->pose;
    k.pose.t.x() += 0.003;
    k.hasPose = true;
    k.poseAligned = true;
  });
  QVERIFY(!w_->caseData()->hasFit());
  w_->frameView()->setFocus();
  QTest::keyClick(w_.get(), Qt::Key_5, Qt::AltModifier);
  QCOMPARE(w_->step(), ui::Step::Elastic);
  QTest::keyClick(w_.get(), Qt::Key_F9);
  QElapsedTimer t;
  t.start();
  while (!w_->caseData()->hasFit() && t.elapsed() < 120000) QTest::qWait(50);
  QVERIFY2(w_->caseData()->hasFit(), qPrintable(w_->findChild<QLabel*>("fitStatus")->text()));
  auto* chart = w_->findChild<QChartView*>("fitChart");
  QVERIFY(chart);
  auto* series = qobject_cast<QLineSeries*>(chart->chart()->series().front());
  QVERIFY(series->count() >= 2);
  const double first = series->at(0).y(), last = series->at(series->count() - 1).y();
  qInfo("fit: %s; chart %d points, %.2f px -> %.2f px", qPrintable(w_->findChild<QLabel*>("fitStatus")->text()),
        series->count(), first, last);
  QVERIFY(last < first);
  QVERIFY(w_->stepDone(ui::Step::Elastic));
  // Where the organ may be (issue 38): the outline at the fit's two far ends, dashed over the frame and in the
  // legend. Each lies near the fitted organ's own outline (rendered here from the case), as far as the bound allows
  // at the organ's depth: off by more than a fifth of a pixel, by less than three times the bound seen there.
  const QList<QPolygonF> possible = w_->frameView()->possibleOutlines();
  QCOMPARE(possible.size(), 2);
  bool named = false;
  for (const auto& e : w_->frameView()->legend()) named |= e.text.startsWith("where the organ may be");
  QVERIFY(named);
  {
    // Not over the rehearsal: with an instrument of step 7 in hand the bound (on the fitted shape, which the tissue
    // leaves) is neither drawn nor named; back with the previous tool, it is again.
    ui::FrameView* view = w_->frameView();
    const ui::Tool before = view->tool();
    auto boundNamed = [&] {
      for (const auto& e : view->legend())
        if (e.text.startsWith("where the organ may be")) return true;
      return false;
    };
    view->setTool(ui::Tool::Grasp);
    QVERIFY(!boundNamed());
    view->setTool(before);
    QVERIFY(boundNamed());
  }
  {
    const auto& fc = *w_->caseData();
    const auto own = imaging::maskOutlines(imaging::renderMask(fc.camera, fc.pose, fc.surfaceView()));
    QVERIFY(!own.empty());
    double depth = 0;
    for (const auto& p : fc.fit->nodes) depth += fc.pose.apply(p).z() / static_cast<double>(fc.fit->nodes.size());
    const QString text = w_->findChild<QLabel*>("fitStatus")->text();
    const int at = text.indexOf("may be up to ");
    QVERIFY2(at >= 0, qPrintable(text));
    const double boundMm = text.mid(at + 13).section(' ', 0, 0).toDouble();
    const double boundPx = 1e-3 * boundMm * fc.camera.K(0, 0) / depth;
    for (const auto& poly : possible) {
      double sum = 0;
      for (const QPointF& q : poly) {
        double nearest = std::numeric_limits<double>::infinity();
        for (const auto& p : own.front()) nearest = std::min(nearest, std::hypot(p.x() - q.x(), p.y() - q.y()));
        sum += nearest;
      }
      const double mean = sum / poly.size();
      qInfo(
          "where the organ may be: an outline %d points, %.2f px from the fit's on average (the bound %.2f mm, "
          "%.2f px at the organ's depth)",
          static_cast<int>(poly.size()), mean, boundMm, boundPx);
      QVERIFY(mean > 0.2 && mean < 3 * boundPx);
    }
  }
  const std::vector<Eigen::Vector3d> fitted = w_->caseData()->fit->nodes;
  // Keep or revert: offered while the fit is the last edit. Revert by key and redo, then by the button.
  auto* keep = w_->findChild<QPushButton*>("fitKeep");
  auto* revert = w_->findChild<QPushButton*>("fitRevert");
  QVERIFY(keep && revert && keep->isEnabled() && revert->isEnabled());
  const Pose fittedPose = w_->caseData()->pose;
  QTest::keyClick(w_.get(), Qt::Key_Z, Qt::ControlModifier);
  QVERIFY(!w_->caseData()->hasFit());
  QVERIFY(!revert->isEnabled());
  QVERIFY(w_->frameView()->possibleOutlines().isEmpty());  // no drawing of a fit that is gone
  const QKeyCombination redo = QKeySequence::keyBindings(QKeySequence::Redo).front()[0];  // the platform's redo key
  QTest::keyClick(w_.get(), redo.key(), redo.keyboardModifiers());
  QCOMPARE(w_->caseData()->fit->nodes.size(), fitted.size());
  QVERIFY(revert->isEnabled());
  QTest::mouseClick(revert, Qt::LeftButton);
  QVERIFY(!w_->caseData()->hasFit());
  QVERIFY(w_->frameView()->possibleOutlines().isEmpty());
  const Pose& before = w_->caseData()->pose;  // the rigid pre-pass's change is reverted too
  QVERIFY((before.t - (c.groundTruth->pose.t + Eigen::Vector3d(0.003, 0, 0))).norm() < 1e-12);
  QVERIFY((before.R - c.groundTruth->pose.R).norm() < 1e-12);
  QTest::keyClick(w_.get(), redo.key(), redo.keyboardModifiers());
  QCOMPARE(w_->caseData()->fit->nodes.size(), fitted.size());
  QVERIFY((w_->caseData()->pose.t - fittedPose.t).norm() < 1e-12);
  QTest::mouseClick(keep, Qt::LeftButton);
  QVERIFY(!keep->isEnabled() && !revert->isEnabled());
  // The redone fit is the same fit: its bound is drawn again (the box hides and shows it).
  QCOMPARE(w_->frameView()->possibleOutlines().size(), 2);
  auto* showBound = w_->findChild<QCheckBox*>("fitShowBound");
  QVERIFY(showBound && showBound->isChecked());
  QTest::mouseClick(showBound, Qt::LeftButton, {}, QPoint(8, showBound->height() / 2));
  QVERIFY(w_->frameView()->possibleOutlines().isEmpty());
  QTest::mouseClick(showBound, Qt::LeftButton, {}, QPoint(8, showBound->height() / 2));
  QCOMPARE(w_->frameView()->possibleOutlines().size(), 2);
  QVERIFY(w_->findChild<QLabel*>("fitStatus")->text().startsWith("Fit kept"));
  QVERIFY2(w_->findChild<QLabel*>("fitStatus")->text().contains("Uncertainty: the surface may be up to"),
           qPrintable(w_->findChild<QLabel*>("fitStatus")->text()));  // the bound stays once kept
  QCOMPARE(w_->caseData()->fit->nodes.size(), fitted.size());
  // Stored in the case file.
  const QString path = QString::fromStdString(tempPath("fit.rehearse"));
  ui::saveCaseFile(*w_->caseData(), path);
  const app::Case back = ui::loadCaseFile(path);
  QVERIFY(back.hasFit());
  QCOMPARE(back.fit->nodes.size(), fitted.size());
  double worst = 0;
  for (std::size_t i = 0; i < fitted.size(); ++i) worst = std::max(worst, (back.fit->nodes[i] - fitted[i]).norm());
  QVERIFY(worst < 1e-12);
  const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR");
  if (!dir.isEmpty()) {
    QTest::qWait(100);
    w_->grab().save(QString::fromLocal8Bit(dir) + "/step5-fit.png");
  }
}

// A ridge sketched on the frame (step 3, segment type Ridge, click by click), its curve clicked on the
// organ (step 5, K), one undo step, and the fit holding it.
void TestSimulationGui::anatomicalCurveStep() {
  w_->editCase("test: true pose, no fit", [](app::Case& k) {
    k.fit.reset();
    k.pose = k.groundTruth->pose;
    k.hasPose = true;
  });
  const auto& c0 = *w_->caseData();
  const Eigen::Vector2d centre = c0.camera.project(c0.groundTruth->pose.apply(c0.organ->centreOfGravity));
  const std::vector<Eigen::Vector2d> along = {centre + Eigen::Vector2d(-160, 0), centre,
                                              centre + Eigen::Vector2d(160, 0)};
  auto* view = w_->frameView();
  auto click = [&](const Eigen::Vector2d& framePixel) {
    QTest::mouseClick(view, Qt::LeftButton, Qt::NoModifier,
                      view->toWidget(QPointF(framePixel.x(), framePixel.y())).toPoint());
  };
  view->setFocus();
  QTest::keyClick(w_.get(), Qt::Key_3, Qt::AltModifier);
  QCOMPARE(w_->step(), ui::Step::Contour);
  auto* type = w_->findChild<QComboBox*>("segmentType");
  QVERIFY(type);
  type->setFocus();
  QTest::keyClick(type, Qt::Key_Down);  // Silhouette -> Ridge
  QCOMPARE(type->currentData().toString(), QStringLiteral("ridge"));
  view->setFocus();
  QTest::keyClick(w_.get(), Qt::Key_C);  // click-by-click
  const std::size_t before = w_->caseData()->contour.segments.size();
  for (const auto& p : along) click(p);
  QTest::keyClick(view, Qt::Key_Return);
  const auto& segs = w_->caseData()->contour.segments;
  QCOMPARE(segs.size(), before + 1);
  QCOMPARE(QString::fromStdString(segs.back().type), QStringLiteral("ridge"));
  QVERIFY(segs.back().modelVertices.empty());
  // Step 5: the same curve on the organ, by three clicks.
  QTest::keyClick(w_.get(), Qt::Key_5, Qt::AltModifier);
  QTest::keyClick(w_.get(), Qt::Key_K);
  QCOMPARE(view->tool(), ui::Tool::OrganCurve);
  for (const auto& p : along) click(p);
  QTest::keyClick(view, Qt::Key_Return);
  const auto& c = *w_->caseData();
  const auto& nodes = c.contour.segments.back().modelVertices;
  qInfo("organ curve: %zu nodes from 3 clicks; %s", nodes.size(),
        qPrintable(w_->findChild<QLabel*>("fitCurves")->text()));
  QVERIFY(nodes.size() >= 5);
  // A chain along the surface: consecutive nodes share a surface edge; its ends project near the clicks.
  std::set<std::pair<int, int>> edges;
  for (const auto& t : c.organ->surface)
    for (int k = 0; k < 3; ++k) edges.insert({std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])});
  for (std::size_t i = 1; i < nodes.size(); ++i)
    QVERIFY(edges.count({std::min(nodes[i - 1], nodes[i]), std::max(nodes[i - 1], nodes[i])}));
  const Eigen::Vector2d end = c.camera.project(c.pose.apply(c.organ->volume.points[nodes.back()]));
  // (the node nearest to the click on the triangle under it: within one surface edge, about 40 px here)
  QVERIFY2((end - along.back()).norm() < 45,
           qPrintable(QString("last node projects %1 px from the last click").arg((end - along.back()).norm())));
  QVERIFY(w_->findChild<QLabel*>("fitCurves")->text().contains("1 with their curve"));
  // The picks are one undo step.
  QTest::keyClick(w_.get(), Qt::Key_Z, Qt::ControlModifier);
  QVERIFY(w_->caseData()->contour.segments.back().modelVertices.empty());
  const QKeyCombination redo = QKeySequence::keyBindings(QKeySequence::Redo).front()[0];
  QTest::keyClick(w_.get(), redo.key(), redo.keyboardModifiers());
  QCOMPARE(w_->caseData()->contour.segments.back().modelVertices.size(), nodes.size());
  // The fit runs with the ridge held.
  QTest::keyClick(w_.get(), Qt::Key_F9);
  QElapsedTimer t;
  t.start();
  while (!w_->caseData()->hasFit() && t.elapsed() < 120000) QTest::qWait(50);
  QVERIFY2(w_->caseData()->hasFit(), qPrintable(w_->findChild<QLabel*>("fitStatus")->text()));
  qInfo("fit with the ridge: %s", qPrintable(w_->findChild<QLabel*>("fitStatus")->text()));
  const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR");
  if (!dir.isEmpty()) {
    QTest::qWait(100);
    w_->grab().save(QString::fromLocal8Bit(dir) + "/step5-ridge.png");
  }
}

// The material set in the Simulation panel is the one the GUI's fit uses, and the GUI's fit and
// `rehearse register` (the same inputs written to files) give the same registered nodes.
void TestSimulationGui::guiFitUsesTheCaseMaterialAndMatchesTheCommandLine() {
  auto* model = panel_->findChild<QComboBox*>("simMaterial");
  auto* young = panel_->findChild<QDoubleSpinBox*>("simYoung");
  QVERIFY(model && young);
  model->setCurrentIndex(static_cast<int>(simcore::MaterialModel::StVK));
  young->setValue(54.0);
  std::shared_ptr<const app::Case> c = w_->caseData();  // a version of the case (the document moves on)
  QVERIFY(c->material.model == simcore::MaterialModel::StVK);
  QCOMPARE(c->material.young, 54e3);
  // What the fit would build from the case: every parenchyma element StVK at 54 kPa (Lame mu = E / 2(1 + nu)).
  const simcore::FemModel fm = app::fitModel(app::fitInputFromCase(*c));
  const double mu = 54e3 / (2 * (1 + c->material.poisson));
  int parenchyma = 0;
  for (std::size_t e = 0; e < fm.tets.size(); ++e) {
    if (c->organ->volume.tetLabels[e] != app::kParenchymaLabel) continue;
    ++parenchyma;
    QVERIFY(fm.model[e] == simcore::MaterialModel::StVK);
    QVERIFY(std::abs(fm.lame[e].mu - mu) < 1e-9 * mu);
  }
  QVERIFY(parenchyma > 1000);
  // Which way is down, told on the fit page by keyboard (one undo step): towards the image bottom.
  QTest::keyClick(w_.get(), Qt::Key_5, Qt::AltModifier);
  auto* down = w_->findChild<QComboBox*>("fitDown");
  QVERIFY(down && down->isVisible());
  QCOMPARE(down->currentIndex(), 0);  // not known
  QCOMPARE(w_->caseData()->down.norm(), 0.0);
  down->setFocus();
  QTest::keyClick(down, Qt::Key_Down);
  QCOMPARE(w_->caseData()->down, Eigen::Vector3d(0, 1, 0));
  w_->undoStack()->undo();
  QCOMPARE(w_->caseData()->down.norm(), 0.0);
  QCOMPARE(down->currentIndex(), 0);
  w_->undoStack()->redo();
  QCOMPARE(down->currentIndex(), 1);
  QCOMPARE(app::fitInputFromCase(*w_->caseData()).gravityCamera, Eigen::Vector3d(0, 9.81, 0));
  // The GUI fit (F9) from the current contour and pose; the command line gets the same version.
  w_->editCase("test: no fit", [](app::Case& k) { k.fit.reset(); });
  c = w_->caseData();
  QTest::keyClick(w_.get(), Qt::Key_F9);
  QTRY_VERIFY2_WITH_TIMEOUT(w_->caseData()->hasFit(), qPrintable(w_->findChild<QLabel*>("fitStatus")->text()), 120000);
  const auto fitted = w_->caseData();
  // The same inputs as files, through the command line.
  const std::string dir = tempPath("gui-vs-cli");
  std::filesystem::create_directories(dir);
  simcore::saveMesh(c->organ->volume, dir + "/organ.vtu");
  imaging::saveCamera(c->camera, dir + "/camera.yaml");
  imaging::savePose(c->pose, dir + "/pose.json");
  imaging::saveContour(c->contour, dir + "/contour.json");
  QString nodes;
  for (int a : c->attachments) nodes += QString::number(a) + " ";
  const QString d = QString::fromStdString(dir);
  QProcess p;
  p.start(QStringLiteral(REHEARSE_BINARY), {"register",
                                            "--mesh",
                                            d + "/organ.vtu",
                                            "--material",
                                            "stvk",
                                            "--young",
                                            QString::number(c->material.young, 'g', 17),
                                            "--poisson",
                                            QString::number(c->material.poisson, 'g', 17),
                                            "--density",
                                            QString::number(c->material.density, 'g', 17),
                                            "--vessel-young",
                                            QString::number(c->material.vesselYoung, 'g', 17),
                                            "--fixed-nodes",
                                            nodes.trimmed(),
                                            "--camera",
                                            d + "/camera.yaml",
                                            "--pose",
                                            d + "/pose.json",
                                            "--contour",
                                            d + "/contour.json",
                                            "--out",
                                            d + "/registered.vtu",
                                            "--gravity-camera",
                                            "0,9.81,0"});
  QVERIFY(p.waitForFinished(300000));
  QVERIFY2(p.exitCode() == 0, qPrintable(QString::fromUtf8(p.readAllStandardError())));
  const simcore::Mesh registered = simcore::loadMesh(dir + "/registered.vtu");
  QCOMPARE(registered.points.size(), fitted->fit->nodes.size());
  double worst = 0;
  for (std::size_t i = 0; i < registered.points.size(); ++i)
    worst = std::max(worst, (registered.points[i] - fitted->pose.apply(fitted->fit->nodes[i])).norm());
  qInfo(
      "GUI fit (StVK, 54 kPa, down towards the image bottom) against rehearse register on the same inputs: largest "
      "node difference %.2e m; %s",
      worst, fitted->fit->status.c_str());
  QVERIFY2(worst < 1e-9, qPrintable(QString::number(worst)));
  // The fit's uncertainty (issue 38): the command says the same sentence as the fit page's status, both from the
  // same fit, with a finite bound in millimetres.
  const QString out = QString::fromUtf8(p.readAllStandardOutput());
  const auto line =
      QRegularExpression(QStringLiteral("register: (the surface may be up to ([0-9.]+) mm[^\n]*)")).match(out);
  QVERIFY2(line.hasMatch(), qPrintable(out));
  QVERIFY(line.captured(2).toDouble() > 0);
  const QString page = w_->findChild<QLabel*>("fitStatus")->text();
  QVERIFY2(page.contains(QStringLiteral("Uncertainty: ") + line.captured(1)), qPrintable(page + " | " + out));
  // The tolerance (issue 38): typed on the fit page below that bound, the same fit is not determined, the page and
  // the command line (--tolerance-mm, exit 4) say so with the bound against it.
  auto* tolerance = w_->findChild<QDoubleSpinBox*>("fitTolerance");
  QVERIFY(tolerance && tolerance->isVisible());
  QCOMPARE(tolerance->value(), 5.0);
  tolerance->setFocus();
  QTest::keyClick(tolerance, Qt::Key_A, Qt::ControlModifier);
  QTest::keyClicks(tolerance, QStringLiteral("0.5"));
  QTest::keyClick(tolerance, Qt::Key_Return);
  QCOMPARE(tolerance->value(), 0.5);
  w_->editCase("test: no fit", [](app::Case& k) { k.fit.reset(); });
  QTest::keyClick(w_.get(), Qt::Key_F9);
  QTRY_VERIFY2_WITH_TIMEOUT(w_->caseData()->hasFit(), qPrintable(w_->findChild<QLabel*>("fitStatus")->text()), 120000);
  const QString strict = w_->findChild<QLabel*>("fitStatus")->text();
  QVERIFY2(strict.startsWith("AMBIGUOUS: the surface may be up to") &&
               strict.contains("more than the 0.5 mm asked for") && strict.contains("a second frame"),
           qPrintable(strict));
  QStringList again = p.arguments();
  again << "--tolerance-mm"
        << "0.5";
  p.start(QStringLiteral(REHEARSE_BINARY), again);
  QVERIFY(p.waitForFinished(300000));
  const QString strictErr = QString::fromUtf8(p.readAllStandardError());
  QCOMPARE(p.exitCode(), 4);
  QVERIFY2(strictErr.contains("more than the 0.5 mm asked for"), qPrintable(strictErr));
  tolerance->setValue(5.0);
}

namespace {
// secondFrameInTheGui, one method per phase of the scenario; what a phase makes, the later phases use. A failed
// QVERIFY returns from its phase: the test checks QTest::currentTestFailed() after each.
struct SecondFrameScenario {
  explicit SecondFrameScenario(std::unique_ptr<MainWindow>& w) : w_(w) {}

  std::unique_ptr<MainWindow>& w_;
  app::Case c0;
  Pose truth;                                  // the organ's true pose
  simcore::SimulationState sagged;             // the organ sagging 2 g away from the camera
  Pose motion;                                 // the camera's motion to the second frame
  cv::Mat3b second;                            // the second frame
  imaging::ContourSegment outline1, outline2;  // the sagged organ's outline in each frame
  Pose start;                                  // the fit's start: the true pose 3 mm off
  QComboBox* sketchOn = nullptr;               // step 3's Sketch on

  // The textured first frame, the organ sagging, the second frame seen 12 mm across, both outlines and the start.
  void makeTheFrames() {
    c0 = *w_->caseData();
    QVERIFY(c0.groundTruth);
    truth = c0.groundTruth->pose;
    // A textured first frame (the phantom's organ is rendered without texture: nothing to track on it): tissue with
    // speckle, as a liver's capsule shows it.
    cv::Mat3b first = imaging::makeTissueBackground(c0.camera.width, c0.camera.height, 7);
    {
      cv::Mat1f speckle(first.size());
      cv::RNG rng(7);  // (its own generator: the same speckle whatever ran before)
      rng.fill(speckle, cv::RNG::NORMAL, 0, 1);
      cv::GaussianBlur(speckle, speckle, cv::Size(0, 0), 2.0);
      cv::Mat3f tissue;
      first.convertTo(tissue, CV_32FC3);
      for (int y = 0; y < first.rows; ++y)
        for (int x = 0; x < first.cols; ++x) tissue(y, x) *= 1.0f + 1.5f * speckle(y, x);
      tissue.convertTo(first, CV_8UC3);
    }
    // The organ sagging 2 g away from the camera on its ligaments: a sag one outline cannot see.
    const simcore::FemModel model =
        simcore::FemModel::build(c0.organ->volume, {}, {simcore::MaterialModel::Corotational, 27e3, 0.4, 1000});
    simcore::SimulationSettings load;
    load.gravity = truth.R.transpose() * Eigen::Vector3d(0, 0, 2 * 9.81);
    simcore::Integrator sag(model, c0.attachments, load);
    sagged = sag.initialState();
    QVERIFY(sag.solveStatic(sagged).ok);
    SurfaceView rest = c0.organ->volume.surfaceView();  // (the sagged shape)
    rest.vertices = sagged.x.data();
    rest.triangles = c0.organ->surface.front().data();
    rest.triangleCount = c0.organ->surface.size();
    std::vector<double> seen;  // the sagged shape at the true pose, camera frame
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < rest.vertexCount; ++i) {
      const Eigen::Vector3d q = truth.apply(rest.vertex(i));
      seen.insert(seen.end(), {q.x(), q.y(), q.z()});
      centre += q / static_cast<double>(rest.vertexCount);
    }
    SurfaceView inCamera = rest;
    inCamera.vertices = seen.data();
    motion = testing::lookingAt(Eigen::Vector3d(0.012, 0, 0), centre);
    cv::Mat1b mask;
    second = testing::secondView(c0.camera, first, inCamera, motion, mask);
    Pose seenSecond;
    seenSecond.R = motion.R * truth.R;
    seenSecond.t = motion.R * truth.t + motion.t;
    auto outlineAt = [&](const Pose& pose) {
      const auto borders = imaging::maskOutlines(imaging::renderMask(c0.camera, pose, rest));
      imaging::ContourSegment seg;
      if (!borders.empty())
        for (std::size_t i = 0; i < borders.front().size(); i += 3) seg.points.push_back(borders.front()[i]);
      seg.closed = true;
      return seg;
    };
    outline1 = outlineAt(truth), outline2 = outlineAt(seenSecond);
    QVERIFY(outline1.points.size() > 20 && outline2.points.size() > 20);
    start = truth;
    start.t.x() += 0.003;  // the rigid alignment a little off
    w_->editCase("test: a textured frame, its outline and a start", [&](app::Case& k) {
      k.rawFrame = first;
      k.frame = first;
      k.contour.width = k.camera.width;
      k.contour.height = k.camera.height;
      k.contour.segments = {outline1};
      k.pose = start;
      k.hasPose = true;
      k.poseAligned = true;
      k.fit.reset();
      k.down.setZero();
      k.frame2 = cv::Mat3b();
      k.contour2 = {};
      k.baselineMm = 0;
    });
  }
  // Step 2: the second frame opened, its baseline typed; one of another size refused.
  void openTheSecondFrame() {
    // Step 2: the second frame and how far the scope moved.
    w_->frameView()->setFocus();
    QTest::keyClick(w_.get(), Qt::Key_2, Qt::AltModifier);
    const std::string secondPath = tempPath("second-frame.png");
    QVERIFY(cv::imwrite(secondPath, second));
    w_->framePage()->openSecondFrame(QString::fromStdString(secondPath));
    QCOMPARE(w_->caseData()->frame2.cols, c0.camera.width);
    QVERIFY2(w_->findChild<QLabel*>("secondFrameLabel")->text().contains("say how far the scope moved"),
             qPrintable(w_->findChild<QLabel*>("secondFrameLabel")->text()));
    auto* baseline = w_->findChild<QDoubleSpinBox*>("secondFrameBaseline");
    QVERIFY(baseline && baseline->isVisible());
    baseline->setFocus();
    QTest::keyClick(baseline, Qt::Key_A, Qt::ControlModifier);
    QTest::keyClicks(baseline, QStringLiteral("12"));
    QTest::keyClick(baseline, Qt::Key_Return);
    QCOMPARE(w_->caseData()->baselineMm, 12.0);
    // A second frame of another size is refused with a sentence, the case unchanged.
    const std::string smallPath = tempPath("small-frame.png");
    QVERIFY(cv::imwrite(smallPath, cv::Mat3b(100, 120, cv::Vec3b(40, 40, 40))));
    QSignalSpy opened(w_->framePage(), &ui::FramePage::frameSourceOpened);
    w_->framePage()->openSecondFrame(QString::fromStdString(smallPath));
    QCOMPARE(opened.count(), 1);
    QVERIFY(!opened.front().at(0).toBool() && opened.front().at(1).toString().contains("120x100"));
    QCOMPARE(w_->caseData()->frame2.cols, c0.camera.width);
  }
  // Step 3: a freehand stroke on the second frame goes to its outline; undone, the outline is given.
  void sketchOnTheSecondFrame() {
    // Step 3: sketch on the second frame. A freehand stroke goes to its outline, not the first frame's.
    QTest::keyClick(w_.get(), Qt::Key_3, Qt::AltModifier);
    sketchOn = w_->findChild<QComboBox*>("sketchOn");
    QVERIFY(sketchOn && sketchOn->isEnabled());
    sketchOn->setFocus();
    QTest::keyClick(sketchOn, Qt::Key_Down);
    QVERIFY(w_->frameView()->secondFrameShown());
    w_->frameView()->setFocus();
    QTest::keyClick(w_->frameView(), Qt::Key_F);
    const QPointF a = w_->frameView()->toWidget(QPointF(outline2.points[0].x(), outline2.points[0].y()));
    const QPointF b = w_->frameView()->toWidget(QPointF(outline2.points[20].x(), outline2.points[20].y()));
    QTest::mousePress(w_->frameView(), Qt::LeftButton, {}, a.toPoint());
    for (int i = 1; i <= 10; ++i) {
      QMouseEvent move(QEvent::MouseMove, a + (b - a) * i / 10.0, w_->frameView()->mapToGlobal(a + (b - a) * i / 10.0),
                       Qt::NoButton, Qt::LeftButton, Qt::NoModifier);
      QCoreApplication::sendEvent(w_->frameView(), &move);
    }
    QTest::mouseRelease(w_->frameView(), Qt::LeftButton, {}, b.toPoint());
    QCOMPARE(w_->caseData()->contour2.segments.size(), std::size_t(1));
    QCOMPARE(w_->caseData()->contour.segments.size(), std::size_t(1));
    QCOMPARE(w_->caseData()->contour.segments.front().points.size(), outline1.points.size());
    QTest::keyClick(w_.get(), Qt::Key_Z, Qt::ControlModifier);
    QVERIFY(w_->caseData()->contour2.segments.empty());
    w_->editCase("test: the second frame's outline", [&](app::Case& k) { k.contour2.segments = {outline2}; });
    if (const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR"); !dir.isEmpty()) {
      QTest::qWait(100);
      w_->grab().save(QString::fromLocal8Bit(dir) + "/step3-second-frame.png");
    }
  }
  // Step 5: the fit with both frames, against the first frame alone; its motion and its bound.
  void fitWithBothFrames() {
    // Step 5: the fit with both frames; the first frame is shown again there.
    QTest::keyClick(w_.get(), Qt::Key_5, Qt::AltModifier);
    QVERIFY(!w_->frameView()->secondFrameShown());
    QTest::keyClick(w_.get(), Qt::Key_F9);
    QTRY_VERIFY2_WITH_TIMEOUT(w_->caseData()->hasFit(), qPrintable(w_->findChild<QLabel*>("fitStatus")->text()),
                              180000);
    const QString status = w_->findChild<QLabel*>("fitStatus")->text();
    const auto fitted = w_->caseData();
    auto error = [&](const Pose& pose, const std::vector<Eigen::Vector3d>& nodes) {
      double sum = 0;
      for (std::size_t i = 0; i < nodes.size(); ++i)
        sum += (pose.apply(nodes[i]) - truth.apply(sagged.x.segment<3>(3 * static_cast<Eigen::Index>(i)))).norm();
      return 1e3 * sum / static_cast<double>(nodes.size());
    };
    const double two = error(fitted->pose, fitted->fit->nodes);
    // The same fit with the first frame alone (the one pipeline, without the second frame).
    app::FitInput alone = app::fitInputFromCase(*fitted);
    alone.start = start;
    const auto oneFrame = app::runElasticFit(alone);
    QVERIFY2(oneFrame.ok, oneFrame.status.c_str());
    std::vector<Eigen::Vector3d> oneNodes(c0.organ->volume.points.size());
    for (std::size_t i = 0; i < oneNodes.size(); ++i)
      oneNodes[i] = oneFrame.x.segment<3>(3 * static_cast<Eigen::Index>(i));
    const double one = error(oneFrame.pose, oneNodes);
    qInfo("second frame in the GUI: %s\n  mean node error %.2f mm with both frames, %.2f mm with the first alone",
          qPrintable(status), two, one);
    // The page says the second frame was used, how its motion was found and what it adds to the bound.
    QVERIFY2(status.contains("Second frame: camera motion from ") && status.contains("features"), qPrintable(status));
    QVERIFY2(!status.contains("was set aside") && status.contains("mm of it from the estimated camera motion"),
             qPrintable(status));
    // The motion the fit used against the one that made the second frame (the same estimate, made again here).
    const simcore::RegistrationFrame used = app::secondFrame(*fitted);
    const double turnOff = Eigen::AngleAxisd(used.motion.R * motion.R.transpose()).angle() * 180 / M_PI;
    const double directionOff =
        std::acos(std::clamp(used.motion.t.normalized().dot(motion.t.normalized()), -1.0, 1.0)) * 180 / M_PI;
    qInfo("  %zu features; the motion's turn %.3f degrees off, its direction %.3f", used.tracks.size(), turnOff,
          directionOff);
    QVERIFY(used.tracks.size() >= 100 && turnOff < 0.3 && directionOff < 0.5);
    // Its bound covers the error of the surface facing the camera (the sagged truth's), and the fit with both frames
    // stays near the one-frame fit on this phantom, whose sag the fit's own model explains exactly (on real organs
    // the second frame's gain is measured by bench_registration_real --second-frame).
    const int at = status.indexOf("Uncertainty: the surface may be up to ");
    QVERIFY(at >= 0);
    const double boundMm = status.mid(at + 38).section(' ', 0, 0).toDouble();
    std::vector<char> front(c0.organ->volume.points.size(), 0);
    for (const auto& t : c0.organ->surface) {
      const Eigen::Vector3d p0 = fitted->pose.apply(fitted->fit->nodes[t[0]]),
                            p1 = fitted->pose.apply(fitted->fit->nodes[t[1]]),
                            p2 = fitted->pose.apply(fitted->fit->nodes[t[2]]);
      if ((p1 - p0).cross(p2 - p0).dot(p0) < 0)
        for (int v : t) front[static_cast<std::size_t>(v)] = 1;
    }
    double facingSum = 0;
    int facing = 0;
    for (std::size_t i = 0; i < front.size(); ++i)
      if (front[i])
        facingSum += 1e3 * (fitted->pose.apply(fitted->fit->nodes[i]) -
                            truth.apply(sagged.x.segment<3>(3 * static_cast<Eigen::Index>(i))))
                               .norm(),
            ++facing;
    qInfo("  the facing surface %.2f mm from the truth, the bound %.2f mm", facingSum / facing, boundMm);
    QVERIFY(facing > 0 && facingSum / facing <= boundMm);
    QVERIFY(two < one + 1.5);
  }
  // Saved with the case and read back; Clear (step 2) takes the second frame away.
  void saveAndClear() {
    // Saved with the case and read back.
    const QString path = QString::fromStdString(tempPath("second-frame.rehearse"));
    ui::saveCaseFile(*w_->caseData(), path);
    const app::Case back = ui::loadCaseFile(path);
    QCOMPARE(back.frame2.cols, c0.camera.width);
    QCOMPARE(back.baselineMm, 12.0);
    QCOMPARE(back.contour2.segments.size(), std::size_t(1));
    QCOMPARE(back.contour2.segments.front().points.size(), outline2.points.size());
    QCOMPARE(cv::norm(back.frame2, w_->caseData()->frame2, cv::NORM_INF), 0.0);
    // Clear (step 2): gone, and step 3 sketches on the first frame only.
    QTest::keyClick(w_.get(), Qt::Key_2, Qt::AltModifier);
    QTest::mouseClick(w_->findChild<QPushButton*>("clearSecondFrame"), Qt::LeftButton);
    QVERIFY(w_->caseData()->frame2.empty());
    QVERIFY(!sketchOn->isEnabled());
    w_->editCase("test: the phantom's frame again", [&](app::Case& k) {
      k.rawFrame = c0.rawFrame;
      k.frame = c0.frame;
      k.contour = c0.contour;
      k.pose = c0.pose;
      k.fit = c0.fit;
      k.baselineMm = 0;
    });
  }
};
}  // namespace

// A second frame (issue 38), given as an assistant gives it: a second image with the scope moved 12 mm across (made
// from the first through the organ's surface at its true pose, so the organ's texture moves with it), opened on the
// frame page with how far the scope moved, its outline sketched with Sketch on: Second frame (the drawing goes to
// it, not to the first frame's outline), F9. The organ sags 2 g away from the camera, which one outline cannot see.
// The fit estimates the camera's motion from features tracked between the frames and uses both outlines: measured
// against the same fit with the first frame alone. Saved with the case and read back; Clear takes it away.
void TestSimulationGui::secondFrameInTheGui() {
  SecondFrameScenario s(w_);
  s.makeTheFrames();
  if (QTest::currentTestFailed()) return;
  s.openTheSecondFrame();
  if (QTest::currentTestFailed()) return;
  s.sketchOnTheSecondFrame();
  if (QTest::currentTestFailed()) return;
  s.fitWithBothFrames();
  if (QTest::currentTestFailed()) return;
  s.saveAndClear();
}

// An ambiguous fit, driven as an assistant would: an organ symmetric about the view axis (an oblate
// spheroid) outlined whole, F9. The word comes first in capitals, the alternatives are listed; choosing one
// shows the organ there over the frame; Fit from It puts the organ there (one undo step) and fits from it.
void TestSimulationGui::ambiguousFitOffersItsAlternatives() {
  const Eigen::Vector3d radii(0.05, 0.05, 0.025);
  simcore::TetrahedraliseOptions to;
  to.targetTets = 3000;
  simcore::Mesh volume = simcore::tetrahedraliseImplicit(
      [radii](const Eigen::Vector3d& p) { return p.cwiseQuotient(radii).norm() < 1 ? 1 : 0; },
      Eigen::AlignedBox3d(-radii * 1.1, radii * 1.1), to, 4.0 / 3 * M_PI * radii.prod());
  auto organ = app::Organ::fromVolume(std::move(volume), "spheroid");
  Pose pose;
  pose.t = Eigen::Vector3d(0, 0, 0.35);
  app::Case probe = *w_->caseData();
  probe.organ = organ;
  probe.fit.reset();
  const auto borders = imaging::maskOutlines(imaging::renderMask(probe.camera, pose, probe.surfaceView()));
  QVERIFY(!borders.empty());
  imaging::ContourSegment seg;
  for (std::size_t i = 0; i < borders.front().size(); i += 3) seg.points.push_back(borders.front()[i]);
  seg.closed = true;
  w_->editCase("test: a spheroid, its outline and pose", [&](app::Case& k) {
    k.organ = organ;
    k.attachments.clear();
    k.fit.reset();
    k.contour.width = k.camera.width;
    k.contour.height = k.camera.height;
    k.contour.segments = {seg};
    k.pose = pose;
    k.hasPose = true;
    k.poseAligned = true;
  });
  w_->frameView()->setFocus();
  QTest::keyClick(w_.get(), Qt::Key_5, Qt::AltModifier);
  QTest::keyClick(w_.get(), Qt::Key_F9);
  QTRY_VERIFY_WITH_TIMEOUT(w_->caseData()->hasFit(), 120000);
  auto* status = w_->findChild<QLabel*>("fitStatus");
  qInfo("%s", qPrintable(status->text()));
  QVERIFY2(status->text().startsWith("AMBIGUOUS: "), qPrintable(status->text()));
  QCOMPARE(status->palette().color(QPalette::WindowText), ui::palette::warning());  // it stands out
  {
    // On a laptop's screen (1280x800; issue 62: the paragraph was cut off top and bottom and pushed its chart off
    // the window) nothing of the page is cut off or drawn over.
    const QSize before = w_->size();
    w_->resize(1280, 800);
    QTest::qWait(200);
    QVERIFY(w_->height() <= 800);
    const QStringList problems = layoutProblems(w_.get());
    shot(*w_, "laptop-step5-ambiguous");
    QVERIFY2(problems.isEmpty(), qPrintable(problems.join("\n")));
    w_->resize(before);
  }
  auto* list = w_->findChild<QComboBox*>("fitAlternatives");
  QVERIFY(list && list->isVisible());
  const auto alternatives = w_->fitPage()->alternatives();
  QCOMPARE(list->count(), static_cast<int>(alternatives.size()) + 1);
  QVERIFY(!alternatives.empty());
  // Choosing the first alternative by keyboard shows the organ there over the frame.
  list->setFocus();
  QTest::keyClick(list, Qt::Key_Down);
  QCOMPARE(list->currentIndex(), 1);
  QVERIFY((w_->frameView()->caseData()->pose.t - alternatives[0].t).norm() < 1e-12);
  QVERIFY((w_->frameView()->caseData()->pose.R - alternatives[0].R).norm() < 1e-12);
  QVERIFY((w_->caseData()->pose.R - alternatives[0].R).norm() > 0.1);  // the case itself is unchanged
  const int undoBefore = w_->undoStack()->index();
  const Pose firstFit = w_->caseData()->pose;
  QTest::mouseClick(w_->findChild<QPushButton*>("fitFromAlternative"), Qt::LeftButton);
  QTRY_VERIFY_WITH_TIMEOUT(w_->caseData()->hasFit() && !status->text().startsWith("Fitting"), 120000);
  // From there without the rigid stage: the organ stays turned as the alternative put it.
  QVERIFY2((w_->caseData()->pose.R - alternatives[0].R).norm() < 1e-9, qPrintable(status->text()));
  QVERIFY(w_->undoStack()->index() >= undoBefore + 2);  // the pose, then the fit
  w_->undoStack()->undo();
  w_->undoStack()->undo();
  QVERIFY(w_->caseData()->hasFit());  // the first fit, at its pose
  QVERIFY((w_->caseData()->pose.R - firstFit.R).norm() < 1e-12);
  w_->undoStack()->undo();
  QVERIFY(!w_->caseData()->hasFit());
  QVERIFY(!list->isVisible());
  QVERIFY(status->palette().color(QPalette::WindowText) != ui::palette::warning());
}
