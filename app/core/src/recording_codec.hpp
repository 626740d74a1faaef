#pragma once
// Internal to the recording: what the recorder needs of the codecs beyond recording.hpp.
#include <rehearse/simcore/session/session.hpp>

#include <cstdint>
#include <string>

namespace rehearse::app::detail {
/// A checkpoint's bytes naming its setups by the hashes the recorder already has (encodeCheckpointState computes them).
std::string encodeCheckpoint(const simcore::Checkpoint& c, std::uint64_t setupHashValue, std::uint64_t pendingSetupHash);
}  // namespace rehearse::app::detail
