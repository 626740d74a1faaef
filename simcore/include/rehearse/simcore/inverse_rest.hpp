#pragma once
// The registered shape as the starting equilibrium (issue 34): the rest shape that sags into a given shape under the
// body's own loads (gravity, on its attachments), so that a rehearsal starting from the organ as the frame shows it
// stays there until an instrument acts. Inverse elastostatics by Sellier's fixed point (Sellier 2011, "An iterative
// method for the inverse elasto-static problem", J. Fluids Struct. 27): X_{k+1} = X_k - w (x(X_k) - target), x(X) the
// static equilibrium from rest X (Newton, exact tangent), each solve started from the last one's displacement. The
// material's own stiffness and density are kept (the mass is density times the rest shape's volume); the attachments
// stay where the target has them.
#include <rehearse/simcore/session/body.hpp>

#include <functional>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct InverseRestOptions {
  double tolerance = 1e-5;  ///< m: the largest node distance between the rest shape's equilibrium and the target
  int maxIterations = 40;
  /// Pa/m: the tissue around the organ carries it (support.hpp): the supports are placed on the target for the
  /// weight of each rest shape tried, and the result's `supports` are the last ones. 0: the setup's supports as given.
  double supportModulus = 0;
  /// After each iteration: its number (1-based) and the largest node distance (m); false cancels.
  std::function<bool(int iteration, double error)> progress;
};

struct InverseRestResult {
  enum class Outcome { Converged, NotConverged, Refused, Cancelled };
  Outcome outcome = Outcome::Refused;
  std::vector<Eigen::Vector3d> rest;         ///< the rest shape (m, the target's frame)
  std::vector<Eigen::Vector3d> equilibrium;  ///< its static equilibrium under the loads (within `error` of the target)
  std::vector<NodeAnchor> supports;          ///< the supports it stands on (the setup's, or those placed)
  double supportLoad = 0;                    ///< N: the weight the supports carry at the target (0 without)
  double error = 0;                          ///< m: the largest node distance between equilibrium and target
  double sag = 0;                            ///< m: the largest node distance between rest and equilibrium
  int iterations = 0;                        ///< static solves done
  std::string status;                        ///< one sentence: what was found, or why not
  bool converged() const { return outcome == Outcome::Converged; }
};

/// The rest shape whose equilibrium under `setup`'s gravity, held at `setup.fixedNodes`, is `target` (one position per
/// node of setup.mesh, metres), standing on the setup's supports or on those placed (options.supportModulus).
/// `setup.rest` and `setup.start` are not read. Without gravity the target is its own
/// rest shape (no solve). Refused, with a sentence, when nothing holds the body under gravity, the target does not
/// match the mesh or is not finite, or an element of the target is inverted. Never throws for a numerical failure: a
/// static solve that fails or an iteration that stops approaching the target ends with NotConverged and the best rest
/// shape found (its equilibrium and error said).
InverseRestResult solveRestShape(const BodySetup& setup, const std::vector<Eigen::Vector3d>& target,
                                 const InverseRestOptions& options = {});

/// `setup` made to start from `target` on a solved rest shape `r` (solveRestShape for this setup and target): rest
/// `r.rest`, start `target`, supports `r.supports`. Nothing changes unless `r` converged; true when it did.
bool useRestShape(BodySetup& setup, const std::vector<Eigen::Vector3d>& target, const InverseRestResult& r);

/// `setup` made to start from `target` in equilibrium: its rest shape solved (solveRestShape), `start` the target
/// itself (its equilibrium lies within the result's error of it, so the organ moves at most that far without an
/// instrument). Unchanged (with the result saying why) unless the solve converged.
InverseRestResult startInEquilibrium(BodySetup& setup, const std::vector<Eigen::Vector3d>& target,
                                     const InverseRestOptions& options = {});

}  // namespace rehearse::simcore
