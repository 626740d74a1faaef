#include "rehearse/app/gesture.hpp"
#include "rehearse/app/incorrect_actions.hpp"

#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/input_ranges.hpp>
#include <rehearse/text_input.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace rehearse::app {
namespace {
using json = nlohmann::json;

Eigen::Vector3d vec3(const json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 3) throw std::runtime_error("the gesture script's \"" + what + "\" must be [x, y, z] in metres");
  Eigen::Vector3d v;
  for (int k = 0; k < 3; ++k) {
    if (!j[static_cast<std::size_t>(k)].is_number()) throw std::runtime_error("the gesture script's \"" + what + "\" holds something that is not a number");
    v[k] = j[static_cast<std::size_t>(k)].get<double>();
  }
  if (!v.allFinite()) throw std::runtime_error("the gesture script's \"" + what + "\" is not finite");
  return v;
}

double number(const json& j, const char* key, double fallback, double lo, double hi) {
  if (!j.contains(key)) return fallback;
  if (!j[key].is_number()) throw std::runtime_error(std::string("the gesture script's \"") + key + "\" must be a number");
  const double v = j[key].get<double>();
  if (!std::isfinite(v) || v < lo || v > hi)
    throw std::runtime_error(std::string("the gesture script's \"") + key + "\" must lie in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return v;
}

simcore::InputEvent toolAt(const Eigen::Vector3d& p, int tool = 0) {
  simcore::InputEvent e;
  e.kind = simcore::InputKind::ToolPose;
  e.tool = tool;
  e.position = p;
  return e;
}

}  // namespace

