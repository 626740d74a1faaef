// Reusing the factorisation and constraints: the lagged Newton variants reach the exact method's
// solution (their error is what the benchmark reports); attachments as Lagrange multipliers (Schur
// complement + Gauss-Seidel) give the projection's solution and multipliers that balance the load;
// general linear constraints match a dense KKT solve.
#include "box_mesh.hpp"
#include "test_support.hpp"

#include "phantom/phantom.hpp"

#include <rehearse/simcore/integrator.hpp>

#include <Eigen/Dense>


using namespace rehearse::simcore;

namespace {
FemModel phantomModel(const rehearse::phantom::Phantom& c, MaterialModel model = MaterialModel::Corotational) {
  return FemModel::build(c.volume, {{2, {model, 620e3, 0.45, 1100}}}, {model, 27e3, 0.40, 1000});
}

Eigen::VectorXd run(const FemModel& m, const std::vector<int>& fixed, SimulationSettings s, int steps, int* factorisations = nullptr,
                    int* failures = nullptr) {
  Integrator in(m, fixed, s);
  auto state = in.initialState();
  int f = 0, bad = 0;
  for (int i = 0; i < steps; ++i) {
    const auto rep = in.step(state);
    f += rep.factorisations;
    bad += !rep.ok;
    if (!state.x.allFinite()) return {};
  }
  if (factorisations) *factorisations = f;
  if (failures) *failures = bad;
  return state.x;
}
}  // namespace

class TestConstraints : public QObject {
  Q_OBJECT
 private slots:
  // Every method solves the same implicit Euler equations: the iterated ones converge to the exact
  // method's states; the linearised one (one solve per step) stays close, with far fewer factorisations.
  void laggedMethodsReachTheExactSolution() {
    const auto c = rehearse::phantom::makePhantom();
    const FemModel m = phantomModel(c);
    SimulationSettings s;
    s.tolerance = 1e-9;
    s.maxNewtonIterations = 30;
    int exactFactorisations = 0;
    const Eigen::VectorXd ref = run(m, c.attachments, s, 40, &exactFactorisations);
    QVERIFY(ref.size() > 0);
    const double sag = (ref - m.restVector()).norm();
    for (NewtonMethod method :
         {NewtonMethod::LaggedPcg, NewtonMethod::Chord, NewtonMethod::Linearised, NewtonMethod::NewtonKrylov}) {
      SimulationSettings sm = s;
      sm.method = method;
      int factorisations = 0, failures = 0;
      const Eigen::VectorXd x = run(m, c.attachments, sm, 40, &factorisations, &failures);
      QVERIFY(x.size() > 0);
      const double err = (x - ref).norm() / sag;
      qInfo("%-11s relative error %.2e after 0.4 s, %d factorisations (exact: %d)", toString(method).c_str(), err, factorisations,
            exactFactorisations);
      QCOMPARE(failures, 0);
      QVERIFY(factorisations < exactFactorisations / 2);
      QVERIFY2(err < (method == NewtonMethod::Linearised ? 2e-2 : 1e-6), qPrintable(QString::number(err)));
    }
    QVERIFY(newtonMethodFromString("chord") == NewtonMethod::Chord);
    QVERIFY(newtonMethodFromString("newton-krylov") == NewtonMethod::NewtonKrylov);
    QVERIFY_THROWS_EXCEPTION(MeshError, newtonMethodFromString("magic"));
  }

