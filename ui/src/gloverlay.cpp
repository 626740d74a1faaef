#include "rehearse/ui/gloverlay.hpp"

#include "glcommon.hpp"

#include <QGuiApplication>
#include <QMatrix4x4>
#include <QOffscreenSurface>
#include <QOpenGLBuffer>
#include <QOpenGLContext>
#include <QOpenGLFramebufferObject>
#include <QOpenGLFunctions>
#include <QOpenGLShaderProgram>
#include <QOpenGLVertexArrayObject>

#include <algorithm>
#include <limits>
#include <vector>

namespace rehearse::ui {
namespace {
const char* kVertex = R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
uniform mat4 projection;
out vec3 vPosition;
out vec3 vNormal;
void main() {
  vPosition = position;
  vNormal = normal;
  gl_Position = projection * vec4(position, 1.0);
})";
// As imaging::renderOverlay: the normal turned towards the eye, 0.25 ambient + 0.75 headlight.
const char* kFragment = R"(#version 330 core
in vec3 vPosition;
in vec3 vNormal;
uniform vec3 colour;
out vec4 fragColour;
void main() {
  float d = abs(dot(normalize(vNormal), normalize(-vPosition)));
  fragColour = vec4(colour * (0.25 + 0.75 * d), 1.0);
})";
}  // namespace

struct GLOverlay::Impl {
  QOffscreenSurface surface;
  QOpenGLContext context;
  QOpenGLShaderProgram program;
  std::unique_ptr<QOpenGLFramebufferObject> fbo;
  bool ok = false;
};

GLOverlay::GLOverlay() : d_(std::make_unique<Impl>()) {
  if (!makeOffscreenContext(d_->context, d_->surface)) return;
  d_->ok = d_->program.addShaderFromSourceCode(QOpenGLShader::Vertex, kVertex) &&
           d_->program.addShaderFromSourceCode(QOpenGLShader::Fragment, kFragment) && d_->program.link();
  d_->context.doneCurrent();
}

GLOverlay::~GLOverlay() {
  if (d_->context.isValid() && d_->context.makeCurrent(&d_->surface)) {
    d_->fbo.reset();
    d_->program.removeAllShaders();
    d_->context.doneCurrent();
  }
}

bool GLOverlay::valid() const { return d_->ok; }

bool GLOverlay::render(const imaging::Camera& camera, const Pose& pose, const SurfaceView& s, const QColor& colour, QImage& out) {
  if (!d_->ok || camera.width <= 0 || camera.height <= 0 || !s.vertices || !s.triangles) return false;
  // Camera-frame positions and area-weighted vertex normals (as the CPU renderer).
  std::vector<float> data(6 * s.vertexCount, 0.0f);
  std::vector<Eigen::Vector3d> x(s.vertexCount), n(s.vertexCount, Eigen::Vector3d::Zero());
  double zMin = std::numeric_limits<double>::infinity(), zMax = 0;
  for (std::size_t i = 0; i < s.vertexCount; ++i) x[i] = pose.apply(s.vertex(i));
  std::vector<unsigned> indices;
  indices.reserve(3 * s.triangleCount);
  for (std::size_t t = 0; t < s.triangleCount; ++t) {
    const int* tri = s.triangles + 3 * t;
    const Eigen::Vector3d fn = (x[tri[1]] - x[tri[0]]).cross(x[tri[2]] - x[tri[0]]);
    for (int k = 0; k < 3; ++k) {
      n[tri[k]] += fn;
      indices.push_back(static_cast<unsigned>(tri[k]));
      zMin = std::min(zMin, x[tri[k]].z());
      zMax = std::max(zMax, x[tri[k]].z());
    }
  }
  if (!(zMax > 1e-3)) {  // nothing in front of the camera
    out = QImage(camera.width, camera.height, QImage::Format_RGBA8888);
    out.fill(Qt::transparent);
    return true;
  }
  for (std::size_t i = 0; i < s.vertexCount; ++i) {
    const Eigen::Vector3d m = n[i].norm() > 0 ? Eigen::Vector3d(n[i].normalized()) : Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) data[6 * i + k] = static_cast<float>(x[i][k]), data[6 * i + 3 + k] = static_cast<float>(m[k]);
  }
  if (!d_->context.makeCurrent(&d_->surface)) return false;
  auto* gl = d_->context.functions();
  if (!d_->fbo || d_->fbo->size() != QSize(camera.width, camera.height)) {
    d_->fbo = std::make_unique<QOpenGLFramebufferObject>(QSize(camera.width, camera.height), QOpenGLFramebufferObject::Depth);
    if (!d_->fbo->isValid()) {
      d_->fbo.reset();
      d_->context.doneCurrent();
      return false;
    }
  }
  d_->fbo->bind();
  gl->glViewport(0, 0, camera.width, camera.height);
  gl->glClearColor(0, 0, 0, 0);
  gl->glClearDepthf(1);
  gl->glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl->glEnable(GL_DEPTH_TEST);
  gl->glDepthFunc(GL_LESS);
  gl->glDisable(GL_CULL_FACE);
  gl->glDisable(GL_BLEND);
  const QMatrix4x4 projection = pinholeProjection(camera, zMin, zMax);
  QOpenGLVertexArrayObject vao;
  vao.create();
  vao.bind();
  QOpenGLBuffer vbo(QOpenGLBuffer::VertexBuffer), ibo(QOpenGLBuffer::IndexBuffer);
  vbo.create();
  vbo.bind();
  vbo.allocate(data.data(), static_cast<int>(data.size() * sizeof(float)));
  ibo.create();
  ibo.bind();
  ibo.allocate(indices.data(), static_cast<int>(indices.size() * sizeof(unsigned)));
  d_->program.bind();
  d_->program.enableAttributeArray(0);
  d_->program.enableAttributeArray(1);
  d_->program.setAttributeBuffer(0, GL_FLOAT, 0, 3, 6 * sizeof(float));
  d_->program.setAttributeBuffer(1, GL_FLOAT, 3 * sizeof(float), 3, 6 * sizeof(float));
  d_->program.setUniformValue("projection", projection);
  d_->program.setUniformValue("colour", QVector3D(float(colour.redF()), float(colour.greenF()), float(colour.blueF())));
  gl->glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(indices.size()), GL_UNSIGNED_INT, nullptr);
  d_->program.release();
  vao.release();
  const QImage image = d_->fbo->toImage();
  d_->fbo->release();
  vbo.destroy();
  ibo.destroy();
  vao.destroy();
  d_->context.doneCurrent();
  if (image.isNull()) return false;
  out = image.convertToFormat(QImage::Format_RGBA8888);
  return true;
}

}  // namespace rehearse::ui
