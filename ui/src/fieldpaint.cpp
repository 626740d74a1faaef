// The operative field over the frame while rehearsing (FrameView::paintField): each clip as a titanium bar across
// the structure it closed, and the blood from each stump as a film running down the organ's surface from the stump
// (simcore::bloodFilm: a falling film, no fluid solver; the surface holds what flowed out while the film runs off the
// organ, not all the blood lost), drawn where the camera sees it (the live surface's depth buffer: blood in an incision
// under intact tissue is hidden by it); burnt tissue as a line along the hook's path. Front-facing triangles only, far
// to near.
#include "rehearse/ui/frameview.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/session/bloodfilm.hpp>
#include <rehearse/simcore/session/contact.hpp>

#include <QPainter>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>

namespace rehearse::ui {

struct FrameView::FieldGraph {
  const simcore::CutSurface* surface = nullptr;
  std::size_t nodes = 0;
  std::vector<std::vector<int>> neighbours;
  // The blood film last drawn and what it was drawn from (a paint without a new snapshot draws it again as it was).
  std::vector<simcore::Bleed> filmBleeds;
  std::vector<Eigen::Vector3d> filmLive;
  Eigen::Vector3d filmDown = Eigen::Vector3d::Zero();
  std::vector<double> film;
  QImage blood;        ///< the film as the camera sees it, frame pixels (premultiplied), from `bloodAt`
  QPoint bloodAt;
  // The burnt elements' faces on the boundary (outward), for the labels and elements they were found on.
  const std::vector<int>* labels = nullptr;
  const std::vector<std::array<int, 4>>* tets = nullptr;
  std::vector<std::array<int, 3>> burnt;
};

namespace {
// The boundary faces of the burnt elements (a face no other element shares), outward.
std::vector<std::array<int, 3>> burntBoundary(const std::vector<std::array<int, 4>>& tets,
                                              const std::vector<int>& labels) {
  std::map<std::array<int, 3>, int> count;
  for (const auto& t : tets)
    for (int k = 0; k < 4; ++k) {
      std::array<int, 3> f = {t[static_cast<std::size_t>((k + 1) % 4)], t[static_cast<std::size_t>((k + 2) % 4)],
                              t[static_cast<std::size_t>((k + 3) % 4)]};
      std::sort(f.begin(), f.end());
      ++count[f];
    }
  std::vector<std::array<int, 3>> out;
  for (std::size_t e = 0; e < tets.size() && e < labels.size(); ++e) {
    if (!simcore::isBurnt(labels[e])) continue;
    const auto& t = tets[e];
    // Faces opposite each vertex, ordered so their normal points away from it (positively oriented elements).
    static const int faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    for (const auto& face : faces) {
      std::array<int, 3> f = {t[static_cast<std::size_t>(face[0])], t[static_cast<std::size_t>(face[1])],
                              t[static_cast<std::size_t>(face[2])]};
      std::array<int, 3> key = f;
      std::sort(key.begin(), key.end());
      if (count[key] == 1) out.push_back(f);
    }
  }
  return out;
}

// Whether the triangle's nodes are all nodes of a shape of `n`.
bool onShape(const std::array<int, 3>& t, std::size_t n) {
  return std::none_of(t.begin(), t.end(), [n](int v) { return v < 0 || static_cast<std::size_t>(v) >= n; });
}

}  // namespace

void FrameView::setLiveField(simcore::OperativeField field, const Eigen::Vector3d& gravity,
                             std::shared_ptr<const std::vector<int>> labels,
                             std::shared_ptr<const std::vector<std::array<int, 4>>> tets) {
  const bool shown = !field_.clips.empty() || !field_.bleeds.empty() || fieldLabels_ != labels;
  field_ = std::move(field);
  gravity_ = gravity;
  fieldLabels_ = std::move(labels);
  fieldTets_ = std::move(tets);
  if (shown || !field_.clips.empty() || !field_.bleeds.empty()) update();
}

namespace {
// The blood film as the camera sees it, in frame pixels: the live surface rasterised (its depth buffer hides what the
// organ's own tissue covers), each pixel of a wet triangle coloured by the film interpolated across it (a film has no
// facets: the nodes' values blended, its edge fading where the film thins out), lit by the scope's light with a gloss,
// then softened by a pixel. Null when nothing wet is in view.
QImage bloodImage(const imaging::Camera& camera, const std::vector<Eigen::Vector3d>& live,
                  const std::vector<std::array<int, 3>>& triangles, const std::vector<double>& film, QPoint& at) {
  const std::size_t n = live.size();
  // Per wet triangle, once: its corners in the frame and its light (not per pixel).
  struct WetTriangle {
    Eigen::Vector2d a, ab, ac;
    double area = 0, light = 0;
  };
  std::vector<int> wet(triangles.size(), -1);
  std::vector<WetTriangle> wets;
  Eigen::AlignedBox2d box;
  for (std::size_t k = 0; k < triangles.size(); ++k) {
    const auto& t = triangles[k];
    if (std::any_of(t.begin(), t.end(), [n](int v) { return v < 0 || static_cast<std::size_t>(v) >= n; })) return {};
    if (!(std::max({film[static_cast<std::size_t>(t[0])], film[static_cast<std::size_t>(t[1])],
                    film[static_cast<std::size_t>(t[2])]}) > 0.02))
      continue;
    const Eigen::Vector3d &A = live[static_cast<std::size_t>(t[0])], &B = live[static_cast<std::size_t>(t[1])],
                          &C = live[static_cast<std::size_t>(t[2])];
    if (!(A.z() > 1e-6 && B.z() > 1e-6 && C.z() > 1e-6)) continue;  // (crossing the eye: never drawn)
    WetTriangle w;
    w.a = camera.project(A);
    const Eigen::Vector2d pb = camera.project(B), pc = camera.project(C);
    w.ab = pb - w.a;
    w.ac = pc - w.a;
    w.area = w.ab.x() * w.ac.y() - w.ab.y() * w.ac.x();
    if (!(std::abs(w.area) > 1e-12)) continue;
    const Eigen::Vector3d normal = (B - A).cross(C - A).normalized();
    w.light = std::clamp(-normal.dot(((A + B + C) / 3).normalized()), 0.0, 1.0);
    if (!std::isfinite(w.light)) w.light = 0;
    wet[k] = static_cast<int>(wets.size());
    wets.push_back(w);
    box.extend(w.a);
    box.extend(pb);
    box.extend(pc);
  }
  if (box.isEmpty()) return {};
  const int x0 = std::max(0, static_cast<int>(std::floor(box.min().x())) - 2),
            y0 = std::max(0, static_cast<int>(std::floor(box.min().y())) - 2),
            x1 = std::min(camera.width - 1, static_cast<int>(std::ceil(box.max().x())) + 2),
            y1 = std::min(camera.height - 1, static_cast<int>(std::ceil(box.max().y())) + 2);
  if (x1 < x0 || y1 < y0) return {};
  SurfaceView sv;
  std::vector<double> vertices;
  vertices.reserve(3 * n);
  for (const auto& p : live) vertices.insert(vertices.end(), {p.x(), p.y(), p.z()});
  sv.vertices = vertices.data();
  sv.vertexCount = n;
  sv.triangles = triangles.front().data();
  sv.triangleCount = triangles.size();
  // Only the wet part's box of the frame (the camera's principal point moved into it): a whole 1920x1080 frame's
  // buffers for a stream 100 px long were most of the cost.
  imaging::Camera part = camera;
  part.K(0, 2) -= x0;
  part.K(1, 2) -= y0;
  part.width = x1 - x0 + 1;
  part.height = y1 - y0 + 1;
  imaging::Rasterization r;
  try {
    r = imaging::rasterizeCameraFrame(part, live, sv, 1, 1e-3, true);
  } catch (const std::exception&) {
    return {};  // a bad camera: nothing to draw
  }
  cv::Mat bgra(y1 - y0 + 1, x1 - x0 + 1, CV_8UC4, cv::Scalar(0, 0, 0, 0));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const int k = r.triangle(y - y0, x - x0);
      if (k < 0 || wet[static_cast<std::size_t>(k)] < 0) continue;
      const auto& t = triangles[static_cast<std::size_t>(k)];
      const WetTriangle& w = wets[static_cast<std::size_t>(wet[static_cast<std::size_t>(k)])];
      const Eigen::Vector2d p = Eigen::Vector2d(x + 0.5, y + 0.5) - w.a;
      const double wb = (p.x() * w.ac.y() - p.y() * w.ac.x()) / w.area,
                   wc = (w.ab.x() * p.y() - w.ab.y() * p.x()) / w.area;
      const double wa = 1 - wb - wc;
      const double f = std::clamp(wa * film[static_cast<std::size_t>(t[0])] + wb * film[static_cast<std::size_t>(t[1])] +
                                      wc * film[static_cast<std::size_t>(t[2])],
                                  0.0, 1.0);
      const double edge = std::clamp((f - 0.05) / 0.2, 0.0, 1.0);  // the film's edge fades out
      if (!(edge > 0)) continue;
      const double light = w.light;
      // Fresh blood under the scope's light: bright red where thin, darker where it pools, with a gloss.
      const double lit = 0.6 + 0.4 * light, gloss = 0.5 * std::pow(light, 400.0);  // (the scope's light is at the eye)
      const double red = (195 - 75 * f) * lit + 60 * gloss, green = (24 - 16 * f) * lit + 120 * gloss,
                   blue = (20 - 12 * f) * lit + 110 * gloss;
      const double alpha = (0.8 + 0.18 * f) * edge;
      bgra.at<cv::Vec4b>(y - y0, x - x0) = cv::Vec4b(cv::saturate_cast<uchar>(alpha * blue),
                                                     cv::saturate_cast<uchar>(alpha * green),
                                                     cv::saturate_cast<uchar>(alpha * red),
                                                     cv::saturate_cast<uchar>(255 * alpha));
    }
  cv::GaussianBlur(bgra, bgra, cv::Size(3, 3), 0.8);
  at = QPoint(x0, y0);
  return QImage(bgra.data, bgra.cols, bgra.rows, static_cast<int>(bgra.step), QImage::Format_ARGB32_Premultiplied)
      .copy();
}
}  // namespace

