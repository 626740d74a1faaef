#include "rehearse/ui/frameview.hpp"

#include <QTimer>

#include "tools/tools.hpp"

#include <rehearse/imaging/render.hpp>

#include <QFontMetricsF>
#include <QKeyEvent>
#include <QMouseEvent>
#include <QPainter>
#include <QWheelEvent>

#include <algorithm>
#include <cmath>
#include <vector>

namespace rehearse::ui {

FrameView::FrameView(QWidget* parent) : QWidget(parent) {
  setMinimumSize(320, 200);
  setMouseTracking(true);
  setFocusPolicy(Qt::StrongFocus);
  setAttribute(Qt::WA_OpaquePaintEvent);
  settle_ = new QTimer(this);
  settle_->setSingleShot(true);
  settle_->setInterval(250);
  connect(settle_, &QTimer::timeout, this, [this] { scaleFrame(); });
  tools_[Tool::Freehand] = tools::makeDrawTool(*this, true);
  tools_[Tool::ClickPoints] = tools::makeDrawTool(*this, false);
  tools_[Tool::EditPoints] = tools::makeEditPointsTool(*this);
  tools_[Tool::Erase] = tools::makeEraseTool(*this);
  tools_[Tool::Align] = tools::makeGizmoTool(*this);
  tools_[Tool::Landmarks] = tools::makeLandmarkTool(*this);
  tools_[Tool::OrganCurve] = tools::makeOrganCurveTool(*this);
  tools_[Tool::Attachments] = tools::makeAttachmentTool(*this);
  tools_[Tool::Grasp] = tools::makeGraspTool(*this);
  tools_[Tool::Scissors] = tools::makeScissorsTool(*this);
  tools_[Tool::Clip] = tools::makeClipTool(*this);
  tools_[Tool::Cautery] = tools::makeCauteryTool(*this);
}

FrameView::~FrameView() = default;

FrameTool* FrameView::current() const {
  const auto it = tools_.find(tool_);
  return it == tools_.end() ? nullptr : it->second.get();
}

void FrameView::setFrame(const QImage& frame) {
  const bool sameSize = frame.size() == frame_.size();
  frame_ = frame;
  if (!sameSize) fitToWindow();
  update();
}

void FrameView::setFrame(const QImage& frame, const QImage& scaledToView) {
  setFrame(frame);
  const QSize size = frameSizeInView();
  if (scaledToView.isNull() || size.isEmpty() || scaledToView.size() != size) return;
  const QTransform toWidget = frameToWidget();
  scaledFrame_.image = scaledToView;
  scaledFrame_.at = toWidget.mapRect(QRectF(QPointF(0, 0), QSizeF(frame_.size()))).topLeft();
  scaledFrame_.key = frame_.cacheKey();
  scaledFrame_.transform = toWidget;
  scaledFrame_.smooth = true;
}

QSize FrameView::frameSizeInView() const {
  if (frame_.isNull() || zoom_ >= 2.0) return {};
  return frameToWidget().mapRect(QRectF(QPointF(0, 0), QSizeF(frame_.size()))).size().toSize();
}

bool FrameView::scaledFrameFits() const {
  return scaledFrame_.key == frame_.cacheKey() && scaledFrame_.transform == frameToWidget() &&
         scaledFrame_.smooth == (zoom_ < 2.0);
}

void FrameView::scaleFrame() {
  if (frame_.isNull() || scaledFrameFits()) return;
  const QTransform toWidget = frameToWidget();
  const bool smooth = zoom_ < 2.0;
  const QRectF target = toWidget.mapRect(QRectF(QPointF(0, 0), QSizeF(frame_.size())));
  scaledFrame_.image = frame_.scaled(target.size().toSize(), Qt::IgnoreAspectRatio, smooth ? Qt::SmoothTransformation : Qt::FastTransformation);
  scaledFrame_.at = target.topLeft();
  scaledFrame_.key = frame_.cacheKey();
  scaledFrame_.transform = toWidget;
  scaledFrame_.smooth = smooth;
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

void FrameView::paintInstrument(QPainter& painter) {
  if (!pointer_ || !isInstrument(tool_) || !case_ || frame_.isNull()) return;
  const QString name = tool_ == Tool::Grasp      ? tr("Grasper")
                       : tool_ == Tool::Scissors ? tr("Scissors")
                       : tool_ == Tool::Clip     ? tr("Clip applier")
                                                 : tr("Cautery hook");
  const QColor colour = tool_ == Tool::Grasp      ? QColor(60, 170, 80)
                        : tool_ == Tool::Scissors ? QColor(150, 60, 190)
                        : tool_ == Tool::Clip     ? QColor(120, 130, 150)
                                                  : QColor(230, 150, 30);
  painter.save();
  QFont font = painter.font();
  font.setPointSizeF(std::max(7.0, 0.85 * font.pointSizeF()));
  painter.setFont(font);
  const QFontMetricsF fm(font);
  const QRectF box(*pointer_ + QPointF(14, 12), QSizeF(fm.horizontalAdvance(name) + 10, fm.height() + 4));
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setPen(Qt::NoPen);
  painter.setBrush(QColor(20, 20, 24, 190));
  painter.drawRoundedRect(box, 4, 4);
  painter.setBrush(colour);
  painter.drawRect(QRectF(box.left(), box.top() + 3, 3, box.height() - 6));
  painter.setPen(QColor(240, 240, 240));
  painter.drawText(box.adjusted(6, 0, 0, 0), Qt::AlignVCenter | Qt::AlignLeft, name);
  painter.restore();
}

void FrameView::setDeviceTip(std::optional<Eigen::Vector3d> tip, bool working) {
  if (tip == deviceTip_ && working == deviceWorking_) return;
  deviceTip_ = tip;
  deviceWorking_ = working;
  update();
}

void FrameView::paintDeviceTip(QPainter& painter) {
  if (!deviceTip_ || !case_ || frame_.isNull() || !(deviceTip_->z() > 1e-4)) return;
  const Eigen::Vector2d f = case_->camera.project(*deviceTip_);
  if (!f.allFinite()) return;
  const QPointF at = toWidget(QPointF(f.x(), f.y()));
  // Its depth against the tissue along the view ray (the frame shows neither).
  QString depth = tr("off the organ");
  if (const auto s = liveSurfaceAt(f)) {
    const double mm = 1e3 * (deviceTip_->z() - s->z());
    depth = mm < 0 ? tr("%1 mm before the tissue").arg(-mm, 0, 'f', 0) : tr("%1 mm into the tissue").arg(mm, 0, 'f', 0);
  }
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setPen(QPen(QColor(250, 250, 255), 2));
  painter.setBrush(deviceWorking_ ? QBrush(QColor(250, 250, 255, 120)) : Qt::NoBrush);
  painter.drawEllipse(at, 9, 9);
  painter.drawLine(at + QPointF(-15, 0), at + QPointF(-6, 0));
  painter.drawLine(at + QPointF(6, 0), at + QPointF(15, 0));
  painter.drawLine(at + QPointF(0, -15), at + QPointF(0, -6));
  painter.drawLine(at + QPointF(0, 6), at + QPointF(0, 15));
  const QString text = tr("3D mouse · %1").arg(depth);
  const QFontMetricsF fm(painter.font());
  QRectF box(at + QPointF(14, -30), QSizeF(fm.horizontalAdvance(text) + 10, fm.height() + 4));
  // Above the ring, inside the view (near an edge it slides along, never past it).
  box.moveLeft(std::clamp(box.left(), 4.0, std::max(4.0, width() - 4.0 - box.width())));
  painter.setPen(Qt::NoPen);
  painter.setBrush(QColor(20, 20, 24, 190));
  painter.drawRoundedRect(box, 4, 4);
  painter.setPen(QColor(240, 240, 240));
  painter.drawText(box.adjusted(5, 0, 0, 0), Qt::AlignVCenter | Qt::AlignLeft, text);
  painter.restore();
}

void FrameView::leaveEvent(QEvent* e) {
  if (pointer_) update(QRect(pointer_->toPoint() + QPoint(10, 8), QSize(180, 36)));
  pointer_.reset();
  emit cursorLeft();
  QWidget::leaveEvent(e);
}

void FrameView::setTool(Tool t) {
  if (t != tool_) {
    // The grasper keeps its hold while the scissors cut or the clip applier clips (an assistant's traction); any
    // other tool lets go.
    const auto instrument = isInstrument;
    if (current() && !(tool_ == Tool::Grasp && instrument(t))) current()->finish();
    if (!instrument(t) && instrument(tool_) && tool_ != Tool::Grasp) tools_.at(Tool::Grasp)->finish();
    if (current()) current()->setActive(false);
    if (const auto it = tools_.find(t); it != tools_.end()) it->second->setActive(true);
  }
  if (t == Tool::OrganCurve && tool_ != Tool::OrganCurve)
    emit toolMessage(tr("Click along the ridge or ligament on the organ drawn over the frame; the nearest sketched one gets the curve."));
  const bool changed = t != tool_;
  tool_ = t;
  setCursor(current() ? current()->cursor() : Qt::OpenHandCursor);
  update();
  if (changed) emit toolChanged(t);
}

void FrameView::finishSegment() {
  if (auto* t = current(); t && (tool_ == Tool::Freehand || tool_ == Tool::ClickPoints)) t->finish();
}

void FrameView::finishOrganCurve() { tools_.at(Tool::OrganCurve)->finish(); }

const std::vector<LandmarkPair>& FrameView::landmarks() const {
  static const std::vector<LandmarkPair> none;
  return case_ ? case_->landmarks : none;
}

QPointF FrameView::handlePosition(GizmoHandle h) const { return tools::gizmoHandlePosition(*this, h); }

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
double FrameView::scale() const { return frameToWidget().m11(); }

imaging::Contour FrameView::currentContour() const {
  imaging::Contour c = case_ ? (secondShown_ ? case_->contour2 : case_->contour) : imaging::Contour{};
  if (!frame_.isNull()) {
    c.width = frame_.width();
    c.height = frame_.height();
  }
  return c;
}

std::optional<OrganHit> FrameView::organAt(const Eigen::Vector2d& fp) const {
  if (!case_ || !case_->hasPose || case_->organ->surface.empty()) return std::nullopt;
  // One ray through the clicked point (microseconds), not a render of the frame.
  const auto pick = imaging::pickSurface(case_->camera, case_->pose, case_->surfaceView(), fp);
  if (!pick) return std::nullopt;
  return OrganHit{pick->model, pick->nearestVertex};
}

std::optional<Eigen::Vector3d> FrameView::liveSurfaceAt(const Eigen::Vector2d& f, SurfacePick pick,
                                                       const std::vector<Eigen::Vector3d>* shape) const {
  const bool outerPoint = pick == SurfacePick::OuterPoint;
  const auto& c = case_;
  if (!c || !c->hasPose) return std::nullopt;
  const auto& live = shape && shape->size() == live_.size() ? *shape : live_;
  std::vector<double> vertices;
  SurfaceView sv = c->surfaceView();
  Pose pose = c->pose;
  const auto& cut = liveSurface_;
  std::vector<std::array<int, 3>> outer;
  if (cut && !live.empty()) {
    sv.triangles = cut->triangles.empty() ? nullptr : cut->triangles.front().data();
    sv.triangleCount = cut->triangles.size();
    sv.vertexCount = live.size();
    if (outerPoint && cut->cut.size() == cut->triangles.size()) {
      for (std::size_t k = 0; k < cut->triangles.size(); ++k)
        if (!cut->cut[k]) outer.push_back(cut->triangles[k]);
      sv.triangles = outer.empty() ? nullptr : outer.front().data();
      sv.triangleCount = outer.size();
    }
  }
  if (live.size() == sv.vertexCount) {
    vertices.reserve(3 * live.size());
    for (const auto& x : live) vertices.insert(vertices.end(), {x.x(), x.y(), x.z()});
    sv.vertices = vertices.data();
    pose = Pose{};
  }
  try {
    const auto hit = imaging::pickSurface(c->camera, pose, sv, f);
    if (!hit) return std::nullopt;
    if (pick != SurfacePick::Node) return pose.apply(hit->model);
    return pose.apply(hit->nearestVertex >= 0 ? sv.vertex(static_cast<std::size_t>(hit->nearestVertex)) : hit->model);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// ------------------------------------------------------------------------------------------ painting

// An instrument of step 7 in hand (isInstrument): the registration's marks (landmarks through the rest pose, the
// assistant's contour and the organ curves bound to it, the fit's "where the organ may be") do not follow the tissue,
// and are not drawn over the rehearsal (people saw the landmarks, then the contour and the fit's dashed bound, stay
// through a grasp).

void FrameView::paintEvent(QPaintEvent*) {
  ++paints_;
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
  const QTransform toWidget = frameToWidget();
  // The frame scaled to the view, kept while neither changes: while rehearsing over the frame only the organ over it
  // changes, and a smooth scale of the whole frame was half of each repaint (bench_rehearsal_view). A frame that
  // changes at each step (the composited view) is drawn through the painter's transform instead until it has stayed
  // the same a quarter of a second: scaling each new one first took 7-24 ms of the GUI thread per repaint (the patient
  // liver's 1920x1080 frame, the simulation running on both cores), the window's longest pauses while rehearsing.
  // The composited view's worker scales each frame it composes (setFrame(frame, scaled)): drawing that copy took 0.5 ms
  // median against 5.3 through the transform (the patient liver in step 7, test_operative_gui).
  if (scaledFrameFits()) {
    ++paintsFromScaled_;
    painter.drawImage(scaledFrame_.at, scaledFrame_.image);
  } else {
    painter.save();
    painter.setTransform(toWidget);
    painter.drawImage(QPointF(0, 0), frame_);
    painter.restore();
    settle_->start();  // (again: the frame or the view changed since it was started)
  }
  painter.setTransform(toWidget);
  if (overlayVisible_) paintOverlay(painter);
  const bool marks = !isInstrument(tool_);
  if (!possible_.isEmpty() && !secondShown_ && marks) {
    QPen pen(palette::possibleOutline(), 2.0, Qt::DashLine);
    pen.setCosmetic(true);
    painter.setPen(pen);
    painter.setBrush(Qt::NoBrush);
    for (const auto& poly : possible_) painter.drawPolygon(poly);
  }
  // Contour: segments coloured by type.
  const auto contour = marks ? currentContour() : imaging::Contour{};
  for (const auto& s : contour.segments) {
    QPolygonF poly;
    for (const auto& p : s.points) poly << QPointF(p.x(), p.y());
    QPen cpen(tools::segmentColour(s.type), 2.5);
    cpen.setCosmetic(true);
    painter.setPen(cpen);
    if (s.closed) painter.drawPolygon(poly);
    else painter.drawPolyline(poly);
  }
  painter.resetTransform();
  // (the simulation's marks: in step 7, or with an instrument in hand wherever it was taken)
  const bool simulating = rehearsing_ || isInstrument(tool_);
  if (simulating) paintField(painter);
  paintOrganMarks(painter, contour);
  for (const auto& [kind, tool] : tools_)
    if (kind != tool_) tool->paintIdle(painter);
  if (FrameTool* t = current()) t->paint(painter);
  paintInstrument(painter);
  paintDeviceTip(painter);
  if (simulating) paintWarning(painter);
  paintLegend(painter);
}

void FrameView::setSecondFrameShown(bool second) {
  if (second == secondShown_) return;
  secondShown_ = second;
  emit shownFrameChanged(second);
  update();
}

void FrameView::setPossibleOutlines(QList<QPolygonF> outlines, const QString& text) {
  if (outlines.isEmpty() && possible_.isEmpty()) return;
  possible_ = std::move(outlines);
  possibleText_ = text;
  update();
}

void FrameView::setWarning(std::vector<Eigen::Vector3d> cameraPoints, const QString& text) {
  if (text.isEmpty() && warningText_.isEmpty()) return;
  warningAt_ = std::move(cameraPoints);
  warningText_ = text;
  update();
}

void FrameView::paintWarning(QPainter& painter) {
  if (warningText_.isEmpty()) return;
  const QColor magenta(235, 40, 235);
  if (case_) {
    painter.setPen(QPen(magenta, 2));
    painter.setBrush(Qt::NoBrush);
    for (const auto& p : warningAt_) {
      if (p.z() <= 0) continue;
      const auto uv = case_->camera.project(p);
      painter.drawEllipse(toWidget(QPointF(uv.x(), uv.y())), 5, 5);
    }
  }
  const QFontMetrics fm(font());
  const QRect text = fm.boundingRect(QRect(0, 0, std::max(200, width() - 40), 200), Qt::TextWordWrap, warningText_);
  const QRect box(QPoint((width() - text.width()) / 2 - 8, 8), text.size() + QSize(16, 10));
  painter.setPen(Qt::NoPen);
  painter.setBrush(QColor(40, 0, 40, 200));
  painter.drawRoundedRect(box, 4, 4);
  painter.setPen(QColor(255, 170, 255));
  painter.drawText(box.adjusted(8, 5, -8, -5), Qt::TextWordWrap, warningText_);
}

bool FrameView::toolsBusy() const {
  for (const auto& [tool, t] : tools_)
    if (t && t->busy()) return true;
  return false;
}


QList<LegendEntry> FrameView::legend() const {
  QList<LegendEntry> out;
  if (frame_.isNull()) return out;
  if (overlayVisible_ && !silhouette_.isEmpty()) out.push_back({palette::organOutline(), tr("organ outline (O hides)")});
  // Each inner structure in the colour it is drawn in (a single red swatch stood for yellow vessels before).
  if (overlayVisible_ && !inner_.isNull()) {
    if (innerKey_.isEmpty()) out.push_back({QColor(200, 60, 60), tr("inner structures: colours as in step 1")});
    for (const auto& [colour, name] : innerKey_) out.push_back({colour, tr("inside: %1").arg(name)});
  }
  const bool marks = !isInstrument(tool_);
  if (!possible_.isEmpty() && !secondShown_ && marks) out.push_back({palette::possibleOutline(), possibleText_});
  std::vector<std::string> types;
  if (case_ && marks)
    for (const auto& seg : (secondShown_ ? case_->contour2 : case_->contour).segments)
      if (std::find(types.begin(), types.end(), seg.type) == types.end()) types.push_back(seg.type);
  for (const char* t : {"silhouette", "ridge", "ligament"})
    if (std::find(types.begin(), types.end(), std::string(t)) != types.end())
      out.push_back({tools::segmentColour(t), tr("contour: %1").arg(tr(t))});
  if (case_ && !case_->landmarks.empty() && marks) {
    out.push_back({palette::landmarkOnOrgan(), tr("landmark on the organ")});
    out.push_back({palette::landmarkInFrame(), tr("landmark in the frame")});
  }
  return out;
}

QRect FrameView::legendRect() const {
  const auto entries = legend();
  if (!legendVisible_ || entries.isEmpty()) return {};
  const QFontMetrics fm(font());
  int w = 0;
  for (const auto& e : entries) w = std::max(w, fm.horizontalAdvance(e.text));
  const int line = fm.height() + 4;
  const QSize size(w + 36, line * static_cast<int>(entries.size()) + 10);
  return QRect(QPoint(8, height() - 8 - size.height()), size);
}

void FrameView::setLegendVisible(bool visible) {
  legendVisible_ = visible;
  update();
}

void FrameView::paintLegend(QPainter& painter) {
  const QRect box = legendRect();
  if (box.isEmpty()) return;
  painter.resetTransform();
  painter.setOpacity(1.0);
  // The box was measured with the widget's font: draw with it (a tool's larger font left on the painter cut entries off).
  painter.setFont(font());
  painter.setRenderHint(QPainter::Antialiasing, false);
  painter.setPen(Qt::NoPen);
  painter.setBrush(QColor(0, 0, 0, 170));
  painter.drawRect(box);
  const QFontMetrics fm(font());
  const int line = fm.height() + 4;
  int y = box.top() + 5;
  for (const auto& e : legend()) {
    painter.fillRect(QRect(box.left() + 8, y + line / 2 - 6, 16, 12), e.colour);  // the swatch, solid
    painter.setPen(QColor(235, 235, 235));
    painter.drawText(QRect(box.left() + 30, y, box.width() - 32, line), Qt::AlignVCenter | Qt::AlignLeft, e.text);
    y += line;
  }
  painter.setRenderHint(QPainter::Antialiasing);
}

void FrameView::paintOverlay(QPainter& painter) {
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
  QPen pen(palette::organOutline(), 2.0);
  pen.setCosmetic(true);
  painter.setPen(pen);
  painter.setBrush(Qt::NoBrush);
  for (const auto& poly : silhouette_) painter.drawPolygon(poly);
}

void FrameView::paintOrganMarks(QPainter& painter, const imaging::Contour& contour) {
  if (!case_ || !case_->hasPose) return;
  // The organ curves of ridges and ligaments, through the current pose and shape: dashed, with their nodes.
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
    const QColor colour = tools::segmentColour(s.type);
    painter.setPen(QPen(colour.lighter(130), 2, Qt::DashLine));
    painter.setBrush(Qt::NoBrush);
    painter.drawPolyline(poly);
    painter.setBrush(colour);
    painter.setPen(QPen(QColor(30, 30, 30), 1));
    for (const auto& q : poly) painter.drawEllipse(q, 2.5, 2.5);
  }
  // Landmarks: model points through the current pose (orange) and their image points (cyan).
  for (std::size_t i = 0; i < case_->landmarks.size() && !isInstrument(tool_); ++i) {
    const auto& l = case_->landmarks[i];
    const Eigen::Vector3d xc = case_->pose.apply(l.model);
    QPointF m;
    if (xc.z() > 0) {
      const auto uv = case_->camera.project(xc);
      m = toWidget(QPointF(uv.x(), uv.y()));
      painter.setPen(QPen(palette::landmarkOnOrgan(), 2));
      painter.setBrush(Qt::NoBrush);
      painter.drawEllipse(m, 6, 6);
      painter.drawText(m + QPointF(8, -8), QString::number(i + 1));
    }
    if (!l.hasImage) continue;
    const QPointF q = toWidget(QPointF(l.image.x(), l.image.y()));
    painter.setPen(QPen(palette::landmarkInFrame(), 2));
    painter.drawLine(q + QPointF(-6, 0), q + QPointF(6, 0));
    painter.drawLine(q + QPointF(0, -6), q + QPointF(0, 6));
    painter.drawText(q + QPointF(8, 14), QString::number(i + 1));
    if (!m.isNull()) {
      painter.setPen(QPen(QColor(255, 255, 255, 120), 1, Qt::DashLine));
      painter.drawLine(m, q);
    }
  }
}

// ------------------------------------------------------------------------------------------ input

void FrameView::wheelEvent(QWheelEvent* e) {
  if (frame_.isNull()) return;
  if (current() && current()->wheel(e)) {
    e->accept();
    update();
    return;
  }
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
  bool pan = e->button() == Qt::MiddleButton || (e->button() == Qt::LeftButton && !current());
  if (!pan && case_ && !frame_.isNull() && current()) pan = !current()->press(e, w, Eigen::Vector2d(f.x(), f.y()));
  if (pan) {
    panning_ = true;
    lastMouse_ = w;
    setCursor(Qt::ClosedHandCursor);
  }
}

void FrameView::mouseMoveEvent(QMouseEvent* e) {
  const QPointF w = e->position();
  const QPointF f = toFrame(w);
  if (isInstrument(tool_)) {
    // The instrument's name follows the tip: only where its label was and is repainted.
    auto label = [](const QPointF& p) { return QRect(p.toPoint() + QPoint(10, 8), QSize(180, 36)); };
    const QRect dirty = pointer_ ? label(*pointer_).united(label(w)) : label(w);
    pointer_ = w;
    update(dirty);
  }
  if (panning_) {
    pan_ += w - lastMouse_;
    lastMouse_ = w;
    update();
  } else if (current()) {
    current()->move(w, Eigen::Vector2d(f.x(), f.y()));
  }
  if (!frame_.isNull()) emit cursorMoved(f);
}

void FrameView::mouseReleaseEvent(QMouseEvent* e) {
  if (panning_) {
    panning_ = false;
    setCursor(current() ? current()->cursor() : Qt::OpenHandCursor);
    return;
  }
  if (current()) current()->release(e);
}

void FrameView::mouseDoubleClickEvent(QMouseEvent* e) {
  if (current() && current()->doubleClick()) return;
  if (tool_ == Tool::Navigate) fitToWindow();
  QWidget::mouseDoubleClickEvent(e);
}

std::vector<std::pair<QString, QString>> FrameView::viewKeys() {
  return {{QStringLiteral("Home"), tr("Fit the frame to the view")},
          {QStringLiteral("+"), tr("Zoom in")},
          {QStringLiteral("-"), tr("Zoom out")},
          {QStringLiteral("Return"), tr("End the click-by-click segment or the curve being picked")},
          {QStringLiteral("Esc"), tr("Abandon what the tool is drawing")},
          {QStringLiteral("Backspace"), tr("Take the last point of the curve on the organ back")},
          {QStringLiteral("Space"), tr("Grasper: close the jaws at the cursor, or open them")}};
}

void FrameView::endGesture() {
  // Quietly: nothing it would post (the blade off, the instrument withdrawn) or say ("Cut ended.") belongs to the run
  // from rest (while recording, that run's session is still being built: a post there said "not ready").
  const QSignalBlocker quiet(this);
  if (current() && current()->abandon()) update();
}

void FrameView::clearLive() {
  live_.clear();
  liveSurface_.reset();
  setLiveField({}, Eigen::Vector3d::Zero());
  setWarning({}, {});
  update();
}

void FrameView::setLiveJaws(bool closed, bool holding) {
  if (!closed) return;
  if (const auto it = tools_.find(Tool::Grasp); it != tools_.end() && it->second) it->second->jawsSeen(closed, holding);
  if (!holding) update();
}

void FrameView::keyPressEvent(QKeyEvent* e) {
  if (current() && current()->key(e)) return;
  switch (e->key()) {
    case Qt::Key_Home: fitToWindow(); break;
    case Qt::Key_Plus:
    case Qt::Key_Equal: zoom_ = std::min(32.0, zoom_ * 1.25); update(); break;
    case Qt::Key_Minus: zoom_ = std::max(0.25, zoom_ / 1.25); update(); break;
    case Qt::Key_Return:
    case Qt::Key_Enter:
      if (current()) current()->finish();
      break;
    case Qt::Key_Escape:
      if (!current() || !current()->abandon()) QWidget::keyPressEvent(e);
      break;
    default: QWidget::keyPressEvent(e);
  }
}

}  // namespace rehearse::ui
