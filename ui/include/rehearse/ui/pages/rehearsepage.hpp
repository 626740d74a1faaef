#pragma once
// Step 7, the rehearsal: the instruments the surgeon drives with the mouse in the frame view (the
// grasper now; contact and cutting come next), their live state from the simulation session (what the
// jaws hold, the force on the tissue, slips), in the composited view of step 6 or the overlay.
#include "rehearse/ui/pages/steppage.hpp"

#include <QElapsedTimer>

#include <rehearse/simcore/session/body.hpp>

#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

class QLabel;
class QLineSeries;
class QValueAxis;
class QTimer;

namespace rehearse::simcore {
class ForceLoop;
}

class QLineEdit;
class QPushButton;

namespace rehearse::ui {
class Throttle;
}

namespace rehearse::ui {

struct SimulationFrame;

class RehearsePage : public StepPage {
  Q_OBJECT
 public:
  explicit RehearsePage(Workbench& wb, QWidget* parent = nullptr);
  ~RehearsePage() override;
  void refresh(const app::Case& c) override;
  /// A simulation snapshot was shown: the instrument's state in words.
  void showFrame(const std::shared_ptr<const SimulationFrame>& f);
  /// Where the tool-force loop is (the simulation panel's; null while no session runs): the page's chart
  /// shows the last 5 s of its 1 kHz force, and its rate and jitter.
  void setForceLoop(std::function<const simcore::ForceLoop*()> loop) { loop_ = std::move(loop); }
  /// Redraws the chart from the loop now (the page's timer does it 15 times a second while it is shown).
  void updateChart();
  /// Reset or another organ: the chart shows the loop's force from now on, not the ended run's last 5 s (a person saw
  /// the old pull's trace scroll out over the organ at rest).
  void forgetForceHistory();
  /// What the Record button and the Review button do (the main window's): start returns one sentence on error.
  struct RecordHandlers {
    std::function<QString(const QString& trainee)> start;
    std::function<void()> stop;
    std::function<void()> review;
  };
  void setRecordHandlers(RecordHandlers h) { record_ = std::move(h); }
  /// Shows whether a session is being recorded (and which), or why it stopped.
  void showRecording(bool on, const QString& text);
  /// The trainee's name as typed (recorded with the session, whichever way the recording is started).
  QString trainee() const;

 protected:
  void showEvent(QShowEvent* e) override;
  void hideEvent(QHideEvent* e) override;

 private:
  std::function<const simcore::ForceLoop*()> loop_;
  /// s, the loop's clock: samples up to it belong to a run that ended (forgetForceHistory); -inf: none.
  double chartFrom_ = -std::numeric_limits<double>::infinity();
  QLineSeries* series_ = nullptr;
  QLineSeries* limit_ = nullptr;  ///< the grasp's limit, dashed, while the jaws hold
  double graspLimit_ = 0;         ///< N, from the last frame while its jaws held tissue; 0: not holding
  QValueAxis* axisX_ = nullptr;
  QValueAxis* axisY_ = nullptr;
  QLabel* loopRate_ = nullptr;
  QElapsedTimer loopRateShown_;  ///< when loopRate_'s text was last made (updateChart)
  QTimer* chartTimer_ = nullptr;
  QLabel* status_ = nullptr;
  QLabel* force_ = nullptr;
  std::optional<QString> pendingStatus_;  // set per frame, shown through labelThrottle_
  QString forceText_;
  std::unique_ptr<Throttle> labelThrottle_;
  int slips_ = 0, cuts_ = 0, vesselCuts_ = 0, tears_ = 0;  // (cuts_: strokes that cut)
  bool jawsHeldTissue_ = false;  // a frame since the jaws last opened showed them holding tissue
  bool slippedFromJaws_ = false;  // the tissue slipped out of the jaws since they last held it: opening them releases nothing
  bool wasCutting_ = false, strokeCounted_ = false;
  long lastSteps_ = 0;  ///< the last frame's step: a smaller one is a new session
  /// Steps in a row that did not converge (counted through the frames; 0 after a converged one): from 10 on, the page
  /// says the organ's motion is not its equilibrium.
  long unconverged_ = 0;
  long lastNotConverged_ = 0;  ///< the last frame's SimulationFrame::stepsNotConverged
  bool saidUnconverged_ = false;  ///< the page's line says so (and is to say when they converge again)
  /// The model that steps and its last steps' wall times (ms), for the rate line.
  simcore::BodyModel model_ = simcore::BodyModel::Fem;
  std::vector<double> stepMs_;
  RecordHandlers record_;
  QPushButton* recordButton_ = nullptr;
  QLineEdit* trainee_ = nullptr;
  QLabel* recordState_ = nullptr;
};

}  // namespace rehearse::ui
