// The Newton iterations of one implicit Euler step, one class per NewtonMethod (newton_iteration.hpp): the
// linearised step, the Newton loop they share, and the exact, lagged-pcg, chord and Newton-Krylov solves.
#include "newton_iteration.hpp"
#include "fem_patch.hpp"

#include <Eigen/SparseCholesky>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace rehearse::simcore::detail {

namespace {
// Newton-Krylov: conjugate-gradient iterations per Newton iteration at most, and the count above which the lagged
// factor is taken as drifted (a recent factor needed 1-4 per Newton iteration in the grasp-pulls on the liver preset
// and the patient liver).
constexpr int kKrylovBudget = 40;
constexpr int kKrylovDrift = 2;
// Accelerated chord, asynchronous refresh: the slow iterations (not halving the residual) after which a step rebuilds
// the factor in itself once.
constexpr int kAndersonStall = 4;
// Synchronous and accelerated: factors rebuilt at an iterate within one try, at most. After a tear on the patient liver
// (9,265 elements) each slow iteration rebuilt its factor: 12 and 13 factorisations in two steps of 1.9 and 2.0 s;
// capped, the mixed iterations on the kept factor converged after one retry at half the step (1.3 s each, the same
// error against exact Newton).
constexpr int kSyncRebuilds = 2;
// Held back by the inversion guard: this many guarded moves in a row, none lowering the residual below this share of
// the one before, end the step's iterations.
constexpr int kHeldBackIterations = 4;
// SimulationSettings::accuracyPosition: the largest contraction an estimate is trusted at (beyond, the iterations go on
// to the residual's tolerance), and the tool force resolved whatever its size (N).
constexpr double kAccuracyContraction = 0.9;
constexpr double kAccuracyForceFloor = 1e-3;
constexpr double kHeldBackProgress = 0.99;
// The verification (NewtonLoop::verify): conjugate gradients on the tangent at the iterate to this share of the residual,
// within this many iterations (each one solve with the factor and one product with the tangent).
constexpr double kVerifyForcing = 1e-5;
constexpr int kVerifyBudget = 40;
constexpr double kVerifyMargin = 0.8;
// The factor's estimate is checked on the tangent when the iterations contracted by more than this, or the factor was
// built more than this far (m, the largest node) from the step's start.
constexpr double kVerifyRho = 0.8;
constexpr double kStaleFactor = 5e-3;

// The factor's correction within this factor of the Newton correction: the factor stands for the tangent there.
constexpr double kVerifyAgree = 1.5;
// Newton's second correction (NewtonLoop::secondCorrection): solved on the tangent to this share of its residual; the
// iterate is in Newton's region, where a distance is given, when the second is at most this share of the first (Newton
// converging quadratically there); under this share of the accuracy asked it is not judged (both corrections at
// rounding's scale).
constexpr double kSecondForcing = 1e-3;
constexpr double kSecondRatio = 0.1;
constexpr double kSecondFloor = 1e-2;

// A contact left out of the set that the corrected positions press through by more than this share of the accuracy.
constexpr double kContactSlack = 0.1;

// SimulationSettings::localElimination: a chord move leaving more than this share of the residual before it, ...
constexpr double kEliminationTrigger = 0.25;
// ... with at least this share of its square on the free nodes among the 64 largest (the seeds; the patch is they and
// their free neighbours: without the neighbours the patch's solve moved the residual onto them, and the tail stayed) ...
constexpr double kEliminationShare = 0.5;
// ... is eliminated by at most this many iterations on the patch (its tangent factorised once), ended at a hundredth of
// the patch's first residual.
constexpr int kEliminationIterations = 8;
// With a factor built on the second thread, only once this many of the step's iterations have failed to halve the
// residual (ChordNewton's slow iterations): ungated, the window's variant slowed (median 70 ms instead of 31 on the patient
// liver's pull); gated at 2, p99 181 ms against 225 over five runs, but in three more runs 327 ms with two steps inexact.
constexpr int kEliminationAsyncGate = 2;
}  // namespace

NewtonIteration::NewtonIteration(Integrator& in, NewtonStep& s)
    : in_(in),
      s_(s),
      w(*in.w_),
      model_(in.model_),
      settings_(in.settings_),
      mass3_(in.mass3_),
      gravityForce_(in.gravityForce_),
      h(s.h),
      alpha(in.settings_.rayleighMass),
      beta(in.settings_.rayleighStiffness),
      lagged(s.lagged),
      hasConstraints(s.hasConstraints),
      rep(s.rep) {}

void NewtonIteration::estimateError(const Eigen::VectorXd& netResidual, const Eigen::VectorXd& xEnd) {
  w.errorLambdaValid = false;
  if (!settings_.estimateError || !w.estimateThisStep || settings_.solver != LinearSolverKind::Cholmod || !w.chol->valid() ||
      !netResidual.allFinite())
    return;
  // J d = -r + H^T dmu with H (xEnd + h d) = value: the correction one more iteration with this factor would make
  // (the multipliers so far carried, as the linearised step's correction carries them: their forces are in r).
  w.tmp = -netResidual;
  if (!w.chol->solve(w.tmp, w.errorDv)) return;
  project(w.errorDv);
  StepReport scratch;
  if (hasConstraints) {
    w.errorCarried = w.cons.multipliers();
    w.lambdaCarried = w.errorCarried;
    const bool solved = solveConstrained(w.tmp, xEnd, h, w.errorDv, scratch, true, &w.lambdaCarried);
    w.errorLambda = (w.cons.multipliers() - w.errorCarried) / h;  // momentum per step -> force (N)
    w.cons.multipliers() = w.errorCarried;                      // what the step computed, unchanged
    if (!solved || !w.errorLambda.allFinite()) return;
    w.errorLambdaValid = true;
  }
  double largest = 0;
  for (Eigen::Index i = 0; i + 2 < w.errorDv.size(); i += 3) largest = std::max(largest, w.errorDv.segment<3>(i).norm());
  rep.errorPosition = h * largest;
}

// ---- Linearised ----

