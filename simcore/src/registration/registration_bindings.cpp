// The registration's correspondences (every stage binds with these): the contour resampled, its points bound to the
// silhouette (the rigid stage: to its edges; the elastic stage: at its vertices), the anatomical curves' nodes to
// their image curves, the seen points to the surface, and a bound point held on its ray.
#include "contour_registration.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace rehearse::simcore::detail {

// Contour points at uniform spacing with their 2D normals (perpendicular to the local tangent).
std::vector<Sample> contourSamples(const std::vector<std::vector<Eigen::Vector2d>>& contour, double spacing) {
  std::vector<Sample> out;
  for (const auto& seg : contour) {
    if (seg.size() < 2) continue;
    std::vector<Eigen::Vector2d> pts{seg.front()};
    double carry = 0;
    for (std::size_t i = 1; i < seg.size(); ++i) {
      const Eigen::Vector2d a = seg[i - 1], b = seg[i];
      const double len = (b - a).norm();
      double s = spacing - carry;
      while (s <= len) {
        pts.push_back(a + (b - a) * (s / len));
        s += spacing;
      }
      carry = len - (s - spacing);
    }
    if ((pts.back() - seg.back()).norm() > 0.25 * spacing) pts.push_back(seg.back());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector2d t = pts[std::min(i + 1, pts.size() - 1)] - pts[i > 0 ? i - 1 : 0];
      const Eigen::Vector2d n = t.norm() > 0 ? Eigen::Vector2d(-t.y(), t.x()).normalized() : Eigen::Vector2d(0, 0);
      out.push_back({pts[i], n});
    }
  }
  return out;
}

// Bindings further than `factor` times the median distance (and than `floorPx`) are outliers.
void dropOutliers(std::vector<Binding>& bindings, double factor, double floorPx) {
  if (bindings.empty()) return;
  std::vector<double> d;
  for (const auto& b : bindings) d.push_back(b.distance);
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  const double limit = std::max(factor * d[d.size() / 2], floorPx);
  bindings.erase(std::remove_if(bindings.begin(), bindings.end(), [&](const Binding& b) { return b.distance > limit; }),
                 bindings.end());
}

// For the rigid pass: every contour point to the nearest compatible point of the silhouette edges (the
// pose has six unknowns, so many correspondences anywhere on the edges are best), outliers dropped.
std::vector<Binding> bindForRigid(const std::vector<Sample>& samples, const std::vector<SilhouetteEdge>& sil,
                                  const RegistrationOptions& o) {
  std::vector<Binding> out;
  const SilhouetteGrid grid(sil);
  for (const auto& s : samples) {
    double d, t;
    const int i = grid.nearest(s.pixel, s.normal, o.normalDot, d, t);
    if (i < 0) continue;
    const SilhouetteEdge& e = sil[static_cast<std::size_t>(i)];
    out.push_back({e.a, e.b, t, s.pixel, d, e.normal, e.bulge});
  }
  dropOutliers(out, o.outlierFactor, 4.0);
  return out;
}

// Binds the silhouette to the contour at the silhouette's vertices (the projected surface nodes on the
// silhouette, with the mean normal of their silhouette edges): each vertex to the foot of its
// perpendicular on the nearest compatible stretch of contour (so nothing pulls along the outline), vertices
// whose nearest contour point is an open end of the contour are left free (a partial contour says nothing
// beyond its ends), and far outliers are dropped. Binding at nodes keeps the constraints consistent: one
// pair of constraints across the ray per node.
std::vector<Binding> bindContour(const std::vector<Sample>& samples, const std::vector<std::size_t>& segmentStarts,
                                 const std::vector<SilhouetteEdge>& sil, const std::vector<char>& fixed,
                                 const RegistrationOptions& o, double floorPx) {
  std::map<int, std::pair<Eigen::Vector2d, Eigen::Vector2d>> vertices;  // node -> pixel, summed normal
  for (const auto& e : sil)
    for (int k = 0; k < 2; ++k) {
      const int node = k ? e.b : e.a;
      if (fixed[node]) continue;  // held by the ligaments: cannot follow
      auto [it, added] = vertices.try_emplace(node, k ? e.pb : e.pa, Eigen::Vector2d::Zero());
      it->second.second += e.normal;
    }
  std::vector<Binding> out;
  for (const auto& [node, pn] : vertices) {
    const Eigen::Vector2d n = pn.second.norm() > 0 ? Eigen::Vector2d(pn.second.normalized()) : Eigen::Vector2d::Zero();
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector2d foot = Eigen::Vector2d::Zero(), footNormal = Eigen::Vector2d::Zero();
    bool atEnd = false;
    for (std::size_t sgi = 0; sgi < segmentStarts.size(); ++sgi) {
      const std::size_t begin = segmentStarts[sgi],
                        end = sgi + 1 < segmentStarts.size() ? segmentStarts[sgi + 1] : samples.size();
      for (std::size_t i = begin; i + 1 < end; ++i) {
        const Sample &p = samples[i], &q = samples[i + 1];
        const Eigen::Vector2d tangent = q.pixel - p.pixel;
        if (tangent.norm() == 0) continue;
        const Eigen::Vector2d cn(-tangent.y() / tangent.norm(), tangent.x() / tangent.norm());
        if (n.squaredNorm() > 0 && std::abs(cn.dot(n)) < o.normalDot) continue;
        const double t = closestParameter(p.pixel, q.pixel, pn.first);
        const Eigen::Vector2d f = p.pixel + t * tangent;
        const double d = (f - pn.first).norm();
        if (d < best) {
          best = d;
          foot = f;
          footNormal = cn;
          atEnd = (i == begin && t == 0.0) || (i + 2 == end && t == 1.0);
        }
      }
    }
    if (std::isfinite(best) && !(atEnd && best > 2.0)) out.push_back({node, node, 0, foot, best, footNormal});
  }
  dropOutliers(out, o.outlierFactor, floorPx);
  return out;
}

