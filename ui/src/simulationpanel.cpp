#include "rehearse/ui/simulationpanel.hpp"
#include "rehearse/ui/throttle.hpp"

#include <rehearse/app/materials.hpp>

#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/inverse_rest.hpp>
#include <rehearse/simcore/support.hpp>
#include <rehearse/simcore/scene.hpp>

#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QPaintEvent>
#include <QLinearGradient>
#include <QMouseEvent>
#include <QPainter>
#include <QPointer>
#include <QPushButton>
#include <QFutureWatcher>
#include <QSignalBlocker>
#include <QThread>
#include <QtConcurrent/QtConcurrent>
#include <QVBoxLayout>
#include <QWheelEvent>

#include <future>
#include <algorithm>
#include <mutex>
#include <cmath>

Q_DECLARE_METATYPE(std::shared_ptr<const rehearse::ui::SimulationFrame>)

namespace rehearse::ui {

// ------------------------------------------------------------------------------------ session glue

// What turns the session's snapshots into frames for this panel: fixed for one organ (one session), read
// on the session's thread.
struct SimulationPanel::FrameContext {
  std::shared_ptr<const app::Case> organ;
  std::vector<Eigen::Vector3d> rest;  ///< camera frame (m)
  std::vector<std::array<int, 4>> tets;
  std::vector<int> incidence;  ///< elements per node (stress averaged onto nodes)
  std::shared_ptr<const std::vector<int>> supports;  ///< the supported nodes (kept by index through cuts)
  long generation = 0;         ///< frames of an older session are dropped
  // On the session's thread (its published callback, once per step): steps not converged since the start or a Reset.
  long lastStep = 0, notConverged = 0;
};

namespace {
// A word-wrapped label of a fixed number of lines: a longer text is drawn as far as they hold it, ending in an
// ellipsis (text() stays whole; the panel puts it in the tooltip).
class LinesLabel : public QLabel {
 public:
  LinesLabel(int lines, QWidget* parent) : QLabel(parent), lines_(lines) { setProperty("elidesItsText", true); }

 protected:
  void paintEvent(QPaintEvent*) override {
    QPainter p(this);
    p.setPen(palette().color(QPalette::WindowText));
    const QRect room = contentsRect();
    const QFontMetrics fm = fontMetrics();
    const QRect lines(0, 0, room.width(), lines_ * fm.lineSpacing());
    auto fits = [&](const QString& t) { return fm.boundingRect(lines, Qt::TextWordWrap, t).height() <= lines.height(); };
    QString shown = text();
    if (!fits(shown)) {
      int lo = 0, hi = static_cast<int>(shown.size());
      while (lo < hi) {
        const int mid = (lo + hi + 1) / 2;
        if (fits(shown.left(mid) + QChar(0x2026))) lo = mid;
        else hi = mid - 1;
      }
      shown = shown.left(lo) + QChar(0x2026);
    }
    p.drawText(room, Qt::AlignTop | Qt::AlignLeft | Qt::TextWordWrap, shown);
  }

