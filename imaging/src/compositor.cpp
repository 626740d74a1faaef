// The composition J (appearance_fit.hpp): I_B, and over it the deformed organ re-shaded with Theta and its
// albedo, its texture looked up where each of its points was at rest. Prepared once per registered organ;
// each deformed shape is rasterised at the frame's resolution, shaded once per covered pixel, and only its
// rim is supersampled.
#include <rehearse/imaging/appearance_fit.hpp>

#include "sampling.hpp"

#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <array>
#include <cmath>

namespace rehearse::imaging {

struct Compositor::Impl {
  Camera camera;
  Pose pose;
  Eigen::Matrix3d Kinv;
  std::vector<int> triangles;  ///< 3 per triangle (the rest's; a deformed shape must have the same)
  std::size_t vertexCount = 0;
  std::vector<double> restVertices;  ///< model frame, 3n (compose() with no shape)
  std::vector<Eigen::Vector3d> restCam;  ///< rest vertices, camera frame
  std::vector<Eigen::Vector3f> restCamF;  ///< the same in single precision (the per-pixel shading's)
  float kf[5] = {};                       ///< K's fx, skew, cx, fy, cy
  Eigen::Vector3f lightF = Eigen::Vector3f::Zero(), kdF = Eigen::Vector3f::Zero(), ksF = Eigen::Vector3f::Zero();
  Rasterization restSeen;                ///< what the frame shows of the organ at rest (triangle, depth)
  cv::Mat3b frame, background;
  cv::Mat3f albedo;
  cv::Mat3f residual;  ///< frameResidual(); empty while it is made (and when texture only)
  Appearance theta;
  bool textureOnly = false;
  bool frameDetail = true;
  float trust = 1;  ///< CompositionInput::trust (1 while the residual is made: that is the model's own)
  /// What a re-shaded point the frame saw carries from where the frame saw it: trust x residual + (1 - trust) x the
  /// frame (shadeAt); empty while the residual is made, and when there is nothing to carry.
  cv::Mat3f carried;
  std::vector<int> triangleMaterial;  ///< CompositionInput's (empty: all the organ's surface)
  std::vector<cv::Vec3f> materials;
  /// exp(-alpha^2 / 2 sigma^2) against cos(alpha) in [0, 1] (the specular lobe), linearly interpolated.
  std::vector<float> lobe;
  /// The scope's fall-off cos^n(psi) against cos^2(psi) in [0, 1] (no power per pixel); empty for n = 0.
  std::vector<float> falloff;
  /// The organ's surface is closed and wound outward: its triangles facing away from the camera are hidden,
  /// and are not rasterised (half the rasteriser's work).
  bool cull = false;
  bool specular_ = false;  ///< Theta has a specular lobe (ks > 0, sigma > 0)

  float falloffAt(const Eigen::Vector3f& p, float squaredNorm) const {
    if (falloff.empty()) return 1.0f;
    if (!(p.z() > 0) || !(squaredNorm > 0)) return 0.0f;
    const float u = std::clamp(p.z() * p.z() / squaredNorm, 0.0f, 1.0f) * static_cast<float>(falloff.size() - 1);
    const std::size_t i = std::min(static_cast<std::size_t>(u), falloff.size() - 2);
    const float f = u - static_cast<float>(i);
    return (1 - f) * falloff[i] + f * falloff[i + 1];
  }

  float lobeAt(float cosAlpha) const {
    const float u = std::clamp(cosAlpha, 0.0f, 1.0f) * static_cast<float>(lobe.size() - 1);
    const std::size_t i = std::min(static_cast<std::size_t>(u), lobe.size() - 2);
    const float f = u - static_cast<float>(i);
    return (1 - f) * lobe[i] + f * lobe[i + 1];
  }

