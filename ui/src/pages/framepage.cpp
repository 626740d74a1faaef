#include "rehearse/ui/pages/framepage.hpp"

#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QFutureWatcher>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QSettings>
#include <QSlider>
#include <QSpinBox>
#include <QToolButton>
#include <QVBoxLayout>

#include <optional>
#include <QtConcurrent/QtConcurrent>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

namespace rehearse::ui {

FramePage::FramePage(Workbench& wb, QWidget* parent) : StepPage(wb, app::Step::Frame, parent) {
  auto* l = new QVBoxLayout(this);
  auto* open = new QPushButton(tr("Open Image or Video... (Ctrl+F)"), this);
  open->setMinimumHeight(36);
  connect(open, &QPushButton::clicked, this, &FramePage::openFrameDialog);
  l->addWidget(open);
  auto* cam = new QHBoxLayout;
  auto* device = new QSpinBox(this);
  device->setAccessibleName(tr("Camera device number"));
  device->setRange(0, 9);
  auto* openDevice = new QPushButton(tr("Live Camera"), this);
  connect(openDevice, &QPushButton::clicked, this, [this, device] { openCameraDevice(device->value()); });
  cam->addWidget(new QLabel(tr("Device"), this));
  cam->addWidget(device);
  cam->addWidget(openDevice, 1);
  l->addLayout(cam);
  auto* videoBox = new QGroupBox(tr("Video"), this);
  auto* vl = new QVBoxLayout(videoBox);
  videoSlider_ = new QSlider(Qt::Horizontal, videoBox);
  videoSlider_->setObjectName(QStringLiteral("videoSlider"));
  videoSlider_->setEnabled(false);
  connect(videoSlider_, &QSlider::valueChanged, this, [this](int v) {
    if (!updating_) showVideoFrame(v);
  });
  vl->addWidget(videoSlider_);
  auto* row = new QHBoxLayout;
  auto* prev = new QToolButton(videoBox);
  prev->setText(QStringLiteral("<"));
  prev->setToolTip(tr("Previous frame (,)"));
  prev->setShortcut(QKeySequence(Qt::Key_Comma));
  connect(prev, &QToolButton::clicked, this, [this] { if (videoFrames_ > 0) showVideoFrame(std::max(0, shownVideoFrame_ - 1)); });
  auto* next = new QToolButton(videoBox);
  next->setText(QStringLiteral(">"));
  next->setToolTip(tr("Next frame (.)"));
  next->setShortcut(QKeySequence(Qt::Key_Period));
  connect(next, &QToolButton::clicked, this, [this] { if (videoFrames_ > 0) showVideoFrame(std::min(videoFrames_ - 1, shownVideoFrame_ + 1)); });
  videoLabel_ = new QLabel(tr("no video"), videoBox);
  row->addWidget(prev);
  row->addWidget(videoLabel_, 1);
  row->addWidget(next);
  vl->addLayout(row);
  useFrameButton_ = new QPushButton(tr("Use This Frame (Ctrl+Return)"), videoBox);
  useFrameButton_->setEnabled(false);
  useFrameButton_->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_Return));
  connect(useFrameButton_, &QPushButton::clicked, this, &FramePage::useShownFrame);
  vl->addWidget(useFrameButton_);
  // A second frame (issue 38): the scope moved 1-2 cm sideways; its outline (step 3) and the motion estimated from the
  // frames give the fit the depth one outline cannot.
  auto* secondBox = new QGroupBox(tr("Second frame (the scope moved)"), this);
  auto* sl = new QVBoxLayout(secondBox);
  secondLabel_ = new QLabel(secondBox);
  secondLabel_->setObjectName(QStringLiteral("secondFrameLabel"));
  secondLabel_->setWordWrap(true);
  sl->addWidget(secondLabel_);
  auto* secondRow = new QHBoxLayout;
  auto* useSecond = new QPushButton(tr("Use Shown Video Frame"), secondBox);
  useSecond->setObjectName(QStringLiteral("useSecondFrame"));
  useSecond->setToolTip(tr("The video frame shown above, with the scope moved 1-2 cm sideways from the first frame"));
  connect(useSecond, &QPushButton::clicked, this, &FramePage::useShownFrameAsSecond);
  auto* openSecond = new QPushButton(tr("Open Image..."), secondBox);
  connect(openSecond, &QPushButton::clicked, this, [this] {
    const QString p =
        QFileDialog::getOpenFileName(wb_.window, tr("Open Second Frame"), dialogFolder(),
                                     tr("Images (*.png *.jpg *.jpeg *.bmp *.tif *.tiff)"));
    if (!p.isEmpty()) {
      rememberDialogFolder(p);
      openSecondFrame(p);
    }
  });
  auto* clearSecond = new QPushButton(tr("Clear"), secondBox);
  clearSecond->setObjectName(QStringLiteral("clearSecondFrame"));
  connect(clearSecond, &QPushButton::clicked, this, [this] {
    if (!data() || data()->frame2.empty()) return;
    wb_.doc->edit(tr("Clear second frame"), [](app::Case& k) {
      k.frame2 = cv::Mat3b();
      k.contour2 = {};
    });
  });
  secondRow->addWidget(useSecond);
  secondRow->addWidget(openSecond);
  secondRow->addWidget(clearSecond);
  sl->addLayout(secondRow);
  auto* moveRow = new QHBoxLayout;
  auto* moveLabel = new QLabel(tr("Scope &moved:"), secondBox);
  baseline_ = new QDoubleSpinBox(secondBox);
  baseline_->setAccessibleName(tr("How far the scope moved"));
  baseline_->setObjectName(QStringLiteral("secondFrameBaseline"));
  baseline_->setRange(0, 200);
  baseline_->setDecimals(1);
  baseline_->setSuffix(tr(" mm"));
  baseline_->setSpecialValueText(tr("not known"));
  baseline_->setKeyboardTracking(false);
  baseline_->setToolTip(
      tr("How far the scope moved between the two frames (a tracker's, a robot's, or the port's "
         "marks): the frames give the move's direction only, not its length."));
  moveLabel->setBuddy(baseline_);
  connect(baseline_, &QDoubleSpinBox::valueChanged, this, [this](double mm) {
    if (updating_ || !data() || data()->baselineMm == mm) return;
    wb_.doc->edit(tr("Set how far the scope moved"), [mm](app::Case& k) { k.baselineMm = mm; });
  });
  moveRow->addWidget(moveLabel);
  moveRow->addWidget(baseline_, 1);
  sl->addLayout(moveRow);
  l->addWidget(videoBox);
  l->addWidget(secondBox);
  auto* camBox = new QGroupBox(tr("Camera intrinsics (px)"), this);
  auto* form = new QFormLayout(camBox);
  const QString names[4] = {tr("fx"), tr("fy"), tr("cx"), tr("cy")};
  for (int k = 0; k < 4; ++k) {
    auto* s = new QDoubleSpinBox(camBox);
    s->setRange(k < 2 ? 1 : -100000, 100000);  // a focal length of 0 is a degenerate camera
    s->setDecimals(2);
    s->setKeyboardTracking(false);
    form->addRow(names[k], s);
    intrinsics_[k] = s;
    connect(s, &QDoubleSpinBox::valueChanged, this, [this] {
      if (updating_ || !data()) return;
      const double fx = intrinsics_[0]->value(), fy = intrinsics_[1]->value(), cx = intrinsics_[2]->value(), cy = intrinsics_[3]->value();
      wb_.doc->edit(tr("Edit intrinsics"), [=](app::Case& k) {
        k.camera.K(0, 0) = fx;
        k.camera.K(1, 1) = fy;
        k.camera.K(0, 2) = cx;
        k.camera.K(1, 2) = cy;
      });
    });
  }
  distortionLabel_ = new QLabel(camBox);
  distortionLabel_->setWordWrap(true);
  form->addRow(tr("Distortion"), distortionLabel_);
  auto* loadCal = new QPushButton(tr("Load Calibration..."), camBox);
  connect(loadCal, &QPushButton::clicked, this, [this] {
    const QString p = QFileDialog::getOpenFileName(wb_.window, tr("Load Camera Calibration"), dialogFolder(),
                                                   tr("Calibrations (*.yaml *.yml *.xml *.json *.txt)"));
    if (!p.isEmpty()) {
      rememberDialogFolder(p);
      loadCalibration(p);
    }
  });
  auto* defaults = new QPushButton(tr("Default From Image Size"), camBox);
  connect(defaults, &QPushButton::clicked, this, [this] {
    if (!data() || data()->frame.empty()) return;
    wb_.doc->edit(tr("Default intrinsics"), [](app::Case& k) { k.camera = imaging::Camera::defaultFor(k.frame.cols, k.frame.rows); });
  });
  form->addRow(loadCal);
  form->addRow(defaults);
  l->addWidget(camBox);
  l->addStretch(1);
  connect(&cameraTimer_, &QTimer::timeout, this, [this] { showVideoFrame(-1); });
}

