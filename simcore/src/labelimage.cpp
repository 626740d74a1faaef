// Label images: the format dispatch, colour tables and the checks every reader shares (ITK's side is
// labelimage_itk.cpp, CGAL's labelimage_cgal.cpp).
#include <rehearse/simcore/labelimage.hpp>

#include "labelimage_raw.hpp"

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

namespace rehearse::simcore {

LabelImage readInrLabelImage(const std::string& path, std::size_t maxVoxels);  // labelimage_cgal.cpp

namespace {

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

constexpr const char* kExtensions[] = {".nii.gz", ".inr.gz", ".nrrd", ".nhdr", ".nii", ".mha", ".mhd", ".inr"};

std::string fileName(const std::string& path) { return std::filesystem::path(path).filename().string(); }

// The path without its image extension: "ct.seg.nrrd" -> "ct.seg", "a.nii.gz" -> "a".
std::string stemOf(const std::string& path) {
  const std::string l = lower(path);
  for (const char* ext : kExtensions)
    if (endsWith(l, ext)) return path.substr(0, path.size() - std::string(ext).size());
  return path;
}

LabelImage fromRaw(detail::RawLabelImage raw, const std::string& name) {
  LabelImage image;
  image.size = raw.size;
  for (int d = 0; d < 3; ++d) {
    image.spacing[d] = raw.spacingMm[d] * 1e-3;
    image.origin[d] = raw.originMm[d] * 1e-3;
    for (int r = 0; r < 3; ++r) image.direction(r, d) = raw.direction[r * 3 + d];
  }
  image.labels = std::move(raw.labels);
  image.names = std::move(raw.names);
  image.format = raw.format;
  image.notes = std::move(raw.notes);
  image.frame = "LPS";
  if (!(image.spacing.minCoeff() > 0) || !image.spacing.allFinite())
    throw MeshError(name + " has a voxel size of zero or less; its header is damaged.");
  if (!image.origin.allFinite()) throw MeshError(name + "'s origin is not a number; its header is damaged.");
  if (!image.direction.allFinite() ||
      (image.direction.transpose() * image.direction - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3)
    throw MeshError(name + "'s axes are not perpendicular (a sheared image); resample it first.");
  return image;
}

// ITK's NIfTI reader makes the image's axes orthonormal with an SVD that never returns on a matrix of huge or
// non-finite values (a damaged sform or pixdim: LINPACK's loop does not converge). The header's geometry is checked
// here first, NIfTI-1 and NIfTI-2, either byte order, through zlib for .nii.gz; what ITK would reject on its own is
// left to it.
void checkNiftiGeometry(const std::string& path, const std::string& name) {
  unsigned char h[540] = {};
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) return;
  const int got = gzread(f, h, sizeof h);
  gzclose(f);
  // Where the geometry lies in each version: header size, bytes of a real and of a form code, offsets of pixdim[0],
  // qform_code (sform_code follows it), quatern_b, qoffset_x and srow_x[0] (the NIfTI-1 and NIfTI-2 layouts).
  struct Layout {
    int size, real, code, pixdim, qform, quatern, offset, srow;
  };
  // A number of `bytes` at `at`, in the file's byte order (swapped when it is not this machine's).
  auto number = [&h](int at, int bytes, bool swap, bool integer) -> double {
    unsigned char b[8];
    std::memcpy(b, h + at, static_cast<std::size_t>(bytes));
    if (swap) std::reverse(b, b + bytes);
    if (integer) {
      std::int32_t i32 = 0;
      std::int16_t i16 = 0;
      return bytes == 4 ? (std::memcpy(&i32, b, 4), i32) : (std::memcpy(&i16, b, 2), i16);
    }
    float f32 = 0;
    double f64 = 0;
    return bytes == 4 ? (std::memcpy(&f32, b, 4), static_cast<double>(f32)) : (std::memcpy(&f64, b, 8), f64);
  };
  for (const Layout& v : {Layout{348, 4, 2, 76, 252, 256, 268, 280}, Layout{540, 8, 4, 104, 344, 352, 376, 400}})
    for (bool swap : {false, true}) {
      if (got < v.size || number(0, 4, swap, true) != v.size) continue;
      auto reals = [&](int at, int n) {
        std::vector<double> r;
        for (int k = 0; k < n; ++k) r.push_back(number(at + k * v.real, v.real, swap, false));
        return r;
      };
      // Millimetres: a voxel or an offset beyond 100 m, or a quaternion component beyond 1, is damage, not anatomy.
      auto fine = [](const std::vector<double>& values, double limit) {
        return std::all_of(values.begin(), values.end(),
                           [limit](double x) { return std::isfinite(x) && std::abs(x) <= limit; });
      };
      const bool qform = number(v.qform, v.code, swap, true) > 0,
                 sform = number(v.qform + v.code, v.code, swap, true) > 0;
      if (!fine(reals(v.pixdim + v.real, 3), 1e5) ||
          (qform && (!fine(reals(v.quatern, 3), 1.001) || !fine(reals(v.offset, 3), 1e5))) ||
          (sform && !fine(reals(v.srow, 12), 1e5)))
        throw MeshError(name +
                        "'s header is damaged: its voxel size or orientation holds values that are not numbers "
                        "or far too large.");
      return;
    }
  // Not a NIfTI header: ITK says so.
}

// MetaIO (ITK's MetaImage reader) reads fields sized by the header's NDims before it checks it: a damaged
// "NDims = 399999999" kept it busy for minutes (a TransformMatrix of NDims x NDims values). The count is checked here
// first; MetaIO itself handles at most 10 dimensions.
void checkMetaImageHeader(const std::string& path, const std::string& name) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::size_t read = 0;
  auto trim = [](std::string t) {
    while (!t.empty() && std::isspace(static_cast<unsigned char>(t.back()))) t.pop_back();
    std::size_t b = 0;
    while (b < t.size() && std::isspace(static_cast<unsigned char>(t[b]))) ++b;
    return t.substr(b);
  };
  while (read < 65536 && std::getline(in, line)) {
    read += line.size() + 1;
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
    if (key == "NDims") {
      char* end = nullptr;
      const long n = std::strtol(value.c_str(), &end, 10);
      if (end == value.c_str() || n < 1 || n > 10)
        throw MeshError(name + "'s header is damaged: NDims = " + value.substr(0, 24) +
                        " (a label image has 3 dimensions).");
    }
    if (key == "ElementDataFile") break;  // the voxels follow
  }
}

}  // namespace

