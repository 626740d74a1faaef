#pragma once
// Tetrahedralisation with CGAL Mesh_3 (kept behind this small interface: CGAL headers are slow to compile).
#include <rehearse/simcore/mesh.hpp>
#include <rehearse/simcore/quality.hpp>

#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace rehearse::simcore {

/// Thrown when a long job was cancelled by its caller.
struct Cancelled : std::runtime_error {
  Cancelled() : std::runtime_error("Cancelled.") {}
};

struct TetrahedraliseOptions {
  std::size_t targetTets = 5000;  ///< wanted element count (used when cellSize == 0)
  double cellSize = 0;            ///< target edge length (m); 0 derives it from targetTets
  bool optimise = true;           ///< exude slivers after refinement (no time limit, so results are reproducible)
  unsigned seed = 0;              ///< Mesh_3's random seed: same input and seed give the same mesh
  /// Mesh surfaces whose outer part intersects itself (inside decided by ray parity) instead of refusing them.
  bool allowSelfIntersections = false;
  /// Called with a fraction in [0, 1] (never decreasing) and a stage name, or with a negative fraction
  /// while a stage of unknown length runs (refinement: its query count; exudation: its element count);
  /// may be called often. Thread: the caller's.
  std::function<void(double, const std::string&)> progress;
  /// Set to true from any thread to cancel; the call then throws Cancelled.
  const std::atomic<bool>* cancel = nullptr;
  /// When set, tetrahedraliseSurface puts here the outer part of the surface as it meshed it (checked, holes
  /// closed, outward, metres, unused points dropped): the organ's own surface, finer than the elements' boundary,
  /// which the views draw (app::VisualSurface).
  Mesh* outerSurface = nullptr;
};

/// Region labels for implicit meshing: 0 outside, > 0 inside (the element label).
using LabelFunction = std::function<int(const Eigen::Vector3d&)>;

/// Meshes an implicit labelled domain inside `bounds` (metres). Labels > 0 become tet labels.
Mesh tetrahedraliseImplicit(const LabelFunction& label, const Eigen::AlignedBox3d& bounds,
                            const TetrahedraliseOptions& options, double volumeEstimate);

/// Result of checking (and possibly repairing) the closed parts of a surface before meshing.
struct SurfaceCheck {
  std::vector<std::string> notes;  ///< one sentence per repair or ignored part
  int outerPart = -1;              ///< triangle label of the outer surface
  std::vector<int> innerParts;     ///< triangle labels of closed parts inside it (vessels, tumours)
  long selfIntersections = 0;      ///< triangle pairs of the outer surface that intersect
  double outerVolume = 0;          ///< m^3
};

/// Checks a surface mesh (metres): closes small holes, orients parts, finds the outer part and the
/// closed parts inside it, counts self-intersections. Throws MeshError with one sentence when
/// the surface cannot be meshed (no closed part, outer part self-intersecting). When `repaired` is
/// given it receives the closed, outward-oriented parts (outer and inner) with their labels.
SurfaceCheck checkSurface(const Mesh& surface, bool allowSelfIntersections = false, Mesh* repaired = nullptr);

/// Counts intersecting triangle pairs of a surface (all parts together); -1 if it could not be computed.
long countSelfIntersections(const Mesh& surface);

/// Tetrahedralises a closed surface (metres). The outer part gets label 1; each closed part inside
/// it gets its own label (2, 3, ...) named after the part. Notes (repairs) are appended to `notes`.
Mesh tetrahedraliseSurface(const Mesh& surface, const TetrahedraliseOptions& options,
                           std::vector<std::string>* notes = nullptr);

}  // namespace rehearse::simcore
