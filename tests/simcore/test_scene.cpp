// Scenes declare their components: only those are built; unknown components and parameters are refused
// by name; the command line runs a scene reproducing SOFA's liver.scn.
#include "test_support.hpp"

#include <rehearse/simcore/scene.hpp>

#include <QProcess>

using namespace rehearse::simcore;

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
}  // namespace

class TestScene : public QObject {
  Q_OBJECT
 private slots:
  void onlyDeclaredComponentsAreBuilt() {
    REQUIRE_SHARED("sofa/liver.msh");
    const Scene a = parseScene(base(false), REHEARSE_SHARED_DATA), b = parseScene(base(true), REHEARSE_SHARED_DATA);
    QCOMPARE(a.components.size(), std::size_t(5));
    QCOMPARE(b.components.size(), std::size_t(6));
    QVERIFY(std::find(a.components.begin(), a.components.end(), "attachments") == a.components.end());
    QVERIFY(a.fixedNodes.empty());
    QCOMPARE(b.fixedNodes, std::vector<int>({3, 39, 64}));
    QCOMPARE(b.componentBytes - a.componentBytes, 3 * sizeof(int));
    QCOMPARE(a.settings.timeStep, 0.02);
    QCOMPARE(a.settings.gravity.y(), -9.81);
    // Without a gravity or damping component there is none.
    const Scene bare = parseScene(R"({"components": [{"type": "mesh", "file": "sofa/liver.msh"}]})", REHEARSE_SHARED_DATA);
    QCOMPARE(bare.settings.gravity.norm(), 0.0);
    QCOMPARE(bare.settings.rayleighMass, 0.0);
    QCOMPARE(bare.components.size(), std::size_t(1));
  }

  void badScenesAreRefusedByName() {
    REQUIRE_SHARED("sofa/liver.msh");
    auto expect = [](const std::string& json, const char* fragment) {
      try {
        parseScene(json, REHEARSE_SHARED_DATA);
        QFAIL(qPrintable(QString("accepted: %1").arg(QString::fromStdString(json))));
      } catch (const MeshError& e) {
        QVERIFY2(QString(e.what()).contains(fragment), e.what());
      }
    };
    expect(R"({"components": [{"type": "mesh", "file": "sofa/liver.msh"}, {"type": "haptics"}]})", "unknown component 'haptics'");
    expect(R"({"components": [{"type": "mesh", "file": "sofa/liver.msh", "scale": 2}]})", "no parameter 'scale'");
    expect(R"({"components": [{"type": "mesh"}]})", "needs the parameter 'file'");
    expect(R"({"components": [{"type": "gravity"}]})", "no 'mesh'");
    expect(R"({"components": [{"type": "mesh", "file": "sofa/liver.msh"}, {"type": "gravity", "vector": "down"}]})", "wrong kind");
    expect(R"({"components": [{"type": "mesh", "file": "sofa/liver.msh"}, {"type": "solver", "kind": "magic"}]})", "cholmod, cg or dense");
    expect(R"({"components": [{"type": "mesh", "file": "sofa/liver.msh"}, {"type": "solver", "factor": "magic"}]})", "supernodal or simplicial");
    expect(R"({"components": 3})", "components");
    expect("{oops", "not valid JSON");
  }

  // SOFA's liver.scn as a scene, run by the command line; the description lists every component.
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
