// The 6-DoF input device path (issue 37): the 3D mouse's steering against its analytic motion (speed x time along the
// mapped axis, the dead zone, a pivot about the trocar that keeps the shaft's length and turns it by rate x time, a
// twist about the shaft that moves nothing); libspnav itself talking to a stand-in spacenavd over its UNIX socket
// (FakeSpacenavd: the daemon's event protocol, so the library's own parsing is exercised): readings, buttons, a lost
// daemon and no daemon said in a sentence; and a scripted device (the test double) grasping and pulling the liver
// preset through a session: the held node follows the steered jaws, the force rendered to a device with force output
// is the session's, and the recording replays bit for bit.
#include "fake_spacenavd.hpp"
#include "session_inputs.hpp"
#include "test_support.hpp"

#include <rehearse/app/spacenav.hpp>
#include <rehearse/simcore/session/body.hpp>
#include <rehearse/simcore/session/device.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QElapsedTimer>
#include <QProcess>
#include <QThread>
#include <QtTest>

#include <cmath>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

DeviceReading rate(const Eigen::Vector3d& t, const Eigen::Vector3d& r = Eigen::Vector3d::Zero(), unsigned buttons = 0) {
  DeviceReading d;
  d.translation = t;
  d.rotation = r;
  d.buttons = buttons;
  return d;
}

// Reads until a reading comes (libspnav's socket delivers asynchronously) or 2 s pass.
bool readSoon(MotionDevice& d, DeviceReading& r, std::string& error) {
  QElapsedTimer t;
  t.start();
  while (t.elapsed() < 2000) {
    if (d.read(r, error)) return true;
    if (!error.empty()) return false;
    QThread::msleep(5);
  }
  return false;
}

bool bitIdentical(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<std::size_t>(a.size())) == 0;
}

}  // namespace

class TestDevice : public QObject {
  Q_OBJECT
 private slots:
  // Pushing: 1 s at full travel moves the tip speed x 1 s along the mapped camera axis (x right, y up = -y, z away =
  // -z), 100 steps of 10 ms; half travel past the dead zone half as fast; inside the dead zone nothing.
  void pushingMovesAtTheSetSpeed() {
    SteeringSettings s;
    const Eigen::Vector3d trocar(0, -0.1, -0.1), start(0.01, 0.02, 0.15);
    struct Case {
      Eigen::Vector3d push, expected;
    };
    const double half = 0.5 * (1 - s.deadZone) + s.deadZone;  // half-way past the dead zone
    for (const Case& c :
         {Case{{1, 0, 0}, {s.speed, 0, 0}}, Case{{0, 1, 0}, {0, -s.speed, 0}}, Case{{0, 0, 1}, {0, 0, -s.speed}},
          Case{{-half, 0, 0}, {-0.5 * s.speed, 0, 0}}, Case{{0.9 * s.deadZone, 0, -0.9 * s.deadZone}, {0, 0, 0}}}) {
      Eigen::Vector3d tip = start;
      bool moved = false;
      for (int k = 0; k < 100; ++k) {
        const SteeringStep st = steer(tip, trocar, rate(c.push), 0.01, s);
        tip = st.tip;
        moved |= st.moved;
      }
      const double err = (tip - start - c.expected).norm();
      QVERIFY2(err <= 1e-12, qPrintable(QString::number(err)));
      QCOMPARE(moved, c.expected.norm() > 0);
    }
  }

