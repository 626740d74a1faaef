// The review window (issue 16): its construction and layout (toolbar, menu, keys), the sessions' lists, opening a
// session as an attempt, and the metrics' table. The replay, seeking and playing are in reviewwindow_replay.cpp, the
// exports in reviewwindow_export.cpp, the shared internals in reviewparts.hpp.
#include "rehearse/ui/reviewwindow.hpp"

#include "reviewparts.hpp"

#include <QAction>
#include <QComboBox>
#include <QDateTime>
#include <QLocale>
#include <QFileDialog>
#include <QFileInfo>
#include <QGuiApplication>
#include <QHeaderView>
#include <QInputDialog>
#include <QKeyEvent>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QScreen>
#include <QSignalBlocker>
#include <QSplitter>
#include <QStatusBar>
#include <QThreadPool>
#include <QTableWidget>
#include <QTimer>
#include <QToolBar>
#include <QVBoxLayout>
#include <QtConcurrent/QtConcurrentRun>

#include <algorithm>

namespace rehearse::ui {

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
  // A name typed without the file's kind gets it (a report named "r.txt" was written as PDF under that name).
  auto withSuffix = [](QString path, const QString& suffix) {
    if (!path.isEmpty() && QFileInfo(path).suffix().compare(suffix, Qt::CaseInsensitive) != 0) path += "." + suffix;
    return path;
  };
  fileMenu->addAction(tr("Export &Video..."), this, [this, withSuffix] {
    const QString path = withSuffix(
        QFileDialog::getSaveFileName(this, tr("Export video"), suggestedExportPath("mp4"), tr("MP4 video (*.mp4)")),
        "mp4");
    if (path.isEmpty()) return;
    const QString err = exportVideo(path, 0, duration(0));
    if (!err.isEmpty()) QMessageBox::warning(this, tr("Export video"), err);
  })->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_E));
  fileMenu->addAction(tr("Export &Report (PDF)..."), this, [this, withSuffix] {
    const QString path = withSuffix(
        QFileDialog::getSaveFileName(this, tr("Export report"), suggestedExportPath("pdf"), tr("PDF (*.pdf)")), "pdf");
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

bool ReviewWindow::ready(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a && a->ready;
}

int ReviewWindow::attemptsShown() const { return (attempts_[0] ? 1 : 0) + (attempts_[1] ? 1 : 0); }

double ReviewWindow::duration(int attempt) const {
  const auto& a = attempts_[static_cast<std::size_t>(std::clamp(attempt, 0, 1))];
  return a ? a->duration() : 0;
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

bool ReviewWindow::event(QEvent* e) {
  // Sessions recorded while the window was open are listed when it is activated again.
  if (e->type() == QEvent::WindowActivate) refreshSessions();
  return QMainWindow::event(e);
}

void ReviewWindow::keyPressEvent(QKeyEvent* e) { QMainWindow::keyPressEvent(e); }  // the review's keys are actions (build)

}  // namespace rehearse::ui
