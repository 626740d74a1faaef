// libFuzzer entry point for one hand-written parser (chosen at compile time). Any exception other than
// MeshError, any crash, leak or undefined behaviour is a finding.
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>

#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace rehearse::simcore;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
#if defined(FUZZ_FORMAT_gmsh)
    Mesh m = parseGmsh(bytes);
#elif defined(FUZZ_FORMAT_vtk)
    Mesh m = parseVtkLegacy(bytes);
#elif defined(FUZZ_FORMAT_vtu)
    Mesh m = parseVtu(bytes);
#else
    Mesh m = parseMedit(bytes);
#endif
    validateMesh(m, "fuzz input");
    repairVolume(m);
    computeQuality(m);
    boundaryTriangles(m, true);
  } catch (const MeshError&) {
  }
  return 0;
}
