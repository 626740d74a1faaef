// A novel view of the estimated organ (appearance_fit.hpp, composeNovelView): the organ through another camera,
// re-shaded with Theta lit by that camera's scope, its albedo looked up where the fitted frame saw it at rest.
#include <rehearse/imaging/appearance_fit.hpp>
#include <rehearse/imaging/render.hpp>

#include "sampling.hpp"

#include <opencv2/core/utility.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace rehearse::imaging {

NovelView composeNovelView(const CompositionInput& in, const Camera& view, const Pose& viewPose,
                           const cv::Mat3b& background, const std::vector<double>& deformedVertices) {
  if (auto p = in.camera.problem(); !p.empty()) throw InputError(p);
  if (auto p = view.problem(); !p.empty()) throw InputError("The view's camera: " + p);
  const cv::Size size(view.width, view.height);
  if (!background.empty() && background.size() != size)
    throw InputError("The view's image is " + std::to_string(background.cols) + "x" + std::to_string(background.rows) +
                     " but the view's camera is calibrated for " + std::to_string(size.width) + "x" +
                     std::to_string(size.height) + "; give the image that camera took.");
  if (in.frame.size() != cv::Size(in.camera.width, in.camera.height))
    throw InputError("The frame's size is not the camera's.");
  if (!in.textureOnly && in.albedo.size() != in.frame.size())
    throw InputError("The albedo's size is not the camera's.");
  if (!(in.trust >= 0 && in.trust <= 1))
    throw InputError("The share of the model's change to apply (the fit's trust) must be within 0 and 1.");
  const SurfaceView& rest = in.rest;
  SurfaceView shape = rest;
  if (!deformedVertices.empty()) {
    if (deformedVertices.size() != 3 * rest.vertexCount)
      throw InputError("The deformed organ has " + std::to_string(deformedVertices.size() / 3) +
                       " nodes, the registered one " + std::to_string(rest.vertexCount) + ".");
    shape.vertices = deformedVertices.data();
  }
  // What the fitted frame saw of the organ at rest (its depth), and the organ through the view.
  const Rasterization fittedSeen = rasterize(in.camera, in.pose, rest, 1);
  // Texture only: tissue the fitted frame never showed (hidden there, or beyond its border) takes the organ's mean
  // colour in that frame, as the compositor's does, not the background through the organ.
  const cv::Vec3f unseenColour = in.textureOnly ? meanOrganColour(in.frame, fittedSeen.triangle) : cv::Vec3f();
  // What the model leaves of the fitted frame (Compositor::frameResidual), carried with the tissue it was seen on.
  cv::Mat3f residual;
  if (!in.textureOnly && in.frameDetail) {
    CompositionInput atRest = in;
    atRest.deformed = atRest.rest;
    if (atRest.background.size() != atRest.frame.size()) atRest.background = atRest.frame;
    residual = Compositor(atRest).frameResidual();
  }
  // The view's own pose is what is wrong when the organ is behind it or out of it (said as such: a person read "the
  // organ lies behind the camera" and looked at the frame's pose; an organ off the view gave a black picture, unsaid).
  bool inFront = false, behind = false;
  Eigen::AlignedBox3d box;
  for (std::size_t i = 0; i < shape.vertexCount; ++i) {
    const Eigen::Vector3d p = viewPose.apply(shape.vertex(i));
    inFront |= p.z() > 1e-3;
    behind |= p.z() <= 1e-3;
    box.extend(p);
  }
  if (!inFront)
    throw InputError("The organ lies behind the view's camera at the view's pose; check that pose (z must be positive "
                     "in the view camera's frame).");
  // A camera among the organ's own points (some in front of it, some behind, the lens within their extent) would
  // draw a cut through the tissue as if it were the organ (a person's pose put it 5 cm into the organ: drawn, unsaid).
  if (behind && box.contains(Eigen::Vector3d::Zero()))
    throw InputError("The view's camera lies inside the organ at the view's pose; check that pose (the organ must lie "
                     "wholly in front of the camera).");
  const SurfaceGeometry g = surfaceGeometry(view, viewPose, shape);
  if (cv::countNonZero(g.triangle >= 0) == 0)
    throw InputError("The organ is not in the view at the view's pose; check that pose.");
  // Which side of each triangle each camera faces (the sign of its normal against the line of sight, whatever the
  // winding): a view that sees a triangle from the other side than the fitted frame did sees the back of an open
  // surface, which the frame never showed (a person saw the frame's texture mirrored on an open CT surface's back).
  std::vector<char> otherSide(rest.triangleCount, 0);
  for (std::size_t t = 0; t < rest.triangleCount; ++t) {
    auto facing = [&](const SurfaceView& s, const Pose& p) {
      const int* tri = s.triangles + 3 * t;
      const Eigen::Vector3d a = p.apply(s.vertex(static_cast<std::size_t>(tri[0]))),
                            b = p.apply(s.vertex(static_cast<std::size_t>(tri[1]))),
                            c = p.apply(s.vertex(static_cast<std::size_t>(tri[2])));
      return (b - a).cross(c - a).dot(a) < 0;
    };
    otherSide[t] = facing(rest, in.pose) != facing(shape, viewPose);
  }
  // The scope's light moves with the view; a second source is the scene's (appearance.hpp): its direction, fixed to
  // the organ's surroundings, turned from the fitted camera's frame into the view's.
  Appearance theta = in.theta;
  theta.roomDirection = viewPose.R * (in.pose.R.transpose() * in.theta.roomDirection);
  NovelView out;
  out.image = background.empty() ? cv::Mat3b(size, cv::Vec3b(0, 0, 0)) : background.clone();
  out.covered = cv::Mat1b(size, uchar(0));
  out.seen = cv::Mat1b(size, uchar(0));
  cv::parallel_for_(cv::Range(0, size.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < size.width; ++x) {
        const int t = g.triangle(y, x);
        if (t < 0) continue;
        const cv::Vec3f w = g.barycentric(y, x);
        const int* tri = rest.triangles + 3 * t;
        const Eigen::Vector3d atRest = w[0] * rest.vertex(static_cast<std::size_t>(tri[0])) +
                                       w[1] * rest.vertex(static_cast<std::size_t>(tri[1])) +
                                       w[2] * rest.vertex(static_cast<std::size_t>(tri[2]));
        // Where the fitted frame had that point, and whether it saw it (the nearest surface there, within 2 mm).
        const Eigen::Vector3d c = in.pose.apply(atRest);
        bool seen = false;
        double qx = 0, qy = 0;
        if (c.z() > 1e-3 && !otherSide[static_cast<std::size_t>(t)]) {
          const Eigen::Vector2d q = in.camera.project(c);
          qx = q.x(), qy = q.y();
          const int ix = static_cast<int>(std::lround(qx)), iy = static_cast<int>(std::lround(qy));
          if (ix >= 0 && iy >= 0 && ix < in.camera.width && iy < in.camera.height && fittedSeen.triangle(iy, ix) >= 0)
            seen = fittedSeen.depth(iy, ix) > c.z() - 0.002;
        }
        if (seen) out.seen(y, x) = 255;
        if (in.textureOnly) {
          const cv::Vec3f bgr = seen ? bilinear(in.frame, qx, qy) : unseenColour;
          out.image(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(bgr[0]), cv::saturate_cast<uchar>(bgr[1]),
                                      cv::saturate_cast<uchar>(bgr[2]));
          out.covered(y, x) = 255;
          continue;
        }
        const cv::Vec3f albedo = seen ? bilinear(in.albedo, qx, qy) : cv::Vec3f(1, 1, 1);
        const cv::Vec3f carried = seen && !residual.empty() ? bilinear(residual, qx, qy) : cv::Vec3f(0, 0, 0);
        const cv::Vec3f pf = g.position(y, x), nf = g.normal(y, x);
        double diffuse, specular;
        const Eigen::Vector3d normal(nf[0], nf[1], nf[2]);
        theta.terms(Eigen::Vector3d(pf[0], pf[1], pf[2]), normal, diffuse, specular);
        const Eigen::Vector3d second = theta.secondSource(normal);
        // The model's change applied as far as the fit earned it (CompositionInput::trust): the rest is the frame's
        // own colour where it saw the point.
        const double trust = seen ? in.trust : 1.0;
        const cv::Vec3f own = trust < 1 ? bilinear(in.frame, qx, qy) : cv::Vec3f(0, 0, 0);
        cv::Vec3b& o = out.image(y, x);
        for (int k = 0; k < 3; ++k) {
          const double model =
              std::min(255.0 * (albedo[k] * (theta.kd[2 - k] * diffuse + second[2 - k]) + theta.ks[2 - k] * specular),
                       255.0) +
              carried[k];
          o[k] = cv::saturate_cast<uchar>(std::min(trust * model + (1 - trust) * own[k], 255.0));
        }
        out.covered(y, x) = 255;
      }
  });
  return out;
}

}  // namespace rehearse::imaging
