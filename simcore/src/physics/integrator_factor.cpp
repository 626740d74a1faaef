// The lagged factorisation: built, requested (refreshed at once, deferred, or on the second thread), swapped in at a
// step boundary, adopted from a state, recorded into it.
#include <rehearse/simcore/integrator.hpp>

#include "integrator_work.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <limits>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <tbb/task_arena.h>
#include <unistd.h>

namespace rehearse::simcore {

using namespace detail;

// Reads only the model, the fixed nodes and the masses (all const after construction), so the asynchronous
// refresh runs it on another thread with its own matrices and solver.
bool Integrator::buildLagged(CholmodSolver& chol, Eigen::SparseMatrix<double>& Kd, Eigen::SparseMatrix<double>& J,
                             const Eigen::VectorXd& at, double h, double alpha, double beta, bool simplicial,
                             int& attempts) const {
  assembleStiffness(model_, at, Kd);
  newtonMatrix(Kd, Kd, J, h, alpha, beta);
  ++attempts;
  chol.setSimplicial(simplicial);
  if (chol.factorise(J)) return true;
  // Indefinite (inverted or strongly compressed elements): projected Newton, then a diagonal shift.
  assembleStiffness(model_, at, Kd, projectionOf(settings_));
  newtonMatrix(Kd, Kd, J, h, alpha, beta);
  return simcore::factoriseShifted(chol, J, model_.diagonalSlot, attempts);
}

void Integrator::requestFactor(const Eigen::VectorXd& at, double h, StepReport& rep) {
  Work::Request& q = *w_->request;
  if (q.pending) return;  // one at a time: the steps keep the old factor until it is in
  if (q.Kd.size() == 0) q.Kd = q.J = model_.pattern;
  q.at = at;
  q.step = h;
  q.attempts = 0;
  q.pending = true;
  q.built = q.ok = false;
  q.rows = w_->cons.constraints();
  rep.factorRequested = true;
  // Built on the second thread in both modes (the build depends only on its inputs); a deferred one is swapped
  // in only once installed (installRequestedFactor waits for it), where the recording says.
  {
    const double alpha = settings_.rayleighMass, beta = settings_.rayleighStiffness;
    const bool simplicial = settings_.simplicialFactor;
    Work::Request* const build = &q;  // its address is stable (the request may be abandoned while it runs)
    q.job = std::async(std::launch::async, [this, build, alpha, beta, simplicial] {
      Work::Request& q = *build;
      // The stepping thread comes first: this thread yields its core to it (nice 10: a tenth of its share when both
      // want the core; the steps are paced, so the build has the rest), and its element loop runs here alone instead
      // of taking the stepping thread's worker (an arena of one). Measured on the liver preset's paced grasp-pull:
      // BENCHMARKS.md, "Converged at every step", what each idea bought.
      setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
      tbb::task_arena alone(1);
      return alone.execute([&] {
        return buildLagged(*q.chol, q.Kd, q.J, q.at, q.step, alpha, beta, simplicial, q.attempts) &&
               q.compliance.prepare(*q.chol, q.rows, fixed_);
      });
    });
  }
}

// Swaps the requested factor in when it is built (asynchronous: the job finished; deferred: installed).
bool Integrator::swapInRequested(StepReport& rep) {
  Work& w = *w_;
  Work::Request& q = *w.request;
  if (!q.pending) return false;
  if (settings_.factorRefresh != FactorRefresh::Deferred && q.job.valid()) {
    if (q.job.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
    q.ok = q.job.get();
    q.built = true;
  }
  if (!q.built) return false;
  q.pending = false;
  rep.factorisations += q.attempts;
  // A factor for another time step, or one that failed, is dropped (the next drift asks again).
  if (!q.ok || q.step != w.laggedStep || q.at.size() != w.x0.size()) return false;
  std::swap(w.chol, q.chol);
  std::swap(w.Kd, q.Kd);
  std::swap(w.J, q.J);
  std::swap(w.laggedAt, q.at);
  std::swap(w.cons.compliance(), q.compliance);  // the blocks solved with it (their factor: the same object)
  w.cons.invalidate();
  rep.factorSwapped = true;
  return true;
}

bool Integrator::installRequestedFactor() {
  Work::Request& q = *w_->request;
  if (!q.pending) return false;
  if (q.job.valid()) {
    q.ok = q.job.get();
  } else if (!q.built) {
    q.ok = buildLagged(*q.chol, q.Kd, q.J, q.at, q.step, settings_.rayleighMass, settings_.rayleighStiffness,
                       settings_.simplicialFactor, q.attempts) &&
           q.compliance.prepare(*q.chol, q.rows, fixed_);
  }
  q.built = true;  // swapped in at the next step's start
  return q.ok;
}

void Integrator::dropRequest() {
  Work& w = *w_;
  auto finished = [](const Work::Request& q) {
    return !q.job.valid() || q.job.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
  };
  if (finished(*w.request)) {
    if (w.request->job.valid()) (void)w.request->job.get();
  } else {
    // Still being built: left to finish on the second thread. A request abandoned earlier whose build has ended
    // takes its place; if none has and two are still running, the oldest is waited for (a bound on the builds
    // left running beside the steps).
    auto spare = std::find_if(w.abandoned.begin(), w.abandoned.end(), [&](const auto& q) { return finished(*q); });
    if (spare == w.abandoned.end() && w.abandoned.size() >= 2) spare = w.abandoned.begin();
    std::unique_ptr<Work::Request> next;
    if (spare != w.abandoned.end()) {
      next = std::move(*spare);
      w.abandoned.erase(spare);
      if (next->job.valid()) (void)next->job.get();
    } else {
      next = std::make_unique<Work::Request>();
    }
    w.abandoned.push_back(std::move(w.request));
    w.request = std::move(next);
  }
  w.request->pending = false;
  w.request->built = false;
}

bool Integrator::factorPending() const { return w_->request->pending; }

bool Integrator::prepareLagged(const Eigen::VectorXd& at, const std::vector<int>& toolNodes) {
  if (settings_.method == NewtonMethod::Exact || settings_.solver != LinearSolverKind::Cholmod ||
      at.size() != rest_.size())
    return false;
  StepReport rep;
  if (!refreshLaggedAt(at, settings_.timeStep, rep)) return false;
  std::vector<int> nodes = toolNodes;
  for (const auto& c : attachmentConstraints_)
    for (int node : c.nodes)
      if (node >= 0) nodes.push_back(node);
  // The steps' constrained solves (ConstraintSolver::solve) take their blocks from this cache, keyed on the factor.
  (void)w_->cons.compliance().prepare(*w_->chol, nodes, fixed_);  // a failed solve: the step solves them again
  return true;
}

bool Integrator::refreshLaggedAt(const Eigen::VectorXd& at, double h, StepReport& rep, bool keepRequest) {
  Work& w = *w_;
  w.laggedStep = h;
  w.laggedAt = at;  // the factor's identity, part of the complete state (SimulationState::lagged)
  w.refresh = false;
  w.drift = false;
  if (!keepRequest && w.request->pending) {
    // A factor requested before this one is older. Left pending until its build ended (live) or a recorded swap
    // installed it (a replay, which has none for it), it blocked the requests after it for a time that depended on
    // the second thread: a chord run's replay differed from step 14 on (issue 34). Dropped now, in both, without
    // waiting for its build: this build does not queue behind it (the steps that rebuild their factor in the step
    // waited for both, one after the other).
    dropRequest();
  }
  w.cons.invalidate();
  return buildLagged(*w.chol, w.Kd, w.J, at, h, settings_.rayleighMass, settings_.rayleighStiffness,
                     settings_.simplicialFactor, rep.factorisations);
}

// The complete state in, before a step: the lagged factor it names is the one this step uses (rebuilt
// when the integrator holds another one, e.g. after restoring a checkpoint or in a second integrator),
// and the forces it carries at x are the ones the residual scale uses.
bool Integrator::adopt(const SimulationState& state, StepReport& rep) {
  Work& w = *w_;
  w.forcesValid = state.forcesValid && state.forces.size() == state.x.size() && state.x.size() > 0;
  if (w.forcesValid) {
    w.forcesAt = state.x;
    w.forces = state.forces;
  }
  const bool refresh = state.lagged.refresh || w.invalidated;
  w.invalidated = false;
  const bool lagged = settings_.method != NewtonMethod::Exact && settings_.solver == LinearSolverKind::Cholmod;
  if (!lagged) {
    w.refresh = true;
    return true;
  }
  if (!state.lagged.valid || state.lagged.at.size() != state.x.size() || state.lagged.step <= 0) {
    w.refresh = true;  // a state without a lagged factor (fresh, or from an exact step): build one at its start
    return true;
  }
  const bool same = w.chol->valid() && w.laggedStep == state.lagged.step &&
                    w.laggedAt.size() == state.lagged.at.size() && w.laggedAt == state.lagged.at &&
                    !w.refresh;  // refresh: the factor holds another matrix or is stale
  if (!same && !refresh) {
    // The factor the state names, built again: a request the state names too is newer and stays.
    if (!refreshLaggedAt(state.lagged.at, state.lagged.step, rep, true)) return false;
  }
  w.refresh = refresh;
  w.drift = state.lagged.drift;
  return true;
}

void Integrator::requestAgain(const SimulationState& state) {
  if (!state.lagged.requested || w_->request->pending || settings_.factorRefresh == FactorRefresh::Synchronous ||
      state.lagged.requestedAt.size() != state.x.size())
    return;
  StepReport rep;
  requestFactor(state.lagged.requestedAt, state.lagged.requestedStep, rep);
}

void Integrator::record(SimulationState& state) const {
  const Work& w = *w_;
  // Synchronous refresh: a drifted factor is rebuilt at the next step's start, like a stale one.
  const bool sync = settings_.factorRefresh == FactorRefresh::Synchronous;
  state.lagged.refresh = w.refresh || (sync && w.drift);
  state.lagged.drift = !sync && w.drift;
  state.lagged.valid = w.laggedStep > 0 && !state.lagged.refresh;
  if (state.lagged.valid) {
    state.lagged.at = w.laggedAt;  // same size from the second step on: no allocation
    state.lagged.step = w.laggedStep;
  }
  state.forcesValid = w.forcesValid && w.forcesAt.size() == state.x.size() && w.forcesAt == state.x;
  if (state.forcesValid) state.forces = w.forces;
  state.lagged.requested = w.request->pending;
  if (state.lagged.requested) {
    state.lagged.requestedAt = w.request->at;  // same size from the second request on: no allocation
    state.lagged.requestedStep = w.request->step;
  }
}

}  // namespace rehearse::simcore
