#include <rehearse/simcore/session/session.hpp>
#include <rehearse/simcore/session/forceloop.hpp>
#include <rehearse/simcore/input_ranges.hpp>
#include "grasplimit.hpp"

#include <algorithm>
#include <numeric>
#include <array>
#include <cmath>
#include <limits>
#include <set>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

namespace rehearse::simcore {
namespace {
// Where the jaws held the tissue at the last step's end: the held nodes at their offsets from them (the hold's rows),
// averaged. (What the grasp limit moves the jaws from, and what a pull is measured from.)
Eigen::Vector3d gripOf(const ToolState& tool, const Eigen::VectorXd& x) {
  Eigen::Vector3d grip = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < tool.held.size(); ++k)
    grip += x.segment<3>(3 * static_cast<Eigen::Index>(tool.held[k])) - tool.heldOffset[k];
  return grip / static_cast<double>(tool.held.size());
}
}  // namespace

Eigen::Vector3d defaultTrocar(const std::vector<Eigen::Vector3d>& rest) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : rest) c += p;
  c /= static_cast<double>(std::max<std::size_t>(1, rest.size()));
  double r = 0;
  for (const auto& p : rest) r = std::max(r, (p - c).norm());
  return c + 2 * r * Eigen::Vector3d(0, -1, -2).normalized();
}

Session::Session(BodySetup setup) : setup_(std::move(setup)), started_(std::chrono::steady_clock::now()) {
  if (const std::string why = cauteryProblem(setup_.tools.cautery); !why.empty())
    throw MeshError("The scene cannot be simulated: " + why + ".");
  if (!std::isfinite(setup_.material.tearStrain) || setup_.material.tearStrain < 0)
    throw MeshError("The tissue's tear strain is negative.");
  for (const auto& [label, m] : setup_.byLabel)
    if (!std::isfinite(m.tearStrain) || m.tearStrain < 0)
      throw MeshError("Label " + std::to_string(label) + "'s tear strain is negative.");
  body_ = makeBody(setup_);
  if (!setup_.tools.trocar) setup_.tools.trocar = defaultTrocar(body_->restPositions());
  {
    // The cut's quality floor: the stated one, or half the uncut mesh's worst element when that is poorer.
    const auto& rest = body_->restPositions();
    double worst = 1;
    for (const auto& t : body_->tetrahedra())
      worst =
          std::min(worst, tetShapeQuality(rest[static_cast<std::size_t>(t[0])], rest[static_cast<std::size_t>(t[1])],
                                          rest[static_cast<std::size_t>(t[2])], rest[static_cast<std::size_t>(t[3])]));
    setup_.tools.cut.minQuality = std::min(setup_.tools.cut.minQuality, 0.5 * worst);
  }
  elementsChanged();
  uncut_ = setup_;
  {
    const auto& rest = body_->restPositions();
    double sum = 0;
    std::size_t count = 0;
    for (const auto& t : body_->tetrahedra())
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b)
          sum += (rest[static_cast<std::size_t>(t[static_cast<std::size_t>(a)])] -
                  rest[static_cast<std::size_t>(t[static_cast<std::size_t>(b)])])
                     .norm(),
              ++count;
    meanEdge_ = count ? sum / static_cast<double>(count) : 0;
  }
  state_ = body_->initialState();
  updateSurfaceNodes();
  StepReport rest;
  rest.ok = true;
  rest.outcome = StepStatus::Converged;  // no step taken: nothing left unsolved
  publish(rest, {});
  loop_.start([this] { run(); });
}

Session::~Session() {
  loop_.stop();
}

void Session::post(InputEvent e) {
  if (e.wallTime == 0) e.wallTime = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  loop_.post(std::move(e));
}

void Session::play() {
  loop_.play();
}

void Session::pause() {
  loop_.pause();
}

void Session::stepOnce() {
  loop_.stepOnce();
}

void Session::reset() {
  loop_.reset();
}

ToolForceModel Session::toolForce() const {
  const std::array<double, 18> v = loop_.toolForce();
  ToolForceModel m;
  m.step = static_cast<long>(v[0]);
  m.tip = Eigen::Vector3d(v[1], v[2], v[3]);
  m.force = Eigen::Vector3d(v[4], v[5], v[6]);
  for (int k = 0; k < 9; ++k) m.stiffness.data()[k] = v[static_cast<std::size_t>(7 + k)];
  m.maxForce = v[16];
  m.reach = v[17];
  return m;
}

std::shared_ptr<const Snapshot> Session::snapshot() const {
  return loop_.snapshot();
}

void Session::setPublishedCallback(std::function<void()> f) {
  loop_.setPublishedCallback(std::move(f));
}

void Session::setPublishStress(bool on) {
  loop_.setPublishStress(on);
}

