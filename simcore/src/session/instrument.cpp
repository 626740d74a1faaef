// The instruments the session runs (instrument.hpp): the grasper and the scissors/hook.
#include <rehearse/simcore/session/instrument.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

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
      host.emitEvent("release");
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
      host.emitEvent("grasp");
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
    const double max = host.tools().maxGraspForce;
    if (tool.held.empty() || !(tool.graspForce.norm() > max)) return false;
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "The tissue slipped out of the grasper at %.1f N (the scene's maximum grasp force is %.1f N).",
                  tool.graspForce.norm(), max);
    message = buf;
    tool.released = tool.held;  // the tissue leaves the jaws
    std::sort(tool.released.begin(), tool.released.end());
    tool.held.clear();
    tool.heldOffset.clear();
    tool.stiffness.setZero();  // nothing held: the force does not follow the tool any more
    tool.graspForce.setZero();
    host.emitEvent("slip");
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

}  // namespace

std::vector<std::unique_ptr<Instrument>> makeInstruments() {
  std::vector<std::unique_ptr<Instrument>> all;
  all.push_back(std::make_unique<Grasper>());
  all.push_back(std::make_unique<Scissors>());
  return all;
}

}  // namespace rehearse::simcore
