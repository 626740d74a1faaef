// The rest shape that sags into a given shape (inverse elastostatics by fixed point; inverse_rest.hpp).
#include <rehearse/simcore/inverse_rest.hpp>
#include <rehearse/simcore/words.hpp>

#include <rehearse/simcore/support.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

namespace rehearse::simcore {
namespace {

double largestDistance(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  double e = 0;
  for (Eigen::Index i = 0; i + 2 < a.size(); i += 3) e = std::max(e, (a.segment<3>(i) - b.segment<3>(i)).norm());
  return e;
}

std::string mm(double metres) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g mm", 1e3 * metres);
  return buf;
}

// The rigid motion nearest (least squares over the nodes) to the displacement field d of nodes at x: t + w x (x - c).
Eigen::VectorXd rigidPart(const Eigen::VectorXd& d, const Eigen::VectorXd& x) {
  const Eigen::Index n = x.size() / 3;
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), t = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < n; ++i) c += x.segment<3>(3 * i), t += d.segment<3>(3 * i);
  c /= static_cast<double>(n);
  t /= static_cast<double>(n);
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d r = x.segment<3>(3 * i) - c;
    inertia += r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose();
    b += r.cross(d.segment<3>(3 * i) - t);
  }
  const Eigen::Vector3d w = inertia.ldlt().solve(b);
  Eigen::VectorXd out(d.size());
  for (Eigen::Index i = 0; i < n; ++i) out.segment<3>(3 * i) = t + w.cross(x.segment<3>(3 * i) - c);
  return out;
}

std::string newtons(double n) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g N", n);
  return buf;
}

// The first element whose orientation differs between two placements of the nodes (-1: none).
int flippedElement(const std::vector<std::array<int, 4>>& tets, const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  auto volume = [](const Eigen::VectorXd& x, const std::array<int, 4>& t) {
    Eigen::Matrix3d D;
    for (int k = 0; k < 3; ++k) D.col(k) = x.segment<3>(3 * t[k + 1]) - x.segment<3>(3 * t[0]);
    return D.determinant();
  };
  for (std::size_t e = 0; e < tets.size(); ++e)
    if (volume(a, tets[e]) * volume(b, tets[e]) <= 0) return static_cast<int>(e);
  return -1;
}

// Why no rest shape can be solved for `target` (in r, false), or true; without gravity the target is its own rest
// shape (r converged, false).
bool solvable(const BodySetup& setup, const std::vector<Eigen::Vector3d>& target, const InverseRestOptions& options,
              InverseRestResult& r) {
  const std::size_t n = setup.mesh.points.size();
  if (target.size() != n) {
    r.status = "The shape to start from has " + std::to_string(target.size()) + " nodes and the body " +
               std::to_string(n) + ": no rest shape was solved.";
    return false;
  }
  if (!std::all_of(target.begin(), target.end(), [](const Eigen::Vector3d& p) { return p.allFinite(); })) {
    r.status = "The shape to start from has a position that is not a number: no rest shape was solved.";
    return false;
  }
  if (setup.settings.gravity.norm() == 0) {
    r.outcome = InverseRestResult::Outcome::Converged;
    r.rest = r.equilibrium = target;
    r.status = "Without gravity the shape is its own rest shape.";
    return false;
  }
  if (setup.fixedNodes.empty() && setup.supports.empty() && !(options.supportModulus > 0)) {
    r.status = "Nothing holds the organ (no attachments, no support): under gravity it has no equilibrium to start "
               "from; hold nodes (H) or let the tissue around it carry it (Support on the Simulation panel).";
    return false;
  }
  return true;
}

// The static solves: exact Newton to a tight residual (the start must be an equilibrium of the rehearsal's own
// steps, whatever their method), on the setup's material, attachments and gravity.
SimulationSettings staticSettings(const SimulationSettings& settings) {
  SimulationSettings s = settings;
  s.method = NewtonMethod::Exact;
  s.factorRefresh = FactorRefresh::Synchronous;
  s.tolerance = std::min(s.tolerance, 1e-8);  // (1e-9 stalls on round-off for stiff neo-Hookean beams)
  s.maxNewtonIterations = std::max(s.maxNewtonIterations, 50);
  return s;
}

// The fixed point's state: the rest shape X, the last solve's displacement u, the supports and their shift, the best
// rest shape so far with its equilibrium, supports and load, and the step's relaxation.
struct RestIteration {
  enum class Solve { Ok, Failed, Refused };

