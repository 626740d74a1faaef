// The fit's public entry points (appearance_fit.hpp): the usable pixels, the specular separation, inpainting, the
// driver of fitAppearance's stages (appearance_fit_stages.hpp), and the per-frame shares, albedo and PSNR.
#include <rehearse/imaging/appearance_fit.hpp>

#include "appearance_fit_stages.hpp"

#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>
#include <opencv2/xphoto/inpainting.hpp>

#include <algorithm>
#include <array>
#include <cmath>

namespace rehearse::imaging {

using detail::Light;
using detail::median;
using detail::Projected;
using detail::Sample;

cv::Mat1b usablePixels(const cv::Mat3b& frame, const cv::Mat1b& organ, int borderPx) {
  if (frame.size() != organ.size()) throw InputError("The frame and the organ's mask differ in size.");
  cv::Mat1b out;
  cv::erode(organ, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));  // the rim mixes organ and background
  std::vector<cv::Mat1b> ch;
  cv::split(frame, ch);
  cv::Mat1b saturated = (ch[0] >= 250) & (ch[1] >= 250) & (ch[2] >= 250);  // a clipped channel alone is dropped per sample
  out.setTo(0, saturated);
  // The scope's dark border: near-black pixels connected to the image's edge.
  cv::Mat1b grey;
  cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
  cv::Mat1b dark = grey < 10;
  cv::Mat1i labels;
  const int n = cv::connectedComponents(dark, labels, 8, CV_32S);
  std::vector<char> touches(static_cast<std::size_t>(n), 0);
  for (int x = 0; x < labels.cols; ++x) touches[labels(0, x)] = touches[labels(labels.rows - 1, x)] = 1;
  for (int y = 0; y < labels.rows; ++y) touches[labels(y, 0)] = touches[labels(y, labels.cols - 1)] = 1;
  cv::Mat1b border(frame.size(), uchar(0));
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x)
      if (labels(y, x) > 0 && touches[labels(y, x)]) border(y, x) = 255;
  if (borderPx > 0 && cv::countNonZero(border) > 0)
    cv::dilate(border, border, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * borderPx + 1, 2 * borderPx + 1)));
  out.setTo(0, border);
  return out;
}

SpecularSeparation separateSpecular(const cv::Mat3b& frame, const cv::Mat1b& organ) {
  SpecularSeparation s;
  s.highlights = cv::Mat1b(frame.size(), uchar(0));
  s.diffuse = frame.clone();
  // The organ's diffuse chromaticity: which channel is typically its largest, middle and smallest, and the
  // median ratios smallest / largest (r) and smallest / middle (q). A pixel c = D chroma + S (1, 1, 1) has
  // c_min - r c_max = S (1 - r): its specular part S; where the largest channel is clipped, the middle one
  // stands in (c_min - q c_mid = S (1 - q)).
  cv::Scalar meanColour = cv::mean(frame, organ);
  std::array<int, 3> order{0, 1, 2};  // BGR indices, largest first
  std::sort(order.begin(), order.end(), [&](int a, int b) { return meanColour[a] > meanColour[b]; });
  const int hiC = order[0], midC = order[1], loC = order[2];
  std::vector<double> ratios, midRatios;
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x)
      if (organ(y, x)) {
        const cv::Vec3b c = frame(y, x);
        if (c[hiC] >= 20 && c[hiC] < 250) ratios.push_back(static_cast<double>(c[loC]) / c[hiC]);
        if (c[midC] >= 20 && c[midC] < 250) midRatios.push_back(static_cast<double>(c[loC]) / c[midC]);
      }
  if (ratios.size() < 20) return s;
  const double r = std::min(median(ratios), 0.9), q = midRatios.size() >= 20 ? median(midRatios) : 1.0;
  cv::Mat1f spec(frame.size(), 0.0f);
  std::vector<double> values;
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x)
      if (organ(y, x)) {
        const cv::Vec3b c = frame(y, x);
        double v = 0;
        if (c[hiC] < 250) v = (c[loC] - r * c[hiC]) / (1 - r);
        else if (q < 0.9) v = (c[loC] - q * c[midC]) / (1 - q);
        else v = c[loC] >= 250 ? 255.0 : 0.0;  // a grey organ's clipped pixel: specular only when all channels clip
        v = std::max(0.0, v);
        spec(y, x) = static_cast<float>(v);
        values.push_back(v);
      }
  const double med = median(values);
  std::vector<double> dev(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) dev[i] = std::abs(values[i] - med);
  const double floor = med + std::max(10.0, 5 * 1.4826 * median(dev));
  cv::Mat1b peak = (spec > floor) & organ;
  cv::morphologyEx(peak, peak, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(3, 3)));  // isolated pixels are noise
  cv::Mat1i labels;
  s.blobs = std::max(0, cv::connectedComponents(peak, labels, 8, CV_32S) - 1);
  if (s.blobs == 0) return s;
  // The highlight: the peaks and the lobe around them where the specular part is above the noise.
  cv::Mat1b lobe = (spec > med + std::max(3.0, 2 * 1.4826 * median(dev))) & organ;
  cv::dilate(peak, s.highlights, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(15, 15)));
  s.highlights &= lobe;
  s.highlights |= peak;
  s.count = cv::countNonZero(s.highlights);
  // I_D: the specular part taken off every channel; clipped pixels (whose true value is unknown) filled.
  cv::Mat1b clipped(frame.size(), uchar(0));
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x) {
      if (!s.highlights(y, x)) continue;
      cv::Vec3b& d = s.diffuse(y, x);
      const cv::Vec3b c = frame(y, x);
      if (std::max({c[0], c[1], c[2]}) >= 250) clipped(y, x) = 255;
      for (int k = 0; k < 3; ++k) d[k] = cv::saturate_cast<uchar>(c[k] - spec(y, x));
    }
  if (cv::countNonZero(clipped) > 0) {
    cv::dilate(clipped, clipped, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
    cv::Mat3b filled;
    cv::inpaint(s.diffuse, clipped, filled, 5, cv::INPAINT_TELEA);
    s.diffuse = filled;
  }
  return s;
}

