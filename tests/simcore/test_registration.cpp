// Elastic registration onto a silhouette (issue 5 engine): the visible silhouette of the phantom, the
// ground-truth pose giving no correction, a rigid offset recovered, an elastic deformation recovered
// (against CalculiX on a finer mesh), and clear failures for unusable contours and poses. Contours are made
// independently of the engine: OpenCV's border of the CPU renderer's mask of the organ.
#include "test_support.hpp"
#include "icosphere.hpp"
#include "calculix.hpp"
#include "realorgan.hpp"
#include "test_registration_support.hpp"
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

#include <QStandardPaths>

using namespace rehearse;
using namespace rehearse::simcore;

class TestRegistration : public QObject {
  Q_OBJECT
  phantom::Phantom c_;
  std::unique_ptr<SaggedLiver> sagged_;  // loadSaggedLiver's, built once

 private slots:
  void initTestCase() { c_ = phantom::makePhantom(); }

  // The silhouette at the true pose: its chords project onto the rendered mask's border (the renderer
  // draws the same flat triangles), and its edges bent like PN triangles' lie nearer the outline of a
  // finer mesh of the same smooth organ than the chords do (the coarse mesh's flat faces cut inside it).
  void silhouetteMatchesTheRenderedOutline() {
    const FemModel m = organModel(c_);
    const auto sil = visibleSilhouette(c_.surface, m.restVector(), c_.truePose, c_.camera.pinhole());
    QVERIFY(sil.size() > 50);
    auto chords = sil;
    for (auto& e : chords) e.pm = 0.5 * (e.pa + e.pb);
    const auto contour = outline(c_, c_.truePose, c_.surfaceView());
    QVERIFY(!contour.empty());
    const Residual2D r = contourResidual(contour, chords);
    qInfo("%zu silhouette edges; rendered outline to the chords: mean %.2f px, RMS %.2f px, max %.2f px", sil.size(),
          r.mean, r.rms, r.hausdorff);
    QVERIFY(r.mean < 0.5);
    QVERIFY(r.hausdorff < 3.0);
    phantom::PhantomOptions fineOptions;
    fineOptions.targetTets = 16000;
    const phantom::Phantom fine = phantom::makePhantom(fineOptions);
    const auto fineOutline = outline(fine, c_.truePose, fine.surfaceView());
    const Residual2D toChords = contourResidual(fineOutline, chords), toCurved = contourResidual(fineOutline, sil);
    double bulge = 0;
    for (const auto& e : sil) bulge += (e.pm - 0.5 * (e.pa + e.pb)).norm() / sil.size();
    qInfo(
        "outline of the %zu-tet mesh to the %zu-tet mesh's chords: mean %.2f px, RMS %.2f px; to its bent edges: mean "
        "%.2f px, RMS %.2f px "
        "(mean bulge %.2f px)",
        fine.volume.tets.size(), c_.volume.tets.size(), toChords.mean, toChords.rms, toCurved.mean, toCurved.rms,
        bulge);
    QVERIFY(bulge > 0.2);
    QVERIFY(toCurved.mean < 0.8 * toChords.mean);
  }

