// The registration suite's shared parts (see test_registration_support.hpp): the sagged-liver fixture, the check
// of a bound's far ends, and secondFrameFixesDepth's phases.
#include "test_registration_support.hpp"

#include <rehearse/imaging/motion.hpp>

// The bound's far ends (RegistrationUncertainty::ends), checked against their definition from scratch: two, on either
// side of the result, each moving the surface facing the camera (its front-facing triangles' nodes, seen from the
// camera at the result's pose) by the bound on average. Returns the two ends' mean moves (mm).
std::pair<double, double> checkEnds(const RegistrationResult& r,
                                    const std::vector<std::array<int, 3>>& surface) {
  if (r.uncertainty.ends.size() != 2) {
    qWarning("%zu ends for a bound of %.2f mm", r.uncertainty.ends.size(), r.uncertainty.surfaceMm);
    return {-1, -1};
  }
  const auto n = static_cast<std::size_t>(r.x.size() / 3);
  auto at = [](const Pose& p, const Eigen::VectorXd& x, int i) { return p.apply(x.segment<3>(3 * i)); };
  std::vector<char> front(n, 0);
  for (const auto& t : surface) {
    const Eigen::Vector3d a = at(r.pose, r.x, t[0]), b = at(r.pose, r.x, t[1]), c = at(r.pose, r.x, t[2]);
    if ((b - a).cross(c - a).dot(a) < 0)
      for (int v : t) front[static_cast<std::size_t>(v)] = 1;
  }
  double moved[2] = {0, 0};
  Eigen::Vector3d shift[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::size_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!front[i]) continue;
    ++count;
    for (int e = 0; e < 2; ++e) {
      const auto& end = r.uncertainty.ends[static_cast<std::size_t>(e)];
      const Eigen::Vector3d d = at(end.pose, end.x, static_cast<int>(i)) - at(r.pose, r.x, static_cast<int>(i));
      moved[e] += 1e3 * d.norm();
      shift[e] += d;
    }
  }
  if (count == 0 || shift[0].dot(shift[1]) > 0) return {-1, -1};  // not on either side
  return {moved[0] / static_cast<double>(count), moved[1] / static_cast<double>(count)};
}

// The fixture, built once into cache, or null with why ("absent: ..." when the data set is not there).
const SaggedLiver* loadSaggedLiver(std::unique_ptr<SaggedLiver>& cache, QString& why) {
  if (cache) return cache.get();
  const std::string path = std::string(REHEARSE_SHARED_DATA) + "/bodyparts3d/FMA7197_Liver.obj";
  if (!std::filesystem::exists(path)) {
    why = QStringLiteral("absent: ../shared/data/bodyparts3d/FMA7197_Liver.obj");
    return nullptr;
  }
  if (QStandardPaths::findExecutable("ccx").isEmpty()) {
    why = QStringLiteral("CalculiX (ccx) is not installed; scripts/install-deps.sh installs calculix-ccx");
    return nullptr;
  }
  auto L = std::make_unique<SaggedLiver>();
  const Mesh surface = testing::loadOrganSurface(path);
  TetrahedraliseOptions to;
  to.allowSelfIntersections = true;
  to.targetTets = 8000;
  to.seed = 7;
  const Mesh fine = tetrahedraliseSurface(surface, to);
  to.targetTets = 2500;
  to.seed = 0;
  L->organ = app::Organ::fromVolume(tetrahedraliseSurface(surface, to), path);
  if (!(fine.tets.size() > 2 * L->organ->volume.tets.size())) {
    why = QStringLiteral("the CalculiX mesh is not finer than the fit's");
    return nullptr;
  }
  L->fineTets = fine.tets.size();
  L->cam = testing::scikitSurgeryCamera();
  L->truth = testing::broadsideView(fine, L->cam);
  const double heldDepth = testing::farthestShareDepth(fine, L->truth, 0.12);
  L->gCamera = 9.81 * Eigen::Vector3d(0.2, 1.0, 0.3).normalized();
  const Eigen::VectorXd u =
      runCalculixStatic(fine, {}, {15e3, 0.45, 1060, true}, L->truth.R.transpose() * L->gCamera, true,
                        testing::surfaceNodesBeyond(fine, L->truth, heldDepth), "bodyparts3d-sag");
  if (u.size() == 0) {
    why = QStringLiteral("ccx failed");
    return nullptr;
  }
  std::vector<Eigen::Vector3d> deformed(fine.points.size());
  for (std::size_t i = 0; i < deformed.size(); ++i) {
    deformed[i] = fine.points[i] + u.segment<3>(3 * static_cast<Eigen::Index>(i));
    L->sag = std::max(L->sag, u.segment<3>(3 * static_cast<Eigen::Index>(i)).norm());
  }
  const auto& tris = L->deformedTriangles = boundaryTriangles(fine, false);
  auto& verts = L->deformedVertices;
  for (const auto& p : deformed) verts.insert(verts.end(), {p.x(), p.y(), p.z()});
  const auto outlines = imaging::maskOutlines(
      imaging::renderMask(L->cam, L->truth, {verts.data(), deformed.size(), tris.front().data(), tris.size()}));
  if (outlines.empty()) {
    why = QStringLiteral("the sagged liver has no outline in the view");
    return nullptr;
  }
  L->outline = outlines.front();
  const std::vector<int> markers = testing::visibleMarkers(fine, deformed, L->truth, L->cam, 40);
  if (markers.size() != 40) {
    why = QStringLiteral("fewer than 40 visible markers");
    return nullptr;
  }
  app::FitInput in;
  in.organ = L->organ;
  in.attachments = L->attachments = testing::surfaceNodesBeyond(L->organ->volume, L->truth, heldDepth);
  in.materials = app::labelMaterials(app::defaultMaterial(*L->organ));
  L->model = app::fitModel(in);
  std::vector<Eigen::Vector3d> markerRest;
  for (int m : markers) {
    markerRest.push_back(fine.points[m]);
    L->markerTruth.push_back(L->truth.apply(deformed[m]));
  }
  L->embedded = embedPoints(L->model, markerRest);
  L->start = L->truth;
  L->start.t.x() += 0.02;
  cache = std::move(L);
  return cache.get();
}

