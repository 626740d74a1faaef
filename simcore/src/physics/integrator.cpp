#include <rehearse/simcore/integrator.hpp>

#include "integrator_work.hpp"
#include "newton_iteration.hpp"

#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>

#include <chrono>
#include <future>
#include <cstdio>
#include <cmath>
#include <limits>

namespace rehearse::simcore {

using namespace detail;

namespace {
// Runs a step's iterations through their one interface.
detail::NewtonIteration::Try iterate(detail::NewtonIteration&& iteration) { return iteration.run(); }
}  // namespace

NewtonMethod newtonMethodFromString(const std::string& name) {
  if (name == "exact") return NewtonMethod::Exact;
  if (name == "lagged-pcg") return NewtonMethod::LaggedPcg;
  if (name == "chord") return NewtonMethod::Chord;
  if (name == "linearised") return NewtonMethod::Linearised;
  if (name == "newton-krylov") return NewtonMethod::NewtonKrylov;
  throw MeshError("Unknown Newton method '" + name + "' (use exact, lagged-pcg, chord, linearised or newton-krylov).");
}

std::string toString(StepStatus s) {
  switch (s) {
    case StepStatus::Converged:
      return "converged";
    case StepStatus::Inexact:
      return "inexact";
    case StepStatus::Inverted:
      return "inverted";
    case StepStatus::Refused:
      return "refused";
    default:
      return "failed";
  }
}

std::string toString(NewtonMethod m) {
  switch (m) {
    case NewtonMethod::Exact:
      return "exact";
    case NewtonMethod::LaggedPcg:
      return "lagged-pcg";
    case NewtonMethod::Chord:
      return "chord";
    case NewtonMethod::NewtonKrylov:
      return "newton-krylov";
    default:
      return "linearised";
  }
}

std::string settingsProblem(const SimulationSettings& s, bool constrained) {
  if (!(s.volumeBarrier >= 0 && s.volumeBarrier < 1))
    return "The volume barrier is the volume ratio J below which a crushed element resists more: a number from 0 (off) "
           "up to, not including, 1.";
  if (s.solver == LinearSolverKind::Cholmod) return {};
  const char* name = s.solver == LinearSolverKind::ConjugateGradient ? "cg" : "dense";
  if (s.attachments == AttachmentMode::Lagrange || constrained)
    return std::string(
               "Constraints (Lagrange attachments, tool or fit constraints) are solved on CHOLMOD's factorisation, not "
               "with the ") +
           name + " solver; use the cholmod solver, or projected attachments without constraints.";
  if (s.method != NewtonMethod::Exact)
    return std::string("The ") + toString(s.method) + " method reuses CHOLMOD's factorisation; with the " + name +
           " solver use the exact method (or the cholmod solver).";
  return {};
}

Integrator::Integrator(const FemModel& model, std::vector<int> fixedNodes, SimulationSettings settings)
    : model_(model), fixed_(model.nodeCount(), 0), settings_(settings), w_(std::make_unique<Work>()) {
  if (const std::string problem = settingsProblem(settings, false); !problem.empty()) throw MeshError(problem);
  for (int n : fixedNodes) {
    if (n < 0 || n >= static_cast<int>(model.nodeCount()))
      throw MeshError("Fixed node " + std::to_string(n) + " does not exist (the mesh has " +
                      std::to_string(model.nodeCount()) + " nodes, numbered from 0).");
    if (settings.attachments == AttachmentMode::Projection) {
      fixed_[n] = 1;
    } else {
      for (int a = 0; a < 3; ++a) {
        ScalarConstraint c;
        c.nodes = {n, -1, -1, -1};
        c.weights = {1, 0, 0, 0};
        c.direction = Eigen::Vector3d::Unit(a);
        c.value = model.rest[n][a];
        attachmentConstraints_.push_back(c);
      }
    }
  }
  const auto n = static_cast<Eigen::Index>(model.nodeCount());
  mass3_.resize(3 * n);
  gravityForce_.resize(3 * n);
  for (Eigen::Index i = 0; i < n; ++i) {
    mass3_.segment<3>(3 * i).setConstant(model.lumpedMass[i]);
    gravityForce_.segment<3>(3 * i) = model.lumpedMass[i] * settings.gravity;
  }
  rest_ = model.restVector();
  gravityWorkAtRest_ = gravityForce_.dot(rest_);
  {
    Eigen::AlignedBox3d box;
    for (Eigen::Index i = 0; i + 2 < rest_.size(); i += 3) box.extend(rest_.segment<3>(i));
    organSize_ = box.isEmpty() ? 1.0 : std::max(box.diagonal().norm(), 1e-6);
  }
  Work& w = *w_;
  for (Eigen::VectorXd* vec : {&w.x0,  &w.v0,     &w.Mv0,    &w.v,     &w.vn,    &w.xt, &w.r,  &w.rn, &w.dv, &w.f,
                               &w.tmp, &w.savedX, &w.savedV, &w.stepX, &w.stepV, &w.pr, &w.pz, &w.pp, &w.pq, &w.pk})
    vec->setZero(3 * n);
  w.Kd = w.K = w.J = model.pattern;
  w.cons.setConstraints(attachmentConstraints_, fixed_);
}

Integrator::~Integrator() {
  if (!w_) return;
  // Their builds read the model.
  if (w_->request->job.valid()) w_->request->job.wait();
  for (auto& q : w_->abandoned)
    if (q->job.valid()) q->job.wait();
}

int Integrator::symbolicAnalyses() const {
  int n = w_->chol->analyses() + w_->request->chol->analyses();
  for (const auto& q : w_->abandoned) n += q->chol->analyses();
  return n;
}
int Integrator::numericFactorisations() const {
  int n = w_->chol->factorisations() + w_->request->chol->factorisations();
  for (const auto& q : w_->abandoned) n += q->chol->factorisations();
  return n;
}
const Eigen::VectorXd& Integrator::multipliers() const { return w_->lambdaOut; }
const Eigen::VectorXd& Integrator::errorMultipliers() const {
  static const Eigen::VectorXd none;
  return w_->errorLambdaValid ? w_->errorLambda : none;
}
const Eigen::MatrixXd& Integrator::constraintCompliance() const { return w_->cons.schur(); }

std::size_t Integrator::memoryBytes() const {
  const Work& w = *w_;
  std::size_t bytes = 0;
  for (const Eigen::VectorXd* v :
       {&w.x0, &w.v0,  &w.Mv0,    &w.v,      &w.vn,       &w.xt,     &w.r,           &w.rn,           &w.dv,
        &w.f,  &w.tmp, &w.savedX, &w.savedV, &w.stepX,    &w.stepV,  &w.pr,          &w.pz,           &w.pp,
        &w.pq, &w.pk,  &w.pn,     &w.py,     &w.forcesAt, &w.forces, &w.tangentItAt, &w.tangentEndAt, &w.forcesEnd})
    bytes += sizeof(double) * static_cast<std::size_t>(v->size());
  for (const Eigen::SparseMatrix<double>* m : {&w.Kd, &w.K, &w.J})
    bytes += static_cast<std::size_t>(m->nonZeros()) * (sizeof(double) + sizeof(int)) +
             static_cast<std::size_t>(m->outerSize() + 1) * sizeof(int);
  for (const TangentState* t : {&w.tangent0, &w.tangentIt, &w.tangentEnd})
    bytes += t->F.size() * (sizeof(Eigen::Matrix3d) + sizeof(TangentCache));
  bytes += w.cons.memoryBytes() + w.request->compliance.memoryBytes();
  bytes += (w.chol->factorEntries() + w.request->chol->factorEntries()) * (sizeof(double) + sizeof(int));
  for (const auto& q : w.abandoned)
    bytes += q->compliance.memoryBytes() + q->chol->factorEntries() * (sizeof(double) + sizeof(int));
  return bytes;
}

void Integrator::setConstraints(std::vector<ScalarConstraint> constraints) {
  if (const std::string problem = settingsProblem(settings_, !constraints.empty()); !problem.empty())
    throw MeshError(problem);
  std::vector<ScalarConstraint> all = attachmentConstraints_;
  all.insert(all.end(), constraints.begin(), constraints.end());
  w_->cons.setConstraints(std::move(all), fixed_);  // validates them (one sentence for a bad one)
  constraints_ = std::move(constraints);
}

void Integrator::invalidateFactorisation() {
  w_->refresh = true;
  w_->invalidated = true;
  w_->cons.invalidate();
  w_->tangentItValid = false;  // prepared with the parameters before the change
  w_->tangentEndValid = false;
}

SimulationState Integrator::initialState() const {
  SimulationState s;
  s.x = rest_;
  s.v = Eigen::VectorXd::Zero(s.x.size());
  return s;
}

void Integrator::project(Eigen::VectorXd& r) const {
  for (std::size_t i = 0; i < fixed_.size(); ++i)
    if (fixed_[i]) r.segment<3>(3 * i).setZero();
}

void Integrator::projectMatrix(Eigen::SparseMatrix<double>& A) const {
  // Fixed dofs: identity rows and columns, keeping the sparsity pattern (so the analysis is reused).
  for (int k = 0; k < A.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, k); it; ++it)
      if (fixed_[it.row() / 3] || fixed_[it.col() / 3]) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
}