GestureScript parseGestureScript(const std::string& text) {
  if (const std::string why = jsonTextProblem(text, "the gesture script"); !why.empty()) throw std::runtime_error(why);
  json j;
  try {
    j = json::parse(text);
  } catch (const std::exception&) {
    throw std::runtime_error("the gesture script is not valid JSON");
  }
  if (!j.is_object() || j.value("format", "") != "rehearse-gesture")
    throw std::runtime_error("the gesture script must be an object with \"format\": \"rehearse-gesture\" (README, File formats)");
  GestureScript s;
  s.duration = number(j, "duration", 1.0, 1e-6, 3600);
  s.dt = number(j, "dt", 0.0, 0.0, simcore::InputRanges::maxTimeStep);
  // No time step (the scene's), or one in the range every input path holds; and a run that ends.
  if (s.dt != 0 && s.dt < simcore::InputRanges::minTimeStep)
    throw std::runtime_error("the gesture script's dt " + simcore::detail::number(s.dt) + " s is below " +
                             simcore::detail::number(simcore::InputRanges::minTimeStep) + " s");
  if (s.dt > 0)
    if (const std::string why = simcore::runLengthProblem(s.duration / s.dt, s.dt); !why.empty())
      throw std::runtime_error("the gesture script: " + why);
  if (j.contains("tools")) {
    const auto& t = j["tools"];
    if (t.contains("grasp_radius_mm")) s.graspRadius = 1e-3 * number(t, "grasp_radius_mm", 6, 0.1, 100);
    if (t.contains("max_grasp_force_n")) s.maxGraspForce = number(t, "max_grasp_force_n", 15, 0.0, 1e6);
    if (t.contains("blade_length_mm")) s.bladeLength = 1e-3 * number(t, "blade_length_mm", 30, 1, 300);
    if (t.contains("trocar")) s.trocar = vec3(t["trocar"], "trocar");
    if (t.contains("tool_radius_mm")) s.toolRadius = 1e-3 * number(t, "tool_radius_mm", 0, 0, 50);
    if (t.contains("depenetration_speed_mm_s")) s.depenetrationSpeed = 1e-3 * number(t, "depenetration_speed_mm_s", 50, 0, 1e5);
    if (t.contains("clip_length_mm")) s.clipLength = 1e-3 * number(t, "clip_length_mm", 9, 1, 50);
    if (t.contains("clip_gap_mm")) s.clipGap = 1e-3 * number(t, "clip_gap_mm", 0.5, 0, 10);
    if (t.contains("clip_min_squeeze")) s.clipMinSqueeze = number(t, "clip_min_squeeze", 0.1, 0, 1);
    if (t.contains("cut_latency_steps")) s.cutLatencySteps = static_cast<int>(number(t, "cut_latency_steps", 5, -1, 1000));
    if (t.contains("tear_latency_steps"))
      s.tearLatencySteps = static_cast<int>(number(t, "tear_latency_steps", 5, -1, 1000));
  }
  if (j.contains("tear_strain")) s.tearStrain = number(j, "tear_strain", 0, 0, 10);
  if (j.contains("tear_strain_by_label")) {
    const auto& t = j["tear_strain_by_label"];
    if (!t.is_object()) throw std::runtime_error("\"tear_strain_by_label\" must be an object of labels and strains");
    for (const auto& [key, value] : t.items()) {
      int label = 0;
      try {
        std::size_t used = 0;
        label = std::stoi(key, &used);
        if (used != key.size() || label <= 0) throw std::invalid_argument(key);
      } catch (const std::exception&) {
        throw std::runtime_error("\"tear_strain_by_label\" names '" + key + "', not a positive element label");
      }
      s.tearStrainByLabel[label] = number(t, key.c_str(), 0, 0, 10);
    }
  }
  if (j.contains("incorrect_actions")) {
    s.incorrectActions = j["incorrect_actions"].dump();
    parseActionRules(s.incorrectActions);  // refused here, with its sentence, rather than when replayed
  }
  if (!j.contains("events") || !j["events"].is_array()) throw std::runtime_error("the gesture script has no \"events\" list");
  double last = 0;
  std::string current = "grasper";
  for (const auto& e : j["events"]) {
    GestureEvent g;
    g.t = number(e, "t", 0, 0, 3600);
    if (g.t < last) throw std::runtime_error("the gesture script's events must be in time order (t = " + std::to_string(g.t) + " after " + std::to_string(last) + ")");
    last = g.t;
    if (e.contains("tool")) {
      const std::string tool = e["tool"].is_string() ? e["tool"].get<std::string>() : std::string();
      if (tool != "grasper" && tool != "scissors" && tool != "hook" && tool != "clip applier" && tool != "cautery")
        throw std::runtime_error("the gesture script names an unknown tool '" + tool +
                                 "'; use grasper, scissors, hook, clip applier or cautery");
      g.tool = tool;
      current = tool;
    }
    if (e.contains("cut")) {
      const std::string w = e["cut"].is_string() ? e["cut"].get<std::string>() : std::string();
      if (w != "on" && w != "off") throw std::runtime_error("the gesture script's \"cut\" must be \"on\" or \"off\"");
      if (current != "scissors" && current != "hook")
        throw std::runtime_error("the gesture script cuts with the " + current + " at t = " + std::to_string(g.t) +
                                 "; choose \"tool\": \"scissors\" or \"hook\" first");
      g.cut = w == "on";
    }
    if (e.contains("jaws") && current != "grasper")
      throw std::runtime_error("the gesture script closes jaws at t = " + std::to_string(g.t) + " while holding the " + current + "; choose \"tool\": \"grasper\" first");
    if (e.contains("clip")) {
      if (!e["clip"].is_string() || e["clip"].get<std::string>() != "close")
        throw std::runtime_error("the gesture script's \"clip\" must be \"close\"");
      if (current != "clip applier")
        throw std::runtime_error("the gesture script closes a clip at t = " + std::to_string(g.t) +
                                 " while holding the " + current + "; choose \"tool\": \"clip applier\" first");
      g.clip = true;
      if (e.contains("across")) g.across = vec3(e["across"], "across");
      if (e.contains("aim")) {
        if (!e["aim"].is_number_integer() || e["aim"].get<long long>() < 1 || e["aim"].get<long long>() > 1000000)
          throw std::runtime_error("the gesture script's clip \"aim\" must be an element label (a positive integer)");
        g.aim = static_cast<int>(e["aim"].get<long long>());
      }
    }
    if (e.contains("energy")) {
      const std::string w = e["energy"].is_string() ? e["energy"].get<std::string>() : std::string();
      if (w != "on" && w != "off")
        throw std::runtime_error("the gesture script's \"energy\" must be \"on\" or \"off\"");
      if (current != "cautery")
        throw std::runtime_error("the gesture script applies energy at t = " + std::to_string(g.t) +
                                 " while holding the " + current + "; choose \"tool\": \"cautery\" first");
      g.energy = w == "on";
    }
    if (e.contains("tip")) g.tip = vec3(e["tip"], "tip");
    if (e.contains("tip_near")) g.tipNear = vec3(e["tip_near"], "tip_near");
    if (e.contains("move")) g.move = vec3(e["move"], "move");
    g.over = number(e, "over", 0, 0, 3600);
    if (e.contains("jaws")) {
      const std::string w = e["jaws"].is_string() ? e["jaws"].get<std::string>() : std::string();
      if (w != "close" && w != "open") throw std::runtime_error("the gesture script's \"jaws\" must be \"close\" or \"open\"");
      g.jawsClosed = w == "close";
    }
    if (!g.tip && !g.tipNear && !g.move && !g.jawsClosed && !g.cut && !g.clip && !g.energy && !e.contains("tool"))
      throw std::runtime_error("a gesture script event at t = " + std::to_string(g.t) +
                               " does nothing (no tip, tip_near, move, jaws, cut, clip or energy)");
    s.events.push_back(g);
  }
  return s;
}

