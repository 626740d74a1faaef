// Registration's inputs and its command line (issue 5 onwards): a contour of another organ fails, unusable contours,
// cameras and poses give clear errors, `rehearse register` as a user runs it, and cancel stops early. Split from
// test_registration (the engine's accuracy) to keep each file readable.
#include "test_support.hpp"
#include "calculix.hpp"
#include "realorgan.hpp"
#include "registration_cases.hpp"
#include <rehearse/app/elasticfit.hpp>

#include "phantom/phantom.hpp"
#include <rehearse/app/casefolder.hpp>

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/registration.hpp>

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QProcess>

#include <filesystem>
#include <map>
#include <set>
#include <tuple>

#include <QStandardPaths>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {
// `rehearse ARGS`: its exit code, standard output and standard error.
std::tuple<int, QString, QString> run(const QStringList& args) {
  QProcess p;
  p.start(QStringLiteral(REHEARSE_BINARY), args);
  p.waitForFinished(300000);
  return std::make_tuple(p.exitCode(), QString::fromUtf8(p.readAllStandardOutput()),
                         QString::fromUtf8(p.readAllStandardError()));
}
}  // namespace

class TestRegistrationInputs : public QObject {
  Q_OBJECT
  phantom::Phantom c_;

  // commandLine's phases (each asserts; commandLine returns when one failed). With a ridge drawn on the frame and its
  // nodes on the organ (P2ILF's form), the report measures the curve too and the 3D error falls further.
  void ridgeOnTheCommandLine(const std::string& dir, const QStringList& common, const imaging::Contour& contour,
                             const FemModel& m, const Deformed& truth, double e1) {
    const QString d = QString::fromStdString(dir);
    const AnatomicalCurve ridge = frontRidge(c_, m, truth.x);
    QJsonArray xs, ys, vs;
    for (const auto& p : ridge.image) {
      xs.append(p.x());
      ys.append(p.y());
    }
    for (int v : ridge.nodes) vs.append(QString::number(v));  // P2ILF writes numbers as strings
    QJsonArray contours;
    for (const auto& seg : contour.segments) {
      QJsonArray sx, sy;
      for (const auto& p : seg.points) {
        sx.append(p.x());
        sy.append(p.y());
      }
      contours.append(QJsonObject{{"contourType", "Silhouette"}, {"imagePoints", QJsonObject{{"x", sx}, {"y", sy}}}});
    }
    contours.append(QJsonObject{{"contourType", "Ridge"},
                                {"imagePoints", QJsonObject{{"x", xs}, {"y", ys}}},
                                {"modelPoints", QJsonObject{{"vertices", vs}}}});
    writeFile(
        dir + "/p2ilf.json",
        QJsonDocument(QJsonObject{{"numOfContours", contours.size()}, {"contour", contours}}).toJson().toStdString());
    auto [cr, outr, errr] =
        run(common + QStringList{"--contour", d + "/p2ilf.json", "--out", d + "/ridge.vtu", "--report",
                                 d + "/ridge.json", "--ground-truth", d + "/truth.vtu"});
    QVERIFY2(cr == 0, qPrintable(errr));
    qInfo("with the ridge: %s", qPrintable(outr.trimmed()));
    const QJsonArray rits = QJsonDocument::fromJson(QByteArray::fromStdString(readFile(dir + "/ridge.json")))
                                .object()["iterations"]
                                .toArray();
    QVERIFY(rits.last().toObject().contains("curve_mean_px"));
    QVERIFY(rits.last().toObject()["curve_mean_px"].toDouble() < rits.first().toObject()["curve_mean_px"].toDouble());
    QVERIFY(rits.last().toObject()["error_mean_mm"].toDouble() < e1);
    // The organ given as a surface (tetrahedralised by the command): the curve's vertices index that
    // surface and are mapped onto the new volume's surface nodes.
    const Mesh obj = loadMesh(dir + "/organ_surface.obj");
    QJsonArray objVertices;
    for (int v : ridge.nodes) {
      std::size_t best = 0;
      for (std::size_t i = 1; i < obj.points.size(); ++i)
        if ((obj.points[i] - m.rest[v]).squaredNorm() < (obj.points[best] - m.rest[v]).squaredNorm()) best = i;
      objVertices.append(static_cast<int>(best));
    }
    QJsonObject ridgeEntry = contours.last().toObject();
    ridgeEntry["modelPoints"] = QJsonObject{{"vertices", objVertices}};
    contours[contours.size() - 1] = ridgeEntry;
    writeFile(
        dir + "/p2ilf-surface.json",
        QJsonDocument(QJsonObject{{"numOfContours", contours.size()}, {"contour", contours}}).toJson().toStdString());
    QStringList surfaceArgs = common;
    surfaceArgs[surfaceArgs.indexOf("--mesh") + 1] = d + "/organ_surface.obj";
    surfaceArgs.removeAt(surfaceArgs.indexOf("--fixed-nodes") + 1);  // node numbers of the other mesh
    surfaceArgs.removeAt(surfaceArgs.indexOf("--fixed-nodes"));
    auto [cs, outs, errs] =
        run(surfaceArgs + QStringList{"--contour", d + "/p2ilf-surface.json", "--out", d + "/surface-fit.vtu",
                                      "--report", d + "/surface.json", "--iterations", "4"});
    // Held nowhere (its node numbers were the other mesh's): the sag cannot be estimated, so the fit is written but
    // not called determined, and the sentence says what would make it so.
    QVERIFY2(cs == 4 && errs.contains("no node is held: mark where the ligaments hold the organ"), qPrintable(errs));
    QVERIFY(QFile::exists(d + "/surface-fit.vtu"));
    qInfo("surface mesh with the ridge: %s", qPrintable(outs.trimmed()));
    const QJsonArray sits = QJsonDocument::fromJson(QByteArray::fromStdString(readFile(dir + "/surface.json")))
                                .object()["iterations"]
                                .toArray();
    QVERIFY(sits.last().toObject()["curve_mean_px"].toDouble() < sits.first().toObject()["curve_mean_px"].toDouble());
    // A vertex the surface does not have: one line, no output.
    objVertices.append(999999);
    ridgeEntry["modelPoints"] = QJsonObject{{"vertices", objVertices}};
    contours[contours.size() - 1] = ridgeEntry;
    writeFile(
        dir + "/p2ilf-bad.json",
        QJsonDocument(QJsonObject{{"numOfContours", contours.size()}, {"contour", contours}}).toJson().toStdString());
    auto [cb, outb, errb] =
        run(surfaceArgs + QStringList{"--contour", d + "/p2ilf-bad.json", "--out", d + "/bad.vtu"});
    QVERIFY2(cb != 0 && errb.trimmed().count('\n') == 0 && errb.contains("999999"), qPrintable(errb));
    QVERIFY(!QFile::exists(d + "/bad.vtu"));
  }

