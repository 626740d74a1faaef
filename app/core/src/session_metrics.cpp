// A recorded session's metrics: one replay that compares its checksums and measures the session (motion, events,
// forces, strain, the cut against a planned line, structures damaged). The one table the command line, the review
// window and the PDF read is review.cpp's metricValues.
#include "rehearse/app/recording.hpp"
#include "rehearse/app/incorrect_actions.hpp"

#include "rehearse/app/review.hpp"

#include <rehearse/simcore/session/events.hpp>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <functional>
#include <map>
#include <set>

namespace rehearse::app {

ReplayResult replayRecording(const Recording& r, double forceThresholdN) {
  ReplayOptions o;
  o.forceThresholdN = forceThresholdN;
  return replayRecording(r, o);
}

namespace {
double distanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double len2 = d.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * d)).norm();
}
}  // namespace

namespace {
// Which parts of a stored checkpoint differ from the straight replay's at its step (none: empty). Each part is put into
// the replay's checkpoint in turn and the encodings compared, so every byte a checkpoint carries counts.
std::vector<std::string> checkpointDifference(const simcore::Checkpoint& stored, const simcore::Checkpoint& replayed) {
  const std::string reference = encodeCheckpointState(replayed);
  if (encodeCheckpointState(stored) == reference) return {};
  std::vector<std::string> parts;
  auto differs = [&](const char* what, const std::function<void(simcore::Checkpoint&)>& take) {
    simcore::Checkpoint mixed = replayed;
    take(mixed);
    if (encodeCheckpointState(mixed) != reference) parts.push_back(what);
  };
  if (stateChecksum(stored.state) != stateChecksum(replayed.state)) parts.push_back("positions and velocities");
  else differs("solver state", [&](simcore::Checkpoint& c) { c.state = stored.state; });
  differs("body setup", [&](simcore::Checkpoint& c) { c.setup = stored.setup; });
  differs("instruments", [&](simcore::Checkpoint& c) { c.tool = stored.tool; });
  differs("operative field", [&](simcore::Checkpoint& c) { c.field = stored.field; });
  differs("cut under way", [&](simcore::Checkpoint& c) {
    c.pendingChange = stored.pendingChange;
    c.restOfSweep = stored.restOfSweep;
  });
  if (parts.empty()) parts.push_back("bytes");
  return parts;
}

std::string joinedParts(const std::vector<std::string>& parts) {
  std::string out = "its ";
  for (std::size_t i = 0; i < parts.size(); ++i) out += (i ? (i + 1 == parts.size() ? " and " : ", ") : "") + parts[i];
  return out + (parts.size() > 1 ? " differ" : " differs");
}

// One replay of a recorded session, in its stages: open (what the session can and cannot measure, in words), verify
// (where the checkpoints belong), the steps (each compared and measured in turn), then the metrics of the whole run.
class SessionReplay {
 public:
  SessionReplay(const Recording& r, const ReplayOptions& options)
      : r_(r),
        options_(options),
        forceThresholdN_(options.forceThresholdN),
        rest_(r.setup.rest.empty() ? r.setup.mesh.points : r.setup.rest),
        steps_(r.summary.complete || r.checksums.empty() ? r.summary.steps : r.checksums.rbegin()->first) {}
  SessionReplay(const SessionReplay&) = delete;
  SessionReplay& operator=(const SessionReplay&) = delete;

  ReplayResult run() {
    open();
    findInstrumentSwaps();
    prepareVerification();
    simcore::replaySession(r_.setup, r_.events, steps_,
                           [this](long step, const simcore::Session& session) { replayStep(step, session); });
    finish();
    return std::move(out_);
  }

 private:
  // What this session cannot say, in words; the incorrect actions under the rules the session was recorded with.
  void open() {
    m_.forceThresholdN = forceThresholdN_;
    for (const auto& [label, name] : r_.setup.mesh.labelNames)
      if (simcore::structureKind(name) == simcore::StructureKind::Tumour) tumourLabel_ = label;
    if (r_.setup.mesh.namesAVessel()) {
      m_.vesselCuts = 0;
      m_.bloodLossMl = 0.0;
    } else
      m_.vesselWhy = "the case names no vessel (no element label named vessel, vein or artery)";
    if (tumourLabel_)
      m_.tumourBreaches = 0;
    else
      m_.tumourWhy = "the case marks no tumour (no element label named as one: tumour, lesion, metastasis...)";
    bool tears = r_.setup.material.tearStrain > 0;
    for (const auto& [label, mat] : r_.setup.byLabel) tears = tears || mat.tearStrain > 0;
    for (const auto& e : r_.events)
      tears = tears || (e.kind == simcore::InputKind::Parameter && e.name == "tear_strain");
    if (tears) {
      m_.tears = 0;
      m_.attachmentsTorn = 0;
    } else {
      m_.attachmentsWhy = "no material of the case declares a tear strain: nothing can tear";
    }
    if (!options_.plannedCut) m_.cutDeviationWhy = "the case has no planned cut line";
    try {
      finder_.emplace(parseActionRules(r_.summary.meta.rules));
      for (const auto& [rule, words] : actionRuleNames())
        if (const auto why = finder_->notCounted(rule)) m_.ruleNotCounted[rule] = *why;
    } catch (const std::exception& e) {
      m_.rulesError = std::string("the session's incorrect-action rules cannot be read: ") + e.what();
    }
  }