  const BodySetup& setup;
  const std::vector<Eigen::Vector3d>& target;
  const InverseRestOptions& options;
  const std::size_t n;
  Eigen::VectorXd goal;
  const Eigen::Vector3d g;
  const bool placing;
  const SimulationSettings s;
  Mesh mesh;
  Eigen::VectorXd X, u, bestX, bestX_eq;
  std::vector<NodeAnchor> supports, bestSupports;
  Eigen::VectorXd shift, bestShift;
  bool shifting;
  double load = 0, bestLoad = 0;
  double best = std::numeric_limits<double>::infinity(), previous = best, relax = 1.0;
  std::string stop;

  RestIteration(const BodySetup& setup_, const std::vector<Eigen::Vector3d>& target_,
                const InverseRestOptions& options_);
  Solve equilibrium(int k, SimulationState& state, InverseRestResult& r);
  void keepBest(const SimulationState& state, double error);
  bool correct(const SimulationState& state, double error);
  InverseRestResult& finish(InverseRestResult& r) const;
};

RestIteration::RestIteration(const BodySetup& setup_, const std::vector<Eigen::Vector3d>& target_,
                             const InverseRestOptions& options_)
    : setup(setup_),
      target(target_),
      options(options_),
      n(setup_.mesh.points.size()),
      goal(static_cast<Eigen::Index>(3 * n)),
      g(setup_.settings.gravity),
      placing(options_.supportModulus > 0),
      s(staticSettings(setup_.settings)),
      mesh(setup_.mesh) {
  for (std::size_t i = 0; i < n; ++i) goal.segment<3>(static_cast<Eigen::Index>(3 * i)) = target[i];
  mesh.unitToMetre = 1.0;
  X = goal, u = Eigen::VectorXd::Zero(goal.size()), bestX = goal;
  supports = setup.supports;
  // The supports' points follow the corrections' rigid part: a rigid move of the rest shape hardly moves an organ its
  // supports hold (its equilibrium follows their points instead), so the rest shape alone approached the target at
  // 13 % per solve on a liver held at one node. At convergence the organ is in equilibrium at the target all the same.
  shift = Eigen::VectorXd::Zero(goal.size()), bestShift = shift;
  shifting = placing || !setup.supports.empty();
  if (!placing) {
    // The setup's own supports carry what they carry at the target.
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& a : supports) sum += a.stiffness * (a.at - target[static_cast<std::size_t>(a.node)]);
    load = sum.norm();
  }
}

// The equilibrium of rest shape k (the k-th static solve) in `state`. Refused (r says why) when nothing can hold the
// organ; Failed (`stop` says why) when the solve did not converge or the shape cannot be simulated.
RestIteration::Solve RestIteration::equilibrium(int k, SimulationState& state, InverseRestResult& r) {
  for (std::size_t i = 0; i < n; ++i) mesh.points[i] = X.segment<3>(static_cast<Eigen::Index>(3 * i));
  try {
    FemModel model = FemModel::build(mesh, setup.byLabel, setup.material);
    if (placing) {
      // The weight of this rest shape, carried at the target.
      SupportPlacement placed =
          placeSupports(mesh.tets, target, model.lumpedMass, setup.fixedNodes, g, options.supportModulus);
      if (!placed.problem.empty() && setup.fixedNodes.empty()) {
        r.status = "Nothing holds the organ: no attachments, and the tissue around it cannot carry it (" +
                   placed.problem + "); hold nodes (H) or change gravity on the Simulation panel.";
        return Solve::Refused;
      }
      supports = std::move(placed.anchors);
      load = placed.load;
    } else {
      supports = setup.supports;
    }
    for (auto& a : supports) a.at += shift.segment<3>(3 * static_cast<Eigen::Index>(a.node));
    model.anchors = supports;
    Integrator integrator(model, setup.fixedNodes, s);
    state = integrator.initialState();
    state.x = X + u;  // from the last solve's displacement: near its equilibrium
    const StepReport rep = integrator.solveStatic(state);
    if (!rep.ok || !state.x.allFinite()) {
      stop = "the static solve from rest shape " + std::to_string(k) + " did not converge (" + rep.status + ")";
      return Solve::Failed;
    }
  } catch (const std::exception& e) {
    stop = std::string("rest shape ") + std::to_string(k) + " cannot be simulated (" + e.what() + ")";
    return Solve::Failed;
  }
  return Solve::Ok;
}

void RestIteration::keepBest(const SimulationState& state, double error) {
  best = error;
  bestX = X;
  bestX_eq = state.x;
  bestSupports = supports;
  bestLoad = load;
  bestShift = shift;
}

