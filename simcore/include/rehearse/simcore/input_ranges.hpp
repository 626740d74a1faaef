#pragma once
// The ranges every input path (scene files, the command line, gesture scripts, recordings, case files) holds a
// simulation's settings and materials to (issue 60): values outside them are refused with a sentence, since inside
// the old ranges a run could be set never to end (a tolerance of 1e-300 with 10,000 Newton iterations and 60 retries,
// Poisson's ratio 0.4999999999, 1e12 steps). Header-only: the recording codec is built alone for fuzzing.
#include <rehearse/simcore/integrator.hpp>

#include <cmath>
#include <cstdio>
#include <string>

namespace rehearse::simcore {

/// The limits, stated once (README: "Limits on input files").
struct InputRanges {
  static constexpr double minTimeStep = 1e-5, maxTimeStep = 1.0;          ///< s
  static constexpr int maxNewtonIterations = 200, maxRetries = 10;        ///< per step
  static constexpr double minTolerance = 1e-14, maxTolerance = 1.0;       ///< relative residual
  static constexpr double maxAccuracy = 0.01;  ///< m: SimulationSettings::accuracyPosition (0 turns it off)
  static constexpr int maxSolverIterations = 100000;                      ///< CG, Gauss-Seidel sweeps
  static constexpr double maxDamping = 1e3;                               ///< Rayleigh alpha (1/s), beta (s)
  static constexpr double maxGravity = 1e3;                               ///< m/s^2
  static constexpr double maxYoung = 1e12;                                ///< Pa
  static constexpr double maxPoisson = 0.4999;                            ///< near-incompressible, still solvable
  static constexpr double minDensity = 1.0, maxDensity = 1e5;             ///< kg/m^3
  static constexpr double maxTearStrain = 10.0;
  static constexpr long maxSteps = 1000000;                               ///< one run (scene, gesture script)
  static constexpr double maxDuration = 3600.0;                           ///< s of simulated time in one run
};

namespace detail {
inline bool inClosed(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }
inline std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}
}  // namespace detail

/// Why these settings cannot run (one sentence, no full stop), or empty.
inline std::string settingsProblem(const SimulationSettings& t) {
  using R = InputRanges;
  using detail::inClosed;
  using detail::number;
  if (!inClosed(t.timeStep, R::minTimeStep, R::maxTimeStep))
    return "the time step " + number(t.timeStep) + " s is outside [" + number(R::minTimeStep) + ", " +
           number(R::maxTimeStep) + "] s";
  if (!std::isfinite(t.gravity.norm()) || t.gravity.norm() > R::maxGravity)
    return "gravity is not a vector of at most " + number(R::maxGravity) + " m/s^2";
  if (!inClosed(t.rayleighMass, 0, R::maxDamping) || !inClosed(t.rayleighStiffness, 0, R::maxDamping))
    return "the damping (Rayleigh " + number(t.rayleighMass) + ", " + number(t.rayleighStiffness) +
           ") is outside [0, " + number(R::maxDamping) + "]";
  if (t.maxNewtonIterations < 1 || t.maxNewtonIterations > R::maxNewtonIterations)
    return "the Newton iterations per step (" + std::to_string(t.maxNewtonIterations) + ") are outside [1, " +
           std::to_string(R::maxNewtonIterations) + "]";
  if (t.maxRetries < 0 || t.maxRetries > R::maxRetries)
    return "the retries per step (" + std::to_string(t.maxRetries) + ") are outside [0, " +
           std::to_string(R::maxRetries) + "]";
  if (!inClosed(t.tolerance, R::minTolerance, R::maxTolerance))
    return "the tolerance " + number(t.tolerance) + " is outside [" + number(R::minTolerance) + ", " +
           number(R::maxTolerance) + "]";
  if (t.cgMaxIterations < 0 || t.cgMaxIterations > R::maxSolverIterations || t.gaussSeidelIterations < 0 ||
      t.gaussSeidelIterations > R::maxSolverIterations)
    return "an iteration count of the linear solver is outside [0, " + std::to_string(R::maxSolverIterations) + "]";
  if (!inClosed(t.cgTolerance, 0, 1) || !inClosed(t.gaussSeidelTolerance, 0, 1) ||
      !inClosed(t.staticStepTolerance, 0, 1) || !inClosed(t.refreshResidual, 0, 1e3) ||
      !(std::isfinite(t.linearisedTolerance) && t.linearisedTolerance > 0 && t.linearisedTolerance <= 1))
    return "a tolerance of the solver is not a number in its range (linearised tolerance in (0, 1], the others in "
           "[0, 1])";
  if (!inClosed(t.accuracyPosition, 0, R::maxAccuracy) || !(t.accuracyForce > 0 && t.accuracyForce <= 1))
    return "the accuracy asked of a step (" + number(1e3 * t.accuracyPosition) + " mm, " +
           number(100 * t.accuracyForce) + " % of the tool force) is outside [0, " + number(1e3 * R::maxAccuracy) +
           "] mm and (0, 100] %";
  return {};
}

/// Why this material cannot be simulated (one sentence naming `whose`), or empty.
inline std::string materialRangeProblem(const MaterialParams& m, const std::string& whose) {
  using R = InputRanges;
  using detail::inClosed;
  using detail::number;
  if (!(std::isfinite(m.young) && m.young > 0 && m.young <= R::maxYoung))
    return whose + "'s Young's modulus " + number(m.young) + " Pa is outside (0, " + number(R::maxYoung) + "]";
  if (!inClosed(m.poisson, 0, R::maxPoisson))
    return whose + "'s Poisson ratio " + number(m.poisson) + " is outside [0, " + number(R::maxPoisson) + "]";
  if (!inClosed(m.density, R::minDensity, R::maxDensity))
    return whose + "'s density " + number(m.density) + " kg/m^3 is outside [" + number(R::minDensity) + ", " +
           number(R::maxDensity) + "]";
  if (!inClosed(m.tearStrain, 0, R::maxTearStrain))
    return whose + "'s tear strain " + number(m.tearStrain) + " is outside [0, " + number(R::maxTearStrain) +
           "] (0: it does not tear)";
  return {};
}

/// Why a run of `steps` steps of `timeStep` s is refused, or empty.
inline std::string runLengthProblem(double steps, double timeStep) {
  using R = InputRanges;
  if (!(std::isfinite(steps) && steps >= 1 && steps <= static_cast<double>(R::maxSteps)))
    return "the run has " + detail::number(steps) + " steps; at most " + std::to_string(R::maxSteps) +
           " are simulated in one run";
  if (!(steps * timeStep <= R::maxDuration))
    return "the run lasts " + detail::number(steps * timeStep) + " s of simulated time; at most " +
           detail::number(R::maxDuration) + " s are simulated in one run";
  return {};
}

}  // namespace rehearse::simcore
