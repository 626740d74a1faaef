#include <rehearse/simcore/mesh.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cmath>
#include <tuple>

namespace rehearse::simcore {

std::string Mesh::labelName(int label) const {
  for (const auto& [l, n] : labelNames)
    if (l == label) return n;
  return {};
}

StructureKind structureKind(const std::string& name) {
  std::string n = name;
  for (auto& c : n) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  // Whole words for the abbreviations (no "ivc" inside another word); stems for the rest.
  auto word = [&n](const std::string& w) {
    for (std::size_t at = n.find(w); at != std::string::npos; at = n.find(w, at + 1)) {
      const bool before = at == 0 || !std::isalnum(static_cast<unsigned char>(n[at - 1]));
      const bool after = at + w.size() == n.size() || !std::isalnum(static_cast<unsigned char>(n[at + w.size()]));
      if (before && after) return true;
    }
    return false;
  };
  auto any = [&n](std::initializer_list<const char*> stems) {
    return std::any_of(stems.begin(), stems.end(), [&n](const char* s) { return n.find(s) != std::string::npos; });
  };
  if (any({"ligament"})) return StructureKind::Ligament;
  const bool tumour = any({"tumour", "tumor", "lesion", "metasta", "carcinoma", "nodule"});
  // A tumour's (or a resection's) margin; "the inferior margin of the liver" is a border of the organ, not one.
  if (any({"margin"}) && (tumour || any({"resection", "safety", "ablation"}))) return StructureKind::TumourMargin;
  if (any({"bile", "biliar", "cystic duct", "hepatic duct", "choledoch"}) || word("cbd"))
    return StructureKind::BileDuct;
  if (any({"portal"}) || word("pv")) return StructureKind::PortalVein;
  if (any({"arter", "aorta"}) || word("ha")) return StructureKind::Artery;
  if (any({"vein", "venous", "cava"}) || word("ivc") || word("hv")) return StructureKind::Vein;
  if (any({"vessel", "vascul"})) return StructureKind::Vessel;
  if (tumour) return StructureKind::Tumour;
  return StructureKind::Tissue;
}

std::string structureWords(StructureKind kind, const std::string& labelName) {
  auto lowered = [](std::string t) {
    for (char& ch : t) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return t;
  };
  const std::string what = structureKindName(kind), name = lowered(labelName), k = lowered(what);
  if (name.empty() || name == k || name == k + "s") return what;
  if (name.find(k) != std::string::npos) return labelName;
  return what + " (" + labelName + ")";
}

const char* indefiniteArticle(const std::string& words) {
  return !words.empty() && std::string("aeiouAEIOU").find(words[0]) != std::string::npos ? "An" : "A";
}

const char* structureKindName(StructureKind kind) {
  switch (kind) {
    case StructureKind::Tissue:
      return "tissue";
    case StructureKind::Ligament:
      return "ligament";
    case StructureKind::Vessel:
      return "vessel";
    case StructureKind::Artery:
      return "artery";
    case StructureKind::Vein:
      return "vein";
    case StructureKind::PortalVein:
      return "portal vein";
    case StructureKind::BileDuct:
      return "bile duct";
    case StructureKind::Tumour:
      return "tumour";
    case StructureKind::TumourMargin:
      return "tumour margin";
  }
  return "tissue";
}

bool isVessel(StructureKind kind) {
  return kind == StructureKind::Vessel || kind == StructureKind::Artery || kind == StructureKind::Vein ||
         kind == StructureKind::PortalVein;
}

StructureKind Mesh::labelKind(int label) const { return structureKind(labelName(label)); }

bool Mesh::labelIsVessel(int label) const { return isVessel(labelKind(label)); }

bool Mesh::namesAVessel() const {
  return std::any_of(labelNames.begin(), labelNames.end(), [this](const auto& l) { return labelIsVessel(l.first); });
}

void Mesh::setLabelName(int label, const std::string& name) {
  for (auto& [l, n] : labelNames)
    if (l == label) {
      n = name;
      return;
    }
  labelNames.emplace_back(label, name);
}

SurfaceView Mesh::surfaceView() const {
  SurfaceView v;
  v.vertices = points.empty() ? nullptr : points.front().data();
  v.vertexCount = points.size();
  v.triangles = triangles.empty() ? nullptr : triangles.front().data();
  v.triangleCount = triangles.size();
  return v;
}

Eigen::AlignedBox3d Mesh::bounds() const {
  Eigen::AlignedBox3d b;
  for (const auto& p : points) b.extend(p);
  return b;
}

void Mesh::convertToMetres() {
  if (unitToMetre == 1.0) return;
  for (auto& p : points) p *= unitToMetre;
  unitToMetre = 1.0;
}

std::vector<int> Mesh::compact() {
  std::vector<int> newIndex(points.size(), -1);
  for (const auto& t : triangles)
    for (int v : t) newIndex[v] = 0;
  for (const auto& t : tets)
    for (int v : t) newIndex[v] = 0;
  std::vector<int> oldIndex;
  std::vector<Eigen::Vector3d> kept;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (newIndex[i] == 0) {
      newIndex[i] = static_cast<int>(kept.size());
      kept.push_back(points[i]);
      oldIndex.push_back(static_cast<int>(i));
    }
  for (auto& t : triangles)
    for (int& v : t) v = newIndex[v];
  for (auto& t : tets)
    for (int& v : t) v = newIndex[v];
  points = std::move(kept);
  return oldIndex;
}

std::vector<std::array<int, 3>> boundaryTriangles(const Mesh& m, bool includeInterfaces, std::vector<int>* labels) {
  // Outward faces of a positively oriented tet (a,b,c,d).
  static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  struct Entry {
    std::array<int, 3> key;
    int tet;
    int face;
  };
  std::vector<Entry> entries;
  entries.reserve(m.tets.size() * 4);
  for (std::size_t t = 0; t < m.tets.size(); ++t)
    for (int f = 0; f < 4; ++f) {
      std::array<int, 3> k = {m.tets[t][kFace[f][0]], m.tets[t][kFace[f][1]], m.tets[t][kFace[f][2]]};
      std::sort(k.begin(), k.end());
      entries.push_back({k, static_cast<int>(t), f});
    }
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return std::tie(a.key, a.tet) < std::tie(b.key, b.tet); });
  std::vector<std::array<int, 3>> out;
  if (labels) labels->clear();
  auto label = [&](int t) { return m.tetLabels.empty() ? 0 : m.tetLabels[t]; };
  auto emit = [&](const Entry& e) {
    const auto& tet = m.tets[e.tet];
    out.push_back({tet[kFace[e.face][0]], tet[kFace[e.face][1]], tet[kFace[e.face][2]]});
    if (labels) labels->push_back(label(e.tet));
  };
  for (std::size_t i = 0; i < entries.size();) {
    std::size_t j = i + 1;
    while (j < entries.size() && entries[j].key == entries[i].key) ++j;
    if (j - i == 1) {
      emit(entries[i]);
    } else if (includeInterfaces && j - i == 2 && label(entries[i].tet) != label(entries[i + 1].tet)) {
      emit(label(entries[i].tet) > label(entries[i + 1].tet) ? entries[i] : entries[i + 1]);
    }
    i = j;
  }
  return out;
}

