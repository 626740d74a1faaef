// Checks of our own on input files before assimp, ITK or cv::FileStorage read them (see input_checks.hpp).
#include <rehearse/simcore/input_checks.hpp>

#include <tinyxml2.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <vector>

namespace rehearse::simcore::checks {
namespace {

std::string num(double v) {
  if (std::abs(v) < 1e15 && v == std::floor(v)) return std::to_string(static_cast<long long>(v));
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && isSpace(s.front())) s.remove_prefix(1);
  while (!s.empty() && isSpace(s.back())) s.remove_suffix(1);
  return s;
}

std::string lowerCopy(std::string_view s) {
  std::string l(s);
  for (auto& c : l) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return l;
}

// Splits on whitespace.
std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> w;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && isSpace(s[i])) ++i;
    const std::size_t b = i;
    while (i < s.size() && !isSpace(s[i])) ++i;
    if (i > b) w.push_back(s.substr(b, i - b));
  }
  return w;
}

bool toLong(std::string_view s, long long& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && p == s.data() + s.size();
}

bool toDouble(std::string_view s, double& v) {
  std::string t(s);
  char* end = nullptr;
  v = std::strtod(t.c_str(), &end);
  return !t.empty() && end == t.c_str() + t.size();
}

// Reads the next line of `s` from `pos` (without its end of line); false at the end.
bool nextLine(std::string_view s, std::size_t& pos, std::string_view& line) {
  if (pos >= s.size()) return false;
  const std::size_t nl = s.find('\n', pos);
  const std::size_t end = nl == std::string_view::npos ? s.size() : nl;
  line = s.substr(pos, end - pos);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  pos = end + 1;
  return true;
}

std::string plural(double n, const std::string& word) { return num(n) + " " + word + (n == 1 ? "" : "s"); }

// ---- PLY ----

struct PlyProperty {
  bool list = false;
  int countBytes = 0, valueBytes = 0;
  bool countSigned = false, valueSigned = false, valueFloat = false;
  std::string name;
};
struct PlyElement {
  std::string name;
  long long count = 0;
  std::vector<PlyProperty> properties;
};

int plyTypeBytes(std::string_view t, bool& isSigned, bool& isFloat) {
  isSigned = t == "char" || t == "int8" || t == "short" || t == "int16" || t == "int" || t == "int32";
  isFloat = t == "float" || t == "float32" || t == "double" || t == "float64";
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32") return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

std::string elementWord(const std::string& name) { return name == "vertex" ? "vertice" : name; }

}  // namespace