  /// A deformed triangle's plane (n . x = offset) and its barycentric gradients (w_a = ga . (p - b),
  /// w_b = gb . (p - c)), made once per shape instead of once per pixel. Single precision, like the per-pixel
  /// shading below (positions of 0.1-1 m to 1e-7: 0.1 um), which it halves the cost of.
  struct Plane {
    Eigen::Vector3f n, ga, gb;
    float offset = 0;
  };
  static std::vector<Plane> planes(const std::vector<Eigen::Vector3d>& X, const std::vector<int>& triangles) {
    std::vector<Plane> out(triangles.size() / 3);
    cv::parallel_for_(cv::Range(0, static_cast<int>(out.size())), [&](const cv::Range& range) {
      for (int t = range.start; t < range.end; ++t) {
        const int* tri = triangles.data() + 3 * t;
        const Eigen::Vector3d &a = X[tri[0]], &b = X[tri[1]], &c = X[tri[2]];
        Plane& q = out[static_cast<std::size_t>(t)];
        const Eigen::Vector3d n = (b - a).cross(c - a);
        const double nn = n.squaredNorm();
        q.n = n.cast<float>();
        if (nn <= 0) continue;
        q.offset = static_cast<float>(n.dot(a));
        q.ga = (n.cross(c - b) / nn).cast<float>();  // ((c - b) x (p - b)) . n = (n x (c - b)) . (p - b)
        q.gb = (n.cross(a - c) / nn).cast<float>();
      }
    });
    return out;
  }

  /// The colour (BGR, 0..255 floats) of the deformed surface's triangle `t` seen through image point
  /// (px, py); false where the ray grazes the triangle (the caller keeps the background).
  bool shadeAt(const std::vector<Eigen::Vector3f>& X, const std::vector<Eigen::Vector3f>& N,
               const std::vector<Plane>& P, int t, double px, double py, cv::Vec3f& bgr) const {
    const int* tri = triangles.data() + 3 * t;
    const Plane& q = P[static_cast<std::size_t>(t)];
    const Eigen::Vector3f d(static_cast<float>(Kinv(0, 0) * px + Kinv(0, 1) * py + Kinv(0, 2)),
                            static_cast<float>(Kinv(1, 1) * py + Kinv(1, 2)),
                            1.0f);  // K is upper triangular
    const float denom = q.n.dot(d);
    if (!(std::abs(denom) > 0)) return false;
    const Eigen::Vector3f p = d * (q.offset / denom);
    const float wa = q.ga.dot(p - X[tri[1]]), wb = q.gb.dot(p - X[tri[2]]), wc = 1 - wa - wb;
    // Where the point was at rest, and whether the frame showed it there (the triangle, one sharing a vertex
    // with it, or a surface no nearer than 2 mm in front of it: not hidden behind another part of the organ).
    const Eigen::Vector3f r = wa * restCamF[tri[0]] + wb * restCamF[tri[1]] + wc * restCamF[tri[2]];
    bool seen = false;
    float qx = -1, qy = -1;
    if (r.z() > 0) {
      const float rx = r.x() / r.z(), ry = r.y() / r.z();
      qx = kf[0] * rx + kf[1] * ry + kf[2];
      qy = kf[3] * ry + kf[4];
      const int ix = static_cast<int>(std::floor(qx + 0.5f)), iy = static_cast<int>(std::floor(qy + 0.5f));
      if (ix >= 0 && iy >= 0 && ix < camera.width && iy < camera.height) {
        const int shownTriangle = restSeen.triangle(iy, ix);
        if (shownTriangle >= 0) {
          seen = restSeen.depth(iy, ix) > r.z() - 0.002f;
          const int* shown = triangles.data() + 3 * shownTriangle;
          for (int i = 0; i < 3 && !seen; ++i)
            for (int j = 0; j < 3; ++j) seen |= shown[i] == tri[j];
        }
      }
    }
    const int material = triangleMaterial.empty() ? 0 : triangleMaterial[static_cast<std::size_t>(t)];
    if (textureOnly && material == 0) {
      if (!seen) return false;
      bgr = bilinear(frame, qx, qy);
      return true;
    }
    // The albedo: a material's (tissue the frame never showed: a cut's faces), the frame's where it saw the
    // tissue, else ratio 1, the fitted kd (its back).
    const cv::Vec3f albedoHere = material > 0 ? materials[static_cast<std::size_t>(material - 1)]
                                 : seen       ? bilinear(albedo, qx, qy)
                                              : cv::Vec3f(1, 1, 1);
    Eigen::Vector3f normal = wa * N[tri[0]] + wb * N[tri[1]] + wc * N[tri[2]];
    const float length = normal.norm();
    if (!(length > 0) || !std::isfinite(length)) return false;
    normal *= 1.0f / length;
    if (normal.dot(p) > 0) normal = -normal;  // an open surface seen from inside
    // Theta's model (appearance.hpp): F [kd cos(theta_i) / r^2 + ks exp(-alpha^2 / 2 sigma^2) / (r^2 cos(theta_r))].
    const Eigen::Vector3f toLight = lightF - p;
    const float r2 = std::max(toLight.squaredNorm(), 1e-12f), inv2 = 1.0f / r2;
    const Eigen::Vector3f l = toLight * std::sqrt(inv2);
    const float cosI = normal.dot(l);
    float diffuse = 0, specular = 0;
    const float p2 = p.squaredNorm();
    if (cosI > 0) {
      diffuse = cosI * inv2;
      if (specular_) {
        const Eigen::Vector3f v = p * (-1.0f / std::sqrt(p2));
        const float cosR = std::max(normal.dot(v), 1e-3f);
        const Eigen::Vector3f h = l + v;
        specular = lobeAt(normal.dot(h) / h.norm()) * inv2 / cosR;
      }
    }
    const float falloff = falloffAt(p, p2);  // the scope's light cone and vignetting
    for (int k = 0; k < 3; ++k)
      bgr[k] = 255.0f * falloff * (albedoHere[k] * kdF[2 - k] * diffuse + ksF[2 - k] * specular);
    // The frame's detail over the model as a frame can show it, and the model's change applied as far as the fit
    // earned it: trust (min(model, 255) + residual) + (1 - trust) frame, one lookup of `carried` (made once).
    if (material == 0 && seen && !carried.empty()) {
      const cv::Vec3f c = bilinear(carried, qx, qy);
      for (int k = 0; k < 3; ++k) bgr[k] = trust * std::min(bgr[k], 255.0f) + c[k];
    }
    return true;
  }
  void makeResidual();

