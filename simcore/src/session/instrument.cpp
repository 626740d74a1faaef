// The instruments the session runs (instrument.hpp): the grasper, the scissors/hook, the clip applier and the cautery
// hook.
#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/session/contact.hpp>
#include <rehearse/simcore/session/instrument.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "grasplimit.hpp"

namespace rehearse::simcore {

namespace {

// The grasper: closing the jaws bites every free node within the grasp radius of the tip (the nearest first), each
// held at its place relative to the tip by three bilateral rows; opening them lets go (the tissue leaves the open
// jaws); pulled harder than the jaws hold (their own share of the force above the scene's maximum), the tissue slips.
class Grasper final : public Instrument {
 public:
  const char* name() const override { return "grasper"; }
  bool handles(InputKind kind) const override { return kind == InputKind::Jaw; }
  void act(const InputEvent& e, ToolState& tool, InstrumentHost& host, std::string& message) override {
    tool.jawClosed = e.on;
    tool.jawTip = tool.tip;  // the jaws close (or open) where the instrument is
    tool.jawTool = e.tool;
    tool.released = tool.held;
    std::sort(tool.released.begin(), tool.released.end());
    tool.held.clear();
    tool.heldOffset.clear();
    tool.force.setZero();
    tool.graspForce.setZero();
    if (!e.on) {
      host.emitEvent(eventWord(EventKind::Release));
      host.seedContactEasing();  // the tissue the jaws held may be inside the shaft
      return;
    }
    const double radius = host.tools().graspRadius, r2 = radius * radius;
    const auto& fixed = host.fixedMask();
    const Eigen::VectorXd& x = host.positions();
    std::vector<std::pair<double, int>> near;
    for (std::size_t i = 0; i < fixed.size(); ++i) {
      const double d = (x.segment<3>(3 * static_cast<Eigen::Index>(i)) - tool.tip).squaredNorm();
      if (d <= r2 && !fixed[i]) near.emplace_back(d, static_cast<int>(i));
    }
    std::sort(near.begin(), near.end());
    for (const auto& [d, i] : near) {
      tool.held.push_back(i);
      tool.heldOffset.push_back(x.segment<3>(3 * static_cast<Eigen::Index>(i)) - tool.jawTip);
    }
    if (!near.empty())
      host.emitEvent(eventWord(EventKind::Grasp));
    else
      message = "The jaws closed on nothing: no tissue within " +
                std::to_string(static_cast<int>(std::lround(1e3 * radius))) + " mm of the tip.";
  }
  void moved(const Eigen::Vector3d& to, ToolState& tool, InstrumentHost& host, std::string&) override {
    if (!tool.released.empty() && to != tool.tip) {
      tool.released.clear();  // the instrument moves on: what it let go of is touched like any tissue (eased out)
      host.seedContactEasing();
    }
  }
  void holds(const ToolState& tool, std::vector<ScalarConstraint>& rows) const override {
    if (!tool.jawClosed) return;
    // Each held node keeps its place relative to the jaws: three rows along the body frame's axes.
    for (std::size_t k = 0; k < tool.held.size(); ++k)
      for (int axis = 0; axis < 3; ++axis) {
        ScalarConstraint s;
        s.nodes = {tool.held[k], -1, -1, -1};
        s.weights = {1, 0, 0, 0};
        s.direction = Eigen::Vector3d::Unit(axis);
        s.value = (tool.jawTip + tool.heldOffset[k])[axis];
        rows.push_back(s);
      }
  }
  bool touches(const ToolState&) const override { return true; }
  bool stepped(ToolState& tool, InstrumentHost& host, std::string& message) override {
    // Pulled harder than the jaws can hold: the tissue slips out (the jaws stay closed, holding nothing). The jaws' own
    // share decides: the shaft pressing on the tissue does not open them.
    // The jaws held back at the limit this step let go when the force the step solved came within 5 % of it: the first
    // order prediction the hold-back used can overshoot (a pull in the window let go "at 7.2 N" of 15: the step's
    // stiffness was the tissue's before it gave); below that the jaws keep their hold where they were held back, and
    // the next move is held back again from the force reached, so the slip comes at the limit.
    const double max = host.tools().maxGraspForce;
    const bool atLimit = host.jawsAtGraspLimit() && tool.graspForce.norm() >= kLetGoShare * max;
    if (tool.held.empty() || !(tool.graspForce.norm() > max || atLimit)) return false;
    char buf[400];
    if (host.stepConverged())
      std::snprintf(buf, sizeof buf,
                    "The tissue slipped out of the grasper at %.3g N (the scene's maximum grasp force is %.3g N): %s.",
                    tool.graspForce.norm(), max,
                    // (at 14.9 N of 15, a person read a contradiction)
                    tool.graspForce.norm() <= kWithinOneStep * max ? "the jaws let go as the pull reached it"
                                                         : "the pull went past it within one step");
    else if (!(tool.graspForce.norm() > kWithinOneStep * max))  // (a step taken again at the limit reads there: slipResolved)
      std::snprintf(buf, sizeof buf,
                    "The tissue slipped out of the grasper at %.3g N (the scene's maximum grasp force is %.3g N), on a "
                    "step that did not converge: not the tissue's force at equilibrium.",
                    tool.graspForce.norm(), max);
    else  // a force read on a step that did not converge is not the tissue's at equilibrium
      std::snprintf(buf, sizeof buf,
                    "The tissue slipped out of the grasper on a step that did not converge: its force there reads "
                    "%.3g N, which is not the tissue's at equilibrium (the scene's maximum grasp force is %.3g N); "
                    "pull more slowly for forces the chart can be read by.",
                    tool.graspForce.norm(), max);
    message = buf;
    tool.released = tool.held;  // the tissue leaves the jaws
    std::sort(tool.released.begin(), tool.released.end());
    tool.held.clear();
    tool.heldOffset.clear();
    tool.stiffness.setZero();  // nothing held: the force does not follow the tool any more
    tool.graspForce.setZero();
    host.emitEvent(eventWord(EventKind::Slip));
    return true;
  }
};

// The scissors or the hook: while the blade is on, the tip's sweep (the blade lies on the shaft, from the tip towards
// the trocar) cuts the tissue once the tip has moved two element edges (so that it splits elements rather than only
// snapping to their nodes); switched off, the rest of the sweep is cut. Its shaft does not push the tissue while it
// cuts.
class Scissors final : public Instrument {
 public:
  const char* name() const override { return "scissors"; }
  bool handles(InputKind kind) const override { return kind == InputKind::Cut; }
  void act(const InputEvent& e, ToolState& tool, InstrumentHost& host, std::string& message) override {
    if (e.on) host.finishTopologyChange(message);  // a cut being built is applied before the next one starts
    if (!e.on && host.topologyChangeUnderWay()) {
      // Withdrawn while the last cut's body is being built: the rest of the sweep is cut once it is in (no wait).
      if (tool.cutting && (tool.tip - tool.cutFrom).norm() > 0)
        host.cutWhenIn(tool.cutFrom, tool.tip);
      else
        host.forgetCutProgress();
      tool.cutting = false;
      tool.cutFrom = tool.tip;
      return;
    }
    if (!e.on && tool.cutting && (tool.tip - tool.cutFrom).norm() > 0)
      host.cut(tool.cutFrom, tool.tip, message);         // the rest of the sweep
    if (tool.cutting != e.on) host.seedContactEasing();  // contact resumes (or stops) with the blade
    if (e.on && !tool.cutting) {                         // a new stroke
      tool.structuresCut.clear();
      host.beginStroke();
    }
    tool.cutting = e.on;
    tool.cutFrom = tool.tip;
    host.forgetCutProgress();  // a new cut starts from nothing; what did not open of the last one stays closed
  }
  void moved(const Eigen::Vector3d& to, ToolState& tool, InstrumentHost& host, std::string& message) override {
    // The blade's sweep since the cut last changed the tissue: a sweep too thin to cross whole elements grows until it
    // does.
    if (tool.cutting && to.allFinite() && (to - tool.cutFrom).norm() >= 2 * host.meanEdge() &&
        host.cut(tool.cutFrom, to, message))
      tool.cutFrom = to;
  }
  void holds(const ToolState&, std::vector<ScalarConstraint>&) const override {}
  bool touches(const ToolState& tool) const override { return !tool.cutting; }
  bool stepped(ToolState&, InstrumentHost&, std::string&) override { return false; }
};

// The clip applier: its jaws close at the tip and leave a clip there (field.hpp: the structure between them pulled
// together across the jaws over the clip's closing time); the clip stays on the tissue when the instrument goes. A clip
// that does not reach across the whole structure, or that closes on something that is not a vessel or a duct, is
// misplaced (an event the trainer counts).
class ClipApplier final : public Instrument {
 public:
  const char* name() const override { return "clip applier"; }
  bool handles(InputKind kind) const override { return kind == InputKind::Clip; }
  void act(const InputEvent& e, ToolState& tool, InstrumentHost& host, std::string& message) override {
    if (host.settings().method == NewtonMethod::Linearised) {
      // Its one solve per step does not hold a clip's rows: clip-clip-cut.json on the liver preset inverted 2,077
      // elements within a second (chord: none, converged).
      message =
          "The clip was refused: the linearised method's one solve per step diverges under a clip; choose a "
          "converged method (chord, exact Newton, lagged-PCG or Newton-Krylov) in the Simulation panel.";
      return;
    }
    const ToolSettings& s = host.tools();
    std::string notes;  // what placeClip says about this clip (it does not span, it cannot close to the gap)
    Clip clip = placeClip(
        host.positions(), host.elements(), host.elementLabels(), host.fixedMask(), tool.tip,
        s.trocar.value_or(Eigen::Vector3d(tool.tip - Eigen::Vector3d::UnitZ())), e.vector, s.graspRadius, s.clip,
        host.time(), [&host](int label) { return host.mesh().labelKind(label); }, notes, e.label);
    if (clip.anchor < 0) {  // closed on nothing
      message = notes;
      return;
    }
    const StructureKind kind = host.mesh().labelKind(clip.label);
    const std::string name = host.mesh().labelName(clip.label);
    // "the cystic artery", "the vessel" (not "vessel (vessels)").
    const std::string what = kind == StructureKind::Tissue ? std::string("tissue") : structureWords(kind, name);
    host.field().clips.push_back(std::move(clip));
    host.emitEvent(eventWord(EventKind::Clip));
    const Clip& placed = host.field().clips.back();
    const bool closable = isVessel(kind) || kind == StructureKind::BileDuct;
    if (!closable) {
      host.emitEvent(eventWord(EventKind::ClipMisplaced));
      message = "A clip was placed on " + what + ", not on a vessel or a duct.";
    } else if (!placed.spans) {
      host.emitEvent(eventWord(EventKind::ClipMisplaced));
      message = "A clip was placed on the " + what + " but does not close it.";
    } else {
      message =
          "A clip closes the " + what + " (" + std::to_string(placed.nodes.size() + 1) + " nodes between its jaws).";
    }
    if (!notes.empty()) message += (notes.front() == ' ' ? "" : " ") + notes;
    host.fieldChanged(message);
  }
  void moved(const Eigen::Vector3d&, ToolState&, InstrumentHost&, std::string&) override {}
  void holds(const ToolState&, std::vector<ScalarConstraint>&) const override {}
  bool touches(const ToolState&) const override { return true; }
  bool stepped(ToolState&, InstrumentHost&, std::string&) override { return false; }
};

// The cautery hook (energy): while its power is on, the elements with a node within its radius of the tip heat,
// and one held there for the burn time burns (relabelled burnt: whitened, stiffened, and cut without bleeding). Energy
// that reaches a named structure (a vessel, a duct, a tumour, a ligament) is said once per activation: an incorrect
// action the trainer counts ("energy on structure").
class Cautery final : public Instrument {
 public:
  const char* name() const override { return "cautery hook"; }
  bool handles(InputKind kind) const override { return kind == InputKind::Energy; }
  void act(const InputEvent& e, ToolState&, InstrumentHost& host, std::string& message) override {
    OperativeField& f = host.field();
    if (e.on && !f.energy) {
      f.energyOn.clear();
      stroke_ = Stroke{};
      stroke_.active = true;
    }
    // A stroke that burnt nothing is said when the power goes off, with what to change (a stroke that burnt says so as
    // its burn comes in). What the stroke did is a sentence's, not the physics': it is not in the checkpoint (a replay
    // from a checkpoint taken during a stroke says nothing of that stroke).
    const CauterySettings& c = host.tools().cautery;
    bool due = false;  // heated enough, waiting for a change under way: it burns at a later step
    for (const auto& [element, heat] : f.heating) due = due || heat >= c.burnTime;
    if (!e.on && f.energy && stroke_.active && !stroke_.burnt && !due) {
      char said[320];
      if (stroke_.touching > 0 && !(stroke_.onUnburnt > 0))
        // (It said "no spot of tissue was heated more than 0.00 s" over tissue an earlier stroke had burnt.)
        std::snprintf(said, sizeof said,
                      "The hook burnt nothing more: the tissue within %.0f mm of its tip was burnt already; move it "
                      "onto unburnt tissue to burn further.",
                      1e3 * c.radius);
      else if (stroke_.touching > 0)
        std::snprintf(said, sizeof said,
                      "The hook burnt nothing: no spot of tissue was heated more than %.2f s, and tissue burns after "
                      "%.2f s within %.0f mm of the powered tip; hold the hook still on the tissue longer, or drag it "
                      "more slowly.",
                      stroke_.longest, c.burnTime, 1e3 * c.radius);
      else
        std::snprintf(said, sizeof said,
                      "The hook burnt nothing: the power was on with no tissue within %.0f mm of its tip; touch the "
                      "tissue with the hook's tip while the power is on.",
                      1e3 * c.radius);
      message += (message.empty() ? "" : " ") + std::string(said);
    }
    if (!e.on) stroke_.active = false;
    f.energy = e.on;
  }
  void moved(const Eigen::Vector3d&, ToolState&, InstrumentHost&, std::string&) override {}
  void holds(const ToolState&, std::vector<ScalarConstraint>&) const override {}
  bool touches(const ToolState&) const override { return true; }
  bool stepped(ToolState&, InstrumentHost&, std::string&) override { return false; }
  void stepping(double dt, ToolState& tool, InstrumentHost& host, std::string& message) override {
    OperativeField& f = host.field();
    if (!f.energy || !tool.present || !(dt > 0)) return;
    const CauterySettings& c = host.tools().cautery;
    const auto& tets = host.elements();
    const auto& labels = host.elementLabels();
    const Eigen::VectorXd& x = host.positions();
    const double r2 = c.radius * c.radius;
    std::vector<int> reached;  // unburnt elements within the radius
    bool touching = false;     // any tissue, burnt or not
    for (std::size_t e = 0; e < tets.size(); ++e) {
      // An element heats when the hook is within the radius of it: inside it, or that near one of its faces (on a mesh
      // coarser than the hook, the elements it touches; their nodes and centres can all be further away).
      std::array<Eigen::Vector3d, 4> p;
      Eigen::AlignedBox3d box;
      for (std::size_t k = 0; k < 4; ++k) box.extend(p[k] = x.segment<3>(3 * static_cast<Eigen::Index>(tets[e][k])));
      if (box.exteriorDistance(tool.tip) > c.radius) continue;
      static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
      bool inside = true, near = false;
      const double volume = (p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]);
      for (const auto& f : kFaces) {
        const Eigen::Vector3d &a = p[static_cast<std::size_t>(f[0])], &b = p[static_cast<std::size_t>(f[1])],
                              &d = p[static_cast<std::size_t>(f[2])];
        // The tip on the inner side of every face (the faces' orientation follows the element's).
        inside = inside && (b - a).cross(d - a).dot(tool.tip - a) * volume <= 0;
        Eigen::Vector3d w;
        near = near || (closestOnTriangle(tool.tip, a, b, d, w) - tool.tip).squaredNorm() <= r2;
      }
      if (!inside && !near) continue;
      touching = true;
      if (!isBurnt(e < labels.size() ? labels[e] : 0)) reached.push_back(static_cast<int>(e));
    }
    if (touching) f.energyTime += dt, stroke_.touching += dt;
    if (reached.empty()) return;
    stroke_.onUnburnt += dt;
    // Heat: the sorted list gains the reached elements.
    std::vector<std::pair<int, double>> heated;
    heated.reserve(f.heating.size() + reached.size());
    std::size_t i = 0, j = 0;
    while (i < f.heating.size() || j < reached.size()) {
      if (j == reached.size() || (i < f.heating.size() && f.heating[i].first < reached[j])) {
        heated.push_back(f.heating[i++]);
      } else if (i == f.heating.size() || reached[j] < f.heating[i].first) {
        heated.emplace_back(reached[j++], dt);
      } else {
        heated.emplace_back(reached[j++], f.heating[i++].second + dt);
      }
    }
    f.heating = std::move(heated);
    for (const auto& [e, heat] : f.heating) stroke_.longest = std::max(stroke_.longest, heat);
    // A named structure reached: said once per activation.
    for (int e : reached) {
      const int label = labels[static_cast<std::size_t>(e)];
      const StructureKind kind = host.mesh().labelKind(label);
      if (kind == StructureKind::Tissue || std::find(f.energyOn.begin(), f.energyOn.end(), label) != f.energyOn.end())
        continue;
      f.energyOn.push_back(label);
      host.emitEvent(eventWord(EventKind::EnergyOnStructure));
      host.emitEvent(structureEventWord(EventKind::EnergyOnNamedStructure, structureKindName(kind)));
      const std::string name = host.mesh().labelName(label);
      message = std::string("Energy reached the ") + structureKindName(kind) + (name.empty() ? "" : " (" + name + ")") +
                ", which the hook should not touch.";
    }
    std::vector<int> burnt;
    for (const auto& [e, heat] : f.heating)
      if (heat >= c.burnTime) burnt.push_back(e);
    if (!burnt.empty() && host.burn(burnt, message)) {
      std::erase_if(f.heating, [&c](const std::pair<int, double>& h) { return h.second >= c.burnTime; });
      stroke_.burnt = true;
    }
  }

 private:
  struct Stroke {
    bool active = false;  ///< the power came on in this session (a stroke from before a checkpoint is not judged)
    bool burnt = false;   ///< some tissue burnt since
    double touching = 0;  ///< s with tissue within the radius
    double longest = 0;   ///< s, the most heat any element gathered
    double onUnburnt = 0;  ///< s with unburnt tissue within the radius
  } stroke_;
};

}  // namespace

std::vector<std::unique_ptr<Instrument>> makeInstruments() {
  std::vector<std::unique_ptr<Instrument>> all;
  all.push_back(std::make_unique<Grasper>());
  all.push_back(std::make_unique<Scissors>());
  all.push_back(std::make_unique<ClipApplier>());
  all.push_back(std::make_unique<Cautery>());
  return all;
}

}  // namespace rehearse::simcore