std::string plyProblem(std::string_view bytes) {
  std::size_t pos = 0;
  std::string_view line;
  // A .ply whose first line is not "ply", or whose header holds a line that is not PLY, is refused here: assimp took
  // such headers and looped seeking through the file (found by fuzzing).
  if (!nextLine(bytes, pos, line) || trim(line) != "ply") return "its first line is not 'ply'";
  std::vector<PlyElement> elements;
  int format = -1;  // 0 ascii, 1 little endian, 2 big endian
  bool ended = false;
  while (nextLine(bytes, pos, line)) {
    // A line ends with LF or CR LF; a CR or a NUL byte anywhere else moved assimp's idea of where the binary data
    // starts, and its faces then came out of the wrong bytes and failed its own assertion (found by fuzzing:
    // "x\n\rproperty", "float +\0\x80..."). A header is text: tabs, no other control characters.
    if (std::any_of(line.begin(), line.end(), [](char c) { return c == '\r'; }))
      return "its header has a carriage return inside a line";
    if (std::any_of(line.begin(), line.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20 && c != '\t'; }))
      return "its header holds a control character or a NUL byte";
    const auto w = words(line);
    if (w.empty()) continue;
    if (w[0] == "end_header") {
      ended = true;
      break;
    }
    if (w[0] == "format" && w.size() >= 2) {
      format = w[1] == "ascii" ? 0 : w[1] == "binary_little_endian" ? 1 : w[1] == "binary_big_endian" ? 2 : -2;
      if (format == -2) return "its header names an unknown format '" + std::string(w[1].substr(0, 40)) + "'";
    } else if (w[0] == "comment" || w[0] == "obj_info") {
      continue;
    } else if (w[0] != "element" && w[0] != "property") {
      return "its header has a line that is not PLY ('" + std::string(w[0].substr(0, 20)) + "')";
    } else if (w[0] == "element") {
      long long n = 0;
      if (w.size() < 3 || !toLong(w[2], n) || n < 0) return "its header has an element without a valid count";
      if (n > kMaxSurfaceItems)
        return "it declares " + num(static_cast<double>(n)) + " " + std::string(w[1].substr(0, 40)) +
               " elements, more than " + num(kMaxSurfaceItems) + " (decimate it first)";
      elements.push_back({std::string(w[1].substr(0, 40)), n, {}});
    } else if (w[0] == "property") {
      if (elements.empty()) return "its header has a property before any element";
      PlyProperty p;
      bool s = false, f = false;
      if (w.size() >= 5 && w[1] == "list") {
        p.list = true;
        p.countBytes = plyTypeBytes(w[2], p.countSigned, f);
        p.valueBytes = plyTypeBytes(w[3], p.valueSigned, p.valueFloat);
        if (p.countBytes == 0 || f || p.valueBytes == 0) return "its header has a list property of an unknown type";
        p.name = std::string(w[4]);
      } else if (w.size() >= 3) {
        p.valueBytes = plyTypeBytes(w[1], s, f);
        p.valueSigned = s;
        p.valueFloat = f;
        if (p.valueBytes == 0) return "its header has a property of unknown type '" + std::string(w[1].substr(0, 20)) + "'";
        p.name = std::string(w[2]);
      } else {
        return "its header has an incomplete property line";
      }
      elements.back().properties.push_back(p);
    }
  }
  if (!ended) return "its header has no end_header line";
  if (format < 0) return "its header has no format line";
  long long vertices = 0;
  for (const auto& e : elements)
    if (e.name == "vertex") vertices = e.count;
  auto isIndexList = [](const PlyElement& e, const PlyProperty& p) {
    return e.name == "face" && p.list && (p.name == "vertex_indices" || p.name == "vertex_index");
  };
  const std::string_view body = bytes.substr(std::min(pos, bytes.size()));
  auto badIndex = [&](const PlyElement& e, long long row, double index) {
    return "its " + e.name + " " + num(static_cast<double>(row)) + " refers to vertex " + num(index) + ", but it has " +
           plural(static_cast<double>(vertices), "vertice");
  };
  auto shortOf = [](const PlyElement& e, long long rows) {
    return "it declares " + plural(static_cast<double>(e.count), elementWord(e.name)) + " but holds " + num(static_cast<double>(rows));
  };
  if (format == 0) {
    std::size_t at = 0;
    auto token = [&](std::string_view& t) {
      while (at < body.size() && isSpace(body[at])) ++at;
      const std::size_t b = at;
      while (at < body.size() && !isSpace(body[at])) ++at;
      t = body.substr(b, at - b);
      return at > b;
    };
    std::string_view t;
    for (const auto& e : elements)
      for (long long row = 0; row < e.count; ++row)
        for (const auto& p : e.properties) {
          if (!token(t)) return shortOf(e, row);
          if (!p.list) continue;
          long long n = 0;
          double d = 0;
          if (!toLong(t, n)) {
            if (!toDouble(t, d) || d != std::floor(d)) return "its " + e.name + " " + num(static_cast<double>(row)) + " has a list length that is not a whole number";
            // Compared as a double first: a length such as 3e118 does not fit a whole number type (found by fuzzing).
            if (!(d >= 0 && d <= kMaxFaceCorners))
              return "its " + e.name + " " + num(static_cast<double>(row)) + " has a list of " + num(d) +
                     " values (at most " + num(kMaxFaceCorners) + ")";
            n = static_cast<long long>(d);
          }
          if (n < 0 || n > kMaxFaceCorners)
            return "its " + e.name + " " + num(static_cast<double>(row)) + " has a list of " + num(static_cast<double>(n)) +
                   " values (at most " + num(kMaxFaceCorners) + ")";
          // A face of fewer than 3 corners is none (one of 0 corners aborted assimp's triangulation: found by fuzzing).
          if (isIndexList(e, p) && n < 3)
            return "its " + e.name + " " + num(static_cast<double>(row)) + " has " + num(static_cast<double>(n)) +
                   " corners; a face needs 3 or more";
          for (long long k = 0; k < n; ++k) {
            if (!token(t)) return shortOf(e, row);
            if (isIndexList(e, p)) {
              if (!toDouble(t, d)) return "its " + e.name + " " + num(static_cast<double>(row)) + " has a vertex index that is not a number";
              if (!(d >= 0 && d < static_cast<double>(vertices))) return badIndex(e, row, d);
            }
          }
        }
    return {};
  }
  const bool swap = (format == 2) != (std::endian::native == std::endian::big);
  std::size_t at = 0;
  auto read = [&](int bytesOf, bool isSigned, bool isFloat) -> double {
    unsigned char b[8] = {};
    std::memcpy(b, body.data() + at, static_cast<std::size_t>(bytesOf));
    at += static_cast<std::size_t>(bytesOf);
    if (swap) std::reverse(b, b + bytesOf);
    if (isFloat) {
      if (bytesOf == 4) {
        float f;
        std::memcpy(&f, b, 4);
        return f;
      }
      double d;
      std::memcpy(&d, b, 8);
      return d;
    }
    std::uint64_t u = 0;
    std::memcpy(&u, b, static_cast<std::size_t>(bytesOf));  // little-endian machine assumed after the swap
    if (isSigned && bytesOf < 8 && (u >> (bytesOf * 8 - 1)) & 1) return static_cast<double>(u) - std::ldexp(1.0, bytesOf * 8);
    return static_cast<double>(u);
  };
  for (const auto& e : elements) {
    const bool fixed = std::none_of(e.properties.begin(), e.properties.end(), [](const PlyProperty& p) { return p.list; });
    if (fixed) {
      std::size_t row = 0;
      for (const auto& p : e.properties) row += static_cast<std::size_t>(p.valueBytes);
      const std::size_t left = body.size() - at;
      if (row > 0 && static_cast<double>(row) * static_cast<double>(e.count) > static_cast<double>(left))
        return shortOf(e, static_cast<long long>(left / row));
      at += row * static_cast<std::size_t>(e.count);
      continue;
    }
    for (long long r = 0; r < e.count; ++r)
      for (const auto& p : e.properties) {
        if (!p.list) {
          if (body.size() - at < static_cast<std::size_t>(p.valueBytes)) return shortOf(e, r);
          at += static_cast<std::size_t>(p.valueBytes);
          continue;
        }
        if (body.size() - at < static_cast<std::size_t>(p.countBytes)) return shortOf(e, r);
        const double n = read(p.countBytes, p.countSigned, false);
        if (n < 0 || n > kMaxFaceCorners)
          return "its " + e.name + " " + num(static_cast<double>(r)) + " has a list of " + num(n) + " values (at most " +
                 num(kMaxFaceCorners) + ")";
        if (isIndexList(e, p) && n < 3)
          return "its " + e.name + " " + num(static_cast<double>(r)) + " has " + num(n) + " corners; a face needs 3 or more";
        const std::size_t need = static_cast<std::size_t>(n) * static_cast<std::size_t>(p.valueBytes);
        if (body.size() - at < need) return shortOf(e, r);
        if (!isIndexList(e, p)) {
          at += need;
          continue;
        }
        for (int k = 0; k < static_cast<int>(n); ++k) {
          const double index = read(p.valueBytes, p.valueSigned, p.valueFloat);
          if (!(index >= 0 && index < static_cast<double>(vertices))) return badIndex(e, r, index);
        }
      }
  }
  return {};
}

// ---- OFF ----

