#pragma once
// Helpers shared by the test suites.
#include <QtTest>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

inline std::string sharedData(const std::string& rel) { return std::string(REHEARSE_SHARED_DATA) + "/" + rel; }

/// True when ../shared/data was present at configure time (ctest sets REHEARSE_REQUIRE_SHARED=1): a file of it
/// that is missing then is a failure, not a skip.
inline bool sharedDataRequired() { return qgetenv("REHEARSE_REQUIRE_SHARED") == "1"; }

/// Skips the current test with a message when a file from ../shared/data is absent (fails when the data is
/// required: see sharedDataRequired).
#define REQUIRE_SHARED(rel)                                                                      \
  do {                                                                                           \
    if (!std::filesystem::exists(sharedData(rel))) {                                             \
      const QString why_ = QStringLiteral("../shared/data/%1 is absent").arg(QString::fromStdString(rel)); \
      if (sharedDataRequired()) QFAIL(qPrintable(why_ + QStringLiteral(" (../shared/data was there when configured)"))); \
      QSKIP(qPrintable(why_ + QStringLiteral("; skipping")));                                    \
    }                                                                                            \
  } while (0)

inline std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline void writeFile(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

inline std::string tempPath(const std::string& name) {
  static QTemporaryDir dir;
  return dir.path().toStdString() + "/" + name;
}
