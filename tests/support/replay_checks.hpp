#pragma once
// The reference a seek is checked against: a straight replay of a recording from rest, the state's checksum
// after every step (index = step; index 0, at rest, holds 0).
#include <rehearse/app/recording.hpp>

#include <cstdint>
#include <vector>

namespace rehearse::testing {

inline std::vector<std::uint64_t> straightChecksums(const app::Recording& r) {
  std::vector<std::uint64_t> out{0};
  simcore::replay(r.setup, r.events, r.summary.steps, [&](long, const simcore::SimulationState& s) { out.push_back(app::stateChecksum(s)); });
  return out;
}

}  // namespace rehearse::testing
