// The constraint solver alone (simcore/constraint_solver.hpp), against a dense solve of the KKT system
//   [A  -H^T] [dx]   [rhs            ]
//   [H   0  ] [mu] = [(value - H x)/s]
// for bilateral constraints, including redundant ones (the dense fallback) and nodes fixed by projection;
// unilateral constraints checked by the complementarity conditions (mu >= 0, gap >= 0, mu gap = 0).
#include <QtTest>

#include <rehearse/simcore/constraint_solver.hpp>
#include <rehearse/simcore/mesh.hpp>

#include <Eigen/Dense>

#include <cstring>
#include <random>

using namespace rehearse::simcore;

namespace {
// A chain of n nodes (3 dofs each) joined by springs plus a small tie to the origin: symmetric positive definite.
Eigen::SparseMatrix<double> chainMatrix(int n) {
  std::vector<Eigen::Triplet<double>> t;
  for (int a = 0; a < n; ++a)
    for (int d = 0; d < 3; ++d) {
      t.emplace_back(3 * a + d, 3 * a + d, 0.01);
      if (a + 1 < n) {
        const int b = a + 1;
        const double w = 1.0 + 0.2 * d + 0.01 * a;
        t.emplace_back(3 * a + d, 3 * a + d, w);
        t.emplace_back(3 * b + d, 3 * b + d, w);
        t.emplace_back(3 * a + d, 3 * b + d, -w);
        t.emplace_back(3 * b + d, 3 * a + d, -w);
      }
    }
  Eigen::SparseMatrix<double> A(3 * n, 3 * n);
  A.setFromTriplets(t.begin(), t.end());
  A.makeCompressed();
  return A;
}

// A g x g x g grid of nodes (3 dofs each) coupled to their 26 neighbours by random symmetric 3x3 blocks, a small tie to
// the origin: symmetric positive definite, with supernodes as a tetrahedral mesh's (the chain's are trivial).
Eigen::SparseMatrix<double> gridMatrix(int g) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.5, 1.5);
  auto id = [g](int i, int j, int k) { return (i * g + j) * g + k; };
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < g; ++i)
    for (int j = 0; j < g; ++j)
      for (int k = 0; k < g; ++k) {
        const int a = id(i, j, k);
        for (int d = 0; d < 3; ++d) t.emplace_back(3 * a + d, 3 * a + d, 0.01);
        for (int di = -1; di <= 1; ++di)
          for (int dj = -1; dj <= 1; ++dj)
            for (int dk = -1; dk <= 1; ++dk) {
              const int ii = i + di, jj = j + dj, kk = k + dk;
              if (ii < 0 || jj < 0 || kk < 0 || ii >= g || jj >= g || kk >= g || id(ii, jj, kk) <= a) continue;
              const int b = id(ii, jj, kk);
              Eigen::Matrix3d B;
              for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) B(r, c) = 0.1 * u(rng);
              B = 0.5 * (B + B.transpose()).eval();
              B.diagonal().array() += u(rng);
              for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) {
                  t.emplace_back(3 * a + r, 3 * b + c, -B(r, c));
                  t.emplace_back(3 * b + r, 3 * a + c, -B(c, r));
                  t.emplace_back(3 * a + r, 3 * a + c, B(r, c));
                  t.emplace_back(3 * b + r, 3 * b + c, B(r, c));
                }
            }
      }
  Eigen::SparseMatrix<double> A(3 * g * g * g, 3 * g * g * g);
  A.setFromTriplets(t.begin(), t.end());
  A.makeCompressed();
  return A;
}

double row(const ScalarConstraint& c, const Eigen::VectorXd& v) {
  double out = 0;
  for (int k = 0; k < 4; ++k)
    if (c.nodes[k] >= 0) out += c.weights[k] * c.direction.dot(v.segment<3>(3 * c.nodes[k]));
  return out;
}

ScalarConstraint constraintOn(std::initializer_list<int> nodes, const Eigen::Vector3d& dir, double value, bool unilateral = false) {
  ScalarConstraint c;
  int k = 0;
  for (int n : nodes) {
    c.nodes[k] = n;
    c.weights[k] = 1.0 / static_cast<double>(nodes.size());
    ++k;
  }
  c.direction = dir.normalized();
  c.value = value;
  c.unilateral = unilateral;
  return c;
}
}  // namespace

