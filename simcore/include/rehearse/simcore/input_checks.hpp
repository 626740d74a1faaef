#pragma once
// Checks of our own on input files before a third-party reader (assimp, ITK, cv::FileStorage) sees them: those
// readers crash, hang or read garbage on damaged files (issue 60). Plain C++ on bytes, no heavy dependency, so the
// fuzz build compiles them alone (tests/fuzz, target fuzz_input_checks).
//
// Each function returns the empty string when the bytes pass, else what is wrong as a clause that completes
// "<file> is damaged: ..." (e.g. "it declares 2 faces but holds 1").
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

namespace rehearse::simcore::checks {

/// A polygon with more corners than this is refused (assimp's triangulation is quadratic in them).
inline constexpr long kMaxFaceCorners = 1000;
/// glTF node hierarchy: deeper paths, and more mesh instances reached through it, are refused.
inline constexpr int kMaxGltfDepth = 64;
inline constexpr double kMaxGltfInstances = 10000;
/// Triangles (or points, elements) a surface may declare, as kMaxMeshItems in meshio.hpp.
inline constexpr double kMaxSurfaceItems = 20'000'000;
/// Voxel sizes of a medical label image, millimetres.
inline constexpr double kMinVoxelMm = 0.001, kMaxVoxelMm = 100;
/// Camera calibration files (YAML/XML): size and nesting.
inline constexpr std::size_t kMaxCalibrationBytes = std::size_t(1) << 20;
inline constexpr int kMaxCalibrationDepth = 32;

/// PLY (ascii, binary_little_endian, binary_big_endian): the header's element counts against what the body holds,
/// list lengths, and the faces' vertex indices against the vertex count.
std::string plyProblem(std::string_view bytes);
/// OFF: the declared vertex and face counts against the lines present, corners and indices of each face.
std::string offProblem(std::string_view bytes);
/// OBJ: faces with more than kMaxFaceCorners corners.
std::string objProblem(std::string_view bytes);
/// glTF: the JSON (a .gltf's text, or a .glb's JSON chunk): node references, hierarchy depth and cycles, mesh
/// instances and triangles reached through the hierarchy, accessors against buffer views and buffers, and (.glb)
/// index values against the vertex count. `externalBytes(uri)` gives the size of a buffer's external file (-1: it is
/// missing, or not a regular file inside the glTF's folder), checked against the byteLength the buffer declares;
/// without it external buffers are not checked. Embedded (data:) buffers are checked against their decoded size.
std::string gltfProblem(std::string_view bytes, bool binary,
                        const std::function<long long(const std::string& uri)>& externalBytes = nullptr);

/// NRRD header text (a .nrrd up to its blank line, or a whole .nhdr): dimension 3 or 4, sizes, spacings, space
/// directions and origin finite and plausible, a single data file (no pattern or LIST).
std::string nrrdHeaderProblem(std::string_view header);

/// What the MetaImage header says about its voxels' bytes.
struct MetaImageLayout {
  std::string dataFile;             ///< "LOCAL" or a file name relative to the header
  std::size_t dataOffset = 0;       ///< LOCAL: where the voxels start in the file
  long long headerSize = 0;         ///< bytes to skip in the data file; -1: the voxels are its last bytes
  double expectedBytes = 0;         ///< voxels x channels x bytes per value
  bool compressed = false;
  double compressedBytes = 0;       ///< CompressedDataSize when the header gives one (MetaIO allocates it whole)
};
/// MetaImage header (.mha / .mhd): NDims, DimSize, spacing, element type, and ElementDataFile (no '%' pattern, no
/// LIST). Fills `layout` when it passes.
std::string metaImageHeaderProblem(std::string_view bytes, MetaImageLayout* layout);

/// An OpenCV FileStorage file (YAML, or XML when `xml`): size and nesting depth.
std::string calibrationMarkupProblem(std::string_view bytes, bool xml);

}  // namespace rehearse::simcore::checks
