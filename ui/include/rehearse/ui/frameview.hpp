#pragma once
// Central view: the endoscope frame with the organ drawn over it. CPU (QPainter) rendering, so it
// works over remote desktops and in offscreen tests. Mouse wheel zooms about the cursor, drag pans,
// double-click or Home fits the frame.
#include <QImage>
#include <QWidget>

namespace rehearse::ui {

class FrameView : public QWidget {
  Q_OBJECT
 public:
  explicit FrameView(QWidget* parent = nullptr);
  void setFrame(const QImage& frame);
  void setOverlay(const QImage& organ, const QList<QPolygonF>& silhouette);
  void setOverlayVisible(bool visible);
  bool overlayVisible() const { return overlayVisible_; }
  void setOverlayOpacity(double opacity);
  double zoom() const { return zoom_; }
  /// Frame pixel under a widget position.
  QPointF toFrame(const QPointF& widgetPos) const;
  void fitToWindow();

 signals:
  void cursorMoved(QPointF framePixel);

 protected:
  void paintEvent(QPaintEvent*) override;
  void wheelEvent(QWheelEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void mouseReleaseEvent(QMouseEvent*) override;
  void mouseDoubleClickEvent(QMouseEvent*) override;
  void keyPressEvent(QKeyEvent*) override;
  void resizeEvent(QResizeEvent*) override;

 private:
  QTransform frameToWidget() const;
  QImage frame_, overlay_;
  QList<QPolygonF> silhouette_;
  bool overlayVisible_ = true;
  double opacity_ = 0.45;
  double zoom_ = 1.0;     // relative to fit
  QPointF pan_;           // widget pixels
  bool fitted_ = true;
  bool dragging_ = false;
  QPointF lastMouse_;
};

}  // namespace rehearse::ui
