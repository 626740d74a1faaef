// Tearing: tissue (and what attaches it) pulled past the strain its material declares tears. After every step the
// element stretched furthest past its material's tear strain (MaterialParams::tearStrain: largest principal stretch
// minus 1) is split across that stretch: a square in the plane through its centre, normal to the stretched direction,
// as large as the element, cut through the cut module's re-meshing (cut.hpp) and applied by the session's topology
// mechanism (topology.cpp) like a blade's cut, with the scene's latency. A torn vessel bleeds like a cut one
// (field.cpp: its torn faces are open stumps). Nothing is measured unless some material declares a tear strain. The
// stretch is measured from where the organ started (BodySetup::tearFrom: the registered shape it starts in equilibrium
// at, whose rest shape sags into it stretched): the in-vivo organ is not torn, what tears it is what the instruments add.
#include <rehearse/simcore/session/events.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace rehearse::simcore {
namespace {
Eigen::Vector3d nodeAt(const Eigen::VectorXd& x, int i) { return x.segment<3>(3 * static_cast<Eigen::Index>(i)); }

// Appends a sentence to the message, after a space when it already says something.
void say(std::string& message, const std::string& sentence) { message += (message.empty() ? "" : " ") + sentence; }

// An element past its limit, with its stretched direction.
struct Over {
  double ratio, strain, limit;
  int element;
  Eigen::Vector3d direction;
};

// The elements past their limit, furthest first (by strain over limit), each with its stretched direction.
std::vector<Over> overStretched(const std::vector<std::array<int, 4>>& tets, const std::vector<int>& labels,
                                const std::vector<Eigen::Vector3d>& from, const Eigen::VectorXd& x,
                                const std::function<double(int)>& limitOf) {
  std::vector<Over> over;
  for (std::size_t e = 0; e < tets.size(); ++e) {
    const double limit = limitOf(e < labels.size() ? labels[e] : 0);
    if (!(limit > 0)) continue;
    const auto& t = tets[e];
    Eigen::Matrix3d Dm, Ds;
    for (int k = 0; k < 3; ++k) {
      Dm.col(k) =
          from[static_cast<std::size_t>(t[static_cast<std::size_t>(k + 1)])] - from[static_cast<std::size_t>(t[0])];
      Ds.col(k) = nodeAt(x, t[static_cast<std::size_t>(k + 1)]) - nodeAt(x, t[0]);
    }
    if (!(std::abs(Dm.determinant()) > 0)) continue;
    const Eigen::Matrix3d F = Ds * Dm.inverse();
    if (!(F.determinant() > 0) || !F.allFinite()) continue;  // an inverted element is compressed, not torn
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(F.transpose() * F);
    const double strain = std::sqrt(std::max(es.eigenvalues()(2), 0.0)) - 1;
    if (!(strain > limit)) continue;
    const Eigen::Vector3d stretched = F * es.eigenvectors().col(2);  // the stretched direction, where the tissue is
    over.push_back({strain / limit, strain, limit, static_cast<int>(e),
                    stretched.norm() > 0 ? Eigen::Vector3d(stretched.normalized()) : Eigen::Vector3d::UnitX()});
  }
  std::sort(over.begin(), over.end(), [](const Over& a, const Over& b) {
    return a.ratio != b.ratio ? a.ratio > b.ratio : a.element < b.element;
  });
  return over;
}

// The tear's square across the stretch of element `t`, reaching its farthest node (times `widen`), through the middle
// of the widest gap between its nodes along the stretch.
BladeSweep tearSquare(const Over& o, const std::array<int, 4>& t, const Eigen::VectorXd& x, double widen) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (int v : t) centre += 0.25 * nodeAt(x, v);
  std::array<double, 4> along{};
  for (std::size_t k = 0; k < 4; ++k) along[k] = (nodeAt(x, t[k]) - centre).dot(o.direction);
  std::sort(along.begin(), along.end());
  double offset = 0, gap = -1;
  for (std::size_t k = 0; k + 1 < 4; ++k)
    if (along[k + 1] - along[k] > gap) gap = along[k + 1] - along[k], offset = 0.5 * (along[k] + along[k + 1]);
  centre += offset * o.direction;
  double reach = 0;
  for (int v : t) reach = std::max(reach, (nodeAt(x, v) - centre).norm());
  reach *= widen;
  const Eigen::Vector3d u = o.direction.unitOrthogonal(), w = o.direction.cross(u);
  return BladeSweep{centre - reach * u - reach * w, centre - reach * u + reach * w, centre + reach * u - reach * w,
                    centre + reach * u + reach * w};
}

