// The cut's second stage, the split: a new node on every edge whose ends lie on the two sides, and every element
// holding one re-meshed into pieces (a split element into its two sides, one at the cut's front refined whole),
// snapping more crossings to nodes until every piece meets the stated quality and volume, or refusing the cut.
// The pieces and new nodes stay in `built` until the separation writes them into the mesh.
#include "cut_stages.hpp"
#include <rehearse/simcore/words.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rehearse::simcore::detail {

bool TetCutter::splitElements() {
  built.replaced.assign(in.nt, 0);
  if (in.pending)
    for (const auto& f : *in.pending) built.pendingIn.insert(faceKey(f[0], f[1], f[2]));
  for (int iteration = 0;; ++iteration) {
    startSplit();
    placeEdgePoints();
    remeshElements();
    // Quality of the pieces (rest shape); a failing element makes its nearest crossing snap to a node.
    const PieceCheck check = checkPieces();
    if (check.failing.empty()) {
      r.minQuality = check.minQ;
      r.minVolumeFraction = check.minFraction;
      for (std::size_t t = 0; t < in.nt; ++t)
        r.splitElements += built.split[t], r.refinedElements += built.replaced[t] && !built.split[t];
      return true;
    }
    if (iteration >= 40) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "The cut was refused: %s would keep a piece below the stated quality (%.2f) or volume (%.0e of its element).",
                    quantity(check.failing.size(), "element", "elements").c_str(), in.settings.minQuality,
                    in.settings.minVolumeFraction);
      r.status = buf;
      return false;
    }
    snapFailing(check.failing);
  }
}

void TetCutter::startSplit() {
  built.newNodes.clear();
  built.newRest.clear();
  built.newCurrent.clear();
  built.pieces.clear();
  built.edgePoint.clear();
  built.pendingNew.clear();
  std::fill(built.replaced.begin(), built.replaced.end(), 0);
}

int TetCutter::sigma(int i) const {
  return crossing.zero[static_cast<std::size_t>(i)] ? 0 : (plane.dist[static_cast<std::size_t>(i)] > 0 ? 1 : -1);
}

// Split elements: candidates with nodes on both sides. Each sign-changing edge gets one point.
void TetCutter::placeEdgePoints() {
  const auto& dist = plane.dist;
  built.split.assign(in.nt, 0);
  for (std::size_t t = 0; t < in.nt; ++t) {
    if (!crossing.candidate[t]) continue;
    int pos = 0, neg = 0;
    for (int k = 0; k < 4; ++k) pos += sigma(tetNode(t, k)) > 0, neg += sigma(tetNode(t, k)) < 0;
    if (pos == 0 || neg == 0) continue;
    built.split[t] = 1;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        int i = tetNode(t, a), j = tetNode(t, b);
        if (sigma(i) * sigma(j) >= 0) continue;
        if (i > j) std::swap(i, j);
        if (built.edgePoint.count(edgeKey(i, j))) continue;
        const double u =
            dist[static_cast<std::size_t>(i)] / (dist[static_cast<std::size_t>(i)] - dist[static_cast<std::size_t>(j)]);
        CutNode c;
        c.from = {i, j, -1, -1};
        c.weight = {1 - u, u, 0, 0};
        built.edgePoint.emplace(edgeKey(i, j), in.n0 + static_cast<int>(built.newNodes.size()));
        built.newNodes.push_back(c);
        built.newRest.push_back((1 - u) * in.rest[static_cast<std::size_t>(i)] +
                                u * in.rest[static_cast<std::size_t>(j)]);
        built.newCurrent.push_back((1 - u) * in.current[static_cast<std::size_t>(i)] +
                                   u * in.current[static_cast<std::size_t>(j)]);
      }
  }
}

int TetCutter::pointOn(int i, int j) const {
  const auto it = built.edgePoint.find(edgeKey(i, j));
  return it == built.edgePoint.end() ? -1 : it->second;
}

const V3& TetCutter::restOf(int i) const {
  return i < in.n0 ? in.rest[static_cast<std::size_t>(i)] : built.newRest[static_cast<std::size_t>(i - in.n0)];
}

const V3& TetCutter::currentOf(int i) const {
  return i < in.n0 ? in.current[static_cast<std::size_t>(i)] : built.newCurrent[static_cast<std::size_t>(i - in.n0)];
}

// A node of element t (an old vertex or a point on one of its edges) as weights over t's four vertices.
std::array<double, 4> TetCutter::weightsIn(std::size_t t, int node) const {
  std::array<double, 4> w{0, 0, 0, 0};
  for (int k = 0; k < 4; ++k)
    if (tetNode(t, k) == node) w[static_cast<std::size_t>(k)] = 1;
  if (node >= in.n0) {
    const CutNode& c = built.newNodes[static_cast<std::size_t>(node - in.n0)];
    for (int k = 0; k < 4; ++k)
      for (int m = 0; m < 2; ++m)
        if (tetNode(t, k) == c.from[static_cast<std::size_t>(m)])
          w[static_cast<std::size_t>(k)] += c.weight[static_cast<std::size_t>(m)];
  }
  return w;
}