  // Attachments as Lagrange multipliers: the same equilibrium as the projection, the attached nodes
  // stay put, and the multipliers (the ligament forces) balance the organ's weight.
  void lagrangeAttachmentsMatchProjection() {
    const auto c = rehearse::phantom::makePhantom();
    for (MaterialModel model : {MaterialModel::Linear, MaterialModel::Corotational}) {
      const FemModel m = phantomModel(c, model);
      SimulationSettings s;
      s.tolerance = 1e-8;  // the Lagrange form's round-off floor here is ~5e-9 (a body held only by 27 close nodes)
      Integrator projected(m, c.attachments, s);
      auto a = projected.initialState();
      auto ra = projected.solveStatic(a);
      QVERIFY2(ra.ok, ra.status.c_str());
      s.attachments = AttachmentMode::Lagrange;
      Integrator lagrange(m, c.attachments, s);
      auto b = lagrange.initialState();
      auto rb = lagrange.solveStatic(b);
      QVERIFY2(rb.ok, rb.status.c_str());
      const double sag = (a.x - m.restVector()).norm();
      const double diff = (a.x - b.x).norm() / sag;
      const Eigen::VectorXd& lambda = lagrange.multipliers();
      QCOMPARE(lambda.size(), Eigen::Index(3 * c.attachments.size()));
      Eigen::Vector3d total = Eigen::Vector3d::Zero();
      for (Eigen::Index i = 0; i < lambda.size(); ++i) total[i % 3] += lambda[i];
      const Eigen::Vector3d weight = m.lumpedMass.sum() * s.gravity;
      qInfo("%s: |x_lagrange - x_projection| / |u| = %.2e, violation %.1e m, %d Gauss-Seidel sweeps; ligament force %.4f N vs weight %.4f N",
            toString(model).c_str(), diff, rb.constraintViolation, rb.innerIterations, total.norm(), weight.norm());
      QVERIFY(diff < 1e-6);
      QVERIFY(rb.constraintViolation < 1e-9);
      QVERIFY((total + weight).norm() < 1e-6 * weight.norm());  // the ligaments carry the whole weight
      // Dynamics: the same trajectory.
      SimulationSettings d;
      const Eigen::VectorXd xa = run(m, c.attachments, d, 10);
      d.attachments = AttachmentMode::Lagrange;
      const Eigen::VectorXd xb = run(m, c.attachments, d, 10);
      QVERIFY(xa.size() > 0 && xb.size() > 0);
      const double dd = (xa - xb).norm() / (xa - m.restVector()).norm();
      qInfo("%s, 10 implicit steps: relative difference %.2e", toString(model).c_str(), dd);
      QVERIFY(dd < 1e-5);
      // The methods that reuse a lagged factor hold the same attachments by Lagrange multipliers too.
      for (NewtonMethod method : {NewtonMethod::LaggedPcg, NewtonMethod::Chord, NewtonMethod::NewtonKrylov}) {
        d.method = method;
        int failures = -1;
        const Eigen::VectorXd xl = run(m, c.attachments, d, 10, nullptr, &failures);
        QVERIFY(xl.size() > 0);
        const double dl = (xa - xl).norm() / (xa - m.restVector()).norm();
        qInfo("%s, %s with Lagrange attachments: %d failed steps, relative difference %.2e", toString(model).c_str(),
              toString(method).c_str(), failures, dl);
        QCOMPARE(failures, 0);
        QVERIFY(dl < 1e-5);
      }
    }
  }

  // An embedded vessel wall (a separate surface, mapped into the volume) stiffens the hanging organ; a
  // vanishing wall changes nothing.
  void embeddedWallStiffensTheOrgan() {
    const auto c = rehearse::phantom::makePhantom();
    Mesh wall;  // the faces between the vessels and the parenchyma, with only the points they use
    wall.points = c.volume.points;
    wall.unitToMetre = c.volume.unitToMetre;
    wall.triangles = c.innerSurface;
    wall.compact();
    Mesh organ = c.volume;
    std::fill(organ.tetLabels.begin(), organ.tetLabels.end(), 1);
    const MaterialParams soft{MaterialModel::Linear, 27e3, 0.4, 1000};
    auto sag = [&](const std::vector<EmbeddedSurface>& embedded) {
      const FemModel m = FemModel::build(organ, {}, soft, embedded);
      SimulationSettings s;
      s.gravity = Eigen::Vector3d(0, 9.81, 0);
      s.tolerance = 1e-10;
      Integrator in(m, c.attachments, s);
      auto st = in.initialState();
      const auto rep = in.solveStatic(st);
      if (!rep.ok) qWarning("%s", rep.status.c_str());
      return Eigen::VectorXd(st.x - m.restVector());
    };
    const Eigen::VectorXd none = sag({}), stiff = sag({{wall, 620e3, 1e-3, "vessels"}}), faint = sag({{wall, 1e-6, 1e-3, "vessels"}});
    const double maxNone = none.cwiseAbs().maxCoeff(), maxStiff = stiff.cwiseAbs().maxCoeff();
    qInfo("hanging phantom: largest sag %.3f mm without the vessel wall, %.3f mm with a 1 mm wall of 620 kPa", 1e3 * maxNone, 1e3 * maxStiff);
    QVERIFY(maxStiff < 0.98 * maxNone);
    QVERIFY((faint - none).norm() < 1e-9 * none.norm());
  }

