// Issue 36: the cholecystectomy-like sequence of test_operative driven with the mouse in the real main window, on a
// real organ shape over a real frame: the patient liver's CT surface (scikit-surgery) meshed (5,263 elements), a 70 mm
// cystic artery labelled through it 12 mm under the surface the laparoscope sees, imported through step 1 as an
// assistant imports a labelled model, held by three attachment patches picked with the mouse, its appearance estimated
// from the real frame (step 6); then in step 7, recorded: two clips across the artery (U, a click each; another beside
// one that does not close it), the scissors (B) across it between them (the wheel to its depth), a line burnt with the
// cautery hook (J), and the grasper (R) pulling the liver beside an attachment until it tears or slips out of the jaws,
// whichever comes first. The tear strain is set above the strain the hanging liver already has at rest (measured). Each
// instrument's effect is checked in the session (clips closing the artery, both stumps stopped by them and no blood
// lost, burnt elements, the tear or the slip with its sentence) and the recording replayed headless bit for bit with
// the trainer's metrics and incorrect actions. Skipped (or failed, with REHEARSE_REQUIRE_SHARED=1) when the shared data
// is absent. With REHEARSE_SCREENSHOT_DIR set, it saves the window after each instrument there.
#include "realorgan.hpp"
#include "test_support.hpp"
#include "window_support.hpp"

#include "rehearse/ui/composition.hpp"
#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/pages/appearancepage.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/session/field.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <QDir>
#include <QDoubleSpinBox>
#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QLabel>
#include <QLineEdit>
#include <QProcess>
#include <QRegularExpression>
#include <QPushButton>
#include <QSignalSpy>
#include <QStatusBar>
#include <QTemporaryDir>
#include <QWheelEvent>
#include <QComboBox>
#include <QtTest>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <set>

using namespace rehearse;
using ui::MainWindow;

namespace {
// cholecystectomyWithTheMouse, one method per phase of the scenario (what a phase makes, the later ones use). A failed
// QVERIFY returns from its phase: the test checks QTest::currentTestFailed() after each.
struct Cholecystectomy {
  Cholecystectomy(std::unique_ptr<MainWindow>& w, ui::SimulationPanel* panel, QTemporaryDir& dir)
      : w_(w), panel_(panel), dir_(dir) {}

  std::unique_ptr<MainWindow>& w_;
  ui::SimulationPanel* panel_;
  QTemporaryDir& dir_;
  std::string meshFile;                    // the labelled model
  std::vector<Eigen::Vector3d> line;       // the artery's centre line, camera frame at the import's pose (m)
  const simcore::Mesh* volume_ = nullptr;  // the imported organ's mesh
  std::set<int> arteryNodes;
  ui::FrameView* view = nullptr;
  std::vector<Eigen::Vector3d> rest;  // the session's rest shape, uncut
  QPushButton* record = nullptr;
  qint64 session = 0;                       // the recording's
  std::shared_ptr<const app::Case> case_;   // the case rehearsed
  QLabel* status = nullptr;                 // the rehearse page's status
  std::unique_ptr<SessionHeard> listening;  // what the session said and which events it raised (shown on failure)
  int placed = 0;                           // clips placed
  std::size_t nodesBeforeTear = 0;
  Eigen::Vector2d grip, away;  // where the grasper bites, and the way it pulls (frame pixels)
  QString ended;               // what ended the pull, as the session said it
  ActionPauses pauses{QStringLiteral("the patient liver")};  // the window's longest pause in each action

  bool stepsOn(int n, int ms = 120000) {
    const long now = panel_->lastFrame()->steps;
    return waitFor([&] { return panel_->lastFrame()->steps >= now + n; }, ms);
  }
  // A frame pixel in the view's widget coordinates.
  QPoint widget(const Eigen::Vector2d& px) const {
    return w_->frameView()->toWidget(QPointF(px.x(), px.y())).toPoint();
  }

  // The centre line's point at t, camera frame (where the frame shows the organ).
  Eigen::Vector3d onLine(double t) const {
    const double at = t * static_cast<double>(line.size() - 1);
    const std::size_t k = std::min(line.size() - 2, static_cast<std::size_t>(at));
    return Eigen::Vector3d(line[k] + (at - static_cast<double>(k)) * (line[k + 1] - line[k]));
  }

  // Where the artery is now (the organ sagged a little on its attachments): the artery node nearest the camera within
  // 10 mm of the centre line at `t` (0..1 along it), in the frame.
  Eigen::Vector2d onArtery(double t) const {
    const auto& volume = *volume_;
    const auto& c = *case_;
    const Eigen::Vector3d target = onLine(t);
    const auto f = panel_->lastFrame();
    int best = -1;
    for (int n : arteryNodes) {
      const Eigen::Vector3d& p = f->positions[static_cast<std::size_t>(n)];
      if ((c.pose.apply(volume.points[static_cast<std::size_t>(n)]) - target).norm() > 0.010) continue;
      if (best < 0 || p.z() < f->positions[static_cast<std::size_t>(best)].z()) best = n;
    }
    return c.camera.project(f->positions[static_cast<std::size_t>(best < 0 ? 0 : best)]);
  }

  // The scratch folder (kept with REHEARSE_KEEP) and the real frame.
  void openTheFrame() {
    if (qEnvironmentVariableIsSet("REHEARSE_KEEP")) {
      dir_.setAutoRemove(false);
      qInfo("kept in %s", qPrintable(dir_.path()));
    }
    // The real frame and its laparoscope's intrinsics.
    {
      const QString why = openFrameWithIntrinsics(*w_, sharedData("scikit-surgery/laparoscopy-liver-frame.jpg"),
                                                  sharedData("scikit-surgery/laparoscopy-liver-frame.intrinsics.txt"));
      QVERIFY2(why.isEmpty(), qPrintable(why));
    }
  }

