#pragma once
// What the off-screen OpenGL renderers of the frame view share (GLOverlay, GLCompositor): an OpenGL 3.3
// core context on an off-screen surface, and the frame camera's projection.
#include <rehearse/imaging/camera.hpp>

#include <QGuiApplication>
#include <QMatrix4x4>
#include <QOffscreenSurface>
#include <QOpenGLContext>

#include <algorithm>

namespace rehearse::ui {

/// Makes `context` an OpenGL 3.3 core context on `surface` and makes it current; false when none can be
/// made (Qt's offscreen and minimal platforms have none).
inline bool makeOffscreenContext(QOpenGLContext& context, QOffscreenSurface& surface) {
  const QString platform = QGuiApplication::platformName();
  if (platform == QLatin1String("offscreen") || platform == QLatin1String("minimal")) return false;
  QSurfaceFormat f;
  f.setVersion(3, 3);
  f.setProfile(QSurfaceFormat::CoreProfile);
  context.setFormat(f);
  if (!context.create()) return false;
  const auto got = context.format();
  if (got.majorVersion() < 3 || (got.majorVersion() == 3 && got.minorVersion() < 3)) return false;
  surface.setFormat(got);
  surface.create();
  return context.makeCurrent(&surface);
}

/// The frame camera as an OpenGL projection of camera-frame points with depths in [zMin, zMax] (m): OpenCV's
/// pinhole (pixel centres at integers, y down) to clip space, pixel u's centre at window u + 0.5.
inline QMatrix4x4 pinholeProjection(const imaging::Camera& camera, double zMin, double zMax) {
  const double W = camera.width, H = camera.height, fx = camera.K(0, 0), sk = camera.K(0, 1), fy = camera.K(1, 1);
  const double nearZ = std::max(1e-3, 0.5 * std::max(zMin, 1e-3)), farZ = 2.0 * zMax + 1e-3;
  return QMatrix4x4(float(2 * fx / W), float(2 * sk / W), float(2 * (camera.cx() + 0.5) / W - 1), 0,  //
                    0, float(-2 * fy / H), float(1 - 2 * (camera.cy() + 0.5) / H), 0,                  //
                    0, 0, float((farZ + nearZ) / (farZ - nearZ)), float(-2 * farZ * nearZ / (farZ - nearZ)),  //
                    0, 0, 1, 0);
}

}  // namespace rehearse::ui