  // An instrument swapped for another (grasper -> hook): the tip's jump between them is not a path travelled.
  void findInstrumentSwaps() {
    int lastTool = -1;
    for (const auto& e : r_.events)
      if (e.kind == simcore::InputKind::ToolPose) {
        if (lastTool >= 0 && e.tool != lastTool) swapped_.insert(e.step + 1);
        lastTool = e.tool;
      }
  }

  // The kernels on both sides; which steps have a checkpoint, and every how many steps one is expected.
  void prepareVerification() {
    v_.recorded = r_.numerics;
    v_.replayed = currentNumerics(r_.setup, REHEARSE_APP_VERSION);
    // Every checkpoint is checked against the straight replay (issue 60): it decodes, and the state it restores
    // (encoded again, setups by their hashes) is the replay's own at its step. A seek starts from these.
    checkpointSteps_.insert(r_.checkpointSteps.begin(), r_.checkpointSteps.end());
    canLoadCheckpoints_ = options_.checkpoints && (r_.checkpointSource || !r_.path.empty());
    // A checkpoint row deleted from the store (issue 60): the recorder takes one every N steps after the last and just
    // after each cut (Recorder::afterStep), so the replay knows where each one belongs once N is known. N is not
    // stored: it is the most common gap between the stored checkpoints (a deleted row makes one gap of 2N among many
    // of N). Only for recordings by a build that names its kernels (older recorders followed other rules) with two
    // gaps to go by.
    if (canLoadCheckpoints_ && !r_.numerics.kernel.empty() && checkpointSteps_.size() >= 2) {
      std::map<long, int> gaps;
      long previous = 0;
      for (const long s : checkpointSteps_) {
        ++gaps[s - previous];
        previous = s;
      }
      int most = 0;
      for (const auto& [gap, n] : gaps)
        if (n > most) most = n, checkpointEvery_ = gap;
      if (most < 2) checkpointEvery_ = 0;  // nothing to go by
    }
  }

  void replayStep(long step, const simcore::Session& session) {
    compareChecksum(step, session);
    if (canLoadCheckpoints_ && checkpointSteps_.count(step)) checkCheckpoint(step, session);
    const auto snap = session.snapshot();
    expectCheckpoint(step, snap->events);
    const auto& tool = snap->tool;
    measureMotion(step, tool);
    const double f = tool.force.norm();
    const bool crossed = measureForce(f, *snap);
    countEvents(snap->events);
    measureCut(tool);
    const std::vector<IncorrectAction> incorrect = findIncorrectActions(step, *snap, f);
    const double strain = measureStrain(*snap);
    if (options_.timeline) addSample(step, *snap, f, strain, crossed, incorrect);
    if (options_.progress && !options_.progress(step, steps_, out_)) throw ReplayStopped();
  }

  void compareChecksum(long step, const simcore::Session& session) {
    ++v_.steps;
    if (const auto it = r_.checksums.find(step); it != r_.checksums.end()) {
      ++v_.checked;
      if (stateChecksum(session.state()) != it->second) {
        ++v_.mismatches;
        if (v_.firstMismatch < 0) v_.firstMismatch = step;
      }
    }
  }

