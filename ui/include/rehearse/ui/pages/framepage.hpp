#pragma once
// Step 2, the endoscope frame: an image, a video scrubbed to the frame (decoded on a worker, the latest
// request wins), or a live camera; the camera's intrinsics (calibration file, default, or typed) with which
// the frame is undistorted.
#include "rehearse/ui/pages/steppage.hpp"

#include <QTimer>

#include <memory>
#include <mutex>

#include <opencv2/core.hpp>

class QDoubleSpinBox;
class QLabel;
class QPushButton;
class QSlider;

namespace cv {
class VideoCapture;
}

namespace rehearse::ui {

class FramePage : public StepPage {
  Q_OBJECT
 public:
  FramePage(Workbench& wb, QWidget* parent = nullptr);
  ~FramePage() override;
  void refresh(const app::Case& c) override;

  void openFrameSource(const QString& path);  ///< image or video file
  void openFrameDialog();
  void openCameraDevice(int index);           ///< live camera (opened on a worker)
  void showVideoFrame(int index);             ///< decode and preview frame `index` (-1: the next live frame)
  void useShownFrame();                       ///< take the previewed frame for the case
  /// A second frame of the same scene, the scope moved 1-2 cm (issue 38): the previewed video frame, or an image file;
  /// one undo step. Refused with a sentence (status bar, frameSourceOpened) without a first frame or at another size.
  void useShownFrameAsSecond();
  void openSecondFrame(const QString& path);
  void loadCalibration(const QString& path);
  int videoFrameCount() const { return videoFrames_; }
  int shownVideoFrame() const { return shownVideoFrame_; }
  void stopCamera() { cameraTimer_.stop(); }

 signals:
  void frameSourceOpened(bool ok, const QString& message);
  void videoFrameShown(int index);

 private:
  void useVideo(std::shared_ptr<cv::VideoCapture> cap, int frames, const QString& label);
  /// useShownFrame, with the calibration file found beside the image (empty: none): taken in the same undo step when
  /// the frame would otherwise keep the camera guessed from its size.
  void takeShownFrame(const QString& calibration);

  QSlider* videoSlider_ = nullptr;
  QLabel* videoLabel_ = nullptr;
  QPushButton* useFrameButton_ = nullptr;
  QDoubleSpinBox* intrinsics_[4] = {};  ///< fx, fy, cx, cy (px)
  QLabel* secondLabel_ = nullptr;       ///< the second frame: there or not
  QDoubleSpinBox* baseline_ = nullptr;  ///< how far the scope moved to it (mm)
  void setSecondFrame(const cv::Mat3b& bgr, const QString& what);
  QLabel* distortionLabel_ = nullptr;
  std::shared_ptr<cv::VideoCapture> video_;
  std::shared_ptr<std::mutex> videoMutex_ = std::make_shared<std::mutex>();
  int videoFrames_ = 0;
  int shownVideoFrame_ = -1;
  int pendingVideoFrame_ = -1;
  bool videoDecoding_ = false;
  cv::Mat shownFrame_;
  QTimer cameraTimer_;
};

}  // namespace rehearse::ui
