// Contact alone (issue 33: its own files, tested against brute force): the point hierarchy finds exactly the points
// within a distance of a segment (every point checked), after a refit to moved points too; the closest points of a
// segment and a triangle match a dense sampling of both; shaftContact makes one row per triangle near the shaft
// (triangles checked one by one), skips the held and let-go nodes' triangles, and every row it makes pushes the
// surface away from the shaft's axis.
#include "box_mesh.hpp"

#include <rehearse/simcore/session/contact.hpp>

#include <QtTest>

#include <random>
#include <set>

using namespace rehearse::simcore;

namespace {
double segmentDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double t = d.squaredNorm() > 0 ? std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
  return (p - (a + t * d)).norm();
}
}  // namespace

class TestContact : public QObject {
  Q_OBJECT
 private slots:
  void hierarchyFindsWhatBruteForceFinds() {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    const int n = 3000;
    Eigen::VectorXd x(3 * n);
    for (int i = 0; i < 3 * n; ++i) x[i] = u(rng);
    std::vector<int> ids;
    for (int i = 0; i < n; i += 2) ids.push_back(i);  // a subset, as the surface nodes are of all nodes
    PointBvh bvh;
    bvh.build(ids, x);
    int checked = 0, found = 0;
    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 1) {  // the points move; the hierarchy is refitted, not rebuilt
        for (int i = 0; i < 3 * n; ++i) x[i] += 0.3 * u(rng);
        bvh.refit(x);
      }
      for (int q = 0; q < 200; ++q) {
        const Eigen::Vector3d a(u(rng), u(rng), u(rng)), b = q % 5 == 0 ? a : Eigen::Vector3d(u(rng), u(rng), u(rng));
        const double r = 0.02 + 0.2 * std::abs(u(rng));
        std::vector<int> got;
        bvh.query(a, b, r, x, got);
        std::set<int> expect;
        for (int i : ids)
          if (segmentDistance(x.segment<3>(3 * i), a, b) < r) expect.insert(i);
        QCOMPARE(std::set<int>(got.begin(), got.end()), expect);
        QCOMPARE(got.size(), expect.size());  // no point twice
        ++checked;
        found += static_cast<int>(got.size());
      }
    }
    qInfo("%d queries, %d points found, all as brute force", checked, found);
  }

  void closestPointsMatchSampling() {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1, 1);
    int pierced = 0;
    for (int k = 0; k < 300; ++k) {
      const Eigen::Vector3d s0(u(rng), u(rng), u(rng)), s1(u(rng), u(rng), u(rng)), a(u(rng), u(rng), u(rng)),
          b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
      Eigen::Vector3d onAxis, onTriangle, w;
      if (!closestAxisTriangle(s0, s1, a, b, c, onAxis, onTriangle, w)) {
        ++pierced;
        continue;
      }
      // Dense sampling: 400 points on the segment, a 60 x 60 barycentric grid on the triangle.
      double best = 1e9;
      for (int i = 0; i <= 400; ++i) {
        const Eigen::Vector3d p = s0 + (i / 400.0) * (s1 - s0);
        for (int j = 0; j <= 60; ++j)
          for (int l = 0; j + l <= 60; ++l)
            best = std::min(best, (p - (a + (j / 60.0) * (b - a) + (l / 60.0) * (c - a))).norm());
      }
      const double d = (onAxis - onTriangle).norm();
      QVERIFY2(d <= best + 1e-12, qPrintable(QString("%1 > sampled %2").arg(d).arg(best)));
      QVERIFY(best - d < 0.03);  // the sampling's resolution (about 2 % of the sizes)
      QVERIFY((w[0] * a + w[1] * b + w[2] * c - onTriangle).norm() < 1e-12);
      QVERIFY(std::abs(w.sum() - 1) < 1e-12 && w.minCoeff() >= -1e-12);
      QVERIFY(segmentDistance(onAxis, s0, s1) < 1e-12);
    }
    qInfo("300 segment-triangle pairs: %d pierced, the rest within the sampling's resolution and never further",
          pierced);
    QVERIFY(pierced > 0 && pierced < 150);
  }

  // A 40 x 20 x 20 mm block's surface and a vertical shaft of 3 mm radius pressing 1 mm into the middle of its top
  // face (z = 20 mm): the rows are exactly the distinct closest points of the triangles within 1.5 radii of the axis,
  // each pushing its point away from the axis; the held node's triangles and a let-go node's are skipped.
  void shaftRowsAgainstBruteForce() {
    Mesh m = boxMesh(0.04, 0.02, 0.02, 8, 4, 4);
    const ContactSurface surface = contactSurface(m.points, m.tets);
    Eigen::VectorXd x(3 * static_cast<Eigen::Index>(m.points.size()));
    for (std::size_t i = 0; i < m.points.size(); ++i) x.segment<3>(3 * static_cast<Eigen::Index>(i)) = m.points[i];
    const std::vector<char> fixed(m.points.size(), 0);
    const double r = 0.003;
    const Eigen::Vector3d tip(0.021, 0.011, 0.019), trocar(0.021, 0.011, 0.2);
    auto run = [&](const std::vector<int>& held, std::vector<int> released, std::vector<ScalarConstraint>& rows) {
      PointBvh bvh;
      bvh.build(surface.nodes, x);
      std::vector<std::pair<int, double>> easing;
      return shaftContact(surface, bvh, x, fixed, tip, trocar, r, 0.0, held, released, easing, false, rows);
    };
    std::vector<ScalarConstraint> rows;
    const ShaftContactStats s = run({}, {}, rows);
    // Brute force: every surface triangle, its closest points to the axis; distinct (node, weight) keys within reach.
    std::set<std::vector<std::pair<int, double>>> keys;
    for (const auto& t : surface.triangles) {
      Eigen::Vector3d onAxis, onTriangle, w;
      if (!closestAxisTriangle(tip, trocar, m.points[t[0]], m.points[t[1]], m.points[t[2]], onAxis, onTriangle, w))
        continue;
      const double d = (onTriangle - onAxis).norm();
      if (d > 1.5 * r) continue;
      std::vector<std::pair<int, double>> key;
      for (int q = 0; q < 3; ++q)
        if (w[q] > 1e-12) key.emplace_back(t[q], w[q]);
      std::sort(key.begin(), key.end());
      keys.insert(key);
    }
    qInfo("%d rows (%d touching, %d pierced); brute force: %zu distinct closest points within reach", s.rows,
          s.contacts, s.pierced, keys.size());
    QCOMPARE(static_cast<std::size_t>(s.rows), keys.size());
    QCOMPARE(rows.size(), keys.size());
    QVERIFY(s.contacts > 0);
    for (const auto& c : rows) {
      QVERIFY(c.unilateral);
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (int q = 0; q < 4; ++q)
        if (c.nodes[q] >= 0) p += c.weights[q] * m.points[static_cast<std::size_t>(c.nodes[q])];
      // The direction points from the axis to the point (away from the shaft), the value is the radius out.
      const Eigen::Vector3d axisPoint =
          tip + std::clamp((p - tip).dot(trocar - tip) / (trocar - tip).squaredNorm(), 0.0, 1.0) * (trocar - tip);
      QVERIFY(c.direction.dot(p - axisPoint) >= -1e-12);
      QVERIFY(std::abs(c.value - (c.direction.dot(p) + (r - c.direction.dot(p - axisPoint)))) < 1e-9);
    }
    // The node nearest the tip held: its triangles give no row; let go (and inside the shaft), the same; out of the
    // shaft, a let-go node is dropped from the list.
    int nearest = surface.nodes.front();
    for (int i : surface.nodes)
      if ((m.points[i] - tip).norm() < (m.points[nearest] - tip).norm()) nearest = i;
    auto touchesNearest = [&](const std::vector<ScalarConstraint>& rs) {
      for (const auto& c : rs)
        for (int q = 0; q < 4; ++q)
          if (c.nodes[q] >= 0)
            for (int k = surface.first[nearest]; k < surface.first[nearest + 1]; ++k) {
              const auto& t = surface.triangles[surface.ofNode[k]];
              if (std::find(t.begin(), t.end(), c.nodes[q]) != t.end() && std::count(t.begin(), t.end(), nearest))
                return true;
            }
      return false;
    };
    QVERIFY(touchesNearest(rows));
    std::vector<ScalarConstraint> heldRows, releasedRows;
    run({nearest}, {}, heldRows);
    std::vector<int> released{nearest};
    {
      PointBvh bvh;
      bvh.build(surface.nodes, x);
      std::vector<std::pair<int, double>> easing;
      shaftContact(surface, bvh, x, fixed, tip, trocar, r, 0.0, {}, released, easing, false, releasedRows);
    }
    QVERIFY(heldRows.size() < rows.size());
    QCOMPARE(releasedRows.size(), heldRows.size());
    QCOMPARE(released, std::vector<int>{nearest});  // still inside the shaft: still let go
    std::vector<int> far{surface.nodes.front()};
    QVERIFY(segmentDistance(m.points[far[0]], tip, trocar) >= r);
    {
      PointBvh bvh;
      bvh.build(surface.nodes, x);
      std::vector<std::pair<int, double>> easing;
      std::vector<ScalarConstraint> unused;
      shaftContact(surface, bvh, x, fixed, tip, trocar, r, 0.0, {}, far, easing, false, unused);
    }
    QVERIFY(far.empty());
  }
};

QTEST_GUILESS_MAIN(TestContact)
#include "test_contact.moc"
