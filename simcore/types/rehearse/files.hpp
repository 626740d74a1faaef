#pragma once
// The errors and file helpers every layer shares (issue 63: they lived in imaging/camera.hpp): a user-facing input
// error (one sentence), and writing a file so that it is never half-written. Header-only, no dependency.
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

namespace rehearse {

/// A user-facing input error: `what()` is one sentence saying what is wrong and what to do.
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Writes bytes to `path` through a temporary file and a rename (never half-written). Throws InputError.
inline void writeFileAtomically(const std::string& path, const std::string& bytes) {
  const std::string tmp = path + ".part";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError("Cannot write " + path + "; check that the folder exists and is writable.");
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw InputError("Writing " + path + " failed (disk full?); nothing was changed.");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw InputError("Cannot replace " + path + " (" + ec.message() + ").");
}

}  // namespace rehearse