NewtonIteration::Try LinearisedStep::run() {
  // Linearised implicit Euler (Baraff and Witkin; SOFA's EulerImplicit with one solve): the forces
  // linearised at x0, f(x0 + h v) ~ f(x0) - h K(x0) v, one solve with the lagged factorisation:
  //   J dv = -r0,  r0 = h a M v0 - h (f(x0) + g) + (h^2 + h b) K(x0) v0.
  prepare();
  w.tmp = -w.r;
  w.xt = w.x0 + h * w.v;
  if (hasConstraints) w.cons.multipliers().setZero(w.cons.size());
  if (!solveConstrained(w.tmp, w.xt, h, w.dv, rep) || !w.dv.allFinite()) {
    rep.status = "failed: the linear system could not be solved";
    w.refresh = true;
    return Try::Failed;
  }
  rep.residual = linearisedResidual();
  ++rep.newtonIterations;
  if (!(rep.residual <= settings_.refreshResidual)) w.drift = true;
  // A factor known to have drifted (its replacement is being built on the second thread) preconditions
  // conjugate gradients on the exact linearised matrix instead of standing for it (the asynchronous
  // preconditioner of Courtecuisse et al. 2014): used alone, a stale factor lets the step diverge.
  if (settings_.factorRefresh != FactorRefresh::Synchronous && w.request->pending) correctWithPcg();
  w.v += w.dv;
  if (!std::isfinite(rep.residual) || !w.v.allFinite()) {
    rep.status = "failed: the state became NaN or infinite";
    w.refresh = true;
    return Try::Failed;
  }
  // Elements of the laws not defined inverted keep their floor: the nodes of those that would not are stopped.
  if (guardMove(w.x0, w.v, h)) rep.inversionLimited = true;
  return finish();
}

// f(x0) and K(x0), the scale and the residual r0 of the linearised equations.
void LinearisedStep::prepare() {
  // One pass over the elements gives f(x0) and K(x0) (matrix-free); the last step's end made it when it ended here.
  if (w.tangentEndValid && w.tangentEndAt.size() == w.x0.size() && w.tangentEndAt == w.x0) {
    std::swap(w.tangent0, w.tangentEnd);
    std::swap(w.f, w.forcesEnd);
  } else {
    prepareTangentState(model_, w.x0, w.tangent0, &w.f);
  }
  w.tangentEndValid = false;
  project(w.f);
  s_.scale = std::max({w.Mv0.norm(), h * gravityForce_.norm(), h * w.f.norm(), h * 1e-2 * model_.lumpedMass.sum()});
  applyStiffness(model_, w.tangent0, w.v, w.tmp);
  w.r = (h * alpha) * mass3_.cwiseProduct(w.v) - h * (w.f + gravityForce_) + (h * h + h * beta) * w.tmp;
  project(w.r);
}

// How well the lagged matrix stood for J(x0) = (1 + h a) M + (h^2 + h b) K(x0): the residual of the
// linearised equations with the exact matrix, relative to the scale; a large one refreshes the factor.
void LinearisedStep::applyJ0(const Eigen::VectorXd& in, Eigen::VectorXd& out) {
  applyStiffness(model_, w.tangent0, in, w.pk);
  out = (1 + h * alpha) * mass3_.cwiseProduct(in) + (h * h + h * beta) * w.pk;
  project(out);
}

double LinearisedStep::linearisedResidual() {
  applyJ0(w.dv, w.rn);
  w.rn += w.r;
  if (hasConstraints) w.rn.noalias() -= w.cons.transposedH() * w.cons.multipliers();
  project(w.rn);
  return w.rn.norm() / s_.scale;
}

