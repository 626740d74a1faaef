// VTK XML UnstructuredGrid (.vtu) reader (ascii, inline base64 binary, appended raw/base64, zlib
// compression, UInt32/UInt64 headers, either byte order) and writer (ascii or inline base64).
#include <rehearse/simcore/meshio.hpp>

#include "text_reader.hpp"

#include <tinyxml2.h>
#include <zlib.h>

#include <charconv>
#include <cstdio>
#include <cstring>

namespace rehearse::simcore {
namespace {

[[noreturn]] void fail(const std::string& msg) {
  throw MeshError("This VTU file cannot be read: " + msg + "; check that the file is complete and in that format.");
}

int typeSize(std::string_view t) {
  if (t == "Int8" || t == "UInt8") return 1;
  if (t == "Int16" || t == "UInt16") return 2;
  if (t == "Int32" || t == "UInt32" || t == "Float32") return 4;
  if (t == "Int64" || t == "UInt64" || t == "Float64") return 8;
  return 0;
}

double readValue(const char* p, std::string_view t, bool big) {
  using detail::readBinary;
  if (t == "Int8") return static_cast<signed char>(*p);
  if (t == "UInt8") return static_cast<unsigned char>(*p);
  if (t == "Int16") return readBinary<std::int16_t>(p, big);
  if (t == "UInt16") return readBinary<std::uint16_t>(p, big);
  if (t == "Int32") return readBinary<std::int32_t>(p, big);
  if (t == "UInt32") return readBinary<std::uint32_t>(p, big);
  if (t == "Int64") return static_cast<double>(readBinary<std::int64_t>(p, big));
  if (t == "UInt64") return static_cast<double>(readBinary<std::uint64_t>(p, big));
  if (t == "Float32") return readBinary<float>(p, big);
  return readBinary<double>(p, big);
}

// Decodes base64 made of one or more independently padded segments (as VTK writes header and data).
std::string decodeBase64(std::string_view s, std::size_t maxChars = std::string_view::npos) {
  static int table[256];
  static bool init = [] {
    for (int& v : table) v = -1;
    const char* a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (int i = 0; i < 64; ++i) table[static_cast<unsigned char>(a[i])] = i;
    return true;
  }();
  (void)init;
  std::string out;
  char group[4];
  int n = 0;
  std::size_t used = 0;
  for (char c : s) {
    if (used >= maxChars) break;
    if (std::isspace(static_cast<unsigned char>(c))) continue;
    ++used;
    if (c != '=' && table[static_cast<unsigned char>(c)] < 0) fail("inline binary data is not valid base64");
    group[n++] = c;
    if (n == 4) {
      int v[4];
      int pad = 0;
      for (int k = 0; k < 4; ++k) {
        if (group[k] == '=') {
          v[k] = 0;
          ++pad;
        } else {
          if (pad) fail("inline binary data is not valid base64");
          v[k] = table[static_cast<unsigned char>(group[k])];
        }
      }
      if (pad > 2) fail("inline binary data is not valid base64");
      unsigned int w = (v[0] << 18) | (v[1] << 12) | (v[2] << 6) | v[3];
      out.push_back(static_cast<char>((w >> 16) & 0xff));
      if (pad < 2) out.push_back(static_cast<char>((w >> 8) & 0xff));
      if (pad < 1) out.push_back(static_cast<char>(w & 0xff));
      n = 0;
    }
  }
  return out;
}

struct Context {
  bool big = false;
  int headerSize = 4;
  bool compressed = false;
  std::string_view appended;  // raw bytes after '_' (raw encoding) or base64 text
  bool appendedRaw = true;
};

std::uint64_t header(const char* p, const Context& c) {
  return c.headerSize == 8 ? detail::readBinary<std::uint64_t>(p, c.big) : detail::readBinary<std::uint32_t>(p, c.big);
}

// Binary payload (after the header) of one array, from a byte blob that starts with its header; at most `maxBytes`
// of it (what the piece's declared points and cells can hold): a small file whose compressed blocks claim gigabytes is
// refused before anything is decompressed.
std::string payload(std::string_view blob, const Context& c, std::size_t* consumed, std::uint64_t maxBytes) {
  const std::size_t hs = c.headerSize;
  if (!c.compressed) {
    if (blob.size() < hs) fail("a binary array is truncated");
    std::uint64_t n = header(blob.data(), c);
    if (n > blob.size() - hs) fail("a binary array is truncated");
    if (n > maxBytes) fail("a binary array holds more data than the piece's points and cells declare");
    if (consumed) *consumed = hs + n;
    return std::string(blob.substr(hs, n));
  }
  if (blob.size() < 3 * hs) fail("a compressed array header is truncated");
  std::uint64_t blocks = header(blob.data(), c);
  std::uint64_t blockSize = header(blob.data() + hs, c);
  std::uint64_t lastSize = header(blob.data() + 2 * hs, c);
  if (blocks > (blob.size() - 3 * hs) / hs) fail("a compressed array header is inconsistent");
  std::size_t pos = (3 + blocks) * hs;
  {
    std::uint64_t total = 0;  // what the blocks say they expand to, before any is expanded
    for (std::uint64_t b = 0; b < blocks && total <= maxBytes; ++b)
      total += (b + 1 == blocks && lastSize) ? lastSize : blockSize;
    if (total > maxBytes)
      fail("a compressed array claims more data than the piece's points and cells declare (at least " +
           std::to_string(total >> 20) + " MiB)");
  }
  std::string out;
  for (std::uint64_t b = 0; b < blocks; ++b) {
    std::uint64_t csize = header(blob.data() + (3 + b) * hs, c);
    if (csize > blob.size() - pos) fail("a compressed block is truncated");
    const std::uint64_t declared = (b + 1 == blocks && lastSize) ? lastSize : blockSize;
    // zlib cannot expand more than about 1032:1; a larger claim is a corrupt header, not data.
    if (declared > csize * 1032 + 64 || declared > (std::uint64_t(1) << 31)) fail("a compressed block header is inconsistent");
    uLongf usize = static_cast<uLongf>(declared);
    std::string block(usize, '\0');
    if (uncompress(reinterpret_cast<Bytef*>(block.data()), &usize,
                   reinterpret_cast<const Bytef*>(blob.data() + pos), static_cast<uLong>(csize)) != Z_OK)
      fail("a compressed block does not decompress");
    block.resize(usize);
    out += block;
    pos += csize;
  }
  if (consumed) *consumed = pos;
  return out;
}

std::vector<double> readArray(const tinyxml2::XMLElement* e, const Context& c, std::size_t expected) {
  const char* type = e->Attribute("type");
  const char* format = e->Attribute("format");
  if (!type || !typeSize(type)) fail("a DataArray has a missing or unsupported type");
  std::string_view t(type);
  std::string_view f = format ? format : "ascii";
  std::vector<double> out;
  if (f == "ascii") {
    const char* text = e->GetText();
    detail::TextReader r(text ? text : "", "VTU");
    out.reserve(std::min(expected, r.remaining() / 2 + 1));
    while (!r.atEnd()) {
      if (out.size() >= expected) break;
      out.push_back(r.real("data value"));
    }
  } else {
    std::string bytes;
    // Up to 16 components per declared value (a vector array read for its first one), and a MiB of slack.
    const std::uint64_t maxBytes = static_cast<std::uint64_t>(expected) * typeSize(t) * 16 + (std::uint64_t{1} << 20);
    if (f == "binary") {
      const char* text = e->GetText();
      std::string raw = decodeBase64(text ? text : "");
      bytes = payload(raw, c, nullptr, maxBytes);
    } else if (f == "appended") {
      std::int64_t offset = e->Int64Attribute("offset", -1);
      if (offset < 0 || static_cast<std::uint64_t>(offset) > c.appended.size()) fail("a DataArray has a bad appended offset");
      auto rest = c.appended.substr(offset);
      if (c.appendedRaw) {
        bytes = payload(rest, c, nullptr, maxBytes);
      } else {
        // base64: decode the header segment first to learn the data size.
        const std::size_t hs = c.headerSize;
        if (!c.compressed) {
          std::string h = decodeBase64(rest, (hs + 2) / 3 * 4);
          if (h.size() < hs) fail("a binary array is truncated");
          std::uint64_t n = header(h.data(), c);
          if (n > rest.size()) fail("a binary array is truncated");
          std::string d = decodeBase64(rest.substr((hs + 2) / 3 * 4), (n + 2) / 3 * 4);
          bytes = h.substr(0, hs) + d;
        } else {
          std::string h3 = decodeBase64(rest, (3 * hs + 2) / 3 * 4);
          if (h3.size() < 3 * hs) fail("a compressed array header is truncated");
          std::uint64_t blocks = header(h3.data(), c);
          if (blocks > rest.size()) fail("a compressed array header is inconsistent");
          std::size_t hchars = ((3 + blocks) * hs + 2) / 3 * 4;
          std::string h = decodeBase64(rest, hchars);
          if (h.size() < (3 + blocks) * hs) fail("a compressed array header is truncated");
          std::uint64_t total = 0;
          for (std::uint64_t b = 0; b < blocks; ++b) total += header(h.data() + (3 + b) * hs, c);
          if (total > rest.size()) fail("a compressed array is truncated");
          std::string d = decodeBase64(rest.substr(std::min(hchars, rest.size())), (total + 2) / 3 * 4);
          bytes = h.substr(0, (3 + blocks) * hs) + d;
        }
        bytes = payload(bytes, c, nullptr, maxBytes);
      }
    } else {
      fail("DataArray format '" + std::string(f) + "' is not supported");
    }
    const std::size_t sz = typeSize(t);
    std::size_t n = bytes.size() / sz;
    out.resize(std::min(n, expected));
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = readValue(bytes.data() + i * sz, t, c.big);
  }
  if (out.size() < expected) fail("a DataArray holds fewer values than the piece declares");
  return out;
}

const tinyxml2::XMLElement* findArray(const tinyxml2::XMLElement* parent, const char* name) {
  if (!parent) return nullptr;
  for (auto* a = parent->FirstChildElement("DataArray"); a; a = a->NextSiblingElement("DataArray")) {
    const char* n = a->Attribute("Name");
    if (!name || (n && std::strcmp(n, name) == 0)) return a;
  }
  return nullptr;
}

}  // namespace

Mesh parseVtu(std::string_view bytes) {
  Context c;
  std::string xml;
  auto ap = bytes.find("<AppendedData");
  if (ap != std::string_view::npos) {
    auto close = bytes.find('>', ap);
    if (close == std::string_view::npos) fail("the AppendedData tag is not closed");
    std::string_view tag = bytes.substr(ap, close - ap);
    c.appendedRaw = tag.find("base64") == std::string_view::npos;
    auto us = bytes.find('_', close);
    if (us == std::string_view::npos) fail("the appended data has no '_' marker");
    c.appended = bytes.substr(us + 1);
    // The XML before the appended block, closed (the grid element is normally closed before it).
    const std::string_view prefix = bytes.substr(0, ap);
    xml = std::string(prefix) + (prefix.rfind("</UnstructuredGrid>") != std::string_view::npos ? "</VTKFile>" : "</UnstructuredGrid></VTKFile>");
  } else {
    xml = std::string(bytes);
  }
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.data(), xml.size()) != tinyxml2::XML_SUCCESS) fail(std::string("the XML is malformed (") + doc.ErrorName() + ")");
  auto* root = doc.FirstChildElement("VTKFile");
  if (!root) fail("the VTKFile element is missing");
  const char* type = root->Attribute("type");
  if (!type || std::strcmp(type, "UnstructuredGrid") != 0) fail("only UnstructuredGrid files are supported");
  const char* bo = root->Attribute("byte_order");
  c.big = bo && std::strcmp(bo, "BigEndian") == 0;
  const char* ht = root->Attribute("header_type");
  c.headerSize = ht && std::strcmp(ht, "UInt64") == 0 ? 8 : 4;
  c.compressed = root->Attribute("compressor") != nullptr;
  auto* grid = root->FirstChildElement("UnstructuredGrid");
  auto* piece = grid ? grid->FirstChildElement("Piece") : nullptr;
  if (!piece) fail("the Piece element is missing");
  if (piece->NextSiblingElement("Piece")) fail("files with several pieces are not supported");
  std::int64_t np = piece->Int64Attribute("NumberOfPoints", -1);
  std::int64_t nc = piece->Int64Attribute("NumberOfCells", -1);
  if (np < 0 || nc < 0 || np > static_cast<std::int64_t>(kMaxMeshItems) || nc > static_cast<std::int64_t>(kMaxMeshItems))
    fail("NumberOfPoints or NumberOfCells is missing or out of range");
  auto* pointsArray = findArray(piece->FirstChildElement("Points"), nullptr);
  auto* cells = piece->FirstChildElement("Cells");
  auto* conn = findArray(cells, "connectivity");
  auto* offs = findArray(cells, "offsets");
  auto* types = findArray(cells, "types");
  if (!pointsArray || !conn || !offs || !types) fail("the Points or Cells arrays are missing");
  Mesh m;
  auto p = readArray(pointsArray, c, 3 * np);
  m.points.resize(np);
  for (std::int64_t i = 0; i < np; ++i) m.points[i] = {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
  auto o = readArray(offs, c, nc);
  auto ty = readArray(types, c, nc);
  const long long lastOffset = nc ? detail::toInteger(o.back()) : 0;
  if (lastOffset < 0) fail("cell offsets are inconsistent");
  std::size_t connSize = static_cast<std::size_t>(lastOffset);
  if (connSize > 16 * kMaxMeshItems) fail("the connectivity size is out of range");
  auto cn = readArray(conn, c, connSize);
  std::vector<std::pair<int, std::size_t>> target(nc, {0, 0});
  double prev = 0;
  auto idx = [&](double v) {
    if (!(v >= 0 && v < static_cast<double>(np))) fail("a cell refers to a point that does not exist");
    return static_cast<int>(v);
  };
  for (std::int64_t i = 0; i < nc; ++i) {
    double end = o[i];
    if (!(end >= prev && end <= static_cast<double>(connSize))) fail("cell offsets are inconsistent");
    auto b = static_cast<std::size_t>(prev), n = static_cast<std::size_t>(end) - b;
    int t = detail::toLabel(ty[i]);
    if ((t == 10 || t == 24) && n >= 4) {
      target[i] = {2, m.tets.size()};
      m.tets.push_back({idx(cn[b]), idx(cn[b + 1]), idx(cn[b + 2]), idx(cn[b + 3])});
      m.tetLabels.push_back(0);
    } else if ((t == 5 || t == 22) && n >= 3) {
      target[i] = {1, m.triangles.size()};
      m.triangles.push_back({idx(cn[b]), idx(cn[b + 1]), idx(cn[b + 2])});
      m.triangleLabels.push_back(0);
    }
    prev = end;
  }
  // Labels: the first single-component integer cell array.
  if (auto* cd = piece->FirstChildElement("CellData")) {
    for (auto* a = cd->FirstChildElement("DataArray"); a; a = a->NextSiblingElement("DataArray")) {
      const char* at = a->Attribute("type");
      if (!at || std::string_view(at).find("Float") != std::string_view::npos) continue;
      if (a->IntAttribute("NumberOfComponents", 1) != 1) continue;
      auto v = readArray(a, c, nc);
      for (std::int64_t i = 0; i < nc; ++i) {
        if (target[i].first == 2) m.tetLabels[target[i].second] = detail::toLabel(v[i]);
        if (target[i].first == 1) m.triangleLabels[target[i].second] = detail::toLabel(v[i]);
      }
      break;
    }
  }
  return m;
}

