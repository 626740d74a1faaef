#include "rehearse/ui/steadybox.hpp"

#include <QEvent>
#include <QPainter>
#include <QResizeEvent>
#include <QStyle>
#include <QStyleOption>
#include <QSizeGrip>

#include <algorithm>

namespace rehearse::ui {

SteadyBox::SteadyBox(QWidget* content, QWidget* parent) : QWidget(parent), content_(content) {
  content_->setParent(this);
  setSizePolicy(content_->sizePolicy());
  content_->setGeometry(rect());
}

QSize SteadyBox::sizeHint() const {
  return content_->sizeHint();
}

QSize SteadyBox::minimumSizeHint() const {
  return content_->minimumSizeHint();
}

bool SteadyBox::hasHeightForWidth() const {
  return content_->hasHeightForWidth();
}

int SteadyBox::heightForWidth(int width) const {
  return content_->heightForWidth(width);
}

int SteadyBox::need(int width) const {
  const int h = content_->hasHeightForWidth() ? content_->heightForWidth(width) : content_->sizeHint().height();
  return std::clamp(h, content_->minimumHeight(), std::max(content_->minimumHeight(), content_->maximumHeight()));
}

int SteadyBox::wanted() const {
  // A wrapping text fits any width by taking more lines (its height says it); one that does not wrap wants its hint,
  // unless its layout ignores it.
  if (content_->sizePolicy().horizontalPolicy() == QSizePolicy::Ignored) return 0;
  const int w = content_->hasHeightForWidth() ? content_->minimumSizeHint().width() : content_->sizeHint().width();
  return std::clamp(w, content_->minimumWidth(), std::max(content_->minimumWidth(), content_->maximumWidth()));
}

void SteadyBox::refit() {
  const int needed = need(width());
  const int wants = wanted();
  // The layout hears of it only when the height it would give changes, or the content wants more width than it has
  // (a line that does not wrap: a longer text); a narrower text keeps the room it had (nothing beside it jitters).
  if (needed != lastNeed_ || (wants > width() && wants != lastWants_)) {
    lastNeed_ = needed;
    lastWants_ = wants;
    ++passedOn_;
    updateGeometry();
  }
  content_->setGeometry(rect());
}

bool SteadyBox::event(QEvent* e) {
  // The content's updateGeometry posts a LayoutRequest here (the box has no layout of its own to invalidate).
  if (e->type() == QEvent::LayoutRequest) {
    refit();
    return true;
  }
  if (e->type() == QEvent::Show) refit();  // its text may have changed while hidden (no request is posted then)
  return QWidget::event(e);
}

void SteadyBox::resizeEvent(QResizeEvent* e) {
  QWidget::resizeEvent(e);
  lastNeed_ = need(width());  // what the layout just gave it room for
  lastWants_ = wanted();
  content_->setGeometry(rect());
}

LinesLabel::LinesLabel(int lines, QWidget* parent) : QLabel(parent), lines_(lines) {
  setProperty("elidesItsText", true);
  setWordWrap(true);
  setAlignment(Qt::AlignTop | Qt::AlignLeft);
  fixHeight();
}

void LinesLabel::fixHeight() {
  const QMargins m = contentsMargins();
  setFixedHeight(lines_ * fontMetrics().lineSpacing() + m.top() + m.bottom() + 2 * margin() + 4);
}

void LinesLabel::changeEvent(QEvent* e) {
  QLabel::changeEvent(e);
  if (e->type() == QEvent::FontChange) fixHeight();
}

void LinesLabel::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.setPen(palette().color(QPalette::WindowText));
  const QRect room = contentsRect().adjusted(margin(), margin(), -margin(), -margin());
  const QFontMetrics fm = fontMetrics();
  const QRect lines(0, 0, room.width(), lines_ * fm.lineSpacing());
  auto fits = [&](const QString& t) { return fm.boundingRect(lines, Qt::TextWordWrap, t).height() <= lines.height(); };
  QString shown = text();
  if (!fits(shown)) {
    int lo = 0, hi = static_cast<int>(shown.size());
    while (lo < hi) {
      const int mid = (lo + hi + 1) / 2;
      if (fits(shown.left(mid) + QChar(0x2026))) lo = mid;
      else hi = mid - 1;
    }
    shown = shown.left(lo) + QChar(0x2026);
  }
  p.drawText(room, Qt::AlignTop | Qt::AlignLeft | Qt::TextWordWrap, shown);
}

ElidingStatusBar::ElidingStatusBar(QWidget* parent) : QStatusBar(parent) {
  connect(this, &QStatusBar::messageChanged, this, [this](const QString& message) { setToolTip(message); });
}

// As QStatusBar::paintEvent (the panel, the frames of the widgets shown beside the message, the message from the left
// to the first of them), with the message elided to that room.
void ElidingStatusBar::paintEvent(QPaintEvent* e) {
  const QString message = currentMessage();
  if (message.isEmpty()) {
    QStatusBar::paintEvent(e);
    return;
  }
  QPainter p(this);
  QStyleOption opt;
  opt.initFrom(this);
  style()->drawPrimitive(QStyle::PE_PanelStatusBar, &opt, &p, this);
  const bool rtl = layoutDirection() == Qt::RightToLeft;
  int left = 6, right = width() - 12;
  // While a message is shown QStatusBar hides its normal widgets: the ones still visible are the permanent ones.
  for (QWidget* w : findChildren<QWidget*>(QString(), Qt::FindDirectChildrenOnly)) {
    if (!w->isVisible() || w->isWindow()) continue;
    if (!qobject_cast<QSizeGrip*>(w)) {
      opt.rect = w->geometry().adjusted(-1, -1, 1, 1);
      style()->drawPrimitive(QStyle::PE_FrameStatusBarItem, &opt, &p, w);
      if (rtl)
        left = std::max(left, w->x() + w->width() + 2);
      else
        right = std::min(right, w->x() - 2);
    }
  }
  const QRect room(left, 0, std::max(0, right - left), height());
  p.setPen(palette().windowText().color());
  p.drawText(room, Qt::AlignLeading | Qt::AlignVCenter | Qt::TextSingleLine,
             fontMetrics().elidedText(message, Qt::ElideRight, room.width()));
}

}  // namespace rehearse::ui
