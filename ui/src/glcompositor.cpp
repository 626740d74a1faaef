#include "rehearse/ui/glcompositor.hpp"

#include "glcommon.hpp"
#include "rehearse/ui/organglview.hpp"

#include <rehearse/imaging/render.hpp>

#include <QGuiApplication>
#include <QMatrix4x4>
#include <QOffscreenSurface>
#include <QOpenGLBuffer>
#include <QOpenGLContext>
#include <QOpenGLExtraFunctions>
#include <QOpenGLFramebufferObject>
#include <QOpenGLShaderProgram>
#include <QOpenGLVertexArrayObject>

#include <algorithm>
#include <limits>

namespace rehearse::ui {
namespace {

const char* kQuadVertex = R"(#version 330 core
const vec2 corners[4] = vec2[4](vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(-1.0, 1.0), vec2(1.0, 1.0));
out vec2 uv;
void main() {
  vec2 c = corners[gl_VertexID];
  uv = vec2(0.5 * (c.x + 1.0), 0.5 * (1.0 - c.y));  // image row 0 at the top
  gl_Position = vec4(c, 0.0, 1.0);
})";
const char* kQuadFragment = R"(#version 330 core
in vec2 uv;
uniform sampler2D background;
out vec4 colour;
void main() { colour = vec4(texture(background, uv).rgb, 1.0); })";

const char* kOrganVertex = R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in vec3 rest;
layout(location = 3) in float detail;  // the frame's detail kept (imaging::frameDetailWeights)
uniform mat4 projection;
out vec3 vPosition;
out vec3 vNormal;
out vec3 vRest;
out float vDetail;
void main() {
  vPosition = position;
  vNormal = normal;
  vRest = rest;
  vDetail = detail;
  gl_Position = projection * vec4(position, 1.0);
})";
// Theta's model (imaging/appearance.hpp) per fragment, as imaging::Compositor does per pixel.
const char* kOrganFragment = R"(#version 330 core
in vec3 vPosition;
in vec3 vNormal;
in vec3 vRest;
in float vDetail;
uniform sampler2D albedo;     // BGR ratios, sampled as RGB
uniform sampler2D frame;
uniform sampler2D restDepth;  // camera z of what the frame shows at rest, 0 where it shows no organ
uniform sampler2D residual;   // what the model leaves of the frame at rest (imaging::Compositor::frameResidual), 0..1 units
uniform vec2 size;
uniform vec4 intrinsics;      // fx, fy, cx, cy
uniform float skew;
uniform vec3 light;
uniform vec3 kd;
uniform vec3 ks;
uniform float sigma;
uniform float falloff;       // n of cos^n off the scope's axis (appearance.hpp)
uniform vec3 roomDirection;  // a second source (appearance.hpp): the distant light's direction (0: none) ...
uniform vec3 kr;             // ... its diffuse reflection ...
uniform vec3 ka;             // ... and the ambient term
uniform bool textureOnly;
uniform vec3 unseenColour;   // texture only: tissue the frame never showed (imaging::meanOrganColour)
uniform bool restCull;       // the surface is closed and wound outward (imaging::closedAndOutward)
uniform float trust;         // the share of the model's change applied where the frame saw the tissue (CompositionInput::trust)
out vec4 colour;
void main() {
  vec3 p = vPosition;
  vec3 r = vRest;
  // The rest triangle's normal as its vertices wind (the CPU compositor's restBack): the rest position's derivatives
  // across the window span the rest triangle, their cross product is its normal times the window-space orientation of
  // the triangle drawn now (gl_FrontFacing: counter-clockwise). A triangle that faced away from the camera at rest was
  // never shown by the frame.
  vec3 restNormal = (gl_FrontFacing ? 1.0 : -1.0) * cross(dFdx(r), dFdy(r));
  bool backAtRest = restCull && dot(r, restNormal) >= 0.0;
  bool seen = false;
  vec2 q = vec2(-1.0);
  if (r.z > 0.0 && !backAtRest) {
    q = vec2(intrinsics.x * r.x / r.z + skew * r.y / r.z + intrinsics.z, intrinsics.y * r.y / r.z + intrinsics.w);
    ivec2 i = ivec2(floor(q + 0.5));
    if (i.x >= 0 && i.y >= 0 && i.x < int(size.x) && i.y < int(size.y)) seen = texelFetch(restDepth, i, 0).r > r.z - 0.002;
  }
  vec2 uv = (clamp(q, vec2(0.0), size - 1.0) + 0.5) / size;
  float keep = clamp(vDetail, 0.0, 1.0);  // stretched over more than the frame showed of it: the model, as far as it is
  if (textureOnly) {
    colour = vec4(seen ? mix(unseenColour, texture(frame, uv).rgb, keep) : unseenColour, 1.0);
    return;
  }
  vec3 a = seen ? texture(albedo, uv).rgb : vec3(1.0);
  vec3 n = normalize(vNormal);
  if (dot(n, -p) < 0.0) n = -n;
  vec3 toLight = light - p;
  float r2 = max(dot(toLight, toLight), 1e-12);
  vec3 l = toLight / sqrt(r2);
  float cosI = dot(n, l);
  float diffuse = 0.0, specular = 0.0;
  if (cosI > 0.0) {
    vec3 v = -p / length(p);
    float cosR = max(dot(n, v), 1e-3);
    float alpha = acos(clamp(dot(n, normalize(l + v)), -1.0, 1.0));
    diffuse = cosI / r2;
    specular = sigma > 0.0 ? exp(-alpha * alpha / (2.0 * sigma * sigma)) / (r2 * cosR) : 0.0;
  }
  float f = falloff > 0.0 ? pow(max(p.z, 0.0) / length(p), falloff) : 1.0;
  vec3 detail = seen ? texture(residual, uv).rgb : vec3(0.0);  // the frame's detail, carried with the tissue
  vec3 second = a * (kr * max(dot(n, roomDirection), 0.0) + ka);
  vec3 model = min(f * (a * kd * diffuse + ks * specular) + second, 1.0) + detail;
  if (seen) model = mix(texture(frame, uv).rgb, model, trust);
  vec3 plain = min(f * (kd * diffuse + ks * specular) + kr * max(dot(n, roomDirection), 0.0) + ka, 1.0);
  if (seen) model = mix(plain, model, keep);
  colour = vec4(clamp(model, 0.0, 1.0), 1.0);
})";

}  // namespace

