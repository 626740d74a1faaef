#pragma once
// The tissue around an organ that carries it besides its attachments (issue 61). In the abdomen the liver, kidney or
// uterus rests on the organs, fat and connective tissue beneath it: a registered organ held only at a few picked nodes
// has no equilibrium at its registered shape (it hangs from a thin edge, or falls). The surface that faces along
// gravity rests on an elastic foundation (Winkler 1867: a bed of independent springs, pressure = modulus x
// displacement), the boundary condition the patient-specific liver models give the surrounding organs as springs on
// the organ's surface (Plantefeve et al. 2016, Ann Biomed Eng 44(1): ligaments and the surrounding tissue as springs;
// Nikolaev et al. 2020, IEEE TMI 39(5): its stiffness estimated, of the order used here). The foundation's modulus is the
// surrounding tissue's Young's modulus over the depth it deforms through: a few kPa (Kerdok et al. 2006, in-vivo
// porcine liver and abdominal viscera) over a few centimetres, about 1e5 Pa/m (0.1 kPa per mm).
//
// At the registered shape the springs are preloaded so that together they carry the organ's weight with its resultant
// through the organ's centre of mass: the support's pressure varies linearly across its footprint (the classical
// eccentric footing), so the organ needs nothing else to stand still where the frame shows it. Held nodes carry no
// spring (they are held). Each spring is zero-length from its node to a point above the registered position along
// -gravity; a node's stiffness is the modulus times its share of the footprint (the surface's area projected along
// gravity), so the foundation's stiffness together is the modulus times the footprint's area.
#include <rehearse/simcore/fem.hpp>

#include <Eigen/Core>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct SupportPlacement {
  std::vector<NodeAnchor> anchors;  ///< one per supported node
  double area = 0;                  ///< m^2: the footprint carried (projected along gravity; held nodes excluded)
  double load = 0;                  ///< N: the weight the springs carry together
  double stiffness = 0;             ///< N/m: their stiffness together
  int pulling = 0;                  ///< supported nodes whose spring pulls (the centre of mass lies off the footprint)
  std::string problem;              ///< why none could be placed (empty when placed)
};

/// Springs from the surface of `tets` at `shape` (m) that faces along `gravity` (m/s^2), held nodes excluded, carrying
/// the weight of `lumpedMass` (kg per node) at `shape` with their resultant through its centre of mass. `modulus`:
/// the foundation's, Pa/m (N/m per m^2 of surface). Nothing placed (and `problem` says why) without gravity, with a
/// modulus that is not positive, or when no surface faces along gravity.
SupportPlacement placeSupports(const std::vector<std::array<int, 4>>& tets, const std::vector<Eigen::Vector3d>& shape,
                               const Eigen::VectorXd& lumpedMass, const std::vector<int>& fixedNodes,
                               const Eigen::Vector3d& gravity, double modulus);

/// The nodes that hold the organ for its picked attachments. A ligament attaches over an area, not at a point: one pinned
/// node is a point constraint whose own elements a pull anywhere crushes (the BodyParts3D liver held by one pick and
/// pulled 20 mm, 60 mm away: its elements at the pick at 1-2 % of their volume, 127-150 of 150 steps inexact; held by
/// the pick and its neighbours on the surface, the worst element at 49 % and every step converged). So a lone pick (no
/// other pick among its neighbours on the surface) holds its neighbours on the surface too: the nodes that share a
/// boundary triangle with it (the nodes that share an element with it, for a pick inside the organ). Picks beside
/// other picks (along an edge, a region) hold as picked. Sorted, without repeats; node numbers outside the mesh are
/// kept as given (the body refuses them with its own sentence). `lone` (may be null): how many picks were lone.
std::vector<int> attachmentPatches(const Mesh& volume, const std::vector<int>& picked, std::size_t* lone = nullptr);

/// The default foundation modulus, Pa/m (see above).
constexpr double kDefaultSupportModulus = 1e5;

}  // namespace rehearse::simcore
