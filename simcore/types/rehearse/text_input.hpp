#pragma once
// Text inputs a user or another machine hands the program (scenes, gesture scripts, contours, thresholds, appearance
// files, case folders' JSON, recorded JSON): read only from a regular file of bounded size, and refused when nested
// deeper than any file of ours is (issue 60: a FIFO blocked the open; whole files were read with no size cap; a
// script nested 100,000 deep crashed the JSON library's recursive printing). Header-only, no dependency.
#include <cstddef>
#include <fstream>
#include <string>
#include <string_view>
#include <sys/stat.h>

namespace rehearse {

inline constexpr std::size_t kMaxJsonInputBytes = std::size_t{16} << 20;  ///< 16 MiB
inline constexpr int kMaxJsonDepth = 64;  ///< our deepest file (a recorded setup) nests 5 levels

/// The deepest nesting of `{` and `[` outside strings in JSON text, counted up to `stopAt` (then `stopAt` + 1).
inline int jsonNestingDepth(std::string_view text, int stopAt = kMaxJsonDepth) {
  int depth = 0, deepest = 0;
  bool inString = false, escaped = false;
  for (char c : text) {
    if (inString) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') inString = false;
      continue;
    }
    if (c == '"') inString = true;
    else if (c == '{' || c == '[') {
      if (++depth > deepest) deepest = depth;
      if (deepest > stopAt) return deepest;
    } else if ((c == '}' || c == ']') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

/// Why JSON text is refused before it is parsed (too long, nested too deep), or empty. `what` names it.
inline std::string jsonTextProblem(std::string_view text, const std::string& what,
                                   std::size_t maxBytes = kMaxJsonInputBytes) {
  if (text.size() > maxBytes)
    return what + " is " + std::to_string(text.size() >> 10) + " KiB; at most " + std::to_string(maxBytes >> 20) +
           " MiB is read";
  if (jsonNestingDepth(text) > kMaxJsonDepth)
    return what + " is nested more than " + std::to_string(kMaxJsonDepth) + " levels deep, which no file of ours is";
  return {};
}

/// Reads a text input file: a regular file (not a folder, a FIFO or a device) of at most `maxBytes`. False with
/// `why` (one sentence without a full stop, naming the file) when it cannot be.
inline bool readTextInput(const std::string& path, std::string& text, std::string& why,
                          std::size_t maxBytes = kMaxJsonInputBytes) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    why = path + " does not exist or cannot be reached";
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    why = path + (S_ISDIR(st.st_mode) ? " is a folder" : " is not a regular file (a pipe or a device)") +
          ", not a file to read";
    return false;
  }
  if (static_cast<std::size_t>(st.st_size) > maxBytes) {
    why = path + " is " + std::to_string(static_cast<long long>(st.st_size) >> 20) + " MiB; at most " +
          std::to_string(maxBytes >> 20) + " MiB is read";
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    why = path + " cannot be opened; check its permissions";
    return false;
  }
  text.assign(static_cast<std::size_t>(st.st_size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  // A file that grew while it was read is read up to the size it had: never more than the limit.
  return true;
}

}  // namespace rehearse
