#include <rehearse/simcore/cut.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numeric>
#include <unordered_map>
#include <unordered_set>

namespace rehearse::simcore {
namespace {
using V3 = Eigen::Vector3d;

std::uint64_t edgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
}

struct FaceKey {
  std::array<int, 3> n;
  bool operator==(const FaceKey&) const = default;
};
struct FaceHash {
  std::size_t operator()(const FaceKey& k) const {
    std::uint64_t h = static_cast<std::uint32_t>(k.n[0]);
    h = h * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint32_t>(k.n[1]);
    h = h * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint32_t>(k.n[2]);
    return static_cast<std::size_t>(h ^ (h >> 29));
  }
};
FaceKey faceKey(int a, int b, int c) {
  std::array<int, 3> n{a, b, c};
  std::sort(n.begin(), n.end());
  return {n};
}

double signedVolume(const V3& a, const V3& b, const V3& c, const V3& d) { return (b - a).dot((c - a).cross(d - a)) / 6.0; }

constexpr std::array<std::array<int, 3>, 4> kFaces{{{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};

// A convex polygon in cyclic order, triangulated as a fan from its first vertex in `before`'s order (for a
// quad: the diagonal from it). `before` orders by rest position (then node number), so two elements sharing
// the polygon triangulate it alike, and so do the two sides of a separated face (equal places, other numbers).
template <class Before>
void triangulate(const std::vector<int>& poly, std::vector<std::array<int, 3>>& out, const Before& before) {
  const std::size_t n = poly.size();
  if (n < 3) return;
  const std::size_t m = static_cast<std::size_t>(std::min_element(poly.begin(), poly.end(), before) - poly.begin());
  for (std::size_t k = 1; k + 1 < n; ++k) out.push_back({poly[m], poly[(m + k) % n], poly[(m + k + 1) % n]});
}

struct Piece {
  std::array<int, 4> n;
  int parent;
  int side;  // +1 / -1 a side of a separated element, 0 a refined one
};

}  // namespace

double tetShapeQuality(const V3& a, const V3& b, const V3& c, const V3& d) {
  const double l2 = ((b - a).squaredNorm() + (c - a).squaredNorm() + (d - a).squaredNorm() + (c - b).squaredNorm() + (d - b).squaredNorm() +
                     (d - c).squaredNorm()) /
                    6.0;
  if (!(l2 > 0)) return 0;
  return 6.0 * std::sqrt(2.0) * std::abs(signedVolume(a, b, c, d)) / (l2 * std::sqrt(l2));
}

void extendByCut(Eigen::VectorXd& v, const std::vector<CutNode>& newNodes) {
  const Eigen::Index n0 = v.size() / 3;
  v.conservativeResize(3 * (n0 + static_cast<Eigen::Index>(newNodes.size())));
  for (std::size_t k = 0; k < newNodes.size(); ++k) {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int j = 0; j < 4; ++j)
      if (newNodes[k].from[static_cast<std::size_t>(j)] >= 0)
        p += newNodes[k].weight[static_cast<std::size_t>(j)] * v.segment<3>(3 * static_cast<Eigen::Index>(newNodes[k].from[static_cast<std::size_t>(j)]));
    v.segment<3>(3 * (n0 + static_cast<Eigen::Index>(k))) = p;
  }
}

CutResult cutTetrahedra(std::vector<V3>& rest, std::vector<V3>& current, std::vector<std::array<int, 4>>& tets, std::vector<int>& labels,
                        const BladeSweep& blade, const CutSettings& s, CutProgress* progress) {
  std::vector<std::array<int, 3>>* pending = progress ? &progress->pendingFaces : nullptr;
  std::vector<int>* cutNodes = progress ? &progress->nodes : nullptr;
  CutResult r;
  const int n0 = static_cast<int>(rest.size());
  if (current.size() != rest.size() || labels.size() != tets.size()) {
    r.status = "The cut was refused: the mesh's positions or labels do not match it.";
    return r;
  }
  // The blade's plane and quad (a0, b0, b1, a1).
  const std::array<V3, 4> quad{blade.a0, blade.b0, blade.b1, blade.a1};
  V3 normal = (blade.b1 - blade.a0).cross(blade.a1 - blade.b0);
  const double area = 0.5 * normal.norm();
  const double scale = std::max({(blade.b0 - blade.a0).norm(), (blade.a1 - blade.a0).norm(), (blade.b1 - blade.a1).norm(), 1e-12});
  if (!std::isfinite(area) || area < 1e-6 * scale * scale || area < 1e-12) {
    r.status = "The blade swept no area (it moved along itself or not at all); nothing was cut.";
    return r;
  }
  normal /= 2 * area;
  const V3 origin = 0.25 * (quad[0] + quad[1] + quad[2] + quad[3]);
  auto insideQuad = [&](const V3& p) {
    int pos = 0, neg = 0;
    for (int i = 0; i < 4; ++i) {
      const V3& q = quad[static_cast<std::size_t>(i)];
      const V3& q1 = quad[static_cast<std::size_t>((i + 1) % 4)];
      const double side = normal.dot((q1 - q).cross(p - q));
      pos += side > 0;
      neg += side < 0;
    }
    return pos == 0 || neg == 0;
  };
  // Inside any sweep of this continuous cut (each projected along its own plane's normal).
  auto insideSwept = [&](const V3& p) {
    if (insideQuad(p)) return true;
    if (!progress) return false;
    for (const BladeSweep& b : progress->sweeps) {
      const std::array<V3, 4> q{b.a0, b.b0, b.b1, b.a1};
      V3 nb = (b.b1 - b.a0).cross(b.a1 - b.b0);
      if (!(nb.norm() > 0)) continue;
      nb.normalize();
      int pos = 0, neg = 0;
      for (int i = 0; i < 4; ++i) {
        const double side = nb.dot((q[static_cast<std::size_t>((i + 1) % 4)] - q[static_cast<std::size_t>(i)]).cross(p - q[static_cast<std::size_t>(i)]));
        pos += side > 0;
        neg += side < 0;
      }
      if (pos == 0 || neg == 0) return true;
    }
    return false;
  };
  const std::size_t nt = tets.size();
  std::vector<double> dist(current.size());
  for (std::size_t i = 0; i < current.size(); ++i) dist[i] = normal.dot(current[i] - origin);
  auto tetNode = [&](std::size_t t, int k) { return tets[t][static_cast<std::size_t>(k)]; };

  // Crossed elements whose crossing lies inside the swept quad (raw signs, before snapping).
  // Where the plane crosses element t (the mean of its edges' crossings and its nodes on the plane, raw
  // signs); false when it does not.
  auto crossingCentre = [&](std::size_t t, V3& centre) {
    V3 c = V3::Zero();
    int count = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const int i = tetNode(t, a), j = tetNode(t, b);
        const double di = dist[static_cast<std::size_t>(i)], dj = dist[static_cast<std::size_t>(j)];
        if ((di < 0 && dj > 0) || (di > 0 && dj < 0)) {
          const double u = di / (di - dj);
          c += (1 - u) * current[static_cast<std::size_t>(i)] + u * current[static_cast<std::size_t>(j)];
          ++count;
        }
      }
    for (int k = 0; k < 4; ++k)
      if (dist[static_cast<std::size_t>(tetNode(t, k))] == 0) c += current[static_cast<std::size_t>(tetNode(t, k))], ++count;
    if (count == 0) return false;
    centre = c / count;
    return true;
  };
  // Element t's rest volume when it is positive at rest and now (an inverted element is not cut), else 0.
  auto cuttableVolume = [&](std::size_t t) {
    const auto& e = tets[t];
    const double vr = signedVolume(rest[static_cast<std::size_t>(e[0])], rest[static_cast<std::size_t>(e[1])], rest[static_cast<std::size_t>(e[2])],
                                   rest[static_cast<std::size_t>(e[3])]);
    const double vc = signedVolume(current[static_cast<std::size_t>(e[0])], current[static_cast<std::size_t>(e[1])], current[static_cast<std::size_t>(e[2])],
                                   current[static_cast<std::size_t>(e[3])]);
    return vr > 0 && vc > 0 ? vr : 0.0;
  };
  std::vector<char> candidate(nt, 0), relevant(current.size(), 0);
  std::vector<double> restVol(nt, 0.0);
  for (std::size_t t = 0; t < nt; ++t) {
    double lo = 1e300, hi = -1e300;
    for (int k = 0; k < 4; ++k) lo = std::min(lo, dist[static_cast<std::size_t>(tetNode(t, k))]), hi = std::max(hi, dist[static_cast<std::size_t>(tetNode(t, k))]);
    if (!(lo <= 0 && hi >= 0)) continue;
    V3 c;
    if (!crossingCentre(t, c) || !insideQuad(c)) continue;
    const double vr = cuttableVolume(t);
    if (!(vr > 0)) {
      ++r.skippedInverted;
      continue;
    }
    candidate[t] = 1;
    restVol[t] = vr;
    for (int k = 0; k < 4; ++k) relevant[static_cast<std::size_t>(tetNode(t, k))] = 1;
  }
  // Elements holding a crossed edge of a candidate whose crossing lies in the region this continuous cut has
  // swept so far are cut too (else they would stop the cut where an earlier strip ended).
  if (progress && !progress->sweeps.empty()) {
    std::unordered_map<std::uint64_t, char> crossed;
    auto crossedEdges = [&](std::size_t t) {
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) {
          const int i = tetNode(t, a), j = tetNode(t, b);
          const double di = dist[static_cast<std::size_t>(i)], dj = dist[static_cast<std::size_t>(j)];
          if ((di < 0 && dj > 0) || (di > 0 && dj < 0)) crossed[edgeKey(i, j)] = 1;
        }
    };
    for (std::size_t t = 0; t < nt; ++t)
      if (candidate[t]) crossedEdges(t);
    for (bool grew = true; grew;) {
      grew = false;
      for (std::size_t t = 0; t < nt; ++t) {
        if (candidate[t]) continue;
        bool holds = false;
        for (int a = 0; a < 4 && !holds; ++a)
          for (int b = a + 1; b < 4 && !holds; ++b) holds = crossed.count(edgeKey(tetNode(t, a), tetNode(t, b))) > 0;
        if (!holds) continue;
        V3 c;
        if (!crossingCentre(t, c) || !insideSwept(c)) continue;
        const double vr = cuttableVolume(t);
        if (!(vr > 0)) continue;
        candidate[t] = 1;
        restVol[t] = vr;
        for (int k = 0; k < 4; ++k) relevant[static_cast<std::size_t>(tetNode(t, k))] = 1;
        crossedEdges(t);
        grew = true;
      }
    }
  }
  // With nothing crossed, faces of earlier updates may still open (below); the status says so otherwise.
  const bool crossedAny = std::find(candidate.begin(), candidate.end(), 1) != candidate.end();
  for (std::size_t t = 0; t < nt && cutNodes && !cutNodes->empty(); ++t)
    if (candidate[t])
      for (int k = 0; k < 4; ++k) relevant[static_cast<std::size_t>(tetNode(t, k))] = 1;
  if (!crossedAny && (!pending || pending->empty())) {
    r.status = r.skippedInverted ? "The blade crossed only inverted elements; nothing was cut." : "The blade crossed no tissue.";
    return r;
  }
  // Snapping: a crossing near a node passes through the node. Nodes already on this continuous cut stay on it.
  std::vector<char> zero(current.size(), 0);
  if (cutNodes)
    for (int i : *cutNodes)
      if (i >= 0 && i < n0) zero[static_cast<std::size_t>(i)] = 1;
  for (std::size_t t = 0; t < nt; ++t) {
    if (!candidate[t]) continue;
    for (int a = 0; a < 4; ++a) {
      const int i = tetNode(t, a);
      if (dist[static_cast<std::size_t>(i)] == 0) zero[static_cast<std::size_t>(i)] = 1;
      for (int b = a + 1; b < 4; ++b) {
        const int j = tetNode(t, b);
        const double di = dist[static_cast<std::size_t>(i)], dj = dist[static_cast<std::size_t>(j)];
        if (!((di < 0 && dj > 0) || (di > 0 && dj < 0))) continue;
        const double u = di / (di - dj);
        if (u < s.snap) zero[static_cast<std::size_t>(i)] = 1;
        if (u > 1 - s.snap) zero[static_cast<std::size_t>(j)] = 1;
      }
    }
  }

  // The cut's front: an edge crossed inside the quad that an element outside the quad also holds would put a
  // node on that element's edge (refining it, and its pieces would lie behind the next update's strip).
  // Instead the crossing snaps to the edge's nearer node, so the front runs along element faces and a
  // continuous cut resumes there.
  {
    std::unordered_map<std::uint64_t, std::array<int, 2>> edgeUse;  // (elements, candidates) holding the edge
    for (std::size_t t = 0; t < nt; ++t) {
      bool near = false;
      for (int k = 0; k < 4 && !near; ++k) near = relevant[static_cast<std::size_t>(tetNode(t, k))];
      if (!near) continue;
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) {
          const int i = tetNode(t, a), j = tetNode(t, b);
          if (!relevant[static_cast<std::size_t>(i)] || !relevant[static_cast<std::size_t>(j)]) continue;
          auto& u = edgeUse[edgeKey(i, j)];
          ++u[0];
          u[1] += candidate[t];
        }
    }
    for (bool changed = s.snapFront; changed;) {
      changed = false;
      for (std::size_t t = 0; t < nt; ++t) {
        if (!candidate[t]) continue;
        for (int a = 0; a < 4; ++a)
          for (int b = a + 1; b < 4; ++b) {
            const int i = tetNode(t, a), j = tetNode(t, b);
            const std::size_t ui = static_cast<std::size_t>(i), uj = static_cast<std::size_t>(j);
            if (zero[ui] || zero[uj] || !((dist[ui] < 0 && dist[uj] > 0) || (dist[ui] > 0 && dist[uj] < 0))) continue;
            const auto& u = edgeUse.at(edgeKey(i, j));
            if (u[1] == u[0]) continue;
            zero[std::abs(dist[ui]) <= std::abs(dist[uj]) ? ui : uj] = 1;
            changed = true;
          }
      }
    }
  }

  std::vector<CutNode> newNodes;
  std::vector<V3> newRest, newCurrent;
  std::vector<Piece> pieces;
  std::vector<char> replaced(nt, 0);
  std::unordered_map<std::uint64_t, int> edgePoint;
  std::unordered_set<FaceKey, FaceHash> pendingIn, pendingNew;
  if (pending)
    for (const auto& f : *pending) pendingIn.insert(faceKey(f[0], f[1], f[2]));
  for (int iteration = 0;; ++iteration) {
    auto sigma = [&](int i) { return zero[static_cast<std::size_t>(i)] ? 0 : (dist[static_cast<std::size_t>(i)] > 0 ? 1 : -1); };
    newNodes.clear();
    newRest.clear();
    newCurrent.clear();
    pieces.clear();
    edgePoint.clear();
    pendingNew.clear();
    std::fill(replaced.begin(), replaced.end(), 0);
    // Split elements: candidates with nodes on both sides. Each sign-changing edge gets one point.
    std::vector<char> split(nt, 0);
    for (std::size_t t = 0; t < nt; ++t) {
      if (!candidate[t]) continue;
      int pos = 0, neg = 0;
      for (int k = 0; k < 4; ++k) pos += sigma(tetNode(t, k)) > 0, neg += sigma(tetNode(t, k)) < 0;
      if (pos == 0 || neg == 0) continue;
      split[t] = 1;
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) {
          int i = tetNode(t, a), j = tetNode(t, b);
          if (sigma(i) * sigma(j) >= 0) continue;
          if (i > j) std::swap(i, j);
          if (edgePoint.count(edgeKey(i, j))) continue;
          const double u = dist[static_cast<std::size_t>(i)] / (dist[static_cast<std::size_t>(i)] - dist[static_cast<std::size_t>(j)]);
          CutNode c;
          c.from = {i, j, -1, -1};
          c.weight = {1 - u, u, 0, 0};
          edgePoint.emplace(edgeKey(i, j), n0 + static_cast<int>(newNodes.size()));
          newNodes.push_back(c);
          newRest.push_back((1 - u) * rest[static_cast<std::size_t>(i)] + u * rest[static_cast<std::size_t>(j)]);
          newCurrent.push_back((1 - u) * current[static_cast<std::size_t>(i)] + u * current[static_cast<std::size_t>(j)]);
        }
    }
    auto pointOn = [&](int i, int j) {
      const auto it = edgePoint.find(edgeKey(i, j));
      return it == edgePoint.end() ? -1 : it->second;
    };
    auto restOf = [&](int i) -> const V3& { return i < n0 ? rest[static_cast<std::size_t>(i)] : newRest[static_cast<std::size_t>(i - n0)]; };
    auto currentOf = [&](int i) -> const V3& { return i < n0 ? current[static_cast<std::size_t>(i)] : newCurrent[static_cast<std::size_t>(i - n0)]; };
    // A node of element t (an old vertex or a point on one of its edges) as weights over t's four vertices.
    auto weightsIn = [&](std::size_t t, int node) {
      std::array<double, 4> w{0, 0, 0, 0};
      for (int k = 0; k < 4; ++k)
        if (tetNode(t, k) == node) w[static_cast<std::size_t>(k)] = 1;
      if (node >= n0) {
        const CutNode& c = newNodes[static_cast<std::size_t>(node - n0)];
        for (int k = 0; k < 4; ++k)
          for (int m = 0; m < 2; ++m)
            if (tetNode(t, k) == c.from[static_cast<std::size_t>(m)]) w[static_cast<std::size_t>(k)] += c.weight[static_cast<std::size_t>(m)];
      }
      return w;
    };
    // Cones the polygons from a new node at the mean of `verts` (within element t).
    auto before = [&](int x, int y) {
      const V3 &px = restOf(x), &py = restOf(y);
      if (px.x() != py.x()) return px.x() < py.x();
      if (px.y() != py.y()) return px.y() < py.y();
      if (px.z() != py.z()) return px.z() < py.z();
      return x < y;
    };
    auto cone = [&](std::size_t t, const std::vector<std::vector<int>>& polys, const std::vector<int>& verts, int side) {
      std::array<double, 4> w{0, 0, 0, 0};
      for (int v : verts) {
        const auto wv = weightsIn(t, v);
        for (int k = 0; k < 4; ++k) w[static_cast<std::size_t>(k)] += wv[static_cast<std::size_t>(k)] / static_cast<double>(verts.size());
      }
      CutNode c;
      V3 pr = V3::Zero(), pc = V3::Zero();
      for (int k = 0; k < 4; ++k) {
        c.from[static_cast<std::size_t>(k)] = tetNode(t, k);
        c.weight[static_cast<std::size_t>(k)] = w[static_cast<std::size_t>(k)];
        pr += w[static_cast<std::size_t>(k)] * rest[static_cast<std::size_t>(tetNode(t, k))];
        pc += w[static_cast<std::size_t>(k)] * current[static_cast<std::size_t>(tetNode(t, k))];
      }
      const int centre = n0 + static_cast<int>(newNodes.size());
      newNodes.push_back(c);
      newRest.push_back(pr);
      newCurrent.push_back(pc);
      std::vector<std::array<int, 3>> tris;
      for (const auto& p : polys) triangulate(p, tris, before);
      for (const auto& tri : tris) {
        Piece piece{{tri[0], tri[1], tri[2], centre}, static_cast<int>(t), side};
        if (signedVolume(restOf(piece.n[0]), restOf(piece.n[1]), restOf(piece.n[2]), restOf(piece.n[3])) < 0) std::swap(piece.n[0], piece.n[1]);
        pieces.push_back(piece);
      }
    };
    // The parts of face (a, b, c) on either side of its edge points, with the side of each part.
    auto faceParts = [&](int a, int b, int c, std::vector<std::pair<std::vector<int>, int>>& out) {
      const std::array<int, 3> v{a, b, c};
      std::array<int, 3> p{pointOn(a, b), pointOn(b, c), pointOn(c, a)};  // p[k] on edge (v[k], v[k+1])
      const int k = (p[0] >= 0) + (p[1] >= 0) + (p[2] >= 0);
      auto sideOfPart = [&](const std::vector<int>& part) {
        for (int x : part)
          if (x < n0 && sigma(x) != 0) return sigma(x);
        return 0;
      };
      auto add = [&](std::vector<int> part) {
        const int sd = sideOfPart(part);
        out.emplace_back(std::move(part), sd);
      };
      if (k == 0) {
        add({a, b, c});
      } else if (k == 1) {
        const int e = p[0] >= 0 ? 0 : (p[1] >= 0 ? 1 : 2);
        const int x = v[static_cast<std::size_t>(e)], y = v[static_cast<std::size_t>((e + 1) % 3)], z = v[static_cast<std::size_t>((e + 2) % 3)];
        add({x, p[static_cast<std::size_t>(e)], z});
        add({p[static_cast<std::size_t>(e)], y, z});
      } else if (k == 2) {
        // The vertex between the two pointed edges is cut off.
        const int e = p[0] < 0 ? 0 : (p[1] < 0 ? 1 : 2);  // the edge without a point: (v[e], v[e+1])
        const int x = v[static_cast<std::size_t>(e)], y = v[static_cast<std::size_t>((e + 1) % 3)], z = v[static_cast<std::size_t>((e + 2) % 3)];
        const int pyz = p[static_cast<std::size_t>((e + 1) % 3)], pzx = p[static_cast<std::size_t>((e + 2) % 3)];
        add({pyz, z, pzx});
        add({x, y, pyz, pzx});
      } else {
        add({a, p[0], p[2]});
        add({b, p[1], p[0]});
        add({c, p[2], p[1]});
        add({p[0], p[1], p[2]});
      }
    };
    for (std::size_t t = 0; t < nt; ++t) {
      bool touched = split[t];
      if (!touched)
        for (int a = 0; a < 4 && !touched; ++a)
          for (int b = a + 1; b < 4 && !touched; ++b) touched = pointOn(tetNode(t, a), tetNode(t, b)) >= 0;
      if (!touched) continue;
      replaced[t] = 1;
      std::vector<std::pair<std::vector<int>, int>> parts;
      for (const auto& f : kFaces) {
        const std::size_t first = parts.size();
        faceParts(tetNode(t, f[0]), tetNode(t, f[1]), tetNode(t, f[2]), parts);
        // A face on an earlier cut that has not opened yet stays on it in its pieces.
        if (pendingIn.count(faceKey(tetNode(t, f[0]), tetNode(t, f[1]), tetNode(t, f[2])))) {
          std::vector<std::array<int, 3>> tris;
          for (std::size_t k = first; k < parts.size(); ++k) triangulate(parts[k].first, tris, before);
          for (const auto& tri : tris) pendingNew.insert(faceKey(tri[0], tri[1], tri[2]));
        }
      }
      if (!split[t]) {
        std::vector<std::vector<int>> polys;
        for (auto& [poly, sd] : parts) polys.push_back(poly);
        cone(t, polys, {tetNode(t, 0), tetNode(t, 1), tetNode(t, 2), tetNode(t, 3)}, 0);
        continue;
      }
      // The cut polygon: snapped vertices and edge points, in cyclic order on the plane.
      std::vector<int> cut;
      for (int k = 0; k < 4; ++k)
        if (sigma(tetNode(t, k)) == 0) cut.push_back(tetNode(t, k));
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b)
          if (const int q = pointOn(tetNode(t, a), tetNode(t, b)); q >= 0) cut.push_back(q);
      {
        V3 c = V3::Zero();
        for (int q : cut) c += currentOf(q);
        c /= static_cast<double>(cut.size());
        const V3 e1 = (currentOf(cut[0]) - c).normalized(), e2 = normal.cross(e1);
        std::vector<std::pair<double, int>> byAngle;
        for (int q : cut) byAngle.emplace_back(std::atan2((currentOf(q) - c).dot(e2), (currentOf(q) - c).dot(e1)), q);
        std::sort(byAngle.begin(), byAngle.end());
        for (std::size_t k = 0; k < cut.size(); ++k) cut[k] = byAngle[k].second;
      }
      for (int sd : {1, -1}) {
        std::vector<std::vector<int>> polys{cut};
        std::vector<int> verts = cut;
        for (auto& [poly, psd] : parts)
          if (psd == sd) polys.push_back(poly);
        for (int k = 0; k < 4; ++k)
          if (sigma(tetNode(t, k)) == sd) verts.push_back(tetNode(t, k));
        cone(t, polys, verts, sd);
      }
    }
    // Quality of the pieces (rest shape); a failing element makes its nearest crossing snap to a node.
    std::vector<double> parentQuality(nt, -1);
    std::unordered_set<int> failing;
    double minQ = 1, minFraction = 1;
    for (const Piece& p : pieces) {
      const std::size_t t = static_cast<std::size_t>(p.parent);
      const auto& e = tets[t];
      if (parentQuality[t] < 0) {
        parentQuality[t] = tetShapeQuality(rest[static_cast<std::size_t>(e[0])], rest[static_cast<std::size_t>(e[1])], rest[static_cast<std::size_t>(e[2])],
                                           rest[static_cast<std::size_t>(e[3])]);
        if (restVol[t] <= 0)
          restVol[t] = signedVolume(rest[static_cast<std::size_t>(e[0])], rest[static_cast<std::size_t>(e[1])], rest[static_cast<std::size_t>(e[2])],
                                    rest[static_cast<std::size_t>(e[3])]);
      }
      const double v = signedVolume(restOf(p.n[0]), restOf(p.n[1]), restOf(p.n[2]), restOf(p.n[3]));
      const double q = tetShapeQuality(restOf(p.n[0]), restOf(p.n[1]), restOf(p.n[2]), restOf(p.n[3]));
      const double fraction = restVol[t] > 0 ? v / restVol[t] : 0;
      const double vc = signedVolume(currentOf(p.n[0]), currentOf(p.n[1]), currentOf(p.n[2]), currentOf(p.n[3]));
      minQ = std::min(minQ, q);
      minFraction = std::min(minFraction, fraction);
      if (!(vc > 0) || fraction < s.minVolumeFraction || q < s.minQuality) failing.insert(p.parent);
    }
    if (failing.empty()) {
      r.minQuality = minQ;
      r.minVolumeFraction = minFraction;
      for (std::size_t t = 0; t < nt; ++t) r.splitElements += split[t], r.refinedElements += replaced[t] && !split[t];
      break;
    }
    if (iteration >= 40) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "The cut was refused: %zu element(s) would keep a piece below the stated quality (%.2f) or volume (%.0e of its element).",
                    failing.size(), s.minQuality, s.minVolumeFraction);
      r.status = buf;
      return r;
    }
    std::vector<int> order(failing.begin(), failing.end());
    std::sort(order.begin(), order.end());
    bool progressed = false;
    for (int t : order) {
      // The crossing nearest a node of this element snaps to that node.
      double best = 2;
      int node = -1;
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) {
          int i = tetNode(static_cast<std::size_t>(t), a), j = tetNode(static_cast<std::size_t>(t), b);
          if (i > j) std::swap(i, j);
          const int q = pointOn(i, j);
          if (q < 0) continue;
          const double u = newNodes[static_cast<std::size_t>(q - n0)].weight[1];
          if (u < best) best = u, node = i;
          if (1 - u < best) best = 1 - u, node = j;
        }
      if (node >= 0 && !zero[static_cast<std::size_t>(node)]) {
        zero[static_cast<std::size_t>(node)] = 1;
        progressed = true;
      }
    }
    if (!progressed) {
      for (int t : order) candidate[static_cast<std::size_t>(t)] = 0;  // cannot be improved: not cut
    }
  }

  // Assemble: replaced elements give their first piece their index, the rest are appended.
  // Each element's side of the cut: a piece its own; an element left whole the side of its nodes off the cut
  // (0 when it straddles the plane outside the quad, or lies flat on the cut: decided below).
  std::vector<int> side(nt, 0), parentOf(nt, -1);
  std::vector<char> flat(nt, 0);
  for (std::size_t t = 0; t < nt; ++t) {
    if (replaced[t]) continue;
    int sd = 0;
    bool mixed = false;
    for (int k = 0; k < 4; ++k) {
      const std::size_t i = static_cast<std::size_t>(tetNode(t, k));
      if (zero[i]) continue;
      const int sg = dist[i] > 0 ? 1 : -1;
      mixed = mixed || (sd != 0 && sg != sd);
      sd = sg;
    }
    side[t] = mixed ? 0 : sd;
    flat[t] = !mixed && sd == 0;
  }
  {
    std::vector<char> first(nt, 1);
    for (const Piece& p : pieces) {
      const std::size_t t = static_cast<std::size_t>(p.parent);
      if (first[t]) {
        tets[t] = p.n;
        side[t] = p.side;
        parentOf[t] = p.parent;
        first[t] = 0;
      } else {
        tets.push_back(p.n);
        labels.push_back(labels[t]);
        side.push_back(p.side);
        parentOf.push_back(p.parent);
        flat.push_back(0);
      }
    }
  }
  rest.insert(rest.end(), newRest.begin(), newRest.end());
  current.insert(current.end(), newCurrent.begin(), newCurrent.end());
  r.newNodes = newNodes;
  r.duplicateOf.assign(newNodes.size(), -1);

  // Separation: faces between the two sides; each of their nodes is duplicated per group of its
  // elements still connected through faces that were not separated.
  std::unordered_map<FaceKey, std::array<int, 2>, FaceHash> faces;
  std::vector<char> onCut(rest.size(), 0);
  for (std::size_t i = 0; i < zero.size(); ++i) onCut[i] = zero[i];
  for (std::size_t i = zero.size(); i < rest.size(); ++i) onCut[i] = 1;
  // Faces of earlier cuts that have not opened yet (still shared): they separate too once the cut around
  // them is complete.
  for (const FaceKey& k : pendingIn)
    for (int v : k.n) onCut[static_cast<std::size_t>(v)] = 1;
  for (const FaceKey& k : pendingNew)
    for (int v : k.n) onCut[static_cast<std::size_t>(v)] = 1;
  std::vector<std::vector<int>> incident(rest.size());
  for (std::size_t t = 0; t < tets.size(); ++t) {
    const auto& e = tets[t];
    bool any = false;
    for (int k = 0; k < 4; ++k) any = any || onCut[static_cast<std::size_t>(e[static_cast<std::size_t>(k)])];
    if (!any) continue;
    for (int k = 0; k < 4; ++k)
      if (onCut[static_cast<std::size_t>(e[static_cast<std::size_t>(k)])]) incident[static_cast<std::size_t>(e[static_cast<std::size_t>(k)])].push_back(static_cast<int>(t));
    for (const auto& f : kFaces) {
      auto [it, inserted] = faces.try_emplace(faceKey(e[static_cast<std::size_t>(f[0])], e[static_cast<std::size_t>(f[1])], e[static_cast<std::size_t>(f[2])]),
                                              std::array<int, 2>{static_cast<int>(t), -1});
      if (!inserted) it->second[1] = static_cast<int>(t);
    }
  }
  // Elements flat on the cut (all four nodes on it) join the side most of their neighbours are on, else the
  // side their centre is on (a lone flat element must not become a piece of its own).
  for (int pass = 0; pass < 2; ++pass)
    for (std::size_t t = 0; t < tets.size(); ++t) {
      if (!flat[t]) continue;
      int vote = 0;
      const auto& e = tets[t];
      for (const auto& f : kFaces) {
        const auto it = faces.find(faceKey(e[static_cast<std::size_t>(f[0])], e[static_cast<std::size_t>(f[1])], e[static_cast<std::size_t>(f[2])]));
        if (it == faces.end() || it->second[1] < 0) continue;
        vote += side[static_cast<std::size_t>(it->second[0] == static_cast<int>(t) ? it->second[1] : it->second[0])];
      }
      if (vote != 0) side[t] = vote > 0 ? 1 : -1;
      else if (pass == 1) {
        V3 c = V3::Zero();
        for (int k : e) c += 0.25 * current[static_cast<std::size_t>(k)];
        side[t] = normal.dot(c - origin) >= 0 ? 1 : -1;
      }
    }
  std::unordered_set<FaceKey, FaceHash> cutFaces;
  std::vector<int> cutLabels;
  for (const auto& [key, pair] : faces) {
    if (pair[1] < 0) continue;
    const int s0 = side[static_cast<std::size_t>(pair[0])], s1 = side[static_cast<std::size_t>(pair[1])];
    if (s0 * s1 >= 0) continue;
    // Within one split element always; elsewhere where the blade passed (not beyond the cut's front).
    const bool sameParent = parentOf[static_cast<std::size_t>(pair[0])] >= 0 && parentOf[static_cast<std::size_t>(pair[0])] == parentOf[static_cast<std::size_t>(pair[1])];
    if (sameParent || insideSwept((current[static_cast<std::size_t>(key.n[0])] + current[static_cast<std::size_t>(key.n[1])] + current[static_cast<std::size_t>(key.n[2])]) / 3.0)) {
      cutFaces.insert(key);
      cutLabels.push_back(labels[static_cast<std::size_t>(pair[0])]);
      cutLabels.push_back(labels[static_cast<std::size_t>(pair[1])]);
    }
  }
  for (const auto* set : {&pendingIn, &pendingNew})
    for (const FaceKey& k : *set) {
      const auto it = faces.find(k);
      if (it != faces.end() && it->second[1] >= 0) cutFaces.insert(k);
    }
  r.separatedFaces = cutFaces.size();
  std::vector<char> onSeparated(rest.size(), 0);
  for (const auto& k : cutFaces)
    for (int v : k.n) onSeparated[static_cast<std::size_t>(v)] = 1;
  struct Replacement {
    int tet, from, to;
  };
  std::vector<Replacement> replacements;
  for (std::size_t v = 0; v < rest.size(); ++v) {
    if (!onSeparated[v]) continue;
    const auto& inc = incident[v];
    std::vector<int> parent(inc.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int x) {
      while (parent[static_cast<std::size_t>(x)] != x) x = parent[static_cast<std::size_t>(x)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
      return x;
    };
    auto localOf = [&](int t) { return static_cast<int>(std::find(inc.begin(), inc.end(), t) - inc.begin()); };
    for (std::size_t a = 0; a < inc.size(); ++a) {
      const auto& e = tets[static_cast<std::size_t>(inc[a])];
      for (const auto& f : kFaces) {
        const int x = e[static_cast<std::size_t>(f[0])], y = e[static_cast<std::size_t>(f[1])], z = e[static_cast<std::size_t>(f[2])];
        if (x != static_cast<int>(v) && y != static_cast<int>(v) && z != static_cast<int>(v)) continue;
        const FaceKey key = faceKey(x, y, z);
        if (cutFaces.count(key)) continue;
        const auto& pair = faces.at(key);
        if (pair[1] < 0) continue;
        const int other = pair[0] == inc[a] ? pair[1] : pair[0];
        const int lb = localOf(other);
        if (lb < static_cast<int>(inc.size())) parent[static_cast<std::size_t>(find(static_cast<int>(a)))] = find(lb);
      }
    }
    std::vector<int> roots;
    for (std::size_t a = 0; a < inc.size(); ++a) {
      const int root = find(static_cast<int>(a));
      auto it = std::find(roots.begin(), roots.end(), root);
      if (it == roots.end()) {
        roots.push_back(root);
        it = roots.end() - 1;
      }
      const auto group = it - roots.begin();
      if (group == 0) continue;
      replacements.push_back({inc[a], static_cast<int>(v), -static_cast<int>(group)});  // group index, resolved below
    }
    // New nodes for groups 1..: a copy of v.
    std::vector<int> copyIndex(roots.size(), static_cast<int>(v));
    for (std::size_t g = 1; g < roots.size(); ++g) {
      CutNode c;
      if (static_cast<int>(v) < n0) {
        c.from = {static_cast<int>(v), -1, -1, -1};
        c.weight = {1, 0, 0, 0};
        r.duplicateOf.push_back(static_cast<int>(v));
      } else {
        c = newNodes[v - static_cast<std::size_t>(n0)];
        r.duplicateOf.push_back(-1);
      }
      copyIndex[g] = n0 + static_cast<int>(r.newNodes.size());
      r.newNodes.push_back(c);
      ++r.duplicatedNodes;
    }
    for (auto& rep : replacements)
      if (rep.from == static_cast<int>(v) && rep.to < 0) rep.to = copyIndex[static_cast<std::size_t>(-rep.to)];
  }
  for (std::size_t k = newNodes.size(); k < r.newNodes.size(); ++k) {
    // The copies' positions: their originals'.
    const CutNode& c = r.newNodes[k];
    V3 pr = V3::Zero(), pc = V3::Zero();
    for (int j = 0; j < 4; ++j)
      if (c.from[static_cast<std::size_t>(j)] >= 0) {
        pr += c.weight[static_cast<std::size_t>(j)] * rest[static_cast<std::size_t>(c.from[static_cast<std::size_t>(j)])];
        pc += c.weight[static_cast<std::size_t>(j)] * current[static_cast<std::size_t>(c.from[static_cast<std::size_t>(j)])];
      }
    rest.push_back(pr);
    current.push_back(pc);
  }
  std::unordered_map<std::uint64_t, int> renamed;  // (element, old node) -> new node
  for (const auto& rep : replacements) renamed[(static_cast<std::uint64_t>(rep.tet) << 32) | static_cast<std::uint32_t>(rep.from)] = rep.to;
  if (pending) {
    // What stays pending: cut faces whose two elements still share all three nodes (at the cut's front),
    // and earlier pending faces away from this cut.
    pending->clear();
    auto name = [&](int t, int v) {
      const auto it = renamed.find((static_cast<std::uint64_t>(t) << 32) | static_cast<std::uint32_t>(v));
      return it == renamed.end() ? v : it->second;
    };
    for (const FaceKey& k : cutFaces) {
      const auto& pair = faces.at(k);
      const FaceKey a = faceKey(name(pair[0], k.n[0]), name(pair[0], k.n[1]), name(pair[0], k.n[2]));
      const FaceKey b = faceKey(name(pair[1], k.n[0]), name(pair[1], k.n[1]), name(pair[1], k.n[2]));
      if (a == b) pending->push_back(a.n);
    }
    for (const FaceKey& k : pendingIn)
      if (!faces.count(k)) pending->push_back(k.n);
    std::sort(pending->begin(), pending->end());
  }
  for (const auto& rep : replacements)
    for (auto& n : tets[static_cast<std::size_t>(rep.tet)])
      if (n == rep.from) n = rep.to;
  if (cutNodes) {
    // On the cut now: what was, the snapped nodes, the new edge points, and every copy of them.
    std::vector<char> on(rest.size(), 0);
    for (int i : *cutNodes)
      if (i >= 0 && static_cast<std::size_t>(i) < on.size()) on[static_cast<std::size_t>(i)] = 1;
    for (std::size_t i = 0; i < zero.size(); ++i) on[i] = on[i] || zero[i];
    for (std::size_t k = 0; k < r.newNodes.size(); ++k) {
      const bool edgePointCopy = k >= newNodes.size() && r.duplicateOf[k] < 0 && r.newNodes[k].from[1] >= 0 && r.newNodes[k].from[2] < 0;
      const bool edgePoint = k < newNodes.size() && newNodes[k].from[2] < 0;
      const bool copyOfOn = k >= newNodes.size() && r.duplicateOf[k] >= 0 && on[static_cast<std::size_t>(r.duplicateOf[k])];
      if (edgePoint || edgePointCopy || copyOfOn) on[static_cast<std::size_t>(n0) + k] = 1;
    }
    cutNodes->clear();
    for (std::size_t i = 0; i < on.size(); ++i)
      if (on[i]) cutNodes->push_back(static_cast<int>(i));
  }
  std::sort(cutLabels.begin(), cutLabels.end());
  cutLabels.erase(std::unique(cutLabels.begin(), cutLabels.end()), cutLabels.end());
  r.cutLabels = cutLabels;
  r.changed = !pieces.empty() || r.duplicatedNodes > 0;
  if (progress && r.changed) progress->sweeps.push_back(blade);
  char buf[240];
  std::snprintf(buf, sizeof buf, "Cut: %zu element(s) split and %zu refined, %zu face(s) separated, %zu node(s) duplicated.", r.splitElements, r.refinedElements,
                r.separatedFaces, r.duplicatedNodes);
  r.status = buf;
  if (!r.changed)
    r.status = !crossedAny ? (r.skippedInverted ? "The blade crossed only tissue crushed inside out, which cannot be cut; nothing was cut." : "The blade crossed no tissue.")
                           : "The blade only grazed the tissue (it touched it without passing through); nothing was cut: draw it across the tissue again, a little deeper.";
  return r;
}

}  // namespace rehearse::simcore
