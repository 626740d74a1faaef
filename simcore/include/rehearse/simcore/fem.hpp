#pragma once
// Tetrahedral FEM, element level and assembly: the immutable model (rest shape, materials by label)
// and, for nodal positions x (3n, metres, node-major xyz), the elastic energy (J), the nodal elastic
// forces f = -dE/dx (N) and the stiffness K = d^2E/dx^2 (N/m). Integrators and solvers build on these.
#include <rehearse/simcore/material.hpp>
#include <rehearse/simcore/mesh.hpp>

#include <Eigen/Sparse>

#include <map>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct MaterialParams {
  MaterialModel model = MaterialModel::Corotational;
  double young = 3000;    ///< Pa
  double poisson = 0.3;   ///< 0 <= nu < 0.5
  double density = 1000;  ///< kg/m^3
  /// The engineering strain at which this material tears: its largest principal stretch minus 1 (a bar pulled to
  /// 1 + tearStrain times its length). The session splits an element stretched past it across its stretch, through
  /// the cut's re-meshing (Session: tearing). 0: it does not tear.
  double tearStrain = 0;
};

/// An inner structure (vessels, a tumour) given as its own closed or open triangle surface, embedded in
/// the volume by barycentric mapping: each surface vertex follows the tetrahedron that contains it
/// (x_s = J x), and the surface's own stiffness, a membrane of edge springs, acts back on the volume's
/// nodes (f += J^T f_s, K += J^T K_s J). The surface is massless.
struct EmbeddedSurface {
  Mesh surface;             ///< triangles; its unit as loaded
  double young = 620e3;     ///< Pa, of the wall
  double thickness = 1e-3;  ///< m, of the wall
  std::string name;
};

/// Where each vertex of an embedded surface sits: a tetrahedron's nodes and barycentric weights.
struct SurfaceEmbedding {
  std::string name;
  std::vector<std::array<int, 4>> nodes;
  std::vector<Eigen::Vector4d> weights;
  std::vector<std::array<int, 3>> triangles;
  std::size_t outside = 0;  ///< vertices outside every tetrahedron (mapped to the nearest one, extrapolated)
  double farthestOutside = 0;  ///< m, the largest distance of such a vertex from its tetrahedron
};

/// A spring between two mapped points (p = sum w_i x_i over the first four nodes, q over the last four).
struct EmbeddedSpring {
  std::array<int, 8> nodes;
  std::array<double, 8> weights;  ///< +w for p's nodes, -w for q's (so p - q = sum weights * x)
  double stiffness = 0;           ///< N/m
  double restLength = 0;          ///< m
};

/// A node held elastically to a point: force -stiffness (x - at), zero-length. The tissue around an organ carrying it
/// (BodySetup::supports, support.hpp).
struct NodeAnchor {
  int node = 0;
  Eigen::Vector3d at = Eigen::Vector3d::Zero();  ///< m
  double stiffness = 0;                          ///< N/m
  bool operator==(const NodeAnchor& o) const { return node == o.node && at == o.at && stiffness == o.stiffness; }
};

struct FemModel {
  std::vector<Eigen::Vector3d> rest;        ///< rest positions (m)
  std::vector<std::array<int, 4>> tets;
  std::vector<Eigen::Matrix3d> Bm;          ///< inverse rest edge matrix per tet
  std::vector<double> restVolume;           ///< m^3 (positive)
  std::vector<MaterialModel> model;         ///< per tet
  std::vector<Lame> lame;                   ///< per tet
  Eigen::VectorXd lumpedMass;               ///< per node (kg)
  /// Sparsity pattern of the 3n x 3n stiffness (values zero), where each element's 12x12 block goes
  /// (elementSlots[e][12 * col + row] indexes the pattern's value array), and where the diagonal entries are.
  Eigen::SparseMatrix<double> pattern;
  std::vector<std::array<int, 144>> elementSlots;
  std::vector<int> diagonalSlot;
  std::vector<SurfaceEmbedding> embeddings;
  std::vector<EmbeddedSpring> springs;
  std::vector<std::array<int, 576>> springSlots;  ///< 24x24 blocks, column-major, like elementSlots
  /// Nodes held elastically to points (set after build; their energy, forces and stiffness join the material's).
  std::vector<NodeAnchor> anchors;