struct GLCompositor::Impl {
  QOffscreenSurface surface;
  QOpenGLContext context;
  QOpenGLShaderProgram quad, organ;
  std::unique_ptr<QOpenGLFramebufferObject> fbo;
  int fboSamples = -1;
  GLuint background = 0, albedo = 0, frame = 0, restDepth = 0, residual = 0;
  bool ok = false, prepared = false, software = false;
  imaging::Camera camera;
  Pose pose;
  std::vector<int> triangles;
  std::vector<double> restVertices;
  std::vector<float> restCam;  ///< 3 per vertex
  imaging::Appearance theta;
  bool textureOnly = false;
  QVector3D unseenColour;  ///< RGB 0..1: texture only, tissue the frame never showed (imaging::meanOrganColour)
  bool restCull = false;   ///< imaging::closedAndOutward at rest: triangles that faced away then were never seen
  float trust = 1;
  double zMax = 1;

  GLuint upload(QOpenGLExtraFunctions* gl, GLuint tex, const cv::Mat& m, GLint internal, GLenum format, GLenum type, GLint filter) {
    if (!tex) gl->glGenTextures(1, &tex);
    gl->glBindTexture(GL_TEXTURE_2D, tex);
    gl->glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    const cv::Mat c = m.isContinuous() ? m : m.clone();
    gl->glTexImage2D(GL_TEXTURE_2D, 0, internal, c.cols, c.rows, 0, format, type, c.data);
    gl->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filter);
    gl->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filter);
    gl->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    gl->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    return tex;
  }

  bool target(int samples) {
    const QSize size(camera.width, camera.height);
    if (fbo && fbo->size() == size && fboSamples == samples) return true;
    QOpenGLFramebufferObjectFormat f;
    f.setAttachment(QOpenGLFramebufferObject::Depth);
    f.setSamples(samples > 1 ? samples : 0);
    fbo = std::make_unique<QOpenGLFramebufferObject>(size, f);
    fboSamples = samples;
    if (!fbo->isValid()) fbo.reset();
    return fbo != nullptr;
  }

  void drawBackground(QOpenGLExtraFunctions* gl) {
    gl->glViewport(0, 0, camera.width, camera.height);
    gl->glClearColor(0, 0, 0, 1);
    gl->glClearDepthf(1);
    gl->glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    gl->glDisable(GL_DEPTH_TEST);
    gl->glDisable(GL_CULL_FACE);
    gl->glDisable(GL_BLEND);
    QOpenGLVertexArrayObject vao;
    vao.create();
    vao.bind();
    quad.bind();
    gl->glActiveTexture(GL_TEXTURE0);
    gl->glBindTexture(GL_TEXTURE_2D, background);
    quad.setUniformValue("background", 0);
    gl->glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    quad.release();
    vao.release();
    vao.destroy();
  }

  bool readBack(QImage& out) {
    const QImage image = fbo->toImage();
    fbo->release();
    if (image.isNull()) return false;
    out = image.convertToFormat(QImage::Format_RGB32);  // (the format QPainter draws as it is)
    return true;
  }
};

