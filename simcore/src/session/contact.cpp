#include <rehearse/simcore/session/contact.hpp>

#include <rehearse/simcore/mesh.hpp>

#include <algorithm>
#include <cmath>
#include <set>

namespace rehearse::simcore {

// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5), with its barycentric weights.
Eigen::Vector3d closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  const Eigen::Vector3d& c, Eigen::Vector3d& w) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return w = {1, 0, 0}, a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return w = {0, 1, 0}, b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return w = {1 - v, v, 0}, a + v * ab;
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return w = {0, 0, 1}, c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double v = d2 / (d2 - d6);
    return w = {1 - v, 0, v}, a + v * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double v = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return w = {0, 1 - v, v}, b + v * (c - b);
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, u = vc * denom;
  return w = {1 - v - u, v, u}, a + v * ab + u * ac;
}

namespace {
// Closest points of segments p1-q1 (parameter s) and p2-q2 (parameter t) (Ericson 5.1.9).
void closestSegmentSegment(const Eigen::Vector3d& p1, const Eigen::Vector3d& q1, const Eigen::Vector3d& p2,
                           const Eigen::Vector3d& q2, double& s, double& t) {
  const Eigen::Vector3d d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  if (a <= 1e-30 && e <= 1e-30) return void(s = t = 0);
  if (a <= 1e-30) {
    s = 0;
    t = std::clamp(f / e, 0.0, 1.0);
    return;
  }
  const double c = d1.dot(r);
  if (e <= 1e-30) {
    t = 0;
    s = std::clamp(-c / a, 0.0, 1.0);
    return;
  }
  const double b = d1.dot(d2), denom = a * e - b * b;
  s = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
  t = (b * s + f) / e;
  if (t < 0) {
    t = 0;
    s = std::clamp(-c / a, 0.0, 1.0);
  } else if (t > 1) {
    t = 1;
    s = std::clamp((b - c) / a, 0.0, 1.0);
  }
}
}  // namespace

// The closest points of segment s0-s1 (the instrument's axis) and triangle abc: `onAxis`, `onTriangle` with
// its barycentric weights `w`. False when the segment passes through the triangle (no direction apart).
bool closestAxisTriangle(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1, const Eigen::Vector3d& a,
                         const Eigen::Vector3d& b, const Eigen::Vector3d& c, Eigen::Vector3d& onAxis,
                         Eigen::Vector3d& onTriangle, Eigen::Vector3d& w) {
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double ds0 = n.dot(s0 - a), ds1 = n.dot(s1 - a);
  if (ds0 * ds1 < 0) {  // crosses the plane: inside the triangle?
    const double t = ds0 / (ds0 - ds1);
    const Eigen::Vector3d x = s0 + t * (s1 - s0);
    Eigen::Vector3d wx;
    if ((closestOnTriangle(x, a, b, c, wx) - x).squaredNorm() <= 1e-24 * std::max(1.0, n.norm())) return false;
  }
  double best = std::numeric_limits<double>::infinity();
  auto consider = [&](const Eigen::Vector3d& pa, const Eigen::Vector3d& pt, const Eigen::Vector3d& wt) {
    const double d = (pa - pt).squaredNorm();
    if (d < best) best = d, onAxis = pa, onTriangle = pt, w = wt;
  };
  Eigen::Vector3d wt;
  for (const Eigen::Vector3d* e : {&s0, &s1}) {
    const Eigen::Vector3d q = closestOnTriangle(*e, a, b, c, wt);
    consider(*e, q, wt);
  }
  const std::array<const Eigen::Vector3d*, 3> v{&a, &b, &c};
  for (int k = 0; k < 3; ++k) {
    double s, t;
    closestSegmentSegment(s0, s1, *v[static_cast<std::size_t>(k)], *v[static_cast<std::size_t>((k + 1) % 3)], s, t);
    Eigen::Vector3d wk = Eigen::Vector3d::Zero();
    wk[k] = 1 - t;
    wk[(k + 1) % 3] = t;
    consider(s0 + s * (s1 - s0),
             (1 - t) * *v[static_cast<std::size_t>(k)] + t * *v[static_cast<std::size_t>((k + 1) % 3)], wk);
  }
  return best > 0;
}

ContactSurface contactSurface(const std::vector<Eigen::Vector3d>& rest, const std::vector<std::array<int, 4>>& tets) {
  ContactSurface c;
  std::vector<char> on(rest.size(), 0);
  Mesh m;
  m.points = rest;
  m.tets = tets;
  c.triangles = boundaryTriangles(m, false);
  for (const auto& t : c.triangles)
    for (int v : t) on[static_cast<std::size_t>(v)] = 1;
  // Each node's triangles (compressed rows): contact finds triangles through their nodes.
  c.first.assign(on.size() + 1, 0);
  for (const auto& t : c.triangles)
    for (int v : t) ++c.first[static_cast<std::size_t>(v) + 1];
  for (std::size_t i = 0; i < on.size(); ++i) c.first[i + 1] += c.first[i];
  c.ofNode.assign(static_cast<std::size_t>(c.first.back()), 0);
  std::vector<int> fill(c.first.begin(), c.first.end() - 1);
  for (std::size_t k = 0; k < c.triangles.size(); ++k)
    for (int v : c.triangles[k])
      c.ofNode[static_cast<std::size_t>(fill[static_cast<std::size_t>(v)]++)] = static_cast<int>(k);
  for (std::size_t i = 0; i < on.size(); ++i)
    if (on[i]) c.nodes.push_back(static_cast<int>(i));
  return c;
}