void makeSecondFrame(const SaggedLiver* L, RegistrationFrame& second) {
  // The second camera: 15 mm along the first one's X, its axis through the organ's centre (first camera frame).
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& m : L->markerTruth) centre += m / static_cast<double>(L->markerTruth.size());
  const Eigen::Vector3d eye(0.015, 0, 0);
  const Eigen::Vector3d z = (centre - eye).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
  second.camera = L->cam.pinhole();
  second.motion.R.row(0) = x.transpose();
  second.motion.R.row(1) = z.cross(x).transpose();
  second.motion.R.row(2) = z.transpose();
  second.motion.t = -second.motion.R * eye;
  Pose seen;
  seen.R = second.motion.R * L->truth.R;
  seen.t = second.motion.R * L->truth.t + second.motion.t;
  const auto outlines = imaging::maskOutlines(imaging::renderMask(L->cam, seen, L->deformedView()));
  QVERIFY(!outlines.empty());
  second.contour = {outlines.front()};
}

void checkTwoFrames(const SaggedLiver* L, RegistrationOptions& o, const RegistrationResult& one) {
  const auto outlines2 = L->fit(L->outline, o);
  QVERIFY2(outlines2.ok, outlines2.status.c_str());
  // And 200 features tracked between the frames (0.5 px noise).
  o.frames[0].tracks = testing::trackedFeatures(L->deformedView(), L->truth, o.frames[0].motion, L->cam, 200, 0.5, 3);
  QVERIFY(o.frames[0].tracks.size() == 200);
  const auto two = L->fit(L->outline, o);
  QVERIFY2(two.ok, two.status.c_str());
  qInfo(
      "one frame: %.2f mm (bound %.2f mm, %s); two frames 15 mm apart: outlines %.2f mm (bound %.2f mm), with "
      "features %.2f mm (bound %.2f mm, %s), %s; feature residual %.2f px",
      1e3 * L->error(one), one.uncertainty.surfaceMm, one.uncertainty.weakest.c_str(), 1e3 * L->error(outlines2),
      outlines2.uncertainty.surfaceMm, 1e3 * L->error(two), two.uncertainty.surfaceMm,
      two.uncertainty.weakest.c_str(), two.status.c_str(), two.iterations.back().points.mean);
  // The mean offset of the markers along the view: the depth the outline leaves to the model's size.
  auto depthOffset = [&](const RegistrationResult& r) {
    const auto at = mapEmbedded(L->embedded, r.x);
    double sum = 0;
    for (std::size_t i = 0; i < L->markerTruth.size(); ++i) sum += (r.pose.apply(at[i]) - L->markerTruth[i]).z();
    return sum / static_cast<double>(L->markerTruth.size());
  };
  qInfo("  mean offset along the view: one frame %.2f mm, outlines of two %.2f mm, with features %.2f mm",
        1e3 * depthOffset(one), 1e3 * depthOffset(outlines2), 1e3 * depthOffset(two));
  QVERIFY(std::abs(depthOffset(two)) < 0.5 * std::abs(depthOffset(one)));
  QVERIFY(L->error(two) < 0.7 * L->error(one));
  QVERIFY(outlines2.uncertainty.surfaceMm < one.uncertainty.surfaceMm);
  // The bound shrinks with what the features add, and still covers the error within 3x.
  QVERIFY(two.uncertainty.computed && two.uncertainty.surfaceMm < 0.5 * one.uncertainty.surfaceMm);
  QVERIFY(1e3 * L->error(two) <= two.uncertainty.surfaceMm && two.uncertainty.surfaceMm <= 3e3 * L->error(two));
  QCOMPARE(two.uncertainty.motionMm, 0.0);  // (the motion given)
  // Where the organ may be, drawn on the fit page: the two ends move the facing surface by the bound (within 5 %).
  for (const auto* r : {&one, &two}) {
    const auto moved = checkEnds(*r, L->organ->surface);
    qInfo("  the bound's ends: %.2f and %.2f mm for a bound of %.2f mm (%s)", moved.first, moved.second,
          r->uncertainty.surfaceMm, r->uncertainty.weakest.c_str());
    QVERIFY(std::abs(moved.first - r->uncertainty.surfaceMm) < 0.05 * r->uncertainty.surfaceMm);
    QVERIFY(std::abs(moved.second - r->uncertainty.surfaceMm) < 0.05 * r->uncertainty.surfaceMm);
  }
}

