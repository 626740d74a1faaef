// The static solve (Newton on the equilibrium, for registration and the quasi-static steps): Integrator::solveStatic
// and its iterations (detail::StaticSolve).
#include <rehearse/simcore/integrator.hpp>

#include "integrator_work.hpp"

#include <Eigen/Dense>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <limits>

namespace rehearse::simcore {

using namespace detail;

namespace detail {

// One static solve: Newton on f(x) + f_ext = 0 from the state's positions, with its chord, projected and shifted
// tangents, trust region and line search (Integrator::solveStatic runs it).
class StaticSolve {
 public:
  StaticSolve(Integrator& in, SimulationState& state, const Eigen::VectorXd& extra, StepReport& rep);
  void run();
  void finish();

 private:
  bool balanced(int it);
  bool solveStep(int it);
  bool moved();
  double potential(const Eigen::VectorXd& at) const;
  bool usableStep(Eigen::VectorXd& d) const;
  void buildTangent(bool projected);

  Integrator& in_;
  Integrator::Work& w;
  const FemModel& model_;
  const SimulationSettings& settings_;
  SimulationState& state_;
  StepReport& rep;
  const Eigen::VectorXd fext;
  const bool hasConstraints;
  const double scale;
  Eigen::VectorXd x, r, dx;
  double regularisation = 0;
  int maxIterations = 0;
  double previousResidual = 1e300;
  int stalled = 0;
  double residualBefore = 1e300;  // the previous iteration's (chord)
  bool roundOff = false, smallStep = false;
  // A Newton step larger than ten times the organ is a near-singular solve, not a move: refused, and the
  // projected tangent (then growing diagonal shifts) tried instead. Steps beyond a quarter of the organ are
  // shortened to that (a trust region; the next iterations continue).
  const double organSize;
};

namespace {
Eigen::VectorXd externalForces(const Eigen::VectorXd& gravityForce, const Eigen::VectorXd& extra) {
  Eigen::VectorXd fext = gravityForce;
  if (extra.size() == fext.size()) fext += extra;
  return fext;
}
}  // namespace

StaticSolve::StaticSolve(Integrator& in, SimulationState& state, const Eigen::VectorXd& extra, StepReport& rep)
    : in_(in),
      w(*in.w_),
      model_(in.model_),
      settings_(in.settings_),
      state_(state),
      rep(rep),
      fext(externalForces(in.gravityForce_, extra)),
      hasConstraints(!in.attachmentConstraints_.empty() || !in.constraints_.empty()),
      scale(std::max(fext.norm(), 1e-2 * model_.lumpedMass.sum())),
      x(state.x),
      organSize(in.organSize_) {
  if (hasConstraints) w.cons.multipliers().setZero(w.cons.size());
  // A body held only by constraints has a singular stiffness: the Newton matrix gets M / (1 s)^2, which
  // only slows the softest modes (the residual below is the true one, so the equilibrium is unchanged).
  // (Not needed when nodes are fixed by projection: they hold the body, and the regularisation would make
  // Newton converge only linearly in the softest modes.)
  const bool heldByProjection = std::find(in.fixed_.begin(), in.fixed_.end(), 1) != in.fixed_.end();
  regularisation = hasConstraints && !heldByProjection ? 1.0 : 0.0;
  maxIterations = std::max(settings_.maxNewtonIterations, 30) + (hasConstraints ? 30 : 0);
}

double StaticSolve::potential(const Eigen::VectorXd& at) const {
  return elasticEnergy(model_, at) - fext.dot(at - in_.rest_);
}

bool StaticSolve::usableStep(Eigen::VectorXd& d) const {
  const double largest = d.size() ? d.cwiseAbs().maxCoeff() : 0.0;
  if (!std::isfinite(largest) || largest > 10 * organSize) return false;
  if (largest > 0.25 * organSize) d *= 0.25 * organSize / largest;
  return true;
}

void StaticSolve::buildTangent(bool projected) {
  assembleStiffness(model_, x, w.K, projected ? projectionOf(settings_) : TangentProjection::None);
  if (regularisation > 0)
    for (Eigen::Index i = 0; i < w.K.rows(); ++i)
      w.K.valuePtr()[model_.diagonalSlot[i]] += regularisation * in_.mass3_[i];
  in_.projectMatrix(w.K);
}

void StaticSolve::run() {
  for (int it = 0; it < maxIterations; ++it) {
    if (balanced(it)) break;
    if (!solveStep(it)) {
      rep.status = hasConstraints ? "failed: the stiffness matrix or the constraint system could not be solved"
                                  : "failed: the stiffness matrix could not be factorised";
      break;
    }
    if (moved()) break;
  }
}

// The out-of-balance force at x into r; true when the iterations end here (converged, stalled at round-off, or
// not finite).
bool StaticSolve::balanced(int it) {
  elasticForces(model_, x, r);
  r += fext;  // out-of-balance force
  in_.project(r);
  if (hasConstraints && it > 0) r.noalias() += w.cons.transposedH() * w.cons.multipliers();
  rep.residual = r.norm() / scale;
  if (!std::isfinite(rep.residual)) return true;
  const double violation = hasConstraints ? w.cons.violation(x) : 0.0;
  if (rep.residual <= settings_.tolerance && (!hasConstraints || (it > 0 && violation <= 1e-9))) {
    rep.ok = true;
    return true;
  }
  // Round-off floor: an ill-conditioned system (slender elements, stiff materials under small loads)
  // cannot reduce the residual below ~eps * cond; three iterations without progress within 100x of the
  // tolerance are accepted, and the status says so.
  stalled = rep.residual > 0.9 * previousResidual ? stalled + 1 : 0;
  previousResidual = std::min(previousResidual, rep.residual);
  if (stalled >= 3 && rep.residual <= 100 * settings_.tolerance && (!hasConstraints || violation <= 1e-9)) {
    rep.ok = true;
    roundOff = true;
    return true;
  }
  return false;
}

// The Newton move into dx; false when neither the tangent nor its projected and shifted forms could be solved.
bool StaticSolve::solveStep(int it) {
  // Solve for the total multipliers (none yet in the first iteration, when Ht may still have the size of
  // the previous solve's constraints).
  if (hasConstraints && it > 0) r.noalias() -= w.cons.transposedH() * w.cons.multipliers();
  bool solved = false;
  // Chord: the factor of an earlier static tangent (of this solve or the last one) while the residual
  // still at least halves per iteration; a fresh tangent otherwise, or when the lagged step is unusable.
  const bool chord = settings_.staticChord && settings_.solver == LinearSolverKind::Cholmod && w.chol->valid() &&
                     w.staticFactor == w.chol->factorisations() && rep.residual < 0.5 * residualBefore;
  residualBefore = rep.residual;
  if (chord) {
    const Eigen::VectorXd lambdaStart = w.cons.multipliers();
    solved = in_.solveConstrained(r, x, 1.0, dx, rep) && usableStep(dx);
    if (!solved) w.cons.multipliers() = lambdaStart;
  }
  if (!solved) buildTangent(false);
  if (!solved && settings_.solver == LinearSolverKind::Cholmod) {
    ++rep.factorisations;
    w.cons.invalidate();
    // Each attempt starts from the same multipliers (a failed one can leave them absurd).
    const Eigen::VectorXd lambdaStart = w.cons.multipliers();
    solved = factoriseWith(*w.chol, settings_, w.K) && in_.solveConstrained(r, x, 1.0, dx, rep) && usableStep(dx);
    if (!solved) {
      // Indefinite, or nearly singular (a step the organ cannot make): projected Newton, then diagonal
      // shifts (Levenberg-Marquardt) growing until the step is usable.
      buildTangent(true);
      solved = in_.factoriseShifted(w.K, rep, [&] {
        w.cons.multipliers() = lambdaStart;
        return in_.solveConstrained(r, x, 1.0, dx, rep) && usableStep(dx);
      });
    }
    if (solved) w.staticFactor = w.chol->factorisations();
  } else if (!solved) {
    solved = in_.solveLinear(w.K, r, dx);
    if (!solved) {
      Eigen::SparseMatrix<double> Ks = w.K;
      for (double shift = 1e-6 * Ks.diagonal().cwiseAbs().maxCoeff(); !solved && shift < 1e12; shift *= 10) {
        for (Eigen::Index i = 0; i < Ks.rows(); ++i)
          Ks.valuePtr()[model_.diagonalSlot[i]] = w.K.valuePtr()[model_.diagonalSlot[i]] + shift;
        solved = in_.solveLinear(Ks, r, dx);
      }
    }
    in_.project(dx);
  }
  return solved;
}

// The move along dx (a line search without constraints); true when it was below the caller's resolution.
bool StaticSolve::moved() {
  double t = 1.0;
  Eigen::VectorXd xn = x + dx;
  // Armijo on the potential; with constraints the constraint forces do work too, so the merit is the
  // residual norm instead.
  if (settings_.lineSearch && !hasConstraints) {
    const double e0 = potential(x);
    while ((!std::isfinite(potential(xn)) || potential(xn) > e0 + 1e-4 * t * (-r.dot(dx))) && t > 1e-4) {
      t *= 0.5;
      xn = x + t * dx;
    }
  }
  x = xn;
  ++rep.newtonIterations;
  // Moves below the caller's resolution: converged for its purpose (a registration needs micrometres,
  // not the force balance to round-off, and projected Newton converges only linearly).
  if (settings_.staticStepTolerance > 0 && t * dx.cwiseAbs().maxCoeff() < settings_.staticStepTolerance &&
      w.cons.violation(x) <= 1e-9) {
    rep.ok = true;
    smallStep = true;
    return true;
  }
  return false;
}

// The state and the status.
void StaticSolve::finish() {
  SimulationState& state = state_;
  if (rep.ok && x.allFinite()) {
    state.x = x;
    state.v.setZero();
    // Round-off: the residual stalled within 100x of the tolerance (the state is kept; the word says it is not under
    // it).
    in_.describe(state, true, !roundOff, settings_.tolerance, rep);
    if (rep.outcome == StepStatus::Converged)
      rep.status = smallStep
                       ? "converged (the last Newton move was below " + micrometres(settings_.staticStepTolerance) + ")"
                       : "converged";
    else if (rep.outcome == StepStatus::Inexact)
      rep.status = "inexact: stalled at round-off, relative residual " + figure(rep.residual) +
                   " within 100x the tolerance " + figure(settings_.tolerance);
    else if (rep.outcome == StepStatus::Inverted)
      rep.status = statusSentence(rep);
  } else {
    rep.ok = false;
    in_.describe(state, false, false, settings_.tolerance, rep);
    if (rep.status.empty())
      rep.status =
          "failed: not converged (relative residual " + std::to_string(rep.residual) + "); the state was rolled back";
  }
  if (hasConstraints) w.lambdaOut = w.cons.multipliers();
  w.refresh = true;  // the factor now holds the static tangent
}

}  // namespace detail

StepReport Integrator::solveStatic(SimulationState& state, const Eigen::VectorXd& extra) {
  const auto t0 = std::chrono::steady_clock::now();
  Work& w = *w_;
  // A static solve's factor changes between solves (each rebinding of a registration, each fresh tangent): the rows'
  // compliance in one solve of their columns, not node by node (ConstraintSolver::directColumns); steps keep theirs.
  struct Direct {
    ConstraintSolver& cons;
    explicit Direct(ConstraintSolver& c) : cons(c) { cons.directColumns = true; }
    ~Direct() { cons.directColumns = false; }
  } direct(w.cons);
  StepReport rep;
  if (const std::string problem = settingsProblem(settings_, !constraints_.empty()); !problem.empty()) {
    rep.status = "refused: " + problem;
    rep.outcome = StepStatus::Refused;
    return rep;
  }
  detail::StaticSolve solve(*this, state, extra, rep);
  solve.run();
  solve.finish();
  rep.energy = totalEnergy(state);
  rep.constraintViolation = w_->cons.violation(state.x);
  rep.wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

}  // namespace rehearse::simcore
