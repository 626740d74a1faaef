#include "rehearse/ui/pages/rehearsepage.hpp"

#include "rehearse/ui/simulationpanel.hpp"
#include "rehearse/ui/steadybox.hpp"
#include "rehearse/ui/throttle.hpp"

#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/session/forceloop.hpp>

#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QTimer>
#include <QVBoxLayout>
#include <QGraphicsLayout>
#include <QtCharts/QChart>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QValueAxis>

#include <algorithm>
#include <cmath>

namespace rehearse::ui {

RehearsePage::RehearsePage(Workbench& wb, QWidget* parent) : StepPage(wb, app::Step::Rehearse, parent) {
  auto* layout = new QVBoxLayout(this);
  auto* intro = new QLabel(
      tr("Rehearse the gesture on the registered organ: with the grasper, press on the organ to close the jaws "
         "there, drag to pull it, release to let go (Space closes them at the cursor and keeps them closed); with "
         "the scissors, press on the organ and drag across it to cut, release to stop; with the clip applier, click "
         "over "
         "a vessel to clip it (a cut vessel bleeds unless a clip lies behind the cut); with the cautery hook, press "
         "and drag "
         "to burn a line (burnt tissue stiffens, whitens and is cut without bleeding). Take the scissors or the clip "
         "applier while the jaws hold and they keep the traction, which opens the incision. The wheel moves the "
         "instrument's tip deeper or shallower while you hold it. "
         "The simulation runs while you work (Simulation panel: material, ligaments); the view shows it "
         "composited into the frame once the appearance is estimated (step 6), cut faces in preset interior "
         "colours; the overlay (F3) shows cut tissue in dark red."),
      this);
  intro->setWordWrap(true);
  intro->setObjectName(QStringLiteral("rehearseIntro"));
  // (Added last, below the chart: the tools, what they do and the force come first, where the page opens; above
  // them the intro pushed the status and the force below the fold at 1600x900.)
  auto* grasper =
      toolButton(this, tr("Grasper (R)"), tr("Press on the organ to grasp it, drag to pull, release to let go"),
                 Tool::Grasp, Qt::Key_R);
  grasper->setObjectName(QStringLiteral("grasperTool"));
  layout->addWidget(grasper);
  auto* scissors =
      toolButton(this, tr("Scissors (B)"), tr("Press on the organ and drag across it to cut, release to stop"),
                 Tool::Scissors, Qt::Key_B);
  scissors->setObjectName(QStringLiteral("scissorsTool"));
  layout->addWidget(scissors);
  auto* clipper = toolButton(this, tr("Clip applier (U)"),
                             tr("Click on the organ over a vessel to close a clip across it; cut between two clips "
                                "and the vessel does not bleed"),
                             Tool::Clip, Qt::Key_U);
  clipper->setObjectName(QStringLiteral("clipTool"));
  layout->addWidget(clipper);
  auto* cautery = toolButton(this, tr("Cautery hook (J)"),
                             tr("Press on the organ to apply energy, drag to burn a line (the tissue whitens and "
                                "stiffens; a cut along it does not bleed), release to stop"),
                             Tool::Cautery, Qt::Key_J);
  cautery->setObjectName(QStringLiteral("cauteryTool"));
  layout->addWidget(cautery);
  // Recording for the trainer: into the case file, as the rehearsal runs (from rest: the simulation restarts).
  auto* recordRow = new QHBoxLayout;
  trainee_ = new QLineEdit(this);
  trainee_->setAccessibleName(tr("Trainee"));
  trainee_->setObjectName(QStringLiteral("traineeName"));
  trainee_->setPlaceholderText(tr("trainee (name or id)"));
  trainee_->setToolTip(tr("Who rehearses: recorded with the session"));
  recordButton_ = new QPushButton(tr("Record"), this);
  recordButton_->setObjectName(QStringLiteral("recordButton"));
  recordButton_->setCheckable(true);
  recordButton_->setToolTip(tr(
      "Record the rehearsal into the case file (Ctrl+R): the simulation starts again from rest; press again to stop"));
  auto* review = new QPushButton(tr("Review..."), this);
  review->setObjectName(QStringLiteral("reviewButton"));
  review->setToolTip(tr("Replay and review the sessions recorded in this case (Ctrl+Shift+R)"));
  recordRow->addWidget(trainee_, 1);
  recordRow->addWidget(recordButton_);
  recordRow->addWidget(review);
  layout->addLayout(recordRow);
  recordState_ = new QLabel(this);
  recordState_->setObjectName(QStringLiteral("recordState"));
  recordState_->setWordWrap(true);
  layout->addWidget(recordState_);
  connect(recordButton_, &QPushButton::clicked, this, [this](bool on) {
    if (on) {
      const QString err =
          record_.start ? record_.start(trainee_->text().trimmed()) : tr("Recording is not available here.");
      if (!err.isEmpty()) showRecording(false, err);
    } else if (record_.stop) {
      record_.stop();
    }
  });
  connect(review, &QPushButton::clicked, this, [this] {
    if (record_.review) record_.review();
  });
  // The status and the force lines change many times a second while the instruments work: each has a fixed number
  // of lines (a longer text ends in an ellipsis, whole in the tooltip) and sits in a SteadyBox, so that a new text is
  // only repainted. They were laid out anew at each change, and at each change of their line count the whole page
  // with them (13-22 ms of the GUI thread each, issue 64); the chart and the buttons below moved up and down.
  status_ = new LinesLabel(4, this);
  status_->setObjectName(QStringLiteral("rehearseStatus"));
  layout->addWidget(new SteadyBox(status_, this));
  force_ = new LinesLabel(3, this);
  labelThrottle_ = std::make_unique<Throttle>(this, [this] {
    if (pendingStatus_) {
      status_->setText(*pendingStatus_);
      status_->setToolTip(*pendingStatus_);
    }
    pendingStatus_.reset();
    force_->setText(forceText_);
    force_->setToolTip(forceText_);
  });
  force_->setObjectName(QStringLiteral("rehearseForce"));
  // A press beside the organ after a slip: the grasper says to press on the organ, and the page's "The tissue slipped
  // out of the jaws" is over (a person read the two together, as if the press had slipped).
  if (wb_.view)
    connect(wb_.view, &FrameView::toolMessage, this, [this](const QString& said) {
      if (!said.contains(QLatin1String("Press on the organ to grasp it"))) return;
      if (pendingStatus_.value_or(status_->text()).contains(QLatin1String("slipped out of the jaws"))) {
        pendingStatus_ = QString();
        labelThrottle_->request();
      }
    });
  // (A long line, with the shares, counts or a step not converged, wraps: it never widens the panel and shrinks the
  // frame.)
  QFont big = force_->font();
  big.setPointSizeF(big.pointSizeF() * 1.4);
  force_->setFont(big);
  layout->addWidget(new SteadyBox(force_, this));
  // The tool force as the 1 kHz loop computes it (the force on the tissue; a haptic device renders its opposite).
  series_ = new QLineSeries;
  auto* chart = new QChart;
  chart->addSeries(series_);
  chart->legend()->hide();
  chart->setTitle(tr("Tool force (N) over the last 5 s"));
  chart->setTheme(QChart::ChartThemeDark);
  // (The units are in the title: the axes' own titles were cut off at the page's foot, and the time's ticks fell on
  // -3.75 s and -1.25 s, read "-3.8" and "-1.3"; a person's check.)
  axisX_ = new QValueAxis;
  axisX_->setRange(-5, 0);
  axisX_->setTickCount(6);
  axisX_->setLabelFormat(QStringLiteral("%.0f"));
  axisY_ = new QValueAxis;
  axisY_->setRange(0, 1);
  axisY_->setLabelFormat(QStringLiteral("%g"));
  // Three force ticks and thin margins: the chart fits above the panel's fold at 1600 x 900 with its labels readable
  // (five ticks in 150 px were elided to "...").
  axisY_->setTickCount(3);
  chart->layout()->setContentsMargins(0, 0, 0, 0);
  chart->setMargins(QMargins(6, 2, 6, 2));
  chart->addAxis(axisX_, Qt::AlignBottom);
  chart->addAxis(axisY_, Qt::AlignLeft);
  series_->attachAxis(axisX_);
  series_->attachAxis(axisY_);
  // While the jaws hold, the force at which they let go (a person watched the trace rise with the axis rescaling under
  // it, and could not tell how near the slip was).
  limit_ = new QLineSeries;
  limit_->setName(tr("grasp limit"));
  QPen dashed(QColor(255, 150, 40), 1.5, Qt::DashLine);
  limit_->setPen(dashed);
  chart->addSeries(limit_);
  limit_->attachAxis(axisX_);
  limit_->attachAxis(axisY_);
  auto* chartView = new QChartView(chart, this);
  chartView->setObjectName(QStringLiteral("toolForceChart"));
  // 150 px: the whole chart above the panel's fold on a 1600 x 900 screen (at 200 its time axis fell below it, under a
  // scroll bar: a person's check). No antialiasing: the chart redraws 15 times a second beside the organ.
  chartView->setMinimumHeight(150);
  layout->addWidget(chartView, 1);
  loopRate_ = new QLabel(this);
  loopRate_->setObjectName(QStringLiteral("forceLoopRate"));
  // Its length changes with the numbers in it: it never widens the panel (which would shrink the frame under the hand);
  // the tooltip has it all.
  loopRate_->setSizePolicy(QSizePolicy::Ignored, QSizePolicy::Preferred);
  layout->addWidget(new SteadyBox(loopRate_, this));
  layout->addWidget(intro);
  chartTimer_ = new QTimer(this);
  chartTimer_->setInterval(66);  // 15 Hz: the GUI thread's time goes to the organ's view first
  connect(chartTimer_, &QTimer::timeout, this, &RehearsePage::updateChart);
}

void RehearsePage::showEvent(QShowEvent* e) {
  StepPage::showEvent(e);
  chartTimer_->start();
}

void RehearsePage::hideEvent(QHideEvent* e) {
  StepPage::hideEvent(e);
  chartTimer_->stop();
}

void RehearsePage::forgetForceHistory() {
  const simcore::ForceLoop* loop = loop_ ? loop_() : nullptr;
  const auto last = loop ? loop->samples(0.5) : std::vector<simcore::ForceSample>{};
  chartFrom_ = last.empty() ? -std::numeric_limits<double>::infinity() : last.back().time;
  updateChart();
}

void RehearsePage::updateChart() {
  const simcore::ForceLoop* loop = loop_ ? loop_() : nullptr;
  if (!loop) {
    series_->clear();
    loopRate_->setText(tr("Tool-force loop: no simulation running."));
    return;
  }
  const auto samples = loop->samples(5.0);
  QList<QPointF> points;
  double top = 1.0;
  if (!samples.empty() && samples.back().time < chartFrom_)
    chartFrom_ = -std::numeric_limits<double>::infinity();  // another loop, its clock from 0: nothing of the old run
  if (!samples.empty()) {
    const double now = samples.back().time;
    const std::size_t stride = std::max<std::size_t>(1, samples.size() / 250);  // a point per 20 ms on the chart
    points.reserve(static_cast<int>(samples.size() / stride + 1));
    for (std::size_t i = 0; i < samples.size(); i += stride) {
      if (samples[i].time <= chartFrom_) continue;  // the ended run's
      const double f = samples[i].force.norm();
      top = std::max(top, f);
      points.append(QPointF(samples[i].time - now, f));
    }
  }
  series_->replace(points);
  if (graspLimit_ > 0) {
    limit_->replace(QList<QPointF>{{-5.0, graspLimit_}, {0.0, graspLimit_}});
    top = std::max(top, graspLimit_);
  } else if (limit_->count() > 0) {
    limit_->clear();
  }
  // The top on a 1-2-5 ladder: the axis moves in steps, not with every sample.
  const double scaled = 1.1 * top, decade = std::pow(10.0, std::floor(std::log10(scaled)));
  double nice = 10 * decade;
  for (double m : {1.0, 2.0, 5.0})
    if (m * decade >= scaled) {
      nice = m * decade;
      break;
    }
  axisY_->setRange(0, nice);
  // The rates below, twice a second (statistics of the last 10 s; the text in a SteadyBox does not lay the page out
  // again, which cost 10-25 ms of the GUI thread per change on 2 cores under the simulation's load, issue 64).
  if (loopRateShown_.isValid() && loopRateShown_.elapsed() < 500) return;
  loopRateShown_.start();
  const auto t = loop->timing();
  // The model's own rate beside the loop's (one line: the chart above keeps its height): how long the deformation's
  // step takes, and whether the loop's force between steps is the model's (the precomputed model's stiffness is exact)
  // or an extrapolation (the FEM's).
  QString model;
  if (!stepMs_.empty()) {
    std::vector<double> ms = stepMs_;
    std::nth_element(ms.begin(), ms.begin() + static_cast<std::ptrdiff_t>(ms.size() / 2), ms.end());
    const double median = ms[ms.size() / 2];
    switch (model_) {
      case simcore::BodyModel::Precomputed:
        model = tr(" · precomputed %1 ms/step, exact").arg(median, 0, 'f', 2);
        break;
      case simcore::BodyModel::Hybrid:
        model = tr(" · hybrid %1 ms/step, exact").arg(median, 0, 'f', 2);
        break;
      case simcore::BodyModel::Ffd:
        model = tr(" · FFD %1 ms/step, Hertz").arg(median, 0, 'f', 2);
        break;
      default:
        model = tr(" · FEM %1 ms/step, extrapolated").arg(median, 0, 'f', 1);
    }
  }
  loopRate_->setText(tr("Force loop %1 Hz (p99 %2 ms%3)%4")
                         .arg(t.rateHz, 0, 'f', 0)
                         .arg(t.p99PeriodMs, 0, 'f', 2)
                         .arg(t.realtime ? tr(", real-time") : QString())
                         .arg(model));
  loopRate_->setToolTip(
      tr("%1\nThe tool force computed at %2 Hz on its own thread (period: median %3 ms, 99th percentile %4 ms). %5")
          .arg(loopRate_->text())
          .arg(t.rateHz, 0, 'f', 0)
          .arg(t.medianPeriodMs, 0, 'f', 2)
          .arg(t.p99PeriodMs, 0, 'f', 2)
          .arg(model_ == simcore::BodyModel::Precomputed || model_ == simcore::BodyModel::Hybrid
                   ? tr("The %1 model's stiffness at the instrument is exact (linear and static): between its steps "
                        "the loop renders the model's own force.")
                         .arg(model_ == simcore::BodyModel::Hybrid ? tr("hybrid") : tr("precomputed"))
               : model_ == simcore::BodyModel::Ffd
                   ? tr("Between the FFD model's steps the loop follows Hertz's law along the pull by its slope (the "
                        "force itself is Hertz's law at each step).")
                   : tr("Between the FEM's steps the loop extrapolates the last step's force with its "
                        "stiffness (a guess until the next step).")));
}

void RehearsePage::refresh(const app::Case& c) {
  if (!c.hasPose)
    status_->setText(tr("Place the organ over the frame first (step 4)."));
  else if (status_->text().isEmpty() || status_->text().startsWith(tr("Place the organ")))
    status_->setText(
        tr("Pick the grasper (R), the scissors (B), the clip applier (U) or the cautery hook (J) and press on the "
           "organ."));
}

RehearsePage::~RehearsePage() = default;

void RehearsePage::showFrame(const std::shared_ptr<const SimulationFrame>& f) {
  if (!f) return;
  // A new session (a new organ, case, reset or recording) starts its counts from nothing.
  if (f->steps < lastSteps_ || f->steps == 0) {
    slips_ = cuts_ = vesselCuts_ = tears_ = 0;
    wasCutting_ = strokeCounted_ = slippedFromJaws_ = jawsHeldTissue_ = false;
    unconverged_ = 0;
    saidUnconverged_ = false;
    // ... and what the last one said goes with it ("Released: the tissue relaxes." stayed over a new case's organ).
    if (!status_->text().isEmpty()) pendingStatus_ = QString();
  }
  if (f->steps < lastSteps_ || f->steps == 0 || f->model != model_) stepMs_.clear();
  model_ = f->model;
  if (f->steps > lastSteps_ && f->report.wallMs > 0) {
    stepMs_.push_back(f->report.wallMs);
    if (stepMs_.size() > 100) stepMs_.erase(stepMs_.begin());
  }
  // Steps in a row that do not converge (a person set 3 kPa and a 50 ms step, grasped and let go: the organ ran 86 then
  // 162 mm from its start, every step inexact, while the page said "Released: the tissue relaxes."). Counted from the
  // session's own count of such steps, every step whether drawn or not: when a step between two frames converged, the
  // run is the last step's alone. The FFD model has no equilibrium to converge to.
  if (f->steps > lastSteps_) {
    const long stepped = f->steps - lastSteps_, failed = f->stepsNotConverged - lastNotConverged_;
    unconverged_ = f->model == simcore::BodyModel::Ffd || f->report.outcome == simcore::StepStatus::Converged ? 0
                   : failed >= stepped                                                                  ? unconverged_ + stepped
                                                                                                        : 1;
  }
  lastSteps_ = f->steps;
  lastNotConverged_ = f->stepsNotConverged;
  graspLimit_ = f->tool.held.empty() ? 0.0 : f->maxGraspForce;
  simcore::EventCounts counted;
  counted.add(f->events);
  slips_ += counted.slips;
  if (!f->tool.held.empty()) slippedFromJaws_ = false, jawsHeldTissue_ = true;
  if (counted.slips > 0) slippedFromJaws_ = true;
  // Strokes that cut, not the cut's updates (a person read "cuts: 10" after three strokes): a stroke counts at its
  // first cut; one still being built when the blade is lifted is the same stroke.
  if (f->tool.cutting && !wasCutting_) strokeCounted_ = false;
  wasCutting_ = f->tool.cutting;
  if (counted.cuts > 0 && !strokeCounted_) {
    ++cuts_;
    strokeCounted_ = true;
  }
  vesselCuts_ += counted.vesselCuts;
  // A slip is said in the status bar too, where "Grasped: drag to pull" stood (a helper read it beside "the jaws are
  // closed on nothing"): the sentence says at what force and what the scene allows.
  if (counted.slips > 0 && !f->message.isEmpty() && wb_.status) {
    wb_.status(f->message);
    // Over the grasper's own line too: its "Grasped: drag to pull" stays on top of the status bar for 10 s and hid the
    // slip's sentence beside the page's "the jaws are closed on nothing".
    if (wb_.view) emit wb_.view->toolMessage(f->message);
  }
  const int tore = counted.tears;
  tears_ += tore;
  auto status = [this](const QString& text) { pendingStatus_ = text; };
  const auto& t = f->tool;
  // Each tear's sentence is kept in the Messages panel too: the page's line shows the newest only (a person counted 5
  // sentences against "TORN: 6").
  if (tore > 0 && !f->message.isEmpty() && wb_.log) wb_.log(f->message);
  if (tore > 0 && !f->message.isEmpty())
    status(f->message);  // what tore, and at what strain
  else if (t.cutting)
    // (In words: "Cutting: 3932 elements, 858 nodes." read as jargon to a person.)
    status(tr("Cutting: the organ's mesh re-made along the blade (%1 elements now).").arg(f->elements));
  else if (!t.held.empty())
    status(t.held.size() == 1 ? tr("The jaws hold the tissue at 1 node of its mesh.")
                              : tr("The jaws hold the tissue at %1 nodes of its mesh.").arg(t.held.size()));
  else if (t.jawClosed)
    status(f->message.isEmpty() ? tr("The jaws are closed on nothing.") : f->message);
  else if (std::find(f->events.begin(), f->events.end(), "release") != f->events.end()) {
    // (After a slip the jaws hold nothing: a person read "Released: the tissue relaxes." over a slip.)
    // (The grasper itself opens and is withdrawn at a slip, while the button may still be held.)
    // (Jaws that closed on nothing released nothing: a person read "Released: the tissue relaxes." after a miss.)
    status(slippedFromJaws_   ? tr("The tissue slipped out of the jaws; the grasper opened and was withdrawn: press on "
                                   "the organ to grasp again.")
           : jawsHeldTissue_ && unconverged_ > 0
               ? tr("Released, but the steps are not converging: what the tissue does now is not its own motion (a "
                    "smaller time step or a stiffer tissue in the Simulation panel, or Reset).")
           : jawsHeldTissue_ ? tr("Released: the tissue relaxes.")
                             : tr("The jaws opened: they had closed on nothing."));
    slippedFromJaws_ = jawsHeldTissue_ = false;
  }
  else if (cuts_ > 0 && pendingStatus_.value_or(status_->text()).startsWith(tr("Cutting")))
    status(tr("Cut: the organ's mesh re-made along the blade (%1 elements now).").arg(f->elements));
  // A run of steps that do not converge is said over the instruments' own lines (a tear's sentence stays).
  if (unconverged_ >= 10 && tore == 0) {
    status(tr("The last %1 steps did not converge: the organ's motion is not its equilibrium. A smaller time step or a "
              "stiffer tissue (Simulation panel), or Reset, brings it back.")
               .arg(unconverged_));
    saidUnconverged_ = true;
  } else if (saidUnconverged_ && unconverged_ == 0) {
    if (!pendingStatus_) status(tr("The steps converge again."));
    saidUnconverged_ = false;
  }
  QString extra;
  // The blood first (the counts after it: three lines at the page's width had cut "bleeding 1..." off).
  if (f->field.bloodLoss > 0) {
    double rate = 0;
    for (const auto& b : f->field.bleeds)
      if (b.stoppedBy < 0) rate += b.rate;
    // From 750 mL on, the class of haemorrhage it is for an adult (ATLS), in capitals from class III.
    static const char* const classes[] = {"", "", QT_TR_NOOP("class II haemorrhage"),
                                          QT_TR_NOOP("CLASS III HAEMORRHAGE"), QT_TR_NOOP("CLASS IV HAEMORRHAGE")};
    const int c = simcore::haemorrhageClass(f->field.bloodLoss);
    extra += tr("   blood lost: %1 mL%2%3")
                 .arg(1e6 * f->field.bloodLoss, 0, 'f', 1)
                 .arg(c >= 2 ? QStringLiteral(", ") + tr(classes[c]) : QString())
                 .arg(rate > 0 ? tr(" (bleeding %1 mL/s)").arg(1e6 * rate, 0, 'f', 2) : QString());
  }
  if (slips_) extra += tr("   slips: %1").arg(slips_);
  if (cuts_) extra += tr("   cuts: %1").arg(cuts_);
  if (vesselCuts_) extra += tr("   vessels cut: %1").arg(vesselCuts_);
  if (tears_) extra += tr("   TORN: %1").arg(tears_);
  if (!f->field.clips.empty()) extra += tr("   clips: %1").arg(f->field.clips.size());
  if (f->field.energy) extra += tr("   ENERGY ON");
  // While the jaws hold and the shaft touches, the two shares (the jaws' decides a slip).
  QString shares;
  // (Forces in different directions: a total below a share read as a mistake to a person, so the directions are said.)
  if (!t.held.empty() && (t.force - t.graspForce).norm() >= 0.005) {
    const Eigen::Vector3d shaft = t.force - t.graspForce;
    const bool apart = t.graspForce.dot(shaft) < 0.5 * t.graspForce.norm() * shaft.norm();  // over 60 degrees
    shares = (apart ? tr(" (jaws %1 N and shaft %2 N, in different directions)") : tr(" (jaws %1 N, shaft %2 N)"))
                 .arg(t.graspForce.norm(), 0, 'f', 2)
                 .arg(shaft.norm(), 0, 'f', 2);
  }
  else if (t.held.empty() && t.force.norm() >= 0.005)
    // Nothing held: the force is the shaft's, resting where the instrument was left (a person read 0.6-1.9 N after
    // "Cut ended." as a force left over from the cut).
    shares = tr(" (the shaft against the tissue)");
  // A force from a step that did not converge is not the tissue's equilibrium force: said next to the number
  // (issue 32: 18 kN, then 135 N, were shown from steps with a relative residual near 1).
  // The FFD model has no equilibrium at all: its force is Hertz's contact law at the hold's or poke's depth.
  if (t.force.norm() > 0 && f->model == simcore::BodyModel::Ffd)
    shares += tr(" — Hertz's contact law (the FFD model is geometric: no equilibrium force)");
  else if (t.force.norm() > 0 && f->report.outcome != simcore::StepStatus::Converged)
    shares += tr(" — step not converged (relative residual %1): not the equilibrium force")
                  .arg(f->report.residual, 0, 'g', 2);
  forceText_ = tr("Tool force %1 N%2%3").arg(t.force.norm(), 0, 'f', 2).arg(shares, extra);
  // A vessel cut, a refused cut and the end of a stroke (whether the organ came apart, what still joins) are said
  // in the session's words: the status never says "Cut" over tissue that still joins.
  if (!f->message.isEmpty() &&
      (f->message.contains(QLatin1String("vessel")) || f->message.contains(QLatin1String("The cut")) ||
       f->message.contains(QLatin1String(" was cut")) || f->message.contains(QLatin1String("breached")) ||
       f->message.contains(QLatin1String("clip")) || f->message.contains(QLatin1String("bleed")) ||
       f->message.contains(QLatin1String("Energy")) || f->message.contains(QLatin1String("burns"))))
    status(f->message);
  labelThrottle_->request();  // the labels at most 15 times a second, the newest always shown
}

QString RehearsePage::trainee() const {
  return trainee_->text().trimmed();
}

void RehearsePage::showRecording(bool on, const QString& text) {
  recordButton_->setChecked(on);
  recordButton_->setText(on ? tr("Stop recording") : tr("Record"));
  trainee_->setEnabled(!on);
  recordState_->setText(text);
  recordState_->setStyleSheet(on ? QStringLiteral("color: #e04040; font-weight: bold") : QString());
}

}  // namespace rehearse::ui
