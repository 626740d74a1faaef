// The simulation session: determinism of a recorded run (every Newton method, the lagged ones included),
// exact continuation from a checkpoint of the complete state, the grasp holding a node on the tool tip,
// inputs applied at step boundaries on the session's own thread, and honest statuses for what it cannot do.
#include "test_support.hpp"

#include "box_mesh.hpp"
#include "phantom/phantom.hpp"

#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <QElapsedTimer>
#include <QThread>
#include <cstring>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {

bool bitIdentical(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<std::size_t>(a.size())) == 0;
}

const phantom::Phantom& organ() {
  static const phantom::Phantom p = [] {
    phantom::PhantomOptions o;
    o.targetTets = 1500;
    o.width = 320;
    o.height = 180;
    return phantom::makePhantom(o);
  }();
  return p;
}

BodySetup setupFor(NewtonMethod method) {
  BodySetup s;
  s.mesh = organ().volume;
  s.fixedNodes = organ().attachments;
  s.material = {MaterialModel::StVK, 27e3, 0.4, 1000};  // nonlinear: the lagged methods differ from exact
  s.settings.method = method;
  s.settings.timeStep = 0.01;
  s.settings.gravity = Eigen::Vector3d(0, 9.81, 0);
  return s;
}

InputEvent event(InputKind kind, bool on = false) {
  InputEvent e;
  e.kind = kind;
  e.on = on;
  return e;
}
InputEvent toolAt(const Eigen::Vector3d& p) {
  InputEvent e = event(InputKind::ToolPose);
  e.position = p;
  return e;
}
InputEvent jaw(bool closed) { return event(InputKind::Jaw, closed); }
InputEvent cut(bool on) { return event(InputKind::Cut, on); }
InputEvent parameter(const char* name, double value) {
  InputEvent e = event(InputKind::Parameter);
  e.name = name;
  e.value = value;
  return e;
}
InputEvent gravity(const Eigen::Vector3d& g) {
  InputEvent e = event(InputKind::Gravity);
  e.vector = g;
  return e;
}

// The surface node farthest from the attachments along x: free to be grasped and pulled.
int freeNode() {
  const auto& v = organ().volume;
  int best = -1;
  for (const auto& t : organ().surface)
    for (int n : t)
      if (best < 0 || v.points[n].x() > v.points[best].x()) best = n;
  return best;
}

// A recorded rehearsal: grasp at step 4, pull 1 mm per step, a stiffness edit, a gravity change, release.
std::vector<InputEvent> script() {
  const Eigen::Vector3d start = organ().volume.points[freeNode()];
  std::vector<InputEvent> ev;
  auto add = [&](long step, InputEvent e) {
    e.step = step;
    e.wallTime = 0.01 * step + 1e-6;
    ev.push_back(e);
  };
  add(3, toolAt(start));
  add(4, jaw(true));
  for (long k = 5; k <= 13; ++k) add(k, toolAt(start + Eigen::Vector3d(0.001 * (k - 4), -0.0005 * (k - 4), 0)));
  add(10, parameter("young", 40e3));
  add(15, gravity(Eigen::Vector3d(2.0, 9.0, 0.5)));
  add(18, jaw(false));
  return ev;
}

constexpr long kSteps = 24;

std::vector<SimulationState> run(NewtonMethod m) {
  std::vector<SimulationState> states;
  replay(setupFor(m), script(), kSteps, [&](long, const SimulationState& s) { states.push_back(s); });
  return states;
}

}  // namespace

