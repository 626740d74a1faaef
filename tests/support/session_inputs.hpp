#pragma once
// The instruments' inputs and a preset's body, for the rehearsal tests and benchmark (issue 15).
#include "phantom/presets.hpp"

#include <rehearse/simcore/session/session.hpp>

#include <string>

namespace rehearse::testing {

inline simcore::InputEvent toolAt(const Eigen::Vector3d& p) {
  simcore::InputEvent e;
  e.kind = simcore::InputKind::ToolPose;
  e.position = p;
  return e;
}
inline simcore::InputEvent jaws(bool closed) {
  simcore::InputEvent e;
  e.kind = simcore::InputKind::Jaw;
  e.on = closed;
  return e;
}
/// The scissors' blade on or off.
inline simcore::InputEvent cutting(bool on) {
  simcore::InputEvent e;
  e.kind = simcore::InputKind::Cut;
  e.tool = 1;
  e.on = on;
  return e;
}

/// A scene's body as the session takes it (metres, its attachments, materials and settings).
inline simcore::BodySetup sceneBody(const simcore::Scene& p) {
  simcore::BodySetup s;
  s.mesh = p.mesh;
  s.mesh.convertToMetres();
  s.fixedNodes = p.fixedNodes;
  s.material = p.defaultMaterial;
  s.byLabel = p.materials;
  s.settings = p.settings;
  return s;
}

/// A preset's body as the session takes it.
inline simcore::BodySetup presetBody(const std::string& name, const std::string& sharedData = "../shared/data") {
  return sceneBody(phantom::makePreset(name, sharedData));
}

}  // namespace rehearse::testing
