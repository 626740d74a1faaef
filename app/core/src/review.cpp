#include "rehearse/app/review.hpp"

#include <rehearse/simcore/session/events.hpp>
#include <rehearse/text_input.hpp>

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/mesh.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <map>
#include <cmath>
#include <limits>
#include <cstdio>
#include <stdexcept>

namespace rehearse::app {

double maxGreenStrain(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& current,
                      const std::vector<std::array<int, 4>>& tets) {
  double worst = 0;
  for (const auto& t : tets) {
    if (t[0] < 0 ||
        static_cast<std::size_t>(std::max({t[0], t[1], t[2], t[3]})) >= std::min(rest.size(), current.size()))
      continue;
    Eigen::Matrix3d Dm, Ds;
    for (int k = 0; k < 3; ++k) {
      Dm.col(k) = rest[static_cast<std::size_t>(t[k + 1])] - rest[static_cast<std::size_t>(t[0])];
      Ds.col(k) = current[static_cast<std::size_t>(t[k + 1])] - current[static_cast<std::size_t>(t[0])];
    }
    const double det = Dm.determinant();
    if (!(std::abs(det) > 0)) continue;  // a degenerate rest element has no strain to speak of
    const Eigen::Matrix3d F = Ds * Dm.inverse();
    const Eigen::Matrix3d E = 0.5 * (F.transpose() * F - Eigen::Matrix3d::Identity());
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(E, Eigen::EigenvaluesOnly);
    worst = std::max(worst, es.eigenvalues().cwiseAbs().maxCoeff());
  }
  return worst;
}

std::vector<MetricValue> metricValues(const SessionMetrics& m) {
  std::vector<MetricValue> v = {
      {"duration_s", m.durationS, "s", ""},
      {"path_length_m", m.pathLengthM, "m", ""},
      {"economy_of_motion", m.economy, "", ""},
      {"grasps", m.grasps, "", ""},
      {"slips", m.slips, "", ""},
      {"cut_updates", m.cuts, "", ""},
      {"vessel_cuts", m.vesselCuts, "", m.vesselCuts ? "" : m.vesselWhy},
      {"max_force_n", m.maxForceN, "N", ""},
      {"mean_force_n", m.meanForceN, "N", ""},
      {"time_over_threshold_s", m.timeOverThresholdS, "s", ""},
      {"max_strain", m.maxStrain, "", m.maxStrain ? "" : "not computed in this replay"},
      {"cut_length_m", m.cutLengthM, "m", ""},
      {"cut_deviation_mean_m", m.cutDeviationMeanM, "m", m.cutDeviationMeanM ? "" : m.cutDeviationWhy},
      {"cut_deviation_max_m", m.cutDeviationMaxM, "m", m.cutDeviationMaxM ? "" : m.cutDeviationWhy},
      {"tumour_breaches", m.tumourBreaches, "", m.tumourBreaches ? "" : m.tumourWhy},
      {"tears", m.tears, "", m.tears ? "" : m.attachmentsWhy},
      {"attachments_torn", m.attachmentsTorn, "", m.attachmentsTorn ? "" : m.attachmentsWhy},
      {"clips", m.clips, "", ""},
      {"misplaced_clips", m.misplacedClips, "", ""},
      {"blood_loss_ml", m.bloodLossMl, "mL", m.bloodLossMl ? "" : m.vesselWhy},
      {"energy_time_s", m.energyTimeS, "s", ""},
      {"energy_on_structures", m.energyOnStructures, "", ""},
  };
  // The trainer's incorrect actions under the session's rules: the total, and the rules no other metric counts.
  for (const auto& [name, rule] :
       std::vector<std::pair<std::string, std::string>>{{"incorrect_actions", ""},
                                                        {"vessel_cuts_without_clips", "vessel_cut_without_clips"},
                                                        {"force_over_limit", "force_over_limit"},
                                                        {"instrument_outside_view", "outside_view"}}) {
    std::string why;
    const auto n = m.incorrectCount(rule, &why);
    v.push_back({name, n ? std::optional<double>(*n) : std::nullopt, "", n ? "" : why});
  }
  for (auto& x : v)
    x.count = x.name == "grasps" || x.name == "slips" || x.name == "cut_updates" || x.name == "vessel_cuts" ||
              x.name == "tumour_breaches" || x.name == "tears" || x.name == "attachments_torn" || x.name == "clips" ||
              x.name == "misplaced_clips" || x.name == "energy_on_structures" || x.name == "incorrect_actions" ||
              x.name == "vessel_cuts_without_clips" || x.name == "force_over_limit" ||
              x.name == "instrument_outside_view";
  return v;
}

std::string metricWords(const std::string& name) {
  static const std::map<std::string, std::string> words = {
      {"duration_s", "duration"},
      {"path_length_m", "path length"},
      {"economy_of_motion", "economy of motion (1: the straight path)"},
      {"cut_updates", "cut updates"},
      {"vessel_cuts", "vessels cut"},
      {"max_force_n", "largest force"},
      {"mean_force_n", "mean force"},
      {"time_over_threshold_s", "time over the force threshold"},
      {"max_strain", "largest strain"},
      {"cut_length_m", "cut length"},
      {"cut_deviation_mean_m", "mean distance from the planned cut"},
      {"cut_deviation_max_m", "largest distance from the planned cut"},
      {"tumour_breaches", "cuts into the tumour"},
      {"attachments_torn", "attachments torn"},
      {"misplaced_clips", "misplaced clips"},
      {"blood_loss_ml", "blood loss"},
      {"energy_time_s", "energy applied for"},
      {"energy_on_structures", "energy on named structures"},
      {"incorrect_actions", "incorrect actions"},
      {"vessel_cuts_without_clips", "vessels cut without clips"},
      {"force_over_limit", "force over the limit"},
      {"instrument_outside_view", "instrument outside the view"},
  };
  const auto it = words.find(name);
  return it == words.end() ? name : it->second;  // (grasps, slips, tears, clips: already words)
}

std::string metricAmount(const MetricValue& m, double v) {
  char b[64];
  if (m.count)
    std::snprintf(b, sizeof b, "%lld", std::llround(v));
  else if (m.unit == "m")
    std::snprintf(b, sizeof b, "%.1f mm", 1e3 * v);
  else if (m.unit == "s" && v > 0 && v < 0.095)  // a step or a few (10 ms each): not "0.0 s"
    std::snprintf(b, sizeof b, "%.2f s", v);
  else if (m.unit == "N" || m.unit == "s")
    std::snprintf(b, sizeof b, "%.1f %s", v, m.unit.c_str());
  else if (m.unit == "mL")
    std::snprintf(b, sizeof b, std::abs(v) < 10 ? "%.2f mL" : "%.1f mL", v);
  else if (m.name == "max_strain")
    std::snprintf(b, sizeof b, "%.1f %%", 100 * v);
  else if (m.name == "economy_of_motion")
    std::snprintf(b, sizeof b, "%.2f of 1", v);
  else
    std::snprintf(b, sizeof b, "%.3g%s%s", v, m.unit.empty() ? "" : " ", m.unit.c_str());
  return b;
}

std::string metricText(const MetricValue& m) { return m.value ? metricAmount(m, *m.value) : "not determined"; }

std::vector<Threshold> parseThresholds(const std::string& text) {
  if (const std::string why = jsonTextProblem(text, "the thresholds file"); !why.empty()) throw std::runtime_error(why);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const std::exception&) {
    throw std::runtime_error("the thresholds are not JSON (expected {\"max_force_n\": {\"max\": 15}, ...})");
  }
  if (!j.is_object()) throw std::runtime_error("the thresholds must be a JSON object of metric names");
  const auto names = metricValues(SessionMetrics{});
  std::vector<Threshold> out;
  for (const auto& [name, limit] : j.items()) {
    if (std::none_of(names.begin(), names.end(), [&](const MetricValue& v) { return v.name == name; }))
      throw std::runtime_error("the thresholds name an unknown metric '" + name + "'");
    if (!limit.is_object())
      throw std::runtime_error("the threshold of " + name + " must be {\"min\": x} and/or {\"max\": y}");
    Threshold t;
    t.metric = name;
    for (const auto& [key, value] : limit.items()) {
      if (key != "min" && key != "max")
        throw std::runtime_error("the threshold of " + name + " has '" + key + "'; only min and max are known");
      if (!value.is_number()) throw std::runtime_error("the threshold " + key + " of " + name + " is not a number");
      (key == "min" ? t.min : t.max) = value.get<double>();
    }
    if (!t.min && !t.max) throw std::runtime_error("the threshold of " + name + " has neither min nor max");
    if (t.min && t.max && *t.min > *t.max) throw std::runtime_error("the threshold of " + name + " has min above max");
    out.push_back(t);
  }
  return out;
}

