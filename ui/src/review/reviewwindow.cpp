#include "rehearse/ui/reviewwindow.hpp"

#include "rehearse/ui/reviewreport.hpp"

#include <rehearse/simcore/session/events.hpp>
#include <QAction>
#include <QApplication>
#include <QComboBox>
#include <QDateTime>
#include <QLocale>
#include <QDir>
#include <QFileInfo>
#include <QEventLoop>
#include <QFileDialog>
#include <QFutureWatcher>
#include <QGuiApplication>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QInputDialog>
#include <QKeyEvent>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QMouseEvent>
#include <QResizeEvent>
#include <QPainter>
#include <QPainterPath>
#include <QProgressDialog>
#include <QPushButton>
#include <QScreen>
#include <QSignalBlocker>
#include <QSplitter>
#include <QStatusBar>
#include <QSysInfo>
#include <QThreadPool>
#include <QTableWidget>
#include <QTimer>
#include <QToolBar>
#include <QVBoxLayout>
#include <QtConcurrent/QtConcurrentRun>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <mutex>

namespace rehearse::ui {

namespace {

QImage toQImage(const cv::Mat3b& m) { return QImage(m.data, m.cols, m.rows, static_cast<qsizetype>(m.step), QImage::Format_BGR888).copy(); }

// The attempt's force over time, the events as ticks, the threshold dashed and the playhead; a click or a
// drag seeks (through `seek`, the window's common time).
class TimelineWidget : public QWidget {
 public:
  std::function<void(double)> seek;
  /// The samples replayed so far (all of them once the replay is done).
  std::shared_ptr<const std::vector<app::TimelineSample>> timeline;
  double threshold = 0, now = 0;
  double total = 1;               ///< s: the time axis' length (the session's, expected from its steps while replaying)
  long replayed = 0, steps = 0;   ///< while the replay runs: how far it is
  bool done = false;              ///< the replay is complete
  TimelineWidget() {
    setObjectName(QStringLiteral("timeline"));
    setMinimumHeight(110);
    setCursor(Qt::PointingHandCursor);
    setToolTip(
        tr("Tool force over time; ticks: grasp (green), slip (orange), cut (purple), vessel cut (red), force over the "
           "threshold (grey; the threshold is the dashed line), incorrect action (cyan, longer). Click or drag to "
           "seek."));
  }
  double timeAt(double x) const {
    return std::clamp((x - 8) / std::max(1.0, width() - 16.0), 0.0, 1.0) * total;
  }
  double xAt(double t) const { return 8 + t / std::max(1e-9, total) * (width() - 16.0); }

 protected:
  void paintEvent(QPaintEvent*) override {
    QPainter p(this);
    p.fillRect(rect(), QColor(30, 32, 36));
    if (!done) {  // the part not replayed yet, shaded, and how far the replay is
      const double x0 = timeline && !timeline->empty() ? xAt(timeline->back().time) : 8;
      p.fillRect(QRectF(x0, 0, width() - x0, height()), QColor(45, 48, 54));
      p.setPen(Qt::lightGray);  // in the part still to come (shorter where it is narrow)
      const QRectF rest(x0 + 8, 20, width() - x0 - 16, height() - 24);
      const QString full = steps > 0 ? tr("replaying the session to check it: step %1 of %2 (the view reaches the part "
                                          "replayed)")
                                           .arg(replayed)
                                           .arg(steps)
                                     : tr("replaying the session to check it...");
      const QString brief = steps > 0 ? tr("replaying: %1 %").arg(100 * replayed / std::max(1L, steps)) : tr("replaying");
      const bool fits = p.fontMetrics().boundingRect(rest.toRect(), Qt::TextWordWrap, full).height() <= rest.height();
      if (fits)
        p.drawText(rest, Qt::AlignCenter | Qt::TextWordWrap, full);
      else  // (a narrow part left: at the right edge, whole)
        p.drawText(QRectF(8, rest.top(), width() - 16, rest.height()), Qt::AlignRight | Qt::AlignVCenter, brief);
    }
    if (!timeline || timeline->empty()) return;
    double fmax = std::max(threshold, 1e-6);
    for (const auto& s : *timeline) fmax = std::max(fmax, s.force);
    fmax *= 1.1;
    const double top = 22, bottom = height() - 6;
    auto Y = [&](double f) { return bottom - f / fmax * (bottom - top); };
    if (threshold > 0) {
      p.setPen(QPen(QColor(220, 80, 80), 1, Qt::DashLine));
      p.drawLine(QPointF(8, Y(threshold)), QPointF(width() - 8, Y(threshold)));
    }
    QPainterPath path;
    path.moveTo(xAt(timeline->front().time), Y(timeline->front().force));
    for (const auto& s : *timeline) path.lineTo(xAt(s.time), Y(s.force));
    p.setPen(QPen(QColor(90, 160, 255), 1.5));
    p.drawPath(path);
    // The force crossing the threshold first: what happened at the same step (a slip at the grasp's limit) is drawn
    // over its grey tick, not hidden under it.
    for (const bool crossings : {true, false})
      for (const auto& s : *timeline)
        for (const auto& e : s.events) {
          const simcore::EventKind kind = simcore::eventKind(e);
          if ((kind == simcore::EventKind::ForceOverThreshold) != crossings) continue;
          const QColor c = reviewEventColour(e);  // as the report names them
          if (!c.isValid()) continue;
          p.setPen(QPen(c, 3));
          p.drawLine(QPointF(xAt(s.time), 2),
                     QPointF(xAt(s.time), kind == simcore::EventKind::IncorrectAction ? 34 : 16));
        }
    p.setPen(QPen(Qt::white, 2));
    p.drawLine(QPointF(xAt(now), 0), QPointF(xAt(now), height()));
    p.setPen(Qt::lightGray);
    p.drawText(QRectF(width() - 160, 2, 150, 18), Qt::AlignRight, QStringLiteral("%1 N max").arg(fmax / 1.1, 0, 'f', 1));
  }
  void mousePressEvent(QMouseEvent* e) override {
    if (seek) seek(timeAt(e->position().x()));
  }
  void mouseMoveEvent(QMouseEvent* e) override {
    if ((e->buttons() & Qt::LeftButton) && seek) seek(timeAt(e->position().x()));
  }
};

// The view: the rendered image, scaled to fit; a drag turns the 3D view.
class ViewLabel : public QLabel {
 public:
  std::function<void(double, double)> turn;
  ViewLabel() {
    setObjectName(QStringLiteral("reviewView"));
    setMinimumSize(320, 240);
    setAlignment(Qt::AlignCenter);
    setStyleSheet("background: #202226");
  }

