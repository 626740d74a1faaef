#pragma once
// The integrator's workspace and small helpers, shared by its translation units (integrator.cpp: the step;
// integrator_factor.cpp: the lagged factorisation, refreshed at once or on the second thread; integrator_static.cpp:
// the static solve). Internal to simcore.
#include <rehearse/simcore/integrator.hpp>

#include <Eigen/Sparse>

#include <future>
#include <memory>
#include <string>
#include <vector>

namespace rehearse::simcore {

// Everything a step needs, sized once: a step that converges does not allocate.
struct Integrator::Work {
  std::unique_ptr<CholmodSolver> chol = std::make_unique<CholmodSolver>();
  TangentState tangent0;           // the tangent at the step start: Rayleigh damping beta K(x0) v, matrix-free
  Eigen::SparseMatrix<double> Kd;  // K(x0) (exact method) or the lagged stiffness (lagged methods)
  Eigen::SparseMatrix<double> K;   // tangent stiffness at the current iterate
  Eigen::SparseMatrix<double> J;   // the factorised Newton matrix (exact, or lagged)
  Eigen::VectorXd x0, v0, Mv0, v, vn, xt, r, rn, dv, f, tmp, savedX, savedV, stepX, stepV;
  Eigen::VectorXd firstIterate;   // SimulationState::firstIterate, for the step's first try
  bool useFirstIterate = false;
  Eigen::VectorXd pr, pz, pp, pq, pk, pn, py;  // PCG (py: newton-krylov's multiplier correction)
  ConstraintSolver cons;                       // attachments (Lagrange mode) then the extra constraints
  Eigen::VectorXd lambdaOut;                   // multipliers of the last solve, as forces (N)
  Eigen::VectorXd lambdaCarried;               // lagged-pcg: the multipliers whose forces the free solve already holds
  Eigen::VectorXd errorDv, errorCarried;       // the step's error estimate: its correction, the multipliers kept
  Eigen::VectorXd errorLambda;                 // the multipliers' distance from the converged answer's (N)
  bool errorLambdaValid = false;
  Eigen::VectorXd muBefore, muChange;  // SimulationSettings::accuracyPosition: the multipliers before a solve, their change
  bool estimateThisStep = true;  // Integrator::step: this step estimates its error (SimulationSettings::estimateErrorEvery)
  long stepsTaken = 0;
  double laggedStep = -1;                      // h the lagged factor was built for (-1: none)
  Eigen::VectorXd laggedAt;                    // positions it was built at (with laggedStep: its identity)
  bool invalidated = false;                    // invalidateFactorisation() was called: rebuild at the next step
  bool refresh = true;                         // rebuild the lagged factor at the next opportunity
  bool drift = false;  // the lagged factor drifted (its residual grew): rebuild it where settings.factorRefresh says
  // The requested factor (asynchronous and deferred refresh): built into its own solver and matrices, then
  // swapped with chol, Kd and J (the solvers keep their analyses: the pattern is the same).
  struct Request {
    std::unique_ptr<CholmodSolver> chol = std::make_unique<CholmodSolver>();
    Eigen::SparseMatrix<double> Kd, J;
    Eigen::VectorXd at;
    double step = -1;
    int attempts = 0;
    bool pending = false;  // requested and not swapped in yet
    bool built = false;    // the build finished (ok tells how)
    bool ok = false;
    std::future<bool> job;  // asynchronous: the build under way on the second thread
    // The constraint rows when it was requested: their nodes' compliance blocks are solved with the new factor where
    // it is built, and come in with it (a factor swapped in under a touching shaft otherwise stalled the step that
    // met it: 20 nodes x 5.5 ms at 17k tets).
    std::vector<ScalarConstraint> rows;
    NodeCompliance compliance;
  };
  // On the heap: the build on the second thread writes into it by its address, so a request dropped while still being
  // built moves to `abandoned` whole (its job left to finish there, its result never used) and the step that dropped
  // it does not wait for it; a finished one is taken back as the next request's buffers (its solver's analysis kept).
  std::unique_ptr<Request> request = std::make_unique<Request>();
  std::vector<std::unique_ptr<Request>> abandoned;
  int staticFactor = -1;             // chol.factorisations() just after a static tangent was factorised
  Eigen::VectorXd forcesAt, forces;  // elastic forces at the end of the last step (projected), and where
  bool forcesValid = false;
  // Linearised method: the tangent and forces at the end of the last step (its nonlinear residual needs the
  // forces there; the next step starts from the same pass when it starts at the same positions).
  TangentState tangentEnd;
  Eigen::VectorXd tangentEndAt, forcesEnd;
  bool tangentEndValid = false;
  // Newton-Krylov: the tangent prepared with the last residual (at tangentItAt: the current iterate, then the step's
  // end, which the next step starting there reuses for its damping).
  TangentState tangentIt;
  TangentState tangentSpare;  // NewtonLoop::secondCorrection's tangent (tangentIt stays the step end's)
  Eigen::VectorXd tangentItAt;
  bool tangentItValid = false;
  Eigen::VectorXd bestX, bestV;  // the attempt with the smallest residual (a step that does not converge)
  std::vector<int> limiting;     // elements a move would have taken below their floor (guardMove)
  // Chord method, SimulationSettings::chordAcceleration: Anderson's mixing of the last chord corrections (Walker and
  // Ni 2011, type II). g = v + dv (the plain chord iterate), f = dv (the lagged factor's preconditioned residual),
  // mu the multipliers after that solve; differences of consecutive ones, at most kDepth kept (a ring).
  struct Anderson {
    static constexpr int kDepth = 6;
    std::vector<Eigen::VectorXd> dG, dF, dMu;
    Eigen::VectorXd g, f, mu;  // the last iteration's g, f and multipliers
    int count = 0;             // differences held (<= kDepth)
    int next = 0;              // the ring's next slot
    bool havePrevious = false;
    // At most kDepth x kDepth, held in place (a step that converges allocates nothing: test_allocation).
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kDepth, kDepth> gram;
    Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kDepth, 1> rhs, gamma;
    Eigen::VectorXd plainDv, plainMu;  // the plain chord correction of this iteration (the safeguard falls back to it)
    /// Sizes the ring for 3n velocities and `constraints` multipliers (allocates only when those change).
    void size(Eigen::Index n, Eigen::Index constraints) {
      dG.resize(kDepth);
      dF.resize(kDepth);
      dMu.resize(kDepth);
      for (int i = 0; i < kDepth; ++i) {
        if (dG[i].size() != n) dG[i].setZero(n);
        if (dF[i].size() != n) dF[i].setZero(n);
        if (dMu[i].size() != constraints) dMu[i].setZero(constraints);
      }
      if (g.size() != n) g.setZero(n);
      if (f.size() != n) f.setZero(n);
      if (plainDv.size() != n) plainDv.setZero(n);
      if (mu.size() != constraints) mu.setZero(constraints);
      if (plainMu.size() != constraints) plainMu.setZero(constraints);
    }
    void reset() {
      count = 0;
      next = 0;
      havePrevious = false;
    }
  } anderson;
};

namespace detail {
// Every numeric factorisation goes through here, so the factor kind follows the settings as they are now.
inline bool factoriseWith(CholmodSolver& chol, const SimulationSettings& settings,
                          const Eigen::SparseMatrix<double>& M) {
  chol.setSimplicial(settings.simplicialFactor);
  return chol.factorise(M);
}
// "10 micrometres", for statuses.
inline std::string micrometres(double metres) {
  char text[48];
  std::snprintf(text, sizeof text, "%g micrometres", 1e6 * metres);
  return text;
}
inline std::string figure(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}
}  // namespace detail

}  // namespace rehearse::simcore
