#pragma once
// The Open-CAS ex-vivo liver frame (../shared/data/open-cas, see its README row): the left camera's intrinsics
// and distortion, the frame undistorted with them (every step works on undistorted frames), the CT surface
// already in that camera's frame (pose = identity, millimetres), and the challenge's bead mask undistorted
// the same way. For tests and benchmarks; `available()` is false when the data is absent.
#include <rehearse/imaging/camera.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <array>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace rehearse::testdata {

struct OpenCas {
  imaging::Camera camera;        ///< the undistorted frame's pinhole (no distortion left)
  cv::Mat3b frame;               ///< undistorted, BGR
  cv::Mat1b beads;               ///< 255 on the fiducial beads (MASK_left), undistorted
  std::vector<double> vertices;  ///< the CT surface, camera frame, metres, 3n
  std::vector<std::array<int, 3>> triangles;

  static std::string directory() { return std::string(REHEARSE_SHARED_DATA) + "/open-cas/"; }
  static bool available() { return std::filesystem::exists(directory() + "Stereo_SD_d_complete_22_IMG_left.bmp"); }

  static OpenCas load() {
    OpenCas c;
    const std::string dir = directory();
    std::ifstream k(dir + "calib.left.intrinsics.txt"), d(dir + "calib.left.distortion.txt");
    imaging::Camera raw;
    for (int r = 0; r < 3; ++r)
      for (int col = 0; col < 3; ++col) k >> raw.K(r, col);
    for (double& v : raw.distortion) d >> v;
    const cv::Mat3b distorted = cv::imread(dir + "Stereo_SD_d_complete_22_IMG_left.bmp", cv::IMREAD_COLOR);
    const cv::Mat1b beads = cv::imread(dir + "Stereo_SD_d_complete_22_MASK_left.png", cv::IMREAD_GRAYSCALE);
    cv::Mat K(3, 3, CV_64F), D(1, 5, CV_64F);
    for (int r = 0; r < 3; ++r)
      for (int col = 0; col < 3; ++col) K.at<double>(r, col) = raw.K(r, col);
    for (int i = 0; i < 5; ++i) D.at<double>(0, i) = raw.distortion[static_cast<std::size_t>(i)];
    cv::Mat mapX, mapY;
    cv::initUndistortRectifyMap(K, D, cv::Mat(), K, distorted.size(), CV_32FC1, mapX, mapY);
    cv::remap(distorted, c.frame, mapX, mapY, cv::INTER_LINEAR);
    cv::remap(beads, c.beads, mapX, mapY, cv::INTER_NEAREST);
    c.camera = raw;
    c.camera.distortion = {};
    c.camera.width = distorted.cols;
    c.camera.height = distorted.rows;
    simcore::LoadOptions lo;
    lo.unit = "mm";
    simcore::Mesh m = simcore::loadMesh(dir + "Stereo_SD_d_complete_22_CT_cut.stl", lo);
    m.convertToMetres();
    for (const auto& p : m.points) c.vertices.insert(c.vertices.end(), {p.x(), p.y(), p.z()});
    c.triangles = m.triangles;
    return c;
  }
  SurfaceView surface() const {
    return {vertices.data(), vertices.size() / 3, triangles.front().data(), triangles.size()};
  }
};

}  // namespace rehearse::testdata
