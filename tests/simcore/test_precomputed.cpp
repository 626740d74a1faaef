// Precomputed linear elasticity (issue 37): superposition of the precomputed responses against the linear FEM's static
// solution solved directly (Eigen's SimplicialLDLT on the stiffness with the held and fixed nodes eliminated; the
// responses come from CHOLMOD), on the patient liver's CT shape meshed (../shared/data, scikit-surgery), hung by its
// highest 8 % of surface nodes under gravity: one held node, a grasp's patch of several, none (the sag). The
// instrument's force at the held nodes against the reaction K u - f_g of the direct solution; the co-rotational law's
// stiffness at rest against the linear law's; single precision's error and memory; refusals (nothing holds the organ,
// a driven node that is fixed, a node without a response, a cancelled build); a near-incompressible material.
#include "realorgan.hpp"
#include "session_inputs.hpp"
#include "static_checks.hpp"
#include "test_support.hpp"
#include "test_precomputed_support.hpp"

#include <rehearse/app/gesture.hpp>
#include <rehearse/app/recording.hpp>
#include <rehearse/simcore/cut.hpp>
#include <rehearse/simcore/hybrid.hpp>
#include <rehearse/simcore/precomputed.hpp>
#include <rehearse/simcore/session/body.hpp>
#include <rehearse/simcore/session/session.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <Eigen/SparseCholesky>

#include <nlohmann/json.hpp>

#include <QtTest>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <random>
#include <set>

using rehearse::testing::firstFreeSurfaceNode;
using rehearse::testing::holdAt;
using namespace rehearse;
using namespace rehearse::simcore;

class TestPrecomputed : public QObject {
  Q_OBJECT
  Organ organ_;

  // The `count` surface nodes nearest the surface node farthest from the attachments (a grasp's patch there).
  std::vector<int> patch(std::size_t count) const {
    const auto& p = organ_.mesh.points;
    Eigen::Vector3d hold = Eigen::Vector3d::Zero();
    int nh = 0;
    for (std::size_t i = 0; i < p.size(); ++i)
      if (organ_.fixed[i]) hold += p[i], ++nh;
    hold /= nh;
    int far = organ_.driven.front();
    for (int v : organ_.driven)
      if ((p[static_cast<std::size_t>(v)] - hold).norm() > (p[static_cast<std::size_t>(far)] - hold).norm()) far = v;
    std::vector<int> by = organ_.driven;
    std::sort(by.begin(), by.end(), [&](int a, int b) {
      return (p[static_cast<std::size_t>(a)] - p[static_cast<std::size_t>(far)]).norm() <
             (p[static_cast<std::size_t>(b)] - p[static_cast<std::size_t>(far)]).norm();
    });
    by.resize(count);
    return by;
  }

 private slots:
  void initTestCase() {
    REQUIRE_SHARED("scikit-surgery/patient-liver/liver.vtk");
    TetrahedraliseOptions to;
    to.allowSelfIntersections = true;
    to.targetTets = 4000;
    organ_.mesh =
        tetrahedraliseSurface(testing::loadOrganSurface(sharedData("scikit-surgery/patient-liver/liver.vtk")), to);
    organ_.fixed.assign(organ_.mesh.points.size(), 0);
    for (int v : testing::highestSurfaceNodes(organ_.mesh, 0.08)) organ_.fixed[static_cast<std::size_t>(v)] = 1;
    for (int v : testing::surfaceNodes(organ_.mesh))
      if (!organ_.fixed[static_cast<std::size_t>(v)]) organ_.driven.push_back(v);
    qInfo("patient liver: %zu elements, %zu nodes, %zu surface nodes driven, %ld fixed", organ_.mesh.tets.size(),
          organ_.mesh.points.size(), organ_.driven.size(), std::count(organ_.fixed.begin(), organ_.fixed.end(), 1));
  }

  // One held node, a grasp's patch of 6 held together (each displaced alike and a little apart), none: the
  // superposition equals the direct static solution to 1e-8 relative, and the force at the held nodes the reaction.
  void superpositionEqualsTheStaticSolution_data() {
    QTest::addColumn<int>("held");
    QTest::addColumn<double>("poisson");
    QTest::addColumn<bool>("surfaceRows");
    QTest::newRow("none (the sag)") << 0 << 0.45 << false;
    QTest::newRow("one node") << 1 << 0.45 << false;
    QTest::newRow("a patch of 6") << 6 << 0.45 << false;
    QTest::newRow("a patch of 6, nu 0.499") << 6 << 0.499 << false;
    QTest::newRow("one node, surface rows only") << 1 << 0.45 << true;
    QTest::newRow("a patch of 6, surface rows only") << 6 << 0.45 << true;
  }
  void superpositionEqualsTheStaticSolution() {
    QFETCH(int, held);
    QFETCH(double, poisson);
    QFETCH(bool, surfaceRows);
    const FemModel model = FemModel::build(organ_.mesh, {}, material(MaterialModel::Linear, poisson));
    std::string why;
    int calls = 0;
    PrecomputeSettings s;
    s.drivenRowsOnly = surfaceRows;
    s.progress = [&](double done) {
      ++calls;
      return done >= 0 && done <= 1;
    };
    QElapsedTimer clock;
    clock.start();
    const auto p = PrecomputedElasticity::build(model, organ_.fixed, organ_.driven, kGravity, s, why);
    QVERIFY2(p.has_value(), why.c_str());
    const double buildMs = static_cast<double>(clock.elapsed());
    QVERIFY(calls >= 1);
    const std::vector<int> nodes = patch(static_cast<std::size_t>(held));
    const std::vector<Eigen::Vector3d> d = spreadPull(nodes.size());
    Eigen::VectorXd u;
    std::vector<Eigen::Vector3d> force, reaction;
    QVERIFY2(p->solve(nodes, d, u, &force, why), why.c_str());
    const Eigen::VectorXd ref = directSolve(model, organ_.fixed, nodes, d, &reaction);
    const double err = relative(u, ref);
    const auto [forceErr, forceNorm] = largestDifference(force, reaction);
    qInfo(
        "%d held, nu %.3f: largest displacement %.1f mm, relative error %.2e; force at the held nodes up to %.3f N "
        "(error %.2e N); %zu responses (%.1f MB) built in %.0f ms",
        held, poisson, 1e3 * ref.reshaped(3, ref.size() / 3).colwise().norm().maxCoeff(), err, forceNorm, forceErr,
        3 * organ_.driven.size(), p->memoryBytes() / 1e6, buildMs);
    QVERIFY(u.allFinite());
    QVERIFY2(err <= 1e-8, qPrintable(QString::number(err)));
    if (held > 0) QVERIFY2(forceErr <= 1e-8 * forceNorm, qPrintable(QString::number(forceErr / forceNorm)));
    // The held nodes are where they were put.
    for (std::size_t k = 0; k < nodes.size(); ++k) QVERIFY((u.segment<3>(3 * nodes[k]) - d[k]).norm() <= 1e-12);
    if (held == 1) {  // the haptic loop's update for one node alone: the same force
      const int j = p->drivenIndex(nodes[0]);
      QVERIFY((p->forceAt(j, d[0]) - force[0]).norm() <= 1e-9 * force[0].norm());
    }
  }

