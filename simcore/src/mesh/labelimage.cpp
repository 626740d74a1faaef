// Label images: the format dispatch, colour tables and the checks every reader shares (ITK's side is
// labelimage_itk.cpp, CGAL's labelimage_cgal.cpp).
#include <rehearse/simcore/input_checks.hpp>
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
#include <vector>

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
void checkNiftiGeometry(const std::string& path, const std::string& name, std::size_t maxVoxels) {
  const bool gz = endsWith(lower(path), ".gz");
  unsigned char h[540] = {};
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) return;  // ITK says it cannot open the file
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
  // The byte order as the NIfTI library decides it (need_nhdr_swap): by dim[0] when it is not 0, by the header size
  // only when it is. A file whose size field reads 348 one way and whose dim[0] reads 1-7 only the other way is read
  // swapped by ITK (found by fuzzing: its geometry, unchecked in that order, reached an SVD that aborts on NaN).
  auto dim0 = [&h](bool nifti1, bool swap) -> long long {
    unsigned char b[8];
    const int bytes = nifti1 ? 2 : 8;
    std::memcpy(b, h + (nifti1 ? 40 : 16), static_cast<std::size_t>(bytes));
    if (swap) std::reverse(b, b + bytes);
    std::int16_t i16 = 0;
    std::int64_t i64 = 0;
    return nifti1 ? (std::memcpy(&i16, b, 2), i16) : (std::memcpy(&i64, b, 8), i64);
  };
  for (const Layout& v : {Layout{348, 4, 2, 76, 252, 256, 268, 280}, Layout{540, 8, 4, 104, 344, 352, 376, 400}})
    for (bool sizeSwap : {false, true}) {
      if (got < v.size || number(0, 4, sizeSwap, true) != v.size) continue;
      const bool one = v.size == 348;
      bool swap = sizeSwap;
      if (const long long d0 = dim0(one, false); d0 != 0) {
        if (d0 >= 1 && d0 <= 7)
          swap = false;
        else if (const long long s0 = dim0(one, true); s0 >= 1 && s0 <= 7)
          swap = true;
        else
          throw MeshError("Cannot read " + name + ": it is not a NIfTI image (its number of dimensions, " +
                          std::to_string(d0) + ", is not 1 to 7 in either byte order).");
      }
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
      // Where the voxels start and how many bytes they take (dim[0..7], bitpix, vox_offset): a truncated file or a
      // vox_offset of 1e12, -100 or NaN was read as garbage or zeros without a word.
      const int dimAt = one ? 40 : 16, dimBytes = one ? 2 : 8, bitpixAt = one ? 72 : 14, voxOffsetAt = one ? 108 : 168;
      const double rank = number(dimAt + (dimBytes == 8 && swap ? 4 : 0), dimBytes == 2 ? 2 : 4, swap, true);
      if (!(rank >= 1 && rank <= 7)) return;  // ITK refuses the dimensions
      double voxels = 1;
      for (int d = 1; d <= static_cast<int>(rank); ++d) {
        // NIfTI-2's dimensions are 64-bit: read the low or high half as the byte order says (sizes below 2^31).
        const int at = dimAt + d * dimBytes + (dimBytes == 8 && swap ? 4 : 0);
        const double n = number(at, dimBytes == 2 ? 2 : 4, swap, true);
        if (!(n >= 1)) return;  // ITK refuses the dimensions
        voxels *= n;
      }
      const double bitpix = number(bitpixAt, 2, swap, true);
      double voxOffset = 0;
      if (one) {
        voxOffset = number(voxOffsetAt, 4, swap, false);
      } else {
        std::int64_t o = 0;
        unsigned char b[8];
        std::memcpy(b, h + voxOffsetAt, 8);
        if (swap) std::reverse(b, b + 8);
        std::memcpy(&o, b, 8);
        voxOffset = static_cast<double>(o);
      }
      std::error_code ec;
      const double fileBytes = static_cast<double>(std::filesystem::file_size(path, ec));
      // A .nii.gz's header is followed by at most a few extensions: an offset past 1 GiB is damage (and would make
      // us inflate a gigabyte to find out).
      if (!std::isfinite(voxOffset) || voxOffset < 0 || voxOffset > (gz ? double(1 << 30) : fileBytes)) {
        char b[32];
        std::snprintf(b, sizeof b, "%.3g", voxOffset);
        throw MeshError(name + "'s header is damaged: its voxels start at byte " + b +
                        ", which is not in the file; re-export the image.");
      }
      if (!(bitpix >= 8) || voxels > static_cast<double>(maxVoxels)) return;  // ITK refuses, with our message
      const double needed = voxOffset + voxels * bitpix / 8;
      double held = fileBytes;
      if (gz) {
        // Decompressed bytes, counted in a stream and no further than needed (a hostile .nii.gz may inflate to
        // terabytes).
        held = 0;
        gzFile z = gzopen(path.c_str(), "rb");
        if (!z) return;
        std::vector<char> chunk(1 << 16);
        int n = 0;
        while (held < needed && (n = gzread(z, chunk.data(), static_cast<unsigned>(chunk.size()))) > 0) held += n;
        const bool broken = n < 0;
        gzclose(z);
        if (broken)
          throw MeshError(name + "'s compressed data is damaged (zlib cannot inflate it); re-export the image.");
      }
      if (held < needed) {
        char share[32];
        std::snprintf(share, sizeof share, "%.1f", std::max(0.0, held - voxOffset) / (needed - voxOffset) * 100);
        throw MeshError(name + " is truncated: it holds " + share + " % of its voxels' bytes; copy the whole file again.");
      }
      return;
    }
  // ITK's NIfTI library reads headers whose size field is neither (found by fuzzing: a size of 16220 with a NaN in
  // its sform reached an assertion in ITK's SVD, SIGABRT); the standard fixes it at 348 or 540, so nothing else is read.
  if (got < 0)
    throw MeshError("Cannot read " + name + ": its compressed data is damaged (zlib cannot inflate it); re-export the "
                    "image.");
  if (got < 348)
    throw MeshError("Cannot read " + name + ": it is not a NIfTI image (it holds " + std::to_string(std::max(got, 0)) +
                    " bytes, fewer than a NIfTI header's 348).");
  throw MeshError("Cannot read " + name + ": it is not a NIfTI image (its header does not begin with a NIfTI-1 or "
                  "NIfTI-2 header size, 348 or 540 bytes in either byte order).");
}