void Session::rebuildBody() {
  // A parameter edit: a new body with the same nodes; the state (positions, velocities, time) carries over,
  // the lagged factor is rebuilt at the next step (the old one belongs to the old parameters).
  if (body_) body_->carryInto(setup_);  // the hybrid model's region (the model's responses: when they still hold)
  std::unique_ptr<DeformableBody> body;
  try {
    body = makeBody(setup_);
  } catch (...) {
    setup_.hybridBefore.reset();
    throw;
  }
  setup_.hybridBefore.reset();  // (its memory is the new body's or free)
  body_ = std::move(body);
  state_.lagged.valid = false;
  state_.forcesValid = false;
  updateToolConstraints();
}

void Session::updateToolConstraints() {
  std::vector<ScalarConstraint> c;
  for (const auto& i : instruments_) i->holds(tool_, c);  // what the instruments hold the tissue with
  // Contact: the boundary's triangles near the instrument's shaft (a capsule from the tip to the trocar) are
  // kept out of it by unilateral constraints at their closest points to its axis (barycentric weights on the
  // triangle's three nodes, along the direction from the axis): the surface is pushed, also between nodes.
  // Triangles within half the radius more are constrained too (inactive until they touch: an instrument moving
  // during the step meets them). Candidates: the triangles of the surface nodes within the radius plus the
  // longest surface edge (a BVH over the nodes, refitted each step). Not while the blade cuts; not the
  // triangles of held nodes. Detected only once an instrument is in the scene.
  tool_.contacts = 0;
  tool_.pierced = 0;
  contactConstraints_ = 0;
  const bool touches =
      std::all_of(instruments_.begin(), instruments_.end(), [this](const auto& i) { return i->touches(tool_); });
  if (tool_.present && touches && setup_.tools.toolRadius > 0 && bvh_ && !contact_.nodes.empty() &&
      setup_.tools.trocar) {
    ++contactQueries_;
    const ShaftContactStats found = shaftContact(
        contact_, *bvh_, state_.x, body_->fixedMask(), tool_.tip, *setup_.tools.trocar, setup_.tools.toolRadius,
        setup_.tools.depenetrationSpeed, tool_.held, tool_.released, tool_.easing, seedEasing_, c);
    contactConstraints_ = found.rows;
    tool_.contacts = found.contacts;
    tool_.pierced = found.pierced;
  }
  seedEasing_ = false;
  if (!field_.clips.empty()) {
    // The clips' rows (the tissue's own: node against node), not on nodes the jaws hold (three rows each already).
    std::vector<ScalarConstraint> clips;
    clipRows(field_, state_.time, setup_.tools.clip.closeTime, clips);
    for (auto& r : clips)
      if (std::find(tool_.held.begin(), tool_.held.end(), r.nodes[0]) == tool_.held.end()) c.push_back(r);
  }
  toolNodes_.clear();
  for (const auto& r : c)
    for (int node : r.nodes)
      if (node >= 0) toolNodes_.push_back(node);
  toolRows_ = c;
  body_->setToolConstraints(std::move(c));
}

void Session::updateSurfaceNodes() { useContactSurface(contactSurface(body_->restPositions(), body_->tetrahedra())); }

void Session::useContactSurface(ContactSurface c) {
  contact_ = std::move(c);
  tool_.easing.clear();  // it names triangles of the surface this one replaces
  // The contact's bounding-volume hierarchy only where instruments have a shaft to touch with.
  bvh_.reset();
  if (setup_.tools.toolRadius > 0) {
    bvh_ = std::make_shared<PointBvh>();
    bvh_->build(contact_.nodes, state_.x);
    ++constructions_.contactHierarchies;
  }
}

