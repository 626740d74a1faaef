#include <rehearse/imaging/render.hpp>

#include "render_into.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace rehearse::imaging {

std::vector<Eigen::Vector3d> vertexNormals(const std::vector<Eigen::Vector3d>& x, const SurfaceView& s) {
  std::vector<Eigen::Vector3d> normal(x.size(), Eigen::Vector3d::Zero());
  for (std::size_t t = 0; t < s.triangleCount; ++t) {
    const int* tri = s.triangles + 3 * t;
    const Eigen::Vector3d n = (x[tri[1]] - x[tri[0]]).cross(x[tri[2]] - x[tri[0]]);
    for (int k = 0; k < 3; ++k) normal[tri[k]] += n;
  }
  for (auto& n : normal) {
    const double l = n.norm();
    n = l > 0 ? Eigen::Vector3d(n / l) : Eigen::Vector3d(0, 0, -1);
  }
  return normal;
}

namespace {

struct Posed {
  std::vector<Eigen::Vector3d> x;       // camera frame
  std::vector<Eigen::Vector3d> normal;  // camera frame, unit (area-weighted vertex normals)
};

Posed pose3(const Pose& pose, const SurfaceView& s, bool normals) {
  Posed p;
  p.x.resize(s.vertexCount);
  for (std::size_t i = 0; i < s.vertexCount; ++i) p.x[i] = pose.apply(s.vertex(i));
  if (normals) p.normal = vertexNormals(p.x, s);
  return p;
}

Eigen::Matrix3d scaledK(const Camera& c, int s) {
  Eigen::Matrix3d K = c.K;
  K.row(0) *= s;
  K.row(1) *= s;
  K(0, 2) = s * c.cx() + (s - 1) / 2.0;
  K(1, 2) = s * c.cy() + (s - 1) / 2.0;
  K(2, 2) = 1;
  return K;
}

void checkCamera(const Camera& c) {
  if (auto p = c.problem(); !p.empty()) throw InputError(p);
}

}  // namespace

bool closedAndOutward(const std::vector<Eigen::Vector3d>& points, const SurfaceView& s) {
  if (s.triangleCount == 0 || points.size() != s.vertexCount) return false;
  std::vector<std::pair<int, int>> edges;  // directed, as the triangles run them
  edges.reserve(3 * s.triangleCount);
  double volume = 0, area = 0;
  for (std::size_t t = 0; t < s.triangleCount; ++t) {
    const int* tri = s.triangles + 3 * t;
    for (int k = 0; k < 3; ++k) edges.emplace_back(tri[k], tri[(k + 1) % 3]);
    volume += points[tri[0]].dot(points[tri[1]].cross(points[tri[2]]));
    area += 0.5 * (points[tri[1]] - points[tri[0]]).cross(points[tri[2]] - points[tri[0]]).norm();
  }
  std::sort(edges.begin(), edges.end());
  // The edges not shared with a triangle running them the other way: borders, and edges run twice the same way (a
  // triangle turned over, a non-manifold edge). A hole no wider than half its border's length shows the inside
  // through it; culling hides that inside (the background shows instead) and nothing else.
  double defects = 0;
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const bool twice = (i + 1 < edges.size() && edges[i + 1] == edges[i]) || (i > 0 && edges[i - 1] == edges[i]);
    if (twice || !std::binary_search(edges.begin(), edges.end(), std::make_pair(edges[i].second, edges[i].first)))
      defects += (points[static_cast<std::size_t>(edges[i].first)] - points[static_cast<std::size_t>(edges[i].second)]).norm();
  }
  constexpr double kOpening = 0.02;  // of the square root of the area: the widest opening culled (render.hpp)
  return volume > 0 && 0.5 * defects <= kOpening * std::sqrt(area);
}

