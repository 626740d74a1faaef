#include "rehearse/ui/pages/appearancepage.hpp"

#include "rehearse/ui/composition.hpp"

#include <rehearse/app/appearancestep.hpp>

#include <QAction>
#include <QComboBox>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPushButton>
#include <QTableWidget>
#include <QCheckBox>
#include <QVBoxLayout>

namespace rehearse::ui {

AppearancePage::AppearancePage(Workbench& wb, Composition* composition, QWidget* parent)
    : StepPage(wb, app::Step::Appearance, parent), composition_(composition) {
  auto* layout = new QVBoxLayout(this);
  auto* intro = new QLabel(tr("Estimate the light and the organ's reflectance from the frame through the registered organ; the frame "
                              "view then shows the organ re-shaded into the frame (F2 composited, F3 overlay, F4 3D)."),
                           this);
  intro->setWordWrap(true);
  layout->addWidget(intro);
  auto* fillRow = new QHBoxLayout;
  auto* fillLabel = new QLabel(tr("&Background fill:"), this);
  inpaint_ = new QComboBox(this);
  inpaint_->setObjectName(QStringLiteral("appearanceInpaint"));
  inpaint_->setToolTip(tr("How the frame behind the organ is filled, shown where the organ moves away. Telea is the "
                          "best measured on organ-sized holes in a real frame, and as fast as any (BENCHMARKS.md)."));
  inpaint_->addItem(tr("Telea (default)"), QStringLiteral("telea"));
  inpaint_->addItem(tr("Navier-Stokes"), QStringLiteral("ns"));
  inpaint_->addItem(tr("Frequency-selective (slow)"), QStringLiteral("fsr"));
  inpaint_->addItem(tr("Shift-map (slowest)"), QStringLiteral("shiftmap"));
  fillLabel->setBuddy(inpaint_);
  fillRow->addWidget(fillLabel);
  fillRow->addWidget(inpaint_, 1);
  layout->addLayout(fillRow);
  turn_ = new QCheckBox(tr("Let the shading settle the &turn the outline leaves open"), this);
  turn_->setObjectName(QStringLiteral("appearanceTurn"));
  turn_->setChecked(true);
  turn_->setToolTip(
      tr("An outline hardly changes when the organ turns about the camera's X or Y axis, but its shading does: the "
         "estimate also tries turns up to 15\u00b0 that keep the organ on the outline (step 3) and takes the one whose "
         "shading the light explains clearly best, as one step Undo puts back. Off: the organ stays where it is now (Undo puts back a turn taken earlier)."));
  layout->addWidget(turn_);
  auto* row = new QHBoxLayout;
  auto* run = new QPushButton(tr("Estimate Appearance (F10)"), this);
  run->setObjectName(QStringLiteral("appearanceRun"));
  connect(run, &QPushButton::clicked, this, &AppearancePage::estimate);
  auto* clear = new QPushButton(tr("Clear"), this);
  clear->setObjectName(QStringLiteral("appearanceClear"));
  clear->setToolTip(tr("Forget the estimate (Ctrl+Z brings it back)"));
  connect(clear, &QPushButton::clicked, this, [this] {
    if (data() && data()->appearance) wb_.doc->edit(tr("Clear appearance"), [](app::Case& k) { k.appearance.reset(); });
  });
  row->addWidget(run);
  row->addWidget(clear);
  layout->addLayout(row);
  // F10 from anywhere: to this step, and estimate.
  auto* key = new QAction(tr("Estimate Appearance (from any step)"), this);  // named: the keyboard reference
  key->setShortcut(QKeySequence(Qt::Key_F10));
  connect(key, &QAction::triggered, this, &AppearancePage::estimate);
  wb_.window->addAction(key);
  status_ = new QLabel(this);
  status_->setObjectName(QStringLiteral("appearanceStatus"));
  status_->setWordWrap(true);
  status_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  layout->addWidget(status_);
  // The fitted parameters, as DejaVu's Table 1: the light's position and per-channel reflectances.
  table_ = new QTableWidget(4, 3, this);
  table_->setAccessibleName(tr("Estimated light and reflectance"));
  table_->setObjectName(QStringLiteral("appearanceTable"));
  table_->setHorizontalHeaderLabels({tr("x / R"), tr("y / G"), tr("z / B")});
  table_->setVerticalHeaderLabels({tr("Light (mm)"), tr("k_d"), tr("k_s"), tr("\u03c3 / n / light")});
  table_->setWordWrap(false);
  table_->setToolTip(tr(
      "Theta as DejaVu's Table 1: the light's position in the camera frame, the diffuse and specular reflectance per "
      "colour channel, the roughness \u03c3 and the scope's fall-off n (cos^n off its axis: the light's cone and the "
      "lens vignetting) and the light's distance from the lens. "
      "* marks a channel the frame does not measure (clipped over its highlight)."));
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::Stretch);
  table_->setVerticalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  table_->verticalHeader()->setSectionResizeMode(QHeaderView::Fixed);
  table_->verticalHeader()->setDefaultSectionSize(24);
  table_->setFixedHeight(table_->horizontalHeader()->sizeHint().height() + 4 * 24 + 4);
  layout->addWidget(table_);
  report_ = new QLabel(this);
  report_->setObjectName(QStringLiteral("appearanceReport"));
  report_->setWordWrap(true);
  report_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  layout->addWidget(report_);
  // The two layers the composition is made of.
  auto* layers = new QGridLayout;
  diffuse_ = new QLabel(this);
  diffuse_->setObjectName(QStringLiteral("appearanceDiffuse"));
  background_ = new QLabel(this);
  background_->setObjectName(QStringLiteral("appearanceBackground"));
  residual_ = new QLabel(this);
  residual_->setObjectName(QStringLiteral("appearanceResidual"));
  for (QLabel* l : {diffuse_, background_, residual_}) {
    l->setMinimumSize(120, 68);
    l->setMaximumHeight(90);
    l->setAlignment(Qt::AlignCenter);
    l->setFrameShape(QFrame::StyledPanel);
  }
  diffuse_->setToolTip(tr("The frame without its specular highlights (I_D): what the diffuse part is fitted to"));
  background_->setToolTip(tr("The frame with the organ filled in (I_B): what shows where the organ moves away"));
  layers->addWidget(new QLabel(tr("Diffuse image I_D"), this), 0, 0);
  layers->addWidget(new QLabel(tr("Background I_B"), this), 0, 1);
  layers->addWidget(new QLabel(tr("Left unexplained"), this), 0, 2);
  residual_->setToolTip(
      tr("What Theta leaves of the frame on the organ, |frame - model| x 3: the organ's texture, specks, beads, and "
         "wherever the model does not hold (bright where it explains least)"));
  layers->addWidget(diffuse_, 1, 0);
  layers->addWidget(background_, 1, 1);
  layers->addWidget(residual_, 1, 2);
  layout->addLayout(layers);
  layout->addStretch(1);
  connect(composition_, &Composition::readyChanged, this, &AppearancePage::showLayers);
}