  /// A deformed shape as compose() draws it: its vertices in the camera frame (double and single precision), their
  /// normals, its triangles' planes, its vertices' image points and what the camera sees of it.
  struct Shape {
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector3f> Xf, Nf;
    std::vector<Plane> P;
    std::vector<Eigen::Vector2d> uv;
    Rasterization seen;
  };
  void shadeCovered(const Shape& s, const cv::Rect& box, int scale, cv::Mat3b& out, cv::Mat1b& onRim) const;
  cv::Vec3b supersample(const Shape& s, const cv::Point& q, int scale, const cv::Mat3b& out) const;
};

Compositor::Compositor(const CompositionInput& in) : d_(std::make_unique<Impl>()) {
  if (auto p = in.camera.problem(); !p.empty()) throw InputError(p);
  const cv::Size size(in.camera.width, in.camera.height);
  if (in.frame.size() != size || in.background.size() != size) throw InputError("The frame's size is not the camera's.");
  if (!in.textureOnly && in.albedo.size() != size) throw InputError("The albedo's size is not the camera's.");
  if (!(in.trust >= 0 && in.trust <= 1))
    throw InputError("The share of the model's change to apply (the fit's trust) must be within 0 and 1.");
  Impl& d = *d_;
  d.camera = in.camera;
  d.pose = in.pose;
  d.Kinv = in.camera.K.inverse();
  d.triangles.assign(in.rest.triangles, in.rest.triangles + 3 * in.rest.triangleCount);
  d.vertexCount = in.rest.vertexCount;
  d.restVertices.assign(in.rest.vertices, in.rest.vertices + 3 * in.rest.vertexCount);
  d.restCam.resize(in.rest.vertexCount);
  for (std::size_t i = 0; i < in.rest.vertexCount; ++i) d.restCam[i] = in.pose.apply(in.rest.vertex(i));
  d.restCamF.resize(d.restCam.size());
  for (std::size_t i = 0; i < d.restCam.size(); ++i) d.restCamF[i] = d.restCam[i].cast<float>();
  d.kf[0] = static_cast<float>(in.camera.K(0, 0)), d.kf[1] = static_cast<float>(in.camera.K(0, 1)),
  d.kf[2] = static_cast<float>(in.camera.K(0, 2));
  d.kf[3] = static_cast<float>(in.camera.K(1, 1)), d.kf[4] = static_cast<float>(in.camera.K(1, 2));
  d.lightF = in.theta.lightPosition.cast<float>();
  d.kdF = in.theta.kd.cast<float>();
  d.ksF = in.theta.ks.cast<float>();
  d.cull = closedAndOutward(d.restCam, in.rest);
  d.restSeen = rasterizeCameraFrame(in.camera, d.restCam, in.rest, 1, 1e-3, d.cull);
  d.frame = in.frame;
  d.background = in.background;
  d.albedo = in.albedo.empty() ? cv::Mat3f(size, cv::Vec3f(1, 1, 1)) : in.albedo;
  d.theta = in.theta;
  d.textureOnly = in.textureOnly;
  d.frameDetail = in.frameDetail;
  if (!in.triangleMaterial.empty()) {
    if (in.triangleMaterial.size() != in.rest.triangleCount)
      throw InputError("The surface's materials are not one per triangle.");
    for (int m : in.triangleMaterial)
      if (m < 0 || m > static_cast<int>(in.materials.size()))
        throw InputError("A triangle names a material the surface does not have.");
  }
  d.triangleMaterial = in.triangleMaterial;
  d.materials = in.materials;
  // The lobe as a function of cos(alpha): 4,097 entries keep it within 1e-4 of exp(-acos(c)^2 / 2 sigma^2)
  // for sigma >= 0.02 rad (test_appearance compares it with Appearance::shade).
  d.lobe.resize(4097);
  const double sigma = std::max(in.theta.roughness, 1e-6);
  for (std::size_t i = 0; i < d.lobe.size(); ++i) {
    const double alpha = std::acos(static_cast<double>(i) / static_cast<double>(d.lobe.size() - 1));
    d.lobe[i] = static_cast<float>(std::exp(-alpha * alpha / (2 * sigma * sigma)));
  }
  d.specular_ = in.theta.roughness > 0 && in.theta.ks.maxCoeff() > 0;
  // cos^n(psi) = (cos^2 psi)^(n/2), tabulated on cos^2 psi: 16,385 entries keep it within 1e-4 of the power
  // for n <= 200 (the fit's bound), against 3e-5 of the 8-bit output's step.
  if (in.theta.falloff > 0) {
    d.falloff.resize(16385);
    for (std::size_t i = 0; i < d.falloff.size(); ++i)
      d.falloff[i] = static_cast<float>(
          std::pow(static_cast<double>(i) / static_cast<double>(d.falloff.size() - 1), 0.5 * in.theta.falloff));
  }
  if (!d.textureOnly && d.frameDetail) d.makeResidual();
  d.trust = static_cast<float>(in.trust);
  if (!d.textureOnly && d.trust < 1) {
    cv::Mat3f own;
    d.frame.convertTo(own, CV_32FC3, 1.0 - d.trust);
    d.carried = d.residual.empty() ? own : cv::Mat3f(d.residual * d.trust + own);
  } else if (!d.residual.empty()) {
    d.carried = d.residual;
  }
}

// The frame minus the model at rest, on the organ's pixels whose four neighbours show the organ too (a rim pixel
// mixes the organ with what is behind it: carried inward when the organ moves, it would draw a seam).
void Compositor::Impl::makeResidual() {
  std::vector<Eigen::Vector3f> N(restCam.size());
  const std::vector<Eigen::Vector3d> normals =
      vertexNormals(restCam, SurfaceView{restVertices.data(), vertexCount, triangles.data(), triangles.size() / 3});
  for (std::size_t i = 0; i < N.size(); ++i) N[i] = normals[i].cast<float>();
  const std::vector<Plane> P = planes(restCam, triangles);
  cv::Mat3f out(frame.size(), cv::Vec3f(0, 0, 0));
  const cv::Mat1i& tri = restSeen.triangle;
  cv::parallel_for_(cv::Range(1, std::max(1, frame.rows - 1)), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 1; x + 1 < frame.cols; ++x) {
        const int t = tri(y, x);
        if (t < 0 || tri(y - 1, x) < 0 || tri(y + 1, x) < 0 || tri(y, x - 1) < 0 || tri(y, x + 1) < 0) continue;
        if (!triangleMaterial.empty() && triangleMaterial[static_cast<std::size_t>(t)] != 0) continue;
        cv::Vec3f model;
        if (!shadeAt(restCamF, N, P, t, x, y, model)) continue;
        // Against the model as the frame can show it (a highlight brighter than white is white there): a clipped
        // highlight carries nothing to where the organ moves.
        const cv::Vec3b f = frame(y, x);
        for (int k = 0; k < 3; ++k) out(y, x)[k] = f[k] - std::min(model[k], 255.0f);
      }
  });
  residual = out;
}

