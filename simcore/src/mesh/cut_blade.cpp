// The cut's first stage, the blade: the plane and quad it swept, the elements whose crossing lies inside the quad
// (or in what this continuous cut swept before), and the nodes the cut passes through (snapping).
#include "cut_stages.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace rehearse::simcore::detail {

TetCutter::TetCutter(std::vector<V3>& rest, std::vector<V3>& current, std::vector<std::array<int, 4>>& tets,
                     std::vector<int>& labels, const BladeSweep& blade, const CutSettings& settings,
                     CutProgress* progress)
    : in{rest,
         current,
         tets,
         labels,
         blade,
         settings,
         progress,
         progress ? &progress->pendingFaces : nullptr,
         progress ? &progress->nodes : nullptr,
         static_cast<int>(rest.size()),
         tets.size()} {}

bool TetCutter::inputsMatch() {
  if (in.current.size() != in.rest.size() || in.labels.size() != in.tets.size()) {
    r.status = "The cut was refused: the mesh's positions or labels do not match it.";
    return false;
  }
  return true;
}

bool TetCutter::placeBlade() {
  const BladeSweep& blade = in.blade;
  plane.quad = {blade.a0, blade.b0, blade.b1, blade.a1};
  V3 normal = (blade.b1 - blade.a0).cross(blade.a1 - blade.b0);
  const double area = 0.5 * normal.norm();
  const double scale =
      std::max({(blade.b0 - blade.a0).norm(), (blade.a1 - blade.a0).norm(), (blade.b1 - blade.a1).norm(), 1e-12});
  if (!std::isfinite(area) || area < 1e-6 * scale * scale || area < 1e-12) {
    r.status = "The blade swept no area (it moved along itself or not at all); nothing was cut.";
    return false;
  }
  normal /= 2 * area;
  plane.normal = normal;
  const auto& quad = plane.quad;
  plane.origin = 0.25 * (quad[0] + quad[1] + quad[2] + quad[3]);
  plane.dist.assign(in.current.size(), 0.0);
  for (std::size_t i = 0; i < in.current.size(); ++i) plane.dist[i] = plane.normal.dot(in.current[i] - plane.origin);
  return true;
}

bool TetCutter::insideQuad(const V3& p) const {
  const auto& quad = plane.quad;
  int pos = 0, neg = 0;
  for (int i = 0; i < 4; ++i) {
    const V3& q = quad[static_cast<std::size_t>(i)];
    const V3& q1 = quad[static_cast<std::size_t>((i + 1) % 4)];
    const double side = plane.normal.dot((q1 - q).cross(p - q));
    pos += side > 0;
    neg += side < 0;
  }
  return pos == 0 || neg == 0;
}

// Inside any sweep of this continuous cut (each projected along its own plane's normal).
bool TetCutter::insideSwept(const V3& p) const {
  if (insideQuad(p)) return true;
  if (!in.progress) return false;
  for (const BladeSweep& b : in.progress->sweeps) {
    const std::array<V3, 4> q{b.a0, b.b0, b.b1, b.a1};
    V3 nb = (b.b1 - b.a0).cross(b.a1 - b.b0);
    if (!(nb.norm() > 0)) continue;
    nb.normalize();
    int pos = 0, neg = 0;
    for (int i = 0; i < 4; ++i) {
      const double side = nb.dot((q[static_cast<std::size_t>((i + 1) % 4)] - q[static_cast<std::size_t>(i)])
                                     .cross(p - q[static_cast<std::size_t>(i)]));
      pos += side > 0;
      neg += side < 0;
    }
    if (pos == 0 || neg == 0) return true;
  }
  return false;
}

// Where the plane crosses element t (the mean of its edges' crossings and its nodes on the plane, raw
// signs); false when it does not.
bool TetCutter::crossingCentre(std::size_t t, V3& centre) const {
  const auto& dist = plane.dist;
  V3 c = V3::Zero();
  int count = 0;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) {
      const int i = tetNode(t, a), j = tetNode(t, b);
      const double di = dist[static_cast<std::size_t>(i)], dj = dist[static_cast<std::size_t>(j)];
      if ((di < 0 && dj > 0) || (di > 0 && dj < 0)) {
        const double u = di / (di - dj);
        c += (1 - u) * in.current[static_cast<std::size_t>(i)] + u * in.current[static_cast<std::size_t>(j)];
        ++count;
      }
    }
  for (int k = 0; k < 4; ++k)
    if (dist[static_cast<std::size_t>(tetNode(t, k))] == 0)
      c += in.current[static_cast<std::size_t>(tetNode(t, k))], ++count;
  if (count == 0) return false;
  centre = c / count;
  return true;
}

// Element t's rest volume when it is positive at rest and now (an inverted element is not cut), else 0.
double TetCutter::cuttableVolume(std::size_t t) const {
  const auto& e = in.tets[t];
  const auto& rest = in.rest;
  const auto& current = in.current;
  const double vr = signedVolume(rest[static_cast<std::size_t>(e[0])], rest[static_cast<std::size_t>(e[1])],
                                 rest[static_cast<std::size_t>(e[2])], rest[static_cast<std::size_t>(e[3])]);
  const double vc = signedVolume(current[static_cast<std::size_t>(e[0])], current[static_cast<std::size_t>(e[1])],
                                 current[static_cast<std::size_t>(e[2])], current[static_cast<std::size_t>(e[3])]);
  return vr > 0 && vc > 0 ? vr : 0.0;
}

