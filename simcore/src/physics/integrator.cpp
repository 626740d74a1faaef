#include <rehearse/simcore/integrator.hpp>

#include "integrator_work.hpp"

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
// Newton-Krylov: conjugate-gradient iterations per Newton iteration at most, and the count above which the lagged
// factor is taken as drifted (a recent factor needed 1-4 per Newton iteration in the grasp-pulls on the liver preset
// and the patient liver).
constexpr int kKrylovBudget = 40;
constexpr int kKrylovDrift = 2;
// Accelerated chord, asynchronous refresh: the slow iterations (not halving the residual) after which a step rebuilds
// the factor in itself once.
constexpr int kAndersonStall = 4;
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
  if (w_ && w_->request.job.valid()) w_->request.job.wait();  // it reads the model
}

int Integrator::symbolicAnalyses() const { return w_->chol->analyses() + w_->request.chol->analyses(); }
int Integrator::numericFactorisations() const {
  return w_->chol->factorisations() + w_->request.chol->factorisations();
}
const Eigen::VectorXd& Integrator::multipliers() const { return w_->lambdaOut; }
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
  bytes += w.cons.memoryBytes() + w.request.compliance.memoryBytes();
  bytes += (w.chol->factorEntries() + w.request.chol->factorEntries()) * (sizeof(double) + sizeof(int));
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