  void labelTheArtery() {
    // The labelled model: the CT surface meshed, and where the import will place it (its automatic pose) a cystic
    // artery labelled along the organ's middle row in the image, its centre line 12 mm under the surface seen there.
    meshFile = (dir_.path() + "/liver-artery.msh").toStdString();
    {
      simcore::TetrahedraliseOptions to;
      to.allowSelfIntersections = true;
      to.targetTets = 6000;
      simcore::Mesh m = simcore::tetrahedraliseSurface(
          rehearse::testing::loadOrganSurface(sharedData("scikit-surgery/patient-liver/liver.vtk")), to);
      app::Case probe = *w_->caseData();
      probe.setOrgan(app::Organ::fromVolume(m));
      const imaging::Camera& cam = probe.camera;
      double x0 = 1e9, x1 = -1e9;
      for (const auto& p : m.points) {
        const double x = cam.project(probe.pose.apply(p)).x();
        x0 = std::min(x0, x), x1 = std::max(x1, x);
      }
      const Eigen::Vector2d middle = cam.project(probe.pose.apply(probe.organ->centreOfGravity));
      for (int k = 0; k <= 16; ++k) {
        const Eigen::Vector2d px(middle.x() + (k / 16.0 - 0.5) * 0.25 * (x1 - x0), middle.y());
        const auto hit = imaging::pickSurface(cam, probe.pose, probe.surfaceView(), px);
        QVERIFY2(hit, "the artery's row leaves the organ");
        const double z = hit->depth + 0.012;
        line.emplace_back((px.x() - cam.cx()) / cam.fx() * z, (px.y() - cam.cy()) / cam.fy() * z, z);
      }
      // The longest run without a jump in depth (the surface seen along the row folds over itself in places).
      {
        std::size_t from = 0, best = 0, bestLength = 0;
        for (std::size_t k = 1; k <= line.size(); ++k)
          if (k == line.size() || std::abs(line[k].z() - line[k - 1].z()) > 0.02) {
            if (k - from > bestLength) best = from, bestLength = k - from;
            from = k;
          }
        line = std::vector<Eigen::Vector3d>(line.begin() + static_cast<long>(best),
                                            line.begin() + static_cast<long>(best + bestLength));
      }
      QVERIFY(line.size() >= 2 && (line.back() - line.front()).norm() > 0.05);
      auto distance = [&](const Eigen::Vector3d& q) {
        double d = 1e9;
        for (std::size_t k = 0; k + 1 < line.size(); ++k) {
          const Eigen::Vector3d a = line[k], ab = line[k + 1] - a;
          const double s = std::clamp((q - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
          d = std::min(d, (q - (a + s * ab)).norm());
        }
        return d;
      };
      int artery = 0;
      for (std::size_t t = 0; t < m.tets.size(); ++t) {
        Eigen::Vector3d q = Eigen::Vector3d::Zero();
        for (int k : m.tets[t]) q += probe.pose.apply(m.points[static_cast<std::size_t>(k)]) / 4;
        if (distance(q) < 0.007) m.tetLabels[t] = 2, ++artery;
      }
      // In one piece (its elements joined by shared nodes): a clip stops the stumps of its own piece only.
      std::vector<int> root(m.points.size());
      std::iota(root.begin(), root.end(), 0);
      std::function<int(int)> find = [&](int v) {
        return root[static_cast<std::size_t>(v)] == v
                   ? v
                   : root[static_cast<std::size_t>(v)] = find(root[static_cast<std::size_t>(v)]);
      };
      for (std::size_t t = 0; t < m.tets.size(); ++t)
        if (m.tetLabels[t] == 2)
          for (int k = 1; k < 4; ++k)
            root[static_cast<std::size_t>(find(m.tets[t][static_cast<std::size_t>(k)]))] = find(m.tets[t][0]);
      std::set<int> pieces;
      for (std::size_t t = 0; t < m.tets.size(); ++t)
        if (m.tetLabels[t] == 2) pieces.insert(find(m.tets[t][0]));
      QCOMPARE(pieces.size(), std::size_t(1));
      m.setLabelName(1, "liver");
      m.setLabelName(2, "cystic artery");
      qInfo("the patient liver: %zu elements; the cystic artery: %d elements along %.0f mm, 12 mm deep", m.tets.size(),
            artery, 1e3 * (line.back() - line.front()).norm());
      QVERIFY(artery > 15);
      simcore::saveMesh(m, meshFile);
    }
  }

  void importTheModel() {
    // Imported through step 1 (in metres, as written): the labels come with it, the artery a structure of its kind.
    w_->meshPage()->setMeshUnit("m");
    QSignalSpy imported(w_.get(), &MainWindow::meshImported);
    w_->meshPage()->importMesh(QString::fromStdString(meshFile));
    QVERIFY(imported.wait(180000));
    QVERIFY2(imported.first().at(0).toBool(), qPrintable(imported.first().at(1).toString()));
    volume_ = &w_->caseData()->organ->volume;
    const auto& volume = *volume_;
    QCOMPARE(volume.labelName(2), std::string("cystic artery"));
    QCOMPARE(simcore::structureKindName(volume.labelKind(2)), "artery");
    for (std::size_t t = 0; t < volume.tets.size(); ++t)
      if (volume.tetLabels[t] == 2) arteryNodes.insert(volume.tets[t].begin(), volume.tets[t].end());
    w_->editCase("Accept the import's placement (test)", [](app::Case& c) { c.hasPose = c.poseAligned = true; });
    view = w_->frameView();
    view->setFocus();
  }

  void attachTheRim() {
    // Three attachment patches of 30 mm along the upper rim (H, a click each), where ligaments hold a liver: fewer or
    // smaller ones concentrate its weight (three of 20 mm stretch the tissue beside them by 122 % at rest).
    {
      QTest::keyClick(w_.get(), Qt::Key_1, Qt::AltModifier);
      QTest::keyClick(w_.get(), Qt::Key_H);
      QCOMPARE(view->tool(), ui::Tool::Attachments);
      w_->findChild<QDoubleSpinBox*>("attachmentRadius")->setValue(30);
      const auto k = w_->caseData();
      const cv::Mat1b mask = imaging::renderMask(k->camera, k->pose, k->surfaceView());
      int left = mask.cols, right = -1;
      for (int y = 0; y < mask.rows; ++y)
        for (int x = 0; x < mask.cols; ++x)
          if (mask(y, x)) left = std::min(left, x), right = std::max(right, x);
      for (double at : {0.2, 0.5, 0.8}) {
        const int x = left + static_cast<int>(at * (right - left));
        int top = 0;
        while (top < mask.rows && !mask(top, x)) ++top;
        const std::size_t before = w_->caseData()->attachments.size();
        QTest::mouseClick(view, Qt::LeftButton, {}, widget(Eigen::Vector2d(x, top + 25)));
        QVERIFY2(w_->caseData()->attachments.size() > before,
                 qPrintable(QString("the click at (%1, %2) px attached nothing: %3")
                                .arg(x)
                                .arg(top + 25)
                                .arg(w_->statusBar()->currentMessage())));
      }
      qInfo("%zu attachment nodes", w_->caseData()->attachments.size());
    }
  }

  void estimateAndSave() {
    // Step 6 on the real frame, for the composited view.
    QTest::keyClick(w_.get(), Qt::Key_6, Qt::AltModifier);
    {
      QSignalSpy estimated(w_->appearancePage(), &ui::AppearancePage::estimated);
      QTest::keyClick(w_.get(), Qt::Key_F10);
      QVERIFY(estimated.wait(120000));
      QVERIFY2(estimated.first().at(0).toBool(), qPrintable(estimated.first().at(1).toString()));
    }
    QVERIFY(waitFor([&] { return w_->composition()->ready(); }, 60000));
    // Saved (a recording goes into the case file), then step 7, recorded under the trainee's name.
    {
      QSignalSpy saved(w_.get(), &MainWindow::caseSaved);
      w_->saveCaseAs(dir_.path() + "/chole.rehearse");
      QVERIFY(saved.wait(60000));
      QVERIFY(saved.first().at(0).toBool());
    }
  }

  void startRecording() {
    const auto& volume = *volume_;
    // This scenario's organ hangs on its three rim patches under gravity down the image, as it was designed (clips,
    // cut and bleeding, its tear strain set above the hanging's): the panel's gravity and support set so, as an
    // assistant would (the defaults since issue 61: into the scene, carried by the tissue around it).
    panel_->findChild<QComboBox*>("simGravity")->setCurrentIndex(0);
    panel_->findChild<QDoubleSpinBox*>("simSupport")->setValue(0);
    QTest::keyClick(w_.get(), Qt::Key_7, Qt::AltModifier);
    QCOMPARE(w_->step(), ui::Step::Rehearse);
    QVERIFY(w_->showingComposited());
    const std::size_t nodes = volume.points.size();
    QVERIFY(waitFor(
        [&] {
          return panel_->lastFrame() && panel_->lastFrame()->positions.size() == nodes &&
                 panel_->lastFrame()->steps > 10;
        },
        180000));
    // How far the tissue is stretched already (the largest principal stretch over the elements) from where a tear
    // measures it: where the organ started (BodySetup::tearFrom, issue 61: the registered shape it starts in
    // equilibrium at), else its rest shape. A liver hung on three patches of its rim sags and stretches beside them
    // (59-122 % from its rest shape), so the tear strain is set above what the tissue has at rest, and only the pull
    // tears it. (Measured from the rest shape after tears were measured from the start, it set 110 %: the jaws slipped
    // first with the tissue at 235 % from its start.)
    auto largestStrain = [&] {
      const auto& setup = panel_->session()->setup();
      const auto& from = setup.tearFrom.size() == setup.rest.size() ? setup.tearFrom : setup.rest;
      const auto f = panel_->lastFrame();
      double largest = 0;
      for (const auto& t : setup.mesh.tets) {
        Eigen::Matrix3d Dm, Ds;
        for (int k = 0; k < 3; ++k) {
          const auto a0 = static_cast<std::size_t>(t[0]),
                     ak = static_cast<std::size_t>(t[static_cast<std::size_t>(k + 1)]);
          Dm.col(k) = from[ak] - from[a0];
          Ds.col(k) = f->positions[ak] - f->positions[a0];
        }
        largest = std::max(largest, Eigen::JacobiSVD<Eigen::Matrix3d>(Ds * Dm.inverse()).singularValues()(0) - 1);
      }
      return largest;
    };
    const double atRest = largestStrain();
    rest = panel_->session()->setup().rest;  // the session's rest shape, uncut
    // At least 100 %: a clip closing this coarse mesh's 18-19 mm elements over a 4-10 mm artery squeezes them to half
    // and stretches the tissue beside them by 31-60 % and more (measured: torn at 60 % as the first clip closed), and
    // the clips, the cut and the burn are not to tear it; the grasp's pull is.
    const int tearPercent = std::max(100, static_cast<int>(std::ceil(100 * atRest / 10) * 10) + 20);
    qInfo("%s; the tissue stretched up to %.0f %% at rest: it tears at %d %%", qPrintable(panel_->startSentence()),
          100 * atRest, tearPercent);
    auto* tears = panel_->findChild<QDoubleSpinBox*>("simTearStrain");
    tears->setFocus();
    typeInto(tears, QString::number(tearPercent));
    QVERIFY(waitFor([&] { return std::abs(w_->caseData()->material.tearStrain - tearPercent / 100.0) < 1e-9; }));
    // The clip applier's jaws as long as the panel allows (20 mm): the artery is as thick as this mesh's elements.
    auto* clipLength = panel_->findChild<QDoubleSpinBox*>("simClipLength");
    clipLength->setFocus();
    typeInto(clipLength, QStringLiteral("20"));
    QCOMPARE(clipLength->value(), 20.0);
    QTest::keyClicks(w_->findChild<QLineEdit*>("traineeName"), "A. Surgeon");
    record = w_->findChild<QPushButton*>("recordButton");
    QTest::mouseClick(record, Qt::LeftButton);
    QVERIFY2(w_->recording(), qPrintable(w_->messageLog().join(" | ")));
    QVERIFY(waitFor(
        [&] {
          return panel_->recordingId() > 0 && panel_->lastFrame()->positions.size() == nodes &&
                 panel_->lastFrame()->steps > 10;
        },
        180000));
    session = panel_->recordingId();
    case_ = w_->caseData();
    status = w_->rehearsePage()->findChild<QLabel*>("rehearseStatus");
    view->setFocus();
  }

  void clipTheArtery() {
    listening = std::make_unique<SessionHeard>(panel_);
    // Two clips across the artery (U, a click each), one near each end. On this coarse mesh the artery is as thick as
    // its elements, and a clip closed where they stick out past the jaws does not close it (said; a misplaced clip the
    // trainer counts): as a surgeon does, another is placed beside it until one closes the artery there.
    QTest::keyClick(w_.get(), Qt::Key_U);
    QCOMPARE(view->tool(), ui::Tool::Clip);
    std::vector<Eigen::Vector2d> clipped;  // where the closing ones were placed (frame pixels)
    for (const auto& tries :
         {std::vector<double>{0.1, 0.15, 0.05, 0.2, 0.25}, std::vector<double>{0.9, 0.85, 0.95, 0.8, 0.75}}) {
      for (double t : tries) {
        const std::size_t before = panel_->lastFrame()->field.clips.size();
        const QString was = status->text();
        const Eigen::Vector2d at = onArtery(t);
        const QPoint click = widget(at);
        pauses.start();
        QTest::mouseClick(view, Qt::LeftButton, {}, click);
        QVERIFY2(waitFor([&] { return panel_->lastFrame()->field.clips.size() == before + 1; }),
                 qPrintable(w_->statusBar()->currentMessage() + " | " + status->text()));
        ++placed;
        QVERIFY2(w_->statusBar()->currentMessage().contains("aimed at the cystic artery"),
                 qPrintable(w_->statusBar()->currentMessage()));
        QVERIFY(waitFor([&] { return status->text() != was && status->text().contains("clip"); }, 10000));
        pauses.stop("clip");
        const auto& clip = panel_->lastFrame()->field.clips.back();
        qInfo("clip at %.2f of the artery, on label %d, %zu nodes: %s", t, clip.label, clip.nodes.size() + 1,
              qPrintable(status->text()));
        QCOMPARE(clip.label, 2);
        QCOMPARE(status->text().contains("does not close it"), !clip.spans);
        if (clip.spans) {
          clipped.push_back(at);
          break;
        }
      }
    }
    QCOMPARE(clipped.size(), std::size_t(2));
    shot(*w_, "liver-clips");
  }

  void cutBetweenTheClips() {
    QStringList& heard = listening->lines;
    const auto& volume = *volume_;
    const auto& c = *case_;
    // The scissors across the artery between the clips (B; press beside it, the wheel to its depth, drag across).
    QTest::keyClick(w_.get(), Qt::Key_B);
    QCOMPARE(view->tool(), ui::Tool::Scissors);
    {
      // Across the centre line's middle, 60 px (16 mm) either side: only faces wholly inside the blade's sweep open,
      // and this mesh's are 15-20 mm.
      const Eigen::Vector2d m = c.camera.project(onLine(0.5)),
                            d = (c.camera.project(line.back()) - c.camera.project(line.front())).normalized();
      Eigen::Vector2d n(-d.y(), d.x());
      QPoint a = widget(m - 60 * n), b = widget(m + 60 * n);
      const auto hit = [&](const Eigen::Vector2d& px) {  // the surface the view shows there: its depth (mm)
        const auto f = panel_->lastFrame();
        SurfaceView sv = c.surfaceView();
        std::vector<double> now(3 * f->positions.size());
        for (std::size_t i = 0; i < f->positions.size(); ++i)
          for (int k = 0; k < 3; ++k) now[3 * i + static_cast<std::size_t>(k)] = f->positions[i][k];
        sv.vertices = now.data();
        const auto h = imaging::pickSurface(c.camera, Pose(), sv, px);
        return h ? 1e3 * h->depth : -1.0;
      };

      // The press on the side whose surface lies nearer the artery's (the other side can fall on a fold of the liver
      // farther back: CI once pressed where the surface was 44 mm behind the artery's and cut under it).
      const double over = hit(m);
      if (std::abs(hit(m + 60 * n) - over) < std::abs(hit(m - 60 * n) - over)) std::swap(a, b), n = -n;
      // The artery's depth where it is now (its nodes within 10 mm of the centre line's middle, as the session has
      // them): the organ sags on its attachments, by more or less as the machine runs fewer or more steps.
      double arteryAt = 0;
      {
        const auto f = panel_->lastFrame();
        int count = 0;
        for (int k : arteryNodes)
          if ((c.pose.apply(volume.points[static_cast<std::size_t>(k)]) - onLine(0.5)).norm() < 0.010)
            arteryAt += 1e3 * f->positions[static_cast<std::size_t>(k)].z(), ++count;
        QVERIFY(count > 0);
        arteryAt /= count;
      }
      // The blade goes in 20 mm behind the pressed surface, spans 30 mm back from there, and the wheel takes it 2 mm
      // deeper a notch (or shallower): as a surgeon does, the notches that put the artery's centre in the blade's
      // middle, and while the artery is not cut (the session says nothing was cut, or the cut missed it: one face
      // opened above it, in one run of four), a stroke again 4 mm deeper (as it asks).
      const double pressedAt = hit(m - 60 * n);
      int notches = std::clamp(static_cast<int>(std::lround((arteryAt + 15 - pressedAt - 20) / 2)), -30, 10);
      for (int stroke = 0; stroke < 4; ++stroke, notches += 2) {
        qInfo(
            "scissors: pressing where the surface is %.0f mm deep, the artery's centre %.0f mm deep under a surface "
            "%.0f mm deep: %d notches deeper",
            hit(m - 60 * n), arteryAt, hit(m), notches);
        pauses.start();
        QTest::mousePress(view, Qt::LeftButton, {}, a);
        QVERIFY2(waitFor([&] { return panel_->lastFrame()->tool.cutting; }, 20000),
                 qPrintable(w_->statusBar()->currentMessage()));
        heard.clear();
        wheelDeeper(view, a, notches);
        for (int i = 1; i <= 12; ++i) {
          QTest::mouseMove(view, a + (b - a) * (i / 12.0));
          QVERIFY(stepsOn(3));
        }
        QTest::mouseRelease(view, Qt::LeftButton, {}, b);
        QVERIFY(waitFor([&] { return !panel_->lastFrame()->tool.cutting; }));
        const auto said = [&] { return heard.join(" | "); };
        QVERIFY2(waitFor(
                     [&] {
                       return !panel_->lastFrame()->field.bleeds.empty() || said().contains("Nothing was cut") ||
                              said().contains("The cut is done");
                     },
                     60000),
                 qPrintable(said()));
        pauses.stop("cut");
        if (!panel_->lastFrame()->field.bleeds.empty() || said().contains("A cystic artery was cut")) break;
      }
    }
    pauses.start();
    QVERIFY2(waitFor([&] { return !panel_->lastFrame()->field.bleeds.empty(); }, 60000), qPrintable(heard.join(" | ")));
    QVERIFY(stepsOn(10));
    pauses.stop("cut");
    {
      const auto f = panel_->lastFrame();
      int stopped = 0;
      for (const auto& b : f->field.bleeds) stopped += b.stoppedBy >= 0;
      qInfo("cut between the clips: %zu cut faces, %zu stumps, %d stopped by a clip; %.3f mL lost; %s",
            f->surface->cutCount, f->field.bleeds.size(), stopped, 1e6 * f->field.bloodLoss,
            qPrintable(status->text()));
      for (const auto& b : f->field.bleeds) {
        QString behind;
        for (const auto& clip : f->field.clips)
          behind += QString(" %1").arg(
              1e3 * (f->surface->rest[static_cast<std::size_t>(clip.anchor)] - b.at).dot(b.normal), 0, 'f', 1);
        qInfo("  stump: %.1f mm^2, normal (%.2f, %.2f, %.2f), stopped by %d; clips along its normal (mm):%s",
              1e6 * b.area, b.normal.x(), b.normal.y(), b.normal.z(), b.stoppedBy, qPrintable(behind));
      }
      QCOMPARE(stopped, static_cast<int>(f->field.bleeds.size()));
      QCOMPARE(f->field.bloodLoss, 0.0);
    }
    shot(*w_, "liver-clip-cut");
  }

  void burnALine() {
    const auto& c = *case_;
    // The cautery hook (J): a line burnt on the liver 25 % of its height below the artery, away from it.
    QTest::keyClick(w_.get(), Qt::Key_J);
    QCOMPARE(view->tool(), ui::Tool::Cautery);
    double y0 = 1e9, y1 = -1e9;  // the organ's rows in the frame
    for (const auto& p : panel_->lastFrame()->positions) {
      const double y = c.camera.project(p).y();
      y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
    {
      const Eigen::Vector2d from = c.camera.project(onLine(0.4)) + Eigen::Vector2d(0, 0.25 * (y1 - y0)),
                            to = c.camera.project(onLine(0.6)) + Eigen::Vector2d(0, 0.25 * (y1 - y0));
      const QPoint pressed = widget(from);
      pauses.start();
      QTest::mousePress(view, Qt::LeftButton, {}, pressed);
      QVERIFY2(waitFor([&] { return panel_->lastFrame()->field.energy; }),
               qPrintable(w_->statusBar()->currentMessage()));
      QVERIFY(stepsOn(25));  // (the hook burns what it holds for 0.2 s: a line of dwells on this mesh)
      for (int i = 1; i <= 4; ++i) {
        QTest::mouseMove(view, widget(from + (to - from) * (i / 4.0)));
        QVERIFY(stepsOn(25));
      }
      QTest::mouseRelease(view, Qt::LeftButton, {}, widget(to));
      QVERIFY(waitFor([&] { return !panel_->lastFrame()->field.energy; }));
      QVERIFY(stepsOn(5));
      pauses.stop("cautery");
      const auto f = panel_->lastFrame();
      const long burnt = f->labels ? std::count_if(f->labels->begin(), f->labels->end(), simcore::isBurnt) : 0;
      qInfo("cautery: %ld elements burnt, energy on tissue %.2f s", burnt, f->field.energyTime);
      QVERIFY(burnt > 0);
      // The burn is drawn along the hook's path (issue 61: a flat polygon of the burnt elements' faces, not a line):
      // the trail the view keeps has the stroke's points on the tissue the powered tip went over, one stroke, as long
      // in the frame as the drag at least (the tissue the shaft pushes moves with the hook, and the trail with the
      // tissue).
      const auto& trail = view->burnTrail();
      QVERIFY2(trail.size() >= 4, qPrintable(QStringLiteral("%1 trail points; %2 s of energy on tissue")
                                                  .arg(trail.size())
                                                  .arg(f->field.energyTime)));
      Eigen::AlignedBox2d extent;
      double off = 0;  // px: the trail's farthest point from the drag
      for (const auto& t : trail) {
        QCOMPARE(t.stroke, trail.front().stroke);
        Eigen::Vector3d x = Eigen::Vector3d::Zero();
        for (int k = 0; k < 3; ++k)
          x += t.weights[k] * f->positions[static_cast<std::size_t>(t.nodes[static_cast<std::size_t>(k)])];
        extent.extend(c.camera.project(x));
        const Eigen::Vector2d q = c.camera.project(x);
        const double s = std::clamp((q - from).dot(to - from) / (to - from).squaredNorm(), 0.0, 1.0);
        off = std::max(off, (q - (from + s * (to - from))).norm());
      }
      const double dragged = (to - from).norm();
      qInfo("the burn's trail: %zu points over %.0f x %.0f px of the frame, for a drag of %.0f px; at most %.0f px "
            "from it",
            trail.size(), extent.sizes().x(), extent.sizes().y(), dragged, off);
      QVERIFY(extent.sizes().norm() >= 0.5 * dragged);
    }
    shot(*w_, "liver-cautery");
  }

  void graspBesideAnAttachment() {
    QStringList& heard = listening->lines;
    const auto& c = *case_;
    // The grasper (R) beside a ligament's attachment, where the liver's weight stretches it most, pulled away from the
    // attachment until the tissue tears (pulled elsewhere, this heavy coarse liver slips out of the jaws at the scene's
    // 15 N first: three bites below the artery slipped at 16-20 N). The jaws on a surface node the camera sees that
    // shares an element with an attached node (the jaws hold the nodes within their bite; this mesh's nodes are about
    // 15 mm apart), the most stretched such element's; the pull along the frame from the attached node to it.
    QTest::keyClick(w_.get(), Qt::Key_R);
    QCOMPARE(view->tool(), ui::Tool::Grasp);
    nodesBeforeTear = panel_->lastFrame()->positions.size();
    grip = Eigen::Vector2d::Zero(), away = Eigen::Vector2d::UnitY();
    {
      const auto f = panel_->lastFrame();
      const auto& fixedNodes = panel_->session()->setup().fixedNodes;  // the attachments as the session holds them
      std::set<int> fixed(fixedNodes.begin(), fixedNodes.end()), surface;
      qInfo("attachments: %zu in the case, %zu in the session", c.attachments.size(), fixedNodes.size());
      for (const auto& t : c.organ->surface) surface.insert(t.begin(), t.end());
      // The surface the grasper picks on (the view's live shape, cut): the jaws bite at the nearest node of the
      // triangle under the cursor, which must be the free node.
      const auto& live = view->liveShape();
      QVERIFY(view->liveSurface() && live.size() >= c.organ->volume.points.size());
      SurfaceView sv = c.surfaceView();
      sv.triangles = view->liveSurface()->triangles.front().data();
      sv.triangleCount = view->liveSurface()->triangles.size();
      sv.vertexCount = live.size();
      std::vector<double> now;
      for (const auto& x : live) now.insert(now.end(), {x.x(), x.y(), x.z()});
      sv.vertices = now.data();
      double most = -1;
      for (const auto& t : c.organ->volume.tets) {
        Eigen::Matrix3d Dm, Ds;
        for (int k = 0; k < 3; ++k) {
          const auto a0 = static_cast<std::size_t>(t[0]),
                     ak = static_cast<std::size_t>(t[static_cast<std::size_t>(k + 1)]);
          Dm.col(k) = rest[ak] - rest[a0];
          Ds.col(k) = f->positions[ak] - f->positions[a0];
        }
        const double strain = Eigen::JacobiSVD<Eigen::Matrix3d>(Ds * Dm.inverse()).singularValues()(0) - 1;
        if (strain <= most) continue;
        for (int held : t)
          for (int free : t) {
            if (!fixed.count(held) || fixed.count(free) || !surface.count(free)) continue;
            const Eigen::Vector3d& p = f->positions[static_cast<std::size_t>(free)];
            const Eigen::Vector2d q = c.camera.project(p);
            // Where the press lands: the widget's whole pixel back in the frame (near the rim, a pixel off the organ).
            const QPointF back = view->toFrame(QPointF(widget(q)));
            const auto seen = imaging::pickSurface(c.camera, Pose(), sv, Eigen::Vector2d(back.x(), back.y()));
            if (!seen || seen->nearestVertex != free) continue;  // hidden, off the organ, or another node bitten
            const Eigen::Vector2d from = c.camera.project(f->positions[static_cast<std::size_t>(held)]);
            if ((q - from).norm() < 5) continue;
            most = strain, grip = q, away = (q - from).normalized();
          }
      }
      QVERIFY2(most >= 0, "no surface node beside an attachment is in view");
      qInfo("grasp beside an attachment, on an element stretched %.0f %%", 100 * most);
    }
    heard.clear();
    QSignalSpy said(view, &ui::FrameView::toolMessage);  // what the grasper says when pressed (the status bar forgets)
    const QPoint bite = widget(grip);
    pauses.start();
    QTest::mouseMove(view, bite);
    // (a press soon after the hook's release would be taken for a double click: a hand takes longer)
    QTest::mousePress(view, Qt::LeftButton, {}, bite, 1000);
    const long pressedAtStep = panel_->lastFrame()->steps;
    if (!waitFor([&] { return !panel_->lastFrame()->tool.held.empty(); }, 30000)) {
      w_->grab().save(QDir::temp().filePath("operative-gui-grasp-failed.png"));
      qInfo("the grasper's tool: %d; its sentences: %lld", static_cast<int>(view->tool()),
            static_cast<long long>(said.count()));
    }
    QVERIFY2(waitFor([&] { return !panel_->lastFrame()->tool.held.empty(); }, 30000),
             qPrintable(QString("at (%1, %2) px, step %3 (now %4): ")
                            .arg(grip.x())
                            .arg(grip.y())
                            .arg(pressedAtStep)
                            .arg(panel_->lastFrame()->steps) +
                        (said.isEmpty() ? QString("the grasper said nothing") : said.last().at(0).toString()) + " | " +
                        status->text() + " | " + heard.join(" | ")));
    QVERIFY(stepsOn(3));
    pauses.stop("grasp");
  }

  void pullUntilItTearsOrSlips() {
    QStringList& heard = listening->lines;
    const auto& c = *case_;
    // Pulled 6 px (1.6 mm) a move until the tissue tears or slips out of the jaws, whichever comes first (the scene's
    // grasp holds 15 N, the liver's own weight: on this liver, pulled beside its attachment, the jaws slipped at 27 N
    // after 3 mm, before the element there, stretched 59-67 % at rest, reached the 90 % it tears at).
    int slips = 0, torn = 0;
    Eigen::Vector2d last = grip;
    const quint64 paintsBefore = view->paints(), scaledBefore = view->paintsFromScaled();
    pauses.start();
    for (int i = 1; i <= 150 && ended.isEmpty(); ++i) {
      last = grip + 6.0 * i * away;
      QTest::mouseMove(view, widget(last));
      QVERIFY(stepsOn(3));
      const auto f = panel_->lastFrame();
      for (const auto& e : f->events) {
        torn += e == "tear";
        slips += e == "slip";
      }
      // (A frame shown carries its own step's events only: a tear on a step between two frames is heard, not seen in
      // the last frame. A person stops pulling on the sentence; the pull had gone on 900 px, out of the view.)
      const bool said = std::any_of(heard.begin(), heard.end(), [](const QString& l) {
        return l.contains(" tore") || l.contains("slipped");
      });
      if (torn + slips > 0 || f->tool.held.empty() || said) ended = status->text();
      if (i % 20 == 0) qInfo("pulled %d px: %.1f N; %s", 6 * i, f->tool.force.norm(), qPrintable(status->text()));
    }
    // What ended it, as the session said it (the page's line may already say something newer).
    QVERIFY2(waitFor(
                 [&] {
                   for (const auto& said : heard)
                     if (said.contains(" tore") || said.contains("slipped")) return ended = said, true;
                   return false;
                 },
                 10000),
             qPrintable(heard.join(" | ")));
    qInfo("pulled %.0f px of the frame (%.1f mm at the organ): %s", (last - grip).norm(),
          1e3 * (last - grip).norm() * onLine(0.5).z() / c.camera.fx(), qPrintable(ended));
    for (const auto& said : heard)
      if (said.contains("tear") || said.contains("slip")) qInfo("  %s", qPrintable(said));
    auto* force = w_->rehearsePage()->findChild<QLabel*>("rehearseForce");
    if (ended.contains("tore")) {
      QVERIFY(waitFor([&] { return panel_->lastFrame()->positions.size() > nodesBeforeTear; },
                      60000));  // torn: the tear's faces get their own nodes
      QVERIFY2(waitFor([&] { return force->text().contains("TORN"); }, 30000), qPrintable(force->text()));
      // Every tear's sentence is in the Messages panel: as many as the page counts (a person read 5 against 6).
      const auto tornCount = [&] {
        return QRegularExpression(QStringLiteral("TORN: ([0-9]+)")).match(force->text()).captured(1).toLongLong();
      };
      const auto tearSentences = [&] { return static_cast<long long>(w_->messageLog().filter(" tore: stretched").size()); };
      QVERIFY2(waitFor([&] { return tornCount() > 0 && tornCount() == tearSentences(); }, 10000),
               qPrintable(QStringLiteral("%1 against %2 sentences").arg(force->text()).arg(tearSentences())));
    } else {
      // The sentence says why the jaws let go, with the force, above the grasp's limit.
      const QRegularExpression at(
          QStringLiteral("slipped out of the grasper at ([0-9.]+) N \\(the scene's maximum grasp "
                         "force is ([0-9.]+) N\\)"));
      const auto m = at.match(ended);
      QVERIFY2(m.hasMatch(), qPrintable(ended));
      // At the limit, within one step's change (issue 61: the jaws let go where the force reaches it, to first order
      // from the last step: 14.2 and 15.3 N seen for 15 N; before that the slip came at 27-39 N). It asserted "above"
      // and failed on a fresh clone when the jaws let go at 14.2 N.
      QVERIFY2(std::abs(m.captured(1).toDouble() - m.captured(2).toDouble()) <= 0.25 * m.captured(2).toDouble(),
               qPrintable(ended));
      QVERIFY(panel_->lastFrame()->tool.held.empty());
      // The status bar says it too (it had kept "Grasped: drag to pull" beside the page's "closed on nothing").
      QVERIFY2(waitFor([&] { return w_->statusText().contains("slipped out of the grasper"); }, 5000),
               qPrintable(w_->statusText()));
      // As a person sees the status bar: its temporary message when there is one (the grasper's "Grasped: drag to
      // pull" hid the slip's sentence for 10 s), else the case's line.
      const QString seen =
          w_->statusBar()->currentMessage().isEmpty() ? w_->statusText() : w_->statusBar()->currentMessage();
      QVERIFY2(seen.contains("slipped out of the grasper"), qPrintable(seen));
      // And the Messages panel keeps it once (it was logged twice: as the status bar's line and as the simulation's).
      const QString slip = m.captured(0);
      const QStringList log = w_->messageLog();
      const auto logged = std::count_if(log.begin(), log.end(), [&](const QString& l) { return l.contains(slip); });
      QVERIFY2(logged == 1, qPrintable(log.join(" | ")));
    }
    QVERIFY(stepsOn(10));
    pauses.stop(ended.contains("tore") ? "pull and tear" : "pull and slip");
    // The composited frames came scaled to the view from the composition's worker: the GUI thread drew them as they
    // were (issue 64: drawing each new 1920x1080 frame through the painter's transform took it 5 ms median, 13 ms p99).
    const quint64 paints = view->paints() - paintsBefore, scaled = view->paintsFromScaled() - scaledBefore;
    qInfo("the frame view painted %llu times in the pull, %llu of them from the worker's scaled frame",
          static_cast<unsigned long long>(paints), static_cast<unsigned long long>(scaled));
    QVERIFY(paints >= 20);
    QVERIFY2(scaled >= 0.9 * static_cast<double>(paints), qPrintable(QString::number(scaled)));
    shot(*w_, "liver-tear");
    const QPoint released = widget(last);
    pauses.start();
    QTest::mouseRelease(view, Qt::LeftButton, {}, released);
    QVERIFY(stepsOn(5));
    pauses.stop("release");
    QTest::mouseClick(record, Qt::LeftButton);  // stop
    QVERIFY2(!w_->recording(), qPrintable(w_->messageLog().join(" | ")));
    panel_->pause();
  }

  void replayHeadless() {
    // Headless: replayed bit for bit, with the trainer's metrics and incorrect actions.
    QProcess p;
    const QString metricsFile = dir_.path() + "/metrics.json";
    p.start(QStringLiteral(REHEARSE_BINARY), {"replay", dir_.path() + "/chole.rehearse", "--session",
                                              QString::number(session), "--verify", "--metrics", metricsFile});
    QVERIFY(p.waitForFinished(900000));
    const QString out = QString::fromUtf8(p.readAllStandardOutput()), err = QString::fromUtf8(p.readAllStandardError());
    QVERIFY2(p.exitCode() == 0, qPrintable(out + err));
    QVERIFY2(out.contains("checksums match"), qPrintable(out));
    QFile mf(metricsFile);
    QVERIFY(mf.open(QIODevice::ReadOnly));
    const QJsonObject metrics = QJsonDocument::fromJson(mf.readAll()).object();
    QStringList listed;
    for (const auto& a : metrics["incorrect_action_list"].toArray())
      listed << QString("%1 s %2").arg(a.toObject()["time_s"].toDouble()).arg(a.toObject()["rule"].toString());
    qInfo(
        "replayed: %s\nmetrics: clips %d (misplaced %d), vessel cuts %d (without clips %d), blood lost %.3f mL, energy "
        "%.2f s, tears %d; incorrect actions %d (%s), outside the view %d",
        qPrintable(out.trimmed().replace('\n', " / ")), metrics["clips"].toInt(), metrics["misplaced_clips"].toInt(),
        metrics["vessel_cuts"].toInt(), metrics["vessel_cuts_without_clips"].toInt(-1),
        metrics["blood_loss_ml"].toDouble(), metrics["energy_time_s"].toDouble(), metrics["tears"].toInt(),
        metrics["incorrect_actions"].toInt(-1), qPrintable(listed.join(", ")),
        metrics["instrument_outside_view"].toInt(-1));
    QCOMPARE(metrics["clips"].toInt(), placed);
    QCOMPARE(metrics["misplaced_clips"].toInt(), placed - 2);
    QCOMPARE(listed.filter("clip_misplaced").size(), placed - 2);
    QVERIFY(metrics["vessel_cuts"].toInt() >= 1);
    QCOMPARE(metrics["vessel_cuts_without_clips"].toInt(-1), 0);
    QCOMPARE(metrics["blood_loss_ml"].toDouble(), 0.0);
    QVERIFY(metrics["energy_time_s"].toDouble() > 0);
    // A tear the session said is counted; tears are incorrect actions (one per over-pull). On this liver the tissue
    // beside the attachments, at 59-69 % at rest, can also tear while the clips, the cut and the burn load it (a tear
    // at 1.44 s, before the grasp, in one run): that is the session's answer, and the replay's count is the reference.
    if (ended.contains("tore")) QVERIFY(metrics["tears"].toInt(-1) >= 1);
    QCOMPARE(listed.filter(" tear").isEmpty(), metrics["tears"].toInt(-1) == 0);
    QVERIFY(listed.filter("energy_on_structure").isEmpty());    // the hook stayed away from the artery
    QCOMPARE(metrics["instrument_outside_view"].toInt(-1), 0);  // the GUI records the case's camera as the view
  }

  void importAnotherOrgan() {
    // A mesh imported over the rehearsal (a helper imported the patient liver over the phantom's): the old session's
    // clips, blood, cut and organ leave the frame view at once, though the new organ's session, paused, draws nothing
    // over them (without the mend: 2 clips, 2 bleeding stumps and the old organ's 1650 nodes still drawn).
    const auto& field = w_->frameView()->liveField();
    qInfo("before the import: %zu clips, %zu bleeding stumps, %zu live nodes drawn", field.clips.size(),
          field.bleeds.size(), w_->frameView()->liveShape().size());
    QVERIFY(!field.clips.empty() && !w_->frameView()->liveShape().empty());
    QSignalSpy imported(w_.get(), &MainWindow::meshImported);
    w_->meshPage()->importMesh(QString::fromStdString(meshFile));
    QVERIFY(imported.wait(180000));
    QVERIFY2(imported.first().at(0).toBool(), qPrintable(imported.first().at(1).toString()));
    QTest::qWait(500);  // any frame of the old session still on its way
    const auto& now = w_->frameView()->liveField();
    qInfo("after: %zu clips, %zu bleeding stumps, %zu live nodes drawn; the organ placed: %d", now.clips.size(),
          now.bleeds.size(), w_->frameView()->liveShape().size(), w_->caseData()->hasPose);
    QVERIFY(now.clips.empty() && now.bleeds.empty() && now.bloodLoss == 0);
    QVERIFY(w_->frameView()->liveShape().empty() && !w_->frameView()->liveSurface());
  }
};
}  // namespace

class TestOperativeGui : public QObject {
  Q_OBJECT
  std::unique_ptr<MainWindow> w_;
  ui::SimulationPanel* panel_ = nullptr;
  QTemporaryDir dir_;

 private slots:
  void initTestCase() {
    QCoreApplication::setOrganizationName("RehearseOperativeGuiTest");
    MainWindow::setRenderer(MainWindow::Renderer::Software);
    QVERIFY(openPhantomCase(w_));
    panel_ = w_->simulationPanel();
    QVERIFY(dir_.isValid());
  }

  void cholecystectomyWithTheMouse() {
    REQUIRE_SHARED("scikit-surgery/laparoscopy-liver-frame.jpg");
    REQUIRE_SHARED("scikit-surgery/patient-liver/liver.vtk");
    Cholecystectomy s(w_, panel_, dir_);
    s.openTheFrame();

    if (QTest::currentTestFailed()) return;
    s.labelTheArtery();
    if (QTest::currentTestFailed()) return;
    s.importTheModel();
    if (QTest::currentTestFailed()) return;
    s.attachTheRim();
    if (QTest::currentTestFailed()) return;
    s.estimateAndSave();
    if (QTest::currentTestFailed()) return;
    s.startRecording();
    if (QTest::currentTestFailed()) return;
    s.clipTheArtery();
    if (QTest::currentTestFailed()) return;
    s.cutBetweenTheClips();
    if (QTest::currentTestFailed()) return;
    s.burnALine();
    if (QTest::currentTestFailed()) return;
    s.graspBesideAnAttachment();
    if (QTest::currentTestFailed()) return;
    s.pullUntilItTearsOrSlips();
    if (QTest::currentTestFailed()) return;
    s.replayHeadless();
    if (QTest::currentTestFailed()) return;
    s.importAnotherOrgan();
  }

  void cleanupTestCase() {
    closeDiscardingChanges(*w_);
    w_.reset();
  }
};

QTEST_MAIN(TestOperativeGui)
#include "test_operative_gui.moc"
