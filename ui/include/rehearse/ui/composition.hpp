#pragma once
// The composited view's engine (step 6 on): the case's organ re-shaded with its estimated appearance over
// the frame's inpainted background, as the frame view shows it from then on. It keeps the layers the
// estimate needs (I_D, I_B, the albedo; made by the appearance step, or remade on a worker when a case
// is opened) and an imaging::Compositor, and composes a deformed shape (a simulation snapshot) on a
// worker, the newest request winning, so the GUI never waits for it. No case state lives here.
#include <rehearse/app/appearancestep.hpp>

#include <QFutureWatcher>
#include <QImage>
#include <QObject>

#include <memory>
#include <mutex>
#include <optional>
#include <vector>

namespace rehearse::ui {

class GLCompositor;

class Composition : public QObject {
  Q_OBJECT
 public:
  explicit Composition(QObject* parent = nullptr);
  ~Composition() override;

  /// Follows the case: with a current estimate whose layers are not here, remakes them on a worker (then
  /// readyChanged(true)); without one, drops them (readyChanged(false)).
  void setCase(std::shared_ptr<const app::Case> c);
  /// The layers the appearance step has just made for `estimate`: used, instead of remade, when the case
  /// holding that estimate arrives through setCase.
  void offer(std::shared_ptr<const app::AppearanceEstimate> estimate, app::AppearanceLayers layers);
  bool ready() const { return compositor_ != nullptr; }
  /// Composes with OpenGL (GLCompositor, on this thread) when a hardware context can be made (or any
  /// context, with `evenInSoftware`: under llvmpipe the CPU compositor on a worker is faster and keeps the
  /// GUI thread free, bench_gl_compose); else with the CPU compositor on a worker. Call before the first case.
  void useOpenGL(bool on, bool evenInSoftware = false);
  /// True when the composited view is drawn by OpenGL now.
  bool usesOpenGL() const { return gl_ != nullptr && glPrepared_; }
  /// Composes the organ with its volume nodes at `cameraPositions` (camera frame, metres, volume node order;
  /// empty: the case's shape at rest) on a worker; emits composed(J). A request made while one runs
  /// replaces any waiting one.
  /// With `cut` (a snapshot's boundary after cuts), the positions are the cut mesh's nodes: the cut organ is
  /// composited, its cut faces in preset interior colours (app::makeCutCompositor, made once per cut surface).
  void request(std::vector<Eigen::Vector3d> cameraPositions = {},
               std::shared_ptr<const simcore::CutSurface> cut = nullptr);
  /// The same on this thread (tests, screenshots); a null image when not ready.
  QImage composeNow(const std::vector<Eigen::Vector3d>& cameraPositions = {},
                    const std::shared_ptr<const simcore::CutSurface>& cut = nullptr) const;
  /// Once a cut organ was composited: which colours its cut faces take (empty before).
  QString cutSentence() const;
  QImage diffuseImage() const { return diffuse_; }
  QImage backgroundImage() const { return background_; }
  QImage residualImage() const { return residual_; }  ///< what Theta leaves of the frame on the organ (x 3)
  QImage lastComposed() const { return last_; }
  /// lastComposed() scaled smoothly to the size setViewScale asked when it was requested (null when none was asked, or
  /// composed with OpenGL): the frame view draws it as it is (FrameView::setFrame(frame, scaled)).
  QImage lastScaled() const { return lastScaled_; }
  /// The size the composited view draws a frame at (FrameView::frameSizeInView): each composition the worker makes
  /// from now on is scaled to it there too, off the GUI thread. Empty: none.
  void setViewScale(QSize size) { viewScale_ = size; }
  /// Why there is no composited view (empty when ready): a sentence for the status bar.
  QString whyNot() const { return whyNot_; }
  /// Waits for the worker and for what its results start (tests): the view then shows the newest composition.
  void waitForIdle();

 signals:
  void readyChanged(bool ready);
  void composed(const QImage& j);

 private:
  struct Prepared;
  /// The compositor of the last cut surface composited (made on the worker, kept until the next cut or estimate).
  struct CutCache {
    mutable std::mutex mutex;
    std::shared_ptr<const simcore::CutSurface> surface;
    std::shared_ptr<const imaging::Compositor> compositor;
    std::string said;
  };
  /// J for `cameraPositions` (empty: at rest), of the cut organ when `cut` is given; null when it cannot be made.
  /// A composition and its copy at the view's scale.
  struct Composed {
    QImage image, scaled;
  };
  static QImage composeWith(const std::shared_ptr<const imaging::Compositor>& compositor,
                            const std::shared_ptr<const app::Case>& c, const std::shared_ptr<CutCache>& cache,
                            const Pose& pose, const std::vector<Eigen::Vector3d>& cameraPositions,
                            const std::shared_ptr<const simcore::CutSurface>& cut);
  void install(const std::shared_ptr<const app::Case>& c, const app::AppearanceLayers& layers, std::unique_ptr<imaging::Compositor> compositor);
  void startNext();
  static std::vector<double> modelVertices(const app::Case* c, const Pose& pose,
                                           const std::vector<Eigen::Vector3d>& cameraPositions, bool cut);

  std::shared_ptr<const app::AppearanceEstimate> estimate_;  ///< the estimate the layers belong to
  std::shared_ptr<const app::Case> case_;
  std::shared_ptr<const imaging::Compositor> compositor_;
  QImage diffuse_, background_, residual_, last_, lastScaled_;
  QSize viewScale_;
  QString whyNot_;
  QFutureWatcher<std::shared_ptr<Prepared>> prepareWatcher_;
  std::shared_ptr<const app::AppearanceEstimate> preparing_;
  QFutureWatcher<Composed> composeWatcher_;
  bool composing_ = false;  ///< a composition job started whose finish handler has not run yet
  std::optional<std::vector<Eigen::Vector3d>> waiting_;
  std::shared_ptr<const simcore::CutSurface> waitingCut_;
  std::shared_ptr<CutCache> cutCache_ = std::make_shared<CutCache>();
  std::unique_ptr<GLCompositor> gl_;
  bool glPrepared_ = false;
  bool glPending_ = false;  ///< a GL composition is queued on this thread's event loop
  std::shared_ptr<const app::AppearanceEstimate> offered_;
  app::AppearanceLayers offeredLayers_;
};

}  // namespace rehearse::ui
