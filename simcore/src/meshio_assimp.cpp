// Surfaces through assimp: each mesh instance in the node hierarchy becomes a labelled part, with the
// node transforms applied (glTF files often scale at the node level).
#include <rehearse/simcore/meshio.hpp>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <map>

namespace rehearse::simcore {
namespace {

void collect(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent, Mesh& m) {
  const aiMatrix4x4 transform = parent * node->mTransformation;
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
  for (unsigned c = 0; c < node->mNumChildren; ++c) collect(scene, node->mChildren[c], transform, m);
}

}  // namespace

Mesh loadSurfaceAssimp(const std::string& path) {
  Assimp::Importer importer;
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS, aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS |
                                                          aiComponent_COLORS | aiComponent_TEXCOORDS |
                                                          aiComponent_BONEWEIGHTS | aiComponent_ANIMATIONS |
                                                          aiComponent_TEXTURES | aiComponent_LIGHTS |
                                                          aiComponent_CAMERAS | aiComponent_MATERIALS);
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* scene = importer.ReadFile(
      path, aiProcess_RemoveComponent | aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_SortByPType);
  if (!scene || !scene->mRootNode)
    throw MeshError("This surface file cannot be read: " + std::string(importer.GetErrorString()) +
                    "; check that the file is complete and in the format its extension says.");
  Mesh m;
  collect(scene, scene->mRootNode, aiMatrix4x4(), m);
  return m;
}

}  // namespace rehearse::simcore