double metresPerUnit(const std::string& unit) {
  if (unit == "m") return 1.0;
  if (unit == "dm") return 0.1;
  if (unit == "cm") return 0.01;
  if (unit == "mm") return 0.001;
  throw MeshError("Unknown length unit '" + unit + "'; use m, dm, cm or mm.");
}

OrganSize checkOrganSize(double sizeMetres, const std::string& unit) {
  OrganSize out;
  out.organSized = sizeMetres >= 0.01 && sizeMetres <= 1.0;
  if (out.organSized) return out;
  double perUnit = sizeMetres;  // the file's own coordinates' extent
  try {
    perUnit = sizeMetres / metresPerUnit(unit);
  } catch (const MeshError&) {
  }
  for (const char* name : {"mm", "m", "cm", "dm"})
    if (const double s = perUnit * metresPerUnit(name); name != unit && s >= 0.01 && s <= 1.0) out.likely.emplace_back(name, s);
  return out;
}

std::string OrganSize::likelyText() const {
  std::string text;
  for (std::size_t i = 0; i < likely.size(); ++i) {
    char one[64];
    std::snprintf(one, sizeof one, "%s (%.0f mm across)", likely[i].first.c_str(), likely[i].second * 1e3);
    text += std::string(i == 0 ? "" : i + 1 == likely.size() ? " or " : ", ") + one;
  }
  return text;
}

void validateMesh(const Mesh& m, const std::string& what) {
  if (m.points.empty()) throw MeshError(what + " holds no points; choose a file that contains a mesh.");
  if (m.triangles.empty() && m.tets.empty())
    throw MeshError(what + " holds no triangles or tetrahedra; choose a surface or volume mesh.");
  if (m.points.size() > kMaxMeshItems || m.triangles.size() > kMaxMeshItems || m.tets.size() > kMaxMeshItems)
    throw MeshError(what + " is too large (more than " + std::to_string(kMaxMeshItems) +
                    " points or elements); decimate it first.");
  for (std::size_t i = 0; i < m.points.size(); ++i)
    if (!m.points[i].allFinite())
      throw MeshError(what + " has a non-finite coordinate (NaN or infinity) at point " + std::to_string(i) +
                      "; fix or re-export the mesh.");
  const int n = static_cast<int>(m.points.size());
  auto checkIndex = [&](int v, const char* kind, std::size_t e) {
    if (v < 0 || v >= n)
      throw MeshError(what + " has " + kind + " " + std::to_string(e) + " referring to point " + std::to_string(v) +
                      ", which does not exist; the file is inconsistent.");
  };
  for (std::size_t e = 0; e < m.triangles.size(); ++e)
    for (int v : m.triangles[e]) checkIndex(v, "triangle", e);
  for (std::size_t e = 0; e < m.tets.size(); ++e)
    for (int v : m.tets[e]) checkIndex(v, "tetrahedron", e);
  if (m.triangleLabels.size() != m.triangles.size() || m.tetLabels.size() != m.tets.size())
    throw MeshError(what + " has a label count that does not match its element count.");
}

}  // namespace rehearse::simcore