// The vertex and face counts as assimp 5.2's OFF reader takes them from the header, before it allocates for them:
// optional prefix letters (ST, C, N, 4, n) and OFF, or no keyword at all (then the first token must be a digit), an
// optional dimension, then the counts read as unsigned decimal digits (no digits: 0; wrapping past 2^32 as it does).
// False when assimp refuses the header itself. Its reading differs from ours (case, the prefixes, the dimension), so
// the counts it would allocate for are checked on their own.
bool assimpOffCounts(std::string_view bytes, std::uint32_t& nv, std::uint32_t& nf) {
  // Read in place (not a copy of the file): position i in assimp's buffer, which is the file and a NUL after it.
  const std::size_t end = bytes.size() + 1;
  std::size_t i = 0;
  auto at = [&](std::size_t k) { return k < bytes.size() ? bytes[k] : '\0'; };
  auto skipSpacesAndLineEnd = [&] {
    while (at(i) == ' ' || at(i) == '\t' || at(i) == '\r' || at(i) == '\n') ++i;
  };
  auto skipLine = [&] {
    while (at(i) != '\r' && at(i) != '\n' && at(i) != '\0') ++i;
    while (at(i) == '\r' || at(i) == '\n') ++i;
  };
  auto nextToken = [&] {
    skipSpacesAndLineEnd();
    while (i < end && (at(i) == '#' || at(i) == '\n' || at(i) == '\r')) {
      skipLine();
      skipSpacesAndLineEnd();
    }
  };
  auto strtoul10 = [&] {
    std::uint32_t v = 0;
    while (at(i) >= '0' && at(i) <= '9') v = v * 10u + static_cast<std::uint32_t>(at(i++) - '0');
    return v;
  };
  nextToken();
  bool hasDimension = false;
  if (i + 2 < end && at(i) == 'S' && at(i + 1) == 'T') i += 2;
  if (i + 1 < end && at(i) == 'C') ++i;
  if (i + 1 < end && at(i) == 'N') ++i;
  if (i + 1 < end && at(i) == '4') ++i;
  if (i + 1 < end && at(i) == 'n') {
    hasDimension = true;
    ++i;
  }
  if (i + 3 < end && at(i) == 'O' && at(i + 1) == 'F' && at(i + 2) == 'F') {
    i += 3;
    nextToken();
  } else {
    nextToken();
    if (i + 1 >= end || at(i) < '0' || at(i) > '9') return false;
  }
  if (hasDimension) {
    if (strtoul10() > 3) return false;
    nextToken();
  }
  nextToken();
  nv = strtoul10();
  nextToken();
  nf = strtoul10();
  return true;
}