class TestSession : public QObject {
  Q_OBJECT
 private slots:
  // The events' words are the recordings' format (issue 63: typed events): each kind reads back from its word, the
  // words recorded before the kinds existed are these exact strings, and a word no kind has stays Other.
  void eventWordsAreTheRecordingsFormat() {
    using K = simcore::EventKind;
    const std::vector<std::pair<std::string, K>> recorded = {
        {"grasp", K::Grasp}, {"release", K::Release}, {"slip", K::Slip}, {"cut", K::Cut},
        {"cut through label 2", K::CutThroughLabel}, {"portal vein cut", K::StructureCut},
        {"vessel cut", K::VesselCut}, {"tumour margin breached", K::TumourMarginBreached}, {"clip", K::Clip},
        {"clip misplaced", K::ClipMisplaced}, {"burn", K::Burn}, {"energy on structure", K::EnergyOnStructure},
        {"energy on artery", K::EnergyOnNamedStructure}, {"bleeding", K::Bleeding},
        {"bleeding stopped", K::BleedingStopped}, {"tear", K::Tear}, {"artery torn", K::StructureTorn},
        {"vessel torn", K::VesselTorn}, {"attachment torn", K::AttachmentTorn},
        {"force over threshold", K::ForceOverThreshold}, {"incorrect action: tear", K::IncorrectAction},
        {"cut through label x", K::Other}, {"grasped", K::Other}, {"", K::Other}};
    for (const auto& [word, kind] : recorded) {
      QVERIFY2(simcore::eventKind(word) == kind, word.c_str());
      if (*simcore::eventWord(kind)) QCOMPARE(std::string(simcore::eventWord(kind)), word);
    }
    QCOMPARE(simcore::cutThroughLabelWord(17), std::string("cut through label 17"));
    QCOMPARE(simcore::cutLabelOf("cut through label 17"), 17);
    QCOMPARE(simcore::cutLabelOf("cut through label 17 "), -1);
    QCOMPARE(simcore::cutLabelOf("cut through label -3"), -1);
    QCOMPARE(simcore::structureEventWord(K::StructureTorn, "bile duct"), std::string("bile duct torn"));
    QCOMPARE(simcore::structureEventWord(K::EnergyOnNamedStructure, "vein"), std::string("energy on vein"));
    simcore::EventCounts c;
    c.add({"grasp", "cut", "cut through label 2", "vessel cut", "portal vein cut", "tear", "tear", "artery torn",
           "vessel torn", "attachment torn", "slip", "energy on artery", "energy on structure"});
    QCOMPARE(c.grasps, 1);
    QCOMPARE(c.cuts, 1);
    QCOMPARE(c.vesselCuts, 1);
    QCOMPARE(c.tears, 2);
    QCOMPARE(c.attachmentsTorn, 1);
    QCOMPARE(c.slips, 1);
    QCOMPARE(c.energyOnStructures, 1);
    QCOMPARE(c.clips + c.burns + c.bleedings + c.releases, 0);
  }
  void recordedRunIsBitIdentical_data() {
    QTest::addColumn<int>("method");
    QTest::newRow("exact") << static_cast<int>(NewtonMethod::Exact);
    QTest::newRow("lagged-pcg") << static_cast<int>(NewtonMethod::LaggedPcg);
    QTest::newRow("chord") << static_cast<int>(NewtonMethod::Chord);
    QTest::newRow("linearised") << static_cast<int>(NewtonMethod::Linearised);
    QTest::newRow("newton-krylov") << static_cast<int>(NewtonMethod::NewtonKrylov);
  }
  void recordedRunIsBitIdentical() {
    QFETCH(int, method);
    const auto m = static_cast<NewtonMethod>(method);
    const auto a = run(m), b = run(m);
    QCOMPARE(a.size(), static_cast<std::size_t>(kSteps));
    QCOMPARE(b.size(), a.size());
    for (std::size_t k = 0; k < a.size(); ++k) {
      QVERIFY2(a[k].x.allFinite(), qPrintable(QStringLiteral("step %1").arg(k + 1)));
      QVERIFY2(bitIdentical(a[k].x, b[k].x) && bitIdentical(a[k].v, b[k].v) && a[k].time == b[k].time,
               qPrintable(QStringLiteral("step %1 differs between two replays").arg(k + 1)));
    }
    // The script did something: the grasped node followed the tip (bilateral constraints), keeping where it
    // was relative to the tip when the jaws closed (the state after 4 steps: the grasp applies at boundary 4).
    const int node = freeNode();
    const Eigen::Vector3d start = organ().volume.points[node];
    const Eigen::Vector3d offset = a[3].x.segment<3>(3 * node) - start;
    const Eigen::Vector3d tip = start + Eigen::Vector3d(0.009, -0.0045, 0) + offset;
    const Eigen::Vector3d held = a[13].x.segment<3>(3 * node);  // after step 14: the tip's last move applied at 13
    QVERIFY2((held - tip).norm() < 2e-4,
             qPrintable(QStringLiteral("held node %1 mm from the tip").arg(1e3 * (held - tip).norm())));
  }