bool FrameView::trailPlace(const BurnTrailPoint& p, Eigen::Vector3d& x) const {
  x.setZero();
  for (int k = 0; k < 3; ++k) {
    const int v = p.nodes[static_cast<std::size_t>(k)];
    if (v < 0 || static_cast<std::size_t>(v) >= live_.size()) return false;
    x += p.weights[k] * live_[static_cast<std::size_t>(v)];
  }
  return true;
}

void FrameView::followHook(long step, const Eigen::Vector3d& tip, bool present, bool energy, double radius,
                           double touchedTime) {
  if (step < hookStep_ || touchedTime < hookTouched_) clearBurnTrail();  // a reset or a new session: start again
  hookStep_ = step;
  hookRadius_ = radius;
  if (energy && !hookPowered_) ++hookStroke_;  // the power came on: a new stroke
  hookPowered_ = energy;
  // The simulation said the powered tip touched tissue since the last frame shown (its time on tissue grew): the
  // trail goes on where it is. (Not this frame's distance alone: the frames the window sees are a sample of the
  // steps, and the shaft's contact keeps the surface about its radius from the tip, near the hook's own radius.)
  const bool touched = touchedTime > hookTouched_;
  hookTouched_ = touchedTime;
  if (!energy || !present || !touched || !case_ || !case_->organ || live_.empty() || !tip.allFinite()) return;
  // The nearest point of the surface (the cut one once cut): where it burns, as seen from outside. Within twice
  // the radius (tissue that moved on since the step that touched it); none further: no point is made up.
  const auto& triangles = liveSurface_ ? liveSurface_->triangles : case_->organ->surface;
  const std::size_t n = live_.size();
  double best = std::pow(2 * radius, 2);
  BurnTrailPoint at;
  bool found = false;
  for (const auto& t : triangles) {
    if (!onShape(t, n)) continue;
    const Eigen::Vector3d &a = live_[static_cast<std::size_t>(t[0])], &b = live_[static_cast<std::size_t>(t[1])],
                          &c = live_[static_cast<std::size_t>(t[2])];
    Eigen::Vector3d w;
    const double d2 = (simcore::closestOnTriangle(tip, a, b, c, w) - tip).squaredNorm();
    if (d2 <= best) best = d2, at.nodes = t, at.weights = w, found = true;
  }
  if (!found) return;
  at.stroke = hookStroke_;
  // A point every fifth of the radius along the stroke (the line between them is drawn).
  Eigen::Vector3d last, here;
  if (!burnTrail_.empty() && burnTrail_.back().stroke == at.stroke && trailPlace(burnTrail_.back(), last) &&
      trailPlace(at, here) && (last - here).norm() < 0.2 * radius)
    return;
  burnTrail_.push_back(at);
  update();
}

