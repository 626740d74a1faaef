#pragma once
// The composition J (imaging::Compositor, the CPU reference) drawn with OpenGL off screen: the background
// I_B as a textured quad, then the deformed organ with a fragment shader evaluating Theta's model at each
// fragment from the interpolated camera-frame point and normal, the albedo and frame textures looked up at
// the point's rest projection, the rest depth deciding what the frame saw; edges by 4x multisampling.
// For the GUI's composited view where a context can be made; the CPU compositor remains the headless path
// (tests, `rehearse compose`, offscreen). test_gl compares the two (PSNR >= 35 dB).
#include <rehearse/imaging/appearance_fit.hpp>

#include <QImage>

#include <memory>
#include <vector>

namespace rehearse::ui {

class GLCompositor {
 public:
  GLCompositor();
  ~GLCompositor();
  GLCompositor(const GLCompositor&) = delete;
  GLCompositor& operator=(const GLCompositor&) = delete;
  /// False when no OpenGL 3.3 context could be made (then every call fails).
  bool valid() const;
  /// True when the context is a software rasteriser (Mesa's llvmpipe, softpipe, swrast): there the shaded
  /// fragments cost CPU time on the calling thread, and the CPU compositor on a worker is the better path.
  bool softwareRenderer() const;
  /// Uploads the organ at rest and its layers (everything in `rest` but `deformed`). False when OpenGL failed.
  bool prepare(const imaging::CompositionInput& rest);
  /// J (Format_RGB888, the camera's size) for the organ moved to `deformedVertices` (model frame, 3n,
  /// the rest's vertex order; empty: at rest), with `samples` x multisampling. False when OpenGL failed or
  /// the shape is another mesh's.
  bool compose(const std::vector<double>& deformedVertices, QImage& out, int samples = 4);
  /// The background alone through the same path and read-back (the reference cost of a frame).
  bool drawBackgroundOnly(QImage& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> d_;
};

}  // namespace rehearse::ui