bool Integrator::solveLinear(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, Eigen::VectorXd& y) {
  w_->cons.invalidate();
  w_->refresh = true;
  w_->chol->setSimplicial(settings_.simplicialFactor);
  return solveOnce(settings_.solver, A, b, y, *w_->chol, settings_.cgMaxIterations, settings_.cgTolerance);
}

bool Integrator::factoriseShifted(const Eigen::SparseMatrix<double>& A, StepReport& rep,
                                  const std::function<bool()>& accept) {
  w_->cons.invalidate();
  w_->chol->setSimplicial(settings_.simplicialFactor);
  return simcore::factoriseShifted(*w_->chol, A, model_.diagonalSlot, rep.factorisations, [&] {
    w_->cons.invalidate();  // each attempt is a new factor
    return !accept || accept();
  });
}

// Solves (factor) dx = rhs + H^T mu with H (x + s dx) = value for the constraints (constraint_solver.hpp),
// where s is the position scale of dx (h for velocities, 1 for positions). Without constraints:
// dx = A^-1 rhs. Uses the current factor (the caller made it); mu (total) ends in w.cons.multipliers().
bool Integrator::solveConstrained(const Eigen::VectorXd& rhs, const Eigen::VectorXd& x, double s, Eigen::VectorXd& dx,
                                  StepReport& rep, bool freeGiven, const Eigen::VectorXd* carried) {
  Work& w = *w_;
  if (!freeGiven && !w.chol->solve(rhs, dx)) return false;
  project(dx);
  w.cons.gaussSeidelIterations = settings_.gaussSeidelIterations;
  w.cons.gaussSeidelTolerance = settings_.gaussSeidelTolerance;
  return w.cons.solve(*w.chol, x, s, dx, rep.innerIterations, carried);
}