FramePage::~FramePage() { cameraTimer_.stop(); }

namespace {
// Why an image file gave no picture, in the file's terms: empty, missing, or not an image format we read.
QString unreadableImage(const QString& path) {
  const QFileInfo info(path);
  if (!info.exists()) return FramePage::tr("%1 does not exist (moved or deleted?).").arg(info.fileName());
  if (info.size() == 0) return FramePage::tr("%1 is empty (0 bytes); copy the whole file again.").arg(info.fileName());
  return FramePage::tr("%1 is not a readable image; use PNG, JPEG, BMP or TIFF.").arg(info.fileName());
}
// The camera a frame of this size gets when nothing says better (Camera::defaultFor): a guess, said as one.
bool guessedCamera(const imaging::Camera& c) {
  const imaging::Camera d = imaging::Camera::defaultFor(c.width, c.height);
  return c.K == d.K && c.distortion == d.distortion;
}

// A calibration written beside the frame under its name ("frame.intrinsics.txt", "frame.yaml", ...), if any.
QString calibrationBeside(const QString& framePath) {
  const QFileInfo f(framePath);
  for (const char* ext : {".intrinsics.txt", ".calibration.yaml", ".calibration.yml", ".yaml", ".yml"}) {
    const QFileInfo c(f.dir().filePath(f.completeBaseName() + QLatin1String(ext)));
    if (c.isFile()) return c.filePath();
  }
  return {};
}
}  // namespace

