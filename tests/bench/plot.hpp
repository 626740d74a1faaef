#pragma once
// Minimal log-log line/scatter plots written as PNG with OpenCV, for the benchmark reports.
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

struct PlotSeries {
  std::string name;
  std::vector<double> x, y;
  bool lines = true;
};

inline void writeLogLogPlot(const std::string& path, const std::string& title, const std::string& xLabel, const std::string& yLabel,
                            const std::vector<PlotSeries>& series) {
  const int W = 900, H = 620, left = 90, right = 230, top = 70, bottom = 70;
  cv::Mat3b img(H, W, cv::Vec3b(255, 255, 255));
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const auto& s : series)
    for (std::size_t i = 0; i < s.x.size(); ++i)
      if (s.x[i] > 0 && s.y[i] > 0) {
        x0 = std::min(x0, s.x[i]), x1 = std::max(x1, s.x[i]);
        y0 = std::min(y0, s.y[i]), y1 = std::max(y1, s.y[i]);
      }
  if (!(x1 >= x0)) return;
  x0 = std::pow(10, std::floor(std::log10(x0))), x1 = std::pow(10, std::ceil(std::log10(x1) + 1e-9));
  y0 = std::pow(10, std::floor(std::log10(y0))), y1 = std::pow(10, std::ceil(std::log10(y1) + 1e-9));
  auto px = [&](double x) { return left + (W - left - right) * (std::log10(x) - std::log10(x0)) / (std::log10(x1) - std::log10(x0)); };
  auto py = [&](double y) { return H - bottom - (H - top - bottom) * (std::log10(y) - std::log10(y0)) / (std::log10(y1) - std::log10(y0)); };
  const cv::Scalar grid(225, 225, 225), ink(40, 40, 40);
  for (double d = x0; d <= x1 * 1.0001; d *= 10) {
    cv::line(img, {int(px(d)), top}, {int(px(d)), H - bottom}, grid);
    char b[32];
    std::snprintf(b, sizeof b, "%g", d);
    cv::putText(img, b, {int(px(d)) - 12, H - bottom + 20}, cv::FONT_HERSHEY_SIMPLEX, 0.45, ink, 1, cv::LINE_AA);
  }
  for (double d = y0; d <= y1 * 1.0001; d *= 10) {
    cv::line(img, {left, int(py(d))}, {W - right, int(py(d))}, grid);
    char b[32];
    std::snprintf(b, sizeof b, "%g", d);
    cv::putText(img, b, {8, int(py(d)) + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, ink, 1, cv::LINE_AA);
  }
  cv::rectangle(img, {left, top}, {W - right, H - bottom}, ink);
  cv::putText(img, title, {left, 24}, cv::FONT_HERSHEY_SIMPLEX, 0.6, ink, 1, cv::LINE_AA);
  cv::putText(img, xLabel, {left + 150, H - 25}, cv::FONT_HERSHEY_SIMPLEX, 0.5, ink, 1, cv::LINE_AA);
  cv::putText(img, yLabel, {8, top - 12}, cv::FONT_HERSHEY_SIMPLEX, 0.5, ink, 1, cv::LINE_AA);
  static const cv::Scalar colours[] = {{200, 80, 30},  {40, 40, 200}, {40, 160, 40}, {160, 40, 160}, {0, 140, 220},
                                       {120, 120, 0},  {90, 90, 90},  {0, 0, 0},     {200, 0, 120},  {60, 200, 200},
                                       {150, 100, 50}, {50, 100, 150}, {100, 200, 100}, {200, 150, 0}, {0, 80, 80}, {128, 0, 255}};
  for (std::size_t k = 0; k < series.size(); ++k) {
    const auto& s = series[k];
    const cv::Scalar c = colours[k % 16];
    cv::Point prev(-1, -1);
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!(s.x[i] > 0 && s.y[i] > 0)) continue;
      const cv::Point p(int(px(s.x[i])), int(py(s.y[i])));
      cv::circle(img, p, 4, c, cv::FILLED, cv::LINE_AA);
      if (s.lines && prev.x >= 0) cv::line(img, prev, p, c, 2, cv::LINE_AA);
      prev = p;
    }
    const int ly = top + 10 + 20 * static_cast<int>(k);
    cv::circle(img, {W - right + 15, ly - 4}, 4, c, cv::FILLED, cv::LINE_AA);
    cv::putText(img, s.name, {W - right + 25, ly}, cv::FONT_HERSHEY_SIMPLEX, 0.42, ink, 1, cv::LINE_AA);
  }
  cv::imwrite(path, img);
}
