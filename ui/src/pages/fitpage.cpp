#include "rehearse/ui/pages/fitpage.hpp"

#include "rehearse/ui/frameview.hpp"

#include <rehearse/app/elasticfit.hpp>

#include <QAction>
#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QVBoxLayout>
#include <QtCharts/QChart>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QValueAxis>

namespace rehearse::ui {

FitPage::FitPage(Workbench& wb, QWidget* parent) : StepPage(wb, app::Step::Elastic, parent) {
  auto* layout = new QVBoxLayout(this);
  auto* intro = new QLabel(tr("Fit the organ onto the sketched contour: the silhouette is pulled onto it in the image plane and "
                              "the elastic model (the case's material, see the Simulation panel, held by its ligaments) decides the rest. "
                              "Afterwards keep the fit, or revert it (Ctrl+Z)."),
                           this);
  intro->setWordWrap(true);
  layout->addWidget(intro);
  rigid_ = new QCheckBox(tr("Rigid pre-pass (refine the pose first)"), this);
  rigid_->setObjectName(QStringLiteral("fitRigid"));
  rigid_->setChecked(true);
  layout->addWidget(rigid_);
  addDownRow(layout);
  addToleranceRow(layout);
  addCurvePicking(layout);
  addFitButtons(layout);
  addBoundAndStatus(layout);
  addAlternatives(layout);
  addChart(layout);
}

void FitPage::addDownRow(QVBoxLayout* layout) {
  // Which way is down: the fit estimates the organ's sag with its pose; told the direction of gravity it
  // also finds the part of the sag along the view, which the outline cannot show.
  auto* downRow = new QHBoxLayout;
  auto* downLabel = new QLabel(tr("&Down (gravity):"), this);
  down_ = new QComboBox(this);
  down_->setObjectName(QStringLiteral("fitDown"));
  down_->setToolTip(tr("Which way gravity points in this view, if known: the fit then also finds how the organ sags towards or "
                       "away from the camera, which the outline alone cannot show. Its size is still the fit's to find."));
  const std::pair<QString, Eigen::Vector3d> downs[] = {{tr("Not known"), Eigen::Vector3d::Zero()},
                                                       {tr("Towards the image bottom"), Eigen::Vector3d::UnitY()},
                                                       {tr("Towards the image top"), -Eigen::Vector3d::UnitY()},
                                                       {tr("Towards the image left"), -Eigen::Vector3d::UnitX()},
                                                       {tr("Towards the image right"), Eigen::Vector3d::UnitX()},
                                                       {tr("Away from the camera"), Eigen::Vector3d::UnitZ()},
                                                       {tr("Towards the camera"), -Eigen::Vector3d::UnitZ()}};
  for (const auto& [name, d] : downs) down_->addItem(name, QVariant::fromValue(QList<double>{d.x(), d.y(), d.z()}));
  downLabel->setBuddy(down_);
  connect(down_, &QComboBox::activated, this, [this](int index) {
    const QList<double> v = down_->itemData(index).value<QList<double>>();
    const Eigen::Vector3d d(v.value(0), v.value(1), v.value(2));
    if (!data() || (data()->down - d).norm() < 1e-12) return;
    wb_.doc->edit(tr("Set which way is down"), [&d](app::Case& k) { k.down = d; });
  });
  downRow->addWidget(downLabel);
  downRow->addWidget(down_, 1);
  layout->addLayout(downRow);
}

void FitPage::addToleranceRow(QVBoxLayout* layout) {
  // How sure a fit must be to count as determined: its own bound on how far its surface may be (issue 38).
  auto* toleranceRow = new QHBoxLayout;
  auto* toleranceLabel = new QLabel(tr("&Tolerance:"), this);
  tolerance_ = new QDoubleSpinBox(this);
  tolerance_->setAccessibleName(tr("Tolerance"));
  tolerance_->setObjectName(QStringLiteral("fitTolerance"));
  tolerance_->setAccessibleName(tr("Tolerance"));
  tolerance_->setRange(0.5, 50);
  tolerance_->setSingleStep(0.5);
  tolerance_->setDecimals(1);
  tolerance_->setSuffix(tr(" mm"));
  tolerance_->setValue(5.0);
  tolerance_->setToolTip(
      tr("A fit is determined only when its own bound on how far its surface may be from the truth is "
         "within this; otherwise it is shown as ambiguous, with what would decide it."));
  toleranceLabel->setBuddy(tolerance_);
  toleranceRow->addWidget(toleranceLabel);
  toleranceRow->addWidget(tolerance_, 1);
  layout->addLayout(toleranceRow);
}

void FitPage::addCurvePicking(QVBoxLayout* layout) {
  // Anatomical curves: a ridge or ligament sketched in step 3, and the same curve clicked on the organ.
  auto* pickCurve = toolButton(this, tr("Pick Curve on Organ (K)"),
                               tr("Click along the ridge or ligament on the organ drawn over the frame; the sketched ridge or "
                                  "ligament nearest to the first click gets the curve. Enter ends, Backspace takes back a click."),
                               Tool::OrganCurve, Qt::Key_K);
  pickCurve->setObjectName(QStringLiteral("pickCurve"));
  layout->addWidget(pickCurve);
  curves_ = new QLabel(this);
  curves_->setObjectName(QStringLiteral("fitCurves"));
  curves_->setWordWrap(true);
  layout->addWidget(curves_);
}

void FitPage::addFitButtons(QVBoxLayout* layout) {
  auto* row = new QHBoxLayout;
  auto* fit = new QPushButton(tr("Fit to Contour (F9)"), this);
  fit->setObjectName(QStringLiteral("fitButton"));
  connect(fit, &QPushButton::clicked, this, &FitPage::runElasticFit);
  // F9 from anywhere, as F10: to this step, and fit. (The button's own key acted only while this page showed: F9 on
  // step 4's page did nothing, a person's check found.)
  auto* key = new QAction(tr("Fit to Contour (from any step)"), this);  // named: the keyboard reference
  key->setShortcut(QKeySequence(Qt::Key_F9));
  connect(key, &QAction::triggered, this, &FitPage::runElasticFit);
  wb_.window->addAction(key);
  auto* clear = new QPushButton(tr("Clear Fit"), this);
  clear->setObjectName(QStringLiteral("fitClear"));
  connect(clear, &QPushButton::clicked, this, [this] {
    if (data() && data()->fit) wb_.doc->edit(tr("Clear elastic fit"), [](app::Case& k) { k.fit.reset(); });
  });
  row->addWidget(fit);
  row->addWidget(clear);
  layout->addLayout(row);
  // After a fit: keep it, or revert it (its undo step) -- offered while it is the last edit.
  auto* decide = new QHBoxLayout;
  keep_ = new QPushButton(tr("Keep Fit"), this);
  keep_->setObjectName(QStringLiteral("fitKeep"));
  revert_ = new QPushButton(tr("Revert Fit (Ctrl+Z)"), this);
  revert_->setObjectName(QStringLiteral("fitRevert"));
  revert_->setToolTip(tr("Back to the organ and pose before the fit; Redo brings the fit back."));
  connect(keep_, &QPushButton::clicked, this, [this] {
    if (fitUndoIndex_ != wb_.doc->undoStack()->index()) return;
    fitUndoIndex_ = -1;
    keep_->setEnabled(false);
    revert_->setEnabled(false);
    // The bound stays in view once the fit is kept (it is the fit's, not the case part's status).
    status_->setText(tr("Fit kept: %1\nUncertainty: %2.")
                         .arg(QString::fromStdString(data()->fit ? data()->fit->status : std::string()))
                         .arg(uncertainty_));
  });
  connect(revert_, &QPushButton::clicked, this, [this] {
    if (fitUndoIndex_ != wb_.doc->undoStack()->index()) return;
    wb_.doc->undoAsked([this] {  // Redo brings the fit back, and with it this choice
      status_->setText(tr("Fit reverted: the organ and the pose are as before it (Ctrl+Shift+Z brings it back)."));
    });
  });
  connect(wb_.doc->undoStack(), &QUndoStack::indexChanged, this, [this](int index) {
    const bool open = fitUndoIndex_ >= 0 && index == fitUndoIndex_;
    keep_->setEnabled(open);
    revert_->setEnabled(open);
  });
  keep_->setEnabled(false);
  revert_->setEnabled(false);
  decide->addWidget(keep_);
  decide->addWidget(revert_);
  layout->addLayout(decide);
}

void FitPage::addBoundAndStatus(QVBoxLayout* layout) {
  // Where the organ may be: its outline at the fit's two far ends, dashed over the frame (the bound drawn).
  showBound_ = new QCheckBox(tr("Show where the organ &may be"), this);
  showBound_->setObjectName(QStringLiteral("fitShowBound"));
  showBound_->setChecked(true);
  showBound_->setToolTip(
      tr("After a fit: the organ's outline moved each way along the direction the fit is least sure of, as far as its "
         "bound (dashed): the organ may be anywhere between them."));
  connect(showBound_, &QCheckBox::toggled, this, [this] { showBound(); });
  layout->addWidget(showBound_);
  status_ = new QLabel(this);
  status_->setObjectName(QStringLiteral("fitStatus"));
  status_->setWordWrap(true);
  layout->addWidget(status_);
}

void FitPage::addAlternatives(QVBoxLayout* layout) {
  // An ambiguous fit's alternatives: choosing one previews the organ there over the frame.
  alternativesBox_ = new QWidget(this);
  auto* altRow = new QHBoxLayout(alternativesBox_);
  altRow->setContentsMargins(0, 0, 0, 0);
  alternativesList_ = new QComboBox(alternativesBox_);
  alternativesList_->setObjectName(QStringLiteral("fitAlternatives"));
  alternativesList_->setToolTip(tr("Poses that fit the contour nearly as well as the fit: choose one to see the organ there"));
  auto* useAlt = new QPushButton(tr("Fit from It"), alternativesBox_);
  useAlt->setObjectName(QStringLiteral("fitFromAlternative"));
  useAlt->setToolTip(tr("Put the organ at the chosen pose (one undo step) and fit from there without the rigid stage"));
  altRow->addWidget(alternativesList_, 1);
  altRow->addWidget(useAlt);
  alternativesBox_->setVisible(false);
  layout->addWidget(alternativesBox_);
  connect(alternativesList_, &QComboBox::currentIndexChanged, this, [this](int index) {
    if (!data()) return;
    if (index <= 0 || index > static_cast<int>(alternativePoses_.size())) {
      wb_.view->setCase(data());
      return;
    }
    auto preview = std::make_shared<app::Case>(*data());
    preview->fit.reset();
    preview->pose = alternativePoses_[static_cast<std::size_t>(index - 1)];
    wb_.view->setCase(preview);
  });
  connect(useAlt, &QPushButton::clicked, this, [this] { useAlternative(alternativesList_->currentIndex() - 1); });
}

void FitPage::addChart(QVBoxLayout* layout) {
  // Live chart: the contour-to-silhouette distance against run time.
  series_ = new QLineSeries;
  series_->setName(tr("mean distance (px)"));
  auto* chart = new QChart;
  chart->addSeries(series_);
  chart->legend()->hide();
  chart->setTitle(tr("Contour to silhouette (px) against time (s)"));
  chart->setTheme(QChart::ChartThemeDark);
  axisX_ = new QValueAxis;
  axisX_->setTitleText(tr("s"));
  axisX_->setRange(0, 1);
  axisY_ = new QValueAxis;
  axisY_->setTitleText(tr("px"));
  axisY_->setRange(0, 10);
  chart->addAxis(axisX_, Qt::AlignBottom);
  chart->addAxis(axisY_, Qt::AlignLeft);
  series_->attachAxis(axisX_);
  series_->attachAxis(axisY_);
  auto* chartView = new QChartView(chart, this);
  chartView->setObjectName(QStringLiteral("fitChart"));
  chartView->setRenderHint(QPainter::Antialiasing);
  chartView->setMinimumHeight(220);
  layout->addWidget(chartView, 1);
}

void FitPage::showAlternatives(const std::vector<simcore::RegistrationAlternative>& alternatives, bool ambiguous) {
  const QSignalBlocker block(alternativesList_);
  alternativesList_->clear();
  alternativePoses_.clear();
  alternativesList_->addItem(tr("The fit"));
  for (const auto& a : alternatives) {
    alternativePoses_.push_back(a.pose);
    alternativesList_->addItem(tr("Alternative %1: %2 mm away, %3 px").arg(alternativePoses_.size()).arg(a.apartMm, 0, 'f', 0).arg(a.score, 0, 'f', 2));
  }
  alternativesBox_->setVisible(!alternatives.empty());
  // The word that the overlay may be wrong stands out (orange, bold) while the fit is ambiguous.
  status_->setStyleSheet(ambiguous ? QStringLiteral("color: %1; font-weight: bold;").arg(palette::warning().name()) : QString());
}

void FitPage::useAlternative(int index) {
  if (!data() || index < 0 || index >= static_cast<int>(alternativePoses_.size())) return;
  const Pose pose = alternativePoses_[static_cast<std::size_t>(index)];
  wb_.doc->edit(tr("Use alternative pose"), [&pose](app::Case& k) {
    k.pose = pose;
    k.fit.reset();
  });
  runFit(false);
}

void FitPage::showBound() {
  const auto c = data();
  const bool current = c && c->fit && c->fit == boundFit_ && (c->pose.R - boundPose_.R).norm() < 1e-12 &&
                       (c->pose.t - boundPose_.t).norm() < 1e-12;
  // (kept while not drawn: Redo brings the same fit back, and its bound with it)
  wb_.view->setPossibleOutlines(current && showBound_->isChecked() ? boundOutlines_ : QList<QPolygonF>{}, boundText_);
}

void FitPage::refresh(const app::Case& c) {
  if (!wb_.jobs->isRunning()) showBound();  // (cleared once the fit they belong to is not the case's)
  if (!c.hasFit() && !wb_.jobs->isRunning()) {
    alternativePoses_.clear();
    alternativesBox_->setVisible(false);
    status_->setStyleSheet(QString());
  }
  // No stale word about a fit that is no longer there (undone or cleared).
  if (!c.hasFit() && !wb_.jobs->isRunning() && !status_->text().isEmpty() && !status_->text().startsWith(tr("Fit reverted")))
    status_->setText(tr("No elastic fit yet: F9 fits the organ onto the contour."));
  {
    // The case's direction: one of the list's, or an entry of its own (a case written by hand).
    const QSignalBlocker block(down_);
    int found = -1;
    for (int i = 0; i < down_->count() && found < 0; ++i) {
      const QList<double> v = down_->itemData(i).value<QList<double>>();
      if ((Eigen::Vector3d(v.value(0), v.value(1), v.value(2)) - c.down).norm() < 1e-9) found = i;
    }
    if (found < 0) {
      down_->addItem(tr("(%1, %2, %3) in the camera frame").arg(c.down.x(), 0, 'f', 2).arg(c.down.y(), 0, 'f', 2).arg(c.down.z(), 0, 'f', 2),
                     QVariant::fromValue(QList<double>{c.down.x(), c.down.y(), c.down.z()}));
      found = down_->count() - 1;
    }
    down_->setCurrentIndex(found);
  }
  int sketched = 0, onOrgan = 0;
  for (const auto& s : c.contour.segments)
    if (!s.isSilhouette()) {
      ++sketched;
      onOrgan += !s.modelVertices.empty();
    }
  curves_->setText(sketched == 0 ? tr("No ridge or ligament sketched: the fit uses the silhouette alone.")
                                 : tr("Ridges and ligaments: %1 sketched, %2 with their curve on the organ (held by the fit).")
                                       .arg(sketched)
                                       .arg(onOrgan));
}

void FitPage::runElasticFit() { runFit(rigid_->isChecked()); }

void FitPage::runFit(bool rigidPrepass) {
  if (!wb_.doc->hasCase()) return;
  const auto c = data();
  wb_.goToStep(app::Step::Elastic);  // (F9 from another step: the fit's page shows what it does, or what it needs)
  if (const std::string missing = app::missingFor(*c, app::Step::Elastic); !missing.empty()) {
    status_->setText(tr("The fit needs %1.").arg(QString::fromStdString(missing)));
    wb_.status(status_->text());
    return;
  }
  series_->clear();
  axisY_->setRange(0, 10);
  axisX_->setRange(0, 1);
  // The case's organ, attachments and material (the Simulation panel's), through the one fit pipeline.
  app::FitInput input = app::fitInputFromCase(*c);
  input.rigidPrepass = rigidPrepass;
  input.toleranceMm = tolerance_->value();
  status_->setText(tr("Fitting... (Esc cancels)"));
  showAlternatives({}, false);
  boundFit_.reset();  // (the last fit's bound is not this one's)
  showBound();
  wb_.jobs->run(tr("Elastic fit..."), [this, c, input](const std::atomic<bool>& cancel, const auto& progress) -> std::function<void()> {
    try {
      auto onIteration = [this, c, &cancel, &progress](const simcore::RegistrationIteration& it, const Eigen::VectorXd& x, const Pose& pose) {
        // Live: the organ deforms over the frame and the chart grows (on the GUI thread), as a preview.
        auto preview = std::make_shared<app::Case>(*c);
        simcore::RegistrationResult partial;
        partial.x = x;
        preview->fit = app::toCasePart(partial);
        preview->pose = pose;
        const double t = it.wallMs / 1000.0, px = it.score();
        QMetaObject::invokeMethod(this, [this, preview, t, px] {
          series_->append(t, px);
          axisX_->setRange(0, std::max(1.0, 1.2 * t));
          axisY_->setRange(0, std::max(axisY_->max(), 1.1 * px));
          axisY_->applyNiceNumbers();  // round ticks (0, 2, 4, ...)
          wb_.view->setCase(preview);
        }, Qt::QueuedConnection);
        progress(std::min(0.95, 0.05 + 0.045 * it.iteration), QStringLiteral("%1 px").arg(px, 0, 'f', 2));
        return !cancel.load();
      };
      // The second frame (step 2), its outline (step 3) and the camera's motion estimated from the two frames.
      app::FitInput in = input;
      QString secondNote;
      if (!c->frame2.empty()) {
        std::string motion;
        in.frames = {app::secondFrame(*c, &motion)};
        secondNote = tr(" Second frame: %1; %2 features.")
                         .arg(QString::fromStdString(motion))
                         .arg(in.frames.front().tracks.size());
      }
      const simcore::RegistrationResult r = app::runElasticFit(in, onIteration);
      const QString status = QString::fromStdString(r.status);
      if (r.cancelled || !r.ok) {
        return [this, status, cancelled = r.cancelled] {
          wb_.view->setCase(data());  // back to the case as it was
          status_->setText(cancelled ? tr("Cancelled; the case is unchanged.") : tr("The fit failed: %1").arg(status));
          wb_.status(status_->text());
          emit fitFinished(false, status_->text());
        };
      }
      auto fit = app::toCasePart(r);
      const Pose pose = r.pose;
      const double ms = r.iterations.empty() ? 0.0 : r.iterations.back().wallMs;
      const QString uncertainty = QString::fromStdString(app::uncertaintySentence(r.uncertainty));
      QList<QPolygonF> outlines;
      for (const auto& line : app::boundOutlines(*c, r)) {
        QPolygonF poly;
        for (const auto& p : line) poly << QPointF(p.x(), p.y());
        outlines << poly;
      }
      const double boundMm = r.uncertainty.surfaceMm;
      return [this, fit, pose, status, ms, uncertainty, outlines, boundMm, secondNote, ambiguous = r.ambiguous,
              alternatives = r.alternatives] {
        boundOutlines_ = outlines;
        boundFit_ = fit;
        boundPose_ = pose;
        boundText_ = tr("where the organ may be (the fit's bound, %1 mm)").arg(boundMm, 0, 'f', 1);
        wb_.doc->edit(tr("Elastic fit"), [&](app::Case& k) {
          k.fit = fit;
          k.pose = pose;
        });
        showBound();
        fitUndoIndex_ = wb_.doc->undoStack()->index();
        uncertainty_ = uncertainty;
        keep_->setEnabled(true);
        revert_->setEnabled(true);
        // An ambiguous fit begins with the word, in capitals: the overlay may be wrong.
        QString said = status;
        if (ambiguous && said.startsWith(QStringLiteral("ambiguous: "))) said = tr("AMBIGUOUS: %1").arg(said.mid(11));
        // How far the 3D result may be from the truth, from the fit itself (its second line).
        status_->setText(tr("%1 (%2 s). Keep it, or revert it (Ctrl+Z).\nUncertainty: %3.%4")
                             .arg(said)
                             .arg(ms / 1000.0, 0, 'f', 1)
                             .arg(uncertainty)
                             .arg(secondNote));
        showAlternatives(alternatives, ambiguous);
        wb_.status(tr("Elastic fit: %1").arg(said));
        emit fitFinished(true, status);
      };
    } catch (const std::exception& e) {
      const QString message = QString::fromUtf8(e.what());
      return [this, message] {
        wb_.view->setCase(data());
        status_->setText(tr("The fit failed: %1").arg(message));
        wb_.status(status_->text());  // (the status bar had stayed at "Elastic fit...", and nothing was logged)
        emit fitFinished(false, status_->text());
      };
    }
  });
}

}  // namespace rehearse::ui

