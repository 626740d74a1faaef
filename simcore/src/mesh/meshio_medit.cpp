// Medit ascii .mesh reader and writer (Vertices, Triangles, Tetrahedra with reference labels).
#include <rehearse/simcore/meshio.hpp>

#include "text_reader.hpp"

#include <cstdio>
#include <map>

namespace rehearse::simcore {

Mesh parseMedit(std::string_view bytes) {
  detail::TextReader r(bytes, "Medit .mesh");
  // Items per entry of the sections we skip.
  static const std::map<std::string, int> kSkip = {
      {"edges", 3},           {"corners", 1},      {"ridges", 1},          {"requiredvertices", 1},
      {"requirededges", 1},   {"requiredtriangles", 1}, {"quadrilaterals", 5}, {"hexahedra", 9},
      {"prisms", 7},          {"normals", 3},      {"normalatvertices", 2}, {"tangents", 3},
      {"tangentatvertices", 2}, {"identifier", 0}, {"geometry", 0}};
  Mesh m;
  bool sawVersion = false, sawVertices = false;
  auto idx = [&](long long v) {
    if (v < 1 || v > static_cast<long long>(m.points.size()))
      r.fail("an element refers to vertex " + std::to_string(v) + ", which does not exist");
    return static_cast<int>(v - 1);
  };
  while (!r.atEnd()) {
    auto t = r.token();
    if (t[0] == '#') {
      r.line();
      continue;
    }
    auto k = detail::lower(t);
    if (k == "meshversionformatted") {
      long long v = r.integer("version");
      if (v < 1 || v > 4) r.fail("mesh version " + std::to_string(v) + " is not supported");
      sawVersion = true;
    } else if (k == "dimension") {
      if (r.integer("dimension") != 3) r.fail("only 3D meshes are supported");
    } else if (k == "vertices") {
      std::size_t n = r.count("vertex", kMaxMeshItems);
      r.expectRoom(n, 8, "vertices");
      m.points.resize(n);
      for (auto& p : m.points) {
        p.x() = r.real("x");
        p.y() = r.real("y");
        p.z() = r.real("z");
        r.integer("vertex reference");
      }
      sawVertices = true;
    } else if (k == "triangles") {
      std::size_t n = r.count("triangle", kMaxMeshItems);
      for (std::size_t i = 0; i < n; ++i) {
        std::array<int, 3> tri;
        for (int& v : tri) v = idx(r.integer("triangle vertex"));
        m.triangles.push_back(tri);
        m.triangleLabels.push_back(static_cast<int>(r.integer("triangle reference")));
      }
    } else if (k == "tetrahedra") {
      std::size_t n = r.count("tetrahedron", kMaxMeshItems);
      for (std::size_t i = 0; i < n; ++i) {
        std::array<int, 4> tet;
        for (int& v : tet) v = idx(r.integer("tetrahedron vertex"));
        m.tets.push_back(tet);
        m.tetLabels.push_back(static_cast<int>(r.integer("tetrahedron reference")));
      }
    } else if (k == "end") {
      break;
    } else if (auto it = kSkip.find(k); it != kSkip.end()) {
      if (it->second == 0) {
        r.line();
        continue;
      }
      std::size_t n = r.count(it->first.c_str(), kMaxMeshItems);
      for (std::size_t i = 0; i < n * it->second; ++i) r.token();
    } else {
      r.fail("keyword '" + std::string(t.substr(0, 30)) + "' is not supported");
    }
  }
  if (!sawVersion || !sawVertices) r.fail("MeshVersionFormatted or Vertices is missing");
  return m;
}

std::string writeMedit(const Mesh& m) {
  std::string out = "MeshVersionFormatted 2\nDimension 3\nVertices\n" + std::to_string(m.points.size()) + "\n";
  char buf[160];
  for (const auto& p0 : m.points) {
    Eigen::Vector3d p = p0 * m.unitToMetre;
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g 0\n", p.x(), p.y(), p.z());
    out += buf;
  }
  if (!m.triangles.empty()) {
    out += "Triangles\n" + std::to_string(m.triangles.size()) + "\n";
    for (std::size_t i = 0; i < m.triangles.size(); ++i) {
      const auto& t = m.triangles[i];
      std::snprintf(buf, sizeof buf, "%d %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1, m.triangleLabels.empty() ? 0 : m.triangleLabels[i]);
      out += buf;
    }
  }
  if (!m.tets.empty()) {
    out += "Tetrahedra\n" + std::to_string(m.tets.size()) + "\n";
    for (std::size_t i = 0; i < m.tets.size(); ++i) {
      const auto& t = m.tets[i];
      std::snprintf(buf, sizeof buf, "%d %d %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1, m.tetLabels.empty() ? 0 : m.tetLabels[i]);
      out += buf;
    }
  }
  out += "End\n";
  return out;
}

}  // namespace rehearse::simcore
