// libFuzzer entry point for our checks on third-party formats (input_checks.hpp): PLY, OFF, OBJ, glTF/GLB, NRRD and
// MetaImage headers, OpenCV YAML/XML. The first byte chooses the check; any exception, crash, leak, undefined
// behaviour or slow input is a finding (the checks return a sentence, they never throw).
#include <rehearse/simcore/input_checks.hpp>

#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace rehearse::simcore::checks;
  if (size == 0) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  MetaImageLayout layout;
  switch (data[0] % 9) {
    case 0: plyProblem(bytes); break;
    case 1: offProblem(bytes); break;
    case 2: objProblem(bytes); break;
    case 3: gltfProblem(bytes, false); break;
    case 4: gltfProblem(bytes, true); break;
    case 5: nrrdHeaderProblem(bytes); break;
    case 6: metaImageHeaderProblem(bytes, &layout); break;
    case 7: calibrationMarkupProblem(bytes, false); break;
    default: calibrationMarkupProblem(bytes, true); break;
  }
  return 0;
}
