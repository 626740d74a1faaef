#pragma once
// Instruments (simcore, no Qt): what an instrument holds, what it asks of the body at a step boundary, and the events
// it emits, behind one small interface the session runs without knowing their kinds. The grasper (jaws: a bite holds
// nodes, the hold's rows, a slip above the scene's maximum force) and the scissors/hook (a blade: its sweep cuts the
// tissue through the session's topology change) and the clip applier (a clip left in the operative field, field.hpp)
// and the cautery hook (burns tissue through a topology change that relabels it) live in instrument.cpp, listed in
// makeInstruments().
//
// The instrument's state is the session's ToolState (one instrument in the hand at a time, part of every checkpoint),
// so a recording replays bit for bit whatever instrument made it.
#include <rehearse/simcore/constraint_solver.hpp>
#include <rehearse/simcore/session/body.hpp>
#include <rehearse/simcore/session/field.hpp>

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct ToolState;
struct InputEvent;
enum class InputKind;

/// What an instrument may ask of the session at a step boundary.
class InstrumentHost {
 public:
  virtual ~InstrumentHost() = default;
  virtual const Eigen::VectorXd& positions() const = 0;  ///< the nodes now (m), 3 per node
  virtual const std::vector<char>& fixedMask() const = 0;
  virtual const ToolSettings& tools() const = 0;
  virtual const SimulationSettings& settings() const = 0;  ///< the time step and method in use
  virtual double meanEdge() const = 0;                   ///< of the uncut mesh (m)
  /// The jaws were held back this step to let go at the grasp limit (ToolSettings::slipAtLimit): let go now.
  virtual bool jawsAtGraspLimit() const { return false; }
  /// Whether the step just taken converged (an inexact step's forces are not the equilibrium's: a force read there is
  /// said with that word).
  virtual bool stepConverged() const { return true; }
  virtual void emitEvent(const std::string& event) = 0;  ///< (not "emit": a Qt macro wherever Qt is included)
  /// Tissue that was inside the shaft when it became free to touch it is eased out from the next contact detection.
  virtual void seedContactEasing() = 0;
  // Topology changes (the session orchestrates them; the cut module computes the new mesh).
  /// Cuts along the blade's sweep from `from` to `to`; true when the tissue changed (or a change is being built).
  virtual bool cut(const Eigen::Vector3d& from, const Eigen::Vector3d& to, std::string& message) = 0;
  /// A change under way is applied now (waiting for its build).
  virtual void finishTopologyChange(std::string& message) = 0;
  /// Whether a change is still being built on the second thread.
  virtual bool topologyChangeUnderWay() const = 0;
  /// The rest of a sweep to cut once the change under way is in.
  virtual void cutWhenIn(const Eigen::Vector3d& from, const Eigen::Vector3d& to) = 0;
  /// What did not open of the last cut stays closed: the next cut starts from nothing.
  virtual void forgetCutProgress() = 0;
  /// A blade stroke begins (its sentence comes when all of it is in).
  virtual void beginStroke() = 0;
  // The operative field (field.hpp): what instruments leave on the tissue.
  virtual OperativeField& field() = 0;
  virtual const std::vector<std::array<int, 4>>& elements() const = 0;
  virtual const std::vector<int>& elementLabels() const = 0;
  virtual double time() const = 0;       ///< s, simulated
  virtual const Mesh& mesh() const = 0;  ///< the body's mesh (its label names: what a structure is)
  /// The field changed (a clip placed): its rows and the stumps that bleed follow.
  virtual void fieldChanged(std::string& message) = 0;
  /// Burns these elements (relabelled burnt, stiffened) through a topology change; false while another change is
  /// under way (the heat is kept: they burn at a later step).
  virtual bool burn(const std::vector<int>& elements, std::string& message) = 0;
};

/// One instrument.
class Instrument {
 public:
  virtual ~Instrument() = default;
  virtual const char* name() const = 0;
  /// Whether it acts on this kind of input (the grasper on the jaws, the scissors on the blade).
  virtual bool handles(InputKind kind) const = 0;
  /// The input, at a step boundary.
  virtual void act(const InputEvent& e, ToolState& tool, InstrumentHost& host, std::string& message) = 0;
  /// The tip moves to `to` (before `tool.tip` is set).
  virtual void moved(const Eigen::Vector3d& to, ToolState& tool, InstrumentHost& host, std::string& message) = 0;
  /// The rows it holds the tissue with (bilateral), appended.
  virtual void holds(const ToolState& tool, std::vector<ScalarConstraint>& rows) const = 0;
  /// Whether its shaft touches the tissue now (a blade that cuts does not push it).
  virtual bool touches(const ToolState& tool) const = 0;
  /// After a step with the tool's force known; true when what it holds changed (its rows must be made again).
  virtual bool stepped(ToolState& tool, InstrumentHost& host, std::string& message) = 0;
  /// Before every step of `dt` seconds (the cautery heats the tissue at its tip).
  virtual void stepping(double /*dt*/, ToolState& /*tool*/, InstrumentHost& /*host*/, std::string& /*message*/) {}
};

/// The instruments a session runs: the grasper, the scissors/hook, the clip applier and the cautery hook.
std::vector<std::unique_ptr<Instrument>> makeInstruments();

}  // namespace rehearse::simcore
