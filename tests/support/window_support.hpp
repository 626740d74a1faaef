#pragma once
// The GUI suites' shared hand: the real main window opened on the built-in phantom case as the application shows it
// (dark theme, 1600x900, active for keyboard shortcuts), a screenshot for the README, a drag as a hand makes it.
#include "fresh_start.hpp"
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <opencv2/imgproc.hpp>

#include <QAbstractSpinBox>
#include <QApplication>
#include <QElapsedTimer>
#include <QTimer>
#include <QWheelEvent>
#include <QSignalSpy>
#include <QStandardPaths>
#include <QtTest>

#include <functional>
#include <memory>

namespace {
// A view's image as 8-bit BGR (what the imaging code compares).
inline cv::Mat3b toMat(const QImage& image) {
  const QImage rgb = image.convertToFormat(QImage::Format_RGB888);
  cv::Mat3b bgr;
  cv::cvtColor(cv::Mat(rgb.height(), rgb.width(), CV_8UC3, const_cast<uchar*>(rgb.constBits()),
                       static_cast<std::size_t>(rgb.bytesPerLine())),
               bgr, cv::COLOR_RGB2BGR);
  return bgr;
}

// Where a cut organ is seen through the case's camera (`organ`, 255) and where its cut faces are (`cut`): the session's
// positions are in the camera frame.
struct CutFacesSeen {
  cv::Mat1b organ, cut;
};
inline CutFacesSeen cutFacesSeen(const rehearse::imaging::Camera& camera, const std::vector<Eigen::Vector3d>& positions,
                                 const rehearse::simcore::CutSurface& surface) {
  std::vector<double> xyz;
  for (const auto& p : positions) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
  const rehearse::SurfaceView sv{xyz.data(), positions.size(), surface.triangles.front().data(),
                                 surface.triangles.size()};
  const auto g = rehearse::imaging::surfaceGeometry(camera, rehearse::Pose{}, sv);
  CutFacesSeen out{g.mask(), cv::Mat1b(g.triangle.size(), uchar(0))};
  for (int y = 0; y < g.triangle.rows; ++y)
    for (int x = 0; x < g.triangle.cols; ++x)
      if (const int t = g.triangle(y, x); t >= 0 && surface.cut[static_cast<std::size_t>(t)]) out.cut(y, x) = 255;
  return out;
}

// A scissors stroke down the organ (frame pixels): at `atWidth` of its width in the image, from a tenth of its height
// below its top there to a tenth of its height past its bottom; `cameraPoints` are its nodes in the camera frame.
inline std::pair<Eigen::Vector2d, Eigen::Vector2d> strokeDownTheOrgan(const rehearse::imaging::Camera& camera,
                                                                      const std::vector<Eigen::Vector3d>& cameraPoints,
                                                                      double atWidth) {
  double x0 = 1e9, x1 = -1e9;
  std::vector<Eigen::Vector2d> px;
  for (const auto& p : cameraPoints) {
    px.push_back(camera.project(p));
    x0 = std::min(x0, px.back().x()), x1 = std::max(x1, px.back().x());
  }
  const double column = x0 + atWidth * (x1 - x0);
  double y0 = 1e9, y1 = -1e9;
  for (const auto& p : px)
    if (std::abs(p.x() - column) < 6) y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  return {Eigen::Vector2d(column, y0 + 0.1 * (y1 - y0)), Eigen::Vector2d(column, y1 + 0.1 * (y1 - y0))};
}

// Opens the main window on the phantom case; false (with a QWARN) when it did not come up.
[[nodiscard]] inline bool openPhantomCase(std::unique_ptr<rehearse::ui::MainWindow>& w) {
  using rehearse::ui::MainWindow;
  forgetEarlierRuns();
  rehearse::ui::applyDarkTheme(*qApp);  // as the application runs (and as the README screenshots show it)
  w = std::make_unique<MainWindow>();
  w->resize(1600, 900);
  w->show();
  if (!QTest::qWaitForWindowExposed(w.get())) return false;
  w->activateWindow();  // keyboard shortcuts need the active window (under a real X server too)
  if (!QTest::qWaitForWindowActive(w.get())) return false;
  QSignalSpy loaded(w.get(), &MainWindow::caseLoaded);
  w->openCase({});
  return loaded.wait(60000);
}
}  // namespace

