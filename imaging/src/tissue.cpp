// Procedural abdominal-tissue background for the phantom frame. Deterministic for a seed.
#include <rehearse/imaging/render.hpp>

#include <opencv2/imgproc.hpp>

#include <cmath>

namespace rehearse::imaging {
namespace {

cv::Mat1f valueNoise(int width, int height, cv::RNG& rng, const std::vector<std::pair<int, float>>& octaves) {
  cv::Mat1f sum(height, width, 0.0f);
  float total = 0;
  for (auto [cells, weight] : octaves) {
    cv::Mat1f grid(std::max(2, cells * height / width), cells);
    rng.fill(grid, cv::RNG::UNIFORM, 0.0f, 1.0f);
    cv::Mat1f up;
    cv::resize(grid, up, cv::Size(width, height), 0, 0, cv::INTER_CUBIC);
    sum += weight * up;
    total += weight;
  }
  return sum / total;
}

}  // namespace

cv::Mat3b makeTissueBackground(int width, int height, unsigned seed) {
  cv::RNG rng(seed * 7919u + 17u);
  cv::Mat1f base = valueNoise(width, height, rng, {{6, 1.0f}, {14, 0.6f}, {40, 0.35f}, {120, 0.2f}});
  cv::Mat1f fat = valueNoise(width, height, rng, {{4, 1.0f}, {10, 0.5f}, {30, 0.25f}});
  cv::Mat3f img(height, width);
  const cv::Vec3f wall(72, 80, 172), wallDark(42, 38, 112), fatColour(105, 165, 200);  // BGR
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const float b = base(y, x);
      cv::Vec3f c = wallDark + (wall - wallDark) * std::clamp((b - 0.3f) / 0.4f, 0.0f, 1.0f);
      const float f = 0.8f * std::clamp((fat(y, x) - 0.63f) / 0.10f, 0.0f, 1.0f);
      img(y, x) = c * (1 - f) + fatColour * (0.85f + 0.3f * b) * f;
    }
  // Small vessels: smooth random walks, drawn dark red and blurred.
  cv::Mat3f vessels(height, width, cv::Vec3f(0, 0, 0));
  cv::Mat1f vmask(height, width, 0.0f);
  for (int v = 0; v < 14; ++v) {
    cv::Point2f p(rng.uniform(0.0f, static_cast<float>(width)), rng.uniform(0.0f, static_cast<float>(height)));
    float angle = rng.uniform(0.0f, 6.2832f);
    const float thick = rng.uniform(1.5f, 4.0f) * width / 1280.0f;
    std::vector<cv::Point> pts;
    for (int k = 0; k < 60; ++k) {
      pts.emplace_back(cv::Point(cvRound(p.x), cvRound(p.y)));
      angle += rng.gaussian(0.25);
      p += cv::Point2f(std::cos(angle), std::sin(angle)) * (8.0f * width / 1280.0f);
    }
    cv::polylines(vmask, pts, false, cv::Scalar(1.0), std::max(1, cvRound(thick)), cv::LINE_AA);
  }
  cv::GaussianBlur(vmask, vmask, cv::Size(0, 0), 1.5);
  const cv::Vec3f vesselColour(40, 30, 105);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const float m = std::min(1.0f, vmask(y, x)) * 0.8f;
      img(y, x) = img(y, x) * (1 - m) + vesselColour * m;
    }
  // Illumination from the scope tip: brighter at the centre.
  const float cx = width / 2.0f, cy = height / 2.0f, R = 0.6f * width;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const float r2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (R * R);
      img(y, x) *= 1.15f / (1.0f + 1.6f * r2);
    }
  // Moist glints: a few small elongated highlights, brighter near the centre.
  cv::Mat1f glint(height, width, 0.0f);
  const float s = width / 1280.0f;
  for (int g = 0; g < 45; ++g) {
    cv::Point2f p(rng.uniform(0.0f, static_cast<float>(width)), rng.uniform(0.0f, static_cast<float>(height)));
    const float r2 = ((p.x - cx) * (p.x - cx) + (p.y - cy) * (p.y - cy)) / (R * R);
    cv::ellipse(glint, p, cv::Size2f(rng.uniform(3.0f, 9.0f) * s, rng.uniform(1.0f, 3.0f) * s), rng.uniform(0.0f, 180.0f),
                0, 360, cv::Scalar(200.0 / (1.0 + 2.0 * r2)), -1, cv::LINE_AA);
  }
  cv::GaussianBlur(glint, glint, cv::Size(0, 0), 1.2 * s);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) img(y, x) += cv::Vec3f(glint(y, x), glint(y, x), glint(y, x));
  cv::Mat3b out;
  img.convertTo(out, CV_8UC3);
  return out;
}

void applyScopeVignette(cv::Mat3b& image, double radiusFraction, double softEdgePx) {
  const double cx = (image.cols - 1) / 2.0, cy = (image.rows - 1) / 2.0, R = radiusFraction * image.cols;
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      const double d = std::hypot(x - cx, y - cy);
      const double w = std::clamp((R - d) / softEdgePx, 0.0, 1.0);
      if (w < 1) image(y, x) = image(y, x) * w;
    }
}

}  // namespace rehearse::imaging