  void checkpointContinuesExactly_data() { recordedRunIsBitIdentical_data(); }
  void checkpointContinuesExactly() {
    QFETCH(int, method);
    const auto m = static_cast<NewtonMethod>(method);
    const auto events = script();
    constexpr long kAt = 12;  // mid-grasp, after the stiffness edit (step 10), before the gravity change (15)
    Checkpoint cp;
    std::vector<SimulationState> uninterrupted;
    {
      Session s(setupFor(m));
      for (const auto& e : events) s.post(e);
      for (long k = 0; k < kSteps; ++k) {
        if (k == kAt) cp = s.checkpoint();
        s.advance();
        uninterrupted.push_back(s.state());
      }
    }
    QCOMPARE(cp.step, kAt);
    auto continueFrom = [&](const Checkpoint& c) {
      std::vector<SimulationState> out;
      Session s(setupFor(m));  // a new session with the original setup: restore brings the edited one
      s.restore(c);
      for (const auto& e : events)
        if (e.step >= c.step) s.post(e);
      for (long k = c.step; k < kSteps; ++k) {
        s.advance();
        out.push_back(s.state());
      }
      return out;
    };
    const auto restored = continueFrom(cp);
    QCOMPARE(static_cast<long>(restored.size()), kSteps - kAt);
    for (long k = kAt; k < kSteps; ++k)
      QVERIFY2(
          bitIdentical(restored[k - kAt].x, uninterrupted[k].x) &&
              bitIdentical(restored[k - kAt].v, uninterrupted[k].v),
          qPrintable(QStringLiteral("step %1 differs after restoring the checkpoint of step %2").arg(k + 1).arg(kAt)));
    // What makes the state complete matters: without the lagged factor's identity and the carried forces,
    // a lagged method continues differently (so the comparison above can fail).
    // (Chord keeps its factor across these steps; linearised may have just refreshed, then there is nothing to strip.)
    if (m == NewtonMethod::Chord) QVERIFY(cp.state.lagged.valid);
    if (m != NewtonMethod::Exact && cp.state.lagged.valid) {
      Checkpoint partial = cp;
      partial.state.lagged.valid = false;
      partial.state.forcesValid = false;
      const auto other = continueFrom(partial);
      bool anyDifferent = false;
      for (long k = kAt; k < kSteps; ++k) anyDifferent |= !bitIdentical(other[k - kAt].x, uninterrupted[k].x);
      QVERIFY2(anyDifferent,
               "positions and velocities alone reproduced a lagged run: the test would not see a missing part");
    }
  }

