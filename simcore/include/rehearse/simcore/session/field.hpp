#pragma once
// The operative field (simcore, no Qt): what the instruments leave on the tissue and what follows from it, part of
// every checkpoint and snapshot. Clips (the clip applier's, issue 36): each closes the tissue between its jaws (the
// clipped section's nodes pulled together across the jaws, relative to the node the clip moves with, over the clip's
// closing time). Bleeding: every open stump of a cut blood vessel (the cut faces of one vessel label on one side of
// the cut) bleeds at its cross-section times the flow speed of its kind, unless a clip on the same piece of the vessel
// lies behind it; the volume lost is integrated step by step (deterministic: a replay loses the same blood).
#include <rehearse/simcore/mesh.hpp>

#include <Eigen/Core>

#include <array>
#include <functional>
#include <cmath>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct CutSurface;
struct ScalarConstraint;

/// One clip on the tissue.
struct Clip {
  Eigen::Vector3d across = Eigen::Vector3d::UnitZ();  ///< the jaws' closing direction (unit, body frame)
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();    ///< the clipped structure's direction (unit; the clip's width)
  int label = 0;                                      ///< the element label it closed on (0: plain tissue)
  int anchor = -1;                                    ///< the node the clip moves with
  std::vector<int> nodes;    ///< the clipped nodes besides the anchor (of the label's elements, within the jaws)
  std::vector<double> from;  ///< each node's offset along `across` from the clip's centre when placed (m)
  std::vector<double> to;    ///< the offset it is closed to: all within half the gap (m)
  double anchorFrom = 0, anchorTo = 0;  ///< the anchor's offsets, likewise
  double placedAt = 0;                  ///< s, simulated time it was placed
  double gap = 0;                       ///< m, the closed clip's inner gap
  bool spans = true;  ///< the jaws reach across the whole structure there (false: some of it is outside them)
  bool operator==(const Clip&) const = default;
};

/// One open stump of a cut blood vessel.
struct Bleed {
  int label = 0;
  Eigen::Vector3d at = Eigen::Vector3d::Zero();      ///< the stump's centre (m, rest frame of the cut body)
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< out of the vessel into the cut (unit, rest frame)
  int node = -1;                                     ///< the surface node nearest `at` (where the blood is drawn from)
  double area = 0;                                   ///< m^2, the stump's cut faces (the vessel's open cross-section)
  double rate = 0;                                   ///< m^3/s while open
  int stoppedBy = -1;                                ///< the clip behind it (index in OperativeField::clips); -1 open
  double lost = 0;                                   ///< m^3 lost from this stump so far
  bool operator==(const Bleed&) const = default;
};

/// A burnt element's label: its own plus this (so a cut carries the burn with the label, a cut through burnt tissue
/// cuts no named structure and opens no bleeding stump, and the burnt material is the label's own, stiffened).
constexpr int kBurntLabel = 1000000;
inline bool isBurnt(int label) { return label >= kBurntLabel; }
inline int burntLabel(int label) { return isBurnt(label) ? label : label + kBurntLabel; }
inline int unburntLabel(int label) { return isBurnt(label) ? label - kBurntLabel : label; }

struct OperativeField {
  std::vector<Clip> clips;
  std::vector<Bleed> bleeds;
  double bloodLoss = 0;  ///< m^3, all stumps since the start
  bool energy = false;   ///< the cautery hook's power is on
  /// Elements heating under the powered hook: (element, seconds of power within its radius so far), sorted; an element
  /// burns at CauterySettings::burnTime. Cleared by a cut (it renumbers the elements).
  std::vector<std::pair<int, double>> heating;
  /// The named structures' labels energy reached since the power last came on (each said once).
  std::vector<int> energyOn;
  double energyTime = 0;  ///< s the power was on with tissue within the hook's radius
  bool operator==(const OperativeField&) const = default;
};