void FramePage::refresh(const app::Case& c) {
  updating_ = true;
  const double values[4] = {c.camera.fx(), c.camera.fy(), c.camera.cx(), c.camera.cy()};
  for (int k = 0; k < 4; ++k) intrinsics_[k]->setValue(values[k]);
  const auto& d = c.camera.distortion;
  secondLabel_->setText(c.frame2.empty()
                            ? tr("None: one outline leaves the organ's depth to its model; a second frame with the "
                                 "scope moved 1-2 cm sideways fixes it by parallax.")
                            : tr("%1x%2, %3 outline segments sketched on it%4.")
                                  .arg(c.frame2.cols)
                                  .arg(c.frame2.rows)
                                  .arg(c.contour2.segments.size())
                                  .arg(c.baselineMm > 0 ? QString() : tr("; say how far the scope moved")));
  baseline_->setValue(c.baselineMm);
  distortionLabel_->setText(QStringLiteral("k1 %1  k2 %2  p1 %3  p2 %4  k3 %5").arg(d[0]).arg(d[1]).arg(d[2]).arg(d[3]).arg(d[4]));
  updating_ = false;
}

void FramePage::openFrameDialog() {
  const QString p = QFileDialog::getOpenFileName(wb_.window, tr("Open Endoscope Image or Video"), dialogFolder(),
                                                 tr("Images and videos (*.png *.jpg *.jpeg *.bmp *.tif *.mp4 *.avi *.mkv *.mov)"));
  if (!p.isEmpty()) {
    rememberDialogFolder(p);
    openFrameSource(p);
  }
}

void FramePage::openFrameSource(const QString& path) {
  wb_.goToStep(app::Step::Frame);
  const QString ext = QFileInfo(path).suffix().toLower();
  const bool isVideo = QStringList{"mp4", "avi", "mkv", "mov", "m4v", "mpg", "webm"}.contains(ext);
  if (!isVideo) {
    cv::Mat3b img = cv::imread(path.toStdString(), cv::IMREAD_COLOR);
    if (img.empty()) {
      const QString msg = unreadableImage(path);
      wb_.status(msg);
      emit frameSourceOpened(false, msg);
      return;
    }
    cameraTimer_.stop();
    video_.reset();
    videoFrames_ = 0;
    videoSlider_->setEnabled(false);
    videoLabel_->setText(tr("no video"));
    shownFrame_ = img;
    // A calibration beside the image, under its name, is the scope's (a helper opened the scikit-surgery frame beside
    // its intrinsics and worked on with fx = fy = 1536 px instead of 2012 and 2018).
    takeShownFrame(calibrationBeside(path));
    emit frameSourceOpened(true, {});
    return;
  }
  // Opening a video probes the container and decoder: off the GUI thread.
  auto mutex = videoMutex_;
  wb_.jobs->run(tr("Opening video %1...").arg(QFileInfo(path).fileName()), [this, path, mutex](const std::atomic<bool>&, const auto&) -> std::function<void()> {
    auto cap = std::make_shared<cv::VideoCapture>();
    std::lock_guard<std::mutex> lock(*mutex);
    if (!cap->open(path.toStdString()) || !cap->isOpened()) {
      const QString msg = tr("%1 cannot be decoded as a video; check the file or convert it to MP4 (H.264).").arg(QFileInfo(path).fileName());
      return [this, msg] {
        wb_.status(msg);
        emit frameSourceOpened(false, msg);
      };
    }
    const int frames = static_cast<int>(cap->get(cv::CAP_PROP_FRAME_COUNT));
    return [this, cap, frames, path] {
      useVideo(cap, std::max(0, frames), {});
      wb_.status(tr("Video %1: %2 frames; scrub to pick the frame to work on.").arg(QFileInfo(path).fileName()).arg(videoFrames_));
      emit frameSourceOpened(true, {});
      showVideoFrame(0);
    };
  });
}