  // Unusable input: one line on stderr, a non-zero exit, nothing written.
  void unusableInputOnTheCommandLine(const std::string& dir, const QStringList& common) {
    const QString d = QString::fromStdString(dir);
    writeFile(dir + "/empty.json", R"({"width": 1280, "height": 720, "segments": []})");
    auto [c2, o2, e2] = run(common + QStringList{"--contour", d + "/empty.json", "--out", d + "/x.vtu"});
    QVERIFY2(c2 != 0 && e2.trimmed().count('\n') == 0 && e2.contains("empty"), qPrintable(e2));
    QVERIFY(!QFile::exists(d + "/x.vtu"));
    // A self-intersecting contour (a figure of eight) and a pose behind the camera.
    imaging::Contour eight;
    eight.width = 1280;
    eight.height = 720;
    imaging::ContourSegment loop;
    for (int i = 0; i < 66; ++i) {  // past a full turn: the lobes meet at the centre
      const double t = 2 * M_PI * (i + 0.25) / 60;
      loop.points.emplace_back(640 + 200 * std::sin(t), 360 + 100 * std::sin(2 * t));
    }
    eight.segments.push_back(loop);
    imaging::saveContour(eight, dir + "/eight.json");
    auto [c3, o3, e3] = run(common + QStringList{"--contour", d + "/eight.json", "--out", d + "/x.vtu"});
    QVERIFY2(c3 != 0 && e3.trimmed().count('\n') == 0 && e3.contains("crosses itself"), qPrintable(e3));
    Pose behind = c_.truePose;
    behind.t.z() = -behind.t.z();
    imaging::savePose(behind, dir + "/behind.json");
    QStringList args = common;
    args[args.indexOf("--pose") + 1] = d + "/behind.json";
    auto [c4, o4, e4] = run(args + QStringList{"--contour", d + "/contour.json", "--out", d + "/x.vtu"});
    QVERIFY2(c4 != 0 && e4.trimmed().count('\n') == 0 && e4.contains("behind the camera"), qPrintable(e4));
    QVERIFY(!QFile::exists(d + "/x.vtu"));
  }