 protected:
  void resizeEvent(QResizeEvent* e) override {  // the picture follows the view's size
    QLabel::resizeEvent(e);
    const QImage image = property("image").value<QImage>();
    if (!image.isNull()) setPixmap(QPixmap::fromImage(image.scaled(size(), Qt::KeepAspectRatio, Qt::SmoothTransformation)));
  }
  void mousePressEvent(QMouseEvent* e) override { last_ = e->position(); }
  void mouseMoveEvent(QMouseEvent* e) override {
    if (!(e->buttons() & Qt::LeftButton) || !turn) return;
    const QPointF d = e->position() - last_;
    last_ = e->position();
    turn(d.x() * 0.01, -d.y() * 0.01);
  }

 private:
  QPointF last_;
};

}  // namespace

// Where a seek landed (computed off the GUI thread: a seek replays up to a checkpoint interval of steps, a second or
// more on a large organ; issue 62 measured a 7.6 s freeze while dragging the timeline).
struct SeekResult {
  long step = 0;
  long generation = 0;  ///< ReviewAttempt::viewGeneration it was drawn for
  QImage image;         ///< the view's picture (drawn on the worker too)
  QImage scaled;        ///< the same at the view's size
  std::string note;     ///< Replayer::lastSeekNote
  std::string error;    ///< the seek failed (a damaged recording)
};

// Between a session's replay (on the window's replay pool) and the GUI thread: the replay leaves what it has so far here
// (the GUI thread takes it on a timer; nothing is posted to a window that may be gone), and stops when asked.
struct ReplayControl {
  std::mutex mutex;
  std::condition_variable changed;
  bool stop = false;
  long holdAt = -1;  ///< the replay waits after this step until it is changed (ReviewWindow::holdReplaysAt)
  bool fresh = false;
  long step = 0, steps = 0;
  std::shared_ptr<const std::vector<app::TimelineSample>> line;
  app::VerifyResult verify;
  std::chrono::steady_clock::time_point published;
  void halt() {
    {
      std::lock_guard<std::mutex> lock(mutex);
      stop = true;
    }
    changed.notify_all();
  }
  void hold(long step) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      holdAt = step;
    }
    changed.notify_all();
  }
};

// The view's replayer and renderers, built on a worker (a large organ's session takes a while to build).
struct ReviewViewer {
  std::shared_ptr<app::Replayer> replayer;
  std::unique_ptr<app::ReviewRenderer> frame, orbit;
};

class ReviewAttempt {
 public:
  ~ReviewAttempt() {
    // Nothing is waited for: the replay stops at its next step, and the reading, the view's building and a seek hold
    // what they use (their watchers go with the attempt, so nothing lands here).
    if (control) control->halt();
  }
  std::unique_ptr<QFutureWatcher<app::Recording>> loader;
  QWidget* widget = nullptr;
  QLabel* title = nullptr;
  ViewLabel* view = nullptr;
  TimelineWidget* timelineView = nullptr;
  QTableWidget* table = nullptr;
  app::Recording recording;
  app::ReplayResult result;
  std::shared_ptr<app::Replayer> replayer;  ///< the view's (a seek on a worker holds it too)
  std::unique_ptr<app::ReviewRenderer> frameRenderer, orbitRenderer;
  bool ready = false;
  QString error;
  QFutureWatcher<app::ReplayResult>* watcher = nullptr;
  std::shared_ptr<ReplayControl> control;
  std::unique_ptr<QFutureWatcher<std::shared_ptr<ReviewViewer>>> viewerWatcher;
  bool viewable = false;  ///< the replayer and renderers are built: the view seeks (as far as the replay has checked)
  /// The samples replayed so far (the whole timeline once ready), the checksums and checkpoints compared so far, how
  /// far the replay is and how long the session is expected to be (its steps times its time step).
  std::shared_ptr<const std::vector<app::TimelineSample>> line = std::make_shared<const std::vector<app::TimelineSample>>();
  app::VerifyResult checkedSoFar;
  long replayed = 0, replaySteps = 0;
  double expectedDuration = 0;
  // The view's seek, one at a time on a worker: the newest step asked for while one runs is sought next (a drag's
  // intermediate positions are skipped); the view shows `shown` (its snapshot) until the next one lands.
  std::unique_ptr<QFutureWatcher<SeekResult>> seeker;
  long wanted = -1;  ///< the step the window's time asks for
  long shown = -1;   ///< the step the view shows (-1: none yet)
  long lastStep = 0; ///< Replayer::steps(), read once (the replayer is the worker's while a seek runs)
  std::string seekNote;
  long viewGeneration = 0;   ///< counts changes of the view (3D or frame, a turn): a picture for an older one is stale
  long shownGeneration = -1; ///< the generation of the picture shown
  bool stale() const { return shown != wanted || shownGeneration != viewGeneration; }

  /// The last step a seek may go to: the replay's checked part until it is done.
  long reachable() const { return viewable ? (ready ? lastStep : std::min(replayed, lastStep)) : 0; }
  long stepAt(double t) const { return std::min(app::stepAtTime(*line, t), reachable()); }
  /// The time shown so far (the replayed part).
  double available() const { return line->empty() ? 0 : line->back().time; }
  /// The view's renderer: the case's frame, or the 3D view (always without a case camera).
  const app::ReviewRenderer& renderer(bool threeD) const { return threeD || !frameRenderer ? *orbitRenderer : *frameRenderer; }
  double duration() const { return ready ? available() : std::max(expectedDuration, available()); }
};

