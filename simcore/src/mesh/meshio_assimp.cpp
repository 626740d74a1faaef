// Surfaces through assimp: each mesh instance in the node hierarchy becomes a labelled part, with the
// node transforms applied (glTF files often scale at the node level).
#include <rehearse/simcore/meshio.hpp>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <rehearse/simcore/isolated.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <new>
#include <string_view>
#include <map>
#include <utility>
#include <vector>

namespace rehearse::simcore {
namespace {

// The largest surface we accept (kMaxSurfaceItems) reads in well under a minute; a reader still busy after this is
// stuck on a damaged file.
constexpr double kSurfaceReadSeconds = 300;

// One node's meshes, with its accumulated transform.
void collectNode(const aiScene* scene, const aiNode* node, const aiMatrix4x4& transform, Mesh& m) {
  for (unsigned i = 0; i < node->mNumMeshes; ++i) {
    const aiMesh* mesh = scene->mMeshes[node->mMeshes[i]];
    if (!(mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    const int label = static_cast<int>(m.labelNames.size());
    std::string name = node->mName.length ? node->mName.C_Str() : mesh->mName.C_Str();
    if (name.empty()) name = "part " + std::to_string(label);
    m.setLabelName(label, name);
    // Weld exactly coincident vertices (STL stores each triangle's corners separately).
    std::map<std::array<double, 3>, int> weld;
    std::vector<int> index(mesh->mNumVertices);
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      aiVector3D p = transform * mesh->mVertices[v];
      // Before the weld: a NaN key compares equal to any other in the map, so a "v nan nan nan" was merged into another
      // point, its triangles dropped as degenerate, and the file imported with a hole and no word (a person's check).
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw MeshError("This surface file has a non-finite coordinate (NaN or infinity) at vertex " + std::to_string(v) +
                        " of its part '" + std::string(mesh->mName.C_Str()).substr(0, 60) + "'; the file is damaged.");
      std::array<double, 3> key = {p.x, p.y, p.z};
      auto [it, inserted] = weld.emplace(key, static_cast<int>(m.points.size()));
      if (inserted) m.points.emplace_back(p.x, p.y, p.z);
      index[v] = it->second;
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;
      std::array<int, 3> t{};
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        if (face.mIndices[k] >= mesh->mNumVertices) ok = false;
        else t[k] = index[face.mIndices[k]];
      }
      if (!ok || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
      m.triangles.push_back(t);
      m.triangleLabels.push_back(label);
    }
  }
}

// Every node of the hierarchy, without recursion (a damaged file's 20,000-deep chain overflowed the stack), and
// at most kMaxNodeVisits of them (our glTF check bounds instances first; this bounds any other format).
void collect(const aiScene* scene, Mesh& m) {
  constexpr std::size_t kMaxNodeVisits = 1'000'000;
  std::vector<std::pair<const aiNode*, aiMatrix4x4>> todo = {{scene->mRootNode, scene->mRootNode->mTransformation}};
  std::size_t visits = 0;
  while (!todo.empty()) {
    auto [node, transform] = todo.back();
    todo.pop_back();
    if (++visits > kMaxNodeVisits)
      throw MeshError("This surface file's node hierarchy has more than a million nodes; flatten it first.");
    collectNode(scene, node, transform, m);
    for (unsigned c = node->mNumChildren; c-- > 0;)
      todo.emplace_back(node->mChildren[c], transform * node->mChildren[c]->mTransformation);
  }
}

// The mesh through the pipe from the child: counts, then the arrays as they lie in memory (the same program on both
// ends), then the part names.
template <typename T>
void put(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}
template <typename T>
void putArray(std::string& out, const std::vector<T>& v) {
  put(out, static_cast<std::uint64_t>(v.size()));
  if (!v.empty()) out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}
std::string encode(const Mesh& m) {
  std::string out;
  putArray(out, m.points);
  putArray(out, m.triangles);
  putArray(out, m.triangleLabels);
  put(out, static_cast<std::uint64_t>(m.labelNames.size()));
  for (const auto& [label, name] : m.labelNames) {
    put(out, static_cast<std::int64_t>(label));
    put(out, static_cast<std::uint64_t>(name.size()));
    out += name;
  }
  return out;
}
struct Reader {
  std::string_view in;
  std::size_t at = 0;
  template <typename T>
  T get() {
    if (in.size() - at < sizeof(T)) throw MeshError("This surface file's reader returned a damaged mesh.");
    T v;
    std::memcpy(&v, in.data() + at, sizeof v);
    at += sizeof v;
    return v;
  }
  template <typename T>
  void getArray(std::vector<T>& v) {
    const auto n = get<std::uint64_t>();
    if (n > (in.size() - at) / sizeof(T)) throw MeshError("This surface file's reader returned a damaged mesh.");
    v.resize(n);
    if (n > 0) std::memcpy(static_cast<void*>(v.data()), in.data() + at, n * sizeof(T));
    at += n * sizeof(T);
  }
};
Mesh decode(std::string_view bytes) {
  Mesh m;
  Reader r{bytes};
  r.getArray(m.points);
  r.getArray(m.triangles);
  r.getArray(m.triangleLabels);
  const auto names = r.get<std::uint64_t>();
  for (std::uint64_t i = 0; i < names; ++i) {
    const auto label = r.get<std::int64_t>();
    const auto size = r.get<std::uint64_t>();
    if (size > bytes.size() - r.at) throw MeshError("This surface file's reader returned a damaged mesh.");
    m.labelNames.emplace_back(static_cast<int>(label), std::string(bytes.substr(r.at, size)));
    r.at += size;
  }
  return m;
}

Mesh readInThisProcess(const std::string& path) {
  Assimp::Importer importer;
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS, aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS |
                                                          aiComponent_COLORS | aiComponent_TEXCOORDS |
                                                          aiComponent_BONEWEIGHTS | aiComponent_ANIMATIONS |
                                                          aiComponent_TEXTURES | aiComponent_LIGHTS |
                                                          aiComponent_CAMERAS | aiComponent_MATERIALS);
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* scene = importer.ReadFile(
      // ValidateDataStructure first: assimp's own check of what the importer built (face indices beyond the vertex
      // count crashed the later steps).
      path, aiProcess_ValidateDataStructure | aiProcess_RemoveComponent | aiProcess_Triangulate |
                aiProcess_JoinIdenticalVertices | aiProcess_SortByPType);
  if (!scene || !scene->mRootNode) {
    // assimp's validation speaks of its own structures ("aiScene::mNumMeshes is 0"): said in the file's terms.
    const std::string error = importer.GetErrorString();
    std::error_code ec;
    if (std::filesystem::file_size(path, ec) == 0 && !ec)
      throw MeshError("This surface file is empty (0 bytes); copy the whole file again.");
    if (error.find("mNumMeshes is 0") != std::string::npos)
      throw MeshError("This surface file holds no surface (no triangles were found in it); check that it is the "
                      "organ's surface and in the format its extension says.");
    // The library's sentence, quoted without its own full stop (it read "OBJ-file is too small.;" here before).
    std::string said = error;
    while (!said.empty() && (said.back() == '.' || said.back() == ' ' || said.back() == '\n')) said.pop_back();
    throw MeshError("This surface file cannot be read (the reader says \u201c" + said +
                    "\u201d); check that the file is complete and in the format its extension says.");
  }
  Mesh m;
  collect(scene, m);
  return m;
}

}  // namespace

Mesh loadSurfaceAssimp(const std::string& path) {
  // assimp 5.2 is not ours to mend and its readers have known memory errors on damaged files (a fuzzing run found one
  // that our checks before it let through): it reads in a child process, and a crash there refuses the file.
  const IsolatedResult r = runIsolated(
      [&] {
        try {
          return encode(readInThisProcess(path));
        } catch (const MeshError&) {
          throw;
        } catch (const std::bad_alloc&) {
          throw MeshError("This surface file needs more memory than is available; decimate the mesh first.");
        } catch (const std::exception& e) {
          throw MeshError(std::string("This surface file cannot be read (") + e.what() +
                          "); check that the file is complete and in the format its extension says.");
        }
      },
      kSurfaceReadSeconds);
  switch (r.status) {
    case IsolatedResult::Status::Done:
      return decode(r.bytes);
    case IsolatedResult::Status::Threw:
      throw MeshError(r.message);
    case IsolatedResult::Status::Crashed:
    case IsolatedResult::Status::TimedOut:
      break;
  }
  throw MeshError("This surface file cannot be read: the reader " + r.message +
                  " on it; check that the file is complete and in the format its extension says (nothing was changed).");
}

}  // namespace rehearse::simcore