void FrameView::paintField(QPainter& painter) {
  const bool anyBurnt = fieldLabels_ && std::any_of(fieldLabels_->begin(), fieldLabels_->end(), simcore::isBurnt);
  if (!case_ || live_.empty() || (field_.clips.empty() && field_.bleeds.empty() && !anyBurnt)) return;
  const std::size_t n = live_.size();
  if (!fieldGraph_) fieldGraph_ = std::make_shared<FieldGraph>();
  if (anyBurnt && fieldTets_ && fieldLabels_) paintBurntFaces(painter);
  if (anyBurnt && !burnTrail_.empty()) paintBurnTrail(painter);  // (a stroke that burnt nothing says so, and draws nothing)
  const bool bleeding = std::any_of(field_.bleeds.begin(), field_.bleeds.end(), [n](const simcore::Bleed& b) {
    return b.lost > 0 && b.node >= 0 && static_cast<std::size_t>(b.node) < n;
  });
  if (bleeding && liveSurface_) paintBlood(painter);
  paintClips(painter);
}

std::optional<QPointF> FrameView::fieldPoint(const Eigen::Vector3d& p) const {
  if (!(p.z() > 1e-6)) return std::nullopt;
  const auto uv = case_->camera.project(p);
  return toWidget(QPointF(uv.x(), uv.y()));
}