  // The checkpoint stored after `step` against the replay's state there: damaged, incomplete (an older build's) or
  // sound.
  void checkCheckpoint(long step, const simcore::Session& session) {
    ++v_.checkpointsChecked;
    try {
      simcore::Checkpoint stored =
          r_.checkpointSource ? r_.checkpointSource(step) : loadCheckpoint(r_.path, r_.summary.id, step);
      // As a seek restores it (Replayer::startAt): the setup as a replay runs it (the refresh deferred to the recorded
      // swaps).
      stored.setup = simcore::replaySetup(std::move(stored.setup));
      if (stored.pendingChange) stored.pendingChange->setup = simcore::replaySetup(std::move(stored.pendingChange->setup));
      if (stored.step != step)
        v_.damagedCheckpoints.emplace_back(step, "it says it was taken after step " + std::to_string(stored.step));
      else if (const auto parts = checkpointDifference(stored, session.checkpoint()); !parts.empty()) {
        // A recording made before recordings named their kernels was checkpointed by an older build, whose checkpoints
        // did not carry the instruments' and the field's whole state (and the cut's, as it is now): such a checkpoint
        // is sound for what it holds but a seek from it would not land on the straight run. Incomplete, not damaged.
        const bool olderFormat = r_.numerics.kernel.empty() &&
                                 std::all_of(parts.begin(), parts.end(), [](const std::string& p) {
                                   return p == "instruments" || p == "operative field" || p == "cut under way";
                                 });
        (olderFormat ? v_.incompleteCheckpoints : v_.damagedCheckpoints)
            .emplace_back(step, "it restores another state than the replay's at that step (" + joinedParts(parts) + ")");
      }
    } catch (const std::exception& e) {
      v_.damagedCheckpoints.emplace_back(step, e.what());
    }
  }

  // A step where the recorder took a checkpoint (N steps after the last, or a cut) whose row is not in the recording.
  void expectCheckpoint(long step, const std::vector<std::string>& events) {
    if (checkpointEvery_ <= 0) return;
    const bool cut = std::find(events.begin(), events.end(), "cut") != events.end();
    if (step - lastExpectedCheckpoint_ >= checkpointEvery_ || cut) {
      lastExpectedCheckpoint_ = step;
      if (!checkpointSteps_.count(step)) {
        ++v_.checkpointsChecked;
        v_.damagedCheckpoints.emplace_back(
            step, "its row is missing from the recording: the others were taken every " +
                      std::to_string(checkpointEvery_) + " steps and after each cut");
      }
    }
  }

  // The tip's path (economy per instrument: its own straight distance).
  void measureMotion(long step, const simcore::ToolState& tool) {
    if (!tool.present) return;
    if (!seen_) first_ = last_ = tool.tip;
    if (swapped_.count(step)) {
      straight_ += (last_ - first_).norm();
      first_ = last_ = tool.tip;
    }
    m_.pathLengthM += (tool.tip - last_).norm();
    last_ = tool.tip;
    seen_ = true;
  }

  // The force's largest, its sum and the time over the threshold; the field's blood lost and energy time. True when
  // the force went over the threshold at this step.
  bool measureForce(double f, const simcore::Snapshot& snap) {
    m_.maxForceN = std::max(m_.maxForceN, f);
    if (f > 0) {
      forceSum_ += f;
      ++forceSteps_;
    }
    if (m_.bloodLossMl) m_.bloodLossMl = 1e6 * snap.field.bloodLoss;
    m_.energyTimeS = snap.field.energyTime;
    const bool over = f > forceThresholdN_;
    if (over) m_.timeOverThresholdS += snap.time - time_;
    const bool overBefore = previousForce_ > forceThresholdN_;
    previousForce_ = f;
    time_ = snap.time;
    return over && !overBefore;
  }

  void countEvents(const std::vector<std::string>& events) {
    simcore::EventCounts c;
    c.add(events);
    m_.grasps += c.grasps;
    m_.slips += c.slips;
    m_.cuts += c.cuts;
    m_.clips += c.clips;
    m_.misplacedClips += c.misplacedClips;
    m_.energyOnStructures += c.energyOnStructures;
    if (m_.tears) *m_.tears += c.tears;
    if (m_.attachmentsTorn) *m_.attachmentsTorn += c.attachmentsTorn;
    if (m_.vesselCuts) *m_.vesselCuts += c.vesselCuts;
    for (const auto& e : events)
      if (tumourLabel_ && simcore::cutLabelOf(e) == tumourLabel_) ++*m_.tumourBreaches;
  }

  // The blade's path while it cuts, and its distance from the planned line.
  void measureCut(const simcore::ToolState& tool) {
    if (tool.present && tool.cutting) {
      if (wasCutting_) m_.cutLengthM += (tool.tip - lastCut_).norm();
      lastCut_ = tool.tip;
      if (options_.plannedCut) {
        const double d = distanceToSegment(tool.tip, options_.plannedCut->first, options_.plannedCut->second);
        deviationSum_ += d;
        ++cuttingSteps_;
        m_.cutDeviationMaxM = std::max(m_.cutDeviationMaxM.value_or(0.0), d);
      }
    }
    wasCutting_ = tool.present && tool.cutting;
  }

