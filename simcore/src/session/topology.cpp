// Topology changes of the session (a cut today; tearing and burning next): the request (the blade's sweep) computed
// into a new mesh by the cut module, the new body built at once or on the second thread, swapped in at a step boundary
// with the state carried across, and what the change says (events, the stroke's sentence, the cut surface).
#include <rehearse/simcore/session/session.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <unordered_map>

namespace rehearse::simcore {

bool Session::cut(const Eigen::Vector3d& from, const Eigen::Vector3d& to, std::string& message) {
  // One cut at a time: while the last one's body is being built the sweep grows (the blade's start stays).
  if (pendingCut_) return false;
  // The blade: from the tip back along the shaft towards the trocar; its sweep between the two poses is
  // planar (both shafts pass through the trocar).
  const Eigen::Vector3d trocar = *setup_.tools.trocar;
  auto bladeEnd = [&](const Eigen::Vector3d& tip) {
    const Eigen::Vector3d d = trocar - tip;
    const double L = std::min(setup_.tools.bladeLength, 0.999 * d.norm());
    return d.norm() > 0 ? Eigen::Vector3d(tip + L * d.normalized()) : tip;
  };
  BladeSweep sweep{from, bladeEnd(from), to, bladeEnd(to)};
  std::vector<Eigen::Vector3d> rest = body_->restPositions();
  const std::size_t n = rest.size();
  std::vector<Eigen::Vector3d> current(n);
  for (std::size_t i = 0; i < n; ++i) current[i] = state_.x.segment<3>(3 * static_cast<Eigen::Index>(i));
  std::vector<std::array<int, 4>> tets = body_->tetrahedra();
  std::vector<int> labels = body_->labels();
  CutProgress progress = setup_.cut;
  const CutResult r = cutTetrahedra(rest, current, tets, labels, sweep, setup_.tools.cut, &progress);
  if (!r.changed) {
    if (r.status.rfind("The cut was refused", 0) == 0) message = stroke_.lastRefusal = r.status;
    return false;
  }
  ++stroke_.updates;
  stroke_.split += r.splitElements;
  stroke_.separatedFaces += r.separatedFaces;
  stroke_.skippedInverted += r.skippedInverted;
  stroke_.lastRefusal.clear();
  ++constructions_.cutMeshes;
  BodySetup next = setup_;
  next.mesh.points = rest;
  next.mesh.unitToMetre = 1.0;
  next.mesh.triangles.clear();
  next.mesh.triangleLabels.clear();
  next.mesh.tets = std::move(tets);
  next.mesh.tetLabels = std::move(labels);
  next.rest.clear();
  next.cut = std::move(progress);
  const auto& fixed = body_->fixedMask();
  for (std::size_t k = 0; k < r.duplicateOf.size(); ++k)
    if (r.duplicateOf[k] >= 0 && fixed[static_cast<std::size_t>(r.duplicateOf[k])])
      next.fixedNodes.push_back(static_cast<int>(n + k));
  ++next.topology;
  const int latency = setup_.tools.cutLatencySteps;
  if (setup_.settings.factorRefresh != FactorRefresh::Synchronous || latency >= 0) {
    // The new body and its first factorisation on another thread; the old body steps on meanwhile, until the
    // boundary `latency` steps on (the same in every run) or, without a latency, until it is ready.
    PendingCut p;
    p.applyAt = latency >= 0 ? steps_ + latency : -1;
    p.factorAt = state_.x;
    extendByCut(p.factorAt, r.newNodes);
    p.setup = std::move(next);
    p.newNodes = r.newNodes;
    p.cutLabels = r.cutLabels;
    launchCutBuild(p);
    pendingCut_ = std::move(p);
    return true;
  }
  const BodySetup before = setup_;
  const SimulationState stateBefore = state_;
  setup_ = std::move(next);
  extendByCut(state_.x, r.newNodes);
  extendByCut(state_.v, r.newNodes);
  state_.lagged = {};
  state_.forcesValid = false;
  state_.forces.resize(0);
  try {
    rebuildBody();
  } catch (const std::exception& ex) {
    setup_ = before;
    state_ = stateBefore;
    rebuildBody();
    message = std::string("The cut was refused: ") + ex.what();
    return false;
  }
  cutApplied(r.cutLabels, message);
  return true;
}

void Session::launchCutBuild(PendingCut& p) const {
  p.built = std::async(std::launch::async, [setup = p.setup, at = p.factorAt, uncut = uncut_, edge = meanEdge_]() {
    Built b;
    b.body = makeFemBody(setup);
    b.body->prepareFactor(at);
    b.surface = makeCutSurface(uncut, setup.mesh, edge);
    b.contact = contactSurface(b.body->restPositions(), b.body->tetrahedra());
    return b;
  });
}

void Session::cutApplied(const std::vector<int>& cutLabels, std::string& message) {
  tets_ = std::make_shared<const std::vector<std::array<int, 4>>>(body_->tetrahedra());
  updateSurfaceNodes();
  updateCutSurface();
  cutEvents(cutLabels, message);
}

void Session::cutEvents(const std::vector<int>& cutLabels, std::string& message) {
  seedEasing_ = true;  // the surface is new: what lies inside the shaft now is eased out at the next constraints
  events_.push_back("cut");
  for (int label : cutLabels) events_.push_back("cut through label " + std::to_string(label));
  // A vessel (a label the organ's mesh names as one, Mesh::labelIsVessel) cut by this stroke is one event, however many
  // updates the cut takes.
  for (int label : cutLabels)
    if (setup_.mesh.labelIsVessel(label) &&
        std::find(tool_.vesselsCut.begin(), tool_.vesselsCut.end(), label) == tool_.vesselsCut.end()) {
      tool_.vesselsCut.push_back(label);
      events_.push_back("vessel cut");
      message = "A vessel (" + setup_.mesh.labelName(label) + ", label " + std::to_string(label) + ") was cut.";
    }
}

bool Session::finishPendingCut(bool wait, std::string& message) {
  if (!pendingCut_) return false;
  if (!wait && pendingCut_->built.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
  PendingCut p = std::move(*pendingCut_);
  pendingCut_.reset();
  Built built;
  try {
    built = p.built.get();
  } catch (const std::exception& ex) {
    message = std::string("The cut was refused: ") + ex.what();
    restOfSweep_.reset();
    return false;
  }
  // The state carried across from where the tissue is now (the old body went on stepping meanwhile).
  setup_ = std::move(p.setup);
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
  retire(std::move(body_));
  body_ = std::move(built.body);
  tets_ = std::make_shared<const std::vector<std::array<int, 4>>>(body_->tetrahedra());
  useContactSurface(std::move(built.contact));
  surface_ = std::move(built.surface);
  ++constructions_.cutSurfaces;
  cutEvents(p.cutLabels, message);
  updateToolConstraints();
  // The rest of a sweep the blade finished while this cut was being built.
  if (restOfSweep_) {
    const auto [from, to] = *restOfSweep_;
    restOfSweep_.reset();
    if (cut(from, to, message) && pendingCut_)
      pendingCut_->clearProgress = true;
    else
      setup_.cut.clear();
  }
  return true;
}

std::size_t connectedPieces(const std::vector<std::array<int, 4>>& tets, std::size_t nodes) {
  std::vector<int> parent(nodes);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i)
      i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    return i;
  };
  for (const auto& t : tets)
    for (int k = 1; k < 4; ++k) parent[static_cast<std::size_t>(find(t[static_cast<std::size_t>(k)]))] = find(t[0]);
  std::vector<char> root(nodes, 0);
  std::size_t pieces = 0;
  for (const auto& t : tets)
    if (const int r = find(t[0]); !root[static_cast<std::size_t>(r)]) root[static_cast<std::size_t>(r)] = 1, ++pieces;
  return pieces;
}