class TestConstraintSolver : public QObject {
  Q_OBJECT
 private slots:
  void unitBlocksHaveTheBitsOfASolveAlone();
  void bilateralMatchesDenseKkt() {
    const int n = 40;
    const auto A = chainMatrix(n);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    Eigen::VectorXd rhs(3 * n), x(3 * n);
    for (Eigen::Index i = 0; i < rhs.size(); ++i) {
      rhs[i] = u(rng);
      x[i] = 0.01 * u(rng);
    }
    std::vector<ScalarConstraint> cs = {constraintOn({0}, {1, 0, 0}, 0.02), constraintOn({5, 6}, {0, 1, 1}, -0.01),
                                        constraintOn({12, 20, 30}, {1, 2, 3}, 0.005), constraintOn({39}, {0, 0, 1}, 0.03)};
    // Either way of making A^-1 H^T: the nodes' compliance blocks (steps), one solve of H^T's columns (static solves).
    for (const bool direct : {false, true})
      for (const double s : {1.0, 0.01}) {
        ConstraintSolver solver;
        solver.directColumns = direct;
        solver.setConstraints(cs, std::vector<char>(n, 0));
        CholmodSolver chol;
        QVERIFY(chol.factorise(A));
        Eigen::VectorXd dx;
        QVERIFY(chol.solve(rhs, dx));
        int sweeps = 0;
        QVERIFY(solver.solve(chol, x, s, dx, sweeps));
        // Reference: the dense KKT system.
        const Eigen::Index m = static_cast<Eigen::Index>(cs.size());
        Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3 * n + m, 3 * n + m);
        K.topLeftCorner(3 * n, 3 * n) = Eigen::MatrixXd(A);
        Eigen::VectorXd f(3 * n + m);
        f.head(3 * n) = rhs;
        for (Eigen::Index i = 0; i < m; ++i) {
          const auto& c = cs[static_cast<std::size_t>(i)];
          for (int k = 0; k < 4; ++k)
            if (c.nodes[k] >= 0)
              for (int d = 0; d < 3; ++d) {
                K(3 * n + i, 3 * c.nodes[k] + d) += c.weights[k] * c.direction[d];
                K(3 * c.nodes[k] + d, 3 * n + i) -= c.weights[k] * c.direction[d];
              }
          f[3 * n + i] = (c.value - row(c, x)) / s;
        }
        const Eigen::VectorXd ref = K.fullPivLu().solve(f);
        const double dxErr = (dx - ref.head(3 * n)).norm() / ref.head(3 * n).norm();
        const double muErr = (solver.multipliers() - ref.tail(m)).norm() / ref.tail(m).norm();
        qInfo(
            "%s, s = %g: dx %.2e, multipliers %.2e from the dense KKT solve; %d Gauss-Seidel sweeps; violation %.2e m",
            direct ? "H^T's columns" : "node blocks", s, dxErr, muErr, sweeps, solver.violation(x + s * dx));
        QVERIFY(dxErr < 1e-8);
        QVERIFY(muErr < 1e-8);
        QVERIFY(solver.violation(x + s * dx) < 1e-10);
      }
  }

  // A grasp pulled along: the same rows with new values keep W (no multi-column solve per step, issue 34). One solver
  // kept across the values, a refactorised matrix (without invalidate()), a moved row and a new fixed node gives the
  // bits a fresh solver gives each time, and both hold their constraints.
  void schurKeptWhileOnlyTheValuesChange() {
    const int n = 30;
    Eigen::SparseMatrix<double> A = chainMatrix(n);
    const Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(3 * n, -0.5, 0.5), x = Eigen::VectorXd::Zero(3 * n);
    CholmodSolver chol;
    QVERIFY(chol.factorise(A));
    ConstraintSolver kept;
    std::vector<char> fixed(n, 0);
    for (int k = 0; k < 8; ++k) {
      const double pull = 0.01 * k;
      std::vector<ScalarConstraint> cs = {constraintOn({7}, {1, 0, 0}, pull), constraintOn({7}, {0, 1, 0}, -pull),
                                          constraintOn({k < 5 ? 20 : 21}, {0, 0, 1}, 0.02)};
      if (k == 3) {  // the matrix changes under the same factor object (stiffer): W must follow it
        A = 2.0 * chainMatrix(n);
        QVERIFY(chol.factorise(A));
      }
      if (k == 6) fixed[2] = 1;
      kept.setConstraints(cs, fixed);
      kept.multipliers().setZero(kept.size());  // as each step starts (the warm start is another matter)
      ConstraintSolver fresh;
      fresh.setConstraints(cs, fixed);
      Eigen::VectorXd a, b;
      QVERIFY(chol.solve(rhs, a));
      b = a;
      int sweeps = 0;
      QVERIFY(kept.solve(chol, x, 1.0, a, sweeps));
      QVERIFY(fresh.solve(chol, x, 1.0, b, sweeps));
      QVERIFY2(a == b, qPrintable(QString("step %1: |dx - dx_fresh| = %2").arg(k).arg((a - b).norm())));
      QVERIFY(kept.schur() == fresh.schur());
      QVERIFY(kept.violation(x + a) < 1e-10);
    }
  }

  void redundantAndFixed() {
    const int n = 20;
    const auto A = chainMatrix(n);
    const Eigen::VectorXd rhs = Eigen::VectorXd::Constant(3 * n, 0.5), x = Eigen::VectorXd::Zero(3 * n);
    // The same constraint twice (W singular): the dense fallback holds it; node 3 is fixed by projection.
    std::vector<ScalarConstraint> cs = {constraintOn({10}, {1, 0, 0}, 0.1), constraintOn({10}, {1, 0, 0}, 0.1),
                                        constraintOn({3, 4}, {0, 1, 0}, 0.05)};
    std::vector<char> fixed(n, 0);
    fixed[3] = 1;
    // The caller's matrix with the fixed dofs as identity rows and columns, and a projected free solution.
    Eigen::SparseMatrix<double> P = A;
    for (int k = 0; k < P.outerSize(); ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(P, k); it; ++it)
        if (fixed[it.row() / 3] || fixed[it.col() / 3]) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
    CholmodSolver chol;
    QVERIFY(chol.factorise(P));
    Eigen::VectorXd dx;
    QVERIFY(chol.solve(rhs, dx));
    dx.segment<3>(9).setZero();
    const Eigen::VectorXd free = dx;
    for (const bool direct : {false, true}) {
      dx = free;
      ConstraintSolver solver;
      solver.directColumns = direct;
      solver.setConstraints(cs, fixed);
      int sweeps = 0;
      QVERIFY(solver.solve(chol, x, 1.0, dx, sweeps));
      QVERIFY(dx.allFinite());
      QVERIFY(dx.segment<3>(9).norm() == 0);  // the fixed node took no constraint force
      QVERIFY(std::abs(row(cs[0], dx) - 0.1) < 1e-10);
      QVERIFY(std::abs(row(cs[2], dx) - 0.05) < 1e-10);  // held by node 4 alone (node 3 does not move)
    }
    ConstraintSolver solver;
    // A bad constraint is refused with a sentence.
    QVERIFY_THROWS_EXCEPTION(MeshError, solver.setConstraints({constraintOn({n + 5}, {1, 0, 0}, 0)}, fixed));
  }

  void unilateralComplementarity() {
    const int n = 30;
    const auto A = chainMatrix(n);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(3 * n);
    for (int a = 0; a < n; ++a) rhs[3 * a + 2] = -1.0;  // pushed down in z
    const Eigen::VectorXd x = Eigen::VectorXd::Zero(3 * n);
    // A floor at z >= -0.5 under every other node, and one far below that never touches.
    std::vector<ScalarConstraint> cs;
    for (int a = 0; a < n; a += 2) cs.push_back(constraintOn({a}, {0, 0, 1}, -0.5, true));
    cs.push_back(constraintOn({1}, {0, 0, 1}, -1e6, true));
    CholmodSolver chol;
    QVERIFY(chol.factorise(A));
    Eigen::VectorXd dx;
    QVERIFY(chol.solve(rhs, dx));
    const double freeLowest = dx.minCoeff();
    ConstraintSolver solver;
    solver.setConstraints(cs, std::vector<char>(n, 0));
    int sweeps = 0;
    QVERIFY(solver.solve(chol, x, 1.0, dx, sweeps));
    const auto& mu = solver.multipliers();
    double worstComplementarity = 0, worstGap = 0;
    int active = 0;
    for (std::size_t i = 0; i < cs.size(); ++i) {
      const double gap = row(cs[i], dx) - cs[i].value;
      QVERIFY(mu[static_cast<Eigen::Index>(i)] >= 0);
      worstGap = std::min(worstGap, gap);
      worstComplementarity = std::max(worstComplementarity, std::abs(mu[static_cast<Eigen::Index>(i)] * gap));
      active += mu[static_cast<Eigen::Index>(i)] > 0;
    }
    qInfo("free solution reaches z = %.2f; with the floor: %d of %zu contacts active, worst gap %.2e, worst mu*gap %.2e, %d sweeps",
          freeLowest, active, cs.size(), worstGap, worstComplementarity, sweeps);
    QVERIFY(freeLowest < -0.5);  // the floor matters
    QVERIFY(active > 0);
    QCOMPARE(mu[static_cast<Eigen::Index>(cs.size() - 1)], 0.0);  // the far floor never pushes
    QVERIFY(worstGap > -1e-8);
    QVERIFY(worstComplementarity < 1e-8);
  }

  // Contacts strongly coupled through a soft, barely tied chain and a grasp pulling its first node (as
  // the shaft pressing beside a grasp): Gauss-Seidel crawls there, so the active set finishes the solve.
  // Reference: every set of active contacts enumerated (2^10) on the dense W = H A^-1 H^T, the one whose
  // solution is complementary (mu >= 0, gap >= 0) taken; the solver's multipliers must equal it.
  void coupledContactsMatchTheEnumeratedComplementarySolution() {
    const int n = 12;
    const auto A = chainMatrix(n);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(3 * n);
    for (int a = 0; a < n; ++a) rhs[3 * a + 2] = -1.0;
    const Eigen::VectorXd x = Eigen::VectorXd::Zero(3 * n);
    std::vector<ScalarConstraint> cs;
    cs.push_back(constraintOn({0}, {0, 0, 1}, 3.0));  // the grasp lifts node 0
    for (int a = 1; a <= 10; ++a)                       // floors, some under the free shape, some above it
      cs.push_back(constraintOn({a, a + 1}, Eigen::Vector3d(0.1 * (a % 3), 0, 1), -2.0 - 1.5 * a + 4.0 * (a % 2), true));
    const auto m = static_cast<Eigen::Index>(cs.size());
    // The dense reference.
    const Eigen::MatrixXd Ad(A);
    const Eigen::LDLT<Eigen::MatrixXd> Af(Ad);
    const Eigen::VectorXd freeDx = Af.solve(rhs);
    Eigen::MatrixXd Ht = Eigen::MatrixXd::Zero(3 * n, m);
    for (Eigen::Index i = 0; i < m; ++i) {
      Eigen::VectorXd unit = Eigen::VectorXd::Zero(3 * n);
      for (int k = 0; k < 4; ++k)
        if (cs[static_cast<std::size_t>(i)].nodes[k] >= 0)
          unit.segment<3>(3 * cs[static_cast<std::size_t>(i)].nodes[k]) += cs[static_cast<std::size_t>(i)].weights[k] * cs[static_cast<std::size_t>(i)].direction;
      Ht.col(i) = unit;
    }
    const Eigen::MatrixXd W = Ht.transpose() * Af.solve(Ht);
    Eigen::VectorXd e(m);
    for (Eigen::Index i = 0; i < m; ++i) e[i] = cs[static_cast<std::size_t>(i)].value - row(cs[static_cast<std::size_t>(i)], freeDx);
    Eigen::VectorXd reference;
    int solutions = 0;
    for (int mask = 0; mask < (1 << 10); ++mask) {
      std::vector<Eigen::Index> act = {0};
      for (int b = 0; b < 10; ++b)
        if (mask & (1 << b)) act.push_back(b + 1);
      const auto k = static_cast<Eigen::Index>(act.size());
      Eigen::MatrixXd Wa(k, k);
      Eigen::VectorXd ea(k);
      for (Eigen::Index a = 0; a < k; ++a) {
        ea[a] = e[act[static_cast<std::size_t>(a)]];
        for (Eigen::Index b = 0; b < k; ++b) Wa(a, b) = W(act[static_cast<std::size_t>(a)], act[static_cast<std::size_t>(b)]);
      }
      const Eigen::VectorXd la = Wa.fullPivLu().solve(ea);
      Eigen::VectorXd mu = Eigen::VectorXd::Zero(m);
      for (Eigen::Index a = 0; a < k; ++a) mu[act[static_cast<std::size_t>(a)]] = la[a];
      const Eigen::VectorXd w = W * mu - e;
      bool ok = true;
      for (Eigen::Index i = 1; i < m; ++i) ok &= mu[i] >= -1e-12 && w[i] >= -1e-9 * e.cwiseAbs().maxCoeff();
      if (ok) {
        ++solutions;
        reference = mu;
      }
    }
    QCOMPARE(solutions, 1);  // W is positive definite: one complementary solution
    int activeContacts = 0;
    for (Eigen::Index i = 1; i < m; ++i) activeContacts += reference[i] > 0;
    QVERIFY(activeContacts >= 2 && activeContacts <= 8);  // some push, some do not: a real complementarity problem

    CholmodSolver chol;
    QVERIFY(chol.factorise(A));
    Eigen::VectorXd dx;
    QVERIFY(chol.solve(rhs, dx));
    ConstraintSolver solver;
    solver.setConstraints(cs, std::vector<char>(n, 0));
    int sweeps = 0;
    QVERIFY(solver.solve(chol, x, 1.0, dx, sweeps));
    const double error = (solver.multipliers() - reference).norm() / reference.norm();
    qInfo("%d of 10 contacts active; active set after %d sweeps, %d iterations; multipliers against the enumeration %.2e relative",
          activeContacts, sweeps, solver.activeSetIterations(), error);
    QVERIFY(solver.activeSetIterations() > 0);
    QVERIFY(error < 1e-9);
    QVERIFY(solver.violation(x + dx) < 1e-9);
    // Gauss-Seidel alone (no active set) on the same problem: still off after its 300 sweeps.
    ConstraintSolver gs;
    gs.activeSetAfterSweeps = -1;
    gs.setConstraints(cs, std::vector<char>(n, 0));
    Eigen::VectorXd dx2;
    QVERIFY(chol.solve(rhs, dx2));
    int sweeps2 = 0;
    QVERIFY(gs.solve(chol, x, 1.0, dx2, sweeps2));
    const double gsError = (gs.multipliers() - reference).norm() / reference.norm();
    qInfo("Gauss-Seidel alone: %d sweeps, multipliers %.2e relative", sweeps2, gsError);
  }
};

