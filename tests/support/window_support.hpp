#pragma once
// The GUI suites' shared hand: the real main window opened on the built-in phantom case as the application shows it
// (dark theme, 1600x900, active for keyboard shortcuts), a screenshot for the README, a drag as a hand makes it.
#include "fresh_start.hpp"
#include "rehearse/ui/pages/meshpage.hpp"
#ifdef REHEARSE_SHARED_DATA
#include "test_support.hpp"
#endif
#include "rehearse/ui/gui.hpp"
#include "rehearse/ui/mainwindow.hpp"
#include "rehearse/ui/simulationpanel.hpp"

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <opencv2/imgproc.hpp>

#include <QAbstractItemView>
#include <QAbstractScrollArea>
#include <QAbstractSpinBox>
#include <QCheckBox>
#include <QComboBox>
#include <QDockWidget>
#include <QGraphicsView>
#include <QLabel>
#include <QLineEdit>
#include <QMenuBar>
#include <QMessageBox>
#include <QProgressBar>
#include <QRadioButton>
#include <QSlider>
#include <QTabBar>
#include <QToolBar>
#include <QApplication>
#include <QElapsedTimer>
#include <QEventLoop>
#include <QFile>
#include <QPointer>
#include <QTimer>
#include <QWheelEvent>
#include <QSignalSpy>
#include <QStandardPaths>
#include <QtTest>

