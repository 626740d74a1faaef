#include "rehearse/ui/pages/steppage.hpp"

#include <QAction>
#include <QPushButton>

namespace rehearse::ui {

StepPage::StepPage(Workbench& wb, app::Step step, QWidget* parent) : QWidget(parent), wb_(wb), step_(step) {}

QPushButton* StepPage::toolButton(QWidget* parent, const QString& text, const QString& tip, Tool tool, Qt::Key key) {
  auto* button = new QPushButton(text, parent);
  button->setToolTip(tip);
  connect(button, &QPushButton::clicked, this, [this, tool] { wb_.view->setTool(tool); });
  auto* shortcut = new QAction(this);
  shortcut->setShortcut(QKeySequence(key));
  connect(shortcut, &QAction::triggered, this, [this, tool] {
    wb_.goToStep(step_);
    wb_.view->setTool(tool);
  });
  wb_.window->addAction(shortcut);
  return button;
}

void StepPage::stepKey(Qt::Key key, Tool tool) {
  auto* a = new QAction(this);
  a->setShortcut(QKeySequence(key));
  connect(a, &QAction::triggered, this, [this, tool] {
    if (wb_.currentStep() == step_) wb_.view->setTool(tool);
  });
  wb_.window->addAction(a);
}

}  // namespace rehearse::ui
