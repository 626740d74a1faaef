// Counts in the sentences simcore writes for people: "1 element", "3 elements", never "3 element(s)" (a person
// read the brackets as the program's jargon).
#pragma once

#include <cstddef>
#include <string>

namespace rehearse::simcore {

/// "n one" for n == 1, else "n many": quantity(1, "face", "faces") is "1 face".
inline std::string quantity(std::size_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

}  // namespace rehearse::simcore
