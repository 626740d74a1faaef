// Gmsh MSH reader (v1, v2.2 ascii/binary, v4.1 ascii/binary) and MSH 2.2 ascii writer.
// Keeps triangles and tetrahedra (corner nodes of higher-order ones); other element types are skipped.
#include <rehearse/simcore/meshio.hpp>

#include "text_reader.hpp"

#include <charconv>
#include <cstdio>
#include <map>
#include <sstream>
#include <unordered_map>

namespace rehearse::simcore {
namespace {

using detail::TextReader;

int nodesPerElement(long long type) {
  switch (type) {
    case 1: return 2;
    case 2: return 3;
    case 3: return 4;
    case 4: return 4;
    case 5: return 8;
    case 6: return 6;
    case 7: return 5;
    case 8: return 3;
    case 9: return 6;
    case 10: return 9;
    case 11: return 10;
    case 12: return 27;
    case 13: return 18;
    case 14: return 14;
    case 15: return 1;
    case 16: return 8;
    case 17: return 20;
    case 18: return 15;
    case 19: return 13;
    case 20: return 9;
    case 21: return 10;
    case 29: return 20;
    default: return -1;
  }
}
bool isTriangle(long long type) { return type == 2 || type == 9 || type == 20 || type == 21; }
bool isTet(long long type) { return type == 4 || type == 11 || type == 29; }

struct Builder {
  Mesh mesh;
  std::unordered_map<long long, int> nodeIndex;
  TextReader* r = nullptr;