ReviewWindow::ReviewWindow(const QString& file, std::optional<imaging::Camera> camera, cv::Mat3b frame, QWidget* parent)
    : ReviewWindow([f = file.toStdString()] { return app::listRecordings(f); }, [f = file.toStdString()](qint64 id) { return app::loadRecording(f, id); }, file,
                   std::move(camera), std::move(frame), parent, true) {
  file_ = file;
  try {
    const std::string kept = app::loadCaseThresholds(file.toStdString());
    if (!kept.empty()) {  // before any replay is ready: its table is filled with them
      thresholds_ = app::parseThresholds(kept);
      thresholdsText_ = QString::fromStdString(kept);
    }
  } catch (const std::exception& e) {
    status_->setText(tr("The case's thresholds cannot be read: %1").arg(QString::fromStdString(e.what())));
  }
}

ReviewWindow::ReviewWindow(std::function<std::vector<app::RecordingSummary>()> list, std::function<app::Recording(qint64)> load, const QString& title,
                           std::optional<imaging::Camera> camera, cv::Mat3b frame, QWidget* parent, bool loadOnWorker)
    : QMainWindow(parent), list_(std::move(list)), load_(std::move(load)), camera_(std::move(camera)), frame_(std::move(frame)),
      loadOnWorker_(loadOnWorker) {
  build(title);
}

void ReviewWindow::build(const QString& title) {
  setWindowTitle(tr("Review - %1").arg(title));
  // As large as the screen allows (it opened 1500x900 on a laptop's 1280x800, its right and bottom off the screen).
  const QRect room = (parentWidget() ? parentWidget()->screen() : QGuiApplication::primaryScreen())->availableGeometry();
  resize(std::min(1500, room.width() - 40), std::min(900, room.height() - 60));
  auto* bar = addToolBar(tr("Review"));
  bar->setObjectName("reviewToolbar");
  bar->addWidget(new QLabel(tr(" Session ")));
  first_ = new QComboBox;
  first_->setObjectName("firstSession");
  bar->addWidget(first_);
  bar->addWidget(new QLabel(tr("  compare with ")));
  second_ = new QComboBox;
  second_->setObjectName("secondSession");
  bar->addWidget(second_);
  bar->addSeparator();
  QAction* play = bar->addAction(tr("Play/Pause"), this, [this] { setPlaying(!playing_); });
  play->setToolTip(tr("Play or pause (Space)"));
  bar->addAction(tr("<"), this, [this] { stepBy(-1); })->setToolTip(tr("One step back (Left; Shift: ten)"));
  bar->addAction(tr(">"), this, [this] { stepBy(1); })->setToolTip(tr("One step on (Right; Shift: ten)"));
  bar->addWidget(new QLabel(tr("  speed ")));
  speed_ = new QComboBox;
  speed_->setObjectName("speed");
  for (double s : {0.25, 0.5, 1.0, 2.0, 4.0}) speed_->addItem(QStringLiteral("%1x").arg(s), s);
  speed_->setCurrentIndex(2);
  connect(speed_, &QComboBox::currentIndexChanged, this, [this](int) { setSpeed(speed_->currentData().toDouble()); });
  bar->addWidget(speed_);
  bar->addSeparator();
  QAction* view3d = bar->addAction(tr("3D / Frame view"), this, [this] { setThreeD(!threeD_); });
  view3d->setToolTip(tr("Switch between the organ over the case's frame and a 3D view turned by dragging (V)"));
  QMenu* fileMenu = menuBar()->addMenu(tr("&Review"));
  fileMenu->addAction(tr("Export &Video..."), this, [this] {
    const QString path =
        QFileDialog::getSaveFileName(this, tr("Export video"), suggestedExportPath("mp4"), tr("MP4 video (*.mp4)"));
    if (path.isEmpty()) return;
    const QString err = exportVideo(path, 0, duration(0));
    if (!err.isEmpty()) QMessageBox::warning(this, tr("Export video"), err);
  })->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_E));
  fileMenu->addAction(tr("Export &Report (PDF)..."), this, [this] {
    const QString path =
        QFileDialog::getSaveFileName(this, tr("Export report"), suggestedExportPath("pdf"), tr("PDF (*.pdf)"));
    if (path.isEmpty()) return;
    const QString err = exportReport(path);
    if (!err.isEmpty()) QMessageBox::warning(this, tr("Export report"), err);
  })->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_P));
  fileMenu->addAction(tr("&Thresholds..."), this, [this] {
    bool ok = false;
    const QString text = QInputDialog::getMultiLineText(this, tr("Thresholds"),
                                                        tr("A limit per metric, as JSON, e.g. {\"max_force_n\": {\"max\": 15}, \"economy_of_motion\": {\"min\": 0.8}}:"),
                                                        thresholdsText_.isEmpty() ? QStringLiteral("{}") : thresholdsText_, &ok);
    if (!ok) return;
    const QString err = setThresholds(text);
    if (!err.isEmpty()) QMessageBox::warning(this, tr("Thresholds"), err);
  })->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_T));
  fileMenu->addAction(tr("&Close"), this, &QWidget::close)->setShortcut(QKeySequence::Close);
  split_ = new QSplitter(Qt::Horizontal);
  setCentralWidget(split_);
  status_ = new QLabel;
  statusBar()->addWidget(status_, 1);
  replayPool_ = new QThreadPool(this);
  replayPool_->setMaxThreadCount(2);  // two sessions compared replay side by side
  progressTimer_ = new QTimer(this);
  progressTimer_->setInterval(50);
  connect(progressTimer_, &QTimer::timeout, this, &ReviewWindow::pollReplays);
  timer_ = new QTimer(this);
  timer_->setInterval(33);
  connect(timer_, &QTimer::timeout, this, &ReviewWindow::tick);
  // The review's keys are actions of this window: they work whichever of its widgets has the keyboard focus (a session
  // list that took the focus swallowed Space, Home and End), and they are not the main window's (Home there fits the frame).
  auto key = [this](QKeySequence sequence, std::function<void()> f, const QString& what) {
    auto* a = new QAction(what, this);  // named: the keyboard reference lists it
    a->setProperty("rehearseWhere", tr("Review window"));
    a->setShortcut(sequence);
    a->setShortcutContext(Qt::WindowShortcut);
    connect(a, &QAction::triggered, this, std::move(f));
    addAction(a);
  };
  key(
      Qt::Key_Space, [this] { setPlaying(!playing_); }, tr("Play or pause"));
  key(
      Qt::Key_Left, [this] { stepBy(-1); }, tr("One step back"));
  key(
      Qt::Key_Right, [this] { stepBy(1); }, tr("One step on"));
  key(
      QKeySequence(Qt::SHIFT | Qt::Key_Left), [this] { stepBy(-10); }, tr("Ten steps back"));
  key(
      QKeySequence(Qt::SHIFT | Qt::Key_Right), [this] { stepBy(10); }, tr("Ten steps on"));
  key(
      Qt::Key_Home,
      [this] {
        setPlaying(false);
        seekTime(0);
      },
      tr("To the start"));
  key(
      Qt::Key_End,
      [this] {
        setPlaying(false);
        seekTime(duration(0));
      },
      tr("To the end"));
  key(
      Qt::Key_V, [this] { setThreeD(!threeD_); }, tr("The 3D view (drag to turn) or the frame"));
  for (QComboBox* c : {first_, second_, speed_}) c->setFocusPolicy(Qt::ClickFocus);
  fillSessionLists();
  connect(first_, &QComboBox::activated, this, [this](int) { openSession(0, first_->currentData().toLongLong()); });
  connect(second_, &QComboBox::activated, this, [this](int) { openSession(1, second_->currentData().toLongLong()); });
  if (!sessions_.empty()) openSession(0, sessions_.back().id);
  else status_->setText(tr("%1 holds no recorded session: record one in step 7 (Rehearse) first.").arg(title));
}