// The tear's front when the tear parts the tissue along faces (ToolSettings::tearRemovesElements): the over-stretched
// elements the plane through the worst one's centre, across its stretch, runs through, reached from it through shared
// faces. (Every over-stretched element at once took a uniformly stretched bar out whole; the worst one alone let the
// patient liver's pull outrun its tears, 18 of them, until the steps stalled.)
// The elements holding a node the jaws hold are the jaws' bite: they stay with the jaws, and the front is the tissue
// beside the bite (the worst over-stretched element outside it seeds the plane). Taken out with the rest, the bite's
// nodes were left with no element, pinned and dropped by the jaws: a bar pulled at its end stayed in one piece.
// When every over-stretched element is in the bite, the bite is parted as any tissue.
std::vector<int> tearFront(const std::vector<Over>& allOver, const std::vector<std::array<int, 4>>& tets,
                           const Eigen::VectorXd& x, const std::vector<int>& held) {
  auto bites = [&](int e) {
    for (int v : tets[static_cast<std::size_t>(e)])
      if (std::find(held.begin(), held.end(), v) != held.end()) return true;
    return false;
  };
  std::vector<Over> outside;
  for (const Over& o : allOver)
    if (!bites(o.element)) outside.push_back(o);
  const std::vector<Over>& over = outside.empty() ? allOver : outside;
  const Over& worst = over.front();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (int v : tets[static_cast<std::size_t>(worst.element)]) centre += 0.25 * nodeAt(x, v);
  auto crossed = [&](int e) {
    double lo = 1e300, hi = -1e300;
    for (int v : tets[static_cast<std::size_t>(e)]) {
      const double d = (nodeAt(x, v) - centre).dot(worst.direction);
      lo = std::min(lo, d), hi = std::max(hi, d);
    }
    return lo < 0 && hi > 0;
  };
  std::vector<int> candidates;
  for (const Over& o : over)
    if (o.element == worst.element || crossed(o.element)) candidates.push_back(o.element);
  auto shareAFace = [&](int a, int b) {
    int shared = 0;
    for (int u : tets[static_cast<std::size_t>(a)])
      for (int v : tets[static_cast<std::size_t>(b)]) shared += u == v;
    return shared >= 3;
  };
  std::vector<int> front{worst.element};
  std::vector<char> taken(candidates.size(), 0);
  for (std::size_t k = 0; k < candidates.size(); ++k) taken[k] = candidates[k] == worst.element;
  for (std::size_t i = 0; i < front.size(); ++i)
    for (std::size_t k = 0; k < candidates.size(); ++k)
      if (!taken[k] && shareAFace(front[i], candidates[k])) {
        taken[k] = 1;
        front.push_back(candidates[k]);
      }
  return front;
}

// The named structures the tear went through, each new one's events recorded ("a, b (name)"); `attached` is set when
// one is a ligament.
std::string tornStructures(const std::vector<int>& tornLabels, const Mesh& mesh, std::vector<std::string>& events,
                           bool& attached) {
  std::string structures;
  for (int l : tornLabels) {
    const StructureKind kind = mesh.labelKind(l);
    if (kind == StructureKind::Tissue) continue;
    attached = attached || kind == StructureKind::Ligament;
    const std::string what = structureKindName(kind);
    const std::string torn = structureEventWord(EventKind::StructureTorn, what);
    if (std::find(events.begin(), events.end(), torn) == events.end()) {
      events.push_back(torn);
      if (isVessel(kind) && kind != StructureKind::Vessel) events.push_back(eventWord(EventKind::VesselTorn));
      const std::string name = mesh.labelName(l);
      structures += (structures.empty() ? "" : ", ") + what + (name.empty() ? "" : " (" + name + ")");
    }
  }
  return structures;
}
}  // namespace