void Session::apply(const InputEvent& e, std::string& message) {
  // A cut being built elsewhere is applied before anything that rebuilds the body (the blade's own next cut: Scissors).
  if (e.kind == InputKind::Parameter || e.kind == InputKind::Gravity) finishPendingChange(true, message);
  switch (e.kind) {
    case InputKind::ToolPose:
      for (auto& i : instruments_) i->moved(e.position, tool_, *this, message);
      // The jaws go with the tip, unless another instrument moved it and the scene keeps their hold.
      if (!(tool_.jawClosed && setup_.tools.jawsKeepTheirHold && e.tool != tool_.jawTool)) tool_.jawTip = e.position;
      tool_.tip = e.position;
      if (!tool_.present) seedEasing_ = true;
      tool_.present = true;
      break;
    case InputKind::Jaw:
    case InputKind::Cut:
    case InputKind::Clip:
    case InputKind::Energy:
      if (!bodyModelChangesTissue(setup_.model) && e.kind != InputKind::Jaw && e.on) {
        // The precomputed responses are the intact organ's, computed once: a change of the tissue would need them all
        // again; the FFD deforms the surface alone, geometrically.
        const char* what = e.kind == InputKind::Cut ? "cut" : e.kind == InputKind::Clip ? "clip" : "burn";
        message =
            std::string(setup_.model == BodyModel::Ffd ? "The FFD model cannot " : "The precomputed model cannot ") +
            what +
            (setup_.model == BodyModel::Ffd ? ": it deforms the surface alone, geometrically."
                                            : ": its responses are the intact organ's, computed once.") +
            " Choose the FEM or the hybrid model (the Simulation panel's model, or a scene's \"model\") to " + what +
            ".";
        break;
      }
      for (auto& i : instruments_)
        if (i->handles(e.kind)) i->act(e, tool_, *this, message);
      break;
    case InputKind::Parameter: {
      if (e.name == "clip_length") {  // the clip applier's next clips (the body stays as it is)
        if (e.value >= 0.001 && e.value <= 0.05)
          setup_.tools.clip.length = e.value;
        else
          message =
              "A clip length of " + std::to_string(e.value) + " m is outside [0.001, 0.05] m; it was not applied.";
        break;
      }
      if (e.name == "grasp_radius") {  // the jaws' bite: what their next closing holds (the body stays as it is)
        if (e.value > 0 && e.value <= 0.1)
          setup_.tools.graspRadius = e.value;
        else
          message = "A grasp radius of " + std::to_string(e.value) + " m is outside (0, 0.1] m; it was not applied.";
        break;
      }
      if (e.name == "tear_strain") {  // where the tissue (label 0) or one label's material tears; the body stays
        if (!(e.value >= 0 && e.value <= 10)) {
          message = "A tear strain of " + std::to_string(e.value) + " is outside [0, 10]; it was not applied.";
        } else if (e.label > 0) {
          setup_.byLabel.try_emplace(e.label, setup_.material).first->second.tearStrain = e.value;
        } else {
          setup_.material.tearStrain = e.value;
        }
        tearRefused_ = false;
        break;
      }
      BodySetup before = setup_;
      if (e.label > 0 && (e.name == "young" || e.name == "poisson")) {
        // One label's own material (e.g. the vessels'), starting from the parenchyma's when it had none.
        if (e.name == "young" && e.value == 0) {
          setup_.byLabel.erase(e.label);
        } else {
          auto it = setup_.byLabel.try_emplace(e.label, setup_.material).first;
          (e.name == "young" ? it->second.young : it->second.poisson) = e.value;
        }
      } else if (e.name == "young")
        setup_.material.young = e.value;
      else if (e.name == "poisson")
        setup_.material.poisson = e.value;
      else if (e.name == "density")
        setup_.material.density = e.value;
      else if (e.name == "dt")
        setup_.settings.timeStep = e.value;
      else if (e.name == "accuracy" && e.value >= 0 && e.value <= InputRanges::maxAccuracy)  // m (0: the residual alone)
        setup_.settings.accuracyPosition = e.value;
      else if (e.name == "accuracy") {
        char buf[160];
        std::snprintf(buf, sizeof buf, "The accuracy %g mm was not applied: it is asked in [0, %g] mm.", 1e3 * e.value,
                      1e3 * InputRanges::maxAccuracy);
        message = buf;
        break;
      }
      else if (e.name == "method" && !field_.clips.empty() &&
               static_cast<NewtonMethod>(std::clamp(static_cast<int>(e.value), 0, 4)) == NewtonMethod::Linearised) {
        message = "The linearised method was refused: its one solve per step diverges under the clips on the tissue.";
        break;
      } else if (e.name == "method" && e.value >= 0 && e.value <= static_cast<int>(NewtonMethod::NewtonKrylov))
        // (Clamped to [0, 3] before 2026-11-27: Newton-Krylov, the panel's fifth, ran the linearised method.)
        setup_.settings.method = static_cast<NewtonMethod>(static_cast<int>(e.value));
      else if (e.name == "method") {
        message = "Unknown method " + std::to_string(e.value) + "; it was not applied.";
        break;
      } else if (e.name == "body_model" && (e.value == 0 || e.value == 1 || e.value == 2 || e.value == 3)) {
        // 0 fem, 1 precomputed, 2 hybrid, 3 ffd (the enum's order)
        const BodyModel m = static_cast<BodyModel>(static_cast<int>(e.value));
        if (!bodyModelChangesTissue(m) && !field_.clips.empty()) {
          message = "The " + std::string(m == BodyModel::Ffd ? "FFD" : "precomputed") +
                    " model was refused: the clips on the tissue hold nodes inside the organ, which it cannot move.";
          break;
        }
        if (m == BodyModel::Ffd && setup_.topology > 0) {
          // (The precomputed model's responses are computed for the organ as it is, cut or not.)
          message =
              "The FFD model was refused: the organ has been cut, torn or burnt, and its surface is no longer the one "
              "closed piece a geometry image maps (reset the organ first, or choose the hybrid model).";
          break;
        }
        setup_.model = m;
      } else if (e.name == "body_model") {
        message = "Unknown deformable model " + std::to_string(e.value) + "; it was not applied.";
        break;
      } else if (e.name == "model" && e.value >= 0 && e.value <= static_cast<int>(MaterialModel::NeoHookeanSplit))
        setup_.material.model = static_cast<MaterialModel>(static_cast<int>(e.value));
      else if (e.name == "model") {
        message = "Unknown material law " + std::to_string(e.value) + "; it was not applied.";
        break;
      } else {
        message = "Unknown parameter '" + e.name + "'; it was not applied.";
        break;
      }
      for (auto& [label, m] : setup_.byLabel) {
        m.model = setup_.material.model;
        m.density = setup_.material.density;
      }
      try {
        rebuildBody();
        if (e.name == "body_model") {
          message = body_->buildNote();
          if (setup_.model != BodyModel::Fem && !setup_.supports.empty())
            message += std::string(message.empty() ? "" : " ") + "The " + bodyModelName(setup_.model) +
                       " model hangs the organ from its held nodes; the tissue around it carries it in the FEM only.";
        }
      } catch (const std::exception& ex) {
        setup_ = std::move(before);
        rebuildBody();
        message = std::string("The edit was refused: ") + ex.what();
      }
      break;
    }
    case InputKind::Gravity:
      setup_.settings.gravity = e.vector;
      rebuildBody();
      break;
    case InputKind::Factor:
      body_->installRequestedFactor();  // only replays post these (the recording of an asynchronous refresh)
      break;
    case InputKind::CutApplied:
      // Only replays post these: the live run applied its cut here. A cut with a latency is applied at its own step
      // (advance), the same in the replay; the event then names that one, already applied, not the next one.
      if (builds_.underWay() && (builds_.pending()->applyAt < 0 || builds_.pending()->late))
        finishPendingChange(true, message);
      break;
  }
  if (e.kind == InputKind::ToolPose || e.kind == InputKind::Jaw || e.kind == InputKind::Clip)
    updateToolConstraints();  // rebuildBody did it for the others
}

