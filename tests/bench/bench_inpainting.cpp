// Benchmark of the background inpainting methods (issue 14): held-out patches of a real laparoscopic frame
// (../shared/data/scikit-surgery/laparoscopy-liver-frame.jpg) are removed and filled by each method; PSNR
// and SSIM of the filled patch against the original, and the time per frame. Not a test.
//   bench_inpainting [OUT_DIR] [--patches N] [--radius PX]
#include <rehearse/imaging/appearance_fit.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

using namespace rehearse;

namespace {

// SSIM (Wang et al. 2004, 11x11 Gaussian window, sigma 1.5) on the grey image, averaged over `mask`.
double ssim(const cv::Mat3b& a, const cv::Mat3b& b, const cv::Mat1b& mask) {
  cv::Mat ga, gb;
  cv::cvtColor(a, ga, cv::COLOR_BGR2GRAY);
  cv::cvtColor(b, gb, cv::COLOR_BGR2GRAY);
  ga.convertTo(ga, CV_64F);
  gb.convertTo(gb, CV_64F);
  const double c1 = std::pow(0.01 * 255, 2), c2 = std::pow(0.03 * 255, 2);
  cv::Mat mua, mub, saa, sbb, sab;
  const cv::Size w(11, 11);
  cv::GaussianBlur(ga, mua, w, 1.5);
  cv::GaussianBlur(gb, mub, w, 1.5);
  cv::GaussianBlur(ga.mul(ga), saa, w, 1.5);
  cv::GaussianBlur(gb.mul(gb), sbb, w, 1.5);
  cv::GaussianBlur(ga.mul(gb), sab, w, 1.5);
  saa -= mua.mul(mua);
  sbb -= mub.mul(mub);
  sab -= mua.mul(mub);
  cv::Mat num = (2 * mua.mul(mub) + c1).mul(2 * sab + c2), den = (mua.mul(mua) + mub.mul(mub) + c1).mul(saa + sbb + c2);
  cv::Mat map = num / den;
  return cv::mean(map, mask)[0];
}

}  // namespace

int main(int argc, char** argv) {
  std::string out = ".";
  int patches = 12, radius = 40;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--patches" && i + 1 < argc) patches = std::atoi(argv[++i]);
    else if (a == "--radius" && i + 1 < argc) radius = std::atoi(argv[++i]);
    else out = a;
  }
  const std::string path = std::string(REHEARSE_SHARED_DATA) + "/scikit-surgery/laparoscopy-liver-frame.jpg";
  const cv::Mat3b frame = cv::imread(path, cv::IMREAD_COLOR);
  if (frame.empty()) {
    std::printf("%s is absent; skipped\n", path.c_str());
    return 0;
  }
  std::filesystem::create_directories(out);
  // Held-out patches: discs spread over the frame's well-lit middle (not the scope's dark border).
  std::mt19937 rng(14);
  std::uniform_int_distribution<int> px(frame.cols / 5, 4 * frame.cols / 5), py(frame.rows / 5, 4 * frame.rows / 5);
  cv::Mat1b hole(frame.size(), uchar(0));
  for (int k = 0; k < patches; ++k) cv::circle(hole, {px(rng), py(rng)}, radius, cv::Scalar(255), cv::FILLED);
  std::ofstream csv(out + "/inpainting.csv");
  csv << "method,width,height,hole_px,psnr_db,ssim,ms_median\n";
  std::printf("frame %dx%d, %d discs of %d px radius (%d px held out)\n", frame.cols, frame.rows, patches, radius, cv::countNonZero(hole));
  std::printf("%-10s %9s %7s %10s\n", "method", "PSNR dB", "SSIM", "median ms");
  for (auto m : {imaging::InpaintMethod::Telea, imaging::InpaintMethod::NavierStokes, imaging::InpaintMethod::FsrFast, imaging::InpaintMethod::ShiftMap}) {
    std::vector<double> ms;
    cv::Mat3b filled;
    for (int rep = 0; rep < 3; ++rep) {
      const auto t0 = std::chrono::steady_clock::now();
      filled = imaging::inpaintRegion(frame, hole, m, 0);
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(ms.begin(), ms.end());
    const double db = imaging::psnr(frame, filled, hole), s = ssim(frame, filled, hole);
    std::printf("%-10s %9.2f %7.3f %10.0f\n", imaging::inpaintMethodName(m), db, s, ms[1]);
    csv << imaging::inpaintMethodName(m) << "," << frame.cols << "," << frame.rows << "," << cv::countNonZero(hole) << "," << db << "," << s << "," << ms[1] << "\n";
  }
  std::printf("wrote %s/inpainting.csv\n", out.c_str());
  return 0;
}
