#pragma once
// A thin CHOLMOD (supernodal Cholesky) wrapper that keeps everything it allocates: the symbolic
// analysis (redone only when the sparsity pattern changes), the numeric factor, and the solve's
// result and workspace (cholmod_solve2), so repeated factorise/solve calls do not allocate.
#include <Eigen/Sparse>

#include <memory>

namespace rehearse::simcore {

class CholmodSolver {
 public:
  CholmodSolver();
  ~CholmodSolver();
  CholmodSolver(const CholmodSolver&) = delete;
  CholmodSolver& operator=(const CholmodSolver&) = delete;

  /// Simplicial LL' on a copy of the matrix that we permute ourselves (AMD, once per pattern) instead of
  /// the supernodal factorisation: CHOLMOD then neither transposes the matrix nor starts OpenMP teams, so
  /// a re-factorisation allocates nothing; it costs about twice the supernodal one. Takes effect at the
  /// next factorisation (a new analysis).
  void setSimplicial(bool on);

  /// Numeric factorisation of a symmetric matrix (both triangles stored, the lower one is read).
  /// Returns false when it is not positive definite.
  bool factorise(const Eigen::SparseMatrix<double>& A);
  bool valid() const;
  /// x = A^-1 b with the last factorisation (x may alias nothing; no allocation once sized).
  bool solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  /// X = A^-1 B for several right-hand sides at once (columns).
  bool solve(const Eigen::MatrixXd& B, Eigen::MatrixXd& X);
  int analyses() const;
  int factorisations() const;
  /// Entries stored for the factor L (0 before the first factorisation).
  std::size_t factorEntries() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> d_;
};

}  // namespace rehearse::simcore
