// The simulation panel's frames and their view (simulationview.hpp).
#include "rehearse/ui/simulationview.hpp"

#include <QLinearGradient>
#include <QMouseEvent>
#include <QPainter>
#include <QThread>
#include <QWheelEvent>

#include <algorithm>
#include <cmath>

namespace rehearse::ui {

// ------------------------------------------------------------------------------------------ frames

FrameBasis frameBasis(std::shared_ptr<const app::Case> organ, const simcore::BodySetup& b, long generation) {
  FrameBasis ctx;
  ctx.organ = std::move(organ);
  ctx.rest = b.start.empty() ? b.rest : b.start;  // displacements from where the rehearsal starts
  ctx.tets = b.mesh.tets;
  ctx.incidence.assign(ctx.rest.size(), 0);
  for (const auto& t : ctx.tets)
    for (int v : t) ++ctx.incidence[static_cast<std::size_t>(v)];
  auto supported = std::make_shared<std::vector<int>>();
  for (const auto& a : b.supports) supported->push_back(a.node);
  ctx.supports = std::move(supported);
  ctx.held = std::make_shared<const std::vector<int>>(b.fixedNodes);
  ctx.maxGraspForce = b.tools.maxGraspForce;
  ctx.generation = generation;
  return ctx;
}

std::shared_ptr<const SimulationFrame> makeSimulationFrame(FrameBasis& ctx, const simcore::Snapshot& snap, int colouring) {
  if (snap.step > ctx.lastStep)
    ctx.notConverged += snap.report.outcome != simcore::StepStatus::Converged;
  else if (snap.step < ctx.lastStep)
    ctx.notConverged = 0;  // a Reset: counted again from the start
  ctx.lastStep = snap.step;
  auto f = std::make_shared<SimulationFrame>();
  const std::size_t n = snap.positions.size();
  f->positions = snap.positions;
  f->value.assign(n, 0.0);
  if (colouring == 0 || snap.stress.size() != ctx.tets.size()) {
    for (std::size_t i = 0; i < n && i < ctx.rest.size(); ++i)
      f->value[i] = 1e3 * (f->positions[i] - ctx.rest[i]).norm();
    colouring = 0;
  } else {
    for (std::size_t e = 0; e < ctx.tets.size(); ++e)
      for (int v : ctx.tets[e]) f->value[v] += 1e-3 * snap.stress[e] / std::max(1, ctx.incidence[v]);
  }
  f->valueMax = f->value.empty() ? 0 : *std::max_element(f->value.begin(), f->value.end());
  // After a cut, a piece that nothing carries (no held, supported or grasped node: a fragment the blade chipped off)
  // falls away with gravity for as long as the rehearsal runs; its displacement is not the organ's. The colour bar's
  // top is the carried pieces' largest (a person saw the bar read 31,242 mm, then 90,163, and the whole organ flat blue).
  if (colouring == 0 && snap.topologyVersion > 0 && snap.tets && n > 0) {
    if (ctx.piecesOf != snap.tets || ctx.piece.size() != n) {  // (once per topology change, not at every step)
      ctx.piecesOf = snap.tets;
      ctx.piece = simcore::nodePieces(*snap.tets, n);
      ctx.pieceHeld.assign(static_cast<std::size_t>(std::max(0, *std::max_element(ctx.piece.begin(), ctx.piece.end()) + 1)), 0);
      for (const auto* nodes : {ctx.held.get(), ctx.supports.get()})
        if (nodes)
          for (int a : *nodes)
            if (a >= 0 && static_cast<std::size_t>(a) < n && ctx.piece[static_cast<std::size_t>(a)] >= 0)
              ctx.pieceHeld[static_cast<std::size_t>(ctx.piece[static_cast<std::size_t>(a)])] = 1;
    }
    std::vector<char> carried = ctx.pieceHeld;  // ... and the pieces the jaws hold
    for (int a : snap.tool.held)
      if (a >= 0 && static_cast<std::size_t>(a) < n && ctx.piece[static_cast<std::size_t>(a)] >= 0)
        carried[static_cast<std::size_t>(ctx.piece[static_cast<std::size_t>(a)])] = 1;
    double most = -1;
    for (std::size_t i = 0; i < n; ++i)
      if (ctx.piece[i] >= 0 && carried[static_cast<std::size_t>(ctx.piece[i])]) most = std::max(most, f->value[i]);
    if (most >= 0) f->valueMax = most;  // (nothing carried at all: the whole organ's, as before)
  }
  if (colouring == 0) {
    // Displacement: the colour bar's top is the largest (a pull moves a few nodes far: at the 98th percentile a person
    // read 0.01-0.02 mm over a torn organ pulled centimetres), at least 1 mm (at rest, micrometres of noise had coloured
    // the organ red and yellow under a bar reading 0.00).
    f->valueScale = std::max(f->valueMax, 1.0);
  } else if (!f->value.empty()) {
    std::vector<double> sorted = f->value;
    auto at = sorted.begin() + static_cast<std::ptrdiff_t>(0.98 * (sorted.size() - 1));
    std::nth_element(sorted.begin(), at, sorted.end());
    f->valueScale = *at > 0 ? *at : f->valueMax;
  }
  f->colouring = colouring;
  f->report = snap.report;
  f->time = snap.time;
  f->steps = snap.step;
  f->youngInUse = snap.material.young;
  f->thread = QThread::currentThreadId();
  f->organ = ctx.organ;
  f->tool = snap.tool;
  f->events = snap.events;
  f->surface = snap.surface;
  f->field = snap.field;
  f->labels = snap.labels;
  f->gravity = snap.gravity;
  f->supports = ctx.supports;
  f->held = ctx.held;
  f->maxGraspForce = ctx.maxGraspForce;
  f->stepsNotConverged = ctx.notConverged;
  f->elements = snap.elements;
  f->responseKey = snap.responseKey;
  f->model = snap.model;
  f->trocar = snap.trocar;
  f->toolRadius = snap.toolRadius;
  f->mass = snap.mass;
  f->tets = snap.tets;
  f->message = QString::fromStdString(snap.message);
  // Which elements are inside out (the report counts them): J = det(edges now) / det(edges at rest) <= 0.
  if (snap.report.invertedElements > 0) {
    const auto& tets = snap.tets ? *snap.tets : ctx.tets;
    const auto& rest = snap.surface ? snap.surface->rest : ctx.rest;
    f->invertedNode.assign(n, 0);
    for (std::size_t e = 0; e < tets.size(); ++e) {
      const auto& t = tets[e];
      if (std::any_of(t.begin(), t.end(), [&](int v) {
            return v < 0 || static_cast<std::size_t>(v) >= n || static_cast<std::size_t>(v) >= rest.size();
          }))
        continue;
      auto volume = [&](const std::vector<Eigen::Vector3d>& p) {
        return (p[t[1]] - p[t[0]]).dot((p[t[2]] - p[t[0]]).cross(p[t[3]] - p[t[0]]));
      };
      if (volume(snap.positions) * volume(rest) > 0) continue;
      f->inverted.push_back(static_cast<int>(e));
      f->invertedAt.push_back(
          0.25 * (snap.positions[t[0]] + snap.positions[t[1]] + snap.positions[t[2]] + snap.positions[t[3]]));
      for (int v : t) f->invertedNode[v] = 1;
    }
  }
  return f;
}

// -------------------------------------------------------------------------------------------- view

namespace {
// Blue - cyan - green - yellow - red.
// The colour bar's top value in at most five characters (at rest it is round-off: 0.00).
QString scaleLabel(double v) { return QString::number(v < 0.005 ? 0.0 : v, 'f', v >= 100 ? 0 : v >= 10 ? 1 : 2); }

QColor colourMap(double t) {
  static const double stops[5][3] = {{40, 70, 200}, {40, 190, 220}, {60, 200, 90}, {240, 220, 60}, {220, 50, 40}};
  t = std::clamp(t, 0.0, 1.0) * 4;
  const int i = std::min(3, static_cast<int>(t));
  const double u = t - i;
  return QColor::fromRgbF(((1 - u) * stops[i][0] + u * stops[i + 1][0]) / 255,
                          ((1 - u) * stops[i][1] + u * stops[i + 1][1]) / 255,
                          ((1 - u) * stops[i][2] + u * stops[i + 1][2]) / 255);
}
}  // namespace

SimulationView::SimulationView(QWidget* parent) : QWidget(parent) {
  setMinimumSize(240, 180);
  setAttribute(Qt::WA_OpaquePaintEvent);
  setToolTip(tr("Drag to turn, wheel to zoom, double-click to reset the view"));
}

void SimulationView::setFrame(std::shared_ptr<const SimulationFrame> f) {
  // The organ's centre and size frame the view: computed once per organ, not on every paint.
  if (f && f->organ && !f->positions.empty() && (!frame_ || frame_->organ != f->organ)) {
    Eigen::AlignedBox3d box;
    for (const auto& p : f->positions) box.extend(p);
    centre_ = box.center();
    size_ = 0.5 * box.diagonal().norm();  // the bounding sphere's radius
  }
  frame_ = std::move(f);
  update();
}

void SimulationView::clearFrame(const QString& why) {
  frame_.reset();
  emptyText_ = why;
  update();
}

void SimulationView::paintEvent(QPaintEvent*) {
  QPainter painter(this);
  painter.fillRect(rect(), QColor(24, 25, 28));
  if (!frame_ || !frame_->organ || frame_->positions.empty()) {
    painter.setPen(QColor(150, 150, 150));
    painter.drawText(rect().adjusted(12, 12, -12, -12), Qt::AlignCenter | Qt::TextWordWrap,
                     emptyText_.isEmpty() ? tr("No simulation yet: choose a preset and press Step or Play")
                                          : emptyText_);
    return;
  }
  const app::Case& organCase = *frame_->organ;
  const auto& organ = *organCase.organ;
  const Eigen::Vector3d& cog = centre_;
  const double size = size_;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(turntable_.pitch, Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(turntable_.yaw, Eigen::Vector3d::UnitY()))
                                .toRotationMatrix();
  // Framed like the 3D organ view (turntableView): the bounding sphere's outline spans 80 % of the smaller
  // side of the drawing area (left of the colour bar) whichever way the organ turns; the sphere is taken
  // from the first frame, and the organ sags within it.
  const double W = std::max(width() - 80, 10), H = std::max(height(), 10);
  const double f = 1.1 * std::min(W, H), cx = W / 2.0, cy = H / 2.0;
  const double ratio = f / (0.4 * std::min(W, H));
  const Eigen::Vector3d t = Eigen::Vector3d(0, 0, size * std::sqrt(1 + ratio * ratio) / turntable_.zoom) - R * cog;
  std::vector<Eigen::Vector3d> cam(frame_->positions.size());
  for (std::size_t i = 0; i < cam.size(); ++i) cam[i] = R * frame_->positions[i] + t;
  auto project = [&](const Eigen::Vector3d& p) { return QPointF(cx + f * p.x() / p.z(), cy + f * p.y() / p.z()); };
  // Painter's algorithm: far triangles first, Lambert-shaded by a light at the eye.
  struct Tri {
    double depth;
    std::size_t index;
  };
  // After a cut the simulation's own boundary (cut tissue marked), else the organ's surface.
  const auto& triangles = frame_->surface ? frame_->surface->triangles : organ.surface;
  std::vector<Tri> order;
  order.reserve(triangles.size());
  for (std::size_t k = 0; k < triangles.size(); ++k) {
    const auto& tri = triangles[k];
    const double z = cam[tri[0]].z() + cam[tri[1]].z() + cam[tri[2]].z();
    if (cam[tri[0]].z() > 1e-6 && cam[tri[1]].z() > 1e-6 && cam[tri[2]].z() > 1e-6) order.push_back({z, k});
  }
  std::sort(order.begin(), order.end(), [](const Tri& a, const Tri& b) { return a.depth > b.depth; });
  const double vmax = std::max(frame_->valueScale, 1e-9);
  painter.setRenderHint(QPainter::Antialiasing, false);
  for (const Tri& o : order) {
    const auto& tri = triangles[o.index];
    const Eigen::Vector3d n = (cam[tri[1]] - cam[tri[0]]).cross(cam[tri[2]] - cam[tri[0]]).normalized();
    const Eigen::Vector3d c = (cam[tri[0]] + cam[tri[1]] + cam[tri[2]]) / 3;
    const double shade = 0.35 + 0.65 * std::abs(n.dot(c.normalized()));
    const double v = (frame_->value[tri[0]] + frame_->value[tri[1]] + frame_->value[tri[2]]) / 3;
    const bool inverted =
        !frame_->invertedNode.empty() &&
        (frame_->invertedNode[tri[0]] || frame_->invertedNode[tri[1]] || frame_->invertedNode[tri[2]]);
    QColor col = inverted                                           ? QColor(235, 40, 235)
                 : frame_->surface && frame_->surface->cut[o.index] ? QColor(150, 30, 40)
                                                                    : colourMap(v / vmax);
    col = QColor::fromRgbF(col.redF() * shade, col.greenF() * shade, col.blueF() * shade);
    const QPointF pts[3] = {project(cam[tri[0]]), project(cam[tri[1]]), project(cam[tri[2]])};
    painter.setPen(QPen(col, 0.8));
    painter.setBrush(col);
    painter.drawConvexPolygon(pts, 3);
  }
  painter.setRenderHint(QPainter::Antialiasing);
  painter.setPen(Qt::NoPen);
  // What the session holds besides the picks (a lone pick's neighbours on the surface: a person saw 3 dots where 48
  // nodes were held), smaller and paler; the picks over them.
  if (frame_->held) {
    painter.setBrush(QColor(255, 190, 120, 200));
    for (int a : *frame_->held)
      if (a >= 0 && static_cast<std::size_t>(a) < cam.size() && cam[a].z() > 0)
        painter.drawEllipse(project(cam[a]), 1.7, 1.7);
  }
  painter.setBrush(QColor(255, 150, 40));
  for (int a : organCase.attachments)
    if (a >= 0 && static_cast<std::size_t>(a) < cam.size() && cam[a].z() > 0)
      painter.drawEllipse(project(cam[a]), 2.5, 2.5);
  // What holds the organ, said under the arrow in the dots' colours: the held nodes (orange), and the tissue around it
  // carrying it: its supported nodes, small and blue-grey (under the organ's surface, where gravity presses it: seen
  // when the view is turned). (A person read "on its supports (135 nodes)" beside the orange dots as their count.)
  // Within the drawing area (left of the colour bar), elided where narrow; the whole sentence in the panel's status.
  // Below the gravity arrow (which reaches 30 px down), on a dark band so that the organ behind does not hide it.
  double captionY = 92;
  auto caption = [&](const QColor& colour, const QString& said) {
    painter.setPen(colour);
    const QString text = painter.fontMetrics().elidedText(said, Qt::ElideRight, static_cast<int>(std::max(W - 24, 10.0)));
    const QRectF box(18, captionY, painter.fontMetrics().horizontalAdvance(text) + 6, 16);
    painter.fillRect(box, QColor(24, 25, 28, 190));
    painter.drawText(box.adjusted(3, 0, 0, 0), Qt::AlignLeft, text);
    painter.setPen(Qt::NoPen);
    captionY += 18;
  };
  if (frame_->held && !frame_->held->empty())
    caption(QColor(255, 170, 80), frame_->held->size() == 1 ? tr("held: 1 node") : tr("held: %1 nodes").arg(frame_->held->size()));
  if (frame_->supports && !frame_->supports->empty()) {
    painter.setBrush(QColor(110, 170, 210, 200));
    for (int a : *frame_->supports)
      if (a >= 0 && static_cast<std::size_t>(a) < cam.size() && cam[a].z() > 0)
        painter.drawEllipse(project(cam[a]), 1.6, 1.6);
    caption(QColor(110, 170, 210), tr("supported below: %1 nodes").arg(frame_->supports->size()));
  }
  // Gravity, as the case states it, turned with the view: an arrow (a crossed circle where it points into the view, a
  // dotted one where it points out of it).
  if (frame_->gravity.norm() > 0) {
    const Eigen::Vector3d d = R * frame_->gravity.normalized();
    const QPointF o(30, 56), tip = o + 24 * QPointF(d.x(), d.y());
    painter.setPen(QPen(QColor(120, 200, 255), 2));
    painter.setBrush(Qt::NoBrush);
    if (std::hypot(d.x(), d.y()) > 0.25) {
      painter.drawLine(o, tip);
      const QPointF back = (o - tip) / std::max(1e-9, std::hypot(o.x() - tip.x(), o.y() - tip.y()));
      const QPointF side(-back.y(), back.x());
      painter.drawLine(tip, tip + 7 * back + 4 * side);
      painter.drawLine(tip, tip + 7 * back - 4 * side);
    }
    if (std::abs(d.z()) > 0.5) {
      painter.drawEllipse(o, 7, 7);
      if (d.z() > 0) {
        painter.drawLine(o + QPointF(-5, -5), o + QPointF(5, 5));
        painter.drawLine(o + QPointF(-5, 5), o + QPointF(5, -5));
      } else {
        painter.drawEllipse(o, 1.5, 1.5);
      }
    }
    painter.drawText(QRectF(o.x() + 12, o.y() - 22, 120, 16), Qt::AlignLeft, tr("gravity"));
  }
  // Colour bar with its unit.
  const QRect bar(width() - 62, 30, 14, height() - 70);
  QLinearGradient g(bar.bottomLeft(), bar.topLeft());
  for (int i = 0; i <= 8; ++i) g.setColorAt(i / 8.0, colourMap(i / 8.0));
  painter.fillRect(bar, g);
  painter.setPen(QColor(200, 200, 200));
  const QString unit = frame_->colouring == 0 ? tr("mm") : tr("kPa");
  painter.drawText(QRect(width() - 80, 6, 78, 20), Qt::AlignCenter, frame_->colouring == 0 ? tr("|u|") : tr("σ vM"));
  painter.drawText(QRect(width() - 46, bar.top() - 6, 46, 16), Qt::AlignLeft, scaleLabel(frame_->valueScale));
  painter.drawText(QRect(width() - 46, bar.bottom() - 8, 46, 16), Qt::AlignLeft, QStringLiteral("0"));
  painter.drawText(QRect(width() - 80, bar.bottom() + 6, 78, 20), Qt::AlignCenter, unit);
  painter.drawText(rect().adjusted(6, 4, -80, -4), Qt::AlignLeft | Qt::AlignTop,
                   tr("t = %1 s, %2 steps").arg(frame_->time, 0, 'f', 2).arg(frame_->steps));
  if (const QString w = warningText(*frame_); !w.isEmpty()) {
    const QRect area = warningArea(QWidget::size(), painter.fontMetrics(), w);
    painter.fillRect(area.adjusted(-3, -2, 3, 2), QColor(24, 25, 28, 190));  // the organ behind does not hide it
    painter.setPen(QColor(255, 120, 255));
    painter.drawText(area, Qt::AlignLeft | Qt::AlignTop | Qt::TextWordWrap, w);
  }
}

QRect SimulationView::marksArea() {
  // The time line (y 4-24), the arrow about (30, 56) reaching 30 px, its word to x 162, the captions at y 92-126.
  return QRect(0, 0, 170, 128);
}

QRect SimulationView::warningArea(const QSize& size, const QFontMetrics& fm, const QString& text) {
  const int width = std::max(size.width() - 86, 40);
  const QRect wrapped = fm.boundingRect(QRect(0, 0, width, 10000), Qt::AlignLeft | Qt::AlignTop | Qt::TextWordWrap, text);
  return QRect(6, size.height() - 6 - wrapped.height(), width, wrapped.height());
}

QString warningText(const SimulationFrame& f) {
  const auto& r = f.report;
  if (r.outcome == simcore::StepStatus::Inverted)
    return (r.invertedElements == 1
                ? QObject::tr(
                      "Warning: 1 element inside out (magenta; volume ratio %1): the shape there is not tissue.")
                : QObject::tr("Warning: %1 elements inside out (magenta; smallest volume ratio %2): the shape there is "
                              "not tissue.")
                      .arg(r.invertedElements))
        .arg(r.minVolumeRatio, 0, 'g', 3);
  if (r.outcome == simcore::StepStatus::Inexact && r.inversionLimited)
    return QObject::tr(
               "Warning: the step was held back to keep elements from turning inside out (relative residual %1).")
        .arg(r.residual, 0, 'g', 3);
  return {};
}

void SimulationView::mousePressEvent(QMouseEvent* e) { turntable_.press(e->position()); }
void SimulationView::mouseMoveEvent(QMouseEvent* e) {
  if (!(e->buttons() & Qt::LeftButton)) return;
  turntable_.drag(e->position());
  update();
}
void SimulationView::mouseDoubleClickEvent(QMouseEvent*) {
  turntable_.reset();
  update();
}
void SimulationView::wheelEvent(QWheelEvent* e) {
  turntable_.wheel(e->angleDelta().y());
  update();
}

}  // namespace rehearse::ui