#include <algorithm>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

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
// What a person would find cut off or drawn over in `window` at its present size (issue 62): a label or button whose
// text needs more room than it has, a widget reaching outside the window, two widgets drawn over each other. Widgets
// inside a scroll area count where they can be scrolled to (the part outside its viewport is not cut off); the inner
// parts of boxes, lists and tool bars are theirs. One line per problem; empty when there is none.
inline QString shownText(const QLabel* label) {  // without its mnemonic's ampersand ("&Tolerance:")
  QString t = label->text();
  if (label->buddy()) t.replace(QRegularExpression("&(?=[^&])"), QString());
  return t;
}
inline QStringList layoutProblems(QWidget* window) {
  auto name = [](QWidget* w) {
    QString n = w->objectName().isEmpty() ? QString::fromLatin1(w->metaObject()->className()) : w->objectName();
    if (auto* l = qobject_cast<QLabel*>(w)) n += " \"" + l->text().left(50) + "\"";
    if (auto* b = qobject_cast<QAbstractButton*>(w)) n += " \"" + b->text() + "\"";
    return n;
  };
  auto insideOf = [](QWidget* w, auto isKind) {
    for (QWidget* p = w->parentWidget(); p; p = p->parentWidget())
      if (isKind(p)) return true;
    return false;
  };
  auto part = [](QWidget* p) {  // widgets whose children are their own inner parts
    return qobject_cast<QComboBox*>(p) || qobject_cast<QAbstractSpinBox*>(p) || qobject_cast<QAbstractItemView*>(p) ||
           qobject_cast<QToolBar*>(p) || qobject_cast<QTabBar*>(p) || qobject_cast<QMenuBar*>(p);
  };
  auto scrolled = [](QWidget* p) { return qobject_cast<QAbstractScrollArea*>(p) != nullptr; };
  auto seen = [window](QWidget* w) {  // the part a person sees, in the window's coordinates
    QRect r(w->mapTo(window, QPoint(0, 0)), w->size());
    for (QWidget* p = w->parentWidget(); p && p != window; p = p->parentWidget())
      r &= QRect(p->mapTo(window, QPoint(0, 0)), p->size());
    return r & window->rect();
  };
  QStringList out;
  std::vector<std::pair<QWidget*, QRect>> shown;
  for (QWidget* w : window->findChildren<QWidget*>()) {
    if (!w->isVisible() || w->isWindow() || insideOf(w, part) || w->inherits("QDockWidgetTitleButton")) continue;
    auto* label = qobject_cast<QLabel*>(w);
    auto* button = qobject_cast<QAbstractButton*>(w);
    const bool leaf = (label && !label->text().isEmpty()) || button || qobject_cast<QComboBox*>(w) ||
                      qobject_cast<QAbstractSpinBox*>(w) || qobject_cast<QLineEdit*>(w) ||
                      qobject_cast<QGraphicsView*>(w) || qobject_cast<QProgressBar*>(w) || qobject_cast<QSlider*>(w);
    if (!leaf) continue;
    const QRect whole(w->mapTo(window, QPoint(0, 0)), w->size());
    if (!insideOf(w, scrolled) && !window->rect().contains(whole))
      out << QString("%1 reaches outside the window (%2,%3 %4x%5 in %6x%7)")
                 .arg(name(w))
                 .arg(whole.x())
                 .arg(whole.y())
                 .arg(whole.width())
                 .arg(whole.height())
                 .arg(window->width())
                 .arg(window->height());
    if (label && label->pixmap().isNull() && !label->property("elidesItsText").toBool()) {
      const QRect room = label->contentsRect();
      const int needs = label->wordWrap() ? label->heightForWidth(label->width()) : label->sizeHint().height();
      if (needs > label->height() + 1)
        out << QString("%1 is cut off: its text needs %2 px of height, it has %3").arg(name(w)).arg(needs).arg(label->height());
      else if (!label->wordWrap() && label->sizePolicy().horizontalPolicy() != QSizePolicy::Ignored &&
               label->fontMetrics().horizontalAdvance(shownText(label)) > room.width() + 1 &&
               label->textFormat() != Qt::RichText && !Qt::mightBeRichText(label->text()))
        out << QString("%1 is cut off: its text needs %2 px of width, it has %3")
                   .arg(name(w))
                   .arg(label->fontMetrics().horizontalAdvance(shownText(label)))
                   .arg(room.width());
    }
    if (button && !button->text().isEmpty() && button->sizeHint().width() > button->width() + 1 &&
        !qobject_cast<QCheckBox*>(w) && !qobject_cast<QRadioButton*>(w))
      out << QString("%1 is cut off: it needs %2 px of width, it has %3").arg(name(w)).arg(button->sizeHint().width()).arg(button->width());
    const QRect r = seen(w);
    // Cut off by a scroll area that does not scroll sideways (its page wider than its viewport).
    for (QWidget* p = w->parentWidget(); p; p = p->parentWidget())
      if (auto* area = qobject_cast<QAbstractScrollArea*>(p);
          area && area->horizontalScrollBarPolicy() == Qt::ScrollBarAlwaysOff && !qobject_cast<QAbstractItemView*>(area)) {
        const QRect port(area->viewport()->mapTo(window, QPoint(0, 0)), area->viewport()->size());
        if (whole.right() > port.right() + 1 && whole.left() < port.right())
          out << QString("%1 is cut off on the right by its scroll area (%2 px of %3)")
                     .arg(name(w))
                     .arg(port.right() - whole.left())
                     .arg(whole.width());
        break;
      }
    if (!r.isEmpty()) shown.emplace_back(w, r);
  }
  for (std::size_t i = 0; i < shown.size(); ++i)
    for (std::size_t j = i + 1; j < shown.size(); ++j) {
      const auto& [a, ra] = shown[i];
      const auto& [b, rb] = shown[j];
      if (a->isAncestorOf(b) || b->isAncestorOf(a)) continue;
      const QRect both = ra & rb;
      if (both.width() > 2 && both.height() > 2)
        out << QString("%1 and %2 are drawn over each other (%3x%4 px)").arg(name(a), name(b)).arg(both.width()).arg(both.height());
    }
  return out;
}

inline void shot(QWidget& w, const char* name) {
  const QByteArray dir = qgetenv("REHEARSE_SCREENSHOT_DIR");
  if (dir.isEmpty()) return;
  QTest::qWait(50);
  w.grab().save(QString::fromLocal8Bit(dir) + "/" + name + ".png");
}

