#include "rehearse/ui/pages/steppage.hpp"

#include "rehearse/ui/frameview.hpp"

#include <QAction>
#include <QDir>
#include <QFileInfo>
#include <QPushButton>
#include <QSettings>

namespace rehearse::ui {

StepPage::StepPage(Workbench& wb, app::Step step, QWidget* parent) : QWidget(parent), wb_(wb), step_(step) {}

QPushButton* StepPage::toolButton(QWidget* parent, const QString& text, const QString& tip, Tool tool, Qt::Key key) {
  auto* button = new QPushButton(text, parent);
  button->setToolTip(tip);
  // Pressed while its tool is in hand (a helper pressed R and could not tell which instrument it held).
  button->setCheckable(true);
  // In the theme's highlight while pressed: Fusion's sunken shade of the dark theme's button (40 against 48 levels) did
  // not show which one was (a person's check: "the tool buttons never look pressed").
  button->setStyleSheet(QStringLiteral("QPushButton:checked { background-color: palette(highlight); color: "
                                       "palette(highlighted-text); font-weight: bold; border: 1px solid "
                                       "palette(light); border-radius: 3px; padding: 4px 8px; }"));
  connect(button, &QPushButton::clicked, this, [this, tool, button] {
    wb_.view->setTool(tool);
    button->setChecked(wb_.view->tool() == tool);
    // The keys go to the frame view, where the tool works (Space there closes the grasper's jaws; the button kept them).
    wb_.view->setFocus();
  });
  if (wb_.view) {
    button->setChecked(wb_.view->tool() == tool);
    connect(wb_.view, &FrameView::toolChanged, button, [button, tool](Tool t) { button->setChecked(t == tool); });
  }
  auto* shortcut = new QAction(text, this);  // named: the keyboard reference lists it
  shortcut->setShortcut(QKeySequence(key));
  shortcut->setProperty("rehearseWhere",
                        QStringLiteral("Step %1 %2")
                            .arg(app::index(step_) + 1)
                            .arg(QString::fromLatin1(app::kSteps[static_cast<std::size_t>(app::index(step_))].title)));
  connect(shortcut, &QAction::triggered, this, [this, tool] {
    wb_.goToStep(step_);
    wb_.view->setTool(tool);
  });
  wb_.window->addAction(shortcut);
  return button;
}

void StepPage::stepKey(const QKeySequence& key, std::function<void()> handler, const QString& what) {
  wb_.keys->bind(key, step_, std::move(handler), what);
}

void StepKeys::bind(const QKeySequence& key, app::Step step, std::function<void()> handler, const QString& what) {
  const QString text = key.toString();
  auto& byStep = handlers_[text];
  if (byStep.empty()) {
    auto* a = new QAction(window_);
    a->setShortcut(key);
    QObject::connect(a, &QAction::triggered, window_, [this, text] {
      const auto& h = handlers_[text];
      if (auto it = h.find(current_()); it != h.end()) it->second();
    });
    window_->addAction(a);
    actions_[text] = a;
  }
  byStep[step] = std::move(handler);
  QVariantMap described = actions_[text]->property("rehearseStepKeys").toMap();
  described[QString::number(app::index(step))] = what;
  actions_[text]->setProperty("rehearseStepKeys", described);
  actions_[text]->setEnabled(current_() == step || byStep.count(current_()));
}

void StepKeys::stepShown(app::Step step) {
  for (const auto& [text, action] : actions_) action->setEnabled(handlers_[text].count(step) > 0);
}

QString dialogFolder() {
  const QString last = QSettings().value(QStringLiteral("lastDir")).toString();
  return !last.isEmpty() && QFileInfo(last).isDir() ? last : QDir::homePath();
}

void rememberDialogFolder(const QString& file) {
  if (!file.isEmpty()) QSettings().setValue(QStringLiteral("lastDir"), QFileInfo(file).absolutePath());
}

}  // namespace rehearse::ui