bool Session::limitJawsAtGraspForce() {
  // Where the jaws were at the last step's end: the held nodes sit at their offsets from them (the hold's rows).
  jawMove_.valid = false;
  if (!setup_.tools.slipAtLimit || !tool_.jawClosed || tool_.held.empty() || tool_.jawTip != tool_.tip) return false;
  const Eigen::Vector3d before = gripOf(tool_, state_.x);
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  for (int n : tool_.held) velocity += state_.v.segment<3>(3 * static_cast<Eigen::Index>(n));
  velocity /= static_cast<double>(tool_.held.size());
  // The grasp force along the move, to first order: F(s) = F + s K d for the share s of the move d taken, d the jaws'
  // move beyond where the held tissue goes on its own over the step (K, the step's stiffness, includes the tissue's
  // inertia: a steady pull adds only what the tissue's stretching adds, and lets go within that one step's change).
  const double h = setup_.settings.timeStep;
  const Eigen::Vector3d d = tool_.jawTip - before - velocity * h, f = tool_.graspForce, kd = tool_.stiffness * d;
  const double max = setup_.tools.maxGraspForce;
  jawMove_ = JawMove{true, before, tool_.jawTip - before};  // (the whole move: the tissue's own share too)
  if (!(f + kd).allFinite() || (f + kd).norm() <= max || kd.squaredNorm() == 0) return false;
  // |f + s kd| = max: the larger root of a s^2 + b s + c = 0 (c < 0 when the force is below the limit now).
  const double a = kd.squaredNorm(), b = 2 * f.dot(kd), c = f.squaredNorm() - max * max;
  const double share = c >= 0 ? 0.0 : std::clamp((-b + std::sqrt(b * b - 4 * a * c)) / (2 * a), 0.0, 1.0);
  tool_.jawTip = before + velocity * h + share * d;
  jawMove_.move = tool_.jawTip - before;
  return true;
}

