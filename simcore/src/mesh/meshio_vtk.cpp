// VTK legacy reader (ascii/binary; POLYDATA and UNSTRUCTURED_GRID, old and 5.1 cell layouts) and writer.
#include <rehearse/simcore/meshio.hpp>

#include "text_reader.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>

namespace rehearse::simcore {
namespace {

using detail::iequals;
using detail::TextReader;

int typeSize(std::string_view t) {
  auto l = detail::lower(t);
  if (l == "bit") return -1;
  if (l == "unsigned_char" || l == "char") return 1;
  if (l == "short" || l == "unsigned_short") return 2;
  if (l == "int" || l == "unsigned_int" || l == "float") return 4;
  if (l == "long" || l == "unsigned_long" || l == "double" || l == "vtktypeint64" || l == "vtktypeuint64" ||
      l == "vtkidtype")
    return 8;
  return 0;
}
bool isIntegerType(std::string_view t) {
  auto l = detail::lower(t);
  return l != "float" && l != "double";
}

struct Reader {
  TextReader r;
  bool binary = false;

  // Reads n values of the named VTK type as doubles.
  std::vector<double> values(std::size_t n, std::string_view type) {
    int size = typeSize(type);
    if (size <= 0) r.fail("data type '" + std::string(type) + "' is not supported");
    if (n > 8 * kMaxMeshItems) r.fail("a data array is too large");
    if (binary) {
      if (r.position() == 0 || r.bytes()[r.position() - 1] != '\n') r.skipLineEnd();
    }
    r.expectRoom(n, binary ? size : 2, "values");
    std::vector<double> out(n);
    if (binary) {
      auto d = r.take(n * size, "binary data array");
      auto l = detail::lower(type);
      for (std::size_t i = 0; i < n; ++i) {
        const char* p = d.data() + i * size;
        double v = 0;
        if (l == "float") v = detail::readBinary<float>(p, true);
        else if (l == "double") v = detail::readBinary<double>(p, true);
        else if (l == "char") v = static_cast<signed char>(*p);
        else if (l == "unsigned_char") v = static_cast<unsigned char>(*p);
        else if (l == "short") v = detail::readBinary<std::int16_t>(p, true);
        else if (l == "unsigned_short") v = detail::readBinary<std::uint16_t>(p, true);
        else if (l == "int") v = detail::readBinary<std::int32_t>(p, true);
        else if (l == "unsigned_int") v = detail::readBinary<std::uint32_t>(p, true);
        else if (l == "vtktypeuint64" || l == "unsigned_long") v = static_cast<double>(detail::readBinary<std::uint64_t>(p, true));
        else v = static_cast<double>(detail::readBinary<std::int64_t>(p, true));
        out[i] = v;
      }
    } else {
      for (auto& v : out) v = r.real("data value");
    }
    return out;
  }

  // Cells in either layout; returns per-cell point lists.
  std::vector<std::vector<long long>> cells(const char* what) {
    std::size_t n = r.count(what, kMaxMeshItems);
    std::size_t size = r.count("cell list size", 16 * kMaxMeshItems);
    std::vector<std::vector<long long>> out;
    auto next = r.peekToken();
    if (iequals(next, "OFFSETS")) {  // VTK 5.1 layout: n = offsets count, size = connectivity size
      r.token();
      auto otype = r.token();
      auto offsets = values(n, otype);
      auto c = r.token();
      if (!iequals(c, "CONNECTIVITY")) r.fail("expected CONNECTIVITY after OFFSETS");
      auto ctype = r.token();
      auto conn = values(size, ctype);
      if (n == 0) return out;
      for (std::size_t i = 0; i + 1 < n; ++i) {
        double a = offsets[i], b = offsets[i + 1];
        if (!(a >= 0 && b >= a && b <= static_cast<double>(size))) r.fail("cell offsets are inconsistent");
        std::vector<long long> cell;
        for (auto k = static_cast<std::size_t>(a); k < static_cast<std::size_t>(b); ++k) cell.push_back(detail::toInteger(conn[k]));
        out.push_back(std::move(cell));
      }
      return out;
    }
    auto data = values(size, "int");
    std::size_t k = 0;
    out.reserve(std::min(n, data.size()));
    for (std::size_t i = 0; i < n; ++i) {
      if (k >= data.size()) r.fail("the cell list is shorter than declared");
      auto cnt = detail::toInteger(data[k++]);
      if (cnt < 0 || static_cast<std::size_t>(cnt) > data.size() - k) r.fail("a cell has an impossible point count");
      std::vector<long long> cell(cnt);
      for (auto& v : cell) v = detail::toInteger(data[k++]);
      out.push_back(std::move(cell));
    }
    return out;
  }
};

// Which elements each input cell became, for cell labels: kind (0 none, 1 triangles, 2 tet), first, count.
struct Target {
  int kind;
  std::size_t first, count = 1;
};

// One legacy file's parse: the reader, the mesh so far, and what the cells became.
struct LegacyParse {
  Reader R;
  bool poly = false;
  Mesh m;
  std::vector<std::vector<long long>> ugCells;
  std::vector<double> ugTypes;
  std::vector<Target> cellTarget;

