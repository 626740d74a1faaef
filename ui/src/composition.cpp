#include "rehearse/ui/composition.hpp"

#include "rehearse/ui/casedocument.hpp"
#include "rehearse/ui/glcompositor.hpp"

#include <QTimer>

#include <QtConcurrent/QtConcurrent>

namespace rehearse::ui {

struct Composition::Prepared {
  std::shared_ptr<const app::AppearanceEstimate> estimate;
  app::AppearanceLayers layers;
  std::unique_ptr<imaging::Compositor> compositor;
  QString error;
};

Composition::Composition(QObject* parent) : QObject(parent) {
  whyNot_ = tr("no appearance estimated yet (step 6)");
  connect(&prepareWatcher_, &QFutureWatcher<std::shared_ptr<Prepared>>::finished, this, [this] {
    const auto p = prepareWatcher_.result();
    preparing_.reset();
    if (case_ && p && case_->appearance == p->estimate && case_->appearanceCurrent()) {
      if (p->compositor) install(case_, p->layers, std::move(p->compositor));
      else {
        whyNot_ = tr("the appearance could not be applied: %1").arg(p->error);
        emit readyChanged(false);
      }
    } else {
      setCase(case_);  // the case moved on while the layers were made
    }
  });
  connect(&composeWatcher_, &QFutureWatcher<Composed>::finished, this, [this] {
    composing_ = false;
    const Composed j = composeWatcher_.result();
    if (!j.image.isNull() && compositor_) {
      last_ = j.image;
      lastScaled_ = j.scaled;
      emit composed(last_);
    }
    startNext();
  });
}

Composition::~Composition() {
  prepareWatcher_.waitForFinished();
  composeWatcher_.waitForFinished();
}

void Composition::useOpenGL(bool on, bool evenInSoftware) {
  gl_.reset();
  glPrepared_ = false;
  if (!on) return;
  gl_ = std::make_unique<GLCompositor>();
  if (!gl_->valid() || (gl_->softwareRenderer() && !evenInSoftware)) gl_.reset();
}

void Composition::waitForIdle() {
  // Until the finish handlers have run, not only until the jobs have finished: a watcher's finished signal comes as a
  // posted event, after isRunning() already says false (a test that read the view then saw the composition before).
  while (preparing_ || composing_ || waiting_ || glPending_) {
    prepareWatcher_.waitForFinished();
    composeWatcher_.waitForFinished();
    QCoreApplication::processEvents();  // the finish handlers run here (and may start the waiting request)
  }
}

void Composition::setCase(std::shared_ptr<const app::Case> c) {
  case_ = std::move(c);
  const bool wasReady = ready();
  auto drop = [&](const QString& why) {
    compositor_.reset();
    glPrepared_ = false;
    estimate_.reset();
    diffuse_ = background_ = residual_ = last_ = lastScaled_ = QImage();
    waiting_.reset();
    waitingCut_.reset();
    whyNot_ = why;
    if (wasReady) emit readyChanged(false);
  };
  if (!case_ || !case_->appearance) return drop(tr("no appearance estimated yet (step 6)"));
  if (!case_->appearanceCurrent())
    return drop(tr("the appearance was estimated at another pose, shape or frame; estimate it again (step 6, F10)"));
  if (ready() && estimate_ == case_->appearance) return;
  if (ready()) drop(tr("the appearance is being applied..."));
  if (offered_ && offered_ == case_->appearance) {  // the step's own layers: no remaking
    const app::AppearanceLayers layers = std::move(offeredLayers_);
    offered_.reset();
    offeredLayers_ = {};
    try {
      install(case_, layers, app::makeCompositor(app::appearanceInputFromCase(*case_), layers, case_->appearance->theta, case_->appearance->reshading()));
      return;
    } catch (const std::exception& e) {
      whyNot_ = tr("the appearance could not be applied: %1").arg(QString::fromUtf8(e.what()));
      return;
    }
  }
  whyNot_ = tr("the appearance is being applied...");
  if (preparing_) return;  // its finish handler (not run yet) looks at the case again
  preparing_ = case_->appearance;
  prepareWatcher_.setFuture(QtConcurrent::run([c = case_]() {
    auto p = std::make_shared<Prepared>();
    p->estimate = c->appearance;
    try {
      app::AppearanceInput in = app::appearanceInputFromCase(*c);
      in.inpaint = imaging::parseInpaintMethod(p->estimate->inpaint);
      p->layers = app::appearanceLayers(in, p->estimate->theta);
      p->compositor = app::makeCompositor(in, p->layers, p->estimate->theta, p->estimate->reshading());
    } catch (const std::exception& e) {
      p->error = QString::fromUtf8(e.what());
    }
    return p;
  }));
}

void Composition::offer(std::shared_ptr<const app::AppearanceEstimate> estimate, app::AppearanceLayers layers) {
  offered_ = std::move(estimate);
  offeredLayers_ = std::move(layers);
}

void Composition::install(const std::shared_ptr<const app::Case>& c, const app::AppearanceLayers& layers, std::unique_ptr<imaging::Compositor> compositor) {
  estimate_ = c->appearance;
  compositor_ = std::move(compositor);
  cutCache_ = std::make_shared<CutCache>();  // a running job keeps its own
  glPrepared_ = false;
  if (gl_) {
    const app::AppearanceInput in = app::appearanceInputFromCase(*c);
    glPrepared_ = gl_->prepare(app::compositionInput(in, layers, c->appearance->theta, c->appearance->reshading()));  // false: the CPU compositor draws instead
  }
  diffuse_ = frameToQImage(layers.diffuse);
  background_ = frameToQImage(layers.background);
  residual_ = layers.residual.empty() ? QImage() : frameToQImage(layers.residual);
  whyNot_.clear();
  last_ = composeNow();
  lastScaled_ = QImage();
  emit readyChanged(true);
  emit composed(last_);
}

std::vector<double> Composition::modelVertices(const app::Case* c, const Pose& pose,
                                               const std::vector<Eigen::Vector3d>& cameraPositions, bool cut) {
  std::vector<double> v;
  if (cameraPositions.empty()) return v;
  const Eigen::Matrix3d Rt = pose.R.transpose();
  std::vector<Eigen::Vector3d> model(cameraPositions.size());
  for (std::size_t i = 0; i < model.size(); ++i) model[i] = Rt * (cameraPositions[i] - pose.t);
  // The organ's own surface, carried by the volume's nodes (the compositor was made with it); a volume of
  // another node count gives an empty list, which the compositor refuses. A cut organ is drawn through its
  // cut mesh's boundary (the positions are that mesh's nodes).
  if (!cut && c && c->organ->visual) {
    model = c->organ->visual->map(model);
    if (model.empty()) v.push_back(0);  // not the compositor's mesh: refused below, nothing drawn
  }
  v.reserve(3 * model.size());
  for (const auto& m : model) v.insert(v.end(), {m.x(), m.y(), m.z()});
  return v;
}

QImage Composition::composeWith(const std::shared_ptr<const imaging::Compositor>& compositor,
                                const std::shared_ptr<const app::Case>& c, const std::shared_ptr<CutCache>& cache,
                                const Pose& pose, const std::vector<Eigen::Vector3d>& cameraPositions,
                                const std::shared_ptr<const simcore::CutSurface>& cut) {
  if (!compositor) return {};
  try {
    std::shared_ptr<const imaging::Compositor> use = compositor;
    if (cut) {
      if (!c) return {};
      std::lock_guard<std::mutex> lock(cache->mutex);
      if (cache->surface != cut) {
        app::CutComposition made = app::makeCutCompositor(*compositor, *c, *cut);
        cache->compositor = std::move(made.compositor);
        cache->surface = cut;
        cache->said = made.said;
      }
      use = cache->compositor;
    }
    return frameToQImage(use->compose(modelVertices(c.get(), pose, cameraPositions, cut != nullptr), 2));
  } catch (const std::exception&) {
    return {};  // a snapshot of another mesh (the organ was replaced meanwhile): nothing to show
  }
}

QString Composition::cutSentence() const {
  std::lock_guard<std::mutex> lock(cutCache_->mutex);
  return QString::fromStdString(cutCache_->said);
}

QImage Composition::composeNow(const std::vector<Eigen::Vector3d>& cameraPositions,
                               const std::shared_ptr<const simcore::CutSurface>& cut) const {
  if (!compositor_ || !estimate_) return {};
  if (usesOpenGL() && !cut) {
    QImage j;
    if (gl_->compose(modelVertices(case_.get(), estimate_->pose, cameraPositions, false), j, 4)) return j;
  }
  return composeWith(compositor_, case_, cutCache_, estimate_->pose, cameraPositions, cut);
}

void Composition::request(std::vector<Eigen::Vector3d> cameraPositions,
                          std::shared_ptr<const simcore::CutSurface> cut) {
  if (!ready()) return;
  waiting_ = std::move(cameraPositions);
  waitingCut_ = std::move(cut);
  if (usesOpenGL() && !waitingCut_) {
    // On this thread (the context's), once the events queued now are handled: the newest request wins.
    if (!glPending_) {
      glPending_ = true;
      QTimer::singleShot(0, this, [this] {
        glPending_ = false;
        if (!waiting_ || !compositor_) return;
        const std::vector<Eigen::Vector3d> positions = std::move(*waiting_);
        const auto cut = std::move(waitingCut_);
        waiting_.reset();
        waitingCut_.reset();
        const QImage j = composeNow(positions, cut);
        if (!j.isNull()) {
          last_ = j;
          lastScaled_ = QImage();
          emit composed(last_);
        }
      });
    }
    return;
  }
  if (!composing_) startNext();  // else the finish handler starts it
}

void Composition::startNext() {
  if (!waiting_ || !compositor_ || !estimate_) {
    waiting_.reset();
    waitingCut_.reset();
    return;
  }
  std::vector<Eigen::Vector3d> positions = std::move(*waiting_);
  auto cut = std::move(waitingCut_);
  waiting_.reset();
  waitingCut_.reset();
  composing_ = true;
  composeWatcher_.setFuture(QtConcurrent::run([compositor = compositor_, c = case_, cache = cutCache_,
                                                pose = estimate_->pose, positions = std::move(positions),
                                                cut = std::move(cut), scale = viewScale_]() -> Composed {
    Composed j{composeWith(compositor, c, cache, pose, positions, cut), {}};
    // The view's copy, as FrameView::scaleFrame makes it: scaling each new frame on the GUI thread paused the window.
    if (!j.image.isNull() && !scale.isEmpty())
      j.scaled = j.image.scaled(scale, Qt::IgnoreAspectRatio, Qt::SmoothTransformation);
    return j;
  }));
}

}  // namespace rehearse::ui