 private slots:
  void initTestCase() { c_ = phantom::makePhantom(); }

  void contourOfAnotherOrganFails() {
    REQUIRE_SHARED("bodyparts3d/FMA7205_Left_Kidney.obj");
    // BodyParts3D is in mm. This test was written with the file's numbers read as metres (a kidney 1000 times its
    // size, which loadMesh now refuses: coordinates beyond 10 m); that outline is kept as it was. With the kidney at
    // its real size the fit comes out "ambiguous" rather than failed (measured), a case for its own test.
    Mesh kidney = loadMesh(sharedData("bodyparts3d/FMA7205_Left_Kidney.obj"), {"mm"});
    for (auto& p : kidney.points) p *= 1000;
    const Eigen::Vector3d centre = kidney.bounds().center();
    std::vector<double> vertices;
    std::vector<int> triangles;
    // The kidney at the liver's depth, in the liver's place, seen from the side that shows its bean shape.
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Vector3d liverCentre = c_.truePose.apply(c_.centreOfGravity());
    for (const auto& p : kidney.points) {
      const Eigen::Vector3d q = turn * (p - centre) + liverCentre;
      vertices.insert(vertices.end(), {q.x(), q.y(), q.z()});
    }
    for (const auto& t : kidney.triangles) triangles.insert(triangles.end(), t.begin(), t.end());
    SurfaceView view{vertices.data(), kidney.points.size(), triangles.data(), kidney.triangles.size()};
    const auto contour = imaging::maskOutlines(imaging::renderMask(c_.camera, Pose{}, view));
    QVERIFY(!contour.empty());
    const FemModel m = organModel(c_);
    SimulationSettings s;
    s.gravity.setZero();
    RegistrationOptions o;
    o.rigidPrepass = true;
    const auto res = registerToContour(m, c_.attachments, s, c_.surface, contour, c_.truePose, c_.camera.pinhole(), o);
    double moved = 0;
    for (std::size_t i = 0; i < m.nodeCount(); ++i)
      moved = std::max(moved, (res.x.segment<3>(3 * i) - m.rest[i]).norm());
    double rigidPx = -1;
    for (const auto& it : res.iterations)
      if (it.stage == "rigid") rigidPx = it.score();
    qInfo("kidney outline (%zu points) against the liver: %s; largest node move %.1f mm; after the rigid stage %.1f px",
          contour.front().size(), res.status.c_str(), 1e3 * moved, rigidPx);
    QVERIFY(!res.ok);
    QVERIFY(res.status.rfind("failed", 0) == 0);
    QVERIFY(res.status.find('\n') == std::string::npos);
  }

  void unusableInputGivesClearErrors() {
    const FemModel m = organModel(c_);
    SimulationSettings s;
    s.gravity.setZero();
    const Pinhole cam = c_.camera.pinhole();
    auto expectThrow = [&](const std::vector<std::vector<Eigen::Vector2d>>& contour, const Pose& pose,
                           const char* fragment) {
      try {
        registerToContour(m, c_.attachments, s, c_.surface, contour, pose, cam);
        QFAIL("no error");
      } catch (const MeshError& e) {
        QVERIFY2(std::string(e.what()).find(fragment) != std::string::npos, e.what());
        QVERIFY(std::string(e.what()).find('\n') == std::string::npos);
      }
    };
    expectThrow({}, c_.truePose, "empty");
    expectThrow({{Eigen::Vector2d(10, 10)}}, c_.truePose, "single point");
    Pose behind = c_.truePose;
    behind.t.z() = -behind.t.z();
    expectThrow(outline(c_, c_.truePose, c_.surfaceView()), behind, "behind the camera");
    // A contour far outside the image binds to nothing useful: a failure status, not a result.
    std::vector<Eigen::Vector2d> far;
    for (int i = 0; i < 50; ++i) far.emplace_back(5000 + 10 * i, -3000 + 5 * i);
    const auto res = registerToContour(m, c_.attachments, s, c_.surface, {far}, c_.truePose, cam);
    qInfo("far contour: %s", res.status.c_str());
    QVERIFY(!res.ok);
    QVERIFY(res.status.rfind("failed", 0) == 0);
    // Absurd coordinates: refused at once (resampling them would not end).
    expectThrow({{Eigen::Vector2d(1e12, 1e12), Eigen::Vector2d(2e12, -1e12)}}, c_.truePose, "far outside the image");
    // Anatomical curves: a NaN image point and a curve made only of ligament-held nodes.
    RegistrationOptions o;
    o.curves = {{{c_.attachments[0], c_.attachments[1]},
                 {Eigen::Vector2d(100, 100), Eigen::Vector2d(std::nan(""), 3)},
                 "ridge"}};
    try {
      registerToContour(m, c_.attachments, s, c_.surface, outline(c_, c_.truePose, c_.surfaceView()), c_.truePose, cam,
                        o);
      QFAIL("a NaN curve point was accepted");
    } catch (const MeshError& e) {
      QVERIFY2(std::string(e.what()).find("not a number") != std::string::npos, e.what());
    }
    o.curves = {{{c_.attachments[0], c_.attachments[1], c_.attachments[2]},
                 {Eigen::Vector2d(600, 300), Eigen::Vector2d(700, 320)},
                 "ligament"}};
    const auto held = registerToContour(m, c_.attachments, s, c_.surface, outline(c_, c_.truePose, c_.surfaceView()),
                                        c_.truePose, cam, o);
    qInfo("a curve on held nodes only: %s", held.status.c_str());
    QVERIFY(held.x.allFinite());
  }

