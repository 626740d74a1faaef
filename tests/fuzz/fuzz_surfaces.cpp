// libFuzzer entry point for the surface readers as a user reaches them (simcore::loadMesh): our structure checks
// (input_checks.hpp), then assimp 5.2 (not instrumented: its crashes, hangs and leaks are still findings) with its data
// structure validated. The first byte chooses the format (PLY, OFF, OBJ, glTF, GLB); the rest is the file. A refusal
// (MeshError) is the expected outcome of most inputs; a crash, a hang or any other exception is a finding.
#include <rehearse/simcore/meshio.hpp>

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* extensions[] = {".ply", ".off", ".obj", ".gltf", ".glb"};
  const std::string path =
      "/tmp/fuzz-surface-" + std::to_string(::getpid()) + extensions[data[0] % 5];
  if (FILE* f = std::fopen(path.c_str(), "wb")) {
    std::fwrite(data + 1, 1, size - 1, f);
    std::fclose(f);
  } else {
    return 0;
  }
  try {
    rehearse::simcore::loadMesh(path);
  } catch (const rehearse::simcore::MeshError&) {
  }
  std::remove(path.c_str());
  return 0;
}
