// libFuzzer entry point for the camera calibration readers as a user reaches them (imaging::loadCamera): our scan of
// OpenCV's YAML and XML (nesting, size), then cv::FileStorage (OpenCV 4.6, not instrumented: its crashes, hangs and
// memory past the limit are still findings), and our JSON and text readers. The first byte chooses the format (.yaml, .yml,
// .xml, .json, .txt); the rest is the file. A refusal (InputError) is the expected outcome of most inputs; a crash, a hang
// or any other exception is a finding.
#include <rehearse/imaging/camera.hpp>

#include "fuzz_file.hpp"

#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  readAsFile(data, size, {".yaml", ".yml", ".xml", ".json", ".txt"}, "camera", [](const std::string& path) {
    try {
      rehearse::imaging::loadCamera(path, 640, 480);
    } catch (const rehearse::InputError&) {
    }
  });
  return 0;
}
