#include "rehearse/ui/frameview.hpp"

#include <QKeyEvent>
#include <QMouseEvent>
#include <QPainter>
#include <QWheelEvent>

namespace rehearse::ui {

FrameView::FrameView(QWidget* parent) : QWidget(parent) {
  setMinimumSize(320, 200);
  setMouseTracking(true);
  setFocusPolicy(Qt::StrongFocus);
  setAttribute(Qt::WA_OpaquePaintEvent);
}

void FrameView::setFrame(const QImage& frame) {
  frame_ = frame;
  fitToWindow();
}

void FrameView::setOverlay(const QImage& organ, const QList<QPolygonF>& silhouette) {
  overlay_ = organ;
  silhouette_ = silhouette;
  update();
}

void FrameView::setOverlayVisible(bool visible) {
  overlayVisible_ = visible;
  update();
}

void FrameView::setOverlayOpacity(double opacity) {
  opacity_ = std::clamp(opacity, 0.0, 1.0);
  update();
}

void FrameView::fitToWindow() {
  zoom_ = 1.0;
  pan_ = {};
  fitted_ = true;
  update();
}

QTransform FrameView::frameToWidget() const {
  if (frame_.isNull()) return {};
  const double fit = std::min(width() / double(frame_.width()), height() / double(frame_.height()));
  const double s = fit * zoom_;
  const double ox = (width() - frame_.width() * s) / 2 + pan_.x();
  const double oy = (height() - frame_.height() * s) / 2 + pan_.y();
  return QTransform(s, 0, 0, s, ox, oy);
}

QPointF FrameView::toFrame(const QPointF& p) const { return frameToWidget().inverted().map(p); }

void FrameView::paintEvent(QPaintEvent*) {
  QPainter painter(this);
  painter.fillRect(rect(), QColor(18, 18, 20));
  if (frame_.isNull()) {
    painter.setPen(QColor(170, 170, 170));
    QFont f = font();
    f.setPointSizeF(f.pointSizeF() * 1.4);
    painter.setFont(f);
    painter.drawText(rect(), Qt::AlignCenter, tr("No frame yet"));
    return;
  }
  painter.setRenderHint(QPainter::SmoothPixmapTransform, zoom_ < 2.0);
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setTransform(frameToWidget());
  painter.drawImage(QPointF(0, 0), frame_);
  if (overlayVisible_) {
    if (!overlay_.isNull()) {
      painter.setOpacity(opacity_);
      painter.drawImage(QPointF(0, 0), overlay_);
      painter.setOpacity(1.0);
    }
    QPen pen(QColor(120, 255, 140), 2.0);
    pen.setCosmetic(true);
    painter.setPen(pen);
    for (const auto& poly : silhouette_) painter.drawPolygon(poly);
  }
}

void FrameView::wheelEvent(QWheelEvent* e) {
  if (frame_.isNull()) return;
  const QPointF anchor = e->position();
  const QPointF before = toFrame(anchor);
  const double factor = std::pow(1.0015, e->angleDelta().y());
  zoom_ = std::clamp(zoom_ * factor, 0.25, 32.0);
  // Keep the frame point under the cursor fixed.
  const QPointF after = frameToWidget().map(before);
  pan_ += anchor - after;
  fitted_ = false;
  update();
  e->accept();
}

void FrameView::mousePressEvent(QMouseEvent* e) {
  if (e->button() == Qt::LeftButton || e->button() == Qt::MiddleButton) {
    dragging_ = true;
    lastMouse_ = e->position();
    setCursor(Qt::ClosedHandCursor);
  }
}

void FrameView::mouseMoveEvent(QMouseEvent* e) {
  if (dragging_) {
    pan_ += e->position() - lastMouse_;
    lastMouse_ = e->position();
    fitted_ = false;
    update();
  }
  if (!frame_.isNull()) emit cursorMoved(toFrame(e->position()));
}

void FrameView::mouseReleaseEvent(QMouseEvent*) {
  dragging_ = false;
  unsetCursor();
}

void FrameView::mouseDoubleClickEvent(QMouseEvent*) { fitToWindow(); }

void FrameView::keyPressEvent(QKeyEvent* e) {
  switch (e->key()) {
    case Qt::Key_Home: fitToWindow(); break;
    case Qt::Key_Plus:
    case Qt::Key_Equal: zoom_ = std::min(32.0, zoom_ * 1.25); update(); break;
    case Qt::Key_Minus: zoom_ = std::max(0.25, zoom_ / 1.25); update(); break;
    default: QWidget::keyPressEvent(e);
  }
}

void FrameView::resizeEvent(QResizeEvent*) { update(); }

}  // namespace rehearse::ui
