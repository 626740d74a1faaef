// The cut suite's shared checks (see test_cut_support.hpp).
#include "test_cut_support.hpp"
#include "session_inputs.hpp"

#include <algorithm>
#include <map>
#include <numeric>

using namespace rehearse;

double volume(const std::vector<Eigen::Vector3d>& p, const std::array<int, 4>& t) {
  return (p[static_cast<std::size_t>(t[1])] - p[static_cast<std::size_t>(t[0])])
             .dot((p[static_cast<std::size_t>(t[2])] - p[static_cast<std::size_t>(t[0])])
                      .cross(p[static_cast<std::size_t>(t[3])] - p[static_cast<std::size_t>(t[0])])) /
         6.0;
}

std::vector<int> components(std::size_t nodes, const std::vector<std::array<int, 4>>& tets, int* count) {
  std::vector<int> parent(nodes);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x)
      x = parent[static_cast<std::size_t>(x)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
    return x;
  };
  for (const auto& t : tets)
    for (int k = 1; k < 4; ++k) parent[static_cast<std::size_t>(find(t[static_cast<std::size_t>(k)]))] = find(t[0]);
  std::map<int, int> ids;
  std::vector<int> out;
  for (const auto& t : tets) out.push_back(ids.try_emplace(find(t[0]), static_cast<int>(ids.size())).first->second);
  *count = static_cast<int>(ids.size());
  return out;
}

std::vector<std::array<int, 3>> boundaryFaces(const std::vector<std::array<int, 4>>& tets, int* overused) {
  std::map<std::array<int, 3>, std::pair<int, std::array<int, 3>>> faces;
  static const int f[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (const auto& t : tets)
    for (const auto& q : f) {
      std::array<int, 3> o{t[static_cast<std::size_t>(q[0])], t[static_cast<std::size_t>(q[1])],
                           t[static_cast<std::size_t>(q[2])]};
      std::array<int, 3> k = o;
      std::sort(k.begin(), k.end());
      auto& e = faces[k];
      ++e.first;
      e.second = o;
    }
  std::vector<std::array<int, 3>> out;
  *overused = 0;
  for (const auto& [k, e] : faces) {
    if (e.first == 1) out.push_back(e.second);
    if (e.first > 2) ++*overused;
  }
  return out;
}

double area(const std::vector<Eigen::Vector3d>& p, const std::vector<std::array<int, 3>>& tris) {
  double a = 0;
  for (const auto& t : tris)
    a += 0.5 * (p[static_cast<std::size_t>(t[1])] - p[static_cast<std::size_t>(t[0])])
                   .cross(p[static_cast<std::size_t>(t[2])] - p[static_cast<std::size_t>(t[0])])
                   .norm();
  return a;
}

Validity validity(const std::vector<Eigen::Vector3d>& p, const std::vector<std::array<int, 4>>& tets) {
  Validity v;
  for (const auto& t : tets) {
    const double vol = volume(p, t);
    v.inverted += !(vol > 0);
    v.totalVolume += vol;
    v.minQuality = std::min(
        v.minQuality, simcore::tetShapeQuality(p[static_cast<std::size_t>(t[0])], p[static_cast<std::size_t>(t[1])],
                                               p[static_cast<std::size_t>(t[2])], p[static_cast<std::size_t>(t[3])]));
  }
  return v;
}

double minQualityOf(const simcore::Mesh& m) {
  return validity(m.points, m.tets).minQuality;
}

simcore::BodySetup liverSetup() {
  return testing::presetBody("liver");
}

simcore::BladeSweep planeX(double x0, double y0, double y1) {
  return {{x0, y0, -0.01}, {x0, y0, 0.03}, {x0, y1, -0.01}, {x0, y1, 0.03}};
}