GLCompositor::GLCompositor() : d_(std::make_unique<Impl>()) {
  if (!makeOffscreenContext(d_->context, d_->surface)) return;
  const QString renderer = QString::fromLatin1(reinterpret_cast<const char*>(d_->context.functions()->glGetString(GL_RENDERER)));
  d_->software = OrganGLView::isSoftwareRenderer(renderer);
  d_->ok = d_->quad.addShaderFromSourceCode(QOpenGLShader::Vertex, kQuadVertex) && d_->quad.addShaderFromSourceCode(QOpenGLShader::Fragment, kQuadFragment) &&
           d_->quad.link() && d_->organ.addShaderFromSourceCode(QOpenGLShader::Vertex, kOrganVertex) &&
           d_->organ.addShaderFromSourceCode(QOpenGLShader::Fragment, kOrganFragment) && d_->organ.link();
  d_->context.doneCurrent();
}

GLCompositor::~GLCompositor() {
  if (d_->context.isValid() && d_->context.makeCurrent(&d_->surface)) {
    auto* gl = d_->context.extraFunctions();
    for (GLuint* t : {&d_->background, &d_->albedo, &d_->frame, &d_->restDepth, &d_->residual})
      if (*t) gl->glDeleteTextures(1, t);
    d_->fbo.reset();
    d_->quad.removeAllShaders();
    d_->organ.removeAllShaders();
    d_->context.doneCurrent();
  }
}

bool GLCompositor::valid() const { return d_->ok; }

bool GLCompositor::softwareRenderer() const { return d_->software; }