void AppearancePage::showLayers() {
  auto thumb = [](const QImage& img, QLabel* l) {
    if (img.isNull()) {
      l->setPixmap({});
      l->setText(tr("(none)"));
    } else {
      l->setPixmap(QPixmap::fromImage(img.scaled(l->width() - 4, l->height() - 4, Qt::KeepAspectRatio, Qt::SmoothTransformation)));
    }
  };
  thumb(composition_->diffuseImage(), diffuse_);
  thumb(composition_->backgroundImage(), background_);
  thumb(composition_->residualImage(), residual_);
}

void AppearancePage::refresh(const app::Case& c) {
  const auto& a = c.appearance;
  for (int r = 0; r < 4; ++r)
    for (int k = 0; k < 3; ++k) {
      QString text;
      if (a) {
        const auto& t = a->theta;
        if (r == 0) text = QString::number(1e3 * t.lightPosition[k], 'f', 1);
        else if (r == 1) text = QString::number(t.kd[k], 'g', 4);
        else if (r == 2) text = a->highlightFound ? QString::number(t.ks[k], 'g', 4) + (a->ksMeasured[static_cast<std::size_t>(k)] ? QString() : QStringLiteral(" *"))
                                                  : tr("not determined");
        else if (r == 3 && k == 0)
          text = a->highlightFound ? QString::number(t.roughness, 'f', 3) : tr("not determined");
        else if (r == 3 && k == 1)
          text = tr("n %1").arg(t.falloff, 0, 'f', 2);
        else if (r == 3 && k == 2)
          text = tr("%1 mm").arg(1e3 * t.lightPosition.norm(), 0, 'f', 1);  // ("light 20.7 mm off lens" was cut)
      }
      auto* item = table_->item(r, k);
      if (!item) table_->setItem(r, k, item = new QTableWidgetItem);
      item->setText(text);
      QString tip;
      if (a && r == 3 && k == 2) tip = tr("The light is %1 mm from the lens.").arg(1e3 * a->theta.lightPosition.norm(), 0, 'f', 1);
      if (a && r == 2 && a->highlightFound && !a->ksMeasured[static_cast<std::size_t>(k)])
        tip = tr("* not measured: this channel is clipped all over the highlight, so its specular reflectance is the "
                 "other channels' mean.");
      item->setToolTip(tip);
    }
  if (!a) {
    report_->clear();
    if (!wb_.jobs->isRunning())
      status_->setText(app::missingFor(c, app::Step::Appearance).empty()
                           ? tr("No appearance yet: F10 estimates it from the frame and the organ as registered.")
                           : tr("The appearance needs %1.").arg(QString::fromStdString(app::missingFor(c, app::Step::Appearance))));
    status_->setStyleSheet(QString());
    return;
  }
  QStringList lines;
  for (const auto& s : a->stages)
    lines << tr("%1: %2 levels, %3 ms").arg(QString::fromStdString(s.name)).arg(s.rms, 0, 'f', 2).arg(s.ms, 0, 'f', 0);
  // The share floored, as the re-shading's line below says it (89.95 % is not yet the 90 % that re-shades in full).
  lines << tr("Explains %1 % of the shading (smooth: %2 %); at rest %3 dB in the organ; %4 s.")
               .arg(imaging::explainedPercent(a->explained))
               .arg(imaging::explainedPercent(a->smoothShare))
               .arg(a->restPsnr, 0, 'f', 1)
               .arg(a->totalMs / 1000, 0, 'f', 2);
  // How far the composited view follows the model (imaging::reshadeTrust): said whenever it is not in full.
  if (a->textureOnly)
    lines << tr("Drawn as texture only: the frame's own colours follow the tissue.");
  else if (a->reshading().trust < 1)
    lines << tr("Re-shading applies %1 % of the model's change to the frame's colours (in full from 90 % explained).")
                 .arg(imaging::trustPercent(a->reshading().trust));
  else
    lines << tr("Re-shading applies the model's change in full (90 % or more explained).");
  if (!a->sources.empty()) {
    // The light the frame shows: the scope's alone, each second source tried beside it, and the one Theta carries.
    QStringList tried;
    for (const auto& k : a->sources)
      tried << tr("%1 %2 %").arg(QString::fromStdString(k.name)).arg(imaging::explainedPercent(k.explainedWith)) +
                   (k.used ? tr(" (used)") : QString());
    lines << tr("Light: the scope's light alone explains %1 %; with %2.").arg(imaging::explainedPercent(a->scopeExplained)).arg(tried.join(QStringLiteral(", ")));
    auto rgb = [](const Eigen::Vector3d& v) {
      return QStringLiteral("%1 / %2 / %3").arg(v.x(), 0, 'g', 3).arg(v.y(), 0, 'g', 3).arg(v.z(), 0, 'g', 3);
    };
    if (a->theta.hasDistantLight())
      lines << tr("Distant light towards (%1, %2, %3) in the camera frame, k_r %4.")
                   .arg(a->theta.roomDirection.x(), 0, 'f', 2)
                   .arg(a->theta.roomDirection.y(), 0, 'f', 2)
                   .arg(a->theta.roomDirection.z(), 0, 'f', 2)
                   .arg(rgb(a->theta.kr));
    if (a->theta.hasAmbient()) lines << tr("Ambient term k_a %1.").arg(rgb(a->theta.ka));
  }
  if (!a->checks.empty()) {
    QStringList without;
    for (const auto& k : a->checks)
      without << tr("%1 %2 %").arg(QString::fromStdString(k.part)).arg(imaging::explainedPercent(k.explainedWithout)) +
                     (k.holds ? QString() : tr(" (not seen)"));
    lines << tr("Left out of the scope's light (%1 % with every part): %2.")
                 .arg(imaging::explainedPercent(a->sources.empty() ? a->explained : a->scopeExplained))
                 .arg(without.join(QStringLiteral(", ")));
  }
  if (!a->turnSaid.empty() && !a->turned) lines << QString::fromStdString(a->turnSaid);
  report_->setText(lines.join(QLatin1Char('\n')));
  if (!wb_.jobs->isRunning()) {
    QString text = QString::fromStdString(a->status);
    if (!text.isEmpty()) text[0] = text[0].toUpper();
    if (a->turned) text += QStringLiteral(". ") + QString::fromStdString(a->turnSaid);
    if (!c.appearanceCurrent())
      text = tr("STALE: estimated at another pose, shape or frame; the composited view is off until it is estimated again (F10). %1").arg(text);
    status_->setText(text);
    // A second source used is a warning too: it can stand in for an organ registered off the frame's.
    const bool secondSource = a->theta.hasDistantLight() || a->theta.hasAmbient();
    const bool warn = a->textureOnly || !a->highlightFound || a->lightAtBound || !c.appearanceCurrent() || secondSource;
    status_->setStyleSheet(warn ? QStringLiteral("color: %1; font-weight: bold;").arg(palette::warning().name()) : QString());
  }
}

