#pragma once
// What the benchmarks share: their command line ([OUT_DIR] [--quick], the folder created) and the gesture scripts they
// run (resources/gestures).
#include <rehearse/app/gesture.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace rehearse::testing {

struct BenchArgs {
  std::string out = ".";  ///< where the CSV goes (created)
  bool quick = false;     ///< the built-in organ only, fewer repeats (ctest's quick runs)
};

inline BenchArgs benchArgs(int argc, char** argv) {
  BenchArgs a;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--quick") == 0) a.quick = true;
    else a.out = argv[i];
  }
  std::filesystem::create_directories(a.out);
  return a;
}

/// A gesture script of resources/gestures by its file name (throws std::runtime_error with the parser's sentence).
inline app::GestureScript gestureScript(const std::string& name) {
  std::ifstream in(std::string(REHEARSE_SOURCE_DIR) + "/resources/gestures/" + name);
  std::stringstream ss;
  ss << in.rdbuf();
  return app::parseGestureScript(ss.str());
}

}  // namespace rehearse::testing