  // Static solves with the chord option (the factor of an earlier static tangent reused while the
  // residual halves) reach the exact Newton equilibrium on a nonlinear problem: a co-rotational beam whose
  // tip is lifted by 2 cm (a large rotation), then by 2.2 cm from there, as a registration's rebinding does.
  void chordStaticSolvesMatchNewton() {
    const Mesh box = boxMesh(0.1, 0.02, 0.02, 10, 2, 2);
    const FemModel m = FemModel::build(box, {}, {MaterialModel::Corotational, 1e5, 0.45, 1000});
    const std::vector<int> clamp = nodesAtX(box, 0), tip = nodesAtX(box, 0.1);
    auto lift = [&](double dz) {
      std::vector<ScalarConstraint> cs;
      for (int n : tip) {
        ScalarConstraint c;
        c.nodes = {n, -1, -1, -1};
        c.weights = {1, 0, 0, 0};
        c.direction = Eigen::Vector3d::UnitZ();
        c.value = m.rest[n].z() + dz;
        cs.push_back(c);
      }
      return cs;
    };
    auto run = [&](bool chord, int& factorisations) {
      SimulationSettings s;
      s.gravity = Eigen::Vector3d(0, 0, -9.81);
      s.tolerance = 1e-9;
      s.staticChord = chord;
      Integrator in(m, clamp, s);
      auto st = in.initialState();
      factorisations = 0;
      for (double dz : {0.02, 0.022}) {
        in.setConstraints(lift(dz));
        const auto rep = in.solveStatic(st);
        if (!rep.ok) qWarning("%s", rep.status.c_str());
        factorisations += rep.factorisations;
      }
      return Eigen::VectorXd(st.x);
    };
    int exactF = 0, chordF = 0;
    const Eigen::VectorXd exact = run(false, exactF), chord = run(true, chordF);
    const double diff = (chord - exact).cwiseAbs().maxCoeff(), size = (exact - m.restVector()).cwiseAbs().maxCoeff();
    qInfo("lifted co-rotational beam: chord and exact Newton differ by %.2e m of %.2e m; factorisations %d (exact) and %d (chord)", diff, size,
          exactF, chordF);
    QVERIFY(size > 0.015);
    QVERIFY(diff < 1e-6 * size);
    QVERIFY(chordF < exactF);
  }

