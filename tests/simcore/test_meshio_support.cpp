// The mesh I/O suite's shared parts (see test_meshio_support.hpp).
#include "test_meshio_support.hpp"
#include "cli_run.hpp"
#include "test_support.hpp"

#include <rehearse/simcore/quality.hpp>

#include <nlohmann/json.hpp>
#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <regex>
#include <set>
#include <sstream>

using namespace rehearse::simcore;

std::size_t vtkDeclaredPoints(const std::string& bytes) {
  std::smatch m;
  std::string head = bytes.substr(0, 4096);
  if (std::regex_search(head, m, std::regex("POINTS (\\d+)"))) return std::stoul(m[1]);
  return 0;
}

std::size_t objUsedVertices(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  std::set<std::string> positions;
  std::vector<std::string> verts;
  std::set<long> used;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) verts.push_back(line.substr(2));
    if (line.rfind("f ", 0) == 0) {
      std::istringstream f(line.substr(2));
      std::string tok;
      while (f >> tok) used.insert(std::stol(tok.substr(0, tok.find('/'))) - 1);
    }
  }
  // Distinct positions among used vertices (we weld exact duplicates).
  for (long u : used) {
    std::istringstream p(verts.at(u));
    double x, y, z;
    p >> x >> y >> z;
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g", x, y, z);
    positions.insert(buf);
  }
  return positions.size();
}

Mesh twoTets() {
  Mesh m;
  m.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  m.tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};
  // Second tet: orientation of (1,2,3,4)
  if (tetVolume(m.points[1], m.points[2], m.points[3], m.points[4]) < 0) std::swap(m.tets[1][2], m.tets[1][3]);
  m.tetLabels = {7, 9};
  m.triangles = {{0, 2, 1}};
  m.triangleLabels = {3};
  return m;
}

void compareMeshes(const Mesh& a, const Mesh& b, bool withTriangles) {
  QCOMPARE(b.points.size(), a.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) QVERIFY((a.points[i] - b.points[i]).norm() < 1e-12);
  QCOMPARE(b.tets.size(), a.tets.size());
  for (std::size_t i = 0; i < a.tets.size(); ++i) {
    QVERIFY(a.tets[i] == b.tets[i]);
    QCOMPARE(b.tetLabels[i], a.tetLabels[i]);
  }
  if (withTriangles) {
    QCOMPARE(b.triangles.size(), a.triangles.size());
    for (std::size_t i = 0; i < a.triangles.size(); ++i) QVERIFY(a.triangles[i] == b.triangles[i]);
  }
}

std::string msh22Binary(const Mesh& m) {
  std::string s = "$MeshFormat\n2.2 1 8\n";
  putLE<int>(s, 1);
  s += "\n$EndMeshFormat\n$Nodes\n" + std::to_string(m.points.size()) + "\n";
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    putLE<int>(s, static_cast<int>(i + 10));  // non-contiguous tags
    for (int k = 0; k < 3; ++k) putLE<double>(s, m.points[i][k]);
  }
  s += "\n$EndNodes\n$Elements\n" + std::to_string(m.tets.size()) + "\n";
  putLE<int>(s, 4);
  putLE<int>(s, static_cast<int>(m.tets.size()));
  putLE<int>(s, 2);
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    putLE<int>(s, static_cast<int>(e + 1));
    putLE<int>(s, m.tetLabels[e]);
    putLE<int>(s, m.tetLabels[e]);
    for (int v : m.tets[e]) putLE<int>(s, v + 10);
  }
  s += "\n$EndElements\n";
  return s;
}