GestureResult runGesture(simcore::BodySetup setup, const GestureScript& script, const GestureHooks& hooks) {
  if (script.dt > 0) setup.settings.timeStep = script.dt;
  if (script.graspRadius) setup.tools.graspRadius = *script.graspRadius;
  if (script.maxGraspForce) setup.tools.maxGraspForce = *script.maxGraspForce;
  if (script.bladeLength) setup.tools.bladeLength = *script.bladeLength;
  if (script.trocar) setup.tools.trocar = *script.trocar;
  if (script.toolRadius) setup.tools.toolRadius = *script.toolRadius;
  if (script.depenetrationSpeed) setup.tools.depenetrationSpeed = *script.depenetrationSpeed;
  if (script.cutLatencySteps) setup.tools.cutLatencySteps = *script.cutLatencySteps;
  if (script.tearLatencySteps) setup.tools.tearLatencySteps = *script.tearLatencySteps;
  if (script.clipLength) setup.tools.clip.length = *script.clipLength;
  if (script.clipGap) setup.tools.clip.gap = *script.clipGap;
  if (script.clipMinSqueeze) setup.tools.clip.minSqueeze = *script.clipMinSqueeze;
  if (script.tearStrain) {
    setup.material.tearStrain = *script.tearStrain;
    for (auto& [label, m] : setup.byLabel) m.tearStrain = *script.tearStrain;
  }
  for (const auto& [label, strain] : script.tearStrainByLabel)
    setup.byLabel.try_emplace(label, setup.material).first->second.tearStrain = strain;
  const double h = setup.settings.timeStep;
  if (const std::string why = simcore::runLengthProblem(script.duration / h, h); !why.empty())
    throw std::runtime_error("the gesture script: " + why);
  const long steps = std::max(1L, static_cast<long>(std::lround(script.duration / h)));
  if (hooks.start) hooks.start(setup);
  simcore::Session session(setup);
  if (hooks.step) session.setStepHook(hooks.step);
  GestureResult out;
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  // A move in progress: from `from` by `by` between steps [k0, k1].
  struct Move {
    Eigen::Vector3d from, by;
    long k0 = 0, k1 = 0;
  };
  std::vector<Move> moves;
  std::size_t next = 0;
  int tool = 0;  // 0 grasper, 1 scissors, 2 hook, 3 clip applier, 4 cautery
  for (long k = 0; k < steps; ++k) {
    if (hooks.boundary) hooks.boundary(k, session);
    const double t = k * h;
    while (next < script.events.size() && script.events[next].t <= t + 1e-9) {
      const GestureEvent& e = script.events[next++];
      if (e.tool)
        tool = *e.tool == "grasper"        ? 0
               : *e.tool == "scissors"     ? 1
               : *e.tool == "hook"         ? 2
               : *e.tool == "clip applier" ? 3
                                           : 4;
      if (e.tipNear) {
        const auto snap = session.snapshot();
        double best = 1e300;
        for (const auto& p : snap->positions)
          if ((p - *e.tipNear).squaredNorm() < best) best = (p - *e.tipNear).squaredNorm(), tip = p;
        session.post(toolAt(tip, tool));
      }
      if (e.tip) {
        tip = *e.tip;
        session.post(toolAt(tip, tool));
      }
      if (e.move) {
        const long span = std::max(0L, static_cast<long>(std::lround(e.over / h)));
        if (span == 0) {
          tip += *e.move;
          session.post(toolAt(tip, tool));
        } else {
          moves.push_back({tip, *e.move, k, k + span});
        }
      }
      if (e.jawsClosed) {
        simcore::InputEvent j;
        j.kind = simcore::InputKind::Jaw;
        j.on = *e.jawsClosed;
        session.post(j);
      }
      if (e.energy) {
        simcore::InputEvent c;
        c.kind = simcore::InputKind::Energy;
        c.tool = tool;
        c.on = *e.energy;
        session.post(c);
      }
      if (e.clip) {
        simcore::InputEvent c;
        c.kind = simcore::InputKind::Clip;
        c.tool = tool;
        c.on = true;
        c.vector = e.across.value_or(Eigen::Vector3d::Zero());
        c.label = e.aim;
        session.post(c);
      }
      if (e.cut) {
        simcore::InputEvent c;
        c.kind = simcore::InputKind::Cut;
        c.tool = tool;
        c.on = *e.cut;
        session.post(c);
      }
    }
    for (auto it = moves.begin(); it != moves.end();) {
      const double s = std::min(1.0, static_cast<double>(k - it->k0 + 1) / static_cast<double>(it->k1 - it->k0));
      tip = it->from + s * it->by;
      session.post(toolAt(tip, tool));
      it = s >= 1.0 ? moves.erase(it) : it + 1;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const simcore::StepReport rep = session.advance();
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const auto snap = session.snapshot();
    GestureStep row;
    row.step = snap->step;
    row.time = snap->time;
    row.wallMs = ms;
    row.massKg = snap->mass;
    row.elements = snap->elements;
    row.nodes = snap->positions.size();
    row.grasped = snap->tool.held.size();
    row.contacts = static_cast<std::size_t>(snap->tool.contacts);
    row.toolForce = snap->tool.force;
    row.tip = snap->tool.tip;
    row.events = snap->events;
    row.report = rep;
    row.message = snap->message;
    out.failed += !rep.ok;
    out.events.add(row.events);
    out.bloodLoss = snap->field.bloodLoss;
    out.steps.push_back(std::move(row));
  }
  // A cut whose body was still being built when the script ended is applied: the run's mesh has every cut the blade made
  // (its events are the last row's).
  if (session.applyPendingChange() && !out.steps.empty()) {
    const auto snap = session.snapshot();
    auto& last = out.steps.back();
    for (const auto& e : snap->events) last.events.push_back(e);
    out.events.add(snap->events);
    out.bloodLoss = snap->field.bloodLoss;
    last.elements = snap->elements;
    last.nodes = snap->positions.size();
  }
  out.final = session.state();
  out.contactQueries = session.contactQueries();
  // The volume as it ends: the (possibly cut) mesh at the final positions.
  out.finalMesh = session.setup().mesh;
  out.finalMesh.triangles.clear();
  out.finalMesh.triangleLabels.clear();
  for (std::size_t i = 0; i < out.finalMesh.points.size(); ++i) out.finalMesh.points[i] = out.final.x.segment<3>(static_cast<Eigen::Index>(3 * i));
  return out;
}

}  // namespace rehearse::app
