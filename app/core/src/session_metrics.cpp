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

}  // namespace

ReplayResult replayRecording(const Recording& r, const ReplayOptions& options) {
  const double forceThresholdN = options.forceThresholdN;
  ReplayResult out;
  VerifyResult& v = out.verify;
  SessionMetrics& m = out.metrics;
  m.forceThresholdN = forceThresholdN;
  // What this session cannot say, in words.
  int tumourLabel = 0;
  for (const auto& [label, name] : r.setup.mesh.labelNames)
    if (simcore::structureKind(name) == simcore::StructureKind::Tumour) tumourLabel = label;
  if (r.setup.mesh.namesAVessel()) {
    m.vesselCuts = 0;
    m.bloodLossMl = 0.0;
  } else
    m.vesselWhy = "the case names no vessel (no element label named vessel, vein or artery)";
  if (tumourLabel)
    m.tumourBreaches = 0;
  else
    m.tumourWhy = "the case marks no tumour (no element label named as one: tumour, lesion, metastasis...)";
  bool tears = r.setup.material.tearStrain > 0;
  for (const auto& [label, mat] : r.setup.byLabel) tears = tears || mat.tearStrain > 0;
  for (const auto& e : r.events) tears = tears || (e.kind == simcore::InputKind::Parameter && e.name == "tear_strain");
  if (tears) {
    m.tears = 0;
    m.attachmentsTorn = 0;
  } else {
    m.attachmentsWhy = "no material of the case declares a tear strain: nothing can tear";
  }
  if (!options.plannedCut) m.cutDeviationWhy = "the case has no planned cut line";
  // The incorrect actions under the rules the session was recorded with.
  std::optional<IncorrectActionFinder> finder;
  try {
    finder.emplace(parseActionRules(r.summary.meta.rules));
    for (const auto& [rule, words] : actionRuleNames())
      if (const auto why = finder->notCounted(rule)) m.ruleNotCounted[rule] = *why;
  } catch (const std::exception& e) {
    m.rulesError = std::string("the session's incorrect-action rules cannot be read: ") + e.what();
  }
  double deviationSum = 0;
  long cuttingSteps = 0;
  std::vector<Eigen::Vector3d> rest = r.setup.rest.empty() ? r.setup.mesh.points : r.setup.rest;
  bool wasCutting = false;
  double previousForce = 0;
  Eigen::Vector3d lastCut = Eigen::Vector3d::Zero();
  const long steps = r.summary.complete || r.checksums.empty() ? r.summary.steps : r.checksums.rbegin()->first;
  double time = 0;  // simulated (the time step may be edited during the session: each step's own length counts)
  bool seen = false;
  Eigen::Vector3d first = Eigen::Vector3d::Zero(), last = Eigen::Vector3d::Zero();
  double forceSum = 0;
  long forceSteps = 0;
  // An instrument swapped for another (grasper -> hook): the tip's jump between them is not a path travelled.
  std::set<long> swapped;  // steps whose snapshot shows the new instrument's first pose
  double straight = 0;     // the straight distances of the instruments swapped out
  {
    int lastTool = -1;
    for (const auto& e : r.events)
      if (e.kind == simcore::InputKind::ToolPose) {
        if (lastTool >= 0 && e.tool != lastTool) swapped.insert(e.step + 1);
        lastTool = e.tool;
      }
  }
  v.recorded = r.numerics;
  v.replayed = currentNumerics(r.setup, REHEARSE_APP_VERSION);
  // Every checkpoint is checked against the straight replay (issue 60): it decodes, and the state it restores (encoded
  // again, setups by their hashes) is the replay's own at its step. A seek starts from these.
  const std::set<long> checkpointSteps(r.checkpointSteps.begin(), r.checkpointSteps.end());
  const bool canLoadCheckpoints = options.checkpoints && (r.checkpointSource || !r.path.empty());
  auto checkCheckpoint = [&](long step, const simcore::Session& session) {
    ++v.checkpointsChecked;
    try {
      simcore::Checkpoint stored =
          r.checkpointSource ? r.checkpointSource(step) : loadCheckpoint(r.path, r.summary.id, step);
      // As a seek restores it (Replayer::startAt): the setup as a replay runs it (the refresh deferred to the recorded
      // swaps).
      stored.setup = simcore::replaySetup(std::move(stored.setup));
      if (stored.pendingChange) stored.pendingChange->setup = simcore::replaySetup(std::move(stored.pendingChange->setup));
      if (stored.step != step)
        v.damagedCheckpoints.emplace_back(step, "it says it was taken after step " + std::to_string(stored.step));
      else if (const auto parts = checkpointDifference(stored, session.checkpoint()); !parts.empty()) {
        // A recording made before recordings named their kernels was checkpointed by an older build, whose checkpoints
        // did not carry the instruments' and the field's whole state (and the cut's, as it is now): such a checkpoint
        // is sound for what it holds but a seek from it would not land on the straight run. Incomplete, not damaged.
        const bool olderFormat = r.numerics.kernel.empty() &&
                                 std::all_of(parts.begin(), parts.end(), [](const std::string& p) {
                                   return p == "instruments" || p == "operative field" || p == "cut under way";
                                 });
        (olderFormat ? v.incompleteCheckpoints : v.damagedCheckpoints)
            .emplace_back(step, "it restores another state than the replay's at that step (" + joinedParts(parts) + ")");
      }
    } catch (const std::exception& e) {
      v.damagedCheckpoints.emplace_back(step, e.what());
    }
  };
  // A checkpoint row deleted from the store (issue 60): the recorder takes one every N steps after the last and just
  // after each cut (Recorder::afterStep), so the replay knows where each one belongs once N is known. N is not stored:
  // it is the most common gap between the stored checkpoints (a deleted row makes one gap of 2N among many of N). Only
  // for recordings by a build that names its kernels (older recorders followed other rules) with two gaps to go by.
  long checkpointEvery = 0, lastExpectedCheckpoint = 0;
  if (canLoadCheckpoints && !r.numerics.kernel.empty() && checkpointSteps.size() >= 2) {
    std::map<long, int> gaps;
    long previous = 0;
    for (const long s : checkpointSteps) {
      ++gaps[s - previous];
      previous = s;
    }
    int most = 0;
    for (const auto& [gap, n] : gaps)
      if (n > most) most = n, checkpointEvery = gap;
    if (most < 2) checkpointEvery = 0;  // nothing to go by
  }
  simcore::replaySession(r.setup, r.events, steps, [&](long step, const simcore::Session& session) {
    ++v.steps;
    if (const auto it = r.checksums.find(step); it != r.checksums.end()) {
      ++v.checked;
      if (stateChecksum(session.state()) != it->second) {
        ++v.mismatches;
        if (v.firstMismatch < 0) v.firstMismatch = step;
      }
    }
    if (canLoadCheckpoints && checkpointSteps.count(step)) checkCheckpoint(step, session);
    const auto snap = session.snapshot();
    if (checkpointEvery > 0) {
      const auto& events = snap->events;
      const bool cut = std::find(events.begin(), events.end(), "cut") != events.end();
      if (step - lastExpectedCheckpoint >= checkpointEvery || cut) {
        lastExpectedCheckpoint = step;
        if (!checkpointSteps.count(step)) {
          ++v.checkpointsChecked;
          v.damagedCheckpoints.emplace_back(
              step, "its row is missing from the recording: the others were taken every " +
                        std::to_string(checkpointEvery) + " steps and after each cut");
        }
      }
    }
    const auto& tool = snap->tool;
    if (tool.present) {
      if (!seen) first = last = tool.tip;
      if (swapped.count(step)) {  // economy per instrument: its own straight distance
        straight += (last - first).norm();
        first = last = tool.tip;
      }
      m.pathLengthM += (tool.tip - last).norm();
      last = tool.tip;
      seen = true;
    }
    const double f = tool.force.norm();
    m.maxForceN = std::max(m.maxForceN, f);
    if (f > 0) {
      forceSum += f;
      ++forceSteps;
    }
    if (m.bloodLossMl) m.bloodLossMl = 1e6 * snap->field.bloodLoss;
    m.energyTimeS = snap->field.energyTime;
    const bool over = f > forceThresholdN;
    if (over) m.timeOverThresholdS += snap->time - time;
    const bool overBefore = previousForce > forceThresholdN;
    previousForce = f;
    time = snap->time;
    simcore::EventCounts c;
    c.add(snap->events);
    m.grasps += c.grasps;
    m.slips += c.slips;
    m.cuts += c.cuts;
    m.clips += c.clips;
    m.misplacedClips += c.misplacedClips;
    m.energyOnStructures += c.energyOnStructures;
    if (m.tears) *m.tears += c.tears;
    if (m.attachmentsTorn) *m.attachmentsTorn += c.attachmentsTorn;
    if (m.vesselCuts) *m.vesselCuts += c.vesselCuts;
    for (const auto& e : snap->events)
      if (tumourLabel && simcore::cutLabelOf(e) == tumourLabel) ++*m.tumourBreaches;
    if (tool.present && tool.cutting) {
      if (wasCutting) m.cutLengthM += (tool.tip - lastCut).norm();
      lastCut = tool.tip;
      if (options.plannedCut) {
        const double d = distanceToSegment(tool.tip, options.plannedCut->first, options.plannedCut->second);
        deviationSum += d;
        ++cuttingSteps;
        m.cutDeviationMaxM = std::max(m.cutDeviationMaxM.value_or(0.0), d);
      }
    }
    wasCutting = tool.present && tool.cutting;
    std::vector<IncorrectAction> incorrect;
    if (finder) {
      IncorrectActionFinder::StepFacts facts;
      facts.step = step;
      facts.time = snap->time;
      facts.toolPresent = tool.present;
      facts.tip = tool.tip;
      facts.holding = !tool.held.empty();
      facts.cutting = tool.cutting;
      facts.energy = snap->field.energy;
      facts.force = f;
      facts.events = &snap->events;
      incorrect = finder->step(facts);
    }
    double strain = 0;
    if (options.strain) {
      const auto& restNow = snap->surface ? snap->surface->rest : rest;
      strain = snap->tets ? maxGreenStrain(restNow, snap->positions, *snap->tets) : 0;
      m.maxStrain = std::max(m.maxStrain.value_or(0.0), strain);
    }
    if (options.timeline) {
      TimelineSample t;
      t.step = step;
      t.time = snap->time;
      t.toolPresent = tool.present;
      t.tip = tool.tip;
      t.force = f;
      t.strain = strain;
      t.holding = !tool.held.empty();
      t.cutting = tool.cutting;
      t.newInstrument = swapped.count(step) > 0;
      t.events = snap->events;
      if (over && !overBefore) t.events.push_back(simcore::eventWord(simcore::EventKind::ForceOverThreshold));
      for (const auto& a : incorrect) t.events.push_back(simcore::incorrectActionWord(a.rule));
      out.timeline.push_back(std::move(t));
    }
    if (options.progress && !options.progress(step, steps, out)) throw ReplayStopped();
  });
  if (options.plannedCut) {
    if (cuttingSteps)
      m.cutDeviationMeanM = deviationSum / static_cast<double>(cuttingSteps);
    else
      m.cutDeviationWhy = "the blade never cut";
  }
  if (finder) m.incorrectActions = finder->found();
  m.durationS = time;
  m.meanForceN = forceSteps ? forceSum / static_cast<double>(forceSteps) : 0;
  m.economy = m.pathLengthM > 0 ? (straight + (last - first).norm()) / m.pathLengthM : 0;
  return out;
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
