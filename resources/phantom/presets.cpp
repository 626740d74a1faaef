#include "phantom/presets.hpp"

#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>

#include <cmath>
#include <filesystem>

namespace rehearse::phantom {
namespace {
// DejaVu's materials (Table 1). Density is the tissue's (IT'IS Foundation tissue properties database v4.1: vitreous
// humour 1005, kidney 1066, liver 1079, uterus 1105 kg/m^3; the vessels inside take the organ's, as the session's
// parameter edits do): an organ's mass follows its own volume. (The paper's masses — eye 7 g, kidney 115 g, liver 1.2 kg, uterus 80 g — are its organs'; forcing them
// onto another organ gave the phantom 2,894 kg/m^3 and the patient liver 527.)
struct Table {
  const char* name;
  simcore::MaterialModel model;
  double young, poisson, density, vesselYoung, vesselPoisson;  // Pa, -, kg/m^3, Pa, -
};
constexpr Table kTable[] = {{"eye", simcore::MaterialModel::Corotational, 150e3, 0.45, 1005, 0, 0},
                            {"kidney", simcore::MaterialModel::Linear, 250e3, 0.40, 1066, 3200e3, 0.45},
                            {"liver", simcore::MaterialModel::StVK, 27e3, 0.40, 1079, 620e3, 0.45},
                            {"uterus", simcore::MaterialModel::Corotational, 400e3, 0.35, 1105, 0, 0}};
}  // namespace

const std::vector<std::string>& presetNames() {
  static const std::vector<std::string> names = {"eye", "kidney", "liver", "uterus", "sofa-liver"};
  return names;
}

simcore::Scene makePreset(const std::string& name, const simcore::Mesh& organ, const std::vector<int>& attachments) {
  for (const auto& c : kTable)
    if (name == c.name) {
      simcore::Scene s;
      s.mesh = organ;
      s.mesh.convertToMetres();
      double volume = 0;
      for (const auto& t : s.mesh.tets)
        volume += std::abs(simcore::tetVolume(s.mesh.points[t[0]], s.mesh.points[t[1]], s.mesh.points[t[2]], s.mesh.points[t[3]]));
      if (!(volume > 0)) throw simcore::MeshError("The organ has no volume; tetrahedralise it before simulating.");
      s.defaultMaterial = {c.model, c.young, c.poisson, c.density};
      if (c.vesselYoung > 0) s.materials[kVesselLabel] = {c.model, c.vesselYoung, c.vesselPoisson, c.density};
      s.fixedNodes = attachments;
      s.settings.timeStep = 0.01;
      s.settings.gravity = Eigen::Vector3d(0, 9.81, 0);  // the phantom's model y axis points down (inferior)
      s.components = {"mesh", "material", "attachments", "gravity", "damping", "implicit_euler", "solver"};
      return s;
    }
  throw simcore::MeshError("Unknown preset '" + name + "'; use eye, kidney, liver, uterus or sofa-liver.");
}

void setMaterialModel(simcore::Scene& scene, simcore::MaterialModel model) {
  scene.defaultMaterial.model = model;
  for (auto& [label, m] : scene.materials) m.model = model;
}

simcore::Scene makePreset(const std::string& name, const std::string& sharedData) {
  if (name == "sofa-liver") {
    const std::string path = sharedData + "/sofa/liver.msh";
    if (!std::filesystem::exists(path))
      throw simcore::MeshError("The sofa-liver preset reads " + path + ", which is absent here; run from the project folder.");
    simcore::Scene s;
    s.mesh = simcore::loadMesh(path, {"m"});  // SOFA's scene uses the file's numbers as they are
    s.defaultMaterial = {simcore::MaterialModel::Corotational, 3000, 0.3, 1.0};
    s.fixedNodes = {3, 39, 64};
    s.settings.timeStep = 0.02;
    s.settings.gravity = Eigen::Vector3d(0, -9.81, 0);
    s.components = {"mesh", "material", "attachments", "gravity", "damping", "implicit_euler", "solver"};
    return s;
  }
  bool known = false;
  for (const auto& n : presetNames()) known |= n == name;
  if (!known) throw simcore::MeshError("Unknown preset '" + name + "'; use eye, kidney, liver, uterus or sofa-liver.");
  const Phantom ph = makePhantom();
  return makePreset(name, ph.volume, ph.attachments);
}

}  // namespace rehearse::phantom