namespace {

// One triangle's rows y0..y1 (its columns x0..x1) drawn into the buffers where it is nearer. Compiled for AVX2 too and
// chosen at run time: the same operations, elementwise and without fused multiply-adds, so the same result on any
// processor (measured 10-15 % faster where AVX2 is).
__attribute__((target_clones("avx2", "default"))) void drawTriangle(Rasterization& r, const SurfaceView& s,
                                                                   const std::vector<Eigen::Vector3d>& pts,
                                                                   const std::vector<Eigen::Vector2d>& uv, int t, int x0,
                                                                   int x1, int y0, int y1) {
  const int* tri = s.triangles + 3 * t;
  const Eigen::Vector2d a = uv[tri[0]], b = uv[tri[1]], c = uv[tri[2]];
  const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
  const double inv = 1.0 / area;
  // The barycentric weights are linear along a row: each row's span is solved for (widened by a pixel),
  // and only it is walked, with the weights computed and tested per pixel as before.
  const double g0 = (b.y() - c.y()) * inv, g1 = (c.y() - a.y()) * inv, g2 = -g0 - g1;
  const double iz0 = 1.0 / pts[tri[0]].z(), iz1 = 1.0 / pts[tri[1]].z(), iz2 = 1.0 / pts[tri[2]].z();
  for (int y = y0; y <= y1; ++y) {
    int* tid = r.triangle.ptr<int>(y);
    float* dep = r.depth.ptr<float>(y);
    const double py = y, px0 = x0;
    const double w0s = ((b.x() - px0) * (c.y() - py) - (b.y() - py) * (c.x() - px0)) * inv;
    const double w1s = ((c.x() - px0) * (a.y() - py) - (c.y() - py) * (a.x() - px0)) * inv;
    const double w2s = 1.0 - w0s - w1s;
    double lo = x0, hi = x1;
    bool empty = false;
    for (const auto& [w, g] : {std::pair{w0s, g0}, std::pair{w1s, g1}, std::pair{w2s, g2}}) {
      if (g > 0)
        lo = std::max(lo, x0 - w / g);
      else if (g < 0)
        hi = std::min(hi, x0 - w / g);
      else
        empty |= w < 0;
    }
    if (empty) continue;
    const int xs = std::max(x0, static_cast<int>(std::ceil(lo)) - 1),
              xe = std::min(x1, static_cast<int>(std::floor(hi)) + 1);
    // Without a branch (vectorised): a pixel outside the triangle, or behind what is drawn there, keeps it.
    const double bx = b.x(), by = b.y(), cx = c.x(), cy = c.y(), ax = a.x(), ay = a.y();
    for (int x = xs; x <= xe; ++x) {
      const double px = x;
      const double w0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) * inv;
      const double w1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) * inv;
      const double w2 = 1.0 - w0 - w1;
      const double z = 1.0 / (w0 * iz0 + w1 * iz1 + w2 * iz2);
      const bool nearer = (w0 >= 0) & (w1 >= 0) & (w2 >= 0) & (z < static_cast<double>(dep[x]));
      dep[x] = nearer ? static_cast<float>(z) : dep[x];
      tid[x] = nearer ? t : tid[x];
    }
  }
}

}  // namespace

Rasterization rasterizeCameraFrame(const Camera& camera, const std::vector<Eigen::Vector3d>& pts, const SurfaceView& s,
                                   int scale, double nearPlane, bool cullBackFaces) {
  Rasterization r;
  rasterizeCameraFrameInto(r, camera, pts, s, scale, nearPlane, cullBackFaces);
  return r;
}

