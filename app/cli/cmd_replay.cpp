// rehearse replay | publish: the recorded sessions of a case file (verify, metrics, video, report) and the
// training database.
#include "support.hpp"

#include <rehearse/simcore/words.hpp>
#include <rehearse/text_input.hpp>

#include "phantom/phantom.hpp"
#include "phantom/presets.hpp"
#include "rehearse/app/casefolder.hpp"
#include "rehearse/app/elasticfit.hpp"
#include "rehearse/app/appearancestep.hpp"
#include "rehearse/app/gesture.hpp"
#include "rehearse/app/recording.hpp"
#include "rehearse/app/review.hpp"
#include "rehearse/app/materials.hpp"
#include "rehearse/app/trainingdb.hpp"

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/registration.hpp>
#include <rehearse/simcore/scene.hpp>
#include <rehearse/simcore/session/step_truth.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <nlohmann/json.hpp>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <unistd.h>

namespace rehearse::app::cli {

namespace {

// Where the sessions come from: a case file, or the training centre's database (postgresql:[SERVICE]: the libpq service
// name, or the environment when empty).
struct SessionSource {
  std::string file;
  bool fromDb = false;
  std::string service;

  std::vector<RecordingSummary> list() const {
    if (!fromDb) return listRecordings(file);
    std::vector<RecordingSummary> out;
    for (const auto& p : TrainingDatabase(service).sessions()) out.push_back(p.summary);
    return out;
  }
  Recording load(std::int64_t sid) const {
    // A session from the database keeps its connection open for its checkpoints.
    return fromDb ? TrainingDatabase(service).load(sid) : loadRecording(file, sid);
  }
};

// The command line read and checked: the sessions' source, the replay's options and the trainer's thresholds.
struct ReplayRequest {
  Options o;
  SessionSource source;
  ReplayOptions ro;
  std::vector<Threshold> thresholds;
};

// --force-threshold and --planned-cut.
void readMeasureOptions(ReplayRequest& req) {
  Options& o = req.o;
  const double threshold = o.count("force-threshold") ? parseNumber(o["force-threshold"], "--force-threshold") : 10.0;
  if (!(threshold >= 0)) throw UsageError("--force-threshold must be a force in N, 0 or more");
  req.ro.forceThresholdN = threshold;
  if (o.count("planned-cut")) {
    const std::string& p = o["planned-cut"];
    const auto colon = p.find(':');
    if (colon == std::string::npos)
      throw UsageError("--planned-cut takes two points X,Y,Z:X,Y,Z (m, the recording's frame)");
    req.ro.plannedCut = std::make_pair(parseVector(p.substr(0, colon), "--planned-cut"),
                                       parseVector(p.substr(colon + 1), "--planned-cut"));
  }
}

// The trainer's thresholds: --thresholds, else the ones kept in the case file.
void loadThresholds(ReplayRequest& req) {
  Options& o = req.o;
  const std::string& file = req.source.file;
  if (!o.count("thresholds") && !req.source.fromDb) {
    const std::string kept = loadCaseThresholds(file);
    if (!kept.empty()) {
      try {
        req.thresholds = parseThresholds(kept);
      } catch (const std::runtime_error& e) {
        throw UsageError(file + ": its kept thresholds: " + e.what());
      }
    }
  }
  if (o.count("thresholds")) {
    std::string text, why;
    if (!readTextInput(o["thresholds"], text, why)) throw UsageError("the thresholds " + why);
    try {
      req.thresholds = parseThresholds(text);
    } catch (const std::runtime_error& e) {
      throw UsageError(o["thresholds"] + ": " + e.what());
    }
  }
}

// --video, --report and the video's options: for one session, with the right suffixes, the report with its writer.
void checkOneSessionOutputs(Options& o) {
  const bool oneSession =
      o.count("video") || o.count("report") || o.count("from") || o.count("to") || o.count("fps") || o.count("size");
  if (oneSession && !o.count("session"))
    throw UsageError("--video, --report, --from, --to, --fps and --size are for one session: give --session ID");
  if ((o.count("fps") || o.count("size")) && !o.count("video"))
    throw UsageError("--fps and --size set the video: give --video OUT.mp4");
  if ((o.count("from") || o.count("to")) && !o.count("video") && !o.count("exact-check"))
    throw UsageError("--from and --to set the span of the video or of the exact check: give --video OUT.mp4 or "
                     "--exact-check OUT.csv");
  if (o.count("video") && std::filesystem::path(o["video"]).extension() != ".mp4")
    throw UsageError("--video must end in .mp4");
  if (o.count("report") && std::filesystem::path(o["report"]).extension() != ".pdf")
    throw UsageError("--report must end in .pdf");
  // Said before the replay, not after it (it takes seconds).
  for (const char* key : {"video", "report"}) {
    if (!o.count(key)) continue;
    std::filesystem::path folder = std::filesystem::path(o[key]).parent_path();
    if (folder.empty()) folder = ".";
    std::error_code ec;
    if (!std::filesystem::is_directory(folder, ec))
      throw UsageError(std::string("--") + key + ": the folder " + folder.string() + " does not exist");
    if (::access(folder.c_str(), W_OK) != 0)
      throw UsageError(std::string("--") + key + ": the folder " + folder.string() + " is not writable");
  }
}

ReplayRequest parseReplayRequest(const std::vector<std::string>& args) {
  if (args.size() < 3 || args[2].rfind("--", 0) == 0)
    throw UsageError(
        "replay needs the case file (or postgresql:[SERVICE]): rehearse replay CASE [--session ID] [--verify]");
  ReplayRequest req;
  req.source.file = args[2];
  req.o = parseOptions(args, 3, replayCommand());
  const std::string& file = req.source.file;
  req.source.fromDb = file.rfind("postgresql:", 0) == 0;
  req.source.service = req.source.fromDb ? file.substr(11) : std::string();
  if (!req.source.fromDb && !std::filesystem::exists(file)) throw UsageError(file + " does not exist");
  readMeasureOptions(req);
  loadThresholds(req);
  checkOneSessionOutputs(req.o);
  return req;
}

// --metrics-csv: every session's metrics, one row each (a trainer's spreadsheet across attempts); each replay verified.
int writeMetricsCsv(ReplayRequest& req) {
  Options& o = req.o;
  if (o.count("session") || o.count("metrics") || o.count("verify"))
    throw UsageError("--metrics-csv covers every session; --session, --metrics and --verify are for one");
  std::ostringstream csv;
  csv.precision(17);
  csv << "session,trainee,started_utc,complete,steps,duration_s,path_length_m,economy_of_motion,grasps,slips,cut_"
         "updates,vessel_cuts,max_force_n,"
         "mean_force_n,force_threshold_n,time_over_threshold_s,max_strain,cut_length_m,cut_deviation_mean_m,cut_"
         "deviation_max_m,tumour_breaches,"
         "tears,attachments_torn,clips,misplaced_clips,blood_loss_ml,energy_time_s,energy_on_structures,"
         "incorrect_actions,vessel_cuts_without_clips,force_over_limit,instrument_outside_view,checksums,"
         "checksums_differing\n";
  ReplayOptions ro = req.ro;
  ro.strain = true;
  auto opt = [](const auto& v) { return v ? std::to_string(*v) : std::string(); };  // empty: not determined
  auto quoted = [](const std::string& s) {
    std::string q = "\"";
    for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
    return q + "\"";
  };
  long differing = 0, damaged = 0;
  const auto sessions = req.source.list();
  for (const auto& s : sessions) {
    const ReplayResult r = replayRecording(req.source.load(s.id), ro);
    const SessionMetrics& m = r.metrics;
    differing += r.verify.mismatches;
    damaged += static_cast<long>(r.verify.damagedCheckpoints.size());
    csv << s.id << ',' << quoted(s.meta.trainee) << ',' << s.startedUtc << ',' << (s.complete ? 1 : 0) << ','
        << r.verify.steps << ',' << m.durationS << ',' << m.pathLengthM << ',' << m.economy << ',' << m.grasps << ','
        << m.slips << ',' << m.cuts << ',' << opt(m.vesselCuts) << ',' << m.maxForceN << ',' << m.meanForceN << ','
        << m.forceThresholdN << ',' << m.timeOverThresholdS << ',' << opt(m.maxStrain) << ',' << m.cutLengthM << ','
        << opt(m.cutDeviationMeanM) << ',' << opt(m.cutDeviationMaxM) << ',' << opt(m.tumourBreaches) << ','
        << opt(m.tears) << ',' << opt(m.attachmentsTorn) << ',' << m.clips << ',' << m.misplacedClips << ','
        << opt(m.bloodLossMl) << ',' << m.energyTimeS << ',' << m.energyOnStructures << ','
        << opt(m.incorrectCount("")) << ',' << opt(m.incorrectCount("vessel_cut_without_clips")) << ','
        << opt(m.incorrectCount("force_over_limit")) << ',' << opt(m.incorrectCount("outside_view")) << ','
        << r.verify.checked << ',' << r.verify.mismatches << '\n';
  }
  rehearse::writeFileAtomically(o["metrics-csv"], csv.str());
  std::printf("metrics of %zu sessions written to %s\n", sessions.size(), o["metrics-csv"].c_str());
  if (differing) {
    std::fprintf(stderr, "rehearse: %ld checksums differ on replay (column checksums_differing)\n", differing);
    return 4;
  }
  if (damaged) {
    std::fprintf(stderr, "rehearse: %ld checkpoints are damaged (rehearse replay CASE --session ID --verify names them)\n",
                 damaged);
    return 4;
  }
  return 0;
}

// Without --session: the list.
int printSessions(ReplayRequest& req) {
  const auto sessions = req.source.list();
  if (sessions.empty()) std::printf("%s holds no recorded session\n", req.source.file.c_str());
  for (const auto& s : sessions)
    std::printf("session %lld  %s  trainee '%s'  case '%s'  %ld steps%s\n", static_cast<long long>(s.id),
                s.startedUtc.c_str(), s.meta.trainee.c_str(), s.meta.caseName.c_str(), s.steps,
                s.complete ? "" : "  (cut short)");
  if (req.o.count("verify")) throw UsageError("--verify needs --session ID (the list above)");
  return 0;
}

std::int64_t sessionId(Options& o) {
  try {
    std::size_t used = 0;
    const std::int64_t id = std::stoll(o["session"], &used);
    if (used != o["session"].size()) throw std::invalid_argument("trailing");
    return id;
  } catch (const std::exception&) {
    throw UsageError("--session takes a session number, not '" + o["session"] + "'");
  }
}

// --metrics: the session's metrics, their verdicts and the incorrect actions as JSON.
void writeMetricsJson(const std::string& path, std::int64_t id, const Recording& rec, const ReplayResult& replayed,
                      const std::vector<Verdict>& verdicts) {
  nlohmann::json j = {{"session", id},
                      {"trainee", rec.summary.meta.trainee},
                      {"started_utc", rec.summary.startedUtc},
                      {"force_threshold_n", replayed.metrics.forceThresholdN},
                      {"replay_verified", replayVerified(replayed.verify)},
                      {"replay_check", replayCheckSentence(replayed.verify)},
                      {"checksums", replayed.verify.checked},
                      {"checksums_differing", replayed.verify.mismatches}};
  for (const auto& v : metricValues(replayed.metrics)) {
    j[v.name] = !v.value  ? nlohmann::json(nullptr)
                : v.count ? nlohmann::json(std::lround(*v.value))
                          : nlohmann::json(*v.value);
    if (!v.value) j[v.name + "_why"] = v.why;
  }
  nlohmann::json js = nlohmann::json::array();
  for (const auto& v : verdicts) {
    nlohmann::json row = {{"metric", v.metric.name}, {"result", resultWord(v.result)}};
    row["value"] = v.metric.value ? nlohmann::json(*v.metric.value) : nlohmann::json(nullptr);
    if (v.threshold.min) row["min"] = *v.threshold.min;
    if (v.threshold.max) row["max"] = *v.threshold.max;
    js.push_back(row);
  }
  j["verdicts"] = js;
  // The incorrect actions, each with its time (the rules the session was recorded with).
  nlohmann::json ia = nlohmann::json::array();
  for (const auto& a : replayed.metrics.incorrectActions)
    ia.push_back({{"rule", a.rule}, {"step", a.step}, {"time_s", a.time}, {"what", a.what}});
  j["incorrect_action_list"] = ia;
  if (!replayed.metrics.rulesError.empty()) j["incorrect_actions_why"] = replayed.metrics.rulesError;
  writeReport(path, j);
  std::printf("metrics written to %s\n", path.c_str());
}

// The incorrect actions, the replay check when it has something to say (and --verify does not), the verdicts.
void printFindings(bool verify, const ReplayResult& replayed, const std::vector<Verdict>& verdicts) {
  for (const auto& a : replayed.metrics.incorrectActions)
    std::printf("incorrect action at %.2f s (step %ld): %s: %s\n", a.time, a.step, a.rule.c_str(), a.what.c_str());
  if (!verify && replayed.verify.mismatches == 0 && !replayVerified(replayed.verify))
    std::printf("replay check: %s\n", replayCheckSentence(replayed.verify).c_str());
  for (const auto& v : verdicts) {
    const auto& m = v.metric;  // counts as whole numbers ("grasps: pass (1)")
    const std::string value = !m.value  ? m.why
                              : m.count ? std::to_string(std::llround(*m.value))
                                        : std::to_string(*m.value);
    std::printf("%s: %s (%s)\n", m.name.c_str(), resultWord(v.result), value.c_str());
  }
}

// --video and --report: drawn by a replayer that seeks from the sound checkpoints.
void writeVideoAndReport(ReplayRequest& req, const Recording& rec, const ReplayResult& replayed) {
  Options& o = req.o;
  int width = 640, height = 480;
  if (o.count("size")) {
    char x = 0;
    std::istringstream in(o["size"]);
    if (!(in >> width >> x >> height) || x != 'x' || !in.eof())
      throw UsageError("--size takes WIDTHxHEIGHT in pixels, e.g. 1280x720");
  }
  Replayer replayer(rec);
  replayer.avoidCheckpoints(replayed.verify);  // the video seeks from the sound ones
  for (const auto& [step, why] : replayed.verify.damagedCheckpoints)
    std::fprintf(stderr, "rehearse: the checkpoint after step %ld is damaged (%s): the video seeks past it\n", step,
                 why.c_str());
  ReviewRenderer renderer(rec.setup, width, height);
  if (o.count("video")) {
    const double fps = o.count("fps") ? parseNumber(o["fps"], "--fps") : 25.0;
    auto stepAt = [&](const std::string& key, long fallback) {
      if (!o.count(key)) return fallback;
      const double t = parseNumber(o[key], key == "from" ? "--from" : "--to");
      if (!(t >= 0)) throw UsageError("--" + key + " must be a time in seconds, 0 or more");
      long step = 0;
      for (const auto& s : replayed.timeline)
        if (s.time <= t + 1e-9) step = s.step;
      return step;
    };
    const long from = stepAt("from", 0), to = stepAt("to", replayer.steps());
    if (from >= to)
      throw UsageError("--from must come before --to within the session (" +
                       std::to_string(replayed.metrics.durationS) + " s)");
    const int frames = writeReviewVideo(replayer, renderer, replayed.timeline, from, to, fps, o["video"]);
    std::printf("video: %d frames of %dx%d at %g fps (steps %ld to %ld) written to %s\n", frames,
                renderer.camera().width, renderer.camera().height, fps, from, to, o["video"].c_str());
  }
  if (o.count("report")) {
    const ReviewReport report = makeReviewReport(rec, replayed, req.thresholds, replayer, renderer);
    writeReviewPdf(report, o["report"]);
    std::printf("report written to %s\n", o["report"].c_str());
  }
}

// Without --verify: metrics, a video or a report of a replay that is not the recorded run are written (they say so) but
// not taken as the trainee's: exit 4, as --verify and --metrics-csv do.
int replayCheckExit(std::int64_t id, const VerifyResult& v) {
  if (v.mismatches || !v.damagedCheckpoints.empty()) {
    std::fprintf(stderr, "rehearse: session %lld %s\n", static_cast<long long>(id), replayCheckSentence(v).c_str());
    return 4;
  }
  return 0;
}

// --verify: every checksum and checkpoint (exit 4 when one differs, or there is nothing to verify against).
int verifyExit(std::int64_t id, const VerifyResult& v) {
  if (v.mismatches) {
    std::fprintf(stderr,
                 "rehearse: session %lld does not replay: %ld of %ld checksums differ, the first after step %ld; %s\n",
                 static_cast<long long>(id), v.mismatches, v.checked, v.firstMismatch, replayProvenance(v).c_str());
    return 4;
  }
  if (v.checked == 0) {
    std::fprintf(stderr, "rehearse: session %lld has no checksum to verify against\n", static_cast<long long>(id));
    return 4;
  }
  if (!v.damagedCheckpoints.empty()) {
    for (const auto& [step, why] : v.damagedCheckpoints)
      std::fprintf(stderr, "rehearse: session %lld: the checkpoint after step %ld is damaged: %s\n",
                   static_cast<long long>(id), step, why.c_str());
    std::fprintf(stderr,
                 "rehearse: session %lld does not verify: %zu of %ld checkpoints are damaged (the run replays: all %ld "
                 "checksums match)\n",
                 static_cast<long long>(id), v.damagedCheckpoints.size(), v.checkpointsChecked, v.checked);
    return 4;
  }
  if (v.incompleteCheckpoints.empty())
    std::printf("verified: %ld steps replayed, all %ld checksums match, all %ld checkpoints restore the replay's state\n",
                v.steps, v.checked, v.checkpointsChecked);
  else
    std::printf("verified: %ld steps replayed, all %ld checksums match, %ld of %ld checkpoints restore the replay's "
                "state; %zu by an older build do not hold the instruments' or the field's whole state (seeking replays "
                "past them)\n",
                v.steps, v.checked, v.checkpointsChecked - static_cast<long>(v.incompleteCheckpoints.size()),
                v.checkpointsChecked, v.incompleteCheckpoints.size());
  std::printf("kernel: %s\n", v.replayed.kernel.c_str());
  return 0;
}

// --exact-check OUT.csv: every step (or every N, and every step with an event) taken again from the same start by exact
// Newton to a relative residual of 1e-10; the run's distance from that answer (mm, N) beside its own estimate, one row
// per step. Exit 4 when a step the run ended on its accuracy is farther than that accuracy, or an estimate is under half
// the truth (the estimate is what the window shows); steps exact Newton cannot resolve are counted and said, not judged.
int exactCheck(std::int64_t id, const Recording& rec, const Options& o) {
  simcore::ExactCheckOptions eo;
  if (o.count("every")) eo.every = parseCount(o.at("every"), "--every", 1, 1000000);
  const long steps = rec.summary.complete || rec.checksums.empty() ? rec.summary.steps : rec.checksums.rbegin()->first;
  // --from/--to: the span in seconds of simulated time (the steps that end inside it)
  const double dt = rec.setup.settings.timeStep;
  for (const char* key : {"from", "to"})
    if (o.count(key)) {
      const double t = parseNumber(o.at(key), key[0] == 'f' ? "--from" : "--to");
      if (!(t >= 0)) throw UsageError(std::string("--") + key + " must be a time in seconds, 0 or more");
      const long step = key[0] == 'f' ? std::max(1L, static_cast<long>(std::ceil(t / dt - 1e-9)))
                                      : static_cast<long>(std::floor(t / dt + 1e-9));
      (key[0] == 'f' ? eo.from : eo.to) = step;
    }
  if (eo.to >= 0 && eo.to < eo.from) throw UsageError("--to comes before --from: no step to check");
  const double asked = rec.setup.settings.accuracyPosition;
  const std::string out = o.at("exact-check");
  // The estimate is judged where the truth is over a tenth of the accuracy asked, or 1 um without one (below, on the
  // liver preset after a cut, a step ended on the relative residual estimated 0.16 um for 1.2 um: an error that cannot
  // move a step past what was asked, not resolved by the estimate's one solve).
  const double judged = std::max(1e-6, asked / 10);
  std::ofstream csv(out);
  if (!csv) throw UsageError("--exact-check: " + out + " cannot be written");
  csv << "step,time_s,events,outcome,ended_on_accuracy,residual,iterations,factorisations,estimate_mm,true_mm,"
         "force_estimate_n,force_error_n,force_n,exact_iterations,exact_events,resolved,own_converged_mm,own_to_exact_mm,exact_from_end_mm,why\n";
  long checked = 0, unresolved = 0, beyond = 0, under = 0, lowAt = -1, worstAt = -1, otherSolution = 0;
  double otherApart = 0;
  double worst = 0, worstForce = 0, lowest = 1e300;
  std::printf("checking session %lld against exact Newton (relative residual 1e-10), %s\n",
              static_cast<long long>(id), eo.every > 1 ? ("every " + std::to_string(eo.every) + " steps and every step with an event").c_str() : "every step");
  eo.each = [&](const simcore::StepTruth& t) {
    ++checked;
    std::string said;
    for (const auto& e : t.events) said += (said.empty() ? "" : " ") + e;
    std::string exactSaid;
    for (const auto& e : t.exactEvents) exactSaid += (exactSaid.empty() ? "" : " ") + e;
    csv << t.step << ',' << t.time << ",\"" << said << "\"," << static_cast<int>(t.report.outcome) << ','
        << t.report.withinAccuracy << ',' << t.report.residual << ',' << t.report.newtonIterations << ','
        << t.report.factorisations << ',' << 1e3 * t.report.errorPosition << ',' << 1e3 * t.errorPosition << ','
        << t.report.errorForce << ',' << t.errorForce << ',' << t.force << ',' << t.exactIterations << ",\""
        << exactSaid << "\"," << t.resolved << ',' << 1e3 * t.ownConverged << ',' << 1e3 * t.ownToExact << ','
        << 1e3 * t.exactFromEnd << ",\"" << t.why << "\"\n";
    if (!t.resolved) {
      ++unresolved;
      return true;
    }
    if (t.anotherSolution(asked)) {
      ++otherSolution;
      otherApart = std::max(otherApart, t.errorPosition);  // where exact Newton's other answer lies from the run
      return true;
    }
    if (t.errorPosition > worst) worst = t.errorPosition, worstAt = t.step;
    worstForce = std::max(worstForce, t.errorForce);
    if (t.report.withinAccuracy && asked > 0 && t.errorPosition > asked) ++beyond;
    if (t.errorPosition > judged && std::isfinite(t.report.errorPosition)) {
      const double ratio = t.report.errorPosition / t.errorPosition;
      if (ratio < lowest) lowest = ratio, lowAt = t.step;
      if (ratio < 0.5) ++under;
    }
    if (checked % 50 == 0) std::printf("  %ld steps checked, the largest error so far %.4f mm\n", checked, 1e3 * worst), std::fflush(stdout);
    return true;
  };
  simcore::checkAgainstExact(rec.setup, rec.events, steps, eo);
  std::printf("checked %ld of %ld steps: the largest distance from exact Newton's answer %.4f mm (step %ld), tool force %.4f N;"
              " %ld not resolved by exact Newton (no truth there)\n",
              checked, steps, 1e3 * worst, worstAt, worstForce, unresolved);
  if (otherSolution > 0)
    std::printf("%s where exact Newton went to another solution of the step's equations (up to %.4f mm away): the "
                "run's own method converged as far, or exact Newton started where the run ended, stays by the run's answer; not "
                "counted above\n",
                simcore::quantity(static_cast<std::size_t>(otherSolution), "step", "steps").c_str(), 1e3 * otherApart);
  if (lowAt >= 0)
    std::printf("the run's own estimate at least %.2f times the truth (step %ld) where the truth is over %.4f mm; %ld under "
                "half\n",
                lowest, lowAt, 1e3 * judged, under);
  if (asked > 0)
    std::printf("asked %.4f mm: %s ended on it %s farther\n", 1e3 * asked,
                simcore::quantity(static_cast<std::size_t>(beyond), "step", "steps").c_str(), beyond == 1 ? "is" : "are");
  else
    std::printf("no accuracy asked (the relative residual 1e-6 ended the steps)\n");
  std::printf("written %s\n", out.c_str());
  if (beyond > 0 || under > 0) {
    std::fprintf(stderr, "rehearse: session %lld: %s farther than the accuracy asked, %s under half the true error\n",
                 static_cast<long long>(id), simcore::quantity(static_cast<std::size_t>(beyond), "step", "steps").c_str(),
                 simcore::quantity(static_cast<std::size_t>(under), "estimate", "estimates").c_str());
    return 4;
  }
  return 0;
}

// --session ID: the session loaded and, when anything is asked of it, replayed once for all the outputs.
int replayOneSession(ReplayRequest& req) {
  Options& o = req.o;
  const std::int64_t id = sessionId(o);
  const Recording rec = req.source.load(id);
  std::printf("session %lld: %zu events, %zu checksums, %ld steps%s\n", static_cast<long long>(id), rec.events.size(),
              rec.checksums.size(), rec.summary.steps,
              rec.summary.complete ? "" : " (cut short: what was recorded is replayed)");
  if (o.count("exact-check")) {
    if (o.count("verify") || o.count("metrics") || o.count("video") || o.count("report"))
      throw UsageError("--exact-check replays on its own: ask it without --verify, --metrics, --video or --report");
    return exactCheck(id, rec, o);
  }
  if (o.count("every")) throw UsageError("--every is for --exact-check");
  if (!o.count("verify") && !o.count("metrics") && !o.count("video") && !o.count("report")) return 0;
  ReplayOptions ro = req.ro;
  ro.strain = o.count("metrics") || o.count("report") || !req.thresholds.empty();
  ro.timeline = o.count("video") || o.count("report");
  const ReplayResult replayed = replayRecording(rec, ro);
  const auto verdicts = judge(replayed.metrics, req.thresholds);
  if (o.count("metrics")) writeMetricsJson(o["metrics"], id, rec, replayed, verdicts);
  printFindings(o.count("verify") > 0, replayed, verdicts);
  if (o.count("video") || o.count("report")) writeVideoAndReport(req, rec, replayed);
  return o.count("verify") ? verifyExit(id, replayed.verify) : replayCheckExit(id, replayed.verify);
}

}  // namespace

int cmdReplay(const std::vector<std::string>& args) {
  ReplayRequest req = parseReplayRequest(args);
  if (req.o.count("metrics-csv")) return writeMetricsCsv(req);
  if (!req.o.count("session")) return printSessions(req);
  return replayOneSession(req);
}

int cmdPublish(const std::vector<std::string>& args) {
  std::vector<std::string> files;
  std::size_t i = 2;
  for (; i < args.size() && args[i].rfind("--", 0) != 0; ++i) files.push_back(args[i]);
  if (files.empty()) throw UsageError("publish needs case files: rehearse publish CASE... [--service NAME]");
  auto o = parseOptions(args, i, publishCommand());
  for (const auto& f : files)
    if (!std::filesystem::exists(f)) throw UsageError(f + " does not exist");
  TrainingDatabase db(o.count("service") ? o["service"] : std::string());
  std::vector<std::string> lines;  // said once every file is published (a database error: only the error)
  for (const auto& f : files) {
    const auto r = db.publish(f);
    lines.push_back(f + ": " + std::to_string(r.published) + " published, " + std::to_string(r.already) +
                    " already there, " + std::to_string(r.skipped) + " not published");
    for (const auto& n : r.notes) lines.push_back("  " + n);
  }
  for (const auto& line : lines) std::printf("%s\n", line.c_str());
  return 0;
}

const Command& replayCommand() {
  static const Command command{
      "replay",
      "  rehearse replay CASE [--session ID [--verify] [--metrics OUT.json] [--video OUT.mp4] [--report OUT.pdf]\n"
      "                [--from S] [--to S] [--fps N] [--size WxH] | --metrics-csv OUT.csv] [--force-threshold N]\n"
      "                [--thresholds T.json] [--planned-cut X,Y,Z:X,Y,Z] [--exact-check OUT.csv [--every N]]\n"
      "                                   the sessions recorded in CASE; --verify re-simulates one and compares "
      "every\n"
      "                                   recorded checksum (exit 4 when one differs); --metrics writes the "
      "session's\n"
      "                                   duration, path length, economy of motion, grasps, slips, cuts, forces, "
      "the\n"
      "                                   time over the force threshold (10 N by default), the largest tissue "
      "strain, the\n"
      "                                   cut's length and deviation from a planned line (m), structures damaged, "
      "and a\n"
      "                                   pass/fail per metric of T.json ({\"max_force_n\": {\"max\": 15}}); "
      "--video: the\n"
      "                                   span [--from, --to] s as MP4 (25 fps of simulated time, 640x480 unless "
      "given);\n"
      "                                   --report: a PDF with the metrics, their plots and key frames; "
      "--metrics-csv:\n"
      "                                   every session's metrics, one row each (exit 4 when a replay differs); "
      "CASE\n"
      "                                   postgresql:[SERVICE] reads the training database instead (below);\n"
      "                                   --exact-check: each step taken again by exact Newton from the same start,\n"
      "                                   its distance (mm, N) beside the run's estimate (exit 4: farther than asked)\n",
      {{"session", "ID", "the session to replay (the list without it)"},
       {"list", "", "list the sessions (the default without --session)"},
       {"verify", "", "re-simulate and compare every recorded checksum (exit 4 when one differs)"},
       {"metrics", "OUT.json", "the session's metrics and verdicts"},
       {"metrics-csv", "OUT.csv", "every session's metrics, one row each"},
       {"force-threshold", "N", "the force (N) the time over is measured against (default 10)"},
       {"thresholds", "T.json", "a pass/fail limit per metric"},
       {"planned-cut", "A:B", "the planned cut line, X,Y,Z:X,Y,Z in metres"},
       {"video", "OUT.mp4", "the span [--from, --to] as a video"},
       {"report", "OUT.pdf", "metrics, plots and key frames"},
       {"from", "S", "the video's (or --exact-check's) first second"},
       {"to", "S", "the video's (or --exact-check's) last second"},
       {"fps", "N", "the video's frames per second of simulated time (default 25)"},
       {"size", "WxH", "the video's size (default 640x480)"},
       {"exact-check", "OUT.csv", "each step against exact Newton's answer from the same start, one row per step"},
       {"every", "N", "--exact-check every N steps (and every step with an event)"}},
      cmdReplay};
  return command;
}

const Command& publishCommand() {
  static const Command command{
      "publish",
      "  rehearse publish CASE... [--service NAME]\n"
      "                                   publish the complete sessions of case files into the training database\n"
      "                                   (PostgreSQL; the connection from the libpq service NAME or the "
      "environment:\n"
      "                                   PGHOST, PGPORT, PGDATABASE, PGUSER, PGPASSFILE, PGSSLMODE); idempotent: a\n"
      "                                   session already there is not written again; each is replayed and verified "
      "first\n",
      {{"service", "NAME", "the libpq service of the training database (else the PG* environment)"}},
      cmdPublish};
  return command;
}

}  // namespace rehearse::app::cli