// The next rest shape, corrected by the equilibrium's distance from the goal; false (`stop` says why) when no
// correction can go on.
bool RestIteration::correct(const SimulationState& state, double error) {
  // The correction starts from the best rest shape so far (after an overshoot: soft tissue, large sag, with a shorter
  // step), and is shortened while it would turn an element inside out (a sliver of a fine mesh can).
  Eigen::VectorXd base = X, correction = state.x - goal, baseShift = shift;
  if (error > previous) {
    relax *= 0.5;
    base = bestX;
    baseShift = bestShift;
    correction = bestX_eq - goal;
    u = bestX_eq - bestX;
    previous = best;
  } else {
    previous = error;
    u = state.x - X;
  }
  int flipped = -1;
  for (; relax >= 1.0 / 16; relax *= 0.5) {
    X = base - relax * correction;
    if ((flipped = flippedElement(mesh.tets, X, goal)) < 0) break;
  }
  if (shifting) shift = baseShift - relax * rigidPart(correction, goal);
  if (relax < 1.0 / 16) {
    stop = flipped >= 0
               ? "the rest shape would turn element " + std::to_string(flipped) +
                     " inside out (the organ sags too far for its mesh)"
               : "the iteration stopped approaching the shape (error " + mm(error) + " after " + mm(best) + ")";
    return false;
  }
  if (error <= previous) relax = std::min(1.0, 2 * relax);  // back to full corrections while they work
  return true;
}

// The result: the best rest shape and its equilibrium, and what was found.
InverseRestResult& RestIteration::finish(InverseRestResult& r) const {
  if (bestX_eq.size() == 0) {
    r.outcome = r.outcome == InverseRestResult::Outcome::Cancelled ? r.outcome : InverseRestResult::Outcome::Refused;
    r.status = "No rest shape was found: " + stop + ".";
    return r;
  }
  r.rest.resize(n);
  r.equilibrium.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    r.rest[i] = bestX.segment<3>(static_cast<Eigen::Index>(3 * i));
    r.equilibrium[i] = bestX_eq.segment<3>(static_cast<Eigen::Index>(3 * i));
  }
  r.error = best;
  r.sag = largestDistance(bestX, bestX_eq);
  r.supports = bestSupports;
  r.supportLoad = bestLoad;
  if (r.outcome == InverseRestResult::Outcome::Cancelled) {
    r.status = "The rest shape's solve was cancelled.";
  } else if (best <= options.tolerance) {
    r.outcome = InverseRestResult::Outcome::Converged;
    r.status = "Rest shape solved in " + quantity(static_cast<std::size_t>(r.iterations), "static solve", "static solves") +
               ": its equilibrium under gravity is the shape within " + mm(best) +
               "; the rest shape lies up to " + mm(r.sag) + " from it (the sag it takes under gravity)" +
               (r.supportLoad > 0 ? "; the tissue around it carries " + newtons(r.supportLoad) + " of its weight on " +
                                        std::to_string(r.supports.size()) + " surface nodes."
                                  : ".");
  } else {
    r.outcome = InverseRestResult::Outcome::NotConverged;
    r.status = "The rest shape was not found to " + mm(options.tolerance) + ": " +
               (stop.empty() ? "the iterations ran out" : stop) + "; the best one's equilibrium is " + mm(best) +
               " from the shape, so the organ would not stay where the frame shows it: let the tissue around it carry "
               "it (Support on the Simulation panel), stiffen that support, or hold more nodes (H).";
  }
  return r;
}

}  // namespace

InverseRestResult solveRestShape(const BodySetup& setup, const std::vector<Eigen::Vector3d>& target,
                                 const InverseRestOptions& options) {
  InverseRestResult r;
  if (!solvable(setup, target, options, r)) return r;
  RestIteration it(setup, target, options);
  for (int k = 1; k <= std::max(1, options.maxIterations); ++k) {
    SimulationState state;
    const RestIteration::Solve solved = it.equilibrium(k, state, r);
    if (solved == RestIteration::Solve::Refused) return r;
    if (solved == RestIteration::Solve::Failed) break;
    r.iterations = k;
    const double error = largestDistance(state.x, it.goal);
    if (error < it.best) it.keepBest(state, error);
    if (options.progress && !options.progress(k, error)) {
      r.outcome = InverseRestResult::Outcome::Cancelled;
      it.stop = "cancelled";
      break;
    }
    if (error <= options.tolerance) break;
    if (!it.correct(state, error)) break;
  }
  return it.finish(r);
}

bool useRestShape(BodySetup& setup, const std::vector<Eigen::Vector3d>& target, const InverseRestResult& r) {
  if (!r.converged()) return false;
  setup.rest = r.rest;
  setup.start = target;  // exactly where the frame shows it; its equilibrium is within r.error
  setup.tearFrom = target;  // what the instruments stretch is measured from there
  setup.supports = r.supports;
  return true;
}

InverseRestResult startInEquilibrium(BodySetup& setup, const std::vector<Eigen::Vector3d>& target,
                                     const InverseRestOptions& options) {
  InverseRestResult r = solveRestShape(setup, target, options);
  useRestShape(setup, target, r);
  return r;
}

}  // namespace rehearse::simcore