StepReport Session::resolveGraspLimit(const SimulationState& start, StepReport rep) {
  const double max = setup_.tools.maxGraspForce;
  if (!rep.ok || !jawMove_.valid) return rep;
  double f = body_->toolForce(true).norm();
  if (!(f > kPastTheLimit * max)) return rep;
  // Regula falsi on the force along the jaws' move this step (held back or not), Illinois' variant: below, the jaws
  // kept where the last step left them (the force it ended with, as a first guess: held still, the tissue's own motion
  // eases it); above, the move this step took. Aimed between the let-go share and the limit, and taken again until the
  // force lands there (at most three more solves, only at a slip): a step left below the let-go share would keep the
  // jaws back without a slip, and the hand's next move would be held back again. (Along the share of the move beyond
  // where the tissue goes on its own, the first order's axis, a steady pull has nothing to take back: the jaws and the
  // tissue move together.)
  const double target = 0.5 * (kLetGoShare + 1) * max;
  double sLo = 0, fLo = tool_.graspForce.norm(), sHi = 1, fHi = f;
  int kept = 0;  // which end the last two tries kept (-1 low, +1 high): Illinois halves the other's distance
  const bool swapped = rep.factorSwapped, requested = rep.factorRequested;
  double wallMs = rep.wallMs;
  int factorisations = rep.factorisations;
  auto landed = [&](double force) { return force >= kLetGoShare * max && force <= kPastTheLimit * max; };
  for (int again = 0; again < 3 && !landed(f) && sHi > sLo; ++again) {
    double s = fHi > fLo && fLo < target ? sLo + (sHi - sLo) * (target - fLo) / (fHi - fLo) : sLo;
    s = std::clamp(s, sLo, sHi);
    tool_.jawTip = jawMove_.from + s * jawMove_.move;
    std::vector<ScalarConstraint> holds;  // the instruments' holds: the first rows (updateToolConstraints)
    for (const auto& i : instruments_) i->holds(tool_, holds);
    if (holds.size() > toolRows_.size()) break;
    std::copy(holds.begin(), holds.end(), toolRows_.begin());
    body_->setToolConstraints(toolRows_);
    SimulationState tryAgain = start;
    tryAgain.lagged = state_.lagged;  // the factor the first try ended with (and what it asked for)
    std::optional<StepReport> next = body_->stepAgain(tryAgain);
    if (!next) break;
    state_ = std::move(tryAgain);
    rep = *next;
    wallMs += rep.wallMs;
    factorisations += rep.factorisations;
    if (!rep.ok) break;  // (the state is the step's start: the next step goes on from there)
    f = body_->toolForce(true).norm();
    if (f > target) {
      sHi = s;
      fHi = f;
      if (kept == 1) fLo = target - 0.5 * (target - fLo);
      kept = 1;
    } else {
      sLo = s;
      fLo = f;
      if (kept == -1) fHi = target + 0.5 * (fHi - target);
      kept = -1;
    }
  }
  rep.factorSwapped = swapped;
  rep.factorRequested = requested || rep.factorRequested;
  rep.wallMs = wallMs;
  rep.factorisations = factorisations;
  slipDue_ = true;  // held back at the limit: the tissue slips once the force is within kLetGoShare of it
  return rep;
}

