// The command line's appearance step, run as a user would (split from test_cli.cpp): the fit and its verdict, the turn
// an outline leaves open, composing with a fitted or untrusted THETA, on the phantom and the real Open-CAS frame.
#include "cli_run.hpp"
#include "test_support.hpp"
#include "opencas.hpp"
#include "traced_outline.hpp"

#include <QDir>
#include <QJsonArray>
#include <QJsonDocument>
#include <QRegularExpression>
#include <QJsonObject>
#include <rehearse/imaging/appearance_fit.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <algorithm>
#include <cmath>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace {
using testing::expectOneLineError;
using testing::Run;
using testing::run;
}  // namespace

class TestCliAppearance : public QObject {
  Q_OBJECT
 private slots:
  // Issue 62: the turn an outline leaves open, settled by the shading. The phantom's frame, its organ's outline traced
  // as a hand would (two pieces with a gap, wavering 2 px), and the organ registered off the frame's pose by a turn about
  // the camera's X or Y axis through its centre (what a contour fit leaves, "weakest: a turn about the camera's X axis").
  // Without the outline step 6 explains less than 90 % there; with it the organ is turned back to within 1.5 degrees of
  // the frame's pose (the truth the frame was rendered at) and the shading explained to 90 % or more. At the frame's
  // pose, and moved sideways, it is left where it was.
  void appearanceSettlesTheOpenTurn_data() {
    QTest::addColumn<double>("aboutX");
    QTest::addColumn<double>("aboutY");
    QTest::addColumn<double>("sidewaysMm");
    QTest::addColumn<bool>("turns");
    QTest::newRow("turned 5 degrees about X") << 5.0 << 0.0 << 0.0 << true;
    QTest::newRow("turned -6 about X and 4 about Y") << -6.0 << 4.0 << 0.0 << true;
    QTest::newRow("turned 9 degrees about X and 2 about Y") << 9.0 << 2.0 << 0.0 << true;
    // About Y a light at the lens shades the organ nearly alike: it explains over 90 % already, and no turn is asked.
    QTest::newRow("turned 8 degrees about Y") << 0.0 << 8.0 << 0.0 << false;
    QTest::newRow("at the frame's pose") << 0.0 << 0.0 << 0.0 << false;
    // Moved sideways, not turned: the best turn the outline allows scores 1.8 points more at the working resolution,
    // under the 2 a refit needs (and a refit would need 3 more to be taken).
    QTest::newRow("moved 4 mm sideways") << 0.0 << 0.0 << 4.0 << false;
  }
  void appearanceSettlesTheOpenTurn() {
    QFETCH(double, aboutX);
    QFETCH(double, aboutY);
    QFETCH(double, sidewaysMm);
    QFETCH(bool, turns);
    using namespace rehearse;
    static const QString dir = [] {
      const QString d = QString::fromStdString(tempPath("cli-turn"));
      run({"phantom", "--out", d});
      return d;
    }();
    QVERIFY(QFile::exists(dir + "/frame.png"));
    const Pose truth = imaging::loadPose((dir + "/pose.json").toStdString());
    simcore::Mesh m = simcore::loadMesh((dir + "/organ.vtu").toStdString());
    m.convertToMetres();
    const auto triangles = simcore::boundaryTriangles(m, false);
    std::vector<double> vertices;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& p : m.points) vertices.insert(vertices.end(), {p.x(), p.y(), p.z()}), centre += truth.apply(p);
    centre /= double(m.points.size());
    const SurfaceView surface{vertices.data(), m.points.size(), triangles.front().data(), triangles.size()};
    const cv::Mat frame = cv::imread((dir + "/frame.png").toStdString());
    const imaging::Camera camera = imaging::loadCamera((dir + "/camera.yaml").toStdString(), frame.cols, frame.rows);
    // The outline of the organ the frame shows, traced in two pieces.
    const imaging::Contour contour = handTracedOutline(camera, truth, surface);
    QVERIFY(!contour.empty());
    imaging::saveContour(contour, (dir + "/outline.json").toStdString());
    const Eigen::Matrix3d Q = (Eigen::AngleAxisd(aboutX * M_PI / 180, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(aboutY * M_PI / 180, Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    Pose registered = truth.turnedAbout(Q, centre);
    registered.t.x() += 1e-3 * sidewaysMm;
    imaging::savePose(registered, (dir + "/registered.json").toStdString());
    const QStringList common{"appearance", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml",
                             "--pose", dir + "/registered.json", "--image", dir + "/frame.png"};
    auto readJson = [](const QString& path) {
      QFile f(path);
      f.open(QIODevice::ReadOnly);
      return QJsonDocument::fromJson(f.readAll()).object();
    };
    auto without = run(common + QStringList{"--out", dir + "/theta0.json", "--report", dir + "/report0.json"});
    QVERIFY2(without.code == 0 || without.code == 4, qPrintable(without.err));
    const double before = readJson(dir + "/report0.json")["explained"].toDouble();
    auto with = run(common + QStringList{"--out", dir + "/theta.json", "--report", dir + "/report.json", "--contour",
                                         dir + "/outline.json", "--turned-pose", dir + "/turned.json"});
    QVERIFY2(with.code == 0, qPrintable(with.err + with.out));
    const QJsonObject report = readJson(dir + "/report.json"), turn = report["turn"].toObject();
    const Pose turned = imaging::loadPose((dir + "/turned.json").toStdString());
    const double offDeg = Eigen::AngleAxisd(turned.R * truth.R.transpose()).angle() * 180 / M_PI;
    const double wasDeg = Eigen::AngleAxisd(registered.R * truth.R.transpose()).angle() * 180 / M_PI;
    qInfo("registered %.1f deg off: explains %.1f %%; settled %s (%.1f, %.1f deg, %d turns scored, %.1f -> %.1f %% at the "
          "working resolution, %.0f ms): %.1f deg off, explains %.1f %%; outline %.2f -> %.2f px",
          wasDeg, 100 * before, turn["adopted"].toBool() ? "turned" : "not turned", turn["about_x_deg"].toDouble(),
          turn["about_y_deg"].toDouble(), turn["candidates"].toInt(), 100 * turn["scored_before"].toDouble(),
          100 * turn["scored_best"].toDouble(), turn["ms"].toDouble(), offDeg,
          100 * report["explained"].toDouble(), turn["outline_before_px"].toDouble(),
          turn["outline_after_px"].toDouble());
    QVERIFY(turn["searched"].toBool());
    QVERIFY2(with.out.contains(turn["said"].toString()), qPrintable(with.out));
    if (turns) {
      QVERIFY2(before < 0.9, qPrintable(QString::number(before)));  // the case it is for
      QVERIFY2(turn["adopted"].toBool(), qPrintable(turn["said"].toString()));
      QVERIFY2(offDeg <= 1.5, qPrintable(QString::number(offDeg)));
      QVERIFY(report["explained"].toDouble() >= 0.9);
      QVERIFY(turn["said"].toString().contains("Undo puts it back"));
    } else {
      QVERIFY2(!turn["adopted"].toBool(), qPrintable(turn["said"].toString()));
      QCOMPARE(report["explained"].toDouble(), before);
      QVERIFY((turned.t - registered.t).norm() == 0 && (turned.R - registered.R).norm() == 0);
    }
    // --contour without --turned-pose, and the reverse, are refused in one sentence.
    expectOneLineError(run(common + QStringList{"--out", dir + "/t.json", "--contour", dir + "/outline.json"}), 2,
                       "give --turned-pose");
    expectOneLineError(run(common + QStringList{"--out", dir + "/t.json", "--turned-pose", dir + "/t2.json"}), 2,
                       "needs --contour");
  }

  // The same on the real ex-vivo frame (Open-CAS), whose CT surface is in the camera's frame and whose shading no
  // laparoscope light explains (BENCHMARKS.md: at most 47 % for any point light, 0 % within the scope's): the outline
  // of that surface given, the organ at the CT's pose or turned 5 degrees off it is left where it is (texture only,
  // exit 4), never turned on shading the model does not explain.
  void appearanceTurnIsNotTakenFromAFrameTheModelDoesNotExplain_data() {
    QTest::addColumn<double>("aboutX");
    QTest::newRow("at the CT's pose") << 0.0;
    QTest::newRow("turned 5 degrees about X") << 5.0;
  }
  void appearanceTurnIsNotTakenFromAFrameTheModelDoesNotExplain() {
    QFETCH(double, aboutX);
    using namespace rehearse;
    REQUIRE_SHARED("open-cas/Stereo_SD_d_complete_22_IMG_left.bmp");
    const auto oc = testdata::OpenCas::load();
    const QString dir = QString::fromStdString(tempPath("cli-turn-opencas"));
    QDir().mkpath(dir);
    imaging::saveCamera(oc.camera, (dir + "/camera.yaml").toStdString());
    QVERIFY(cv::imwrite((dir + "/frame.png").toStdString(), oc.frame));
    imaging::Contour contour;
    contour.width = oc.camera.width, contour.height = oc.camera.height;
    for (const auto& b : imaging::maskOutlines(imaging::renderMask(oc.camera, Pose{}, oc.surface())))
      contour.segments.push_back({b, true, "silhouette", {}});
    QVERIFY(!contour.segments.empty());
    imaging::saveContour(contour, (dir + "/outline.json").toStdString());
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < oc.vertices.size(); i += 3) centre += Eigen::Vector3d(oc.vertices[i], oc.vertices[i + 1], oc.vertices[i + 2]);
    centre /= double(oc.vertices.size() / 3);
    const Pose registered = Pose{}.turnedAbout(Eigen::AngleAxisd(aboutX * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix(), centre);
    imaging::savePose(registered, (dir + "/registered.json").toStdString());
    const auto r = run({"appearance", "--mesh", testdata::OpenCas::directory().c_str() + QString("Stereo_SD_d_complete_22_CT_cut.stl"),
                        "--unit", "mm", "--camera", dir + "/camera.yaml", "--pose", dir + "/registered.json", "--image",
                        dir + "/frame.png", "--out", dir + "/theta.json", "--report", dir + "/report.json", "--contour",
                        dir + "/outline.json", "--turned-pose", dir + "/turned.json"});
    QVERIFY2(r.code == 4, qPrintable(r.err + r.out));  // texture only, as without the search
    QFile f(dir + "/report.json");
    QVERIFY(f.open(QIODevice::ReadOnly));
    const QJsonObject turn = QJsonDocument::fromJson(f.readAll()).object()["turn"].toObject();
    qInfo("%s (%d turns scored, at the working resolution %.1f -> %.1f %%, %.0f ms)", qPrintable(turn["said"].toString()),
          turn["candidates"].toInt(), 100 * turn["scored_before"].toDouble(), 100 * turn["scored_best"].toDouble(),
          turn["ms"].toDouble());
    QVERIFY(turn["searched"].toBool());
    QVERIFY(!turn["adopted"].toBool());
    const Pose turned = imaging::loadPose((dir + "/turned.json").toStdString());
    QVERIFY((turned.R - registered.R).norm() == 0 && (turned.t - registered.t).norm() == 0);
  }

  // Issue 65: a fit's verdict travels with its THETA. On the Open-CAS frame (no scope light explains it: texture
  // only, exit 4) the THETA is marked so, and compose with it says so and does not re-shade, in the frame and in a
  // novel view: its image is, pixel for pixel, the one `--texture-only` draws with the same values stripped of their
  // verdict, and not the re-shaded one those values give (which compose says it drew "as given").
  void composeDoesNotReshadeWithAFitThatExplainedTooLittle() {
    using namespace rehearse;
    REQUIRE_SHARED("open-cas/Stereo_SD_d_complete_22_IMG_left.bmp");
    const auto oc = testdata::OpenCas::load();
    const QString dir = QString::fromStdString(tempPath("cli-untrusted-theta"));
    QDir().mkpath(dir);
    imaging::saveCamera(oc.camera, (dir + "/camera.yaml").toStdString());
    QVERIFY(cv::imwrite((dir + "/frame.png").toStdString(), oc.frame));
    imaging::savePose(Pose{}, (dir + "/pose.json").toStdString());
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < oc.vertices.size(); i += 3)
      centre += Eigen::Vector3d(oc.vertices[i], oc.vertices[i + 1], oc.vertices[i + 2]);
    centre /= double(oc.vertices.size() / 3);
    // The novel view: the organ turned 15 degrees about the camera's vertical axis through its centre.
    imaging::savePose(Pose{}.turnedAbout(Eigen::AngleAxisd(15 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix(),
                                         centre),
                      (dir + "/view-pose.json").toStdString());
    const QStringList organ = {"--mesh", testdata::OpenCas::directory().c_str() + QString("Stereo_SD_d_complete_22_CT_cut.stl"),
                               "--unit", "mm", "--camera", dir + "/camera.yaml", "--pose", dir + "/pose.json",
                               "--image", dir + "/frame.png"};
    const Run fit = run(QStringList{"appearance"} + organ + QStringList{"--out", dir + "/theta.json"});
    QVERIFY2(fit.code == 4, qPrintable(fit.err + fit.out));  // texture only
    QFile f(dir + "/theta.json");
    QVERIFY(f.open(QIODevice::ReadOnly));
    QJsonObject theta = QJsonDocument::fromJson(f.readAll()).object();
    f.close();
    const QJsonObject verdict = theta["fit"].toObject();
    qInfo("THETA's verdict: explained %.3f, reshade %s: %s", verdict["explained"].toDouble(),
          verdict["reshade"].toBool() ? "yes" : "no", qPrintable(verdict["said"].toString()));
    QVERIFY(verdict.contains("reshade") && !verdict["reshade"].toBool());
    QVERIFY(verdict["explained"].toDouble() < 0.5);
    QVERIFY(!verdict["said"].toString().isEmpty());
    // The same values without their verdict (as a hand-written THETA would give them).
    theta.remove("fit");
    QFile bare(dir + "/bare.json");
    QVERIFY(bare.open(QIODevice::WriteOnly));
    bare.write(QJsonDocument(theta).toJson());
    bare.close();
    // And with a verdict of 70 % explained (re-shaded half way: imaging::reshadeTrust).
    QJsonObject earned = verdict;
    earned["explained"] = 0.7;
    earned["reshade"] = true;
    theta["fit"] = earned;
    QFile half(dir + "/half.json");
    QVERIFY(half.open(QIODevice::WriteOnly));
    half.write(QJsonDocument(theta).toJson());
    half.close();
    // At the texture-only line with the flag still saying re-shade: nothing of the model's change, and said so.
    earned["explained"] = 0.5;
    theta["fit"] = earned;
    QFile line(dir + "/line.json");
    QVERIFY(line.open(QIODevice::WriteOnly));
    line.write(QJsonDocument(theta).toJson());
    line.close();
    const Run atLine = run(QStringList{"compose"} + organ + QStringList{"--theta", dir + "/line.json", "--out", dir + "/line.png"});
    QVERIFY2(atLine.code == 0, qPrintable(atLine.err));
    QVERIFY2(atLine.out.contains("not re-shaded where the frame saw the tissue: the fit behind line.json explained 50 %"),
             qPrintable(atLine.out));
    const QStringList novel = {"--view-camera", dir + "/camera.yaml", "--view-pose", dir + "/view-pose.json"};
    for (const bool novelView : {false, true}) {
      const QStringList view = novelView ? novel : QStringList();
      const QString tag = novelView ? "novel" : "frame";
      const Run untrusted = run(QStringList{"compose"} + organ + view + QStringList{"--theta", dir + "/theta.json", "--out", dir + "/u-" + tag + ".png"});
      QVERIFY2(untrusted.code == 0, qPrintable(untrusted.err));
      // (It explains 0 % with the scope's light alone, 29-37 % with the second source the frame bears out: still too
      // little.)
      const QRegularExpressionMatch said =
          QRegularExpression("not re-shaded: the fit behind theta.json is marked texture only \\(it explained (\\d+) %")
              .match(untrusted.out);
      QVERIFY2(said.hasMatch(), qPrintable(untrusted.out));
      QVERIFY(said.captured(1).toInt() < 50 && std::abs(said.captured(1).toInt() - 100 * verdict["explained"].toDouble()) <= 1);
      const Run texture = run(QStringList{"compose"} + organ + view +
                              QStringList{"--theta", dir + "/bare.json", "--texture-only", "--out", dir + "/t-" + tag + ".png"});
      QVERIFY2(texture.code == 0, qPrintable(texture.err));
      QVERIFY2(!texture.out.contains("re-shaded"), qPrintable(texture.out));
      const Run given = run(QStringList{"compose"} + organ + view + QStringList{"--theta", dir + "/bare.json", "--out", dir + "/g-" + tag + ".png"});
      QVERIFY2(given.code == 0, qPrintable(given.err));
      QVERIFY2(given.out.contains("re-shaded with bare.json as given: it carries no fit's verdict"), qPrintable(given.out));
      const cv::Mat3b u = cv::imread((dir + "/u-" + tag + ".png").toStdString()),
                      t = cv::imread((dir + "/t-" + tag + ".png").toStdString()),
                      g = cv::imread((dir + "/g-" + tag + ".png").toStdString());
      QVERIFY(!u.empty() && u.size() == t.size() && u.size() == g.size());
      cv::Mat diffTexture, diffGiven;
      cv::absdiff(u, t, diffTexture);
      cv::absdiff(u, g, diffGiven);
      const int differTexture = cv::countNonZero(diffTexture.reshape(1) > 0),
                differGiven = cv::countNonZero(diffGiven.reshape(1) > 2);
      qInfo("%s: the untrusted THETA's image differs from --texture-only's in %d channel values, from the re-shaded "
            "one's in %d (by more than 2 levels)",
            qPrintable(tag), differTexture, differGiven);
      QCOMPARE(differTexture, 0);
      QVERIFY(differGiven > 1000);
      // Half way: where texture only draws the organ, the mean of it and the full re-shade (within a level).
      const Run halfWay = run(QStringList{"compose"} + organ + view + QStringList{"--theta", dir + "/half.json", "--out", dir + "/h-" + tag + ".png"});
      QVERIFY2(halfWay.code == 0, qPrintable(halfWay.err));
      QVERIFY2(halfWay.out.contains("re-shaded at 50 % of the model's change: the fit behind half.json explained 70 %"),
               qPrintable(halfWay.out));
      const cv::Mat3b h = cv::imread((dir + "/h-" + tag + ".png").toStdString());
      QVERIFY(h.size() == t.size());
      int drawn = 0, nearMean = 0, fromGiven = 0;
      // Texture only draws tissue the frame never showed in the organ's mean colour there (the novel view), where a
      // re-shade draws the model in full: no share to mix.
      const cv::Vec3f organMean = imaging::meanOrganColour(oc.frame, imaging::rasterize(oc.camera, Pose{}, oc.surface()).triangle);
      const cv::Vec3b unseen(cv::saturate_cast<uchar>(organMean[0]), cv::saturate_cast<uchar>(organMean[1]),
                             cv::saturate_cast<uchar>(organMean[2]));
      for (int y = 0; y < h.rows; ++y)
        for (int x = 0; x < h.cols; ++x) {
          const cv::Vec3b tv = t(y, x), gv = g(y, x), hv = h(y, x);
          if (tv == cv::Vec3b(0, 0, 0)) continue;  // the organ is not drawn here (the novel view's background)
          if (novelView && tv == unseen) continue;
          if (tv == gv) continue;                                   // no change to mix
          ++drawn;
          int worst = 0, apart = 0;
          for (int k = 0; k < 3; ++k) {
            worst = std::max(worst, std::abs(2 * hv[k] - tv[k] - gv[k]));
            apart = std::max(apart, std::abs(hv[k] - gv[k]));
          }
          nearMean += worst <= 3;  // twice the level, and the two roundings
          fromGiven += apart >= 2;
        }
      qInfo("%s, THETA explained 70 %%: of %d px where texture only and the full re-shade differ, %d within a level of "
            "their mean, %d 2+ levels from the full re-shade",
            qPrintable(tag), drawn, nearMean, fromGiven);
      if (novelView) {  // at rest both ends are the frame, but for the rim's samples the frame never saw
        QVERIFY(drawn > 10000);
        QVERIFY(nearMean >= 0.98 * drawn);
      }
    }
  }

  void appearanceAndCompose() {
    const QString dir = QString::fromStdString(tempPath("cli-appearance"));
    QCOMPARE(run({"phantom", "--out", dir}).code, 0);
    auto r = run({"appearance", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose",
                  dir + "/pose.json", "--image", dir + "/frame.png", "--out", dir + "/theta.json", "--report",
                  dir + "/report.json", "--inpaint", "ns"});
    QVERIFY2(r.code == 0, qPrintable(r.err + r.out));
    auto readJson = [](const QString& path) {
      QFile f(path);
      f.open(QIODevice::ReadOnly);
      return QJsonDocument::fromJson(f.readAll()).object();
    };
    const QJsonObject fitted = readJson(dir + "/theta.json"), truth = readJson(dir + "/appearance.json");
    const QJsonObject report = readJson(dir + "/report.json");
    for (int k = 0; k < 3; ++k) {
      const double kd = fitted["kd"].toArray()[k].toDouble(), kdTrue = truth["kd"].toArray()[k].toDouble();
      QVERIFY2(std::abs(kd - kdTrue) < 0.05 * kdTrue,
               qPrintable(QString("kd %1: %2 against %3").arg(k).arg(kd).arg(kdTrue)));
      QVERIFY(std::abs(fitted["light_position"].toArray()[k].toDouble() -
                       truth["light_position"].toArray()[k].toDouble()) < 0.005);
    }
    QVERIFY(std::abs(fitted["roughness"].toDouble() - truth["roughness"].toDouble()) <
            0.1 * truth["roughness"].toDouble());
    QCOMPARE(report["stages"].toArray().size(), 5);  // highlights, diffuse, specular, second source, background
    // The phantom is lit by its scope alone: no second source is used, and the report says what each would explain.
    QCOMPARE(report["second_sources"].toArray().size(), 3);
    for (const auto& s : report["second_sources"].toArray()) QVERIFY(!s.toObject()["used"].toBool());
    QVERIFY(!fitted.contains("distant_light") && !fitted.contains("ambient"));
    QVERIFY(report["rest_psnr_db"].toDouble() >= 30);
    QVERIFY(report["status"].toString().contains(
        "red channel is clipped"));  // the phantom's red clips at its highlight: said
    // The fit's verdict travels with THETA (issue 65): this one explains the phantom's shading and may re-shade.
    QVERIFY(fitted["fit"].toObject()["reshade"].toBool());
    QVERIFY(std::abs(fitted["fit"].toObject()["explained"].toDouble() - report["explained"].toDouble()) < 1e-12);
    // Compose a sag simulated on the same mesh (the liver preset is the built-in phantom hung by its
    // ligaments; nodes in the input order).
    QCOMPARE(run({"simulate", "--preset", "liver", "--steps", "10", "--out", dir + "/sag.vtu"}).code, 0);
    // The case folder's own attachments.json is read by --fixed-nodes too (it was refused before).
    QCOMPARE(run({"simulate", "--mesh", dir + "/organ.vtu", "--fixed-nodes", dir + "/attachments.json", "--steps", "2",
                  "--out", dir + "/held.vtu"})
                 .code,
             0);
    r = run({"compose", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose", dir + "/pose.json",
             "--image", dir + "/frame.png", "--theta", dir + "/theta.json", "--deformed", dir + "/sag.vtu", "--out",
             dir + "/j.png"});
    QVERIFY2(r.code == 0, qPrintable(r.err));
    // A trusted fit re-shades in full, and says so (a person's hand-edited 95 % was re-shaded without a word).
    QVERIFY2(r.out.contains("re-shaded in full: the fit behind theta.json explained 9"), qPrintable(r.out));
    QVERIFY2(!r.out.contains("note:"), qPrintable(r.out));  // its sentence and its number agree
    QVERIFY(QFile(dir + "/j.png").size() > 10000);
    // Drawn through a surface of its own (--visual, issue 35) carried by the volume's tetrahedra: here the volume's
    // own boundary, whose vertices are nodes, so the carried sag is the sag itself and the image the same.
    r = run({"compose", "--mesh", dir + "/organ.vtu", "--visual", dir + "/organ_surface.obj", "--camera",
             dir + "/camera.yaml", "--pose", dir + "/pose.json", "--image", dir + "/frame.png", "--theta",
             dir + "/theta.json", "--deformed", dir + "/sag.vtu", "--out", dir + "/jv.png"});
    QVERIFY2(r.code == 0, qPrintable(r.err));
    {
      const cv::Mat3b direct = cv::imread((dir + "/j.png").toStdString()),
                      carried = cv::imread((dir + "/jv.png").toStdString());
      const double db = rehearse::imaging::psnr(direct, carried, cv::Mat1b(direct.size(), uchar(255)));
      qInfo("the sag drawn through the boundary as a surface of its own: %.1f dB against the nodes drawn directly", db);
      QVERIFY(db >= 50);
    }
    // --visual needs a volume to carry it, and a surface of that organ: one sentence each.
    expectOneLineError(run({"compose", "--mesh", dir + "/organ_surface.obj", "--visual", dir + "/organ_surface.obj",
                            "--camera", dir + "/camera.yaml", "--pose", dir + "/pose.json", "--image",
                            dir + "/frame.png", "--theta", dir + "/theta.json", "--out", dir + "/v.png"}),
                       2, "needs the organ's volume");
    {
      rehearse::simcore::Mesh shifted = rehearse::simcore::loadMesh((dir + "/organ_surface.obj").toStdString());
      for (auto& p : shifted.points) p.x() += 0.05;
      rehearse::simcore::saveMesh(shifted, (dir + "/shifted.vtu").toStdString());
    }
    expectOneLineError(run({"compose", "--mesh", dir + "/organ.vtu", "--visual", dir + "/shifted.vtu", "--camera",
                            dir + "/camera.yaml", "--pose", dir + "/pose.json", "--image", dir + "/frame.png",
                            "--theta", dir + "/theta.json", "--out", dir + "/v.png"}),
                       1, "outside its volume mesh");
    QVERIFY(!QFile::exists(dir + "/v.png"));
    // A novel view (issue 35) through the fitting camera at the fitting pose is the frame again inside the organ,
    // re-shaded and texture-only; the novel-view options without a view camera are a usage error.
    const cv::Mat3b frame = cv::imread((dir + "/frame.png").toStdString(), cv::IMREAD_COLOR);
    for (const bool texture : {false, true}) {
      QStringList args{"compose",
                       "--mesh",
                       dir + "/organ.vtu",
                       "--camera",
                       dir + "/camera.yaml",
                       "--pose",
                       dir + "/pose.json",
                       "--image",
                       dir + "/frame.png",
                       "--theta",
                       dir + "/theta.json",
                       "--view-camera",
                       dir + "/camera.yaml",
                       "--view-pose",
                       dir + "/pose.json",
                       "--out",
                       dir + "/novel.png"};
      if (texture) args << "--texture-only";
      r = run(args);
      QVERIFY2(r.code == 0, qPrintable(r.err));
      const cv::Mat3b view = cv::imread((dir + "/novel.png").toStdString(), cv::IMREAD_COLOR);
      QCOMPARE(view.size(), frame.size());
      cv::Mat1b organ;
      cv::cvtColor(view, organ, cv::COLOR_BGR2GRAY);
      organ = organ > 0;
      cv::erode(organ, organ, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
      const double db = rehearse::imaging::psnr(frame, view, organ);
      qInfo("novel view at the fitting pose (%s): %d px, %.1f dB", texture ? "texture-only" : "re-shaded",
            cv::countNonZero(organ), db);
      QVERIFY(cv::countNonZero(organ) > 50000);
      QVERIFY(db >= 30);
    }
    expectOneLineError(run({"compose", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose",
                            dir + "/pose.json", "--image", dir + "/frame.png", "--theta", dir + "/theta.json",
                            "--view-pose", dir + "/pose.json", "--out", dir + "/n.png"}),
                       2, "need --view-camera");
    // Bad input: the organ behind the camera, a deformed mesh of another organ, an unknown inpainting method.
    QFile behind(dir + "/behind.json");
    behind.open(QIODevice::WriteOnly);
    behind.write(R"({"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0, 0, -0.5]})");
    behind.close();
    expectOneLineError(run({"appearance", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose",
                            dir + "/behind.json", "--image", dir + "/frame.png", "--out", dir + "/x.json"}),
                       1, "behind the camera");
    QVERIFY(!QFile::exists(dir + "/x.json"));
    expectOneLineError(run({"compose", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose",
                            dir + "/pose.json", "--image", dir + "/frame.png", "--theta", dir + "/theta.json",
                            "--deformed", dir + "/organ_surface.obj", "--out", dir + "/k.png"}),
                       1, "same mesh in the same order");
    // A novel view whose own pose puts the organ behind its camera, or off its view, and an image of another size than
    // the view's camera: the view is named (a person read "behind the camera" and checked the frame's pose; an organ
    // off the view gave a black picture, unsaid).
    QFile off(dir + "/off.json");
    off.open(QIODevice::WriteOnly);
    off.write(R"({"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0.5, 0, 0.2]})");
    off.close();
    const QStringList organ{"--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose", dir + "/pose.json",
                            "--image", dir + "/frame.png", "--theta", dir + "/theta.json", "--view-camera",
                            dir + "/camera.yaml"};
    expectOneLineError(run(QStringList{"compose"} + organ + QStringList{"--view-pose", dir + "/behind.json", "--out", dir + "/b.png"}),
                       1, "behind the view's camera at the view's pose");
    expectOneLineError(run(QStringList{"compose"} + organ + QStringList{"--view-pose", dir + "/off.json", "--out", dir + "/b.png"}),
                       1, "not in the view at the view's pose; check that pose (--view-pose off.json).");
    {  // the view's camera at the organ's centre, among its points
      const rehearse::simcore::Mesh m = rehearse::simcore::loadMesh((dir + "/organ.vtu").toStdString());
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (const auto& p : m.points) c += p / static_cast<double>(m.points.size());
      QFile inside(dir + "/inside.json");
      inside.open(QIODevice::WriteOnly);
      inside.write(QString(R"({"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [%1, %2, %3]})").arg(-c.x()).arg(-c.y()).arg(-c.z()).toUtf8());
    }
    expectOneLineError(run(QStringList{"compose"} + organ + QStringList{"--view-pose", dir + "/inside.json", "--out", dir + "/b.png"}),
                       1, "The view's camera lies inside the organ at the view's pose");
    cv::imwrite((dir + "/small.png").toStdString(), cv::Mat3b(100, 160, cv::Vec3b(40, 40, 40)));
    expectOneLineError(run(QStringList{"compose"} + organ +
                           QStringList{"--view-pose", dir + "/pose.json", "--view-image", dir + "/small.png", "--out", dir + "/b.png"}),
                       1, "The view's image is 160x100 but the view's camera is calibrated for");
    QVERIFY(!QFile::exists(dir + "/b.png"));
    // A mesh in millimetres read as metres measures kilometres: refused with the unit it is likely in.
    {
      rehearse::simcore::Mesh mm = rehearse::simcore::loadMesh((dir + "/organ_surface.obj").toStdString());
      for (auto& p : mm.points) p *= 1000;
      rehearse::simcore::saveMesh(mm, (dir + "/organ_mm.vtu").toStdString());
    }
    expectOneLineError(run({"appearance", "--mesh", dir + "/organ_mm.vtu", "--camera", dir + "/camera.yaml", "--pose",
                            dir + "/pose.json", "--image", dir + "/frame.png", "--out", dir + "/x.json"}),
                       2, "probably in mm");
    QVERIFY(!QFile::exists(dir + "/x.json"));
    // A THETA whose number was edited away from its own sentence: said, and the number taken (here 95 % with a sentence
    // of the phantom's 9x %: within a point, no note; 50 %: a note, and "not re-shaded where the frame saw the tissue").
    {
      QFile f(dir + "/theta.json");
      f.open(QIODevice::ReadOnly);
      QJsonObject t = QJsonDocument::fromJson(f.readAll()).object();
      QJsonObject v = t["fit"].toObject();
      v["explained"] = 0.5;
      t["fit"] = v;
      QFile e(dir + "/edited.json");
      e.open(QIODevice::WriteOnly);
      e.write(QJsonDocument(t).toJson());
    }
    r = run({"compose", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose", dir + "/pose.json",
             "--image", dir + "/frame.png", "--theta", dir + "/edited.json", "--out", dir + "/e.png"});
    QVERIFY2(r.code == 0, qPrintable(r.err));
    QVERIFY2(r.out.contains("note: edited.json says the fit explained 50 % of the organ's shading, but its sentence says 9"),
             qPrintable(r.out));
    QVERIFY2(r.out.contains("not re-shaded where the frame saw the tissue"), qPrintable(r.out));
    // Issue 35's bad input: a frame with no organ pixels (black), a wholly saturated organ (white), a mesh that
    // misses the frame: one sentence each, no THETA written.
    for (const auto& [value, name] : {std::pair{0, "black.png"}, std::pair{255, "white.png"}}) {
      cv::imwrite((dir + "/" + name).toStdString(), cv::Mat3b(frame.size(), cv::Vec3b(value, value, value)));
      expectOneLineError(run({"appearance", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose",
                              dir + "/pose.json", "--image", dir + "/" + name, "--out", dir + "/z.json"}),
                         1, "usable pixels");
      QVERIFY(!QFile::exists(dir + "/z.json"));
    }
    QFile aside(dir + "/aside.json");
    aside.open(QIODevice::WriteOnly);
    aside.write(R"({"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [5, 0, 0.2]})");
    aside.close();
    expectOneLineError(run({"appearance", "--mesh", dir + "/organ.vtu", "--camera", dir + "/camera.yaml", "--pose",
                            dir + "/aside.json", "--image", dir + "/frame.png", "--out", dir + "/z.json"}),
                       1, "not in the frame");
    QVERIFY(!QFile::exists(dir + "/z.json"));
    // A case folder stores no alignment: without --pose the fit would take the automatic first guess as the pose.
    expectOneLineError(run({"appearance", "--case", dir, "--out", dir + "/y.json"}), 2,
                       "a case folder stores no alignment");
    QVERIFY(!QFile::exists(dir + "/y.json"));
    expectOneLineError(run({"appearance", "--case", dir, "--pose", dir + "/pose.json", "--out", dir + "/y.json",
                            "--inpaint", "magic"}),
                       1, "choose telea, ns, shiftmap or fsr");
  }
};

QTEST_MAIN(TestCliAppearance)
#include "test_cli_appearance.moc"