// The order `triangulate` starts its fans by: rest position, then node number.
bool TetCutter::before(int x, int y) const {
  const V3 &px = restOf(x), &py = restOf(y);
  if (px.x() != py.x()) return px.x() < py.x();
  if (px.y() != py.y()) return px.y() < py.y();
  if (px.z() != py.z()) return px.z() < py.z();
  return x < y;
}

// Cones the polygons from a new node at the mean of `verts` (within element t).
void TetCutter::cone(std::size_t t, const std::vector<std::vector<int>>& polys, const std::vector<int>& verts,
                     int side) {
  std::array<double, 4> w{0, 0, 0, 0};
  for (int v : verts) {
    const auto wv = weightsIn(t, v);
    for (int k = 0; k < 4; ++k)
      w[static_cast<std::size_t>(k)] += wv[static_cast<std::size_t>(k)] / static_cast<double>(verts.size());
  }
  CutNode c;
  V3 pr = V3::Zero(), pc = V3::Zero();
  for (int k = 0; k < 4; ++k) {
    c.from[static_cast<std::size_t>(k)] = tetNode(t, k);
    c.weight[static_cast<std::size_t>(k)] = w[static_cast<std::size_t>(k)];
    pr += w[static_cast<std::size_t>(k)] * in.rest[static_cast<std::size_t>(tetNode(t, k))];
    pc += w[static_cast<std::size_t>(k)] * in.current[static_cast<std::size_t>(tetNode(t, k))];
  }
  const int centre = in.n0 + static_cast<int>(built.newNodes.size());
  built.newNodes.push_back(c);
  built.newRest.push_back(pr);
  built.newCurrent.push_back(pc);
  std::vector<std::array<int, 3>> tris;
  for (const auto& p : polys) triangulate(p, tris, [this](int x, int y) { return before(x, y); });
  for (const auto& tri : tris) {
    Piece piece{{tri[0], tri[1], tri[2], centre}, static_cast<int>(t), side};
    if (signedVolume(restOf(piece.n[0]), restOf(piece.n[1]), restOf(piece.n[2]), restOf(piece.n[3])) < 0)
      std::swap(piece.n[0], piece.n[1]);
    built.pieces.push_back(piece);
  }
}

// The parts of face (a, b, c) on either side of its edge points, with the side of each part.
void TetCutter::faceParts(int a, int b, int c, FaceParts& out) const {
  const std::array<int, 3> v{a, b, c};
  std::array<int, 3> p{pointOn(a, b), pointOn(b, c), pointOn(c, a)};  // p[k] on edge (v[k], v[k+1])
  const int k = (p[0] >= 0) + (p[1] >= 0) + (p[2] >= 0);
  auto sideOfPart = [&](const std::vector<int>& part) {
    for (int x : part)
      if (x < in.n0 && sigma(x) != 0) return sigma(x);
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
    const int x = v[static_cast<std::size_t>(e)], y = v[static_cast<std::size_t>((e + 1) % 3)],
              z = v[static_cast<std::size_t>((e + 2) % 3)];
    add({x, p[static_cast<std::size_t>(e)], z});
    add({p[static_cast<std::size_t>(e)], y, z});
  } else if (k == 2) {
    // The vertex between the two pointed edges is cut off.
    const int e = p[0] < 0 ? 0 : (p[1] < 0 ? 1 : 2);  // the edge without a point: (v[e], v[e+1])
    const int x = v[static_cast<std::size_t>(e)], y = v[static_cast<std::size_t>((e + 1) % 3)],
              z = v[static_cast<std::size_t>((e + 2) % 3)];
    const int pyz = p[static_cast<std::size_t>((e + 1) % 3)], pzx = p[static_cast<std::size_t>((e + 2) % 3)];
    add({pyz, z, pzx});
    add({x, y, pyz, pzx});
  } else {
    add({a, p[0], p[2]});
    add({b, p[1], p[0]});
    add({c, p[2], p[1]});
    add({p[0], p[1], p[2]});
  }
}

void TetCutter::remeshElements() {
  for (std::size_t t = 0; t < in.nt; ++t) {
    bool touched = built.split[t];
    if (!touched)
      for (int a = 0; a < 4 && !touched; ++a)
        for (int b = a + 1; b < 4 && !touched; ++b) touched = pointOn(tetNode(t, a), tetNode(t, b)) >= 0;
    if (!touched) continue;
    remeshElement(t);
  }
}