std::string msh41(const Mesh& m, bool binary) {
  std::string s = std::string("$MeshFormat\n4.1 ") + (binary ? "1" : "0") + " 8\n";
  if (binary) {
    putLE<int>(s, 1);
    s += "\n";
  }
  s += "$EndMeshFormat\n$PhysicalNames\n2\n3 7 \"liver\"\n3 9 \"vessel\"\n$EndPhysicalNames\n$Entities\n";
  auto sz = [&](std::size_t v) { binary ? putLE<std::uint64_t>(s, v) : void(s += std::to_string(v) + " "); };
  auto in = [&](int v) { binary ? putLE<int>(s, v) : void(s += std::to_string(v) + " "); };
  auto dbl = [&](double v) {
    if (binary) putLE<double>(s, v);
    else {
      char b[40];
      std::snprintf(b, sizeof b, "%.17g ", v);
      s += b;
    }
  };
  auto nl = [&] {
    if (!binary) s += "\n";
  };
  sz(0), sz(0), sz(0), sz(2), nl();
  for (int e = 0; e < 2; ++e) {
    in(e + 1);
    for (int k = 0; k < 6; ++k) dbl(0);
    sz(1), in(m.tetLabels[e]), sz(0), nl();
  }
  if (binary) s += "\n";
  s += "$EndEntities\n$Nodes\n";
  sz(1), sz(m.points.size()), sz(1), sz(m.points.size()), nl();
  in(3), in(1), in(0), sz(m.points.size()), nl();
  for (std::size_t i = 0; i < m.points.size(); ++i) sz(i + 1), nl();
  for (const auto& p : m.points) dbl(p.x()), dbl(p.y()), dbl(p.z()), nl();
  if (binary) s += "\n";
  s += "$EndNodes\n$Elements\n";
  sz(2), sz(2), sz(1), sz(2), nl();
  for (int e = 0; e < 2; ++e) {
    in(3), in(e + 1), in(4), sz(1), nl();
    sz(e + 1);
    for (int v : m.tets[e]) sz(v + 1);
    nl();
  }
  if (binary) s += "\n";
  s += "$EndElements\n";
  return s;
}

std::string vtk51Ascii(const Mesh& m) {
  std::string s = "# vtk DataFile Version 5.1\nnew layout\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n";
  for (const auto& p : m.points) s += std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
  s += "CELLS 3 8\nOFFSETS vtktypeint64\n0 4 8\nCONNECTIVITY vtktypeint64\n";
  for (const auto& t : m.tets) s += std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + " " + std::to_string(t[3]) + "\n";
  s += "CELL_TYPES 2\n10\n10\nCELL_DATA 2\nFIELD FieldData 1\nregion 1 2 int\n7 9\n";
  return s;
}

std::string base64(const std::string& in) {
  static const char* a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < in.size(); i += 3) {
    unsigned w = static_cast<unsigned char>(in[i]) << 16;
    if (i + 1 < in.size()) w |= static_cast<unsigned char>(in[i + 1]) << 8;
    if (i + 2 < in.size()) w |= static_cast<unsigned char>(in[i + 2]);
    out += a[(w >> 18) & 63];
    out += a[(w >> 12) & 63];
    out += i + 1 < in.size() ? a[(w >> 6) & 63] : '=';
    out += i + 2 < in.size() ? a[w & 63] : '=';
  }
  return out;
}