namespace {
std::string encodeBase64(const std::string& in) {
  static const char* a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < in.size(); i += 3) {
    unsigned int w = static_cast<unsigned char>(in[i]) << 16;
    if (i + 1 < in.size()) w |= static_cast<unsigned char>(in[i + 1]) << 8;
    if (i + 2 < in.size()) w |= static_cast<unsigned char>(in[i + 2]);
    out.push_back(a[(w >> 18) & 63]);
    out.push_back(a[(w >> 12) & 63]);
    out.push_back(i + 1 < in.size() ? a[(w >> 6) & 63] : '=');
    out.push_back(i + 2 < in.size() ? a[w & 63] : '=');
  }
  return out;
}

template <class T>
std::string dataArray(const char* type, const char* name, int comps, const std::vector<T>& v, bool ascii) {
  std::string out = std::string("<DataArray type=\"") + type + "\"" + (name ? std::string(" Name=\"") + name + "\"" : "") +
                    " NumberOfComponents=\"" + std::to_string(comps) + "\" format=\"" + (ascii ? "ascii" : "binary") + "\">\n";
  if (ascii) {
    char buf[40];
    for (std::size_t i = 0; i < v.size(); ++i) {
      if constexpr (std::is_floating_point_v<T>) std::snprintf(buf, sizeof buf, "%.17g", static_cast<double>(v[i]));
      else std::snprintf(buf, sizeof buf, "%lld", static_cast<long long>(v[i]));
      out += buf;
      out += (i + 1) % 12 == 0 ? '\n' : ' ';
    }
  } else {
    std::uint64_t n = v.size() * sizeof(T);
    std::string h(reinterpret_cast<const char*>(&n), 8);
    std::string d(reinterpret_cast<const char*>(v.data()), n);
    out += encodeBase64(h) + encodeBase64(d);
  }
  out += "\n</DataArray>\n";
  return out;
}
}  // namespace