// Each pass solves J d = -rn by PCG, then corrects the multipliers' change with the lagged factor (carried, as the
// lagged-pcg method does), until the linearised residual is under refreshResidual (or 4 passes).
void LinearisedStep::correctWithPcg() {
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

// The step's end: the new state, and the residual of the nonlinear equations there.
NewtonIteration::Try LinearisedStep::finish() {
  s_.v = w.v;
  s_.x = w.x0 + h * w.v;
  w.forcesValid = false;
  if (hasConstraints) w.lambdaOut = w.cons.multipliers() / h;
  // The residual of the nonlinear equations at the step's end (the Newton methods' residual), net of the
  // constraint forces: one pass over the elements at x, which the next step starting here reuses.
  prepareTangentState(model_, s_.x, w.tangentEnd, &w.forcesEnd);
  w.tangentEndAt = s_.x;
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
  rep.residual = w.rn.norm() / s_.scale;
  estimateError(w.rn, s_.x);
  if (!std::isfinite(rep.residual)) {
    rep.status = "failed: the state became NaN or infinite";
    w.refresh = true;
    w.tangentEndValid = false;
    return Try::Failed;
  }
  return rep.residual <= settings_.linearisedTolerance ? Try::Converged : Try::Inexact;
}

// ---- The Newton loop ----

// With Rayleigh damping the lagged methods need the tangent at each step's start, which is the last step's last
// iterate: their residual prepares it too (a tenth more per pass, one pass of the element rotations less per step).
// Newton-Krylov: the residual's pass over the elements also prepares the tangent at the iterate (matrix-free).
NewtonLoop::NewtonLoop(Integrator& in, NewtonStep& s, bool krylov)
    : NewtonIteration(in, s),
      prepareInResidual_(krylov || (s.lagged && in.settings().rayleighStiffness != 0)),
      accuracy_(in.settings().accuracyPosition > 0) {}

NewtonIteration::Try NewtonLoop::run() {
  start();
  const int maxIterations = lagged ? std::max(settings_.maxNewtonIterations, 30) : settings_.maxNewtonIterations;
  bool ok = false;
  int heldBack = 0;  // guarded moves in a row that did not lower the residual
  for (int it = 0; it < maxIterations; ++it) {
    if (!std::isfinite(s_.rn)) break;
    if (s_.rn <= settings_.tolerance * s_.scale && !(hasConstraints && it == 0)) {
      ok = true;
      break;
    }
    // J dv = -r + H^T mu, with mu the total multipliers (momentum units).
    w.tmp = -w.r;
    w.xt = w.x0 + h * w.v;
    if (accuracy_ && hasConstraints) w.muBefore = w.cons.multipliers();
    if (!solve() || !w.dv.allFinite()) {
      rep.status = "failed: the linear system could not be solved";
      break;
    }
    double correction = 0;  // m: h times the largest node's correction
    if (accuracy_) {
      for (Eigen::Index i = 0; i + 2 < w.dv.size(); i += 3) correction = std::max(correction, w.dv.segment<3>(i).squaredNorm());
      correction = h * std::sqrt(correction);
      if (it > 0 && lastCorrection_ > 0) {
        correctionRatio_ = std::max(correctionRatio_, correction / lastCorrection_);
        ratioMeasured_ = true;
        beyondFirst_ = beyondFirst_ || it > 1;
      }
    }
    if (accuracy_ && it > 0 && withinAccuracy()) {
      ok = true;
      rep.withinAccuracy = true;
      break;
    }
    bool guarded = false;
    double rnew = move(guarded);
    if (guarded) rep.inversionLimited = true;
    const bool searched = settings_.lineSearch && (!std::isfinite(rnew) || rnew > s_.rn);
    if (searched) rnew = lineSearch(rnew, guarded);
    const double previous = s_.rn;
    w.v = w.vn;
    ++rep.newtonIterations;
    std::swap(w.r, w.rn);
    s_.rn = rnew;
    // Moves the inversion guard shortened without lowering the residual, several times running: the equations ask
    // for a shape the guard does not let the elements take (a clip or a shaft pressing nodes through their
    // neighbours). More iterations, new factors and halved steps did not change that (the phantom with clips and the
    // hook: 30 such iterations per attempt, two attempts, a second per step); the step ends here, inexact, and says so.
    heldBack = guarded && !(rnew < kHeldBackProgress * previous) ? heldBack + 1 : 0;
    if (settings_.heldBackStop && heldBack >= kHeldBackIterations) {
      rep.guardStalled = true;
      break;
    }
    // The contraction the accuracy's estimate divides by: the largest residual ratio of this step's plain moves (a
    // move shortened by the guard or the line search, or mixed with earlier ones, says nothing of the plain
    // correction's; before any plain one, none is known); a shortened move's correction is not compared with the next.
    lastCorrection_ = guarded || searched ? 0.0 : correction;
    const bool plain = accuracy_ && plainMove_ && !guarded && !searched;
    if (plain) contraction_ = std::max(measured_ ? contraction_ : 0.0, previous > 0 ? rnew / previous : 1.0);
    measured_ = measured_ || plain;
    if (!iterated(previous)) break;
  }
  return finish(ok, maxIterations);
}

// Issue 61: nonlinear elimination (Lanzkron, Rose and Wilkes 1996; Cai and Keyes 2002) of the few nodes that hold
// nearly all of the residual (a torn flap springing back, which the lagged factor does not hold): Newton on their own
// equations, the rest of the organ fixed where it is, each with the exact (projected) tangent of what touches them.
bool NewtonLoop::eliminate(Eigen::VectorXd& vel, Eigen::VectorXd& res, double& rnorm) {
  const Eigen::Index n = res.size() / 3;
  Eigen::VectorXd net = res;
  if (hasConstraints && w.cons.multipliers().size() == w.cons.transposedH().cols() &&
      w.cons.transposedH().rows() == net.size())
    net.noalias() -= w.cons.transposedH() * w.cons.multipliers();
  std::vector<char> excluded(static_cast<std::size_t>(n), 0);
  for (Eigen::Index i = 0; i < n; ++i) excluded[static_cast<std::size_t>(i)] = fixedNode(static_cast<std::size_t>(i));
  for (const ScalarConstraint& c : w.cons.constraints())
    for (int k = 0; k < 4; ++k)
      if (c.nodes[k] >= 0 && c.weights[k] != 0) excluded[static_cast<std::size_t>(c.nodes[k])] = 1;
  std::vector<std::pair<double, int>> q(static_cast<std::size_t>(n));
  double total = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    q[static_cast<std::size_t>(i)] = {net.segment<3>(3 * i).squaredNorm(), static_cast<int>(i)};
    total += q[static_cast<std::size_t>(i)].first;
  }
  if (!(total > 0)) return false;
  const std::size_t top = std::min<std::size_t>(q.size(), 64);
  std::partial_sort(q.begin(), q.begin() + static_cast<std::ptrdiff_t>(top), q.end(),
                    [](const auto& a, const auto& b) { return a.first > b.first || (a.first == b.first && a.second < b.second); });
  detail::NodePatch p;
  double held = 0;
  for (std::size_t k = 0; k < top && held < 0.99 * total; ++k) {
    held += q[k].first;
    if (!excluded[static_cast<std::size_t>(q[k].second)]) p.nodes.push_back(q[k].second);
  }
  double seedShare = 0;
  for (int s : p.nodes) seedShare += net.segment<3>(3 * s).squaredNorm();
  if (p.nodes.empty() || seedShare < kEliminationShare * total) return false;
  // The seeds and their neighbours (free ones).
  {
    std::vector<char> seed(static_cast<std::size_t>(n), 0);
    for (int s : p.nodes) seed[static_cast<std::size_t>(s)] = 1;
    std::vector<char> taken = seed;
    for (const auto& t : model_.tets)
      if (seed[static_cast<std::size_t>(t[0])] || seed[static_cast<std::size_t>(t[1])] || seed[static_cast<std::size_t>(t[2])] ||
          seed[static_cast<std::size_t>(t[3])])
        for (int v : t)
          if (!taken[static_cast<std::size_t>(v)] && !excluded[static_cast<std::size_t>(v)]) {
            taken[static_cast<std::size_t>(v)] = 1;
            p.nodes.push_back(v);
          }
  }
  detail::completePatch(model_, p);
  const Eigen::Index m = 3 * static_cast<Eigen::Index>(p.nodes.size());
  const Eigen::VectorXd vBefore = vel, rBefore = res;
  const double rnBefore = rnorm;
  Eigen::VectorXd rB(m), fB, kv, d(m);
  auto localResidual = [&]() {
    w.xt = w.x0 + h * vel;
    detail::patchForces(model_, p, w.xt, fB);
    if (beta != 0 && lagged) detail::patchStiffnessProduct(model_, p, w.tangent0, vel, kv);
    for (std::size_t l = 0; l < p.nodes.size(); ++l) {
      const Eigen::Index g = 3 * p.nodes[l], i = 3 * static_cast<Eigen::Index>(l);
      rB.segment<3>(i) = (1 + h * alpha) * mass3_.segment<3>(g).cwiseProduct(vel.segment<3>(g)) - w.Mv0.segment<3>(g) -
                         h * (fB.segment<3>(i) + gravityForce_.segment<3>(g));
      if (beta != 0 && lagged) rB.segment<3>(i) += (h * beta) * kv.segment<3>(i);
    }
    return rB.norm();
  };
  double rb = localResidual();
  const double first = rb;
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::SparseMatrix<double> J(m, m);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  Eigen::VectorXd full(vel.size());
  int done = 0;
  for (int it = 0; it < kEliminationIterations; ++it) {
    if (rb <= 0.01 * first || rb <= 0.1 * settings_.tolerance * s_.scale) break;
    if (it == 0) {  // the tangent once: its later iterations are the patch's own chord
    trip.clear();
    for (std::size_t l = 0; l < p.nodes.size(); ++l)
      for (int k = 0; k < 3; ++k)
        trip.emplace_back(3 * static_cast<int>(l) + k, 3 * static_cast<int>(l) + k,
                          (1 + h * alpha) * mass3_(3 * p.nodes[l] + k));
    detail::patchStiffness(model_, p, w.xt, TangentProjection::Checked, h * h + h * beta, trip);
    J.setFromTriplets(trip.begin(), trip.end());
    ldlt.compute(J);
    if (ldlt.info() != Eigen::Success) break;
    }
    d = ldlt.solve(-rB);
    if (!d.allFinite()) break;
    full.setZero();
    for (std::size_t l = 0; l < p.nodes.size(); ++l) full.segment<3>(3 * p.nodes[l]) = d.segment<3>(3 * static_cast<Eigen::Index>(l));
    w.xt = w.x0 + h * vel;
    guardMove(w.xt, full, h);
    const Eigen::VectorXd vAt = vel;
    double t = 1;
    double rnew = 0;
    for (;;) {
      for (int g : p.nodes) vel.segment<3>(3 * g) = vAt.segment<3>(3 * g) + t * full.segment<3>(3 * g);
      rnew = localResidual();
      if (std::isfinite(rnew) && rnew < (1 - 1e-4 * t) * rb) break;
      t *= 0.5;
      if (t < 1.0 / 16) break;
    }
    if (!(std::isfinite(rnew) && rnew < rb)) {
      vel = vAt;
      rb = localResidual();
      break;
    }
    rb = rnew;
    ++done;
  }
  if (done == 0) {
    vel = vBefore;
    return false;
  }
  residual(vel, res);
  rnorm = netNorm(res);
  const bool better = std::isfinite(rnorm) && rnorm < rnBefore;
  if (!better) {
    vel = vBefore;
    res = rBefore;
    rnorm = rnBefore;
    return false;
  }
  return true;
}