void FramePage::useVideo(std::shared_ptr<cv::VideoCapture> cap, int frames, const QString& label) {
  cameraTimer_.stop();
  video_ = std::move(cap);
  videoFrames_ = frames;
  updating_ = true;
  videoSlider_->setRange(0, std::max(0, videoFrames_ - 1));
  videoSlider_->setValue(0);
  videoSlider_->setEnabled(videoFrames_ > 1);
  updating_ = false;
  useFrameButton_->setEnabled(true);
  if (!label.isEmpty()) videoLabel_->setText(label);
}

void FramePage::openCameraDevice(int index) {
  // Opening a device can take seconds (or hang on a busy driver): off the GUI thread, like a video.
  auto mutex = videoMutex_;
  wb_.jobs->run(tr("Opening camera %1...").arg(index), [this, index, mutex](const std::atomic<bool>&, const auto&) -> std::function<void()> {
    auto cap = std::make_shared<cv::VideoCapture>();
    std::lock_guard<std::mutex> lock(*mutex);
    if (!cap->open(index) || !cap->isOpened()) {
      return [this, index] {
        const QString msg = tr("Camera device %1 cannot be opened; check that it is connected and not in use.").arg(index);
        wb_.status(msg);
        emit frameSourceOpened(false, msg);
      };
    }
    return [this, cap, index] {
      useVideo(cap, 0, tr("live camera %1").arg(index));
      cameraTimer_.start(66);
      emit frameSourceOpened(true, {});
    };
  });
}

void FramePage::showVideoFrame(int index) {
  if (!video_) return;
  if (videoDecoding_) {
    pendingVideoFrame_ = index;  // the latest request wins
    return;
  }
  videoDecoding_ = true;
  auto cap = video_;
  auto mutex = videoMutex_;
  auto watcher = new QFutureWatcher<cv::Mat>(this);
  connect(watcher, &QFutureWatcher<cv::Mat>::finished, this, [this, watcher, index] {
    cv::Mat frame = watcher->result();
    watcher->deleteLater();
    videoDecoding_ = false;
    if (!frame.empty()) {
      shownFrame_ = frame;
      if (index >= 0) shownVideoFrame_ = index;
      wb_.view->setFrame(frameToQImage(frame));
      if (index >= 0) videoLabel_->setText(tr("frame %1 of %2").arg(index).arg(videoFrames_));
      updating_ = true;
      if (index >= 0) videoSlider_->setValue(index);
      updating_ = false;
      if (index >= 0) emit videoFrameShown(index);
    } else if (index >= 0) {
      wb_.status(tr("Frame %1 could not be decoded.").arg(index));
    }
    if (pendingVideoFrame_ >= 0 && pendingVideoFrame_ != index) {
      const int next = pendingVideoFrame_;
      pendingVideoFrame_ = -1;
      showVideoFrame(next);
    }
  });
  watcher->setFuture(QtConcurrent::run([cap, mutex, index]() -> cv::Mat {
    std::lock_guard<std::mutex> lock(*mutex);
    cv::Mat frame;
    if (index >= 0) cap->set(cv::CAP_PROP_POS_FRAMES, index);
    cap->read(frame);
    if (!frame.empty() && frame.channels() != 3) cv::cvtColor(frame, frame, frame.channels() == 1 ? cv::COLOR_GRAY2BGR : cv::COLOR_BGRA2BGR);
    return frame;
  }));
}

void FramePage::useShownFrame() { takeShownFrame({}); }

