#pragma once
// Structured tetrahedral meshes for the physics tests.
#include <rehearse/simcore/mesh.hpp>

#include <cmath>
#include <utility>
#include <vector>

/// Box [0,L]x[0,b]x[0,h] split into n x m x k cubes of 6 tetrahedra each (conforming Kuhn split),
/// positively oriented, label 1.
inline rehearse::simcore::Mesh boxMesh(double L, double b, double h, int n, int m, int k) {
  rehearse::simcore::Mesh mesh;
  auto id = [&](int i, int j, int l) { return (i * (m + 1) + j) * (k + 1) + l; };
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= m; ++j)
      for (int l = 0; l <= k; ++l) mesh.points.emplace_back(L * i / n, b * j / m, h * l / k);
  static const int kuhn[6][4] = {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7}, {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}};
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j)
      for (int l = 0; l < k; ++l) {
        int c[8];
        for (int q = 0; q < 8; ++q) c[q] = id(i + (q & 1), j + ((q >> 1) & 1), l + ((q >> 2) & 1));
        for (const auto& t : kuhn) {
          std::array<int, 4> tet = {c[t[0]], c[t[1]], c[t[2]], c[t[3]]};
          const auto& p = mesh.points;
          if ((p[tet[1]] - p[tet[0]]).cross(p[tet[2]] - p[tet[0]]).dot(p[tet[3]] - p[tet[0]]) < 0) std::swap(tet[2], tet[3]);
          mesh.tets.push_back(tet);
          mesh.tetLabels.push_back(1);
        }
      }
  return mesh;
}

/// Nodes on the plane x = value.
inline std::vector<int> nodesAtX(const rehearse::simcore::Mesh& m, double x) {
  std::vector<int> out;
  for (std::size_t i = 0; i < m.points.size(); ++i)
    if (std::abs(m.points[i].x() - x) < 1e-12) out.push_back(static_cast<int>(i));
  return out;
}