  std::size_t nodeCount() const { return rest.size(); }
  /// Bytes held by the model, including the per-element scratch of assembly (144 doubles per tet).
  std::size_t memoryBytes() const {
    return rest.size() * sizeof(Eigen::Vector3d) + tets.size() * (sizeof(std::array<int, 4>) + sizeof(Eigen::Matrix3d) + 2 * sizeof(double) +
                                                                  sizeof(Lame) + 144 * (sizeof(int) + sizeof(double))) +
           static_cast<std::size_t>(pattern.nonZeros()) * (sizeof(double) + sizeof(int)) + diagonalSlot.size() * sizeof(int) +
           springs.size() * (sizeof(EmbeddedSpring) + 576 * sizeof(int));
  }
  /// Builds from a volume mesh (metres): materials by tet label; labels not in the map use `fallback`.
  /// Throws MeshError for empty meshes, degenerate rest elements or invalid parameters.
  /// Embedded surfaces (optional) add their springs; their vertices must lie inside the volume (those
  /// outside are mapped to the nearest tetrahedron and counted in SurfaceEmbedding::outside).
  static FemModel build(const Mesh& mesh, const std::map<int, MaterialParams>& byLabel, const MaterialParams& fallback,
                        const std::vector<EmbeddedSurface>& embedded = {});
  Eigen::VectorXd restVector() const;  ///< 3n
};

/// Sets the corotational elements' volume barrier (Lame::barrier) to J below which it acts (0: none), as
/// SimulationSettings::volumeBarrier asks of a simulated body.
void setVolumeBarrier(FemModel& m, double J);

/// Positions of an embedded surface's vertices for nodal positions x (the mapping x_s = J x).
std::vector<Eigen::Vector3d> mapEmbedded(const FemModel& m, std::size_t which, const Eigen::VectorXd& x);
/// Barycentric embedding of points (metres, rest frame) in the model's tetrahedra (markers, probes).
SurfaceEmbedding embedPoints(const FemModel& m, const std::vector<Eigen::Vector3d>& points);
/// The same on a bare tetrahedral mesh (rest positions, elements): each point takes the tetrahedron that holds
/// it, or, outside them all, the nearest one (by distance), its barycentric weights then extrapolating the
/// element's affine map (so an affine motion of the nodes moves every point exactly). Degenerate (flat)
/// tetrahedra hold nothing. Throws MeshError when there is no usable tetrahedron.
SurfaceEmbedding embedPoints(const std::vector<Eigen::Vector3d>& rest, const std::vector<std::array<int, 4>>& tets,
                             const std::vector<Eigen::Vector3d>& points);
/// Positions of embedded points for nodal positions (one per node).
std::vector<Eigen::Vector3d> mapEmbedded(const SurfaceEmbedding& e, const std::vector<Eigen::Vector3d>& nodes);
std::vector<Eigen::Vector3d> mapEmbedded(const SurfaceEmbedding& e, const Eigen::VectorXd& x);