bool GLCompositor::prepare(const imaging::CompositionInput& in) {
  Impl& d = *d_;
  d.prepared = false;
  if (!d.ok || !in.camera.problem().empty()) return false;
  const cv::Size size(in.camera.width, in.camera.height);
  if (in.frame.size() != size || in.background.size() != size) return false;
  d.camera = in.camera;
  d.pose = in.pose;
  d.triangles.assign(in.rest.triangles, in.rest.triangles + 3 * in.rest.triangleCount);
  d.restVertices.assign(in.rest.vertices, in.rest.vertices + 3 * in.rest.vertexCount);
  std::vector<Eigen::Vector3d> restCam(in.rest.vertexCount);
  d.restCam.resize(3 * in.rest.vertexCount);
  for (std::size_t i = 0; i < in.rest.vertexCount; ++i) {
    restCam[i] = in.pose.apply(in.rest.vertex(i));
    for (int k = 0; k < 3; ++k) d.restCam[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(restCam[i][k]);
  }
  // What the frame shows of the organ at rest: its depth (0 where none), as the CPU compositor's test.
  const imaging::Rasterization seen = imaging::rasterizeCameraFrame(in.camera, restCam, in.rest, 1);
  cv::Mat1f depth = seen.depth.clone();
  depth.setTo(0.0f, seen.triangle < 0);
  d.theta = in.theta;
  d.textureOnly = in.textureOnly;
  const cv::Vec3f unseen = imaging::meanOrganColour(in.frame, seen.triangle) * (1.0f / 255.0f);  // BGR
  d.unseenColour = QVector3D(unseen[2], unseen[1], unseen[0]);
  d.restCull = imaging::closedAndOutward(restCam, in.rest);
  if (!(in.trust >= 0 && in.trust <= 1)) return false;  // the CPU compositor refuses it with its sentence
  d.trust = static_cast<float>(in.trust);
  const cv::Mat3f albedo = in.albedo.empty() ? cv::Mat3f(size, cv::Vec3f(1, 1, 1)) : in.albedo;
  // The frame's detail, as the CPU compositor carries it (0 where none: texture only, or the model alone asked).
  cv::Mat3f residual(size, cv::Vec3f(0, 0, 0));
  if (!in.textureOnly && in.frameDetail) {
    try {
      const cv::Mat3f r = imaging::Compositor(in).frameResidual();
      if (r.size() == size) residual = r * (1.0 / 255.0);
    } catch (const std::exception&) {
      return false;  // the CPU compositor refuses this input: so does this one
    }
  }
  if (!d.context.makeCurrent(&d.surface)) return false;
  auto* gl = d.context.extraFunctions();
  d.background = d.upload(gl, d.background, in.background, GL_RGB8, GL_BGR, GL_UNSIGNED_BYTE, GL_LINEAR);
  d.frame = d.upload(gl, d.frame, in.frame, GL_RGB8, GL_BGR, GL_UNSIGNED_BYTE, GL_LINEAR);
  d.albedo = d.upload(gl, d.albedo, albedo, GL_RGB32F, GL_BGR, GL_FLOAT, GL_LINEAR);
  d.restDepth = d.upload(gl, d.restDepth, depth, GL_R32F, GL_RED, GL_FLOAT, GL_NEAREST);
  d.residual = d.upload(gl, d.residual, residual, GL_RGB32F, GL_BGR, GL_FLOAT, GL_LINEAR);
  d.context.doneCurrent();
  d.prepared = true;
  return true;
}

bool GLCompositor::drawBackgroundOnly(QImage& out) {
  Impl& d = *d_;
  if (!d.prepared || !d.context.makeCurrent(&d.surface)) return false;
  auto* gl = d.context.extraFunctions();
  if (!d.target(1)) {
    d.context.doneCurrent();
    return false;
  }
  d.fbo->bind();
  d.drawBackground(gl);
  const bool ok = d.readBack(out);
  d.context.doneCurrent();
  return ok;
}

bool GLCompositor::compose(const std::vector<double>& deformedVertices, QImage& out, int samples) {
  Impl& d = *d_;
  if (!d.prepared) return false;
  const std::vector<double>& v = deformedVertices.empty() ? d.restVertices : deformedVertices;
  if (v.size() != d.restVertices.size()) return false;
  const std::size_t n = v.size() / 3;
  // Camera-frame positions and smooth normals of the deformed shape, as the CPU compositor makes them.
  std::vector<Eigen::Vector3d> x(n);
  double zMin = std::numeric_limits<double>::infinity(), zMax = 0;
  for (std::size_t i = 0; i < n; ++i) {
    x[i] = d.pose.apply(Eigen::Vector3d(v[3 * i], v[3 * i + 1], v[3 * i + 2]));
    zMin = std::min(zMin, x[i].z());
    zMax = std::max(zMax, x[i].z());
  }
  const SurfaceView surface{v.data(), n, d.triangles.data(), d.triangles.size() / 3};
  const std::vector<Eigen::Vector3d> normals = imaging::vertexNormals(x, surface);
  std::vector<Eigen::Vector3d> rest(n);
  for (std::size_t i = 0; i < n; ++i) rest[i] = Eigen::Vector3d(d.restCam[3 * i], d.restCam[3 * i + 1], d.restCam[3 * i + 2]);
  const std::vector<float> keep = imaging::frameDetailWeights(d.camera, rest, x, d.triangles);
  constexpr std::size_t kStride = 10;  // position, normal, rest, the frame's detail kept
  std::vector<float> data(kStride * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = 0; k < 3; ++k) {
      data[kStride * i + k] = static_cast<float>(x[i][static_cast<int>(k)]);
      data[kStride * i + 3 + k] = static_cast<float>(normals[i][static_cast<int>(k)]);
      data[kStride * i + 6 + k] = d.restCam[3 * i + k];
    }
    data[kStride * i + 9] = keep[i];
  }
  if (!d.context.makeCurrent(&d.surface)) return false;
  auto* gl = d.context.extraFunctions();
  if (!d.target(samples)) {
    d.context.doneCurrent();
    return false;
  }
  d.fbo->bind();
  d.drawBackground(gl);
  if (zMax > 1e-3) {
    gl->glEnable(GL_DEPTH_TEST);
    gl->glDepthFunc(GL_LESS);
    const imaging::Camera& c = d.camera;
    const double W = c.width, H = c.height, fx = c.K(0, 0), sk = c.K(0, 1), fy = c.K(1, 1);
    const QMatrix4x4 projection = pinholeProjection(c, zMin, zMax);
    std::vector<unsigned> indices(d.triangles.begin(), d.triangles.end());
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
    QOpenGLShaderProgram& p = d.organ;
    p.bind();
    for (int a = 0; a < 4; ++a) {
      p.enableAttributeArray(a);
      p.setAttributeBuffer(a, GL_FLOAT, static_cast<int>(3 * a * sizeof(float)), a < 3 ? 3 : 1,
                           static_cast<int>(kStride * sizeof(float)));
    }
    p.setUniformValue("projection", projection);
    const GLuint textures[] = {d.albedo, d.frame, d.restDepth, d.residual};
    const char* names[] = {"albedo", "frame", "restDepth", "residual"};
    for (int t = 0; t < 4; ++t) {
      gl->glActiveTexture(GL_TEXTURE0 + static_cast<GLenum>(t));
      gl->glBindTexture(GL_TEXTURE_2D, textures[t]);
      p.setUniformValue(names[t], t);
    }
    p.setUniformValue("size", QVector2D(float(W), float(H)));
    p.setUniformValue("intrinsics", QVector4D(float(fx), float(fy), float(c.cx()), float(c.cy())));
    p.setUniformValue("skew", float(sk));
    const auto& th = d.theta;
    p.setUniformValue("light", QVector3D(float(th.lightPosition.x()), float(th.lightPosition.y()), float(th.lightPosition.z())));
    p.setUniformValue("kd", QVector3D(float(th.kd.x()), float(th.kd.y()), float(th.kd.z())));
    p.setUniformValue("ks", QVector3D(float(th.ks.x()), float(th.ks.y()), float(th.ks.z())));
    p.setUniformValue("sigma", float(th.roughness));
    p.setUniformValue("falloff", float(th.falloff));
    const bool distant = th.hasDistantLight();
    p.setUniformValue("roomDirection", distant ? QVector3D(float(th.roomDirection.x()), float(th.roomDirection.y()),
                                                           float(th.roomDirection.z()))
                                               : QVector3D(0, 0, 0));
    p.setUniformValue("kr", distant ? QVector3D(float(th.kr.x()), float(th.kr.y()), float(th.kr.z())) : QVector3D(0, 0, 0));
    p.setUniformValue("ka", QVector3D(float(th.ka.x()), float(th.ka.y()), float(th.ka.z())));
    p.setUniformValue("textureOnly", d.textureOnly);
    p.setUniformValue("unseenColour", d.unseenColour);
    p.setUniformValue("restCull", d.restCull);
    p.setUniformValue("trust", d.trust);
    gl->glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(indices.size()), GL_UNSIGNED_INT, nullptr);
    p.release();
    vao.release();
    vbo.destroy();
    ibo.destroy();
    vao.destroy();
    gl->glActiveTexture(GL_TEXTURE0);
  }
  const bool ok = d.readBack(out);
  d.context.doneCurrent();
  return ok;
}

}  // namespace rehearse::ui
