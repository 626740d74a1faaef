#pragma once
// Image sampling shared by the compositors (compositor.cpp, novelview.cpp): bilinear lookup of a 3-channel image
// at a sub-pixel position (pixel centres at integers), clamped to the image.
#include <opencv2/core.hpp>

#include <algorithm>

namespace rehearse::imaging {

/// A bilinear lookup's four pixels and weights, made once for several images of the same size.
struct BilinearTap {
  int x0, y0, x1, y1;
  float fx, fy;
};

template <typename T>
[[gnu::always_inline]] inline cv::Vec3f bilinear(const cv::Mat_<cv::Vec<T, 3>>& img, const BilinearTap& t) {
  const auto &a = img(t.y0, t.x0), &b = img(t.y0, t.x1), &c = img(t.y1, t.x0), &d = img(t.y1, t.x1);
  cv::Vec3f out;
  for (int k = 0; k < 3; ++k)
    out[k] = (1 - t.fy) * ((1 - t.fx) * static_cast<float>(a[k]) + t.fx * static_cast<float>(b[k])) +
             t.fy * ((1 - t.fx) * static_cast<float>(c[k]) + t.fx * static_cast<float>(d[k]));
  return out;
}

template <typename T>
[[gnu::always_inline]] inline cv::Vec3f bilinear(const cv::Mat_<cv::Vec<T, 3>>& img, double qx, double qy) {
  const double x = std::clamp(qx, 0.0, img.cols - 1.0), y = std::clamp(qy, 0.0, img.rows - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  return bilinear(img, BilinearTap{x0, y0, std::min(x0 + 1, img.cols - 1), std::min(y0 + 1, img.rows - 1),
                                   static_cast<float>(x - x0), static_cast<float>(y - y0)});
}

}  // namespace rehearse::imaging