  // Asynchronous refresh (issue 15): a drifted lagged factor is rebuilt on a second thread while the steps
  // go on with the old one, and swapped in when ready; the swap is recorded (a Factor event at its step), so a
  // replay (deferred refresh: the factor is built when the recording says) gives the live run's states bit
  // for bit, whatever the thread's timing was. No step of the live run factorised a drifted factor itself.
  void asynchronousRefreshReplaysBitForBit() {
    for (const NewtonMethod m : {NewtonMethod::Linearised, NewtonMethod::Chord}) {
      BodySetup setup = setupFor(m);
      setup.material.young = 8e3;  // softer: the lagged factor drifts (and is refreshed) several times
      setup.settings.factorRefresh = FactorRefresh::Asynchronous;
      Session live(setup);
      for (const auto& e : script()) live.post(e);
      // 60 steps, and on while no build has been swapped in yet (up to 600 more, 20 ms apart): on a loaded machine the
      // second thread may not finish within the first 60 (seen once: 3 requests, 0 swaps, beside a CGAL build).
      long kLong = 60;
      std::vector<SimulationState> states;
      int requested = 0, swapped = 0, waitedForDrift = 0;
      for (long k = 0; k < kLong || (swapped == 0 && k < 660); ++k) {
        if (k >= kLong) QThread::msleep(20), kLong = k + 1;
        const StepReport rep = live.advance();
        QVERIFY2(rep.ok, rep.status.c_str());
        requested += rep.factorRequested;
        swapped += rep.factorSwapped;
        // Steps that factorised on this thread: the first one and those right after a body rebuild (the
        // stiffness edit at step 10, the gravity change at 15), never one whose factor only drifted.
        if (rep.factorisations > 0 && k != 0 && k != 10 && k != 15) ++waitedForDrift;
        states.push_back(live.state());
        if (k % 7 == 3) QThread::msleep(20);  // some requests finish within one step, some take several
      }
      const QString name = QString::fromStdString(toString(m));
      QVERIFY2(requested >= 2 && swapped >= 1,
               qPrintable(QStringLiteral("%1: %2 requests, %3 swaps").arg(name).arg(requested).arg(swapped)));
      // Linearised never waits, whatever the second thread's timing; chord iterates on with the old factor while
      // the new one is built, and a step that cannot converge with it is retried with half the time step (a new
      // factor, on this thread): how often depends on how long the build took (printed, not asserted).
      const QString waits = QStringLiteral("%1: %2 steps factorised on the stepping thread, %3 requests")
                                .arg(name)
                                .arg(waitedForDrift)
                                .arg(requested);
      qInfo("%s", qPrintable(waits));
      if (m == NewtonMethod::Linearised) QVERIFY2(waitedForDrift == 0, qPrintable(waits));
      const auto rec = live.recorded();
      const auto factors =
          std::count_if(rec.begin(), rec.end(), [](const InputEvent& e) { return e.kind == InputKind::Factor; });
      QCOMPARE(static_cast<int>(factors), swapped);
      long k = 0;
      bool same = true;
      replay(setup, rec, kLong, [&](long step, const SimulationState& s) {
        same = same && bitIdentical(s.x, states[static_cast<std::size_t>(step - 1)].x) &&
               bitIdentical(s.v, states[static_cast<std::size_t>(step - 1)].v);
        k = step;
      });
      QCOMPARE(k, kLong);
      QVERIFY2(same, qPrintable(name + ": the replay of the recorded swaps differs from the live asynchronous run"));
      // Without the Factor events the replay differs (so the comparison above could fail).
      std::vector<InputEvent> stripped;
      for (const auto& e : rec)
        if (e.kind != InputKind::Factor) stripped.push_back(e);
      bool differs = false;
      replay(setup, stripped, kLong, [&](long step, const SimulationState& s) {
        differs |= !bitIdentical(s.x, states[static_cast<std::size_t>(step - 1)].x);
      });
      QVERIFY2(differs, qPrintable(name + ": the swaps changed nothing"));
    }
  }

