#pragma once
// Simulation presets: the four cases of DejaVu (eye, kidney, liver, uterus; materials from its table,
// geometry of the built-in phantom or of any loaded organ, density of the tissue (mass from the organ's volume)), hung by the
// organ's attachment nodes, and SOFA's liver.scn on ../shared/data/sofa/liver.msh.
#include "phantom/phantom.hpp"

#include <rehearse/simcore/scene.hpp>

#include <string>
#include <vector>

namespace rehearse::phantom {

/// "eye", "kidney", "liver", "uterus", "sofa-liver".
const std::vector<std::string>& presetNames();
/// A preset on a given organ (volume mesh in metres, its attachments); gravity along the model's +y
/// (the phantom's inferior direction). Throws simcore::MeshError for an unknown name.
simcore::Scene makePreset(const std::string& name, const simcore::Mesh& organ, const std::vector<int>& attachments);
/// The same parameters with another material law for every label (the benchmarks and the elastic fit use
/// the co-rotational law with the DejaVu liver's moduli).
void setMaterialModel(simcore::Scene& scene, simcore::MaterialModel model);
/// A preset on the built-in phantom (or, for sofa-liver, on SOFA's file, looked up under `sharedData`).
simcore::Scene makePreset(const std::string& name, const std::string& sharedData = "../shared/data");

}  // namespace rehearse::phantom