  // The contour's distances to the silhouette come from a grid of its edges (a fit asks hundreds of times): the same
  // numbers, bit for bit, as trying every edge, for points on the outline, scattered over and far outside the image,
  // on a pixel lattice (cell borders), and for a silhouette of a single edge.
  void silhouetteDistancesMatchEveryEdge() {
    const FemModel m = organModel(c_);
    const auto sil = visibleSilhouette(c_.surface, m.restVector(), c_.truePose, c_.camera.pinhole());
    std::vector<std::vector<Eigen::Vector2d>> sets{outline(c_, c_.truePose, c_.surfaceView())};
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-0.5, 1.5);
    const double w = c_.camera.width, h = c_.camera.height;
    std::vector<Eigen::Vector2d> scattered, far, lattice;
    for (int i = 0; i < 3000; ++i) scattered.emplace_back(u(rng) * w, u(rng) * h);
    for (const Eigen::Vector2d& p : {Eigen::Vector2d(-5000, -5000), Eigen::Vector2d(1e5, 3), Eigen::Vector2d(3, -1e5),
                                     Eigen::Vector2d(0.5 * w, 0.5 * h)})
      far.push_back(p);
    for (int y = 0; y < h; y += 7)
      for (int x = 0; x < w; x += 7) lattice.emplace_back(x, y);
    sets.push_back(scattered);
    sets.push_back(far);
    sets.push_back(lattice);
    auto everyEdge = [](const std::vector<Eigen::Vector2d>& points, const std::vector<SilhouetteEdge>& edges) {
      double sum = 0, sum2 = 0, largest = 0;
      for (const auto& p : points) {
        double best = std::numeric_limits<double>::infinity();
        for (const auto& e : edges) {
          double d;
          e.nearest(p, &d);
          best = std::min(best, d);
        }
        sum += best, sum2 += best * best, largest = std::max(largest, best);
      }
      const double n = static_cast<double>(points.size());
      return Eigen::Vector3d(sum / n, std::sqrt(sum2 / n), largest);
    };
    const std::vector<SilhouetteEdge> one{sil.front()};
    for (const auto* edges : {&sil, &one})
      for (const auto& points : sets) {
        const Residual2D r = contourResidual({points}, *edges);
        const Eigen::Vector3d ref = everyEdge(points, *edges);
        QCOMPARE(r.points, points.size());
        QVERIFY(r.mean == ref[0] && r.rms == ref[1] && r.hausdorff == ref[2]);
      }
    qInfo("%zu edges; %zu outline, %zu scattered, %zu far and %zu lattice points: the same distances as every edge",
          sil.size(), sets[0].size(), scattered.size(), far.size(), lattice.size());
  }

  // Against an analytic outline: a sphere of radius r at distance d on the optical axis projects to a
  // circle of radius f r / sqrt(d^2 - r^2). An icosphere's silhouette chords cut inside it; the bent
  // edges' middles lie near it.
  void bentSilhouetteFollowsASphere() {
    Mesh sphere;
    const double r = 0.05, d = 0.25, f = 1000;
    addIcosphere(sphere, Eigen::Vector3d(0, 0, d), r, 2, 0);
    Pinhole cam;
    cam.K << f, 0, 640, 0, f, 360, 0, 0, 1;
    cam.width = 1280;
    cam.height = 720;
    Eigen::VectorXd x(3 * sphere.points.size());
    for (std::size_t i = 0; i < sphere.points.size(); ++i) x.segment<3>(3 * i) = sphere.points[i];
    const auto sil = visibleSilhouette(sphere.triangles, x, Pose{}, cam);
    QVERIFY(sil.size() > 20);
    const double rho = f * r / std::sqrt(d * d - r * r);
    const Eigen::Vector2d centre(640, 360);
    double chord = 0, bent = 0;
    for (const auto& e : sil) {
      chord += std::abs((0.5 * (e.pa + e.pb) - centre).norm() - rho) / sil.size();
      bent += std::abs((e.pm - centre).norm() - rho) / sil.size();
    }
    qInfo(
        "%zu silhouette edges of a %zu-triangle icosphere; circle of %.1f px: the chords' middles %.2f px from it, the "
        "bent edges' %.2f px",
        sil.size(), sphere.triangles.size(), rho, chord, bent);
    QVERIFY(chord > 1.0);
    QVERIFY(bent < 0.25 * chord);
  }

  void groundTruthPoseNeedsNoCorrection() {
    const FemModel m = organModel(c_);
    const auto contour = outline(c_, c_.truePose, c_.surfaceView());
    SimulationSettings s;
    s.gravity.setZero();
    const auto res = registerToContour(m, c_.attachments, s, c_.surface, contour, c_.truePose, c_.camera.pinhole());
    QVERIFY2(res.ok, res.status.c_str());
    const double moved = (res.x - m.restVector()).cwiseAbs().maxCoeff();
    qInfo("%s; largest node correction %.3f mm in %zu iterations", res.status.c_str(), 1e3 * moved,
          res.iterations.size());
    QVERIFY(moved < 1e-3);  // under a millimetre: the outline is pixel-quantised
    QVERIFY(res.iterations.back().residual.mean < 1.0);
  }

  void rigidOffsetIsRecovered() {
    const FemModel m = organModel(c_);
    const auto contour = outline(c_, c_.truePose, c_.surfaceView());
    const Pose start =
        offset(c_.truePose, Eigen::Vector3d(0.006, -0.004, 0.0), Eigen::Vector3d::UnitZ(), 4.0, c_.centreOfGravity());
    RegistrationOptions o;
    o.elastic = false;
    o.rigidIterations = 30;
    SimulationSettings s;
    s.gravity.setZero();
    const auto res = registerToContour(m, c_.attachments, s, c_.surface, contour, start, c_.camera.pinhole(), o);
    QVERIFY2(res.ok, res.status.c_str());
    const double dt = (res.pose.t - c_.truePose.t).norm();
    const double dr = Eigen::AngleAxisd(res.pose.R * c_.truePose.R.transpose()).angle() * 180 / M_PI;
    qInfo("rigid: start %.2f px -> %.2f px; pose error %.2f mm, %.2f degrees (start 7.2 mm, 4 degrees)",
          res.iterations.front().residual.mean, res.iterations.back().residual.mean, 1e3 * dt, dr);
    QVERIFY(res.iterations.back().residual.mean < 1.0);
    QVERIFY(dr < 1.0);
    QVERIFY(dt < 0.003);
  }

  // A rigid stage stopped early (one ICP iteration, no hops) from a start far off ends in a poor place; the
  // ambiguity probes' short fits from around it find poses that fit the contour clearly better, and the fit
  // continues from the best of them instead of reporting the poor one (or calling the better ones
  // alternatives). Without adoption (adoptRounds = 0) the same fit stays where it stopped.
  void clearlyBetterProbeIsAdopted() {
    const FemModel m = organModel(c_);
    const auto contour = outline(c_, c_.truePose, c_.surfaceView());
    // 3 cm right, 2 cm deeper and turned 40 degrees about the camera's x axis: one ICP iteration leaves the
    // organ about 2.5 mm off (about 2 px); the whole rigid stage reaches 0.7 mm from it.
    const Pose start =
        offset(c_.truePose, Eigen::Vector3d(0.03, 0.0, 0.02), Eigen::Vector3d::UnitX(), 40.0, c_.centreOfGravity());
    RegistrationOptions o;
    o.elastic = false;
    o.rigidIterations = 1;
    o.hops = false;
    SimulationSettings s;
    s.gravity.setZero();
    RegistrationOptions without = o;
    without.adoptRounds = 0;
    const auto stopped =
        registerToContour(m, c_.attachments, s, c_.surface, contour, start, c_.camera.pinhole(), without);
    const auto adopted = registerToContour(m, c_.attachments, s, c_.surface, contour, start, c_.camera.pinhole(), o);
    QVERIFY2(stopped.ok && adopted.ok, (stopped.status + " / " + adopted.status).c_str());
    auto poseError = [&](const Pose& p) {
      double sum = 0;
      for (const auto& q : c_.volume.points) sum += (p.apply(q) - c_.truePose.apply(q)).norm();
      return 1e3 * sum / static_cast<double>(c_.volume.points.size());
    };
    const double before = stopped.iterations.back().score(), after = adopted.iterations.back().score();
    qInfo("stopped early: %.2f px, organ %.2f mm from the truth; with adoption (%d): %.2f px, %.2f mm", before,
          poseError(stopped.pose), adopted.adopted, after, poseError(adopted.pose));
    QCOMPARE(stopped.adopted, 0);
    QVERIFY(adopted.adopted >= 1);
    QVERIFY(after < 0.85 * before);
    QVERIFY(poseError(adopted.pose) < 0.5 * poseError(stopped.pose));
    QVERIFY(poseError(adopted.pose) < 2.0);
  }

  // The elastic deformation recovered, against ground truth that is not our model: the phantom meshed again 2.5x finer,
  // sagged 3 g sideways in the image on its ligaments by CalculiX (Neo-Hookean, vessels 23x stiffer), its outline
  // rendered at the true pose as the contour. The fit (our co-rotational model on the coarse mesh, from the rest shape)
  // must bring the organ's visible surface within a stated distance of the truth, interpolated at our nodes.
  void calculixSagIsRecovered() {
    if (QStandardPaths::findExecutable("ccx").isEmpty())
      QFAIL("CalculiX (ccx) is not installed; scripts/install-deps.sh installs calculix-ccx");
    phantom::PhantomOptions po;
    po.targetTets = 10000;
    const phantom::Phantom fine = phantom::makePhantom(po);
    QVERIFY(fine.volume.tets.size() > 2 * c_.volume.tets.size());
    const Eigen::Vector3d g = c_.truePose.R.transpose() * Eigen::Vector3d(3 * 9.81, 0, 0);
    const Eigen::VectorXd u = runCalculixStatic(fine.volume, {{phantom::kVesselLabel, {620e3, 0.45, 1000, true}}},
                                                {27e3, 0.4, 1000, true}, g, true, fine.attachments, "phantom-sag");
    QVERIFY2(u.size() > 0, "ccx failed");
    std::vector<double> deformed(3 * fine.volume.points.size());
    for (std::size_t i = 0; i < fine.volume.points.size(); ++i)
      for (int k = 0; k < 3; ++k)
        deformed[3 * i + k] = fine.volume.points[i][k] + u[3 * static_cast<Eigen::Index>(i) + k];
    SurfaceView fineDeformed = fine.surfaceView();
    fineDeformed.vertices = deformed.data();
    const auto contour = outline(fine, fine.truePose, fineDeformed);
    QVERIFY(!contour.empty());
    // The truth at our nodes: CalculiX's displacement interpolated in the fine tetrahedron holding the
    // node's rest position (the nearest one for nodes just outside the finer surface).
    const FemModel m = organModel(c_);
    std::vector<int> nodes;
    {
      std::set<int> onSurface;
      for (const auto& t : c_.surface) onSurface.insert(t.begin(), t.end());
      nodes.assign(onSurface.begin(), onSurface.end());
    }
    std::vector<Eigen::Vector3d> truth(c_.volume.points.size());
    for (int v : nodes) {
      const Eigen::Vector3d p = c_.volume.points[v];
      double bestInside = -1e9;
      Eigen::Vector3d best = Eigen::Vector3d::Zero();
      for (const auto& t : fine.volume.tets) {
        const auto& P = fine.volume.points;
        Eigen::Matrix3d A;
        A << P[t[1]] - P[t[0]], P[t[2]] - P[t[0]], P[t[3]] - P[t[0]];
        const Eigen::Vector3d b = A.partialPivLu().solve(p - P[t[0]]);
        const double w[4] = {1 - b.sum(), b.x(), b.y(), b.z()};
        const double inside = *std::min_element(w, w + 4);
        if (inside <= bestInside) continue;
        bestInside = inside;
        best.setZero();
        for (int k = 0; k < 4; ++k) best += std::clamp(w[k], 0.0, 1.0) * u.segment<3>(3 * t[k]);
        best /= std::clamp(w[0], 0.0, 1.0) + std::clamp(w[1], 0.0, 1.0) + std::clamp(w[2], 0.0, 1.0) +
                std::clamp(w[3], 0.0, 1.0);
      }
      truth[v] = p + best;
    }
    // The visible surface: nodes the camera sees at the true pose (depth test against the rest render).
    const auto ras = imaging::rasterize(c_.camera, c_.truePose, c_.surfaceView());
    std::vector<int> visible;
    for (int v : nodes) {
      const Eigen::Vector3d xc = c_.truePose.apply(c_.volume.points[v]);
      const Eigen::Vector2d px = c_.camera.project(xc);
      const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
      if (x < 0 || y < 0 || x >= ras.depth.cols || y >= ras.depth.rows) continue;
      if (ras.triangle(y, x) >= 0 && xc.z() <= ras.depth(y, x) + 1e-3) visible.push_back(v);
    }
    QVERIFY(visible.size() > 100);
    // The error in the camera frame: across the view (what a silhouette shows) and along it (depth).
    // In the camera frame: the fit may have moved the pose too (its rigid pre-pass).
    auto meanError = [&](const Eigen::VectorXd& x, const std::vector<int>& which, int part = 0,
                         const Pose* pose = nullptr) {
      const Pose& at = pose ? *pose : c_.truePose;
      double e = 0;
      for (int v : which) {
        const Eigen::Vector3d d = at.apply(x.segment<3>(3 * v)) - c_.truePose.apply(truth[v]);
        e += part == 0 ? d.norm() : part == 1 ? d.head<2>().norm() : std::abs(d.z());
      }
      return e / which.size();
    };
    double sag = 0;
    for (int v : nodes) sag = std::max(sag, (truth[v] - c_.volume.points[v]).norm());
    SimulationSettings s;
    s.gravity.setZero();
    const auto res = registerToContour(m, c_.attachments, s, c_.surface, contour, c_.truePose, c_.camera.pinhole());
    QVERIFY2(res.ok, res.status.c_str());
    const Eigen::VectorXd rest = m.restVector();
    const double visibleBefore = meanError(rest, visible), visibleAfter = meanError(res.x, visible, 0, &res.pose);
    const double allBefore = meanError(rest, nodes), allAfter = meanError(res.x, nodes, 0, &res.pose);
    qInfo(
        "CalculiX sag (%zu fine tets, largest %.1f mm) fitted on %zu tets: %s; visible surface %.2f -> %.2f mm, whole "
        "surface %.2f -> %.2f mm; "
        "2D %.2f -> %.2f px",
        fine.volume.tets.size(), 1e3 * sag, c_.volume.tets.size(), res.status.c_str(), 1e3 * visibleBefore,
        1e3 * visibleAfter, 1e3 * allBefore, 1e3 * allAfter, res.iterations.front().residual.mean,
        res.iterations.back().residual.mean);
    qInfo("  visible surface across the view %.2f -> %.2f mm, in depth %.2f -> %.2f mm",
          1e3 * meanError(rest, visible, 1), 1e3 * meanError(res.x, visible, 1, &res.pose),
          1e3 * meanError(rest, visible, 2), 1e3 * meanError(res.x, visible, 2, &res.pose));
    qInfo("  pose moved by %.2f mm", 1e3 * (res.pose.t - c_.truePose.t).norm());
    QVERIFY(sag > 0.008);  // a real sag to recover
    // Measured 12.5 -> 6.6 mm (visible), 9.7 -> 5.2 mm (whole surface), 18.6 -> 0.8 px: a silhouette pins
    // the rim across the view, not where the surface slides along it or in depth (issue 13 works on that).
    QVERIFY2(visibleAfter < 0.008, "the visible surface ended more than 8 mm from CalculiX's");
    QVERIFY(visibleAfter < 0.6 * visibleBefore);
    QVERIFY(allAfter < 0.7 * allBefore);
    QVERIFY(res.iterations.back().residual.mean < 1.5);
  }

  // The sag estimated with the pose (issue 13), on a real organ against CalculiX: the BodyParts3D liver
  // meshed twice (8,000 tets for CalculiX, 2,500 for the fit), held by the 12 % of its surface farthest from
  // the scikit-surgery laparoscope, sagged by a body load down the image and a little away (Neo-Hookean,
  // 15 kPa, NLGEOM), its whole outline the contour; the fit (the application's liver preset, rigid stage on)
  // from the true pose moved 2 cm sideways. Explained by its pose alone, the sagging outline puts the organ
  // in the wrong place (the outline's sag taken for a move and a turn); with the sag, the visible surface
  // ends nearer CalculiX's and the load found points down the image as CalculiX's did.
  void realLiverSagIsEstimatedWithThePose() {
    QString why;
    const SaggedLiver* L = loadSaggedLiver(sagged_, why);
    if (!L) {
      if (why.startsWith(QStringLiteral("absent")) && !sharedDataRequired()) QSKIP(qPrintable(why));
      QFAIL(qPrintable(why));
    }
    const auto& organ = L->organ;
    RegistrationOptions o;
    o.rigidPrepass = true;
    const auto withSag = L->fit(L->outline, o);
    o.estimateSag = false;
    const auto poseOnly = L->fit(L->outline, o);
    QVERIFY2(withSag.ok && poseOnly.ok, (withSag.status + " / " + poseOnly.status).c_str());
    const Eigen::Vector3d load = withSag.pose.R * withSag.load;
    const double cosine = load.normalized().dot(L->gCamera.normalized());
    RegistrationResult undeformed;
    undeformed.x = L->model.restVector();
    undeformed.pose = L->truth;
    qInfo(
        "BodyParts3D liver (%zu tets for CalculiX, %zu for the fit), sagged %.1f mm: undeformed at the true pose %.2f "
        "mm; fit with the sag %.2f mm "
        "(%s; load %.2f %.2f %.2f m/s^2 in the camera frame, %.0f degrees from CalculiX's), with the pose alone %.2f "
        "mm",
        L->fineTets, organ->volume.tets.size(), 1e3 * L->sag, 1e3 * L->error(undeformed), 1e3 * L->error(withSag),
        withSag.status.c_str(), load.x(), load.y(), load.z(), std::acos(std::clamp(cosine, -1.0, 1.0)) * 180 / M_PI,
        1e3 * L->error(poseOnly));
    QVERIFY(L->sag > 0.015);
    // The fit's own bound on how far its visible surface may be (issue 38) against CalculiX's truth: it covers the
    // error and is not a blanket (at most 3x it); the weakest direction is named.
    const auto& un = withSag.uncertainty;
    qInfo(
        "  bound %.2f mm (curvature %.2f, spread %.2f; misfit %.2f px, correlation %.2f), weakest %s; true error %.2f "
        "mm",
        un.surfaceMm, un.curvatureMm, un.spreadMm, un.misfitPx, un.correlation, un.weakest.c_str(),
        1e3 * L->error(withSag));
    QVERIFY(un.computed && !un.weakest.empty());
    QVERIFY2(1e3 * L->error(withSag) <= un.surfaceMm && un.surfaceMm <= 3e3 * L->error(withSag),
             qPrintable(QString("bound %1 mm, error %2 mm").arg(un.surfaceMm).arg(1e3 * L->error(withSag))));
    QVERIFY(un.targetMm >= un.curvatureMm);
    QCOMPARE(poseOnly.load.norm(), 0.0);  // not estimated: the given gravity (none)
    QVERIFY(cosine > 0.8);
    QVERIFY(L->error(withSag) < 0.9 * L->error(poseOnly));
    // Not told which way is down, the outline does not show the part of the sag along the view: the probe
    // with a weaker prior may say so, but only for a fit that is indeed more than 3 mm off (no false alarm).
    QVERIFY2(!withSag.ambiguous || L->error(withSag) > 0.003, withSag.status.c_str());
    // The part of the sag along the view is what the outline cannot show: told which way is down (the
    // gravity's direction in the camera frame, its size left to the fit), the sag found takes it too.
    o.estimateSag = true;
    o.gravityCamera = L->gCamera;
    const auto toldDown = L->fit(L->outline, o);
    const Eigen::Vector3d toldLoad = toldDown.pose.R * toldDown.load;
    qInfo("  told which way is down: with the sag %.2f mm (load %.2f %.2f %.2f m/s^2, %.0f degrees from CalculiX's)",
          1e3 * L->error(toldDown), toldLoad.x(), toldLoad.y(), toldLoad.z(),
          std::acos(std::clamp(toldLoad.normalized().dot(L->gCamera.normalized()), -1.0, 1.0)) * 180 / M_PI);
    QVERIFY2(toldDown.ok && toldDown.sagDetermined, toldDown.status.c_str());
    // Determined only within its bound (5.5 mm here, its error 3.61 mm): at the default 5 mm tolerance it says so.
    QVERIFY2(toldDown.ambiguous == (toldDown.uncertainty.surfaceMm > 5), toldDown.status.c_str());
    QVERIFY2(!toldDown.ambiguous || toldDown.status.find("more than the 5.0 mm asked for") != std::string::npos,
             toldDown.status.c_str());
    // (Its size is not used: centring the sag on 1 g gave 2.48 mm here but put the kidney of
    // bench_registration_real, whose fit model sags ten times more per unit load than CalculiX's, 36 mm off.)
    QVERIFY(L->error(toldDown) < 0.004);
    QVERIFY(L->error(toldDown) < 0.9 * L->error(withSag));
    QVERIFY(toldLoad.normalized().dot(L->gCamera.normalized()) > 0.95);
  }

  // A second frame (issue 38): the camera moved 15 mm across the view and turned to keep the organ in the middle, the
  // outline sketched on both. Two outlines alone barely help (a smooth organ's outlines 3 degrees apart are nearly the
  // same rim); features tracked between the frames (triangulated through the motion, weighed by their depth's noise)
  // decide what one outline leaves to the model's size, the depth: the sagged BodyParts3D liver's error against
  // CalculiX's falls, and so does the fit's own bound, which still covers it.
  void secondFrameFixesDepth() {
    QString why;
    const SaggedLiver* L = loadSaggedLiver(sagged_, why);
    if (!L) {
      if (why.startsWith(QStringLiteral("absent")) && !sharedDataRequired()) QSKIP(qPrintable(why));
      QFAIL(qPrintable(why));
    }
    RegistrationOptions o;
    o.rigidPrepass = true;
    const auto one = L->fit(L->outline, o);
    QVERIFY2(one.ok, one.status.c_str());
    RegistrationFrame second;
    makeSecondFrame(L, second);
    if (QTest::currentTestFailed()) return;
    o.frames = {second};
    checkTwoFrames(L, o, one);
    if (QTest::currentTestFailed()) return;
    checkEstimatedMotion(L, o, second, one);
    if (QTest::currentTestFailed()) return;
    checkSecondFrameCommandLine(L, second);
    if (QTest::currentTestFailed()) return;
    // A motion that is not a rotation, or an empty outline on the second frame, is refused with a sentence.
    o.frames[0].motion.R(0, 0) = 2;
    try {
      L->fit(L->outline, o);
      QFAIL("a motion that is not a rotation was accepted");
    } catch (const MeshError& e) {
      QVERIFY2(std::string(e.what()).find("not a rotation") != std::string::npos, e.what());
    }
    o.frames[0] = second;
    o.frames[0].contour.clear();
    try {
      L->fit(L->outline, o);
      QFAIL("an empty second outline was accepted");
    } catch (const MeshError& e) {
      QVERIFY2(std::string(e.what()).find("frame 2 is empty") != std::string::npos, e.what());
    }
  }

  // Stiff and extreme models under the same fit: near-incompressible parenchyma, a 1000x vessel/parenchyma
  // ratio at 10 MPa, a very soft organ, and the nonlinear laws. Each ends finite, with a status, and
  // never further from the contour than it started without saying so.
  void extremeModelsStayFinite() {
    const Deformed truth = deformSideways(c_, organModel(c_));
    QVERIFY(truth.x.size() > 0);
    struct Case {
      const char* name;
      MaterialParams parenchyma, vessels;
    };
    const Case cases[] = {
        {"nu 0.499",
         {MaterialModel::Corotational, 27e3, 0.499, 1000},
         {MaterialModel::Corotational, 620e3, 0.499, 1000}},
        {"10 MPa / 10 GPa vessels",
         {MaterialModel::Corotational, 10e6, 0.45, 1000},
         {MaterialModel::Corotational, 10e9, 0.45, 1000}},
        {"100 Pa", {MaterialModel::Corotational, 100, 0.4, 1000}, {MaterialModel::Corotational, 1e5, 0.45, 1000}},
        {"stvk", {MaterialModel::StVK, 27e3, 0.4, 1000}, {MaterialModel::StVK, 620e3, 0.45, 1000}},
        {"neohookean nu 0.49",
         {MaterialModel::NeoHookean, 27e3, 0.49, 1000},
         {MaterialModel::NeoHookean, 620e3, 0.49, 1000}},
    };
    SimulationSettings s;
    s.gravity.setZero();
    for (const auto& k : cases) {
      const FemModel m = FemModel::build(c_.volume, {{2, k.vessels}}, k.parenchyma);
      Pose start = c_.truePose;
      start.t.x() += 0.004;
      const auto res =
          registerToContour(m, c_.attachments, s, c_.surface, truth.contour, start, c_.camera.pinhole(), {});
      QVERIFY2(res.x.allFinite(), k.name);
      QVERIFY2(res.pose.t.allFinite() && res.pose.R.allFinite(), k.name);
      QVERIFY2(!res.status.empty(), k.name);
      QVERIFY(!res.iterations.empty());
      const double first = res.iterations.front().residual.mean, last = res.iterations.back().residual.mean;
      qInfo("%-24s %s: %.2f px -> %.2f px, %zu iterations, %.0f ms", k.name, res.status.c_str(), first, last,
            res.iterations.size(), res.iterations.back().wallMs);
      if (res.ok)
        QVERIFY2(last <= first, k.name);
      else
        QVERIFY2(res.status.find("worse") != std::string::npos || res.status.find("not") != std::string::npos,
                 res.status.c_str());
    }
  }

  // An anatomical curve (a ridge across the organ's visible side, its nodes and their projections in the
  // deformed truth) added to the silhouette: the fit follows it and the 3D error falls further than with
  // the silhouette alone.
  void anatomicalCurveConstrainsTheFit() {
    const FemModel m = organModel(c_);
    const Deformed truth = deformSideways(c_, m);
    QVERIFY(truth.x.size() > 0);
    const auto& contour = truth.contour;
    const Pinhole cam = c_.camera.pinhole();
    const AnatomicalCurve ridge = frontRidge(c_, m, truth.x);
    QVERIFY(ridge.nodes.size() >= 8);
    auto meanError = [&](const Eigen::VectorXd& x) {
      double e = 0;
      for (std::size_t i = 0; i < m.nodeCount(); ++i) e += (x.segment<3>(3 * i) - truth.x.segment<3>(3 * i)).norm();
      return e / m.nodeCount();
    };
    SimulationSettings s;
    s.gravity.setZero();
    const auto plain = registerToContour(m, c_.attachments, s, c_.surface, contour, c_.truePose, cam);
    RegistrationOptions o;
    o.curves = {ridge};
    o.onIteration = [](const RegistrationIteration& it, const Eigen::VectorXd&, const Pose&) {
      qInfo("  iteration %d: %.2f px, curve %.2f px, %zu bound, %.0f ms", it.iteration, it.residual.mean,
            it.curves.mean, it.bound, it.wallMs);
      return true;
    };
    const auto withCurve = registerToContour(m, c_.attachments, s, c_.surface, contour, c_.truePose, cam, o);
    QVERIFY2(plain.ok && withCurve.ok, withCurve.status.c_str());
    const auto& first = withCurve.iterations.front();
    const auto& last = withCurve.iterations.back();
    qInfo(
        "ridge of %zu nodes: curve distance %.2f px -> %.2f px; node error %.2f mm (undeformed), %.2f mm (silhouette "
        "only), %.2f mm "
        "(silhouette and ridge); %s; %.0f ms (silhouette only %.0f ms)",
        ridge.nodes.size(), first.curves.mean, last.curves.mean, 1e3 * meanError(m.restVector()),
        1e3 * meanError(plain.x), 1e3 * meanError(withCurve.x), withCurve.status.c_str(), last.wallMs,
        plain.iterations.back().wallMs);
    QVERIFY(first.curves.points > 0);
    QVERIFY(last.curves.mean < 0.5 * first.curves.mean);
    QVERIFY(meanError(withCurve.x) < 0.9 * meanError(plain.x));
    // The curve alone (no silhouette) is enough to fit; a curve node the organ does not have is refused.
    const auto curveOnly = registerToContour(m, c_.attachments, s, c_.surface, {}, c_.truePose, cam, o);
    QVERIFY2(curveOnly.ok, curveOnly.status.c_str());
    QVERIFY(meanError(curveOnly.x) < meanError(m.restVector()));
    o.curves[0].nodes.push_back(static_cast<int>(m.nodeCount()) + 5);
    try {
      registerToContour(m, c_.attachments, s, c_.surface, contour, c_.truePose, cam, o);
      QFAIL("a curve node outside the mesh was accepted");
    } catch (const MeshError& e) {
      QVERIFY2(std::string(e.what()).find("does not have") != std::string::npos, e.what());
    }
  }

  // The outline of another organ (BodyParts3D's left kidney, placed where the liver is) cannot be reached
  // by a plausible deformation of the liver: a clear failure status, not a result.
  // A contour that does not determine the pose is said to be ambiguous, never a plain success: an organ
  // symmetric about the view axis (an oblate spheroid, 100 x 100 x 50 mm, its short axis along the view)
  // has the same outline whatever its turn about that axis, so turns of it fit the contour as well (the
  // reference: that symmetry, not our code). The phantom, a liver-like shape, is determined by its whole
  // outline (no false alarm).
  void undeterminedPoseIsReportedAmbiguous() {
    RegistrationOptions o;
    o.elastic = false;
    SimulationSettings s;
    s.gravity.setZero();
    double phantomBound = -1;
    {
      const auto res =
          registerToContour(organModel(c_), c_.attachments, s, c_.surface, outline(c_, c_.truePose, c_.surfaceView()),
                            c_.truePose, c_.camera.pinhole(), o);
      qInfo("phantom: %s; bound %.2f mm, weakest %s", res.status.c_str(), res.uncertainty.surfaceMm,
            res.uncertainty.weakest.c_str());
      QVERIFY2(res.ok && !res.ambiguous && res.alternatives.empty(), res.status.c_str());
      phantomBound = res.uncertainty.surfaceMm;
      QVERIFY(res.uncertainty.computed && phantomBound > 0 && phantomBound < 5);
      QVERIFY2(res.uncertainty.weakest.find("a turn about") == 0, res.uncertainty.weakest.c_str());
      // Its far ends lie along the curvature's weakest direction, by the bound each way: the phantom tilted about its
      // centre (named so: before, the turn's move about the camera was named "a move along the camera's Y axis").
      const auto moved = checkEnds(res, c_.surface);
      QVERIFY(std::abs(moved.first - phantomBound) < 0.05 * phantomBound);
      QVERIFY(std::abs(moved.second - phantomBound) < 0.05 * phantomBound);
      for (const auto& end : res.uncertainty.ends) {
        const Eigen::Vector3d shift = end.pose.apply(c_.centreOfGravity()) - res.pose.apply(c_.centreOfGravity());
        const double turned = Eigen::AngleAxisd(end.pose.R * res.pose.R.transpose()).angle() * 180 / M_PI;
        qInfo("phantom's end: its centre moved (%.3f, %.3f, %.3f) mm, turned %.3f degrees", 1e3 * shift.x(),
              1e3 * shift.y(), 1e3 * shift.z(), turned);
        QVERIFY(shift.norm() < 0.5 * phantomBound && turned > 0.1 && turned < 2);
      }
    }
    const Eigen::Vector3d radii(0.05, 0.05, 0.025);
    TetrahedraliseOptions to;
    to.targetTets = 3000;
    Mesh volume =
        tetrahedraliseImplicit([radii](const Eigen::Vector3d& p) { return p.cwiseQuotient(radii).norm() < 1 ? 1 : 0; },
                               Eigen::AlignedBox3d(-radii * 1.1, radii * 1.1), to, 4.0 / 3 * M_PI * radii.prod());
    const FemModel m = FemModel::build(volume, {}, {MaterialModel::Corotational, 27e3, 0.4, 1000});
    const auto surface = boundaryTriangles(volume, false);
    std::vector<double> vertices;
    for (const auto& p : volume.points) vertices.insert(vertices.end(), {p.x(), p.y(), p.z()});
    const SurfaceView view{vertices.data(), volume.points.size(), surface.front().data(), surface.size()};
    Pose truth;
    truth.t = Eigen::Vector3d(0.0, 0.0, 0.35);
    const auto contour = outline(c_, truth, view);
    QVERIFY(!contour.empty());
    const auto res = registerToContour(m, {}, s, surface, contour, truth, c_.camera.pinhole(), o);
    qInfo("spheroid: %s", res.status.c_str());
    QVERIFY2(res.ok && res.ambiguous, res.status.c_str());
    QVERIFY(res.status.rfind("ambiguous: ", 0) == 0);
    QVERIFY(res.status.find("ridge or ligament curve") !=
            std::string::npos);  // the outline is whole: only a curve can tell
    QVERIFY(!res.alternatives.empty());
    bool turnAboutView = false;
    for (const auto& a : res.alternatives) {
      const Eigen::AngleAxisd turn(a.pose.R * res.pose.R.transpose());
      const double aboutView = turn.angle() * std::abs(turn.axis().z()) * 180 / M_PI;
      const double across = turn.angle() * turn.axis().head<2>().norm() * 180 / M_PI;
      qInfo("alternative: %.1f degrees about the view, %.1f across, moved %.1f mm; %.1f mm apart, %.2f px", aboutView,
            across, 1e3 * (a.pose.t - res.pose.t).norm(), a.apartMm, a.score);
      QVERIFY(a.apartMm > 5);
      turnAboutView |= aboutView > 10 && across < 6 && (a.pose.t - res.pose.t).norm() < 0.002;
    }
    QVERIFY(turnAboutView);  // the symmetry itself is among them
    // They span the set (issue 38): the farthest first, each other one more than 5 mm from those before it.
    for (std::size_t i = 1; i < res.alternatives.size(); ++i) {
      QVERIFY(res.alternatives[i].apartMm <= res.alternatives[0].apartMm);
      for (std::size_t j = 0; j < i; ++j) {
        double sum = 0;
        for (const auto& p : volume.points)
          sum += (res.alternatives[i].pose.apply(p) - res.alternatives[j].pose.apply(p)).norm();
        QVERIFY(1e3 * sum / static_cast<double>(volume.points.size()) > 5);
      }
    }
    // The fit's bound (issue 38) names that turn as its weakest direction and is far wider than the phantom's.
    qInfo("spheroid: bound %.2f mm (curvature %.2f, spread %.2f), weakest %s", res.uncertainty.surfaceMm,
          res.uncertainty.curvatureMm, res.uncertainty.spreadMm, res.uncertainty.weakest.c_str());
    QVERIFY2(res.uncertainty.weakest.find("turn about the camera's Z") != std::string::npos,
             res.uncertainty.weakest.c_str());
    QVERIFY(res.uncertainty.surfaceMm > 3 * phantomBound);
    {
      // The far ends the fit page draws: the spheroid turned about the view each way, by the bound at its front.
      const auto moved = checkEnds(res, surface);
      QVERIFY(std::abs(moved.first - res.uncertainty.surfaceMm) < 0.05 * res.uncertainty.surfaceMm);
      QVERIFY(std::abs(moved.second - res.uncertainty.surfaceMm) < 0.05 * res.uncertainty.surfaceMm);
      for (const auto& end : res.uncertainty.ends) {
        const Eigen::AngleAxisd turn(end.pose.R * res.pose.R.transpose());
        qInfo("spheroid's end: turned %.1f degrees about (%.2f, %.2f, %.2f), moved %.2f mm", turn.angle() * 180 / M_PI,
              turn.axis().x(), turn.axis().y(), turn.axis().z(), 1e3 * (end.pose.t - res.pose.t).norm());
        QVERIFY(std::abs(turn.axis().z()) > 0.9 && turn.angle() > 2 * M_PI / 180);
      }
    }
    // The command line: the best fit is written, the report names the alternatives, the exit code is 4.
    const std::string dir = tempPath("register-spheroid");
    std::filesystem::create_directories(dir);
    saveMesh(volume, dir + "/spheroid.vtu");
    imaging::saveCamera(c_.camera, dir + "/camera.json");
    imaging::Contour file;
    file.width = c_.camera.width;
    file.height = c_.camera.height;
    for (const auto& seg : contour) file.segments.push_back({seg, true, "silhouette", {}});
    imaging::saveContour(file, dir + "/contour.json");
    imaging::savePose(truth, dir + "/pose.json");
    QProcess p;
    p.start(QStringLiteral(REHEARSE_BINARY),
            {"register", "--mesh", QString::fromStdString(dir + "/spheroid.vtu"), "--camera",
             QString::fromStdString(dir + "/camera.json"), "--contour", QString::fromStdString(dir + "/contour.json"),
             "--pose", QString::fromStdString(dir + "/pose.json"), "--rigid-only", "--out",
             QString::fromStdString(dir + "/registered.vtu"), "--report", QString::fromStdString(dir + "/report.json"),
             "--ends-out", QString::fromStdString(dir + "/end.vtu")});
    QVERIFY(p.waitForFinished(300000));
    const QString err = QString::fromUtf8(p.readAllStandardError());
    QCOMPARE(p.exitCode(), 4);
    QVERIFY2(err.startsWith("rehearse: ambiguous: "), qPrintable(err));
    QVERIFY(std::filesystem::exists(dir + "/registered.vtu"));
    const QJsonObject report =
        QJsonDocument::fromJson(QByteArray::fromStdString(readFile(dir + "/report.json"))).object();
    QVERIFY(report["ok"].toBool() && report["ambiguous"].toBool() && !report["determined"].toBool());
    const QJsonArray alternatives = report["alternatives"].toArray();
    QVERIFY(!alternatives.isEmpty());
    for (const auto& a : alternatives) {
      QVERIFY(a.toObject()["apart_mm"].toDouble() > 5);
      QCOMPARE(a.toObject()["pose"].toObject()["t"].toArray().size(), 3);
      QCOMPARE(a.toObject()["pose"].toObject()["R"].toArray().size(), 3);
    }
    // Where the organ may be: the two far ends written beside the fit (camera frame), each moving the fitted surface
    // that faces the camera by the reported bound on average (within 5 %), their poses in the report.
    const QJsonObject u = report["uncertainty"].toObject();
    QCOMPARE(u["ends"].toArray().size(), 2);
    const double bound = u["surface_mm"].toDouble();
    const Mesh fitted = loadMesh(dir + "/registered.vtu");
    std::vector<char> front(fitted.points.size(), 0);
    for (const auto& t : surface) {
      const Eigen::Vector3d &a = fitted.points[t[0]], &b = fitted.points[t[1]], &c = fitted.points[t[2]];
      if ((b - a).cross(c - a).dot(a) < 0)
        for (int v : t) front[static_cast<std::size_t>(v)] = 1;
    }
    for (const char* name : {"/end-1.vtu", "/end-2.vtu"}) {
      QVERIFY2(std::filesystem::exists(dir + name), name);
      const Mesh end = loadMesh(dir + name);
      QCOMPARE(end.points.size(), fitted.points.size());
      double sum = 0;
      std::size_t count = 0;
      for (std::size_t i = 0; i < end.points.size(); ++i)
        if (front[i]) sum += 1e3 * (end.points[i] - fitted.points[i]).norm(), ++count;
      qInfo("rehearse register --ends-out: %s moves the facing surface %.2f mm (the bound %.2f mm)", name,
            sum / static_cast<double>(count), bound);
      QVERIFY(std::abs(sum / static_cast<double>(count) - bound) < 0.05 * bound);
    }
  }
};

QTEST_GUILESS_MAIN(TestRegistration)
#include "test_registration.moc"
