#include "rehearse/ui/organview.hpp"
#include "rehearse/ui/pages/meshpage.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/mesh.hpp>

#include <QMouseEvent>
#include <QPainter>
#include <QWheelEvent>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace rehearse::ui {

OrganView::OrganView(QWidget* parent) : QWidget(parent) {
  setMinimumSize(200, 160);
  setAttribute(Qt::WA_OpaquePaintEvent);
  setToolTip(tr("Drag to turn the organ, wheel to zoom, double-click to reset"));
}

void turntableView(const app::Case& c, const Turntable& t, int W, int H, imaging::Camera& camera, Pose& pose) {
  camera.width = W;
  camera.height = H;
  const double f = 1.1 * std::min(W, H);
  camera.K << f, 0, (W - 1) / 2.0, 0, f, (H - 1) / 2.0, 0, 0, 1;
  camera.distortion.fill(0);
  // Framed so that the outline of the organ's bounding sphere (radius r f / sqrt(d^2 - r^2) in pixels at
  // distance d) spans 80 % of the view's smaller side, whichever way the organ turns.
  const auto box = c.organ->volume.bounds();
  const Eigen::Vector3d centre = box.center();
  const double radius = std::max(0.5 * box.diagonal().norm(), 1e-9);
  const Eigen::Matrix3d start = c.hasPose ? c.pose.R : Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitX()).toRotationMatrix();
  pose.R = (Eigen::AngleAxisd(t.pitch, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(t.yaw, Eigen::Vector3d::UnitY())).toRotationMatrix() * start;
  const double ratio = f / (0.4 * std::min(W, H));
  pose.t = Eigen::Vector3d(0, 0, radius * std::sqrt(1 + ratio * ratio) / t.zoom) - pose.R * centre;
}

void OrganView::setCase(std::shared_ptr<const app::Case> c) {
  if (!takeCase(case_, std::move(c))) return;
  dirty_ = true;
  update();
}

void OrganView::render() {
  dirty_ = false;
  image_ = QImage();
  if (!case_ || case_->organ->surface.empty() || width() < 10 || height() < 10) return;
  // Rendered in device pixels (sharp on HiDPI screens), drawn at the widget's logical size.
  const double dpr = std::max(1.0, devicePixelRatioF());
  const int W = static_cast<int>(std::lround(width() * dpr)), H = static_cast<int>(std::lround(height() * dpr));
  imaging::Camera cam;
  Pose p;
  turntableView(*case_, turntable_, W, H, cam, p);
  cv::Mat4b organ = imaging::renderOverlay(cam, p, case_->surfaceView(), cv::Vec3b(120, 150, 215));
  // Inner structures (labels other than the outer one), drawn over it half-transparent.
  const auto& inner = case_->organ->innerSurface;
  cv::Mat rgba;
  cv::cvtColor(organ, rgba, cv::COLOR_BGRA2RGBA);
  image_ = QImage(rgba.data, rgba.cols, rgba.rows, static_cast<int>(rgba.step), QImage::Format_RGBA8888).copy();
  QPainter painter(&image_);
  if (!inner.empty()) {
    // Each structure in its label's colour, as step 1's list, the legend and the view over the frame draw it (they
    // were all drawn one blue here, which over the organ's colour read lavender beside a yellow legend).
    const auto& labels = case_->organ->innerSurfaceLabels;
    std::vector<int> kinds(labels.begin(), labels.end());
    std::sort(kinds.begin(), kinds.end());
    kinds.erase(std::unique(kinds.begin(), kinds.end()), kinds.end());
    if (labels.size() != inner.size()) kinds.assign(1, 0);
    painter.setOpacity(0.7);
    for (int label : kinds) {
      std::vector<std::array<int, 3>> faces;
      for (std::size_t i = 0; i < inner.size(); ++i)
        if (labels.size() != inner.size() || labels[i] == label) faces.push_back(inner[i]);
      SurfaceView v = case_->surfaceView();  // the organ's current shape (fitted or rest)
      v.triangles = faces.front().data();
      v.triangleCount = faces.size();
      const QColor colour = labelColour(label);
      cv::Mat4b in = imaging::renderOverlay(cam, p, v, cv::Vec3b(colour.blue(), colour.green(), colour.red()));
      cv::cvtColor(in, rgba, cv::COLOR_BGRA2RGBA);
      painter.drawImage(0, 0, QImage(rgba.data, rgba.cols, rgba.rows, static_cast<int>(rgba.step), QImage::Format_RGBA8888));
    }
    painter.setOpacity(1.0);
  }
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setPen(Qt::NoPen);
  painter.setBrush(QColor(255, 150, 40));
  for (int a : case_->attachments) {
    const Eigen::Vector3d x = p.apply(case_->shapeNodes()[a]);
    if (x.z() <= 0) continue;
    const auto uv = cam.project(x);
    painter.drawEllipse(QPointF(uv.x(), uv.y()), 2.5 * dpr, 2.5 * dpr);
  }
  painter.end();
  image_.setDevicePixelRatio(dpr);
}

void OrganView::paintEvent(QPaintEvent*) {
  if (dirty_) render();
  QPainter painter(this);
  painter.fillRect(rect(), QColor(24, 25, 28));
  if (image_.isNull()) {
    painter.setPen(QColor(150, 150, 150));
    painter.drawText(rect(), Qt::AlignCenter, tr("No organ mesh yet"));
    return;
  }
  painter.drawImage(0, 0, image_);
  painter.setPen(QColor(170, 170, 170));
  painter.drawText(rect().adjusted(6, 4, -6, -4), Qt::AlignLeft | Qt::AlignBottom,
                   tr("the case's organ: %1 tets, %2 attachments").arg(case_->organ->volume.tets.size()).arg(case_->attachments.size()));
}

void OrganView::mousePressEvent(QMouseEvent* e) { turntable_.press(e->position()); }

void OrganView::mouseMoveEvent(QMouseEvent* e) {
  if (!(e->buttons() & Qt::LeftButton)) return;
  turntable_.drag(e->position());
  dirty_ = true;
  update();
}

void OrganView::mouseDoubleClickEvent(QMouseEvent*) {
  turntable_.reset();
  dirty_ = true;
  update();
}

void OrganView::wheelEvent(QWheelEvent* e) {
  turntable_.wheel(e->angleDelta().y());
  dirty_ = true;
  update();
}

void OrganView::resizeEvent(QResizeEvent*) { dirty_ = true; }

}  // namespace rehearse::ui
