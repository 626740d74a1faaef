#pragma once
// The trainer's cohort view (issue 16): the sessions published in the training database, by trainee, with
// their metrics, and one metric over each trainee's attempts as a plot (a learning curve). A double click
// opens the session in the review window (read from the database).
#include <rehearse/app/trainingdb.hpp>

#include <QMainWindow>

#include <memory>

class QComboBox;
class QListWidget;
class QTableWidget;
class QLabel;
namespace QtCharts {}
class QChartView;

namespace rehearse::ui {

class ReviewWindow;

class CohortWindow : public QMainWindow {
  Q_OBJECT
 public:
  /// `db` stays open while the window (and the review windows it opens) live.
  explicit CohortWindow(std::shared_ptr<app::TrainingDatabase> db, QWidget* parent = nullptr);
  /// Reads the sessions again (after a publish).
  void reload();
  QStringList trainees() const;
  int sessionRows() const;
  /// The plotted metric's values per trainee, in attempt order (what the chart shows).
  std::vector<std::pair<QString, std::vector<double>>> curves() const;
  void setMetric(const QString& name);
  void selectTrainee(const QString& name);  ///< empty: everyone
  ReviewWindow* openSession(qint64 id);

 private:
  void fill();
  std::shared_ptr<app::TrainingDatabase> db_;
  std::vector<app::PublishedSession> sessions_;
  QListWidget* trainees_ = nullptr;
  QTableWidget* table_ = nullptr;
  QComboBox* metric_ = nullptr;
  QChartView* chart_ = nullptr;
  QLabel* status_ = nullptr;
  QString trainee_;
};

}  // namespace rehearse::ui
