// PLY pre-parse checks (see input_checks.hpp): the header, its element list, and the ASCII or binary body.
#include <rehearse/simcore/input_checks.hpp>

#include "input_checks_parts.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace rehearse::simcore::checks {

using namespace detail;

namespace {

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

bool isIndexList(const PlyElement& e, const PlyProperty& p) {
  return e.name == "face" && p.list && (p.name == "vertex_indices" || p.name == "vertex_index");
}

std::string badIndex(const PlyElement& e, long long row, double index, long long vertices) {
  return "its " + e.name + " " + num(static_cast<double>(row)) + " refers to vertex " + num(index) + ", but it has " +
         plural(static_cast<double>(vertices), "vertice");
}

// The rows the data after the header is enough for, counted in the header's order: a text file's values are not tied to
// its lines, so a face's line read where a vertex is declared counts as one (a person's file with 3 vertices and a face
// read "holds 4").
std::string shortOf(const PlyElement& e, long long rows, bool binary) {
  return "it declares " + plural(static_cast<double>(e.count), elementWord(e.name)) + " but the " +
         (binary ? "bytes" : "values") + " after its header make only " + num(static_cast<double>(rows));
}

// A "property" line of the header (its words `w`), added to the last element.
std::string plyPropertyProblem(const std::vector<std::string_view>& w, std::vector<PlyElement>& elements) {
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
  return {};
}

// The header after its first line, up to end_header (`pos` then at the body): its elements, and its format (0 ascii,
// 1 little endian, 2 big endian).
std::string plyHeaderProblem(std::string_view bytes, std::size_t& pos, std::vector<PlyElement>& elements, int& format) {
  std::string_view line;
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
      if (auto problem = plyPropertyProblem(w, elements); !problem.empty()) return problem;
    }
  }
  if (!ended) return "its header has no end_header line";
  if (format < 0) return "its header has no format line";
  return {};
}

// An ASCII body: its rows' tokens, list lengths and vertex indices.
std::string plyAsciiProblem(const std::vector<PlyElement>& elements, std::string_view body, long long vertices) {
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
        if (!token(t)) return shortOf(e, row, false);
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
          if (!token(t)) return shortOf(e, row, false);
          if (isIndexList(e, p)) {
            if (!toDouble(t, d)) return "its " + e.name + " " + num(static_cast<double>(row)) + " has a vertex index that is not a number";
            if (!(d >= 0 && d < static_cast<double>(vertices))) return badIndex(e, row, d, vertices);
          }
        }
      }
  return {};
}

// A binary body: its rows' sizes, list lengths and vertex indices.
std::string plyBinaryProblem(const std::vector<PlyElement>& elements, std::string_view body, long long vertices,
                             bool swap) {
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
        return shortOf(e, static_cast<long long>(left / row), true);
      at += row * static_cast<std::size_t>(e.count);
      continue;
    }
    for (long long r = 0; r < e.count; ++r)
      for (const auto& p : e.properties) {
        if (!p.list) {
          if (body.size() - at < static_cast<std::size_t>(p.valueBytes)) return shortOf(e, r, true);
          at += static_cast<std::size_t>(p.valueBytes);
          continue;
        }
        if (body.size() - at < static_cast<std::size_t>(p.countBytes)) return shortOf(e, r, true);
        const double n = read(p.countBytes, p.countSigned, false);
        if (n < 0 || n > kMaxFaceCorners)
          return "its " + e.name + " " + num(static_cast<double>(r)) + " has a list of " + num(n) + " values (at most " +
                 num(kMaxFaceCorners) + ")";
        if (isIndexList(e, p) && n < 3)
          return "its " + e.name + " " + num(static_cast<double>(r)) + " has " + num(n) + " corners; a face needs 3 or more";
        const std::size_t need = static_cast<std::size_t>(n) * static_cast<std::size_t>(p.valueBytes);
        if (body.size() - at < need) return shortOf(e, r, true);
        if (!isIndexList(e, p)) {
          at += need;
          continue;
        }
        for (int k = 0; k < static_cast<int>(n); ++k) {
          const double index = read(p.valueBytes, p.valueSigned, p.valueFloat);
          if (!(index >= 0 && index < static_cast<double>(vertices))) return badIndex(e, r, index, vertices);
        }
      }
  }
  return {};
}

}  // namespace

std::string plyProblem(std::string_view bytes) {
  std::size_t pos = 0;
  std::string_view line;
  // A .ply whose first line is not "ply", or whose header holds a line that is not PLY, is refused here: assimp took
  // such headers and looped seeking through the file (found by fuzzing).
  if (!nextLine(bytes, pos, line) || trim(line) != "ply") return "its first line is not 'ply'";
  std::vector<PlyElement> elements;
  int format = -1;  // 0 ascii, 1 little endian, 2 big endian
  if (auto problem = plyHeaderProblem(bytes, pos, elements, format); !problem.empty()) return problem;
  long long vertices = 0;
  for (const auto& e : elements)
    if (e.name == "vertex") vertices = e.count;
  const std::string_view body = bytes.substr(std::min(pos, bytes.size()));
  if (format == 0) return plyAsciiProblem(elements, body, vertices);
  const bool swap = (format == 2) != (std::endian::native == std::endian::big);
  return plyBinaryProblem(elements, body, vertices, swap);
}

}  // namespace rehearse::simcore::checks
