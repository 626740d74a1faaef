// Scenes declare their components: only those are built; unknown components and parameters are refused
// by name; the command line runs a scene reproducing SOFA's liver.scn.
#include "test_support.hpp"

#include "box_mesh.hpp"
#include "icosphere.hpp"

#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/scene.hpp>

#include <filesystem>

#include <QProcess>

using namespace rehearse::simcore;
namespace simcore = rehearse::simcore;

namespace {
std::string base(bool withAttachments) {
  std::string s = R"({"components": [
    {"type": "mesh", "file": "sofa/liver.msh"},
    {"type": "material", "model": "corotational", "young": 3000, "poisson": 0.3, "density": 1},)";
  if (withAttachments) s += R"(
    {"type": "attachments", "nodes": [3, 39, 64]},)";
  s += R"(
    {"type": "gravity", "vector": [0, -9.81, 0]},
    {"type": "damping", "rayleigh_mass": 0.1, "rayleigh_stiffness": 0.1},
    {"type": "implicit_euler", "dt": 0.02, "steps": 5}]})";
  return s;
}

// Files of our own (no ../shared/data needed): a 10 x 4 x 4 cm beam of tetrahedra and a sphere surface
// inside it, as an inner structure.
struct Files {
  std::string dir, beam, sphere;
  simcore::Mesh beamMesh;
  Files() {
    dir = tempPath("scene-files");
    std::filesystem::create_directories(dir);
    beam = dir + "/beam.vtu";
    sphere = dir + "/sphere.vtk";
    beamMesh = boxMesh(0.1, 0.04, 0.04, 10, 4, 4);
    saveMesh(beamMesh, beam);
    simcore::Mesh s;
    addIcosphere(s, {0.05, 0.02, 0.02}, 0.012, 2, 1);
    saveMesh(s, sphere);
  }
};

std::string fixedNodesJson(const simcore::Mesh& m) {
  std::string out;
  for (int n : nodesAtX(m, 0.0)) out += (out.empty() ? "" : ", ") + std::to_string(n);
  return "[" + out + "]";
}
}  // namespace

