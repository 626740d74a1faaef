#pragma once
// A session's inputs (session.hpp): the timestamped events posted to its mailbox and recorded with the step they
// applied at.
#include <Eigen/Core>

#include <string>

namespace rehearse::simcore {

enum class InputKind {
  ToolPose,   ///< the tool tip moved to `position` (m, body frame)
  Jaw,        ///< the jaws closed (`on`) or opened
  Cut,        ///< the cutting instrument on (`on`) or off
  Parameter,  ///< `name` ("young", "poisson", "density", "model", "dt", "method", "tear_strain": where the material
              ///< tears (MaterialParams::tearStrain; 0 never), "clip_length": the clip applier's
              ///< next clips, "grasp_radius": the jaws' bite, what
              ///< their next closing holds) set to `value` (SI; model and method:
              ///< MaterialModel / NewtonMethod index); with `label` > 0, "young" and "poisson" of that label's
              ///< material (e.g. the vessels'; "young" 0 removes it: the label then uses the parenchyma's)
  Gravity,    ///< gravity set to `vector` (m/s^2, body frame)
  Factor,  ///< recorded, not posted by a user: the lagged factor requested earlier (asynchronous refresh) was swapped
           ///< in at this step boundary; a replay (FactorRefresh::Deferred) installs it at the same boundary
  CutApplied,  ///< recorded, not posted by a user: a cut computed earlier, whose new body was built on another thread
               ///< (asynchronous refresh), replaced the body at this step boundary; a replay applies it here
  Clip,        ///< the clip applier's jaws closed at the tip: a clip is left there (`vector`: the jaws' closing
               ///< direction; zero: the shaft's, made perpendicular to the clipped structure)
  Energy,      ///< the cautery hook's power on (`on`) or off: tissue within its radius of the tip burns over time
};

struct InputEvent {
  InputKind kind = InputKind::ToolPose;
  double wallTime = 0;  ///< s since the session started, when posted (for review; replay goes by `step`)
  long step = -1;       ///< the step boundary it applies at: set by the session when applied; a replay posts it
  int tool = 0;
  int label = 0;  ///< Parameter: 0 the parenchyma (and unlisted labels), else an element label
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d vector = Eigen::Vector3d::Zero();
  bool on = false;
  std::string name;
  double value = 0;
  bool operator==(const InputEvent&) const = default;
};

}  // namespace rehearse::simcore
