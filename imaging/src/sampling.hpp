#pragma once
// Image sampling shared by the compositors (compositor.cpp, novelview.cpp): bilinear lookup of a 3-channel image
// at a sub-pixel position (pixel centres at integers), clamped to the image.
#include <opencv2/core.hpp>

#include <algorithm>

namespace rehearse::imaging {

template <typename T>
[[gnu::always_inline]] inline cv::Vec3f bilinear(const cv::Mat_<cv::Vec<T, 3>>& img, double qx, double qy) {
  const double x = std::clamp(qx, 0.0, img.cols - 1.0), y = std::clamp(qy, 0.0, img.rows - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, img.cols - 1), y1 = std::min(y0 + 1, img.rows - 1);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const auto &a = img(y0, x0), &b = img(y0, x1), &c = img(y1, x0), &d = img(y1, x1);
  cv::Vec3f out;
  for (int k = 0; k < 3; ++k)
    out[k] = (1 - fy) * ((1 - fx) * static_cast<float>(a[k]) + fx * static_cast<float>(b[k])) +
             fy * ((1 - fx) * static_cast<float>(c[k]) + fx * static_cast<float>(d[k]));
  return out;
}

}  // namespace rehearse::imaging
