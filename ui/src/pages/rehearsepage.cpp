#include "rehearse/ui/pages/rehearsepage.hpp"

#include "rehearse/ui/simulationpanel.hpp"

#include <QLabel>
#include <QPushButton>
#include <QVBoxLayout>

#include <algorithm>

namespace rehearse::ui {

RehearsePage::RehearsePage(Workbench& wb, QWidget* parent) : StepPage(wb, app::Step::Rehearse, parent) {
  auto* layout = new QVBoxLayout(this);
  auto* intro = new QLabel(tr("Rehearse the gesture on the registered organ: with the grasper, press on the organ to close the jaws "
                              "there, drag to pull it, release to let go. The simulation runs while you pull (Simulation panel: "
                              "material, ligaments); the view shows it composited into the frame once the appearance is estimated "
                              "(step 6). Cutting comes in a later version."),
                           this);
  intro->setWordWrap(true);
  layout->addWidget(intro);
  auto* grasper = toolButton(this, tr("Grasper (R)"), tr("Press on the organ to grasp it, drag to pull, release to let go"), Tool::Grasp, Qt::Key_R);
  grasper->setObjectName(QStringLiteral("grasperTool"));
  layout->addWidget(grasper);
  status_ = new QLabel(this);
  status_->setObjectName(QStringLiteral("rehearseStatus"));
  status_->setWordWrap(true);
  layout->addWidget(status_);
  force_ = new QLabel(this);
  force_->setObjectName(QStringLiteral("rehearseForce"));
  QFont big = force_->font();
  big.setPointSizeF(big.pointSizeF() * 1.4);
  force_->setFont(big);
  layout->addWidget(force_);
  layout->addStretch(1);
}

void RehearsePage::refresh(const app::Case& c) {
  if (!c.hasPose) status_->setText(tr("Place the organ over the frame first (step 4)."));
  else if (status_->text().isEmpty() || status_->text().startsWith(tr("Place the organ")))
    status_->setText(tr("Pick the grasper (R) and press on the organ."));
}

void RehearsePage::showFrame(const std::shared_ptr<const SimulationFrame>& f) {
  if (!f) return;
  slips_ += static_cast<int>(std::count(f->events.begin(), f->events.end(), "slip"));
  const auto& t = f->tool;
  if (!t.held.empty())
    status_->setText(tr("Holding %n node(s) of tissue.", nullptr, static_cast<int>(t.held.size())));
  else if (t.jawClosed)
    status_->setText(f->message.isEmpty() ? tr("The jaws are closed on nothing.") : f->message);
  else if (std::find(f->events.begin(), f->events.end(), "release") != f->events.end())
    status_->setText(tr("Released: the tissue relaxes."));
  force_->setText(tr("Tool force %1 N%2").arg(t.force.norm(), 0, 'f', 2).arg(slips_ ? tr("   (slips: %1)").arg(slips_) : QString()));
}

}  // namespace rehearse::ui
