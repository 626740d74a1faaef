// The composition J (appearance_fit.hpp): I_B, and over it the deformed organ re-shaded with Theta and its
// albedo, its texture looked up where each of its points was at rest. Prepared once per registered organ;
// each deformed shape is rasterised at the frame's resolution, shaded once per covered pixel, and only its
// rim is supersampled.
#include <rehearse/imaging/appearance_fit.hpp>

#include "render_into.hpp"
#include "sampling.hpp"

#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <mutex>

namespace rehearse::imaging {

struct Compositor::Impl {
  Camera camera;
  Pose pose;
  std::vector<int> triangles;  ///< 3 per triangle (the rest's; a deformed shape must have the same)
  std::size_t vertexCount = 0;
  std::vector<double> restVertices;  ///< model frame, 3n (compose() with no shape)
  std::vector<Eigen::Vector3d> restCam;  ///< rest vertices, camera frame
  std::vector<Eigen::Vector3f> restCamF;  ///< the same in single precision (the per-pixel shading's)
  float kf[5] = {};                       ///< K's fx, skew, cx, fy, cy
  float kinvF[5] = {};                    ///< K^-1's (0,0), (0,1), (0,2), (1,1), (1,2) (K is upper triangular)
  Eigen::Vector3f lightF = Eigen::Vector3f::Zero(), kdF = Eigen::Vector3f::Zero(), ksF = Eigen::Vector3f::Zero();
  /// The second source (appearance.hpp): the distant light's direction and reflection, the ambient term (RGB).
  Eigen::Vector3f roomF = Eigen::Vector3f::Zero(), krF = Eigen::Vector3f::Zero(), kaF = Eigen::Vector3f::Zero();
  Rasterization restSeen;                ///< what the frame shows of the organ at rest (triangle, depth)
  cv::Mat3b frame, background;
  cv::Mat3f albedo;
  cv::Mat3f residual;  ///< frameResidual(); empty while it is made (and when texture only)
  Appearance theta;
  bool textureOnly = false;
  /// Texture only: the colour of tissue the frame never showed (meanOrganColour: the organ's mean in the frame).
  cv::Vec3f unseenColour;
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
  /// With `cull`: the triangles that faced away from the camera at rest (1). The frame cannot have shown them: a point
  /// of one is never given the frame's colours, even where its rest position lands on a triangle sharing a vertex with
  /// it (a fold: the underside a pull turns into view took the lit top's colours, a bright tick at each shared vertex).
  std::vector<char> restBack;
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
  /// w_b = gb . (p - c)), made once per shape instead of once per pixel, with what its pixels' shading reads of its
  /// vertices (b and c, their rest positions and normals) in one place: a run of pixels on a triangle reads one record
  /// instead of a line of five arrays each (20,000 triangles: the arrays are not in cache). Single precision, like the
  /// per-pixel shading below (positions of 0.1-1 m to 1e-7: 0.1 um), which it halves the cost of.
  struct Plane {
    Eigen::Vector3f n, ga, gb;
    float offset = 0;
    Eigen::Vector3f b, c;              ///< the deformed vertices b and c
    std::array<Eigen::Vector3f, 3> r;  ///< the vertices at rest (camera frame)
    std::array<Eigen::Vector3f, 3> m;  ///< the vertices' normals
    std::array<float, 3> w{1, 1, 1};   ///< the vertices' share of the frame's detail (frameDetailWeights)
  };
  static std::vector<Plane> planes(const std::vector<Eigen::Vector3d>& X, const std::vector<Eigen::Vector3d>& N,
                                   const std::vector<Eigen::Vector3f>& rest, const std::vector<int>& triangles,
                                   const std::vector<float>& detail = {}) {
    std::vector<Plane> out(triangles.size() / 3);
    cv::parallel_for_(cv::Range(0, static_cast<int>(out.size())), [&](const cv::Range& range) {
      for (int t = range.start; t < range.end; ++t) {
        const int* tri = triangles.data() + 3 * t;
        const Eigen::Vector3d &a = X[tri[0]], &b = X[tri[1]], &c = X[tri[2]];
        Plane& q = out[static_cast<std::size_t>(t)];
        q.b = b.cast<float>(), q.c = c.cast<float>();
        for (int k = 0; k < 3; ++k) q.r[k] = rest[tri[k]], q.m[k] = N[tri[k]].cast<float>();
        if (!detail.empty())
          for (int k = 0; k < 3; ++k) q.w[k] = detail[static_cast<std::size_t>(tri[k])];
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

  /// The colours (BGR, 0..255 floats) of the deformed surface's triangle `t` seen through `n` (at most kBatch) image
  /// points (px[i], py[i]); ok[i] false where the ray grazes the triangle (the caller keeps the background). The
  /// geometry and the light are computed for all points first, in loops the compiler vectorises (no branch, no lookup),
  /// then each point's tables and images are read: this halved the shading's time against one point at a time.
  /// The first loop runs over whole groups of kLanes points (px and py hold at least n rounded up to kLanes; the
  /// points past n are computed and dropped): a run of a few pixels on one small triangle is then shaded in one
  /// vector iteration, not in the loop's scalar remainder. Each point's arithmetic is the same either way.
  static constexpr int kBatch = 64, kLanes = 8;
  void shadeBatch(const std::vector<Plane>& P, int t, int n, const float* px, const float* py, cv::Vec3f* bgr,
                  bool* ok) const;
  /// One point (the rim's samples).
  bool shadeAt(const std::vector<Plane>& P, int t, double px, double py, cv::Vec3f& bgr) const {
    alignas(32) float x[kLanes], y[kLanes];
    std::fill(x, x + kLanes, static_cast<float>(px));
    std::fill(y, y + kLanes, static_cast<float>(py));
    bool ok = false;
    shadeBatch(P, t, 1, x, y, &bgr, &ok);
    return ok;
  }
  /// Shades the pixels [x0, x1) of row y, whose triangles are tri[x] (-1: none), into colour[x - x0] and ok[x - x0].
  void shadeRow(const std::vector<Plane>& P, const int* tri, int y, int x0, int x1, cv::Vec3f* colour,
                bool* ok) const;
  void makeResidual();

  /// A deformed shape as compose() draws it: its vertices in the camera frame, its triangles' planes (with what the
  /// shading reads of their vertices), its vertices' image points and what the camera sees of it.
  struct Shape {
    std::vector<Eigen::Vector3d> X;
    std::vector<Plane> P;
    std::vector<Eigen::Vector2d> uv;
    Rasterization seen;
  };
  // The last shape's rasterisation, kept for the next (each compose takes it, and gives its own back, under the lock).
  mutable std::mutex scratchMutex;
  mutable Rasterization scratch;
  void shadeCovered(const Shape& s, const cv::Rect& box, int scale, cv::Mat3b& out, cv::Mat1b& onRim) const;
  cv::Vec3b supersample(const Shape& s, const cv::Point& q, int scale, const cv::Mat3b& out) const;
};

// Compiled for AVX2 too and chosen at run time: elementwise operations without fused multiply-adds, so the same colours
// on any processor, 10-15 % faster where AVX2 is (BENCHMARKS.md).
__attribute__((target_clones("avx2", "default"))) void Compositor::Impl::shadeBatch(
    const std::vector<Plane>& P, int t, int n, const float* px, const float* py, cv::Vec3f* bgr, bool* ok) const {
  const int* tri = triangles.data() + 3 * t;
  const Plane& q = P[static_cast<std::size_t>(t)];
  const float nx = q.n.x(), ny = q.n.y(), nz = q.n.z(), offset = q.offset;
  const float gax = q.ga.x(), gay = q.ga.y(), gaz = q.ga.z(), gbx = q.gb.x(), gby = q.gb.y(), gbz = q.gb.z();
  const Eigen::Vector3f &Xb = q.b, &Xc = q.c;
  const Eigen::Vector3f &R0 = q.r[0], &R1 = q.r[1], &R2 = q.r[2];
  const Eigen::Vector3f &N0 = q.m[0], &N1 = q.m[1], &N2 = q.m[2];
  const float lx = lightF.x(), ly = lightF.y(), lz = lightF.z();
  const bool withFalloff = !falloff.empty();
  const float specularOn = specular_ ? 1.0f : 0.0f;
  const float lobeScale = static_cast<float>(lobe.size() - 1);
  const float falloffScale = withFalloff ? static_cast<float>(falloff.size() - 1) : 0.0f;
  // The geometry and the light, per point: where the ray meets the triangle's plane, its barycentric weights, where
  // that point was at rest and its image there, the interpolated normal, Theta's diffuse and specular terms before
  // their tables (appearance.hpp: F [kd cos(theta_i) / r^2 + ks exp(-alpha^2 / 2 sigma^2) / (r^2 cos(theta_r))]).
  alignas(64) float valid[kBatch], rzs[kBatch], diffuse[kBatch], specular[kBatch], lobeF[kBatch], fallF[kBatch],
      tapFx[kBatch], tapFy[kBatch], room[kBatch], keep[kBatch];
  const float W0 = q.w[0], W1 = q.w[1], W2 = q.w[2];
  const float dx_ = roomF.x(), dy_ = roomF.y(), dz_ = roomF.z();
  alignas(64) int nearest[kBatch], lobeK[kBatch], fallK[kBatch], tapX[kBatch], tapY[kBatch];
  const int width = camera.width, height = camera.height;
  const float lastX = static_cast<float>(width - 1), lastY = static_cast<float>(height - 1);
  const int lobeLast = static_cast<int>(lobe.size()) - 2, fallLast = withFalloff ? static_cast<int>(falloff.size()) - 2 : 0;
  static_assert(kBatch % kLanes == 0);
  const int lanes = (n + kLanes - 1) / kLanes * kLanes;
  for (int i = 0; i < lanes; ++i) {
    const float dx = kinvF[0] * px[i] + kinvF[1] * py[i] + kinvF[2], dy = kinvF[3] * py[i] + kinvF[4];
    const float denom = nx * dx + ny * dy + nz;
    const float s = offset / denom;
    const float x = dx * s, y = dy * s, z = s;
    const float wa = gax * (x - Xb.x()) + gay * (y - Xb.y()) + gaz * (z - Xb.z()),
                wb = gbx * (x - Xc.x()) + gby * (y - Xc.y()) + gbz * (z - Xc.z());
    const float wc = 1 - wa - wb;
    keep[i] = std::min(1.0f, std::max(0.0f, wa * W0 + wb * W1 + wc * W2));  // the frame's detail kept here
    // Where the point was at rest, and its image there: the nearest pixel (-1: none) and the bilinear lookup's.
    const float rx = wa * R0.x() + wb * R1.x() + wc * R2.x(), ry = wa * R0.y() + wb * R1.y() + wc * R2.y(),
                rz = wa * R0.z() + wb * R1.z() + wc * R2.z();
    const float irz = 1.0f / rz;
    const float qx = kf[0] * (rx * irz) + kf[1] * (ry * irz) + kf[2], qy = kf[3] * (ry * irz) + kf[4];
    rzs[i] = rz;
    const float ux = qx + 0.5f, uy = qy + 0.5f;  // in [0, size) the nearest pixel is the truncation
    const bool inside = (rz > 0) & (ux >= 0) & (uy >= 0) & (ux < static_cast<float>(width)) &
                        (uy < static_cast<float>(height));
    nearest[i] = inside ? static_cast<int>(uy) * width + static_cast<int>(ux) : -1;
    const float bx = std::min(lastX, std::max(0.0f, qx)), by = std::min(lastY, std::max(0.0f, qy));  // NaN: 0
    tapX[i] = static_cast<int>(bx), tapY[i] = static_cast<int>(by);
    tapFx[i] = bx - static_cast<float>(tapX[i]), tapFy[i] = by - static_cast<float>(tapY[i]);
    float mx = wa * N0.x() + wb * N1.x() + wc * N2.x(), my = wa * N0.y() + wb * N1.y() + wc * N2.y(),
          mz = wa * N0.z() + wb * N1.z() + wc * N2.z();
    const float length2 = mx * mx + my * my + mz * mz;
    valid[i] = (std::abs(denom) > 0) & (length2 > 0) & (length2 <= 3.4e38f) ? 1.0f : 0.0f;
    // Normalised, and turned towards the camera (an open surface seen from inside).
    const float scale = (mx * x + my * y + mz * z > 0 ? -1.0f : 1.0f) / std::sqrt(std::max(length2, 1e-30f));
    mx *= scale, my *= scale, mz *= scale;
    room[i] = std::max(0.0f, mx * dx_ + my * dy_ + mz * dz_);
    const float tx = lx - x, ty = ly - y, tz = lz - z;
    const float r2 = std::max(tx * tx + ty * ty + tz * tz, 1e-12f), inv2 = 1.0f / r2, invR = std::sqrt(inv2);
    const float cosI = (mx * tx + my * ty + mz * tz) * invR;
    const float p2 = x * x + y * y + z * z, invP = -1.0f / std::sqrt(std::max(p2, 1e-30f));
    const float vx = x * invP, vy = y * invP, vz = z * invP;  // towards the camera
    const float cosR = std::max(mx * vx + my * vy + mz * vz, 1e-3f);
    const float hx = tx * invR + vx, hy = ty * invR + vy, hz = tz * invR + vz;
    const float h2 = hx * hx + hy * hy + hz * hz;
    const float cosAlpha = (mx * hx + my * hy + mz * hz) / std::sqrt(std::max(h2, 1e-30f));  // h = 0: 0
    const float lit = cosI > 0 ? 1.0f : 0.0f;
    diffuse[i] = lit * cosI * inv2;
    specular[i] = specularOn * lit * inv2 / cosR;
    const float lu = std::min(std::max(cosAlpha, 0.0f), 1.0f) * lobeScale;  // NaN: 0 (max(NaN, 0) is 0)
    lobeK[i] = std::min(static_cast<int>(lu), lobeLast);
    lobeF[i] = lu - static_cast<float>(lobeK[i]);
    // The scope's light cone and vignetting: cos^2(psi) = z^2 / |p|^2 on the fall-off's table (-1: behind the scope).
    const bool inFront = (z > 0) & (p2 > 0);
    const float fu = std::min(std::max(z * z / std::max(p2, 1e-30f), 0.0f), 1.0f) * falloffScale;
    fallK[i] = inFront ? std::min(static_cast<int>(fu), fallLast) : -1;
    fallF[i] = fu - static_cast<float>(std::max(fallK[i], 0));
  }
  const int material = triangleMaterial.empty() ? 0 : triangleMaterial[static_cast<std::size_t>(t)];
  const cv::Vec3f materialAlbedo = material > 0 ? materials[static_cast<std::size_t>(material - 1)] : cv::Vec3f();
  const int* shownTriangle = restSeen.triangle.ptr<int>(0);
  const float* shownDepth = restSeen.depth.ptr<float>(0);
  const bool backAtRest = !restBack.empty() && restBack[static_cast<std::size_t>(t)];
  for (int i = 0; i < n; ++i) {
    ok[i] = false;
    if (!(valid[i] > 0)) continue;
    // Whether the frame showed the point where it was at rest (the triangle, one sharing a vertex with it, or a
    // surface no nearer than 2 mm in front of it: not hidden behind another part of the organ).
    bool seen = false;
    if (const int at = nearest[i]; at >= 0 && !backAtRest) {
      if (const int shownT = shownTriangle[at]; shownT >= 0) {
        seen = shownDepth[at] > rzs[i] - 0.002f;
        const int* shown = triangles.data() + 3 * shownT;
        for (int a = 0; a < 3 && !seen; ++a)
          for (int b = 0; b < 3; ++b) seen |= shown[a] == tri[b];
      }
    }
    const BilinearTap tap{tapX[i], tapY[i], std::min(tapX[i] + 1, width - 1), std::min(tapY[i] + 1, height - 1),
                          tapFx[i], tapFy[i]};
    cv::Vec3f& out = bgr[i];
    if (textureOnly && material == 0) {
      // Tissue the frame never showed (an underside a pull turns into view) has no texture to carry: it takes the
      // organ's mean colour rather than showing the background through the organ; so, as far as it is stretched over
      // more than the frame showed of it (frameDetailWeights), does tissue the frame saw obliquely.
      out = seen ? keep[i] * bilinear(frame, tap) + (1 - keep[i]) * unseenColour : unseenColour;
      ok[i] = true;
      continue;
    }
    // The albedo: a material's (tissue the frame never showed: a cut's faces), the frame's where it saw the
    // tissue, else ratio 1, the fitted kd (its back).
    const cv::Vec3f albedoHere = material > 0 ? materialAlbedo : seen ? bilinear(albedo, tap) : cv::Vec3f(1, 1, 1);
    const float spec =
        specular[i] > 0 ? ((1 - lobeF[i]) * lobe[lobeK[i]] + lobeF[i] * lobe[lobeK[i] + 1]) * specular[i] : 0.0f;
    const float fall = !withFalloff ? 1.0f
                       : fallK[i] < 0 ? 0.0f
                                      : (1 - fallF[i]) * falloff[fallK[i]] + fallF[i] * falloff[fallK[i] + 1];
    // The model's shading: what the albedo multiplies (the scope's diffuse term and the second source), and the rest.
    float shaded[3], glossy[3];
    for (int k = 0; k < 3; ++k) {
      shaded[k] = 255.0f * (fall * kdF[2 - k] * diffuse[i] + krF[2 - k] * room[i] + kaF[2 - k]);
      glossy[k] = 255.0f * fall * ksF[2 - k] * spec;
      out[k] = albedoHere[k] * shaded[k] + glossy[k];
    }
    // The frame's detail over the model as a frame can show it, and the model's change applied as far as the fit
    // earned it: trust (min(model, 255) + residual) + (1 - trust) frame, one lookup of `carried` (made once); where the
    // tissue is stretched over more than the frame showed of it, the model (albedo 1) instead, as far as it is.
    if (material == 0 && seen && !carried.empty()) {
      const cv::Vec3f c = bilinear(carried, tap);
      for (int k = 0; k < 3; ++k) out[k] = trust * std::min(out[k], 255.0f) + c[k];
    }
    if (material == 0 && seen && keep[i] < 1)
      for (int k = 0; k < 3; ++k)
        out[k] = keep[i] * out[k] + (1 - keep[i]) * std::min(shaded[k] + glossy[k], 255.0f);
    ok[i] = true;
  }
}

void Compositor::Impl::shadeRow(const std::vector<Plane>& P, const int* tri, int y, int x0, int x1, cv::Vec3f* colour,
                                bool* ok) const {
  alignas(64) float px[kBatch], py[kBatch];
  for (int i = 0; i < kBatch; ++i) py[i] = static_cast<float>(y);
  for (int x = x0; x < x1;) {
    const int t = tri[x];
    int end = x + 1;  // the run of pixels on the same triangle, up to a batch
    while (end < x1 && end - x < kBatch && tri[end] == t) ++end;
    if (t < 0) {
      std::fill(ok + (x - x0), ok + (end - x0), false);
    } else {
      const int lanes = (end - x + kLanes - 1) / kLanes * kLanes;  // (past the run: shadeBatch's last group)
      for (int i = 0; i < lanes; ++i) px[i] = static_cast<float>(x + i);
      shadeBatch(P, t, end - x, px, py, colour + (x - x0), ok + (x - x0));
    }
    x = end;
  }
}

cv::Vec3f meanOrganColour(const cv::Mat3b& frame, const cv::Mat1i& triangleAtRest) {
  cv::Scalar m;
  if (triangleAtRest.size() == frame.size() && cv::countNonZero(triangleAtRest >= 0) > 0)
    m = cv::mean(frame, triangleAtRest >= 0);
  else
    m = cv::mean(frame);  // the frame shows none of the organ at rest: its own mean
  return cv::Vec3f(static_cast<float>(m[0]), static_cast<float>(m[1]), static_cast<float>(m[2]));
}

std::vector<float> frameDetailWeights(const Camera& camera, const std::vector<Eigen::Vector3d>& rest,
                                      const std::vector<Eigen::Vector3d>& now, const std::vector<int>& triangles) {
  std::vector<float> w(rest.size(), 1.0f);
  if (now.size() != rest.size()) return w;
  // Each triangle's image area (px^2) at rest and now, summed at its vertices.
  std::vector<double> atRest(rest.size(), 0.0), atNow(rest.size(), 0.0);
  auto area = [&](const std::vector<Eigen::Vector3d>& X, const int* t) {
    Eigen::Vector2d q[3];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& x = X[static_cast<std::size_t>(t[k])];
      if (!(x.z() > 1e-6)) return 0.0;
      q[k] = camera.project(x);
    }
    return 0.5 * std::abs((q[1] - q[0]).x() * (q[2] - q[0]).y() - (q[1] - q[0]).y() * (q[2] - q[0]).x());
  };
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const double a = area(rest, triangles.data() + t), b = area(now, triangles.data() + t);
    for (int k = 0; k < 3; ++k) {
      atRest[static_cast<std::size_t>(triangles[t + static_cast<std::size_t>(k)])] += a;
      atNow[static_cast<std::size_t>(triangles[t + static_cast<std::size_t>(k)])] += b;
    }
  }
  constexpr double kFull = 2.0, kNone = 5.0, kTiny = 0.05;  // area ratios; px^2 (a tiny area's ratio is not noise)
  for (std::size_t i = 0; i < w.size(); ++i) {
    const double ratio = (atNow[i] + kTiny) / (atRest[i] + kTiny);
    w[i] = static_cast<float>(std::clamp((kNone - ratio) / (kNone - kFull), 0.0, 1.0));
  }
  return w;
}

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
  const Eigen::Matrix3d Kinv = in.camera.K.inverse();
  d.kinvF[0] = static_cast<float>(Kinv(0, 0)), d.kinvF[1] = static_cast<float>(Kinv(0, 1)),
  d.kinvF[2] = static_cast<float>(Kinv(0, 2)), d.kinvF[3] = static_cast<float>(Kinv(1, 1)),
  d.kinvF[4] = static_cast<float>(Kinv(1, 2));
  d.lightF = in.theta.lightPosition.cast<float>();
  d.kdF = in.theta.kd.cast<float>();
  d.ksF = in.theta.ks.cast<float>();
  if (in.theta.hasDistantLight()) d.roomF = in.theta.roomDirection.cast<float>(), d.krF = in.theta.kr.cast<float>();
  d.kaF = in.theta.ka.cast<float>();
  d.cull = closedAndOutward(d.restCam, in.rest);
  d.restSeen = rasterizeCameraFrame(in.camera, d.restCam, in.rest, 1, 1e-3, d.cull);
  if (d.cull) {
    d.restBack.resize(in.rest.triangleCount);
    for (std::size_t t = 0; t < in.rest.triangleCount; ++t) {
      const Eigen::Vector3d &a = d.restCam[d.triangles[3 * t]], &b = d.restCam[d.triangles[3 * t + 1]],
                            &c = d.restCam[d.triangles[3 * t + 2]];
      d.restBack[t] = a.dot((b - a).cross(c - a)) >= 0;  // the rasteriser's culling test (render.cpp)
    }
  }
  d.frame = in.frame;
  d.background = in.background;
  d.albedo = in.albedo.empty() ? cv::Mat3f(size, cv::Vec3f(1, 1, 1)) : in.albedo;
  d.theta = in.theta;
  d.textureOnly = in.textureOnly;
  d.unseenColour = meanOrganColour(in.frame, d.restSeen.triangle);
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
  const std::vector<Eigen::Vector3d> normals =
      vertexNormals(restCam, SurfaceView{restVertices.data(), vertexCount, triangles.data(), triangles.size() / 3});
  const std::vector<Plane> P = planes(restCam, normals, restCamF, triangles);
  cv::Mat3f out(frame.size(), cv::Vec3f(0, 0, 0));
  const cv::Mat1i& tri = restSeen.triangle;
  cv::parallel_for_(cv::Range(1, std::max(1, frame.rows - 1)), [&](const cv::Range& rows) {
    std::vector<cv::Vec3f> model(static_cast<std::size_t>(frame.cols));
    std::unique_ptr<bool[]> ok(new bool[static_cast<std::size_t>(frame.cols)]);
    for (int y = rows.start; y < rows.end; ++y) {
      if (frame.cols < 3) break;
      shadeRow(P, tri.ptr<int>(y), y, 1, frame.cols - 1, model.data(), ok.get());
      for (int x = 1; x + 1 < frame.cols; ++x) {
        const int t = tri(y, x);
        if (t < 0 || tri(y - 1, x) < 0 || tri(y + 1, x) < 0 || tri(y, x - 1) < 0 || tri(y, x + 1) < 0) continue;
        if (!triangleMaterial.empty() && triangleMaterial[static_cast<std::size_t>(t)] != 0) continue;
        if (!ok[static_cast<std::size_t>(x - 1)]) continue;
        // Against the model as the frame can show it (a highlight brighter than white is white there): a clipped
        // highlight carries nothing to where the organ moves.
        const cv::Vec3f& m = model[static_cast<std::size_t>(x - 1)];
        const cv::Vec3b f = frame(y, x);
        for (int k = 0; k < 3; ++k) out(y, x)[k] = f[k] - std::min(m[k], 255.0f);
      }
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
  if (box.width <= 0 || box.height <= 0) return;
  const Rasterization& seen = s.seen;
  cv::parallel_for_(cv::Range(box.y, box.y + box.height), [&](const cv::Range& rows) {
    std::vector<cv::Vec3f> colour(static_cast<std::size_t>(box.width));
    std::unique_ptr<bool[]> ok(new bool[static_cast<std::size_t>(box.width)]);
    for (int y = rows.start; y < rows.end; ++y) {
      const int* tid = seen.triangle.ptr<int>(y);
      shadeRow(s.P, tid, y, box.x, box.x + box.width, colour.data(), ok.get());
      cv::Vec3b* row = out.ptr<cv::Vec3b>(y);
      for (int x = box.x; x < box.x + box.width; ++x)
        if (ok[static_cast<std::size_t>(x - box.x)]) row[x] = put(colour[static_cast<std::size_t>(x - box.x)]);
      if (scale <= 1) continue;
      // The rim, without a branch (vectorised): a neighbour differs when one of the two shows the organ and the other
      // not, or both do 3 mm apart in depth; the image's edge has no neighbour there.
      const float* z = seen.depth.ptr<float>(y);
      const int* up = seen.triangle.ptr<int>(y > 0 ? y - 1 : y);
      const int* down = seen.triangle.ptr<int>(y + 1 < out.rows ? y + 1 : y);
      const float* zUp = seen.depth.ptr<float>(y > 0 ? y - 1 : y);
      const float* zDown = seen.depth.ptr<float>(y + 1 < out.rows ? y + 1 : y);
      uchar* flag = onRim.ptr<uchar>(y - box.y) - box.x;
      const int xa = std::max(box.x, 1), xb = std::min(box.x + box.width, out.cols - 1);
      auto differs = [](int t, int u, float zt, float zu) {
        const bool a = t >= 0, b = u >= 0;
        return (a != b) | (a & b & (std::abs(zu - zt) > 0.003f));
      };
      for (int x = xa; x < xb; ++x)
        flag[x] = differs(tid[x], tid[x - 1], z[x], z[x - 1]) | differs(tid[x], tid[x + 1], z[x], z[x + 1]) |
                  differs(tid[x], up[x], z[x], zUp[x]) | differs(tid[x], down[x], z[x], zDown[x]);
      for (int x : {box.x, box.x + box.width - 1}) {  // the box's ends (at the image's edge, one side has none)
        if (x < xa || x >= xb) {
          const int t = tid[x];
          flag[x] = (x > 0 && differs(t, tid[x - 1], z[x], z[x - 1])) ||
                    (x + 1 < out.cols && differs(t, tid[x + 1], z[x], z[x + 1])) ||
                    differs(t, up[x], z[x], zUp[x]) || differs(t, down[x], z[x], zDown[x]);
        }
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
    else if (!shadeAt(s.P, candidates[b], meanX[b] / taken[b], meanY[b] / taken[b], c))
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
  {
    const std::lock_guard<std::mutex> lock(d.scratchMutex);
    std::swap(s.seen, d.scratch);  // (empty when another compose holds them: that one allocates its own)
  }
  struct GiveBack {
    const Impl& d;
    Rasterization& seen;
    ~GiveBack() {
      const std::lock_guard<std::mutex> lock(d.scratchMutex);
      std::swap(seen, d.scratch);
    }
  } giveBack{d, s.seen};
  rasterizeCameraFrameInto(s.seen, d.camera, X, surface, 1, 1e-3, d.cull);
  s.P = Impl::planes(X, N, d.restCamF, d.triangles, frameDetailWeights(d.camera, d.restCam, X, d.triangles));
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