// Issue 64: the iterate is within the accuracy asked in physical units (SimulationSettings::accuracyPosition,
// accuracyForce) when the correction just solved for at it (w.dv, the multipliers' change) divided by 1 - rho is: the
// corrections a fixed-point iteration contracting by rho still makes sum to that. rho is the largest of this step's
// residual ratios over its plain moves and of its corrections' ratios to the one before (largest node against largest
// node): the residual's ratio alone read 0.001 on the patient liver after a tear, where the first residual is mostly the
// step's new load, while the corrections shrank by 0.3-0.8 per iteration and the step ended 0.08-0.10 mm from exact
// Newton's answer with 0.05 mm asked (`rehearse replay --exact-check`). Both measured, or no estimate. The chord's rho is
// at least 0.5 until a ratio beyond the step's first is measured (NewtonLoop::rho): the first ratio is measured along the
// first move, the new load's direction, which the factor holds; on a torn bar swung on the grasper steps ending after
// one move read 0.003-0.01 there, contracted by about 0.6 along what was left, and ended 0.0139-0.0288 mm from the
// answer with 0.0069-0.0116 mm estimated (test_step_error aTearCheckedAgainstExactNewtonOffline, 1 run in 30-100).
// Never at a step's first iterate: its first correction is
// always taken (the holds' multipliers start from zero there, and a small load still moves the organ). Ending here,
// the correction is not applied: the iterate, its forces and residual are the step's end, its multipliers put back.
bool NewtonLoop::withinAccuracy() {
  if (!measured_ || !ratioMeasured_ || !(rho() <= kAccuracyContraction)) return false;
  const double gain = 1.0 / (1.0 - rho());
  double largest = 0;
  for (Eigen::Index i = 0; i + 2 < w.dv.size(); i += 3) largest = std::max(largest, w.dv.segment<3>(i).squaredNorm());
  if (!(gain * h * std::sqrt(largest) <= settings_.accuracyPosition)) return false;
  // The tool force by the residual's contraction alone (the corrections' ratio is the nodes': with it the force's
  // estimate rose to 11 times its truth on the liver preset's pull, and never needed it there or on the patient liver).
  const double forceGain = 1.0 / (1.0 - contraction_);
  const auto& rows = in_.constraints();
  if (hasConstraints && w.cons.multipliers().size() == w.muBefore.size()) {
    if (!rows.empty()) {
      w.muChange = w.cons.multipliers() - w.muBefore;
      const double force = toolForceOf(rows, w.cons.multipliers(), false).norm() / h;
      const double change = toolForceOf(rows, w.muChange, false).norm() / h;
      if (!(forceGain * change <= std::max(settings_.accuracyForce * force, kAccuracyForceFloor))) return false;
    }
    w.cons.multipliers() = w.muBefore;
  }
  return true;
}

// The factor's own estimate is not trusted: the iterations contracted slowly (the factor is far from the tangent), or the
// factor was built where the organ no longer is (a torn body's first factor is built where the tear began; its flap
// then springs away).
bool NewtonLoop::suspect() const {
  if (in_.verifyEveryEstimate() && w.estimateThisStep) return true;
  if ((measured_ && !(contraction_ <= kVerifyRho)) || (ratioMeasured_ && !(correctionRatio_ <= kVerifyRho))) return true;
  if (w.laggedAt.size() != w.x0.size()) return true;
  double far = 0;
  for (Eigen::Index i = 0; i + 2 < w.x0.size(); i += 3)
    far = std::max(far, (w.laggedAt.segment<3>(i) - w.x0.segment<3>(i)).squaredNorm());
  return far > kStaleFactor * kStaleFactor;
}

bool NewtonLoop::contactsChange() {
  const auto& rows = in_.constraints();
  const Eigen::VectorXd& mu = w.cons.multipliers();
  if (mu.size() < static_cast<Eigen::Index>(rows.size())) return false;
  const Eigen::Index first = mu.size() - static_cast<Eigen::Index>(rows.size());
  w.vn = w.xt + h * w.dv;  // the corrected positions (w.vn is the move's, made after this)
  double largest = 0;
  for (Eigen::Index i = first; i < mu.size(); ++i) largest = std::max(largest, std::abs(mu[i]));
  for (std::size_t k = 0; k < rows.size(); ++k) {
    if (!rows[k].unilateral) continue;
    const double m = mu[first + static_cast<Eigen::Index>(k)];
    if (m < -1e-9 * std::max(largest, 1e-300)) return true;
    if (m <= 0 && constraintValue(rows[k], w.vn) < rows[k].value - kContactSlack * settings_.accuracyPosition) return true;
  }
  return false;
}

