// Mesh file dispatch: size checks, format by extension, validation, unit conversion, repairs.
#include <rehearse/simcore/input_checks.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>

#include "text_reader.hpp"

#include <cstdio>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace rehearse::simcore {

const std::vector<std::string>& supportedMeshExtensions() {
  static const std::vector<std::string> ext = {".msh", ".vtk", ".vtu", ".mesh", ".obj", ".stl",
                                               ".ply", ".off", ".gltf", ".glb"};
  return ext;
}

namespace {
std::string extensionOf(const std::string& path) { return detail::lower(fs::path(path).extension().string()); }

std::string readAll(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw MeshError("The file " + path + " does not exist; check the path.");
  if (fs::is_directory(path, ec)) throw MeshError(path + " is a folder, not a mesh file; choose a file inside it.");
  if (!fs::is_regular_file(path, ec))
    throw MeshError(path + " is not a regular file (a pipe or a device), not a mesh file to read.");
  auto size = fs::file_size(path, ec);
  if (ec) throw MeshError("The file " + path + " cannot be read (" + ec.message() + ").");
  if (size > kMaxMeshFileBytes)
    throw MeshError("The file " + path + " is too large (" + std::to_string(size >> 20) +
                    " MiB, limit 2048 MiB); decimate the mesh first.");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw MeshError("The file " + path + " cannot be opened; check its permissions.");
  std::string bytes(size, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) throw MeshError("The file " + path + " could not be read completely.");
  return bytes;
}
}  // namespace