// Every node of the anatomical curves to the nearest point of its image curve (one binding per node; nodes
// whose nearest point is an open end, further than 2 px, are left free; fixed nodes too when given).
std::vector<Binding> bindCurves(const std::vector<AnatomicalCurve>& curves, const Eigen::VectorXd& x, const Pose& pose,
                                const Pinhole& cam, const std::vector<char>* fixed) {
  std::vector<Binding> out;
  std::vector<char> seen(static_cast<std::size_t>(x.size() / 3), 0);
  for (const auto& c : curves)
    for (int node : c.nodes) {
      if (seen[node] || (fixed && (*fixed)[node])) continue;
      seen[node] = 1;
      const Eigen::Vector3d q = pose.apply(x.segment<3>(3 * node));
      if (!(q.z() > 1e-6)) continue;
      const Foot f = nearestOnPolyline(c.image, cam.project(q));
      if (std::isfinite(f.distance) && !(f.atEnd && f.distance > 2.0))
        out.push_back({node, node, 0, f.point, f.distance, f.normal});
    }
  return out;
}

// The bound point on the ray through its contour point: two constraints across the ray (model frame). When
// sliding, one: the point on the plane through the camera centre and the contour's tangent line there, so
// it is held across the contour and free along it.
void rayConstraints(const Binding& b, const Pose& pose, const Pinhole& cam, bool sliding,
                    std::vector<ScalarConstraint>& out) {
  if (sliding && b.normal.squaredNorm() > 0) {
    const Eigen::Vector3d line(b.normal.x(), b.normal.y(), -b.normal.dot(b.contour));  // the tangent line in the image
    const Eigen::Vector3d plane = cam.K.transpose() * line;  // camera frame, through the centre
    ScalarConstraint c;
    c.nodes = {b.a, b.b, -1, -1};
    c.weights = {1 - b.t, b.t, 0, 0};
    c.direction = (pose.R.transpose() * plane).normalized();
    c.value = -plane.dot(pose.t) / plane.norm();
    out.push_back(c);
    return;
  }
  const Eigen::Vector3d d = (pose.R.transpose() * cam.ray(b.contour)).normalized();
  const Eigen::Vector3d origin = -pose.R.transpose() * pose.t;
  Eigen::Vector3d helper = Eigen::Vector3d::Unit(0);
  if (std::abs(d.x()) > 0.6) helper = Eigen::Vector3d::Unit(1);
  const Eigen::Vector3d n1 = d.cross(helper).normalized(), n2 = d.cross(n1).normalized();
  for (const Eigen::Vector3d& n : {n1, n2}) {
    ScalarConstraint c;
    c.nodes = {b.a, b.b, -1, -1};
    c.weights = {1 - b.t, b.t, 0, 0};
    c.direction = n;
    c.value = n.dot(origin);
    out.push_back(c);
  }
}
// Each seen point to the nearest surface node facing the first camera (its normal from the shape x), held across the
// surface there; far ones (more than 3x the median, at least 4 px) dropped.
std::vector<Binding> bindPoints(const std::vector<SeenPoint>& points, const std::vector<std::array<int, 3>>& surface,
                                const Eigen::VectorXd& x, const Pose& pose, const Pinhole& cam) {
  std::vector<Binding> out;
  if (points.empty()) return out;
  std::vector<Eigen::Vector3d> normal(static_cast<std::size_t>(x.size() / 3), Eigen::Vector3d::Zero());
  for (const auto& t : surface) {
    const Eigen::Vector3d a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
    const Eigen::Vector3d n = (b - a).cross(c - a);  // area-weighted
    for (int v : t) normal[static_cast<std::size_t>(v)] += n;
  }
  std::vector<int> front;
  for (std::size_t i = 0; i < normal.size(); ++i) {
    if (normal[i].squaredNorm() == 0) continue;
    normal[i].normalize();
    if ((pose.R * normal[i]).dot(pose.apply(x.segment<3>(3 * static_cast<Eigen::Index>(i)))) < 0)
      front.push_back(static_cast<int>(i));
  }
  for (const auto& p : points) {
    double best = std::numeric_limits<double>::infinity();
    int node = -1;
    for (int i : front) {
      const double d = (pose.apply(x.segment<3>(3 * i)) - p.target).squaredNorm();
      if (d < best) best = d, node = i;
    }
    if (node < 0) continue;
    Binding b{node, node, 0, cam.project(p.target), cam.K(0, 0) * std::sqrt(best) / p.target.z()};
    b.surfacePoint = true;
    b.target = p.target;
    b.surfaceNormal = normal[static_cast<std::size_t>(node)];
    b.pxPerMetre = p.pxPerMetre;
    out.push_back(b);
  }
  dropOutliers(out, 3.0, 4.0);
  return out;
}

}  // namespace rehearse::simcore::detail
