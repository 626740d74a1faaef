// The linear solvers alone (simcore/linear_solver.hpp), against Eigen's dense Cholesky (LLT) of the same
// matrix: CHOLMOD supernodal and simplicial, multi right-hand sides, CG and the dense LDL^T of solveOnce;
// the symbolic analysis reused while the pattern is unchanged; an indefinite matrix refused by the plain
// factorisation and factorised by factoriseShifted with the smallest shift that works.
#include <QtTest>

#include <rehearse/simcore/linear_solver.hpp>
#include <rehearse/simcore/numerics.hpp>

#include <Eigen/Dense>

#include <cstring>
#include <random>

using namespace rehearse::simcore;

namespace {
// 3D grid Laplacian (n^3 nodes, 3 dofs each, 6-neighbour springs) plus `shift` on the diagonal, both
// triangles stored: symmetric, positive definite for shift > 0, with the pattern of a FEM stiffness.
Eigen::SparseMatrix<double> gridMatrix(int n, double shift, std::vector<int>* diagonalSlot = nullptr) {
  auto id = [n](int i, int j, int k) { return (i * n + j) * n + k; };
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const int a = id(i, j, k);
        const int nb[3] = {i + 1 < n ? id(i + 1, j, k) : -1, j + 1 < n ? id(i, j + 1, k) : -1, k + 1 < n ? id(i, j, k + 1) : -1};
        for (int b : nb) {
          if (b < 0) continue;
          for (int d = 0; d < 3; ++d) {
            const double w = 1.0 + 0.1 * d;
            t.emplace_back(3 * a + d, 3 * a + d, w);
            t.emplace_back(3 * b + d, 3 * b + d, w);
            t.emplace_back(3 * a + d, 3 * b + d, -w);
            t.emplace_back(3 * b + d, 3 * a + d, -w);
          }
        }
        for (int d = 0; d < 3; ++d) t.emplace_back(3 * a + d, 3 * a + d, shift);
      }
  Eigen::SparseMatrix<double> A(3 * n * n * n, 3 * n * n * n);
  A.setFromTriplets(t.begin(), t.end());
  A.makeCompressed();
  if (diagonalSlot) {
    diagonalSlot->assign(static_cast<std::size_t>(A.rows()), -1);
    for (int c = 0; c < A.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, c); it; ++it)
        if (it.row() == it.col()) (*diagonalSlot)[static_cast<std::size_t>(c)] = static_cast<int>(&it.valueRef() - A.valuePtr());
  }
  return A;
}

Eigen::VectorXd randomVector(Eigen::Index n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::VectorXd v(n);
  for (Eigen::Index i = 0; i < n; ++i) v[i] = u(rng);
  return v;
}
}  // namespace

namespace {
// The bytes of a supernodal (or simplicial) solve of the grid system: equal only for bit-identical results.
QByteArray solveBits(bool simplicial) {
  const Eigen::SparseMatrix<double> A = gridMatrix(14, 0.01);  // 8,232 dofs: supernodes large enough for BLAS-3
  const Eigen::VectorXd b = randomVector(A.rows(), 7);
  CholmodSolver solver;
  solver.setSimplicial(simplicial);
  Eigen::VectorXd x;
  if (!solver.factorise(A) || !solver.solve(b, x)) return {};
  return QByteArray(reinterpret_cast<const char*>(x.data()), static_cast<int>(x.size() * sizeof(double)));
}
}  // namespace

class TestLinearSolver : public QObject {
  Q_OBJECT
 private slots:
  // Issue 60: the process's OpenBLAS is pinned to one kernel set whatever OPENBLAS_CORETYPE says (ctest runs this suite
  // under Prescott, Haswell, SkylakeX, Zen, Cooperlake and unset), and CHOLMOD's calls reach it whatever BLAS the
  // machine's alternatives select. The kernels do round differently (another core's solve differs in its bits), so the
  // pin is what makes a recording's checksums the same on every processor; the simplicial factor calls no BLAS.
  void blasKernelIsPinnedWhateverTheProcessor() {
    const QByteArray env = qgetenv("OPENBLAS_CORETYPE");
    const std::string kernel = blasKernel();
    qInfo("OPENBLAS_CORETYPE=%s: %s", env.isEmpty() ? "(unset)" : env.constData(), kernel.c_str());
    QVERIFY2(kernel.rfind("OpenBLAS ", 0) == 0, kernel.c_str());  // CHOLMOD's dgemm_ is OpenBLAS's, not libblas.so.3's
    QVERIFY2(kernel.size() > 9 && kernel.substr(kernel.size() - std::strlen(kPinnedBlasCore)) == kPinnedBlasCore,
             kernel.c_str());
    QVERIFY(pinBlasKernel());
    const QByteArray pinned = solveBits(false), simplicial = solveBits(true);
    QVERIFY(!pinned.isEmpty() && !simplicial.isEmpty());
    // Another kernel set, where this processor runs one: the supernodal solve's bits change, the simplicial one's not.
    const char* other = nullptr;
    for (const char* core : {"SkylakeX", "Haswell", "Zen"})
      if (!other && selectBlasCore(core)) other = core;
    if (other) {
      const std::string otherKernel = blasKernel();
      const QByteArray supernodalThere = solveBits(false), simplicialThere = solveBits(true);
      QVERIFY(pinBlasKernel());
      QCOMPARE(QString::fromStdString(blasKernel()), QString::fromStdString(kernel));
      qInfo("%s: supernodal solve %s the pinned one's bits; simplicial %s", otherKernel.c_str(),
            supernodalThere == pinned ? "equals" : "differs from", simplicialThere == simplicial ? "equal" : "differ");
      QVERIFY2(supernodalThere != pinned, "another kernel set gave the same bits: this test shows nothing here");
      QCOMPARE(simplicialThere, simplicial);
    }
    QCOMPARE(solveBits(false), pinned);  // back on the pinned kernels: the same bits again
    if (!other) QSKIP("this processor has neither AVX2 nor AVX-512: no other OpenBLAS kernel set to compare with");
  }

