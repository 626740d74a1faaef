#include "rehearse/ui/reviewwindow.hpp"

#include "rehearse/ui/reviewreport.hpp"

#include <QAction>
#include <QApplication>
#include <QComboBox>
#include <QDateTime>
#include <QDir>
#include <QFileInfo>
#include <QEventLoop>
#include <QFileDialog>
#include <QFutureWatcher>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QInputDialog>
#include <QKeyEvent>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QMouseEvent>
#include <QPainter>
#include <QPainterPath>
#include <QProgressDialog>
#include <QPushButton>
#include <QSignalBlocker>
#include <QSplitter>
#include <QStatusBar>
#include <QSysInfo>
#include <QTableWidget>
#include <QTimer>
#include <QToolBar>
#include <QVBoxLayout>
#include <QtConcurrent/QtConcurrentRun>

#include <algorithm>
#include <atomic>
#include <cmath>

namespace rehearse::ui {

namespace {

QImage toQImage(const cv::Mat3b& m) { return QImage(m.data, m.cols, m.rows, static_cast<qsizetype>(m.step), QImage::Format_BGR888).copy(); }

// The attempt's force over time, the events as ticks, the threshold dashed and the playhead; a click or a
// drag seeks (through `seek`, the window's common time).
class TimelineWidget : public QWidget {
 public:
  std::function<void(double)> seek;
  const std::vector<app::TimelineSample>* timeline = nullptr;
  double threshold = 0, now = 0;
  TimelineWidget() {
    setObjectName(QStringLiteral("timeline"));
    setMinimumHeight(110);
    setCursor(Qt::PointingHandCursor);
    setToolTip(
        tr("Tool force over time; ticks: grasp (green), slip (orange), cut (purple), vessel cut (red), force over the "
           "threshold (dashed "
           "line, red tick), incorrect action (cyan, longer). Click or drag to seek."));
  }
  double timeAt(double x) const {
    if (!timeline || timeline->empty()) return 0;
    const double t1 = timeline->back().time;
    return std::clamp((x - 8) / std::max(1.0, width() - 16.0), 0.0, 1.0) * t1;
  }
  double xAt(double t) const {
    const double t1 = timeline && !timeline->empty() ? std::max(1e-9, timeline->back().time) : 1;
    return 8 + t / t1 * (width() - 16.0);
  }

