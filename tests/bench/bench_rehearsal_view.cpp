// Benchmark of the rehearsal view (issue 15; not a test): the real main window on the built-in phantom
// case (a 1280x720 frame), step 7, driven with mouse events as a hand would (a move every 16 ms): while
// pulling with the grasper for 4 s, then while cutting across the organ with the scissors for 4 s, then 4 s while the cut
// bleeds (no input), the
// frame view's repaints per second, how many of them showed a new drawing of the simulated organ over the
// frame, the time each paint takes, and the simulation steps done meanwhile. The window is 2560x1400, so the frame view
// shows the frame at least at its own size. Needs an X server (xvfb-run); --software draws the overlay without OpenGL
// (QPainter), as the tests do; --opengl through OpenGL (here Mesa's llvmpipe); without either the window chooses as
// `rehearse` does by default (MainWindow::Renderer::Automatic).
//   xvfb-run -a -s "-screen 0 2560x1440x24" bench_rehearsal_view [OUT_DIR] [--software | --opengl]
#include "window_support.hpp"

#include "rehearse/ui/frameview.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <QApplication>
#include <QElapsedTimer>
#include <QSignalSpy>
#include <QTest>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <vector>

using namespace rehearse;

namespace {

// Counts the frame view's paints and times each (the filter runs the paint itself), and how many of them
// showed a new drawing of the organ (the overlay image changed since the last paint).
class PaintMeter : public QObject {
 public:
  explicit PaintMeter(const ui::MainWindow& w) : w_(w) {}
  bool eventFilter(QObject* o, QEvent* e) override {
    if (e->type() != QEvent::Paint || busy_) return false;
    busy_ = true;
    QElapsedTimer t;
    t.start();
    static_cast<QWidget*>(o)->removeEventFilter(this);
    QCoreApplication::sendEvent(o, e);
    static_cast<QWidget*>(o)->installEventFilter(this);
    ms.push_back(static_cast<double>(t.nsecsElapsed()) * 1e-6);
    const qint64 key = w_.organOverlay().cacheKey();
    if (key != lastKey_) ++organFrames;
    lastKey_ = key;
    busy_ = false;
    return true;
  }
  std::vector<double> ms;
  long organFrames = 0;

 private:
  const ui::MainWindow& w_;
  qint64 lastKey_ = 0;
  bool busy_ = false;
};

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5)];
}

struct Phase {
  const char* name;
  double seconds = 0, fps = 0, organFps = 0, paintMedianMs = 0, paintP99Ms = 0, stepsPerSecond = 0;
};

}  // namespace