  // General linear constraints against a dense KKT solve: a linear beam, clamped by projection, with
  // its tip pulled to a prescribed height and two nodes tied together along x.
  void constraintsAgainstDenseKkt() {
    const Mesh box = boxMesh(0.1, 0.02, 0.02, 10, 2, 2);
    const FemModel m = FemModel::build(box, {}, {MaterialModel::Linear, 1e5, 0.3, 1000});
    const std::vector<int> clamp = nodesAtX(box, 0), tip = nodesAtX(box, 0.1);
    std::vector<ScalarConstraint> cs;
    ScalarConstraint lift;  // mean tip height = +5 mm
    for (int k = 0; k < 4; ++k) {
      lift.nodes[k] = tip[k];
      lift.weights[k] = 0.25;
    }
    lift.direction = Eigen::Vector3d::UnitZ();
    for (int k = 0; k < 4; ++k) lift.value += 0.25 * m.rest[tip[k]].z();
    lift.value += 0.005;
    cs.push_back(lift);
    ScalarConstraint tie;  // x of a tip node minus x of the opposite one = its rest difference
    tie.nodes = {tip.front(), tip.back(), -1, -1};
    tie.weights = {1, -1, 0, 0};
    tie.direction = Eigen::Vector3d::UnitX();
    tie.value = m.rest[tip.front()].x() - m.rest[tip.back()].x();
    cs.push_back(tie);
    SimulationSettings s;
    s.gravity = Eigen::Vector3d(0, 0, -9.81);
    s.tolerance = 1e-10;
    Integrator in(m, clamp, s);
    in.setConstraints(cs);
    auto state = in.initialState();
    const auto rep = in.solveStatic(state);
    QVERIFY2(rep.ok, rep.status.c_str());
    // Dense KKT of the linear problem on the free dofs: [K H^T; H 0] [u; -mu] = [f; g - H x0].
    const Eigen::Index n3 = 3 * m.nodeCount();
    Eigen::MatrixXd K = Eigen::MatrixXd(elasticStiffness(m, m.restVector()));
    Eigen::VectorXd f(n3);
    for (std::size_t i = 0; i < m.nodeCount(); ++i) f.segment<3>(3 * i) = m.lumpedMass[i] * s.gravity;
    std::vector<char> fixed(m.nodeCount(), 0);
    for (int n : clamp) fixed[n] = 1;
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, n3);
    Eigen::VectorXd g(2);
    for (int i = 0; i < 2; ++i) {
      for (int k = 0; k < 4; ++k)
        if (cs[i].nodes[k] >= 0) H.row(i).segment<3>(3 * cs[i].nodes[k]) += cs[i].weights[k] * cs[i].direction.transpose();
      g[i] = cs[i].value - H.row(i).dot(m.restVector());
    }
    std::vector<Eigen::Index> freeDofs;
    for (Eigen::Index i = 0; i < n3; ++i)
      if (!fixed[i / 3]) freeDofs.push_back(i);
    const Eigen::Index nf = static_cast<Eigen::Index>(freeDofs.size());
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(nf + 2, nf + 2);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(nf + 2);
    for (Eigen::Index i = 0; i < nf; ++i) {
      for (Eigen::Index j = 0; j < nf; ++j) A(i, j) = K(freeDofs[i], freeDofs[j]);
      for (int r = 0; r < 2; ++r) A(i, nf + r) = A(nf + r, i) = H(r, freeDofs[i]);
      b[i] = f[freeDofs[i]];
    }
    b.tail<2>() = g;
    const Eigen::VectorXd sol = A.fullPivLu().solve(b);
    double worst = 0, size = 0;
    for (Eigen::Index i = 0; i < nf; ++i) {
      const double u = state.x[freeDofs[i]] - m.restVector()[freeDofs[i]];
      worst = std::max(worst, std::abs(u - sol[i]));
      size = std::max(size, std::abs(sol[i]));
    }
    const Eigen::Vector2d mu = -sol.tail<2>();
    qInfo("constrained beam: max |u - u_kkt| = %.2e m of %.2e m; multipliers %.5f, %.5f N vs KKT %.5f, %.5f N", worst, size,
          in.multipliers()[0], in.multipliers()[1], mu[0], mu[1]);
    QVERIFY(worst < 1e-9 * std::max(1.0, size / 1e-3));
    QVERIFY(std::abs(in.multipliers()[0] - mu[0]) < 1e-6 * std::max(1.0, std::abs(mu[0])));
    QVERIFY(rep.constraintViolation < 1e-10);

    // A unilateral floor under the free-hanging tip (z >= rest - 1 mm): it holds the tip up and pushes only.
    std::vector<ScalarConstraint> floor;
    for (int n : tip) {
      ScalarConstraint fl;
      fl.nodes = {n, -1, -1, -1};
      fl.weights = {1, 0, 0, 0};
      fl.direction = Eigen::Vector3d::UnitZ();
      fl.value = m.rest[n].z() - 0.001;
      fl.unilateral = true;
      floor.push_back(fl);
    }
    in.setConstraints(floor);
    auto dropped = in.initialState();
    const auto r2 = in.solveStatic(dropped);
    QVERIFY2(r2.ok, r2.status.c_str());
    for (Eigen::Index i = 0; i < in.multipliers().size(); ++i) QVERIFY(in.multipliers()[i] >= 0);
    for (int n : tip) QVERIFY(dropped.x[3 * n + 2] >= m.rest[n].z() - 0.001 - 1e-9);
    qInfo("floor: the tip rests at %.3f mm, pushed by %.4f N", 1e3 * (dropped.x[3 * tip[0] + 2] - m.rest[tip[0]].z()), in.multipliers().sum());

    // Invalid constraints are refused with a sentence.
    ScalarConstraint bad;
    bad.nodes = {100000, -1, -1, -1};
    QVERIFY_THROWS_EXCEPTION(MeshError, in.setConstraints({bad}));
  }
};

QTEST_GUILESS_MAIN(TestConstraints)
#include "test_constraints.moc"