void FramePage::takeShownFrame(const QString& calibration) {
  if (shownFrame_.empty() || !data()) return;
  cv::Mat3b frame = shownFrame_.clone();
  // The calibration beside the image, read before the edit (one undo step takes both); why not, when it is not one.
  std::optional<imaging::Camera> beside;
  QString unread;
  if (!calibration.isEmpty()) {
    try {
      const imaging::Camera cam = imaging::loadCamera(calibration.toStdString(), frame.cols, frame.rows);
      if (cam.width == frame.cols && cam.height == frame.rows)
        beside = cam;
      else
        unread = tr("it is for %1x%2 images").arg(cam.width).arg(cam.height);
    } catch (const std::exception& e) {
      unread = QString::fromUtf8(e.what());
    }
  }
  const imaging::Camera& was = data()->camera;
  const bool sameSize = was.width == frame.cols && was.height == frame.rows;
  if (beside && sameSize && !guessedCamera(was)) beside.reset();  // a camera stated for this size is kept
  const int shown = shownVideoFrame_;
  const bool fromVideo = video_ != nullptr && videoFrames_ > 0;
  // The outline was sketched on the frame it replaces: it does not belong to this one (another moment, maybe another
  // size). It goes with the old frame, in the same undo step, so that step 3 is to be done again.
  // So is the elastic fit to that outline (the shape and its "where the organ may be"): kept, steps 4-5 read done on a
  // frame nothing was fitted to. The hand's alignment, if any, stays as this frame's start.
  // And the appearance estimated from the old frame's pixels (step 6): kept, the composited view re-shaded the new frame
  // with another frame's light and albedo, and step 6's table showed them as this frame's (a helper read the phantom's
  // numbers over the patient liver's frame).
  const bool hadContour = !data()->contour.segments.empty(), hadSecond = !data()->frame2.empty(),
             hadFit = data()->hasFit(), hadAppearance = data()->appearance != nullptr;
  // The landmark pairs' points in the frame are the old frame's (a helper saw a pair drawn on the real frame at the
  // phantom's pixel): the pairs go too, their points on the organ picked again with the new frame's.
  const std::size_t hadPairs = data()->landmarks.size();
  wb_.doc->edit(fromVideo ? tr("Pick frame %1").arg(shown) : tr("Open frame"), [frame, beside](app::Case& k) {
    k.contour.segments.clear();
    k.fit.reset();
    k.appearance.reset();
    k.landmarks.clear();
    if (k.frame2.size() != frame.size()) {  // (a second frame of another size does not go with this one)
      k.frame2 = cv::Mat3b();
      k.contour2 = {};
    }
    if (beside) {
      k.camera = *beside;
    } else if (k.camera.width != frame.cols || k.camera.height != frame.rows) {
      // A frame of another size keeps no stale calibration: the stated default, editable in the panel.
      k.camera = imaging::Camera::defaultFor(frame.cols, frame.rows);
    }
    k.rawFrame = frame;
    app::undistortFrame(k);
    k.contour.width = frame.cols;
    k.contour.height = frame.rows;
  });
  QString text = fromVideo ? tr("Using frame %1 of the video.").arg(shown)
                 : beside  ? tr("Frame opened with the calibration found beside it, %1 (fx %2, fy %3 px).")
                                .arg(QFileInfo(calibration).fileName())
                                .arg(beside->fx(), 0, 'f', 1)
                                .arg(beside->fy(), 0, 'f', 1)
                           : tr("Frame opened.");
  if (!unread.isEmpty())
    text += tr(" %1 beside it was not read as its calibration: %2").arg(QFileInfo(calibration).fileName(), unread);
  // What went with the old frame, in one sentence, in the workflow's order: each thing (the first names the previous
  // frame, the others refer to it), and the step that makes it again.
  struct Gone {
    int step;
    QString first, later, redo;
  };
  std::vector<Gone> went;
  if (hadContour)
    went.push_back({3, tr("the contour sketched on the previous frame"), tr("the contour sketched on it"), tr("sketch")});
  if (hadPairs == 1)
    went.push_back({4, tr("the landmark pair picked on the previous frame"), tr("the landmark pair picked on it"),
                    tr("pick the pairs")});
  else if (hadPairs > 1)
    went.push_back({4, tr("the %1 landmark pairs picked on the previous frame").arg(hadPairs),
                    tr("the %1 landmark pairs picked on it").arg(hadPairs), tr("pick the pairs")});
  if (hadFit) went.push_back({5, tr("the fit to the previous frame"), tr("the fit to it"), tr("fit")});
  if (hadAppearance)
    went.push_back({6, tr("the appearance estimated from the previous frame"), tr("the appearance estimated from it"),
                    tr("estimate the appearance (F10)")});
  QStringList gone, redo, steps;
  for (const Gone& g : went) {
    gone << (gone.isEmpty() ? g.first : g.later);
    redo << g.redo;
    steps << QString::number(g.step);
  }
  auto listed = [this](const QStringList& l) {
    return l.size() <= 1 ? l.join(QString()) : l.mid(0, l.size() - 1).join(QStringLiteral(", ")) + tr(" and ") + l.back();
  };
  if (!gone.isEmpty()) {
    QString first = listed(gone);
    first[0] = first[0].toUpper();
    text += QLatin1Char(' ') +
            (gone.size() == 1 ? tr("%1 was removed: %2 on this one (step %3), or Undo to go back to it.")
                              : tr("%1 were removed: %2 on this one (steps %3), or Undo to go back to them."))
                .arg(first, listed(redo), listed(steps));
  }
  if (hadSecond && data()->frame2.empty()) text += tr(" The second frame, of another size, was removed.");
  // What the frame does not say is said as a guess: the focal length decides how deep the fitted organ lies.
  if (guessedCamera(data()->camera))
    text += tr(" The camera is a default guessed from the image size (fx = fy = %1 px, centred): load the scope's "
               "calibration (Load Calibration...) before the fit.")
                .arg(data()->camera.fx(), 0, 'f', 0);
  wb_.status(text);
}