ReviewWindow::~ReviewWindow() {
  for (auto& a : attempts_)
    if (a && a->watcher) {
      a->watcher->disconnect(this);
      a->control->halt();
    }
  replayPool_->waitForDone();  // each replay stops at its next step
}

QString sessionTime(const std::string& startedUtc) {
  QDateTime t = QDateTime::fromString(QString::fromStdString(startedUtc), Qt::ISODate);
  if (!t.isValid()) return QString::fromStdString(startedUtc);
  return QLocale().toString(t.toLocalTime(), QLocale::ShortFormat);
}

QString ReviewWindow::attemptTitle(const ReviewAttempt& a) const {
  const auto& s = a.recording.summary;
  return tr("<b>Session %1</b> - %2 - %3")
      .arg(s.id)
      .arg(QString::fromStdString(s.meta.trainee).toHtmlEscaped())
      .arg(sessionTime(s.startedUtc));
}

void ReviewWindow::holdReplaysAt(long step) {
  holdReplaysAt_ = step;
  for (auto& a : attempts_)
    if (a && a->control) a->control->hold(step);
}

long ReviewWindow::stepsReplayed(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a ? a->replayed : 0;
}

void ReviewWindow::pollReplays() {
  bool running = false;
  for (auto& a : attempts_) {
    if (!a || a->ready || !a->error.isEmpty()) continue;
    running = true;
    if (!a->control) continue;  // still being read
    {
      std::lock_guard<std::mutex> lock(a->control->mutex);
      if (!a->control->fresh) continue;
      a->control->fresh = false;
      a->line = a->control->line;
      a->checkedSoFar = a->control->verify;
      a->replayed = a->control->step;
      a->replaySteps = a->control->steps;
    }
    a->timelineView->timeline = a->line;
    a->timelineView->replayed = a->replayed;
    a->timelineView->steps = a->replaySteps;
    a->timelineView->total = std::max({a->expectedDuration, a->available(), 1e-3});
    a->title->setText(attemptTitle(*a) + tr("<br>replaying to check it: step %1 of %2").arg(a->replayed).arg(a->replaySteps));
    refresh();
  }
  if (!running) progressTimer_->stop();
}

void ReviewWindow::refreshSessions() {
  const qint64 a = first_->currentData().toLongLong(), b = second_->currentData().toLongLong();
  const std::size_t before = sessions_.size();
  fillSessionLists();
  // The lists keep what they showed.
  if (const int i = first_->findData(a); i >= 0) first_->setCurrentIndex(i);
  if (const int i = second_->findData(b); i >= 0) second_->setCurrentIndex(i);
  if (sessions_.size() > before && status_->text().contains(tr("holds no recorded session"))) openSession(0, sessions_.back().id);
}

void ReviewWindow::fillSessionLists() {
  try {
    sessions_ = list_();
  } catch (const std::exception& e) {
    status_->setText(QString::fromStdString(e.what()));
  }
  const QSignalBlocker b1(first_), b2(second_);
  first_->clear();
  second_->clear();
  second_->addItem(tr("(none)"), qint64(0));
  for (const auto& s : sessions_) {
    const QString label = QStringLiteral("%1  %2  %3%4")
                              .arg(s.id)
                              .arg(QString::fromStdString(s.meta.trainee.empty() ? std::string("(no name)") : s.meta.trainee))
                              .arg(sessionTime(s.startedUtc))
                              .arg(s.complete ? QString() : tr("  (cut short)"));
    first_->addItem(label, qint64(s.id));
    second_->addItem(label, qint64(s.id));
  }
}

