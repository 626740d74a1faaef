#pragma once
// Time stepping and static equilibrium for the tetrahedral FEM model:
//   implicit (backward) Euler on velocities with Newton iterations and a line search,
//     M (v+ - v) = h (f(x + h v+) - D v+ + f_ext),  D = alpha M + beta K  (Rayleigh damping),
//   and a static solve f(x) + f_ext = 0 (for registration), both with fixed nodes by projection.
// Linear solves: CHOLMOD supernodal Cholesky with the symbolic analysis reused while the pattern is
// unchanged, preconditioned conjugate gradients, or a dense LDL^T (reference for small systems).
// A step that fails (NaN, no convergence) is rolled back and retried with half the time step.
//
// Reusing the factorisation (NewtonMethod): re-factorising the tangent at every Newton iteration is
// exact but costs ~30 ms for a 3.4k-tet organ here; the lagged variants keep one factorisation over many
// steps and refresh it only when convergence slows (their error is measured in BENCHMARKS.md).
//
// Constraints: fixed nodes by projection (default) or as Lagrange multipliers, plus any scalar linear
// constraints on the positions (contour and tool constraints build on these), solved through the Schur
// complement W = H A^-1 H^T with projected Gauss-Seidel, as SOFA's constraint correction does.
//
// The parts, each tested on its own: linear_solver.hpp (CHOLMOD, CG, dense; shifted factorisation),
// constraint_solver.hpp (Schur complement and Gauss-Seidel), this file (implicit Euler with Newton and a
// line search, the lagged-factor policy, the static solve), and SimulationState (the complete state).
#include <rehearse/simcore/constraint_solver.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/linear_solver.hpp>

#include <array>
#include <limits>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace rehearse::simcore {

enum class NewtonMethod {
  Exact,       ///< assemble and factorise the exact tangent at every Newton iteration
  LaggedPcg,   ///< exact tangent, solved by CG preconditioned with a lagged factorisation
  Chord,       ///< iterate with a lagged factorisation (refreshed when convergence slows) to the tolerance
  Linearised,  ///< one solve with the lagged factorisation per step, no convergence test (SOFA's default)
  /// Inexact Newton to the tolerance: the exact tangent applied matrix-free (prepared in the same pass over the
  /// elements as the residual), solved by conjugate gradients preconditioned with the lagged factorisation (refreshed
  /// on the second thread when it needs more than a few iterations: Courtecuisse et al. 2014), each solve only as
  /// accurate as the residual calls for (forcing term 0.1 x the relative residual) and within an iteration budget.
  /// Constraints: the lagged factor's constrained step, then CG with the constraint preconditioner of its active set.
  NewtonKrylov,
};
/// The interactive default (issue 34): what the GUI's Simulation panel, `rehearse gesture` and `rehearse simulate` run
/// (scenes and presets without a method), converged to the tolerance at every step. Chosen by measurement against
/// linearised (one solve, not converged: up to 1e-2) and newton-krylov (two Newton iterations, but each CG iteration
/// a solve and two tangent products): BENCHMARKS.md, "Rehearsal on real organs". SimulationSettings{} stays exact: the
/// library's reference.
constexpr NewtonMethod kInteractiveMethod = NewtonMethod::Chord;
/// "exact", "lagged-pcg", "chord", "linearised", "newton-krylov"; throws MeshError naming the accepted values.
NewtonMethod newtonMethodFromString(const std::string& name);
std::string toString(NewtonMethod m);

enum class AttachmentMode { Projection, Lagrange };

/// When a lagged factorisation that has drifted (its residual grew) is rebuilt. A factor that no longer
/// belongs to the system (a new time step, a parameter edit, a restored state) is always rebuilt at once.
enum class FactorRefresh {
  Synchronous,   ///< at the next step's start, on the stepping thread (that step waits for it)
  Asynchronous,  ///< on a second thread from the step's start positions; the steps go on with the old factor and
                 ///< the new one is swapped in at the first step start after it is ready (Courtecuisse et al. 2014)
  Deferred,  ///< requested and built like Asynchronous but swapped in only after installRequestedFactor() (which waits
             ///< for the build): the replay of an asynchronous run, the recording saying at which step each factor came
             ///< in
};

