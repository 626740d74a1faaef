// The blood on the organ's surface as the views draw it (bloodfilm.hpp): a falling film from each stump, held on the
// surface only for the time it takes to run off.
#include "rehearse/simcore/session/bloodfilm.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>

namespace rehearse::simcore {

double filmSpeed(double thickness, double sine, const BloodFilmSettings& s) {
  if (!(thickness > 0) || !(s.viscosity > 0)) return 0;
  return s.density * s.gravity * thickness * thickness * std::max(0.0, sine) / (3 * s.viscosity);
}

std::vector<std::vector<int>> surfaceNeighbours(const std::vector<std::array<int, 3>>& triangles, std::size_t n) {
  std::vector<std::vector<int>> nb(n);
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[static_cast<std::size_t>(k)], b = t[static_cast<std::size_t>((k + 1) % 3)];
      if (a < 0 || b < 0 || static_cast<std::size_t>(a) >= n || static_cast<std::size_t>(b) >= n || a == b) continue;
      nb[static_cast<std::size_t>(a)].push_back(b);
      nb[static_cast<std::size_t>(b)].push_back(a);
    }
  for (auto& v : nb) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
  }
  return nb;
}

BloodFilm bloodFilm(const std::vector<Bleed>& bleeds, const std::vector<Eigen::Vector3d>& live,
                    const std::vector<std::array<int, 3>>& triangles, const std::vector<std::vector<int>>& neighbours,
                    const Eigen::Vector3d& down, const BloodFilmSettings& s, const std::vector<char>& cutFaces) {
  const std::size_t n = live.size();
  BloodFilm out;
  out.film.assign(n, 0.0);
  out.onSurface.assign(bleeds.size(), 0.0);
  out.runOff.assign(bleeds.size(), std::numeric_limits<double>::infinity());
  out.covered.assign(bleeds.size(), 0.0);
  out.source.assign(bleeds.size(), -1);
  if (n == 0 || neighbours.size() != n || !(s.thickness > 0)) return out;
  const bool gravity = down.allFinite() && down.norm() > 0.5;

  // Each node's area (a third of its triangles') and normal (area-weighted, outward as the triangles turn).
  std::vector<double> area(n, 0.0);
  std::vector<Eigen::Vector3d> normal(n, Eigen::Vector3d::Zero());
  for (const auto& t : triangles) {
    if (std::any_of(t.begin(), t.end(), [n](int v) { return v < 0 || static_cast<std::size_t>(v) >= n; })) continue;
    const Eigen::Vector3d &a = live[static_cast<std::size_t>(t[0])], &b = live[static_cast<std::size_t>(t[1])],
                          &c = live[static_cast<std::size_t>(t[2])];
    const Eigen::Vector3d cross = (b - a).cross(c - a);
    if (!cross.allFinite()) continue;
    for (int v : t) {
      area[static_cast<std::size_t>(v)] += cross.norm() / 6;
      normal[static_cast<std::size_t>(v)] += cross;
    }
  }
  // Where blood leaves the organ: where the surface faces down, and its lowest nodes.
  std::vector<char> leaves(n, 0);
  if (gravity) {
    double lowest = -std::numeric_limits<double>::infinity();
    for (const auto& p : live)
      if (p.allFinite()) lowest = std::max(lowest, down.dot(p));
    for (std::size_t v = 0; v < n; ++v) {
      if (!live[v].allFinite() || neighbours[v].empty()) continue;
      const double len = normal[v].norm();
      leaves[v] = (len > 0 && down.dot(normal[v]) >= s.drips * len) || down.dot(live[v]) >= lowest - s.lowest;
    }
  }

  // The incisions: nodes of a cut's faces, and of the organ's own surface (both: an incision's lip).
  std::vector<char> inCut(n, 0), outer(n, 0);
  const bool incisions = gravity && cutFaces.size() == triangles.size();
  if (incisions)
    for (std::size_t f = 0; f < triangles.size(); ++f)
      for (int v : triangles[f])
        if (v >= 0 && static_cast<std::size_t>(v) < n) (cutFaces[f] ? inCut : outer)[static_cast<std::size_t>(v)] = 1;

  const double vertical = filmSpeed(s.thickness, 1.0, s), slowest = s.crawl * vertical;
  auto edgeTime = [&](int v, int w) {
    // An incision's walls lie together (the tissue closes behind the blade): the film runs over its mouth, not into
    // it (the incision a stump bleeds into is drawn full around it, above).
    if (incisions && inCut[static_cast<std::size_t>(w)] && !outer[static_cast<std::size_t>(w)] &&
        !(inCut[static_cast<std::size_t>(v)] && !outer[static_cast<std::size_t>(v)]))
      return std::numeric_limits<double>::infinity();
    const Eigen::Vector3d e = live[static_cast<std::size_t>(w)] - live[static_cast<std::size_t>(v)];
    const double len = e.norm();
    if (!(len > 0) || !std::isfinite(len)) return std::numeric_limits<double>::infinity();
    return len / (gravity ? std::max(slowest, filmSpeed(s.thickness, down.dot(e) / len, s)) : slowest);
  };
  using Item = std::pair<double, int>;
  std::vector<double> time(n), spread(n);
  std::vector<int> from(n), order;
  for (std::size_t i = 0; i < bleeds.size(); ++i) {
    const Bleed& b = bleeds[i];
    if (!(b.lost > 0) || b.node < 0 || static_cast<std::size_t>(b.node) >= n || !(vertical > 0)) continue;
    int source = b.node;
    if (incisions && inCut[static_cast<std::size_t>(b.node)] && !outer[static_cast<std::size_t>(b.node)]) {
      // Inside an incision: the vessel's pressure (arterial 90 mmHg is 1.2 m of blood; a portal vein's 10 mmHg, 13 cm)
      // is far above the few centimetres of an organ's height, so the blood leaves the incision by its nearest mouth,
      // not its lowest: the lip node nearest the stump along the incision's faces. The incision fills around the stump
      // as far as that mouth, and the stream starts there. (By the lowest lip, a trunk cut through to the organ's side
      // ran out at its back under a laparoscope looking down, and the camera saw no blood at all.)
      std::fill(time.begin(), time.end(), std::numeric_limits<double>::infinity());
      std::fill(from.begin(), from.end(), -1);
      std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
      time[static_cast<std::size_t>(b.node)] = 0;
      queue.emplace(0.0, b.node);
      while (!queue.empty()) {
        const auto [d, v] = queue.top();
        queue.pop();
        if (d > time[static_cast<std::size_t>(v)]) continue;
        if (outer[static_cast<std::size_t>(v)]) {
          source = v;
          break;
        }
        for (int w : neighbours[static_cast<std::size_t>(v)]) {
          if (!inCut[static_cast<std::size_t>(w)]) continue;
          const double len = (live[static_cast<std::size_t>(w)] - live[static_cast<std::size_t>(v)]).norm();
          if (!std::isfinite(len) || d + len >= time[static_cast<std::size_t>(w)]) continue;
          time[static_cast<std::size_t>(w)] = d + len;
          from[static_cast<std::size_t>(w)] = v;
          queue.emplace(d + len, w);
        }
      }
      if (source != b.node) {
        const double reach = time[static_cast<std::size_t>(source)];
        for (std::size_t v = 0; v < n; ++v)
          if (inCut[v] && time[v] <= reach) out.film[v] = 1;  // the incision full around the stump
      }
    }
    out.source[i] = source;
    // The stream's path: the quickest way down from its source to where the blood leaves the organ (the film's time
    // along each edge at its speed on the edge's slope).
    std::fill(time.begin(), time.end(), std::numeric_limits<double>::infinity());
    std::fill(from.begin(), from.end(), -1);
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    time[static_cast<std::size_t>(source)] = 0;
    queue.emplace(0.0, source);
    int exit = -1;
    while (!queue.empty()) {
      const auto [t, v] = queue.top();
      queue.pop();
      if (t > time[static_cast<std::size_t>(v)]) continue;
      if (leaves[static_cast<std::size_t>(v)]) {
        exit = v;
        break;
      }
      for (int w : neighbours[static_cast<std::size_t>(v)]) {
        const double at = t + edgeTime(v, w);
        if (at < time[static_cast<std::size_t>(w)]) {
          time[static_cast<std::size_t>(w)] = at;
          from[static_cast<std::size_t>(w)] = v;
          queue.emplace(at, w);
        }
      }
    }
    if (exit >= 0) out.runOff[i] = time[static_cast<std::size_t>(exit)];
    // The blood on the surface: what flowed out over the run-off time (all of it where it cannot run off).
    const double held = std::isfinite(out.runOff[i]) && b.rate > 0
                            ? std::min(b.lost, b.rate * std::max(s.wets, out.runOff[i]))
                            : b.lost;
    out.onSurface[i] = held;
    // The stream's front: as far down the path as the bleeding's time so far has carried it.
    const double elapsed = b.rate > 0 ? b.lost / b.rate : std::numeric_limits<double>::infinity();
    std::fill(spread.begin(), spread.end(), std::numeric_limits<double>::infinity());
    std::priority_queue<Item, std::vector<Item>, std::greater<>> wet;
    // (Its nodes first, from the stump down: a thin stream wets its path before anything beside it.)
    for (int v = exit; v >= 0; v = from[static_cast<std::size_t>(v)])
      if (time[static_cast<std::size_t>(v)] <= elapsed) {
        spread[static_cast<std::size_t>(v)] = 1e-6 * time[static_cast<std::size_t>(v)];
        wet.emplace(spread[static_cast<std::size_t>(v)], v);
      }
    if (wet.empty()) {
      spread[static_cast<std::size_t>(source)] = 0;
      wet.emplace(0.0, source);
    }
    // The stream as wide as its blood covers at the film's thickness: the nodes the film reaches soonest from its
    // path (where it cannot run off: from the stump, a pool).
    const double target = held / s.thickness;
    double covered = 0, edge = 0;
    order.clear();
    while (!wet.empty() && covered < target) {
      const auto [t, v] = wet.top();
      wet.pop();
      if (t > spread[static_cast<std::size_t>(v)]) continue;
      order.push_back(v);
      covered += area[static_cast<std::size_t>(v)];
      edge = t;
      for (int w : neighbours[static_cast<std::size_t>(v)]) {
        const double at = t + edgeTime(v, w);
        if (at < spread[static_cast<std::size_t>(w)]) {
          spread[static_cast<std::size_t>(w)] = at;
          wet.emplace(at, w);
        }
      }
    }
    out.covered[i] = covered;
    for (int v : order) {
      const double thin = edge > 0 ? spread[static_cast<std::size_t>(v)] / edge : 0;  // 0 on the stream, 1 at its edge
      out.film[static_cast<std::size_t>(v)] = std::max(out.film[static_cast<std::size_t>(v)], 1 - 0.75 * thin);
    }
  }
  return out;
}

}  // namespace rehearse::simcore