std::vector<int> unmeshedLabels(const LabelImage& image, const LabelMeshOptions& options, const Mesh& mesh) {
  std::set<int> wanted(options.only.begin(), options.only.end());
  if (wanted.empty())
    for (const auto& [label, count] : image.labelCounts()) wanted.insert(label);
  for (int label : mesh.tetLabels) wanted.erase(label);
  return {wanted.begin(), wanted.end()};
}

std::string describeLabel(const LabelImage& image, int label) {
  auto it = image.names.find(label);
  return "label " + std::to_string(label) + (it != image.names.end() ? " (" + it->second + ")" : std::string());
}

std::map<int, long> LabelImage::labelCounts() const {
  std::map<int, long> counts;
  for (std::int32_t l : labels)
    if (l != 0) ++counts[l];
  return counts;
}

bool isLabelImagePath(const std::string& path) {
  const std::string l = lower(path);
  for (const char* ext : kExtensions)
    if (endsWith(l, ext)) return true;
  return false;
}

std::map<int, std::string> parseColourTable(const std::string& text) {
  std::map<int, std::string> names;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    const auto quote = line.find('"');
    if (auto hash = line.find('#'); hash != std::string::npos && (quote == std::string::npos || hash < quote))
      line = line.substr(0, hash);  // a comment ('#' inside a quoted ITK-SNAP name is part of the name)
    std::istringstream fields(line);
    long value = 0;
    if (!(fields >> value) || value <= 0 || value > std::numeric_limits<std::int32_t>::max()) continue;
    std::string name;
    if (quote != std::string::npos && quote < line.size()) {
      const auto end = line.find('"', quote + 1);
      if (end == std::string::npos) continue;
      name = line.substr(quote + 1, end - quote - 1);  // ITK-SNAP: IDX R G B A VIS MSH "NAME"
    } else if (!(fields >> name)) {
      continue;  // 3D Slicer: VALUE NAME R G B A
    } else {
      for (auto& c : name)
        if (c == '_') c = ' ';  // Slicer's names cannot hold spaces
    }
    while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) name.pop_back();
    if (name.empty() || name.size() > 200) continue;
    names[static_cast<int>(value)] = name;
  }
  return names;
}