struct SimulationSettings {
  double timeStep = 0.01;                                  ///< s
  Eigen::Vector3d gravity = Eigen::Vector3d(0, -9.81, 0);  ///< m/s^2
  double rayleighMass = 0.1;                               ///< alpha (1/s)
  double rayleighStiffness = 0.1;                          ///< beta (s)
  int maxNewtonIterations = 10;
  double tolerance = 1e-6;  ///< relative residual
  double staticStepTolerance =
      0;  ///< m: a static solve also stops when Newton's largest node move is below this (0: off)
  bool staticChord =
      false;  ///< static solves reuse an earlier static factorisation while the residual halves per iteration (CHOLMOD)
  bool lineSearch = true;
  LinearSolverKind solver = LinearSolverKind::Cholmod;
  bool simplicialFactor = false;  ///< CHOLMOD: simplicial LL' on a matrix permuted here (re-factorising allocates
                                  ///< nothing; about 2x the supernodal cost)
  int cgMaxIterations = 500;
  double cgTolerance = 1e-10;
  int maxRetries = 4;  ///< halvings of the time step after a failed step
  NewtonMethod method = NewtonMethod::Exact;
  AttachmentMode attachments = AttachmentMode::Projection;
  int gaussSeidelIterations = 300;      ///< sweeps; then bilateral sets take a dense solve of W
  double gaussSeidelTolerance = 1e-10;  ///< relative change of the multipliers
  bool reportEnergy = true;             ///< compute StepReport::energy (one more pass over the elements)
  double refreshResidual = 1e-2;        ///< linearised: re-factorise after a step whose relative residual exceeds this
  FactorRefresh factorRefresh = FactorRefresh::Synchronous;  ///< lagged methods: where a drifted factor is rebuilt
  /// The linearised method's tolerance on the relative residual of the nonlinear equations after its one solve
  /// (it does no Newton test; a step above it is `inexact`). Its error is of second order in the velocity change:
  /// measured 1e-6 to 2e-3 in the gesture scripts on the liver phantom, SOFA's liver, kidney and uterus
  /// (BENCHMARKS.md).
  double linearisedTolerance = 1e-2;
  /// Validation runs: a step that does not converge after the retries is rolled back (status `failed`) instead of
  /// kept as the attempt with the smallest residual (status `inexact`).
  bool strict = false;
  /// Keep elements of the laws not defined inverted (guardsInversion) from inverting: a Newton move (and the
  /// linearised step's velocity) that would take one below 10 % of its volume at the step's start, or below 1 % of its
  /// rest volume, stops that element's nodes (Integrator::guardMove).
  bool inversionGuard = true;
  /// Chord method: each iterate mixes the last chord corrections (Anderson acceleration, depth 6, safeguarded: a mixed
  /// move that does not lower the residual is replaced by the plain one). A lagged factor far from the tangent (a
  /// tear's, a contact's) then still converges in a few iterations instead of 30 with a refactorisation; equal to the
  /// plain chord where one correction suffices. Recorded only when on (sessions recorded before replay without it).
  bool chordAcceleration = true;
  /// Projected Newton (an indefinite tangent: inverted, strongly compressed or torn elements) eigen-decomposes only the
  /// elements whose 9x9 stress tangent dP/dF a Cholesky shows not positive definite (TangentProjection::Checked); off,
  /// every element's 12x12 matrix (TangentProjection::Element, 15-30 % of a step's time where it runs, changing
  /// the definite ones only by rounding). Recorded only when on (sessions recorded before replay without it).
  bool checkedProjection = true;
  /// A Newton attempt whose moves the inversion guard shortened four times in a row without lowering the residual by
  /// 1 % ends there (StepReport::guardStalled), and a clip its tissue cannot close further stays as far as it closed
  /// (Session::settleHeldBackClips). Recorded only when on (sessions recorded before replay without it).
  bool heldBackStop = true;
  /// The corotational law's volume barrier (Lame::barrier): below this J = det F an element's energy grows without
  /// bound as it is crushed, so a crushed element's equilibrium stays open instead of the inversion guard stopping its
  /// nodes at its floor step after step. Measured on the operative case at 16-17k elements (BENCHMARKS.md, the 2026-12-07
  /// ninety-eighth session): without it, 11-13 steps of the cut and 49-92 of the pull ended inexact, held back by the
  /// guard, at 1-3.7 s a step; with it (0.3), 1 of 151 in the pull and none in the cut. 0: off. The model carries it
  /// (setVolumeBarrier: sessions' bodies and `rehearse simulate` set it from these settings); recorded only when on
  /// (sessions recorded before it replay without it).
  double volumeBarrier = kVolumeBarrierJ;
  /// Issue 61, an experiment (off by default; the bench's variant "..., local elimination"): a chord move that leaves
  /// more than a quarter of the residual, half or more of it on a few free nodes (64 at most: a torn flap springing
  /// back, which the lagged factor does not hold), is followed by Newton on those nodes and their neighbours alone, the
  /// rest of the organ fixed (nonlinear elimination, Lanzkron, Rose and Wilkes 1996; Cai and Keyes 2002), with the
  /// exact tangent of what touches them (projected where indefinite). Kept only where it lowers the whole residual.
  /// With the synchronous refresh the patient liver's pull that tears took p99 129 ms instead of 545 (fewer factors
  /// rebuilt in the step). With the asynchronous refresh (the window's) it waits for two slow iterations; ungated it made
  /// the steps slower (median 70 ms instead of 31, two inexact), gated it helped in one set of runs and not in the next:
  /// BENCHMARKS.md. It allocates in the steps it acts in. Recorded only when on.
  bool localElimination = false;
  /// Each step estimates its distance from the converged answer in metres and newtons (StepReport::errorPosition,
  /// errorForce: one more solve with the step's factor). It changes nothing the step computes (a replay with it off
  /// gives the same bits), so it is not recorded.
  bool estimateError = true;
  /// The accuracy a step is asked for, in physical units (issue 64): a Newton method's step ends once its largest
  /// node is estimated within `accuracyPosition` (m) of the converged answer of its equations and the tool force within
  /// `accuracyForce` of its size (at least 1 mN), or once the relative residual is under `tolerance`, whichever comes
  /// first. The estimate is the correction the step's own factor gives at the iterate (the solve the next move needs)
  /// divided by 1 - rho, rho the iteration's contraction (from its residuals and its corrections); the step's first
  /// correction is always taken. Where that factor is not to be trusted (a lagged factor whose iterations contracted by
  /// more than 0.8, or built more than 5 mm from where the organ now is: after a tear) the end's distance is measured
  /// again on the tangent there (the Newton correction, conjugate gradients preconditioned by the factor): StepReport::
  /// errorPosition is that figure (NaN where it cannot be known: an indefinite tangent, the contacts' problem unsolved or
  /// changing), and withinAccuracy is false unless it confirms the accuracy. The step's end is not moved by that check.
  /// 0: off, the relative residual alone decides (SimulationSettings{}, the sessions recorded before it existed).
  /// Recorded only when on.
  double accuracyPosition = 0;
  double accuracyForce = 0.005;  ///< fraction of the tool force (with accuracyPosition on)
  /// ... at every this many steps (the others report NaN): the interactive session estimates every 10th step (0.1 s,
  /// the status line's refresh), so the window stays responsive; the command line every step. A cut or torn body's
  /// check on the tangent (Integrator::setVerifyEveryEstimate) is made at those steps; its steps between them say
  /// nothing of the accuracy (StepReport::withinAccuracy false) unless their factor looks suspect and is checked.
  int estimateErrorEvery = 1;
};