// Waits (serving events) until `done` holds, at most `ms`; its last answer. It asks every 10 ms, serving events in an
// event loop as the application's own does (QTest::qWait sleeps 10 ms between its rounds of events: a window waited
// for that way looks paused for 10-20 ms to the ping monitor, whatever it does).
inline bool waitFor(const std::function<bool()>& done, int ms = 60000) {
  QElapsedTimer t;
  t.start();
  while (t.elapsed() < ms) {
    if (done()) return true;
    QEventLoop loop;
    QTimer::singleShot(10, &loop, &QEventLoop::quit);
    loop.exec();
    QCoreApplication::sendPostedEvents(nullptr, QEvent::DeferredDelete);
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
#ifdef REHEARSE_SHARED_DATA  // (the suites that read ../shared/data)
// The scikit-surgery frame with its intrinsics, and the patient liver imported over it through step 1's page
// (millimetres, meshed to about `tets` elements), as an assistant does; empty when all went in, else why not.
[[nodiscard]] inline QString importPatientLiverOverItsFrame(rehearse::ui::MainWindow& w, int tets = 3600) {
  if (const QString why = openFrameWithIntrinsics(w, sharedData("scikit-surgery/laparoscopy-liver-frame.jpg"),
                                                  sharedData("scikit-surgery/laparoscopy-liver-frame.intrinsics.txt"));
      !why.isEmpty())
    return why;
  w.meshPage()->setMeshUnit("mm");
  w.meshPage()->setTargetTets(tets);
  QSignalSpy imported(&w, &rehearse::ui::MainWindow::meshImported);
  w.meshPage()->importMesh(QString::fromStdString(sharedData("scikit-surgery/patient-liver/liver.vtk")));
  if (!imported.wait(180000)) return QStringLiteral("the import did not finish within 180 s");
  return imported.first().at(0).toBool() ? QString() : imported.first().at(1).toString();
}
#endif
// Types `text` into a spin box as a user does (all selected, the digits, then `end`: Return, or Tab to leave it).
// An edit that starts another session over a rehearsal nothing keeps asks first ("endRehearsalBox", opened by the edit
// itself): answered Discard, as a person ending it would. False when a box was asked and did not go.
inline bool discardTheRehearsalIfAsked(rehearse::ui::MainWindow& w) {
  auto* box = w.findChild<QMessageBox*>("endRehearsalBox");
  if (!box) return true;
  QTest::mouseClick(box->button(QMessageBox::Discard), Qt::LeftButton);
  const bool gone = waitFor([&] { return !w.findChild<QMessageBox*>("endRehearsalBox"); }, 10000);
  w.activateWindow();  // (the window manager gives it back after a box; offscreen has none)
  return gone && QTest::qWaitForWindowActive(&w);
}

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

// Counts the layout passes Qt asks of a widget (its LayoutRequest events) while it lives: a label's new text must not
// lay the window out again (issue 64: 11-22 ms of the GUI thread each, 15 times a second while rehearsing).
class LayoutRequests : public QObject {
 public:
  explicit LayoutRequests(QWidget* watched) : watched_(watched) { watched->installEventFilter(this); }
  ~LayoutRequests() override {
    if (watched_) watched_->removeEventFilter(this);
  }
  int count() const { return count_; }
  bool eventFilter(QObject*, QEvent* e) override {
    if (e->type() == QEvent::LayoutRequest) ++count_;
    return false;
  }

 private:
  QPointer<QWidget> watched_;
  int count_ = 0;
};

// The ping monitor of issue 62: a timer every 10 ms on the GUI thread; the longest gap between two of its ticks is the
// longest the window was frozen (busy on the GUI thread) while it ran.
class PingMonitor {
 public:
  void start() {
    clock_.start();
    last_ = 0;
    worst_ = 0;
    lastRun_ = readSchedstat();
    worstRun_ = {};
    QObject::connect(&timer_, &QTimer::timeout, [this] { tick(); });
    timer_.start(10);
  }
  qint64 stop() {
    tick();
    timer_.stop();
    timer_.disconnect();
    return worst_;
  }
  qint64 worst() const { return worst_; }
  /// Of the longest gap: how long the GUI thread ran and how long it waited for a core (the kernel's schedstat; both
  /// -1 where the kernel does not keep it). The rest of the gap it slept (on a lock, or in a call that waits).
  std::pair<double, double> worstSplitMs() const { return {worstRun_.runMs, worstRun_.waitMs}; }

 private:
  struct Sched {
    double runMs = -1, waitMs = -1;
  };
  static Sched readSchedstat() {
    QFile f(QStringLiteral("/proc/thread-self/schedstat"));
    Sched s;
    if (!f.open(QIODevice::ReadOnly)) return s;
    const QList<QByteArray> v = f.readAll().simplified().split(' ');
    if (v.size() >= 2) {
      s.runMs = v[0].toDouble() / 1e6;
      s.waitMs = v[1].toDouble() / 1e6;
    }
    return s;
  }
  void tick() {
    const qint64 now = clock_.elapsed();
    const Sched sched = readSchedstat();
    if (now - last_ > worst_) {
      worst_ = now - last_;
      worstRun_ = sched.runMs < 0 || lastRun_.runMs < 0
                      ? Sched{}
                      : Sched{sched.runMs - lastRun_.runMs, sched.waitMs - lastRun_.waitMs};
    }
    last_ = now;
    lastRun_ = sched;
  }
  QTimer timer_;
  QElapsedTimer clock_;
  qint64 last_ = 0, worst_ = 0;
  Sched lastRun_, worstRun_;
};

// The longest pause of the window in each action of step 7 (issue 64: no action pauses the window more than 50 ms),
// measured by a PingMonitor from the action's first input to its effect, the test's own computations left outside.
// A measurement, not an assertion (timed assertions flake on shared machines): printed when the object goes, and
// appended to the CSV file $REHEARSE_PAUSES_CSV names (case, action, times measured, worst ms, median ms,
// in the worst the GUI thread's ms running and waiting for a core) for
// BENCHMARKS.md.
class ActionPauses {
 public:
  explicit ActionPauses(QString organ) : organ_(std::move(organ)) {}
  ActionPauses(const ActionPauses&) = delete;
  ActionPauses& operator=(const ActionPauses&) = delete;
  ~ActionPauses() {
    const QByteArray csv = qgetenv("REHEARSE_PAUSES_CSV");
    QFile file(QString::fromLocal8Bit(csv));
    const bool writing = !csv.isEmpty() && file.open(QIODevice::Append | QIODevice::Text);
    for (auto& [action, ms] : pauses_) {
      const auto split = split_[action];
      std::sort(ms.begin(), ms.end());
      const qint64 median = ms[ms.size() / 2], worst = ms.back();
      qInfo("the window's longest pause, %s, %s: %lld ms (%zu times, median %lld ms); in it the GUI thread ran %.0f ms "
            "and waited %.0f ms for a core",
            qPrintable(organ_), action.c_str(), static_cast<long long>(worst), ms.size(),
            static_cast<long long>(median), split.first, split.second);
      if (writing)
        file.write(QStringLiteral("\"%1\",\"%2\",%3,%4,%5,%6,%7\n")
                       .arg(organ_, QString::fromStdString(action))
                       .arg(ms.size())
                       .arg(worst)
                       .arg(median)
                       .arg(split.first, 0, 'f', 1)
                       .arg(split.second, 0, 'f', 1)
                       .toUtf8());
    }
  }
  void start() { ping_.start(); }
  void stop(const std::string& action) {
    const qint64 ms = ping_.stop();
    auto& all = pauses_[action];
    if (all.empty() || ms > *std::max_element(all.begin(), all.end())) split_[action] = ping_.worstSplitMs();
    all.push_back(ms);
  }

 private:
  QString organ_;
  PingMonitor ping_;
  std::map<std::string, std::vector<qint64>> pauses_;
  std::map<std::string, std::pair<double, double>> split_;  // of each action's longest pause: ran, waited (ms)
};
}  // namespace
