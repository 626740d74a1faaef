#include <rehearse/simcore/quality.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>

namespace rehearse::simcore {

double tetVolume(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  return (b - a).cross(c - a).dot(d - a) / 6.0;
}

namespace {

struct TetShape {
  double volume, minDihedral, maxDihedral, aspect, edgeSum, maxEdge;
};

TetShape tetShape(const Eigen::Vector3d* p) {
  TetShape s{};
  s.volume = tetVolume(p[0], p[1], p[2], p[3]);
  static constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  // Face normals (outward, unnormalised) opposite each vertex; dihedral along edge (i,j) is between
  // the faces opposite the two other vertices.
  static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  Eigen::Vector3d n[4];
  double area = 0;
  for (int f = 0; f < 4; ++f) {
    n[f] = (p[kFace[f][1]] - p[kFace[f][0]]).cross(p[kFace[f][2]] - p[kFace[f][0]]);
    area += 0.5 * n[f].norm();
  }
  s.minDihedral = 180;
  s.maxDihedral = 0;
  for (auto& e : kEdges) {
    double len = (p[e[0]] - p[e[1]]).norm();
    s.edgeSum += len;
    s.maxEdge = std::max(s.maxEdge, len);
    int others[2], k = 0;
    for (int v = 0; v < 4; ++v)
      if (v != e[0] && v != e[1]) others[k++] = v;
    double na = n[others[0]].norm(), nb = n[others[1]].norm();
    double ang = 0;
    if (na > 0 && nb > 0) {
      double c = std::clamp(-n[others[0]].dot(n[others[1]]) / (na * nb), -1.0, 1.0);
      ang = std::acos(c) * 180.0 / std::numbers::pi;
    }
    s.minDihedral = std::min(s.minDihedral, ang);
    s.maxDihedral = std::max(s.maxDihedral, ang);
  }
  // Inradius r = 3V / A; circumradius from the standard formula.
  double V = std::abs(s.volume);
  Eigen::Vector3d a = p[1] - p[0], b = p[2] - p[0], c = p[3] - p[0];
  Eigen::Vector3d num = a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) + c.squaredNorm() * a.cross(b);
  double R = V > 0 ? num.norm() / (12.0 * V) : std::numeric_limits<double>::infinity();
  double r = area > 0 ? 3.0 * V / area : 0;
  s.aspect = r > 0 ? R / (3.0 * r) : std::numeric_limits<double>::infinity();
  return s;
}

}  // namespace

QualityReport computeQuality(const Mesh& m) {
  QualityReport q;
  q.points = m.points.size();
  q.triangles = m.triangles.size();
  q.tets = m.tets.size();
  q.bounds = m.bounds();
  std::map<int, LabelStats> labels;
  double edgeSum = 0;
  std::size_t edgeCount = 0;
  if (m.isVolume()) {
    q.minDihedralDeg = 180;
    for (std::size_t i = 0; i < m.tets.size(); ++i) {
      Eigen::Vector3d p[4];
      for (int k = 0; k < 4; ++k) p[k] = m.points[m.tets[i][k]] * m.unitToMetre;
      auto s = tetShape(p);
      q.volume += s.volume;
      q.minDihedralDeg = std::min(q.minDihedralDeg, s.minDihedral);
      q.maxDihedralDeg = std::max(q.maxDihedralDeg, s.maxDihedral);
      q.worstAspectRatio = std::max(q.worstAspectRatio, s.aspect);
      edgeSum += s.edgeSum;
      edgeCount += 6;
      if (std::abs(s.volume) <= 1e-12 * s.maxEdge * s.maxEdge * s.maxEdge) ++q.degenerate;
      else if (s.volume < 0) ++q.inverted;
      auto& l = labels[m.tetLabels.empty() ? 0 : m.tetLabels[i]];
      l.count++;
      l.volume += s.volume;
    }
  } else {
    // Edge manifoldness and the enclosed volume (divergence theorem).
    std::map<std::pair<int, int>, int> edgeUse;
    for (std::size_t i = 0; i < m.triangles.size(); ++i) {
      const auto& t = m.triangles[i];
      Eigen::Vector3d a = m.points[t[0]] * m.unitToMetre, b = m.points[t[1]] * m.unitToMetre,
                      c = m.points[t[2]] * m.unitToMetre;
      q.volume += a.dot(b.cross(c)) / 6.0;
      double area = 0.5 * (b - a).cross(c - a).norm();
      double maxE = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
      if (area <= 1e-12 * maxE * maxE) ++q.degenerate;
      edgeSum += (b - a).norm() + (c - b).norm() + (a - c).norm();
      edgeCount += 3;
      for (int k = 0; k < 3; ++k) {
        int u = t[k], v = t[(k + 1) % 3];
        edgeUse[{std::min(u, v), std::max(u, v)}]++;
      }
      auto& l = labels[m.triangleLabels.empty() ? 0 : m.triangleLabels[i]];
      l.count++;
      l.volume += area;
    }
    for (const auto& [e, n] : edgeUse) {
      if (n == 1) ++q.borderEdges;
      if (n > 2) ++q.nonManifoldEdges;
    }
    q.closed = !m.triangles.empty() && q.borderEdges == 0 && q.nonManifoldEdges == 0;
    q.volume = std::abs(q.volume);
  }
  q.meanEdge = edgeCount ? edgeSum / edgeCount : 0;
  for (auto& [label, s] : labels) {
    s.label = label;
    s.name = m.labelName(label);
    q.labels.push_back(s);
  }
  if (!q.bounds.isEmpty() && m.unitToMetre != 1.0)
    q.bounds = Eigen::AlignedBox3d(q.bounds.min() * m.unitToMetre, q.bounds.max() * m.unitToMetre);
  return q;
}

