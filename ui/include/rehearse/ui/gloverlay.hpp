#pragma once
// The organ drawn through the frame's camera with OpenGL, off screen, for the frame view's overlay: the
// same picture as imaging::renderOverlay (smooth vertex normals, shade 0.25 + 0.75 |n . view|, opaque where
// the organ is, transparent elsewhere), made by the GPU (or Mesa) instead of the CPU rasteriser.
#include <rehearse/imaging/camera.hpp>
#include <rehearse/types.hpp>

#include <QColor>
#include <QImage>

#include <memory>

namespace rehearse::ui {

class GLOverlay {
 public:
  GLOverlay();
  ~GLOverlay();
  GLOverlay(const GLOverlay&) = delete;
  GLOverlay& operator=(const GLOverlay&) = delete;
  /// False when no OpenGL 3.3 context could be made (then render() always fails).
  bool valid() const;
  /// The overlay (Format_RGBA8888, the camera's size). False when OpenGL failed; `out` is then unchanged.
  bool render(const imaging::Camera& camera, const Pose& pose, const SurfaceView& surface, const QColor& colour, QImage& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> d_;
};

}  // namespace rehearse::ui