std::string vtuVariant(const Mesh& m, bool compressed) {
  std::vector<float> pts;
  for (const auto& p : m.points)
    for (int k = 0; k < 3; ++k) pts.push_back(static_cast<float>(p[k]));
  std::vector<std::int32_t> conn, offs = {4, 8}, labels = {m.tetLabels[0], m.tetLabels[1]};
  for (const auto& t : m.tets)
    for (int v : t) conn.push_back(v);
  std::vector<std::uint8_t> types = {10, 10};
  auto bytesOf = [](const auto& v) { return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(v[0])); };
  std::string appended;
  auto array = [&](const char* type, const char* name, int comps, const std::string& raw) {
    std::string head = std::string("<DataArray type=\"") + type + "\" Name=\"" + name + "\" NumberOfComponents=\"" + std::to_string(comps) + "\" ";
    if (compressed) {
      uLongf n = compressBound(raw.size());
      std::string z(n, '\0');
      compress(reinterpret_cast<Bytef*>(z.data()), &n, reinterpret_cast<const Bytef*>(raw.data()), raw.size());
      z.resize(n);
      std::string h;
      putLE<std::uint32_t>(h, 1);
      putLE<std::uint32_t>(h, static_cast<std::uint32_t>(raw.size()));
      putLE<std::uint32_t>(h, static_cast<std::uint32_t>(raw.size()));
      putLE<std::uint32_t>(h, static_cast<std::uint32_t>(z.size()));
      return head + "format=\"binary\">" + base64(h) + base64(z) + "</DataArray>\n";
    }
    std::string out = head + "format=\"appended\" offset=\"" + std::to_string(appended.size()) + "\"/>\n";
    putLE<std::uint64_t>(appended, raw.size());
    appended += raw;
    return out;
  };
  std::string s = std::string("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\"") +
                  (compressed ? " header_type=\"UInt32\" compressor=\"vtkZLibDataCompressor\">" : " header_type=\"UInt64\">") +
                  "\n<UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\">\n<CellData>" +
                  array("Int32", "region", 1, bytesOf(labels)) + "</CellData>\n<Points>" + array("Float32", "pts", 3, bytesOf(pts)) +
                  "</Points>\n<Cells>" + array("Int32", "connectivity", 1, bytesOf(conn)) + array("Int32", "offsets", 1, bytesOf(offs)) +
                  array("UInt8", "types", 1, bytesOf(types)) + "</Cells>\n</Piece></UnstructuredGrid>\n";
  if (!compressed) s += "<AppendedData encoding=\"raw\">\n_" + appended + "\n</AppendedData>\n";
  s += "</VTKFile>\n";
  return s;
}

void expectRefused(const std::function<Mesh(std::string_view)>& parse, const std::string& bytes, const char* what) {
  try {
    Mesh m = parse(bytes);
    validateMesh(m, what);  // a parse that "succeeds" must still fail validation
    QFAIL(qPrintable(QString("accepted: %1").arg(what)));
  } catch (const MeshError& e) {
    QVERIFY2(std::string(e.what()).find('\n') == std::string::npos, "error messages are one line");
  }
}

int glbTrianglePrimitives(const std::string& glb) {
  if (glb.size() < 20 || glb.compare(0, 4, "glTF") != 0) return -1;
  std::uint32_t length = 0;
  std::memcpy(&length, glb.data() + 12, 4);
  const auto j = nlohmann::json::parse(glb.substr(20, length));
  int n = 0;
  for (const auto& mesh : j.at("meshes"))
    for (const auto& p : mesh.at("primitives")) n += p.value("mode", 4) == 4;
  return n;
}

void expectFileRefused(const std::string& file, const std::string& bytes, const QString& expect, bool cli,
                       const LoadOptions& options) {
  const std::string p = tempPath(file);
  writeFile(p, bytes);
  try {
    loadMesh(p, options);
    QFAIL(qPrintable("accepted: " + QString::fromStdString(file)));
  } catch (const MeshError& e) {
    const QString w = QString::fromUtf8(e.what());
    QVERIFY2(w.contains(QString::fromStdString(file)) && w.contains(expect) && !w.contains('\n'), qPrintable(w));
  }
  if (!cli) return;
  const auto r = testing::run({"info", QString::fromStdString(p)}, 60000);
  QVERIFY2(r.code >= 1 && r.code <= 123, qPrintable(QString("%1: exit %2 %3").arg(QString::fromStdString(file)).arg(r.code).arg(r.err)));
  QVERIFY2(r.err.trimmed().count('\n') == 0 && r.err.contains(expect), qPrintable(r.err));
}

std::string plyHeader(const char* format, int vertices, int faces, const char* listType) {
  return std::string("ply\nformat ") + format + " 1.0\nelement vertex " + std::to_string(vertices) +
         "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(faces) +
         "\nproperty list " + listType + " vertex_indices\nend_header\n";
}

std::string gltfWith(const std::string& nodes, const std::string& roots, const std::string& extra) {
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": )" + roots + R"(}], "nodes": )" + nodes +
         R"(, "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "accessors": [{"componentType": 5126,
         "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}])" + extra + "}";
}