ShaftContactStats shaftContact(const ContactSurface& surface, PointBvh& bvh, const Eigen::VectorXd& x,
                               const std::vector<char>& fixed, const Eigen::Vector3d& tip,
                               const Eigen::Vector3d& trocar, double radius, double depenetrationSpeed,
                               const std::vector<int>& held, std::vector<int>& released,
                               std::vector<std::pair<int, double>>& easing, bool seed,
                               std::vector<ScalarConstraint>& rows) {
  ShaftContactStats stats;
  bvh.refit(x);
  auto X = [&](int i) { return Eigen::Vector3d(x.segment<3>(3 * static_cast<Eigen::Index>(i))); };
  double longest = 0;
  for (const auto& t : surface.triangles)
    for (int k = 0; k < 3; ++k)
      longest = std::max(
          longest, (X(t[static_cast<std::size_t>(k)]) - X(t[static_cast<std::size_t>((k + 1) % 3)])).squaredNorm());
  longest = std::sqrt(longest);
  const Eigen::Vector3d a = tip, b = trocar;
  const double r = radius, reach = 1.5 * r;
  // Let-go tissue out of the shaft is ordinary tissue again.
  std::erase_if(released, [&](int i) {
    const Eigen::Vector3d ab = b - a;
    const double u = ab.squaredNorm() > 0 ? std::clamp((X(i) - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    return (X(i) - (a + u * ab)).norm() >= r;
  });
  std::vector<int> near;
  bvh.query(a, b, reach + longest, x, near);
  std::vector<int> tris;
  for (int i : near)
    for (int k = surface.first[static_cast<std::size_t>(i)]; k < surface.first[static_cast<std::size_t>(i) + 1]; ++k)
      tris.push_back(surface.ofNode[static_cast<std::size_t>(k)]);
  std::sort(tris.begin(), tris.end());
  tris.erase(std::unique(tris.begin(), tris.end()), tris.end());
  std::set<std::vector<std::pair<int, double>>> seen;
  for (int k : tris) {
    const auto& t = surface.triangles[static_cast<std::size_t>(k)];
    bool anyFree = false, holdsHeld = false;
    for (int v : t) {
      anyFree |= !fixed[static_cast<std::size_t>(v)];
      holdsHeld |= std::find(held.begin(), held.end(), v) != held.end() ||
                   std::binary_search(released.begin(), released.end(), v);
    }
    if (!anyFree || holdsHeld) continue;
    Eigen::Vector3d onAxis = Eigen::Vector3d::Zero(), onTriangle = Eigen::Vector3d::Zero(), w = Eigen::Vector3d::Zero();
    if (!closestAxisTriangle(a, b, X(t[0]), X(t[1]), X(t[2]), onAxis, onTriangle, w)) {
      ++stats.pierced;  // the shaft passes through it: no side to push it to
      continue;
    }
    Eigen::Vector3d n = onTriangle - onAxis;
    double d = n.norm();
    if (d > reach) continue;
    if (!(d > 1e-3 * r)) {
      // On the axis (tissue the jaws just let go of sits at the tip): the direction from the axis is noise, so
      // the surface is pushed along its own inward normal, from where it is (eased out like tissue inside).
      n = -(X(t[1]) - X(t[0])).cross(X(t[2]) - X(t[0]));
      if (!(n.norm() > 0)) continue;  // a collapsed triangle: no side to push it to
      n *= 1e-3 * r / n.norm();
      d = 1e-3 * r;
    }
    // The closest point on a vertex or an edge is shared by the triangles around it: one constraint each
    // (redundant copies make the Schur complement singular and Gauss-Seidel slow).
    std::array<std::pair<int, double>, 3> key{};
    int used = 0;
    for (int q = 0; q < 3; ++q)
      if (w[q] > 1e-12) key[static_cast<std::size_t>(used++)] = {t[static_cast<std::size_t>(q)], w[q]};
    std::sort(key.begin(), key.begin() + used);
    if (!seen.insert(std::vector<std::pair<int, double>>(key.begin(), key.begin() + used)).second) continue;
    ScalarConstraint sc;
    for (int q = 0; q < used; ++q) {
      sc.nodes[static_cast<std::size_t>(q)] = key[static_cast<std::size_t>(q)].first;
      sc.weights[static_cast<std::size_t>(q)] = key[static_cast<std::size_t>(q)].second;
    }
    sc.direction = n / d;
    // Surface inside the shaft when it became free to touch it is held where it is and eased out (easing), not
    // pushed to the radius in one step.
    double keep = r;
    if (depenetrationSpeed > 0) {
      auto it = std::lower_bound(easing.begin(), easing.end(), std::make_pair(k, -1.0));
      if (it != easing.end() && it->first == k) {
        keep = std::min(r, it->second);
      } else if (seed && d < r) {
        easing.insert(it, {k, d});
        keep = d;
      }
    }
    sc.value = sc.direction.dot(onAxis) + keep;
    sc.unilateral = true;
    rows.push_back(sc);
    ++stats.rows;
    if (d <= r * (1 + 1e-3)) ++stats.contacts;  // touching (held at the shaft's surface) or inside
  }
  return stats;
}

}  // namespace rehearse::simcore