class TestScene : public QObject {
  Q_OBJECT
 private slots:
  // Only what a scene declares is built, shown on what is built (not on a counter of our own): without an
  // embedded surface the model has no mapping and no springs; with projected attachments the integrator
  // holds no constraint (Schur complement) storage, with Lagrange ones it holds H^T, A^-1 H^T (3n x m each)
  // and W (m x m); Rayleigh damping is folded into the Newton matrix, so a scene with it holds no matrix more than
  // one without (only the per-element tangent its matrix-free product uses).
  void onlyDeclaredComponentsAreBuilt() {
    const Files f;
    const std::string fixed = fixedNodesJson(f.beamMesh);
    auto scene = [&](bool embedded, bool lagrange, bool damping) {
      std::string s = R"({"components": [{"type": "mesh", "file": "beam.vtu"},
        {"type": "material", "model": "corotational", "young": 20000, "poisson": 0.3, "density": 1000},
        {"type": "attachments", "nodes": )" + fixed + (lagrange ? R"(, "mode": "lagrange"})" : "}") + R"(,
        {"type": "gravity", "vector": [0, -9.81, 0]},)";
      if (embedded) s += R"({"type": "embedded", "file": "sphere.vtk"},)";
      if (damping) s += R"({"type": "damping", "rayleigh_mass": 0.1, "rayleigh_stiffness": 0.05},)";
      return s + R"({"type": "implicit_euler", "dt": 0.01, "steps": 2}]})";
    };
    struct Built {
      std::vector<std::string> components;
      std::size_t embeddings, springs, modelBytes, integratorBytes;
    };
    auto build = [&](bool embedded, bool lagrange, bool damping) -> Built {
      const Scene sc = parseScene(scene(embedded, lagrange, damping), f.dir);
      const FemModel model = FemModel::build(sc.mesh, sc.materials, sc.defaultMaterial, sc.embedded);
      Integrator integrator(model, sc.fixedNodes, sc.settings);
      auto state = integrator.initialState();
      int ok = 0;
      for (int i = 0; i < 2; ++i) ok += integrator.step(state).ok;
      if (ok != 2) qWarning("a step failed");
      return Built{sc.components, model.embeddings.size(), model.springs.size(), model.memoryBytes(), integrator.memoryBytes()};
    };
    const Built minimal = build(false, false, false);
    QVERIFY(!minimal.components.empty());
    QCOMPARE(minimal.components, std::vector<std::string>({"mesh", "material", "attachments", "gravity", "implicit_euler"}));
    QCOMPARE(minimal.embeddings, std::size_t(0));
    QCOMPARE(minimal.springs, std::size_t(0));
    const Built embedded = build(true, false, false);
    QCOMPARE(embedded.embeddings, std::size_t(1));
    QVERIFY(embedded.springs > 0);
    QVERIFY(embedded.modelBytes > minimal.modelBytes);
    const Built damped = build(false, false, true);
    // No damping matrix: the scenes' default method (chord, the interactive one) applies the stiffness damping
    // matrix-free, from the tangent prepared per element at the step's start; its residual prepares the tangent at
    // each iterate (the next step's start) beside it, and where that was (3n doubles).
    QCOMPARE(damped.integratorBytes, minimal.integratorBytes +
                                         2 * f.beamMesh.tets.size() * (sizeof(Eigen::Matrix3d) + sizeof(TangentCache)) +
                                         3 * f.beamMesh.points.size() * sizeof(double));
    QCOMPARE(damped.modelBytes, minimal.modelBytes);
    const Built lagrange = build(false, true, false);
    const std::size_t n3 = 3 * f.beamMesh.points.size(), m = 3 * nodesAtX(f.beamMesh, 0.0).size();
    const std::size_t schur = sizeof(double) * (2 * n3 * m + m * m);
    qInfo("integrator bytes: projected %zu, with damping %zu, Lagrange %zu (the Schur complement's three matrices: %zu)",
          minimal.integratorBytes, damped.integratorBytes, lagrange.integratorBytes, schur);
    QVERIFY(lagrange.integratorBytes >= minimal.integratorBytes + schur);
    // Without a gravity or damping component there is none.
    const Scene bare = parseScene(R"({"components": [{"type": "mesh", "file": "beam.vtu"}]})", f.dir);
    QCOMPARE(bare.settings.gravity.norm(), 0.0);
    QCOMPARE(bare.settings.rayleighMass, 0.0);
    QCOMPARE(bare.settings.rayleighStiffness, 0.0);
    QCOMPARE(bare.components, std::vector<std::string>({"mesh"}));
    // The corotational law's volume barrier: at its default without the implicit_euler component or the parameter,
    // as the scene says with it (0: off).
    QCOMPARE(bare.settings.volumeBarrier, kVolumeBarrierJ);
    QCOMPARE(parseScene(scene(false, false, false), f.dir).settings.volumeBarrier, kVolumeBarrierJ);
    QCOMPARE(parseScene(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "implicit_euler", "volume_barrier": 0}]})",
                        f.dir).settings.volumeBarrier,
             0.0);
    // With another law: unasked, or asked off, it is accepted (the default stands for whatever law there is).
    QVERIFY(parseScene(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "material", "model": "stvk"},
                                          {"type": "implicit_euler"}]})",
                       f.dir).defaultMaterial.model == MaterialModel::StVK);
    QCOMPARE(parseScene(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "material", "model": "stvk"},
                                           {"type": "implicit_euler", "volume_barrier": 0}]})",
                        f.dir).settings.volumeBarrier,
             0.0);
  }

  // Refused by name, on files of our own: these checks run whether or not ../shared/data is there.
  void badScenesAreRefusedByName() {
    const Files f;
    auto expect = [&](const std::string& json, const char* fragment) {
      try {
        parseScene(json, f.dir);
        QFAIL(qPrintable(QString("accepted: %1").arg(QString::fromStdString(json))));
      } catch (const MeshError& e) {
        QVERIFY2(QString(e.what()).contains(fragment), e.what());
      }
    };
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "haptics"}]})", "unknown component 'haptics'");
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu", "scale": 2}]})", "no parameter 'scale'");
    expect(R"({"components": [{"type": "mesh"}]})", "needs the parameter 'file'");
    expect(R"({"components": [{"type": "gravity"}]})", "no 'mesh'");
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "gravity", "vector": "down"}]})", "wrong kind");
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "solver", "kind": "magic"}]})", "cholmod, cg or dense");
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "solver", "factor": "magic"}]})", "supernodal or simplicial");
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "attachments", "nodes": [0], "mode": "glue"}]})", "projection");
    expect(R"({"components": [{"type": "mesh", "file": "no-such-mesh.vtu"}]})", "no-such-mesh.vtu");
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "implicit_euler", "volume_barrier": 1}]})",
           "volume_barrier");
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "implicit_euler", "volume_barrier": -0.1}]})",
           "volume_barrier");
    // Asked for where no law can honour it (the barrier is the corotational law's): refused, not dropped.
    expect(R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "material", "model": "stvk"},
                              {"type": "implicit_euler", "volume_barrier": 0.3}]})",
           "corotational law only");
    expect(R"({"components": 3})", "components");
    expect("{oops", "not valid JSON");
  }

  // SOFA's liver.scn as a scene, run by the command line; the description lists every component.
  // Issue 34: a scene that names no method runs the interactive default (chord) on CHOLMOD, and exact with the cg and
  // dense solvers (the lagged methods need CHOLMOD: those scenes ran before the default changed, and still do); a
  // method the scene names is kept, and a solver that cannot honour it is refused.
  void defaultMethodFollowsTheSolver() {
    const Files f;
    auto method = [&](const std::string& solver) {
      const Scene sc = parseScene(
          R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "attachments", "nodes": [0, 1, 2]}, )" +
              solver + "]}",
          f.dir);
      return std::make_pair(sc.settings.method, sc.methodNamed);
    };
    QVERIFY(method(R"({"type": "gravity"})") == std::make_pair(NewtonMethod::Chord, false));
    QVERIFY(method(R"({"type": "solver", "kind": "cholmod"})") == std::make_pair(NewtonMethod::Chord, false));
    QVERIFY(method(R"({"type": "solver", "kind": "cg"})") == std::make_pair(NewtonMethod::Exact, false));
    QVERIFY(method(R"({"type": "solver", "kind": "dense"})") == std::make_pair(NewtonMethod::Exact, false));
    QVERIFY(method(R"({"type": "solver", "kind": "cg", "method": "chord"})") ==
            std::make_pair(NewtonMethod::Chord, true));
    // The cg scene without a method steps; the one naming chord is refused with a sentence.
    const Scene cg = parseScene(
        R"({"components": [{"type": "mesh", "file": "beam.vtu"}, {"type": "attachments", "nodes": [0, 1, 2]}, {"type": "solver", "kind": "cg"}]})",
        f.dir);
    const FemModel model = FemModel::build(cg.mesh, cg.materials, cg.defaultMaterial);
    Integrator in(model, cg.fixedNodes, cg.settings);
    auto state = in.initialState();
    QVERIFY(in.step(state).ok);
    SimulationSettings named = cg.settings;
    named.method = NewtonMethod::Chord;
    QVERIFY_THROWS_EXCEPTION(MeshError, Integrator(model, cg.fixedNodes, named));
  }

  void commandLineRunsAScene() {
    REQUIRE_SHARED("sofa/liver.msh");
    const std::string scene = tempPath("liver-scene.json");
    std::string text = base(true);
    const std::string from = "sofa/liver.msh", to = std::string(REHEARSE_SHARED_DATA) + "/sofa/liver.msh";
    text.replace(text.find(from), from.size(), to);
    writeFile(scene, text);
    QProcess p;
    p.start(REHEARSE_BINARY, {"simulate", "--scene", QString::fromStdString(scene), "--out", QString::fromStdString(tempPath("scene.vtu"))});
    QVERIFY(p.waitForFinished(120000));
    QVERIFY2(p.exitCode() == 0, p.readAllStandardError().constData());
    QVERIFY(p.readAllStandardOutput().contains("5 steps, 0 failed"));
    QProcess list;
    list.start(REHEARSE_BINARY, {"simulate", "--list-components"});
    QVERIFY(list.waitForFinished(30000));
    const QString out = QString::fromUtf8(list.readAllStandardOutput());
    for (const auto& c : sceneComponents()) QVERIFY(out.contains(QString::fromStdString(c.type + ":")) || out.contains(QString::fromStdString(c.type + " (")));
  }
};

QTEST_GUILESS_MAIN(TestScene)
#include "test_scene.moc"