void AppearancePage::estimate() {
  if (!wb_.doc->hasCase()) return;
  wb_.goToStep(app::Step::Appearance);
  const auto c = data();
  if (const std::string missing = app::missingFor(*c, app::Step::Appearance); !missing.empty()) {
    status_->setText(tr("The appearance needs %1.").arg(QString::fromStdString(missing)));
    return;
  }
  app::AppearanceInput input = app::appearanceInputFromCase(*c);
  const imaging::InpaintMethod method = imaging::parseInpaintMethod(inpaint_->currentData().toString().toStdString());
  input.inpaint = method;
  input.turnByShading = turn_->isChecked();
  status_->setText(tr("Estimating... (Esc cancels)"));
  status_->setStyleSheet(QString());
  wb_.jobs->run(tr("Estimating the appearance..."), [this, c, input, method](const std::atomic<bool>& cancel, const auto& progress) mutable -> std::function<void()> {
    input.progress = [&cancel, &progress](double share, const std::string& what) {
      progress(share, QString::fromStdString(what));
      return !cancel.load();
    };
    try {
      const app::AppearanceOutput out = app::runAppearance(input);
      auto estimate = app::estimateFromRun(out, *c, method);
      app::AppearanceLayers layers{out.fit.separation.diffuse, out.background, out.albedo, out.residual};
      const Pose turnedPose = out.turn.pose;
      return [this, c, estimate, layers, turnedPose] {
        if (data()->pose.t != c->pose.t || data()->pose.R != c->pose.R || data()->shapeDigest() != c->shapeDigest()) {
          status_->setText(tr("The organ moved while its appearance was estimated; estimate it again (F10)."));
          emit estimated(false, status_->text());
          return;
        }
        composition_->offer(estimate, layers);
        wb_.doc->edit(estimate->turned ? tr("Estimate appearance and turn the organ") : tr("Estimate appearance"),
                      [&](app::Case& k) {
                        k.appearance = estimate;
                        if (estimate->turned) k.pose = turnedPose;
                      });
        QString said = QString::fromStdString(estimate->status);
        if (estimate->turned) said += QStringLiteral(". ") + QString::fromStdString(estimate->turnSaid);
        wb_.status(tr("Appearance: %1 (%2 s)").arg(said).arg(estimate->totalMs / 1000, 0, 'f', 1));
        emit estimated(true, said);
      };
    } catch (const imaging::AppearanceCancelled&) {
      return [this] {
        status_->setText(tr("Cancelled; the case is unchanged."));
        wb_.status(status_->text());
        emit estimated(false, status_->text());
      };
    } catch (const std::exception& e) {
      const QString message = QString::fromUtf8(e.what());
      return [this, message] {
        status_->setText(tr("The appearance could not be estimated: %1").arg(message));
        status_->setStyleSheet(QStringLiteral("color: %1; font-weight: bold;").arg(palette::warning().name()));
        wb_.status(status_->text());
        emit estimated(false, status_->text());
      };
    }
  });
}

}  // namespace rehearse::ui