double Integrator::totalEnergy(const SimulationState& s) const {
  return 0.5 * s.v.dot(mass3_.cwiseProduct(s.v)) + elasticEnergy(model_, s.x) -
         (gravityForce_.dot(s.x) - gravityWorkAtRest_);
}

// One implicit Euler step of h from (x, v); on success x, v hold the new state.
void Integrator::newtonMatrix(const Eigen::SparseMatrix<double>& Kd, const Eigen::SparseMatrix<double>& K,
                              Eigen::SparseMatrix<double>& J, double h, double alpha, double beta) const {
  double* out = J.valuePtr();
  const double* kd = Kd.valuePtr();
  const double* k = K.valuePtr();
  for (Eigen::Index i = 0; i < J.nonZeros(); ++i) out[i] = h * beta * kd[i] + h * h * k[i];
  for (Eigen::Index i = 0; i < J.rows(); ++i) out[model_.diagonalSlot[i]] += (1 + h * alpha) * mass3_[i];
  projectMatrix(J);
}

void Integrator::newtonMatrix(const Eigen::SparseMatrix<double>& K, Eigen::SparseMatrix<double>& J, double h) const {
  newtonMatrix(w_->Kd, K, J, h, settings_.rayleighMass, settings_.rayleighStiffness);
}

// The step's driver: the step's start, its factor (lagged methods) or K(x0) (exact), then the iterations of the
// configured method (newton_iteration.hpp).
Integrator::Try Integrator::tryStep(Eigen::VectorXd& x, Eigen::VectorXd& v, double h, StepReport& rep) {
  Work& w = *w_;
  const bool lagged = settings_.method != NewtonMethod::Exact && settings_.solver == LinearSolverKind::Cholmod;
  const bool hasConstraints = !attachmentConstraints_.empty() || !constraints_.empty();
  w.x0 = x;
  w.v0 = v;
  w.v = w.useFirstIterate ? w.firstIterate : v;  // (an offline check starts Newton where a run ended)
  w.useFirstIterate = false;
  project(w.v);
  w.Mv0 = mass3_.cwiseProduct(w.v0);
  if (lagged) {
    const bool stale = w.refresh || w.laggedStep != h || !w.chol->valid();
    if (stale || (w.drift && settings_.factorRefresh == FactorRefresh::Synchronous)) {
      if (!refreshLaggedAt(w.x0, h, rep)) {
        rep.status = "failed: the linear system could not be solved";
        return Try::Failed;
      }
    } else if (w.drift && !w.request->pending) {
      requestFactor(w.x0, h, rep);  // asynchronous or deferred: this step goes on with the old factor
      w.drift = false;
    }
  } else {
    assembleStiffness(model_, w.x0, w.Kd);
  }
  detail::NewtonStep s{x, v, h, rep, lagged, hasConstraints};
  // Every method but exact runs on CHOLMOD's lagged factor; exact (and every method with the cg and dense solvers,
  // which settingsProblem refuses but for exact) factorises the tangent at each iteration.
  switch (lagged ? settings_.method : NewtonMethod::Exact) {
    case NewtonMethod::Linearised:
      return iterate(detail::LinearisedStep(*this, s));
    case NewtonMethod::LaggedPcg:
      return iterate(detail::LaggedPcgNewton(*this, s));
    case NewtonMethod::Chord:
      return iterate(detail::ChordNewton(*this, s));
    case NewtonMethod::NewtonKrylov:
      return iterate(detail::KrylovNewton(*this, s));
    default:
      return iterate(detail::ExactNewton(*this, s));
  }
}