std::optional<std::pair<double, QPolygonF>> FrameView::fieldFace(const std::array<int, 3>& t) const {
  const Eigen::Vector3d &a = live_[static_cast<std::size_t>(t[0])], &b = live_[static_cast<std::size_t>(t[1])],
                        &c = live_[static_cast<std::size_t>(t[2])];
  if ((b - a).cross(c - a).dot(a) >= 0) return std::nullopt;  // facing away from the camera
  QPolygonF poly;
  for (const Eigen::Vector3d* p : {&a, &b, &c})
    if (const auto w = fieldPoint(*p)) poly << *w;
  if (poly.size() != 3) return std::nullopt;
  return std::make_pair((a.z() + b.z() + c.z()) / 3, poly);
}

void FrameView::paintBurntFaces(QPainter& painter) {
  // Burnt tissue whitens: its faces on the surface, front-facing, far to near, in a pale tan over the organ (as
  // coarse as the mesh: the line along the hook's path is drawn over them, below).
  if (fieldGraph_->labels != fieldLabels_.get() || fieldGraph_->tets != fieldTets_.get()) {
    fieldGraph_->labels = fieldLabels_.get();
    fieldGraph_->tets = fieldTets_.get();
    fieldGraph_->burnt = burntBoundary(*fieldTets_, *fieldLabels_);
  }
  const std::size_t n = live_.size();
  std::vector<std::pair<double, QPolygonF>> faces;
  for (const auto& t : fieldGraph_->burnt) {
    if (!onShape(t, n)) continue;
    if (auto face = fieldFace(t)) faces.push_back(std::move(*face));
  }
  std::sort(faces.begin(), faces.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing, false);
  const QColor ash(228, 214, 188, 110);
  painter.setPen(Qt::NoPen);
  painter.setBrush(ash);
  for (const auto& [depth, poly] : faces) painter.drawPolygon(poly);
  painter.restore();
}

// The burn along the hook's path (followHook): where the powered tip went over the tissue, as wide as it burns (twice
// its radius at that depth), coagulated tissue pale around a charred core; on a coarse mesh the burnt elements' faces
// alone were a flat polygon about 10 mm across, not a line (issue 61).
void FrameView::paintBurnTrail(QPainter& painter) {
  const double scale = std::abs(toWidget(QPointF(1, 0)).x() - toWidget(QPointF(0, 0)).x());  // widget px per image px
  struct Stroke {
    double depth;
    QPointF from, to;
    double width;
  };
  std::vector<Stroke> strokes;
  auto place = [&](const BurnTrailPoint& p, Eigen::Vector3d& x) {
    if (!trailPlace(p, x)) return false;
    const Eigen::Vector3d &a = live_[static_cast<std::size_t>(p.nodes[0])],
                          &b = live_[static_cast<std::size_t>(p.nodes[1])],
                          &c = live_[static_cast<std::size_t>(p.nodes[2])];
    return (b - a).cross(c - a).dot(a) < 0 && x.z() > 1e-6;  // on a face the camera sees
  };
  for (std::size_t i = 0; i < burnTrail_.size(); ++i) {
    Eigen::Vector3d p, q;
    if (!place(burnTrail_[i], p)) continue;
    const bool joined = i + 1 < burnTrail_.size() && burnTrail_[i + 1].stroke == burnTrail_[i].stroke &&
                        place(burnTrail_[i + 1], q);
    if (!joined) q = p;
    const auto wp = fieldPoint(p), wq = fieldPoint(q);
    if (!wp || !wq) continue;
    const double depth = 0.5 * (p.z() + q.z());
    strokes.push_back({depth, *wp, *wq, std::max(3.0, 2 * hookRadius_ * case_->camera.fx() / depth * scale)});
  }
  std::sort(strokes.begin(), strokes.end(), [](const Stroke& x, const Stroke& y) { return x.depth > y.depth; });
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing, true);
  const QColor coagulated(232, 220, 196, 225), charred(88, 64, 46, 235);
  for (const auto& st : strokes) {
    painter.setPen(QPen(coagulated, st.width, Qt::SolidLine, Qt::RoundCap, Qt::RoundJoin));
    painter.drawLine(st.from, st.to);
  }
  for (const auto& st : strokes) {
    painter.setPen(QPen(charred, std::max(1.5, 0.3 * st.width), Qt::SolidLine, Qt::RoundCap, Qt::RoundJoin));
    painter.drawLine(st.from, st.to);
  }
  painter.restore();
}