void ReviewWindow::openSession(int attempt, qint64 id) {
  if (attempt < 0 || attempt > 1) return;
  if (const auto& shown = attempts_[static_cast<std::size_t>(attempt)];
      shown && shown->recording.summary.id == id && shown->error.isEmpty() && !shown->ready)
    return;  // chosen again in its list while it replays: its replay goes on (it started over)
  if (exporting_) {
    status_->setText(tr("An export is being written; choose the session again when it is done."));
    return;
  }
  if (auto& old = attempts_[static_cast<std::size_t>(attempt)]) {
    if (old->watcher) {
      old->watcher->disconnect(this);  // its finished signal must not reach the attempt deleted here
      old->watcher->deleteLater();     // (its replay stops at its next step: ~ReviewAttempt halts it)
    }
    delete old->widget;
    old.reset();
  }
  if (attempt == 1 && id <= 0) {
    refresh();
    return;
  }
  auto a = std::make_unique<ReviewAttempt>();
  a->recording.summary.id = id;  // (the title's, until it is loaded)
  for (const auto& s : sessions_)
    if (s.id == id) a->recording.summary = s;
  a->widget = new QWidget;
  auto* v = new QVBoxLayout(a->widget);
  a->title = new QLabel;
  a->view = new ViewLabel;
  a->timelineView = new TimelineWidget;
  a->table = new QTableWidget(0, 3);
  a->table->setHorizontalHeaderLabels({tr("metric"), tr("value"), tr("verdict")});
  a->table->horizontalHeader()->setStretchLastSection(true);
  a->table->verticalHeader()->hide();
  a->table->setEditTriggers(QAbstractItemView::NoEditTriggers);
  a->table->horizontalHeader()->setSectionResizeMode(0, QHeaderView::ResizeToContents);
  a->table->horizontalHeader()->setSectionResizeMode(1, QHeaderView::ResizeToContents);
  a->table->setMinimumHeight(200);
  a->table->setMaximumHeight(420);
  v->addWidget(a->title);
  v->addWidget(a->view, 1);
  v->addWidget(a->timelineView);
  v->addWidget(a->table);
  a->timelineView->seek = [this](double t) { seekTime(t); };
  a->view->turn = [this, attempt](double yaw, double pitch) {
    auto& at = attempts_[static_cast<std::size_t>(attempt)];
    if (!at || !at->orbitRenderer || !threeD_) return;
    at->orbitRenderer->orbit(yaw, pitch);
    ++at->viewGeneration;
    refresh();
  };
  a->title->setWordWrap(true);
  a->title->setText(attemptTitle(*a) + tr("<br>reading the session..."));
  split_->insertWidget(attempt, a->widget);
  ReviewAttempt* raw = a.get();
  attempts_[static_cast<std::size_t>(attempt)] = std::move(a);
  if (attempt == 0) first_->setCurrentIndex(first_->findData(id));
  else second_->setCurrentIndex(second_->findData(id));
  status_->setText(tr("Reading session %1...").arg(id));
  auto loaded = [this, raw, attempt, id](const std::function<app::Recording()>& read) {
    try {
      raw->recording = read();
    } catch (const std::exception& e) {  // said where the session would be shown, and in the status bar
      raw->error = tr("Session %1 cannot be read: %2").arg(id).arg(QString::fromStdString(e.what()));
      raw->title->setText(attemptTitle(*raw));
      status_->setText(raw->error);
      refresh();
      return;
    }
    beginReplay(*raw, attempt);
  };
  if (!loadOnWorker_) {  // (a store whose connection belongs to this thread)
    loaded([&] { return load_(id); });
    return;
  }
  // Read on a worker: a session's setup holds its whole mesh (a large organ's takes a while to decode).
  raw->loader = std::make_unique<QFutureWatcher<app::Recording>>();
  connect(raw->loader.get(), &QFutureWatcher<app::Recording>::finished, this,
          [raw, loaded] { loaded([raw] { return raw->loader->result(); }); });
  raw->loader->setFuture(QtConcurrent::run([load = load_, id] { return load(id); }));
}

void ReviewWindow::beginReplay(ReviewAttempt& attempt0, int attempt) {
  ReviewAttempt* a = &attempt0;
  a->title->setText(attemptTitle(*a));
  // The replay for the timeline and the metrics, off the GUI thread (on the window's own pool: the seeks and exports
  // run on the global one, so a long replay does not hold them back). Its progress is taken on a timer (pollReplays):
  // the timeline grows as it runs and the view seeks as far as it has checked.
  a->control = std::make_shared<ReplayControl>();
  a->control->holdAt = holdReplaysAt_;
  a->expectedDuration = static_cast<double>(a->recording.summary.steps) * a->recording.setup.settings.timeStep;
  a->timelineView->total = std::max(a->expectedDuration, 1e-3);
  a->watcher = new QFutureWatcher<app::ReplayResult>(this);
  ReviewAttempt* raw = a;
  connect(a->watcher, &QFutureWatcher<app::ReplayResult>::finished, this, [this, raw, attempt] {
    try {
      raw->result = raw->watcher->result();
      raw->line = std::make_shared<const std::vector<app::TimelineSample>>(raw->result.timeline);
      raw->checkedSoFar = raw->result.verify;
      raw->replayed = raw->replaySteps = raw->result.verify.steps;
      raw->timelineView->timeline = raw->line;
      raw->timelineView->total = std::max(raw->available(), 1e-9);
      raw->timelineView->done = true;
      raw->timelineView->threshold = raw->result.metrics.forceThresholdN;
      raw->ready = true;
      // Whether this replay is the run that was recorded, in the attempt's title (red when it is not).
      const bool verified = app::replayVerified(raw->result.verify);
      raw->title->setText(attemptTitle(*raw) +
                          tr("<br><span style=\"color:%1\">%2</span>")
                              .arg(verified ? QStringLiteral("#60c060") : QStringLiteral("#ff5050"))
                              .arg((QString::fromStdString(app::replayCheckSentence(raw->result.verify)) +
                                    tr(" - replayed here, on %1").arg(QSysInfo::machineHostName()))
                                       .toHtmlEscaped()));
      fillMetrics(*raw);
    } catch (const std::exception& e) {
      raw->error = QString::fromStdString(e.what());
    }
    refresh();
    emit attemptReady(attempt);
  });
  app::ReplayOptions options;
  options.strain = true;
  options.timeline = true;
  options.checkpoints = !a->recording.checkpointSource;  // a database session's connection is this thread's
  options.progress = [control = a->control](long step, long steps, const app::ReplayResult& soFar) {
    std::unique_lock<std::mutex> lock(control->mutex);
    if (control->stop) return false;
    const auto now = std::chrono::steady_clock::now();
    if (step == 1 || step == steps || step == control->holdAt || now - control->published > std::chrono::milliseconds(100)) {
      control->line = std::make_shared<const std::vector<app::TimelineSample>>(soFar.timeline);
      control->verify = soFar.verify;
      control->step = step;
      control->steps = steps;
      control->fresh = true;
      control->published = now;
    }
    control->changed.wait(lock, [&] { return control->stop || control->holdAt != step; });
    return !control->stop;
  };
  const app::Recording rec = a->recording;
  a->watcher->setFuture(QtConcurrent::run(replayPool_, [rec, options] { return app::replayRecording(rec, options); }));
  // The view's replayer and renderers, built on a worker too; the view seeks once they are.
  a->viewerWatcher = std::make_unique<QFutureWatcher<std::shared_ptr<ReviewViewer>>>();
  connect(a->viewerWatcher.get(), &QFutureWatcher<std::shared_ptr<ReviewViewer>>::finished, this, [this, raw] {
    try {
      const auto viewer = raw->viewerWatcher->result();
      raw->replayer = std::move(viewer->replayer);
      raw->orbitRenderer = std::move(viewer->orbit);
      raw->frameRenderer = std::move(viewer->frame);
      raw->lastStep = raw->replayer->steps();
      raw->seeker = std::make_unique<QFutureWatcher<SeekResult>>();
      connect(raw->seeker.get(), &QFutureWatcher<SeekResult>::finished, this, [this, raw] { seekLanded(*raw); });
      raw->viewable = true;
    } catch (const std::exception& e) {
      raw->error = QString::fromStdString(e.what());
    }
    refresh();
  });
  const std::optional<imaging::Camera> camera = camera_;
  const cv::Mat3b frame = frame_;
  a->viewerWatcher->setFuture(QtConcurrent::run([rec, camera, frame] {
    auto v = std::make_shared<ReviewViewer>();
    v->replayer = std::make_shared<app::Replayer>(rec);
    v->orbit = std::make_unique<app::ReviewRenderer>(rec.setup, 800, 600);
    if (camera) v->frame = std::make_unique<app::ReviewRenderer>(rec.setup, 0, 0, camera, frame);
    return v;
  }));
  if (!progressTimer_->isActive()) progressTimer_->start();
  status_->setText(tr("Replaying session %1 to check it, for its timeline and metrics...").arg(a->recording.summary.id));
}