void rasterizeCameraFrameInto(Rasterization& r, const Camera& camera, const std::vector<Eigen::Vector3d>& pts,
                              const SurfaceView& s, int scale, double nearPlane, bool cullBackFaces) {
  checkCamera(camera);
  scale = std::max(1, scale);
  if (pts.size() != s.vertexCount) throw InputError("The posed surface has " + std::to_string(pts.size()) + " points for " + std::to_string(s.vertexCount) + " vertices.");
  const int W = camera.width * scale, H = camera.height * scale;
  r.scale = scale;
  r.triangle.create(H, W);  // (the buffers given are kept when they have this size: every row is set below)
  r.depth.create(H, W);
  const Eigen::Matrix3d K = scaledK(camera, scale);
  std::vector<Eigen::Vector2d> uv(s.vertexCount);
  for (std::size_t i = 0; i < s.vertexCount; ++i) {
    const auto& xi = pts[i];
    uv[i] = xi.z() > 0 ? Eigen::Vector2d(K(0, 0) * xi.x() / xi.z() + K(0, 1) * xi.y() / xi.z() + K(0, 2),
                                         K(1, 1) * xi.y() / xi.z() + K(1, 2))
                      : Eigen::Vector2d(0, 0);
  }
  // Each triangle set up once (its rows and columns on the image, or none: behind the near plane, edge-on,
  // facing away when culling, or off the image).
  struct Setup {
    int x0 = 0, x1 = -1, y0 = 0, y1 = -1;
  };
  std::vector<Setup> setup(s.triangleCount);
  cv::parallel_for_(cv::Range(0, static_cast<int>(s.triangleCount)), [&](const cv::Range& range) {
    for (int t = range.start; t < range.end; ++t) {
      const int* tri = s.triangles + 3 * t;
      if (pts[tri[0]].z() <= nearPlane || pts[tri[1]].z() <= nearPlane || pts[tri[2]].z() <= nearPlane) continue;
      const Eigen::Vector2d a = uv[tri[0]], b = uv[tri[1]], c = uv[tri[2]];
      const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
      if (std::abs(area) < 1e-12) continue;
      // The image-plane area has the sign of a . ((b - a) x (c - a)) (the points in front of the camera):
      // positive when the triangle's outward side faces away from it.
      if (cullBackFaces && area > 0) continue;
      Setup& q = setup[static_cast<std::size_t>(t)];
      q.x0 = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}))));
      q.x1 = std::min(W - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}))));
      q.y0 = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}))));
      q.y1 = std::min(H - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}))));
      if (q.x0 > q.x1) q.y1 = q.y0 - 1;
    }
  });
  // Bands of rows in parallel, each drawing the triangles that reach its rows, in triangle order: each pixel is
  // drawn by one thread in triangle order, so the result does not depend on the threads.
  const int bands = std::max(1, std::min(H, 4 * cv::getNumThreads()));
  auto bandOf = [&](int y) { return static_cast<int>(static_cast<long>(y) * bands / H); };
  std::vector<std::vector<int>> inBand(static_cast<std::size_t>(bands));
  for (std::size_t t = 0; t < s.triangleCount; ++t)
    if (setup[t].y0 <= setup[t].y1)
      for (int band = bandOf(setup[t].y0); band <= bandOf(setup[t].y1); ++band)
        inBand[static_cast<std::size_t>(band)].push_back(static_cast<int>(t));
  cv::parallel_for_(cv::Range(0, bands), [&](const cv::Range& range) {
    for (int band = range.start; band < range.end; ++band) {
      // The rows y with bandOf(y) == band: y >= band H / bands, rounded up.
      const int bandTop = static_cast<int>((static_cast<long>(band) * H + bands - 1) / bands);
      const int bandEnd = static_cast<int>((static_cast<long>(band + 1) * H + bands - 1) / bands) - 1;
      if (bandTop > bandEnd) continue;
      r.triangle.rowRange(bandTop, bandEnd + 1).setTo(-1);
      r.depth.rowRange(bandTop, bandEnd + 1).setTo(std::numeric_limits<float>::infinity());
      for (int t : inBand[static_cast<std::size_t>(band)]) {
        const Setup& q = setup[static_cast<std::size_t>(t)];
        drawTriangle(r, s, pts, uv, t, q.x0, q.x1, std::max(bandTop, q.y0), std::min(bandEnd, q.y1));
      }
    }
  });
}

namespace {

// Per triangle, the inverse of [a b c] (its camera-frame vertices as columns): the ray t d through a pixel
// meets the triangle's plane where M d / sum(M d) are the point's barycentric coordinates and
// t = 1 / sum(M d) (perspective-correct, no per-pixel cross product). Singular (ok = 0) when the plane
// passes through the camera's centre: the triangle is seen edge-on.
struct TriangleRays {
  std::vector<Eigen::Matrix3d> inverse;
  std::vector<char> ok;
};

TriangleRays triangleRays(const Posed& P, const SurfaceView& s) {
  TriangleRays r;
  r.inverse.resize(s.triangleCount);
  r.ok.assign(s.triangleCount, 0);
  for (std::size_t t = 0; t < s.triangleCount; ++t) {
    const int* tri = s.triangles + 3 * t;
    Eigen::Matrix3d V;
    V << P.x[static_cast<std::size_t>(tri[0])], P.x[static_cast<std::size_t>(tri[1])], P.x[static_cast<std::size_t>(tri[2])];
    const double det = V.determinant();
    const double size = V.col(0).norm() * V.col(1).norm() * V.col(2).norm();
    if (!(std::abs(det) > 1e-12 * size)) continue;
    r.inverse[t] = V.inverse();
    r.ok[t] = 1;
  }
  return r;
}

// Camera-frame point, smooth normal and barycentric coordinates seen along the ray d (z = 1) through a pixel
// of a rasterization that found triangle tid there.
inline __attribute__((always_inline)) bool surfacePoint(const TriangleRays& R, const Posed& P, const SurfaceView& s, int tid, const Eigen::Vector3d& d, Eigen::Vector3d& point,
                  Eigen::Vector3d& normal, Eigen::Vector3d* barycentric = nullptr) {
  const auto t = static_cast<std::size_t>(tid);
  if (!R.ok[t]) return false;
  Eigen::Vector3d w = R.inverse[t] * d;
  const double sum = w.sum();
  if (!(std::abs(sum) > 1e-300)) return false;
  w /= sum;
  point = d / sum;
  const int* tri = s.triangles + 3 * tid;
  normal = (w[0] * P.normal[static_cast<std::size_t>(tri[0])] + w[1] * P.normal[static_cast<std::size_t>(tri[1])] +
            w[2] * P.normal[static_cast<std::size_t>(tri[2])]).normalized();
  if (normal.dot(-point) < 0) normal = -normal;  // an open surface seen from inside
  if (barycentric) *barycentric = w;
  return normal.allFinite();
}

}  // namespace

