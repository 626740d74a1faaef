#pragma once
// A label whose text changes many times a second (a force, a rate, a status) makes Qt lay out its whole window
// again at each change: QLabel::setText always asks its parent's layout, which asks the dock's and the main window's
// (measured, issue 64: 11-22 ms of the GUI thread per change in step 7). A SteadyBox holds one such widget and passes
// its size on only when the room it needs at its present width changes (a line more or less); otherwise the new text
// is only repainted.
#include <QLabel>
#include <QStatusBar>
#include <QWidget>

namespace rehearse::ui {

class SteadyBox : public QWidget {
 public:
  /// Takes `content` as its only child (the box's own layout is none: it places the child itself).
  SteadyBox(QWidget* content, QWidget* parent);

  QSize sizeHint() const override;
  QSize minimumSizeHint() const override;
  bool hasHeightForWidth() const override;
  int heightForWidth(int width) const override;
  /// How many size changes this box passed on to the layout (a test counts them).
  int passedOn() const { return passedOn_; }

 protected:
  bool event(QEvent* e) override;
  void resizeEvent(QResizeEvent* e) override;

 private:
  int need(int width) const;  // the height the content needs at `width`, within its own bounds
  int wanted() const;           // the width it asks for: a wrapping text's least, a single line's preferred
  void refit();

  QWidget* content_;
  int lastNeed_ = -1;
  int lastWants_ = -1;
  int passedOn_ = 0;
};

/// A word-wrapped label of a fixed number of lines: the widgets below it stay put whatever its text's length (they
/// moved with every message, and each move laid the page out again). A longer text is drawn as far as the lines hold
/// it, ending in an ellipsis; text() stays whole (its owner puts it in the tooltip).
class LinesLabel : public QLabel {
 public:
  LinesLabel(int lines, QWidget* parent);

 protected:
  void paintEvent(QPaintEvent* e) override;
  void changeEvent(QEvent* e) override;

 private:
  void fixHeight();
  int lines_;
};

/// QStatusBar draws a temporary message (showMessage) up to its first permanent widget and cuts it there, mid-letter,
/// against that widget's text. This one ends it in an ellipsis; currentMessage() stays whole, and is the bar's tooltip
/// while it is shown (the Messages panel keeps what say() said).
class ElidingStatusBar : public QStatusBar {
 public:
  explicit ElidingStatusBar(QWidget* parent);

 protected:
  void paintEvent(QPaintEvent* e) override;
};

}  // namespace rehearse::ui