bool ReviewWindow::ready(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a && a->ready;
}

int ReviewWindow::attemptsShown() const { return (attempts_[0] ? 1 : 0) + (attempts_[1] ? 1 : 0); }

double ReviewWindow::duration(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a ? a->duration() : 0;
}

long ReviewWindow::stepShown(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a && a->replayer ? a->shown : -1;
}

QString ReviewWindow::suggestedExportPath(const QString& extension) const {
  // Beside the case file, named after it and the session shown: "liver-session-3.mp4".
  const auto& a = attempts_[0];
  const QFileInfo kase(file_);
  const QString dir = file_.isEmpty() ? QDir::homePath() : kase.absolutePath();
  const QString base = file_.isEmpty() ? tr("review") : kase.completeBaseName();
  const QString session = a ? tr("-session-%1").arg(a->recording.summary.id) : QString();
  return QDir(dir).filePath(base + session + "." + extension);
}

long ReviewWindow::stepWanted(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a && a->viewable ? a->stepAt(time_) : -1;
}

bool ReviewWindow::seeking() const {
  return std::any_of(attempts_.begin(), attempts_.end(), [](const auto& a) {
    return a && a->seeker && (a->seeker->isRunning() || (a->viewable && a->error.isEmpty() && a->stale()));
  });
}

void ReviewWindow::startSeek(ReviewAttempt& a) {
  if (!a.seeker || a.seeker->isRunning() || !a.error.isEmpty()) return;  // the one running lands first
  const long step = a.wanted, generation = a.viewGeneration;
  const std::shared_ptr<app::Replayer> replayer = a.replayer;
  // The picture is drawn there too, with a copy of the view's renderer (a turn may change the view's meanwhile).
  auto renderer = std::make_shared<app::ReviewRenderer>(a.renderer(threeD_));
  const auto timeline = a.line;  // the samples so far (a new vector replaces it as the replay goes on)
  const app::VerifyResult checked = a.checkedSoFar;  // the checkpoints it found damaged are not started from
  const std::string who = "session " + std::to_string(a.recording.summary.id);
  const QSize size = a.view->size();
  a.seeker->setFuture(QtConcurrent::run([replayer, renderer, timeline, checked, who, size, step, generation] {
    SeekResult r;
    r.step = step;
    r.generation = generation;
    try {
      replayer->avoidCheckpoints(checked);
      replayer->seek(step);
      r.note = replayer->lastSeekNote();
      const QImage img = toQImage(renderer->render(*replayer->snapshot(), app::tipPath(*timeline, step),
                                                   app::captionAt(*timeline, step, who)));
      r.image = img;
      r.scaled = img.scaled(size, Qt::KeepAspectRatio, Qt::SmoothTransformation);
    } catch (const std::exception& e) {
      r.error = e.what();
    }
    return r;
  }));
}

void ReviewWindow::seekLanded(ReviewAttempt& a) {
  const SeekResult r = a.seeker->result();
  if (!r.error.empty()) {  // a damaged checkpoint: said, and the attempt shows no more
    a.error = tr("Session %1 cannot be shown at step %2: %3")
                  .arg(a.recording.summary.id)
                  .arg(r.step)
                  .arg(QString::fromStdString(r.error));
    a.view->setText(a.error);
  } else {
    a.shown = r.step;
    a.shownGeneration = r.generation;
    a.seekNote = r.note;
    // Drawn at the view's size when the seek started; a view laid out or resized since (a session just opened is
    // laid out after its first seek starts: its picture came out blank) is scaled here.
    const QSize wanted = r.image.size().scaled(a.view->size(), Qt::KeepAspectRatio);
    const QImage fitted =
        r.scaled.size() == wanted ? r.scaled : r.image.scaled(wanted, Qt::IgnoreAspectRatio, Qt::SmoothTransformation);
    a.view->setPixmap(QPixmap::fromImage(fitted));
    a.view->setProperty("image", r.image);
  }
  if (a.error.isEmpty() && a.stale()) startSeek(a);  // the newest position (or view) asked meanwhile
  refresh();
}

app::SessionMetrics ReviewWindow::metrics(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a ? a->result.metrics : app::SessionMetrics{};
}

std::vector<app::Verdict> ReviewWindow::verdicts(int attempt) const { return app::judge(metrics(attempt), thresholds_); }

