#pragma once
// Hyperelastic materials for tetrahedral FEM, written on the deformation gradient F (3x3):
// energy density psi(F) (J/m^3), first Piola-Kirchhoff stress P = dpsi/dF (Pa) and its derivative
// dP/dF applied to a direction (the tangent used for stiffness matrices).
//   linear:        psi = mu |eps|^2 + lambda/2 tr(eps)^2,          eps = (F + F^T)/2 - I
//   corotational:  psi = mu |F - R|^2 + lambda/2 tr(R^T F - I)^2,  F = R S (polar; SOFA's "large")
//   StVK:          psi = mu |E|^2 + lambda/2 tr(E)^2,              E = (F^T F - I)/2
//   Neo-Hookean:   stable form of Smith, de Goes, Kim (2018):
//                  psi = mu'/2 (tr(F^T F) - 3) + lambda'/2 (J - alpha)^2, alpha = 1 + mu'/lambda',
//                  mu' = mu, lambda' = lambda + mu (then it linearises to the same small-strain law);
//                  defined for inverted elements (J <= 0).
//   Neo-Hookean, split (CalculiX's and Abaqus' *HYPERELASTIC, NEO HOOKE), for validation:
//                  psi = C10 (J^-2/3 I1 - 3) + (J - 1)^2 / D1, C10 = mu/2, D1 = 2/K, K = lambda + 2 mu/3;
//                  the same small-strain law, but not defined for inverted elements (J clamped > 0).
#include <Eigen/Core>

#include <string>

namespace rehearse::simcore {

enum class MaterialModel { Linear, Corotational, StVK, NeoHookean, NeoHookeanSplit };

/// Parses "linear", "corotational", "stvk", "neohookean", "neohookean-split"; throws MeshError naming the accepted values.
MaterialModel materialModelFromString(const std::string& name);
std::string toString(MaterialModel m);

struct Lame {
  double mu = 0, lambda = 0;
  /// The corotational law's volume barrier (0: none): below this J = det F an element's energy gains
  /// kVolumeBarrierStiffness (lambda + mu) b(J), b(J) = -(J - Jb)^2 ln(J / Jb), which is zero with its first two
  /// derivatives at Jb and grows without bound as J -> 0 (the barrier of Li et al. 2020, IPC, on the volume instead of
  /// a distance). The corotational energy alone stays finite for a flat element, so a tool or a cut's neighbours can
  /// crush one flat; the inversion guard then stops its nodes at its floor and no step converges again (measured on the
  /// patient liver at 16k elements: BENCHMARKS.md). With the barrier the equilibrium itself keeps the element open.
  double barrier = 0;
  /// From Young's modulus E (Pa) and Poisson's ratio nu (0 <= nu < 0.5).
  static Lame fromYoung(double E, double nu) {
    return {E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))};
  }
};

/// The volume barrier's weight over lambda + mu, and the J below which SimulationSettings::volumeBarrier sets it.
constexpr double kVolumeBarrierStiffness = 10;
constexpr double kVolumeBarrierJ = 0.3;

double energyDensity(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F);
Eigen::Matrix3d firstPiola(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F);
/// dP = (dP/dF)[dF].
Eigen::Matrix3d firstPiolaDifferential(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F, const Eigen::Matrix3d& dF);

/// What the tangent of one element needs that does not depend on the direction (the polar
/// decomposition for the corotational model): prepare once, then apply to the 12 nodal directions.
struct TangentCache {
  Eigen::Matrix3d R, S, Ginv;
};
TangentCache prepareTangent(MaterialModel m, const Eigen::Matrix3d& F);
/// P from a prepared cache (no second polar decomposition for the corotational model).
Eigen::Matrix3d firstPiola(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F, const TangentCache& cache);
Eigen::Matrix3d firstPiolaDifferential(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F, const TangentCache& cache,
                                       const Eigen::Matrix3d& dF);

/// Polar decomposition F = R S with R a rotation (det +1) even for inverted F.
void polarDecomposition(const Eigen::Matrix3d& F, Eigen::Matrix3d& R, Eigen::Matrix3d& S);

}  // namespace rehearse::simcore