Rasterization rasterize(const Camera& camera, const Pose& pose, const SurfaceView& surface, int scale, double nearPlane) {
  checkCamera(camera);
  return rasterizeCameraFrame(camera, pose3(pose, surface, false).x, surface, scale, nearPlane);
}

std::optional<SurfacePick> pickSurface(const Camera& camera, const Pose& pose, const SurfaceView& s, const Eigen::Vector2d& pixel,
                                       double nearPlane) {
  checkCamera(camera);
  // Moller-Trumbore in the camera frame, ray from the centre through the pixel (z = 1 at the image plane).
  const Eigen::Vector3d d = scaledK(camera, 1).inverse() * pixel.homogeneous();
  const Posed P = pose3(pose, s, false);
  std::optional<SurfacePick> best;
  for (std::size_t t = 0; t < s.triangleCount; ++t) {
    const int* tri = s.triangles + 3 * t;
    const Eigen::Vector3d &a = P.x[tri[0]], &b = P.x[tri[1]], &c = P.x[tri[2]];
    if (a.z() <= nearPlane || b.z() <= nearPlane || c.z() <= nearPlane) continue;  // as the rasteriser
    const Eigen::Vector3d e1 = b - a, e2 = c - a, p = d.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-300) continue;
    const double inv = 1 / det;
    const double u = -a.dot(p) * inv;
    if (u < 0 || u > 1) continue;
    const Eigen::Vector3d q = (-a).cross(e1);
    const double v = d.dot(q) * inv;
    if (v < 0 || u + v > 1) continue;
    const double z = e2.dot(q) * inv;  // d has z = 1, so the ray parameter is the depth
    if (z <= 0 || (best && z >= best->depth)) continue;
    if (!best) best.emplace();
    best->triangle = static_cast<int>(t);
    best->depth = z;
  }
  if (!best) return best;
  const Eigen::Vector3d xc = d * best->depth;
  best->model = pose.R.transpose() * (xc - pose.t);
  const int* tri = s.triangles + 3 * best->triangle;
  double nearest = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    const double dist = (P.x[tri[k]] - xc).norm();
    if (dist < nearest) {
      nearest = dist;
      best->nearestVertex = tri[k];
    }
  }
  return best;
}

SurfaceGeometry surfaceGeometry(const Camera& camera, const Pose& pose, const SurfaceView& surface, int scale) {
  checkCamera(camera);
  scale = std::max(1, scale);
  const Posed P = pose3(pose, surface, true);
  bool inFront = false;
  for (const auto& x : P.x) inFront |= x.z() > 1e-3;
  if (!inFront) throw InputError("The organ lies behind the camera; check the pose (z must be positive in the camera frame).");
  Rasterization r = rasterizeCameraFrame(camera, P.x, surface, scale, 1e-3);
  const Eigen::Matrix3d Kinv = scaledK(camera, scale).inverse();
  const TriangleRays rays = triangleRays(P, surface);
  SurfaceGeometry g;
  g.triangle = r.triangle;
  g.position = cv::Mat3f(r.triangle.size(), cv::Vec3f(0, 0, 0));
  g.normal = cv::Mat3f(r.triangle.size(), cv::Vec3f(0, 0, 0));
  g.barycentric = cv::Mat3f(r.triangle.size(), cv::Vec3f(0, 0, 0));
  cv::parallel_for_(cv::Range(0, g.triangle.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < g.triangle.cols; ++x) {
        const int t = g.triangle(y, x);
        if (t < 0) continue;
        Eigen::Vector3d p, n, w;
        if (!surfacePoint(rays, P, surface, t, Kinv * Eigen::Vector3d(x, y, 1), p, n, &w)) {
          g.triangle(y, x) = -1;
          continue;
        }
        const double wa = w[0], wb = w[1];
        g.position(y, x) = cv::Vec3f(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
        g.normal(y, x) = cv::Vec3f(static_cast<float>(n.x()), static_cast<float>(n.y()), static_cast<float>(n.z()));
        g.barycentric(y, x) = cv::Vec3f(static_cast<float>(wa), static_cast<float>(wb), static_cast<float>(1 - wa - wb));
      }
  });
  return g;
}