/// The projection SimulationSettings::checkedProjection chooses.
inline TangentProjection projectionOf(const SimulationSettings& s) {
  return s.checkedProjection ? TangentProjection::Checked : TangentProjection::Element;
}

/// What a step really did, in one word (StepReport::status starts with it):
///   converged: the residual is under the tolerance and no element is inverted;
///   inexact:   the state advanced, but the residual stayed above the tolerance (figure in the status);
///   inverted:  the state advanced with inverted elements (count and smallest volume ratio in the status);
///   failed:    the state was rolled back (NaN, an unsolvable system, or strict settings);
///   refused:   the settings cannot run.
enum class StepStatus { Converged, Inexact, Inverted, Failed, Refused };
std::string toString(StepStatus s);
struct StepReport;
/// The report's status in one sentence that starts with its word: "inexact: relative residual 0.045 above the
/// tolerance 0.01", "inverted: 3 elements inside out (smallest volume ratio -0.2, element 17); ...". Made by the
/// reader (the command line, the GUI), not on the stepping thread.
std::string statusSentence(const StepReport& r);

/// The complete state of a simulated body: everything that decides the next step's result, so that a
/// copy of it restores a run exactly (replay, seeking, checkpoints). Besides positions, velocities and
/// time, that is the lagged factorisation's identity (the positions and time step it was built at: a
/// restored state rebuilds the same factor, bit for bit) and the elastic forces the last step ended with
/// (they set the next step's residual scale). Integrator::step reads and writes all of it.
struct SimulationState {
  Eigen::VectorXd x, v;  ///< positions (m) and velocities (m/s), 3n, node-major
  double time = 0;       ///< s
  struct Lagged {
    bool valid = false;   ///< a lagged factor is named (sized vectors are kept: recording allocates nothing)
    Eigen::VectorXd at;   ///< 3n positions the lagged factor was built at
    double step = -1;     ///< s, the time step it was built for
    bool refresh = true;  ///< rebuild it at the next step's start
    bool drift = false;  ///< asynchronous/deferred refresh: it drifted, a new one is requested at the next step's start
    /// Asynchronous/deferred refresh: a factor was requested at `requestedAt` for `requestedStep` and is not swapped
    /// in yet (an integrator adopting this state without that request makes it again: a checkpoint is complete).
    bool requested = false;
    Eigen::VectorXd requestedAt;
    double requestedStep = -1;
  } lagged;
  Eigen::VectorXd forces;  ///< elastic forces at x from the last step (3n, projected), when forcesValid
  bool forcesValid = false;
  /// An offline check's (checkAgainstExact): the velocities (3n) the next step's first try starts its iterations from,
  /// instead of v (the step's equations stay v's: only where Newton starts changes). Taken and cleared by the step;
  /// empty otherwise. Not part of a recording's state.
  Eigen::VectorXd firstIterate;
};

