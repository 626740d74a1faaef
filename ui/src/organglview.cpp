#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/pages/meshpage.hpp"

#include <rehearse/simcore/mesh.hpp>

#include <QGuiApplication>
#include <QMatrix4x4>
#include <QMouseEvent>
#include <QOffscreenSurface>
#include <QOpenGLContext>
#include <QPainter>
#include <QWheelEvent>

namespace rehearse::ui {
namespace {
const char* kVertex = R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in vec3 colour;
uniform mat4 mvp;
uniform mat3 normalMatrix;
out vec3 vNormal;
out vec3 vColour;
void main() {
  vNormal = normalMatrix * normal;
  vColour = colour;
  gl_Position = mvp * vec4(position, 1.0);
})";
const char* kFragment = R"(#version 330 core
in vec3 vNormal;
in vec3 vColour;
uniform float alpha;
out vec4 fragColour;
void main() {
  vec3 n = normalize(vNormal);
  float light = 0.25 + 0.75 * abs(n.z);
  fragColour = vec4(vColour * light, alpha);
})";
}  // namespace

OrganGLView::OrganGLView(QWidget* parent) : QOpenGLWidget(parent) {
  setMinimumSize(200, 160);
  setToolTip(tr("Drag to turn the organ, wheel to zoom, double-click to reset (OpenGL)"));
}

OrganGLView::~OrganGLView() {
  makeCurrent();
  vbo_.destroy();
  vao_.destroy();
  doneCurrent();
}

bool OrganGLView::openGLAvailable() { return !openGLRenderer().isEmpty(); }

bool OrganGLView::isSoftwareRenderer(const QString& renderer) {
  return renderer.contains(QLatin1String("llvmpipe"), Qt::CaseInsensitive) || renderer.contains(QLatin1String("softpipe"), Qt::CaseInsensitive) ||
         renderer.contains(QLatin1String("swrast"), Qt::CaseInsensitive);
}

QString OrganGLView::openGLRenderer() {
  if (QGuiApplication::platformName() == QLatin1String("offscreen") || QGuiApplication::platformName() == QLatin1String("minimal"))
    return {};
  QOpenGLContext ctx;
  QSurfaceFormat f;
  f.setVersion(3, 3);
  f.setProfile(QSurfaceFormat::CoreProfile);
  ctx.setFormat(f);
  if (!ctx.create()) return {};
  QOffscreenSurface surface;
  surface.setFormat(ctx.format());
  surface.create();
  if (!ctx.makeCurrent(&surface)) return {};
  const bool ok = ctx.format().majorVersion() > 3 || (ctx.format().majorVersion() == 3 && ctx.format().minorVersion() >= 3);
  QString renderer;
  if (ok) {
    const auto* name = reinterpret_cast<const char*>(ctx.functions()->glGetString(GL_RENDERER));
    renderer = name && *name ? QString::fromLatin1(name) : QStringLiteral("unknown renderer");
  }
  ctx.doneCurrent();
  return renderer;
}

void OrganGLView::setCase(std::shared_ptr<const app::Case> c) {
  if (!takeCase(case_, std::move(c))) return;
  dirty_ = true;
  update();
}

void OrganGLView::initializeGL() {
  initializeOpenGLFunctions();
  version_ = QString::fromLatin1(reinterpret_cast<const char*>(glGetString(GL_VERSION)));
  ready_ = program_.addShaderFromSourceCode(QOpenGLShader::Vertex, kVertex) &&
           program_.addShaderFromSourceCode(QOpenGLShader::Fragment, kFragment) && program_.link();
  vao_.create();
  vbo_.create();
  glEnable(GL_DEPTH_TEST);
  dirty_ = true;
}

