// The cut: what the blade's sweep asks of the cut module (cut.hpp computes the new mesh; the session's topology
// mechanism, topology.cpp, builds and swaps the body), and what a cut says: its events, the vessels it cut, and the
// stroke's sentence once all of it is in (whether the organ came apart; the stroke's own record: strokes.cpp).
#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace rehearse::simcore {

bool Session::cut(const Eigen::Vector3d& from, const Eigen::Vector3d& to, std::string& message) {
  // One change at a time: while the last one's body is being built the sweep grows (the blade's start stays).
  if (builds_.underWay()) return false;
  // The blade: from the tip back along the shaft towards the trocar; its sweep between the two poses is
  // planar (both shafts pass through the trocar). A tip pushed deeper than the blade reaches (the wheel, 2 mm a notch)
  // has cut its way there (ToolSettings::bladeReachesTheSurface): the sweep then reaches back along the shaft to where
  // the shaft leaves the tissue (its last crossing of the surface, 2 mm beyond). With the blade alone, a stroke 40 mm
  // deep opened a crack 10 mm under an intact surface: the vessel it cut bled where no one could see it, and the
  // stroke left no mark on the organ (the sessions recorded before it existed still cut so).
  const Eigen::Vector3d trocar = *setup_.tools.trocar;
  auto bladeEnd = [&](const Eigen::Vector3d& tip) {
    const Eigen::Vector3d d = trocar - tip;
    if (!(d.norm() > 0)) return tip;
    const Eigen::Vector3d u = d.normalized();
    double reach = setup_.tools.bladeLength;
    // (Moller-Trumbore on the boundary at the current positions: the farthest crossing along the shaft.)
    for (const auto& t : contact_.triangles) {
      if (!setup_.tools.bladeReachesTheSurface) break;
      const Eigen::Vector3d a = state_.x.segment<3>(3 * static_cast<Eigen::Index>(t[0]));
      const Eigen::Vector3d e1 = state_.x.segment<3>(3 * static_cast<Eigen::Index>(t[1])) - a;
      const Eigen::Vector3d e2 = state_.x.segment<3>(3 * static_cast<Eigen::Index>(t[2])) - a;
      const Eigen::Vector3d p = u.cross(e2);
      const double det = e1.dot(p);
      if (!(std::abs(det) > 1e-18)) continue;
      const Eigen::Vector3d s = tip - a;
      const double b1 = s.dot(p) / det;
      if (b1 < 0 || b1 > 1) continue;
      const Eigen::Vector3d q = s.cross(e1);
      const double b2 = u.dot(q) / det;
      if (b2 < 0 || b1 + b2 > 1) continue;
      const double along = e2.dot(q) / det;
      if (along > 0 && std::isfinite(along)) reach = std::max(reach, along + 0.002);
    }
    return Eigen::Vector3d(tip + std::min(reach, 0.999 * d.norm()) * u);
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
  strokes_.counted(r, message);
  if (!r.changed) return false;
  ++constructions_.cutMeshes;
  TopologyChange change =
      changeFromCut(r, std::move(rest), std::move(tets), std::move(labels), std::move(progress), ChangeKind::Cut);
  if (changeTopology(std::move(change), message)) return true;
  message = "The cut was refused: " + message;
  return false;
}

TopologyChange Session::changeFromCut(const CutResult& r, std::vector<Eigen::Vector3d> rest,
                                      std::vector<std::array<int, 4>> tets, std::vector<int> labels,
                                      CutProgress progress, ChangeKind kind) const {
  const std::size_t n = body_->nodeCount();
  TopologyChange change;
  change.kind = kind;
  change.setup = setup_;
  BodySetup& next = change.setup;
  next.mesh.points = std::move(rest);
  next.mesh.unitToMetre = 1.0;
  next.mesh.triangles.clear();
  next.mesh.triangleLabels.clear();
  next.mesh.tets = std::move(tets);
  next.mesh.tetLabels = std::move(labels);
  next.rest.clear();
  next.start.clear();  // the state carries on
  if (!next.tearFrom.empty()) {  // and so does where a tear's stretch is measured from
    Eigen::VectorXd from(3 * static_cast<Eigen::Index>(next.tearFrom.size()));
    for (std::size_t k = 0; k < next.tearFrom.size(); ++k) from.segment<3>(3 * static_cast<Eigen::Index>(k)) = next.tearFrom[k];
    extendByCut(from, r.newNodes);
    next.tearFrom.resize(static_cast<std::size_t>(from.size() / 3));
    for (std::size_t k = 0; k < next.tearFrom.size(); ++k) next.tearFrom[k] = from.segment<3>(3 * static_cast<Eigen::Index>(k));
  }
  next.cut = std::move(progress);
  const auto& fixed = body_->fixedMask();
  for (std::size_t k = 0; k < r.duplicateOf.size(); ++k)
    if (r.duplicateOf[k] >= 0 && fixed[static_cast<std::size_t>(r.duplicateOf[k])])
      next.fixedNodes.push_back(static_cast<int>(n + k));
  ++next.topology;
  change.newNodes = r.newNodes;
  change.labels = r.cutLabels;
  // A tear opens at its own latency (ToolSettings::tearLatencySteps), a blade's cut at the cut's.
  const int latency = kind == ChangeKind::Tear ? setup_.tools.tearLatencySteps : setup_.tools.cutLatencySteps;
  change.applyAt = latency >= 0 ? steps_ + latency : -1;
  change.late = kind == ChangeKind::Tear && latency >= 0 && setup_.tools.tearWhenBuilt &&
                setup_.settings.factorRefresh != FactorRefresh::Synchronous;
  if (setup_.settings.factorRefresh != FactorRefresh::Synchronous || latency >= 0) {
    change.factorAt = state_.x;
    extendByCut(change.factorAt, r.newNodes);
  }
  return change;
}

void Session::continueSweep(std::string& message) {
  // The rest of a sweep the blade finished while the last cut was being built.
  const auto rest = strokes_.takeRestOfSweep();
  if (!rest) return;
  const auto [from, to] = *rest;
  if (cut(from, to, message) && builds_.underWay())
    builds_.pending()->clearProgress = true;
  else
    setup_.cut.clear();
}

void Session::cutEvents(const std::vector<int>& cutLabels, std::string& message) {
  seedEasing_ = true;  // the surface is new: what lies inside the shaft now is eased out at the next constraints
  events_.push_back(eventWord(EventKind::Cut));
  for (int label : cutLabels) events_.push_back(cutThroughLabelWord(label));
  // A named structure (a label whose name gives it a kind, Mesh::labelKind) cut by this stroke is one event, however
  // many updates the cut takes: "portal vein cut", "artery cut", "vein cut", "bile duct cut", "ligament cut", "tumour
  // cut", "tumour margin breached"; a blood vessel of any kind is also a "vessel cut" (what the metrics count).
  for (int label : cutLabels) {
    const StructureKind kind = setup_.mesh.labelKind(label);
    if (kind == StructureKind::Tissue ||
        std::find(tool_.structuresCut.begin(), tool_.structuresCut.end(), label) != tool_.structuresCut.end())
      continue;
    tool_.structuresCut.push_back(label);
    const std::string what = structureKindName(kind), words = structureWords(kind, setup_.mesh.labelName(label));
    if (kind == StructureKind::TumourMargin)
      events_.push_back(eventWord(EventKind::TumourMarginBreached));
    else if (kind != StructureKind::Vessel)
      events_.push_back(structureEventWord(EventKind::StructureCut, what));
    // In a surgeon's words: "A cystic artery was cut." (the label's number is in the event "cut through label N").
    if (kind == StructureKind::Tumour)
      message = "The " + words + " was cut into.";
    else if (kind == StructureKind::TumourMargin)
      message = "The " + words + " was breached.";
    else
      message = std::string(indefiniteArticle(words)) + " " + words + " was cut.";
    if (isVessel(kind)) events_.push_back(eventWord(EventKind::VesselCut));
  }
}

std::size_t connectedPieces(const std::vector<std::array<int, 4>>& tets, std::size_t nodes) {
  return pieceVolumes(tets, std::vector<Eigen::Vector3d>(nodes, Eigen::Vector3d::Zero())).size();
}

std::vector<int> nodePieces(const std::vector<std::array<int, 4>>& tets, std::size_t nodes) {
  std::vector<int> parent(nodes);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i)
      i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    return i;
  };
  for (const auto& t : tets)
    for (int k = 1; k < 4; ++k) parent[static_cast<std::size_t>(find(t[static_cast<std::size_t>(k)]))] = find(t[0]);
  std::vector<int> id(nodes, -1), piece(nodes, -1);
  int next = 0;
  for (const auto& t : tets)
    if (int& r = id[static_cast<std::size_t>(find(t[0]))]; r < 0) r = next++;
  for (std::size_t i = 0; i < nodes; ++i) piece[i] = id[static_cast<std::size_t>(find(static_cast<int>(i)))];
  return piece;
}

