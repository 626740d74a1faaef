#include "rehearse/app/appearancestep.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>

namespace rehearse::app {
namespace {

// What composition takes from the frame at rest: the background behind the organ and the albedo.
void restLayers(const AppearanceInput& in, const imaging::SurfaceGeometry& g, const imaging::Appearance& theta, const cv::Mat3b& diffuse,
                const cv::Mat1b& usable, cv::Mat3b& background, cv::Mat3f& albedo, double* inpaintMs = nullptr) {
  const auto t0 = std::chrono::steady_clock::now();
  background = imaging::inpaintRegion(in.frame, g.mask(), in.inpaint);
  if (inpaintMs) *inpaintMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  albedo = imaging::albedoRatio(diffuse, g, theta, usable);
}

// The organ's geometry at rest, refusing an organ the frame does not show.
imaging::SurfaceGeometry restGeometry(const AppearanceInput& in) {
  if (in.frame.empty()) throw imaging::InputError("There is no frame to estimate the appearance from; grab a frame first (step 2).");
  if (in.frame.cols != in.camera.width || in.frame.rows != in.camera.height)
    throw imaging::InputError("The frame is " + std::to_string(in.frame.cols) + "x" + std::to_string(in.frame.rows) + " but the camera is calibrated for " +
                              std::to_string(in.camera.width) + "x" + std::to_string(in.camera.height) + "; use the camera of this frame.");
  if (in.triangles.empty()) throw imaging::InputError("The organ has no surface; load the organ first (step 1).");
  imaging::SurfaceGeometry g = imaging::surfaceGeometry(in.camera, in.pose, in.surface());
  if (cv::countNonZero(g.mask()) == 0) throw imaging::InputError("The organ is not in the frame at this pose; align it first (step 4).");
  return g;
}

}  // namespace

AppearanceOutput runAppearance(const AppearanceInput& in) {
  const auto t0 = std::chrono::steady_clock::now();
  auto since = [](auto a) { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count(); };
  const imaging::SurfaceGeometry g = restGeometry(in);
  AppearanceOutput out;
  imaging::AppearanceFitOptions o;
  o.progress = [&](double share, const std::string& what) { return !in.progress || in.progress(0.8 * share, what); };
  out.fit = imaging::fitAppearance(in.frame, g, o);
  if (in.progress && !in.progress(0.8, "filling the background behind the organ")) throw imaging::AppearanceCancelled();
  restLayers(in, g, out.fit.theta, out.fit.separation.diffuse, out.fit.usable, out.background, out.albedo, &out.inpaintMs);
  const cv::Mat3b rest = composeAppearance(in, out.fit.theta, out.background, out.albedo, out.fit.textureOnly, {}, 1);  // the rim is not measured: no supersampling
  cv::Mat1b inner;
  cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  out.restPsnr = imaging::psnr(in.frame, rest, inner);
  out.totalMs = since(t0);
  if (in.progress) in.progress(1.0, "done");
  return out;
}

cv::Mat3b composeAppearance(const AppearanceInput& in, const imaging::Appearance& theta, const cv::Mat3b& background, const cv::Mat3f& albedo,
                            bool textureOnly, const std::vector<double>& deformedVertices, int supersampling) {
  if (!deformedVertices.empty() && deformedVertices.size() != in.vertices.size())
    throw imaging::InputError("The deformed organ has " + std::to_string(deformedVertices.size() / 3) + " nodes, the registered one " +
                              std::to_string(in.vertices.size() / 3) + "; they must be the same mesh in the same order.");
  imaging::CompositionInput c;
  c.camera = in.camera;
  c.pose = in.pose;
  c.rest = in.surface();
  c.deformed = c.rest;
  if (!deformedVertices.empty()) c.deformed.vertices = deformedVertices.data();
  c.frame = in.frame;
  c.background = background;
  c.albedo = albedo;
  c.theta = theta;
  c.textureOnly = textureOnly;
  return imaging::compose(c, supersampling);
}

cv::Mat3b composeWithTheta(const AppearanceInput& in, const imaging::Appearance& theta, const std::vector<double>& deformedVertices) {
  const imaging::SurfaceGeometry g = restGeometry(in);
  const cv::Mat1b usable = imaging::usablePixels(in.frame, g.mask());
  cv::Mat3b background;
  cv::Mat3f albedo;
  restLayers(in, g, theta, imaging::separateSpecular(in.frame, usable).diffuse, usable, background, albedo);
  return composeAppearance(in, theta, background, albedo, false, deformedVertices);
}

}  // namespace rehearse::app