void Session::finishStroke(std::string& message) {
  const Stroke s = stroke_;
  stroke_ = {};
  if (s.updates == 0 && s.lastRefusal.empty()) return;  // the blade crossed nothing: nothing to say
  const std::size_t pieces = connectedPieces(body_->tetrahedra(), body_->nodeCount());
  std::string m;
  if (s.updates == 0) {
    m = "Nothing was cut: " + s.lastRefusal;
  } else {
    m = "The cut is done: " + std::to_string(s.separatedFaces) + " face(s) opened and " + std::to_string(s.split) +
        " element(s) split in " + std::to_string(s.updates) + " update(s); ";
    m += pieces > s.piecesBefore
             ? "the organ came apart (" + std::to_string(pieces) + " pieces, " + std::to_string(s.piecesBefore) +
                   " before)."
             : "the organ is still in " + std::string(pieces == 1 ? "one piece" : std::to_string(pieces) + " pieces") +
                   " (the cut did not go through).";
    if (s.skippedInverted > 0)
      m += " " + std::to_string(s.skippedInverted) +
           " crossed element(s) were inverted and not cut: tissue still joins there.";
    if (!s.lastRefusal.empty()) m += " The stroke's last sweep was not cut: " + s.lastRefusal;
  }
  if (!message.empty()) message += " ";
  message += m;
}

std::shared_ptr<const CutSurface> makeCutSurface(const BodySetup& uncutSetup, const Mesh& cutMesh, double meanEdge) {
  // The boundary of the cut mesh; a triangle is the organ's own surface when its rest centre lies on a
  // triangle of the uncut boundary (a uniform grid over those), cut tissue otherwise.
  Mesh uncut = uncutSetup.mesh;
  uncut.convertToMetres();
  if (!uncutSetup.rest.empty()) uncut.points = uncutSetup.rest;
  const auto outer = boundaryTriangles(uncut, false);
  auto out = std::make_shared<CutSurface>();
  out->triangles = boundaryTriangles(cutMesh, false);
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

bool Session::applyPendingCut() {
  std::lock_guard<std::mutex> stepLock(stepMutex_);
  if (!pendingCut_) return false;
  std::string message;
  const bool applied = finishPendingCut(true, message);
  if (applied) {
    InputEvent c;  // recorded, as any cut applied
    c.kind = InputKind::CutApplied;
    c.step = steps_;
    c.wallTime = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    recorded_.push_back(c);
    publish(snapshot()->report, message, std::move(events_));
    events_.clear();
  }
  return applied;
}

void Session::discardPending() {
  std::lock_guard<std::mutex> lock(mailboxMutex_);
  mailbox_.clear();
}

void Session::forgetCutProgress() {
  if (pendingCut_)
    pendingCut_->clearProgress = true;
  else
    setup_.cut.clear();
}

void Session::beginStroke() {
  stroke_ = {};
  stroke_.open = true;
  stroke_.piecesBefore = connectedPieces(body_->tetrahedra(), body_->nodeCount());
}

}  // namespace rehearse::simcore
