// Checks of our own on input files before assimp, ITK or cv::FileStorage read them (see input_checks.hpp): the shared
// text helpers, OFF, OBJ, NRRD, MetaImage and OpenCV calibrations (PLY and glTF have files of their own).
#include <rehearse/simcore/input_checks.hpp>

#include "input_checks_parts.hpp"

#include <tinyxml2.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <set>
#include <vector>

namespace rehearse::simcore::checks {
namespace detail {

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

}  // namespace detail

using namespace detail;

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
    // MetaIO ends a name at '=' or ':' or at a line end, '\r' included, and then takes the value after the next '=' or
    // ':' wherever it comes (found by fuzzing: "CompressedDataSize \r~= 1e30" was CompressedDataSize = 1e30 to it, a
    // field of another name here, and it asked for 2^63 bytes). A field checked below whose name ends at a carriage
    // return or at its line's end is damage; other lines without '=' are passed over, as before.
    const std::size_t eq = line.find_first_of("=:");
    {
      const std::string_view head = line.substr(0, eq == std::string_view::npos ? line.size() : eq);
      const std::string_view cut = trim(head.substr(0, head.find('\r')));
      static const std::set<std::string_view> checked = {
          "NDims",          "DimSize",         "ElementType",        "ElementDataFile", "CompressedData",
          "CompressedDataSize", "HeaderSize",  "ElementSpacing",     "ElementSize",     "ElementNumberOfChannels"};
      if (checked.count(cut) && (eq == std::string_view::npos || cut.size() != trim(head).size()))
        return "its field " + std::string(cut) + " has no '=' on its line (its value would be read from further on)";
    }
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
    std::string_view value = line.substr(eq);  // after the separators and blanks, as MetaIO's value
    value.remove_prefix(std::min(value.size(), value.find_first_not_of("=: \t")));
    // ... and copies a string field's value (ObjectType, Comment, ...) into a 255-byte buffer with strcpy too (found
    // by fuzzing: a 256-byte ObjectType aborted in glibc's fortify). Values here are short.
    if (value.size() > 200)
      return "a value of " + num(static_cast<double>(value.size())) + " characters for its field '" +
             std::string(trim(name)).substr(0, 40) + "' (MetaImage values are a few words or numbers)";
    fields[key] = std::string(trim(value));
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
  // MetaIO allocates CompressedDataSize bytes at once, as given (found by fuzzing: "CompressedDataSize = 1e30" asked
  // for 2^63 bytes, a negative one for 2^64 - 5): a whole number of bytes, checked against the file by the reader.
  double compressedBytes = 0;
  if (fields.count("CompressedDataSize")) {
    const std::string& c = fields["CompressedDataSize"];
    if (!toDouble(c, compressedBytes) || !(compressedBytes >= 1) || compressedBytes > 1e15 ||
        compressedBytes != std::floor(compressedBytes))
      return "its CompressedDataSize = " + c.substr(0, 24) + " is not a number of bytes";
  }
  if (layout) {  // (where the voxels are, whatever their type)
    layout->compressedBytes = compressedBytes;
    layout->dataFile = file;
    layout->dataOffset = std::min(pos, bytes.size());
  }
  static const std::map<std::string, int> typeBytes = {
      {"MET_CHAR", 1},  {"MET_UCHAR", 1}, {"MET_SHORT", 2},     {"MET_USHORT", 2},     {"MET_INT", 4},
      {"MET_UINT", 4},  {"MET_LONG", 4},  {"MET_ULONG", 4},     {"MET_LONG_LONG", 8},  {"MET_ULONG_LONG", 8},
      {"MET_FLOAT", 4}, {"MET_DOUBLE", 8}};
  // MetaIO reads the type's name up to the first byte that cannot be in it (found by fuzzing: "MET_UCHAR\xff\xff"
  // was a UCHAR image to it, and unknown here, which skipped the data's checks).
  std::string typeName = fields["ElementType"];
  typeName = typeName.substr(0, typeName.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZ_"));
  auto type = typeBytes.find(typeName);
  if (type == typeBytes.end()) return {};  // MetaIO or ITK refuse the type
  long long channels = 1;
  if (fields.count("ElementNumberOfChannels") && (!toLong(fields["ElementNumberOfChannels"], channels) || channels < 1 || channels > 64))
    return "its ElementNumberOfChannels is not a small positive number";
  if (layout) {
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

namespace {

// The XML storage: its nesting depth, then the XML itself.
std::string calibrationXmlProblem(std::string_view bytes, const std::string& deep) {
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

// The YAML storage: one mapping at column 0, its nesting depth and its flow brackets.
std::string calibrationYamlProblem(std::string_view bytes, const std::string& deep) {
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

}  // namespace

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
  if (xml) return calibrationXmlProblem(bytes, deep);
  return calibrationYamlProblem(bytes, deep);
}

}  // namespace rehearse::simcore::checks
