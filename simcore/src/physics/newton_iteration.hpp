#pragma once
// The Newton iterations of one implicit Euler step (Integrator::tryStep), one class per NewtonMethod behind one
// interface (NewtonIteration::run), as Drake's integrators are: the state a step's iterations share (NewtonStep), the
// Newton loop with its line search (NewtonLoop), and what each method owns (its solve, its factor policy).
// Defined in integrator_newton.cpp. Internal to simcore.
#include <rehearse/simcore/integrator.hpp>

#include "integrator_work.hpp"

#include <limits>

namespace rehearse::simcore::detail {

/// What one step's iterations share: set up by Integrator::tryStep (which also made the step's factor or K(x0)),
/// read and updated by the iteration.
struct NewtonStep {
  Eigen::VectorXd& x;  ///< the step's start positions; its end when it advanced
  Eigen::VectorXd& v;  ///< the step's start velocities; its end when it advanced
  double h;            ///< s, this step's time step
  StepReport& rep;     ///< counters, residual, status
  bool lagged;          ///< a lagged factorisation stands for the tangent (any method but exact, on CHOLMOD)
  bool hasConstraints;  ///< attachments as Lagrange multipliers or extra constraints
  double scale = 0;     ///< the residual's scale (momentum units)
  double rn = 0;        ///< Newton loop: the norm of the current residual w.r
};

/// One step's iterations: the interface Integrator::tryStep runs. The base gives the derived classes the integrator's
/// private parts they use (friendship is not inherited).
class NewtonIteration {
 public:
  using Try = Integrator::Try;
  using Work = Integrator::Work;
  NewtonIteration(Integrator& in, NewtonStep& s);
  virtual ~NewtonIteration() = default;
  NewtonIteration(const NewtonIteration&) = delete;
  NewtonIteration& operator=(const NewtonIteration&) = delete;
  /// The step from w.x0, w.v: converged, inexact (s.x and s.v hold the best iterate) or failed (unchanged).
  virtual Try run() = 0;

 protected:
  void project(Eigen::VectorXd& r) const { in_.project(r); }
  bool fixedNode(std::size_t i) const { return in_.fixed_[i] != 0; }
  bool solveConstrained(const Eigen::VectorXd& rhs, const Eigen::VectorXd& x, double positionScale, Eigen::VectorXd& dx,
                        StepReport& rep, bool freeGiven = false, const Eigen::VectorXd* carried = nullptr) {
    return in_.solveConstrained(rhs, x, positionScale, dx, rep, freeGiven, carried);
  }
  bool guardMove(const Eigen::VectorXd& x, Eigen::VectorXd& vel, double h) { return in_.guardMove(x, vel, h); }
  bool refreshLagged(const Eigen::VectorXd& at) { return in_.refreshLaggedAt(at, h, rep); }
  void requestFactor(const Eigen::VectorXd& at) { in_.requestFactor(at, h, rep); }
  bool factoriseShifted(const Eigen::SparseMatrix<double>& A) { return in_.factoriseShifted(A, rep); }
  /// The step's error estimate (StepReport::errorPosition, Integrator::errorMultipliers) from its residual net of the
  /// constraint forces at its end `xEnd`: one more constrained solve with the factor the step has, nothing the step
  /// computed changed (the multipliers are put back).
  void estimateError(const Eigen::VectorXd& netResidual, const Eigen::VectorXd& xEnd);
  bool solveLinear(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, Eigen::VectorXd& y) {
    return in_.solveLinear(A, b, y);
  }
  // The Newton matrix (1 + h alpha) M + h beta Kd + h^2 K into J: exact with Kd = K(x0); the lagged
  // methods use one lagged K for both (leaving K(x0) out of the damping Jacobian costs the exact method
  // many iterations: measured 6-9 instead of 2 per step on the liver preset).
  void buildNewtonMatrix(const Eigen::SparseMatrix<double>& K, Eigen::SparseMatrix<double>& J) const {
    in_.newtonMatrix(K, J, h);
  }

  Integrator& in_;
  NewtonStep& s_;
  Work& w;
  const FemModel& model_;
  const SimulationSettings& settings_;
  const Eigen::VectorXd& mass3_;
  const Eigen::VectorXd& gravityForce_;
  const double h, alpha, beta;
  const bool lagged, hasConstraints;
  StepReport& rep;
};

/// Linearised implicit Euler: one solve with the lagged factor per step, no Newton loop (SOFA's default).
class LinearisedStep final : public NewtonIteration {
 public:
  using NewtonIteration::NewtonIteration;
  Try run() override;

 private:
  void prepare();
  void applyJ0(const Eigen::VectorXd& in, Eigen::VectorXd& out);
  double linearisedResidual();
  void correctWithPcg();
  Try finish();
};

/// The Newton loop shared by the exact, lagged-pcg, chord and Newton-Krylov methods: the residual and the incremental
/// potential, the convergence test, the guarded move, the line search and the step's end. The derived classes solve
/// for the correction and own their factor policy.
class NewtonLoop : public NewtonIteration {
 public:
  NewtonLoop(Integrator& in, NewtonStep& s, bool krylov);
  Try run() final;

 protected:
  /// J dv = -r + H^T mu into w.dv, with w.tmp = -r and w.xt = x0 + h v; false when it could not be solved.
  virtual bool solve() = 0;
  /// After the step's first residual, before the first iteration.
  virtual void started() {}
  /// The move from w.v along w.dv (shortened by the inversion guard: `guarded`) into w.vn with its residual in w.rn;
  /// returns that residual's norm net of the constraint forces.
  virtual double move(bool& guarded);
  /// After an iterate was taken (s_.rn its residual's norm, `previous` the last one's); false ends the iterations.
  virtual bool iterated(double previous) { return true; }