  void cholmodMatchesDenseCholesky() {
    const auto A = gridMatrix(9, 0.05);  // 2187 dofs
    const Eigen::VectorXd b = randomVector(A.rows(), 1);
    const Eigen::VectorXd ref = Eigen::MatrixXd(A).llt().solve(b);
    for (bool simplicial : {false, true}) {
      CholmodSolver chol;
      chol.setSimplicial(simplicial);
      QVERIFY(chol.factorise(A));
      QVERIFY(chol.valid());
      Eigen::VectorXd y;
      QVERIFY(chol.solve(b, y));
      const double err = (y - ref).norm() / ref.norm();
      qInfo("%s CHOLMOD against dense LLT: relative difference %.2e", simplicial ? "simplicial" : "supernodal", err);
      QVERIFY(err < 1e-10);
      // Several right-hand sides at once.
      Eigen::MatrixXd B(A.rows(), 3), X;
      for (int c = 0; c < 3; ++c) B.col(c) = randomVector(A.rows(), 10 + c);
      QVERIFY(chol.solve(B, X));
      const Eigen::MatrixXd refX = Eigen::MatrixXd(A).llt().solve(B);
      QVERIFY((X - refX).norm() / refX.norm() < 1e-10);
      // New values, same pattern: the analysis is reused.
      auto A2 = A;
      for (int k = 0; k < A2.nonZeros(); ++k) A2.valuePtr()[k] *= 2;
      QVERIFY(chol.factorise(A2));
      QVERIFY(chol.solve(b, y));
      QVERIFY((2 * y - ref).norm() / ref.norm() < 1e-10);
      QCOMPARE(chol.analyses(), 1);
      QCOMPARE(chol.factorisations(), 2);
      // Another pattern: analysed again.
      QVERIFY(chol.factorise(gridMatrix(5, 0.05)));
      QCOMPARE(chol.analyses(), 2);
    }
  }

  void solveOnceEveryKind() {
    const auto A = gridMatrix(7, 0.05);
    const Eigen::VectorXd b = randomVector(A.rows(), 2);
    const Eigen::VectorXd ref = Eigen::MatrixXd(A).llt().solve(b);
    CholmodSolver chol;
    for (auto kind : {LinearSolverKind::Cholmod, LinearSolverKind::ConjugateGradient, LinearSolverKind::Dense}) {
      Eigen::VectorXd y;
      QVERIFY(solveOnce(kind, A, b, y, chol, 2000, 1e-12));
      const double err = (y - ref).norm() / ref.norm();
      qInfo("kind %d: relative difference to dense LLT %.2e", static_cast<int>(kind), err);
      QVERIFY(err < 1e-8);
    }
    // CG that cannot converge in its budget says so instead of returning its last iterate.
    Eigen::VectorXd y;
    QVERIFY(!solveOnce(LinearSolverKind::ConjugateGradient, A, b, y, chol, 2, 1e-14));
  }

  void indefiniteMatrixIsShifted() {
    std::vector<int> diagonal;
    auto A = gridMatrix(5, 0.0, &diagonal);
    for (int i = 0; i < 6; ++i) A.valuePtr()[diagonal[static_cast<std::size_t>(i)]] -= 3.0;  // a few negative directions
    const double smallest = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(A)).eigenvalues().minCoeff();
    QVERIFY(smallest < 0);
    CholmodSolver chol;
    QVERIFY(!chol.factorise(A));  // not positive definite: refused
    int attempts = 0;
    QVERIFY(factoriseShifted(chol, A, diagonal, attempts));
    QVERIFY(attempts > 1);
    // The factor is of A + sigma I with the first sigma of the sequence 1e-6 max|diag| x 10^k above -lambda_min.
    const double base = 1e-6 * A.diagonal().cwiseAbs().maxCoeff();
    double sigma = base;
    while (sigma <= -smallest) sigma *= 10;
    Eigen::SparseMatrix<double> I(A.rows(), A.cols());
    I.setIdentity();
    const Eigen::VectorXd b = randomVector(A.rows(), 3);
    Eigen::VectorXd y;
    QVERIFY(chol.solve(b, y));
    const Eigen::VectorXd ref = Eigen::MatrixXd(A + sigma * I).llt().solve(b);
    qInfo("lambda_min %.3f; shifted by %.3g after %d attempts", smallest, sigma, attempts);
    QVERIFY((y - ref).norm() / ref.norm() < 1e-9);
    // An `accept` that refuses every factor: no shift is taken.
    attempts = 0;
    QVERIFY(!factoriseShifted(chol, A, diagonal, attempts, [] { return false; }));
    QVERIFY(attempts > 10);
  }
};

QTEST_MAIN(TestLinearSolver)
#include "test_linear_solver.moc"