cv::Mat1b renderMask(const Camera& camera, const Pose& pose, const SurfaceView& surface, int scale) {
  auto r = rasterize(camera, pose, surface, scale);
  cv::Mat1b full = r.triangle >= 0;
  if (r.scale == 1) return full;
  cv::Mat small;
  cv::resize(full, small, cv::Size(camera.width, camera.height), 0, 0, cv::INTER_AREA);
  return small >= 128;
}

cv::Mat3b renderShaded(const Camera& camera, const Pose& pose, const SurfaceView& surface, const Appearance& appearance,
                       const cv::Mat3b& background, int scale) {
  checkCamera(camera);
  scale = std::max(1, scale);
  const Posed P = pose3(pose, surface, true);
  const Rasterization r = rasterizeCameraFrame(camera, P.x, surface, scale, 1e-3);
  const Eigen::Matrix3d Kinv = scaledK(camera, scale).inverse();
  const TriangleRays rays = triangleRays(P, surface);
  cv::Mat3b bg;
  if (background.empty()) bg = cv::Mat3b(camera.height, camera.width, cv::Vec3b(0, 0, 0));
  else bg = background;
  cv::Mat3b full;
  cv::resize(bg, full, cv::Size(camera.width * scale, camera.height * scale), 0, 0, cv::INTER_LINEAR);
  cv::parallel_for_(cv::Range(0, full.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const int* tid = r.triangle.ptr<int>(y);
      cv::Vec3b* out = full.ptr<cv::Vec3b>(y);
      for (int x = 0; x < full.cols; ++x) {
        if (tid[x] < 0) continue;
        Eigen::Vector3d p, n;
        if (!surfacePoint(rays, P, surface, tid[x], Kinv * Eigen::Vector3d(x, y, 1), p, n)) continue;
        const Eigen::Vector3d rgb = appearance.shade(p, n);
        out[x] = cv::Vec3b(cv::saturate_cast<uchar>(rgb.z() * 255.0), cv::saturate_cast<uchar>(rgb.y() * 255.0),
                           cv::saturate_cast<uchar>(rgb.x() * 255.0));
      }
    }
  });
  if (scale == 1) return full;
  cv::Mat3b small;
  cv::resize(full, small, cv::Size(camera.width, camera.height), 0, 0, cv::INTER_AREA);
  return small;
}

cv::Mat4b renderOverlay(const Camera& camera, const Pose& pose, const SurfaceView& surface, const cv::Vec3b& colour) {
  checkCamera(camera);
  const Posed P = pose3(pose, surface, true);
  const Rasterization r = rasterizeCameraFrame(camera, P.x, surface, 1, 1e-3);
  const Eigen::Matrix3d Kinv = camera.K.inverse();
  const TriangleRays rays = triangleRays(P, surface);
  cv::Mat4b out(camera.height, camera.width, cv::Vec4b(0, 0, 0, 0));
  cv::parallel_for_(cv::Range(0, out.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < out.cols; ++x) {
        int t = r.triangle(y, x);
        if (t < 0) continue;
        Eigen::Vector3d p, n;
        if (!surfacePoint(rays, P, surface, t, Kinv * Eigen::Vector3d(x, y, 1), p, n)) continue;
        const double shade = 0.25 + 0.75 * std::max(0.0, n.dot(-p.normalized()));
        out(y, x) = cv::Vec4b(cv::saturate_cast<uchar>(colour[0] * shade), cv::saturate_cast<uchar>(colour[1] * shade),
                              cv::saturate_cast<uchar>(colour[2] * shade), 255);
      }
  });
  return out;
}

double maskIoU(const cv::Mat1b& a, const cv::Mat1b& b) {
  if (a.size() != b.size()) throw InputError("Masks of different sizes cannot be compared.");
  const double inter = cv::countNonZero(a & b), uni = cv::countNonZero(a | b);
  return uni > 0 ? inter / uni : 1.0;
}

}  // namespace rehearse::imaging