struct StepReport {
  bool ok = false;
  int newtonIterations = 0;
  double residual = 0;  ///< relative residual at the end
  double energy = 0;    ///< kinetic + elastic - gravity work (J)
  double wallMs = 0;
  double timeStepUsed = 0;  ///< s (smaller than asked after retries)
  int retries = 0;
  int factorisations = 0;          ///< numeric factorisations during the step
  int innerIterations = 0;         ///< CG iterations (lagged-pcg, newton-krylov) or Gauss-Seidel sweeps (constraints)
  int eliminations = 0;            ///< SimulationSettings::localElimination: the moves it acted on and kept
  double constraintViolation = 0;  ///< max |H x - value| after the step (m)
  bool factorRequested =
      false;  ///< asynchronous/deferred: a new lagged factor was requested at this step's start positions
  bool factorSwapped = false;  ///< asynchronous: the factor requested earlier was swapped in at this step's start
  StepStatus outcome = StepStatus::Failed;
  int invertedElements = 0;   ///< elements with J = det F <= 0 after the step
  double minVolumeRatio = 1;  ///< the smallest J after the step
  bool inversionLimited =
      false;             ///< a move was shortened to keep elements from inverting (SimulationSettings::inversionGuard)
  /// The inversion guard held the iterations back: its shortened moves stopped lowering the residual (the equations
  /// ask for a shape the elements cannot take without turning inside out), and the step ended there, inexact.
  bool guardStalled = false;
  double tolerance = 0;  ///< the relative residual the outcome was judged against
  /// The step ended on the accuracy asked in millimetres and newtons (SimulationSettings::accuracyPosition), its
  /// relative residual still above `tolerance`, and no check on the tangent at its end said otherwise.
  bool withinAccuracy = false;
  /// How far the step's end lies from the converged answer of its equations (exact Newton's, which its residual
  /// measures), estimated as it runs (issue 64): the correction the step's own factor gives for its last residual,
  /// the attachments and the tool's holds kept (one more solve with the factor the step has); with the accuracy asked
  /// and a factor not to be trusted, the Newton correction on the tangent at the end (SimulationSettings::
  /// accuracyPosition), NaN where that distance cannot be known. `errorPosition`: the
  /// largest node's distance (m); the constraints' force change is Integrator::errorMultipliers (N). NaN when not
  /// estimated (SimulationSettings::estimateError off, a failed step, or no factor: the cg and dense solvers).
  double errorPosition = std::numeric_limits<double>::quiet_NaN();
  /// The check on the tangent ran and found the distance cannot be known there (an indefinite tangent, the contacts'
  /// problem unsolved or changing): errorPosition is NaN for that reason, not for want of an estimate.
  bool errorUnknown = false;
  /// The tool force's distance from the converged answer's (N), from errorMultipliers (the body fills it: it knows
  /// which constraints are the tool's); NaN when not estimated, 0 without a tool.
  double errorForce = std::numeric_limits<double>::quiet_NaN();
  int smallestElement = -1;    ///< the element with the smallest J
  int keptBestOf = 0;          ///< no attempt converged: the best of this many attempts was kept (inexact)
  bool collapsingLaw = false;  ///< inverted elements of a law that collapses (StVK)
  bool invertibleLaw = false;  ///< inverted elements of a law defined inverted (stable Neo-Hookean)
  /// The outcome's word ("converged", "inexact", "inverted": a step writes only that, allocating nothing) or a
  /// sentence of its own (failed, refused, retried steps, static solves); statusSentence() says it all.
  std::string status;
};

