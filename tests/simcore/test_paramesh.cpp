// The parameterized mesh (issue 37): the geometry image of real organ surfaces (../shared/data, meshed as the
// simulation meshes them) reconstructs the surface within 1 % of its size (CGAL's symmetric Hausdorff distance against
// the original triangles), an icosphere's samples lie on the sphere; Hertz's force against the formula worked by hand
// and its exponent 3/2 from two depths; the Gaussian FFD's controls (the nearest vertex follows the tip, the weight at
// the radius, nothing past it, the largest displacement); the tangential spring and its slip at Coulomb's cone; the
// nearest-vertex walk against a full search along a tool's path; refusals (a hole, two pieces, a handle, nothing).
#include "icosphere.hpp"
#include "realorgan.hpp"
#include "test_support.hpp"

#include <rehearse/simcore/paramesh.hpp>
#include <rehearse/simcore/session/forceloop.hpp>

#include <QtTest>

#include <chrono>
#include <cmath>
#include <random>
#include <thread>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

struct Surface {
  std::vector<Eigen::Vector3d> points;
  std::vector<std::array<int, 3>> triangles;
  double size = 0;  ///< m: the bounding box's diagonal
};

// The organ's surface as its file has it (metres).
Surface organSurface(const std::string& rel) {
  const Mesh m = testing::loadOrganSurface(sharedData(rel));
  Surface s;
  s.points = m.points;
  s.triangles = m.triangles;
  return s;
}

Surface sphere(int subdivisions) {
  Mesh m;
  addIcosphere(m, Eigen::Vector3d::Zero(), 0.05, subdivisions, 1);
  return {m.points, m.triangles, 0.1 * std::sqrt(3.0)};
}

}  // namespace

class TestParamesh : public QObject {
  Q_OBJECT
  std::optional<GeometryImage> sphere_;  ///< the icosphere's image (r = 50 mm, 4 subdivisions), made by the first test
  const GeometryImage* sphereImage() {
    if (!sphere_) {
      const Surface s = sphere(4);
      std::string why;
      sphere_ = makeGeometryImage(s.points, s.triangles, {}, why);
    }
    return sphere_ ? &*sphere_ : nullptr;
  }

