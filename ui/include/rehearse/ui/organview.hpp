#pragma once
// The organ alone in 3D, turntable style: drag to turn, wheel to zoom, double-click to reset.
// Software rendering through the CPU renderer (works without OpenGL); ligament attachment nodes are
// drawn as orange dots and the inner structures (other labels) shine through in their colours.
#include "phantom/phantom.hpp"

#include <QImage>
#include <QWidget>

#include <memory>

namespace rehearse::ui {

class OrganView : public QWidget {
  Q_OBJECT
 public:
  explicit OrganView(QWidget* parent = nullptr);
  void setCase(std::shared_ptr<const phantom::Case> c);
  double yaw() const { return yaw_; }
  double pitch() const { return pitch_; }
  QSize sizeHint() const override { return {360, 280}; }

 protected:
  void paintEvent(QPaintEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void mouseDoubleClickEvent(QMouseEvent*) override;
  void wheelEvent(QWheelEvent*) override;
  void resizeEvent(QResizeEvent*) override;

 private:
  void render();
  std::shared_ptr<const phantom::Case> case_;
  QImage image_;
  bool dirty_ = true;
  double yaw_ = 0, pitch_ = -0.3, zoom_ = 1.0;
  QPointF last_;
};

}  // namespace rehearse::ui