std::vector<double> pieceVolumes(const std::vector<std::array<int, 4>>& tets, const std::vector<Eigen::Vector3d>& rest) {
  const std::vector<int> piece = nodePieces(tets, rest.size());
  std::vector<double> volume(static_cast<std::size_t>(
      piece.empty() ? 0 : std::max(0, *std::max_element(piece.begin(), piece.end()) + 1)));
  for (const auto& t : tets) {
    const auto p = [&](int k) -> const Eigen::Vector3d& { return rest[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])]; };
    volume[static_cast<std::size_t>(piece[static_cast<std::size_t>(t[0])])] +=
        std::abs((p(1) - p(0)).cross(p(2) - p(0)).dot(p(3) - p(0))) / 6;
  }
  std::sort(volume.begin(), volume.end(), std::greater<>());
  return volume;
}

void Session::finishStroke(std::string& message) {
  if (const auto s = strokes_.end())
    StrokeTracker::say(*s, pieceVolumes(body_->tetrahedra(), body_->restPositions()), message);
}

void Session::forgetCutProgress() {
  if (builds_.underWay())
    builds_.pending()->clearProgress = true;
  else
    setup_.cut.clear();
}

void Session::beginStroke() {
  strokes_.begin(connectedPieces(body_->tetrahedra(), body_->nodeCount()));
}

}  // namespace rehearse::simcore