 private slots:
  void geometryImageOfASphere() {
    const Surface s = sphere(4);
    std::string why;
    const auto gi = makeGeometryImage(s.points, s.triangles, {}, why);
    sphere_ = gi;
    QVERIFY2(gi, why.c_str());
    QCOMPARE(gi->size, 81);
    QCOMPARE(gi->points.size(), std::size_t(81 * 81));
    QCOMPARE(gi->unplaced, 0);
    // Every sample on a triangle of the icosphere: inside the sphere by at most the chord's sagitta (r (1 - cos(a/2)),
    // a the largest edge's angle; 4 subdivisions: edges of about 0.063 rad), never outside it; normals outward.
    double maxEdge = 0;
    for (const auto& t : s.triangles)
      for (int k = 0; k < 3; ++k)
        maxEdge = std::max(maxEdge, (s.points[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])] -
                                     s.points[static_cast<std::size_t>(t[static_cast<std::size_t>((k + 1) % 3)])])
                                        .norm());
    const double angle = 2 * std::asin(maxEdge / 0.1), sagitta = 0.05 * (1 - std::cos(angle / 2)) * 1.5;
    for (std::size_t k = 0; k < gi->points.size(); ++k) {
      const double r = gi->points[k].norm();
      QVERIFY2(r <= 0.05 + 1e-12 && r >= 0.05 - sagitta, qPrintable(QString("radius %1 mm").arg(1e3 * r, 0, 'f', 4)));
      QVERIFY(gi->normals[k].dot(gi->points[k].normalized()) > 0.95);
    }
    // The grid's cells outward, and the reconstruction's Hausdorff distance within 1 % of the size.
    const auto tris = gi->triangles();
    QCOMPARE(tris.size(), std::size_t(2 * 80 * 80));
    int outward = 0;
    for (const auto& t : tris) {
      const Eigen::Vector3d a = gi->points[static_cast<std::size_t>(t[0])],
                            b = gi->points[static_cast<std::size_t>(t[1])],
                            c = gi->points[static_cast<std::size_t>(t[2])];
      const Eigen::Vector3d n = (b - a).cross(c - a);
      if (n.norm() < 1e-14) continue;  // (the seam's ends squeeze a few cells to nothing)
      outward += n.dot(a + b + c) > 0;
    }
    QVERIFY2(outward > 0.98 * static_cast<double>(tris.size()), qPrintable(QString::number(outward)));
    const double h = surfaceHausdorff(s.points, s.triangles, gi->points, tris);
    qInfo(
        "icosphere r = 50 mm, %zu triangles: 81 x 81 geometry image, seam of %d edges, Hausdorff %.3f mm (%.3f %% of "
        "the size)",
        s.triangles.size(), gi->seamEdges, 1e3 * h, 100 * h / s.size);
    QVERIFY(h >= 0 && h < 0.01 * s.size);
  }

  void geometryImageOfRealOrgans() {
    // The acceptance is 1 % of the organ's size. The paper's 81 x 81 reaches it on BodyParts3D's liver and kidney; the
    // grid grows (121, 161) where it does not: the patient liver and scikit-surgery's kidney reach it at 121 x 121 with
    // the stretch-minimising map (without it: 0.86 % at 161 and 1.86 % at 161, 48 vertices of one small pocket of the
    // kidney 2.2-2.5 mm from every grid point).
    struct Organ {
      const char* name;
      const char* file;
      double bound;  ///< share of the size
    };
    int done = 0;
    std::string over;  // the organs whose reconstruction is farther than their bound
    for (const Organ o : {Organ{"patient liver", "scikit-surgery/patient-liver/liver.vtk", 0.01},
                          Organ{"BodyParts3D liver", "bodyparts3d/FMA7197_Liver.obj", 0.01},
                          Organ{"BodyParts3D kidney", "bodyparts3d/FMA7205_Left_Kidney.obj", 0.01},
                          Organ{"scikit-surgery kidney", "scikit-surgery/kidney/kidney.vtk", 0.01}}) {
      REQUIRE_SHARED(std::string(o.file));
      const Surface s = organSurface(o.file);
      for (const SurfaceMap map : {SurfaceMap::Best}) {
        GeometryImageSettings settings;
        settings.map = map;
        std::string why;
        const auto a = std::chrono::steady_clock::now();
        const auto gi = makeGeometryImage(s.points, s.triangles, settings, why);
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
        QVERIFY2(gi, (std::string(o.name) + ": " + why).c_str());
        // Against the organ (the file's largest piece; its other pieces and the holes closed are counted).
        Eigen::AlignedBox3d box;
        for (const auto& p : gi->sourcePoints) box.extend(p);
        const double size = box.diagonal().norm();
        const double h = surfaceHausdorff(gi->sourcePoints, gi->sourceTriangles, gi->points, gi->triangles());
        qInfo(
            "%s (%zu of the file's %zu triangles, %d other piece(s), %d hole(s) closed, %.0f mm across), %s: %d x %d "
            "in %.2f s, seam %d edges, %d samples placed on the nearest triangle; Hausdorff %.2f mm = %.2f %% of its "
            "size (%.2f %% by the image's own measure); L2 stretch %.2f -> %.2f in %d round(s)",
            o.name, gi->sourceTriangles.size(), s.triangles.size(), gi->droppedPieces, gi->filledHoles, 1e3 * size,
            surfaceMapName(gi->map), gi->size, gi->size, seconds, gi->seamEdges, gi->unplaced, 1e3 * h, 100 * h / size,
            100 * gi->hausdorff / gi->extent, gi->stretchBefore, gi->stretchAfter, gi->stretchRounds);
        // It grows only while it is farther than 1 % (by its own measure), and never past 161.
        QVERIFY(gi->size == 81 || gi->size == 121 || gi->size == 161);
        if (gi->size > 81) QVERIFY(gi->hausdorff <= 0.01 * gi->extent || gi->size == 161);
        QVERIFY(gi->sourceTriangles.size() > s.triangles.size() / 2);  // the organ, not a stray piece
        // The stretch-minimising map, when chosen, lowered the mean-value map's L2 stretch (1 would keep every area and
        // angle) in at least one round.
        if (gi->map == SurfaceMap::Stretch)
          QVERIFY2(
              gi->stretchRounds >= 1 && gi->stretchAfter < gi->stretchBefore && gi->stretchAfter >= 1,
              qPrintable(
                  QString("%1 rounds, %2 -> %3").arg(gi->stretchRounds).arg(gi->stretchBefore).arg(gi->stretchAfter)));
        if (!(h >= 0 && h < o.bound * size)) over += std::string(o.name) + " ";
      }
      ++done;
    }
    QCOMPARE(done, 4);
    QVERIFY2(over.empty(), ("over their bound: " + over).c_str());
  }

  void hertzForceMatchesItsFormula() {
    // Worked by hand: r = 5 mm, E = 4 kPa, nu = 0.45: E* = 4000 / 0.7975 = 5015.674 Pa; d = 4 mm: d^1.5 =
    // 2.529822e-4, sqrt(r) = 0.07071068, F = 4/3 * 0.07071068 * 5015.674 * 2.529822e-4 = 0.1196308 N.
    QVERIFY(std::abs(rigidToolModulus(4000, 0.45) - 5015.6740) < 1e-3);
    QVERIFY(std::abs(hertzForce(0.005, 5015.674, 0.004) - 0.1196308) < 1e-6);
    QCOMPARE(hertzForce(0.005, 5015.674, 0), 0.0);
    QCOMPARE(hertzForce(0.005, 5015.674, -0.001), 0.0);
    // Its exponent from two depths: log(F2 / F1) / log(d2 / d1) = 3/2; and sqrt(r) from two radii.
    QVERIFY(std::abs(std::log(hertzForce(0.005, 5000, 0.006) / hertzForce(0.005, 5000, 0.002)) / std::log(3.0) - 1.5) <
            1e-12);
    QVERIFY(std::abs(hertzForce(0.008, 5000, 0.003) / hertzForce(0.002, 5000, 0.003) - 2.0) < 1e-12);

    // On the model: the tip pressed 4 mm along the inward normal at a vertex of the sphere's image.
    const GeometryImage* gi = sphereImage();  // (made once: its own test checks it)
    QVERIFY(gi);
    FfdSettings fs;
    fs.radius = 0.02;
    fs.maxDisplacement = 0.01;
    ParameterizedMesh pm(*gi, fs);
    const int v = gi->index(40, 40);
    const Eigen::Vector3d p = gi->points[static_cast<std::size_t>(v)], n = gi->normals[static_cast<std::size_t>(v)];
    const auto c = pm.poke(p - 0.004 * n);
    QVERIFY(c.touching);
    QCOMPARE(c.vertex, v);
    QVERIFY(std::abs(c.depth - 0.004) < 1e-12);
    QVERIFY(std::abs(c.normalForce - 0.1196308) < 1e-6);
    QVERIFY((c.force - c.normalForce * n).norm() < 1e-12);  // no tangential force on a straight poke
    // The nearest vertex follows the tip; the weight at the radius 1.1 % (exp(-4.5)); nothing moves past it.
    QVERIFY((pm.positions()[static_cast<std::size_t>(v)] - (p - 0.004 * n)).norm() < 1e-12);
    QVERIFY(std::abs(pm.weight(0.02) - std::exp(-4.5)) < 1e-15);
    QCOMPARE(pm.weight(0.0201), 0.0);
    int moved = 0, pastRadius = 0;
    for (std::size_t k = 0; k < gi->points.size(); ++k) {
      const double shift = (pm.positions()[k] - gi->points[k]).norm(), r = (gi->points[k] - p).norm();
      if (shift > 0) ++moved;
      if (r > fs.radius)
        pastRadius += shift > 0;
      else  // (on a sphere every vertex within the radius is joined to the tool's on the grid)
        QVERIFY(std::abs(shift - 0.004 * pm.weight(r)) < 1e-12);
    }
    QCOMPARE(pastRadius, 0);
    // As many as lie within the radius: the cap's area 2 pi R h (h = r^2 / 2R) over a grid cell's (the sphere's over 80
    // x 80), within the grid's unevenness.
    const double cells = 2 * M_PI * 0.05 * (0.02 * 0.02 / 0.1) / (4 * M_PI * 0.05 * 0.05 / (80.0 * 80.0));
    qInfo("the FFD moved %d vertices within 20 mm (the cap holds %.0f cells' area)", moved, cells);
    QVERIFY(moved > 0.3 * cells && moved < 3 * cells);
    // Deeper than the largest displacement: the surface stops there, and the force is the force at that depth.
    const auto deep = pm.poke(p - 0.015 * n);
    QVERIFY(deep.clamped);
    QVERIFY(std::abs((pm.positions()[static_cast<std::size_t>(v)] - p).norm() - 0.01) < 1e-12);
    QVERIFY(std::abs(deep.normalForce - hertzForce(0.005, rigidToolModulus(fs.youngModulus, fs.poisson), 0.01)) <
            1e-12);
    // Above the surface: at rest, nothing touches.
    const auto above = pm.poke(p + 0.002 * n);
    QVERIFY(!above.touching);
    for (std::size_t k = 0; k < gi->points.size(); ++k) QCOMPARE(pm.positions()[k], gi->points[k]);
  }

  void theForceLoopRendersHertzsForce() {
    // The loop's own model: each tick the FFD at the device's position, the hand given the tissue's force on the tool.
    const GeometryImage* gi = sphereImage();  // (made once: its own test checks it)
    QVERIFY(gi);
    ParameterizedMesh pm(*gi, {});
    const int v = gi->index(40, 40);
    const Eigen::Vector3d p = gi->points[static_cast<std::size_t>(v)], n = gi->normals[static_cast<std::size_t>(v)];
    VirtualDevice device;
    ForceLoop loop([&pm](const Eigen::Vector3d& tip) { return Eigen::Vector3d(-pm.poke(tip).force); }, &device);
    device.setPosition(p - 0.004 * n);
    const Eigen::Vector3d onTissue = loop.tick();
    QVERIFY((onTissue + 0.1196308 * n).norm() < 1e-6);  // the formula worked by hand above, into the organ
    QVERIFY((device.rendered() - 0.1196308 * n).norm() < 1e-6);
    device.setPosition(p + 0.003 * n);  // off the surface
    QCOMPARE(loop.tick(), Eigen::Vector3d(Eigen::Vector3d::Zero()));
    // On its thread for 0.3 s: the ticks run and each renders the force at the device's position.
    device.setPosition(p - 0.002 * n);
    loop.start();
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    loop.stop();
    QVERIFY(loop.timing().ticks > 100);
    QVERIFY((device.rendered() - hertzForce(0.005, rigidToolModulus(4000, 0.45), 0.002) * n).norm() < 1e-9);
  }

  void tangentialSpringSlipsAtTheCone() {
    const GeometryImage* gi = sphereImage();  // (made once: its own test checks it)
    QVERIFY(gi);
    FfdSettings fs;
    fs.tangentialStiffness = 100;
    fs.friction = 0.4;
    ParameterizedMesh pm(*gi, fs);
    const int v = gi->index(40, 40);
    const Eigen::Vector3d p = gi->points[static_cast<std::size_t>(v)], n = gi->normals[static_cast<std::size_t>(v)];
    const Eigen::Vector3d t = n.unitOrthogonal();
    pm.poke(p - 0.005 * n);  // the contact begins: its anchor
    // 0.1 mm sideways (within the same vertex's reach): F_t = k d_t against the motion, below the cone (0.4 F_n).
    const auto c = pm.poke(p - 0.005 * n + 1e-4 * t);
    QCOMPARE(c.vertex, v);
    const Eigen::Vector3d ft = c.force - c.normalForce * c.normal;
    const Eigen::Vector3d onSurface = p - 0.005 * n + 1e-4 * t + c.depth * n;
    Eigen::Vector3d dt = onSurface - (p + 0.0 * n);
    dt -= dt.dot(n) * n;
    QVERIFY2((ft + 100 * dt).norm() < 1e-9, qPrintable(QString::number((ft + 100 * dt).norm())));
    QVERIFY(ft.norm() < 0.4 * c.normalForce);
    // 1 mm sideways: past the cone, it slides: |F_t| = mu F_n exactly, against the motion.
    const auto slid = pm.poke(p - 0.005 * n + 1e-3 * t);
    const Eigen::Vector3d fs2 = slid.force - slid.normalForce * slid.normal;
    QVERIFY(std::abs(fs2.norm() - 0.4 * slid.normalForce) < 1e-12);
    QVERIFY(fs2.dot(t) < 0);
  }

  void theWalkFindsTheNearestVertex() {
    REQUIRE_SHARED(std::string("bodyparts3d/FMA7205_Left_Kidney.obj"));
    const Surface s = organSurface("bodyparts3d/FMA7205_Left_Kidney.obj");
    std::string why;
    auto gi = makeGeometryImage(s.points, s.triangles, {}, why);
    QVERIFY2(gi, why.c_str());
    ParameterizedMesh pm(*gi, {});
    // A tool moving over the surface (a point 2 mm outside it, 1 mm a haptic update, across the seam too).
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> pick(0, gi->size * gi->size - 1);
    Eigen::Vector3d at = gi->points[static_cast<std::size_t>(pick(rng))];
    int agree = 0, total = 0;
    for (int leg = 0; leg < 20; ++leg) {
      const Eigen::Vector3d to = gi->points[static_cast<std::size_t>(pick(rng))];
      const int steps = std::max(1, static_cast<int>((to - at).norm() / 0.001));
      for (int k = 1; k <= steps; ++k) {
        const Eigen::Vector3d q = at + (to - at) * (static_cast<double>(k) / steps);
        const int walked = pm.nearestVertex(q);
        int best = 0;
        for (int w = 1; w < gi->size * gi->size; ++w)
          if ((gi->points[static_cast<std::size_t>(w)] - q).squaredNorm() <
              (gi->points[static_cast<std::size_t>(best)] - q).squaredNorm())
            best = w;
        // The same distance (grid points on the seam coincide in space: either is the nearest).
        agree += std::abs((gi->points[static_cast<std::size_t>(walked)] - q).norm() -
                          (gi->points[static_cast<std::size_t>(best)] - q).norm()) < 1e-12;
        ++total;
      }
      at = to;
    }
    qInfo("nearest-vertex walk: %d of %d updates found the nearest vertex", agree, total);
    QVERIFY(total > 500);
    QVERIFY2(agree >= 0.99 * total, qPrintable(QString("%1 of %2").arg(agree).arg(total)));
  }

  void refusals() {
    std::string why;
    Surface s = sphere(2);
    Surface holed = s;
    holed.triangles.pop_back();
    QVERIFY(!makeGeometryImage(holed.points, holed.triangles, {}, why));
    QVERIFY2(QString::fromStdString(why).contains("holes"), why.c_str());
    Surface two = s;
    const int offset = static_cast<int>(two.points.size());
    for (const auto& p : s.points) two.points.push_back(p + Eigen::Vector3d(1, 0, 0));
    for (const auto& t : s.triangles) two.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    for (int k = offset; k < static_cast<int>(two.points.size()); ++k)  // the second piece the smaller
      two.points[static_cast<std::size_t>(k)] =
          Eigen::Vector3d(1, 0, 0) + 0.5 * (two.points[static_cast<std::size_t>(k)] - Eigen::Vector3d(1, 0, 0));
    const auto largest = makeGeometryImage(two.points, two.triangles, {}, why);  // the largest piece, the other said
    QVERIFY2(largest, why.c_str());
    QCOMPARE(largest->droppedPieces, 1);
    for (const auto& p : largest->points) QVERIFY(p.norm() < 0.0501);
    // A torus (a handle: Euler characteristic 0).
    Surface torus;
    const int U = 24, V = 12;
    for (int i = 0; i < U; ++i)
      for (int j = 0; j < V; ++j) {
        const double a = 2 * M_PI * i / U, b = 2 * M_PI * j / V;
        torus.points.emplace_back((0.05 + 0.02 * std::cos(b)) * std::cos(a), (0.05 + 0.02 * std::cos(b)) * std::sin(a),
                                  0.02 * std::sin(b));
      }
    for (int i = 0; i < U; ++i)
      for (int j = 0; j < V; ++j) {
        const int a = i * V + j, b = ((i + 1) % U) * V + j, c = ((i + 1) % U) * V + (j + 1) % V,
                  d = i * V + (j + 1) % V;
        torus.triangles.push_back({a, b, c});
        torus.triangles.push_back({a, c, d});
      }
    QVERIFY(!makeGeometryImage(torus.points, torus.triangles, {}, why));
    QVERIFY2(QString::fromStdString(why).contains("characteristic 0 (1 handle)"), why.c_str());
    QVERIFY(!makeGeometryImage({}, {}, {}, why));
    QVERIFY(!why.empty());
    GeometryImageSettings tiny;
    tiny.size = 2;
    QVERIFY(!makeGeometryImage(s.points, s.triangles, tiny, why));
    QVERIFY2(QString::fromStdString(why).contains("between 3 and"), why.c_str());
    // An index out of range.
    Surface bad = s;
    bad.triangles[0][1] = 99999;
    QVERIFY(!makeGeometryImage(bad.points, bad.triangles, {}, why));
    QCOMPARE(surfaceHausdorff({}, {}, s.points, s.triangles), -1.0);
  }
};

QTEST_GUILESS_MAIN(TestParamesh)
#include "test_paramesh.moc"