std::vector<Verdict> judge(const SessionMetrics& m, const std::vector<Threshold>& thresholds) {
  const auto values = metricValues(m);
  std::vector<Verdict> out;
  for (const auto& t : thresholds) {
    const auto it =
        std::find_if(values.begin(), values.end(), [&](const MetricValue& v) { return v.name == t.metric; });
    if (it == values.end()) continue;
    Verdict v{*it, t, Verdict::Result::NotDetermined};
    if (it->value)
      v.result = (!t.min || *it->value >= *t.min) && (!t.max || *it->value <= *t.max) ? Verdict::Result::Pass
                                                                                      : Verdict::Result::Fail;
    out.push_back(v);
  }
  return out;
}

const char* resultWord(Verdict::Result r) {
  switch (r) {
    case Verdict::Result::Pass:
      return "pass";
    case Verdict::Result::Fail:
      return "fail";
    default:
      return "not determined";
  }
}

ReviewRenderer::ReviewRenderer(const simcore::BodySetup& setup, int width, int height,
                               const std::optional<imaging::Camera>& camera, const cv::Mat3b& frame) {
  simcore::Mesh m = setup.mesh;
  if (!setup.rest.empty()) m.points = setup.rest;
  uncutTriangles_ = simcore::boundaryTriangles(m, false);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& p : m.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  centre_ = m.points.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(0.5 * (lo + hi));
  const double radius = m.points.empty() ? 0.1 : std::max(1e-3, 0.5 * (hi - lo).norm());
  if (camera) {
    if (!camera->problem().empty())
      throw std::runtime_error("the case's camera cannot be used for review: " + camera->problem());
    camera_ = *camera;
    virtual_ = false;
    if (!frame.empty() && (frame.cols != camera->width || frame.rows != camera->height))
      throw std::runtime_error("the case's frame is not of its camera's size");
    background_ = frame.empty() ? cv::Mat3b(camera->height, camera->width, cv::Vec3b(40, 36, 34)) : frame.clone();
  } else {
    if (width < 16 || height < 16 || width > 8192 || height > 8192)
      throw std::runtime_error("a review image must be 16 to 8192 pixels on a side");
    camera_ = imaging::Camera::defaultFor(width, height);
    // Far enough for the whole organ to fit the narrower field of view, with a margin.
    const double halfFov = std::atan(0.5 * std::min(width, height) / camera_.fx());
    distance_ = 1.25 * radius / std::sin(halfFov);
    background_.create(height, width);
    for (int y = 0; y < height; ++y)
      background_.row(y).setTo(
          cv::Vec3b(static_cast<uchar>(52 - 20 * y / height), static_cast<uchar>(46 - 16 * y / height), 40));
  }
  place();
}

