// Benchmark of the composited view's OpenGL path (issue 14) in one offscreen run: a frame composited
// (background quad + the deformed organ shaded per fragment, 4x multisampled, read back) against the same
// path drawing the frame image alone (quad, read back), at 1280x720 on the phantom and the real organ
// shapes; the ratio is what the acceptance bounds (<= 1.5); absolute rates under Mesa's llvmpipe say
// nothing of a GPU workstation. Medians of repeated runs. Needs an X server (xvfb-run). Not a test.
//   xvfb-run -a bench_gl_compose [OUT_DIR] [--repeat N]
#include "phantom/phantom.hpp"
#include "realorgan.hpp"

#include "rehearse/ui/glcompositor.hpp"

#include <rehearse/imaging/render.hpp>

#include <QElapsedTimer>
#include <QGuiApplication>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>

using namespace rehearse;

int main(int argc, char** argv) {
  QGuiApplication app(argc, argv);
  std::string out = ".";
  int repeat = 15;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc) repeat = std::max(3, std::atoi(argv[++i]));
    else out = a;
  }
  std::filesystem::create_directories(out);
  ui::GLCompositor gl;
  if (!gl.valid()) {
    std::fprintf(stderr, "bench_gl_compose: no OpenGL 3.3 context (run it under xvfb-run)\n");
    return 1;
  }
  std::ofstream csv(out + "/gl_compose.csv");
  csv << "organ,triangles,width,height,samples,background_only_ms,composited_ms,ratio\n";
  auto median = [&](const std::function<void()>& f) {
    std::vector<double> ms;
    for (int i = 0; i < repeat; ++i) {
      QElapsedTimer t;
      t.start();
      f();
      ms.push_back(t.nsecsElapsed() / 1e6);
    }
    std::sort(ms.begin(), ms.end());
    return ms[ms.size() / 2];
  };
  auto run = [&](const std::string& name, const imaging::Camera& cam, const Pose& pose, const SurfaceView& sv, const cv::Mat3b& frame, const imaging::Appearance& theta) {
    imaging::CompositionInput ci;
    ci.camera = cam;
    ci.pose = pose;
    ci.rest = ci.deformed = sv;
    ci.frame = frame;
    ci.background = frame;
    ci.albedo = cv::Mat3f(frame.size(), cv::Vec3f(1, 1, 1));
    ci.theta = theta;
    if (!gl.prepare(ci)) {
      std::fprintf(stderr, "%s: prepare failed\n", name.c_str());
      return;
    }
    std::vector<double> moved(sv.vertices, sv.vertices + 3 * sv.vertexCount);
    for (std::size_t i = 1; i < moved.size(); i += 3) moved[i] += 0.003;
    QImage j;
    gl.compose(moved, j, 4);  // warm-up (shader compilation, buffers)
    gl.drawBackgroundOnly(j);
    for (int samples : {1, 4}) {
      const double bg = median([&] { gl.drawBackgroundOnly(j); });
      const double comp = median([&] { gl.compose(moved, j, samples); });
      std::printf("%s, %zu triangles, %dx%d, %dx MSAA: frame alone %.2f ms, composited %.2f ms, ratio %.2f\n", name.c_str(), sv.triangleCount, cam.width, cam.height,
                  samples, bg, comp, comp / bg);
      csv << name << "," << sv.triangleCount << "," << cam.width << "," << cam.height << "," << samples << "," << bg << "," << comp << "," << comp / bg << "\n";
    }
  };
  phantom::PhantomOptions po;
  po.width = 1280;
  po.height = 720;
  const phantom::Phantom c = phantom::makePhantom(po);
  run("phantom", c.camera, c.truePose, c.surfaceView(), c.frame, c.trueAppearance);
  for (const auto& [name, file] : std::vector<std::pair<std::string, std::string>>{
           {"patient liver", "/scikit-surgery/patient-liver/liver.vtk"}, {"BodyParts3D liver", "/bodyparts3d/FMA7197_Liver.obj"},
           {"kidney", "/scikit-surgery/kidney/kidney.vtk"}}) {
    const std::string path = std::string(REHEARSE_SHARED_DATA) + file;
    if (!std::filesystem::exists(path)) {
      std::printf("%s: %s is absent; skipped\n", name.c_str(), path.c_str());
      continue;
    }
    const simcore::Mesh organ = testing::loadOrganSurface(path);
    imaging::Camera cam = testing::scikitSurgeryCamera();
    const Pose pose = testing::broadsideView(organ, cam);
    const double k = 1280.0 / cam.width;
    cam.K.row(0) *= k;
    cam.K.row(1) *= k;
    cam.width = 1280;
    cam.height = 720;
    cv::Mat3b frame = imaging::makeTissueBackground(cam.width, cam.height, 9);
    run(name, cam, pose, organ.surfaceView(), frame, c.trueAppearance);
  }
  std::printf("wrote %s/gl_compose.csv\n", out.c_str());
  return 0;
}