// Issue 64: the correction exact Newton would make at the iterate, its largest node's (m) the iterate's distance from
// the step's answer: the lagged factor's constrained correction, refined by conjugate gradients on the tangent at the iterate preconditioned by the factor (the
// Newton-Krylov solve) to 1e-5 of the residual (at 1e-2 the correction was off by up to 2x on a torn bar: the tangent is
// ill-conditioned). Within: confirmed within the accuracy asked (the multipliers put back). Indefinite: a direction of
// non-positive curvature met (a torn flap, a buckling one). Unresolved: the contacts' problem was not solved or changes
// its set. Move: not confirmed; w.dv and the multipliers hold the Newton step there.
NewtonLoop::Verdict NewtonLoop::verify() {
  w.xt = w.x0 + h * w.v;
  w.tmp = -w.r;
  if (hasConstraints) w.muBefore = w.cons.multipliers();
  const int before = rep.innerIterations;
  if (!solveConstrained(w.tmp, w.xt, h, w.dv, rep) || !w.dv.allFinite()) return Verdict::Failed;
  const int sweeps = rep.innerIterations - before;
  // Unilateral rows (the shaft's contacts) whose Gauss-Seidel ran all its sweeps kept its best iterate, not a solution
  // (the active set that follows it failed too): the correction is not the equations' (a bar's torn piece against the
  // shaft: 600 sweeps in a step, its estimate 0.005 mm where exact Newton's answer was 0.18 mm away).
  bool unilateral = false;
  for (const auto& c : in_.constraints()) unilateral = unilateral || c.unilateral;
  if (unilateral && sweeps >= settings_.gaussSeidelIterations) return Verdict::Unresolved;
  if (!(w.tangentItValid && w.tangentItAt.size() == w.xt.size() && w.tangentItAt == w.xt)) {
    prepareTangentState(model_, w.xt, w.tangentIt);
    w.tangentItAt = w.xt;
    w.tangentItValid = true;
  }
  bool definite = true;
  double net = 0;
  int k = 0;
  const double target = kVerifyForcing * s_.rn;
  double chord = 0;  // m: the lagged factor's correction, before the refinement
  for (Eigen::Index i = 0; i + 2 < w.dv.size(); i += 3) chord = std::max(chord, w.dv.segment<3>(i).squaredNorm());
  chord = h * std::sqrt(chord);
  const bool solved = refineOnTangent(target, kVerifyBudget, true, definite, net, k);
  rep.innerIterations += k;
  project(w.dv);
  if (!solved || !w.dv.allFinite()) return Verdict::Failed;
  double largest = 0;
  for (Eigen::Index i = 0; i + 2 < w.dv.size(); i += 3) largest = std::max(largest, w.dv.segment<3>(i).squaredNorm());
  const double newton = h * std::sqrt(largest);
  verifiedEstimate_ = newton;
  bool forceWithin = true;
  w.errorLambdaValid = false;
  if (hasConstraints && w.cons.multipliers().size() == w.muBefore.size()) {
    w.muChange = w.cons.multipliers() - w.muBefore;
    w.errorLambda = w.muChange / h;  // momentum per step -> force (N)
    w.errorLambdaValid = w.errorLambda.allFinite();
    const auto& rows = in_.constraints();
    if (!rows.empty()) {
      const double force = toolForceOf(rows, w.cons.multipliers(), false).norm() / h;
      const double change = toolForceOf(rows, w.muChange, false).norm() / h;
      forceWithin = change <= std::max(settings_.accuracyForce * force, kAccuracyForceFloor);
    }
  }
  // The contacts' set was fixed at the iterate: a contact whose force turns to pulling, or one left out that the corrected
  // positions press through, says the answer lies across a change of contacts, where one Newton correction measures
  // nothing (a bar's torn piece sliding off the shaft: 0.011 mm estimated, exact Newton's answer 0.53 mm away).
  if (unilateral && contactsChange()) return Verdict::Unresolved;
  const bool resolved = definite && net <= target;
  if (!definite) return Verdict::Indefinite;
  // The Newton correction is the distance to first order where the factor's own correction agrees with it (the factor
  // stands for the tangent there); else it is reported, not confirmed. After a tear on the patient liver corrections of
  // 0.004-0.013 mm stood where the answer was 0.06-0.65 mm away, the factor's correction far from them.
  const bool region = chord <= kVerifyAgree * newton && newton <= kVerifyAgree * chord;
  // Newton's region: the second correction, at the iterate moved by the first, is far smaller than the first (Newton
  // converges quadratically there), and the corrections still to come sum to at most second / (1 - theta). Outside it
  // no sum of corrections bounds the distance, which is then not known. After a tear on the patient liver (a replay of
  // one run, 151 steps): steps whose first corrections were 0.004-0.017 mm, agreeing with the factor's, said they were
  // within 0.05 mm and were 0.06-0.47 mm from exact Newton's answer; their second corrections were 3-26 times the
  // first. Steps reported 0.06-0.07 mm away and 0.21-0.27 mm away had second corrections 0.15-0.47 times the first. In
  // the steps before the tear the second was 1e-6 to 1e-4 times the first.
  const double second = secondCorrection();
  if (!std::isfinite(second)) return Verdict::Failed;
  const double theta = second / std::max(newton, 1e-300);
  if (second > kSecondFloor * settings_.accuracyPosition) {
    if (!(theta <= kSecondRatio)) return Verdict::Far;
    verifiedEstimate_ = newton + second / (1 - theta);
  } else {
    verifiedEstimate_ = newton + 2 * second;
  }
  // A margin for the rest (a correction of 0.047 mm was 0.052 mm from exact Newton's answer after a tear, 0.05 asked).
  if (resolved && region && forceWithin && verifiedEstimate_ <= kVerifyMargin * settings_.accuracyPosition)
    return Verdict::Within;
  return Verdict::Move;
}