QString ReviewWindow::setThresholds(const QString& json) {
  try {
    thresholds_ = app::parseThresholds(json.toStdString());
    thresholdsText_ = json;
    if (!file_.isEmpty()) app::saveCaseThresholds(file_.toStdString(), json.toStdString());
  } catch (const std::exception& e) {
    return QString::fromStdString(e.what());
  }
  for (auto& a : attempts_)
    if (a && a->ready) fillMetrics(*a);
  return {};
}

void ReviewWindow::seekTime(double seconds) {
  double longest = 0;
  for (const auto& a : attempts_)
    if (a) longest = std::max(longest, a->duration());
  time_ = std::clamp(seconds, 0.0, longest);
  refresh();
}

void ReviewWindow::stepBy(int steps) {
  const auto& a = attempts_[0];
  if (!a || !a->viewable || a->line->empty()) return;
  const long target = std::clamp(a->stepAt(time_) + steps, 0L, a->reachable());
  const app::TimelineSample* s = app::sampleAt(*a->line, target);
  const double t = s ? s->time : 0.0;
  setPlaying(false);
  seekTime(t);
}

void ReviewWindow::setPlaying(bool on) {
  playing_ = on && attempts_[0] && attempts_[0]->viewable;
  if (playing_) {
    if (time_ >= duration(0) - 1e-9) time_ = 0;  // from the start again
    lastTick_ = 0;
    timer_->start();
  } else {
    timer_->stop();
  }
  refresh();
}

void ReviewWindow::setSpeed(double factor) {
  speedFactor_ = std::clamp(factor, 0.05, 16.0);
  const int i = speed_->findData(speedFactor_);
  if (i >= 0 && i != speed_->currentIndex()) speed_->setCurrentIndex(i);
}

void ReviewWindow::setThreeD(bool on) {
  threeD_ = on;
  for (auto& a : attempts_)
    if (a) ++a->viewGeneration;
  refresh();
}

void ReviewWindow::tick() {
  const qint64 now = QDateTime::currentMSecsSinceEpoch();
  const double dt = lastTick_ ? (now - lastTick_) / 1000.0 : 0.0;
  lastTick_ = now;
  // While a replay runs, playing goes as far as it has replayed and waits there; at the end of the longest, it stops.
  double longest = 0, available = 0;
  bool replaying = false;
  for (const auto& a : attempts_)
    if (a && a->error.isEmpty()) {
      longest = std::max(longest, a->duration());
      available = std::max(available, a->available());
      replaying = replaying || !a->ready;
    }
  time_ = std::max(time_, std::min(replaying ? available : longest, time_ + dt * speedFactor_));
  if (!replaying && time_ >= longest) playing_ = false, timer_->stop();
  refresh();
}

void ReviewWindow::refresh() {
  QStringList state, seekNotes;
  for (std::size_t k = 0; k < attempts_.size(); ++k) {
    auto& a = attempts_[k];
    if (!a) continue;
    if (!a->error.isEmpty()) {
      a->view->setText(a->error);
      continue;
    }
    a->timelineView->now = time_;
    a->timelineView->update();
    if (!a->viewable) continue;
    // The playhead moves at once; the view follows when its seek lands (off the GUI thread).
    a->wanted = a->stepAt(time_);
    if (a->stale()) startSeek(*a);
    QString where = a->shown == a->wanted || a->shown < 0
                        ? tr("session %1: step %2 of %3").arg(a->recording.summary.id).arg(a->wanted).arg(a->lastStep)
                        : tr("session %1: step %2 of %3 (seeking from %4)")
                              .arg(a->recording.summary.id)
                              .arg(a->wanted)
                              .arg(a->lastStep)
                              .arg(a->shown);
    if (!a->ready) where += tr(", replayed to %1").arg(a->replayed);
    state << where;
    if (!a->seekNote.empty())  // a damaged checkpoint passed over: said, the view still shows the step
      seekNotes << tr("session %1: %2").arg(a->recording.summary.id).arg(QString::fromStdString(a->seekNote));
  }
  const QString mode = threeD_ || !camera_ ? tr("3D view (drag to turn)") : tr("over the case's frame");
  // A seek that passed over a damaged checkpoint says so first (the status line is cut at the window's width; the
  // whole sentence is its tooltip).
  const QString line = tr("%1  t = %2 s  %3  %4x  %5").arg(playing_ ? tr("playing") : tr("paused")).arg(time_, 0, 'f', 2).arg(state.join("; ")).arg(speedFactor_).arg(mode);
  status_->setText(seekNotes.isEmpty() ? line : seekNotes.join("; ") + "  |  " + line);
  status_->setToolTip(status_->text());
}

void ReviewWindow::fillMetrics(ReviewAttempt& a) {
  // Once per replay and per change of the thresholds (not per frame).
  const auto values = app::metricValues(a.result.metrics);
  const auto verdicts = app::judge(a.result.metrics, thresholds_);
  a.table->setRowCount(static_cast<int>(values.size()) + 1);
  // The first row: whether the metrics below are the recorded run's at all.
  {
    const bool verified = app::replayVerified(a.result.verify);
    const auto& v = a.result.verify;
    a.table->setItem(0, 0, new QTableWidgetItem(tr("replay check")));
    auto* value = new QTableWidgetItem(
        verified            ? tr("%1 of %1 checksums match").arg(v.checked)
        : v.mismatches      ? tr("%1 of %2 checksums differ").arg(v.mismatches).arg(v.checked)
        : !v.damagedCheckpoints.empty()
            ? tr("%1 of %2 checkpoints damaged (first after step %3)")
                  .arg(v.damagedCheckpoints.size())
                  .arg(v.checkpointsChecked)
                  .arg(v.damagedCheckpoints.front().first)
        : tr("no checksum"));
    value->setToolTip(QString::fromStdString(app::replayCheckSentence(v)));
    a.table->setItem(0, 1, value);
    auto* word = new QTableWidgetItem(verified ? tr("verified") : v.checked ? tr("DOES NOT VERIFY") : tr("not verified"));
    word->setForeground(verified ? QColor(30, 150, 30) : QColor(220, 40, 40));
    a.table->setItem(0, 2, word);
  }
  for (int i = 0; i < static_cast<int>(values.size()); ++i) {
    const auto& m = values[static_cast<std::size_t>(i)];
    const int row = i + 1;
    auto* name = new QTableWidgetItem(QString::fromStdString(app::metricWords(m.name)));
    name->setToolTip(tr("%1 in the thresholds (Ctrl+T) and on the command line").arg(QString::fromStdString(m.name)));
    a.table->setItem(row, 0, name);
    auto* value = new QTableWidgetItem(QString::fromStdString(app::metricText(m)));
    if (!m.value) value->setToolTip(QString::fromStdString(m.why));
    if (m.name == "incorrect_actions" && m.value) {  // each one with its time (the timeline's cyan ticks)
      QStringList lines;
      for (const auto& x : a.result.metrics.incorrectActions)
        lines << tr("%1 s: %2 (%3)")
                     .arg(x.time, 0, 'f', 2)
                     .arg(QString::fromStdString(x.rule), QString::fromStdString(x.what));
      value->setToolTip(lines.isEmpty() ? tr("none under the session's rules") : lines.join("\n"));
    }
    a.table->setItem(row, 1, value);
    QString verdict;
    for (const auto& v : verdicts)
      if (v.metric.name == m.name) verdict = app::resultWord(v.result);
    auto* item = new QTableWidgetItem(verdict);
    if (verdict == "fail") item->setForeground(QColor(220, 40, 40));
    if (verdict == "pass") item->setForeground(QColor(30, 150, 30));
    a.table->setItem(row, 2, item);
  }
}