  void addNode(long long tag, double x, double y, double z) {
    if (!nodeIndex.emplace(tag, static_cast<int>(mesh.points.size())).second)
      r->fail("node " + std::to_string(tag) + " is defined twice");
    mesh.points.emplace_back(x, y, z);
  }
  int node(long long tag) {
    auto it = nodeIndex.find(tag);
    if (it == nodeIndex.end()) r->fail("an element refers to node " + std::to_string(tag) + ", which is not defined");
    return it->second;
  }
  void addElement(long long type, int label, const long long* tags) {
    if (isTriangle(type)) {
      mesh.triangles.push_back({node(tags[0]), node(tags[1]), node(tags[2])});
      mesh.triangleLabels.push_back(label);
    } else if (isTet(type)) {
      mesh.tets.push_back({node(tags[0]), node(tags[1]), node(tags[2]), node(tags[3])});
      mesh.tetLabels.push_back(label);
    }
  }
};

void expectSection(TextReader& r, std::string_view name) {
  auto t = r.token();
  if (t != name) r.fail("expected " + std::string(name) + " but found '" + std::string(t.substr(0, 30)) + "'");
}

void skipSection(TextReader& r, std::string_view start) {
  std::string end = "$End" + std::string(start.substr(1));
  // Binary sections may contain anything: search for the end marker at a line start.
  auto bytes = r.bytes();
  auto p = bytes.find("\n" + end, r.position());
  if (p == std::string_view::npos) r.fail("section " + std::string(start) + " has no " + end);
  r.seek(p + 1 + end.size());
}

void readPhysicalNames(TextReader& r, Mesh& m) {
  std::size_t n = r.count("physical name", 1'000'000);
  for (std::size_t i = 0; i < n; ++i) {
    r.integer("physical dimension");
    long long tag = r.integer("physical tag");
    auto rest = r.line();
    auto a = rest.find('"'), b = rest.rfind('"');
    std::string name = (a != std::string_view::npos && b > a) ? std::string(rest.substr(a + 1, b - a - 1)) : "";
    m.setLabelName(static_cast<int>(tag), name);
  }
  expectSection(r, "$EndPhysicalNames");
}

void readV1(TextReader& r, Builder& b) {
  // $NOD already consumed.
  std::size_t n = r.count("node", kMaxMeshItems);
  r.expectRoom(n, 8, "nodes");
  b.mesh.points.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    long long id = r.integer("node id");
    double x = r.real("x"), y = r.real("y"), z = r.real("z");
    b.addNode(id, x, y, z);
  }
  expectSection(r, "$ENDNOD");
  expectSection(r, "$ELM");
  std::size_t ne = r.count("element", kMaxMeshItems);
  long long tags[32];
  for (std::size_t i = 0; i < ne; ++i) {
    r.integer("element id");
    long long type = r.integer("element type");
    long long phys = r.integer("physical region");
    r.integer("elementary region");
    long long nn = r.integer("node count");
    if (nn < 1 || nn > 32 || (nodesPerElement(type) > 0 && nn != nodesPerElement(type)))
      r.fail("element " + std::to_string(i) + " has an impossible node count " + std::to_string(nn));
    for (long long k = 0; k < nn; ++k) tags[k] = r.integer("element node");
    b.addElement(type, static_cast<int>(phys), tags);
  }
  expectSection(r, "$ENDELM");
}

void readV2Nodes(TextReader& r, Builder& b, bool binary, bool bigEndian) {
  std::size_t n = r.count("node", kMaxMeshItems);
  r.expectRoom(n, binary ? 28 : 8, "nodes");
  b.mesh.points.reserve(n);
  if (binary) {
    r.skipLineEnd();
    auto data = r.take(n * (4 + 24), "binary node block");
    for (std::size_t i = 0; i < n; ++i) {
      const char* p = data.data() + i * 28;
      int id = detail::readBinary<int>(p, bigEndian);
      b.addNode(id, detail::readBinary<double>(p + 4, bigEndian), detail::readBinary<double>(p + 12, bigEndian),
                detail::readBinary<double>(p + 20, bigEndian));
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      long long id = r.integer("node id");
      double x = r.real("x"), y = r.real("y"), z = r.real("z");
      b.addNode(id, x, y, z);
    }
  }
  expectSection(r, "$EndNodes");
}

void readV2Elements(TextReader& r, Builder& b, bool binary, bool bigEndian) {
  std::size_t ne = r.count("element", kMaxMeshItems);
  long long tags[64];
  if (binary) {
    r.skipLineEnd();
    std::size_t done = 0;
    while (done < ne) {
      auto h = r.take(12, "element block header");
      int type = detail::readBinary<int>(h.data(), bigEndian);
      int count = detail::readBinary<int>(h.data() + 4, bigEndian);
      int ntags = detail::readBinary<int>(h.data() + 8, bigEndian);
      int nn = nodesPerElement(type);
      if (nn < 0 || count <= 0 || static_cast<std::size_t>(count) > ne - done || ntags < 0 || ntags > 16)
        r.fail("an element block header is invalid");
      std::size_t ints = 1 + ntags + nn;
      auto data = r.take(static_cast<std::size_t>(count) * ints * 4, "binary element block");
      for (int e = 0; e < count; ++e) {
        const char* p = data.data() + e * ints * 4;
        int label = ntags > 0 ? detail::readBinary<int>(p + 4, bigEndian) : 0;
        for (int k = 0; k < nn; ++k) tags[k] = detail::readBinary<int>(p + 4 * (1 + ntags + k), bigEndian);
        b.addElement(type, label, tags);
      }
      done += count;
    }
  } else {
    for (std::size_t i = 0; i < ne; ++i) {
      r.integer("element id");
      long long type = r.integer("element type");
      long long ntags = r.integer("tag count");
      if (ntags < 0 || ntags > 16) r.fail("element " + std::to_string(i) + " has an impossible tag count");
      long long label = 0;
      for (long long k = 0; k < ntags; ++k) {
        long long t = r.integer("element tag");
        if (k == 0) label = t;
      }
      int nn = nodesPerElement(type);
      if (nn < 0) r.fail("element type " + std::to_string(type) + " is not supported");
      for (int k = 0; k < nn; ++k) tags[k] = r.integer("element node");
      b.addElement(type, static_cast<int>(label), tags);
    }
  }
  expectSection(r, "$EndElements");
}

struct V4;
std::size_t binary_min(const V4& v);

// v4.1 helpers: in binary files counts and tags are size_t (8 bytes), dims/entity tags int.
struct V4 {
  TextReader& r;
  bool binary;
  bool big;
  std::size_t sizeT = 8;
  long long sz(const char* what) {
    if (!binary) return r.integer(what);
    auto d = r.take(sizeT, what);
    return sizeT == 8 ? static_cast<long long>(detail::readBinary<std::uint64_t>(d.data(), big))
                      : detail::readBinary<std::uint32_t>(d.data(), big);
  }
  long long in(const char* what) {
    if (!binary) return r.integer(what);
    return detail::readBinary<int>(r.take(4, what).data(), big);
  }
  double dbl(const char* what) {
    if (!binary) return r.real(what);
    return detail::readBinary<double>(r.take(8, what).data(), big);
  }
  std::size_t count(const char* what) {
    long long v = sz(what);
    if (v < 0 || static_cast<std::size_t>(v) > kMaxMeshItems) r.fail(std::string("the ") + what + " count is out of range");
    return static_cast<std::size_t>(v);
  }
};

std::size_t binary_min(const V4& v) { return v.binary ? 32 : 8; }

void readV4Entities(V4& v, std::map<std::pair<int, int>, int>& physicalOf) {
  std::size_t counts[4];
  for (auto& c : counts) c = v.count("entity");
  for (int dim = 0; dim < 4; ++dim)
    for (std::size_t i = 0; i < counts[dim]; ++i) {
      int tag = static_cast<int>(v.in("entity tag"));
      for (int k = 0; k < (dim == 0 ? 3 : 6); ++k) v.dbl("entity bound");
      std::size_t nphys = v.count("physical tag");
      for (std::size_t k = 0; k < nphys; ++k) {
        int p = static_cast<int>(v.in("physical tag"));
        if (k == 0) physicalOf[{dim, tag}] = p;
      }
      if (dim > 0) {
        std::size_t nb = v.count("bounding entity");
        for (std::size_t k = 0; k < nb; ++k) v.in("bounding entity");
      }
    }
  expectSection(v.r, "$EndEntities");
}

void readV4Nodes(V4& v, Builder& b) {
  std::size_t blocks = v.count("node block");
  std::size_t total = v.count("node");
  v.sz("min node tag");
  v.sz("max node tag");
  v.r.expectRoom(total, binary_min(v), "nodes");
  b.mesh.points.reserve(total);
  std::vector<long long> tags;
  for (std::size_t bl = 0; bl < blocks; ++bl) {
    long long dim = v.in("entity dimension");
    v.in("entity tag");
    long long parametric = v.in("parametric flag");
    std::size_t n = v.count("node");
    if (b.mesh.points.size() + n > total) v.r.fail("node blocks hold more nodes than declared");
    tags.resize(n);
    for (auto& t : tags) t = v.sz("node tag");
    int extra = parametric ? static_cast<int>(std::max<long long>(0, std::min<long long>(dim, 3))) : 0;
    for (std::size_t i = 0; i < n; ++i) {
      double x = v.dbl("x"), y = v.dbl("y"), z = v.dbl("z");
      for (int k = 0; k < extra; ++k) v.dbl("parametric coordinate");
      b.addNode(tags[i], x, y, z);
    }
  }
  expectSection(v.r, "$EndNodes");
}

void readV4Elements(V4& v, Builder& b, const std::map<std::pair<int, int>, int>& physicalOf) {
  std::size_t blocks = v.count("element block");
  v.count("element");
  v.sz("min element tag");
  v.sz("max element tag");
  long long tags[64];
  for (std::size_t bl = 0; bl < blocks; ++bl) {
    int dim = static_cast<int>(v.in("entity dimension"));
    int entity = static_cast<int>(v.in("entity tag"));
    long long type = v.in("element type");
    std::size_t n = v.count("element");
    int nn = nodesPerElement(type);
    if (nn < 0) v.r.fail("element type " + std::to_string(type) + " is not supported");
    auto it = physicalOf.find({dim, entity});
    int label = it != physicalOf.end() ? it->second : entity;
    for (std::size_t e = 0; e < n; ++e) {
      v.sz("element tag");
      for (int k = 0; k < nn; ++k) tags[k] = v.sz("element node");
      b.addElement(type, label, tags);
    }
  }
  expectSection(v.r, "$EndElements");
}

}  // namespace

