#pragma once
// CPU reference rendering of a triangle surface through a pinhole camera (undistorted image).
// Used to make the phantom frame, the software viewport, silhouettes and masks.
#include <rehearse/imaging/appearance.hpp>
#include <rehearse/imaging/camera.hpp>

#include <opencv2/core.hpp>

#include <optional>
#include <vector>

namespace rehearse::imaging {

/// Per-pixel visibility: nearest triangle id (-1 for none) and its depth (camera z, metres).
struct Rasterization {
  cv::Mat1i triangle;
  cv::Mat1f depth;
  int scale = 1;  ///< supersampling factor the buffers were made with
};

/// Rasterises the surface (vertices in model frame, metres) posed by `pose`; `scale` > 1 supersamples.
/// Triangles crossing the plane z = nearPlane are dropped. Throws InputError for a bad camera.
Rasterization rasterize(const Camera& camera, const Pose& pose, const SurfaceView& surface, int scale = 1,
                        double nearPlane = 1e-3);

/// The same for vertices already in the camera frame (one per surface vertex): for renderers that move the
/// surface themselves (the compositor). `cullBackFaces`: triangles facing away from the camera are not drawn
/// (right for a closed surface whose triangles wind outward, where they are hidden anyway: half the work).
Rasterization rasterizeCameraFrame(const Camera& camera, const std::vector<Eigen::Vector3d>& cameraPoints,
                                   const SurfaceView& surface, int scale = 1, double nearPlane = 1e-3,
                                   bool cullBackFaces = false);

/// Whether a surface is closed and wound outward (what back-face culling needs): every edge shared by exactly two
/// triangles that run it in opposite directions, and a positive enclosed volume; or nearly: the edges that are not
/// (borders, a triangle turned over, a non-manifold edge) sum to at most 4 % of the square root of its area: the
/// widest opening they could leave (half their length) at most 2 % of the organ's size. A real organ's surface often
/// has a few such defects (the scikit-surgery kidney: a missing triangle and a turned one, 7 edges, 3.1 mm for a
/// surface of 139 mm squared: 1.1 %): culled, what shows through such an opening is the background instead of the
/// organ's inside; not culled, the composition rasterises twice the triangles and its back faces could take the
/// frame's colours.
bool closedAndOutward(const std::vector<Eigen::Vector3d>& points, const SurfaceView& surface);

/// Smooth unit vertex normals (area-weighted face normals; (0, 0, -1) for a vertex of no area).
std::vector<Eigen::Vector3d> vertexNormals(const std::vector<Eigen::Vector3d>& points, const SurfaceView& surface);

/// What the camera sees through one pixel: the nearest surface point on the ray (the triangle a depth buffer
/// would keep there, without rasterising the frame).
struct SurfacePick {
  int triangle = -1;
  double depth = 0;                                ///< camera z, metres
  Eigen::Vector3d model = Eigen::Vector3d::Zero();  ///< the point in the model frame
  int nearestVertex = -1;                           ///< the triangle's vertex nearest to it
};

/// Casts the ray through `pixel` (undistorted image coordinates, pixel centres at integers) against every
/// triangle in front of z = nearPlane; nothing when it misses. Throws InputError for a bad camera.
std::optional<SurfacePick> pickSurface(const Camera& camera, const Pose& pose, const SurfaceView& surface,
                                       const Eigen::Vector2d& pixel, double nearPlane = 1e-3);

/// What the camera sees of the surface at every pixel centre: the nearest triangle (-1 for none), the
/// camera-frame point and smooth (area-weighted vertex) unit normal there, and the point's barycentric
/// coordinates in its triangle (for texture lookups). Camera frame, metres.
struct SurfaceGeometry {
  cv::Mat1i triangle;
  cv::Mat3f position;
  cv::Mat3f normal;
  cv::Mat3f barycentric;
  cv::Mat1b mask() const { return triangle >= 0; }
};
/// The surface's geometry through the camera at `scale` times its resolution. Throws InputError for a bad
/// camera or when no vertex is in front of the camera.
SurfaceGeometry surfaceGeometry(const Camera& camera, const Pose& pose, const SurfaceView& surface, int scale = 1);

/// 8-bit mask (255 where the surface covers the pixel centre) at the camera's resolution.
cv::Mat1b renderMask(const Camera& camera, const Pose& pose, const SurfaceView& surface, int scale = 1);

/// Torrance-Sparrow render (appearance.hpp) of the surface over `background` (8-bit BGR, camera size),
/// with smooth vertex normals; `scale` > 1 supersamples edges. Returns 8-bit BGR.
cv::Mat3b renderShaded(const Camera& camera, const Pose& pose, const SurfaceView& surface, const Appearance& appearance,
                       const cv::Mat3b& background, int scale = 2);

/// Simple headlight grey shading (for overlays), alpha 255 where covered. Returns 8-bit BGRA.
cv::Mat4b renderOverlay(const Camera& camera, const Pose& pose, const SurfaceView& surface, const cv::Vec3b& colourBgr);

/// Intersection over union of two masks of the same size.
double maskIoU(const cv::Mat1b& a, const cv::Mat1b& b);

/// Procedural tissue background (abdominal wall, fat, small vessels) for the phantom frame: deterministic for a seed.
cv::Mat3b makeTissueBackground(int width, int height, unsigned seed);
/// Darkens outside the circular field of view of a scope (radius as a fraction of the image width).
void applyScopeVignette(cv::Mat3b& image, double radiusFraction = 0.56, double softEdgePx = 18);

}  // namespace rehearse::imaging
