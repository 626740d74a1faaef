#pragma once
// The organ alone in 3D, turntable style: drag to turn, wheel to zoom, double-click to reset.
// Software rendering through the CPU renderer (works without OpenGL); ligament attachment nodes are
// drawn as orange dots and the inner structures (other labels) shine through in their colours.
#include <rehearse/app/case.hpp>

#include <QImage>
#include <QWidget>

#include <algorithm>
#include <cmath>
#include <memory>

namespace rehearse::ui {

/// Turntable controls shared by the software and OpenGL organ views (angles in radians).
struct Turntable {
  double yaw = 0, pitch = 0, zoom = 1.0;
  QPointF last;
  void press(const QPointF& p) { last = p; }
  void drag(const QPointF& p) {
    const QPointF d = p - last;
    last = p;
    yaw += d.x() * 0.01;
    pitch = std::clamp(pitch - d.y() * 0.01, -1.5, 1.5);
  }
  void wheel(int angleDelta) { zoom = std::clamp(zoom * std::pow(1.0015, angleDelta), 0.3, 8.0); }
  void reset() { *this = Turntable{}; }
};

/// The 3D organ views' camera (OpenCV pinhole, W x H pixels) and pose: the organ's current shape (fitted
/// or rest) seen from the endoscope's side when the case has a pose (the view first shows the organ as the
/// frame does, turned by the turntable about its centre and framed to fit), else from a fixed angle. Both
/// the software and the OpenGL view draw through it, so they show the same picture.
void turntableView(const app::Case& c, const Turntable& t, int W, int H, imaging::Camera& camera, Pose& pose);

/// True when two versions of a case show the same organ in the same shape with the same attachments
/// (then a 3D view keeps what it built from it).
inline bool sameMesh(const app::Case* a, const app::Case* b) {
  return a && b && a->organ == b->organ && a->fit == b->fit && a->attachments == b->attachments && a->hasPose == b->hasPose &&
         a->pose.R == b->pose.R;
}

/// Takes a new version of the case into a 3D view's `held`; true when what the view draws changed (then
/// it redraws; a contour or a translation alone does not).
inline bool takeCase(std::shared_ptr<const app::Case>& held, std::shared_ptr<const app::Case> next) {
  const bool same = sameMesh(held.get(), next.get());
  held = std::move(next);
  return !same;
}

class OrganView : public QWidget {
  Q_OBJECT
 public:
  explicit OrganView(QWidget* parent = nullptr);
  void setCase(std::shared_ptr<const app::Case> c);
  QSize sizeHint() const override { return {360, 280}; }
  /// The last render, in device pixels (widget size x device pixel ratio; empty before the first paint).
  const QImage& rendered() const { return image_; }

 protected:
  void paintEvent(QPaintEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void mouseDoubleClickEvent(QMouseEvent*) override;
  void wheelEvent(QWheelEvent*) override;
  void resizeEvent(QResizeEvent*) override;

 private:
  void render();
  std::shared_ptr<const app::Case> case_;
  QImage image_;
  bool dirty_ = true;
  Turntable turntable_;
};

}  // namespace rehearse::ui