/// Why these settings cannot run, in one sentence ("" when they can): the constraint solver (Lagrange
/// attachments, tool and fit constraints: `constrained`) and the lagged Newton methods work on CHOLMOD's
/// factorisation, so CG and the dense solver take only projected attachments with the exact method.
std::string settingsProblem(const SimulationSettings& s, bool constrained);
/// The default method for a linear solver: the interactive one (kInteractiveMethod) on CHOLMOD's factorisation; exact
/// with the cg and dense solvers, which the lagged methods cannot use (a scene or `simulate --solver cg` that names no
/// method runs, as before the default changed, instead of being refused for a method nobody asked for).
inline NewtonMethod defaultMethodFor(LinearSolverKind solver) {
  return solver == LinearSolverKind::Cholmod ? kInteractiveMethod : NewtonMethod::Exact;
}

namespace detail {
class NewtonIteration;  // the Newton iterations of a step (src/physics/newton_iteration.hpp)
class StaticSolve;      // the static solve's iterations (src/physics/integrator_static.cpp)
}  // namespace detail

class Integrator {
 public:
  /// `fixedNodes`: 0-based node indices held at their current position. Throws MeshError with one sentence
  /// for a missing node or settings that cannot run (settingsProblem).
  Integrator(const FemModel& model, std::vector<int> fixedNodes, SimulationSettings settings);
  ~Integrator();
  Integrator(const Integrator&) = delete;
  Integrator& operator=(const Integrator&) = delete;

