// Benchmarks of the foundation: tetrahedralisation, phantom generation, CPU rendering, mesh IO.
// Median of repeated runs; writes CSV to the path given (default bench_foundation.csv). Not a test.
#include "phantom/phantom.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <vector>

using namespace rehearse;

namespace {
double medianMs(int runs, const std::function<void()>& f) {
  std::vector<double> t;
  for (int i = 0; i < runs; ++i) {
    auto a = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}
}  // namespace

int main(int argc, char** argv) {
  const std::string csvPath = argc > 1 ? argv[1] : "bench_foundation.csv";
  const std::string data = std::string(REHEARSE_SHARED_DATA);
  std::ofstream csv(csvPath);
  csv << "benchmark,variant,size,median_ms,runs\n";
  auto row = [&](const char* b, const std::string& v, std::size_t size, double ms, int runs) {
    csv << b << "," << v << "," << size << "," << ms << "," << runs << "\n";
    std::printf("%-22s %-28s %8zu %10.2f ms (median of %d)\n", b, v.c_str(), size, ms, runs);
  };
  const std::string stl = data + "/scikit-surgery/liver_downsample.stl";
  if (std::filesystem::exists(stl)) {
    auto surface = simcore::loadMesh(stl, {"mm"});
    for (std::size_t target : {2000, 6500, 17000}) {
      simcore::TetrahedraliseOptions o;
      o.targetTets = target;
      std::size_t got = 0;
      double ms = medianMs(5, [&] { got = simcore::tetrahedraliseSurface(surface, o).tets.size(); });
      row("tetrahedralise", "liver_downsample.stl target " + std::to_string(target), got, ms, 5);
    }
  }
  phantom::Phantom c;
  double ms = medianMs(5, [&] { c = phantom::makePhantom(); });
  row("phantom", "generate (mesh + frame)", c.volume.tets.size(), ms, 5);
  cv::Mat3b bg(720, 1280, cv::Vec3b(40, 40, 120));
  for (int scale : {1, 2}) {
    ms = medianMs(9, [&] { imaging::renderShaded(c.camera, c.truePose, c.surfaceView(), c.trueAppearance, bg, scale); });
    row("render", "Torrance-Sparrow 1280x720 x" + std::to_string(scale), c.surface.size(), ms, 9);
  }
  ms = medianMs(9, [&] { imaging::renderMask(c.camera, c.truePose, c.surfaceView()); });
  row("render", "mask 1280x720", c.surface.size(), ms, 9);
  ms = medianMs(9, [&] { imaging::makeTissueBackground(1280, 720, 1); });
  row("render", "tissue background 1280x720", 0, ms, 9);
  const std::string oss = data + "/sofa/Ossicles.vtu";
  if (std::filesystem::exists(oss)) {
    ms = medianMs(9, [&] { simcore::loadMesh(oss); });
    row("meshio", "read Ossicles.vtu (ascii)", 5058, ms, 9);
    auto m = simcore::loadMesh(oss);
    const std::string tmp = (std::filesystem::temp_directory_path() / "bench.vtu").string();
    ms = medianMs(9, [&] { simcore::saveMesh(m, tmp, false); });
    row("meshio", "write vtu binary", 5058, ms, 9);
    ms = medianMs(9, [&] { simcore::loadMesh(tmp); });
    row("meshio", "read vtu binary", 5058, ms, 9);
  }
  std::printf("wrote %s\n", csvPath.c_str());
  return 0;
}