// Newton's second correction (m, the largest node's) at the iterate moved by the first (in w.dv, the multipliers updated
// with it), on the tangent there (prepared into a spare: the tangent at the step's end stays for the next step's
// start); w.dv and the iterate as they were. NaN: not solved, or the tangent there is indefinite.
double NewtonLoop::secondCorrection() {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  w.pk = w.dv;
  std::swap(w.tangentIt, w.tangentSpare);
  w.vn = w.v + w.dv;
  residual(w.vn, w.rn);
  if (!prepareInResidual_) prepareTangentState(model_, w.xt, w.tangentIt);
  w.tmp = -w.rn;
  const double target = kSecondForcing * netNorm(w.rn);
  bool solved = solveConstrained(w.tmp, w.xt, h, w.dv, rep) && w.dv.allFinite();
  bool definite = true;
  double net = 0;
  int k = 0;
  if (solved) solved = refineOnTangent(target, kVerifyBudget, true, definite, net, k) && w.dv.allFinite();
  solved = solved && definite;  // an indefinite tangent there: Newton's region is not known either
  rep.innerIterations += k;
  project(w.dv);
  double largest = 0;
  for (Eigen::Index i = 0; i + 2 < w.dv.size(); i += 3) largest = std::max(largest, w.dv.segment<3>(i).squaredNorm());
  std::swap(w.tangentIt, w.tangentSpare);
  w.xt = w.x0 + h * w.v;  // the step's end again, as verify() made it (into the buffers: nothing allocated in a step)
  w.tangentItAt = w.xt;
  w.tangentItValid = true;
  w.dv = w.pk;
  return solved ? h * std::sqrt(largest) : nan;
}

// The first iterate, the damping tangent at the step's start, the residual's scale and the first residual.
void NewtonLoop::start() {
  // The first iterate (the last step's velocity) is shortened when it would invert guarded elements, as every
  // Newton move below is: the iterates never invert an element that was not inverted at the step's start.
  if (guardMove(w.x0, w.v, h)) rep.inversionLimited = true;
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
  // Residual scale: momentum, load and internal forces at the start, with a floor (an acceleration of
  // 0.01 m/s^2 of the whole body) so a body at rest without load still has a meaningful tolerance.
  if (w.forcesValid && w.forcesAt.size() == w.x0.size() && w.forcesAt == w.x0) {
    w.f = w.forces;  // the last step ended here
  } else {
    elasticForces(model_, w.x0, w.f);
    project(w.f);
  }
  s_.scale = std::max({w.Mv0.norm(), h * gravityForce_.norm(), h * w.f.norm(), h * 1e-2 * model_.lumpedMass.sum()});
  if (hasConstraints) w.cons.multipliers().setZero(w.cons.size());
  residual(w.v, w.r);
  s_.rn = w.r.norm();
  started();
}

