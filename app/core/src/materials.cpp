#include "rehearse/app/materials.hpp"

#include "phantom/presets.hpp"

namespace rehearse::app {

LabelMaterials labelMaterials(const MaterialSettings& m) {
  LabelMaterials out;
  out.fallback = {m.model, m.young, m.poisson, m.density, m.tearStrain};
  if (m.vesselYoung > 0) out.byLabel[kVesselLabel] = {m.model, m.vesselYoung, m.vesselPoisson, m.density, m.tearStrain};
  return out;
}

MaterialSettings materialFromScene(const simcore::Scene& s) {
  MaterialSettings m;
  m.model = s.defaultMaterial.model;
  m.young = s.defaultMaterial.young;
  m.poisson = s.defaultMaterial.poisson;
  m.density = s.defaultMaterial.density;
  m.tearStrain = s.defaultMaterial.tearStrain;
  if (const auto v = s.materials.find(kVesselLabel); v != s.materials.end()) {
    m.vesselYoung = v->second.young;
    m.vesselPoisson = v->second.poisson;
  }
  return m;
}

MaterialSettings presetMaterial(const std::string& name, const Organ& organ) {
  return materialFromScene(phantom::makePreset(name, organ.volume, {}));
}

MaterialSettings defaultMaterial(const Organ& organ) {
  if (organ.empty()) return {};
  try {
    MaterialSettings m = presetMaterial("liver", organ);
    m.model = simcore::MaterialModel::Corotational;
    return m;
  } catch (const simcore::MeshError&) {
    return {};  // a degenerate volume: the fit and the simulation will say why
  }
}

}  // namespace rehearse::app