/// The clip applier's settings (ToolSettings::clip).
struct ClipSettings {
  double length = 0.009;   ///< m, the jaws' length (what lies across them is clipped)
  double width = 0.0015;   ///< m, the clip's width along the structure (at least half an element edge is taken)
  double gap = 0.0005;     ///< m, the closed clip's inner gap
  double closeTime = 0.1;  ///< s, the jaws close over this long
  /// The least share of its width the clip squeezes what lies between its jaws to: a vessel meshed by elements coarser
  /// than itself cannot close to the gap without crushing (inverting) the tissue around it, so the clip closes it as
  /// far as this and says so.
  /// 0.5 by default: the liver preset's StVK tissue around its 3 mm vessels (elements of about 8 mm) inverts below
  /// it (clip-clip-cut.json: 10 of 50 steps at 0.25, none at 0.5).
  double minSqueeze = 0.5;
  bool operator==(const ClipSettings&) const = default;
};

/// The cautery hook's settings (ToolSettings::cautery).
struct CauterySettings {
  double radius = 0.003;    ///< m: elements with a node within this of the powered tip heat
  double burnTime = 0.2;    ///< s of power within the radius that burns an element
  double stiffening = 3.0;  ///< burnt tissue's Young's modulus over its own (coagulated tissue stiffens)
  bool operator==(const CauterySettings&) const = default;
};
/// How fast a cut vessel bleeds (issue 61). physiological: each open stump bleeds what the smaller of two limits
/// allows: the flow through its opening driven by its vessel kind's pressure (the orifice equation, Q = Cd A
/// sqrt(2 dP / rho), Cd 0.61 for a sharp-edged opening: White, Fluid Mechanics, orifice meters), and the flow the
/// vessel carries by its calibre (Murray's law, flow as the cube of the diameter: Murray 1926, PNAS 12:207), from the
/// trunk of its kind (bleedingPhysiology); the organ's open stumps together bleed at most its blood supply
/// (`organSupply`, 1.5 L/min for a liver: Lautt 2009, Hepatic Circulation, ch. 2), shared in proportion when they
/// would exceed it. false: a stump's cut area times a speed by kind (0.30 m/s for an artery: one cut vessel of the
/// phantom bled 104 mL/s, more than the heart pumps; the sessions recorded before this existed).
struct BleedingSettings {
  bool physiological = true;
  double organSupply = 1.5e-3 / 60;  ///< m^3/s: the most all open stumps bleed together (the organ's inflow)
  bool operator==(const BleedingSettings&) const = default;
};
/// A vessel kind's physiology for its bleeding: mean pressure over the surroundings (Pa), its trunk's diameter (m)
/// and the flow the trunk carries (m^3/s). Artery (the hepatic artery proper): 90 mmHg, 4.5 mm, 0.35 L/min (a quarter
/// of the liver's inflow); portal vein: 8 mmHg (normal 5-10), 12 mm (Weinreb 1982, AJR 139:497, sonography),
/// 1.1 L/min (three quarters); vein (a hepatic vein) and a vessel of no stated kind: 5 mmHg (central venous pressure
/// 2-8), 10 mm, 0.5 L/min (a third of the outflow). All zero for what is not a blood vessel.
struct VesselPhysiology {
  double pressure = 0, trunkDiameter = 0, trunkFlow = 0;
};
VesselPhysiology bleedingPhysiology(StructureKind kind);
/// m^3/s: what one open stump of `area` (m^2, its opening) of a vessel of `kind` bleeds under BleedingSettings::
/// physiological, before the organ's total bound: min(orifice flow, the trunk's flow times (D / D_trunk)^3 for
/// D = 2 sqrt(area / pi), at most the trunk's flow).
double stumpBleedRate(StructureKind kind, double area);
/// Rates made to fit the organ's supply: when the open stumps (stoppedBy < 0) of `bleeds` bleed more than `supply`
/// together, each open one's rate is scaled by the same factor so that they bleed `supply`. Returns the factor (1
/// when within it).
double boundToSupply(std::vector<Bleed>& bleeds, double supply);

/// The class of haemorrhage a blood loss of `lost` (m^3) is for an adult of 70 kg (70 mL/kg, 4.9 L of blood; ATLS,
/// American College of Surgeons, 10th edition, 2018): 1 up to 15 % of it (750 mL), 2 up to 30 % (1,500 mL), 3 up to
/// 40 % (2,000 mL), 4 beyond; 0 for no loss.
int haemorrhageClass(double lost);
/// The words for a class of haemorrhage ("more than 30 % of an adult's blood, a class III haemorrhage"); empty for 0.
std::string haemorrhageWords(int haemorrhageClass);