bool Integrator::guardMove(const Eigen::VectorXd& x, Eigen::VectorXd& vel, double h) {
  if (!settings_.inversionGuard) return false;
  Work& w = *w_;
  // The floor of each guarded element: 10 % of its volume at the step's start, at least 1 % of its rest volume.
  const InversionFloor floor{&w.x0, 0.1, 0.01};
  bool changed = false;
  for (int round = 0; round < 4; ++round) {
    w.tmp = h * vel;
    const double s = inversionFreeStep(model_, x, w.tmp, floor, &w.limiting);
    if (s >= 1) return changed;
    changed = true;
    if (round == 3) {  // the stopped nodes keep involving new elements: the whole move is shortened instead
      vel *= s;
      return true;
    }
    // The nodes of the elements that would go below their floor stop; the rest of the organ moves on.
    for (int e : w.limiting)
      for (int n : model_.tets[e]) vel.segment<3>(3 * n).setZero();
  }
  return changed;
}

void Integrator::describe(const SimulationState& state, bool advanced, bool withinTolerance, double tolerance,
                          StepReport& rep) const {
  const VolumeRatios ratios = volumeRatios(model_, state.x);
  rep.invertedElements = ratios.inverted;
  rep.minVolumeRatio = ratios.smallest;
  rep.smallestElement = ratios.smallestElement;
  rep.tolerance = tolerance;
  if (!advanced) {
    rep.outcome = StepStatus::Failed;
    return;
  }
  // Only the word here (short strings allocate nothing): statusSentence() makes the sentence from the figures.
  if (ratios.inverted > 0) {
    rep.outcome = StepStatus::Inverted;
    rep.status = "inverted";
    for (const auto m : model_.model) {
      rep.collapsingLaw |= m == MaterialModel::StVK;
      rep.invertibleLaw |= m == MaterialModel::NeoHookean;
    }
  } else if (!withinTolerance) {
    rep.outcome = StepStatus::Inexact;
    rep.status = "inexact";
  } else {
    rep.outcome = StepStatus::Converged;
    rep.status = "converged";
  }
}