StepReport Session::advance() {
  std::lock_guard<std::mutex> stepLock(stepMutex_);
  // The events due at this boundary, in the order they were posted.
  std::vector<InputEvent> due = loop_.takeDue(steps_);
  std::string message;
  // A cut whose body was built on another thread replaces the body as soon as it is ready (recorded, so that
  // a replay applies it at the same boundary; the replay itself waits for the recording's word).
  // One with a boundary that may come late (TopologyChange::late) comes in there or after, when built, never waited
  // for; the replay's (deferred refresh) comes in at the recorded step.
  const bool live = setup_.settings.factorRefresh == FactorRefresh::Asynchronous;
  const TopologyBuilds::PendingChange* pending = builds_.pending();
  const bool cutDue =
      pending && (pending->applyAt >= 0 ? steps_ >= pending->applyAt && (!pending->late || live) : live);
  if (cutDue && finishPendingChange(pending->applyAt >= 0 && !pending->late, message)) {
    InputEvent c;
    c.kind = InputKind::CutApplied;
    c.step = steps_;
    c.wallTime = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    recorded_.push_back(c);
  }
  for (auto& e : due) {
    e.step = steps_;
    apply(e, message);
    recorded_.push_back(e);
  }
  if (strokes_.open() && !tool_.cutting && !builds_.underWay() && !strokes_.restOfSweep()) finishStroke(message);
  slipDue_ = limitJawsAtGraspForce();
  jawsPull_ = false;
  // (10 um: more than the hold's rows leave between the held nodes and the jaws; less than a mouse move's 0.1-1 mm at
  // the organ, or a scripted pull's step)
  if (tool_.jawClosed && !tool_.held.empty() && tool_.heldOffset.size() == tool_.held.size())
    jawsPull_ = (tool_.jawTip - gripOf(tool_, state_.x)).norm() > 1e-5;
  for (auto& i : instruments_) i->stepping(setup_.settings.timeStep, tool_, *this, message);  // the cautery heats
  // Contacts move with the tissue: detected at every step. The clips' rows are made at every step too (closing ones
  // close further; made from the time alone, so a session restored at any step makes the same rows).
  if ((tool_.present && setup_.tools.toolRadius > 0) || !field_.clips.empty() || slipDue_) updateToolConstraints();
  const double timeBefore = state_.time;
  // A step the jaws make is taken again when its force comes out past the limit (ToolSettings::slipResolved; FEM).
  std::optional<SimulationState> start;
  if (jawMove_.valid && setup_.tools.slipResolved && setup_.model == BodyModel::Fem) start = state_;
  StepReport rep = body_->step(state_);
  if (start) rep = resolveGraspLimit(*start, std::move(rep));
  if (rep.guardStalled) settleHeldBackClips(message);
  if (rep.ok && state_.time > timeBefore) {
    const double lossBefore = field_.bloodLoss;
    for (auto& b : field_.bleeds)
      if (b.stoppedBy < 0) {  // an open stump loses blood at its rate
        b.lost += b.rate * (state_.time - timeBefore);
        field_.bloodLoss += b.rate * (state_.time - timeBefore);
      }
    // The loss said as it passes each class of haemorrhage (a person saw 2,443 mL lost and nothing said).
    if (const int now = haemorrhageClass(field_.bloodLoss); now >= 2 && now > haemorrhageClass(lossBefore)) {
      char buf[200];
      const long ml = std::lround(1e6 * field_.bloodLoss);  // (written as the sentence's bounds are: 1,500 mL)
      if (ml >= 1000)
        std::snprintf(buf, sizeof buf, " %ld,%03ld mL of blood lost: %s.", ml / 1000, ml % 1000,
                      haemorrhageWords(now).c_str());
      else
        std::snprintf(buf, sizeof buf, " %ld mL of blood lost: %s.", ml, haemorrhageWords(now).c_str());
      message += buf;
      if (message.front() == ' ') message.erase(0, 1);
    }
  }
  if (rep.factorSwapped) {
    // The asynchronous refresh swapped a factor in at this boundary: recorded, so a replay installs it here.
    InputEvent f;
    f.kind = InputKind::Factor;
    f.step = steps_;
    f.wallTime = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    recorded_.push_back(f);
  }
  ++steps_;
  if (!tool_.easing.empty()) {
    // Eased contact moves out at the scene's speed, and is plain contact once at the shaft's radius.
    const double by = setup_.tools.depenetrationSpeed * setup_.settings.timeStep, r = setup_.tools.toolRadius;
    for (auto& [tri, keep] : tool_.easing) keep += by;
    std::erase_if(tool_.easing, [r](const std::pair<int, double>& e) { return e.second >= r; });
  }
  stepConverged_ = rep.outcome == StepStatus::Converged;
  if ((!tool_.held.empty() || contactConstraints_ > 0) && rep.ok) {
    tool_.force = body_->toolForce();
    tool_.graspForce = tool_.held.empty() ? Eigen::Vector3d::Zero() : body_->toolForce(true);
    tool_.stiffness = body_->toolStiffness();
    // d(force)/d(tip) is the jaws' and the shaft's when the moving tip is theirs; when another instrument moves it (the
    // jaws keep their hold) moving it changes neither to first order: the force loop holds the last force.
    if (tool_.jawClosed && tool_.jawTip != tool_.tip) tool_.stiffness.setZero();
    bool changed = false;  // a slip lets go of what the jaws held: their rows are made again
    for (auto& i : instruments_) changed = i->stepped(tool_, *this, message) || changed;
    if (changed) updateToolConstraints();
  } else if (tool_.held.empty() && contactConstraints_ == 0) {
    tool_.force.setZero();
    tool_.graspForce.setZero();
    tool_.stiffness.setZero();
  }
  if (rep.ok) tearOverStretched(message);  // tissue pulled past its material's tear strain tears (tearing.cpp)
  publish(rep, message, std::move(events_));
  events_.clear();
  if (stepHook_) {
    StepRecord r;
    r.step = steps_;
    r.recorded = &recorded_;
    r.state = &state_;
    const auto snap = snapshot();
    r.snapshot = snap.get();
    r.session = this;
    stepHook_(r);
  }
  return rep;
}