std::string formatQuality(const QualityReport& q) {
  char buf[512];
  std::string out;
  // A volume's boundary is listed by whoever extracts it; a volume file's own triangles only when it has some.
  if (q.tets && !q.triangles)
    std::snprintf(buf, sizeof buf, "points: %zu\ntetrahedra: %zu\n", q.points, q.tets);
  else if (!q.tets)
    std::snprintf(buf, sizeof buf, "points: %zu\ntriangles: %zu\n", q.points, q.triangles);
  else
    std::snprintf(buf, sizeof buf, "points: %zu\ntriangles: %zu\ntetrahedra: %zu\n", q.points, q.triangles, q.tets);
  out += buf;
  if (!q.bounds.isEmpty()) {
    Eigen::Vector3d a = q.bounds.min() * 1e3, b = q.bounds.max() * 1e3, s = b - a;
    // Three short lines: they fit the case panel without scrolling sideways.
    std::snprintf(buf, sizeof buf, "bounds (mm): %.2f x %.2f x %.2f\n  from [%.2f, %.2f, %.2f]\n  to   [%.2f, %.2f, %.2f]\n",
                  s.x(), s.y(), s.z(), a.x(), a.y(), a.z(), b.x(), b.y(), b.z());
    out += buf;
  }
  std::snprintf(buf, sizeof buf, "volume: %.3f cm^3\nmean edge: %.3f mm\n", q.volume * 1e6, q.meanEdge * 1e3);
  out += buf;
  if (q.tets) {
    std::snprintf(buf, sizeof buf,
                  "min dihedral angle: %.2f deg\nmax dihedral angle: %.2f deg\nworst aspect ratio: %.3g\n"
                  "inverted tetrahedra: %zu\ndegenerate tetrahedra: %zu\n",
                  q.minDihedralDeg, q.maxDihedralDeg, q.worstAspectRatio, q.inverted, q.degenerate);
    out += buf;
  } else {
    std::snprintf(buf, sizeof buf, "closed: %s\nborder edges: %zu\nnon-manifold edges: %zu\ndegenerate triangles: %zu\n",
                  q.closed ? "yes" : "no", q.borderEdges, q.nonManifoldEdges, q.degenerate);
    out += buf;
    if (q.selfIntersections >= 0) {
      std::snprintf(buf, sizeof buf, "self-intersecting triangle pairs: %ld\n", q.selfIntersections);
      out += buf;
    }
  }
  out += "labels: " + std::to_string(q.labels.size()) + "\n";
  for (const auto& l : q.labels) {
    if (q.tets)
      std::snprintf(buf, sizeof buf, "  label %d%s%s: %zu elements, %.3f cm^3\n", l.label, l.name.empty() ? "" : " ",
                    l.name.c_str(), l.count, l.volume * 1e6);
    else
      std::snprintf(buf, sizeof buf, "  part %d%s%s: %zu triangles, %.2f cm^2\n", l.label, l.name.empty() ? "" : " ",
                    l.name.c_str(), l.count, l.volume * 1e4);
    out += buf;
  }
  return out;
}

std::vector<std::string> repairVolume(Mesh& m) {
  std::vector<std::string> notes;
  if (!m.isVolume()) return notes;
  std::size_t inverted = 0, degenerate = 0;
  std::vector<char> isDegenerate(m.tets.size(), 0);
  for (std::size_t i = 0; i < m.tets.size(); ++i) {
    const auto& t = m.tets[i];
    Eigen::Vector3d p[4];
    for (int k = 0; k < 4; ++k) p[k] = m.points[t[k]];
    double maxE = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) maxE = std::max(maxE, (p[a] - p[b]).norm());
    double v = tetVolume(p[0], p[1], p[2], p[3]);
    if (std::abs(v) <= 1e-12 * maxE * maxE * maxE) {
      isDegenerate[i] = 1;
      ++degenerate;
    } else if (v < 0) {
      ++inverted;
    }
  }
  if (inverted) {
    for (std::size_t i = 0; i < m.tets.size(); ++i) {
      auto& t = m.tets[i];
      if (!isDegenerate[i] && tetVolume(m.points[t[0]], m.points[t[1]], m.points[t[2]], m.points[t[3]]) < 0)
        std::swap(t[2], t[3]);
    }
    if (inverted == m.tets.size() - degenerate)
      notes.push_back("All tetrahedra were numbered clockwise; they were renumbered counter-clockwise.");
    else
      notes.push_back(std::to_string(inverted) + " of " + std::to_string(m.tets.size()) +
                      " tetrahedra were inverted and have been flipped; check the mesh if that is unexpected.");
  }
  if (degenerate) {
    std::size_t w = 0;
    for (std::size_t i = 0; i < m.tets.size(); ++i)
      if (!isDegenerate[i]) {
        m.tets[w] = m.tets[i];
        m.tetLabels[w] = m.tetLabels[i];
        ++w;
      }
    m.tets.resize(w);
    m.tetLabels.resize(w);
    notes.push_back(std::to_string(degenerate) + " degenerate (flat) tetrahedra were removed.");
  }
  return notes;
}

}  // namespace rehearse::simcore
