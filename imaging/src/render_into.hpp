#pragma once
// rasterizeCameraFrame (render.hpp) into buffers the caller keeps: a renderer that draws many shapes at one size (the
// compositor) reuses them instead of having two frame-sized buffers allocated, and their pages faulted in, per shape.
#include <rehearse/imaging/render.hpp>

namespace rehearse::imaging {

void rasterizeCameraFrameInto(Rasterization& r, const Camera& camera, const std::vector<Eigen::Vector3d>& cameraPoints,
                              const SurfaceView& surface, int scale, double nearPlane, bool cullBackFaces);

}  // namespace rehearse::imaging
