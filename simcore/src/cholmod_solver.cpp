#include "cholmod_solver.hpp"

#include <cholmod.h>

#include <cstring>

namespace rehearse::simcore {

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

  static cholmod_sparse view(const Eigen::SparseMatrix<double>& A) {
    cholmod_sparse s{};
    s.nrow = s.ncol = static_cast<size_t>(A.rows());
    s.nzmax = static_cast<size_t>(A.nonZeros());
    s.p = const_cast<int*>(A.outerIndexPtr());
    s.i = const_cast<int*>(A.innerIndexPtr());
    s.x = const_cast<double*>(A.valuePtr());
    s.stype = -1;  // symmetric, lower triangle used
    s.itype = CHOLMOD_INT;
    s.xtype = CHOLMOD_REAL;
    s.dtype = CHOLMOD_DOUBLE;
    s.sorted = 1;
    s.packed = 1;
    return s;
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
};

CholmodSolver::CholmodSolver() : d_(std::make_unique<Impl>()) {
  cholmod_start(&d_->common);
  d_->common.supernodal = CHOLMOD_SUPERNODAL;  // measured: simplicial 2x, auto 1.3x slower here
  d_->common.final_asis = 1;
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

bool CholmodSolver::factorise(const Eigen::SparseMatrix<double>& A) {
  Impl& d = *d_;
  cholmod_sparse s = Impl::view(A);
  const std::size_t h = Impl::hashPattern(A);
  if (!d.factor || d.rows != A.rows() || d.nonZeros != A.nonZeros() || d.patternHash != h) {
    cholmod_free_factor(&d.factor, &d.common);
    d.factor = cholmod_analyze(&s, &d.common);
    if (!d.factor) return d.ok = false;
    d.rows = A.rows();
    d.nonZeros = A.nonZeros();
    d.patternHash = h;
    ++d.analyses;
  }
  ++d.factorisations;
  const int status = cholmod_factorize(&s, d.factor, &d.common);
  d.ok = status != 0 && d.common.status == CHOLMOD_OK && d.factor->minor >= d.factor->n;
  return d.ok;
}

bool CholmodSolver::valid() const { return d_->ok; }

bool CholmodSolver::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  cholmod_dense B{};
  B.nrow = static_cast<size_t>(b.size());
  B.ncol = 1;
  B.nzmax = B.d = B.nrow;
  B.x = const_cast<double*>(b.data());
  B.xtype = CHOLMOD_REAL;
  B.dtype = CHOLMOD_DOUBLE;
  if (!d_->solveView(B)) return false;
  if (x.size() != b.size()) x.resize(b.size());
  std::memcpy(x.data(), d_->x->x, sizeof(double) * static_cast<std::size_t>(b.size()));
  return x.allFinite();
}

bool CholmodSolver::solve(const Eigen::MatrixXd& b, Eigen::MatrixXd& x) {
  if (b.cols() == 0) {
    x.resize(b.rows(), 0);
    return true;
  }
  cholmod_dense B{};
  B.nrow = static_cast<size_t>(b.rows());
  B.ncol = static_cast<size_t>(b.cols());
  B.d = B.nrow;
  B.nzmax = B.nrow * B.ncol;
  B.x = const_cast<double*>(b.data());
  B.xtype = CHOLMOD_REAL;
  B.dtype = CHOLMOD_DOUBLE;
  if (!d_->solveView(B)) return false;
  if (x.rows() != b.rows() || x.cols() != b.cols()) x.resize(b.rows(), b.cols());
  std::memcpy(x.data(), d_->x->x, sizeof(double) * static_cast<std::size_t>(b.size()));
  return x.allFinite();
}

int CholmodSolver::analyses() const { return d_->analyses; }
std::size_t CholmodSolver::factorEntries() const {
  if (!d_->factor) return 0;
  return d_->factor->is_super ? d_->factor->xsize : d_->factor->nzmax;
}
int CholmodSolver::factorisations() const { return d_->factorisations; }

}  // namespace rehearse::simcore