  // Turning: the shaft pivots about the trocar; 1 s of full turn about x (the shaft perpendicular to x) turns it by
  // turnRate x 1 s and keeps its length (1e-12); a twist about the shaft's own axis moves nothing and is reported;
  // a non-finite reading moves nothing.
  void turningPivotsAboutTheTrocar() {
    SteeringSettings s;
    const Eigen::Vector3d trocar(0, -0.1, 0), start(0, -0.1, 0.15);  // shaft along +z
    Eigen::Vector3d tip = start;
    for (int k = 0; k < 100; ++k) tip = steer(tip, trocar, rate(Eigen::Vector3d::Zero(), {1, 0, 0}), 0.01, s).tip;
    const Eigen::Vector3d a = start - trocar, b = tip - trocar;
    const double angle = std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0));
    qInfo("pivot: %.6f rad (expected %.6f), shaft %.9f m -> %.9f m", angle, s.turnRate, a.norm(), b.norm());
    QVERIFY(std::abs(angle - s.turnRate) <= 1e-9);
    QVERIFY(std::abs(a.norm() - b.norm()) <= 1e-12);
    QVERIFY(std::abs(b.x()) <= 1e-12);  // about x: the tip stays in the y-z plane
    // The cap turned about device z (the camera's -z: along this shaft): a twist.
    const SteeringStep twist = steer(start, trocar, rate(Eigen::Vector3d::Zero(), {0, 0, 1}), 0.01, s);
    QVERIFY(twist.twisted);
    QVERIFY(!twist.moved);
    QCOMPARE(twist.tip, start);
    const SteeringStep nan = steer(start, trocar, rate({std::nan(""), 0, 0}), 0.01, s);
    QVERIFY(!nan.moved && nan.tip == start);
  }

  // libspnav against the stand-in daemon: a motion of (175, -350, 700, 0, 35, 0) counts reads (0.5, -1, 1 clamped,
  // 0, 0.1, 0); the left button's press and release; the daemon stopping is said; with none, openSpaceNav says how
  // to get one.
  void spacenavdProtocol() {
    {
      testing::FakeSpacenavd daemon;
      QVERIFY(daemon.listening());
      std::string why;
      auto device = app::openSpaceNav(why);
      QVERIFY2(device, why.c_str());
      QVERIFY(daemon.accept());
      std::string twice;
      QVERIFY(!app::openSpaceNav(twice));
      QVERIFY(twice.find("already connected") != std::string::npos);
      QVERIFY(daemon.motion(175, -350, 700, 0, 35, 0));
      DeviceReading r;
      std::string error;
      QVERIFY2(readSoon(*device, r, error), error.c_str());
      qInfo("%s: translation (%.3f, %.3f, %.3f), rotation (%.3f, %.3f, %.3f)", device->name().c_str(),
            r.translation.x(), r.translation.y(), r.translation.z(), r.rotation.x(), r.rotation.y(), r.rotation.z());
      QVERIFY(r.kind == DeviceReading::Kind::Rate);
      QVERIFY((r.translation - Eigen::Vector3d(0.5, -1, 1)).norm() <= 1e-12);
      QVERIFY((r.rotation - Eigen::Vector3d(0, 0.1, 0)).norm() <= 1e-12);
      QCOMPARE(r.buttons, 0u);
      QVERIFY(daemon.button(0, true));
      QVERIFY(readSoon(*device, r, error));
      QCOMPARE(r.buttons, 1u);
      QVERIFY((r.translation - Eigen::Vector3d(0.5, -1, 1)).norm() <= 1e-12);  // the cap's last motion kept
      QVERIFY(daemon.button(0, false));
      QVERIFY(daemon.motion(0, 0, 0, 0, 0, 0));
      QVERIFY(readSoon(*device, r, error));
      QCOMPARE(r.buttons, 0u);
      QVERIFY(r.translation.isZero(0));
      daemon.stop();
      QElapsedTimer t;
      t.start();
      while (error.empty() && t.elapsed() < 2000) device->read(r, error);
      qInfo("%s", error.c_str());
      QVERIFY(error.find("connection to spacenavd was lost") != std::string::npos);
    }
    ::setenv("SPNAV_SOCKET", "/nonexistent/spnav.sock", 1);
    std::string why;
    if (QFile::exists("/var/run/spnav.sock")) QSKIP("a real spacenavd runs on this machine");
    QVERIFY(!app::openSpaceNav(why));
    ::unsetenv("SPNAV_SOCKET");
    qInfo("%s", why.c_str());
    QVERIFY(why.find("spacenavd daemon is not running") != std::string::npos);
    QVERIFY(why.find("apt-get install spacenavd") != std::string::npos);
  }

  // `rehearse device` against the stand-in daemon prints the readings it gets; without a daemon it exits 1 with the
  // sentence.
  void theCommandLineShowsTheReadings() {
    {
      testing::FakeSpacenavd daemon;
      QProcess p;
      p.setProcessEnvironment(QProcessEnvironment::systemEnvironment());  // with SPNAV_SOCKET
      p.start(REHEARSE_BINARY, {"device", "--seconds", "1.5"});
      QVERIFY(p.waitForStarted());
      QVERIFY(daemon.accept());
      QVERIFY(daemon.motion(175, -350, 700, 0, 35, 0));
      QThread::msleep(300);  // read apart (the command reads every 10 ms)
      QVERIFY(daemon.button(1, true));
      QVERIFY(p.waitForFinished(20000));
      const QString out = QString::fromUtf8(p.readAllStandardOutput());
      qInfo("%s", qPrintable(out));
      QCOMPARE(p.exitCode(), 0);
      QVERIFY(out.contains("move +0.50 -1.00 +1.00  turn +0.00 +0.10 +0.00  buttons 0"));
      QVERIFY(out.contains("buttons 2"));
      QVERIFY(out.contains("2 readings"));
    }
    if (QFile::exists("/var/run/spnav.sock")) QSKIP("a real spacenavd runs on this machine");
    QProcess p;
    QProcessEnvironment env = QProcessEnvironment::systemEnvironment();
    env.insert("SPNAV_SOCKET", "/nonexistent/spnav.sock");
    p.setProcessEnvironment(env);
    p.start(REHEARSE_BINARY, {"device", "--seconds", "1"});
    QVERIFY(p.waitForFinished(20000));
    QCOMPARE(p.exitCode(), 1);
    QVERIFY(QString::fromUtf8(p.readAllStandardError()).contains("spacenavd daemon is not running"));
  }

  // The test double as a surgeon's hand: 20 steps at rest, the left button pressed on a free surface node (the jaws
  // close there), 60 steps pushing the cap up and away at 60 % while held, then released. The held node follows the
  // steered jaws (1e-6 m); the force the device renders is minus the session's tool force; the recorded session
  // replays bit for bit.
  void aScriptedDeviceGraspsPullsAndReplays() {
    BodySetup setup = testing::presetBody("liver");
    Session live(setup);
    const SimulationState s0 = live.state();
    // The free surface node nearest the camera.
    const auto body = makeBody(setup);
    int node = -1;
    for (const auto& t : boundaryTriangles(setup.mesh, false))
      for (int v : t)
        if (!body->fixedMask()[static_cast<std::size_t>(v)] && (node < 0 || s0.x(3 * v + 2) < s0.x(3 * node + 2)))
          node = v;
    QVERIFY(node >= 0);
    std::vector<DeviceReading> script(20, rate(Eigen::Vector3d::Zero()));
    script.push_back(rate(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1));
    for (int k = 0; k < 60; ++k) script.push_back(rate({0, 0.6, 0.6}, Eigen::Vector3d::Zero(), 1));
    script.push_back(rate(Eigen::Vector3d::Zero()));
    ScriptedDevice device(script, true);
    Eigen::Vector3d tip = s0.x.segment<3>(3 * node);
    live.post(testing::toolAt(tip));
    const Eigen::Vector3d trocar = live.snapshot()->trocar;
    DeviceReading r;
    std::string error;
    bool held = false;
    Eigen::Vector3d pressedAt = Eigen::Vector3d::Zero();
    std::vector<SimulationState> states;
    double worst = 0;
    Eigen::Vector3d jawStart = Eigen::Vector3d::Zero(), nodeStart = Eigen::Vector3d::Zero();
    const double h = setup.settings.timeStep;
    while (device.read(r, error)) {
      const SteeringStep st = steer(tip, trocar, r, h);
      if (st.moved) {
        tip = st.tip;
        live.post(testing::toolAt(tip));
      }
      if ((r.buttons & 1u) != held) {
        held = r.buttons & 1u;
        if (held) {  // the hand brought the jaws onto the node where it is now (it sagged since the start)
          tip = pressedAt = live.state().x.segment<3>(3 * node);
          live.post(testing::toolAt(tip));
        }
        InputEvent jaw = testing::jaws(held);
        jaw.position = tip;  // the jaws close where the tip is (as the GUI's grasper says)
        live.post(jaw);
      }
      QVERIFY(live.advance().ok);
      const auto snap = live.snapshot();
      device.render(-snap->tool.force);
      states.push_back(live.state());
      if (held && !snap->tool.held.empty()) {
        const Eigen::Vector3d at = states.back().x.segment<3>(3 * snap->tool.held[0]);
        if (jawStart.isZero(0)) jawStart = tip, nodeStart = at;
        worst = std::max(worst, ((at - nodeStart) - (tip - jawStart)).norm());
      }
      if (held) QVERIFY(!snap->tool.held.empty());
    }
    QCOMPARE(device.played(), script.size());
    const auto forces = device.rendered();
    QCOMPARE(forces.size(), script.size());
    const Eigen::Vector3d pulled = tip - pressedAt;
    const SteeringSettings defaults;
    const double expected =
        std::sqrt(2.0) * defaults.speed * 60 * h * (0.6 - defaults.deadZone) / (1 - defaults.deadZone);
    double strongest = 0;
    for (const auto& f : forces) strongest = std::max(strongest, f.norm());
    qInfo("pulled the jaws %.3f mm (expected %.3f), the held node followed them to %.1e m, force rendered up to %.2f N",
          1e3 * pulled.norm(), 1e3 * expected, worst, strongest);
    QVERIFY(std::abs(pulled.norm() - expected) <= 1e-12);
    QVERIFY(worst <= 1e-6);
    QVERIFY(forces[70].norm() > 0.05);
    QVERIFY(forces.back().norm() < forces[70].norm());
    long first = -1;
    replay(setup, live.recorded(), static_cast<long>(states.size()), [&](long step, const SimulationState& st) {
      const auto& want = states[static_cast<std::size_t>(step - 1)];
      if (first < 0 && !(bitIdentical(st.x, want.x) && bitIdentical(st.v, want.v))) first = step;
    });
    QVERIFY2(first < 0, qPrintable(QStringLiteral("the replay differs from step %1 on").arg(first)));
  }
};

QTEST_GUILESS_MAIN(TestDevice)
#include "test_device.moc"
