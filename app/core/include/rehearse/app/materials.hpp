#pragma once
// The case's material (app::MaterialSettings) as simcore materials by label, and the names the command
// line, scenes and panels accept for solver settings, parsed in one place (simcore/scene.hpp).
#include "rehearse/app/case.hpp"

#include <rehearse/simcore/scene.hpp>

#include <map>

namespace rehearse::app {

/// Parenchyma (and any label not listed) and, when vesselYoung > 0, kVesselLabel.
struct LabelMaterials {
  simcore::MaterialParams fallback;
  std::map<int, simcore::MaterialParams> byLabel;
};
LabelMaterials labelMaterials(const MaterialSettings& m);

/// The case's material from a scene's (what `rehearse register --scene/--preset` and the panel's presets give).
MaterialSettings materialFromScene(const simcore::Scene& s);

/// A DejaVu preset's material on this organ (the tissue's density: the mass follows the organ's volume).
/// Throws simcore::MeshError for an unknown name or an organ without volume.
MaterialSettings presetMaterial(const std::string& name, const Organ& organ);

/// The material a new organ gets: the DejaVu liver's moduli (vessels 0.62 MPa) with the co-rotational
/// law, as the elastic fit's benchmarks measured it; the liver tissue's density (1,079 kg/m^3). Edited in the
/// Simulation panel. An organ without volume gets MaterialSettings's defaults.
MaterialSettings defaultMaterial(const Organ& organ);

}  // namespace rehearse::app
