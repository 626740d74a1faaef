#pragma once
// The file-reading fuzz targets' input as a file a user would open: the first byte chooses the extension among
// `extensions` (the reader is chosen by it), the rest is the file's bytes, written under /tmp for this process and
// removed afterwards. `read(path)` runs the reader; false when the file could not be written.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <initializer_list>
#include <string>

template <typename Read>
bool readAsFile(const std::uint8_t* data, std::size_t size, std::initializer_list<const char*> extensions,
                const char* stem, Read read) {
  if (size == 0 || extensions.size() == 0) return false;
  const std::string path = std::string("/tmp/fuzz-") + stem + "-" + std::to_string(::getpid()) +
                           extensions.begin()[data[0] % extensions.size()];
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return false;
  std::fwrite(data + 1, 1, size - 1, f);
  std::fclose(f);
  read(path);
  std::remove(path.c_str());
  return true;
}