std::string offProblem(std::string_view bytes) {
  // Each vertex and each face takes a line of its own: a count beyond the file's lines is refused before assimp
  // allocates for it (a header's "946735786" asked for 11 GB).
  if (std::uint32_t nv = 0, nf = 0; assimpOffCounts(bytes, nv, nf)) {
    const double lines = static_cast<double>(std::count(bytes.begin(), bytes.end(), '\n')) + 1;
    if (nv > lines || nf > lines)
      return "its header declares " + plural(static_cast<double>(nv > lines ? nv : nf), nv > lines ? "vertice" : "face") +
             " but the file has only " + plural(lines, "line");
  }
  std::size_t pos = 0;
  std::string_view line;
  // Lines without comments, blank ones skipped.
  auto content = [&](std::vector<std::string_view>& w) {
    while (nextLine(bytes, pos, line)) {
      if (auto hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
      w = words(line);
      if (!w.empty()) return true;
    }
    return false;
  };
  std::vector<std::string_view> w;
  if (!content(w)) return {};
  std::size_t first = 0;
  const std::string head = lowerCopy(w[0]);
  if (head.size() >= 3 && head.compare(head.size() - 3, 3, "off") == 0) first = 1;
  else return {};  // no OFF keyword: assimp decides
  if (w.size() <= first) {  // the counts on the next line
    if (!content(w)) return "it ends before its counts of vertices and faces";
    first = 0;
  }
  std::vector<std::string_view> counts(w.begin() + static_cast<long>(first), w.end());
  long long nv = 0, nf = 0;
  if (counts.size() < 2 || !toLong(counts[0], nv) || !toLong(counts[1], nf) || nv < 0 || nf < 0)
    return "its header has no valid counts of vertices and faces";
  if (nv > kMaxSurfaceItems || nf > kMaxSurfaceItems)
    return "it declares " + plural(static_cast<double>(std::max(nv, nf)), nv > nf ? "vertice" : "face") +
           ", more than " + num(kMaxSurfaceItems) + " (decimate it first)";
  for (long long v = 0; v < nv; ++v) {
    if (!content(w)) return "it declares " + plural(static_cast<double>(nv), "vertice") + " but holds " + num(static_cast<double>(v));
    double x = 0;
    if (w.size() < 3) return "its vertex " + num(static_cast<double>(v)) + " has fewer than 3 coordinates";
    for (int k = 0; k < 3; ++k)
      if (!toDouble(w[static_cast<std::size_t>(k)], x)) return "its vertex " + num(static_cast<double>(v)) + " has a coordinate that is not a number";
  }
  for (long long f = 0; f < nf; ++f) {
    if (!content(w)) return "it declares " + plural(static_cast<double>(nf), "face") + " but holds " + num(static_cast<double>(f));
    long long n = 0;
    if (!toLong(w[0], n) || n < 3 || n > kMaxFaceCorners)
      return "its face " + num(static_cast<double>(f)) + " declares " + std::string(w[0].substr(0, 20)) +
             " corners (3 to " + num(kMaxFaceCorners) + ")";
    if (static_cast<long long>(w.size()) - 1 < n)
      return "its face " + num(static_cast<double>(f)) + " declares " + num(static_cast<double>(n)) + " corners but lists " +
             num(static_cast<double>(w.size() - 1));
    for (long long k = 1; k <= n; ++k) {
      long long i = 0;
      if (!toLong(w[static_cast<std::size_t>(k)], i) || i < 0 || i >= nv)
        return "its face " + num(static_cast<double>(f)) + " refers to vertex " + std::string(w[static_cast<std::size_t>(k)].substr(0, 20)) +
               ", but it has " + plural(static_cast<double>(nv), "vertice");
    }
  }
  return {};
}

// ---- OBJ ----

std::string objProblem(std::string_view bytes) {
  std::size_t pos = 0, number = 0;
  std::string_view line;
  while (nextLine(bytes, pos, line)) {
    ++number;
    std::string_view l = trim(line);
    if (l.size() < 2 || l[0] != 'f' || !isSpace(l[1])) continue;
    std::size_t corners = 0;
    bool in = false;
    for (char c : l.substr(1)) {
      if (!isSpace(c) && !in) ++corners;
      in = !isSpace(c);
    }
    if (corners > static_cast<std::size_t>(kMaxFaceCorners))
      return "its face on line " + num(static_cast<double>(number)) + " has " + num(static_cast<double>(corners)) +
             " corners (at most " + num(kMaxFaceCorners) + ")";
  }
  return {};
}

// ---- glTF ----

std::string gltfProblem(std::string_view bytes, bool binary,
                        const std::function<long long(const std::string& uri)>& externalBytes) {
  std::string_view json = bytes, bin;
  bool haveBin = false;
  auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
  };
  if (binary) {
    if (bytes.size() < 20 || bytes.substr(0, 4) != "glTF") return {};  // assimp says it is not a GLB
    const std::uint32_t jsonLength = u32(12);
    if (u32(16) != 0x4E4F534Au || jsonLength > bytes.size() - 20) return "its JSON chunk is longer than the file";
    json = bytes.substr(20, jsonLength);
    std::size_t at = 20 + static_cast<std::size_t>(jsonLength);
    at = (at + 3) & ~std::size_t(3);
    if (at + 8 <= bytes.size() && u32(at + 4) == 0x004E4942u) {
      const std::uint32_t binLength = u32(at);
      if (binLength > bytes.size() - at - 8) return "its binary chunk is longer than the file";
      bin = bytes.substr(at + 8, binLength);
      haveBin = true;
    }
  }
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(json.begin(), json.end());
  } catch (const std::exception&) {
    return {};  // not JSON: assimp says so
  }
  if (!j.is_object()) return {};
  auto array = [&](const char* key) -> const nlohmann::json& {
    static const nlohmann::json empty = nlohmann::json::array();
    auto it = j.find(key);
    return it != j.end() && it->is_array() ? *it : empty;
  };
  const auto &nodes = array("nodes"), &meshes = array("meshes"), &accessors = array("accessors"),
             &views = array("bufferViews"), &buffers = array("buffers"), &scenes = array("scenes");
  auto index = [](const nlohmann::json& o, const char* key, std::size_t size, long long& out) -> int {
    // 0: absent, 1: valid, -1: out of range or not an index.
    if (!o.is_object() || !o.contains(key)) return 0;
    const auto& v = o.at(key);
    if (!v.is_number_integer()) return -1;
    out = v.get<long long>();
    return out >= 0 && static_cast<std::size_t>(out) < size ? 1 : -1;
  };
  auto number = [](const nlohmann::json& o, const char* key, double fallback) {
    if (!o.is_object() || !o.contains(key) || !o.at(key).is_number()) return fallback;
    return o.at(key).get<double>();
  };
  // Buffers, views, accessors.
  for (std::size_t b = 0; b < buffers.size(); ++b) {
    const double length = number(buffers[b], "byteLength", -1);
    if (!(length >= 0)) return "its buffer " + num(static_cast<double>(b)) + " has no valid byteLength";
    if (binary && b == 0 && !buffers[b].contains("uri") && (!haveBin || length > static_cast<double>(bin.size())))
      return "its buffer 0 declares " + num(length) + " bytes but the binary chunk holds " + num(static_cast<double>(bin.size()));
    // A buffer's own file, or its embedded base64, must hold what it declares (assimp read past a short one).
    if (buffers[b].is_object() && buffers[b].contains("uri") && buffers[b]["uri"].is_string()) {
      const std::string uri = buffers[b]["uri"].get<std::string>();
      double held = -1;
      std::string where;
      if (uri.rfind("data:", 0) == 0) {
        const auto comma = uri.find(',');
        if (comma == std::string::npos || uri.find(";base64", 0) > comma)
          return "its buffer " + num(static_cast<double>(b)) + " embeds data that is not base64";
        const std::size_t chars = uri.size() - comma - 1;
        std::size_t pad = 0;
        for (std::size_t i = uri.size(); i > comma + 1 && uri[i - 1] == '='; --i) ++pad;
        held = static_cast<double>(chars / 4 * 3) - static_cast<double>(std::min<std::size_t>(pad, 2));
        where = "its embedded data";
      } else if (externalBytes) {
        const long long size = externalBytes(uri);
        if (size < 0)
          return "its buffer " + num(static_cast<double>(b)) + " names the file '" + uri.substr(0, 60) +
                 "', which is not a file beside it";
        held = static_cast<double>(size);
        where = "the file '" + uri.substr(0, 60) + "'";
      }
      if (held >= 0 && length > held)
        return "its buffer " + num(static_cast<double>(b)) + " declares " + num(length) + " bytes but " + where +
               " holds " + num(held);
    }
  }
  for (std::size_t v = 0; v < views.size(); ++v) {
    long long b = 0;
    if (index(views[v], "buffer", buffers.size(), b) != 1)
      return "its buffer view " + num(static_cast<double>(v)) + " refers to a buffer it does not have";
    const double offset = number(views[v], "byteOffset", 0), length = number(views[v], "byteLength", -1);
    if (!(offset >= 0 && length >= 0 && offset + length <= number(buffers[static_cast<std::size_t>(b)], "byteLength", -1)))
      return "its buffer view " + num(static_cast<double>(v)) + " reaches beyond the end of its buffer";
  }
  auto componentBytes = [](double t) { return t == 5120 || t == 5121 ? 1 : t == 5122 || t == 5123 ? 2 : t == 5125 || t == 5126 ? 4 : 0; };
  auto components = [](const nlohmann::json& a) {
    static const std::map<std::string, int> n = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4},
                                                 {"MAT2", 4},   {"MAT3", 9}, {"MAT4", 16}};
    if (!a.contains("type") || !a.at("type").is_string()) return 0;
    auto it = n.find(a.at("type").get<std::string>());
    return it == n.end() ? 0 : it->second;
  };
  for (std::size_t a = 0; a < accessors.size(); ++a) {
    const auto& acc = accessors[a];
    const double count = number(acc, "count", -1);
    const int cb = componentBytes(number(acc, "componentType", 0)), nc = acc.is_object() ? components(acc) : 0;
    const std::string what = "its accessor " + num(static_cast<double>(a));
    if (!(count >= 1) || cb == 0 || nc == 0) return what + " has no valid count, componentType or type";
    long long v = 0;
    const int hasView = index(acc, "bufferView", views.size(), v);
    if (hasView == -1) return what + " refers to a buffer view it does not have";
    if (hasView == 0) continue;  // zeros (or sparse values)
    const auto& view = views[static_cast<std::size_t>(v)];
    const double element = cb * nc, stride = number(view, "byteStride", element);
    if (!(stride >= element) || number(acc, "byteOffset", 0) < 0 ||
        number(acc, "byteOffset", 0) + stride * (count - 1) + element > number(view, "byteLength", -1))
      return what + " declares " + num(count) + " values, more than its buffer view holds";
  }
  // The hierarchy: each path from a root, iteratively (a 20,000-deep chain must not overflow our stack either).
  std::vector<double> meshTriangles(meshes.size(), 0.0);
  std::vector<std::pair<long long, long long>> indexChecks;  // (indices accessor, position accessor)
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    if (!meshes[m].is_object() || !meshes[m].contains("primitives") || !meshes[m].at("primitives").is_array()) continue;
    for (const auto& p : meshes[m].at("primitives")) {
      long long pa = 0, ia = 0;
      const nlohmann::json attributes = p.is_object() && p.contains("attributes") ? p.at("attributes") : nlohmann::json::object();
      const int hasPosition = index(attributes, "POSITION", accessors.size(), pa);
      const int hasIndices = index(p, "indices", accessors.size(), ia);
      if (hasPosition == -1 || hasIndices == -1)
        return "its mesh " + num(static_cast<double>(m)) + " refers to an accessor it does not have";
      if (hasPosition == 0) continue;
      const double corners = number(accessors[static_cast<std::size_t>(hasIndices == 1 ? ia : pa)], "count", 0);
      const double mode = number(p, "mode", 4);
      meshTriangles[m] += mode == 4 ? std::floor(corners / 3) : mode == 5 || mode == 6 ? std::max(0.0, corners - 2) : 0;
      if (hasIndices == 1) indexChecks.emplace_back(ia, pa);
    }
  }
  const std::size_t n = nodes.size();
  std::vector<bool> child(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    long long m = 0;
    if (index(nodes[i], "mesh", meshes.size(), m) == -1)
      return "its node " + num(static_cast<double>(i)) + " refers to a mesh it does not have";
    if (!nodes[i].is_object() || !nodes[i].contains("children")) continue;
    const auto& c = nodes[i].at("children");
    if (!c.is_array()) return "its node " + num(static_cast<double>(i)) + " has children that are not a list";
    for (const auto& k : c) {
      if (!k.is_number_integer() || k.get<long long>() < 0 || static_cast<std::size_t>(k.get<long long>()) >= n)
        return "its node " + num(static_cast<double>(i)) + " has a child it does not have";
      child[static_cast<std::size_t>(k.get<long long>())] = true;
    }
  }
  std::vector<std::size_t> roots;
  for (const auto& s : scenes)
    if (s.is_object() && s.contains("nodes") && s.at("nodes").is_array())
      for (const auto& r : s.at("nodes")) {
        if (!r.is_number_integer() || r.get<long long>() < 0 || static_cast<std::size_t>(r.get<long long>()) >= n)
          return "its scene refers to a node it does not have";
        roots.push_back(static_cast<std::size_t>(r.get<long long>()));
      }
  if (scenes.empty())
    for (std::size_t i = 0; i < n; ++i)
      if (!child[i]) roots.push_back(i);
  // Instances and triangles reached below each node, memoised (a DAG of shared levels multiplies them).
  std::vector<int> state(n, 0);  // 0 unseen, 1 on the current path, 2 done
  std::vector<double> instances(n, 0), triangles(n, 0);
  double totalInstances = 0, totalTriangles = 0;
  for (std::size_t root : roots) {
    std::vector<std::pair<std::size_t, std::size_t>> path;  // node, next child
    if (state[root] == 0) path.emplace_back(root, 0), state[root] = 1;
    while (!path.empty()) {
      if (static_cast<int>(path.size()) > kMaxGltfDepth)
        return "its node hierarchy is more than " + num(kMaxGltfDepth) + " levels deep";
      auto& [node, next] = path.back();
      const nlohmann::json* c = nodes[node].is_object() && nodes[node].contains("children") ? &nodes[node].at("children") : nullptr;
      if (c && next < c->size()) {
        const auto k = static_cast<std::size_t>((*c)[next++].get<long long>());
        if (state[k] == 1) return "its node hierarchy has a cycle (node " + num(static_cast<double>(k)) + " is its own ancestor)";
        if (state[k] == 0) path.emplace_back(k, 0), state[k] = 1;
        continue;
      }
      long long m = 0;
      double inst = 0, tri = 0;
      if (index(nodes[node], "mesh", meshes.size(), m) == 1) inst = 1, tri = meshTriangles[static_cast<std::size_t>(m)];
      if (c)
        for (const auto& k : *c) {
          inst += instances[static_cast<std::size_t>(k.get<long long>())];
          tri += triangles[static_cast<std::size_t>(k.get<long long>())];
        }
      instances[node] = std::min(inst, 1e300);
      triangles[node] = std::min(tri, 1e300);
      state[node] = 2;
      path.pop_back();
    }
    totalInstances += instances[root];
    totalTriangles += triangles[root];
  }
  if (totalInstances > kMaxGltfInstances)
    return "its node hierarchy places " + num(totalInstances) + " mesh instances (at most " + num(kMaxGltfInstances) + ")";
  if (totalTriangles > kMaxSurfaceItems)
    return "its node hierarchy places " + num(totalTriangles) + " triangles (at most " + num(kMaxSurfaceItems) + ")";
  // Index values against the vertex count, where the bytes are at hand (the GLB's binary chunk).
  if (haveBin)
    for (auto [ia, pa] : indexChecks) {
      const auto& acc = accessors[static_cast<std::size_t>(ia)];
      long long v = 0;
      if (index(acc, "bufferView", views.size(), v) != 1 || acc.contains("sparse")) continue;
      const auto& view = views[static_cast<std::size_t>(v)];
      long long b = 0;
      if (index(view, "buffer", buffers.size(), b) != 1 || b != 0 || buffers[0].contains("uri")) continue;
      const int cb = componentBytes(number(acc, "componentType", 0));
      const double vertices = number(accessors[static_cast<std::size_t>(pa)], "count", 0);
      const double stride = number(view, "byteStride", cb);
      const double first = number(view, "byteOffset", 0) + number(acc, "byteOffset", 0);
      if (!(stride >= 0 && stride <= static_cast<double>(bin.size()) && first >= 0 &&
            first <= static_cast<double>(bin.size())))
        return "its accessor " + num(static_cast<double>(ia)) + " reaches beyond the binary chunk";
      const auto start = static_cast<std::size_t>(first);
      const auto count = static_cast<std::size_t>(number(acc, "count", 0));
      for (std::size_t i = 0; i < count; ++i) {
        const std::size_t at = start + i * static_cast<std::size_t>(stride);
        if (at + static_cast<std::size_t>(cb) > bin.size()) return "its accessor " + num(static_cast<double>(ia)) + " reaches beyond the binary chunk";
        std::uint32_t value = 0;
        std::memcpy(&value, bin.data() + at, static_cast<std::size_t>(cb));  // glTF is little-endian
        if (value >= vertices)
          return "its accessor " + num(static_cast<double>(ia)) + " holds vertex index " + num(value) + ", but the mesh has " +
                 plural(vertices, "vertice");
      }
    }
  return {};
}