double elasticEnergy(const FemModel& m, const Eigen::VectorXd& x);
/// f = -dE/dx, size 3n.
Eigen::VectorXd elasticForces(const FemModel& m, const Eigen::VectorXd& x);
/// Same, into f (sized once, then reused; elements in parallel, summed in a fixed order).
void elasticForces(const FemModel& m, const Eigen::VectorXd& x, Eigen::VectorXd& f);
/// K = d^2E/dx^2 (symmetric), 3n x 3n, with the model's sparsity pattern.
Eigen::SparseMatrix<double> elasticStiffness(const FemModel& m, const Eigen::VectorXd& x);
/// Per-element tangent data at a configuration, for matrix-free products K(x) v: one pass of polar
/// decompositions, then each product costs one stress differential per element (not 12 as assembly).
struct TangentState {
  std::vector<Eigen::Matrix3d> F;
  std::vector<TangentCache> cache;
  std::vector<Eigen::Matrix3d> springHessian;
};
/// With `forces`, also the elastic forces at x from the same pass (f = -dE/dx, as elasticForces).
void prepareTangentState(const FemModel& m, const Eigen::VectorXd& x, TangentState& state, Eigen::VectorXd* forces = nullptr);
/// out = K(x) v for the configuration `state` was prepared at (out sized once, then reused).
void applyStiffness(const FemModel& m, const TangentState& state, const Eigen::VectorXd& v, Eigen::VectorXd& out);
/// out = a K(xa) v + b K(xb) v for two configurations prepared over the same model (one pass over the elements: the
/// Newton-Krylov tangent, h^2 K at the iterate plus the Rayleigh damping's h beta K at the step start).
void applyStiffnessPair(const FemModel& m, const TangentState& atA, double a, const TangentState& atB, double b,
                        const Eigen::VectorXd& v, Eigen::VectorXd& out);
/// Von Mises equivalent of the Cauchy stress sigma = P F^T / J per element (Pa), for display. Inverted
/// elements (J <= 0) report the first Piola-Kirchhoff stress's equivalent instead.
void vonMisesStress(const FemModel& m, const Eigen::VectorXd& x, std::vector<double>& out);
/// Same, into an existing matrix that has the model's pattern (no allocation; elements in parallel).
/// Projected Newton's tangent (TangentProjection): a positive semi-definite K for indefinite states such as inverted,
/// strongly compressed or torn elements, element by element.
enum class TangentProjection {
  None,     ///< the tangent as it is
  Element,  ///< each element's 12x12 matrix with its negative eigenvalues set to zero (sessions recorded before
            ///< SimulationSettings::checkedProjection)
  Checked,  ///< the same, only for the elements whose 9x9 stress tangent dP/dF a Cholesky shows not positive
            ///< definite (the others' matrices are positive semi-definite already and are kept bit for bit)
};
void assembleStiffness(const FemModel& m, const Eigen::VectorXd& x, Eigen::SparseMatrix<double>& K,
                       TangentProjection projection = TangentProjection::None);

/// Volume ratios J = det F (deformed over rest signed volume) at positions x: how many elements are inverted
/// (J <= 0), the smallest J and its element. With `inverted`, the inverted elements' indices (ascending).
struct VolumeRatios {
  int inverted = 0;
  double smallest = 1;
  int smallestElement = -1;
};
VolumeRatios volumeRatios(const FemModel& m, const Eigen::VectorXd& x, std::vector<int>* inverted = nullptr);
/// The laws that are not defined for inverted elements, whose steps are kept from inverting them (linear,
/// corotational, neohookean-split). StVK and the stable Neo-Hookean are not guarded: StVK collapses under strong
/// compression (its energy vanishes for a flat element and rises again inverted) and the stable Neo-Hookean is
/// defined inverted (it pushes the element back); their inverted elements are reported.
bool guardsInversion(MaterialModel m);
/// The volume a guarded element keeps: J >= max(eta J(reference), smallest), reference being the step's start (x
/// itself when null); an element already below that keeps eta of its J at x.
struct InversionFloor {
  const Eigen::VectorXd* reference = nullptr;
  double eta = 0.1;
  double smallest = 0.01;
};
/// Largest s in [0, 1] such that along x + s' dx, s' in [0, s], every guarded element that is not inverted (at x
/// and at the reference) keeps J = det F above its floor: the roots of each element's cubic det F(s'), found
/// exactly (monotone pieces, bisection). Exactly 1 when nothing limits the move. With `limiting`, every element whose
/// own limit is below 1.
double inversionFreeStep(const FemModel& m, const Eigen::VectorXd& x, const Eigen::VectorXd& dx, const InversionFloor& floor = {},
                         std::vector<int>* limiting = nullptr);

}  // namespace rehearse::simcore