Compositor::~Compositor() = default;

const cv::Mat3f& Compositor::frameResidual() const { return d_->residual; }

const Camera& Compositor::camera() const { return d_->camera; }

std::unique_ptr<Compositor> Compositor::reshaped(const SurfaceView& rest, std::vector<int> triangleMaterial,
                                                 std::vector<cv::Vec3f> materials) const {
  const Impl& d = *d_;
  CompositionInput in;
  in.camera = d.camera;
  in.pose = d.pose;
  in.rest = in.deformed = rest;
  in.frame = d.frame;
  in.background = d.background;
  in.albedo = d.albedo;
  in.theta = d.theta;
  in.textureOnly = d.textureOnly;
  in.frameDetail = d.frameDetail;
  in.trust = d.trust;
  in.triangleMaterial = std::move(triangleMaterial);
  in.materials = std::move(materials);
  return std::make_unique<Compositor>(in);
}

cv::Mat3b Compositor::compose(const std::vector<double>& deformedVertices, int scale) const {
  const Impl& d = *d_;
  const std::vector<double>& v = deformedVertices.empty() ? d.restVertices : deformedVertices;
  if (v.size() != 3 * d.vertexCount)
    throw InputError("The deformed organ has " + std::to_string(v.size() / 3) + " nodes, the registered one " + std::to_string(d.vertexCount) +
                     "; they must be the same mesh in the same order.");
  return compose(SurfaceView{v.data(), d.vertexCount, d.triangles.data(), d.triangles.size() / 3}, scale);
}