LabelImage readLabelImage(const std::string& path, const std::string& colourTable, std::size_t maxVoxels) {
  const std::string name = fileName(path);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw MeshError("Cannot read " + path + ": no such file.");
  if (!isLabelImagePath(path))
    throw MeshError(name +
                    " is not a label image this program reads (NRRD .nrrd/.nhdr, NIfTI .nii/.nii.gz, "
                    "MetaImage .mha/.mhd, INR .inr/.inr.gz).");
  if (!colourTable.empty() && !std::filesystem::is_regular_file(colourTable, ec))
    throw MeshError("Cannot read the colour table " + colourTable + ": no such file.");
  LabelImage image;
  const std::string l = lower(path);
  if (endsWith(l, ".inr") || endsWith(l, ".inr.gz")) {
    image = readInrLabelImage(path, maxVoxels);
  } else {
    // Headers that would keep ITK's readers busy for minutes are refused first (the rest is ITK's to judge).
    if (endsWith(l, ".nii") || endsWith(l, ".nii.gz")) checkNiftiGeometry(path, name);
    if (endsWith(l, ".mha") || endsWith(l, ".mhd")) checkMetaImageHeader(path, name);
    try {
      image = fromRaw(detail::itkReadLabelImage(path, maxVoxels), name);
    } catch (const detail::LabelImageError& e) {
      throw MeshError(e.what());
    }
  }
  const auto counts = image.labelCounts();
  if (counts.empty())
    throw MeshError(name + " has no labelled voxel (every voxel is background, 0); there is nothing to mesh.");
  // A colour table: the one given, else one beside the image.
  std::string table = colourTable;
  if (table.empty()) {
    const std::string stem = stemOf(path);
    std::vector<std::string> candidates = {stem + ".ctbl", stem + "_ColorTable.ctbl", stem + ".txt", stem + ".label"};
    if (endsWith(lower(stem), ".seg")) candidates.push_back(stem.substr(0, stem.size() - 4) + ".ctbl");
    for (const auto& c : candidates)
      if (std::filesystem::is_regular_file(c, ec)) {
        table = c;
        break;
      }
  }
  if (!table.empty()) {
    std::ifstream in(table, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    if (text.str().size() > (16u << 20))
      throw MeshError("The colour table " + fileName(table) + " is over 16 MB; it is not one.");
    const auto names = parseColourTable(text.str());
    int used = 0;
    for (const auto& [label, count] : counts)
      if (auto it = names.find(label); it != names.end()) {
        image.names[label] = it->second;
        ++used;
      }
    image.notes.push_back("Labels named from the colour table " + fileName(table) + " (" + std::to_string(used) +
                          " of the image's " + std::to_string(counts.size()) + " labels).");
  }
  return image;
}

void writeLabelImage(const LabelImage& image, const std::string& path) {
  detail::RawLabelImage raw;
  raw.size = image.size;
  for (int d = 0; d < 3; ++d) {
    raw.spacingMm[d] = image.spacing[d] * 1e3;
    raw.originMm[d] = image.origin[d] * 1e3;
    for (int r = 0; r < 3; ++r) raw.direction[r * 3 + d] = image.direction(r, d);
  }
  raw.labels = image.labels;
  try {
    detail::itkWriteLabelImage(raw, path);
  } catch (const detail::LabelImageError& e) {
    throw MeshError(e.what());
  }
}

}  // namespace rehearse::simcore