 private:
  int lines_;
};

simcore::InputEvent parameter(const std::string& name, double value, int label = 0) {
  simcore::InputEvent e;
  e.kind = simcore::InputKind::Parameter;
  e.name = name;
  e.value = value;
  e.label = label;
  return e;
}

// The same organ in the same shape, place and attachments (then a material or run edit keeps the state).
bool sameBody(const app::Case* a, const app::Case* b) {
  return a && b && a->organ == b->organ && a->shapeNodes() == b->shapeNodes() && a->attachments == b->attachments &&
         a->pose.R == b->pose.R && a->pose.t == b->pose.t;
}

}  // namespace

std::shared_ptr<const SimulationFrame> SimulationPanel::makeFrame(const FrameContext& ctx,
                                                                  const simcore::Snapshot& snap, int colouring) {
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
  if (!f->value.empty()) {
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
  f->stepsNotConverged = ctx.notConverged;
  f->elements = snap.elements;
  f->responseKey = snap.responseKey;
  f->model = snap.model;
  f->trocar = snap.trocar;
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

void SimulationPanel::startSession(const SimulationSetup& s, std::optional<RecordRequest> record) {
  // Building the body (model, first factorisation) takes a while on a large organ: on a worker; the old
  // session keeps its thread until the new one is ready. Commands given meanwhile apply to the new one.
  forceLoop_.reset();  // it reads the session's snapshots
  // The old session's thread is joined (its step, a cut's build under way) and its recording marked complete on a
  // thread of their own (issue 62: Reset while recording froze the window 2 s); what records next waits for it.
  if (session_ || recorder_) {
    QPointer<SimulationPanel> self(this);
    retired_ = std::async(std::launch::async, [old = std::move(session_), rec = std::move(recorder_),
                                               previous = retired_, self]() mutable {
                 if (previous.valid()) previous.wait();
                 old.reset();
                 if (!rec) return;
                 try {
                   rec->finish(rec->lastStep());  // a new session is a new recording (or none)
                 } catch (const std::exception& e) {
                   const QString why = QString::fromStdString(e.what());
                   if (self)
                     QMetaObject::invokeMethod(
                       self.data(),
                       [self, why] {
                         if (self)
                           emit self->recordingStopped(
                               tr("The recorded session could not be marked complete: %1").arg(why));
                       },
                       Qt::QueuedConnection);
                 }
               }).share();
    session_.reset();
    recorder_.reset();
  }
  if (!record && recordRequest_) {  // a new organ (or none) ends the recording: said, never silently
    recordRequest_.reset();
    emit recordingStopped(
        tr("The recording ended: the organ, its shape, pose or attachments changed (what was recorded is kept, "
           "complete)."));
  }
  const long generation = ++generation_;
  startRefused_ = false;
  buildCancelled_->store(true);  // the session being built (its rest-shape solve) is not wanted any more
  buildCancelled_ = std::make_shared<std::atomic<bool>>(false);
  startWord_.clear();
  recordPending_ = record.has_value();
  cancelRecord_ = false;
  if (!s.organ || s.organ->organ->empty()) {
    recordPending_ = false;
    onFailed(tr("No organ volume to simulate; load or tetrahedralise a mesh first."));
    return;
  }
  builtWith_ = s.organ->material;
  pendingSteps_ = 0;
  auto* watcher = new QFutureWatcher<void>(this);
  auto result = std::make_shared<std::pair<std::shared_ptr<simcore::Session>, QString>>();
  auto recorder = std::make_shared<std::shared_ptr<app::Recorder>>();
  auto ctx = std::make_shared<FrameContext>();
  auto started = std::make_shared<QString>();
  connect(watcher, &QFutureWatcher<void>::finished, this, [this, watcher, result, ctx, generation, recorder, started] {
    watcher->deleteLater();
    if (generation != generation_) return;  // a newer organ arrived meanwhile
    startWord_ = *started;
    const bool cancelled = cancelRecord_;
    recordPending_ = cancelRecord_ = false;
    if (!result->first) {
      startRefused_ = true;  // a setting changed on the panel tries again (postRunParameters)
      // The last session's organ is not what runs: no frame of it stays on show (it kept its time and attachments).
      last_.reset();
      view_->clearFrame(result->second);
      onFailed(result->second);
      if (*recorder) emit recordingStopped(tr("The recording did not start: %1").arg(result->second));
      return;
    }
    session_ = std::move(result->first);
    // A refusal said before (nothing held it, no equilibrium) is over: the organ runs (it said so while paused too).
    if (!error_.isEmpty()) {
      error_.clear();
      statusThrottle_->request();
    }
    {
      const auto& b = session_->setup();
      asked_ = {b.settings.timeStep, b.tools.graspRadius, b.tools.clip.length, b.settings.method, b.model,
                b.settings.gravity};
    }
    if (*recorder && cancelled) {
      (*recorder)->finish(0);
    } else if (*recorder) {
      recorder_ = *recorder;
      recorderFailed_->store(false);
      // On the session's thread after every step; a write the file refuses stops the recording, not the simulation.
      session_->setStepHook(
          [rec = recorder_, failed = recorderFailed_, why = recorderError_](const simcore::StepRecord& r) {
            if (failed->load()) return;
            try {
              rec->afterStep(r);
            } catch (const std::exception& e) {
              *why = e.what();
              failed->store(true);
            }
          });
    }
    forceLoop_ = std::make_unique<simcore::ForceLoop>([s = session_.get()] { return s->toolForce(); }, &device_);
    forceLoop_->start();
    session_->setPublishedCallback([this, s = session_.get(), ctx]() {
      // On the session's thread: the frame is made here, the GUI thread only draws it.
      const auto snap = s->snapshot();
      if (snap->step > ctx->lastStep)
        ctx->notConverged += snap->report.outcome != simcore::StepStatus::Converged;
      else if (snap->step < ctx->lastStep)
        ctx->notConverged = 0;  // a Reset: counted again from the start
      ctx->lastStep = snap->step;
      auto frame = makeFrame(*ctx, *snap, colouring_.load());
      QMetaObject::invokeMethod(
          this,
          [this, frame, generation = ctx->generation] {
            if (generation == generation_) onFrame(frame);
          },
          Qt::QueuedConnection);
    });
    session_->setPublishStress(colouring_ == 1);  // publishes the state at rest with this panel's colouring
    // What was asked while the body was being built: edits first (they apply at the first step), then the run.
    if (organ_ && !(organ_->material == builtWith_)) postMaterial(builtWith_, organ_->material);
    postRunParameters();
    for (; pendingSteps_ > 0; --pendingSteps_) session_->stepOnce();
    if (pendingPlay_) session_->play();
    pendingPlay_ = false;
  });
  QPointer<SimulationPanel> self(this);
  precomputeCancelled_->store(false);
  if (buildDialog_) buildDialog_->deleteLater();  // an older session's build: its progress will not come
  buildDialog_.clear();
  watcher->setFuture(QtConcurrent::run([s, result, ctx, generation, record, recorder, started, self,
                                        cancelled = buildCancelled_, cache = startCache_,
                                        precompute = precomputeCancelled_, retiring = retired_] {
    try {
      if (record && retiring.valid()) retiring.wait();  // the last session's recording is complete in the file first
      simcore::BodySetup body = app::bodySetup(s);
      // A long body build (the precomputed model's responses, now or when chosen later in the Solver list) shows its
      // progress with a Cancel; it stops when a newer session is asked for too.
      body.buildProgress = [self, generation, cancelled, precompute](double done) {
        QMetaObject::invokeMethod(
            self,
            [self, done, generation] {
              if (self && self->generation_ == generation) self->showBuildProgress(done);
            },
            Qt::QueuedConnection);
        return !cancelled->load() && !precompute->load();
      };
      app::StartOptions options;
      options.inEquilibrium = s.startInEquilibrium;
      options.supportModulus = s.supportModulus;
      options.cache = cache.get();
      // The rest shape that sags into the registered one is solved in a few static solves: said on the status line
      // as they go, stopped when a newer session is asked for.
      options.progress = [self, cancelled, generation](int k, double error) {
        const QString text = tr("Solving the rest shape that sags into the registered one: static solve %1, %2 mm from it...")
                                 .arg(k)
                                 .arg(1e3 * error, 0, 'g', 3);
        QMetaObject::invokeMethod(
            self,
            [self, text, generation] {
              if (self && self->generation_ == generation) self->status_->setText(text);
            },
            Qt::QueuedConnection);
        return !cancelled->load();
      };
      app::SessionStart start = app::prepareStart(std::move(body), options);
      const QString model = QString::fromStdString(simcore::bodyModelName(start.body.model));
      switch (start.outcome) {
        case app::SessionStart::Outcome::Cancelled:
          return;
        case app::SessionStart::Outcome::NothingHolds:  // a falling organ is not a rehearsal: said, with what to change
          result->second =
              start.supportNotInModel
                  ? tr("The organ was not started: nothing holds it under gravity (the %1 model cannot stand it on "
                       "the tissue around it); hold nodes (H), choose the FEM, or turn gravity off.")
                        .arg(QString::fromStdString(simcore::bodyModelName(s.bodyModel)))
                  : tr("The organ was not started: nothing holds it under gravity; hold nodes (H), let the tissue "
                       "around it carry it (Support, on this panel), or turn gravity off.");
          return;
        case app::SessionStart::Outcome::NoEquilibrium:  // the organ would leave the frame at once: not started
          result->second = tr("The organ was not started: %1").arg(QString::fromStdString(start.rest->status));
          return;
        case app::SessionStart::Outcome::Ready:
          break;
      }
      if (start.supportNotInModel)
        *started = tr("The %1 model hangs the organ from its held nodes; the tissue around it carries it in the FEM "
                      "only. ")
                       .arg(model);
      simcore::BodySetup& b = start.body;
      if (start.start == app::SessionStart::Start::InEquilibrium)
        *started += tr("The organ starts where the frame shows it, in equilibrium under gravity on %1: %2%3")
                        .arg(b.supports.empty()      ? tr("its attachments")
                             : b.fixedNodes.empty() ? tr("the tissue around it")
                                                    : tr("its attachments and the tissue around it"))
                        .arg(QString::fromStdString(start.rest->status))
                        .arg(start.reused ? tr(" (solved for the last session, the same organ)") : QString());
      else if (start.start == app::SessionStart::Start::SagsFromShape)
        *started += tr("The organ starts at rest on the registered shape and will sag from it under gravity.");
      if (record) *recorder = std::make_shared<app::Recorder>(record->file, record->meta, b);
      ctx->organ = s.organ;
      ctx->rest = b.start.empty() ? b.rest : b.start;  // displacements from where the rehearsal starts
      ctx->tets = b.mesh.tets;
      ctx->incidence.assign(ctx->rest.size(), 0);
      for (const auto& t : ctx->tets)
        for (int v : t) ++ctx->incidence[static_cast<std::size_t>(v)];
      {
        auto supported = std::make_shared<std::vector<int>>();
        for (const auto& a : b.supports) supported->push_back(a.node);
        ctx->supports = std::move(supported);
      }
      ctx->generation = generation;
      result->first = std::make_shared<simcore::Session>(std::move(b));
    } catch (const std::exception& e) {
      result->second = QString::fromStdString(e.what());
    }
  }));
}

// -------------------------------------------------------------------------------------------- view

namespace {
// The tooltip of a field, from the scene component's declaration (the one the loader and the command line
// read): help, SI unit and default.
QString declared(const char* component, const char* parameter) {
  for (const auto& c : simcore::sceneComponents())
    if (c.type == component)
      for (const auto& p : c.parameters)
        if (p.name == parameter)
          return QStringLiteral("%1 (scene: %2.%3%4, default %5)")
              .arg(QString::fromStdString(p.help), QString::fromLatin1(component), QString::fromLatin1(parameter),
                   p.unit.empty() ? QString() : QStringLiteral(", ") + QString::fromStdString(p.unit),
                   QString::fromStdString(p.defaultValue));
  return {};
}

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
  painter.setBrush(QColor(255, 150, 40));
  for (int a : organCase.attachments)
    if (a >= 0 && static_cast<std::size_t>(a) < cam.size() && cam[a].z() > 0)
      painter.drawEllipse(project(cam[a]), 2.5, 2.5);
  // The tissue around the organ carrying it: its supported nodes, small and blue-grey (under the organ's surface,
  // where gravity presses it: seen when the view is turned), and said under the arrow.
  if (frame_->supports && !frame_->supports->empty()) {
    painter.setBrush(QColor(110, 170, 210, 200));
    for (int a : *frame_->supports)
      if (a >= 0 && static_cast<std::size_t>(a) < cam.size() && cam[a].z() > 0)
        painter.drawEllipse(project(cam[a]), 1.6, 1.6);
    painter.setPen(QColor(110, 170, 210));
    // Within the drawing area (left of the colour bar), elided where narrow; the whole sentence in the panel's status.
    // Below the gravity arrow (which reaches 30 px down), on a dark band so that the organ behind does not hide it.
    const QString text = painter.fontMetrics().elidedText(
        tr("on its supports (%n nodes)", nullptr, static_cast<int>(frame_->supports->size())), Qt::ElideRight,
        static_cast<int>(std::max(W - 24, 10.0)));
    const QRectF caption(18, 92, painter.fontMetrics().horizontalAdvance(text) + 6, 16);
    painter.fillRect(caption, QColor(24, 25, 28, 190));
    painter.drawText(caption.adjusted(3, 0, 0, 0), Qt::AlignLeft, text);
    painter.setPen(Qt::NoPen);
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
    painter.setPen(QColor(255, 120, 255));
    painter.drawText(rect().adjusted(6, 24, -80, -4), Qt::AlignLeft | Qt::AlignTop | Qt::TextWordWrap, w);
  }
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

// ------------------------------------------------------------------------------------------- panel

SimulationPanel::SimulationPanel(QWidget* parent) : QWidget(parent), startCache_(std::make_shared<app::RestShapeCache>()) {
  qRegisterMetaType<std::shared_ptr<const SimulationFrame>>();
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(4, 4, 4, 4);
  view_ = new SimulationView(this);
  view_->setObjectName(QStringLiteral("simulationView"));
  layout->addWidget(view_, 1);

  auto* form = new QFormLayout;
  form_.preset = new QComboBox(this);
  form_.preset->setObjectName(QStringLiteral("simPreset"));
  for (const char* p : {"liver", "kidney", "eye", "uterus"}) form_.preset->addItem(QString::fromLatin1(p));
  form_.preset->setToolTip(tr("Materials of the DejaVu cases, on the current organ"));
  form->addRow(tr("Preset"), form_.preset);
  form_.model = new QComboBox(this);
  form_.model->setObjectName(QStringLiteral("simMaterial"));
  form_.model->addItems({tr("linear"), tr("corotational"), tr("stvk"), tr("neohookean"), tr("neohookean-split")});
  form_.model->setToolTip(declared("material", "model"));
  form->addRow(tr("Material"), form_.model);
  // A numeric field whose help comes from the scene declaration; edits apply when the value is committed.
  auto field = [&](const char* name, const QString& label, double lo, double hi, int decimals, const QString& suffix,
                   const char* component, const char* parameter) {
    auto* f = new QDoubleSpinBox(this);
    f->setObjectName(QString::fromLatin1(name));
    f->setRange(lo, hi);
    f->setDecimals(decimals);
    f->setSuffix(suffix);
    f->setKeyboardTracking(false);
    f->setToolTip(declared(component, parameter));
    form->addRow(label, f);
    return f;
  };
  form_.young = field("simYoung", tr("Young's modulus"), 0.1, 100000, 1, tr(" kPa"), "material", "young");
  form_.poisson = field("simPoisson", tr("Poisson's ratio"), 0, 0.499, 3, QString(), "material", "poisson");
  form_.poisson->setSingleStep(0.01);
  form_.density = field("simDensity", tr("Density"), 1, 20000, 0, tr(" kg/m³"), "material", "density");
  form_.density->setToolTip(
      form_.density->toolTip() +
      tr("\nThe presets set the tissue's density (liver 1,079 kg/m³); the organ's mass follows its volume."));
  form_.mass = new QLabel(this);
  form_.mass->setObjectName(QStringLiteral("simMass"));
  // Two fields on one form row, the second named by a label between them (a row more would take room from the view).
  auto pairRow = [this, form](const QString& name, QWidget* first, const QString& between, QWidget* second) {
    auto* row = new QWidget(this);
    auto* h = new QHBoxLayout(row);
    h->setContentsMargins(0, 0, 0, 0);
    h->addWidget(first, 1);
    auto* label = new QLabel(between, row);
    label->setBuddy(second);
    h->addWidget(label);
    h->addWidget(second, 1);
    form->addRow(name, row);
  };
  // Where the tissue tears: on the jaw bite's row (the grasp slips or the tissue tears, whichever comes first; a row
  // more, or a wider one, would take room from the frame view).
  form_.tearStrain = new QDoubleSpinBox(this);
  form_.tearStrain->setObjectName(QStringLiteral("simTearStrain"));
  form_.tearStrain->setRange(0, 500);
  form_.tearStrain->setDecimals(0);
  form_.tearStrain->setSuffix(tr(" %"));
  form_.tearStrain->setKeyboardTracking(false);
  form_.tearStrain->setSpecialValueText(tr("never"));
  form_.tearStrain->setAccessibleName(tr("Tears at strain"));
  form_.tearStrain->setToolTip(
      declared("material", "tear_strain") +
      tr("\nPulled further than this, the tissue and its vessels tear (a torn vessel bleeds); the grasp slips or the "
         "tissue tears, whichever comes first. Never: it does not tear."));
  form->addRow(tr("Organ mass"), form_.mass);
  form_.timeStep = field("simTimeStep", tr("Time step"), 0.1, 100, 1, tr(" ms"), "implicit_euler", "dt");
  form_.timeStep->setValue(10);
  form_.jawBite = new QDoubleSpinBox(this);
  form_.jawBite->setAccessibleName(tr("Jaw bite"));
  form_.jawBite->setObjectName(QStringLiteral("simJawBite"));
  form_.jawBite->setRange(1, 30);
  form_.jawBite->setDecimals(1);
  form_.jawBite->setSuffix(tr(" mm"));
  form_.jawBite->setValue(6);
  form_.jawBite->setKeyboardTracking(false);
  form_.jawBite->setToolTip(
      tr("The grasper's bite: closing the jaws holds the tissue's nodes within this distance of the tip. A coarse "
         "mesh's nodes can be a centimetre apart, so a wider bite holds more of it (applies at the next grasp)"));
  pairRow(tr("Jaw bite"), form_.jawBite, tr("tears at"), form_.tearStrain);
  form_.clipLength = new QDoubleSpinBox(this);
  form_.clipLength->setObjectName(QStringLiteral("simClipLength"));
  form_.clipLength->setRange(3, 20);
  form_.clipLength->setDecimals(1);
  form_.clipLength->setSuffix(tr(" mm"));
  form_.clipLength->setValue(9);
  form_.clipLength->setKeyboardTracking(false);
  form_.clipLength->setToolTip(
      tr("The clip applier's clips: their jaws' length across the vessel. A clip shorter than the vessel (as the mesh "
         "has it: a coarse mesh makes it wider) does not close it and is counted as misplaced (applies at the next "
         "clip)"));
  form->addRow(tr("Clip length"), form_.clipLength);
  form_.method = new QComboBox(this);
  form_.method->setObjectName(QStringLiteral("simMethod"));
  // In NewtonMethod's order; chord is the default (converged every step, issue 34); linearised is faster but its one
  // solve per step is not converged (it says so: inexact above 1e-2).
  form_.method->addItems({tr("exact Newton"), tr("lagged-PCG"), tr("chord (converged)"), tr("linearised (one solve)"),
                          tr("Newton–Krylov"), tr("precomputed linear (no cuts)"), tr("hybrid (FEM where you cut)"),
                          tr("FFD surface (no cuts)")});
  form_.method->setCurrentIndex(static_cast<int>(simcore::kInteractiveMethod));
  form_.method->setToolTip(
      declared("solver", "method") + QStringLiteral("\n") +
      tr("precomputed linear: Cotin's precomputed linear elasticity instead of the FEM: the "
         "organ's static answer to the instruments by superposition of responses computed when "
         "it starts, forces at haptic rate; it cannot cut, tear, clip or burn (said when asked).\n"
         "hybrid: a FEM region where the instruments work (it grows as they move and cut) coupled "
         "to the rest's precomputed responses: the linear static answer of the whole organ; it "
         "cuts, tears, clips and burns.\n"
         "FFD surface: the surface on an 81 x 81 geometry image deformed around the grasp by a "
         "Gaussian free-form deformation, Hertz's force: geometric, no equilibrium (every step says "
         "inexact); it cannot cut, tear, clip or burn"));
  form->addRow(tr("Solver"), form_.method);
  form_.gravity = new QComboBox(this);
  form_.gravity->setObjectName(QStringLiteral("simGravity"));
  form_.gravity->addItems({tr("down in the image"), tr("into the scene"), tr("off")});
  // A laparoscope looks down into a supine patient: gravity runs mostly along the view, into the scene.
  form_.gravity->setCurrentIndex(1);
  form_.gravity->setToolTip(
      tr("Gravity in the camera frame (9.81 m/s²): the organ is simulated where the frame shows it. Into the scene "
         "(the default): a laparoscope looking down into a supine patient; down in the image: a camera looking "
         "across. Stored with the case; drawn as an arrow in the 3D view"));
  form_.support = new QDoubleSpinBox(this);
  form_.support->setObjectName(QStringLiteral("simSupport"));
  form_.support->setRange(0, 1e6);
  form_.support->setDecimals(0);
  form_.support->setSuffix(tr(" Pa/mm"));
  form_.support->setKeyboardTracking(false);
  form_.support->setSpecialValueText(tr("none"));
  form_.support->setAccessibleName(tr("Carried by the tissue around it"));
  form_.support->setToolTip(
      tr("The tissue around the organ carries it: the surface facing along gravity rests on an elastic bed of this "
         "stiffness per mm it is pressed (100 Pa/mm: a few kPa of tissue a few centimetres deep), which carries its "
         "weight where the frame shows it; the held nodes hold it too. None: only the held nodes hold it. The FEM "
         "only; a change starts the organ again."));
  form->addRow(tr("Gravity"), form_.gravity);
  form->addRow(tr("Support"), form_.support);
  connect(form_.gravity, &QComboBox::currentIndexChanged, this, &SimulationPanel::postRunParameters);
  // A stated choice of the case (saved with it, undoable) as well as a run parameter.
  connect(form_.gravity, &QComboBox::currentIndexChanged, this, &SimulationPanel::materialFieldsEdited);
  form_.start = new QCheckBox(tr("Start where the frame shows it"), this);
  form_.start->setObjectName(QStringLiteral("simStartInEquilibrium"));
  form_.start->setChecked(true);
  form_.start->setToolTip(
      tr("The organ starts on the registered shape in equilibrium under gravity, held by its attachment nodes and "
         "carried by the tissue around it (Support): its rest shape is solved first, and it stays there until an "
         "instrument acts. Off: the registered shape is its rest shape, and it sags from there."));
  form->addRow(QString(), form_.start);
  connect(form_.start, &QCheckBox::toggled, this, [this](bool on) {
    if (recordRequest_) {  // a recorded session's start is part of it: not changed under it
      const QSignalBlocker block(form_.start);
      form_.start->setChecked(!on);
      const QString why = tr("Stop the recording first: how the organ starts is part of the recorded session.");
      status_->setText(why);
      emit statusChanged(why);
      return;
    }
    if (!organ_) return;
    playing_ = false;
    pendingPlay_ = false;
    startSession(setup());  // a new session from the new start
    updateButtons();
  });
  form_.colouring = new QComboBox(this);
  form_.colouring->setObjectName(QStringLiteral("simColouring"));
  form_.colouring->addItems({tr("displacement (mm)"), tr("von Mises stress (kPa)")});
  form->addRow(tr("Colour by"), form_.colouring);

  auto* buttons = new QHBoxLayout;
  playButton_ = new QPushButton(tr("Play"), this);
  playButton_->setObjectName(QStringLiteral("simPlay"));
  playButton_->setToolTip(tr("Play or pause the simulation (F5)"));
  stepButton_ = new QPushButton(tr("Step"), this);
  stepButton_->setObjectName(QStringLiteral("simStep"));
  stepButton_->setToolTip(tr("One time step (F6)"));
  resetButton_ = new QPushButton(tr("Reset"), this);
  resetButton_->setObjectName(QStringLiteral("simReset"));
  resetButton_->setToolTip(tr("Back to the rest shape (Shift+F5)"));
  buttons->addWidget(playButton_);
  buttons->addWidget(stepButton_);
  buttons->addWidget(resetButton_);
  layout->addLayout(buttons);
  status_ = new LinesLabel(6, this);
  statusThrottle_ = std::make_unique<Throttle>(this, [this] {
    const QString text = statusText();
    status_->setText(text);
    status_->setToolTip(text);
    emit statusChanged(text);
  });
  status_->setObjectName(QStringLiteral("simStatus"));
  status_->setWordWrap(true);
  // A fixed height of six lines, the text from the top: the controls below stay put whatever the sentence's length
  // (they moved with every message); a longer one ends in an ellipsis at the sixth line (it was cut off mid-line) and
  // is whole in the tooltip. (In a scroll area of its own it cost the GUI thread 50 ms at each new sentence.)
  status_->setAlignment(Qt::AlignTop | Qt::AlignLeft);
  status_->setFixedHeight(6 * status_->fontMetrics().lineSpacing() + 4);
  layout->addWidget(status_);
  // The settings below the controls and the status: on a 900-px screen Play, Step, Reset and what the simulation says
  // stay in view without scrolling the panel (the settings, changed less often, scroll).
  layout->addLayout(form);

  connect(playButton_, &QPushButton::clicked, this, &SimulationPanel::togglePlay);
  connect(stepButton_, &QPushButton::clicked, this, &SimulationPanel::stepOnce);
  connect(resetButton_, &QPushButton::clicked, this, &SimulationPanel::reset);
  connect(form_.preset, &QComboBox::currentTextChanged, this, &SimulationPanel::applyPreset);
  connect(form_.model, &QComboBox::currentIndexChanged, this, &SimulationPanel::materialFieldsEdited);
  connect(form_.method, &QComboBox::currentIndexChanged, this, &SimulationPanel::postRunParameters);
  connect(form_.timeStep, &QDoubleSpinBox::valueChanged, this, &SimulationPanel::postRunParameters);
  connect(form_.jawBite, &QDoubleSpinBox::valueChanged, this, &SimulationPanel::postRunParameters);
  connect(form_.clipLength, &QDoubleSpinBox::valueChanged, this, &SimulationPanel::postRunParameters);
  for (QDoubleSpinBox* s : {form_.young, form_.poisson, form_.density, form_.tearStrain, form_.support})
    connect(s, &QDoubleSpinBox::valueChanged, this, &SimulationPanel::materialFieldsEdited);
  connect(form_.density, &QDoubleSpinBox::valueChanged, this, &SimulationPanel::updateMass);
  connect(form_.colouring, &QComboBox::currentIndexChanged, this, [this](int c) {
    colouring_ = c;
    if (session_) session_->setPublishStress(c == 1);  // republishes the current state coloured this way
  });
  // Plausible soft-tissue values until a case arrives with its material.
  fillMaterial(app::MaterialSettings{simcore::MaterialModel::Corotational, 27e3, 0.4, 1060});
  updateButtons();
}

SimulationPanel::~SimulationPanel() {
  ++generation_;
  buildCancelled_->store(true);
  forceLoop_.reset();
  session_.reset();  // joins the session's thread before the panel goes
  waitForRetired();
  if (recorder_) {
    try {
      recorder_->finish(recorder_->lastStep());
    } catch (...) {
    }
  }
}

QString SimulationPanel::startRecording(const QString& file, const app::SessionMeta& meta) {
  if (file.isEmpty()) return tr("Save the case to a file first (File > Save): the rehearsal is recorded into it.");
  if (!organ_ || organ_->organ->empty())
    return tr("No organ volume to rehearse on; load or tetrahedralise a mesh first.");
  // The recorder opens the file on the worker; a file it cannot write is said at once instead.
  try {
    (void)app::listRecordings(file.toStdString());
  } catch (const std::exception& e) {
    return QString::fromStdString(e.what());
  }
  const bool wasPlaying = playing_;
  recordRequest_ = RecordRequest{file.toStdString(), meta};
  startSession(setup(), recordRequest_);
  if (wasPlaying) play();
  return {};
}

void SimulationPanel::stopRecording() {
  recordRequest_.reset();
  if (recordPending_) cancelRecord_ = true;
  waitForRetired();
  if (!recorder_) return;
  if (session_) session_->setStepHook({});  // waits for the step in progress
  try {
    recorder_->finish(recorder_->lastStep());
  } catch (const std::exception& e) {
    *recorderError_ = e.what();
  }
  recorder_.reset();
}

qint64 SimulationPanel::recordingId() const { return recorder_ ? recorder_->id() : 0; }

void SimulationPanel::suspendRecording() {
  waitForRetired();  // (a session a reset ended is being marked complete in the file about to be copied)
  if (recorder_) recorder_->suspend();
}

void SimulationPanel::waitForRetired() {
  if (retired_.valid()) retired_.wait();
}

void SimulationPanel::caseFileReplaced(const QString& file) {
  if (recordRequest_) recordRequest_->file = file.toStdString();  // a reset goes on recording into the file as saved
  if (!recorder_) return;
  try {
    recorder_->reopen(file.toStdString());
  } catch (const std::exception& e) {
    *recorderError_ = e.what();
    recorderFailed_->store(true);
  }
}

SimulationSetup SimulationPanel::setup() const {
  SimulationSetup s;
  s.organ = organ_;
  if (organ_) {
    const auto& m = organ_->material;  // the case's material: what the fields show once the window applied them
    s.model = m.model;
    s.young = m.young;
    s.poisson = m.poisson;
    s.density = m.density;
    s.vesselYoung = m.vesselYoung;
    s.vesselPoisson = m.vesselPoisson;
    s.tearStrain = m.tearStrain;
    s.supportModulus = m.supportModulus;
  }
  s.timeStep = 1e-3 * form_.timeStep->value();
  s.graspRadius = 1e-3 * form_.jawBite->value();
  s.clipLength = 1e-3 * form_.clipLength->value();
  // The list's entries after the Newton methods are models: the precomputed one keeps the interactive method for
  // when the FEM is chosen again.
  const int chosen = form_.method->currentIndex();
  const int models = chosen - static_cast<int>(simcore::NewtonMethod::NewtonKrylov);  // 1 precomputed, 2 hybrid, 3 ffd
  s.method = models > 0 ? simcore::kInteractiveMethod : static_cast<simcore::NewtonMethod>(chosen);
  s.bodyModel = models > 0 ? static_cast<simcore::BodyModel>(models) : simcore::BodyModel::Fem;
  static const Eigen::Vector3d directions[] = {{0, 1, 0}, {0, 0, 1}, {0, 0, 0}};
  s.gravity = 9.81 * directions[std::clamp(form_.gravity->currentIndex(), 0, 2)];
  s.startInEquilibrium = form_.start->isChecked();
  return s;
}

void SimulationPanel::fillMaterial(const app::MaterialSettings& m) {
  filling_ = true;
  form_.model->setCurrentIndex(static_cast<int>(m.model));
  form_.young->setValue(m.young / 1e3);
  form_.poisson->setValue(m.poisson);
  form_.density->setValue(m.density);
  form_.tearStrain->setValue(100 * m.tearStrain);
  form_.support->setValue(m.supportModulus / 1e3);
  form_.gravity->setCurrentIndex(static_cast<int>(m.gravity));  // (acts on the run through postRunParameters)
  filling_ = false;
  updateMass();
}

app::MaterialSettings SimulationPanel::fieldsMaterial() const {
  app::MaterialSettings m = organ_ ? organ_->material : app::MaterialSettings{};
  // A field the user did not touch keeps the case's exact value (a field shows it rounded to its decimals).
  auto take = [](const QDoubleSpinBox* field, double caseValue, double scale) {
    const double shown = caseValue / scale;
    return std::abs(field->value() - shown) > 0.5 * std::pow(10.0, -field->decimals()) ? scale * field->value()
                                                                                       : caseValue;
  };
  m.model = static_cast<simcore::MaterialModel>(form_.model->currentIndex());
  m.young = take(form_.young, m.young, 1e3);
  m.poisson = take(form_.poisson, m.poisson, 1.0);
  m.density = take(form_.density, m.density, 1.0);
  m.tearStrain = take(form_.tearStrain, m.tearStrain, 0.01);
  m.supportModulus = take(form_.support, m.supportModulus, 1e3);
  m.gravity = static_cast<app::GravityChoice>(std::clamp(form_.gravity->currentIndex(), 0, 2));
  return m;
}

void SimulationPanel::setCase(std::shared_ptr<const app::Case> c) {
  const auto previous = organ_;
  organ_ = std::move(c);
  if (organ_) fillMaterial(organ_->material);
  const bool sameOrgan = sameBody(previous.get(), organ_.get());
  if (sameOrgan) {
    // The same organ in the same shape, place and attachments keeps running; a material edit is applied
    // at the next step boundary, keeping the state.
    // A new support is a new start (its springs are placed on the registered shape, the rest shape solved on them).
    if (previous->material.supportModulus == organ_->material.supportModulus) {
      if (!(previous->material == organ_->material)) postMaterial(previous->material, organ_->material);
      postRunParameters();  // the case's gravity (an undo, a redo): a new start or posted, as the panel's own change
      return;
    }
  }
  // A new support's start plays on if the organ was playing, as a new gravity's does (it stopped, a user's check); a
  // new organ starts paused.
  const bool playOn = sameOrgan && playing_;
  playing_ = false;
  pendingPlay_ = false;
  startSession(setup());
  if (playOn) play();
  updateButtons();
}

void SimulationPanel::postMaterial(const app::MaterialSettings& before, const app::MaterialSettings& m) {
  if (!session_) return;
  // As timestamped events through the session's mailbox (recorded with the run, like any input).
  if (m.model != before.model) session_->post(parameter("model", static_cast<double>(m.model)));
  if (m.young != before.young) session_->post(parameter("young", m.young));
  if (m.poisson != before.poisson) session_->post(parameter("poisson", m.poisson));
  if (m.density != before.density) session_->post(parameter("density", m.density));
  if (m.tearStrain != before.tearStrain) {
    session_->post(parameter("tear_strain", m.tearStrain));
    if (m.vesselYoung > 0) session_->post(parameter("tear_strain", m.tearStrain, app::kVesselLabel));
  }
  if (m.vesselYoung != before.vesselYoung || m.vesselPoisson != before.vesselPoisson) {
    session_->post(parameter("young", m.vesselYoung, app::kVesselLabel));
    if (m.vesselYoung > 0) session_->post(parameter("poisson", m.vesselPoisson, app::kVesselLabel));
  }
}

void SimulationPanel::applyPreset(const QString& name) {
  if (!organ_ || organ_->organ->empty()) return;
  try {
    emit materialEdited(app::presetMaterial(name.toStdString(), *organ_->organ));
  } catch (const std::exception& e) {
    onFailed(QString::fromStdString(e.what()));
  }
}

void SimulationPanel::updateMass() {
  const double volume =
      organ_ && !organ_->organ->empty() ? organ_->organ->quality.volume : 0.0;  // m^3, as the case panel shows it
  form_.mass->setText(volume > 0 ? tr("%1 g (%2 cm³ x density)")
                                       .arg(volume * form_.density->value() * 1e3, 0, 'f', 0)
                                       .arg(volume * 1e6, 0, 'f', 1)
                                 : tr("no volume mesh"));
}

void SimulationPanel::materialFieldsEdited() {
  if (filling_ || !organ_) return;
  // The material belongs to the case (the fit uses it too): an undoable edit, applied back through setCase.
  const app::MaterialSettings m = fieldsMaterial();
  if (!(m == organ_->material)) emit materialEdited(m);
}

void SimulationPanel::postRunParameters() {
  // Run parameters (time step, solver, gravity): events applied at the next step boundary, keeping the state; each
  // compared with what was last asked (the session's own setup lags until that boundary).
  if (filling_) return;  // a case's fields being shown: setCase acts on them once shown
  if (!session_) {
    // The organ was not started (no equilibrium where the frame shows it, nothing holding it): what the assistant
    // changes on the panel is tried at once.
    if (startRefused_ && organ_) {
      startSession(setup());
      updateButtons();
    }
    return;
  }
  const SimulationSetup s = setup();
  if (s.timeStep != asked_.timeStep) session_->post(parameter("dt", asked_.timeStep = s.timeStep));
  if (s.graspRadius != asked_.graspRadius)
    session_->post(parameter("grasp_radius", asked_.graspRadius = s.graspRadius));
  if (s.clipLength != asked_.clipLength) session_->post(parameter("clip_length", asked_.clipLength = s.clipLength));
  if (s.bodyModel != asked_.model) {
    asked_.model = s.bodyModel;
    precomputeCancelled_->store(false);
    session_->post(parameter("body_model", static_cast<double>(s.bodyModel)));  // the enum's order
  }
  if (s.bodyModel == simcore::BodyModel::Fem && s.method != asked_.method) {
    asked_.method = s.method;
    session_->post(parameter("method", static_cast<double>(s.method)));
  }
  // (What the session ran is read from its last frame: its setup belongs to the stepping thread.)
  const bool cut = last_ && last_->surface;
  if (s.gravity != asked_.gravity && !recordRequest_ && s.startInEquilibrium && !cut) {
    // The start (and the supports) are solved for the gravity they were placed for: another gravity is a new start,
    // solved for it, as long as nothing was cut (then it acts on the running organ). Posted to the running organ, it
    // sagged 5 mm while the panel still said it started in equilibrium (a user's check).
    const bool wasPlaying = playing_;
    playing_ = false;
    pendingPlay_ = false;
    startSession(s);
    if (wasPlaying) play();
    updateButtons();
    return;
  }
  if (s.gravity != asked_.gravity) {
    simcore::InputEvent g;
    g.kind = simcore::InputKind::Gravity;
    g.vector = asked_.gravity = s.gravity;
    session_->post(g);
  }
}

bool SimulationPanel::post(simcore::InputEvent e) {
  if (!session_) return false;
  if (e.kind == simcore::InputKind::ToolPose) device_.setPosition(e.position);
  session_->post(std::move(e));
  if (!playing_) play();
  return true;
}

void SimulationPanel::play() {
  if (!organ_) return;
  if (!session_ && startRefused_) {  // nothing runs until a setting lets it start: Play does not pretend it plays
    updateButtons();
    return;
  }
  playing_ = true;
  error_.clear();
  rate_.clock.start();
  rate_.frames = 0;
  if (session_)
    session_->play();
  else
    pendingPlay_ = true;
  updateButtons();
}

void SimulationPanel::pause() {
  playing_ = false;
  pendingPlay_ = false;
  if (session_) session_->pause();
  updateButtons();
}

void SimulationPanel::togglePlay() { playing_ ? pause() : play(); }

void SimulationPanel::stepOnce() {
  if (!organ_) return;
  playing_ = false;
  error_.clear();
  if (session_)
    session_->stepOnce();
  else
    ++pendingSteps_;  // the body is still being built: the step runs when it is ready
  updateButtons();
}

void SimulationPanel::reset() {
  playing_ = false;
  pendingPlay_ = false;
  pendingSteps_ = 0;
  error_.clear();
  if (recordRequest_ && (recorder_ || recordPending_)) {
    // A recorded session's steps only go forwards: the run from rest is another session (the one recorded so far
    // ends complete where it was; both replay and verify).
    const qint64 ended = recordingId();
    const long at = recorder_ ? recorder_->lastStep() : 0;
    if (recordPending_) cancelRecord_ = true;
    startSession(setup(), recordRequest_);
    emit recordingRestarted(
        ended > 0 ? tr("Reset: recorded session %1 ended at step %2; the run from rest is recorded as a new session.")
                        .arg(ended)
                        .arg(at)
                  : tr("Reset: the run from rest is recorded as a new session."));
  } else if (session_) {
    session_->reset();
  }
  updateButtons();
}

void SimulationPanel::onFrame(std::shared_ptr<const SimulationFrame> f) {
  last_ = f;
  if (asked_.model != f->model && f->message.contains(u"refused")) {
    // The model asked for was refused or its build cancelled: the list shows what runs.
    asked_.model = f->model;
    form_.method->setCurrentIndex(f->model == simcore::BodyModel::Fem
                                      ? static_cast<int>(asked_.method)
                                      : static_cast<int>(simcore::NewtonMethod::NewtonKrylov) +
                                            static_cast<int>(f->model));
  }
  view_->setFrame(f);
  if (recorder_ && recorderFailed_->load()) {
    const QString why = QString::fromStdString(*recorderError_);
    stopRecording();
    emit recordingStopped(tr("The recording stopped (what was recorded is kept): %1").arg(why));
  }
  if (!f->report.ok && f->steps > 0) {
    playing_ = false;  // the worker stopped on a failed step
    updateButtons();
  }
  ++rate_.frames;
  if (rate_.clock.isValid() && rate_.clock.elapsed() > 500) {
    rate_.fps = 1e3 * rate_.frames / static_cast<double>(rate_.clock.elapsed());
    rate_.clock.restart();
    rate_.frames = 0;
  }
  statusThrottle_->request();  // the status line at most 15 times a second, the newest always shown
  emit frameShown(f->steps);
}

void SimulationPanel::showBuildProgress(double done) {
  // Batches that ended after Cancel still report: the dialog does not come back for them.
  if (done >= 1 || precomputeCancelled_->load()) {
    if (buildDialog_) buildDialog_->deleteLater();
    buildDialog_.clear();
    return;
  }
  if (!buildDialog_) {
    const bool ffd = asked_.model == simcore::BodyModel::Ffd;
    buildDialog_ = new QProgressDialog(ffd ? tr("Mapping the organ's surface onto the FFD model's geometry image...")
                                           : tr("Computing the precomputed model's responses to each surface node..."),
                                       tr("Cancel"), 0, 1000, this);
    buildDialog_->setObjectName(QStringLiteral("precomputeProgress"));
    buildDialog_->setWindowTitle(ffd ? tr("FFD model") : tr("Precomputed model"));
    buildDialog_->setWindowModality(Qt::WindowModal);
    buildDialog_->setMinimumDuration(400);
    buildDialog_->setAutoClose(false);
    buildDialog_->setAutoReset(false);
    connect(buildDialog_, &QProgressDialog::canceled, this, [this, flag = precomputeCancelled_] {
      flag->store(true);  // the build stops after its current batch; the session says so and keeps the model it had
      if (buildDialog_) buildDialog_->deleteLater();
      buildDialog_.clear();
    });
  }
  buildDialog_->setValue(static_cast<int>(1000 * std::clamp(done, 0.0, 1.0)));
}

void SimulationPanel::onFailed(const QString& message) {
  playing_ = false;
  error_ = message;
  status_->setText(message);
  emit statusChanged(tr("Simulation: %1").arg(message));
  updateButtons();
}

QString SimulationPanel::statusText() const {
  if (!error_.isEmpty()) return error_;
  if (!last_) return tr("Simulation ready");
  const auto& r = last_->report;
  // An imported organ has no ligament nodes: it falls only where nothing else carries it (no support, gravity on).
  const bool loose = organ_ && organ_->attachments.empty() && !(last_->supports && !last_->supports->empty()) &&
                     last_->gravity.norm() > 0;
  if (last_->steps == 0)
    return !startWord_.isEmpty() ? tr("t = 0. %1").arg(startWord_)
           : loose ? tr("Simulation at rest (t = 0). Nothing holds this organ (no attachment nodes, no support): it "
                        "will fall under gravity.")
                   : tr("Simulation at rest (t = 0)");
  if (!last_->message.isEmpty()) return last_->message;
  const QString rate = playing_ ? tr(" · %1 fps").arg(rate_.fps, 0, 'f', 0) : QString();
  // The fast models do no Newton iteration: their name instead (the model that ran the step).
  const QString solver = last_->model == simcore::BodyModel::Precomputed ? tr("precomputed linear")
                         : last_->model == simcore::BodyModel::Hybrid    ? tr("hybrid")
                         : last_->model == simcore::BodyModel::Ffd       ? tr("FFD")
                         : r.newtonIterations == 1                       ? tr("1 Newton iteration")
                                                                         : tr("%1 Newton iterations").arg(r.newtonIterations);
  return tr("t = %1 s · step %2 ms%3 · %4 · %5")
      .arg(last_->time, 0, 'f', 2)
      .arg(r.wallMs, 0, 'f', 1)
      .arg(rate)
      .arg(solver)
      .arg(QString::fromStdString(simcore::statusSentence(r)));
}

void SimulationPanel::updateButtons() {
  playButton_->setText(playing_ ? tr("Pause") : tr("Play"));
  const bool have = organ_ && !organ_->organ->empty();
  playButton_->setEnabled(have);
  stepButton_->setEnabled(have);
  resetButton_->setEnabled(have);
}

}  // namespace rehearse::ui
