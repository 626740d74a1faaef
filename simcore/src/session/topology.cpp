// Topology changes of the session, one mechanism whatever computed the new mesh (a cut today, cutting.cpp; tearing
// and burning next): a request (TopologyChange: the new body's setup and how the state extends onto new nodes), the
// new body built at once or on the second thread while the old one steps on, and a swap at a step boundary with the
// state carried across; then the new boundary for drawing and contact. The kind of change only words its events. The
// builds themselves (started, held, dropped): topologybuilds.cpp.
#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>

namespace rehearse::simcore {
namespace {
// A tear that parts along faces pins the nodes no element holds any more (BodySetup::fixedNodes): the jaws let go of
// those they held (the torn-off corner is out of every surface; a held node that is fixed has no row to pull on).
void letGoOfPinned(ToolState& tool, const BodySetup& setup) {
  for (std::size_t k = tool.held.size(); k-- > 0;)
    if (std::find(setup.fixedNodes.begin(), setup.fixedNodes.end(), tool.held[k]) != setup.fixedNodes.end()) {
      tool.held.erase(tool.held.begin() + static_cast<std::ptrdiff_t>(k));
      if (k < tool.heldOffset.size()) tool.heldOffset.erase(tool.heldOffset.begin() + static_cast<std::ptrdiff_t>(k));
    }
}
}  // namespace

bool Session::changeTopology(TopologyChange change, std::string& message) {
  body_->carryInto(change.setup);  // the hybrid model's region, grown by the cut's new nodes, and its responses
  if (setup_.settings.factorRefresh != FactorRefresh::Synchronous || change.applyAt >= 0) {
    // The new body and its first factorisation on another thread; the old body steps on meanwhile, until the
    // boundary applyAt (the same in every run) or, without one, until it is ready.
    change.toolNodes = toolNodes_;
    builds_.launch(std::move(change), uncut_, meanEdge_);
    return true;
  }
  const BodySetup before = setup_;
  const SimulationState stateBefore = state_;
  setup_ = std::move(change.setup);
  if (change.kind == ChangeKind::Tear && setup_.tools.tearRemovesElements) letGoOfPinned(tool_, setup_);
  extendByCut(state_.x, change.newNodes);
  extendByCut(state_.v, change.newNodes);
  state_.lagged = {};
  state_.forcesValid = false;
  state_.forces.resize(0);
  try {
    rebuildBody();
  } catch (const std::exception& ex) {
    setup_ = before;
    state_ = stateBefore;
    rebuildBody();
    message = ex.what();
    return false;
  }
  elementsChanged();
  updateSurfaceNodes();
  updateCutSurface();
  topologyChanged(change, message);
  return true;
}

void Session::topologyChanged(const TopologyChange& change, std::string& message) {
  if (change.kind == ChangeKind::Cut) {
    cutEvents(change.labels, message);
    field_.heating.clear();  // it named elements the cut renumbered
  } else if (change.kind == ChangeKind::Tear) {
    seedEasing_ = true;      // the torn surface is new (its events were said when the tear was asked for)
    field_.heating.clear();  // it named elements the re-meshing renumbered
  } else {
    burnEvents(message);
  }
  updateBleeds(message);  // a cut vessel's stumps bleed unless clipped; a burnt one is sealed
}

bool Session::burn(const std::vector<int>& elements, std::string& message) {
  if (builds_.underWay()) return false;  // one change at a time: the heat is kept, they burn at a later step
  TopologyChange change;
  change.kind = ChangeKind::Burn;
  change.setup = setup_;
  BodySetup& next = change.setup;
  next.mesh.tetLabels = body_->labels();
  for (int e : elements) {
    if (e < 0 || static_cast<std::size_t>(e) >= next.mesh.tetLabels.size()) continue;
    int& label = next.mesh.tetLabels[static_cast<std::size_t>(e)];
    if (isBurnt(label)) continue;
    const int burnt = burntLabel(label);
    if (!next.byLabel.count(burnt)) {  // the label's own material, stiffened
      const auto own = next.byLabel.find(label);
      MaterialParams m = own != next.byLabel.end() ? own->second : next.material;
      m.young *= setup_.tools.cautery.stiffening;
      next.byLabel[burnt] = m;
    }
    if (std::find(change.labels.begin(), change.labels.end(), label) == change.labels.end())
      change.labels.push_back(label);
    label = burnt;
  }
  if (change.labels.empty()) return true;
  std::sort(change.labels.begin(), change.labels.end());
  const int latency = setup_.tools.cutLatencySteps;
  change.applyAt = latency >= 0 ? steps_ + latency : -1;
  if (setup_.settings.factorRefresh != FactorRefresh::Synchronous || latency >= 0) change.factorAt = state_.x;
  return changeTopology(std::move(change), message);
}

void Session::burnEvents(std::string& message) {
  events_.push_back(eventWord(EventKind::Burn));
  char buf[200];
  std::snprintf(
      buf, sizeof buf,
      "The tissue under the hook burns: it whitens and stiffens (Young's modulus x%.1f); a cut through it does "
      "not bleed.",
      setup_.tools.cautery.stiffening);
  if (message.find(buf) == std::string::npos) message += (message.empty() ? "" : " ") + std::string(buf);
}

void Session::fieldChanged(std::string& message) {
  updateBleeds(message);  // a clip may stop a stump
  updateToolConstraints();
}

void Session::updateBleeds(std::string& message) {
  if (!surface_ || setup_.topology == 0) return;  // nothing cut: nothing bleeds
  const std::vector<Bleed> before = field_.bleeds;
  field_.bleeds = findBleeds(
      *surface_, body_->tetrahedra(), body_->labels(), field_.clips, before,
      [this](int label) { return setup_.mesh.labelKind(label); }, meanEdge_, setup_.tools.bleeding);
  // What changed: a stump that bleeds now and did not (a new one, or one whose clip is gone), one a clip stopped.
  auto was = [&before, this](const Bleed& b) -> const Bleed* {
    for (const Bleed& p : before)
      if (p.label == b.label && (p.at - b.at).norm() <= meanEdge_ && p.normal.dot(b.normal) > 0) return &p;
    return nullptr;
  };
  double starting = 0, stopped = 0, grown = 0;
  std::vector<int> startingLabels, grownLabels;
  auto note = [](std::vector<int>& labels, int label) {
    if (std::find(labels.begin(), labels.end(), label) == labels.end()) labels.push_back(label);
  };
  for (const Bleed& b : field_.bleeds) {
    const Bleed* p = was(b);
    const bool open = b.stoppedBy < 0, openBefore = p && p->stoppedBy < 0;
    if (open && !openBefore) {
      starting += b.rate;
      note(startingLabels, b.label);
    }
    if (!open && openBefore) stopped += p->rate;
    // A stump that was open and is wider now (the blade went on through the vessel): the cut added to it.
    if (open && openBefore && b.rate > p->rate * (1 + 1e-6)) {
      grown += b.rate - p->rate;
      note(grownLabels, b.label);
    }
  }
  double sealed = 0;  // open stumps that are gone: burnt (their faces are burnt tissue now)
  for (const Bleed& p : before) {
    if (p.stoppedBy >= 0) continue;
    const bool still = std::any_of(field_.bleeds.begin(), field_.bleeds.end(), [&](const Bleed& b) {
      return b.label == p.label && (p.at - b.at).norm() <= meanEdge_ && p.normal.dot(b.normal) > 0;
    });
    // (A stump of a vessel a cut's update has just opened again further along is the cut moving on, not a seal:
    // "The cautery seals ..." was said during a scissors stroke.)
    const bool reopened = std::find(startingLabels.begin(), startingLabels.end(), p.label) != startingLabels.end();
    if (!still && !reopened) sealed += p.rate;
  }
  double open = 0, openBefore = 0;  // all that bleeds now (the page's rate), and before this change
  for (const Bleed& b : field_.bleeds)
    if (b.stoppedBy < 0) open += b.rate;
  for (const Bleed& p : before)
    if (p.stoppedBy < 0) openBefore += p.rate;
  char buf[320];
  // What the cut added is what makes the sentences add up: the rate before, plus it, less what a clip stopped and the
  // cautery sealed, is the rate in all (a stump the blade widened, one that moved along the vessel, the share of the
  // organ's supply each keeps when it is reached: all in it).
  const double added = open - openBefore + stopped + sealed;
  if (starting > 0 || grown > 0) {
    if (starting > 0) events_.push_back(eventWord(EventKind::Bleeding));
    std::string names;
    for (const std::vector<int>* labels : {&startingLabels, &grownLabels})
      for (int l : *labels) {
        const std::string n = structureWords(setup_.mesh.labelKind(l), setup_.mesh.labelName(l));
        if (names.find(n) == std::string::npos) names += (names.empty() ? "" : ", ") + n;
      }
    const bool atSupply = setup_.tools.bleeding.physiological && setup_.tools.bleeding.organSupply > 0 &&
                          open >= setup_.tools.bleeding.organSupply * (1 - 1e-9);
    // (A stump the blade widened by a sliver read "bleeds more: 0.00 mL/s from the cut".)
    char fromCut[40];
    if (1e6 * added < 0.005)
      std::snprintf(fromCut, sizeof fromCut, "under 0.01 mL/s");
    else
      std::snprintf(fromCut, sizeof fromCut, "%.2f mL/s", 1e6 * added);
    std::snprintf(buf, sizeof buf, " The %s bleeds%s: %s from the cut (%.2f mL/s in all%s).", names.c_str(),
                  starting > 0 ? "" : " more", fromCut, 1e6 * open, atSupply ? ", all the organ's supply" : "");
    message += buf;
  }
  if (stopped > 0 || sealed > 0) events_.push_back(eventWord(EventKind::BleedingStopped));
  if (stopped > 0) {
    std::snprintf(buf, sizeof buf, " The clip stops %.2f mL/s of bleeding (%.2f mL/s in all now).", 1e6 * stopped,
                  1e6 * open);
    message += buf;
  }
  if (sealed > 0) {
    std::snprintf(buf, sizeof buf, " The cautery seals %.2f mL/s of bleeding (%.2f mL/s in all now).", 1e6 * sealed,
                  1e6 * open);
    message += buf;
  }
  if (!message.empty() && message.front() == ' ') message.erase(0, 1);
}

bool Session::finishPendingChange(bool wait, std::string& message) {
  if (!builds_.underWay()) return false;
  if (!wait && !builds_.ready()) return false;
  TopologyBuilds::PendingChange p = builds_.take();
  TopologyBuilds::Built built;
  try {
    built = p.built.get();
  } catch (const std::exception& ex) {
    // Its new body could not be built: the old one stays (a burn's heat is kept, and it burns at a later step).
    message = std::string(p.kind == ChangeKind::Cut    ? "The cut was refused: "
                          : p.kind == ChangeKind::Tear ? "The tear could not be made: "
                                                       : "The burn could not be made: ") +
              ex.what();
    if (p.kind == ChangeKind::Cut) strokes_.dropRestOfSweep();
    return false;
  }
  // The state carried across from where the tissue is now (the old body went on stepping meanwhile).
  setup_ = std::move(p.setup);
  setup_.hybridBefore.reset();
  if (p.kind == ChangeKind::Tear && setup_.tools.tearRemovesElements) letGoOfPinned(tool_, setup_);
  if (p.clearProgress) setup_.cut.clear();
  extendByCut(state_.x, p.newNodes);
  extendByCut(state_.v, p.newNodes);
  state_.lagged = {};
  if (setup_.settings.method != NewtonMethod::Exact && setup_.settings.solver == LinearSolverKind::Cholmod) {
    state_.lagged.valid = true;  // the factor the worker built
    state_.lagged.refresh = false;
    state_.lagged.at = std::move(p.factorAt);
    state_.lagged.step = setup_.settings.timeStep;
  }
  state_.forcesValid = false;
  state_.forces.resize(0);
  builds_.retire(std::move(body_));
  body_ = std::move(built.body);
  elementsChanged();
  useContactSurface(std::move(built.contact));
  surface_ = std::move(built.surface);
  ++constructions_.cutSurfaces;
  topologyChanged(p, message);
  updateToolConstraints();
  continueSweep(message);
  return true;
}

bool Session::applyPendingChange() {
  std::lock_guard<std::mutex> stepLock(stepMutex_);
  if (!builds_.underWay()) return false;
  std::string message;
  const bool applied = finishPendingChange(true, message);
  if (applied) {
    InputEvent c;  // recorded, as any change applied
    c.kind = InputKind::CutApplied;
    c.step = steps_;
    c.wallTime = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    recorded_.push_back(c);
    publish(snapshot()->report, message, std::move(events_));
    events_.clear();
  }
  return applied;
}

std::shared_ptr<const CutSurface> makeCutSurface(const BodySetup& uncutSetup, const Mesh& cutMesh, double meanEdge) {
  // The boundary of the cut mesh; a triangle is the organ's own surface when its rest centre lies on a
  // triangle of the uncut boundary (a uniform grid over those), cut tissue otherwise.
  Mesh uncut = uncutSetup.mesh;
  uncut.convertToMetres();
  if (!uncutSetup.rest.empty()) uncut.points = uncutSetup.rest;
  const auto outer = boundaryTriangles(uncut, false);
  auto out = std::make_shared<CutSurface>();
  out->triangles = boundaryTriangles(cutMesh, false, &out->labels);
  const double cell = std::max(meanEdge, 1e-6);
  auto keyOf = [&](const Eigen::Vector3d& p) {
    return std::array<long, 3>{static_cast<long>(std::floor(p.x() / cell)), static_cast<long>(std::floor(p.y() / cell)),
                               static_cast<long>(std::floor(p.z() / cell))};
  };
  std::map<std::array<long, 3>, std::vector<int>> grid;
  for (std::size_t k = 0; k < outer.size(); ++k) {
    Eigen::AlignedBox3d box;
    for (int v : outer[k]) box.extend(uncut.points[static_cast<std::size_t>(v)]);
    const auto lo = keyOf(box.min()), hi = keyOf(box.max());
    for (long x = lo[0]; x <= hi[0]; ++x)
      for (long y = lo[1]; y <= hi[1]; ++y)
        for (long z = lo[2]; z <= hi[2]; ++z) grid[{x, y, z}].push_back(static_cast<int>(k));
  }
  const auto& rest = cutMesh.points;
  out->cut.assign(out->triangles.size(), 1);
  for (std::size_t k = 0; k < out->triangles.size(); ++k) {
    const auto& t = out->triangles[k];
    const Eigen::Vector3d c = (rest[static_cast<std::size_t>(t[0])] + rest[static_cast<std::size_t>(t[1])] +
                               rest[static_cast<std::size_t>(t[2])]) /
                              3.0;
    const auto it = grid.find(keyOf(c));
    if (it == grid.end()) continue;
    for (int o : it->second) {
      const Eigen::Vector3d& a = uncut.points[static_cast<std::size_t>(outer[static_cast<std::size_t>(o)][0])];
      const Eigen::Vector3d& b = uncut.points[static_cast<std::size_t>(outer[static_cast<std::size_t>(o)][1])];
      const Eigen::Vector3d& d = uncut.points[static_cast<std::size_t>(outer[static_cast<std::size_t>(o)][2])];
      const Eigen::Vector3d n = (b - a).cross(d - a);
      const double area2 = n.norm();
      if (!(area2 > 0) || std::abs(n.dot(c - a)) > 1e-9 * area2 * cell) continue;
      // Inside the triangle (barycentric signs).
      const double w0 = n.dot((b - a).cross(c - a)), w1 = n.dot((d - b).cross(c - b)), w2 = n.dot((a - d).cross(c - d));
      if (w0 >= -1e-12 * area2 * area2 && w1 >= -1e-12 * area2 * area2 && w2 >= -1e-12 * area2 * area2) {
        out->cut[k] = 0;
        break;
      }
    }
  }
  out->cutCount = static_cast<std::size_t>(std::count(out->cut.begin(), out->cut.end(), 1));
  out->rest = rest;
  return out;
}

void Session::updateCutSurface() {
  surface_ = makeCutSurface(uncut_, setup_.mesh, meanEdge_);
  ++constructions_.cutSurfaces;
}

void Session::discardPending() {
  loop_.discard();
}

}  // namespace rehearse::simcore