// MetaIO (ITK's MetaImage reader) trusts its header: NDims sized fields before it was checked (a damaged
// "NDims = 399999999" kept it busy for minutes), a '%' pattern in ElementDataFile went to snprintf as a format
// (SIGSEGV), and a truncated, missing or undecodable data file was meshed from uninitialised memory. The header
// (checks::metaImageHeaderProblem) and the bytes of the voxels are checked here first.
void checkMetaImageHeader(const std::string& path, const std::string& name) {
  std::ifstream in(path, std::ios::binary);
  std::string head(65536 + 4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  checks::MetaImageLayout layout;
  if (const std::string p = checks::metaImageHeaderProblem(head, &layout); !p.empty())
    throw MeshError(name + "'s header is damaged: " + p + ".");
  if (layout.dataFile.empty()) return;  // MetaIO says what is missing
  const bool local = layout.dataFile == "LOCAL";
  const std::filesystem::path data =
      local ? std::filesystem::path(path) : std::filesystem::path(path).parent_path() / layout.dataFile;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(data, ec))
    throw MeshError(name + "'s data file " + data.filename().string() + " is missing or not a file; keep it beside the header.");
  const double size = static_cast<double>(std::filesystem::file_size(data, ec));
  double offset = local ? static_cast<double>(layout.dataOffset) : 0;
  if (layout.compressedBytes > size - offset)
    throw MeshError(name + "'s header is damaged: its CompressedDataSize declares " +
                    std::to_string(static_cast<long long>(layout.compressedBytes)) + " bytes, more than the " +
                    std::to_string(static_cast<long long>(std::max(0.0, size - offset))) + " its data file holds.");
  if (layout.expectedBytes <= 0) return;  // a type MetaIO or ITK refuse
  if (layout.headerSize > 0) offset += static_cast<double>(layout.headerSize);
  if (layout.headerSize == -1) offset = std::max(offset, size - layout.expectedBytes);  // the voxels are the last bytes
  auto truncated = [&](double held) {
    char share[32];
    std::snprintf(share, sizeof share, "%.1f", std::max(0.0, held) / layout.expectedBytes * 100);
    return MeshError(name + " is truncated: its data hold " + share + " % of the voxels' bytes its header declares; copy "
                     "the whole file again.");
  };
  if (!layout.compressed) {
    if (size - offset < layout.expectedBytes) throw truncated(size - offset);
    return;
  }
  // Inflated here, in a stream, counting the bytes and stopping past the expected size.
  std::ifstream raw(data, std::ios::binary);
  raw.seekg(static_cast<std::streamoff>(offset));
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) return;  // zlib or gzip
  std::vector<unsigned char> input(1 << 16), output(1 << 16);
  double produced = 0;
  int status = Z_OK;
  while (status == Z_OK && produced <= layout.expectedBytes) {
    if (z.avail_in == 0) {
      raw.read(reinterpret_cast<char*>(input.data()), static_cast<std::streamsize>(input.size()));
      z.avail_in = static_cast<uInt>(raw.gcount());
      z.next_in = input.data();
      if (z.avail_in == 0) break;
    }
    z.next_out = output.data();
    z.avail_out = static_cast<uInt>(output.size());
    status = inflate(&z, Z_NO_FLUSH);
    produced += static_cast<double>(output.size() - z.avail_out);
  }
  inflateEnd(&z);
  if (status != Z_OK && status != Z_STREAM_END)
    throw MeshError(name + "'s compressed data is damaged (zlib cannot inflate it); re-export the image.");
  if (produced > layout.expectedBytes)
    throw MeshError(name + "'s compressed data hold more bytes than its header declares; re-export the image.");
  if (status != Z_STREAM_END || produced < layout.expectedBytes) throw truncated(produced);
}

