#include <rehearse/simcore/linear_solver.hpp>
#include <rehearse/simcore/numerics.hpp>

#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>

#include <cholmod.h>
#include <dlfcn.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <vector>

namespace rehearse::simcore {
namespace {

// OpenBLAS on one thread: factorising these sparse systems was 2x faster than on two here (measured in the design brief, ../shared/DESIGN.md, beside the repository).
void singleThreadedBlas() {
  static const bool done = [] {
    using Fn = void (*)(int);
    auto fn = reinterpret_cast<Fn>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
    // OpenBLAS is loaded as a dependency of the reference BLAS name; look it up by its own name too.
    for (const char* lib : {"libopenblas.so.0", "libopenblas.so"})
      if (!fn)
        if (void* h = dlopen(lib, RTLD_NOLOAD | RTLD_LAZY))
          fn = reinterpret_cast<Fn>(dlsym(h, "openblas_set_num_threads"));
    if (fn) fn(1);
    // CHOLMOD (SuiteSparse 5.12) opens OpenMP regions of CHOLMOD_OMP_NUM_THREADS = 4 threads in its factorisation
    // and solves, whatever omp_set_num_threads says: on two cores beside the stepping thread, the element loops (TBB)
    // and the factor built on the second thread, their wake-ups cost a quarter of the CPU time of a paced grasp-pull
    // (perf, liver preset, chord+async). No active parallel level makes every such region one thread (libgomp, loaded
    // as CHOLMOD's dependency; found by name so nothing links OpenMP).
    using Levels = void (*)(int);
    if (auto levels = reinterpret_cast<Levels>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"))) levels(0);
    return true;
  }();
  (void)done;
}

// OpenBLAS's kernels pinned before main, while no thread calls BLAS: every process that links the solvers computes the
// same bits on any x86-64 processor (numerics.hpp).
[[gnu::constructor]] void pinBlasAtStart() { pinBlasKernel(); }

}  // namespace

bool factoriseShifted(CholmodSolver& solver, const Eigen::SparseMatrix<double>& A, const std::vector<int>& diagonalSlot,
                      int& attempts, const std::function<bool()>& accept) {
  auto attempt = [&](const Eigen::SparseMatrix<double>& M) {
    ++attempts;
    return solver.factorise(M) && (!accept || accept());
  };
  if (attempt(A)) return true;
  const double base = 1e-6 * A.diagonal().cwiseAbs().maxCoeff();
  Eigen::SparseMatrix<double> shifted = A;  // rare path: allocation is fine here
  for (double shift = base; shift < 1e12 * std::max(base, 1e-300); shift *= 10) {
    for (Eigen::Index i = 0; i < shifted.rows(); ++i)
      shifted.valuePtr()[diagonalSlot[static_cast<std::size_t>(i)]] =
          A.valuePtr()[diagonalSlot[static_cast<std::size_t>(i)]] + shift;
    if (attempt(shifted)) return true;
  }
  return false;
}

bool solveOnce(LinearSolverKind kind, const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b,
               Eigen::VectorXd& y, CholmodSolver& cholmod, int cgMaxIterations, double cgTolerance) {
  switch (kind) {
    case LinearSolverKind::Cholmod:
      return cholmod.factorise(A) && cholmod.solve(b, y);
    case LinearSolverKind::ConjugateGradient: {
      Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper,
                               Eigen::IncompleteCholesky<double>>
          cg;
      cg.setMaxIterations(cgMaxIterations);
      cg.setTolerance(cgTolerance);
      cg.compute(A);
      if (cg.info() != Eigen::Success) return false;
      y = cg.solve(b);
      return cg.info() == Eigen::Success && y.allFinite();
    }
    case LinearSolverKind::Dense:
    default: {
      const Eigen::MatrixXd dense(A);
      Eigen::LDLT<Eigen::MatrixXd> ldlt(dense);
      if (ldlt.info() != Eigen::Success) return false;
      y = ldlt.solve(b);
      return y.allFinite();
    }
  }
}

struct CholmodSolver::Impl {
  cholmod_common common{};
  cholmod_factor* factor = nullptr;
  cholmod_dense* x = nullptr;  // cholmod_solve2 reuses these while the sizes match
  cholmod_dense* y = nullptr;
  cholmod_dense* e = nullptr;
  Eigen::Index rows = -1, nonZeros = -1;
  std::size_t patternHash = 0;
  bool ok = false;
  int analyses = 0, factorisations = 0;
  // Simplicial mode: C = P A P' (upper triangle, column form) with a fixed pattern, filled through `slot`
  // (the position in C of each lower-triangle entry of A, in A's storage order); `inverse` maps a row of
  // A to its row in C.
  bool wantSimplicial = false, isSimplicial = false;
  std::vector<int> inverse, cp, ci, slot;
  std::vector<double> cx;
  Eigen::VectorXd bp;
  Eigen::MatrixXd Bp;
  // solveUnitBlocks: each thread's own CHOLMOD workspace (a solve writes its common and its X, Y, E; the factor is
  // only read), kept from call to call.
  struct Workspace {
    cholmod_common common{};
    cholmod_dense *x = nullptr, *y = nullptr, *e = nullptr;
    Eigen::MatrixXd unit, permuted;
    Workspace() {
      cholmod_start(&common);
      common.print = 0;
      common.error_handler = nullptr;
    }
    ~Workspace() {
      cholmod_free_dense(&x, &common);
      cholmod_free_dense(&y, &common);
      cholmod_free_dense(&e, &common);
      cholmod_finish(&common);
    }
    Workspace(const Workspace&) = delete;
    Workspace& operator=(const Workspace&) = delete;
  };
  tbb::enumerable_thread_specific<Workspace> workspaces;