  // The instruments' constraint rows (what the session gives a body): a grasp's patch held by bilateral rows along x,
  // y, z equals the held-node solve; with a floor under the organ (unilateral rows, y <= the lowest rest y, gravity
  // pushing the organ through it), the result is checked against the stiffness itself: K u - f_g = G^T lambda at
  // every free node (1e-8 of the gravity load), lambda >= 0 and the gap >= 0 on the floor's rows, complementary.
  // The hybrid model's core: a FEM region around the held patch (the elements whose centre lies within `radius` of it),
  // the rest condensed onto the interface through its precomputed responses: the whole organ's displacement and the
  // force at the held nodes equal the direct linear static solution (1e-8 relative), for one node and a patch of 6,
  // a small region and a large one; nothing is cut yet, so this is the 'equals the FEM where nothing is cut' half.
  void hybridEqualsTheStaticSolution_data() {
    QTest::addColumn<int>("held");
    QTest::addColumn<double>("radius");
    QTest::newRow("one node, 20 mm region") << 1 << 0.020;
    QTest::newRow("a patch of 6, 20 mm region") << 6 << 0.020;
    QTest::newRow("a patch of 6, 50 mm region") << 6 << 0.050;
    QTest::newRow("a patch of 6, 90 mm region") << 6 << 0.090;
  }
  void hybridEqualsTheStaticSolution() {
    QFETCH(int, held);
    QFETCH(double, radius);
    const FemModel model = FemModel::build(organ_.mesh, {}, material(MaterialModel::Linear, 0.45));
    const std::vector<int> nodes = patch(static_cast<std::size_t>(held));
    std::vector<char> region(model.tets.size(), 0);
    const Eigen::Vector3d at = model.rest[static_cast<std::size_t>(nodes[0])];
    for (std::size_t e = 0; e < model.tets.size(); ++e) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int v : model.tets[e]) c += model.rest[static_cast<std::size_t>(v)] / 4;
      region[e] = (c - at).norm() <= radius;
    }
    std::string why;
    QElapsedTimer clock;
    clock.start();
    const auto h = HybridElasticity::build(model, organ_.fixed, region, kGravity, why);
    QVERIFY2(h, why.c_str());
    const double buildMs = static_cast<double>(clock.elapsed());
    const std::vector<Eigen::Vector3d> d = spreadPull(nodes.size());
    Eigen::VectorXd u;
    std::vector<Eigen::Vector3d> force, reaction;
    QVERIFY2(h->solve(nodes, d, u, &force, why), why.c_str());
    const Eigen::VectorXd ref = directSolve(model, organ_.fixed, nodes, d, &reaction);
    const double err = relative(u, ref);
    const auto [forceErr, forceNorm] = largestDifference(force, reaction);
    qInfo(
        "hybrid, %d held, region %.0f mm: %zu region nodes (%zu elements of the rest joined it: no attachment held "
        "their piece), %zu on the interface, %zu in the rest (%.1f MB of responses, built in %.0f ms); relative error "
        "%.2e, force up to %.3f N (error %.2e N)",
        held, 1e3 * radius, h->regionNodes(), h->absorbedElements(), h->interfaceNodes(), h->restNodes(),
        h->memoryBytes() / 1e6, buildMs, err, forceNorm, forceErr);
    QVERIFY(h->interfaceNodes() > 0);
    QVERIFY2(err <= 1e-8, qPrintable(QString::number(err)));
    QVERIFY2(forceErr <= 1e-8 * forceNorm, qPrintable(QString::number(forceErr / forceNorm)));
    for (std::size_t k = 0; k < nodes.size(); ++k) QVERIFY((u.segment<3>(3 * nodes[k]) - d[k]).norm() <= 1e-12);
    // Refusals: a node outside the region; the region empty or everything; the rest without an attachment of its own.
    int outside = -1;
    for (int v : organ_.driven)
      if (!h->inRegion(v)) outside = v;
    QVERIFY(outside >= 0);
    QVERIFY(!h->solve({outside}, {Eigen::Vector3d::Zero()}, u, nullptr, why));
    QVERIFY2(QString::fromStdString(why).contains("outside the hybrid model's FEM region"), why.c_str());
    QVERIFY(!HybridElasticity::build(model, organ_.fixed, std::vector<char>(model.tets.size(), 0), kGravity, why));
    QVERIFY2(QString::fromStdString(why).contains("empty"), why.c_str());
    QVERIFY(!HybridElasticity::build(model, organ_.fixed, std::vector<char>(model.tets.size(), 1), kGravity, why));
    QVERIFY2(QString::fromStdString(why).contains("whole organ"), why.c_str());
    QVERIFY(!HybridElasticity::build(model, std::vector<char>(model.nodeCount(), 0), region, kGravity, why));
    QVERIFY2(QString::fromStdString(why).contains("not held by an attachment"), why.c_str());
  }

  // The hybrid model under 200 random cuts (as test_cut cuts the FEM): each blade sweep inside the FEM region (a ball
  // of 40 mm around the held patch) re-meshes the elements it crosses (cutTetrahedra); the region takes every element
  // the cut changed, the hybrid is built again from the one before (the rest's responses kept while the cut stays away
  // from the rest), and its answer to the held patch's displacement is the direct linear static solution of the cut
  // mesh, to 1e-8 relative, with the force at the held nodes: never a NaN, never a crash.
  void hybridThroughRandomCuts() {
    std::vector<Eigen::Vector3d> rest = organ_.mesh.points, current = rest;
    std::vector<std::array<int, 4>> tets = organ_.mesh.tets;
    std::vector<int> labels = organ_.mesh.tetLabels;
    if (labels.size() != tets.size()) labels.assign(tets.size(), 1);
    std::vector<char> fixed = organ_.fixed;
    const std::vector<int> nodes = patch(6);
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int v : nodes) centre += rest[static_cast<std::size_t>(v)] / static_cast<double>(nodes.size());
    auto regionAround = [&] {
      std::vector<char> r(tets.size(), 0);
      for (std::size_t e = 0; e < tets.size(); ++e) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (int v : tets[e]) c += rest[static_cast<std::size_t>(v)] / 4;
        r[e] = (c - centre).norm() <= 0.040;
      }
      return r;
    };
    std::vector<char> region = regionAround();
    Mesh mesh = organ_.mesh;
    std::string why;
    auto modelOf = [&] {
      mesh.points = rest;
      mesh.tets = tets;
      mesh.tetLabels = labels;
      return FemModel::build(mesh, {}, material(MaterialModel::Linear, 0.45));
    };
    FemModel model = modelOf();
    auto h = HybridElasticity::build(model, fixed, region, kGravity, why);
    QVERIFY2(h, why.c_str());
    std::mt19937 rng(37);
    std::uniform_real_distribution<double> u(-1, 1);
    auto direction = [&] {
      Eigen::Vector3d d(u(rng), u(rng), u(rng));
      return Eigen::Vector3d(d.norm() > 1e-6 ? d.normalized() : Eigen::Vector3d::UnitX());
    };
    const std::vector<Eigen::Vector3d> d(nodes.size(), Eigen::Vector3d(0.006, -0.004, 0.003));
    int cut = 0, refused = 0, reused = 0, checked = 0;
    std::size_t freed = 0;
    double worst = 0;
    for (int k = 0; k < 200; ++k) {
      // A blade 30 mm long on a random shaft, its tip swept 20 mm, within 30 mm of the patch.
      const Eigen::Vector3d tip = centre + 0.030 * std::abs(u(rng)) * direction(), shaft = direction(),
                            move = 0.020 * direction();
      BladeSweep blade;
      blade.a0 = tip, blade.b0 = tip + 0.030 * shaft, blade.a1 = tip + move, blade.b1 = tip + move + 0.030 * shaft;
      const std::vector<std::array<int, 4>> before = tets;
      const std::size_t nodesBefore = rest.size();
      const CutResult r = cutTetrahedra(rest, current, tets, labels, blade);
      QVERIFY(!r.status.empty());
      if (!r.changed) {
        ++refused;
        continue;
      }
      ++cut;
      // Duplicates of fixed nodes stay fixed; the region takes the elements the cut changed or added.
      fixed.resize(rest.size(), 0);
      for (std::size_t i = 0; i < r.duplicateOf.size(); ++i)
        if (r.duplicateOf[i] >= 0) fixed[nodesBefore + i] = fixed[static_cast<std::size_t>(r.duplicateOf[i])];
      region.resize(tets.size(), 1);
      for (std::size_t e = 0; e < before.size(); ++e)
        if (tets[e] != before[e]) region[e] = 1;
      model = modelOf();
      auto next = HybridElasticity::build(model, fixed, region, kGravity, why, &*h);
      QVERIFY2(next, why.c_str());
      h = std::move(next);
      reused += h->reusedRest();
      // The held patch, where the cut left it (its nodes keep their numbers; a duplicate may now carry their side).
      freed = std::max(freed, h->freePieces());
      std::vector<int> held;
      for (int v : nodes)
        if (h->inRegion(v) && !h->fixedNodes()[static_cast<std::size_t>(v)]) held.push_back(v);
      if (held.empty()) continue;
      const std::vector<Eigen::Vector3d> dh(held.size(), d[0]);
      Eigen::VectorXd uh;
      std::vector<Eigen::Vector3d> force, reaction;
      QVERIFY2(h->solve(held, dh, uh, &force, why), why.c_str());
      QVERIFY(uh.allFinite());
      if (cut % 5 == 0) {  // the direct solve of the cut mesh (every fifth cut: it is the slow part)
        // (a piece the cuts took off is held where it is in both: the hybrid's held nodes)
        const Eigen::VectorXd ref = directSolve(model, h->fixedNodes(), held, dh, &reaction);
        const double err = relative(uh, ref);
        QVERIFY2(ref.norm() < 1, qPrintable(QString("|u| = %1 m: a free piece was not held").arg(ref.norm())));
        worst = std::max(worst, err);
        for (std::size_t j = 0; j < held.size(); ++j)
          QVERIFY2((force[j] - reaction[j]).norm() <= 1e-8 * std::max(1e-3, reaction[j].norm()),
                   qPrintable(QString::number((force[j] - reaction[j]).norm())));
        ++checked;
      }
    }
    qInfo(
        "hybrid through 200 random cuts: %d cut, %d did nothing; the rest's responses kept %d times; %zu elements, "
        "%zu nodes, %zu in the region, up to %zu piece(s) cut free (held where they are); against the direct solve of "
        "the cut mesh %d times: worst relative error %.2e",
        cut, refused, reused, tets.size(), rest.size(), h->regionNodes(), freed, checked, worst);
    QVERIFY(cut > 50);
    QVERIFY(reused > 0);
    QVERIFY(checked >= 10);
    QVERIFY2(worst <= 1e-8, qPrintable(QString::number(worst)));
  }

  void constraintRowsHoldAndPush_data() {
    QTest::addColumn<bool>("surfaceRows");
    QTest::newRow("every node's response") << false;
    QTest::newRow("surface rows only") << true;
  }
  void constraintRowsHoldAndPush() {
    QFETCH(bool, surfaceRows);
    const FemModel model = FemModel::build(organ_.mesh, {}, material(MaterialModel::Linear, 0.45));
    std::string why;
    PrecomputeSettings ps;
    ps.drivenRowsOnly = surfaceRows;
    const auto p = PrecomputedElasticity::build(model, organ_.fixed, organ_.driven, kGravity, ps, why);
    QVERIFY2(p, why.c_str());
    const Eigen::VectorXd rest = model.restVector();
    const std::vector<int> nodes = patch(6);
    const std::vector<Eigen::Vector3d> d(nodes.size(), Eigen::Vector3d(0.008, -0.006, 0.003));
    std::vector<ScalarConstraint> rows;
    for (std::size_t k = 0; k < nodes.size(); ++k) {
      const auto held = holdAt(nodes[k], rest.segment<3>(3 * nodes[k]) + d[k]);
      rows.insert(rows.end(), held.begin(), held.end());
    }
    Eigen::VectorXd u, lambda, direct;
    QVERIFY2(p->solveConstraints(rows, rest, p->sag(), u, lambda, nullptr, why), why.c_str());
    QVERIFY2(p->solve(nodes, d, direct, nullptr, why), why.c_str());
    const double held = relative(u, direct);
    // The floor: every driven node within 15 mm of the lowest point (largest y) is kept at y <= that lowest rest y.
    double lowest = -1e9;
    for (int v : organ_.driven) lowest = std::max(lowest, rest(3 * v + 1));
    std::vector<ScalarConstraint> floor;
    for (int v : organ_.driven)
      if (rest(3 * v + 1) > lowest - 0.015) {
        ScalarConstraint c;
        c.nodes[0] = v;
        c.weights[0] = 1;
        c.direction = -Eigen::Vector3d::UnitY();
        c.value = -lowest;
        c.unilateral = true;
        floor.push_back(c);
      }
    QVERIFY2(p->solveConstraints(floor, rest, p->sag(), u, lambda, nullptr, why), why.c_str());
    const Eigen::SparseMatrix<double> K = elasticStiffness(model, rest);
    Eigen::VectorXd f = K * u;
    for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(model.nodeCount()); ++i)
      f.segment<3>(3 * i) -= model.lumpedMass(i) * kGravity;
    for (std::size_t r = 0; r < floor.size(); ++r)
      f.segment<3>(3 * floor[r].nodes[0]) -= lambda(static_cast<Eigen::Index>(r)) * floor[r].direction;
    double residual = 0, load = 0, worstGap = 0, worstLambda = 0, complementary = 0;
    for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(model.nodeCount()); ++i)
      if (!organ_.fixed[static_cast<std::size_t>(i)]) {
        residual = std::max(residual, f.segment<3>(3 * i).norm());
        load = std::max(load, (model.lumpedMass(i) * kGravity).norm());
      }
    int pushing = 0;
    for (std::size_t r = 0; r < floor.size(); ++r) {
      const double gap = -(rest(3 * floor[r].nodes[0] + 1) + u(3 * floor[r].nodes[0] + 1)) - floor[r].value;
      const double l = lambda(static_cast<Eigen::Index>(r));
      worstGap = std::min(worstGap, gap);
      worstLambda = std::min(worstLambda, l);
      complementary = std::max(complementary, std::abs(l * gap));
      pushing += l > 0;
    }
    qInfo(
        "held patch: %.2e relative to the held-node solve; floor: %zu rows, %d pushing (%.3f N in all), equilibrium "
        "residual %.2e N (load per node up to %.2e N), worst gap %.2e m, worst multiplier %.2e N, |lambda gap| %.2e",
        held, floor.size(), pushing, lambda.sum(), residual, load, worstGap, worstLambda, complementary);
    QVERIFY(held <= 1e-10);
    QVERIFY(pushing > 0 && pushing < static_cast<int>(floor.size()));
    QVERIFY(residual <= 1e-8 * std::max(load, lambda.cwiseAbs().maxCoeff()));
    QVERIFY(worstGap >= -1e-10 && worstLambda >= 0);
    QVERIFY(complementary <= 1e-12);
    // A row on a node without a response is refused.
    const std::set<int> surface(organ_.driven.begin(), organ_.driven.end());
    int inner = 0;
    while (surface.count(inner) || organ_.fixed[static_cast<std::size_t>(inner)]) ++inner;
    ScalarConstraint bad;
    bad.nodes[0] = inner;
    bad.weights[0] = 1;
    QVERIFY(!p->solveConstraints({bad}, rest, p->sag(), u, lambda, nullptr, why));
    QVERIFY(why.find("no precomputed response") != std::string::npos);
  }

  // The model as a scene chooses it, through the session (`rehearse gesture --model precomputed`): the shipped
  // grasp-pull on the liver preset, ended while the jaws hold. Every step converged; at the end the organ is in static
  // equilibrium by the stiffness itself (K u - f_g vanishes at the free nodes the jaws do not hold, 1e-8 of the
  // largest nodal load), and what remains at the held nodes sums to the tool force the session reports. A cut is
  // refused with a sentence (the mesh unchanged); the model survives a recording's setup.
  void aRehearsalOnThePrecomputedModel() {
    std::ifstream in(std::string(REHEARSE_SOURCE_DIR) + "/resources/gestures/grasp-pull.json");
    std::stringstream ss;
    ss << in.rdbuf();
    app::GestureScript script = app::parseGestureScript(ss.str());
    script.duration = 2.2;  // the jaws still hold (they open at 2.3 s)
    simcore::BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Precomputed;
    const app::GestureResult r = app::runGesture(s, script);
    QCOMPARE(r.failed, std::size_t(0));
    std::size_t converged = 0;
    std::vector<double> ms;
    for (const auto& row : r.steps) {
      converged += row.report.outcome == StepStatus::Converged;
      ms.push_back(row.wallMs);
    }
    QCOMPARE(converged, r.steps.size());
    std::sort(ms.begin(), ms.end());
    const auto& last = r.steps.back();
    QVERIFY(last.grasped > 0);
    // Equilibrium by the stiffness (the session's body frame: the setup's mesh, in metres, is the rest shape).
    const testing::Balance balance = testing::linearBalance(s, r.final.x);
    const std::size_t loaded = balance.loaded;
    const Eigen::Vector3d held = balance.force;
    qInfo(
        "precomputed grasp-pull (liver preset, %zu nodes): %zu steps all converged, median %.3f ms, worst %.3f ms; "
        "%zu held; %zu free nodes off equilibrium (the held ones), their force (%.4f, %.4f, %.4f) N, the session's "
        "tool force (%.4f, %.4f, %.4f) N",
        balance.nodes, r.steps.size(), ms[ms.size() / 2], ms.back(), last.grasped, loaded, held.x(), held.y(), held.z(),
        last.toolForce.x(), last.toolForce.y(), last.toolForce.z());
    QVERIFY(loaded <= last.grasped);
    QVERIFY(last.toolForce.norm() > 0.1);
    QVERIFY((held - last.toolForce).norm() <= 1e-6 * last.toolForce.norm());
    // A cut refused, said; the mesh as it was.
    {
      std::ifstream cin(std::string(REHEARSE_SOURCE_DIR) + "/resources/gestures/cut-across.json");
      std::stringstream cs;
      cs << cin.rdbuf();
      const app::GestureResult c = app::runGesture(s, app::parseGestureScript(cs.str()));
      std::string said;
      for (const auto& row : c.steps)
        if (row.message.find("cannot cut") != std::string::npos) said = row.message;
      qInfo("cut: %s", said.c_str());
      QVERIFY(said.find("The precomputed model cannot cut") != std::string::npos);
      QCOMPARE(c.events.cuts, 0);
      QCOMPARE(c.finalMesh.tets.size(), s.mesh.tets.size());
    }
    QVERIFY(app::decodeSetup(app::encodeSetup(s)).model == BodyModel::Precomputed);
    simcore::BodySetup fem = s;
    fem.model = BodyModel::Fem;
    QVERIFY(!nlohmann::json::parse(app::encodeSetup(fem)).contains("model"));  // FEM setups keep their old bytes
  }

  // Extreme cases through the body: a surface node pulled 0.3 m (past what a linear model means: elements turn inside
  // out, counted here from the signed volumes and said by the step), near-incompressible tissue (nu 0.4999), and an
  // organ held by nothing (refused in a sentence). No NaN anywhere.
  void extremeCases() {
    simcore::BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Precomputed;
    {
      const auto body = makeBody(s);
      SimulationState st = body->initialState();
      const int node = firstFreeSurfaceNode(s, *body);
      const std::vector<ScalarConstraint> rows = holdAt(node, st.x.segment<3>(3 * node) + Eigen::Vector3d(0, 0, -0.3));
      body->setToolConstraints(rows);
      const StepReport rep = body->step(st);
      const auto& rest = body->restPositions();
      int inverted = 0;
      for (const auto& t : body->tetrahedra()) {
        auto at = [&](int k) { return Eigen::Vector3d(st.x.segment<3>(3 * t[static_cast<std::size_t>(k)])); };
        const double v = (at(1) - at(0)).cross(at(2) - at(0)).dot(at(3) - at(0));
        const auto r = [&](int k) { return rest[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])]; };
        const double v0 = (r(1) - r(0)).cross(r(2) - r(0)).dot(r(3) - r(0));
        inverted += v * v0 <= 0;
      }
      qInfo("pulled 0.3 m: %s, %d inverted (counted here: %d), tool force %.1f N", rep.status.c_str(),
            rep.invertedElements, inverted, body->toolForce().norm());
      QVERIFY(st.x.allFinite() && st.v.allFinite());
      QCOMPARE(rep.invertedElements, inverted);
      QVERIFY(rep.outcome == (inverted > 0 ? StepStatus::Inverted : StepStatus::Converged));
      QVERIFY(inverted > 0);
    }
    {
      simcore::BodySetup stiff = s;
      stiff.material.poisson = 0.4999;
      for (auto& [label, m] : stiff.byLabel) m.poisson = 0.4999;
      const auto body = makeBody(stiff);
      SimulationState st = body->initialState();
      const StepReport rep = body->step(st);
      QVERIFY(st.x.allFinite());
      QVERIFY(rep.outcome == StepStatus::Converged);
    }
    simcore::BodySetup loose = s;
    loose.fixedNodes.clear();
    try {
      makeBody(loose);
      QFAIL("a body held by nothing was built");
    } catch (const MeshError& e) {
      qInfo("%s", e.what());
      QVERIFY(std::string(e.what()).find("Nothing holds the organ") != std::string::npos);
    }
  }

  // The tool's stiffness the force loop extrapolates with is exact for this model: the force after the jaws moved by
  // delta (a second static solve) equals the first force plus K delta, K = toolStiffness() (1e-9), and K is
  // symmetric.
  void toolStiffnessIsExact() {
    simcore::BodySetup s = testing::presetBody("liver");
    s.model = BodyModel::Precomputed;
    const auto body = makeBody(s);
    SimulationState st = body->initialState();
    const int node = firstFreeSurfaceNode(s, *body);
    auto hold = [&](const Eigen::Vector3d& at) {
      const std::vector<ScalarConstraint> rows = holdAt(node, at);
      body->setToolConstraints(rows);
      body->step(st);
      return body->toolForce();
    };
    const Eigen::Vector3d p0 = st.x.segment<3>(3 * node) + Eigen::Vector3d(0.004, -0.003, 0.006);
    const Eigen::Vector3d delta(0.0012, 0.0007, -0.0009);
    const Eigen::Vector3d f0 = hold(p0);
    const Eigen::Matrix3d K = body->toolStiffness();
    const Eigen::Vector3d f1 = hold(p0 + delta);
    const double err = (f1 - f0 - K * delta).norm() / (f1 - f0).norm();
    qInfo("tool force %.4f -> %.4f N; K delta predicts the change to %.1e relative; K diagonal %.1f %.1f %.1f N/m",
          f0.norm(), f1.norm(), err, K(0, 0), K(1, 1), K(2, 2));
    QVERIFY(err <= 1e-9);
    QVERIFY((K - K.transpose()).norm() <= 1e-12 * K.norm());
  }

  // The co-rotational law's stiffness at rest is the linear law's (so a scene of either law can use the responses).
  void corotationalStiffnessAtRestIsTheLinearOne() {
    const FemModel lin = FemModel::build(organ_.mesh, {}, material(MaterialModel::Linear, 0.45));
    const FemModel cor = FemModel::build(organ_.mesh, {}, material(MaterialModel::Corotational, 0.45));
    const Eigen::SparseMatrix<double> a = elasticStiffness(lin, lin.restVector()),
                                      b = elasticStiffness(cor, cor.restVector());
    const double rel = (a - b).norm() / a.norm();
    qInfo("co-rotational vs linear stiffness at rest: %.2e relative", rel);
    QVERIFY(rel <= 1e-12);
  }

  // Memory: 9 numbers per driven node and node, halved in single precision, whose error is stated (~1e-7).
  void singlePrecisionHalvesTheMemory() {
    const FemModel model = FemModel::build(organ_.mesh, {}, material(MaterialModel::Linear, 0.45));
    std::string why;
    PrecomputeSettings s;
    const auto p64 = PrecomputedElasticity::build(model, organ_.fixed, organ_.driven, kGravity, s, why);
    s.singlePrecision = true;
    const auto p32 = PrecomputedElasticity::build(model, organ_.fixed, organ_.driven, kGravity, s, why);
    QVERIFY(p64 && p32);
    const std::size_t n = organ_.mesh.points.size(), m = organ_.driven.size();
    QVERIFY(p64->memoryBytes() >= 9 * n * m * sizeof(double));
    QVERIFY(p64->memoryBytes() < 9 * n * m * sizeof(double) + 64 * n + 200 * m);
    QVERIFY(p32->memoryBytes() < 9 * n * m * sizeof(float) + 64 * n + 200 * m);
    const std::vector<int> nodes = patch(6);
    const std::vector<Eigen::Vector3d> d(nodes.size(), Eigen::Vector3d(0.01, 0, 0));
    Eigen::VectorXd u64, u32;
    QVERIFY(p64->solve(nodes, d, u64, nullptr, why) && p32->solve(nodes, d, u32, nullptr, why));
    const double err = relative(u32, directSolve(model, organ_.fixed, nodes, d, nullptr));
    qInfo("%zu x %zu responses: %.1f MB in double, %.1f MB in single precision (error %.1e relative)", m, n,
          p64->memoryBytes() / 1e6, p32->memoryBytes() / 1e6, err);
    QVERIFY(err > 1e-12 && err <= 1e-5);
  }

  // Bounded memory: the surface's rows only (9 x surface^2 numbers plus the kept factor) against every node's
  // (9 x surface x nodes), measured; the same static solution either way (1e-12 relative, the floor's rows included).
  // The responses' bytes (the case file's cache) read back to the same answers; damaged or another organ's bytes are
  // refused with a sentence; the key changes with the material, the attachments and gravity; precomputedFor takes a
  // build from the cache, then from stored bytes, and builds again when those are damaged.
  void boundedMemoryAndTheCache() {
    const FemModel model = FemModel::build(organ_.mesh, {}, material(MaterialModel::Linear, 0.45));
    std::string why;
    PrecomputeSettings all, surface;
    surface.drivenRowsOnly = true;
    const auto pa = PrecomputedElasticity::build(model, organ_.fixed, organ_.driven, kGravity, all, why);
    const auto ps = PrecomputedElasticity::build(model, organ_.fixed, organ_.driven, kGravity, surface, why);
    QVERIFY(pa && ps);
    const std::size_t n = organ_.mesh.points.size(), m = organ_.driven.size();
    qInfo("%zu surface nodes of %zu: every node's responses %.1f MB, the surface's only %.1f MB (with the factor)", m,
          n, pa->memoryBytes() / 1e6, ps->memoryBytes() / 1e6);
    QVERIFY(ps->memoryBytes() >= 9 * m * m * sizeof(double));
    QVERIFY(static_cast<double>(ps->memoryBytes()) <
            static_cast<double>(pa->memoryBytes()) * static_cast<double>(m) / static_cast<double>(n) * 1.25);
    const std::vector<int> nodes = patch(6);
    const std::vector<Eigen::Vector3d> d(nodes.size(), Eigen::Vector3d(0.006, 0.004, -0.005));
    Eigen::VectorXd ua, us;
    std::vector<Eigen::Vector3d> fa, fs;
    QVERIFY(pa->solve(nodes, d, ua, &fa, why) && ps->solve(nodes, d, us, &fs, why));
    QVERIFY2(relative(us, ua) <= 1e-12, qPrintable(QString::number(relative(us, ua))));
    for (std::size_t k = 0; k < nodes.size(); ++k) QVERIFY((fs[k] - fa[k]).norm() <= 1e-10 * fa[k].norm());
    // Bytes and back.
    for (const auto* p : {&*pa, &*ps}) {
      const std::string bytes = p->toBytes();
      const auto back = PrecomputedElasticity::fromBytes(bytes, model, why);
      QVERIFY2(back, why.c_str());
      Eigen::VectorXd ub;
      QVERIFY(back->solve(nodes, d, ub, nullptr, why));
      QVERIFY(p == &*pa ? ub == ua : relative(ub, us) <= 1e-14);
      QVERIFY(!PrecomputedElasticity::fromBytes(bytes.substr(0, bytes.size() - 5), model, why));
      QVERIFY(why.find("damaged") != std::string::npos);
      std::string flipped = bytes;
      flipped[2] = 'X';
      QVERIFY(!PrecomputedElasticity::fromBytes(flipped, model, why));
    }
    QVERIFY(!PrecomputedElasticity::fromBytes("", model, why));
    {  // the surface rows' bytes claiming every node's rows: refused on the size, before allocating it
      std::string claimed = ps->toBytes();
      const std::uint64_t allRows = 0;
      std::memcpy(claimed.data() + 8 + 3 * sizeof(std::uint64_t), &allRows, sizeof allRows);
      QVERIFY(!PrecomputedElasticity::fromBytes(claimed, model, why));
      QVERIFY(why.find("damaged") != std::string::npos);
    }
    {  // a NaN among the responses (a faulty writer under a matching checksum): refused
      std::string poisoned = pa->toBytes();
      const double nan = std::nan("");
      std::memcpy(poisoned.data() + poisoned.size() - sizeof nan, &nan, sizeof nan);
      QVERIFY(!PrecomputedElasticity::fromBytes(poisoned, model, why));
    }
    {  // another organ's responses
      Mesh other = testing::presetBody("liver").mesh;
      other.convertToMetres();
      const FemModel otherModel = FemModel::build(other, {}, material(MaterialModel::Linear, 0.45));
      QVERIFY(otherModel.nodeCount() != model.nodeCount());
      QVERIFY(!PrecomputedElasticity::fromBytes(pa->toBytes(), otherModel, why));
      QVERIFY(why.find("not this organ's") != std::string::npos);
    }
    // The key follows what the responses depend on.
    const std::uint64_t k0 = precomputeKey(model, organ_.fixed, organ_.driven, kGravity, all);
    const FemModel softer = FemModel::build(organ_.mesh, {}, material(MaterialModel::Linear, 0.44));
    std::vector<char> fewer = organ_.fixed;
    fewer[static_cast<std::size_t>(std::find(fewer.begin(), fewer.end(), 1) - fewer.begin())] = 0;
    QCOMPARE(precomputeKey(model, organ_.fixed, organ_.driven, kGravity, all), k0);
    QVERIFY(precomputeKey(softer, organ_.fixed, organ_.driven, kGravity, all) != k0);
    QVERIFY(precomputeKey(model, fewer, organ_.driven, kGravity, all) != k0);
    QVERIFY(precomputeKey(model, organ_.fixed, organ_.driven, 2 * kGravity, all) != k0);
    QVERIFY(precomputeKey(model, organ_.fixed, organ_.driven, kGravity, surface) != k0);
    // From the cache, from stored bytes, built again when those are damaged.
    ResponseCache& cache = ResponseCache::shared();
    cache.clear();
    std::uint64_t key = 0;
    std::string from;
    const auto first = precomputedFor(model, organ_.fixed, organ_.driven, kGravity, surface, key, from, why);
    QVERIFY(first && from == "built" && key == precomputeKey(model, organ_.fixed, organ_.driven, kGravity, surface));
    QVERIFY(precomputedFor(model, organ_.fixed, organ_.driven, kGravity, surface, key, from, why) == first);
    QCOMPARE(from, std::string("cache"));
    const auto bytes = std::make_shared<const std::string>(first->toBytes());
    cache.clear();
    cache.offerBytes(key, bytes);
    const auto stored = precomputedFor(model, organ_.fixed, organ_.driven, kGravity, surface, key, from, why);
    QVERIFY(stored && stored != first);
    QCOMPARE(from, std::string("case file"));
    cache.clear();
    cache.offerBytes(key, std::make_shared<const std::string>(bytes->substr(0, 100)));
    QVERIFY(precomputedFor(model, organ_.fixed, organ_.driven, kGravity, surface, key, from, why));
    QCOMPARE(from, std::string("built"));
    QVERIFY(!cache.storedBytes(key));  // the damaged bytes are dropped
    // The cache keeps the most recent past its limit.
    cache.limitBytes = 1;
    precomputedFor(model, organ_.fixed, organ_.driven, kGravity, all, key, from, why);
    QCOMPARE(cache.entries().size(), std::size_t(1));
    cache.limitBytes = std::size_t(1) << 30;
    cache.clear();
  }

  // Through the session, as the Simulation panel chooses the model: a build whose progress answers "cancel" leaves the
  // FEM running with a sentence (the snapshot names no responses), progress is told from 0 to 1, and choosing the
  // model again after the FEM takes the responses from the last build (said) instead of computing them again.
  void theSessionsBuildTellsProgressAndCancels() {
    ResponseCache::shared().clear();
    simcore::BodySetup s = testing::presetBody("liver");
    bool cancel = true;
    std::vector<double> told;
    s.buildProgress = [&](double done) {
      told.push_back(done);
      return !cancel;
    };
    Session session(s);
    auto choose = [&](double model) {
      InputEvent e;
      e.kind = InputKind::Parameter;
      e.name = "body_model";
      e.value = model;
      session.post(e);
      session.advance();
      return session.snapshot();
    };
    auto snap = choose(1);
    qInfo("cancelled: %s", snap->message.c_str());
    QCOMPARE(told.size(), std::size_t(1));
    QVERIFY(snap->message.find("cancelled") != std::string::npos);
    QCOMPARE(snap->responseKey, std::uint64_t(0));
    QVERIFY(session.setup().model == BodyModel::Fem);
    QVERIFY(snap->report.ok);
    cancel = false;
    told.clear();
    snap = choose(1);
    qInfo("built: %s (progress told %zu times)", snap->message.c_str(), told.size());
    QVERIFY(snap->message.find("were computed in") != std::string::npos);
    QVERIFY(snap->responseKey != 0);
    QVERIFY(told.size() >= 2 && std::is_sorted(told.begin(), told.end()) && told.back() == 1.0);
    const std::uint64_t key = snap->responseKey;
    QVERIFY(choose(0)->responseKey == 0);
    told.clear();
    snap = choose(1);
    qInfo("again: %s", snap->message.c_str());
    QVERIFY(snap->message.find("taken from the last build") != std::string::npos);
    QCOMPARE(snap->responseKey, key);
    QVERIFY(told.empty());
    ResponseCache::shared().clear();
  }

  // What cannot be precomputed or solved is refused with a sentence, never answered.
  void refusals() {
    const FemModel model = FemModel::build(organ_.mesh, {}, material(MaterialModel::Linear, 0.45));
    std::string why;
    const std::vector<char> none(organ_.mesh.points.size(), 0);
    QVERIFY(!PrecomputedElasticity::build(model, none, organ_.driven, kGravity, {}, why));
    QVERIFY(why.find("free body") != std::string::npos);
    int fixedNode = -1;
    for (std::size_t i = 0; i < organ_.fixed.size() && fixedNode < 0; ++i)
      if (organ_.fixed[i]) fixedNode = static_cast<int>(i);
    QVERIFY(!PrecomputedElasticity::build(model, organ_.fixed, {organ_.driven[0], fixedNode}, kGravity, {}, why));
    QVERIFY(why.find("is fixed") != std::string::npos);
    QVERIFY(
        !PrecomputedElasticity::build(model, organ_.fixed, {organ_.driven[0], organ_.driven[0]}, kGravity, {}, why));
    QVERIFY(why.find("twice") != std::string::npos);
    PrecomputeSettings small;
    small.maxBytes = 1 << 20;  // 1 MB: the liver's 67 MB of responses are over it
    QVERIFY(!PrecomputedElasticity::build(model, organ_.fixed, organ_.driven, kGravity, small, why));
    qInfo("%s", why.c_str());
    QVERIFY(why.find("would take 0.1 GB") != std::string::npos && why.find("single precision") != std::string::npos);
    PrecomputeSettings cancel;
    cancel.batch = 30;
    int batches = 0;
    cancel.progress = [&](double) { return ++batches < 3; };
    QVERIFY(!PrecomputedElasticity::build(model, organ_.fixed, organ_.driven, kGravity, cancel, why));
    QCOMPARE(batches, 3);
    QVERIFY(why.find("cancelled") != std::string::npos);
    // A node without a response (an interior one), a node held twice.
    const auto p =
        PrecomputedElasticity::build(model, organ_.fixed, {organ_.driven[0], organ_.driven[1]}, kGravity, {}, why);
    QVERIFY(p);
    const std::set<int> surface(organ_.driven.begin(), organ_.driven.end());
    int inner = 0;
    while (surface.count(inner) || organ_.fixed[static_cast<std::size_t>(inner)]) ++inner;
    Eigen::VectorXd u;
    QVERIFY(!p->solve({inner}, {Eigen::Vector3d::Zero()}, u, nullptr, why));
    QVERIFY(why.find("no precomputed response") != std::string::npos);
    QVERIFY(!p->solve({organ_.driven[0], organ_.driven[0]}, {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}, u,
                      nullptr, why));
    QVERIFY(why.find("held twice") != std::string::npos);
  }
};

QTEST_GUILESS_MAIN(TestPrecomputed)
#include "test_precomputed.moc"
