// The case file: one SQLite database (schema in casefile.hpp), through SQLite's own library, the parts' checksums with
// OpenSSL's SHA-256; written to a temporary file beside the target, flushed, then renamed over it
// (casefile_save.cpp), read part by part with the damaged ones named (casefile_load.cpp). Here: what both share.
#include "rehearse/app/casefile.hpp"
#include "casefile_parts.hpp"

#include <rehearse/app/appearancestep.hpp>
#include <rehearse/app/casefolder.hpp>
#include <rehearse/app/incorrect_actions.hpp>
#include <rehearse/app/materials.hpp>
#include <rehearse/app/recording.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/precomputed.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <openssl/evp.h>
#include <sqlite3.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <stdexcept>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

using nlohmann::json;

namespace rehearse::app {
namespace casefile_parts {
[[noreturn]] void fail(const std::string& message) { throw std::runtime_error(message); }

std::string fileName(const std::string& path) { return std::filesystem::path(path).filename().string(); }

std::string sqlProblem(int code) {
  switch (code & 0xff) {
    case SQLITE_FULL: return "the disk is full";
    case SQLITE_READONLY: case SQLITE_PERM: return "the folder or file is read-only";
    case SQLITE_CANTOPEN: return "the file cannot be created there (a folder missing or not writable)";
    case SQLITE_IOERR: return "the disk reported an input/output error";
    case SQLITE_CORRUPT: case SQLITE_NOTADB: return "the file is damaged or not a database";
    case SQLITE_BUSY: case SQLITE_LOCKED: return "another program holds the file";
    default: return "the database reported error " + std::to_string(code & 0xff);
  }
}

std::string sha256(const std::string& data) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  if (EVP_Digest(data.data(), data.size(), md, &length, EVP_sha256(), nullptr) != 1)
    fail("The case's checksums cannot be computed (OpenSSL refused SHA-256).");
  return std::string(reinterpret_cast<const char*>(md), length);
}

std::string utcNowWithMs() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[40];
  const std::size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  std::snprintf(buf + n, sizeof buf - n, ".%03dZ", static_cast<int>(ms));
  return buf;
}

std::string exactNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}


void fsyncPath(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), flags);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

json poseJson(const Pose& p) {
  return {{"R", {{p.R(0, 0), p.R(0, 1), p.R(0, 2)}, {p.R(1, 0), p.R(1, 1), p.R(1, 2)}, {p.R(2, 0), p.R(2, 1), p.R(2, 2)}}},
          {"t", {p.t.x(), p.t.y(), p.t.z()}},
          {"unit", "m"}};
}
Pose poseFrom(const json& j) {
  Pose p;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) p.R(r, k) = j.at("R").at(r).at(k).get<double>();
    p.t[r] = j.at("t").at(r).get<double>();
  }
  return p;
}
json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d vec3(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

const char* gravityWord(GravityChoice g) {
  switch (g) {
    case GravityChoice::DownInTheImage:
      return "down in the image";
    case GravityChoice::Off:
      return "off";
    case GravityChoice::IntoTheScene:
      break;
  }
  return "into the scene";
}

}  // namespace casefile_parts

using namespace casefile_parts;


bool isCaseFile(const std::string& path) {
  struct stat st {};
  if (path.empty() || ::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  std::ifstream f(path, std::ios::binary);
  char header[16] = {};
  return f.read(header, sizeof header) && std::memcmp(header, "SQLite format 3\0", 16) == 0;
}

Case loadCase(const std::string& path, std::vector<std::string>* notes) {
  if (std::filesystem::is_directory(path)) return loadCaseDirectory(path, notes);
  if (isCaseFile(path)) return loadCaseFile(path, notes);
  if (!std::filesystem::exists(path)) fail("The case " + path + " does not exist; give a .rehearse case file or a case folder.");
  fail(fileName(path) + " is not a case: give a .rehearse case file (as the GUI saves) or a case folder (as 'rehearse "
       "phantom --out DIR' writes).");
}

}  // namespace rehearse::app