  explicit LegacyParse(std::string_view bytes) : R{TextReader(bytes, "VTK legacy")} {}

  // The '# vtk DataFile' line, the title, ASCII or BINARY, and the dataset type.
  void header(std::string_view bytes) {
    auto& r = R.r;
    if (bytes.substr(0, 22).find("# vtk DataFile") == std::string_view::npos) r.fail("the '# vtk DataFile' header is missing");
    r.line();
    r.line();  // title
    auto enc = r.token();
    if (iequals(enc, "BINARY")) R.binary = true;
    else if (!iequals(enc, "ASCII")) r.fail("expected ASCII or BINARY");
    auto ds = r.token();
    if (!iequals(ds, "DATASET")) r.fail("expected DATASET");
    auto kind = r.token();
    poly = iequals(kind, "POLYDATA");
    if (!poly && !iequals(kind, "UNSTRUCTURED_GRID"))
      r.fail("dataset type " + std::string(kind) + " is not supported (use POLYDATA or UNSTRUCTURED_GRID)");
  }

  void applyLabels(const std::vector<double>& v) {
    for (std::size_t i = 0; i < cellTarget.size(); ++i) {
      const auto& t = cellTarget[i];
      for (std::size_t k = 0; k < t.count; ++k) {
        if (t.kind == 2) m.tetLabels[t.first + k] = detail::toLabel(v[i]);
        if (t.kind == 1) m.triangleLabels[t.first + k] = detail::toLabel(v[i]);
      }
    }
  }

  void addPoly(const std::vector<long long>& c) {
    if (c.size() < 3) {
      cellTarget.push_back({0, 0});
      return;
    }
    std::size_t first = m.triangles.size();
    for (std::size_t k = 1; k + 1 < c.size(); ++k) {  // fan triangulation of convex polygons
      m.triangles.push_back({static_cast<int>(c[0]), static_cast<int>(c[k]), static_cast<int>(c[k + 1])});
      m.triangleLabels.push_back(0);
    }
    cellTarget.push_back({1, first, m.triangles.size() - first});
  }

  int toInt(long long v) {
    auto& r = R.r;
    if (v < 0 || v > static_cast<long long>(kMaxMeshItems)) r.fail("a cell refers to point " + std::to_string(v) + ", which is out of range");
    return static_cast<int>(v);
  }

  // POINTS n type, then the coordinates.
  void points() {
    auto& r = R.r;
    std::size_t n = r.count("point", kMaxMeshItems);
    auto type = r.token();
    auto v = R.values(3 * n, type);
    m.points.resize(n);
    for (std::size_t i = 0; i < n; ++i) m.points[i] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
  }

  // POLYGONS, VERTICES or LINES of a POLYDATA.
  void polyCells(bool polygons) {
    auto cells = R.cells("cell");
    for (auto& c : cells) {
      for (auto& v : c) v = toInt(v);
      if (polygons) addPoly(c);
      else cellTarget.push_back({0, 0});
    }
  }

  // TRIANGLE_STRIPS of a POLYDATA, as triangles.
  void strips() {
    auto cells = R.cells("strip");
    for (auto& c : cells) {
      std::size_t first = m.triangles.size();
      for (std::size_t k = 0; k + 2 < c.size(); ++k) {
        int a = toInt(c[k]), b = toInt(c[k + 1]), d = toInt(c[k + 2]);
        if (k % 2) std::swap(a, b);
        m.triangles.push_back({a, b, d});
        m.triangleLabels.push_back(0);
      }
      cellTarget.push_back({1, first, m.triangles.size() - first});
    }
  }