  SimulationState initialState() const;
  /// One implicit Euler step of settings.timeStep (sub-stepped on failure). The state is left
  /// unchanged when the step fails after all retries. `swapIn` false: a factor built on the second thread is not
  /// swapped in at this step's start (a step taken again from the same start: the first one swapped what was ready,
  /// and a replay installs a recorded factor once per step boundary, before its first try).
  StepReport step(SimulationState& state, bool swapIn = true);
  /// Newton iterations to static equilibrium under gravity and `extraForces` (N, 3n, may be empty).
  StepReport solveStatic(SimulationState& state, const Eigen::VectorXd& extraForces = {});
  /// Solves A y = b with the configured solver (A symmetric positive definite); exposed for tests.
  bool solveLinear(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, Eigen::VectorXd& y);
  const SimulationSettings& settings() const { return settings_; }
  SimulationSettings& settings() { return settings_; }
  /// Times the CHOLMOD symbolic analysis ran (it is reused while the sparsity pattern is unchanged).
  int symbolicAnalyses() const;
  int numericFactorisations() const;
  /// Bytes held by the integrator: its vectors and matrices and the factor (values and row indices).
  std::size_t memoryBytes() const;
  /// Extra constraints (besides the attachments); replaces the previous ones. Validated (node indices);
  /// refused (MeshError) with a solver that cannot honour them (settingsProblem).
  void setConstraints(std::vector<ScalarConstraint> constraints);
  const std::vector<ScalarConstraint>& constraints() const { return constraints_; }
  /// Forces the lagged factorisation to be rebuilt at the next step (after a parameter change).
  void invalidateFactorisation();
  /// With the accuracy asked (SimulationSettings::accuracyPosition) and a lagged CHOLMOD factor, every step's estimate
  /// (SimulationSettings::estimateErrorEvery) is checked on the tangent at its end, whatever ended it (issue 64): for a
  /// body that was cut or torn (FemBody sets it
  /// from BodySetup::topology; its flaps' stiffness is far from any factor's: on the
  /// patient liver after tears, steps ending after 1-3 chord iterations estimated 0.003-0.025 mm where exact Newton's
  /// answer was 0.09-0.52 mm away). The step's end is not moved; a distance not confirmed is said as such.
  void setVerifyEveryEstimate(bool on) { verifyEveryEstimate_ = on; }
  bool verifyEveryEstimate() const { return verifyEveryEstimate_; }
  /// Deferred refresh: builds the factor requested at an earlier step (from that step's start positions); the
  /// next step swaps it in. False when none is pending (or it failed). Asynchronous: waits for the one under way.
  bool installRequestedFactor();
  /// A requested factor is pending (being built, or waiting for installRequestedFactor).
  bool factorPending() const;
  /// A state restored from a checkpoint names a factor requested and not swapped in yet: request it again now
  /// (before the events of the next boundary: a replay's Factor event there installs it). Nothing otherwise.
  void requestAgain(const SimulationState& state);
  /// Builds the lagged factor at positions `at` for the configured time step now (a body built on another
  /// thread arrives with it, so no step waits for it). False for the exact method (nothing to keep) or when
  /// it could not be factorised. A state naming it (SimulationState::lagged: at, step) then uses it. The compliance
  /// blocks of the attachments' nodes and of `toolNodes` (the nodes the instruments hold and touch) are solved with it
  /// too, so that the first constrained step does not (each alone: the same bits as when a step solves them).
  bool prepareLagged(const Eigen::VectorXd& at, const std::vector<int>& toolNodes = {});
  /// The constraints' compliance W = H A^-1 H^T of the last solve (attachments first in Lagrange mode, then the
  /// constraints), with A the step's matrix (kg): a change de of the constraint values (m) changes the multipliers
  /// by W^-1 de / h (N s). Empty before the first constrained solve.
  const Eigen::MatrixXd& constraintCompliance() const;
  /// Lagrange multipliers of the last solve (N), one per constraint (attachments first in Lagrange mode).
  const Eigen::VectorXd& multipliers() const;
  /// How far the last step's multipliers (N, as multipliers()) are from the converged answer's, estimated with its
  /// error (StepReport::errorPosition); empty when not estimated.
  const Eigen::VectorXd& errorMultipliers() const;