// A node's compliance block solved among others on the threads TBB has (CholmodSolver::solveUnitBlocks, what
// NodeCompliance::prepare calls) has the same bits as the same three columns solved alone with solve(): a cached block
// never depends on which nodes were solved with it or on which core (replays and checkpoints stay bit-exact). And it
// is A^-1: A times the block is the unit block within 1e-10. Supernodal (BLAS) and simplicial factors both.
void TestConstraintSolver::unitBlocksHaveTheBitsOfASolveAlone() {
  const Eigen::SparseMatrix<double> A = gridMatrix(9);
  const Eigen::Index n3 = A.rows();
  for (bool simplicial : {false, true}) {
    CholmodSolver factor;
    factor.setSimplicial(simplicial);
    QVERIFY(factor.factorise(A));
    const std::vector<int> nodes = {0, 17, 363, 728, 404, 5, 260, 111, 600, 42, 333, 700, 81};
    std::vector<int> places(nodes.size());
    for (std::size_t k = 0; k < nodes.size(); ++k) places[k] = static_cast<int>(nodes.size() - 1 - k);  // any order
    Eigen::MatrixXd X = Eigen::MatrixXd::Constant(n3, 3 * static_cast<Eigen::Index>(nodes.size()), -7.0);
    QVERIFY(factor.solveUnitBlocks(nodes.data(), places.data(), nodes.size(), X));
    double worstResidual = 0;
    int differing = 0;
    for (std::size_t k = 0; k < nodes.size(); ++k) {
      Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(n3, 3), alone;
      for (int d = 0; d < 3; ++d) unit(3 * nodes[k] + d, d) = 1;
      QVERIFY(factor.solve(unit, alone));
      const Eigen::MatrixXd block = X.middleCols<3>(3 * places[k]);
      differing += std::memcmp(block.data(), alone.data(), sizeof(double) * static_cast<std::size_t>(alone.size())) != 0;
      worstResidual = std::max(worstResidual, (A * block - unit).cwiseAbs().maxCoeff());
    }
    qInfo("%s: %zu blocks of %lld rows, %d not bit-identical to a solve alone, worst |A X - I| %.2e",
          simplicial ? "simplicial" : "supernodal", nodes.size(), static_cast<long long>(n3), differing, worstResidual);
    QCOMPARE(differing, 0);
    QVERIFY(worstResidual < 1e-10);
    // A node outside the matrix, or a slot beyond X, is refused (nothing written past X).
    const int outside = static_cast<int>(n3 / 3), slot0 = 0, far = static_cast<int>(nodes.size());
    QVERIFY(!factor.solveUnitBlocks(&outside, &slot0, 1, X));
    QVERIFY(!factor.solveUnitBlocks(nodes.data(), &far, 1, X));
  }
}

QTEST_MAIN(TestConstraintSolver)
#include "test_constraint_solver.moc"