  // CELL_TYPES of an UNSTRUCTURED_GRID: its CELLS become tets, triangles or polygons.
  void cellTypes() {
    auto& r = R.r;
    std::size_t n = r.count("cell type", kMaxMeshItems);
    ugTypes = R.values(n, "int");
    if (ugTypes.size() != ugCells.size()) r.fail("CELL_TYPES and CELLS have different counts");
    for (std::size_t i = 0; i < ugCells.size(); ++i) {
      int t = detail::toLabel(ugTypes[i]);
      auto& c = ugCells[i];
      if ((t == 10 || t == 24) && c.size() >= 4) {  // tetra, quadratic tetra (corners first)
        cellTarget.push_back({2, m.tets.size()});
        m.tets.push_back({toInt(c[0]), toInt(c[1]), toInt(c[2]), toInt(c[3])});
        m.tetLabels.push_back(0);
      } else if ((t == 5 || t == 22) && c.size() >= 3) {
        cellTarget.push_back({1, m.triangles.size()});
        m.triangles.push_back({toInt(c[0]), toInt(c[1]), toInt(c[2])});
        m.triangleLabels.push_back(0);
      } else if ((t == 7 || t == 9) && c.size() >= 3) {  // polygon, quad
        for (auto& v : c) v = toInt(v);
        addPoly(c);
      } else {
        cellTarget.push_back({0, 0});
      }
    }
  }

  // SCALARS of a data section of n values; the first integer one of a cell section labels the cells.
  void scalars(std::size_t n, bool cellData, bool& labelled) {
    auto& r = R.r;
    r.token();
    auto type = r.token();
    std::size_t comps = 1;
    auto rest = r.line();
    if (!rest.empty()) {
      std::string s(rest);
      int c = std::atoi(s.c_str());
      if (c < 1 || c > 4) r.fail("SCALARS has an impossible component count");
      comps = c;
    }
    if (iequals(r.peekToken(), "LOOKUP_TABLE")) {
      r.token();
      r.token();
    }
    auto v = R.values(n * comps, type);
    if (cellData && !labelled && comps == 1 && isIntegerType(type) && n == cellTarget.size()) {
      labelled = true;
      applyLabels(v);
    }
  }

  // FIELD inside a data section; its first integer one-component array of a cell section labels the cells.
  void dataField(bool cellData, bool& labelled) {
    auto& r = R.r;
    r.token();
    std::size_t arrays = r.count("field array", 10000);
    for (std::size_t k = 0; k < arrays; ++k) {
      auto name = r.token();
      if (iequals(name, "METADATA")) {  // skip metadata lines up to a blank line
        r.skipLineEnd();
        while (!r.exhausted() && !r.line().empty()) {
        }
        --k;
        continue;
      }
      std::size_t comps = r.count("field components", 1024);
      std::size_t tuples = r.count("field tuples", kMaxMeshItems);
      auto type = r.token();
      auto v = R.values(comps * tuples, type);
      if (cellData && !labelled && comps == 1 && tuples == cellTarget.size() && isIntegerType(type)) {
        labelled = true;
        applyLabels(v);
      }
    }
  }

  // A CELL_DATA or POINT_DATA section and its attributes.
  void dataSection(bool cellData) {
    auto& r = R.r;
    std::size_t n = r.count("attribute", kMaxMeshItems);
    bool labelled = false;
    // Attributes until the next data section or the end.
    while (!r.atEnd()) {
      auto a = r.peekToken();
      if (iequals(a, "CELL_DATA") || iequals(a, "POINT_DATA")) break;
      r.token();
      if (iequals(a, "SCALARS")) {
        scalars(n, cellData, labelled);
      } else if (iequals(a, "VECTORS") || iequals(a, "NORMALS")) {
        r.token();
        R.values(3 * n, r.token());
      } else if (iequals(a, "TENSORS")) {
        r.token();
        R.values(9 * n, r.token());
      } else if (iequals(a, "TEXTURE_COORDINATES")) {
        r.token();
        std::size_t d = r.count("texture dimension", 3);
        R.values(d * n, r.token());
      } else if (iequals(a, "COLOR_SCALARS")) {
        r.token();
        std::size_t c = r.count("colour component", 4);
        R.values(c * n, R.binary ? "unsigned_char" : "float");
      } else if (iequals(a, "LOOKUP_TABLE")) {
        r.token();
        std::size_t s = r.count("lookup table size", kMaxMeshItems);
        R.values(4 * s, R.binary ? "unsigned_char" : "float");
      } else if (iequals(a, "FIELD")) {
        dataField(cellData, labelled);
      } else if (iequals(a, "METADATA")) {
        metadata();
      } else {
        r.fail("attribute '" + std::string(a.substr(0, 30)) + "' is not supported");
      }
    }
  }

  // METADATA: lines up to a blank line.
  void metadata() {
    auto& r = R.r;
    r.skipLineEnd();
    while (!r.exhausted()) {  // metadata lines up to a blank line
      auto l = r.line();
      if (l.empty()) break;
    }
  }

