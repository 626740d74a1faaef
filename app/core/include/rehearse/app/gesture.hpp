#pragma once
// A scripted rehearsal (step 7 without a window): a JSON list of timed instrument events run through the
// simulation session (simcore::Session, the code the GUI drives), step by step, with what each step did.
// The script (README "File formats"):
//   {"format": "rehearse-gesture", "duration": 2.0, "dt": 0.01,
//    "tools": {"grasp_radius_mm": 6, "max_grasp_force_n": 15},
//    "events": [{"t": 0.0, "tool": "grasper", "tip_near": [x, y, z]},   // the tip onto the organ's node nearest this
//    point
//               {"t": 0.1, "jaws": "close"},
//               {"t": 0.2, "move": [0, 0, -0.02], "over": 1.0},       // the tip moved by this, evenly over this time
//               {"t": 1.5, "jaws": "open"},
//               {"t": 1.6, "tool": "scissors", "tip": [x, y, z]},       // scissors or hook: a blade instead of jaws
//               {"t": 1.7, "cut": "on"}, {"t": 1.7, "move": [0.05, 0, 0], "over": 0.5}, {"t": 2.3, "cut": "off"},
//               {"t": 2.4, "tool": "clip applier", "tip": [x, y, z]}, {"t": 2.5, "clip": "close"},
//               {"t": 2.6, "tool": "cautery", "tip": [x, y, z]}, {"t": 2.6, "energy": "on"}, {"t": 3.0, "energy":
//               "off"}]}
// Positions in metres in the body's frame; "tip": [x, y, z] places the tip directly. "tools" may also set
// "blade_length_mm" and "trocar": [x, y, z] (where the shafts enter; the blade lies on the shaft). A clip may give
// "across": [x, y, z], the direction its jaws close along (default: the shaft's, perpendicular to the structure), and
// "aim": 2, the element label it is aimed at (as the GUI's clip applier names the vessel clicked: the jaws close on
// it when it is within their reach, and say so when it is not).
// "tear_strain": 0.3 makes every material tear at that strain; "tear_strain_by_label": {"2": 0.6} one label's.
// "incorrect_actions": {...} the rules the trainer counts (incorrect_actions.hpp; default: all, without a view).
#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::app {

struct GestureEvent {
  double t = 0;                            ///< s
  std::optional<Eigen::Vector3d> tip;      ///< m, body frame
  std::optional<Eigen::Vector3d> tipNear;  ///< m: the tip goes to the node nearest this point at that time
  std::optional<Eigen::Vector3d> move;     ///< m, relative
  double over = 0;                         ///< s, for move (0: at once)
  std::optional<bool> jawsClosed;
  std::optional<bool> cut;            ///< blade on / off (scissors or hook)
  std::optional<std::string> tool;    ///< "grasper", "scissors", "hook", "clip applier", "cautery"
  bool clip = false;                  ///< the clip applier's jaws close: a clip is left at the tip
  std::optional<bool> energy;         ///< the cautery's power on / off
  std::optional<Eigen::Vector3d> across;  ///< the clip's closing direction (default: the shaft's)
  int aim = 0;                            ///< the label the clip is aimed at (0: none)
};

struct GestureScript {
  double duration = 1;  ///< s
  double dt = 0;        ///< s (0: the scene's)
  std::optional<double> graspRadius, maxGraspForce, bladeLength;  ///< m, N, m
  std::optional<Eigen::Vector3d> trocar;                          ///< m, body frame
  std::optional<double> toolRadius;                               ///< m, the shaft's radius for contact (0: none)
  std::optional<double> depenetrationSpeed;                       ///< m/s (ToolSettings::depenetrationSpeed; 0: at once)
  std::optional<int> tearLatencySteps;                            ///< ToolSettings::tearLatencySteps
  std::optional<int> cutLatencySteps;                             ///< ToolSettings::cutLatencySteps (-1: as before it existed)
  std::optional<double> clipLength, clipGap, clipMinSqueeze;      ///< m, m, - (ToolSettings::clip)
  /// "tear_strain": where every material tears (the tissue's and each label's own; MaterialParams::tearStrain);
  /// "tear_strain_by_label": {"2": 0.6} one label's (given its own material, the tissue's, when it had none).
  std::optional<double> tearStrain;
  std::map<int, double> tearStrainByLabel;
  /// "incorrect_actions": the trainer's rules for this rehearsal (incorrect_actions.hpp), as JSON (checked when
  /// parsed); empty: the defaults. Recorded with the session.
  std::string incorrectActions;
  std::vector<GestureEvent> events;  ///< in time order
};

/// Parses a script; throws std::runtime_error with one sentence naming what is wrong or not supported.
GestureScript parseGestureScript(const std::string& json);

struct GestureStep {
  long step = 0;
  double time = 0, wallMs = 0, massKg = 0;
  std::size_t elements = 0, nodes = 0, grasped = 0, contacts = 0;
  Eigen::Vector3d toolForce = Eigen::Vector3d::Zero();  ///< N, the tool's force on the tissue
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  std::vector<std::string> events;
  simcore::StepReport report;
  std::string message;
};

struct GestureResult {
  std::vector<GestureStep> steps;
  simcore::SimulationState final;
  /// The run's events, counted where every count is made (cuts: cut updates applied; clips: clips left, of them
  /// misplaced; bleedings: stumps that bled; burns: burn updates; tears, of them at an attachment).
  simcore::EventCounts events;
  std::size_t failed = 0;  ///< steps not taken
  double bloodLoss = 0;    ///< m^3 at the end
  long contactQueries = 0;  ///< 0 when the script moves no instrument
  simcore::Mesh finalMesh;  ///< the volume at the end: nodes and elements after any cut, at the final positions
};

/// Called as the script runs (e.g. to record it): `start` with the setup the session is built from (the
/// script's tools and time step applied), `step` after each step (the session's step hook: on the stepping
/// thread, under its lock), `boundary` at each step boundary before the script's own events there (k: the steps taken;
/// e.g. a test posting the factors and topology changes an asynchronous run recorded, on a deferred session).
struct GestureHooks {
  std::function<void(const simcore::BodySetup&)> start;
  std::function<void(const simcore::StepRecord&)> step;
  std::function<void(long k, simcore::Session&)> boundary;
};
/// Runs the script on a session built from `setup` (its tools and time step set from the script).
GestureResult runGesture(simcore::BodySetup setup, const GestureScript& script, const GestureHooks& hooks = {});

}  // namespace rehearse::app