Mesh loadMesh(const std::string& path, const LoadOptions& options, std::vector<std::string>* notes) {
  const double scale = metresPerUnit(options.unit);
  const std::string ext = extensionOf(path);
  Mesh m;
  const std::string name = fs::path(path).filename().string();
  try {
    if (ext == ".msh") m = parseGmsh(readAll(path));
    else if (ext == ".vtk") m = parseVtkLegacy(readAll(path));
    else if (ext == ".vtu") m = parseVtu(readAll(path));
    else if (ext == ".mesh") m = parseMedit(readAll(path));
    else if (ext == ".obj" || ext == ".stl" || ext == ".ply" || ext == ".off" || ext == ".gltf" || ext == ".glb") {
      // Existence and size checks with our messages, then our own look at the structure: assimp crashes, hangs or
      // silently drops data on damaged files (issue 60).
      const std::string bytes = readAll(path);
      std::string problem;
      // assimp picks its reader by the content when the one the name says refuses it: a PLY named .glb went to its PLY
      // reader past our PLY check (and crashed it: found by fuzzing). The content must be what the name says.
      const std::string_view head(bytes.data(), std::min<std::size_t>(bytes.size(), 8));
      const auto firstText = bytes.find_first_not_of(" \t\r\n\xef\xbb\xbf");
      const std::string holds = head.substr(0, 3) == "ply" && bytes.size() > 3 && (bytes[3] == '\n' || bytes[3] == '\r')
                                    ? ".ply"
                                : head.substr(0, 4) == "glTF" ? ".glb"
                                : firstText != std::string::npos && bytes[firstText] == '{' ? ".gltf"
                                                                                           : "";
      if (ext == ".glb" && holds != ".glb")
        throw MeshError(name + " is not a GLB file (it does not begin with 'glTF'); check that it is complete.");
      if (ext == ".gltf" && holds != ".gltf")
        throw MeshError(name + " is not a glTF file (it does not begin with '{'); check that it is complete.");
      if (!holds.empty() && holds != ext)
        throw MeshError(name + " holds a " + holds.substr(1) + " file but is named " + ext + "; rename it to " + holds +
                        ".");
      if (ext == ".ply") problem = checks::plyProblem(bytes);
      else if (ext == ".off") problem = checks::offProblem(bytes);
      else if (ext == ".obj") problem = checks::objProblem(bytes);
      else if (ext == ".gltf" || ext == ".glb")
        problem = checks::gltfProblem(bytes, ext == ".glb", [&](const std::string& uri) -> long long {
          // A buffer file beside the glTF (or below its folder): not an absolute path, no "..", a regular file (a
          // pipe or a device would block the reader).
          std::string decoded;  // URIs are percent-encoded ("my%20mesh.bin")
          for (std::size_t i = 0; i < uri.size(); ++i) {
            if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
                std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
              decoded += static_cast<char>(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
              i += 2;
            } else {
              decoded += uri[i];
            }
          }
          const fs::path rel(decoded);
          if (decoded.empty() || rel.is_absolute()) return -1;
          for (const auto& part : rel)
            if (part == "..") return -1;
          std::error_code ec;
          const fs::path file = fs::path(path).parent_path() / rel;
          if (!fs::is_regular_file(file, ec)) return -1;
          const auto size = fs::file_size(file, ec);
          return ec ? -1 : static_cast<long long>(size);
        });
      if (!problem.empty())
        throw MeshError(name + " is damaged: " + problem + "; re-export it from the program that made it.");
      m = loadSurfaceAssimp(path);
    } else {
      throw MeshError("The file type '" + ext + "' of " + name +
                      " is not supported; use .msh, .vtk, .vtu, .mesh, .obj, .stl, .ply, .off, .gltf or .glb.");
    }
  } catch (const MeshError& e) {
    std::string w = e.what();
    if (w.rfind("This ", 0) == 0) throw MeshError(name + ": " + w);
    throw;
  } catch (const std::bad_alloc&) {
    throw MeshError(name + " needs more memory than is available; decimate the mesh first.");
  }
  validateMesh(m, name);
  m.unitToMetre = scale;
  m.convertToMetres();
  // No unit makes an organ 10 km across (a file in mm read as metres is at most a few hundred metres, which the import
  // says with the likely unit): a coordinate beyond that is a damaged file, and an overflowing one (1e308) would give
  // infinite bounds downstream.
  for (std::size_t i = 0; i < m.points.size(); ++i)
    if (!m.points[i].allFinite() || m.points[i].cwiseAbs().maxCoeff() > kMaxCoordinateMetres)
      throw MeshError(name + " has a coordinate of " + [&] {
        char b[32];
        std::snprintf(b, sizeof b, "%.3g", m.points[i].cwiseAbs().maxCoeff());
        return std::string(b);
      }() + " m at point " + std::to_string(i) + ", beyond " + std::to_string(static_cast<int>(kMaxCoordinateMetres)) +
                      " m from the origin, which no length unit makes an organ; the file is damaged.");
  const bool volume = m.isVolume();
  auto repairs = repairVolume(m);
  if (notes) notes->insert(notes->end(), repairs.begin(), repairs.end());
  // Checked against what the file held: the repair removes degenerate tetrahedra, and a volume left without any would
  // otherwise pass as a surface of its boundary triangles (or an empty one).
  if (volume && m.tets.empty())
    throw MeshError(name + " has only degenerate tetrahedra (flat or zero volume); re-mesh the volume.");
  return m;
}

void saveMesh(const Mesh& mesh, const std::string& path, bool ascii) {
  const std::string ext = extensionOf(path);
  std::string bytes;
  if (ext == ".msh") bytes = writeGmsh22(mesh);
  else if (ext == ".vtk") bytes = writeVtkLegacy(mesh, ascii);
  else if (ext == ".vtu") bytes = writeVtu(mesh, ascii);
  else if (ext == ".mesh") bytes = writeMedit(mesh);
  else throw MeshError("Cannot write '" + ext + "' files; use .msh, .vtk, .vtu or .mesh.");
  // Write beside the target and rename, so a failure never leaves a half-written file.
  const std::string tmp = path + ".part";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw MeshError("Cannot write " + path + "; check that the folder exists and is writable.");
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw MeshError("Writing " + path + " failed (disk full?); nothing was changed.");
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw MeshError("Cannot replace " + path + " (" + ec.message() + ").");
}

}  // namespace rehearse::simcore