void FramePage::setSecondFrame(const cv::Mat3b& bgr, const QString& what) {
  QString problem;
  if (!data() || data()->frame.empty())
    problem = tr("Open the first frame before a second one.");
  else if (bgr.cols != data()->camera.width || bgr.rows != data()->camera.height)
    problem = tr("The second frame is %1x%2 but the first is %3x%4: take it from the same video.")
                  .arg(bgr.cols)
                  .arg(bgr.rows)
                  .arg(data()->camera.width)
                  .arg(data()->camera.height);
  if (!problem.isEmpty()) {
    wb_.status(problem);
    emit frameSourceOpened(false, problem);
    return;
  }
  // Undistorted with the case's camera, as the first frame is (every step works on undistorted pixels).
  const cv::Mat3b frame = imaging::undistortImage(bgr.clone(), data()->camera);
  wb_.doc->edit(tr("Set second frame"), [frame](app::Case& k) {
    k.frame2 = frame;
    k.contour2 = {};
    k.contour2.width = frame.cols;
    k.contour2.height = frame.rows;
  });
  wb_.status(tr("%1 is the second frame: sketch the organ's outline on it (step 3, Second frame) and say how far the "
                "scope moved.")
                 .arg(what));
  emit frameSourceOpened(true, {});
}

void FramePage::useShownFrameAsSecond() {
  if (shownFrame_.empty() || !video_ || videoFrames_ <= 0) {
    wb_.status(tr("Open a video and show the frame to use as the second frame."));
    return;
  }
  setSecondFrame(cv::Mat3b(shownFrame_), tr("Frame %1 of the video").arg(shownVideoFrame_));
}

void FramePage::openSecondFrame(const QString& path) {
  const cv::Mat3b img = cv::imread(path.toStdString(), cv::IMREAD_COLOR);
  if (img.empty()) {
    const QString msg = unreadableImage(path);
    wb_.status(msg);
    emit frameSourceOpened(false, msg);
    return;
  }
  setSecondFrame(img, QFileInfo(path).fileName());
}

void FramePage::loadCalibration(const QString& path) {
  if (!data()) return;
  try {
    const int w = data()->frame.empty() ? 0 : data()->frame.cols, h = data()->frame.empty() ? 0 : data()->frame.rows;
    imaging::Camera cam = imaging::loadCamera(path.toStdString(), w, h);
    if (w > 0 && (cam.width != w || cam.height != h))
      throw rehearse::InputError(tr("The calibration is for %1x%2 images but the frame is %3x%4; choose the matching calibration.")
                                    .arg(cam.width).arg(cam.height).arg(w).arg(h).toStdString());
    wb_.doc->edit(tr("Load calibration"), [cam](app::Case& k) {
      if (k.rawFrame.empty()) k.rawFrame = k.frame;  // the frame so far was taken as captured
      k.camera = cam;
      app::undistortFrame(k);
    });
    wb_.status(tr("Calibration loaded from %1.").arg(QFileInfo(path).fileName()));
  } catch (const std::exception& e) {
    wb_.status(QString::fromUtf8(e.what()));
  }
}

}  // namespace rehearse::ui
