// The review window's widgets (reviewparts.hpp): the attempt's timeline (force, events, playhead; a click or a drag
// seeks) and its view (the rendered picture, scaled to fit; a drag turns the 3D view).
#include "reviewparts.hpp"

#include <rehearse/app/review.hpp>
#include <rehearse/simcore/session/events.hpp>

#include <QMouseEvent>
#include <QPainter>
#include <QPainterPath>
#include <QResizeEvent>

#include <algorithm>

namespace rehearse::ui {

TimelineWidget::TimelineWidget() {
  setObjectName(QStringLiteral("timeline"));
  setMinimumHeight(110);
  setCursor(Qt::PointingHandCursor);
  setToolTip(
      tr("Tool force over time; ticks: grasp (green), slip (orange), cut (purple), vessel cut (red), force over the "
         "threshold (grey; the threshold is the dashed line), incorrect action (cyan, longer). Click or drag to "
         "seek."));
}

void TimelineWidget::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), QColor(30, 32, 36));
  if (!done) {  // the part not replayed yet, shaded, and how far the replay is
    const double x0 = timeline && !timeline->empty() ? xAt(timeline->back().time) : 8;
    p.fillRect(QRectF(x0, 0, width() - x0, height()), QColor(45, 48, 54));
    p.setPen(Qt::lightGray);  // in the part still to come (shorter where it is narrow)
    const QRectF rest(x0 + 8, 20, width() - x0 - 16, height() - 24);
    const QString full = steps > 0 ? tr("replaying the session to check it: step %1 of %2 (the view reaches the part "
                                        "replayed)")
                                         .arg(replayed)
                                         .arg(steps)
                                   : tr("replaying the session to check it...");
    const QString brief = steps > 0 ? tr("replaying: %1 %").arg(100 * replayed / std::max(1L, steps)) : tr("replaying");
    const bool fits = p.fontMetrics().boundingRect(rest.toRect(), Qt::TextWordWrap, full).height() <= rest.height();
    if (fits)
      p.drawText(rest, Qt::AlignCenter | Qt::TextWordWrap, full);
    else  // (a narrow part left: at the right edge, whole)
      p.drawText(QRectF(8, rest.top(), width() - 16, rest.height()), Qt::AlignRight | Qt::AlignVCenter, brief);
  }
  if (!timeline || timeline->empty()) return;
  double peak = 0;
  for (const auto& s : *timeline) peak = std::max(peak, s.force);
  const double fmax = 1.1 * std::max({threshold, peak, 1e-6});
  const double top = 22, bottom = height() - 6;
  auto Y = [&](double f) { return bottom - f / fmax * (bottom - top); };
  if (threshold > 0) {
    p.setPen(QPen(QColor(220, 80, 80), 1, Qt::DashLine));
    p.drawLine(QPointF(8, Y(threshold)), QPointF(width() - 8, Y(threshold)));
  }
  QPainterPath path;
  path.moveTo(xAt(timeline->front().time), Y(timeline->front().force));
  for (const auto& s : *timeline) path.lineTo(xAt(s.time), Y(s.force));
  p.setPen(QPen(QColor(90, 160, 255), 1.5));
  p.drawPath(path);
  // The force crossing the threshold first, then the incorrect actions' long ticks, then the rest: what happened at
  // the same step (a slip at the grasp's limit, the vessel cut an incorrect action names) is drawn over them, not
  // hidden under them.
  auto layer = [](simcore::EventKind kind) {
    return kind == simcore::EventKind::ForceOverThreshold ? 0 : kind == simcore::EventKind::IncorrectAction ? 1 : 2;
  };
  for (const int pass : {0, 1, 2})
    for (const auto& s : *timeline)
      for (const auto& e : s.events) {
        const simcore::EventKind kind = simcore::eventKind(e);
        if (layer(kind) != pass) continue;
        const std::optional<app::Rgb> c = app::reviewEventRgb(e);  // as the report names them
        if (!c) continue;
        p.setPen(QPen(QColor(c->r, c->g, c->b), 3));
        p.drawLine(QPointF(xAt(s.time), 2),
                   QPointF(xAt(s.time), kind == simcore::EventKind::IncorrectAction ? 34 : 16));
      }
  p.setPen(QPen(Qt::white, 2));
  p.drawLine(QPointF(xAt(now), 0), QPointF(xAt(now), height()));
  p.setPen(Qt::lightGray);
  p.drawText(QRectF(width() - 160, 2, 150, 18), Qt::AlignRight, tr("peak %1 N").arg(peak, 0, 'f', 1));
}

void TimelineWidget::mousePressEvent(QMouseEvent* e) {
  if (seek) seek(timeAt(e->position().x()));
}

void TimelineWidget::mouseMoveEvent(QMouseEvent* e) {
  if ((e->buttons() & Qt::LeftButton) && seek) seek(timeAt(e->position().x()));
}

ViewLabel::ViewLabel() {
  setObjectName(QStringLiteral("reviewView"));
  setMinimumSize(320, 240);
  setAlignment(Qt::AlignCenter);
  setStyleSheet("background: #202226");
}

void ViewLabel::resizeEvent(QResizeEvent* e) {  // the picture follows the view's size
  QLabel::resizeEvent(e);
  const QImage image = property("image").value<QImage>();
  if (!image.isNull()) setPixmap(QPixmap::fromImage(image.scaled(size(), Qt::KeepAspectRatio, Qt::SmoothTransformation)));
}

void ViewLabel::mousePressEvent(QMouseEvent* e) { last_ = e->position(); }

void ViewLabel::mouseMoveEvent(QMouseEvent* e) {
  if (!(e->buttons() & Qt::LeftButton) || !turn) return;
  const QPointF d = e->position() - last_;
  last_ = e->position();
  turn(d.x() * 0.01, -d.y() * 0.01);
}

}  // namespace rehearse::ui
