#pragma once
// What both bodies are built on (fembody.cpp, precomputedbody.cpp): the setup's mesh in metres with its rest positions.
#include <rehearse/simcore/session/body.hpp>

#include <string>

namespace rehearse::simcore {

/// The setup's mesh in metres, its points replaced by the rest positions when given. Throws MeshError when their
/// count does not match the mesh's.
inline Mesh restMesh(const BodySetup& s) {
  Mesh mesh = s.mesh;
  mesh.convertToMetres();
  if (!s.rest.empty()) {
    if (s.rest.size() != mesh.points.size())
      throw MeshError("The body's rest positions (" + std::to_string(s.rest.size()) + ") do not match its mesh (" +
                      std::to_string(mesh.points.size()) + " nodes).");
    mesh.points = s.rest;
  }
  return mesh;
}

}  // namespace rehearse::simcore