  // A symmetric matrix in compressed columns, seen by CHOLMOD without a copy; stype -1 reads the lower
  // triangle, +1 the upper one.
  static cholmod_sparse symmetricView(Eigen::Index n, std::size_t nonZeros, const int* p, const int* i, const double* x,
                                      int stype) {
    cholmod_sparse s{};
    s.nrow = s.ncol = static_cast<size_t>(n);
    s.nzmax = nonZeros;
    s.p = const_cast<int*>(p);
    s.i = const_cast<int*>(i);
    s.x = const_cast<double*>(x);
    s.stype = stype;
    s.itype = CHOLMOD_INT;
    s.xtype = CHOLMOD_REAL;
    s.dtype = CHOLMOD_DOUBLE;
    s.sorted = 1;
    s.packed = 1;
    return s;
  }
  static cholmod_sparse view(const Eigen::SparseMatrix<double>& A) {
    return symmetricView(A.rows(), static_cast<std::size_t>(A.nonZeros()), A.outerIndexPtr(), A.innerIndexPtr(),
                         A.valuePtr(), -1);
  }
  static std::size_t hashPattern(const Eigen::SparseMatrix<double>& A) {
    std::size_t h = 1469598103934665603ull;
    for (Eigen::Index k = 0; k <= A.outerSize(); k += std::max<Eigen::Index>(1, A.outerSize() / 64))
      h = (h ^ static_cast<std::size_t>(A.outerIndexPtr()[k])) * 1099511628211ull;
    return h;
  }
  bool solveView(cholmod_dense& b) {
    if (!ok) return false;
    return cholmod_solve2(CHOLMOD_A, factor, &b, nullptr, &x, nullptr, &y, &e, &common) != 0;
  }
  // Upper triangle: with the natural ordering CHOLMOD factorises it in place (no transposed copy).
  cholmod_sparse permutedView() { return symmetricView(rows, cx.size(), cp.data(), ci.data(), cx.data(), 1); }
  // AMD ordering of A, the pattern of C and the slots; then CHOLMOD's analysis of C in its natural order.
  cholmod_factor* analyseSimplicial(const Eigen::SparseMatrix<double>& A, cholmod_sparse& s) {
    const int n = static_cast<int>(A.rows());
    std::vector<int> perm(static_cast<std::size_t>(n));
    if (!cholmod_amd(&s, nullptr, 0, perm.data(), &common)) return nullptr;
    inverse.assign(static_cast<std::size_t>(n), 0);
    for (int k = 0; k < n; ++k) inverse[static_cast<std::size_t>(perm[static_cast<std::size_t>(k)])] = k;
    struct Entry {
      int col, row, source;
    };
    std::vector<Entry> entries;
    int source = 0;
    for (int j = 0; j < n; ++j)
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it) {
        if (it.row() < j) continue;
        const int a = inverse[static_cast<std::size_t>(it.row())], b = inverse[static_cast<std::size_t>(j)];
        entries.push_back({std::max(a, b), std::min(a, b), source++});
      }
    std::sort(entries.begin(), entries.end(),
              [](const Entry& l, const Entry& r) { return l.col != r.col ? l.col < r.col : l.row < r.row; });
    cp.assign(static_cast<std::size_t>(n) + 1, 0);
    ci.resize(entries.size());
    cx.assign(entries.size(), 0.0);
    slot.assign(entries.size(), 0);
    for (std::size_t k = 0; k < entries.size(); ++k) {
      ++cp[static_cast<std::size_t>(entries[k].col) + 1];
      ci[k] = entries[k].row;
      slot[static_cast<std::size_t>(entries[k].source)] = static_cast<int>(k);
    }
    for (int j = 0; j < n; ++j) cp[static_cast<std::size_t>(j) + 1] += cp[static_cast<std::size_t>(j)];
    bp.resize(n);
    cholmod_sparse c = permutedView();
    const int methods = common.nmethods, ordering = common.method[0].ordering, postorder = common.postorder,
              supernodal = common.supernodal;
    common.nmethods = 1;
    common.method[0].ordering = CHOLMOD_NATURAL;
    common.postorder = 0;
    common.supernodal = CHOLMOD_SIMPLICIAL;
    cholmod_factor* f = cholmod_analyze(&c, &common);
    common.nmethods = methods;
    common.method[0].ordering = ordering;
    common.postorder = postorder;
    common.supernodal = supernodal;
    if (f && (f->is_super || f->ordering != CHOLMOD_NATURAL)) cholmod_free_factor(&f, &common);
    return f;
  }
  // v = C^-1 v in place with the simplicial L L' (columns: the diagonal first, then rows below it). Our own
  // two triangular sweeps: cholmod_solve2 re-allocates its workspace at every call for this factor kind.
  bool solvePermutedInPlace(double* v) const {
    if (!ok || !factor || factor->is_super || !factor->is_ll) return false;
    const int* p = static_cast<const int*>(factor->p);
    const int* i = static_cast<const int*>(factor->i);
    const int* nz = static_cast<const int*>(factor->nz);
    const double* lx = static_cast<const double*>(factor->x);
    const int n = static_cast<int>(factor->n);
    for (int j = 0; j < n; ++j) {
      const int start = p[j], end = p[j] + nz[j];
      v[j] /= lx[start];
      for (int k = start + 1; k < end; ++k) v[i[k]] -= lx[k] * v[j];
    }
    for (int j = n - 1; j >= 0; --j) {
      const int start = p[j], end = p[j] + nz[j];
      double t = v[j];
      for (int k = start + 1; k < end; ++k) t -= lx[k] * v[i[k]];
      v[j] = t / lx[start];
    }
    return true;
  }
  void fillPermuted(const Eigen::SparseMatrix<double>& A) {
    int source = 0;
    for (Eigen::Index j = 0; j < A.outerSize(); ++j)
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it)
        if (it.row() >= j) cx[static_cast<std::size_t>(slot[static_cast<std::size_t>(source++)])] = it.value();
  }
};