  // A chord step that does not converge with the lagged factor is retried with half the time step on a factor built
  // at once; that factor makes any request still under way older. Such a request used to stay pending until its
  // build ended (live) or a recorded swap installed it (a replay has none for it), blocking the requests after it for
  // a time that depended on the second thread: the replay of this soft co-rotational pull differed from step 14 on.
  void asynchronousChordReplaysAfterRefreshingAtOnce() {
    for (const double radius : {0.0, 0.0025}) {
      BodySetup setup = setupFor(NewtonMethod::Chord);
      setup.material = {MaterialModel::Corotational, 8e3, 0.4, 1000};
      setup.settings.factorRefresh = FactorRefresh::Asynchronous;
      setup.tools.toolRadius = radius;  // with the shaft's contact too
      const Eigen::Vector3d start = organ().volume.points[freeNode()];
      std::vector<InputEvent> events;
      auto add = [&](long step, InputEvent e) {
        e.step = step;
        events.push_back(e);
      };
      add(3, toolAt(start));
      add(4, jaw(true));
      for (long k = 5; k <= 40; ++k) add(k, toolAt(start + Eigen::Vector3d(0.0005 * (k - 4), -0.0005 * (k - 4), 0)));
      add(45, jaw(false));
      Session live(setup);
      for (const auto& e : events) live.post(e);
      long kLong = 60;  // and on while nothing was swapped in yet (a loaded machine's second thread; as above)
      std::vector<SimulationState> states;
      int requested = 0, swapped = 0, atOnce = 0;
      for (long k = 0; k < kLong || (swapped == 0 && k < 660); ++k) {
        if (k >= kLong) QThread::msleep(20), kLong = k + 1;
        const StepReport rep = live.advance();
        QVERIFY2(rep.ok, rep.status.c_str());
        requested += rep.factorRequested;
        swapped += rep.factorSwapped;
        atOnce += rep.factorisations > 0 && !rep.factorSwapped && k > 0;
        states.push_back(live.state());
        if (k % 5 == 2) QThread::msleep(15);  // some requests finish within one step, some take several
      }
      qInfo("shaft radius %g mm: %d requests, %d swaps, %d steps refreshed at once", 1e3 * radius, requested, swapped,
            atOnce);
      QVERIFY(requested >= 3 && swapped >= 1);
      long first = -1;
      replay(setup, live.recorded(), kLong, [&](long step, const SimulationState& st) {
        const auto& want = states[static_cast<std::size_t>(step - 1)];
        if (first < 0 && !(bitIdentical(st.x, want.x) && bitIdentical(st.v, want.v))) first = step;
      });
      QVERIFY2(first < 0, qPrintable(QStringLiteral("the replay differs from step %1 on").arg(first)));
    }
  }

  void recordingHoldsEveryEventWithItsStep() {
    Session s(setupFor(NewtonMethod::Linearised));
    for (const auto& e : script()) s.post(e);
    for (long k = 0; k < kSteps; ++k) s.advance();
    const auto rec = s.recorded();
    const auto ev = script();
    QCOMPARE(rec.size(), ev.size());
    // Applied in step order (stable for events of one step), each at the boundary it named.
    std::vector<InputEvent> sorted = ev;
    std::stable_sort(sorted.begin(), sorted.end(),
                     [](const InputEvent& a, const InputEvent& b) { return a.step < b.step; });
    for (std::size_t i = 0; i < rec.size(); ++i) QVERIFY(rec[i] == sorted[i]);
  }

  void threadPlaysAndAppliesInputsAtBoundaries() {
    Session s(setupFor(NewtonMethod::Linearised));
    std::atomic<int> published{0};
    std::atomic<Qt::HANDLE> where{nullptr};
    s.setPublishedCallback([&] {
      where = QThread::currentThreadId();
      ++published;
    });
    s.play();
    QTRY_VERIFY_WITH_TIMEOUT(s.snapshot()->step >= 5, 20000);
    s.post(parameter("young", 54e3));
    QTRY_VERIFY_WITH_TIMEOUT(s.snapshot()->material.young == 54e3, 20000);
    s.pause();
    QVERIFY(where.load() != QThread::currentThreadId());  // stepped on the session's thread
    const long at = s.snapshot()->step;
    QTest::qWait(200);
    QVERIFY(s.snapshot()->step <= at + 1);  // paused (at most the step in progress finished)
    // Given while paused and no step applied them: the jaws closed on a free node, and an edit. After Reset the
    // organ from rest is not held (a GUI test's clips clicked on a paused organ closed on it after Reset and Play);
    // the edit stays, as edits do over a reset.
    s.post(toolAt(organ().volume.points[freeNode()]));
    s.post(jaw(true));
    s.post(parameter("young", 61e3));
    s.reset();
    QTRY_COMPARE_WITH_TIMEOUT(s.snapshot()->step, 0L, 20000);
    QVERIFY(published.load() > 5);
    s.stepOnce();
    QTRY_COMPARE_WITH_TIMEOUT(s.snapshot()->step, 1L, 20000);
    QVERIFY(s.snapshot()->tool.held.empty());
    QVERIFY(!s.snapshot()->tool.jawClosed);
    QCOMPARE(s.snapshot()->material.young, 61e3);
    QVERIFY(s.recorded().back().name == "young");
    // What is given after the Reset is done.
    s.post(toolAt(organ().volume.points[freeNode()]));
    s.post(jaw(true));
    s.stepOnce();
    QTRY_COMPARE_WITH_TIMEOUT(s.snapshot()->step, 2L, 20000);
    QVERIFY(!s.snapshot()->tool.held.empty());
  }

