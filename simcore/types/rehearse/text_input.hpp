#pragma once
// Text inputs a user or another machine hands the program (scenes, gesture scripts, contours, thresholds, appearance
// files, case folders' JSON, recorded JSON): read only from a regular file of bounded size, and refused when nested
// deeper than any file of ours is (issue 60: a FIFO blocked the open; whole files were read with no size cap; a
// script nested 100,000 deep crashed the JSON library's recursive printing). Header-only, no dependency.
#include <cerrno>
#include <cstddef>
#include <string>
#include <string_view>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

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
  // Opened without blocking, then looked at through the descriptor: what is read is what was checked (a pipe put in
  // the file's place between a check and the open would block it).
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    why = path + (errno == ENOENT ? " does not exist" : " cannot be opened; check its permissions");
    return false;
  }
  struct stat st {};
  const bool statted = ::fstat(fd, &st) == 0;
  if (!statted || !S_ISREG(st.st_mode)) {
    ::close(fd);
    why = path + (statted && S_ISDIR(st.st_mode) ? " is a folder" : " is not a regular file (a pipe or a device)") +
          ", not a file to read";
    return false;
  }
  if (static_cast<std::size_t>(st.st_size) > maxBytes) {
    ::close(fd);
    why = path + " is " + std::to_string(static_cast<long long>(st.st_size) >> 20) + " MiB; at most " +
          std::to_string(maxBytes >> 20) + " MiB is read";
    return false;
  }
  // Up to the size it had: a file that grows while it is read is never read past the limit.
  text.assign(static_cast<std::size_t>(st.st_size), '\0');
  std::size_t got = 0;
  while (got < text.size()) {
    const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  text.resize(got);
  return true;
}

}  // namespace rehearse