std::string statusSentence(const StepReport& r) {
  if (r.status != toString(r.outcome)) return r.status;  // a sentence of its own already
  if (r.outcome == StepStatus::Converged) return r.status;
  const std::string residual =
      "relative residual " + figure(r.residual) + " above the tolerance " + figure(r.tolerance);
  const std::string shortened =
      r.guardStalled       ? "; moves were shortened to keep elements from inverting until they made no more progress"
      : r.inversionLimited ? "; moves were shortened to keep elements from inverting"
                           : "";
  const std::string kept = r.keptBestOf > 0
                               ? " (no attempt converged; kept the best of " + std::to_string(r.keptBestOf) +
                                     ", time step " + figure(r.timeStepUsed) + " s)"
                               : "";
  if (r.outcome == StepStatus::Inexact) return "inexact: " + residual + shortened + kept;
  if (r.outcome == StepStatus::Inverted)
    return "inverted: " + std::to_string(r.invertedElements) + (r.invertedElements == 1 ? " element" : " elements") +
           " inside out (smallest volume ratio " + figure(r.minVolumeRatio) + ", element " +
           std::to_string(r.smallestElement) + ")" + (r.residual > r.tolerance ? "; " + residual : std::string()) +
           shortened + kept +
           (r.collapsingLaw   ? "; the StVK law collapses under strong compression (its energy vanishes for a flat "
                                "element): use corotational or neohookean"
            : r.invertibleLaw ? "; the stable Neo-Hookean law is defined there and pushes them back"
                              : "");
  return r.status;
}

