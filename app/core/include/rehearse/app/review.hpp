#pragma once
// Reviewing a recorded rehearsal (issue 16), without Qt: what a replay gives per step (the timeline: time,
// the instrument's tip and force, the tissue's largest strain, the events), the session's metrics by name
// with the trainer's thresholds and a pass/fail per metric, and the frames the review window, the video
// and the report draw (the organ through the case's camera over its frame, or through a virtual camera).
#include <rehearse/app/recording.hpp>
#include <rehearse/imaging/camera.hpp>

#include <opencv2/core.hpp>

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::app {

/// Greatest principal Green-Lagrange strain magnitude over the elements: max |eigenvalue| of
/// E = (F^T F - I) / 2, F the deformation gradient of each element from `rest` to `current` (m).
double maxGreenStrain(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& current,
                      const std::vector<std::array<int, 4>>& tets);

/// A value per named metric (the names of `rehearse replay --metrics`); nullopt where the session does not
/// determine it, with the reason in `why`.
struct MetricValue {
  std::string name;
  std::optional<double> value;
  std::string unit;
  std::string why;     ///< when there is no value: one sentence
  bool count = false;  ///< a whole number (grasps, slips, ...)
};
std::vector<MetricValue> metricValues(const SessionMetrics& m);
/// A metric's name in words for a person ("path length" for path_length_m; the unit goes with its value); the name
/// itself is what thresholds and the command line use.
std::string metricWords(const std::string& name);
/// A metric's amount as a person reads it, in the unit a surgeon uses for it (lengths in mm, strain in %, forces
/// to 0.1 N, durations to 0.1 s, counts whole, economy of motion as a share of 1): "12.4 mm", "31.2 N", "3", "0.82
/// of 1". `v` is in the metric's own unit (MetricValue::unit: m, N, s, mL, or none). Thresholds use it too.
std::string metricAmount(const MetricValue& m, double v);
/// metricAmount of its value, or "not determined".
std::string metricText(const MetricValue& m);

/// Whether a replay reproduced the recording: every recorded checksum compared and equal, and every checkpoint sound.
/// A session that does not verify shows another run than the one recorded (its metrics and pictures are not the
/// trainee's): every place that shows a session says so (review window, report, cohort view, metrics).
bool replayVerified(const VerifyResult& v);
/// In one sentence: "verified: all 35 checksums and 18 checkpoints match (CHOLMOD supernodal, OpenBLAS 0.3.21
/// Prescott)", "DOES NOT VERIFY: 88 of 89 checksums differ, the first after step 430 - ...: recorded with kernel X,
/// replayed with Y" (replayProvenance), "DOES NOT VERIFY: the checkpoint after step 40 is damaged (...)", or "not
/// verified: ...".
std::string replayCheckSentence(const VerifyResult& v);
/// What made the recording and what replayed it, where they differ ("recorded with kernel X, replayed with Y").
std::string replayProvenance(const VerifyResult& v);

/// A trainer's limit on a metric: the session passes it when min <= value <= max.
struct Threshold {
  std::string metric;
  std::optional<double> min, max;
};
/// Thresholds from JSON {"max_force_n": {"max": 15}, "economy_of_motion": {"min": 0.8}, ...}. Throws
/// std::runtime_error with one sentence (an unknown metric, a limit that is not a number, min > max).
std::vector<Threshold> parseThresholds(const std::string& json);
struct Verdict {
  MetricValue metric;
  Threshold threshold;
  enum class Result { Pass, Fail, NotDetermined } result = Result::NotDetermined;
};
std::vector<Verdict> judge(const SessionMetrics& m, const std::vector<Threshold>& thresholds);
const char* resultWord(Verdict::Result r);  ///< "pass", "fail", "not determined"

/// Draws replayed states: the organ's surface (cut tissue darker) shaded by a headlight over the case's frame
/// (the body is then in that camera's frame) or over a plain background through a virtual camera that looks
/// along +z at the organ; the instrument's shaft from the trocar to the tip, the tip (green open, yellow
/// holding, red cutting), the jaws as a yellow ring where they hold the tissue apart from the tip (the grasper's
/// traction while the scissors cut), the tip's path so far, and a caption.
class ReviewRenderer {
 public:
  /// `camera` and `frame`: the case's (frame: 8-bit BGR of the camera's size); without them a virtual camera
  /// of `width` x `height` framing the setup's rest shape.
  ReviewRenderer(const simcore::BodySetup& setup, int width, int height,
                 const std::optional<imaging::Camera>& camera = std::nullopt, const cv::Mat3b& frame = {});
  /// The image of a snapshot; `path`: the tip's places so far (body frame), `caption` at the top left.
  cv::Mat3b render(const simcore::Snapshot& s, const std::vector<Eigen::Vector3d>& path,
                   const std::string& caption) const;
  const imaging::Camera& camera() const { return camera_; }
  /// Turns the virtual camera about the organ's centre (the review's 3D view; a case camera is not turned).
  void orbit(double yawRadians, double pitchRadians);
  bool virtualCamera() const { return virtual_; }

 private:
  imaging::Camera camera_;
  Pose pose_;  // body frame -> camera
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();
  double distance_ = 0;
  double yaw_ = 0, pitch_ = 0;
  bool virtual_ = true;
  cv::Mat3b background_;
  std::vector<std::array<int, 3>> uncutTriangles_;
  void place();
};

/// The sample of a step (the timeline holds steps 1..n in order: found by its index); null when absent.
const TimelineSample* sampleAt(const std::vector<TimelineSample>& timeline, long step);
/// The last step whose time is at or before `seconds` (0 before the first), by bisection.
long stepAtTime(const std::vector<TimelineSample>& timeline, double seconds);
/// The timeline's per-step samples (ReplayResult::timeline) up to `step`: the tip's path (while present), a
/// non-finite point between two instruments' paths.
std::vector<Eigen::Vector3d> tipPath(const std::vector<TimelineSample>& timeline, long step);
/// A caption for a step: time, force, events.
std::string captionAt(const std::vector<TimelineSample>& timeline, long step, const std::string& who);

/// Writes the span [fromStep, toStep] of a recording as an MP4 video (OpenCV VideoWriter, MPEG-4 part 2) at
/// `fps` frames per second of simulated time: frame k shows the first step at or after fromStep's time + k / fps.
/// Returns the frames written. `progress(done, total)` returns false to cancel (then throws Cancelled-like
/// std::runtime_error "cancelled"). Throws std::runtime_error with one sentence (no MP4 writer, a bad span).
int writeReviewVideo(Replayer& replayer, const ReviewRenderer& renderer, const std::vector<TimelineSample>& timeline,
                     long fromStep, long toStep, double fps, const std::string& path,
                     const std::function<bool(int, int)>& progress = {});

/// What a session's report holds; writeReviewPdf writes it.
struct ReviewReport {
  std::string title;
  std::vector<std::pair<std::string, std::string>> facts;  ///< who, when, case, versions, notes, the replay's check
  std::vector<MetricValue> metrics;
  std::vector<Verdict> verdicts;  ///< one per threshold set
  std::vector<TimelineSample> timeline;
  double forceThresholdN = 0;
  std::vector<std::pair<std::string, cv::Mat3b>>
      keyFrames;  ///< caption, image (first grasp, largest force, first cut, the end)
  std::vector<IncorrectAction> incorrectActions;                     ///< under the session's rules, in time order
  std::string rulesError;                                            ///< why there are none to show (rules unreadable)
  std::vector<std::pair<std::string, std::string>> rulesNotCounted;  ///< rule, why (off, or not determined)
};
/// Gathers a report: `result` from replayRecording with the timeline; key frames drawn by `renderer` from `replayer`.
ReviewReport makeReviewReport(const Recording& r, const ReplayResult& result, const std::vector<Threshold>& thresholds,
                              Replayer& replayer, const ReviewRenderer& renderer);
/// Writes the report as PDF on A4 pages (cairo and pango, no Qt: the GUI and the GUI-less command line write the same
/// file), through a temporary file (never half-written). Throws std::runtime_error with one sentence.
void writeReviewPdf(const ReviewReport& report, const std::string& path);

/// A colour, 0-255 per channel.
struct Rgb {
  unsigned char r = 0, g = 0, b = 0;
};
/// The timeline's tick colour of a recorded event (the review window's and the report's; none: not ticked).
std::optional<Rgb> reviewEventRgb(const std::string& event);
/// The legend of those ticks, in words.
extern const char* const kReviewEventLegend;

}  // namespace rehearse::app