CholmodSolver::CholmodSolver() : d_(std::make_unique<Impl>()) {
  singleThreadedBlas();
  cholmod_start(&d_->common);
  d_->common.supernodal = CHOLMOD_SUPERNODAL;  // measured: simplicial 2x, auto 1.3x slower here
  d_->common.final_asis = 1;
  d_->common.final_ll = 1;  // simplicial mode: LL', so that a matrix that is not positive definite is reported
  d_->common.print = 0;
  d_->common.error_handler = nullptr;
}

CholmodSolver::~CholmodSolver() {
  cholmod_free_factor(&d_->factor, &d_->common);
  cholmod_free_dense(&d_->x, &d_->common);
  cholmod_free_dense(&d_->y, &d_->common);
  cholmod_free_dense(&d_->e, &d_->common);
  cholmod_finish(&d_->common);
}

void CholmodSolver::setSimplicial(bool on) { d_->wantSimplicial = on; }

bool CholmodSolver::factorise(const Eigen::SparseMatrix<double>& A) {
  Impl& d = *d_;
  cholmod_sparse s = Impl::view(A);
  const std::size_t h = Impl::hashPattern(A);
  if (!d.factor || d.rows != A.rows() || d.nonZeros != A.nonZeros() || d.patternHash != h ||
      d.isSimplicial != d.wantSimplicial) {
    cholmod_free_factor(&d.factor, &d.common);
    d.rows = A.rows();
    d.factor = d.wantSimplicial ? d.analyseSimplicial(A, s) : cholmod_analyze(&s, &d.common);
    if (!d.factor) return d.ok = false;
    d.isSimplicial = d.wantSimplicial;
    d.nonZeros = A.nonZeros();
    d.patternHash = h;
    ++d.analyses;
  }
  ++d.factorisations;
  int status = 0;
  if (d.isSimplicial) {
    d.fillPermuted(A);
    cholmod_sparse c = d.permutedView();
    status = cholmod_factorize(&c, d.factor, &d.common);
  } else {
    status = cholmod_factorize(&s, d.factor, &d.common);
  }
  d.ok = status != 0 && d.common.status == CHOLMOD_OK && d.factor->minor >= d.factor->n;
  return d.ok;
}

