#pragma once
// Time stepping and static equilibrium for the tetrahedral FEM model:
//   implicit (backward) Euler on velocities with Newton iterations and a line search,
//     M (v+ - v) = h (f(x + h v+) - D v+ + f_ext),  D = alpha M + beta K  (Rayleigh damping),
//   and a static solve f(x) + f_ext = 0 (for registration), both with fixed nodes by projection.
// Linear solves: CHOLMOD supernodal Cholesky with the symbolic analysis reused while the pattern is
// unchanged, preconditioned conjugate gradients, or a dense LDL^T (reference for small systems).
// A step that fails (NaN, no convergence) is rolled back and retried with half the time step.
#include <rehearse/simcore/fem.hpp>

#include <memory>
#include <string>
#include <vector>

namespace rehearse::simcore {

enum class LinearSolverKind { Cholmod, ConjugateGradient, Dense };

struct SimulationSettings {
  double timeStep = 0.01;                              ///< s
  Eigen::Vector3d gravity = Eigen::Vector3d(0, -9.81, 0);  ///< m/s^2
  double rayleighMass = 0.1;                           ///< alpha (1/s)
  double rayleighStiffness = 0.1;                      ///< beta (s)
  int maxNewtonIterations = 10;
  double tolerance = 1e-6;                             ///< relative residual
  bool lineSearch = true;
  LinearSolverKind solver = LinearSolverKind::Cholmod;
  int cgMaxIterations = 500;
  double cgTolerance = 1e-10;
  int maxRetries = 4;                                  ///< halvings of the time step after a failed step
};

struct SimulationState {
  Eigen::VectorXd x, v;  ///< positions (m) and velocities (m/s), 3n, node-major
  double time = 0;       ///< s
};

struct StepReport {
  bool ok = false;
  int newtonIterations = 0;
  double residual = 0;      ///< relative residual at the end
  double energy = 0;        ///< kinetic + elastic - gravity work (J)
  double wallMs = 0;
  double timeStepUsed = 0;  ///< s (smaller than asked after retries)
  int retries = 0;
  std::string status;       ///< "converged", "not converged (...)", "failed: ...", one sentence
};

class Integrator {
 public:
  /// `fixedNodes`: 0-based node indices held at their current position.
  Integrator(const FemModel& model, std::vector<int> fixedNodes, SimulationSettings settings);
  ~Integrator();
  Integrator(const Integrator&) = delete;
  Integrator& operator=(const Integrator&) = delete;

  SimulationState initialState() const;
  /// One implicit Euler step of settings.timeStep (sub-stepped on failure). The state is left
  /// unchanged when the step fails after all retries.
  StepReport step(SimulationState& state);
  /// Newton iterations to static equilibrium under gravity and `extraForces` (N, 3n, may be empty).
  StepReport solveStatic(SimulationState& state, const Eigen::VectorXd& extraForces = {});
  /// Solves A y = b with the configured solver (A symmetric positive definite); exposed for tests.
  bool solveLinear(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, Eigen::VectorXd& y);
  const SimulationSettings& settings() const { return settings_; }
  SimulationSettings& settings() { return settings_; }
  /// Times the CHOLMOD symbolic analysis ran (it is reused while the sparsity pattern is unchanged).
  int symbolicAnalyses() const;

 private:
  StepReport tryStep(SimulationState& state, double h);
  double totalEnergy(const SimulationState& s) const;
  void project(Eigen::VectorXd& r) const;
  void projectMatrix(Eigen::SparseMatrix<double>& A) const;

  const FemModel& model_;
  std::vector<char> fixed_;
  SimulationSettings settings_;
  Eigen::VectorXd mass3_, gravityForce_;
  struct Solvers;
  std::unique_ptr<Solvers> solvers_;
};

}  // namespace rehearse::simcore