void checkEstimatedMotion(const SaggedLiver* L, const RegistrationOptions& o, const RegistrationFrame& second,
                          const RegistrationResult& one) {
  // The motion estimated from the same features (the move's length given): its uncertainty is in the bound, which
  // covers the error, and a fit it leaves unsure of is not called determined.
  std::vector<imaging::Track> tracks(o.frames[0].tracks.begin(), o.frames[0].tracks.end());
  const imaging::CameraMotion m = imaging::estimateCameraMotion(L->cam, tracks, 0.015);
  QVERIFY2(m.ok, m.status.c_str());
  RegistrationOptions estimated = o;
  estimated.frames[0].motion = m.motion;
  estimated.frames[0].tracks = m.inliers;
  estimated.frames[0].motionDepthSigmaM = m.depthSigmaM;
  estimated.frames[0].motionAtOneSigma = m.motionAtOneSigma;
  const auto fit = L->fit(L->outline, estimated);
  qInfo(
      "  the motion estimated (%s; the turn %.2f degrees off, the move's direction %.2f): %.2f mm, bound %.2f mm "
      "(the motion's share %.2f mm), %s",
      m.status.c_str(), Eigen::AngleAxisd(m.motion.R * second.motion.R.transpose()).angle() * 180 / M_PI,
      std::acos(std::clamp(m.motion.t.normalized().dot(second.motion.t.normalized()), -1.0, 1.0)) * 180 / M_PI,
      1e3 * L->error(fit), fit.uncertainty.surfaceMm, fit.uncertainty.motionMm, fit.status.c_str());
  QVERIFY(fit.uncertainty.computed);
  QVERIFY(1e3 * L->error(fit) <= fit.uncertainty.surfaceMm);
  if (fit.uncertainty.surfaceMm > estimated.toleranceMm) QVERIFY(fit.ambiguous || !fit.ok);
  if (1e3 * m.depthSigmaM > estimated.toleranceMm) {
    // Too uncertain to count: set aside, said, and the fit is the first frame's (never worse than it).
    QCOMPARE(fit.setAsideFrames, std::vector<int>{0});
    QVERIFY2(fit.status.find("frame 2 was set aside") != std::string::npos, fit.status.c_str());
    QCOMPARE(fit.uncertainty.motionMm, 0.0);
    QCOMPARE(L->error(fit), L->error(one));
  } else {
    QVERIFY(fit.setAsideFrames.empty());
    QVERIFY(fit.uncertainty.motionMm > 0);
  }
  // A tolerance wider than the motion's uncertainty keeps the frame, its share in the bound: the pose fitted
  // again through the 1-sigma motion; without that motion, twice the features' depth spread.
  estimated.toleranceMm = 1e3 * m.depthSigmaM + 1;
  const auto kept = L->fit(L->outline, estimated);
  QVERIFY(kept.setAsideFrames.empty());
  QVERIFY(kept.uncertainty.motionMm > 0 && std::isfinite(kept.uncertainty.motionMm));
  QVERIFY(kept.uncertainty.surfaceMm >= kept.uncertainty.motionMm);
  QVERIFY(1e3 * L->error(kept) <= kept.uncertainty.surfaceMm);
  {
    // Its ends lie along the motion's refit (the largest share here), again the bound's move each way.
    const auto moved = checkEnds(kept, L->organ->surface);
    qInfo("  kept: the bound's ends %.2f and %.2f mm for %.2f mm (%s)", moved.first, moved.second,
          kept.uncertainty.surfaceMm, kept.uncertainty.weakest.c_str());
    QVERIFY(std::abs(moved.first - kept.uncertainty.surfaceMm) < 0.05 * kept.uncertainty.surfaceMm);
    QVERIFY(std::abs(moved.second - kept.uncertainty.surfaceMm) < 0.05 * kept.uncertainty.surfaceMm);
  }
  estimated.frames[0].motionAtOneSigma.reset();
  const auto fallback = L->fit(L->outline, estimated);
  QCOMPARE(fallback.uncertainty.motionMm, 2e3 * m.depthSigmaM);
  qInfo("  kept with a %.0f mm tolerance: %.2f mm, the motion's share %.2f mm (a feature's depth spread: %.2f mm)",
        estimated.toleranceMm, 1e3 * L->error(kept), kept.uncertainty.motionMm, fallback.uncertainty.motionMm);
  estimated.frames[0].motionDepthSigmaM = -1;
  try {
    L->fit(L->outline, estimated);
    QFAIL("a negative uncertainty of the motion was accepted");
  } catch (const MeshError& e) {
    QVERIFY2(std::string(e.what()).find("uncertainty") != std::string::npos, e.what());
  }
}

