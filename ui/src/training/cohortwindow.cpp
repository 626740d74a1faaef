#include "rehearse/ui/cohortwindow.hpp"

#include "rehearse/ui/reviewwindow.hpp"

#include <QComboBox>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QListWidget>
#include <QPushButton>
#include <QSplitter>
#include <QStatusBar>
#include <QTableWidget>
#include <QToolBar>
#include <QVBoxLayout>
#include <QtCharts/QChart>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QValueAxis>

#include <algorithm>
#include <map>

namespace rehearse::ui {

namespace {
const std::vector<app::MetricValue>& names() {
  static const std::vector<app::MetricValue> n = app::metricValues(app::SessionMetrics{});
  return n;
}
std::optional<double> metricOf(const app::PublishedSession& s, const QString& name) {
  for (const auto& m : s.metrics)
    if (QString::fromStdString(m.name) == name) return m.value;
  return std::nullopt;
}
}  // namespace

CohortWindow::CohortWindow(std::shared_ptr<app::TrainingDatabase> db, QWidget* parent)
    : QMainWindow(parent), db_(std::move(db)) {
  setWindowTitle(tr("Training cohort - Rehearse"));
  resize(1400, 850);
  auto* bar = addToolBar(tr("Cohort"));
  bar->setObjectName("cohortToolbar");
  bar->addAction(tr("Refresh"), this, &CohortWindow::reload)->setShortcut(QKeySequence::Refresh);
  bar->addWidget(new QLabel(tr("  plot ")));
  metric_ = new QComboBox;
  metric_->setObjectName("cohortMetric");
  for (const auto& m : names()) metric_->addItem(QString::fromStdString(m.name));
  metric_->setCurrentText(QStringLiteral("max_force_n"));
  connect(metric_, &QComboBox::currentTextChanged, this, [this] { fill(); });
  bar->addWidget(metric_);
  auto* split = new QSplitter(Qt::Horizontal);
  trainees_ = new QListWidget;
  trainees_->setObjectName("cohortTrainees");
  connect(trainees_, &QListWidget::currentRowChanged, this, [this](int row) {
    trainee_ = row <= 0 ? QString() : trainees_->item(row)->data(Qt::UserRole).toString();
    fill();
  });
  auto* right = new QSplitter(Qt::Vertical);
  table_ = new QTableWidget;
  table_->setObjectName("cohortSessions");
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->verticalHeader()->hide();
  connect(table_, &QTableWidget::cellDoubleClicked, this,
          [this](int row, int) { openSession(table_->item(row, 0)->data(Qt::UserRole).toLongLong()); });
  chart_ = new QChartView;
  chart_->setObjectName("cohortChart");
  chart_->setMinimumHeight(300);
  right->addWidget(table_);
  right->addWidget(chart_);
  split->addWidget(trainees_);
  split->addWidget(right);
  split->setStretchFactor(1, 4);
  setCentralWidget(split);
  status_ = new QLabel;
  statusBar()->addWidget(status_, 1);
  reload();
}

void CohortWindow::reload() {
  try {
    sessions_ = db_->sessions();
  } catch (const std::exception& e) {
    status_->setText(QString::fromStdString(e.what()));
    return;
  }
  std::map<QString, int> count;
  for (const auto& s : sessions_) ++count[QString::fromStdString(s.summary.meta.trainee)];
  trainees_->blockSignals(true);
  trainees_->clear();
  auto* all = new QListWidgetItem(tr("Everyone (%1 sessions)").arg(sessions_.size()));
  trainees_->addItem(all);
  for (const auto& [name, n] : count) {
    auto* item = new QListWidgetItem(tr("%1 (%2)").arg(name.isEmpty() ? tr("(no name)") : name).arg(n));
    item->setData(Qt::UserRole, name);
    trainees_->addItem(item);
  }
  trainees_->setCurrentRow(0);
  trainees_->blockSignals(false);
  trainee_.clear();
  fill();
}

void CohortWindow::fill() {
  const QStringList shown = {"duration_s",
                             "path_length_m",
                             "economy_of_motion",
                             "grasps",
                             "slips",
                             "cut_updates",
                             "vessel_cuts",
                             "max_force_n",
                             "time_over_threshold_s",
                             "max_strain",
                             "incorrect_actions"};
  QStringList headers = {tr("session"), tr("trainee"), tr("started (UTC)"), tr("case")};
  for (const QString& metric : shown)  // in words, as the review window and the report name them
    headers += QString::fromStdString(app::metricWords(metric.toStdString()));
  headers += tr("replay verified");
  table_->clear();
  table_->setColumnCount(headers.size());
  table_->setHorizontalHeaderLabels(headers);
  table_->setRowCount(0);
  for (const auto& s : sessions_) {
    const QString who = QString::fromStdString(s.summary.meta.trainee);
    if (!trainee_.isEmpty() && who != trainee_) continue;
    const int row = table_->rowCount();
    table_->insertRow(row);
    auto* id = new QTableWidgetItem(QString::number(s.id));
    id->setData(Qt::UserRole, static_cast<qlonglong>(s.id));
    id->setToolTip(QString::fromStdString(s.uid));
    table_->setItem(row, 0, id);
    table_->setItem(row, 1, new QTableWidgetItem(who));
    auto* when = new QTableWidgetItem(sessionTime(s.summary.startedUtc));
    when->setToolTip(QString::fromStdString(s.summary.startedUtc));
    table_->setItem(row, 2, when);
    table_->setItem(row, 3, new QTableWidgetItem(QString::fromStdString(s.summary.meta.caseName)));
    for (int k = 0; k < shown.size(); ++k) {
      const auto v = metricOf(s, shown[k]);
      const auto m = std::find_if(names().begin(), names().end(), [&](const app::MetricValue& x) { return QString::fromStdString(x.name) == shown[k]; });
      table_->setItem(row, 4 + k, new QTableWidgetItem(!v ? tr("n/d")
                                                       : m != names().end() ? QString::fromStdString(app::metricAmount(*m, *v))
                                                                            : QString::number(*v, 'g', 4)));
    }
    // Where its replay was verified (a session opened here is replayed and verified again, and the review says so).
    auto* verified = new QTableWidgetItem(s.verifiedOn.empty() ? tr("at publishing (machine not kept)")
                                                                : QString::fromStdString(s.verifiedOn));
    verified->setToolTip(
        tr("A session replays bit for bit with the same build on any x86-64 processor (its numerical kernels are "
           "pinned); opening the session replays and verifies it here."));
    table_->setItem(row, 4 + static_cast<int>(shown.size()), verified);
  }
  table_->resizeColumnsToContents();
  // The chosen metric over each trainee's attempts.
  auto* chart = new QChart;
  chart->setTheme(QChart::ChartThemeDark);
  chart->setTitle(tr("%1 over each trainee's attempts").arg(metric_->currentText()));
  auto* x = new QValueAxis;
  x->setTitleText(tr("attempt"));
  x->setLabelFormat("%d");
  auto* y = new QValueAxis;
  y->setTitleText(metric_->currentText());
  chart->addAxis(x, Qt::AlignBottom);
  chart->addAxis(y, Qt::AlignLeft);
  double ymax = 0;
  int xmax = 1;
  for (const auto& [name, values] : curves()) {
    auto* line = new QLineSeries;
    line->setName(name.isEmpty() ? tr("(no name)") : name);
    line->setPointsVisible(true);
    for (std::size_t k = 0; k < values.size(); ++k) {
      line->append(static_cast<double>(k + 1), values[k]);
      ymax = std::max(ymax, values[k]);
    }
    xmax = std::max(xmax, static_cast<int>(values.size()));
    chart->addSeries(line);
    line->attachAxis(x);
    line->attachAxis(y);
  }
  x->setRange(1, std::max(2, xmax));
  x->setTickCount(std::min(std::max(2, xmax), 11));
  y->setRange(0, ymax > 0 ? 1.1 * ymax : 1);
  QChart* old = chart_->chart();
  chart_->setChart(chart);
  delete old;
  status_->setText(tr("%1 sessions of %2 trainees in the training database")
                       .arg(sessions_.size())
                       .arg(std::max(0, trainees_->count() - 1)));
}

std::vector<std::pair<QString, std::vector<double>>> CohortWindow::curves() const {
  std::map<QString, std::vector<double>> by;
  for (const auto& s : sessions_) {  // ordered by start time
    const QString who = QString::fromStdString(s.summary.meta.trainee);
    if (!trainee_.isEmpty() && who != trainee_) continue;
    if (const auto v = metricOf(s, metric_->currentText())) by[who].push_back(*v);
  }
  return {by.begin(), by.end()};
}

QStringList CohortWindow::trainees() const {
  QStringList out;
  for (int k = 1; k < trainees_->count(); ++k) out << trainees_->item(k)->data(Qt::UserRole).toString();
  return out;
}

int CohortWindow::sessionRows() const {
  return table_->rowCount();
}

void CohortWindow::setMetric(const QString& name) {
  metric_->setCurrentText(name);
}

void CohortWindow::selectTrainee(const QString& name) {
  for (int k = 0; k < trainees_->count(); ++k)
    if ((k == 0 && name.isEmpty()) || (k > 0 && trainees_->item(k)->data(Qt::UserRole).toString() == name))
      trainees_->setCurrentRow(k);
}

ReviewWindow* CohortWindow::openSession(qint64 id) {
  auto db = db_;
  std::vector<app::RecordingSummary> list;
  for (const auto& s : sessions_) list.push_back(s.summary);
  auto* w = new ReviewWindow([list] { return list; }, [db](qint64 sid) { return db->load(sid); },
                             tr("training database"), std::nullopt, {}, this);
  w->setAttribute(Qt::WA_DeleteOnClose);
  w->setWindowFlag(Qt::Window);
  w->openSession(0, id);
  w->show();
  return w;
}

}  // namespace rehearse::ui