// ITK's NRRD reader smashed its stack on "dimension: 10", read a NaN spacing as 1 mm and followed data-file patterns
// of two billion files: the header is checked here first (checks::nrrdHeaderProblem).
void checkNrrdHeader(const std::string& path, const std::string& name) {
  std::ifstream in(path, std::ios::binary);
  std::string head(65536, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  if (const std::string p = checks::nrrdHeaderProblem(head); !p.empty())
    throw MeshError(name + "'s header is damaged: " + p + ".");
}

// Every format (CGAL's INR too): a voxel outside 0.001-100 mm is a damaged header or another unit, and CGAL's mesher
// never finished on 1e300 or 1e-300 mm.
void checkVoxelSize(const LabelImage& image, const std::string& name) {
  for (int d = 0; d < 3; ++d) {
    const double mm = image.spacing[d] * 1e3;
    if (!(mm >= checks::kMinVoxelMm && mm <= checks::kMaxVoxelMm)) {
      char b[32];
      std::snprintf(b, sizeof b, "%.3g", mm);
      throw MeshError(name + " has a voxel size of " + b + " mm; a medical image's lies between 0.001 and 100 mm, so its "
                      "header is damaged.");
    }
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
    if (endsWith(l, ".nii") || endsWith(l, ".nii.gz")) checkNiftiGeometry(path, name, maxVoxels);
    if (endsWith(l, ".mha") || endsWith(l, ".mhd")) checkMetaImageHeader(path, name);
    if (endsWith(l, ".nrrd") || endsWith(l, ".nhdr")) checkNrrdHeader(path, name);
    try {
      image = fromRaw(detail::itkReadLabelImage(path, maxVoxels), name);
    } catch (const detail::LabelImageError& e) {
      throw MeshError(e.what());
    }
  }
  const auto counts = image.labelCounts();
  if (counts.empty())
    throw MeshError(name + " has no labelled voxel (every voxel is background, 0); there is nothing to mesh.");
  checkVoxelSize(image, name);
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
    // The size first: the table used to be read whole before this check.
    if (std::filesystem::file_size(table, ec) > (16u << 20) || ec)
      throw MeshError("The colour table " + fileName(table) + " is over 16 MB or unreadable; it is not one.");
    std::ifstream in(table, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
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
