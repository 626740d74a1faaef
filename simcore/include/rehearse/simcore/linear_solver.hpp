#pragma once
// The linear solvers of the FEM (one part of the integrator, tested alone against dense solves in
// tests/simcore/test_linear_solver.cpp):
//  - CholmodSolver: a thin CHOLMOD (supernodal or simplicial Cholesky) wrapper that keeps everything it
//    allocates: the symbolic analysis (redone only when the sparsity pattern changes), the numeric factor,
//    and the solve's result and workspace (cholmod_solve2), so repeated factorise/solve calls do not
//    allocate. OpenBLAS is set to one thread (2x faster here on these systems: the design brief, ../shared/DESIGN.md).
//  - factoriseShifted: a Cholesky of a matrix that may be indefinite (a nonlinear material's tangent under
//    large deformation), shifting its diagonal until it factorises.
//  - solveOnce: one solve with CHOLMOD, incomplete-Cholesky preconditioned CG, or a dense LDL^T (reference).
#include <Eigen/Sparse>

#include <functional>
#include <memory>
#include <vector>

namespace rehearse::simcore {

enum class LinearSolverKind { Cholmod, ConjugateGradient, Dense };

class CholmodSolver;

/// Factorises A (symmetric, lower triangle read); when it is not positive definite, or `accept` (which
/// solves with the new factor) refuses the result, factorises A + shift I with the shift growing tenfold
/// from 1e-6 max|diag A| to 1e6 max|diag A|. `diagonalSlot[i]` is where A(i, i) is in A's value array.
/// Each attempt is counted in `attempts`. False when no shift worked.
bool factoriseShifted(CholmodSolver& solver, const Eigen::SparseMatrix<double>& A, const std::vector<int>& diagonalSlot, int& attempts,
                      const std::function<bool()>& accept = nullptr);

/// y = A^-1 b for a symmetric positive definite A with the given kind (CHOLMOD through `cholmod`, CG to
/// `cgTolerance` in at most `cgMaxIterations`, or dense LDL^T). False when the solve failed or is not finite.
bool solveOnce(LinearSolverKind kind, const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, Eigen::VectorXd& y,
               CholmodSolver& cholmod, int cgMaxIterations = 500, double cgTolerance = 1e-10);

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
  /// For each k < count: X.middleCols<3>(3 * slots[k]) = A^-1 [e_3i e_3i+1 e_3i+2], i = nodes[k] (a node's compliance
  /// block). Each block is solved alone, with the same bits as solve() gives for those three columns, whichever thread
  /// solves it: the blocks are spread over the threads TBB has (two cores solve 17 blocks in about half the time).
  /// X must have 3 n rows and room for the slots. False when a solve failed or is not finite.
  bool solveUnitBlocks(const int* nodes, const int* slots, std::size_t count, Eigen::MatrixXd& X);
  int analyses() const;
  int factorisations() const;
  /// Entries stored for the factor L (0 before the first factorisation).
  std::size_t factorEntries() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> d_;
};

}  // namespace rehearse::simcore