InpaintMethod parseInpaintMethod(const std::string& name) {
  if (name == "telea") return InpaintMethod::Telea;
  if (name == "ns") return InpaintMethod::NavierStokes;
  if (name == "shiftmap") return InpaintMethod::ShiftMap;
  if (name == "fsr") return InpaintMethod::FsrFast;
  throw InputError("Unknown inpainting method '" + name + "'; choose telea, ns, shiftmap or fsr.");
}

const char* inpaintMethodName(InpaintMethod m) {
  switch (m) {
    case InpaintMethod::Telea: return "telea";
    case InpaintMethod::NavierStokes: return "ns";
    case InpaintMethod::ShiftMap: return "shiftmap";
    case InpaintMethod::FsrFast: return "fsr";
  }
  return "telea";
}

cv::Mat3b inpaintRegion(const cv::Mat3b& frame, const cv::Mat1b& region, InpaintMethod method, int growPx) {
  if (frame.size() != region.size()) throw InputError("The frame and the region to fill differ in size.");
  cv::Mat1b hole = region.clone();
  if (growPx > 0) cv::dilate(hole, hole, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * growPx + 1, 2 * growPx + 1)));
  const int holePixels = cv::countNonZero(hole);
  if (holePixels == 0) return frame.clone();
  // A large hole (an organ filling much of a full-HD frame) is filled at half resolution: what diffusion
  // puts there is smooth anyway, and it costs a quarter; the pixels outside the hole stay the frame's own.
  if (holePixels > 150000 && (method == InpaintMethod::Telea || method == InpaintMethod::NavierStokes)) {
    cv::Mat3b small, filled, up;
    cv::Mat1b smallHole;
    cv::resize(frame, small, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
    cv::resize(hole, smallHole, small.size(), 0, 0, cv::INTER_NEAREST);
    cv::dilate(smallHole, smallHole, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)));
    cv::inpaint(small, smallHole, filled, 3, method == InpaintMethod::Telea ? cv::INPAINT_TELEA : cv::INPAINT_NS);
    cv::resize(filled, up, frame.size(), 0, 0, cv::INTER_LINEAR);
    cv::Mat3b out = frame.clone();
    up.copyTo(out, hole);
    return out;
  }
  cv::Mat3b out;
  switch (method) {
    case InpaintMethod::Telea: cv::inpaint(frame, hole, out, 5, cv::INPAINT_TELEA); break;
    case InpaintMethod::NavierStokes: cv::inpaint(frame, hole, out, 5, cv::INPAINT_NS); break;
    case InpaintMethod::ShiftMap:
    case InpaintMethod::FsrFast: {
      // xphoto marks the known pixels (non-zero), not the hole.
      cv::Mat1b known = hole == 0;
      cv::Mat work = frame.clone(), result;
      if (method == InpaintMethod::ShiftMap) {
        cv::Mat lab;
        cv::cvtColor(frame, lab, cv::COLOR_BGR2Lab);  // shift-map works on Lab images
        cv::xphoto::inpaint(lab, known, result, cv::xphoto::INPAINT_SHIFTMAP);
        cv::cvtColor(result, result, cv::COLOR_Lab2BGR);
      } else {
        cv::xphoto::inpaint(work, known, result, cv::xphoto::INPAINT_FSR_FAST);
      }
      out = result;
      break;
    }
  }
  return out;
}

void detail::AppearanceFitter::findUsablePixels() {
  const cv::Mat1b organ = in_.g.mask();
  res_.usable = usablePixels(in_.frame, organ);
  if (cv::countNonZero(res_.usable) < 200)
    throw InputError("The organ covers fewer than 200 usable pixels of the frame (outside the scope's view, saturated or too small); check the pose and the frame.");
}