namespace {
// Clamped first: saturate_cast rounds through int, and a radiance beyond 2^31 (a grazing highlight) would wrap to
// black.
cv::Vec3b put(const cv::Vec3f& c) {
  return cv::Vec3b(cv::saturate_cast<uchar>(std::min(c[0], 255.0f)), cv::saturate_cast<uchar>(std::min(c[1], 255.0f)),
                   cv::saturate_cast<uchar>(std::min(c[2], 255.0f)));
}

// The organ's box on the image (its vertices in front of the camera, widened by their neighbours), within the image.
cv::Rect organBox(const std::vector<Eigen::Vector3d>& X, const std::vector<Eigen::Vector2d>& uv, int cols, int rows) {
  cv::Rect box(0, 0, 0, 0);
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  for (std::size_t i = 0; i < X.size(); ++i)
    if (X[i].z() > 0) x0 = std::min(x0, uv[i].x()), x1 = std::max(x1, uv[i].x()), y0 = std::min(y0, uv[i].y()), y1 = std::max(y1, uv[i].y());
  if (x1 >= x0)
    box = cv::Rect(cv::Point(static_cast<int>(std::max(-1.0, std::floor(x0) - 2)), static_cast<int>(std::max(-1.0, std::floor(y0) - 2))),
                   cv::Point(static_cast<int>(std::min(cols + 1.0, std::ceil(x1) + 3)), static_cast<int>(std::min(rows + 1.0, std::ceil(y1) + 3)))) &
          cv::Rect(0, 0, cols, rows);
  return box;
}
}  // namespace