  // rehearse register on the phantom's own files: a contour of the organ deformed by a load the fit does
  // not know, the true pose as the start, a ground truth in the camera frame; the report's 3D error falls.
  void commandLine() {
    const std::string dir = tempPath("register-case");
    app::writeCaseDirectory(app::caseFromPhantom(c_), dir);
    const FemModel m = organModel(c_);
    const Deformed truth = deformSideways(c_, m);
    QVERIFY(truth.x.size() > 0);
    imaging::Contour contour;
    contour.width = c_.camera.width;
    contour.height = c_.camera.height;
    for (const auto& seg : truth.contour) contour.segments.push_back({seg, true, "silhouette", {}});
    imaging::saveContour(contour, dir + "/contour.json");
    Mesh gt = c_.volume;
    gt.convertToMetres();
    for (std::size_t i = 0; i < gt.points.size(); ++i) gt.points[i] = c_.truePose.apply(truth.x.segment<3>(3 * i));
    saveMesh(gt, dir + "/truth.vtu");
    QString nodes;
    for (int a : c_.attachments) nodes += QString::number(a) + " ";
    const QString d = QString::fromStdString(dir);
    const QStringList common = {"register", "--mesh",   d + "/organ.vtu",   "--material", "corotational",
                                "--young",  "27000",    "--poisson",        "0.4",        "--fixed-nodes",
                                nodes,      "--camera", d + "/camera.yaml", "--pose",     d + "/pose.json"};
    auto [code, out, err] = run(common + QStringList{"--contour", d + "/contour.json", "--out", d + "/registered.vtu",
                                                     "--pose-out", d + "/pose-out.json", "--report", d + "/report.json",
                                                     "--ground-truth", d + "/truth.vtu"});
    QVERIFY2(code == 0, qPrintable(err));
    qInfo("%s", qPrintable(out.trimmed()));
    const QJsonObject report =
        QJsonDocument::fromJson(QByteArray::fromStdString(readFile(dir + "/report.json"))).object();
    QVERIFY(report["determined"].toBool() && !report["ambiguous"].toBool() &&
            report["alternatives"].toArray().isEmpty());
    const QJsonArray its = report["iterations"].toArray();
    for (const auto& it : its)
      qInfo("  report: %s, %.3f px, %.3f mm, %.0f ms", qPrintable(it.toObject()["stage"].toString()),
            it.toObject()["mean_px"].toDouble(), it.toObject()["error_mean_mm"].toDouble(),
            it.toObject()["wall_ms"].toDouble());
    QVERIFY(its.size() >= 2);
    const double e0 = its.first().toObject()["error_mean_mm"].toDouble(),
                 e1 = its.last().toObject()["error_mean_mm"].toDouble();
    QVERIFY(e0 > 0 && e1 < e0);
    QVERIFY(its.last().toObject()["mean_px"].toDouble() < its.first().toObject()["mean_px"].toDouble());
    QVERIFY(its.last().toObject()["wall_ms"].toDouble() > 0);
    const Mesh registered = loadMesh(dir + "/registered.vtu");
    QCOMPARE(registered.points.size(), c_.volume.points.size());
    ridgeOnTheCommandLine(dir, common, contour, m, truth, e1);
    if (QTest::currentTestFailed()) return;
    unusableInputOnTheCommandLine(dir, common);
  }

