#include <rehearse/simcore/session/step_truth.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <optional>

namespace rehearse::simcore {

namespace {

// Exact Newton to the tolerance asked, nothing else changed: the same inputs, the same topology changes.
BodySetup exactSetup(BodySetup s, const ExactCheckOptions& o, NewtonMethod method = NewtonMethod::Exact) {
  s.settings.method = method;
  s.settings.tolerance = o.tolerance;
  // (the run's own lagged method converges linearly: more iterations to the same tolerance)
  s.settings.maxNewtonIterations = method == NewtonMethod::Exact ? o.maxIterations : 4 * o.maxIterations;
  s.settings.accuracyPosition = 0;  // the residual's rule alone
  s.settings.estimateError = false;
  return s;
}

double largestNodeDistance(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  double worst = 0;
  for (Eigen::Index i = 0; i + 2 < a.size(); i += 3) worst = std::max(worst, (a.segment<3>(i) - b.segment<3>(i)).norm());
  return worst;
}

}  // namespace

void checkAgainstExact(const BodySetup& setup, const std::vector<InputEvent>& events, long steps,
                       const ExactCheckOptions& o) {
  BodySetup runSetup = replaySetup(setup);
  runSetup.settings.estimateError = true;  // the run's own estimates (computed after the step: no bit changes)
  Session run(runSetup);
  std::map<long, std::vector<InputEvent>> byStep;  // the events applied at each boundary (before step k + 1)
  for (const auto& e : events) {
    run.post(e);
    byStep[e.step].push_back(e);
  }
  // The exact session starts from the recording's own setup (its uncut organ is what later cuts are built from).
  std::unique_ptr<Session> exact, own;
  const NewtonMethod runMethod = runSetup.settings.method;
  const double asked = runSetup.settings.accuracyPosition;
  const long last = o.to < 0 ? steps : std::min(steps, o.to);
  const long every = std::max(1L, o.every);
  for (long k = 0; k < last; ++k) {
    const long n = k + 1;
    const bool wanted = n >= o.from && ((n - o.from) % every == 0 || byStep.count(k) > 0);
    std::optional<Checkpoint> start;
    if (wanted) start = run.checkpoint();
    run.advance();
    if (!wanted) continue;
    const auto snap = run.snapshot();
    StepTruth t;
    t.step = n;
    t.time = snap->time;
    t.report = snap->report;
    t.events = snap->events;
    if (!exact) exact = std::make_unique<Session>(exactSetup(runSetup, o));
    const BodySetup startSetup = start->setup;
    start->setup = exactSetup(startSetup, o);
    exact->discardPending();
    exact->restore(*start);
    if (const auto it = byStep.find(k); it != byStep.end())
      for (const auto& e : it->second) exact->post(e);
    const StepReport ref = exact->advance();
    t.exactIterations = ref.newtonIterations;
    const auto exactSnap = exact->snapshot();
    t.exactEvents = exactSnap->events;
    if (!ref.ok || ref.outcome != StepStatus::Converged) {
      t.why = ref.status.empty() ? std::string("exact Newton did not reach its tolerance") : ref.status;
    } else if (exactSnap->positions.size() != snap->positions.size()) {
      t.why = "exact Newton's step has another mesh (" + std::to_string(exactSnap->positions.size()) + " nodes, the run " +
              std::to_string(snap->positions.size()) + ")";
    } else {
      t.resolved = true;
      t.errorPosition = largestNodeDistance(run.state().x, exact->state().x);
      t.errorForce = (snap->tool.force - exactSnap->tool.force).norm();
      t.force = exactSnap->tool.force.norm();
      const double estimate = t.report.errorPosition;
      if (runMethod != NewtonMethod::Exact && runMethod != NewtonMethod::Linearised &&
          ((asked > 0 && t.errorPosition > asked) || !(t.errorPosition <= 2 * estimate)) && t.errorPosition > 1e-9) {
        if (!own) own = std::make_unique<Session>(exactSetup(runSetup, o, runMethod));
        start->setup = exactSetup(startSetup, o, runMethod);
        own->discardPending();
        own->restore(*start);
        if (const auto it = byStep.find(k); it != byStep.end())
          for (const auto& e : it->second) own->post(e);
        const StepReport ownRep = own->advance();
        if (ownRep.ok && ownRep.outcome == StepStatus::Converged && own->snapshot()->positions.size() == snap->positions.size()) {
          t.ownConverged = largestNodeDistance(run.state().x, own->state().x);
          t.ownToExact = largestNodeDistance(own->state().x, exact->state().x);
        }
        // Exact Newton again, started where the run ended (x0 + h v at the run's end positions): the solution of
        // the step's equations nearest the run, if it is one.
        const double h = startSetup.settings.timeStep;
        if (run.state().x.size() == start->state.x.size() && h > 0) {
          start->setup = exactSetup(startSetup, o);
          start->state.firstIterate = (run.state().x - start->state.x) / h;
          exact->discardPending();
          exact->restore(*start);
          if (const auto it = byStep.find(k); it != byStep.end())
            for (const auto& e : it->second) exact->post(e);
          const StepReport fromEnd = exact->advance();
          if (fromEnd.ok && fromEnd.outcome == StepStatus::Converged &&
              exact->snapshot()->positions.size() == snap->positions.size())
            t.exactFromEnd = largestNodeDistance(run.state().x, exact->state().x);
        }
      }
    }
    if (o.each && !o.each(t)) return;
  }
}

bool StepTruth::anotherSolution(double asked) const {
  const double own = std::max({asked, 2 * report.errorPosition, 1e-9});
  return (ownConverged <= own && ownToExact > own) || (exactFromEnd <= own && errorPosition > own);
}

}  // namespace rehearse::simcore