void FrameView::paintBlood(QPainter& painter) {
  const auto& surface = *liveSurface_;
  const std::size_t n = live_.size();
  if (fieldGraph_->surface != &surface || fieldGraph_->nodes != n) {
    fieldGraph_->surface = &surface;
    fieldGraph_->nodes = n;
    fieldGraph_->neighbours = simcore::surfaceNeighbours(surface.triangles, n);
    fieldGraph_->film.clear();
  }
  const Eigen::Vector3d down = gravity_.norm() > 0 ? Eigen::Vector3d(gravity_.normalized()) : Eigen::Vector3d::Zero();
  auto& g = *fieldGraph_;
  if (g.film.size() != n || g.filmBleeds != field_.bleeds || g.filmDown != down || g.filmLive != live_) {
    g.film = simcore::bloodFilm(field_.bleeds, live_, surface.triangles, g.neighbours, down, {}, surface.cut).film;
    g.filmBleeds = field_.bleeds;
    g.filmLive = live_;
    g.filmDown = down;
    g.blood = surface.triangles.empty() ? QImage() : bloodImage(case_->camera, live_, surface.triangles, g.film, g.bloodAt);
  }
  if (g.blood.isNull()) return;
  painter.save();
  painter.setTransform(frameToWidget());
  painter.setRenderHint(QPainter::SmoothPixmapTransform, true);
  painter.drawImage(g.bloodAt, g.blood);
  painter.restore();
}

void FrameView::paintClips(QPainter& painter) {
  // The clips: a bar across the structure each closed, as long as the nodes between its jaws reach.
  const std::size_t n = live_.size();
  painter.save();
  for (const auto& clip : field_.clips) {
    if (clip.anchor < 0 || static_cast<std::size_t>(clip.anchor) >= n) continue;
    const Eigen::Vector3d p = live_[static_cast<std::size_t>(clip.anchor)];
    const Eigen::Vector3d jaw = clip.axis.cross(clip.across).normalized();
    double reach = 0.001;
    for (int v : clip.nodes)
      if (v >= 0 && static_cast<std::size_t>(v) < n)
        reach = std::max(reach, std::abs(jaw.dot(live_[static_cast<std::size_t>(v)] - p)));
    reach += 0.001;
    const auto a = fieldPoint(p - reach * jaw), b = fieldPoint(p + reach * jaw);
    if (!a || !b) continue;
    const auto side = fieldPoint(p + 0.0015 * clip.axis);  // the clip's 1.5 mm width on the screen
    const double width = std::clamp(
        side ? std::hypot(side->x() - a->x() / 2 - b->x() / 2, side->y() - a->y() / 2 - b->y() / 2) : 4.0, 4.0, 14.0);
    painter.setPen(QPen(QColor(40, 40, 48), width + 3, Qt::SolidLine, Qt::RoundCap));
    painter.drawLine(*a, *b);
    painter.setPen(QPen(clip.spans ? QColor(210, 212, 222) : QColor(235, 190, 80), width, Qt::SolidLine, Qt::RoundCap));
    painter.drawLine(*a, *b);
    painter.setPen(QPen(QColor(250, 250, 255, 200), std::max(1.0, width / 4), Qt::SolidLine, Qt::RoundCap));
    painter.drawLine(*a, *b);  // the titanium's highlight
  }
  painter.restore();
}

}  // namespace rehearse::ui