QString ReviewWindow::statusText() const { return status_->text(); }

QImage ReviewWindow::viewImage(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a ? a->view->property("image").value<QImage>() : QImage();
}

QString ReviewWindow::exportFirst(const QString& doing, bool cancellable, const ExportWork& write) {
  auto& a = attempts_[0];
  if (!a || !a->ready) return tr("The session is still being replayed; export when its timeline shows.");
  setPlaying(false);
  // On a worker (issue 62: a report froze the window 9 s, a video 6 s): a replayer of its own (the view's stays where
  // it is) and a copy of the view's renderer (the view may turn meanwhile); progress and Cancel here.
  auto renderer = std::make_shared<app::ReviewRenderer>(a->renderer(threeD_));
  struct Shared {
    std::atomic<int> done{0}, total{0};
    std::atomic<bool> cancel{false};
  };
  auto shared = std::make_shared<Shared>();
  QProgressDialog progress(doing, cancellable ? tr("Cancel") : QString(), 0, 0, this);
  progress.setObjectName(QStringLiteral("exportProgress"));
  progress.setWindowModality(Qt::WindowModal);
  progress.setMinimumDuration(300);
  if (!cancellable) progress.setCancelButton(nullptr);
  connect(&progress, &QProgressDialog::canceled, this, [shared] { shared->cancel = true; });
  struct Outcome {
    QString status, error;
  };
  QFutureWatcher<Outcome> watcher;
  QEventLoop loop;
  exporting_ = true;
  connect(&watcher, &QFutureWatcher<Outcome>::finished, &loop, &QEventLoop::quit);
  ReviewAttempt* attempt = a.get();
  watcher.setFuture(QtConcurrent::run([attempt, renderer, shared, write]() -> Outcome {
    try {
      app::Replayer replayer(attempt->recording);  // (building it takes a while on a large organ: here, not on the GUI thread)
      replayer.avoidCheckpoints(attempt->result.verify);
      return {write(*attempt, replayer, *renderer,
                    [shared](int done, int total) {
                      shared->done = done;
                      shared->total = total;
                      return !shared->cancel.load();
                    }),
              {}};
    } catch (const std::exception& e) {
      return {{}, QString::fromStdString(e.what())};
    }
  }));
  QTimer poll;
  poll.setInterval(100);
  connect(&poll, &QTimer::timeout, this, [&] {
    if (shared->cancel) return;
    const int total = shared->total;
    if (total > 0) {
      progress.setMaximum(total);
      progress.setLabelText(tr("%1: frame %2 of %3").arg(doing).arg(shared->done.load()).arg(total));
      progress.setValue(std::min(shared->done.load(), total - 1));
    } else {
      progress.setValue(0);  // (busy: shown after its minimum duration)
    }
  });
  poll.start();
  progress.setValue(0);
  if (!watcher.isFinished()) loop.exec();
  exporting_ = false;
  poll.stop();
  const Outcome out = watcher.result();
  progress.reset();
  if (!out.error.isEmpty())
    return out.error == QLatin1String("cancelled") ? tr("The export was cancelled; the partial file was left as it is.")
                                                   : out.error;
  status_->setText(out.status);
  return {};
}

QString ReviewWindow::exportVideo(const QString& path, double from, double to) {
  return exportFirst(tr("Writing the video"), true,
                     [this, path, from, to](ReviewAttempt& a, app::Replayer& replayer, const app::ReviewRenderer& r,
                                            const std::function<bool(int, int)>& progress) {
                       const long first = a.stepAt(from);
                       const int frames =
                           app::writeReviewVideo(replayer, r, a.result.timeline, first, std::max(a.stepAt(to), first + 1),
                                                 25, path.toStdString(), progress);
                       return tr("Video of %1 frames written to %2").arg(frames).arg(path);
                     });
}

QString ReviewWindow::exportReport(const QString& path) {
  const auto thresholds = thresholds_;
  return exportFirst(tr("Writing the report (replaying the session for its key frames)"), false,
                     [this, path, thresholds](ReviewAttempt& a, app::Replayer& replayer, const app::ReviewRenderer& r,
                                              const std::function<bool(int, int)>&) {
                       writeReviewPdf(app::makeReviewReport(a.recording, a.result, thresholds, replayer, r),
                                      path.toStdString());
                       return tr("Report written to %1").arg(path);
                     });
}

bool ReviewWindow::event(QEvent* e) {
  // Sessions recorded while the window was open are listed when it is activated again.
  if (e->type() == QEvent::WindowActivate) refreshSessions();
  return QMainWindow::event(e);
}

void ReviewWindow::keyPressEvent(QKeyEvent* e) { QMainWindow::keyPressEvent(e); }  // the review's keys are actions (build)

}  // namespace rehearse::ui