void checkSecondFrameCommandLine(const SaggedLiver* L, const RegistrationFrame& second) {
  // The command line: the second frame's outline and the motion given; without a motion, refused with a sentence.
  const std::string dir = tempPath("register-second-frame");
  std::filesystem::create_directories(dir);
  simcore::saveMesh(L->organ->volume, dir + "/liver.vtu");
  imaging::saveCamera(L->cam, dir + "/camera.json");
  for (const auto& [name, line] : {std::pair{std::string("contour.json"), L->outline},
                                   std::pair{std::string("contour2.json"), second.contour.front()}}) {
    imaging::Contour file;
    file.width = L->cam.width;
    file.height = L->cam.height;
    file.segments.push_back({line, true, "silhouette", {}});
    imaging::saveContour(file, dir + "/" + name);
  }
  imaging::savePose(L->start, dir + "/pose.json");
  imaging::savePose(second.motion, dir + "/motion.json");
  const QStringList common{"register",
                           "--mesh",
                           QString::fromStdString(dir + "/liver.vtu"),
                           "--camera",
                           QString::fromStdString(dir + "/camera.json"),
                           "--contour",
                           QString::fromStdString(dir + "/contour.json"),
                           "--pose",
                           QString::fromStdString(dir + "/pose.json"),
                           "--out",
                           QString::fromStdString(dir + "/registered.vtu"),
                           "--report",
                           QString::fromStdString(dir + "/report.json"),
                           "--contour2",
                           QString::fromStdString(dir + "/contour2.json")};
  QProcess p;
  p.start(QStringLiteral(REHEARSE_BINARY),
          common + QStringList{"--motion", QString::fromStdString(dir + "/motion.json")});
  QVERIFY(p.waitForFinished(300000));
  const QString out = QString::fromUtf8(p.readAllStandardOutput()), err = QString::fromUtf8(p.readAllStandardError());
  qInfo("%s%s(exit %d)", qPrintable(out), qPrintable(err), p.exitCode());
  QVERIFY2(p.exitCode() == 0 || p.exitCode() == 4, qPrintable(err));
  QVERIFY(out.contains("register: second frame: camera motion given"));
  const QJsonObject report =
      QJsonDocument::fromJson(QByteArray::fromStdString(readFile(dir + "/report.json"))).object();
  QCOMPARE(report["second_frame"].toObject()["features"].toInt(), 0);
  QCOMPARE(report["tolerance_mm"].toDouble(), 5.0);
  QCOMPARE(report["determined"].toBool(), p.exitCode() == 0);
  p.start(QStringLiteral(REHEARSE_BINARY), common);
  QVERIFY(p.waitForFinished(60000));
  QVERIFY(p.exitCode() != 0 && p.exitCode() != 4);
  QVERIFY(QString::fromUtf8(p.readAllStandardError()).contains("needs the camera's motion"));
  p.start(QStringLiteral(REHEARSE_BINARY),
          common + QStringList{"--baseline-mm", "15", "--frame", QString::fromStdString(dir + "/liver.vtu"),
                               "--frame2", QString::fromStdString(dir + "/liver.vtu")});
  QVERIFY(p.waitForFinished(60000));
  QVERIFY(p.exitCode() != 0 && p.exitCode() != 4);
  QVERIFY(QString::fromUtf8(p.readAllStandardError()).contains("Cannot read the frame"));
  // A second frame's option without its outline is refused, not ignored.
  QStringList withoutOutline = common.mid(0, common.size() - 2);
  withoutOutline << "--motion" << QString::fromStdString(dir + "/motion.json");
  p.start(QStringLiteral(REHEARSE_BINARY), withoutOutline);
  QVERIFY(p.waitForFinished(60000));
  QVERIFY(p.exitCode() != 0 && p.exitCode() != 4);
  QVERIFY(QString::fromUtf8(p.readAllStandardError()).contains("--motion is for a second frame"));
}
