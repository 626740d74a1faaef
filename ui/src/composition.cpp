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
  connect(&composeWatcher_, &QFutureWatcher<QImage>::finished, this, [this] {
    const QImage j = composeWatcher_.result();
    if (!j.isNull() && compositor_) {
      last_ = j;
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
  while (prepareWatcher_.isRunning() || composeWatcher_.isRunning() || waiting_ || glPending_) {
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
    diffuse_ = background_ = residual_ = last_ = QImage();
    waiting_.reset();
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
      install(case_, layers, app::makeCompositor(app::appearanceInputFromCase(*case_), layers, case_->appearance->theta, case_->appearance->textureOnly));
      return;
    } catch (const std::exception& e) {
      whyNot_ = tr("the appearance could not be applied: %1").arg(QString::fromUtf8(e.what()));
      return;
    }
  }
  whyNot_ = tr("the appearance is being applied...");
  if (prepareWatcher_.isRunning()) return;  // its finish handler looks at the case again
  preparing_ = case_->appearance;
  prepareWatcher_.setFuture(QtConcurrent::run([c = case_]() {
    auto p = std::make_shared<Prepared>();
    p->estimate = c->appearance;
    try {
      app::AppearanceInput in = app::appearanceInputFromCase(*c);
      in.inpaint = imaging::parseInpaintMethod(p->estimate->inpaint);
      p->layers = app::appearanceLayers(in, p->estimate->theta);
      p->compositor = app::makeCompositor(in, p->layers, p->estimate->theta, p->estimate->textureOnly);
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
  glPrepared_ = false;
  if (gl_) {
    const app::AppearanceInput in = app::appearanceInputFromCase(*c);
    glPrepared_ = gl_->prepare(app::compositionInput(in, layers, c->appearance->theta, c->appearance->textureOnly));  // false: the CPU compositor draws instead
  }
  diffuse_ = frameToQImage(layers.diffuse);
  background_ = frameToQImage(layers.background);
  residual_ = layers.residual.empty() ? QImage() : frameToQImage(layers.residual);
  whyNot_.clear();
  last_ = composeNow();
  emit readyChanged(true);
  emit composed(last_);
}

std::vector<double> Composition::modelVertices(const std::vector<Eigen::Vector3d>& cameraPositions) const {
  std::vector<double> v;
  if (cameraPositions.empty() || !estimate_) return v;
  const Eigen::Matrix3d Rt = estimate_->pose.R.transpose();
  std::vector<Eigen::Vector3d> model(cameraPositions.size());
  for (std::size_t i = 0; i < model.size(); ++i) model[i] = Rt * (cameraPositions[i] - estimate_->pose.t);
  // The organ's own surface, carried by the volume's nodes (the compositor was made with it); a volume of
  // another node count (after a cut) gives an empty list, which the compositor refuses.
  if (case_ && case_->organ->visual) {
    model = case_->organ->visual->map(model);
    if (model.empty()) v.push_back(0);  // not the compositor's mesh: refused below, nothing drawn
  }
  v.reserve(3 * model.size());
  for (const auto& m : model) v.insert(v.end(), {m.x(), m.y(), m.z()});
  return v;
}

QImage Composition::composeNow(const std::vector<Eigen::Vector3d>& cameraPositions) const {
  if (!compositor_) return {};
  if (usesOpenGL()) {
    QImage j;
    if (gl_->compose(modelVertices(cameraPositions), j, 4)) return j;
  }
  try {
    return frameToQImage(compositor_->compose(modelVertices(cameraPositions), 2));
  } catch (const std::exception&) {
    return {};  // a snapshot of another mesh (the organ was replaced meanwhile): nothing to show
  }
}

void Composition::request(std::vector<Eigen::Vector3d> cameraPositions) {
  if (!ready()) return;
  waiting_ = std::move(cameraPositions);
  if (usesOpenGL()) {
    // On this thread (the context's), once the events queued now are handled: the newest request wins.
    if (!glPending_) {
      glPending_ = true;
      QTimer::singleShot(0, this, [this] {
        glPending_ = false;
        if (!waiting_ || !compositor_) return;
        const std::vector<Eigen::Vector3d> positions = std::move(*waiting_);
        waiting_.reset();
        const QImage j = composeNow(positions);
        if (!j.isNull()) {
          last_ = j;
          emit composed(last_);
        }
      });
    }
    return;
  }
  if (!composeWatcher_.isRunning()) startNext();
}

void Composition::startNext() {
  if (!waiting_ || !compositor_) {
    waiting_.reset();
    return;
  }
  std::vector<double> vertices = modelVertices(*waiting_);
  waiting_.reset();
  composeWatcher_.setFuture(QtConcurrent::run([compositor = compositor_, vertices = std::move(vertices)]() -> QImage {
    try {
      return frameToQImage(compositor->compose(vertices, 2));
    } catch (const std::exception&) {
      return {};
    }
  }));
}

}  // namespace rehearse::ui
