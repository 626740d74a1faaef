#pragma once
// Reading and writing meshes. Volumes: Gmsh MSH v1/v2.2/v4.1 (ascii and binary), VTK legacy
// (ascii and binary, POLYDATA and UNSTRUCTURED_GRID), VTK XML .vtu, Medit .mesh.
// Surfaces: OBJ, STL, PLY, OFF, glTF/GLB through assimp, plus VTK legacy POLYDATA.
#include <rehearse/simcore/mesh.hpp>

#include <cstdint>
#include <string>
#include <string_view>

namespace rehearse::simcore {

/// Refuse files above this size before reading them (bytes).
inline constexpr std::uintmax_t kMaxMeshFileBytes = std::uintmax_t(2) << 30;
/// Refuse meshes with more points or elements than this.
inline constexpr std::size_t kMaxMeshItems = 20'000'000;
/// Refuse meshes with a coordinate farther than this from the origin, after unit conversion (metres).
inline constexpr double kMaxCoordinateMetres = 1e4;

struct LoadOptions {
  std::string unit = "m";  // length unit of the file's coordinates ("m", "dm", "cm", "mm")
};

/// Load any supported mesh; coordinates are converted to metres using options.unit.
/// Throws MeshError with one sentence on any problem (never crashes on bad files). Repairs made on
/// import (inverted or flat tetrahedra) are described, one sentence each, in `notes`.
Mesh loadMesh(const std::string& path, const LoadOptions& options = {}, std::vector<std::string>* notes = nullptr);

/// File extensions loadMesh accepts (lower case, with the dot).
const std::vector<std::string>& supportedMeshExtensions();

/// Write a volume mesh: .msh (Gmsh 2.2 ascii), .vtk (legacy, binary unless ascii), .vtu (XML).
/// Coordinates are written in metres. Throws MeshError on failure.
void saveMesh(const Mesh& mesh, const std::string& path, bool ascii = false);

// Parsers on in-memory bytes (used by loadMesh and by the fuzz targets). Coordinates as in the file.
Mesh parseGmsh(std::string_view bytes);
Mesh parseVtkLegacy(std::string_view bytes);
Mesh parseVtu(std::string_view bytes);
Mesh parseMedit(std::string_view bytes);

std::string writeGmsh22(const Mesh& mesh);
std::string writeVtkLegacy(const Mesh& mesh, bool ascii);
std::string writeVtu(const Mesh& mesh, bool ascii);
std::string writeMedit(const Mesh& mesh);

/// Surfaces through assimp (OBJ, STL, PLY, OFF, glTF, GLB); each mesh of the file becomes a part
/// (triangle label = part index, named after the node or mesh). Coordinates as in the file.
Mesh loadSurfaceAssimp(const std::string& path);

/// Check a freshly parsed mesh: non-empty, finite, indices in range, sizes bounded.
/// Throws MeshError with one sentence. `what` names the file for the message.
void validateMesh(const Mesh& mesh, const std::string& what);

}  // namespace rehearse::simcore
