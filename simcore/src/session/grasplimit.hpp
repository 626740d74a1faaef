#pragma once
// Where the jaws let go (ToolSettings::slipAtLimit, slipResolved): shared by the grasper (instrument.cpp) and the
// session's hold-back and step taken again (session.cpp).
namespace rehearse::simcore {
/// Held back at the limit, the tissue slips once the force a step solved is at least this share of the maximum.
inline constexpr double kLetGoShare = 0.95;
/// A held-back step's force more than this share of the maximum is taken again (slipResolved).
inline constexpr double kPastTheLimit = 1.02;
/// A slip's force up to this share of the maximum is the limit reached within one step's change (said so); beyond it,
/// on a step that did not converge, the force read is not the tissue's at equilibrium (instrument.cpp).
inline constexpr double kWithinOneStep = 1.25;
}  // namespace rehearse::simcore