// Each covered pixel shaded once at its centre; with supersampling, the rim marked on the way: pixels with the
// organ on one side and the background (or a farther part of the organ: a fold in front of it, a step in depth
// of 3 mm) on the other, against the four neighbours.
void Compositor::Impl::shadeCovered(const Shape& s, const cv::Rect& box, int scale, cv::Mat3b& out,
                                    cv::Mat1b& onRim) const {
  const Rasterization& seen = s.seen;
  cv::parallel_for_(cv::Range(box.y, box.y + box.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const int* tid = seen.triangle.ptr<int>(y);
      const float* z = seen.depth.ptr<float>(y);
      const int* up = y > 0 ? seen.triangle.ptr<int>(y - 1) : nullptr;
      const int* down = y + 1 < out.rows ? seen.triangle.ptr<int>(y + 1) : nullptr;
      const float* zUp = y > 0 ? seen.depth.ptr<float>(y - 1) : nullptr;
      const float* zDown = y + 1 < out.rows ? seen.depth.ptr<float>(y + 1) : nullptr;
      cv::Vec3b* row = out.ptr<cv::Vec3b>(y);
      uchar* flag = onRim.ptr<uchar>(y - box.y) - box.x;
      for (int x = box.x; x < box.x + box.width; ++x) {
        const int t = tid[x];
        cv::Vec3f c;
        if (t >= 0 && shadeAt(s.Xf, s.Nf, s.P, t, x, y, c)) row[x] = put(c);
        if (scale <= 1) continue;
        auto differs = [&](int u, float zu) {
          return (u < 0) != (t < 0) || (t >= 0 && u >= 0 && std::abs(zu - z[x]) > 0.003f);
        };
        flag[x] = (x > 0 && differs(tid[x - 1], z[x - 1])) || (x + 1 < out.cols && differs(tid[x + 1], z[x + 1])) ||
                  (up && differs(up[x], zUp[x])) || (down && differs(down[x], zDown[x]));
      }
    }
  });
}

