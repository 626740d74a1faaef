// libFuzzer entry point for the surface readers as a user reaches them (simcore::loadMesh): our structure checks
// (input_checks.hpp), then assimp 5.2 (not instrumented) with its data structure validated, in a child process
// (isolated.hpp): a crash of assimp's there is a refusal of the file; a crash, a hang or a leak of this process is a
// finding. The first byte chooses the format (PLY, OFF, OBJ, glTF, GLB); the rest is the file. A refusal
// (MeshError) is the expected outcome of most inputs; a crash, a hang or any other exception is a finding.
#include <rehearse/simcore/meshio.hpp>

#include "fuzz_file.hpp"

#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  readAsFile(data, size, {".ply", ".off", ".obj", ".gltf", ".glb"}, "surface", [](const std::string& path) {
    try {
      rehearse::simcore::loadMesh(path);
    } catch (const rehearse::simcore::MeshError&) {
    }
  });
  return 0;
}