 protected:
  void paintEvent(QPaintEvent*) override {
    QPainter p(this);
    p.fillRect(rect(), QColor(30, 32, 36));
    if (!timeline || timeline->empty()) {
      p.setPen(Qt::lightGray);
      p.drawText(rect(), Qt::AlignCenter, tr("replaying for the timeline..."));
      return;
    }
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
    for (const auto& s : *timeline)
      for (const auto& e : s.events) {
        const QColor c = reviewEventColour(e);  // as the report names them
        if (!c.isValid()) continue;
        p.setPen(QPen(c, 3));
        p.drawLine(QPointF(xAt(s.time), 2), QPointF(xAt(s.time), e.rfind("incorrect action", 0) == 0 ? 34 : 16));
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
    setMinimumSize(320, 240);
    setAlignment(Qt::AlignCenter);
    setStyleSheet("background: #202226");
  }

 protected:
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

class ReviewAttempt {
 public:
  ~ReviewAttempt() {
    if (seeker) seeker->waitForFinished();  // it uses the replayer
  }
  QWidget* widget = nullptr;
  QLabel* title = nullptr;
  ViewLabel* view = nullptr;
  TimelineWidget* timelineView = nullptr;
  QTableWidget* table = nullptr;
  app::Recording recording;
  app::ReplayResult result;
  std::unique_ptr<app::Replayer> replayer;
  std::unique_ptr<app::ReviewRenderer> frameRenderer, orbitRenderer;
  bool ready = false;
  QString error;
  QFutureWatcher<app::ReplayResult>* watcher = nullptr;
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

  long stepAt(double t) const { return app::stepAtTime(result.timeline, t); }
  /// The view's renderer: the case's frame, or the 3D view (always without a case camera).
  const app::ReviewRenderer& renderer(bool threeD) const { return threeD || !frameRenderer ? *orbitRenderer : *frameRenderer; }
  double duration() const { return result.timeline.empty() ? 0 : result.timeline.back().time; }
};

ReviewWindow::ReviewWindow(const QString& file, std::optional<imaging::Camera> camera, cv::Mat3b frame, QWidget* parent)
    : ReviewWindow([f = file.toStdString()] { return app::listRecordings(f); }, [f = file.toStdString()](qint64 id) { return app::loadRecording(f, id); }, file,
                   std::move(camera), std::move(frame), parent) {
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
                           std::optional<imaging::Camera> camera, cv::Mat3b frame, QWidget* parent)
    : QMainWindow(parent), list_(std::move(list)), load_(std::move(load)), camera_(std::move(camera)), frame_(std::move(frame)) {
  build(title);
}

void ReviewWindow::build(const QString& title) {
  setWindowTitle(tr("Review - %1").arg(title));
  resize(1500, 900);
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
      a->watcher->waitForFinished();
    }
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
                              .arg(QString::fromStdString(s.startedUtc))
                              .arg(s.complete ? QString() : tr("  (cut short)"));
    first_->addItem(label, qint64(s.id));
    second_->addItem(label, qint64(s.id));
  }
}

void ReviewWindow::openSession(int attempt, qint64 id) {
  if (attempt < 0 || attempt > 1) return;
  if (exporting_) {
    status_->setText(tr("An export is being written; choose the session again when it is done."));
    return;
  }
  if (auto& old = attempts_[static_cast<std::size_t>(attempt)]) {
    if (old->watcher) {
      old->watcher->disconnect(this);  // its finished signal must not reach the attempt deleted here
      old->watcher->waitForFinished();
      old->watcher->deleteLater();
    }
    delete old->widget;
    old.reset();
  }
  if (attempt == 1 && id <= 0) {
    refresh();
    return;
  }
  auto a = std::make_unique<ReviewAttempt>();
  try {
    a->recording = load_(id);
  } catch (const std::exception& e) {
    status_->setText(QString::fromStdString(e.what()));
    return;
  }
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
  const auto& s = a->recording.summary;
  a->title->setText(tr("<b>Session %1</b> - %2 - %3").arg(s.id).arg(QString::fromStdString(s.meta.trainee)).arg(QString::fromStdString(s.startedUtc)));
  split_->insertWidget(attempt, a->widget);
  // The replay for the timeline and the metrics, off the GUI thread.
  a->watcher = new QFutureWatcher<app::ReplayResult>(this);
  ReviewAttempt* raw = a.get();
  connect(a->watcher, &QFutureWatcher<app::ReplayResult>::finished, this, [this, raw, attempt] {
    try {
      raw->result = raw->watcher->result();
      raw->replayer = std::make_unique<app::Replayer>(raw->recording);
      raw->replayer->avoidCheckpoints(raw->result.verify);  // seeking starts from sound ones
      raw->lastStep = raw->replayer->steps();
      raw->seeker = std::make_unique<QFutureWatcher<SeekResult>>();
      connect(raw->seeker.get(), &QFutureWatcher<SeekResult>::finished, this, [this, raw] { seekLanded(*raw); });
      raw->orbitRenderer = std::make_unique<app::ReviewRenderer>(raw->recording.setup, 800, 600);
      if (camera_) raw->frameRenderer = std::make_unique<app::ReviewRenderer>(raw->recording.setup, 0, 0, camera_, frame_);
      raw->timelineView->timeline = &raw->result.timeline;
      raw->timelineView->threshold = raw->result.metrics.forceThresholdN;
      raw->ready = true;
      // Whether this replay is the run that was recorded, in the attempt's title (red when it is not).
      const auto& s = raw->recording.summary;
      const bool verified = app::replayVerified(raw->result.verify);
      raw->title->setText(tr("<b>Session %1</b> - %2 - %3<br><span style=\"color:%4\">%5</span>")
                              .arg(s.id)
                              .arg(QString::fromStdString(s.meta.trainee).toHtmlEscaped())
                              .arg(QString::fromStdString(s.startedUtc))
                              .arg(verified ? QStringLiteral("#60c060") : QStringLiteral("#ff5050"))
                              .arg((QString::fromStdString(app::replayCheckSentence(raw->result.verify)) +
                                    tr(" - replayed here, on %1").arg(QSysInfo::machineHostName()))
                                       .toHtmlEscaped()));
      raw->title->setWordWrap(true);
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
  const app::Recording rec = a->recording;
  a->watcher->setFuture(QtConcurrent::run([rec, options] { return app::replayRecording(rec, options); }));
  attempts_[static_cast<std::size_t>(attempt)] = std::move(a);
  status_->setText(tr("Replaying session %1 for its timeline and metrics...").arg(id));
  if (attempt == 0) first_->setCurrentIndex(first_->findData(id));
  else second_->setCurrentIndex(second_->findData(id));
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
  return a && a->ready ? a->stepAt(time_) : -1;
}

bool ReviewWindow::seeking() const {
  return std::any_of(attempts_.begin(), attempts_.end(), [](const auto& a) {
    return a && a->seeker && (a->seeker->isRunning() || (a->ready && a->error.isEmpty() && a->stale()));
  });
}

void ReviewWindow::startSeek(ReviewAttempt& a) {
  if (!a.seeker || a.seeker->isRunning() || !a.error.isEmpty()) return;  // the one running lands first
  const long step = a.wanted, generation = a.viewGeneration;
  app::Replayer* replayer = a.replayer.get();
  // The picture is drawn there too, with a copy of the view's renderer (a turn may change the view's meanwhile).
  auto renderer = std::make_shared<app::ReviewRenderer>(a.renderer(threeD_));
  const std::vector<app::TimelineSample>* timeline = &a.result.timeline;  // (fixed once the attempt is ready)
  const std::string who = "session " + std::to_string(a.recording.summary.id);
  const QSize size = a.view->size();
  a.seeker->setFuture(QtConcurrent::run([replayer, renderer, timeline, who, size, step, generation] {
    SeekResult r;
    r.step = step;
    r.generation = generation;
    try {
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
    a.view->setPixmap(QPixmap::fromImage(r.scaled));
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
  if (!a || !a->ready || a->result.timeline.empty()) return;
  const long target = std::clamp(a->stepAt(time_) + steps, 0L, a->lastStep);
  const app::TimelineSample* s = app::sampleAt(a->result.timeline, target);
  const double t = s ? s->time : 0.0;
  setPlaying(false);
  seekTime(t);
}

void ReviewWindow::setPlaying(bool on) {
  playing_ = on && ready(0);
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
  double longest = 0;
  for (const auto& a : attempts_)
    if (a) longest = std::max(longest, a->duration());
  time_ = std::min(longest, time_ + dt * speedFactor_);
  if (time_ >= longest) playing_ = false, timer_->stop();
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
    if (!a->ready) continue;
    // The playhead moves at once; the view follows when its seek lands (off the GUI thread).
    a->wanted = a->stepAt(time_);
    a->timelineView->now = time_;
    a->timelineView->update();
    if (a->stale()) startSeek(*a);
    state << (a->shown == a->wanted || a->shown < 0
                  ? tr("session %1: step %2 of %3").arg(a->recording.summary.id).arg(a->wanted).arg(a->lastStep)
                  : tr("session %1: step %2 of %3 (seeking from %4)")
                        .arg(a->recording.summary.id)
                        .arg(a->wanted)
                        .arg(a->lastStep)
                        .arg(a->shown));
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
    a.table->setItem(row, 0, new QTableWidgetItem(QString::fromStdString(m.name)));
    auto* value = new QTableWidgetItem(m.value ? QString::number(*m.value, 'g', 5) + (m.unit.empty() ? "" : " " + QString::fromStdString(m.unit))
                                               : tr("not determined"));
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
  auto replayer = std::make_shared<app::Replayer>(a->recording);
  replayer->avoidCheckpoints(a->result.verify);
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
  watcher.setFuture(QtConcurrent::run([attempt, replayer, renderer, shared, write]() -> Outcome {
    try {
      return {write(*attempt, *replayer, *renderer,
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