// ---- NRRD ----

namespace {
// "(a,b,c)" -> numbers; false when not of that form.
bool vectorOf(std::string_view s, std::vector<double>& out) {
  out.clear();
  s = trim(s);
  if (s.size() < 2 || s.front() != '(' || s.back() != ')') return false;
  s = s.substr(1, s.size() - 2);
  while (true) {
    const std::size_t comma = s.find(',');
    double v = 0;
    if (!toDouble(trim(s.substr(0, comma)), v)) return false;
    out.push_back(v);
    if (comma == std::string_view::npos) return true;
    s = s.substr(comma + 1);
  }
}

// Splits "(1,0,0) none (0,1,0)" into its vectors and "none"s (spaces may also fall inside the brackets).
std::vector<std::string> vectorWords(std::string_view s) {
  std::vector<std::string> out;
  std::string cur;
  int depth = 0;
  for (char c : s) {
    if (c == '(') ++depth;
    if (c == ')') --depth;
    if (isSpace(c) && depth == 0) {
      if (!cur.empty()) out.push_back(cur), cur.clear();
      continue;
    }
    if (!isSpace(c)) cur += c;
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

std::string voxelProblem(double mm) {
  if (!std::isfinite(mm)) return "a voxel size that is not a number";
  if (mm < kMinVoxelMm || mm > kMaxVoxelMm)
    return "a voxel size of " + num(mm) + " mm (a medical image's lies between " + num(kMinVoxelMm) + " and " +
           num(kMaxVoxelMm) + " mm)";
  return {};
}
}  // namespace

std::string nrrdHeaderProblem(std::string_view header) {
  std::size_t pos = 0;
  std::string_view line;
  if (!nextLine(header, pos, line) || line.substr(0, 4) != "NRRD") return {};  // ITK says it is not NRRD
  std::map<std::string, std::string> fields;
  while (nextLine(header, pos, line)) {
    if (trim(line).empty()) break;  // the data follow
    if (line.front() == '#') continue;
    const std::size_t colon = line.find(": ");
    if (colon == std::string_view::npos || line.find(":=") != std::string_view::npos) continue;  // key:=value pairs
    fields[lowerCopy(trim(line.substr(0, colon)))] = std::string(trim(line.substr(colon + 2)));
  }
  long long dimension = 0;
  if (!fields.count("dimension") || !toLong(fields["dimension"], dimension))
    return "its header has no valid dimension";
  // 2 is left to the reader, which says it is a 2D image; 4 is a 3D Slicer segmentation of overlapping layers, which
  // the reader explains when it has more than one.
  if (dimension < 2 || dimension > 4)
    return "its header declares " + num(static_cast<double>(dimension)) + " dimensions (a segmentation is a 3D label image)";
  if (fields.count("space dimension")) {
    long long s = 0;
    if (!toLong(fields["space dimension"], s) || s != 3) return "its header declares a space of other than 3 dimensions";
  }
  const auto sizes = words(fields["sizes"]);
  if (static_cast<long long>(sizes.size()) != dimension) return "its sizes do not match its dimension";
  for (auto s : sizes) {
    long long v = 0;
    if (!toLong(s, v) || v < 1) return "its sizes are not positive whole numbers";
  }
  int nonSpatial = 0;
  if (fields.count("spacings")) {
    const auto sp = words(fields["spacings"]);
    if (static_cast<long long>(sp.size()) != dimension) return "its spacings do not match its dimension";
    for (auto s : sp) {
      double v = 0;
      if (!toDouble(s, v)) return "its spacings are not numbers";
      if (std::isnan(v) && dimension == 4 && nonSpatial++ == 0) continue;  // the list axis of a 4D segmentation
      if (auto p = voxelProblem(std::abs(v)); !p.empty()) return "its spacings give " + p;
    }
  }
  nonSpatial = 0;
  if (fields.count("space directions")) {
    const auto dirs = vectorWords(fields["space directions"]);
    if (static_cast<long long>(dirs.size()) != dimension) return "its space directions do not match its dimension";
    std::vector<double> v;
    for (const auto& d : dirs) {
      if (d == "none" && dimension == 4 && nonSpatial++ == 0) continue;
      if (!vectorOf(d, v) || v.size() != 3) return "its space directions are not 3D vectors";
      double norm = 0;
      for (double x : v) norm += x * x;
      if (auto p = voxelProblem(std::sqrt(norm)); !p.empty()) return "its space directions give " + p;
    }
  }
  if (fields.count("space origin")) {
    std::vector<double> v;
    if (!vectorOf(fields["space origin"], v) || v.size() != 3) return "its space origin is not a 3D point";
    for (double x : v)
      if (!std::isfinite(x) || std::abs(x) > 1e5) return "its space origin holds " + num(x) + " mm (not a number, or beyond 100 m)";
  }
  for (const char* key : {"data file", "datafile"})
    if (fields.count(key)) {
      const std::string& f = fields[key];
      if (f.substr(0, 4) == "LIST" || words(f).size() != 1 || f.find('%') != std::string::npos)
        return "its data file is a list or a file-name pattern ('" + f.substr(0, 40) +
               "'), which this program does not read; save it as one .nrrd file";
    }
  return {};
}

// ---- MetaImage ----

std::string metaImageHeaderProblem(std::string_view bytes, MetaImageLayout* layout) {
  std::size_t pos = 0;
  std::string_view line;
  std::map<std::string, std::string> fields;
  bool sawData = false;
  // MetaIO reads a field's name up to the next '=', across line ends, and copies it into a 255-byte buffer with strcpy
  // (found by fuzzing: a 400-character name overflowed it, caught by glibc's fortify as SIGABRT). Names here are short.
  std::size_t keyStart = 0;
  while (pos < 65536) {
    const std::size_t lineStart = pos;
    if (!nextLine(bytes, pos, line)) break;
    const std::size_t eq = line.find('=');
    if (eq == std::string_view::npos) continue;
    if (const std::size_t nameBytes = lineStart + eq - keyStart; nameBytes > 200)
      return "a field name of " + num(static_cast<double>(nameBytes)) +
             " characters (the text before an '='; MetaImage names are a few words)";
    keyStart = pos;
    // MetaIO holds the name as a C string: it ends at a NUL byte (found by fuzzing: "NDims\0<bytes> = 1.6e18" was
    // taken for NDims, unchecked here, and MetaIO read values for minutes).
    std::string_view name = line.substr(0, eq);
    name = name.substr(0, name.find('\0'));
    const std::string key(trim(name));
    // MetaIO takes a field given twice as it comes (found by fuzzing: "NDims = 1.6e18" before a later "NDims = 3",
    // which was all this check saw; MetaIO read values for minutes): a header says each once.
    if (fields.count(key)) return "its field '" + key.substr(0, 40) + "' is given twice";
    fields[key] = std::string(trim(line.substr(eq + 1)));
    if (key == "ElementDataFile") {
      sawData = true;
      break;
    }
  }
  long long dims = 0;
  if (fields.count("NDims") && (!toLong(fields["NDims"], dims) || dims < 1 || dims > 10))
    return "its NDims = " + fields["NDims"].substr(0, 24) + " (a label image has 3 dimensions)";
  // MetaIO does not always say so itself (found by fuzzing: a name "ElementDataFile" ended by a NUL byte and no '='
  // after it, with CompressedData = True, made it allocate 2^63 bytes for the compressed voxels).
  if (!sawData) return "it has no ElementDataFile field (where its voxels are)";
  const std::string& file = fields["ElementDataFile"];
  // A name with control characters or a NUL byte is damage (found by fuzzing: MetaIO cut such a name at the NUL and
  // read on into a compressed size of 2^63 bytes).
  if (std::any_of(file.begin(), file.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; }))
    return "its ElementDataFile is not a file name (it holds control characters)";
  if (file.find('%') != std::string::npos || file.substr(0, 4) == "LIST" || words(file).size() != 1)
    return "its ElementDataFile is a list or a file-name pattern ('" + file.substr(0, 40) +
           "'), which this program does not read; save it as one .mha file";
  const auto sizes = words(fields["DimSize"]);
  if (dims > 0 && static_cast<long long>(sizes.size()) != dims) return "its DimSize does not match its NDims";
  double voxels = 1;
  for (auto s : sizes) {
    long long v = 0;
    if (!toLong(s, v) || v < 1) return "its DimSize is not positive whole numbers";
    voxels *= static_cast<double>(v);
  }
  for (const char* key : {"ElementSpacing", "ElementSize"})
    if (fields.count(key))
      for (auto s : words(fields[key])) {
        double v = 0;
        if (!toDouble(s, v)) return std::string("its ") + key + " is not numbers";
        if (auto p = voxelProblem(std::abs(v)); !p.empty()) return std::string("its ") + key + " gives " + p;
      }
  static const std::map<std::string, int> typeBytes = {
      {"MET_CHAR", 1},  {"MET_UCHAR", 1}, {"MET_SHORT", 2},     {"MET_USHORT", 2},     {"MET_INT", 4},
      {"MET_UINT", 4},  {"MET_LONG", 4},  {"MET_ULONG", 4},     {"MET_LONG_LONG", 8},  {"MET_ULONG_LONG", 8},
      {"MET_FLOAT", 4}, {"MET_DOUBLE", 8}};
  auto type = typeBytes.find(fields["ElementType"]);
  if (type == typeBytes.end()) return {};  // MetaIO or ITK refuse the type
  long long channels = 1;
  if (fields.count("ElementNumberOfChannels") && (!toLong(fields["ElementNumberOfChannels"], channels) || channels < 1 || channels > 64))
    return "its ElementNumberOfChannels is not a small positive number";
  if (layout) {
    layout->dataFile = file;
    layout->dataOffset = std::min(pos, bytes.size());
    layout->expectedBytes = voxels * static_cast<double>(channels) * type->second;
    const std::string c = lowerCopy(fields["CompressedData"]);
    layout->compressed = c == "true" || c == "1";
    layout->headerSize = 0;
    if (fields.count("HeaderSize") && !toLong(fields["HeaderSize"], layout->headerSize)) return "its HeaderSize is not a number";
    if (layout->headerSize < -1) return "its HeaderSize is negative";
  }
  return {};
}

// ---- OpenCV FileStorage (YAML, XML) ----

std::string calibrationMarkupProblem(std::string_view bytes, bool xml) {
  if (bytes.size() > kMaxCalibrationBytes)
    return "it is " + num(static_cast<double>(bytes.size() >> 10)) + " kB, more than a calibration file's " +
           num(static_cast<double>(kMaxCalibrationBytes >> 10)) + " kB";
  const std::string deep = "it is nested more than " + num(kMaxCalibrationDepth) + " levels deep";
  // A calibration is text. OpenCV's parsers read it as C strings: a NUL byte inside an XML declaration made its XML
  // parser follow a null pointer (SIGSEGV, found by fuzzing). Control characters other than tab and line ends are
  // refused.
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const auto c = static_cast<unsigned char>(bytes[i]);
    if ((c < 0x20 && c != '\t' && c != '\n' && c != '\r') || c == 0x7f)
      return "it holds a control character (byte " + num(c) + " at offset " + num(static_cast<double>(i)) +
             "), which a calibration's text does not";
  }
  if (xml) {
    int depth = 0;
    for (std::size_t i = 0; i + 1 < bytes.size(); ++i) {
      if (bytes[i] != '<') continue;
      const char n = bytes[i + 1];
      if (n == '?' || n == '!') continue;
      const std::size_t close = bytes.find('>', i);
      if (n == '/') {
        depth = std::max(0, depth - 1);
      } else if (close == std::string_view::npos || bytes[close - 1] != '/') {
        if (++depth > kMaxCalibrationDepth) return deep;
      }
      if (close == std::string_view::npos) break;
      i = close;
    }
    // Then the XML itself, by a parser that checks it (OpenCV's does not): well formed, an OpenCV storage.
    tinyxml2::XMLDocument doc;
    if (doc.Parse(bytes.data(), bytes.size()) != tinyxml2::XML_SUCCESS)
      return std::string("it is not well-formed XML (") + doc.ErrorName() + " at line " + num(doc.ErrorLineNum()) + ")";
    const tinyxml2::XMLElement* root = doc.RootElement();
    if (!root || std::string_view(root->Name()) != "opencv_storage")
      return "its XML is not an OpenCV storage (the root element is not <opencv_storage>)";
    return {};
  }
  // YAML: block levels (distinct indentations, and "- " entries) plus flow brackets, which must pair up.
  std::size_t pos = 0, lineNumber = 0;
  std::string_view line;
  std::vector<std::size_t> indents;
  std::string open;  // the flow brackets open, innermost last
  std::size_t openedOn = 0, topLine = 0;
  while (nextLine(bytes, pos, line)) {
    ++lineNumber;
    const int flow = static_cast<int>(open.size());
    std::size_t indent = 0;
    while (indent < line.size() && (line[indent] == ' ' || line[indent] == '\t')) ++indent;
    if (indent == line.size() || line[indent] == '#') continue;
    if (line[indent] == '%') {
      if (topLine > 0) return "its line " + num(static_cast<double>(lineNumber)) + " is a directive inside the mapping";
      continue;
    }
    // OpenCV 4.6's YAML parser skips three bytes after a top-level collection that ends before the file does and never
    // returned from what followed (found by fuzzing: "   - 1" then "]" at column 0; "--- a: 1" then "  - 2"; a flow
    // list's "]" at column 0; "..." then more). A calibration is one mapping at column 0, as OpenCV and ROS write it:
    // its first entry is a key at column 0, "---" stands alone before it, no document follows, and the lines inside a
    // flow are indented.
    const std::string_view rest = line.substr(indent);
    const std::string where = "its line " + num(static_cast<double>(lineNumber));
    if (rest.substr(0, 3) == "---" || rest.substr(0, 3) == "...") {
      std::size_t after = indent + 3;
      while (after < line.size() && (line[after] == ' ' || line[after] == '\t')) ++after;
      if (topLine > 0 || rest[0] == '.' || indent > 0 || (after < line.size() && line[after] != '#'))
        return where + " is a YAML document marker where a calibration (one mapping) has none";
      continue;
    }
    if (flow == 0) {
      if (topLine == 0) {
        if (indent > 0 || rest[0] == '-' || rest[0] == '[' || rest[0] == '{')
          return where + " should begin the calibration's mapping at column 0 (\"key: value\")";
        topLine = lineNumber;
      }
      while (!indents.empty() && indents.back() >= indent) indents.pop_back();
      indents.push_back(indent);
    } else if (indent == 0) {
      return where + " continues a flow list at column 0; indent it";
    }
    int dashes = 0;
    for (std::size_t k = indent; k + 1 < line.size() && line[k] == '-' && line[k + 1] == ' ';) {
      ++dashes;
      k += 2;
      while (k < line.size() && line[k] == ' ') ++k;
    }
    if (static_cast<int>(indents.size()) + dashes + flow > kMaxCalibrationDepth) return deep;
    char quote = 0;
    for (std::size_t k = indent; k < line.size(); ++k) {
      const char c = line[k];
      if (quote) {
        if (c == quote) quote = 0;
        continue;
      }
      if (c == '"' || c == '\'') quote = c;
      else if (c == '#' && k > 0 && isSpace(line[k - 1])) break;
      else if (c == '[' || c == '{') {
        if (open.empty()) openedOn = lineNumber;
        open.push_back(c);
        if (static_cast<int>(indents.size() + open.size()) + dashes > kMaxCalibrationDepth) return deep;
      } else if (c == ']' || c == '}') {
        if (open.empty() || open.back() != (c == ']' ? '[' : '{'))
          return std::string("its '") + c + "' on line " + num(static_cast<double>(lineNumber)) + " closes no '" +
                 (c == ']' ? '[' : '{') + "'";
        open.pop_back();
      }
    }
  }
  if (!open.empty())
    return std::string("its '") + open.front() + "' on line " + num(static_cast<double>(openedOn)) + " is never closed";
  return {};
}

}  // namespace rehearse::simcore::checks