Mesh parseGmsh(std::string_view bytes) {
  TextReader r(bytes, "Gmsh MSH");
  Builder b;
  b.r = &r;
  if (r.atEnd()) r.fail("the file is empty");
  auto first = r.token();
  if (first == "$NOD") {
    readV1(r, b);
    return std::move(b.mesh);
  }
  if (first != "$MeshFormat") r.fail("it does not start with $MeshFormat or $NOD");
  auto version = r.token();
  long long fileType = r.integer("file type");
  long long dataSize = r.integer("data size");
  bool binary = fileType == 1;
  bool big = false;
  if (binary) {
    r.skipLineEnd();
    auto one = r.take(4, "endianness marker");
    int v = detail::readBinary<int>(one.data(), false);
    if (v == 1) big = false;
    else if (detail::readBinary<int>(one.data(), true) == 1) big = true;
    else r.fail("the binary endianness marker is not 1");
  }
  expectSection(r, "$EndMeshFormat");
  bool v4 = version.substr(0, 1) == "4";
  if (!v4 && version.substr(0, 1) != "2") r.fail("MSH version " + std::string(version) + " is not supported (use 1, 2.2 or 4.1)");
  if (v4 && version != "4.1") r.fail("MSH version " + std::string(version) + " is not supported (use 4.1)");
  if (binary && !v4 && dataSize != 8) r.fail("binary MSH 2 with data size other than 8 is not supported");
  V4 v{r, binary, big, static_cast<std::size_t>(dataSize == 4 ? 4 : 8)};
  std::map<std::pair<int, int>, int> physicalOf;
  bool sawNodes = false, sawElements = false;
  while (!r.atEnd()) {
    auto s = r.token();
    if (s == "$PhysicalNames") readPhysicalNames(r, b.mesh);
    else if (s == "$Entities" && v4) {
      if (binary) r.skipLineEnd();
      readV4Entities(v, physicalOf);
    } else if (s == "$Nodes") {
      if (v4) {
        if (binary) r.skipLineEnd();
        readV4Nodes(v, b);
      } else readV2Nodes(r, b, binary, big);
      sawNodes = true;
    } else if (s == "$Elements") {
      if (!sawNodes) r.fail("$Elements comes before $Nodes");
      if (v4) {
        if (binary) r.skipLineEnd();
        readV4Elements(v, b, physicalOf);
      } else readV2Elements(r, b, binary, big);
      sawElements = true;
    } else if (!s.empty() && s[0] == '$') {
      skipSection(r, s);
    } else {
      r.fail("unexpected text '" + std::string(s.substr(0, 30)) + "' between sections");
    }
  }
  if (!sawNodes || !sawElements) r.fail("the $Nodes or $Elements section is missing");
  return std::move(b.mesh);
}

