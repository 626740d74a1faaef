#include "rehearse/ui/frameview.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/registration.hpp>

#include <QKeyEvent>
#include <QMouseEvent>
#include <QPainter>
#include <QPainterPath>
#include <QWheelEvent>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <vector>

namespace rehearse::ui {
namespace {
constexpr double kHandleRadius = 13;     // widget px
constexpr double kPickRadius = 9;        // widget px, contour points
constexpr double kEraseRadius = 14;      // widget px
constexpr double kRotationPerPixel = 0.005;  // rad per frame pixel for tilts about X and Y

Eigen::Matrix3d axisRotation(int axis, double angle) {
  return Eigen::AngleAxisd(angle, Eigen::Vector3d::Unit(axis)).toRotationMatrix();
}
QColor axisColour(int axis) {
  static const QColor c[3] = {QColor(235, 80, 80), QColor(90, 220, 90), QColor(90, 150, 255)};
  return c[axis];
}
// Contour segments by type: silhouettes yellow, ridges orange, ligaments violet.
QColor segmentColour(const std::string& type) {
  if (type == "ridge") return QColor(255, 130, 50);
  if (type == "ligament") return QColor(200, 130, 255);
  return QColor(255, 220, 40);
}
}  // namespace

FrameView::FrameView(QWidget* parent) : QWidget(parent) {
  setMinimumSize(320, 200);
  setMouseTracking(true);
  setFocusPolicy(Qt::StrongFocus);
  setAttribute(Qt::WA_OpaquePaintEvent);
}

void FrameView::setFrame(const QImage& frame) {
  const bool sameSize = frame.size() == frame_.size();
  frame_ = frame;
  if (!sameSize) fitToWindow();
  update();
}

void FrameView::setOverlay(const QImage& organ, const QList<QPolygonF>& silhouette) {
  overlay_ = organ;
  silhouette_ = silhouette;
  update();
}

void FrameView::setCase(std::shared_ptr<const app::Case> c) {
  case_ = std::move(c);
  wireStale_ = true;
  update();
}

void FrameView::setOverlayStyle(OverlayStyle style) {
  style_ = style;
  update();
}

void FrameView::rebuildWireframe() {
  wireStale_ = false;
  wire_.clear();
  if (!case_ || !case_->hasPose || case_->organ->surface.empty() || !case_->camera.problem().empty()) return;
  // The edges of the triangles that face the camera (all in front of it), each once.
  const SurfaceView sv = case_->surfaceView();
  const Pinhole cam = case_->camera.pinhole();
  std::vector<Eigen::Vector3d> x(sv.vertexCount);
  for (std::size_t i = 0; i < sv.vertexCount; ++i) x[i] = case_->pose.apply(sv.vertex(i));
  std::vector<std::pair<int, int>> edges;
  for (const auto& t : case_->organ->surface) {
    const Eigen::Vector3d &a = x[t[0]], &b = x[t[1]], &c = x[t[2]];
    if (a.z() <= 1e-3 || b.z() <= 1e-3 || c.z() <= 1e-3) continue;
    if ((b - a).cross(c - a).dot(a) >= 0) continue;  // turned away from the camera
    for (int k = 0; k < 3; ++k) edges.emplace_back(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  wire_.reserve(static_cast<qsizetype>(edges.size()));
  for (const auto& [i, j] : edges) {
    const Eigen::Vector2d p = cam.project(x[static_cast<std::size_t>(i)]), q = cam.project(x[static_cast<std::size_t>(j)]);
    wire_.append(QLineF(p.x(), p.y(), q.x(), q.y()));
  }
}

void FrameView::setOverlayVisible(bool visible) {
  overlayVisible_ = visible;
  update();
}

void FrameView::setOverlayOpacity(double opacity) {
  opacity_ = std::clamp(opacity, 0.0, 1.0);
  update();
}

void FrameView::setTool(Tool t) {
  if (drawing_ && tool_ == Tool::ClickPoints) finishSegment();
  if (tool_ == Tool::OrganCurve && t != Tool::OrganCurve) finishOrganCurve();
  if (t == Tool::OrganCurve && tool_ != Tool::OrganCurve)
    emit toolMessage(tr("Click along the ridge or ligament on the organ drawn over the frame; the nearest sketched one gets the curve."));
  tool_ = t;
  drawing_ = false;
  draft_.clear();
  setCursor(t == Tool::Navigate ? Qt::OpenHandCursor : (t == Tool::Align ? Qt::ArrowCursor : Qt::CrossCursor));
  update();
}

void FrameView::fitToWindow() {
  zoom_ = 1.0;
  pan_ = {};
  update();
}

QTransform FrameView::frameToWidget() const {
  const QSize size = frame_.isNull() ? QSize(1280, 720) : frame_.size();
  const double fit = std::min(width() / double(size.width()), height() / double(size.height()));
  const double s = fit * zoom_;
  const double ox = (width() - size.width() * s) / 2 + pan_.x();
  const double oy = (height() - size.height() * s) / 2 + pan_.y();
  return QTransform(s, 0, 0, s, ox, oy);
}

QPointF FrameView::toFrame(const QPointF& p) const { return frameToWidget().inverted().map(p); }
QPointF FrameView::toWidget(const QPointF& p) const { return frameToWidget().map(p); }

imaging::Contour FrameView::currentContour() const {
  imaging::Contour c = case_ ? case_->contour : imaging::Contour{};
  if (!frame_.isNull()) {
    c.width = frame_.width();
    c.height = frame_.height();
  }
  return c;
}

void FrameView::commitContour(const imaging::Contour& c, const QString& text, int mergeId) { emit contourEdited(c, text, mergeId); }

std::optional<std::pair<int, int>> FrameView::pointNear(const QPointF& w, double radius) const {
  const auto c = currentContour();
  std::optional<std::pair<int, int>> best;
  double bestD = radius;
  for (int s = 0; s < static_cast<int>(c.segments.size()); ++s)
    for (int i = 0; i < static_cast<int>(c.segments[s].points.size()); ++i) {
      const auto& p = c.segments[s].points[i];
      const double d = QLineF(w, toWidget(QPointF(p.x(), p.y()))).length();
      if (d <= bestD) {
        bestD = d;
        best = std::make_pair(s, i);
      }
    }
  return best;
}

Eigen::Vector3d FrameView::cogCamera() const {
  if (!case_ || !case_->hasPose) return Eigen::Vector3d(0, 0, -1);
  return case_->pose.apply(case_->organ->centreOfGravity);
}

QPointF FrameView::handlePosition(GizmoHandle h) const {
  const Eigen::Vector3d g = cogCamera();
  if (g.z() <= 0 || !case_) return {};
  const Eigen::Vector2d uv = case_->camera.project(g);
  const QPointF p = toWidget(QPointF(uv.x(), uv.y()));
  switch (h) {
    case GizmoHandle::TranslateX: return p + QPointF(95, 0);
    case GizmoHandle::TranslateY: return p + QPointF(0, 95);
    case GizmoHandle::TranslateZ: return p + QPointF(-67, 67);
    case GizmoHandle::RotateX: return p + QPointF(0, -130);
    case GizmoHandle::RotateY: return p + QPointF(-130, 0);
    case GizmoHandle::RotateZ: return p + QPointF(92, -92);
    default: return p;
  }
}

GizmoHandle FrameView::handleAt(const QPointF& w) const {
  for (auto h : {GizmoHandle::TranslateX, GizmoHandle::TranslateY, GizmoHandle::TranslateZ, GizmoHandle::RotateX,
                 GizmoHandle::RotateY, GizmoHandle::RotateZ}) {
    const QPointF p = handlePosition(h);
    if (!p.isNull() && QLineF(w, p).length() <= kHandleRadius + 3) return h;
  }
  return GizmoHandle::None;
}

void FrameView::dragGizmo(const QPointF& w) {
  const Pose& p0 = dragStartPose_;
  const Eigen::Vector3d g0 = p0.apply(case_->organ->centreOfGravity);
  const QPointF a = toFrame(dragStartMouse_), b = toFrame(w);
  const double du = b.x() - a.x(), dv = b.y() - a.y();
  const auto& cam = case_->camera;
  Pose p = p0;
  QString text;
  auto rotate = [&](int axis, double angle) { p = p0.turnedAbout(axisRotation(axis, angle), g0); };  // the centre stays put
  switch (activeHandle_) {
    case GizmoHandle::TranslateX: p.t.x() += du * g0.z() / cam.fx(); text = tr("Move along camera X"); break;
    case GizmoHandle::TranslateY: p.t.y() += dv * g0.z() / cam.fy(); text = tr("Move along camera Y"); break;
    case GizmoHandle::TranslateZ: p.t.z() -= dv * g0.z() / cam.fy(); text = tr("Move along camera Z"); break;
    case GizmoHandle::RotateX: rotate(0, dv * kRotationPerPixel); text = tr("Rotate about camera X"); break;
    case GizmoHandle::RotateY: rotate(1, du * kRotationPerPixel); text = tr("Rotate about camera Y"); break;
    case GizmoHandle::RotateZ: {
      const Eigen::Vector2d c = cam.project(g0);
      const double a0 = std::atan2(a.y() - c.y(), a.x() - c.x()), a1 = std::atan2(b.y() - c.y(), b.x() - c.x());
      rotate(2, std::remainder(a1 - a0, 2 * M_PI));
      text = tr("Rotate about camera Z");
      break;
    }
    default: return;
  }
  emit poseEdited(p, text, activeMerge_);
}

void FrameView::eraseAt(const QPointF& w) {
  const double r = kEraseRadius;
  std::vector<imaging::ContourSegment> out;
  bool changed = false;
  for (const auto& s : working_.segments) {
    imaging::ContourSegment piece = s;
    piece.points.clear();
    piece.closed = false;
    for (const auto& p : s.points) {
      if (QLineF(w, toWidget(QPointF(p.x(), p.y()))).length() <= r) {
        changed = true;
        if (piece.points.size() >= 2) out.push_back(piece);
        piece.points.clear();
      } else {
        piece.points.push_back(p);
      }
    }
    if (piece.points.size() >= 2) out.push_back(piece);
    else if (!piece.points.empty()) changed = true;
  }
  if (changed) {
    working_.segments = out;
    commitContour(working_, tr("Erase"), activeMerge_);
  }
}

std::vector<Eigen::Vector2d> FrameView::maybeSnap(const std::vector<Eigen::Vector2d>& pts) const {
  if (!snap_ || !case_ || case_->frame.empty() || pts.size() < 2) return pts;
  imaging::ContourSegment s{pts, false, newSegmentType_, {}};
  auto anchors = imaging::resampleSegment(s, 30.0).points;
  return imaging::snapToEdges(case_->frame, anchors);
}

void FrameView::finishSegment() {
  if (draft_.size() >= 2) {
    imaging::Contour c = currentContour();
    c.segments.push_back({maybeSnap(draft_), false, newSegmentType_, {}});
    commitContour(c, tool_ == Tool::Freehand ? tr("Draw segment") : tr("Add segment"));
  }
  draft_.clear();
  drawing_ = false;
  update();
}

void FrameView::paintEvent(QPaintEvent*) {
  QPainter painter(this);
  painter.fillRect(rect(), QColor(18, 18, 20));
  if (frame_.isNull()) {
    painter.setPen(QColor(170, 170, 170));
    QFont f = font();
    f.setPointSizeF(f.pointSizeF() * 1.4);
    painter.setFont(f);
    painter.drawText(rect(), Qt::AlignCenter, tr("No frame yet: open an image or a video (step 2)"));
    return;
  }
  painter.setRenderHint(QPainter::SmoothPixmapTransform, zoom_ < 2.0);
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setTransform(frameToWidget());
  painter.drawImage(QPointF(0, 0), frame_);
  if (overlayVisible_) {
    if (!overlay_.isNull() && style_ == OverlayStyle::Shaded) {
      painter.setOpacity(opacity_);
      painter.drawImage(QRectF(QPointF(0, 0), QSizeF(frame_.size())), overlay_);  // the overlay may be at a lower resolution
      painter.setOpacity(1.0);
    }
    if (!inner_.isNull()) {
      painter.setOpacity(0.7);
      painter.drawImage(QRectF(QPointF(0, 0), QSizeF(frame_.size())), inner_);
      painter.setOpacity(1.0);
    }
    if (style_ == OverlayStyle::Wireframe) {
      if (wireStale_) rebuildWireframe();
      QPen wire(QColor(150, 235, 170, static_cast<int>(std::lround(255 * std::clamp(opacity_ + 0.3, 0.3, 1.0)))), 1.0);
      wire.setCosmetic(true);
      painter.setPen(wire);
      painter.drawLines(wire_);
    }
    QPen pen(QColor(120, 255, 140), 2.0);
    pen.setCosmetic(true);
    painter.setPen(pen);
    painter.setBrush(Qt::NoBrush);
    for (const auto& poly : silhouette_) painter.drawPolygon(poly);
  }
  // Contour: segments coloured by type, points when editing, the draft in cyan.
  const auto contour = currentContour();
  for (const auto& s : contour.segments) {
    QPolygonF poly;
    for (const auto& p : s.points) poly << QPointF(p.x(), p.y());
    QPen cpen(segmentColour(s.type), 2.5);
    cpen.setCosmetic(true);
    painter.setPen(cpen);
    if (s.closed) painter.drawPolygon(poly);
    else painter.drawPolyline(poly);
  }
  painter.resetTransform();
  // The organ curves of ridges and ligaments, through the current pose and shape: dashed, with their nodes.
  if (case_ && case_->hasPose) {
    const SurfaceView sv = case_->surfaceView();
    for (const auto& s : contour.segments) {
      if (s.modelVertices.empty()) continue;
      QPolygonF poly;
      for (int v : s.modelVertices) {
        if (v < 0 || static_cast<std::size_t>(v) >= sv.vertexCount) continue;
        const Eigen::Vector3d xc = case_->pose.apply(sv.vertex(static_cast<std::size_t>(v)));
        if (xc.z() <= 0) continue;
        const auto uv = case_->camera.project(xc);
        poly << toWidget(QPointF(uv.x(), uv.y()));
      }
      painter.setPen(QPen(segmentColour(s.type).lighter(130), 2, Qt::DashLine));
      painter.setBrush(Qt::NoBrush);
      painter.drawPolyline(poly);
      painter.setBrush(segmentColour(s.type));
      painter.setPen(QPen(QColor(30, 30, 30), 1));
      for (const auto& q : poly) painter.drawEllipse(q, 2.5, 2.5);
    }
  }
  if (tool_ == Tool::EditPoints || tool_ == Tool::ClickPoints) {
    painter.setPen(QPen(QColor(30, 30, 30), 1));
    painter.setBrush(QColor(255, 220, 40));
    for (const auto& s : contour.segments)
      for (const auto& p : s.points) painter.drawEllipse(toWidget(QPointF(p.x(), p.y())), 3.5, 3.5);
  }
  if (!draft_.empty()) {
    QPolygonF poly;
    for (const auto& p : draft_) poly << toWidget(QPointF(p.x(), p.y()));
    painter.setPen(QPen(QColor(60, 230, 255), 2.5));
    painter.setBrush(Qt::NoBrush);
    painter.drawPolyline(poly);
  }
  // Attachment nodes through the current pose and shape (orange), while they are being picked.
  if (tool_ == Tool::Attachments && case_ && case_->hasPose) {
    const SurfaceView sv = case_->surfaceView();
    painter.setPen(QPen(QColor(30, 30, 30), 1));
    painter.setBrush(QColor(255, 150, 40));
    for (int a : case_->attachments) {
      if (a < 0 || static_cast<std::size_t>(a) >= sv.vertexCount) continue;
      const Eigen::Vector3d xc = case_->pose.apply(sv.vertex(static_cast<std::size_t>(a)));
      if (xc.z() <= 0) continue;
      const auto uv = case_->camera.project(xc);
      painter.drawEllipse(toWidget(QPointF(uv.x(), uv.y())), 3.5, 3.5);
    }
  }
  // Landmarks: model points through the current pose (orange) and their image points (cyan).
  if (case_ && case_->hasPose) {
    for (std::size_t i = 0; i < landmarks_.size(); ++i) {
      const auto& l = landmarks_[i];
      const Eigen::Vector3d xc = case_->pose.apply(l.model);
      QPointF m;
      if (xc.z() > 0) {
        const auto uv = case_->camera.project(xc);
        m = toWidget(QPointF(uv.x(), uv.y()));
        painter.setPen(QPen(QColor(255, 150, 40), 2));
        painter.setBrush(Qt::NoBrush);
        painter.drawEllipse(m, 6, 6);
        painter.drawText(m + QPointF(8, -8), QString::number(i + 1));
      }
      if (l.hasImage) {
        const QPointF q = toWidget(QPointF(l.image.x(), l.image.y()));
        painter.setPen(QPen(QColor(60, 230, 255), 2));
        painter.drawLine(q + QPointF(-6, 0), q + QPointF(6, 0));
        painter.drawLine(q + QPointF(0, -6), q + QPointF(0, 6));
        painter.drawText(q + QPointF(8, 14), QString::number(i + 1));
        if (!m.isNull()) {
          painter.setPen(QPen(QColor(255, 255, 255, 120), 1, Qt::DashLine));
          painter.drawLine(m, q);
        }
      }
    }
  }
  // Gizmo.
  if (tool_ == Tool::Align && case_ && case_->hasPose && cogCamera().z() > 0) {
    const QPointF c = handlePosition(GizmoHandle::None);
    struct H {
      GizmoHandle h;
      int axis;
      bool rotate;
      const char* label;
    };
    const H handles[] = {{GizmoHandle::TranslateX, 0, false, "X"}, {GizmoHandle::TranslateY, 1, false, "Y"},
                         {GizmoHandle::TranslateZ, 2, false, "Z"}, {GizmoHandle::RotateX, 0, true, "rX"},
                         {GizmoHandle::RotateY, 1, true, "rY"},    {GizmoHandle::RotateZ, 2, true, "rZ"}};
    painter.setPen(QPen(Qt::white, 1));
    painter.setBrush(Qt::white);
    painter.drawEllipse(c, 4, 4);
    QFont f = font();
    f.setBold(true);
    painter.setFont(f);
    for (const auto& h : handles) {
      const QPointF p = handlePosition(h.h);
      QColor col = axisColour(h.axis);
      if (activeHandle_ == h.h) col = col.lighter(140);
      painter.setPen(QPen(col, 2));
      painter.drawLine(c, p);
      painter.setBrush(col.darker(h.rotate ? 200 : 120));
      if (h.rotate) painter.drawEllipse(p, kHandleRadius, kHandleRadius);
      else painter.drawRect(QRectF(p - QPointF(kHandleRadius, kHandleRadius), QSizeF(2 * kHandleRadius, 2 * kHandleRadius)));
      painter.setPen(Qt::white);
      painter.drawText(QRectF(p - QPointF(kHandleRadius, kHandleRadius), QSizeF(2 * kHandleRadius, 2 * kHandleRadius)),
                       Qt::AlignCenter, QString::fromLatin1(h.label));
    }
  }
}

void FrameView::wheelEvent(QWheelEvent* e) {
  if (frame_.isNull()) return;
  const QPointF anchor = e->position();
  const QPointF before = toFrame(anchor);
  zoom_ = std::clamp(zoom_ * std::pow(1.0015, e->angleDelta().y()), 0.25, 32.0);
  pan_ += anchor - frameToWidget().map(before);  // keep the frame point under the cursor
  update();
  e->accept();
}

void FrameView::mousePressEvent(QMouseEvent* e) {
  const QPointF w = e->position();
  const QPointF f = toFrame(w);
  const Eigen::Vector2d fp(f.x(), f.y());
  if (e->button() == Qt::MiddleButton || (e->button() == Qt::LeftButton && tool_ == Tool::Navigate)) {
    panning_ = true;
    lastMouse_ = w;
    setCursor(Qt::ClosedHandCursor);
    return;
  }
  if (!case_ || frame_.isNull()) return;
  switch (tool_) {
    case Tool::Freehand:
      if (e->button() == Qt::LeftButton) {
        drawing_ = true;
        draft_ = {fp};
      }
      break;
    case Tool::ClickPoints:
      if (e->button() == Qt::LeftButton) {
        drawing_ = true;
        draft_.push_back(fp);
        update();
      } else if (e->button() == Qt::RightButton && !draft_.empty()) {
        draft_.pop_back();
        update();
      }
      break;
    case Tool::EditPoints: {
      auto hit = pointNear(w, kPickRadius);
      if (e->button() == Qt::RightButton && hit) {
        imaging::Contour c = currentContour();
        auto& s = c.segments[hit->first];
        s.points.erase(s.points.begin() + hit->second);
        if (s.points.size() < 2) c.segments.erase(c.segments.begin() + hit->first);
        commitContour(c, tr("Delete point"));
      } else if (e->button() == Qt::LeftButton && (e->modifiers() & Qt::ControlModifier)) {
        // Insert on the nearest edge.
        imaging::Contour c = currentContour();
        double best = kPickRadius * 2;
        int bs = -1, bi = -1;
        for (int s = 0; s < static_cast<int>(c.segments.size()); ++s)
          for (int i = 0; i + 1 < static_cast<int>(c.segments[s].points.size()); ++i) {
            const auto& a = c.segments[s].points[i];
            const auto& b = c.segments[s].points[i + 1];
            const QPointF wa = toWidget(QPointF(a.x(), a.y())), wb = toWidget(QPointF(b.x(), b.y()));
            const QPointF ab = wb - wa;
            const double len2 = QPointF::dotProduct(ab, ab);
            const double t = len2 > 0 ? std::clamp(QPointF::dotProduct(w - wa, ab) / len2, 0.0, 1.0) : 0;
            const double d = QLineF(w, wa + t * ab).length();
            if (d < best) {
              best = d;
              bs = s;
              bi = i;
            }
          }
        if (bs >= 0) {
          c.segments[bs].points.insert(c.segments[bs].points.begin() + bi + 1, fp);
          commitContour(c, tr("Insert point"));
        }
      } else if (e->button() == Qt::LeftButton && hit) {
        dragPoint_ = hit;
        working_ = currentContour();
        activeMerge_ = ++mergeCounter_;
      }
      break;
    }
    case Tool::Erase:
      if (e->button() == Qt::LeftButton) {
        erasing_ = true;
        working_ = currentContour();
        activeMerge_ = ++mergeCounter_;
        eraseAt(w);
      }
      break;
    case Tool::Align:
      if (e->button() == Qt::LeftButton) {
        activeHandle_ = handleAt(w);
        if (activeHandle_ != GizmoHandle::None) {
          dragStartPose_ = case_->pose;
          dragStartMouse_ = w;
          activeMerge_ = ++mergeCounter_;
        } else {
          panning_ = true;
          lastMouse_ = w;
        }
        update();
      }
      break;
    case Tool::Landmarks:
      if (e->button() == Qt::LeftButton) {
        if (!landmarks_.empty() && !landmarks_.back().hasImage) {
          emit landmarkImagePicked(fp);
        } else if (const auto hit = organAt(fp)) {
          emit landmarkModelPicked(hit->model);
        }
      }
      break;
    case Tool::Attachments:
      if (e->button() == Qt::LeftButton) toggleAttachmentsAt(fp);
      break;
    case Tool::OrganCurve:
      if (e->button() == Qt::LeftButton) pickOrganCurve(fp);
      else if (e->button() == Qt::RightButton) finishOrganCurve();
      break;
    default: break;
  }
}

void FrameView::mouseMoveEvent(QMouseEvent* e) {
  const QPointF w = e->position();
  const QPointF f = toFrame(w);
  if (panning_) {
    pan_ += w - lastMouse_;
    lastMouse_ = w;
    update();
  } else if (drawing_ && tool_ == Tool::Freehand) {
    const Eigen::Vector2d p(f.x(), f.y());
    if ((p - draft_.back()).norm() * frameToWidget().m11() >= 2.0) {
      draft_.push_back(p);
      update();
    }
  } else if (dragPoint_) {
    working_.segments[dragPoint_->first].points[dragPoint_->second] = Eigen::Vector2d(f.x(), f.y());
    commitContour(working_, tr("Move point"), activeMerge_);
  } else if (erasing_) {
    eraseAt(w);
  } else if (activeHandle_ != GizmoHandle::None) {
    dragGizmo(w);
  }
  if (!frame_.isNull()) emit cursorMoved(f);
}

void FrameView::mouseReleaseEvent(QMouseEvent* e) {
  if (panning_) {
    panning_ = false;
    setTool(tool_);
    return;
  }
  if (drawing_ && tool_ == Tool::Freehand && e->button() == Qt::LeftButton) finishSegment();
  dragPoint_.reset();
  erasing_ = false;
  if (activeHandle_ != GizmoHandle::None) {
    activeHandle_ = GizmoHandle::None;
    update();
  }
  activeMerge_ = -1;
}

void FrameView::mouseDoubleClickEvent(QMouseEvent* e) {
  if (tool_ == Tool::OrganCurve) {
    finishOrganCurve();
    return;
  }
  if (tool_ == Tool::ClickPoints && drawing_) {
    finishSegment();
    return;
  }
  if (tool_ == Tool::Navigate) fitToWindow();
  QWidget::mouseDoubleClickEvent(e);
}

void FrameView::keyPressEvent(QKeyEvent* e) {
  const bool shift = e->modifiers() & Qt::ShiftModifier;
  if (tool_ == Tool::Align && case_ && case_->hasPose) {
    // Keyboard nudges: 1 mm (10 mm with Shift) along camera axes, 1 degree (5) about them.
    const double step = shift ? 0.010 : 0.001, angle = (shift ? 5.0 : 1.0) * M_PI / 180;
    Pose p = case_->pose;
    const Eigen::Vector3d g = p.apply(case_->organ->centreOfGravity);
    auto rotate = [&](int axis, double a) { p = p.turnedAbout(axisRotation(axis, a), g); };
    bool handled = true;
    switch (e->key()) {
      case Qt::Key_Left: p.t.x() -= step; break;
      case Qt::Key_Right: p.t.x() += step; break;
      case Qt::Key_Up: p.t.y() -= step; break;
      case Qt::Key_Down: p.t.y() += step; break;
      case Qt::Key_PageUp: p.t.z() += step; break;
      case Qt::Key_PageDown: p.t.z() -= step; break;
      case Qt::Key_W: rotate(0, -angle); break;
      case Qt::Key_S: rotate(0, angle); break;
      case Qt::Key_A: rotate(1, -angle); break;
      case Qt::Key_D: rotate(1, angle); break;
      case Qt::Key_Q: rotate(2, -angle); break;
      case Qt::Key_E: rotate(2, angle); break;
      default: handled = false;
    }
    if (handled) {
      emit poseEdited(p, tr("Nudge"), -1);
      return;
    }
  }
  switch (e->key()) {
    case Qt::Key_Home: fitToWindow(); break;
    case Qt::Key_Plus:
    case Qt::Key_Equal: zoom_ = std::min(32.0, zoom_ * 1.25); update(); break;
    case Qt::Key_Minus: zoom_ = std::max(0.25, zoom_ / 1.25); update(); break;
    case Qt::Key_Return:
    case Qt::Key_Enter:
      if (tool_ == Tool::OrganCurve) finishOrganCurve();
      else finishSegment();
      break;
    case Qt::Key_Backspace:
      if (tool_ == Tool::OrganCurve && curveSegment_ >= 0) {
        // Take back the last click's stretch of the organ curve.
        imaging::Contour c = currentContour();
        if (curveSegment_ < static_cast<int>(c.segments.size()) && !c.segments[curveSegment_].modelVertices.empty()) {
          auto& mv = c.segments[curveSegment_].modelVertices;
          mv.resize(curveStops_.size() > 1 ? curveStops_[curveStops_.size() - 2] : 0);
          if (!curveStops_.empty()) curveStops_.pop_back();
          commitContour(c, tr("Pick organ curve"), curveMerge_);
        }
      } else {
        QWidget::keyPressEvent(e);
      }
      break;
    case Qt::Key_Escape:
      if (tool_ == Tool::OrganCurve && curveSegment_ >= 0) {
        finishOrganCurve();
      } else if (drawing_) {
        draft_.clear();
        drawing_ = false;
        update();
      } else {
        QWidget::keyPressEvent(e);
      }
      break;
    default: QWidget::keyPressEvent(e);
  }
}

std::optional<FrameView::OrganHit> FrameView::organAt(const Eigen::Vector2d& fp) const {
  if (!case_ || !case_->hasPose || case_->organ->surface.empty()) return std::nullopt;
  // One ray through the clicked point (microseconds), not a render of the frame.
  const auto pick = imaging::pickSurface(case_->camera, case_->pose, case_->surfaceView(), fp);
  if (!pick) return std::nullopt;
  OrganHit hit;
  hit.model = pick->model;
  hit.node = pick->nearestVertex;
  return hit;
}

void FrameView::toggleAttachmentsAt(const Eigen::Vector2d& fp) {
  if (!case_ || !case_->hasPose) {
    emit toolMessage(tr("Attachments are picked on the organ drawn over the frame: open a frame (step 2) first."));
    return;
  }
  const auto hit = organAt(fp);
  if (!hit) {
    emit toolMessage(tr("Click on the organ drawn over the frame where a ligament holds it."));
    return;
  }
  // The surface nodes within the radius of the clicked point (the clicked node at least).
  const SurfaceView sv = case_->surfaceView();
  std::vector<int> patch;
  std::vector<char> seen(sv.vertexCount, 0);
  for (const auto& t : case_->organ->surface)
    for (int v : t) {
      if (seen[static_cast<std::size_t>(v)]) continue;
      seen[static_cast<std::size_t>(v)] = 1;
      if ((sv.vertex(static_cast<std::size_t>(v)) - hit->model).norm() <= attachRadius_) patch.push_back(v);
    }
  if (patch.empty()) patch.push_back(hit->node);
  std::vector<int> nodes = case_->attachments;
  std::sort(nodes.begin(), nodes.end());
  std::sort(patch.begin(), patch.end());
  const bool release = std::any_of(patch.begin(), patch.end(), [&](int v) { return std::binary_search(nodes.begin(), nodes.end(), v); });
  std::vector<int> result;
  if (release) std::set_difference(nodes.begin(), nodes.end(), patch.begin(), patch.end(), std::back_inserter(result));
  else std::set_union(nodes.begin(), nodes.end(), patch.begin(), patch.end(), std::back_inserter(result));
  const auto changed = static_cast<long>(std::max(result.size(), nodes.size()) - std::min(result.size(), nodes.size()));
  emit attachmentsEdited(result, release ? tr("Release %n attachment node(s)", nullptr, static_cast<int>(changed))
                                         : tr("Attach %n node(s)", nullptr, static_cast<int>(changed)));
}

void FrameView::pickOrganCurve(const Eigen::Vector2d& fp) {
  const auto hit = organAt(fp);
  if (!hit) {
    emit toolMessage(tr("Click on the organ drawn over the frame, along the ridge or ligament."));
    return;
  }
  imaging::Contour c = currentContour();
  if (curveSegment_ < 0 || curveSegment_ >= static_cast<int>(c.segments.size())) {
    // The first click chooses the sketched ridge or ligament nearest to it; its organ curve starts anew.
    double best = std::numeric_limits<double>::infinity();
    int target = -1;
    for (int i = 0; i < static_cast<int>(c.segments.size()); ++i) {
      if (c.segments[i].isSilhouette()) continue;
      for (const auto& p : c.segments[i].points)
        if ((p - fp).norm() < best) {
          best = (p - fp).norm();
          target = i;
        }
    }
    if (target < 0) {
      emit toolMessage(tr("Sketch the ridge or ligament on the frame first (step 3, new segments: Ridge or Ligament)."));
      return;
    }
    curveSegment_ = target;
    curveMerge_ = ++mergeCounter_;
    curveStops_.clear();
    c.segments[target].modelVertices.clear();
  }
  auto& seg = c.segments[curveSegment_];
  auto& mv = seg.modelVertices;
  if (mv.empty()) {
    mv.push_back(hit->node);
  } else {
    // Joined to the previous click by the shortest path along the surface (rest shape).
    const auto path = simcore::surfacePath(case_->organ->surface, case_->organ->volume.points, mv.back(), hit->node);
    if (path.size() > 1) mv.insert(mv.end(), path.begin() + 1, path.end());
  }
  curveStops_.push_back(mv.size());
  commitContour(c, tr("Pick organ curve"), curveMerge_);
  emit toolMessage(tr("%1: %2 nodes on the organ. Click on along it; Backspace takes back a click, Enter or a double click ends.")
                       .arg(QString::fromStdString(seg.type))
                       .arg(mv.size()));
}

void FrameView::finishOrganCurve() {
  if (curveSegment_ >= 0) emit toolMessage(tr("Organ curve done; the fit (F9) holds it onto the sketched curve."));
  curveSegment_ = -1;
  curveMerge_ = -1;
  curveStops_.clear();
}

}  // namespace rehearse::ui
