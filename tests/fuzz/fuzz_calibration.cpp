// libFuzzer entry point for the camera calibration readers as a user reaches them (imaging::loadCamera): our scan of
// OpenCV's YAML and XML (nesting, size), then cv::FileStorage (OpenCV 4.6, not instrumented: its crashes, hangs and
// memory past the limit are still findings), and our JSON and text readers. The first byte chooses the format (.yaml, .yml,
// .xml, .json, .txt); the rest is the file. A refusal (InputError) is the expected outcome of most inputs; a crash, a hang
// or any other exception is a finding.
#include <rehearse/imaging/camera.hpp>

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* extensions[] = {".yaml", ".yml", ".xml", ".json", ".txt"};
  const std::string path = "/tmp/fuzz-camera-" + std::to_string(::getpid()) + extensions[data[0] % 5];
  if (FILE* f = std::fopen(path.c_str(), "wb")) {
    std::fwrite(data + 1, 1, size - 1, f);
    std::fclose(f);
  } else {
    return 0;
  }
  try {
    rehearse::imaging::loadCamera(path, 640, 480);
  } catch (const rehearse::imaging::InputError&) {
  }
  std::remove(path.c_str());
  return 0;
}