void OrganGLView::upload() {
  dirty_ = false;
  vertexCount_ = organCount_ = 0;
  if (!case_ || case_->organ->surface.empty()) return;
  // Flat arrays: position, normal, colour per vertex; outer surface first, then inner structures.
  std::vector<float> data;
  auto add = [&](const std::array<int, 3>& t, const Eigen::Vector3f& colour) {
    const Eigen::Vector3d a = case_->shapeNodes()[t[0]], b = case_->shapeNodes()[t[1]], c = case_->shapeNodes()[t[2]];
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    for (const auto& p : {a, b, c}) {
      data.insert(data.end(), {float(p.x()), float(p.y()), float(p.z()), float(n.x()), float(n.y()), float(n.z()), colour.x(),
                               colour.y(), colour.z()});
    }
  };
  for (const auto& t : case_->organ->surface) add(t, {0.85f, 0.55f, 0.45f});
  organCount_ = static_cast<int>(case_->organ->surface.size() * 3);
  // Each structure in its label's colour (as step 1's list and the legend over the frame).
  const auto& inner = case_->organ->innerSurface;
  const auto& labels = case_->organ->innerSurfaceLabels;
  for (std::size_t i = 0; i < inner.size(); ++i) {
    const QColor c = labelColour(labels.size() == inner.size() ? labels[i] : 0);
    add(inner[i], {float(c.redF()), float(c.greenF()), float(c.blueF())});
  }
  vertexCount_ = static_cast<int>(data.size() / 9);
  vao_.bind();
  vbo_.bind();
  vbo_.allocate(data.data(), static_cast<int>(data.size() * sizeof(float)));
  program_.bind();
  program_.enableAttributeArray(0);
  program_.enableAttributeArray(1);
  program_.enableAttributeArray(2);
  program_.setAttributeBuffer(0, GL_FLOAT, 0, 3, 9 * sizeof(float));
  program_.setAttributeBuffer(1, GL_FLOAT, 3 * sizeof(float), 3, 9 * sizeof(float));
  program_.setAttributeBuffer(2, GL_FLOAT, 6 * sizeof(float), 3, 9 * sizeof(float));
  vao_.release();
}

void OrganGLView::paintGL() {
  glClearColor(24 / 255.f, 25 / 255.f, 28 / 255.f, 1);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  if (!ready_) return;
  if (dirty_) upload();
  if (vertexCount_ == 0) return;
  // The same camera as the software view (turntableView), as an OpenGL projection: OpenCV's camera axes
  // (x right, y down, z forward, pixel centres at integers) to clip space, depth between size/20 and 20 size.
  const double dpr = devicePixelRatioF();
  const int W = static_cast<int>(std::lround(width() * dpr)), H = static_cast<int>(std::lround(height() * dpr));
  imaging::Camera cam;
  Pose pose;
  turntableView(*case_, turntable_, W, H, cam, pose);
  const double size = case_->organ->volume.bounds().sizes().maxCoeff();
  const double n = 0.05 * size, far = 20 * size;
  QMatrix4x4 proj(float(2 * cam.fx() / W), 0, float(2 * (cam.cx() + 0.5) / W - 1), 0,  //
                  0, float(-2 * cam.fy() / H), float(1 - 2 * (cam.cy() + 0.5) / H), 0,  //
                  0, 0, float((far + n) / (far - n)), float(-2 * far * n / (far - n)),  //
                  0, 0, 1, 0);
  QMatrix4x4 view(float(pose.R(0, 0)), float(pose.R(0, 1)), float(pose.R(0, 2)), float(pose.t.x()),  //
                  float(pose.R(1, 0)), float(pose.R(1, 1)), float(pose.R(1, 2)), float(pose.t.y()),  //
                  float(pose.R(2, 0)), float(pose.R(2, 1)), float(pose.R(2, 2)), float(pose.t.z()),  //
                  0, 0, 0, 1);
  program_.bind();
  program_.setUniformValue("mvp", proj * view);
  program_.setUniformValue("normalMatrix", view.normalMatrix());
  vao_.bind();
  program_.setUniformValue("alpha", 1.0f);
  glDrawArrays(GL_TRIANGLES, 0, organCount_);
  if (vertexCount_ > organCount_) {
    // Inner structures shine through the organ.
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    program_.setUniformValue("alpha", 0.45f);
    glDrawArrays(GL_TRIANGLES, organCount_, vertexCount_ - organCount_);
    glDisable(GL_BLEND);
    glEnable(GL_DEPTH_TEST);
  }
  vao_.release();
}

void OrganGLView::mousePressEvent(QMouseEvent* e) { turntable_.press(e->position()); }

void OrganGLView::mouseMoveEvent(QMouseEvent* e) {
  if (!(e->buttons() & Qt::LeftButton)) return;
  turntable_.drag(e->position());
  update();
}

void OrganGLView::mouseDoubleClickEvent(QMouseEvent*) {
  turntable_.reset();
  update();
}

void OrganGLView::wheelEvent(QWheelEvent* e) {
  turntable_.wheel(e->angleDelta().y());
  update();
}

}  // namespace rehearse::ui
