// What the app's screenshot of the built-in case shows, checked from outside the app: the phantom's frame
// is found in the PNG by template matching over scales (not from the window's layout), and the organ is
// drawn where the camera puts it: inside the organ's mask (rendered here through the case's camera and
// pose) the screenshot departs from the frame, outside it (in the scope's field of view) it is the frame.
// Usage: screenshot_content SCREENSHOT.png; exit 0 when it holds, 1 with a sentence when not.
#include "phantom/phantom.hpp"
#include <rehearse/app/case.hpp>
#include <rehearse/imaging/render.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdio>

using namespace rehearse;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: screenshot_content SCREENSHOT.png\n");
    return 2;
  }
  const cv::Mat3b shot = cv::imread(argv[1], cv::IMREAD_COLOR);
  if (shot.empty()) {
    std::fprintf(stderr, "the screenshot %s cannot be read\n", argv[1]);
    return 1;
  }
  const app::Case c = app::caseFromPhantom(phantom::makePhantom());
  const cv::Mat3b& frame = c.frame;
  // 1. Where the frame is: best normalised correlation over scales, at a quarter resolution, then refined.
  cv::Mat3b small;
  cv::resize(shot, small, {}, 0.25, 0.25, cv::INTER_AREA);
  double bestScore = -2, bestScale = 0;
  cv::Point bestAt;
  auto tryScale = [&](double s, const cv::Mat3b& image, double imageScale) {
    cv::Mat3b t;
    const cv::Size size(static_cast<int>(std::lround(frame.cols * s * imageScale)), static_cast<int>(std::lround(frame.rows * s * imageScale)));
    if (size.width < 16 || size.height < 16 || size.width > image.cols || size.height > image.rows) return;
    cv::resize(frame, t, size, 0, 0, cv::INTER_AREA);
    cv::Mat1f score;
    cv::matchTemplate(image, t, score, cv::TM_CCOEFF_NORMED);
    double m;
    cv::Point at;
    cv::minMaxLoc(score, nullptr, &m, nullptr, &at);
    if (m > bestScore) {
      bestScore = m;
      bestScale = s;
      bestAt = cv::Point(static_cast<int>(std::lround(at.x / imageScale)), static_cast<int>(std::lround(at.y / imageScale)));
    }
  };
  for (double s = 0.2; s <= 1.5; s += 0.01) tryScale(s, small, 0.25);
  const double coarse = bestScale;
  bestScore = -2;
  for (double s = coarse - 0.012; s <= coarse + 0.012; s += 0.002) tryScale(s, shot, 1.0);
  std::printf("frame found at (%d, %d), scale %.3f, correlation %.3f\n", bestAt.x, bestAt.y, bestScale, bestScore);
  if (bestScore < 0.5) {
    std::fprintf(stderr, "the phantom's frame is not in the screenshot (best correlation %.2f)\n", bestScore);
    return 1;
  }
  // 2. The organ's mask through the case's camera and pose, shrunk and grown away from its edge (the
  // outline and contour lines are drawn there).
  const cv::Mat1b mask = imaging::renderMask(c.camera, c.pose, c.surfaceView());
  cv::Mat1b inside, outside;
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, {25, 25});
  cv::erode(mask, inside, kernel);
  cv::dilate(mask, outside, kernel);
  long in = 0, inChanged = 0, out = 0, outChanged = 0;
  for (int y = 0; y < frame.rows; y += 2)
    for (int x = 0; x < frame.cols; x += 2) {
      const double r = std::hypot(x - frame.cols / 2.0, y - frame.rows / 2.0);
      if (r > 0.5 * frame.cols) continue;  // the scope's dark rim: nothing to tell there
      const int sx = bestAt.x + static_cast<int>(std::lround((x + 0.5) * bestScale - 0.5));
      const int sy = bestAt.y + static_cast<int>(std::lround((y + 0.5) * bestScale - 0.5));
      if (sx < 0 || sy < 0 || sx >= shot.cols || sy >= shot.rows) continue;
      const cv::Vec3b a = shot(sy, sx), b = frame(y, x);
      const int diff = std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
      if (inside(y, x)) {
        ++in;
        inChanged += diff > 40;
      } else if (!outside(y, x)) {
        ++out;
        outChanged += diff > 40;
      }
    }
  const double inShare = in ? double(inChanged) / in : 0, outShare = out ? double(outChanged) / out : 1;
  std::printf("organ drawn over %.1f %% of its mask's inside (%ld samples); frame changed on %.1f %% outside it (%ld samples)\n",
              100 * inShare, in, 100 * outShare, out);
  if (in < 1000 || inShare < 0.9) {
    std::fprintf(stderr, "the organ is not drawn where the camera puts it (%.1f %% of its inside differs from the frame)\n", 100 * inShare);
    return 1;
  }
  if (outShare > 0.05) {
    std::fprintf(stderr, "the frame around the organ is not shown as it is (%.1f %% of it differs)\n", 100 * outShare);
    return 1;
  }
  return 0;
}
