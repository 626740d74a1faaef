#pragma once
// A run's steps against exact Newton's answer (issue 64: the true error, offline). A recorded run (the setup and the
// events a recording holds) is replayed; at each step checked, the state before it is restored into a second session
// that takes the same step with the same inputs by exact Newton to a relative residual of 1e-10, and the two answers
// are compared node by node (m) and by the tool's force (N), beside the run's own estimate of its error.
#include <rehearse/simcore/session/session.hpp>

#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace rehearse::simcore {

/// One step of the run and what exact Newton made of the same step.
struct StepTruth {
  long step = 0;       ///< the step (1 after the first)
  double time = 0;     ///< s, simulated, after it
  StepReport report;   ///< the run's own report (its estimate: errorPosition, errorForce; its status)
  std::vector<std::string> events;  ///< what happened at the step (Snapshot::events)
  /// Exact Newton reached its tolerance from the step's start with the same inputs: the errors below are the truth.
  bool resolved = false;
  std::string why;  ///< when not resolved: what exact Newton said
  double errorPosition = std::numeric_limits<double>::quiet_NaN();  ///< m, the largest node distance
  double errorForce = std::numeric_limits<double>::quiet_NaN();     ///< N, |the tool force - exact Newton's|
  double force = 0;  ///< N, the size of exact Newton's tool force
  int exactIterations = 0;
  std::vector<std::string> exactEvents;  ///< what happened in exact Newton's step (a tear or a slip the run had not)
  /// Where the run is farther from exact Newton's answer than it asked (or than twice its estimate), the same step by
  /// the run's own method converged to the same tolerance: its distance from the run (m) and from exact Newton's answer
  /// (m). Near the run and far from exact Newton's: the step's equations have another solution there, which exact
  /// Newton went to (a torn flap resting either way). NaN when not taken or not converged.
  double ownConverged = std::numeric_limits<double>::quiet_NaN();
  double ownToExact = std::numeric_limits<double>::quiet_NaN();
  /// Taken where ownConverged is: exact Newton on the same step's equations started where the run ended
  /// (SimulationState::firstIterate) instead of at the step's start: its answer's distance from the run's end (m). Small,
  /// the run lies by a solution of its equations, another than the one exact Newton reached from the start. NaN when
  /// not taken or not converged.
  double exactFromEnd = std::numeric_limits<double>::quiet_NaN();
  /// The run's own method converged, or exact Newton started where the run ended, lies where the run is (within `asked`,
  /// m, or twice its estimate) and exact Newton's answer from the start elsewhere: the step's equations have two
  /// solutions there, the run's one of them (not an error of the run).
  bool anotherSolution(double asked) const;
};

struct ExactCheckOptions {
  double tolerance = 1e-10;  ///< exact Newton's relative residual
  int maxIterations = 60;
  long from = 1;   ///< the first step checked
  long to = -1;    ///< the last (-1: the run's last)
  long every = 1;  ///< every how many steps from `from` (steps with an event are always checked)
  /// Called after each step checked; false stops.
  std::function<bool(const StepTruth&)> each;
};

/// Replays `steps` steps of the run and checks those asked for. The replay is the recording's own (replaySetup: the
/// same bits); its error estimates are computed (they change no bit). Throws MeshError for an unusable setup.
void checkAgainstExact(const BodySetup& setup, const std::vector<InputEvent>& events, long steps,
                       const ExactCheckOptions& options);

}  // namespace rehearse::simcore