int main(int argc, char** argv) {
  std::string out = ".";
  ui::MainWindow::Renderer choice = ui::MainWindow::Renderer::Automatic;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--software"))
      choice = ui::MainWindow::Renderer::Software;
    else if (!std::strcmp(argv[i], "--opengl"))
      choice = ui::MainWindow::Renderer::OpenGL;
    else
      out = argv[i];
  }
  QApplication app(argc, argv);
  QCoreApplication::setOrganizationName("RehearseViewBench");
  ui::applyDarkTheme(app);
  ui::MainWindow::setRenderer(choice);
  ui::MainWindow w;
  w.resize(2560, 1400);
  w.show();
  const bool software = !w.overlayUsesOpenGL();
  const std::string mode = std::string(choice == ui::MainWindow::Renderer::Automatic ? "automatic-" : "") +
                           (software ? "qpainter" : "opengl");
  std::printf("%s\n", qPrintable(w.rendererText()));
  if (!QTest::qWaitForWindowExposed(&w)) {
    std::fprintf(stderr, "bench_rehearsal_view: no window (run under xvfb-run)\n");
    return 1;
  }
  w.activateWindow();
  if (!QTest::qWaitForWindowActive(&w))
    std::fprintf(stderr, "bench_rehearsal_view: the window did not become active (measured anyway)\n");
  QSignalSpy loaded(&w, &ui::MainWindow::caseLoaded);
  w.openCase({});
  if (!loaded.wait(120000)) {
    std::fprintf(stderr, "bench_rehearsal_view: the built-in case did not load\n");
    return 1;
  }
  const Pose truth = w.caseData()->groundTruth->pose;
  w.editCase("Register (bench)", [&truth](app::Case& c) {
    c.pose = truth;
    c.hasPose = c.poseAligned = true;
  });
  QTest::keyClick(&w, Qt::Key_7, Qt::AltModifier);
  auto* panel = w.simulationPanel();
  auto* view = w.frameView();
  panel->play();
  waitFor([&] { return panel->lastFrame() && panel->lastFrame()->steps > 100; });
  const auto& c = *w.caseData();
  std::printf("frame %dx%d shown in a %dx%d view (%s)\n", c.frame.cols, c.frame.rows, view->width(), view->height(),
              mode.c_str());
  PaintMeter meter(w);
  view->installEventFilter(&meter);

  auto measure = [&](const char* name, const std::function<QPointF(double)>& path, Qt::Key tool) {
    QTest::keyClick(&w, tool);
    panel->play();
    QTest::mouseMove(view, path(0).toPoint());
    QTest::mousePress(view, Qt::LeftButton, {}, path(0).toPoint());
    meter.ms.clear();
    meter.organFrames = 0;
    const long steps0 = panel->lastFrame()->steps;
    QElapsedTimer t;
    t.start();
    const double seconds = 4.0;
    while (t.elapsed() < seconds * 1000) {
      QTest::mouseMove(view, path(static_cast<double>(t.elapsed()) / (seconds * 1000)).toPoint());
      QTest::qWait(16);
    }
    const double elapsed = static_cast<double>(t.elapsed()) / 1000;
    Phase p{name};
    p.seconds = elapsed;
    p.fps = static_cast<double>(meter.ms.size()) / elapsed;
    p.organFps = static_cast<double>(meter.organFrames) / elapsed;
    p.paintMedianMs = percentile(meter.ms, 0.5);
    p.paintP99Ms = percentile(meter.ms, 0.99);
    p.stepsPerSecond = static_cast<double>(panel->lastFrame()->steps - steps0) / elapsed;
    QTest::mouseRelease(view, Qt::LeftButton, {}, path(1).toPoint());
    waitFor([&] { return !panel->lastFrame()->tool.cutting && panel->lastFrame()->tool.held.empty(); }, 10000);
    return p;
  };
  const Eigen::Vector2d centre = c.camera.project(c.pose.apply(c.organ->centreOfGravity));
  const QPointF mid = view->toWidget(QPointF(centre.x(), centre.y()));
  // Pull: up 2 cm (about 45 px here) and back, twice.
  const Phase pull = measure(
      "pulling", [&](double s) { return mid + QPointF(0, -45 * std::abs(std::sin(2 * M_PI * s))); }, Qt::Key_R);
  // Cut: across the organ's left part, from above its middle down past its lower edge.
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (const auto& p : panel->lastFrame()->positions) {
    const Eigen::Vector2d q = c.camera.project(p);
    x0 = std::min(x0, q.x()), x1 = std::max(x1, q.x()), y0 = std::min(y0, q.y()), y1 = std::max(y1, q.y());
  }
  const QPointF a = view->toWidget(QPointF(x0 + 0.25 * (x1 - x0), y0 + 0.3 * (y1 - y0)));
  const QPointF b = view->toWidget(QPointF(x0 + 0.25 * (x1 - x0), y1 + 0.1 * (y1 - y0)));
  const Phase cut = measure(
      "cutting", [&](double s) { return a + (b - a) * s; }, Qt::Key_B);
  std::printf("cut: %zu elements now\n", panel->lastFrame()->elements);
  // Bleeding: 4 s with no input after a cut through the vessels' trunk, the blood on the surface drawn anew for each new snapshot while a stump
  // bleeds (its film and its layer, on the GUI thread at paint time).
  auto bleedingRate = [&] {
    double rate = 0;
    for (const auto& bl : panel->lastFrame()->field.bleeds)
      if (bl.stoppedBy < 0) rate += bl.rate;
    return rate;
  };
  // The cut that opens the vessel tree's trunk (as test_rehearse_gui's aCutTrunkBleedsWhereTheCameraSeesIt: down the
  // organ at 55 % of its width, the blade 10 notches deeper), not measured: the phase after it is.
  {
    const auto [from, to] = strokeDownTheOrgan(c.camera, panel->lastFrame()->positions, 0.55);
    const QPoint p = view->toWidget(QPointF(from.x(), from.y())).toPoint(),
                 q = view->toWidget(QPointF(to.x(), to.y())).toPoint();
    QTest::keyClick(&w, Qt::Key_B);
    panel->play();
    QTest::mousePress(view, Qt::LeftButton, {}, p);
    waitFor([&] { return panel->lastFrame()->tool.cutting; }, 10000);
    wheelDeeper(view, p, 10);
    for (int i = 1; i <= 20; ++i) {
      QTest::mouseMove(view, p + (q - p) * (i / 20.0));
      const long now = panel->lastFrame()->steps;
      waitFor([&] { return panel->lastFrame()->steps >= now + 3; }, 10000);
    }
    QTest::mouseRelease(view, Qt::LeftButton, {}, q);
    waitFor([&] { return !panel->lastFrame()->tool.cutting && bleedingRate() > 0; }, 30000);
  }
  Phase bleeding{"bleeding"};
  {
    panel->play();
    meter.ms.clear();
    meter.organFrames = 0;
    const long steps0 = panel->lastFrame()->steps;
    QElapsedTimer t;
    t.start();
    while (t.elapsed() < 4000) QTest::qWait(16);
    const double elapsed = static_cast<double>(t.elapsed()) / 1000;
    bleeding.seconds = elapsed;
    bleeding.fps = static_cast<double>(meter.ms.size()) / elapsed;
    bleeding.organFps = static_cast<double>(meter.organFrames) / elapsed;
    bleeding.paintMedianMs = percentile(meter.ms, 0.5);
    bleeding.paintP99Ms = percentile(meter.ms, 0.99);
    bleeding.stepsPerSecond = static_cast<double>(panel->lastFrame()->steps - steps0) / elapsed;
  }
  std::printf("bleeding: %.2f mL/s from the cut's open stumps%s\n", 1e6 * bleedingRate(),
              bleedingRate() > 0 ? "" : " (the cut opened no vessel: the phase measures a view without blood)");

  std::filesystem::create_directories(out);
  const std::string file = out + "/rehearsal-view-" + mode + ".csv";
  std::ofstream csv(file);
  csv << "renderer,phase,seconds,view_fps,organ_fps,paint_median_ms,paint_p99_ms,sim_steps_per_s,frame_w,frame_h,view_"
         "w,view_h\n";
  std::printf("%-9s %8s %9s %10s %14s %12s %12s\n", "phase", "seconds", "view fps", "organ fps", "paint med ms",
              "paint p99", "steps/s");
  for (const Phase& p : {pull, cut, bleeding}) {
    std::printf("%-9s %8.2f %9.1f %10.1f %14.2f %12.2f %12.1f\n", p.name, p.seconds, p.fps, p.organFps, p.paintMedianMs,
                p.paintP99Ms, p.stepsPerSecond);
    csv << mode << ',' << p.name << ',' << p.seconds << ',' << p.fps << ',' << p.organFps << ',' << p.paintMedianMs
        << ',' << p.paintP99Ms << ',' << p.stepsPerSecond << ',' << c.frame.cols << ',' << c.frame.rows << ','
        << view->width() << ',' << view->height() << '\n';
  }
  std::printf("wrote %s\n", file.c_str());
  return 0;
}