namespace {
inline void shot(QWidget& w, const char* name) {
  const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR");
  if (dir.isEmpty()) return;
  QTest::qWait(50);
  w.grab().save(QString::fromLocal8Bit(dir) + "/" + name + ".png");
}

// Waits (serving events) until `done` holds, at most `ms`; its last answer.
inline bool waitFor(const std::function<bool()>& done, int ms = 60000) {
  QElapsedTimer t;
  t.start();
  while (t.elapsed() < ms) {
    if (done()) return true;
    QTest::qWait(10);
  }
  return done();
}

// Drags with the left button from a to b in steps (as a hand would).
inline void drag(QWidget* target, QPointF a, QPointF b, int steps = 8, Qt::KeyboardModifiers mods = {}) {
  QTest::mousePress(target, Qt::LeftButton, mods, a.toPoint());
  for (int i = 1; i <= steps; ++i) QTest::mouseMove(target, (a + (b - a) * (double(i) / steps)).toPoint());
  QTest::mouseRelease(target, Qt::LeftButton, mods, b.toPoint());
}

// The wheel turned `notches` notches towards the user at `at` while the left button holds (the scissors' blade deeper);
// a negative count turns it away (shallower).
inline void wheelDeeper(QWidget* target, QPoint at, int notches) {
  for (int notch = 0; notch < std::abs(notches); ++notch) {
    QWheelEvent wheel(QPointF(at), QPointF(target->mapToGlobal(at)), QPoint(), QPoint(0, notches > 0 ? -120 : 120),
                      Qt::LeftButton, Qt::NoModifier, Qt::NoScrollPhase, false);
    QApplication::sendEvent(target, &wheel);
  }
}

// A frame and its intrinsics opened through step 2's page, as an assistant does; empty when both went in, else why not.
[[nodiscard]] inline QString openFrameWithIntrinsics(rehearse::ui::MainWindow& w, const std::string& frame,
                                                     const std::string& intrinsics) {
  QSignalSpy opened(&w, &rehearse::ui::MainWindow::frameSourceOpened);
  w.framePage()->openFrameSource(QString::fromStdString(frame));
  if (opened.count() == 0 && !opened.wait(60000)) return QStringLiteral("the frame did not open within 60 s");
  if (!opened.first().at(0).toBool()) return opened.first().at(1).toString();
  w.framePage()->loadCalibration(QString::fromStdString(intrinsics));
  return {};
}
// Types `text` into a spin box as a user does (all selected, the digits, then `end`: Return, or Tab to leave it).
inline void typeInto(QAbstractSpinBox* box, const QString& text, Qt::Key end = Qt::Key_Return) {
  box->selectAll();
  QTest::keyClicks(box, text);
  QTest::keyClick(box, end);
}

// What the simulation panel's session said and which events it raised, a line per shown frame that had either
// ("step N: events message"; at most `cap` lines), kept while this lives: for the failure messages of the GUI
// suites and for what they wait on.
class SessionHeard : public QObject {
 public:
  explicit SessionHeard(rehearse::ui::SimulationPanel* panel, int cap = 200) {
    QObject::connect(panel, &rehearse::ui::SimulationPanel::frameShown, this, [this, panel, cap](long) {
      const auto f = panel->lastFrame();
      if (!f) return;
      QString line;
      for (const auto& e : f->events) line += QString::fromStdString(e) + " ";
      if ((!f->message.isEmpty() || !line.isEmpty()) && lines.size() < cap)
        lines << QString("step %1: %2%3").arg(f->steps).arg(line, f->message);
    });
  }
  QStringList lines;
};

// A review window's seek lands off the GUI thread (issue 62): the time asks for `step` at once, the view shows it
// when the seek has landed.
template <class Review>
[[nodiscard]] inline bool landsOn(Review* review, int attempt, long step, int ms = 60000) {
  if (review->stepWanted(attempt) != step) {
    qWarning("the review's time asks for step %ld, not %ld", review->stepWanted(attempt), step);
    return false;
  }
  if (!waitFor([&] { return review->stepShown(attempt) == step && !review->seeking(); }, ms)) {
    qWarning("the review's view shows step %ld, not %ld", review->stepShown(attempt), step);
    return false;
  }
  return true;
}

// The ping monitor of issue 62: a timer every 10 ms on the GUI thread; the longest gap between two of its ticks is the
// longest the window was frozen (busy on the GUI thread) while it ran.
class PingMonitor {
 public:
  void start() {
    clock_.start();
    last_ = 0;
    worst_ = 0;
    QObject::connect(&timer_, &QTimer::timeout, [this] {
      const qint64 now = clock_.elapsed();
      worst_ = std::max(worst_, now - last_);
      last_ = now;
    });
    timer_.start(10);
  }
  qint64 stop() {
    const qint64 now = clock_.elapsed();
    worst_ = std::max(worst_, now - last_);
    timer_.stop();
    timer_.disconnect();
    return worst_;
  }
  qint64 worst() const { return worst_; }

 private:
  QTimer timer_;
  QElapsedTimer clock_;
  qint64 last_ = 0, worst_ = 0;
};
}  // namespace