/// Why these settings cannot burn (a radius below 0, a burn time or stiffening not above 0: burnt tissue would have
/// no stiffness, and every burn would be refused), in words; empty when they can. (Inline: the recording codec's
/// fuzzer links the codec without the session.)
inline std::string cauteryProblem(const CauterySettings& c) {
  if (!std::isfinite(c.radius) || c.radius < 0) return "the cautery hook's radius is not a non-negative number";
  if (!std::isfinite(c.burnTime) || c.burnTime <= 0) return "the cautery hook's burn time is not a positive number";
  if (!std::isfinite(c.stiffening) || c.stiffening <= 0)
    return "the stiffening of burnt tissue is not a positive number (burnt tissue would have no stiffness)";
  return {};
}

/// Where a clip closes when the jaws close at `tip` with the shaft coming from `trocar`: on the element label nearest
/// the tip within `reach` (a vessel's or a duct's first, `kindOf`, as a surgeon closes the clip on the vessel beside
/// the tissue), the nodes of that label's elements within the jaws (the clip's length across the
/// structure, its width along it, `across` either side), pulled together along `across` (given, or the shaft's
/// direction made perpendicular to the structure). `aimed` (a label, 0 for none) is the structure the user aimed the
/// jaws at (the GUI's clip applier names the vessel under the cursor): when an element of it is within reach of the tip
/// (a node within reach, or holding the tip), the clip closes on it, whatever else is nearer, since the view the user
/// aimed in shows the tissue a few steps behind the session; when none is, the rules above, and `message` says the
/// aimed structure was out of reach. `message` says why no clip was placed (nothing within reach), or that the clip
/// does not span the structure. Positions: the nodes now (3 per node).
Clip placeClip(const Eigen::VectorXd& x, const std::vector<std::array<int, 4>>& tets, const std::vector<int>& labels,
               const std::vector<char>& fixed, const Eigen::Vector3d& tip, const Eigen::Vector3d& trocar,
               const Eigen::Vector3d& across, double reach, const ClipSettings& s, double time,
               const std::function<StructureKind(int)>& kindOf, std::string& message, int aimed = 0);
/// The rows that hold every clip's nodes at their offsets at `time` (closing linearly over `closeTime`), each
/// relative to the clip's anchor (weights 1 and -1: the clip's force is internal, not the instrument's).
void clipRows(const OperativeField& f, double time, double closeTime, std::vector<ScalarConstraint>& rows);
/// A clip the tissue did not let close: when its rows at `time` are off by more than `tolerance` (m) at positions `x`
/// (a step the inversion guard held back ended there: closing further would turn the elements around it inside out),
/// it stays as far as it closed, its offsets from now on the ones its nodes have. Returns the width it holds across
/// its jaws (m), or a negative number when its rows were met (nothing changed).
double settleHeldBackClip(Clip& c, const Eigen::VectorXd& x, double time, double closeTime, double tolerance);
/// m/s: the mean flow speed a stump of this kind bleeds at (artery 0.30, portal vein 0.15, vein and unnamed vessel
/// 0.10; 0 for anything that is not a blood vessel).
double bleedSpeed(StructureKind kind);
/// The open stumps of the cut vessels on `surface` (rest positions of the cut body, its elements and labels), each
/// stopped by a clip on the same piece of its vessel that lies behind it; `kindOf(label)` names the labels. Stumps
/// that were there before (`previous`, the same label within an element edge) keep what they lost.
/// `bleeding` chooses the rates (BleedingSettings).
std::vector<Bleed> findBleeds(const CutSurface& surface, const std::vector<std::array<int, 4>>& tets,
                              const std::vector<int>& labels, const std::vector<Clip>& clips,
                              const std::vector<Bleed>& previous, const std::function<StructureKind(int)>& kindOf,
                              double meanEdge, const BleedingSettings& bleeding = BleedingSettings{false});

}  // namespace rehearse::simcore
