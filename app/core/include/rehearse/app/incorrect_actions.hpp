#pragma once
// The trainer's incorrect actions (issue 36): a per-scene list of rules, each with its default, found in a
// session's replay step by step with the time it happened. The rules travel with the recording (its session row,
// SessionMeta::rules), so a session is judged by the rules of the scene it was rehearsed in. Declared in JSON, in a
// gesture script's "incorrect_actions", a case file's "incorrect_actions" (the GUI's rehearsal) or a file given to
// the command line; every rule is on by default:
//   {"vessel_cut_without_clips": true,   // a cut that opens a bleeding vessel stump (no clip behind it)
//    "energy_on_structure": true,        // the cautery's energy reaches a named structure (vessel, duct, tumour...)
//    "force_over_limit": {"limit_n": 10, "longer_than_s": 1},   // the tool's force above the limit for longer
//    "tear": true,                       // tissue pulled past its material's tear strain (once per over-pull: tears
//                                        // within 0.5 s of the last one are the same action)
//    "clip_misplaced": true,             // a clip on no vessel or duct, or not across all of it
//    "outside_view": true,               // an instrument holding, cutting, burning or clipping outside the view
//    "view": {"fx": 800, "fy": 800, "cx": 320, "cy": 240, "width": 640, "height": 480,
//             "from": [0, 0, 0], "to": [0, 0, 1]}}   // the camera, in the body's frame (default: it is the frame)
// A rule set to false is not counted. "outside_view" needs a view: without one it is not determined (said so).
#include <rehearse/app/recording.hpp>
#include <rehearse/imaging/camera.hpp>

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace rehearse::app {

/// The camera that sees the field, in the body's frame: pixel = K (R (x - from)).
struct ActionView {
  imaging::Camera camera;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< body -> camera
  Eigen::Vector3d from = Eigen::Vector3d::Zero();          ///< the camera's centre (m, body frame)
  /// Whether a point (m, body frame) is in front of the camera and projects inside its image.
  bool sees(const Eigen::Vector3d& p) const;
};

struct ActionRules {
  bool vesselCutWithoutClips = true;
  bool energyOnStructure = true;
  bool forceOverLimit = true;
  double forceLimitN = 10;      ///< N
  double forceLongerThanS = 1;  ///< s, continuously above the limit
  bool tear = true;
  bool clipMisplaced = true;
  bool outsideView = true;
  std::optional<ActionView> view;
};

/// Parses rules (empty text: the defaults). Throws std::runtime_error with one sentence (not JSON, an unknown rule, a
/// limit that is not a positive number, a view whose camera cannot be used).
ActionRules parseActionRules(const std::string& json);
/// As JSON again (parseActionRules(actionRulesJson(r)) gives r back); "" for the defaults without a view.
std::string actionRulesJson(const ActionRules& r);
/// The view JSON of a camera whose frame is the body's (the GUI's rehearsal: the organ is in the camera frame).
std::string cameraViewJson(const imaging::Camera& camera);

// IncorrectAction (one found: rule, step, time, words) is in recording.hpp, with the metrics that hold them.
/// The rules in the order they are listed, with the words the review uses ("vessel cut without clips").
const std::vector<std::pair<std::string, std::string>>& actionRuleNames();

/// Finds the incorrect actions as a replay goes, one step at a time.
class IncorrectActionFinder {
 public:
  explicit IncorrectActionFinder(ActionRules rules) : rules_(std::move(rules)) {}
  struct StepFacts {
    long step = 0;
    double time = 0;  ///< s, after the step
    bool toolPresent = false;
    Eigen::Vector3d tip = Eigen::Vector3d::Zero();  ///< m, body frame
    bool holding = false, cutting = false, energy = false;
    double force = 0;  ///< N
    const std::vector<std::string>* events = nullptr;
  };
  /// The step's incorrect actions (also kept in found()).
  std::vector<IncorrectAction> step(const StepFacts& s);
  const std::vector<IncorrectAction>& found() const { return found_; }
  const ActionRules& rules() const { return rules_; }
  /// Whether a rule is counted (on, and determined: outside_view needs a view), else why not in one sentence.
  std::optional<std::string> notCounted(const std::string& rule) const;

 private:
  ActionRules rules_;
  std::vector<IncorrectAction> found_;
  double lastTear_ = -1e9;  ///< s: the last tear (tears that follow within kTearSpell are the same over-pull)
  double overSince_ = -1;   ///< s: when the force last went above the limit (-1: it is not above)
  bool overCounted_ = false;
  bool outside_ = false;  ///< the acting instrument was outside the view at the last step
};

}  // namespace rehearse::app