  void residual(const Eigen::VectorXd& vel, Eigen::VectorXd& out);
  double potential(const Eigen::VectorXd& vel);
  double netNorm(const Eigen::VectorXd& res);
  /// J = (1 + h alpha) M + h beta K(x0) + h^2 K(x), applied matrix-free (the tangent at the iterate in w.tangentIt).
  void applyJ(const Eigen::VectorXd& in, Eigen::VectorXd& out);
  /// The lagged factor's constrained correction in w.dv (its multipliers the constraints') refined by conjugate
  /// gradients on J at the iterate, preconditioned by the factor with the constraints' active set fixed (Newton-Krylov's
  /// solve), until the net residual is under `target` or `budget` iterations (counted in `iterations`); `net` the last
  /// net residual. With `curvature`, an iteration meeting a direction of non-positive curvature stops there and sets
  /// `definite` false (the tangent at the iterate is indefinite).
  bool refineOnTangent(double target, int budget, bool curvature, bool& definite, double& net, int& iterations);

 private:
  // Within: confirmed within the accuracy. Move: not (w.dv the Newton step there). Indefinite: the tangent at the
  // iterate is. Unresolved: the contacts' problem was not solved (its sweeps ran out) or changes its set. Failed: no
  // solve.
  // Far: outside Newton's region (its second correction more than a tenth of its first): the distance is not known.
  enum class Verdict { Within, Move, Indefinite, Unresolved, Far, Failed };
  void start();
  double lineSearch(double rnew, bool guarded);
  bool withinAccuracy();
  Verdict verify();
  double secondCorrection();
  bool contactsChange();
  bool suspect() const;
  Try finish(bool ok, int maxIterations);
  const bool prepareInResidual_;
  const bool accuracy_;       // SimulationSettings::accuracyPosition is on
  double contraction_ = 1.0;  // the largest residual ratio of this step's plain moves (with measured_)
  bool measured_ = false;
  // The corrections' own contraction: the largest ratio of a correction to the one before it in this step (the same
  // largest-node norm as the estimate), and the last correction taken in full (m; 0: shortened, none to compare with).
  double correctionRatio_ = 0;
  double lastCorrection_ = 0;
  bool ratioMeasured_ = false;
  bool beyondFirst_ = false;  // a correction's ratio measured beyond the step's first (not along the first move)
  // The contraction the estimates divide by. Before any correction's ratio beyond the step's first is measured, at
  // least kFirstMoveContraction: the first ratio is measured along the first move, the new load's direction, which the
  // factor holds well; the error left lies elsewhere (integrator_newton.cpp).
  double rho() const {
    return std::max({contraction_, correctionRatio_, beyondFirst_ || !chordMap_ ? 0.0 : kFirstMoveContraction});
  }
  static constexpr double kFirstMoveContraction = 0.5;
  // The check's estimate of the end's distance on the tangent there (m; NaN: none made).
  double verifiedEstimate_ = std::numeric_limits<double>::quiet_NaN();

 protected:
  bool plainMove_ = true;  // the last move was the plain correction (the chord's: not mixed)
  /// Issue 61: Newton on the few free nodes that hold nearly all of the residual `res` at `vel` (its net norm
  /// `rnorm`), the rest fixed; updates all three and returns true when it lowered the net norm.
  bool eliminate(Eigen::VectorXd& vel, Eigen::VectorXd& res, double& rnorm);
  // The moves are the lagged factor's corrections (the chord): their contraction is the factor's mismatch with the
  // tangent, direction by direction (the Newton methods solve with the tangent itself).
  bool chordMap_ = false;
};

/// Exact Newton: the tangent assembled and factorised at every iteration (projected, then shifted, when indefinite);
/// also every method with the cg and dense solvers.
class ExactNewton final : public NewtonLoop {
 public:
  ExactNewton(Integrator& in, NewtonStep& s) : NewtonLoop(in, s, false) {}

 private:
  bool solve() override;
  bool dampingProjected_ = false;
};

/// Lagged-pcg: the exact tangent solved by CG preconditioned with the lagged factor.
class LaggedPcgNewton final : public NewtonLoop {
 public:
  LaggedPcgNewton(Integrator& in, NewtonStep& s) : NewtonLoop(in, s, false) {}

 private:
  bool solve() override;
};

/// Chord: the lagged factor's solves to the tolerance, with Anderson acceleration and the factor's refresh when the
/// residual contracts too slowly.
class ChordNewton final : public NewtonLoop {
 public:
  ChordNewton(Integrator& in, NewtonStep& s);

 private:
  bool solve() override;
  void started() override;
  double move(bool& guarded) override;
  bool iterated(double previous) override;
  bool andersonMix();
  const bool accelerate_;
  Work::Anderson& aa;
  int slowIterations_ = 0;    // accelerated: iterations that did not halve the residual
  bool rebuiltHere_ = false;  // accelerated, asynchronous: the factor was rebuilt in this step once already
  bool projectedLast_ = false;  // synchronous: a projected factor was rebuilt at the last iterate
  bool keptFactor_ = false;     // synchronous: a projected factor rebuilt here contracted no better; kept this step
  int rebuilds_ = 0;            // synchronous: factors rebuilt at an iterate in this try
};

/// Newton-Krylov: inexact Newton, the exact tangent applied matrix-free, CG preconditioned with the lagged factor.
class KrylovNewton final : public NewtonLoop {
 public:
  KrylovNewton(Integrator& in, NewtonStep& s) : NewtonLoop(in, s, true) {}

 private:
  bool solve() override;
};

}  // namespace rehearse::simcore::detail