// A rim pixel's colour from scale x scale samples; a sample takes the nearest of the triangles its 3x3
// neighbourhood shows that covers it, or the background.
cv::Vec3b Compositor::Impl::supersample(const Shape& s, const cv::Point& q, int scale, const cv::Mat3b& out) const {
  const Rasterization& seen = s.seen;
  std::array<int, 9> candidates;
  int count = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const int yy = q.y + dy, xx = q.x + dx;
      if (yy < 0 || xx < 0 || yy >= out.rows || xx >= out.cols) continue;
      const int u = seen.triangle(yy, xx);
      if (u >= 0 && std::find(candidates.begin(), candidates.begin() + count, u) == candidates.begin() + count) candidates[static_cast<std::size_t>(count++)] = u;
    }
  const cv::Vec3f back(background(q.y, q.x)[0], background(q.y, q.x)[1], background(q.y, q.x)[2]);
  // Which triangle each sample takes; each triangle is then shaded once, at its samples' mean position
  // (its colour does not change within a pixel), the samples it does not take showing the background.
  std::array<int, 9> taken{};
  std::array<double, 9> meanX{}, meanY{};
  int none = 0;
  // Each candidate's barycentric weights as linear functions of the image point (w = e + gx x + gy y), and
  // its vertices' inverse depths (1/z is linear on the image).
  struct Edge {
    double e0, gx0, gy0, e1, gx1, gy1, iz0, iz1, iz2;
    bool ok;
  };
  std::array<Edge, 9> edge;
  for (int k = 0; k < count; ++k) {
    const int* tri = triangles.data() + 3 * candidates[static_cast<std::size_t>(k)];
    const Eigen::Vector2d &a = s.uv[tri[0]], &b = s.uv[tri[1]], &c = s.uv[tri[2]];
    const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    Edge& E = edge[static_cast<std::size_t>(k)];
    E.ok = std::abs(area) >= 1e-12;
    if (!E.ok) continue;
    const double inv = 1.0 / area;
    // w0 = ((b.x - x)(c.y - y) - (b.y - y)(c.x - x)) / area, w1 likewise with (c, a).
    E.e0 = (b.x() * c.y() - b.y() * c.x()) * inv, E.gx0 = (b.y() - c.y()) * inv, E.gy0 = (c.x() - b.x()) * inv;
    E.e1 = (c.x() * a.y() - c.y() * a.x()) * inv, E.gx1 = (c.y() - a.y()) * inv, E.gy1 = (a.x() - c.x()) * inv;
    E.iz0 = 1.0 / s.X[tri[0]].z(), E.iz1 = 1.0 / s.X[tri[1]].z(), E.iz2 = 1.0 / s.X[tri[2]].z();
  }
  for (int sy = 0; sy < scale; ++sy)
    for (int sx = 0; sx < scale; ++sx) {
      const double px = q.x + (sx + 0.5) / scale - 0.5, py = q.y + (sy + 0.5) / scale - 0.5;
      int best = -1;
      double bestInvZ = 0;
      for (int k = 0; k < count; ++k) {
        const Edge& E = edge[static_cast<std::size_t>(k)];
        if (!E.ok) continue;
        const double w0 = E.e0 + E.gx0 * px + E.gy0 * py, w1 = E.e1 + E.gx1 * px + E.gy1 * py, w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const double invZ = w0 * E.iz0 + w1 * E.iz1 + w2 * E.iz2;  // the nearest has the largest 1/z
        if (best < 0 || invZ > bestInvZ) best = k, bestInvZ = invZ;
      }
      if (best < 0) {
        ++none;
        continue;
      }
      const auto b = static_cast<std::size_t>(best);
      ++taken[b];
      meanX[b] += px;
      meanY[b] += py;
    }
  // The pixel's own triangle was shaded at its centre already (or gave the background there): its samples
  // take that colour.
  const int own = seen.triangle(q.y, q.x);
  const cv::Vec3f centre(out(q)[0], out(q)[1], out(q)[2]);
  cv::Vec3f sum = back * static_cast<float>(none);
  for (int k = 0; k < count; ++k) {
    const auto b = static_cast<std::size_t>(k);
    if (taken[b] == 0) continue;
    cv::Vec3f c;
    if (candidates[b] == own)
      c = centre;
    else if (!shadeAt(s.Xf, s.Nf, s.P, candidates[b], meanX[b] / taken[b], meanY[b] / taken[b], c))
      c = back;
    // Each sample saturates as a pixel would (a highlight brighter than white does not bleed past the rim).
    for (int ch = 0; ch < 3; ++ch) c[ch] = std::clamp(c[ch], 0.0f, 255.0f);
    sum += static_cast<float>(taken[b]) * c;
  }
  return put(sum / static_cast<float>(scale * scale));
}
cv::Mat3b Compositor::compose(const SurfaceView& deformed, int scale) const {
  const Impl& d = *d_;
  if (deformed.vertexCount != d.vertexCount || deformed.triangleCount * 3 != d.triangles.size())
    throw InputError("The deformed organ has " + std::to_string(deformed.vertexCount) + " vertices, the registered one " + std::to_string(d.vertexCount) +
                     "; they must be the same mesh in the same order.");
  const SurfaceView surface{deformed.vertices, deformed.vertexCount, d.triangles.data(), deformed.triangleCount};
  Impl::Shape s;
  std::vector<Eigen::Vector3d>& X = s.X;
  X.resize(d.vertexCount);
  for (std::size_t i = 0; i < d.vertexCount; ++i) X[i] = d.pose.apply(surface.vertex(i));
  const std::vector<Eigen::Vector3d> N = vertexNormals(X, surface);
  s.seen = rasterizeCameraFrame(d.camera, X, surface, 1, 1e-3, d.cull);
  s.P = Impl::planes(X, d.triangles);
  s.Xf.resize(X.size()), s.Nf.resize(N.size());
  for (std::size_t i = 0; i < X.size(); ++i) s.Xf[i] = X[i].cast<float>(), s.Nf[i] = N[i].cast<float>();
  cv::Mat3b out = d.background.clone();
  s.uv.resize(d.vertexCount);
  for (std::size_t i = 0; i < d.vertexCount; ++i)
    s.uv[i] = X[i].z() > 0 ? Eigen::Vector2d(d.camera.K(0, 0) * X[i].x() / X[i].z() + d.camera.K(0, 1) * X[i].y() / X[i].z() + d.camera.K(0, 2),
                                             d.camera.K(1, 1) * X[i].y() / X[i].z() + d.camera.K(1, 2))
                           : Eigen::Vector2d(-1e9, -1e9);
  // Only inside the organ's box on the image (a pixel beyond it, and its neighbours, show no organ).
  const cv::Rect box = organBox(X, s.uv, out.cols, out.rows);
  cv::Mat1b onRim(box.size(), uchar(0));
  d.shadeCovered(s, box, scale, out, onRim);
  if (scale <= 1) return out;
  // The rim: each of its pixels gets scale x scale samples (Impl::supersample).
  std::vector<cv::Point> rim;
  if (!onRim.empty()) cv::findNonZero(onRim, rim);
  for (auto& q : rim) q += box.tl();
  cv::parallel_for_(cv::Range(0, static_cast<int>(rim.size())), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      const cv::Point q = rim[static_cast<std::size_t>(i)];
      out(q) = d.supersample(s, q, scale, out);
    }
  });
  return out;
}

}  // namespace rehearse::imaging