// Residual of the velocity update, momentum units: (1 + h a) M v - M v0 - h (f(x0 + h v) + g) + h b K(x0) v.
void NewtonLoop::residual(const Eigen::VectorXd& vel, Eigen::VectorXd& out) {
  w.xt = w.x0 + h * vel;
  if (prepareInResidual_) {
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
}

// The incremental potential whose gradient is the residual:
//   Phi(v) = (1 + h a)/2 v.Mv - v.M v0 + E(x0 + h v) - h g.v + h b/2 v.K(x0) v.
double NewtonLoop::potential(const Eigen::VectorXd& vel) {
  w.xt = w.x0 + h * vel;
  if (beta == 0)
    w.pk.setZero();
  else if (lagged)
    applyStiffness(model_, w.tangent0, vel, w.pk);
  else
    w.pk.noalias() = w.Kd * vel;
  return 0.5 * (1 + h * alpha) * vel.dot(mass3_.cwiseProduct(vel)) - vel.dot(w.Mv0) + elasticEnergy(model_, w.xt) -
         h * gravityForce_.dot(vel) + 0.5 * h * beta * vel.dot(w.pk);
}

// Norm of the residual net of the constraint forces (the total multipliers of the last solve).
double NewtonLoop::netNorm(const Eigen::VectorXd& res) {
  if (!hasConstraints || w.cons.multipliers().size() != w.cons.transposedH().cols() ||
      w.cons.transposedH().rows() != res.size())
    return res.norm();
  w.pq = res;
  w.pq.noalias() -= w.cons.transposedH() * w.cons.multipliers();
  return w.pq.norm();
}

double NewtonLoop::move(bool& guarded) {
  w.xt = w.x0 + h * w.v;
  guarded = guardMove(w.xt, w.dv, h);
  w.vn = w.v + w.dv;
  residual(w.vn, w.rn);
  return netNorm(w.rn);
}

// The full step does not reduce the residual (rnew: its net norm). The step minimises the incremental potential Phi
// (its gradient is the residual) on the set the constraints allow: Armijo backtracking on Phi, which accepts progress
// through non-convex regions where the residual norm rises. With constraints, on Phi plus the constraints' violation
// weighted past the largest multiplier (an exact penalty, Nocedal and Wright 2006, section 15.4): the correction,
// solved with a positive definite factor on the constraints' linearisation, descends on it. Backtracking on the
// residual's norm instead stalled the phantom after clips and a cut (a correction 64 times shortened, the residual
// still rising 2-4 % an iteration, 30 iterations twice: 35 attempts of 0.24-0.29 s in one run of test_appearance_gui,
// none after). A move the inversion guard shortened (some nodes' corrections dropped) is not that correction: there,
// and where the merit does not descend, the residual's norm is backtracked on as before.
double NewtonLoop::lineSearch(double rnew, bool guarded) {
  double t = 1.0;
  const double slope = w.r.dot(w.dv);
  auto backtrack = [&](auto&& merit, double m0, double descent) {
    while (t > 1.0 / 1024) {
      const double m = merit(w.vn);
      if (std::isfinite(m) && m <= m0 + 1e-4 * t * descent) break;
      t *= 0.5;
      w.vn = w.v + t * w.dv;
    }
    residual(w.vn, w.rn);
    return netNorm(w.rn);
  };
  if (!hasConstraints) {
    if (slope < 0) return backtrack([&](const Eigen::VectorXd& vel) { return potential(vel); }, potential(w.v), slope);
  } else if (!guarded && w.cons.multipliers().size() == w.cons.size()) {
    const double nu = 2.0 * (w.cons.size() > 0 ? w.cons.multipliers().cwiseAbs().maxCoeff() : 0.0) / h;
    auto violation = [&](const Eigen::VectorXd& vel) {
      w.xt = w.x0 + h * vel;
      double sum = 0;
      for (const ScalarConstraint& c : w.cons.constraints()) {
        const double g = constraintValue(c, w.xt) - c.value;
        sum += c.unilateral ? std::max(0.0, -g) : std::abs(g);
      }
      return sum;
    };
    const double violated = violation(w.v);
    // The merit's slope along the correction, which meets the constraints' linearisation: Phi's, less the violation.
    const double descent = slope - nu * violated;
    if (std::isfinite(nu) && descent < 0)
      return backtrack([&](const Eigen::VectorXd& vel) { return potential(vel) + nu * violation(vel); },
                       potential(w.v) + nu * violated, descent);
  }
  while ((!std::isfinite(rnew) || rnew > s_.rn) && t > 1.0 / 64) {
    t *= 0.5;
    w.vn = w.v + t * w.dv;
    residual(w.vn, w.rn);
    rnew = netNorm(w.rn);
  }
  return rnew;
}

// The step's end: converged, or inexact with the last iterate, or failed (x and v unchanged).
NewtonIteration::Try NewtonLoop::finish(bool ok, int maxIterations) {
  const double rn = s_.rn, scale = s_.scale;
  if (!ok && std::isfinite(rn) && rn <= settings_.tolerance * scale) ok = true;
  rep.residual = rn / scale;
  const bool finite = std::isfinite(rn) && w.v.allFinite();
  if (!finite) {
    ok = false;
    rep.status = "failed: the state became NaN or infinite";
  }
  if (ok || finite) {
    s_.v = w.v;
    s_.x = w.x0 + h * w.v;
    // The last residual evaluated the forces at x: the next step's scale reuses them.
    w.forcesValid = w.xt.size() == s_.x.size() && w.xt == s_.x;
    if (w.forcesValid) {
      w.forcesAt = s_.x;
      w.forces = w.f;
      project(w.forces);
    }
  }
  if (!ok) {
    w.refresh = true;
    if (rep.status.empty()) rep.status = "not converged in " + std::to_string(maxIterations) + " Newton iterations";
  }
  if (hasConstraints) w.lambdaOut = w.cons.multipliers() / h;  // momentum per step -> force (N)
  if (finite) {
    // The residual at the last iterate net of the constraint forces (as the loop judged it).
    w.pq = w.r;
    if (hasConstraints && w.cons.multipliers().size() == w.cons.transposedH().cols() &&
        w.cons.transposedH().rows() == w.pq.size())
      w.pq.noalias() -= w.cons.transposedH() * w.cons.multipliers();
    estimateError(w.pq, s_.x);
    // With the accuracy asked, the estimate is the remaining corrections' sum, as the step was ended on: the next
    // correction divided by one minus the contraction this step showed.
    if (accuracy_ && measured_ && rho() < 1 && std::isfinite(rep.errorPosition)) {
      rep.errorPosition /= 1.0 - rho();
      if (w.errorLambdaValid && contraction_ < 1) w.errorLambda /= 1.0 - contraction_;
    }
    // Issue 64: where the factor's estimate is not to be trusted (its iterations contracted slowly, or it was built
    // where the organ no longer is: after a tear), the distance is measured on the tangent at the end instead, and a
    // step that ended on the accuracy but is not confirmed within it there does not say it is. The step's end is not
    // moved (its positions, velocities and multipliers as it left them).
    const bool verifying = accuracy_ && lagged && settings_.solver == LinearSolverKind::Cholmod && w.chol->valid();
    const bool checked = verifying && suspect();
    // A cut or torn body's step that estimates nothing (SimulationSettings::estimateErrorEvery) and was not checked
    // claims nothing: its factor's contraction alone is not trusted there.
    if (verifying && !checked && in_.verifyEveryEstimate()) rep.withinAccuracy = false;
    if (checked) {
      const Verdict v = verify();
      // The multipliers the step ended with (verify() kept them in muBefore).
      if (hasConstraints && w.muBefore.size() == w.cons.multipliers().size()) w.cons.multipliers() = w.muBefore;
      if (v == Verdict::Within || v == Verdict::Move) {
        rep.errorPosition = verifiedEstimate_;
      } else {
        rep.errorPosition = std::numeric_limits<double>::quiet_NaN();  // not known there
        rep.errorUnknown = true;
        w.errorLambdaValid = false;
      }
      if (v != Verdict::Within) rep.withinAccuracy = false;
    }
  }
  return ok ? Try::Converged : finite ? Try::Inexact : Try::Failed;
}

// ---- Exact ----

bool ExactNewton::solve() {
  w.refresh = true;  // the factor holds this iteration's exact matrix, not a lagged one
  assembleStiffness(model_, w.xt, w.K);
  buildNewtonMatrix(w.K, w.J);
  if (settings_.solver != LinearSolverKind::Cholmod) {
    const bool solved = solveLinear(w.J, w.tmp, w.dv);
    project(w.dv);
    return solved;
  }
  ++rep.factorisations;
  w.cons.invalidate();
  bool factorised = factoriseWith(*w.chol, settings_, w.J) && solveConstrained(w.tmp, w.xt, h, w.dv, rep);
  if (factorised) return true;
  // Indefinite tangent: projected Newton (element tangents clamped to PSD), then a diagonal shift.
  // The damping matrix K(x0) is projected too (an indefinite one would inject energy and leave the
  // incremental potential unbounded below); the residual follows it from here on.
  if (!dampingProjected_ && beta != 0) {
    assembleStiffness(model_, w.x0, w.Kd, projectionOf(settings_));
    dampingProjected_ = true;
    residual(w.v, w.r);
    s_.rn = w.r.norm();
    w.tmp = -w.r;
  }
  assembleStiffness(model_, w.xt, w.K, projectionOf(settings_));
  buildNewtonMatrix(w.K, w.J);
  return factoriseShifted(w.J) && solveConstrained(w.tmp, w.xt, h, w.dv, rep);
}

// ---- Lagged-pcg ----

bool LaggedPcgNewton::solve() {
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
  bool solved = w.chol->solve(w.pr, w.pz);
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
  return solved;
}

// ---- Chord ----

// Anderson acceleration of the chord iteration (SimulationSettings::chordAcceleration): the chord map
// v -> v + dv(v), dv = P^-1 (-r(v)) with the lagged factor P, is a fixed-point iteration whose contraction is poor
// when P is far from the tangent (a tear, a new contact); mixing its last corrections (type II: the combination of
// the last iterates' images whose corrections combine to the smallest one, Walker and Ni 2011) recovers what a
// Krylov method would from the same solves, at the cost of a few inner products. The multipliers are mixed with the
// same weights (each plain iterate meets the constraints' linear equations; an affine combination does too).
ChordNewton::ChordNewton(Integrator& in, NewtonStep& s)
    : NewtonLoop(in, s, false), accelerate_(in.settings().chordAcceleration), aa(w.anderson) {
  chordMap_ = true;
}

bool ChordNewton::solve() { return solveConstrained(w.tmp, w.xt, h, w.dv, rep); }

void ChordNewton::started() {
  aa.reset();
  if (accelerate_) aa.size(w.v.size(), w.cons.multipliers().size());
}

bool ChordNewton::andersonMix() {
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
}

double ChordNewton::move(bool& guarded) {
  const bool mixed = accelerate_ && andersonMix();
  double rnew = NewtonLoop::move(guarded);
  plainMove_ = !mixed;
  if (mixed && (guarded || !std::isfinite(rnew) || rnew > s_.rn)) {
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
    rnew = NewtonLoop::move(guarded);
    plainMove_ = true;
  }
  if (guarded) aa.reset();  // a shortened move is not the chord map's: mix only unshortened ones
  // SimulationSettings::localElimination: the nodes the factor leaves most of the residual on, solved on their own.
  // The move and the elimination are one map, whose contraction the accuracy's estimate measures as the chord's (with
  // the moves after an elimination taken as not comparable, fewer steps ended on the accuracy: on the patient liver's
  // pull the synchronous p99 was 196 ms against 132 ms). The mixing starts again from it (not the chord's map).
  if (settings_.localElimination &&
      (settings_.factorRefresh == FactorRefresh::Synchronous || slowIterations_ >= kEliminationAsyncGate) &&
      std::isfinite(rnew) && rnew > kEliminationTrigger * s_.rn &&
      rnew > settings_.tolerance * s_.scale && eliminate(w.vn, w.rn, rnew)) {
    ++rep.eliminations;
    aa.reset();
  }
  return rnew;
}

bool ChordNewton::iterated(double previous) {
  const double rn = s_.rn, scale = s_.scale;
  // A lagged factor that no longer contracts the residual well is rebuilt here, at the current iterate: at once
  // when it halves the residual no more (the step waits for it), on the second thread already when it does not
  // divide it by ten (the steps go on meanwhile; on the liver preset's paced grasp-pull 3.1 iterations per step
  // instead of 5.0, and 2.7 instead of 4.7 on the patient liver at 16k tets: BENCHMARKS.md).
  const double contraction = settings_.factorRefresh != FactorRefresh::Synchronous ? 0.1 : 0.5;
  // Accelerated with the factor built on the second thread: a step whose iterations keep failing to halve the
  // residual (a factor from before a tear, moves the inversion guard keeps shortening) rebuilds it here once, rather
  // than running its 30 iterations and retrying at half the step (each retry a factorisation too).
  if (accelerate_ && rn > 0.5 * previous && rn > settings_.tolerance * scale) ++slowIterations_;
  const bool stalled = accelerate_ && settings_.factorRefresh != FactorRefresh::Synchronous && !rebuiltHere_ &&
                       slowIterations_ >= kAndersonStall;
  // A projected factor rebuilt at the last iterate (the tangent there was indefinite: after a cut or a tear) that
  // still contracts this slowly is as good as a factor gets here: another one would be projected too. Rebuilding it
  // at every iteration bought nothing (after a cut on the liver preset: five rebuilds of two factorisations each per
  // step, 250 ms, each contracting by 0.62), so this step iterates on with it.
  const bool rebuiltLast = projectedLast_;
  projectedLast_ = false;
  if (rn > contraction * previous && rn > settings_.tolerance * scale) {
    w.xt = w.x0 + h * w.v;
    if (stalled) {
      rebuiltHere_ = true;
      if (!refreshLagged(w.xt)) return false;
      aa.reset();
    } else if (settings_.factorRefresh != FactorRefresh::Synchronous && w.chol->valid()) {
      requestFactor(w.xt);  // built on the second thread; this step iterates on with the old factor
    } else if (rebuiltLast || keptFactor_ || (accelerate_ && rebuilds_ >= kSyncRebuilds)) {
      keptFactor_ = true;
    } else {
      ++rebuilds_;
      const int before = rep.factorisations;
      if (!refreshLagged(w.xt)) return false;
      projectedLast_ = rep.factorisations - before > 1;  // the exact tangent's factorisation failed first
      aa.reset();  // another factor: another chord map
    }
  }
  return true;
}

// ---- Newton-Krylov ----

// J = (1 + h alpha) M + h beta K(x0) + h^2 K(x), applied matrix-free (the tangent at x prepared with the residual).
void NewtonLoop::applyJ(const Eigen::VectorXd& in, Eigen::VectorXd& out) {
  if (beta != 0) {
    applyStiffnessPair(model_, w.tangentIt, h * h, w.tangent0, h * beta, in, out);
  } else {
    applyStiffness(model_, w.tangentIt, in, out);
    out *= h * h;
  }
  out += (1 + h * alpha) * mass3_.cwiseProduct(in);
  project(out);
}

bool NewtonLoop::refineOnTangent(double target, int budget, bool curvature, bool& definite, double& net,
                                 int& iterations) {
  const bool constrained = hasConstraints && w.cons.fixActiveSet();
  auto netOf = [&](const Eigen::VectorXd& res, const Eigen::VectorXd& y) {
    if (!constrained) return res.norm();
    w.pn = res;
    w.pn.noalias() -= w.cons.transposedH() * y;
    return w.pn.norm();
  };
  int k = 0;
  definite = true;
  applyJ(w.dv, w.pq);
  w.pr = w.tmp - w.pq;
  if (constrained) w.pr.noalias() += w.cons.transposedH() * w.cons.multipliers();
  project(w.pr);
  bool solved = w.cons.projectedSolve(*w.chol, w.pr, w.pz, w.py);
  net = netOf(w.pr, w.py);
  w.pp = w.pz;
  double rz = w.pr.dot(w.pz);
  for (; solved && k < budget && net > target && rz > 0; ++k) {
    applyJ(w.pp, w.pq);
    const double curv = w.pp.dot(w.pq);
    if (curvature && !(curv > 0)) {
      definite = false;
      break;
    }
    const double a = rz / curv;
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
  iterations = k;
  return solved;
}

bool KrylovNewton::solve() {
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
  const double rn = s_.rn, scale = s_.scale;
  bool solved = solveConstrained(w.tmp, w.xt, h, w.dv, rep);
  int k = 0;
  if (solved) {
    const double target =
        std::max(0.1 * settings_.tolerance * scale, std::min(1e-4, 0.1 * rn / scale) * std::max(rn, 1e-300));
    bool definite = true;
    double net = 0;
    solved = refineOnTangent(target, kKrylovBudget, false, definite, net, k);
  }
  rep.innerIterations += k;
  if (k > kKrylovDrift) w.drift = true;  // the lagged factor has drifted: a new one at the next step's start
  project(w.dv);
  return solved;
}

}  // namespace rehearse::simcore::detail
