#include "text_reader.hpp"

#include <cctype>
#include <charconv>
#include <cmath>

namespace rehearse::simcore::detail {

void TextReader::skipSpace() {
  while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
}

bool TextReader::atEnd() {
  skipSpace();
  return pos_ >= s_.size();
}

std::string_view TextReader::token() {
  skipSpace();
  if (pos_ >= s_.size()) fail("the file ends too early");
  std::size_t b = pos_;
  while (pos_ < s_.size() && !std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  return s_.substr(b, pos_ - b);
}

std::string_view TextReader::peekToken() {
  std::size_t saved = pos_;
  skipSpace();
  if (pos_ >= s_.size()) {
    pos_ = saved;
    return {};
  }
  auto t = token();
  pos_ = saved;
  return t;
}

std::string_view TextReader::line() {
  std::size_t b = pos_;
  while (pos_ < s_.size() && s_[pos_] != '\n') ++pos_;
  auto l = s_.substr(b, pos_ - b);
  if (pos_ < s_.size()) ++pos_;
  if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
  return l;
}

void TextReader::skipLineEnd() {
  while (pos_ < s_.size() && s_[pos_] != '\n') ++pos_;
  if (pos_ < s_.size()) ++pos_;
}

long long TextReader::integer(const char* what) {
  auto t = token();
  long long v = 0;
  auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || p != t.data() + t.size())
    fail("expected an integer for " + std::string(what) + " but found '" +
         std::string(t.substr(0, 20)) + "'");
  return v;
}

double TextReader::real(const char* what) {
  auto t = token();
  double v = 0;
  auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec == std::errc::result_out_of_range) return std::numeric_limits<double>::infinity();
  if (ec != std::errc() || p != t.data() + t.size())
    fail("expected a number for " + std::string(what) + " but found '" +
         std::string(t.substr(0, 20)) + "'");
  return v;
}

std::size_t TextReader::count(const char* what, std::size_t max) {
  long long v = integer(what);
  if (v < 0 || static_cast<unsigned long long>(v) > max)
    fail("the " + std::string(what) + " count " + std::to_string(v) + " is out of range (0 to " +
         std::to_string(max) + ")");
  return static_cast<std::size_t>(v);
}

std::string_view TextReader::take(std::size_t n, const char* what) {
  if (n > s_.size() - pos_) fail("the file ends inside the " + std::string(what));
  auto v = s_.substr(pos_, n);
  pos_ += n;
  return v;
}

void TextReader::expectRoom(std::size_t n, std::size_t minBytes, const char* what) {
  if (minBytes && n > (remaining() + 1) / minBytes)
    fail("it declares " + std::to_string(n) + " " + what + " but is too short to hold them");
}

void TextReader::fail(const std::string& message) const {
  throw MeshError("This " + format_ + " file cannot be read: " + message + " (byte " +
                  std::to_string(pos_) + "); check that the file is complete and in that format.");
}

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i])))
      return false;
  return true;
}

std::string lower(std::string_view s) {
  std::string r(s);
  for (auto& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

}  // namespace rehearse::simcore::detail