bool CholmodSolver::valid() const { return d_->ok; }

bool CholmodSolver::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  Impl& d = *d_;
  if (d.isSimplicial) {
    if (!d.ok || b.size() != d.rows) return false;
    for (Eigen::Index i = 0; i < b.size(); ++i) d.bp[d.inverse[static_cast<std::size_t>(i)]] = b[i];
    if (!d.solvePermutedInPlace(d.bp.data())) return false;
    if (x.size() != b.size()) x.resize(b.size());
    for (Eigen::Index i = 0; i < b.size(); ++i) x[i] = d.bp[d.inverse[static_cast<std::size_t>(i)]];
    return x.allFinite();
  }
  cholmod_dense B{};
  B.nrow = static_cast<size_t>(b.size());
  B.ncol = 1;
  B.nzmax = B.d = B.nrow;
  B.x = const_cast<double*>(b.data());
  B.xtype = CHOLMOD_REAL;
  B.dtype = CHOLMOD_DOUBLE;
  if (!d.solveView(B)) return false;
  if (x.size() != b.size()) x.resize(b.size());
  std::memcpy(x.data(), d.x->x, sizeof(double) * static_cast<std::size_t>(b.size()));
  return x.allFinite();
}

bool CholmodSolver::solve(const Eigen::MatrixXd& b, Eigen::MatrixXd& x) {
  if (b.cols() == 0) {
    x.resize(b.rows(), 0);
    return true;
  }
  Impl& d = *d_;
  if (d.isSimplicial) {
    if (!d.ok || b.rows() != d.rows) return false;
    if (d.Bp.rows() != b.rows() || d.Bp.cols() != b.cols()) d.Bp.resize(b.rows(), b.cols());
    for (Eigen::Index i = 0; i < b.rows(); ++i) d.Bp.row(d.inverse[static_cast<std::size_t>(i)]) = b.row(i);
    for (Eigen::Index c = 0; c < b.cols(); ++c)
      if (!d.solvePermutedInPlace(d.Bp.col(c).data())) return false;
    if (x.rows() != b.rows() || x.cols() != b.cols()) x.resize(b.rows(), b.cols());
    for (Eigen::Index i = 0; i < b.rows(); ++i) x.row(i) = d.Bp.row(d.inverse[static_cast<std::size_t>(i)]);
    return x.allFinite();
  }
  cholmod_dense B{};
  B.nrow = static_cast<size_t>(b.rows());
  B.ncol = static_cast<size_t>(b.cols());
  B.d = B.nrow;
  B.nzmax = B.nrow * B.ncol;
  B.x = const_cast<double*>(b.data());
  B.xtype = CHOLMOD_REAL;
  B.dtype = CHOLMOD_DOUBLE;
  if (!d.solveView(B)) return false;
  if (x.rows() != b.rows() || x.cols() != b.cols()) x.resize(b.rows(), b.cols());
  std::memcpy(x.data(), d.x->x, sizeof(double) * static_cast<std::size_t>(b.size()));
  return x.allFinite();
}