// A step the inversion guard held back: the clips whose rows it did not meet close no further than their nodes are
// (on a mesh coarser than the vessel, a long clip asked for a squeeze its neighbours could only take inside out, and
// every step after it ran its iterations out: a second a step on the phantom with 18 mm clips).
void Session::settleHeldBackClips(std::string& message) {
  constexpr double kMet = 1e-5;  // m: rows met within a hundredth of a millimetre
  for (std::size_t i = 0; i < field_.clips.size(); ++i) {
    // Said while it closes; a closed clip held back later (a stalled step elsewhere: the hook, the shaft) keeps where
    // its nodes are without a word, at every such step.
    const bool closing = state_.time - field_.clips[i].placedAt <= setup_.tools.clip.closeTime;
    const double width =
        settleHeldBackClip(field_.clips[i], state_.x, state_.time, setup_.tools.clip.closeTime, kMet);
    if (width < 0 || !closing) continue;
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  " Clip %zu closes no further than %.1f mm across its jaws: the tissue around it would turn inside "
                  "out beyond (its elements are coarser than the structure).",
                  i + 1, 1e3 * width);
    message += buf;
  }
}

Checkpoint Session::checkpointLocked() const {
  Checkpoint c{steps_, setup_, state_, tool_, field_, std::nullopt, strokes_.restOfSweep()};
  body_->carryInto(c.setup);  // the hybrid model's region as it grew (a restore builds the same region)
  c.setup.hybridBefore.reset();
  if (const TopologyBuilds::PendingChange* pending = builds_.pending()) {
    c.pendingChange = static_cast<const TopologyChange&>(*pending);
    c.pendingChange->setup.hybridBefore.reset();  // (a restore computes the rest's responses again: the same numbers)
  }
  return c;
}

Checkpoint StepRecord::checkpoint() const { return session->checkpointLocked(); }

void Session::setStepHook(std::function<void(const StepRecord&)> f) {
  std::lock_guard<std::mutex> lock(stepMutex_);
  stepHook_ = std::move(f);
}

void Session::publish(const StepReport& rep, const std::string& message, std::vector<std::string> events) {
  auto s = std::make_shared<Snapshot>();
  const std::size_t n = body_->nodeCount();
  s->positions.resize(n);
  for (std::size_t i = 0; i < n; ++i) s->positions[i] = state_.x.segment<3>(3 * static_cast<Eigen::Index>(i));
  s->step = steps_;
  s->time = state_.time;
  s->report = rep;
  s->topologyVersion = body_->topologyVersion();
  s->tool = tool_;
  s->field = field_;
  s->material = setup_.material;
  s->message = message;
  s->events = std::move(events);
  s->mass = body_->mass();
  s->elements = body_->tetrahedra().size();
  s->responseKey = body_->responseKey();
  s->model = setup_.model;
  s->tets = tets_;
  s->labels = labels_;
  s->surface = setup_.topology > 0 ? surface_ : nullptr;
  s->trocar = *setup_.tools.trocar;
  s->toolRadius = setup_.tools.toolRadius;
  s->gravity = setup_.settings.gravity;
  if (loop_.publishStress()) body_->stress(state_, s->stress);
  {
    std::array<double, 18> v{};
    v[0] = static_cast<double>(steps_);
    for (int k = 0; k < 3; ++k) {
      v[static_cast<std::size_t>(1 + k)] = tool_.tip[k];
      v[static_cast<std::size_t>(4 + k)] = tool_.force[k];
    }
    for (int k = 0; k < 9; ++k) v[static_cast<std::size_t>(7 + k)] = tool_.stiffness.data()[k];
    v[16] = tool_.held.empty() ? 0 : setup_.tools.maxGraspForce;
    v[17] = toolReach(setup_.tools);
    loop_.publishToolForce(v);
  }
  loop_.publish(std::move(s));
}

std::vector<InputEvent> Session::recorded() const {
  std::lock_guard<std::mutex> lock(stepMutex_);
  return recorded_;
}

Checkpoint Session::checkpoint() const {
  std::lock_guard<std::mutex> lock(stepMutex_);
  return checkpointLocked();
}

void Session::restore(const Checkpoint& c) {
  std::lock_guard<std::mutex> lock(stepMutex_);
  builds_.drop(false);  // a change of the state left behind finishes on its own thread
  strokes_.clear(c.restOfSweep);
  setup_ = c.setup;
  body_ = makeBody(setup_);
  elementsChanged();
  surface_.reset();
  if (setup_.topology > 0) updateCutSurface();
  state_ = c.state;
  body_->requestAgain(state_);
  updateSurfaceNodes();
  tool_ = c.tool;
  field_ = c.field;
  steps_ = c.step;
  if (c.pendingChange) {  // the change under way is built again from the same inputs (the same body)
    builds_.launch(*c.pendingChange, uncut_, meanEdge_);
  }
  updateToolConstraints();
  StepReport rest;
  rest.ok = true;
  rest.outcome = StepStatus::Converged;  // no step taken: nothing left unsolved
  publish(rest, {});
}