  void cancelStopsEarly() {
    const FemModel m = organModel(c_);
    SimulationSettings s;
    s.gravity.setZero();
    RegistrationOptions o;
    int calls = 0;
    o.onIteration = [&](const RegistrationIteration&, const Eigen::VectorXd&, const Pose&) { return ++calls < 2; };
    const Pose start =
        offset(c_.truePose, Eigen::Vector3d(0.004, 0, 0), Eigen::Vector3d::UnitZ(), 0, c_.centreOfGravity());
    const auto res = registerToContour(m, c_.attachments, s, c_.surface, outline(c_, c_.truePose, c_.surfaceView()),
                                       start, c_.camera.pinhole(), o);
    QVERIFY(res.cancelled);
    QCOMPARE(calls, 2);
  }

  // A fit's shape that a simulation cannot start from is not kept (runElasticFit: fittedShapeProblem). A person's check
  // on the patient liver: the first fit from the automatic placement said "converged" with the organ crossing the image
  // plane and an element folded flat; Keep Fit took it, and step 7 refused "Tetrahedron 1702 is flat".
  void aShapeTheSimulationCannotStartFromIsNotKept() {
    const FemModel m = organModel(c_);
    RegistrationResult r;
    r.ok = true;
    r.pose = c_.truePose;
    r.x = m.restVector();
    QCOMPARE(QString::fromStdString(app::fittedShapeProblem(m, c_.surface, r)), QString());
    // Element 0's last node moved onto the plane of its other three: flat. The reference is the simulation's own
    // refusal of that shape (FemModel::build, as step 7 builds its body from the fitted shape).
    const auto& t = m.tets[0];
    const Eigen::Vector3d p0 = m.rest[t[0]], n = (m.rest[t[1]] - p0).cross(m.rest[t[2]] - p0).normalized();
    const Eigen::Vector3d p3 = m.rest[t[3]];
    r.x.segment<3>(3 * t[3]) = p3 - n * n.dot(p3 - p0);
    Mesh shape = c_.volume;
    shape.unitToMetre = 1.0;
    for (std::size_t i = 0; i < shape.points.size(); ++i) shape.points[i] = r.x.segment<3>(3 * static_cast<Eigen::Index>(i));
    bool refused = false;
    try {
      FemModel::build(shape, {}, {});
    } catch (const MeshError& e) {
      refused = QString(e.what()).startsWith("Tetrahedron 0 is flat");
    }
    QVERIFY(refused);
    QString why = QString::fromStdString(app::fittedShapeProblem(m, c_.surface, r));
    qInfo("%s", qPrintable(why));
    QVERIFY2(why.contains("elements came out flat (element 0 first)") && why.contains("not kept"), qPrintable(why));
    // Through the plane: inside out (its rest volume's sign lost). The simulation takes that (a person's check found
    // every fit of the patient liver from its automatic placement turned 17-36 elements so): kept, and said.
    r.x.segment<3>(3 * t[3]) = p3 - 2 * n * n.dot(p3 - p0);
    QCOMPARE(QString::fromStdString(app::fittedShapeProblem(m, c_.surface, r)), QString());
    for (std::size_t i = 0; i < shape.points.size(); ++i) shape.points[i] = r.x.segment<3>(3 * static_cast<Eigen::Index>(i));
    QCOMPARE(FemModel::build(shape, {}, {}).tets.size(), m.tets.size());
    why = QString::fromStdString(app::insideOutElements(m, r));
    QVERIFY2(why.contains("elements came out inside out (element 0 first)"), qPrintable(why));
    // The organ's centre on the image plane: about half its surface behind the camera.
    r.x = m.restVector();
    r.pose.t.z() -= c_.truePose.apply(c_.centreOfGravity()).z();
    why = QString::fromStdString(app::fittedShapeProblem(m, c_.surface, r));
    qInfo("%s", qPrintable(why));
    QVERIFY2(why.startsWith("the organ came out crossing the camera's image plane (") && why.contains("step 4"),
             qPrintable(why));
  }
};

QTEST_GUILESS_MAIN(TestRegistrationInputs)
#include "test_registration_inputs.moc"
