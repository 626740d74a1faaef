// Tetrahedralisation with CGAL Mesh_3: volumes against analytic values and the surface's own enclosed
// volume, inner parts as labels, progress and cancel, determinism, and refusal of bad surfaces.
#include "test_support.hpp"
#include "icosphere.hpp"

#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <map>
#include <numbers>

using namespace rehearse::simcore;

namespace {

double labelVolume(const Mesh& m, int label) {
  double v = 0;
  for (std::size_t i = 0; i < m.tets.size(); ++i)
    if (m.tetLabels[i] == label) {
      const auto& t = m.tets[i];
      v += tetVolume(m.points[t[0]], m.points[t[1]], m.points[t[2]], m.points[t[3]]);
    }
  return v;
}

}  // namespace

class TestTetrahedralise : public QObject {
  Q_OBJECT
 private slots:
  // Implicit ball: volume of the mesh against 4/3 pi r^3 (the polyhedral approximation is inscribed).
  void implicitBallVolume() {
    const double r = 0.05;
    TetrahedraliseOptions o;
    o.targetTets = 4000;
    auto m = tetrahedraliseImplicit([r](const Eigen::Vector3d& p) { return p.norm() < r ? 1 : 0; },
                                    Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.06), Eigen::Vector3d::Constant(0.06)), o,
                                    4.0 / 3 * std::numbers::pi * r * r * r);
    auto q = computeQuality(m);
    const double exact = 4.0 / 3 * std::numbers::pi * r * r * r;
    qInfo("ball: %zu tets, volume error %.2f %%, min dihedral %.1f deg", m.tets.size(), 100 * (q.volume - exact) / exact, q.minDihedralDeg);
    QVERIFY(std::abs(q.volume - exact) / exact < 0.03);
    QCOMPARE(q.inverted, std::size_t(0));
    QCOMPARE(q.degenerate, std::size_t(0));
    QVERIFY(m.tets.size() > 3200 && m.tets.size() < 4800);  // within 20 % of the target
    for (const auto& p : m.points) QVERIFY(p.norm() < r * 1.001);
  }

  // Nested closed parts: an outer sphere and an inner sphere become labels 1 and 2.
  void innerPartsBecomeLabels() {
    Mesh s;
    addIcosphere(s, {0, 0, 0}, 0.05, 4, 0);
    addIcosphere(s, {0.01, 0, 0}, 0.02, 3, 1);
    s.setLabelName(0, "liver");
    s.setLabelName(1, "tumour");
    TetrahedraliseOptions o;
    o.targetTets = 6000;
    std::vector<std::string> notes;
    auto m = tetrahedraliseSurface(s, o, &notes);
    Mesh onlyOuter, onlyInner;
    addIcosphere(onlyOuter, {0, 0, 0}, 0.05, 4, 0);
    const double outer = computeQuality(onlyOuter).volume;
    addIcosphere(onlyInner, {0.01, 0, 0}, 0.02, 3, 1);
    const double inner = computeQuality(onlyInner).volume;
    const double v1 = labelVolume(m, 1), v2 = labelVolume(m, 2);
    qInfo("labels: parenchyma %.3f cm^3, tumour %.3f cm^3 (expected %.3f)", v1 * 1e6, v2 * 1e6, inner * 1e6);
    QVERIFY(std::abs(v2 - inner) / inner < 0.06);
    QVERIFY(std::abs((v1 + v2) - outer) / outer < 0.03);
    QCOMPARE(QString::fromStdString(m.labelName(2)), QString("tumour"));
    QCOMPARE(QString::fromStdString(m.labelName(1)), QString("liver"));
  }

  // A real liver surface (scikit-surgery) tetrahedralised: volume matches its enclosed volume.
  void realLiverStl() {
    REQUIRE_SHARED("scikit-surgery/liver_downsample.stl");
    auto s = loadMesh(sharedData("scikit-surgery/liver_downsample.stl"), {"mm"});
    const double enclosed = computeQuality(s).volume;
    TetrahedraliseOptions o;
    o.targetTets = 6500;
    int calls = 0;
    double last = -1;
    std::vector<std::string> stages;
    o.progress = [&](double f, const std::string& stage) {
      stages.push_back(stage);
      if (f < 0) return;  // a stage of unknown length: its counts are in the words
      QVERIFY(f >= last);
      last = f;
      ++calls;
    };
    QElapsedTimer timer;
    timer.start();
    auto m = tetrahedraliseSurface(s, o);
    auto q = computeQuality(m);
    qInfo("liver_downsample.stl: %zu tets in %lld ms, volume %.1f cm^3 vs enclosed %.1f cm^3, min dihedral %.1f deg",
          m.tets.size(), timer.elapsed(), q.volume * 1e6, enclosed * 1e6, q.minDihedralDeg);
    QVERIFY(std::abs(q.volume - enclosed) / enclosed < 0.03);
    QCOMPARE(q.inverted, std::size_t(0));
    QVERIFY(m.tets.size() > 6500 * 0.8 && m.tets.size() < 6500 * 1.2);
    QVERIFY(calls >= 2);
    QCOMPARE(last, 1.0);
    // The refinement says how far it got (its query count rising), then the exudation and what it works on.
    long lastQueries = 0;
    int queryReports = 0;
    bool exudation = false;
    for (const auto& st : stages) {
      if (st.find("inside/outside queries") != std::string::npos && st.find("(pass 1)") != std::string::npos) {
        const long k = std::stol(st.substr(st.find("): ") + 3));
        QVERIFY2(k > lastQueries || st.find(" M ") != std::string::npos, st.c_str());
        lastQueries = k;
        ++queryReports;
      }
      exudation |= st.rfind("removing slivers (exudation) from ", 0) == 0;
    }
    qInfo("%d query-count reports in pass 1, last %ld k", queryReports, lastQueries);
    QVERIFY(queryReports >= 3);
    QVERIFY(exudation);
    QVERIFY(s.bounds().exteriorDistance(m.bounds().min()) < 1e-9 && s.bounds().exteriorDistance(m.bounds().max()) < 1e-9);
  }

  void deterministic() {
    Mesh s;
    addIcosphere(s, {0, 0, 0}, 0.03, 3, 0);
    TetrahedraliseOptions o;
    o.targetTets = 800;
    auto a = tetrahedraliseSurface(s, o), b = tetrahedraliseSurface(s, o);
    QCOMPARE(a.points.size(), b.points.size());
    QVERIFY(a.tets == b.tets);
    for (std::size_t i = 0; i < a.points.size(); ++i) QCOMPARE(a.points[i], b.points[i]);
  }

  void cancel() {
    Mesh s;
    addIcosphere(s, {0, 0, 0}, 0.05, 4, 0);
    std::atomic<bool> stop{false};
    TetrahedraliseOptions o;
    o.targetTets = 200000;
    o.cancel = &stop;
    o.progress = [&](double, const std::string& stage) {
      if (stage == "meshing") stop = true;
    };
    QElapsedTimer t;
    t.start();
    QVERIFY_THROWS_EXCEPTION(Cancelled, tetrahedraliseSurface(s, o));
    qInfo("cancelled after %lld ms", t.elapsed());
  }

  void badSurfacesAreRefused() {
    // Open: an icosphere with a cap of triangles removed (a hole too big to close silently).
    Mesh open;
    addIcosphere(open, {0, 0, 0}, 0.05, 3, 0);
    std::vector<std::array<int, 3>> kept;
    for (const auto& t : open.triangles)
      if ((open.points[t[0]] + open.points[t[1]] + open.points[t[2]]).z() < 0.12) kept.push_back(t);
    QVERIFY(kept.size() < open.triangles.size() - 100);
    open.triangles = kept;
    open.triangleLabels.assign(kept.size(), 0);
    try {
      tetrahedraliseSurface(open, {});
      QFAIL("an open surface was meshed");
    } catch (const MeshError& e) {
      QVERIFY2(QString(e.what()).contains("no closed part"), e.what());
    }
    // A small hole is closed, with a note.
    Mesh small;
    addIcosphere(small, {0, 0, 0}, 0.05, 3, 0);
    small.triangles.pop_back();
    small.triangleLabels.pop_back();
    std::vector<std::string> notes;
    TetrahedraliseOptions o;
    o.targetTets = 500;
    auto m = tetrahedraliseSurface(small, o, &notes);
    QVERIFY(!m.tets.empty());
    QVERIFY(!notes.empty() && QString::fromStdString(notes[0]).contains("holes"));
    // Self-intersecting: one vertex pushed through the opposite side.
    Mesh self;
    addIcosphere(self, {0, 0, 0}, 0.05, 2, 0);
    self.points[0] = -1.5 * self.points[0];
    try {
      tetrahedraliseSurface(self, {});
      QFAIL("a self-intersecting surface was meshed");
    } catch (const MeshError& e) {
      QVERIFY2(QString(e.what()).contains("intersects itself"), e.what());
    }
    QVERIFY_THROWS_EXCEPTION(MeshError, tetrahedraliseSurface(Mesh{}, {}));
    TetrahedraliseOptions tiny;
    tiny.targetTets = 3;
    Mesh ball;
    addIcosphere(ball, {0, 0, 0}, 0.05, 2, 0);
    QVERIFY_THROWS_EXCEPTION(MeshError, tetrahedraliseSurface(ball, tiny));
  }
};

QTEST_GUILESS_MAIN(TestTetrahedralise)
#include "test_tetrahedralise.moc"