std::string writeVtu(const Mesh& m, bool ascii) {
  std::vector<double> pts;
  pts.reserve(m.points.size() * 3);
  for (const auto& p : m.points)
    for (int k = 0; k < 3; ++k) pts.push_back(p[k] * m.unitToMetre);
  std::vector<std::int64_t> conn, offs;
  std::vector<std::uint8_t> types;
  std::vector<std::int32_t> labels;
  for (std::size_t i = 0; i < m.tets.size(); ++i) {
    for (int v : m.tets[i]) conn.push_back(v);
    offs.push_back(static_cast<std::int64_t>(conn.size()));
    types.push_back(10);
    labels.push_back(m.tetLabels.empty() ? 0 : m.tetLabels[i]);
  }
  for (std::size_t i = 0; i < m.triangles.size(); ++i) {
    for (int v : m.triangles[i]) conn.push_back(v);
    offs.push_back(static_cast<std::int64_t>(conn.size()));
    types.push_back(5);
    labels.push_back(m.triangleLabels.empty() ? 0 : m.triangleLabels[i]);
  }
  const char* order = std::endian::native == std::endian::little ? "LittleEndian" : "BigEndian";
  std::string out = std::string("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"") +
                    order + "\" header_type=\"UInt64\">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"" +
                    std::to_string(m.points.size()) + "\" NumberOfCells=\"" + std::to_string(types.size()) + "\">\n";
  out += "<Points>\n" + dataArray("Float64", "Points", 3, pts, ascii) + "</Points>\n";
  out += "<Cells>\n" + dataArray("Int64", "connectivity", 1, conn, ascii) + dataArray("Int64", "offsets", 1, offs, ascii) +
         dataArray("UInt8", "types", 1, types, ascii) + "</Cells>\n";
  out += "<CellData Scalars=\"label\">\n" + dataArray("Int32", "label", 1, labels, ascii) + "</CellData>\n";
  out += "</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  return out;
}

}  // namespace rehearse::simcore
