#pragma once
// Bounds-checked readers over in-memory file bytes, shared by the hand-written parsers.
// Every failure throws MeshError with a sentence naming the format and what was expected.
#include <rehearse/simcore/mesh.hpp>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace rehearse::simcore::detail {

class TextReader {
 public:
  TextReader(std::string_view bytes, std::string format) : s_(bytes), format_(std::move(format)) {}

  bool atEnd();                       // skips whitespace first
  bool exhausted() const { return pos_ >= s_.size(); }  // no skipping
  std::string_view token();           // next whitespace-separated token; throws at end
  std::string_view peekToken();
  std::string_view line();            // rest of the current line (without newline)
  void skipLineEnd();                 // move past the next '\n'
  long long integer(const char* what);
  double real(const char* what);
  std::size_t count(const char* what, std::size_t max);  // non-negative integer <= max
  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return s_.size() - pos_; }
  /// Fails unless `n` items of at least `minBytes` each can still fit in the file: declared counts
  /// never drive an allocation larger than the file can back.
  void expectRoom(std::size_t n, std::size_t minBytes, const char* what);
  void seek(std::size_t p) { pos_ = p < s_.size() ? p : s_.size(); }
  std::string_view bytes() const { return s_; }
  /// Raw bytes at the current position; throws when fewer remain.
  std::string_view take(std::size_t n, const char* what);
  [[noreturn]] void fail(const std::string& message) const;
  const std::string& format() const { return format_; }

 private:
  void skipSpace();
  std::string_view s_;
  std::size_t pos_ = 0;
  std::string format_;
};

template <class T>
T readBinary(const char* p, bool bigEndian) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if (bigEndian != (std::endian::native == std::endian::big)) {
    auto* b = reinterpret_cast<unsigned char*>(&v);
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  }
  return v;
}

/// Integer value of a number read as double, without undefined behaviour: values that are not finite
/// or beyond +-2^53 become `fallback` (which the callers' range checks then refuse).
inline long long toInteger(double v, long long fallback = -1) {
  return (v >= -9007199254740992.0 && v <= 9007199254740992.0) ? static_cast<long long>(v) : fallback;
}
/// A label read as double: clamped into int range (NaN becomes 0).
inline int toLabel(double v) {
  return static_cast<int>(std::max<long long>(-2147483647LL, std::min<long long>(2147483647LL, toInteger(v, 0))));
}

bool iequals(std::string_view a, std::string_view b);
std::string lower(std::string_view s);

}  // namespace rehearse::simcore::detail