Integrator::Try Integrator::tryStep(Eigen::VectorXd& x, Eigen::VectorXd& v, double h, StepReport& rep) {
  Work& w = *w_;
  const double alpha = settings_.rayleighMass, beta = settings_.rayleighStiffness;
  const bool lagged = settings_.method != NewtonMethod::Exact && settings_.solver == LinearSolverKind::Cholmod;
  const bool hasConstraints = !attachmentConstraints_.empty() || !constraints_.empty();
  w.x0 = x;
  w.v0 = v;
  w.v = v;
  project(w.v);
  w.Mv0 = mass3_.cwiseProduct(w.v0);

  // The Newton matrix (1 + h alpha) M + h beta Kd + h^2 K into J: exact with Kd = K(x0); the lagged
  // methods use one lagged K for both (leaving K(x0) out of the damping Jacobian costs the exact method
  // many iterations: measured 6-9 instead of 2 per step on the liver preset).
  auto buildNewtonMatrix = [&](const Eigen::SparseMatrix<double>& K, Eigen::SparseMatrix<double>& J) {
    newtonMatrix(K, J, h);
  };
  auto refreshLagged = [&](const Eigen::VectorXd& at) { return refreshLaggedAt(at, h, rep); };
  if (lagged) {
    const bool stale = w.refresh || w.laggedStep != h || !w.chol->valid();
    if (stale || (w.drift && settings_.factorRefresh == FactorRefresh::Synchronous)) {
      if (!refreshLagged(w.x0)) {
        rep.status = "failed: the linear system could not be solved";
        return Try::Failed;
      }
    } else if (w.drift && !w.request.pending) {
      requestFactor(w.x0, h, rep);  // asynchronous or deferred: this step goes on with the old factor
      w.drift = false;
    }
  } else {
    assembleStiffness(model_, w.x0, w.Kd);
  }
  if (lagged && settings_.method == NewtonMethod::Linearised) {
    // Linearised implicit Euler (Baraff and Witkin; SOFA's EulerImplicit with one solve): the forces
    // linearised at x0, f(x0 + h v) ~ f(x0) - h K(x0) v, one solve with the lagged factorisation:
    //   J dv = -r0,  r0 = h a M v0 - h (f(x0) + g) + (h^2 + h b) K(x0) v0.
    // One pass over the elements gives f(x0) and K(x0) (matrix-free); the last step's end made it when it ended here.
    if (w.tangentEndValid && w.tangentEndAt.size() == w.x0.size() && w.tangentEndAt == w.x0) {
      std::swap(w.tangent0, w.tangentEnd);
      std::swap(w.f, w.forcesEnd);
    } else {
      prepareTangentState(model_, w.x0, w.tangent0, &w.f);
    }
    w.tangentEndValid = false;
    project(w.f);
    const double scale =
        std::max({w.Mv0.norm(), h * gravityForce_.norm(), h * w.f.norm(), h * 1e-2 * model_.lumpedMass.sum()});
    applyStiffness(model_, w.tangent0, w.v, w.tmp);
    w.r = (h * alpha) * mass3_.cwiseProduct(w.v) - h * (w.f + gravityForce_) + (h * h + h * beta) * w.tmp;
    project(w.r);
    w.tmp = -w.r;
    w.xt = w.x0 + h * w.v;
    if (hasConstraints) w.cons.multipliers().setZero(w.cons.size());
    if (!solveConstrained(w.tmp, w.xt, h, w.dv, rep) || !w.dv.allFinite()) {
      rep.status = "failed: the linear system could not be solved";
      w.refresh = true;
      return Try::Failed;
    }
    // How well the lagged matrix stood for J(x0) = (1 + h a) M + (h^2 + h b) K(x0): the residual of the
    // linearised equations with the exact matrix, relative to the scale; a large one refreshes the factor.
    auto applyJ0 = [&](const Eigen::VectorXd& in, Eigen::VectorXd& out) {
      applyStiffness(model_, w.tangent0, in, w.pk);
      out = (1 + h * alpha) * mass3_.cwiseProduct(in) + (h * h + h * beta) * w.pk;
      project(out);
    };
    auto linearisedResidual = [&] {
      applyJ0(w.dv, w.rn);
      w.rn += w.r;
      if (hasConstraints) w.rn.noalias() -= w.cons.transposedH() * w.cons.multipliers();
      project(w.rn);
      return w.rn.norm() / scale;
    };
    rep.residual = linearisedResidual();
    ++rep.newtonIterations;
    if (!(rep.residual <= settings_.refreshResidual)) w.drift = true;
    // A factor known to have drifted (its replacement is being built on the second thread) preconditions
    // conjugate gradients on the exact linearised matrix instead of standing for it (the asynchronous
    // preconditioner of Courtecuisse et al. 2014): used alone, a stale factor lets the step diverge. Each pass
    // solves J d = -rn by PCG, then corrects the multipliers' change with the lagged factor (carried, as the
    // lagged-pcg method does), until the linearised residual is under refreshResidual (or 4 passes).
    if (settings_.factorRefresh != FactorRefresh::Synchronous && w.request.pending) {
      for (int pass = 0; pass < 4 && std::isfinite(rep.residual) && rep.residual > settings_.refreshResidual; ++pass) {
        w.pr = -w.rn;
        const double bnorm = w.pr.norm();
        Eigen::VectorXd& d = w.vn;  // the correction (free part, then constrained)
        d.setZero();
        if (!w.chol->solve(w.pr, w.pz)) break;
        project(w.pz);
        w.pp = w.pz;
        double rz = w.pr.dot(w.pz);
        int k = 0;
        for (; k < settings_.cgMaxIterations && w.pr.norm() > 1e-3 * settings_.refreshResidual * bnorm; ++k) {
          applyJ0(w.pp, w.pq);
          const double a = rz / w.pp.dot(w.pq);
          d += a * w.pp;
          w.pr -= a * w.pq;
          if (!w.chol->solve(w.pr, w.pz)) break;
          project(w.pz);
          const double rzn = w.pr.dot(w.pz);
          w.pp = w.pz + (rzn / rz) * w.pp;
          rz = rzn;
        }
        rep.innerIterations += k;
        if (hasConstraints) {
          // The constraints at the corrected velocities, the multipliers so far carried (their forces are in rn).
          w.lambdaCarried = w.cons.multipliers();
          w.xt = w.x0 + h * (w.v + w.dv);
          if (!solveConstrained(w.tmp, w.xt, h, d, rep, true, &w.lambdaCarried)) break;
        }
        w.dv += d;
        rep.residual = linearisedResidual();
      }
    }
    w.v += w.dv;
    if (!std::isfinite(rep.residual) || !w.v.allFinite()) {
      rep.status = "failed: the state became NaN or infinite";
      w.refresh = true;
      return Try::Failed;
    }
    // Elements of the laws not defined inverted keep their floor: the nodes of those that would not are stopped.
    if (guardMove(w.x0, w.v, h)) rep.inversionLimited = true;
    v = w.v;
    x = w.x0 + h * w.v;
    w.forcesValid = false;
    if (hasConstraints) w.lambdaOut = w.cons.multipliers() / h;
    // The residual of the nonlinear equations at the step's end (the Newton methods' residual), net of the
    // constraint forces: one pass over the elements at x, which the next step starting here reuses.
    prepareTangentState(model_, x, w.tangentEnd, &w.forcesEnd);
    w.tangentEndAt = x;
    w.tangentEndValid = true;
    if (beta == 0)
      w.tmp.setZero();
    else
      applyStiffness(model_, w.tangent0, w.v, w.tmp);
    w.rn = (1 + h * alpha) * mass3_.cwiseProduct(w.v) - w.Mv0 - h * (w.forcesEnd + gravityForce_) + (h * beta) * w.tmp;
    if (hasConstraints && w.cons.multipliers().size() == w.cons.transposedH().cols() &&
        w.cons.transposedH().rows() == w.rn.size())
      w.rn.noalias() -= w.cons.transposedH() * w.cons.multipliers();
    project(w.rn);
    rep.residual = w.rn.norm() / scale;
    if (!std::isfinite(rep.residual)) {
      rep.status = "failed: the state became NaN or infinite";
      w.refresh = true;
      w.tangentEndValid = false;
      return Try::Failed;
    }
    return rep.residual <= settings_.linearisedTolerance ? Try::Converged : Try::Inexact;
  }
  // The first iterate (the last step's velocity) is shortened when it would invert guarded elements, as every
  // Newton move below is: the iterates never invert an element that was not inverted at the step's start.
  if (guardMove(w.x0, w.v, h)) rep.inversionLimited = true;
  // Newton-Krylov: the residual's pass over the elements also prepares the tangent at the iterate (matrix-free).
  const bool krylov = lagged && settings_.method == NewtonMethod::NewtonKrylov;
  // With Rayleigh damping the lagged methods need the tangent at each step's start, which is the last step's last
  // iterate: their residual prepares it too (a tenth more per pass, one pass of the element rotations less per step).
  const bool prepareInResidual = krylov || (lagged && beta != 0);
  // Rayleigh damping with the stiffness at the start of the step (every method: the same residual);
  // the lagged methods have no K(x0) matrix and take the product matrix-free. The last step ended here with the
  // tangent prepared at its last iterate, which is this step's start: that pass is reused.
  if (beta != 0 && lagged) {
    if (w.tangentItValid && w.tangentItAt.size() == w.x0.size() && w.tangentItAt == w.x0)
      std::swap(w.tangent0, w.tangentIt);
    else
      prepareTangentState(model_, w.x0, w.tangent0);
  }
  w.tangentItValid = false;
  // Residual of the velocity update, momentum units: (1 + h a) M v - M v0 - h (f(x0 + h v) + g) + h b K(x0) v.
  auto residual = [&](const Eigen::VectorXd& vel, Eigen::VectorXd& out) {
    w.xt = w.x0 + h * vel;
    if (prepareInResidual) {
      prepareTangentState(model_, w.xt, w.tangentIt, &w.f);
      w.tangentItAt = w.xt;
      w.tangentItValid = true;
    } else {
      elasticForces(model_, w.xt, w.f);
    }
    if (beta == 0)
      w.tmp.setZero();
    else if (lagged)
      applyStiffness(model_, w.tangent0, vel, w.tmp);
    else
      w.tmp.noalias() = w.Kd * vel;
    out = (1 + h * alpha) * mass3_.cwiseProduct(vel) - w.Mv0 - h * (w.f + gravityForce_) + (h * beta) * w.tmp;
    project(out);
  };
  // The incremental potential whose gradient is the residual:
  //   Phi(v) = (1 + h a)/2 v.Mv - v.M v0 + E(x0 + h v) - h g.v + h b/2 v.K(x0) v.
  auto potential = [&](const Eigen::VectorXd& vel) {
    w.xt = w.x0 + h * vel;
    if (beta == 0)
      w.pk.setZero();
    else if (lagged)
      applyStiffness(model_, w.tangent0, vel, w.pk);
    else
      w.pk.noalias() = w.Kd * vel;
    return 0.5 * (1 + h * alpha) * vel.dot(mass3_.cwiseProduct(vel)) - vel.dot(w.Mv0) + elasticEnergy(model_, w.xt) -
           h * gravityForce_.dot(vel) + 0.5 * h * beta * vel.dot(w.pk);
  };
  // Norm of the residual net of the constraint forces (the total multipliers of the last solve).
  auto netNorm = [&](const Eigen::VectorXd& res) {
    if (!hasConstraints || w.cons.multipliers().size() != w.cons.transposedH().cols() ||
        w.cons.transposedH().rows() != res.size())
      return res.norm();
    w.pq = res;
    w.pq.noalias() -= w.cons.transposedH() * w.cons.multipliers();
    return w.pq.norm();
  };
  // Residual scale: momentum, load and internal forces at the start, with a floor (an acceleration of
  // 0.01 m/s^2 of the whole body) so a body at rest without load still has a meaningful tolerance.
  if (w.forcesValid && w.forcesAt.size() == w.x0.size() && w.forcesAt == w.x0) {
    w.f = w.forces;  // the last step ended here
  } else {
    elasticForces(model_, w.x0, w.f);
    project(w.f);
  }
  const double scale =
      std::max({w.Mv0.norm(), h * gravityForce_.norm(), h * w.f.norm(), h * 1e-2 * model_.lumpedMass.sum()});
  if (hasConstraints) w.cons.multipliers().setZero(w.cons.size());
  residual(w.v, w.r);
  double rn = w.r.norm();
  const int maxIterations = settings_.method == NewtonMethod::Linearised && lagged ? 1
                            : lagged ? std::max(settings_.maxNewtonIterations, 30)
                                     : settings_.maxNewtonIterations;
  bool ok = false;
  bool dampingProjected = false;
  // Anderson acceleration of the chord iteration (SimulationSettings::chordAcceleration): the chord map
  // v -> v + dv(v), dv = P^-1 (-r(v)) with the lagged factor P, is a fixed-point iteration whose contraction is poor
  // when P is far from the tangent (a tear, a new contact); mixing its last corrections (type II: the combination of
  // the last iterates' images whose corrections combine to the smallest one, Walker and Ni 2011) recovers what a
  // Krylov method would from the same solves, at the cost of a few inner products. The multipliers are mixed with the
  // same weights (each plain iterate meets the constraints' linear equations; an affine combination does too).
  const bool accelerate = lagged && settings_.method == NewtonMethod::Chord && settings_.chordAcceleration;
  int slowIterations = 0;    // accelerated: iterations that did not halve the residual
  bool rebuiltHere = false;  // accelerated, asynchronous: the factor was rebuilt in this step once already
  Work::Anderson& aa = w.anderson;
  aa.reset();
  if (accelerate) aa.size(w.v.size(), w.cons.multipliers().size());
  auto andersonMix = [&]() -> bool {
    // The multipliers are mixed with the velocities (their count is the constraints', fixed within a step).
    if (w.cons.multipliers().size() != aa.mu.size()) return false;
    const bool withMu = aa.mu.size() > 0;
    aa.plainDv = w.dv;
    if (withMu) aa.plainMu = w.cons.multipliers();
    w.vn = w.v + w.dv;  // g
    if (aa.havePrevious) {
      const int slot = aa.next;
      aa.dG[slot] = w.vn - aa.g;
      aa.dF[slot] = w.dv - aa.f;
      if (withMu) aa.dMu[slot] = w.cons.multipliers() - aa.mu;
      aa.next = (slot + 1) % Work::Anderson::kDepth;
      aa.count = std::min(aa.count + 1, Work::Anderson::kDepth);
    }
    aa.g = w.vn;
    aa.f = w.dv;
    aa.mu = w.cons.multipliers();
    aa.havePrevious = true;
    const int m = aa.count;
    if (m == 0) return false;
    aa.gram.resize(m, m);
    aa.rhs.resize(m);
    for (int i = 0; i < m; ++i) {
      for (int j = 0; j <= i; ++j) aa.gram(i, j) = aa.gram(j, i) = aa.dF[i].dot(aa.dF[j]);
      aa.rhs(i) = aa.dF[i].dot(w.dv);
    }
    // Tikhonov's small shift keeps nearly dependent differences from blowing the weights up.
    const double shift = 1e-12 * aa.gram.diagonal().sum() / m;
    if (!(shift > 0) || !std::isfinite(shift)) return false;
    aa.gram.diagonal().array() += shift;
    aa.gamma = Eigen::LDLT<decltype(aa.gram)>(aa.gram).solve(aa.rhs);
    if (!aa.gamma.allFinite()) return false;
    // v_next = g - dG gamma: the correction from v.
    for (int i = 0; i < m; ++i) {
      w.dv.noalias() -= aa.gamma(i) * aa.dG[i];
      if (withMu) w.cons.multipliers().noalias() -= aa.gamma(i) * aa.dMu[i];
    }
    return w.dv.allFinite();
  };
  for (int it = 0; it < maxIterations; ++it) {
    if (!std::isfinite(rn)) break;
    if (rn <= settings_.tolerance * scale && !(hasConstraints && it == 0)) {
      ok = true;
      break;
    }
    // J dv = -r + H^T mu, with mu the total multipliers (momentum units).
    w.tmp = -w.r;
    w.xt = w.x0 + h * w.v;
    bool solved = false;
    if (!lagged) {
      w.refresh = true;  // the factor holds this iteration's exact matrix, not a lagged one
      assembleStiffness(model_, w.xt, w.K);
      buildNewtonMatrix(w.K, w.J);
      if (settings_.solver == LinearSolverKind::Cholmod) {
        ++rep.factorisations;
        w.cons.invalidate();
        bool factorised = factoriseWith(*w.chol, settings_, w.J) && solveConstrained(w.tmp, w.xt, h, w.dv, rep);
        if (factorised) {
          solved = true;
        } else {
          // Indefinite tangent: projected Newton (element tangents clamped to PSD), then a diagonal shift.
          // The damping matrix K(x0) is projected too (an indefinite one would inject energy and leave the
          // incremental potential unbounded below); the residual follows it from here on.
          if (!dampingProjected && beta != 0) {
            assembleStiffness(model_, w.x0, w.Kd, true);
            dampingProjected = true;
            residual(w.v, w.r);
            rn = w.r.norm();
            w.tmp = -w.r;
          }
          assembleStiffness(model_, w.xt, w.K, true);
          buildNewtonMatrix(w.K, w.J);
          solved = factoriseShifted(w.J, rep) && solveConstrained(w.tmp, w.xt, h, w.dv, rep);
        }
      } else {
        solved = solveLinear(w.J, w.tmp, w.dv);
        project(w.dv);
      }
    } else if (krylov) {
      // Inexact Newton on J d = -r + H^T mu, J = (1 + h alpha) M + h beta K(x0) + h^2 K(x) applied matrix-free (the
      // tangent at x prepared with the residual): the lagged factor's constrained step first (feasible, and it
      // settles the active set and the multipliers), then conjugate gradients on the exact J with the constraint
      // preconditioner of that set (the lagged factor and its Schur complement: the iterates stay on the
      // constraints, the multipliers follow the exact tangent, and Newton keeps its quadratic convergence where a
      // lagged correction of the multipliers made it linear: 6-9 iterations per grasped step on the liver preset).
      // The solve stops at a forcing term of 0.1 x the relative residual, at most 1e-4 (the first iteration of a step
      // starts near 1, and a looser solve cost a third Newton iteration on the liver preset's grasp-pull), or at a
      // tenth of the tolerance, within a budget; a factor that needs more than two iterations has drifted and is
      // rebuilt (on the second thread when asynchronous).
      auto applyJ = [&](const Eigen::VectorXd& in, Eigen::VectorXd& out) {
        if (beta != 0) {
          applyStiffnessPair(model_, w.tangentIt, h * h, w.tangent0, h * beta, in, out);
        } else {
          applyStiffness(model_, w.tangentIt, in, out);
          out *= h * h;
        }
        out += (1 + h * alpha) * mass3_.cwiseProduct(in);
        project(out);
      };
      solved = solveConstrained(w.tmp, w.xt, h, w.dv, rep);
      const bool constrained = solved && hasConstraints && w.cons.fixActiveSet();
      auto netOf = [&](const Eigen::VectorXd& res, const Eigen::VectorXd& y) {
        if (!constrained) return res.norm();
        w.pn = res;
        w.pn.noalias() -= w.cons.transposedH() * y;
        return w.pn.norm();
      };
      int k = 0;
      if (solved) {
        applyJ(w.dv, w.pq);
        w.pr = w.tmp - w.pq;
        if (constrained) w.pr.noalias() += w.cons.transposedH() * w.cons.multipliers();
        project(w.pr);
        const double target =
            std::max(0.1 * settings_.tolerance * scale, std::min(1e-4, 0.1 * rn / scale) * std::max(rn, 1e-300));
        solved = w.cons.projectedSolve(*w.chol, w.pr, w.pz, w.py);
        double net = netOf(w.pr, w.py);
        w.pp = w.pz;
        double rz = w.pr.dot(w.pz);
        for (; solved && k < kKrylovBudget && net > target && rz > 0; ++k) {
          applyJ(w.pp, w.pq);
          const double a = rz / w.pp.dot(w.pq);
          w.dv += a * w.pp;
          w.pr -= a * w.pq;
          solved = w.cons.projectedSolve(*w.chol, w.pr, w.pz, w.py);
          net = netOf(w.pr, w.py);
          const double rzn = w.pr.dot(w.pz);
          w.pp = w.pz + (rzn / rz) * w.pp;
          rz = rzn;
        }
        // The set answers the last residual r = rhs + H^T mu - J d with the forces -H_a^T y: mu - y solves J d = rhs +
        // H^T mu.
        if (solved && constrained) w.cons.multipliers() -= w.py;
      }
      rep.innerIterations += k;
      if (k > kKrylovDrift) w.drift = true;  // the lagged factor has drifted: a new one at the next step's start
      project(w.dv);
    } else if (settings_.method == NewtonMethod::LaggedPcg) {
      // Exact tangent (1 + h alpha) M + h beta K(x0) + h^2 K(x), applied as products (K(x0) matrix-free,
      // K(x) assembled), CG preconditioned by the lagged factor.
      assembleStiffness(model_, w.xt, w.K);
      auto applyJ = [&](const Eigen::VectorXd& in, Eigen::VectorXd& out) {
        out.noalias() = (h * h) * (w.K * in);
        if (beta != 0) {
          applyStiffness(model_, w.tangent0, in, w.pk);
          out += (h * beta) * w.pk;
        }
        out += (1 + h * alpha) * mass3_.cwiseProduct(in);
        project(out);
      };
      w.dv.setZero();
      w.pr = w.tmp;
      // The constraint forces of the last iteration's multipliers go into the CG right-hand side (the exact
      // tangent answers them); the lagged factor then corrects only their change, which vanishes as Newton
      // converges. (With the lagged factor for the whole force, the step never satisfied the exact equations.)
      const bool carry = hasConstraints && w.cons.multipliers().size() == w.cons.transposedH().cols() &&
                         w.cons.transposedH().rows() == w.pr.size();
      if (carry) {
        w.pr.noalias() += w.cons.transposedH() * w.cons.multipliers();
        w.lambdaCarried = w.cons.multipliers();
      }
      const double bnorm = w.pr.norm();
      solved = w.chol->solve(w.pr, w.pz);
      w.pp = w.pz;
      double rz = w.pr.dot(w.pz);
      int k = 0;
      for (; solved && k < settings_.cgMaxIterations && w.pr.norm() > 1e-8 * bnorm; ++k) {
        applyJ(w.pp, w.pq);
        const double a = rz / w.pp.dot(w.pq);
        w.dv += a * w.pp;
        w.pr -= a * w.pq;
        solved = w.chol->solve(w.pr, w.pz);
        const double rzn = w.pr.dot(w.pz);
        w.pp = w.pz + (rzn / rz) * w.pp;
        rz = rzn;
      }
      rep.innerIterations += k;
      if (k > 20) w.drift = true;  // the lagged factor has drifted: rebuild it at the next step
      project(w.dv);
      // The constraint correction (of the multipliers' change) uses the lagged factor.
      if (solved && hasConstraints)
        solved = solveConstrained(w.tmp, w.xt, h, w.dv, rep, true, carry ? &w.lambdaCarried : nullptr);
    } else {
      solved = solveConstrained(w.tmp, w.xt, h, w.dv, rep);
    }
    if (!solved || !w.dv.allFinite()) {
      rep.status = "failed: the linear system could not be solved";
      break;
    }
    const bool mixed = accelerate && andersonMix();
    w.xt = w.x0 + h * w.v;
    bool guarded = guardMove(w.xt, w.dv, h);
    double t = 1.0;
    w.vn = w.v + w.dv;
    residual(w.vn, w.rn);
    double rnew = netNorm(w.rn);
    if (mixed && (guarded || !std::isfinite(rnew) || rnew > rn)) {
      // The mixed move did not lower the residual (or met the inversion guard): the plain chord move instead, and
      // the mixing starts again from it.
      w.dv = aa.plainDv;
      if (aa.plainMu.size() > 0 && aa.plainMu.size() == w.cons.multipliers().size())
        w.cons.multipliers() = aa.plainMu;
      aa.reset();
      aa.g = w.v + w.dv;
      aa.f = w.dv;
      aa.mu = w.cons.multipliers();
      aa.havePrevious = true;
      w.xt = w.x0 + h * w.v;
      guarded = guardMove(w.xt, w.dv, h);
      w.vn = w.v + w.dv;
      residual(w.vn, w.rn);
      rnew = netNorm(w.rn);
    }
    if (guarded) {
      rep.inversionLimited = true;
      aa.reset();  // a shortened move is not the chord map's: mix only unshortened ones
    }
    const bool searchable = settings_.lineSearch && !(settings_.method == NewtonMethod::Linearised && lagged);
    if (searchable && (!std::isfinite(rnew) || rnew > rn)) {
      // The full step does not reduce the residual. Without constraints the step minimises the
      // incremental potential Phi (its gradient is the residual): Armijo backtracking on Phi, which
      // accepts progress through non-convex regions where the residual norm rises.
      const double slope = w.r.dot(w.dv);
      if (!hasConstraints && slope < 0) {
        const double phi0 = potential(w.v);
        while (t > 1.0 / 1024) {
          const double phi = potential(w.vn);
          if (std::isfinite(phi) && phi <= phi0 + 1e-4 * t * slope) break;
          t *= 0.5;
          w.vn = w.v + t * w.dv;
        }
        residual(w.vn, w.rn);
        rnew = netNorm(w.rn);
      } else {
        while ((!std::isfinite(rnew) || rnew > rn) && t > 1.0 / 64) {
          t *= 0.5;
          w.vn = w.v + t * w.dv;
          residual(w.vn, w.rn);
          rnew = netNorm(w.rn);
        }
      }
    }
    const double previous = rn;
    w.v = w.vn;
    ++rep.newtonIterations;
    std::swap(w.r, w.rn);
    rn = rnew;
    // A lagged factor that no longer contracts the residual well is rebuilt here, at the current iterate: at once
    // when it halves the residual no more (the step waits for it), on the second thread already when it does not
    // divide it by ten (the steps go on meanwhile; on the liver preset's paced grasp-pull 3.1 iterations per step
    // instead of 5.0, and 2.7 instead of 4.7 on the patient liver at 16k tets: BENCHMARKS.md).
    const double contraction = settings_.factorRefresh != FactorRefresh::Synchronous ? 0.1 : 0.5;
    // Accelerated with the factor built on the second thread: a step whose iterations keep failing to halve the
    // residual (a factor from before a tear, moves the inversion guard keeps shortening) rebuilds it here once, rather
    // than running its 30 iterations and retrying at half the step (each retry a factorisation too).
    if (accelerate && rn > 0.5 * previous && rn > settings_.tolerance * scale) ++slowIterations;
    const bool stalled = accelerate && settings_.factorRefresh != FactorRefresh::Synchronous && !rebuiltHere &&
                         slowIterations >= kAndersonStall;
    if (lagged && settings_.method == NewtonMethod::Chord && rn > contraction * previous &&
        rn > settings_.tolerance * scale) {
      w.xt = w.x0 + h * w.v;
      if (stalled) {
        rebuiltHere = true;
        if (!refreshLagged(w.xt)) break;
        aa.reset();
      } else if (settings_.factorRefresh != FactorRefresh::Synchronous && w.chol->valid()) {
        requestFactor(w.xt, h, rep);  // built on the second thread; this step iterates on with the old factor
      } else if (!refreshLagged(w.xt)) {
        break;
      } else {
        aa.reset();  // another factor: another chord map
      }
    }
  }
  if (!ok && std::isfinite(rn) && rn <= settings_.tolerance * scale) ok = true;
  rep.residual = rn / scale;
  const bool finite = std::isfinite(rn) && w.v.allFinite();
  if (!finite) {
    ok = false;
    rep.status = "failed: the state became NaN or infinite";
  }
  if (ok || finite) {
    v = w.v;
    x = w.x0 + h * w.v;
    // The last residual evaluated the forces at x: the next step's scale reuses them.
    w.forcesValid = w.xt.size() == x.size() && w.xt == x;
    if (w.forcesValid) {
      w.forcesAt = x;
      w.forces = w.f;
      project(w.forces);
    }
  }
  if (!ok) {
    w.refresh = true;
    if (rep.status.empty()) rep.status = "not converged in " + std::to_string(maxIterations) + " Newton iterations";
  }
  if (hasConstraints) w.lambdaOut = w.cons.multipliers() / h;  // momentum per step -> force (N)
  return ok ? Try::Converged : finite ? Try::Inexact : Try::Failed;
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
  const std::string shortened = r.inversionLimited ? "; moves were shortened to keep elements from inverting" : "";
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

StepReport Integrator::step(SimulationState& state) {
  const auto t0 = std::chrono::steady_clock::now();
  Work& w = *w_;
  w.savedX = state.x;
  w.savedV = state.v;
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
  if (settings_.factorRefresh != FactorRefresh::Synchronous) swapInRequested(swap);
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
    double done = 0, worst = 0;
    Try outcome = Try::Converged;
    StepReport sub;
    while (done < settings_.timeStep * (1 - 1e-9)) {
      const double hh = std::min(h, settings_.timeStep - done);
      const Try t = tryStep(w.stepX, w.stepV, hh, sub);
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
    rep.inversionLimited = sub.inversionLimited;
    rep.residual = sub.residual;
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