StepReport Integrator::step(SimulationState& state, bool swapIn) {
  const auto t0 = std::chrono::steady_clock::now();
  Work& w = *w_;
  w.savedX = state.x;
  w.savedV = state.v;
  w.useFirstIterate = state.firstIterate.size() == state.v.size() && state.v.size() > 0;
  if (w.useFirstIterate) w.firstIterate.swap(state.firstIterate);
  state.firstIterate.resize(0);
  StepReport rep;
  // Settings edited after construction are checked again: refused, never silently changed.
  if (const std::string problem = settingsProblem(settings_, !constraints_.empty()); !problem.empty()) {
    rep.status = "refused: " + problem;
    rep.outcome = StepStatus::Refused;
    return rep;
  }
  if (!adopt(state, rep)) {
    rep.status = "failed: the lagged factorisation of the restored state could not be rebuilt";
    record(state);
    return rep;
  }
  // A factor built on the second thread is swapped in at the first step start after it is ready (never
  // within a step: a replay installs it at the same step boundary, FactorRefresh::Deferred).
  StepReport swap;
  if (swapIn && settings_.factorRefresh != FactorRefresh::Synchronous) swapInRequested(swap);
  w.estimateThisStep = settings_.estimateErrorEvery <= 1 || w.stepsTaken % settings_.estimateErrorEvery == 0;
  ++w.stepsTaken;
  double h = settings_.timeStep;
  const bool linearised = settings_.method == NewtonMethod::Linearised && settings_.solver == LinearSolverKind::Cholmod;
  const double tolerance = linearised ? settings_.linearisedTolerance : settings_.tolerance;
  // The attempt with the smallest residual (its largest sub-step residual) among those that covered the step.
  double bestResidual = std::numeric_limits<double>::infinity();
  double bestH = h;
  StepReport best;
  int retries = 0;
  for (;; ++retries) {
    // Sub-steps of h until the full time step is covered; a sub-step that does not converge goes on from its
    // best iterate (unless strict), so the attempt can be kept when no smaller step converges either.
    w.stepX = w.savedX;
    w.stepV = w.savedV;
    double done = 0, worst = 0, worstError = 0;
    Try outcome = Try::Converged;
    StepReport sub;
    while (done < settings_.timeStep * (1 - 1e-9)) {
      const double hh = std::min(h, settings_.timeStep - done);
      sub.errorPosition = std::numeric_limits<double>::quiet_NaN();
      const Try t = tryStep(w.stepX, w.stepV, hh, sub);
      // The step's error: its sub-steps' largest (NaN when one was not estimated).
      worstError = std::isnan(sub.errorPosition) || std::isnan(worstError) ? std::numeric_limits<double>::quiet_NaN()
                                                                             : std::max(worstError, sub.errorPosition);
      if (t == Try::Failed || (t == Try::Inexact && settings_.strict && !linearised)) {
        outcome = Try::Failed;
        break;
      }
      if (t == Try::Inexact) outcome = Try::Inexact;
      worst = std::max(worst, sub.residual);
      done += hh;
    }
    sub.residual = outcome == Try::Failed ? sub.residual : worst;
    rep.newtonIterations = sub.newtonIterations;
    rep.factorisations = sub.factorisations;
    rep.factorRequested = sub.factorRequested;
    rep.factorSwapped = swap.factorSwapped;
    rep.innerIterations = sub.innerIterations;
    rep.eliminations = sub.eliminations;
    rep.inversionLimited = sub.inversionLimited;
    rep.guardStalled = sub.guardStalled;
    // A step taken in smaller steps solved other equations than the step's: it does not say it is within the accuracy
    // of the step's answer (a torn bar's halved step 0.24 mm from it, each half within 0.05 mm of its own).
    rep.withinAccuracy = sub.withinAccuracy && retries == 0;
    rep.residual = sub.residual;
    rep.errorPosition = outcome == Try::Failed ? std::numeric_limits<double>::quiet_NaN() : worstError;
    // A sub-step whose distance was found not knowable makes the whole step's not known.
    rep.errorUnknown = outcome != Try::Failed && sub.errorUnknown;
    rep.timeStepUsed = h;
    // The linearised method does one solve by design: its step is what it is (a retry would not be that method).
    if (outcome == Try::Converged || (outcome == Try::Inexact && linearised)) {
      state.x = w.stepX;
      state.v = w.stepV;
      state.time += settings_.timeStep;
      rep.ok = true;
      describe(state, true, outcome == Try::Converged, tolerance, rep);
      if (retries && rep.outcome == StepStatus::Converged)
        rep.status =
            "converged with time step " + std::to_string(h) + " s after " + std::to_string(retries) + " retries";
      break;
    }
    // A halved step that does not at least halve the residual will not converge by halving more: the best so far is
    // kept.
    const bool hopeless =
        outcome == Try::Inexact && !settings_.strict && std::isfinite(bestResidual) && worst > 0.5 * bestResidual;
    if (outcome == Try::Inexact && worst < bestResidual) {
      bestResidual = worst;
      bestH = h;
      w.bestX = w.stepX;
      w.bestV = w.stepV;
      best = rep;
    }
    if (retries >= settings_.maxRetries || hopeless) {
      if (std::isfinite(bestResidual)) {
        // No attempt converged: the one with the smallest residual is kept (the simulation goes on; the status
        // says how far from the equations it is).
        const int tried = retries + 1;
        rep = best;
        state.x = w.bestX;
        state.v = w.bestV;
        state.time += settings_.timeStep;
        rep.ok = true;
        rep.timeStepUsed = bestH;
        w.refresh = true;
        w.forcesValid = false;
        rep.keptBestOf = tried;
        describe(state, true, false, tolerance, rep);
      } else {
        state.x = w.savedX;  // rolled back
        state.v = w.savedV;
        rep.ok = false;
        const std::string why = sub.status.empty() ? "not converged" : sub.status;
        describe(state, false, false, tolerance, rep);
        rep.status = "failed: " + (why.rfind("failed: ", 0) == 0 ? why.substr(8) : why) +
                     (settings_.strict && std::isfinite(sub.residual)
                          ? " (relative residual " + std::to_string(sub.residual) + ", strict settings)"
                          : "") +
                     "; the step was rolled back";
      }
      break;
    }
    h *= 0.5;
  }
  rep.retries = retries;
  record(state);
  if (settings_.reportEnergy) rep.energy = totalEnergy(state);
  rep.constraintViolation = w_->cons.violation(state.x);
  rep.wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

}  // namespace rehearse::simcore
