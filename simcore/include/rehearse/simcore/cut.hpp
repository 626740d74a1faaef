#pragma once
// Cutting a tetrahedral mesh by re-meshing (issue 15): the blade's swept surface for one cut update is a
// planar quad (the blade is a segment on the shaft, and every shaft passes through the trocar, so two
// poses of it span a plane). The tetrahedra the quad crosses are split along it, not deleted:
//  - each node gets the side of the plane it lies on; a crossing closer than `snap` of its edge to a node
//    passes through that node instead (snapping: no sliver next to a node);
//  - a crossed element whose crossing lies inside the quad is split into its two sides, each side (a
//    convex polytope: the element's vertices on that side, the crossing points on its edges and the
//    snapped nodes) triangulated on its faces and coned from its centroid. Faces are triangulated by rules
//    that depend only on the face's own points and global node numbers, so neighbours agree and the mesh
//    stays conforming; elements that only share a crossed edge (the cut's front) are refined the same way
//    without being separated;
//  - the two sides are separated where they meet: every node on a separated face is duplicated once per
//    group of its elements still connected through unseparated faces, so the cut opens exactly where the
//    blade passed and stays closed at its front.
// New nodes are interpolations of old ones (the caller carries positions, velocities and the rest shape
// across with `extendByCut`); the pieces tile each element exactly, so volume and mass are conserved. A
// piece below the stated quality or volume makes the nearer node snap instead (repeatedly), and a cut that
// cannot be made within the bounds is refused with a sentence, leaving the mesh unchanged.
#include <Eigen/Core>

#include <array>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct CutSettings {
  double snap = 0.2;               ///< crossings nearer a node than this fraction of their edge pass through the node
  /// No new element below this shape quality (tetShapeQuality: 1 regular, 0 flat). A fixed floor, not one
  /// relative to the parent, so repeated cuts cannot wear it down; the session lowers it to half the uncut
  /// mesh's worst element when that is poorer (such an element could not be cut otherwise).
  double minQuality = 0.03;
  double minVolumeFraction = 1e-3; ///< nor below this fraction of its parent's volume
  /// The cut's front: false refines the elements beyond it that share a crossed edge (the next update
  /// splits them); true snaps those crossings to the nearer node instead (fewer elements, a jagged front).
  bool snapFront = true;
};

/// The planar quad swept by the blade between two poses, in the current configuration (m): the blade's
/// segment a0-b0 at the previous pose and a1-b1 now (a: the tip end).
struct BladeSweep {
  Eigen::Vector3d a0 = Eigen::Vector3d::Zero(), b0 = Eigen::Vector3d::Zero(), a1 = Eigen::Vector3d::Zero(), b1 = Eigen::Vector3d::Zero();
};

/// A continuous cut between updates (see cutTetrahedra).
struct CutProgress {
  std::vector<std::array<int, 3>> pendingFaces;
  std::vector<int> nodes;
  std::vector<BladeSweep> sweeps;
  void clear() { *this = {}; }
};

/// A node the cut added: a weighted sum of nodes that existed before it (weights sum to 1; unused: -1).
struct CutNode {
  std::array<int, 4> from{-1, -1, -1, -1};
  std::array<double, 4> weight{0, 0, 0, 0};
};

struct CutResult {
  bool changed = false;
  std::string status;              ///< one sentence: what the cut did, or why it did nothing
  std::vector<CutNode> newNodes;   ///< appended after the old nodes, in this order
  std::vector<int> duplicateOf;    ///< per new node: the old node it copies (a separated node), else -1
  std::size_t splitElements = 0;   ///< elements separated into two sides
  std::size_t refinedElements = 0; ///< elements at the cut's front refined without separation
  std::size_t separatedFaces = 0;
  std::size_t duplicatedNodes = 0;
  std::size_t skippedInverted = 0; ///< crossed elements not cut because they are inverted now
  std::vector<int> cutLabels;      ///< element labels on the separated faces (sorted, unique)
  double minQuality = 1;           ///< over the new elements (rest shape)
  double minVolumeFraction = 1;    ///< of a new element's volume to its parent's
};

/// Shape quality of a tetrahedron: 6 sqrt(2) |V| / l_rms^3 (1 for the regular tetrahedron, 0 when flat).
double tetShapeQuality(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d);

/// Cuts the mesh in place: `rest` and `current` (per node, m) grow by the new nodes, `tets` and `labels`
/// are re-meshed (replaced elements keep their index for their first piece; the others are appended).
/// `progress` (in/out, may be null): a continuous cut's state between updates: the faces on it that have not
/// opened yet (at its front), the nodes on it (they stay on it, whatever the snapping did), and the sweeps so
/// far (a face between the two sides opens when it lies in any of them, not only in the latest strip).
CutResult cutTetrahedra(std::vector<Eigen::Vector3d>& rest, std::vector<Eigen::Vector3d>& current, std::vector<std::array<int, 4>>& tets,
                        std::vector<int>& labels, const BladeSweep& blade, const CutSettings& settings = {}, CutProgress* progress = nullptr);

/// A 3n node-major vector (positions, velocities) extended by the cut's new nodes.
void extendByCut(Eigen::VectorXd& v, const std::vector<CutNode>& newNodes);

}  // namespace rehearse::simcore
