// libFuzzer entry point for the recording's decoders (issue 32): a recorded setup (JSON), event (JSON) or checkpoint
// (bytes) from a case file or the training database is untrusted. The first byte picks the decoder; the rest is its
// input. Any exception other than std::runtime_error (the decoders' one sentence), any crash, leak or undefined
// behaviour is a finding. A decoded setup or checkpoint must also satisfy the checks the simulation relies on.
#include <rehearse/app/recording.hpp>

#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace {
// The body a fuzzed checkpoint names: one tetrahedron (4 nodes), as a setup store would return it.
rehearse::simcore::BodySetup tinyBody() {
  rehearse::simcore::BodySetup s;
  s.mesh.points = {{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}, {0, 0, 0.01}};
  s.mesh.tets = {{0, 1, 2, 3}};
  s.mesh.tetLabels = {1};
  s.mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  s.mesh.triangleLabels = {1, 1, 1, 1};
  s.fixedNodes = {0};
  return s;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace rehearse;
  if (size == 0) return 0;
  const std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    switch (data[0] % 3) {
      case 0: {
        const simcore::BodySetup s = app::decodeSetup(bytes);
        if (!app::setupProblem(s).empty()) std::abort();  // a decoded setup is a valid one
        const std::size_t n = s.mesh.points.size();
        for (const auto& t : s.mesh.tets)
          for (int v : t)
            if (v < 0 || static_cast<std::size_t>(v) >= n) std::abort();
        break;
      }
      case 1: {
        const simcore::InputEvent e = app::decodeEvent(bytes);
        if (!app::eventProblem(e).empty()) std::abort();
        break;
      }
      default: {
        static const simcore::BodySetup body = tinyBody();
        const simcore::Checkpoint c = app::decodeCheckpointState(bytes, [](std::uint64_t) { return body; });
        if (c.state.x.size() != 12 || c.state.v.size() != 12) std::abort();
        for (int h : c.tool.held)
          if (h < 0 || h >= 4) std::abort();
        break;
      }
    }
  } catch (const std::runtime_error&) {
  }
  return 0;
}