// Crossed elements whose crossing lies inside the swept quad (raw signs, before snapping).
void TetCutter::findCrossed() {
  const auto& dist = plane.dist;
  crossing.candidate.assign(in.nt, 0);
  crossing.relevant.assign(in.current.size(), 0);
  crossing.restVol.assign(in.nt, 0.0);
  for (std::size_t t = 0; t < in.nt; ++t) {
    double lo = 1e300, hi = -1e300;
    for (int k = 0; k < 4; ++k)
      lo = std::min(lo, dist[static_cast<std::size_t>(tetNode(t, k))]),
      hi = std::max(hi, dist[static_cast<std::size_t>(tetNode(t, k))]);
    if (!(lo <= 0 && hi >= 0)) continue;
    V3 c;
    if (!crossingCentre(t, c) || !insideQuad(c)) continue;
    const double vr = cuttableVolume(t);
    if (!(vr > 0)) {
      ++r.skippedInverted;
      continue;
    }
    crossing.candidate[t] = 1;
    crossing.restVol[t] = vr;
    for (int k = 0; k < 4; ++k) crossing.relevant[static_cast<std::size_t>(tetNode(t, k))] = 1;
  }
}

// Elements holding a crossed edge of a candidate whose crossing lies in the region this continuous cut has
// swept so far are cut too (else they would stop the cut where an earlier strip ended).
void TetCutter::growAlongSweeps() {
  if (!in.progress || in.progress->sweeps.empty()) return;
  const auto& dist = plane.dist;
  auto& candidate = crossing.candidate;
  std::unordered_map<std::uint64_t, char> crossed;
  auto crossedEdges = [&](std::size_t t) {
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const int i = tetNode(t, a), j = tetNode(t, b);
        const double di = dist[static_cast<std::size_t>(i)], dj = dist[static_cast<std::size_t>(j)];
        if ((di < 0 && dj > 0) || (di > 0 && dj < 0)) crossed[edgeKey(i, j)] = 1;
      }
  };
  for (std::size_t t = 0; t < in.nt; ++t)
    if (candidate[t]) crossedEdges(t);
  for (bool grew = true; grew;) {
    grew = false;
    for (std::size_t t = 0; t < in.nt; ++t) {
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
      crossing.restVol[t] = vr;
      for (int k = 0; k < 4; ++k) crossing.relevant[static_cast<std::size_t>(tetNode(t, k))] = 1;
      crossedEdges(t);
      grew = true;
    }
  }
}

bool TetCutter::anythingToCut() {
  const auto& candidate = crossing.candidate;
  // With nothing crossed, faces of earlier updates may still open (below); the status says so otherwise.
  crossing.crossedAny = std::find(candidate.begin(), candidate.end(), 1) != candidate.end();
  for (std::size_t t = 0; t < in.nt && in.cutNodes && !in.cutNodes->empty(); ++t)
    if (candidate[t])
      for (int k = 0; k < 4; ++k) crossing.relevant[static_cast<std::size_t>(tetNode(t, k))] = 1;
  if (!crossing.crossedAny && (!in.pending || in.pending->empty())) {
    r.status = r.skippedInverted ? "The blade crossed only inverted elements; nothing was cut."
                                 : "The blade crossed no tissue.";
    return false;
  }
  return true;
}

// Snapping: a crossing near a node passes through the node. Nodes already on this continuous cut stay on it.
void TetCutter::snapNearNodes() {
  const auto& dist = plane.dist;
  auto& zero = crossing.zero;
  zero.assign(in.current.size(), 0);
  if (in.cutNodes)
    for (int i : *in.cutNodes)
      if (i >= 0 && i < in.n0) zero[static_cast<std::size_t>(i)] = 1;
  for (std::size_t t = 0; t < in.nt; ++t) {
    if (!crossing.candidate[t]) continue;
    for (int a = 0; a < 4; ++a) {
      const int i = tetNode(t, a);
      if (dist[static_cast<std::size_t>(i)] == 0) zero[static_cast<std::size_t>(i)] = 1;
      for (int b = a + 1; b < 4; ++b) {
        const int j = tetNode(t, b);
        const double di = dist[static_cast<std::size_t>(i)], dj = dist[static_cast<std::size_t>(j)];
        if (!((di < 0 && dj > 0) || (di > 0 && dj < 0))) continue;
        const double u = di / (di - dj);
        if (u < in.settings.snap) zero[static_cast<std::size_t>(i)] = 1;
        if (u > 1 - in.settings.snap) zero[static_cast<std::size_t>(j)] = 1;
      }
    }
  }
}

// The cut's front: an edge crossed inside the quad that an element outside the quad also holds would put a
// node on that element's edge (refining it, and its pieces would lie behind the next update's strip).
// Instead the crossing snaps to the edge's nearer node, so the front runs along element faces and a
// continuous cut resumes there.
void TetCutter::snapFront() {
  const auto& dist = plane.dist;
  const auto& candidate = crossing.candidate;
  const auto& relevant = crossing.relevant;
  auto& zero = crossing.zero;
  std::unordered_map<std::uint64_t, std::array<int, 2>> edgeUse;  // (elements, candidates) holding the edge
  for (std::size_t t = 0; t < in.nt; ++t) {
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
  for (bool changed = in.settings.snapFront; changed;) {
    changed = false;
    for (std::size_t t = 0; t < in.nt; ++t) {
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

}  // namespace rehearse::simcore::detail