  // FIELD at the top level: its arrays, skipped.
  void field() {
    auto& r = R.r;
    r.token();
    std::size_t arrays = r.count("field array", 10000);
    for (std::size_t k = 0; k < arrays; ++k) {
      r.token();
      std::size_t comps = r.count("field components", 1024);
      std::size_t tuples = r.count("field tuples", kMaxMeshItems);
      R.values(comps * tuples, r.token());
    }
  }
};

}  // namespace

Mesh parseVtkLegacy(std::string_view bytes) {
  LegacyParse P(bytes);
  auto& r = P.R.r;
  P.header(bytes);
  const bool poly = P.poly;

  while (!r.atEnd()) {
    auto key = r.token();
    if (iequals(key, "POINTS")) {
      P.points();
    } else if (poly && (iequals(key, "POLYGONS") || iequals(key, "VERTICES") || iequals(key, "LINES"))) {
      P.polyCells(iequals(key, "POLYGONS"));
    } else if (poly && iequals(key, "TRIANGLE_STRIPS")) {
      P.strips();
    } else if (!poly && iequals(key, "CELLS")) {
      P.ugCells = P.R.cells("cell");
    } else if (!poly && iequals(key, "CELL_TYPES")) {
      P.cellTypes();
    } else if (iequals(key, "CELL_DATA") || iequals(key, "POINT_DATA")) {
      P.dataSection(iequals(key, "CELL_DATA"));
    } else if (iequals(key, "METADATA")) {
      P.metadata();
    } else if (iequals(key, "FIELD")) {
      P.field();
    } else {
      r.fail("section '" + std::string(key.substr(0, 30)) + "' is not supported");
    }
  }
  if (!poly && !P.ugCells.empty() && P.ugTypes.empty()) r.fail("CELL_TYPES is missing");
  return std::move(P.m);
}

std::string writeVtkLegacy(const Mesh& m, bool ascii) {
  std::string out = "# vtk DataFile Version 3.0\nRehearse mesh (metres)\n";
  out += ascii ? "ASCII\n" : "BINARY\n";
  out += "DATASET UNSTRUCTURED_GRID\n";
  out += "POINTS " + std::to_string(m.points.size()) + " double\n";
  char buf[128];
  auto putBE = [&](auto v) {
    char b[sizeof(v)];
    std::memcpy(b, &v, sizeof(v));
    if constexpr (std::endian::native == std::endian::little) std::reverse(b, b + sizeof(v));
    out.append(b, sizeof(v));
  };
  for (const auto& p0 : m.points) {
    Eigen::Vector3d p = p0 * m.unitToMetre;
    if (ascii) {
      std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g\n", p.x(), p.y(), p.z());
      out += buf;
    } else {
      putBE(p.x());
      putBE(p.y());
      putBE(p.z());
    }
  }
  if (!ascii) out += "\n";
  const std::size_t nc = m.tets.size() + m.triangles.size();
  out += "CELLS " + std::to_string(nc) + " " + std::to_string(m.tets.size() * 5 + m.triangles.size() * 4) + "\n";
  auto putCell = [&](auto const& c) {
    if (ascii) {
      out += std::to_string(c.size());
      for (int v : c) out += " " + std::to_string(v);
      out += "\n";
    } else {
      putBE(static_cast<std::int32_t>(c.size()));
      for (int v : c) putBE(static_cast<std::int32_t>(v));
    }
  };
  for (const auto& t : m.tets) putCell(t);
  for (const auto& t : m.triangles) putCell(t);
  if (!ascii) out += "\n";
  out += "CELL_TYPES " + std::to_string(nc) + "\n";
  for (std::size_t i = 0; i < nc; ++i) {
    int type = i < m.tets.size() ? 10 : 5;
    if (ascii) out += std::to_string(type) + "\n";
    else putBE(static_cast<std::int32_t>(type));
  }
  if (!ascii) out += "\n";
  out += "CELL_DATA " + std::to_string(nc) + "\nSCALARS label int 1\nLOOKUP_TABLE default\n";
  for (std::size_t i = 0; i < nc; ++i) {
    int l = i < m.tets.size() ? (m.tetLabels.empty() ? 0 : m.tetLabels[i])
                              : (m.triangleLabels.empty() ? 0 : m.triangleLabels[i - m.tets.size()]);
    if (ascii) out += std::to_string(l) + "\n";
    else putBE(static_cast<std::int32_t>(l));
  }
  if (!ascii) out += "\n";
  return out;
}

}  // namespace rehearse::simcore