std::string writeGmsh22(const Mesh& m) {
  std::string out;
  out.reserve(m.points.size() * 64 + (m.tets.size() + m.triangles.size()) * 48);
  char buf[160];
  out += "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
  if (!m.labelNames.empty()) {
    out += "$PhysicalNames\n" + std::to_string(m.labelNames.size()) + "\n";
    for (const auto& [l, n] : m.labelNames) out += "3 " + std::to_string(l) + " \"" + n + "\"\n";
    out += "$EndPhysicalNames\n";
  }
  out += "$Nodes\n" + std::to_string(m.points.size()) + "\n";
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    const auto p = m.points[i] * m.unitToMetre;
    std::snprintf(buf, sizeof buf, "%zu %.17g %.17g %.17g\n", i + 1, p.x(), p.y(), p.z());
    out += buf;
  }
  out += "$EndNodes\n$Elements\n" + std::to_string(m.triangles.size() + m.tets.size()) + "\n";
  std::size_t id = 1;
  for (std::size_t e = 0; e < m.triangles.size(); ++e) {
    int l = m.triangleLabels.empty() ? 0 : m.triangleLabels[e];
    std::snprintf(buf, sizeof buf, "%zu 2 2 %d %d %d %d %d\n", id++, l, l, m.triangles[e][0] + 1,
                  m.triangles[e][1] + 1, m.triangles[e][2] + 1);
    out += buf;
  }
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    int l = m.tetLabels.empty() ? 0 : m.tetLabels[e];
    const auto& t = m.tets[e];
    std::snprintf(buf, sizeof buf, "%zu 4 2 %d %d %d %d %d %d\n", id++, l, l, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1);
    out += buf;
  }
  out += "$EndElements\n";
  return out;
}

}  // namespace rehearse::simcore