  std::vector<IncorrectAction> findIncorrectActions(long step, const simcore::Snapshot& snap, double f) {
    if (!finder_) return {};
    IncorrectActionFinder::StepFacts facts;
    facts.step = step;
    facts.time = snap.time;
    facts.toolPresent = snap.tool.present;
    facts.tip = snap.tool.tip;
    facts.holding = !snap.tool.held.empty();
    facts.cutting = snap.tool.cutting;
    facts.energy = snap.field.energy;
    facts.force = f;
    facts.events = &snap.events;
    return finder_->step(facts);
  }

  // The tissue's largest strain at this step (0 unless asked for).
  double measureStrain(const simcore::Snapshot& snap) {
    if (!options_.strain) return 0;
    const auto& restNow = snap.surface ? snap.surface->rest : rest_;
    const double strain = snap.tets ? maxGreenStrain(restNow, snap.positions, *snap.tets) : 0;
    m_.maxStrain = std::max(m_.maxStrain.value_or(0.0), strain);
    return strain;
  }

  void addSample(long step, const simcore::Snapshot& snap, double f, double strain, bool crossed,
                 const std::vector<IncorrectAction>& incorrect) {
    TimelineSample t;
    t.step = step;
    t.time = snap.time;
    t.toolPresent = snap.tool.present;
    t.tip = snap.tool.tip;
    t.force = f;
    t.strain = strain;
    t.holding = !snap.tool.held.empty();
    t.cutting = snap.tool.cutting;
    t.newInstrument = swapped_.count(step) > 0;
    t.events = snap.events;
    if (crossed) t.events.push_back(simcore::eventWord(simcore::EventKind::ForceOverThreshold));
    for (const auto& a : incorrect) t.events.push_back(simcore::incorrectActionWord(a.rule));
    out_.timeline.push_back(std::move(t));
  }

  // What needs the whole run: the cut's mean deviation, the incorrect actions, the duration, the mean force, economy.
  void finish() {
    if (options_.plannedCut) {
      if (cuttingSteps_)
        m_.cutDeviationMeanM = deviationSum_ / static_cast<double>(cuttingSteps_);
      else
        m_.cutDeviationWhy = "the blade never cut";
    }
    if (finder_) m_.incorrectActions = finder_->found();
    m_.durationS = time_;
    m_.meanForceN = forceSteps_ ? forceSum_ / static_cast<double>(forceSteps_) : 0;
    m_.economy = m_.pathLengthM > 0 ? (straight_ + (last_ - first_).norm()) / m_.pathLengthM : 0;
  }

  const Recording& r_;
  const ReplayOptions& options_;
  const double forceThresholdN_;
  ReplayResult out_;
  VerifyResult& v_ = out_.verify;
  SessionMetrics& m_ = out_.metrics;
  int tumourLabel_ = 0;
  std::optional<IncorrectActionFinder> finder_;
  const std::vector<Eigen::Vector3d>& rest_;  // the elements' rest positions before any cut
  const long steps_;
  // Verification.
  std::set<long> checkpointSteps_;
  bool canLoadCheckpoints_ = false;
  long checkpointEvery_ = 0, lastExpectedCheckpoint_ = 0;
  // Motion: the tip's first and last positions (per instrument), the steps whose snapshot shows a new instrument's
  // first pose, the straight distances of the instruments swapped out.
  bool seen_ = false;
  Eigen::Vector3d first_ = Eigen::Vector3d::Zero(), last_ = Eigen::Vector3d::Zero();
  std::set<long> swapped_;
  double straight_ = 0;
  // Force: its sum over the steps with one, the previous step's, the simulated time (the time step may be edited
  // during the session: each step's own length counts).
  double forceSum_ = 0;
  long forceSteps_ = 0;
  double previousForce_ = 0;
  double time_ = 0;
  // The cut.
  bool wasCutting_ = false;
  Eigen::Vector3d lastCut_ = Eigen::Vector3d::Zero();
  double deviationSum_ = 0;
  long cuttingSteps_ = 0;
};

}  // namespace

ReplayResult replayRecording(const Recording& r, const ReplayOptions& options) {
  return SessionReplay(r, options).run();
}

std::optional<int> SessionMetrics::incorrectCount(const std::string& rule, std::string* why) const {
  auto say = [&](const std::string& w) {
    if (why) *why = w;
    return std::optional<int>();
  };
  if (!rulesError.empty()) return say(rulesError);
  if (rule.empty()) return static_cast<int>(incorrectActions.size());  // all of them
  if (const auto it = ruleNotCounted.find(rule); it != ruleNotCounted.end()) return say(it->second);
  return static_cast<int>(std::count_if(incorrectActions.begin(), incorrectActions.end(),
                                        [&](const IncorrectAction& a) { return a.rule == rule; }));
}

}  // namespace rehearse::app