bool CholmodSolver::solveUnitBlocks(const int* nodes, const int* slots, std::size_t count, Eigen::MatrixXd& X) {
  Impl& d = *d_;
  if (!d.ok || X.rows() != d.rows) return false;
  for (std::size_t k = 0; k < count; ++k)
    if (nodes[k] < 0 || 3 * static_cast<Eigen::Index>(nodes[k]) + 3 > d.rows || slots[k] < 0 ||
        3 * static_cast<Eigen::Index>(slots[k]) + 3 > X.cols())
      return false;
  std::atomic<bool> ok{true};
  // One block a task: blocks are few (the nodes a tool holds and touches) and each costs milliseconds.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1), [&](const tbb::blocked_range<std::size_t>& r) {
    Impl::Workspace& w = d.workspaces.local();
    const Eigen::Index n = d.rows;
    for (std::size_t k = r.begin(); k != r.end(); ++k) {
      const Eigen::Index node = nodes[k], first = 3 * static_cast<Eigen::Index>(slots[k]);
      if (w.unit.rows() != n || w.unit.cols() != 3) w.unit.setZero(n, 3);
      if (d.isSimplicial) {
        // As solve(B, X): permuted, each column swept alone (no BLAS).
        if (w.permuted.rows() != n || w.permuted.cols() != 3) w.permuted.resize(n, 3);
        w.permuted.setZero();
        for (int c = 0; c < 3; ++c) w.permuted(d.inverse[static_cast<std::size_t>(3 * node + c)], c) = 1;
        bool solved = true;
        for (int c = 0; c < 3; ++c) solved &= d.solvePermutedInPlace(w.permuted.col(c).data());
        if (!solved) {
          ok = false;
          continue;
        }
        for (Eigen::Index i = 0; i < n; ++i)
          X.block<1, 3>(i, first) = w.permuted.row(d.inverse[static_cast<std::size_t>(i)]);
      } else {
        for (int c = 0; c < 3; ++c) w.unit(3 * node + c, c) = 1;
        cholmod_dense B{};
        B.nrow = static_cast<size_t>(n);
        B.ncol = 3;
        B.d = B.nrow;
        B.nzmax = B.nrow * B.ncol;
        B.x = w.unit.data();
        B.xtype = CHOLMOD_REAL;
        B.dtype = CHOLMOD_DOUBLE;
        const bool solved = cholmod_solve2(CHOLMOD_A, d.factor, &B, nullptr, &w.x, nullptr, &w.y, &w.e, &w.common) != 0;
        for (int c = 0; c < 3; ++c) w.unit(3 * node + c, c) = 0;
        if (!solved) {
          ok = false;
          continue;
        }
        std::memcpy(X.col(first).data(), w.x->x, sizeof(double) * static_cast<std::size_t>(3 * n));
      }
      if (!X.middleCols<3>(first).allFinite()) ok = false;
    }
  });
  return ok;
}

int CholmodSolver::analyses() const { return d_->analyses; }
std::size_t CholmodSolver::factorEntries() const {
  if (!d_->factor) return 0;
  return d_->factor->is_super ? d_->factor->xsize : d_->factor->nzmax;
}
int CholmodSolver::factorisations() const { return d_->factorisations; }

}  // namespace rehearse::simcore