  // Played, the session keeps to real time: steps that took longer than their time step (here one step held 0.6 s by
  // the step hook, as a cut's or a tear's step can be) are not made up afterwards at more than real time; it runs on
  // at real time from where it is, at most 0.1 s behind.
  void slowStepsAreNotMadeUpAfterwards() {
    // A small bar hung at one end (48 elements: steps of a fraction of a millisecond, many times faster than real time).
    BodySetup setup;
    setup.mesh = boxMesh(0.04, 0.01, 0.01, 4, 1, 1);
    setup.mesh.unitToMetre = 1.0;
    for (std::size_t i = 0; i < setup.mesh.points.size(); ++i)
      if (setup.mesh.points[i].x() < 1e-9) setup.fixedNodes.push_back(static_cast<int>(i));
    setup.material = {MaterialModel::StVK, 27e3, 0.4, 1000};
    setup.settings.timeStep = 0.01;
    Session s(setup);
    // The held step's end: the simulated time and the wall clock there (read on the session's thread, at once).
    std::atomic<bool> holdNext{false}, held{false};
    double t0 = 0;
    QElapsedTimer wall;
    s.setStepHook([&](const StepRecord& r) {
      if (!holdNext.exchange(false)) return;
      QThread::msleep(600);
      t0 = r.state->time;
      wall.start();
      held = true;
    });
    s.play();
    QTRY_VERIFY_WITH_TIMEOUT(s.snapshot()->step >= 5, 20000);
    holdNext = true;
    QTRY_VERIFY_WITH_TIMEOUT(held.load(), 20000);
    QTest::qWait(1000);
    const double simulated = s.snapshot()->time - t0, elapsed = 1e-3 * static_cast<double>(wall.elapsed());
    s.pause();
    qInfo("after a 0.6 s step: %.3f s simulated in %.3f s", simulated, elapsed);
    // Made up, it simulated the 0.6 s lost on top of the wall clock's (1.64 s in 1.05 s, measured without the bound);
    // at real time, the 0.1 s allowed behind plus a step ahead (10 ms) more than the wall clock (1.15 s in 1.05 s), here
    // with two steps' margin. (A slow machine simulates less, never more.)
    QVERIFY2(simulated <= elapsed + 0.1 + 0.03, qPrintable(QString::number(simulated)));
  }

  void unsupportedInputsSaySo() {
    Session s(setupFor(NewtonMethod::Linearised));
    // The blade on in the air, swept 5 cm: nothing cut, nothing changed.
    const std::size_t elements = s.snapshot()->elements;
    s.post(toolAt(Eigen::Vector3d(1, 1, 1)));
    s.post(cut(true));
    s.post(toolAt(Eigen::Vector3d(1.05, 1, 1)));
    s.post(cut(false));
    s.advance();
    QCOMPARE(s.snapshot()->elements, elements);
    QVERIFY(s.snapshot()->events.empty());
    s.post(parameter("viscosity", 1));
    s.advance();
    QVERIFY(QString::fromStdString(s.snapshot()->message).contains("Unknown parameter"));
    // Jaws closing far from any tissue grasp nothing, and say so.
    s.post(toolAt(Eigen::Vector3d(1, 1, 1)));
    s.post(jaw(true));
    s.advance();
    QVERIFY(s.snapshot()->tool.held.empty());
    QVERIFY(QString::fromStdString(s.snapshot()->message).contains("nothing"));
    // A refused edit (Poisson's ratio 0.5) keeps the previous material and the run going.
    s.post(parameter("poisson", 0.5));
    const StepReport r = s.advance();
    QVERIFY(r.ok);
    QCOMPARE(s.snapshot()->material.poisson, 0.4);
    QVERIFY(QString::fromStdString(s.snapshot()->message).contains("refused"));
  }
};

QTEST_GUILESS_MAIN(TestSession)
#include "test_session.moc"