void ReviewRenderer::orbit(double yaw, double pitch) {
  if (!virtual_) return;
  yaw_ += yaw;
  pitch_ = std::clamp(pitch_ + pitch, -1.5, 1.5);
  place();
}

void ReviewRenderer::place() {
  if (!virtual_) {
    pose_ = Pose{};  // the body is in the camera's frame
    return;
  }
  // Camera looking along +z (y down) turned by yaw about y and pitch about x, at distance_ from the centre.
  const Eigen::Matrix3d turn =
      (Eigen::AngleAxisd(pitch_, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(yaw_, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  pose_.R = turn;
  pose_.t = Eigen::Vector3d(0, 0, distance_) - turn * centre_;
}

cv::Mat3b ReviewRenderer::render(const simcore::Snapshot& s, const std::vector<Eigen::Vector3d>& path,
                                 const std::string& caption) const {
  cv::Mat3b out = background_.clone();
  const auto& tris = s.surface ? s.surface->triangles : uncutTriangles_;
  std::vector<Eigen::Vector3d> cam(s.positions.size());
  for (std::size_t i = 0; i < cam.size(); ++i) cam[i] = pose_.apply(s.positions[i]);
  std::vector<double> verts(3 * cam.size());
  for (std::size_t i = 0; i < cam.size(); ++i)
    for (int k = 0; k < 3; ++k) verts[3 * i + static_cast<std::size_t>(k)] = cam[i][k];
  bool valid = true;
  for (const auto& t : tris)
    for (int n : t) valid &= n >= 0 && static_cast<std::size_t>(n) < cam.size();
  if (valid && !tris.empty()) {
    const SurfaceView view{verts.data(), cam.size(), tris.front().data(), tris.size()};
    imaging::Rasterization r;
    try {
      r = imaging::rasterizeCameraFrame(camera_, cam, view);
    } catch (const std::exception&) {
      valid = false;  // e.g. nothing in front of the camera: the background and the caption only
    }
    if (valid) {
      // Flat headlight shading per triangle; cut tissue in a darker red.
      std::vector<cv::Vec3b> colour(tris.size());
      for (std::size_t k = 0; k < tris.size(); ++k) {
        const auto& t = tris[k];
        const Eigen::Vector3d a = cam[static_cast<std::size_t>(t[0])], b = cam[static_cast<std::size_t>(t[1])],
                              c = cam[static_cast<std::size_t>(t[2])];
        Eigen::Vector3d n = (b - a).cross(c - a);
        const Eigen::Vector3d centre = (a + b + c) / 3;
        const double shade =
            n.norm() > 0 && centre.norm() > 0 ? 0.3 + 0.7 * std::abs(n.normalized().dot(centre.normalized())) : 0.3;
        const bool cutFace = s.surface && k < s.surface->cut.size() && s.surface->cut[k];
        const cv::Vec3d base = cutFace ? cv::Vec3d(60, 50, 150) : cv::Vec3d(120, 135, 215);
        colour[k] = cv::Vec3b(cv::saturate_cast<uchar>(base[0] * shade), cv::saturate_cast<uchar>(base[1] * shade),
                              cv::saturate_cast<uchar>(base[2] * shade));
      }
      const double alpha = virtual_ ? 1.0 : 0.8;  // over the case's frame: the frame shows through a little
      for (int y = 0; y < out.rows; ++y)
        for (int x = 0; x < out.cols; ++x) {
          const int t = r.triangle(y, x);
          if (t < 0) continue;
          const cv::Vec3b c = colour[static_cast<std::size_t>(t)];
          cv::Vec3b& p = out(y, x);
          for (int k = 0; k < 3; ++k) p[k] = cv::saturate_cast<uchar>(alpha * c[k] + (1 - alpha) * p[k]);
        }
    }
  }
  auto pixel = [&](const Eigen::Vector3d& body, cv::Point& at) {
    const Eigen::Vector3d c = pose_.apply(body);
    if (c.z() <= 1e-4) return false;
    const Eigen::Vector2d p = camera_.project(c);
    if (!p.allFinite() || std::abs(p.x()) > 1e5 || std::abs(p.y()) > 1e5) return false;
    at = cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    return true;
  };
  const int thick = std::max(1, out.cols / 400);
  for (std::size_t k = 1; k < path.size(); ++k) {
    cv::Point a, b;
    if (pixel(path[k - 1], a) && pixel(path[k], b)) cv::line(out, a, b, cv::Scalar(230, 210, 60), thick, cv::LINE_AA);
  }
  if (s.tool.present) {
    cv::Point tip, trocar;
    if (pixel(s.tool.tip, tip)) {
      if (pixel(s.trocar, trocar)) cv::line(out, trocar, tip, cv::Scalar(200, 200, 200), 3 * thick, cv::LINE_AA);
      const cv::Scalar c = s.tool.cutting         ? cv::Scalar(40, 40, 230)
                           : !s.tool.held.empty() ? cv::Scalar(40, 220, 240)
                                                  : cv::Scalar(60, 200, 60);
      cv::circle(out, tip, 5 * thick, c, cv::FILLED, cv::LINE_AA);
    }
    // The jaws holding where another instrument left them (the grasper's traction while the scissors cut): a yellow
    // ring there, the tissue they hold.
    cv::Point jaws;
    if (s.tool.jawClosed && !s.tool.held.empty() && s.tool.jawTip != s.tool.tip && pixel(s.tool.jawTip, jaws))
      cv::circle(out, jaws, 5 * thick, cv::Scalar(40, 220, 240), 2 * thick, cv::LINE_AA);
  }
  if (!caption.empty()) {
    const double scale = std::max(0.4, out.cols / 1400.0);
    int base = 0;
    const cv::Size size = cv::getTextSize(caption, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &base);
    cv::rectangle(out, cv::Rect(0, 0, std::min(out.cols, size.width + 12), size.height + base + 10),
                  cv::Scalar(0, 0, 0), cv::FILLED);
    cv::putText(out, caption, cv::Point(6, size.height + 5), cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255, 255, 255),
                1, cv::LINE_AA);
  }
  return out;
}

const TimelineSample* sampleAt(const std::vector<TimelineSample>& timeline, long step) {
  if (step >= 1 && static_cast<std::size_t>(step) <= timeline.size() &&
      timeline[static_cast<std::size_t>(step - 1)].step == step)
    return &timeline[static_cast<std::size_t>(step - 1)];
  for (const auto& s : timeline)  // a timeline not starting at step 1
    if (s.step == step) return &s;
  return nullptr;
}

long stepAtTime(const std::vector<TimelineSample>& timeline, double seconds) {
  const auto it = std::upper_bound(timeline.begin(), timeline.end(), seconds + 1e-9,
                                   [](double t, const TimelineSample& s) { return t < s.time; });
  return it == timeline.begin() ? 0 : std::prev(it)->step;
}

std::vector<Eigen::Vector3d> tipPath(const std::vector<TimelineSample>& timeline, long step) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& s : timeline) {
    if (s.step > step) break;
    // A break (not finite) where one instrument was swapped for another: the drawing does not join them.
    if (s.newInstrument && !out.empty())
      out.push_back(Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
    if (s.toolPresent) out.push_back(s.tip);
  }
  return out;
}

std::string captionAt(const std::vector<TimelineSample>& timeline, long step, const std::string& who) {
  char buf[256];
  const TimelineSample* s = sampleAt(timeline, step);
  if (!s) {
    std::snprintf(buf, sizeof buf, "%s  step %ld", who.c_str(), step);
    return buf;
  }
  std::string events;
  for (const auto& e : s->events)
    if (e.rfind("cut through", 0) != 0) events += (events.empty() ? "  [" : ", ") + e;
  if (!events.empty()) events += "]";
  std::snprintf(buf, sizeof buf, "%s  t = %.2f s  force %.1f N  strain %.3f%s", who.c_str(), s->time, s->force,
                s->strain, events.c_str());
  return buf;
}

int writeReviewVideo(Replayer& replayer, const ReviewRenderer& renderer, const std::vector<TimelineSample>& timeline,
                     long fromStep, long toStep, double fps, const std::string& path,
                     const std::function<bool(int, int)>& progress) {
  if (!(fps > 0 && fps <= 240))
    throw std::runtime_error("the video's frame rate must be between 0 and 240 frames per second");
  if (fromStep < 0 || toStep > replayer.steps() || fromStep >= toStep)
    throw std::runtime_error("the video's span must lie within steps 0 to " + std::to_string(replayer.steps()) +
                             ", its start before its end");
  auto timeOf = [&](long step) {
    const TimelineSample* s = sampleAt(timeline, step);
    return s ? s->time : step * replayer.recording().setup.settings.timeStep;
  };
  const double t0 = timeOf(fromStep), t1 = timeOf(toStep);
  const int frames = static_cast<int>(std::floor((t1 - t0) * fps + 1e-9)) + 1;
  const cv::Size size(renderer.camera().width, renderer.camera().height);
  cv::VideoWriter writer(path, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps, size, true);
  if (!writer.isOpened())
    throw std::runtime_error("cannot write the MP4 video " + path +
                             " (this OpenCV has no MPEG-4 writer, or the folder is not writable)");
  replayer.seek(fromStep);
  for (int k = 0; k < frames; ++k) {
    const double t = t0 + k / fps;
    while (replayer.step() < toStep && timeOf(replayer.step()) < t - 1e-9) replayer.advance();
    const long step = replayer.step();
    writer.write(renderer.render(*replayer.snapshot(), tipPath(timeline, step), captionAt(timeline, step, "")));
    if (progress && !progress(k + 1, frames)) {
      writer.release();
      throw std::runtime_error("cancelled");
    }
  }
  writer.release();
  return frames;
}

bool replayVerified(const VerifyResult& v) {
  return v.checked > 0 && v.mismatches == 0 && v.damagedCheckpoints.empty();
}

std::string replayProvenance(const VerifyResult& v) {
  const RecordedNumerics &a = v.recorded, &b = v.replayed;
  if (a.kernel.empty())
    return "the recording does not name the numerical kernel that made it (recorded before recordings named it); "
           "replayed with " + b.kernel;
  if (a.kernel != b.kernel) return "recorded with kernel " + a.kernel + ", replayed with " + b.kernel;
  if (a.build != b.build)
    return "the same kernel (" + a.kernel + "); recorded by " + a.build + ", replayed by " + b.build;
  return "the same build and kernel (" + b.kernel + ") replayed it: the file was damaged or edited";
}

std::string replayCheckSentence(const VerifyResult& v) {
  if (v.checked == 0) return "not verified: the session holds no checksum to compare its replay with";
  if (v.mismatches)
    return "DOES NOT VERIFY: " + std::to_string(v.mismatches) + " of " + std::to_string(v.checked) +
           " checksums differ, the first after step " + std::to_string(v.firstMismatch) +
           " - what is shown is not the run that was recorded: " + replayProvenance(v);
  if (!v.damagedCheckpoints.empty()) {
    const auto& [step, why] = v.damagedCheckpoints.front();
    std::string s = "DOES NOT VERIFY: the checkpoint after step " + std::to_string(step) + " is damaged (" + why + ")";
    if (v.damagedCheckpoints.size() > 1)
      s += ", and " + std::to_string(v.damagedCheckpoints.size() - 1) + " more of the " +
           std::to_string(v.checkpointsChecked) + " checkpoints";
    return s + "; the run itself replays (all " + std::to_string(v.checked) +
           " checksums match) and seeking starts from the sound ones";
  }
  if (v.checkpointsChecked == 0)
    return "verified: all " + std::to_string(v.checked) + " checksums match (" + v.replayed.kernel + ")";
  const long sound = v.checkpointsChecked - static_cast<long>(v.incompleteCheckpoints.size());
  std::string s = "verified: all " + std::to_string(v.checked) + " checksums and " + std::to_string(sound) +
                  " checkpoints match (" + v.replayed.kernel + ")";
  if (!v.incompleteCheckpoints.empty())
    s += "; " + std::to_string(v.incompleteCheckpoints.size()) +
         " checkpoints by an older build do not hold the instruments' or the field's whole state: seeking replays past "
         "them";
  return s;
}

ReviewReport makeReviewReport(const Recording& r, const ReplayResult& result, const std::vector<Threshold>& thresholds,
                              Replayer& replayer, const ReviewRenderer& renderer) {
  ReviewReport out;
  const auto& s = r.summary;
  out.title =
      "Rehearsal review: session " + std::to_string(s.id) + (s.meta.trainee.empty() ? "" : ", " + s.meta.trainee);
  out.facts = {{"Trainee", s.meta.trainee.empty() ? "(not given)" : s.meta.trainee},
               {"Started (UTC)", s.startedUtc},
               {"Case", s.meta.caseName},
               {"Scene version", s.meta.sceneVersion},
               {"Program version", s.meta.appVersion},
               {"Notes", s.meta.notes},
               {"Steps", std::to_string(result.verify.steps) + (s.complete ? "" : " (the session was cut short)")}};
  const auto& v = result.verify;
  out.facts.push_back({"Replay check", replayCheckSentence(v)});
  out.metrics = metricValues(result.metrics);
  out.verdicts = judge(result.metrics, thresholds);
  out.timeline = result.timeline;
  out.forceThresholdN = result.metrics.forceThresholdN;
  out.incorrectActions = result.metrics.incorrectActions;
  out.rulesError = result.metrics.rulesError;
  for (const auto& [rule, why] : result.metrics.ruleNotCounted) out.rulesNotCounted.emplace_back(rule, why);
  // Key frames: the first grasp, the largest force, the first cut, the first clip, the first bleeding, the first tear,
  // the end.
  std::vector<std::pair<std::string, long>> keys;
  long maxForceStep = -1;
  double maxForce = 0;
  for (const auto& t : result.timeline) {
    if (t.force > maxForce) {
      maxForce = t.force;
      maxForceStep = t.step;
    }
    // (event, caption): each event's first step is a key frame
    using K = simcore::EventKind;
    static const std::pair<K, const char*> firsts[] = {{K::Grasp, "First grasp"},
                                                       {K::Cut, "First cut"},
                                                       {K::Clip, "First clip"},
                                                       {K::Bleeding, "Bleeding"},
                                                       {K::Tear, "First tear"}};
    for (const auto& e : t.events)
      for (const auto& [event, caption] : firsts)
        if (simcore::eventKind(e) == event && std::none_of(keys.begin(), keys.end(), [c = caption](const auto& k) { return k.first == c; }))
          keys.push_back({caption, t.step});
  }
  if (maxForceStep > 0) keys.push_back({"Largest force", maxForceStep});
  if (!result.timeline.empty()) keys.push_back({"End", result.timeline.back().step});
  std::sort(keys.begin(), keys.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  for (const auto& [what, step] : keys) {
    replayer.seek(step);
    char caption[128];
    std::snprintf(caption, sizeof caption, "%s (step %ld)", what.c_str(), step);
    out.keyFrames.push_back({caption, renderer.render(*replayer.snapshot(), tipPath(result.timeline, step),
                                                      captionAt(result.timeline, step, ""))});
  }
  return out;
}

}  // namespace rehearse::app