 private:
  friend class detail::NewtonIteration;
  friend class detail::StaticSolve;
  struct Work;
  enum class Try { Converged, Inexact, Failed };
  /// One implicit Euler step of h from (x, v): converged, or inexact (x and v hold the best iterate, rep.residual
  /// its relative residual), or failed (x and v unchanged).
  Try tryStep(Eigen::VectorXd& x, Eigen::VectorXd& v, double h, StepReport& rep);
  /// Keeps elements of the laws not defined inverted from going below their floor along x + s h vel, s in [0, 1]:
  /// the nodes of those that would are stopped (vel zero there), then, if that keeps involving new elements, the
  /// whole move is shortened. True when vel changed (nothing happens without SimulationSettings::inversionGuard).
  bool guardMove(const Eigen::VectorXd& x, Eigen::VectorXd& vel, double h);
  /// The status word and sentence of a step whose state is `state` (counts its inverted elements).
  void describe(const SimulationState& state, bool advanced, bool withinTolerance, double tolerance,
                StepReport& rep) const;
  bool adopt(const SimulationState& state, StepReport& rep);
  void record(SimulationState& state) const;
  void newtonMatrix(const Eigen::SparseMatrix<double>& Kd, const Eigen::SparseMatrix<double>& K,
                    Eigen::SparseMatrix<double>& J, double h, double alpha, double beta) const;
  void newtonMatrix(const Eigen::SparseMatrix<double>& K, Eigen::SparseMatrix<double>& J, double h) const;
  /// The lagged factor at `at` for step `h` into `chol` (assembling into Kd and J); attempts counted.
  bool buildLagged(CholmodSolver& chol, Eigen::SparseMatrix<double>& Kd, Eigen::SparseMatrix<double>& J,
                   const Eigen::VectorXd& at, double h, double alpha, double beta, bool simplicial,
                   int& attempts) const;
  void requestFactor(const Eigen::VectorXd& at, double h, StepReport& rep);
  bool swapInRequested(StepReport& rep);
  /// Builds the lagged factor at `at` now. A factor requested before it is older: it is dropped at once (its build
  /// left to end on the second thread, never used), so that the next request is made at the same step live and in a
  /// replay, whatever the second thread's timing — unless `keepRequest` (a restored state rebuilding its factor: the
  /// request it names is newer).
  bool refreshLaggedAt(const Eigen::VectorXd& at, double h, StepReport& rep, bool keepRequest = false);
  /// Drops the pending request without waiting for its build (see Work::abandoned).
  void dropRequest();
  double totalEnergy(const SimulationState& s) const;
  void project(Eigen::VectorXd& r) const;
  void projectMatrix(Eigen::SparseMatrix<double>& A) const;
  /// factoriseShifted (linear_solver.hpp) with the settings' factor kind, counting into `rep`.
  bool factoriseShifted(const Eigen::SparseMatrix<double>& A, StepReport& rep,
                        const std::function<bool()>& accept = nullptr);
  bool solveConstrained(const Eigen::VectorXd& rhs, const Eigen::VectorXd& x, double positionScale, Eigen::VectorXd& dx,
                        StepReport& rep, bool freeGiven = false, const Eigen::VectorXd* carried = nullptr);

  const FemModel& model_;
  std::vector<char> fixed_;
  std::vector<ScalarConstraint> attachmentConstraints_, constraints_;
  SimulationSettings settings_;
  Eigen::VectorXd mass3_, gravityForce_, rest_;
  double gravityWorkAtRest_ = 0;
  double organSize_ = 1;  ///< m: the rest shape's bounding-box diagonal (the static solve's trust region)
  bool verifyEveryEstimate_ = false;
  std::unique_ptr<Work> w_;
};

}  // namespace rehearse::simcore