// Element t holds a new node: its faces split at their edge points, then coned (one piece set per side when the
// element is split, one for the whole element when it is only refined).
void TetCutter::remeshElement(std::size_t t) {
  built.replaced[t] = 1;
  FaceParts parts;
  for (const auto& f : kFaces) {
    const std::size_t first = parts.size();
    faceParts(tetNode(t, f[0]), tetNode(t, f[1]), tetNode(t, f[2]), parts);
    // A face on an earlier cut that has not opened yet stays on it in its pieces.
    if (built.pendingIn.count(faceKey(tetNode(t, f[0]), tetNode(t, f[1]), tetNode(t, f[2])))) {
      std::vector<std::array<int, 3>> tris;
      for (std::size_t k = first; k < parts.size(); ++k)
        triangulate(parts[k].first, tris, [this](int x, int y) { return before(x, y); });
      for (const auto& tri : tris) built.pendingNew.insert(faceKey(tri[0], tri[1], tri[2]));
    }
  }
  if (!built.split[t]) {
    std::vector<std::vector<int>> polys;
    for (auto& [poly, sd] : parts) polys.push_back(poly);
    cone(t, polys, {tetNode(t, 0), tetNode(t, 1), tetNode(t, 2), tetNode(t, 3)}, 0);
    return;
  }
  const std::vector<int> cut = cutPolygon(t);
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

// The cut polygon of split element t: snapped vertices and edge points, in cyclic order on the plane.
std::vector<int> TetCutter::cutPolygon(std::size_t t) const {
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
    const V3 e1 = (currentOf(cut[0]) - c).normalized(), e2 = plane.normal.cross(e1);
    std::vector<std::pair<double, int>> byAngle;
    for (int q : cut) byAngle.emplace_back(std::atan2((currentOf(q) - c).dot(e2), (currentOf(q) - c).dot(e1)), q);
    std::sort(byAngle.begin(), byAngle.end());
    for (std::size_t k = 0; k < cut.size(); ++k) cut[k] = byAngle[k].second;
  }
  return cut;
}

// The pieces' quality and volume (rest shape) and their volume now; the elements with a piece below the bounds.
TetCutter::PieceCheck TetCutter::checkPieces() {
  const auto& rest = in.rest;
  auto& restVol = crossing.restVol;
  std::vector<double> parentQuality(in.nt, -1);
  PieceCheck check;
  for (const Piece& p : built.pieces) {
    const std::size_t t = static_cast<std::size_t>(p.parent);
    const auto& e = in.tets[t];
    if (parentQuality[t] < 0) {
      parentQuality[t] = tetShapeQuality(rest[static_cast<std::size_t>(e[0])], rest[static_cast<std::size_t>(e[1])],
                                         rest[static_cast<std::size_t>(e[2])], rest[static_cast<std::size_t>(e[3])]);
      if (restVol[t] <= 0)
        restVol[t] = signedVolume(rest[static_cast<std::size_t>(e[0])], rest[static_cast<std::size_t>(e[1])],
                                  rest[static_cast<std::size_t>(e[2])], rest[static_cast<std::size_t>(e[3])]);
    }
    const double v = signedVolume(restOf(p.n[0]), restOf(p.n[1]), restOf(p.n[2]), restOf(p.n[3]));
    const double q = tetShapeQuality(restOf(p.n[0]), restOf(p.n[1]), restOf(p.n[2]), restOf(p.n[3]));
    const double fraction = restVol[t] > 0 ? v / restVol[t] : 0;
    const double vc = signedVolume(currentOf(p.n[0]), currentOf(p.n[1]), currentOf(p.n[2]), currentOf(p.n[3]));
    check.minQ = std::min(check.minQ, q);
    check.minFraction = std::min(check.minFraction, fraction);
    if (!(vc > 0) || fraction < in.settings.minVolumeFraction || q < in.settings.minQuality)
      check.failing.insert(p.parent);
  }
  return check;
}

// In each failing element, the crossing nearest a node snaps to that node; when none can snap further, the
// failing elements are not cut.
void TetCutter::snapFailing(const std::unordered_set<int>& failing) {
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
        const double u = built.newNodes[static_cast<std::size_t>(q - in.n0)].weight[1];
        if (u < best) best = u, node = i;
        if (1 - u < best) best = 1 - u, node = j;
      }
    if (node >= 0 && !crossing.zero[static_cast<std::size_t>(node)]) {
      crossing.zero[static_cast<std::size_t>(node)] = 1;
      progressed = true;
    }
  }
  if (!progressed) {
    for (int t : order) crossing.candidate[static_cast<std::size_t>(t)] = 0;  // cannot be improved: not cut
  }
}

}  // namespace rehearse::simcore::detail