AppearanceFitResult fitAppearance(const cv::Mat3b& frame, const SurfaceGeometry& g, const AppearanceFitOptions& o) {
  if (frame.empty() || frame.size() != g.triangle.size()) throw InputError("The frame and the organ's geometry differ in size; use the camera of this frame.");
  detail::AppearanceFitter fit(frame, g, o);
  fit.findUsablePixels();
  fit.lightFromHighlights();  // stage 1
  fit.fitLightAndDiffuse();   // stage 2
  fit.fitSpecular();          // stage 3
  fit.fillUnmeasuredKs();
  fit.deliverTheta();
  fit.measureShares();
  fit.fitSecondSource();
  fit.writeStatus();
  return fit.finish();
}

double diffuseShareAt(const cv::Mat3b& diffuse, const SurfaceGeometry& geometry, const cv::Mat1b& use, const Appearance& start,
                      std::size_t maxSamples, int evaluations, Appearance* refined) {
  if (diffuse.size() != geometry.triangle.size() || use.size() != geometry.triangle.size())
    throw InputError("The image, the pixels to use and the organ's geometry differ in size.");
  const std::vector<Sample> samples = detail::collect(diffuse, geometry, use & geometry.mask(), maxSamples);
  if (samples.size() < 50) return 0;
  Light light{start.lightPosition, start.falloff};
  double sigma = 0.1;
  if (evaluations > 0) detail::refine(samples, light, sigma, false, {}, evaluations);  // keeps the start unless it ends finite
  Eigen::VectorXd r;
  const Projected p = detail::solveLinear(samples, light, sigma, false, &r);
  if (refined) {
    *refined = start;
    refined->lightPosition = light.position;
    refined->falloff = light.falloff;
    refined->kd = p.kd;
  }
  return std::clamp(detail::explainedShare(samples, r), -1.0, 1.0);
}

cv::Mat3f albedoRatio(const cv::Mat3b& diffuse, const SurfaceGeometry& rest, const Appearance& theta, const cv::Mat1b& usable) {
  cv::Mat3f out(diffuse.size(), cv::Vec3f(1, 1, 1));
  double peak = 0;
  for (int y = 0; y < diffuse.rows; ++y)
    for (int x = 0; x < diffuse.cols; ++x) {
      if (rest.triangle(y, x) < 0) continue;
      const cv::Vec3f p = rest.position(y, x), n = rest.normal(y, x);
      Sample s{Eigen::Vector3d(p[0], p[1], p[2]), Eigen::Vector3d(n[0], n[1], n[2]), Eigen::Vector3d::Zero()};
      double d, sp;
      detail::basis(s, Light{theta.lightPosition, theta.falloff}, theta.roughness, d, sp);
      peak = std::max(peak, (theta.kd * d + theta.secondSource(s.n)).maxCoeff());
    }
  for (int y = 0; y < diffuse.rows; ++y)
    for (int x = 0; x < diffuse.cols; ++x) {
      if (rest.triangle(y, x) < 0 || !usable(y, x)) continue;
      const cv::Vec3f p = rest.position(y, x), n = rest.normal(y, x);
      Sample s{Eigen::Vector3d(p[0], p[1], p[2]), Eigen::Vector3d(n[0], n[1], n[2]), Eigen::Vector3d::Zero()};
      double d, sp;
      detail::basis(s, Light{theta.lightPosition, theta.falloff}, theta.roughness, d, sp);
      // The diffuse shading of both sources (the albedo scales a second source's as it scales the scope's).
      const Eigen::Vector3d shading = theta.kd * d + theta.secondSource(s.n);
      if (shading.maxCoeff() < 0.05 * peak) continue;
      const cv::Vec3b c = diffuse(y, x);
      for (int k = 0; k < 3; ++k) {
        const double lit = shading[2 - k];  // BGR pixel, RGB shading
        if (lit > 0) out(y, x)[k] = static_cast<float>(std::clamp(c[k] / 255.0 / lit, 0.0, 5.0));
      }
    }
  return out;
}

cv::Mat3b compose(const CompositionInput& in, int scale) { return Compositor(in).compose(in.deformed, scale); }

double psnr(const cv::Mat3b& a, const cv::Mat3b& b, const cv::Mat1b& mask) {
  if (a.size() != b.size()) throw InputError("Images of different sizes cannot be compared.");
  double sum = 0;
  std::size_t n = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      if (!mask.empty() && !mask(y, x)) continue;
      for (int k = 0; k < 3; ++k) {
        const double d = static_cast<double>(a(y, x)[k]) - b(y, x)[k];
        sum += d * d;
      }
      n += 3;
    }
  if (n == 0) return 0;
  const double mse = sum / static_cast<double>(n);
  return mse > 0 ? 10 * std::log10(255.0 * 255.0 / mse) : 99.0;
}

}  // namespace rehearse::imaging