SimulationState Session::state() const {
  std::lock_guard<std::mutex> lock(stepMutex_);
  return state_;
}

void Session::run() {
  using clock = std::chrono::steady_clock;
  clock::time_point playStart{};
  double simAtStart = 0;
  bool wasPlaying = false;
  for (;;) {
    const clock::time_point asked = clock::now();
    const SessionLoop::Order order = loop_.next();  // (its mutex released before the step mutex is taken)
    // It waited there: paused (a question asked, Pause), so the wall clock from the last start counts no more (it was
    // made up after Cancel at 1.5x real time: 43 s of simulation in 27 s, bleeding included).
    if (clock::now() - asked > std::chrono::milliseconds(50)) wasPlaying = false;
    if (order == SessionLoop::Order::Quit) return;
    if (order == SessionLoop::Order::Republish) {
      std::lock_guard<std::mutex> stepLock(stepMutex_);
      // The same step again (the stress asked for): its sentence was said when it was first published (said again,
      // a slip's sentence came back in the status bar and the Messages panel long after, and after a Reset).
      const auto last = snapshot();
      publish(last->report, {});
      continue;
    }
    if (order == SessionLoop::Order::Reset) {
      std::lock_guard<std::mutex> stepLock(stepMutex_);
      builds_.drop(true);
      strokes_.clear();
      if (setup_.topology != uncut_.topology || setup_.mesh.tetLabels != uncut_.mesh.tetLabels) {
        // Back to the organ before any cut or burn (parameter edits stay).
        std::erase_if(setup_.byLabel, [](const auto& m) { return isBurnt(m.first); });
        setup_.mesh = uncut_.mesh;
        setup_.rest = uncut_.rest;
        setup_.start = uncut_.start;
        setup_.tearFrom = uncut_.tearFrom;
        setup_.fixedNodes = uncut_.fixedNodes;
        setup_.topology = uncut_.topology;
        setup_.cut = uncut_.cut;
        body_ = makeBody(setup_);
        elementsChanged();
        surface_.reset();
      }
      state_ = body_->initialState();
      updateSurfaceNodes();
      steps_ = 0;
      tearHeld_ = false;  // said again in the new run
      tool_ = {};
      field_ = {};
      updateToolConstraints();
      StepReport rest;
      rest.ok = true;
      rest.outcome = StepStatus::Converged;  // no step taken: nothing left unsolved
      publish(rest, {});
      wasPlaying = false;
      continue;
    }
    const bool doStep = order == SessionLoop::Order::Step;
    const bool play = loop_.playing() && !doStep;
    if (play && !wasPlaying) {
      playStart = clock::now();
      simAtStart = state().time;
    }
    wasPlaying = play;
    const StepReport rep = advance();
    if (!rep.ok) {
      loop_.stopPlaying();  // the step was rolled back; the snapshot's status says why
      wasPlaying = false;
      continue;
    }
    if (play) {
      // Real time: wait while the simulation is ahead of the wall clock (woken early by pause or quit).
      const double ahead =
          (state().time - simAtStart) - std::chrono::duration<double>(clock::now() - playStart).count();
      if (ahead > 0) loop_.waitWhileAhead(ahead);
      // Behind it by more than kMostBehind (slow steps: a cut, a tear, a loaded machine), the time lost is not made
      // up: the organ goes on at real time from where it is. (Made up, the steps after slow ones ran back to back:
      // a person read 192 fps, and the organ moved faster than real time meanwhile.)
      constexpr double kMostBehind = 0.1;  // s
      if (ahead < -kMostBehind)
        playStart += std::chrono::duration_cast<clock::duration>(std::chrono::duration<double>(-ahead - kMostBehind));
    }
  }
}

BodySetup replaySetup(BodySetup setup) {
  if (setup.settings.factorRefresh == FactorRefresh::Asynchronous)
    setup.settings.factorRefresh = FactorRefresh::Deferred;
  // A step's error estimate is not recorded and changes no bit: a replay skips its solve (the review's seeks and
  // verification replay many steps; with it the review window froze up to 118 ms on the phantom).
  setup.settings.estimateError = false;
  return setup;
}

void replaySession(const BodySetup& setup, const std::vector<InputEvent>& events, long steps,
                   const std::function<void(long, const Session&)>& each) {
  Session s(replaySetup(setup));
  for (const auto& e : events) s.post(e);
  for (long k = 0; k < steps; ++k) {
    s.advance();
    if (each) each(k + 1, s);
  }
}

void replay(const BodySetup& setup, const std::vector<InputEvent>& events, long steps,
            const std::function<void(long, const SimulationState&)>& each) {
  replaySession(setup, events, steps, [&each](long step, const Session& s) {
    if (each) each(step, s.state());
  });
}

}  // namespace rehearse::simcore
