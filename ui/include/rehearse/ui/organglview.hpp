#pragma once
// The organ alone in 3D with OpenGL (used when a GL context can be made; OrganView is the software
// fallback). Same controls: drag to turn, wheel to zoom, double-click to reset.
#include "rehearse/ui/organview.hpp"

#include <QOpenGLBuffer>
#include <QOpenGLFunctions>
#include <QOpenGLShaderProgram>
#include <QOpenGLVertexArrayObject>
#include <QOpenGLWidget>

#include <memory>

namespace rehearse::ui {

class OrganGLView : public QOpenGLWidget, protected QOpenGLFunctions {
  Q_OBJECT
 public:
  explicit OrganGLView(QWidget* parent = nullptr);
  ~OrganGLView() override;
  void setCase(std::shared_ptr<const app::Case> c);
  /// True once initializeGL ran with a working context and shaders.
  bool glReady() const { return ready_; }
  QString glVersion() const { return version_; }
  /// True when this machine can make an OpenGL 3.3 context (false on Qt's offscreen platform).
  static bool openGLAvailable();
  /// The OpenGL 3.3 context's GL_RENDERER string, empty when there is none.
  static QString openGLRenderer();
  /// True when `renderer` names a software rasteriser (Mesa's llvmpipe, softpipe, swrast).
  static bool isSoftwareRenderer(const QString& renderer);

 protected:
  void initializeGL() override;
  void paintGL() override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void mouseDoubleClickEvent(QMouseEvent*) override;
  void wheelEvent(QWheelEvent*) override;

 private:
  void upload();
  std::shared_ptr<const app::Case> case_;
  QOpenGLShaderProgram program_;
  QOpenGLBuffer vbo_{QOpenGLBuffer::VertexBuffer};
  QOpenGLVertexArrayObject vao_;
  int vertexCount_ = 0, organCount_ = 0;
  bool dirty_ = true, ready_ = false;
  QString version_;
  Turntable turntable_;
};

}  // namespace rehearse::ui