void Session::tearOverStretched(std::string& message) {
  if (builds_.underWay()) return;  // one change at a time: an element still over-stretched tears once this one is in
  auto limitOf = [this](int label) {
    const auto it = setup_.byLabel.find(label);
    return it != setup_.byLabel.end() ? it->second.tearStrain : setup_.material.tearStrain;
  };
  bool declared = setup_.material.tearStrain > 0;
  for (const auto& [label, m] : setup_.byLabel) declared = declared || m.tearStrain > 0;
  if (!declared) return;
  if (!bodyModelChangesTissue(setup_.model)) {
    if (!saidNoTear_)
      say(message, std::string(setup_.model == BodyModel::Ffd
                                   ? "The FFD model does not tear (it deforms the surface alone, geometrically)"
                                   : "The precomputed model does not tear (its responses are the intact organ's)") +
                       ": the scene's tear strains are not applied; choose the FEM or the hybrid model to tear.");
    saidNoTear_ = true;
    return;
  }
  // A tear grows while the jaws pull the tissue and stops when they let go (ToolSettings::tearOnlyUnderLoad, issue 61):
  // with nothing held, no element is measured after the first step (that one says if the organ starts past its limit).
  // (Not a shaft's contact: a released grasper stays where it let go, and the tissue springing back onto it tore 12
  // times in 100 steps on the patient liver.) And only at a step the jaws move (ToolSettings::tearOnlyWhilePulled):
  // jaws held still on a torn, still stretched tissue tore it again every 6 steps until released.
  const bool loaded = !tool_.held.empty() && (!setup_.tools.tearOnlyWhilePulled || jawsPull_);
  if (setup_.tools.tearOnlyUnderLoad && !loaded && steps_ > 1) return;
  const auto& rest = body_->restPositions();
  // The stretch is the instruments' (and the tissue's own since): measured from where the organ started, when it
  // started deformed (BodySetup::tearFrom), else from its rest shape.
  const auto& from = setup_.tearFrom.size() == rest.size() ? setup_.tearFrom : rest;
  const auto& tets = body_->tetrahedra();
  const auto& labels = body_->labels();
  const std::vector<Over> over = overStretched(tets, labels, from, state_.x, limitOf);
  if (over.empty()) {
    tearRefused_ = false;
    return;
  }
  // Over-stretched at the first step, before any instrument touched it: the organ hangs stretched past its limit (a
  // registered shape hung on a few attachments stretches beside them) and tears untouched. Said with what
  // to change, before the tear's own sentence.
  // (Tearing only while the jaws pull it, it tears at the first grasp instead.)
  if (steps_ <= 1 && !tool_.present) {
    char said[320];
    std::snprintf(
        said, sizeof said,
        "The tissue is stretched %.0f %% at the start, before anything touched it, where its material tears "
        "at %.0f %%: it tears %s. Raise the tear strain above that (the Simulation panel's "
        "\"tears at\") or hold the organ by more attachments.",
        100 * over.front().strain, 100 * over.front().limit,
        setup_.tools.tearOnlyUnderLoad ? "as soon as the grasper pulls it" : "without being touched");
    say(message, said);
  }
  char buf[320];
  // The tear asked for, either way it is made: the change, then what tore (the tissue, each named structure it went
  // through, an attachment), said once.
  auto makeTear = [&](TopologyChange change, bool attached, double strain, double limit) {
    const std::vector<int> tornLabels = change.labels;
    std::string sentence;
    if (!changeTopology(std::move(change), sentence)) {
      say(message, "The tear could not be made: " + sentence);
      return;
    }
    events_.push_back(eventWord(EventKind::Tear));
    const std::string structures = tornStructures(tornLabels, setup_.mesh, events_, attached);
    if (attached) events_.push_back(eventWord(EventKind::AttachmentTorn));
    std::snprintf(buf, sizeof buf, "The %s tore: stretched %.0f %% where its material tears at %.0f %%%s.",
                  attached ? "tissue at its attachment" : "tissue", 100 * strain, 100 * limit,
                  structures.empty() ? "" : (", through the " + structures).c_str());
    say(message, buf);
    if (!sentence.empty()) message += " " + sentence;
  };
  if (setup_.tools.tearOnlyUnderLoad && !loaded) return;
  // Only a converged step's positions tear: an inexact step's (the best of its tries, kept) can be far from where the
  // tissue is. Tearing them set off a cascade on the patient liver: after two tears an element by the crack kept
  // tripping the inversion guard, the steps stayed inexact (relative residual 0.06 growing to 1), and each tear the
  // wrong strains made grew the mesh from 10,034 to 24,948 elements in 44 steps, 64 m from equilibrium.
  if (!stepConverged_) {
    if (!tearHeld_) {
      std::snprintf(buf, sizeof buf,
                    "The tissue reads %.0f %% stretched where its material tears at %.0f %%, but the step did not "
                    "converge: it is not torn until a step does.",
                    100 * over.front().strain, 100 * over.front().limit);
      say(message, buf);
    }
    tearHeld_ = true;
    return;
  }
  tearHeld_ = false;
  if (setup_.tools.tearRemovesElements) {
    // The tear parts the tissue along the faces of its front's elements: they are taken out of the mesh and the nodes
    // stay, so the unknowns, the factor's size and most of the tangent are as they were. A node no element holds any
    // more (a corner of the front) is pinned where it is, out of every surface: nothing draws, touches or moves it.
    // (Kept on a softened element instead, such nodes bridged the crack: a bar taken apart stayed in one piece.)
    const std::vector<int> front = tearFront(over, tets, state_.x, tool_.held);
    std::vector<int> uses(body_->nodeCount(), 0);
    for (const auto& t : tets)
      for (int v : t) ++uses[static_cast<std::size_t>(v)];
    std::vector<char> out(tets.size(), 0);
    CutResult parted;  // no new nodes: the front's elements out, their labels
    std::vector<int> orphans;
    bool attached = false;
    for (int e : front) {
      const auto& t = tets[static_cast<std::size_t>(e)];
      for (int v : t) attached = attached || body_->fixedMask()[static_cast<std::size_t>(v)];
      const int label = e < static_cast<int>(labels.size()) ? labels[static_cast<std::size_t>(e)] : 0;
      if (std::find(parted.cutLabels.begin(), parted.cutLabels.end(), label) == parted.cutLabels.end())
        parted.cutLabels.push_back(label);
      out[static_cast<std::size_t>(e)] = 1;
      for (int v : t)
        if (--uses[static_cast<std::size_t>(v)] == 0) orphans.push_back(v);
    }
    std::sort(parted.cutLabels.begin(), parted.cutLabels.end());
    std::vector<std::array<int, 4>> keptTets;
    std::vector<int> keptLabels;
    keptTets.reserve(tets.size());
    keptLabels.reserve(tets.size());
    for (std::size_t e = 0; e < tets.size(); ++e)
      if (!out[e]) keptTets.push_back(tets[e]), keptLabels.push_back(e < labels.size() ? labels[e] : 0);
    // The same new setup as a cut's (the state carries on; the same nodes), at the tear's latency.
    TopologyChange change = changeFromCut(parted, rest, std::move(keptTets), std::move(keptLabels), setup_.cut,
                                          ChangeKind::Tear);
    change.setup.fixedNodes.insert(change.setup.fixedNodes.end(), orphans.begin(), orphans.end());
    tearRefused_ = false;
    ++constructions_.cutMeshes;
    makeTear(std::move(change), attached, over.front().strain, over.front().limit);
    return;
  }
  // The tear: a square across the stretch, reaching the element's farthest node, through the middle of the widest gap
  // between its nodes along the stretch (as far from them as it can be: a plane near a node snaps to it and may cross
  // nothing). When the furthest element cannot be split (a sliver, a plane through its nodes), the next ones are
  // tried: the tear goes on where the tissue is over-stretched.
  // When none of them can (each square crosses edges its neighbours share, and the cut's front snaps those to nodes),
  // the same squares twice as large, across the neighbours too (ToolSettings::tearThroughNeighbours).
  constexpr std::size_t kTries = 8;
  const std::size_t tries = std::min(kTries, over.size());
  const std::size_t attempts = setup_.tools.tearThroughNeighbours ? 2 * tries : tries;
  CutResult r;
  std::vector<Eigen::Vector3d> restCopy, current;
  std::vector<std::array<int, 4>> tetsCopy;
  std::vector<int> labelsCopy;
  const Over* torn = nullptr;
  std::string firstStatus;  // why the element alone could not tear (said when no attempt could)
  for (std::size_t attempt = 0; attempt < attempts && !torn; ++attempt) {
    const std::size_t i = attempt % tries;
    const double widen = attempt < tries ? 1.05 : 2.1;
    const Over& o = over[i];
    const BladeSweep square = tearSquare(o, tets[static_cast<std::size_t>(o.element)], state_.x, widen);
    restCopy = rest;
    current.resize(restCopy.size());
    for (std::size_t k = 0; k < current.size(); ++k) current[k] = nodeAt(state_.x, static_cast<int>(k));
    tetsCopy = tets;
    labelsCopy = labels;
    r = cutTetrahedra(restCopy, current, tetsCopy, labelsCopy, square, setup_.tools.cut, nullptr);
    if (r.changed && r.separatedFaces > 0) torn = &o;
    if (attempt == 0) firstStatus = r.status;
  }
  if (!torn) {
    // Said once until a tear is made (it is asked for again at every step while the tissue stays over-stretched).
    if (!tearRefused_) {
      std::snprintf(buf, sizeof buf,
                    "The tissue is stretched %.0f %% where its material tears at %.0f %%, but the tear could not be "
                    "made there: %s",
                    100 * over.front().strain, 100 * over.front().limit,
                    (firstStatus.empty() ? r.status : firstStatus).c_str());
      say(message, buf);
    }
    tearRefused_ = true;
    return;
  }
  const double worstStrain = torn->strain, worstLimit = torn->limit;
  const auto& t = tets[static_cast<std::size_t>(torn->element)];
  tearRefused_ = false;
  ++constructions_.cutMeshes;
  bool attached = false;  // the torn element held by an attachment (a ligament's fixed node) or is a ligament
  for (int v : t) attached = attached || body_->fixedMask()[static_cast<std::size_t>(v)];
  makeTear(changeFromCut(r, std::move(restCopy), std::move(tetsCopy), std::move(labelsCopy), setup_.cut,
                         ChangeKind::Tear),  // at the tear's latency
           attached, worstStrain, worstLimit);
}

}  // namespace rehearse::simcore
