// The operative field (field.hpp): where a clip closes and the rows that close it, and which stumps of cut vessels
// bleed.
#include <rehearse/simcore/constraint_solver.hpp>
#include <rehearse/simcore/session/field.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>

namespace rehearse::simcore {

namespace {
Eigen::Vector3d node(const Eigen::VectorXd& x, int i) { return x.segment<3>(3 * static_cast<Eigen::Index>(i)); }

// A unit vector perpendicular to `a` (unit), from `hint` when it is not along `a`.
Eigen::Vector3d perpendicular(const Eigen::Vector3d& a, const Eigen::Vector3d& hint) {
  Eigen::Vector3d p = hint - hint.dot(a) * a;
  if (p.norm() > 1e-6 * std::max(1.0, hint.norm())) return p.normalized();
  p = a.unitOrthogonal();
  return p;
}

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int i) {
    while (parent[static_cast<std::size_t>(i)] != i)
      i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    return i;
  }
  void join(int a, int b) { parent[static_cast<std::size_t>(find(a))] = find(b); }
};

// Does element `t` hold the tip: one of its nodes within `onNode` of it, or the tip inside it?
bool holdsTip(const Eigen::VectorXd& x, const std::array<int, 4>& t, const Eigen::Vector3d& tip, double onNode) {
  for (int v : t)
    if ((node(x, v) - tip).squaredNorm() <= onNode * onNode) return true;
  Eigen::Matrix3d D;
  for (int k = 0; k < 3; ++k) D.col(k) = node(x, t[static_cast<std::size_t>(k + 1)]) - node(x, t[0]);
  const Eigen::Vector3d r = tip - node(x, t[0]);
  if (r.squaredNorm() > D.colwise().squaredNorm().maxCoeff()) return false;  // too far to be inside
  const Eigen::Vector3d b = D.fullPivLu().solve(r);
  return b.allFinite() && b.minCoeff() >= 0 && b.sum() <= 1;
}

// The element whose label the jaws close on (-1: none within reach). The label of the element whose centre is
// nearest the tip, within reach, a vessel's or a duct's before any other, and a vessel's or a duct's element that
// holds the tip (inside it or on one of its nodes, within 1 mm: a click aims at the shape the view shows, a step or two
// behind) before all. When no centre is within reach (a mesh coarser than the reach: on the patient liver at 5,000
// elements their centres lie 9 mm from their nodes, and a click on an artery's node closed on nothing, or on the
// tissue beside it), the elements the tip touches: by their nodes within reach, or holding the tip.
int nearestElement(const Eigen::VectorXd& x, const std::vector<std::array<int, 4>>& tets,
                   const std::vector<int>& labels, const Eigen::Vector3d& tip, double reach,
                   const std::function<StructureKind(int)>& kindOf) {
  double best = reach * reach, bestClosable = reach * reach;
  int nearest = -1, nearestClosable = -1;
  std::map<int, bool> closable;
  auto canClose = [&](int label) {
    auto it = closable.find(label);
    if (it == closable.end()) {
      const StructureKind k = kindOf ? kindOf(label) : StructureKind::Tissue;
      it = closable.emplace(label, isVessel(k) || k == StructureKind::BileDuct).first;
    }
    return it->second;
  };
  for (int pass = 0; pass < 2 && nearest < 0 && nearestClosable < 0; ++pass) {
    for (std::size_t e = 0; e < tets.size(); ++e) {
      const auto& t = tets[e];
      const int label = e < labels.size() ? labels[e] : 0;
      const bool vessel = canClose(label);
      double d = std::numeric_limits<double>::infinity();
      if (pass == 0) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (int v : t) c += node(x, v);
        d = (0.25 * c - tip).squaredNorm();
      } else {
        for (int v : t) d = std::min(d, (node(x, v) - tip).squaredNorm());
        if (d > best && holdsTip(x, t, tip, 0)) d = 0;
      }
      double dc = d;  // as a closable structure's element
      if (vessel && dc > 0 && holdsTip(x, t, tip, 1e-3)) dc = 0;
      if (d <= best) best = d, nearest = static_cast<int>(e);
      if (vessel && dc <= bestClosable) bestClosable = dc, nearestClosable = static_cast<int>(e);
    }
  }
  if (nearestClosable >= 0) nearest = nearestClosable;
  return nearest;
}

// The structure aimed at, when one of its elements is within reach (by a node, or holding the tip): `nearest` becomes
// that element. Otherwise the note saying why it was not (empty when nothing was aimed at).
std::string aimAt(const Eigen::VectorXd& x, const std::vector<std::array<int, 4>>& tets, const std::vector<int>& labels,
                  const Eigen::Vector3d& tip, double reach, int aimed, int& nearest) {
  std::string aimedNote;
  if (aimed > 0 && tip.allFinite()) {
    double bestAimed = std::numeric_limits<double>::infinity();
    int nearestAimed = -1;
    for (std::size_t e = 0; e < tets.size() && e < labels.size(); ++e) {
      if (labels[e] != aimed) continue;
      double d = std::numeric_limits<double>::infinity();
      for (int v : tets[e]) d = std::min(d, (node(x, v) - tip).squaredNorm());
      if (d > reach * reach && holdsTip(x, tets[e], tip, 0)) d = 0;
      if (d < bestAimed) bestAimed = d, nearestAimed = static_cast<int>(e);
    }
    if (nearestAimed >= 0 && bestAimed <= reach * reach) {
      nearest = nearestAimed;
    } else {
      char buf[200];
      if (nearestAimed >= 0)
        std::snprintf(buf, sizeof buf,
                      " The structure the jaws were aimed at lay %.1f mm from the tip, beyond their reach (%.0f mm).",
                      1e3 * std::sqrt(bestAimed), 1e3 * reach);
      else
        std::snprintf(buf, sizeof buf, " The structure the jaws were aimed at (label %d) is not in the mesh.", aimed);
      aimedNote = buf;
    }
  }
  return aimedNote;
}

// The clipped label's nodes near the tip (sorted) and its elements' mean edge there.
struct NearStructure {
  std::vector<int> near;
  double edge = 0;
};

NearStructure structureNearTip(const Eigen::VectorXd& x, const std::vector<std::array<int, 4>>& tets,
                               const std::vector<int>& labels, int label, int nearest, const Eigen::Vector3d& tip,
                               double search, double width) {
  NearStructure out;
  // The label's nodes near the tip, and its elements' mean edge there.
  std::vector<char> inLabel(static_cast<std::size_t>(x.size() / 3), 0);
  double edgeSum = 0;
  int edges = 0;
  for (std::size_t e = 0; e < tets.size(); ++e) {
    if ((e < labels.size() ? labels[e] : 0) != label) continue;
    const auto& t = tets[e];
    if ((node(x, t[0]) - tip).norm() > 2 * search) continue;
    for (int v : t) inLabel[static_cast<std::size_t>(v)] = 1;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        edgeSum += (node(x, t[static_cast<std::size_t>(a)]) - node(x, t[static_cast<std::size_t>(b)])).norm(), ++edges;
  }
  out.edge = edges ? edgeSum / edges : width;
  // The structure near the tip: its nodes within reach that its elements join to the one nearest the tip (another
  // branch beside it, joined only further away, is not part of what the jaws close on).
  std::vector<char> within(inLabel.size(), 0);
  for (std::size_t i = 0; i < inLabel.size(); ++i)
    within[i] = inLabel[i] && (node(x, static_cast<int>(i)) - tip).norm() <= search;
  std::map<int, std::vector<int>> adjacent;
  for (std::size_t e = 0; e < tets.size(); ++e) {
    if ((e < labels.size() ? labels[e] : 0) != label) continue;
    const auto& t = tets[e];
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        if (a != b && within[static_cast<std::size_t>(t[static_cast<std::size_t>(a)])] &&
            within[static_cast<std::size_t>(t[static_cast<std::size_t>(b)])])
          adjacent[t[static_cast<std::size_t>(a)]].push_back(t[static_cast<std::size_t>(b)]);
  }
  int seed = -1;
  double seedDistance = std::numeric_limits<double>::infinity();
  for (int v : tets[static_cast<std::size_t>(nearest)])
    if (within[static_cast<std::size_t>(v)] && (node(x, v) - tip).norm() < seedDistance)
      seedDistance = (node(x, v) - tip).norm(), seed = v;
  if (seed >= 0) {
    std::vector<char> seen(within.size(), 0);
    std::vector<int> queue = {seed};
    seen[static_cast<std::size_t>(seed)] = 1;
    for (std::size_t q = 0; q < queue.size(); ++q)
      for (int w : adjacent[queue[q]])
        if (!seen[static_cast<std::size_t>(w)]) {
          seen[static_cast<std::size_t>(w)] = 1;
          queue.push_back(w);
        }
    out.near = std::move(queue);
    std::sort(out.near.begin(), out.near.end());
  }
  return out;
}

// The structure's direction: the principal axis of its nodes near the tip (the clip's axis), and the jaws' closing
// direction across it.
void orientClip(Clip& clip, const Eigen::VectorXd& x, const std::vector<int>& near, const Eigen::Vector3d& tip,
                const Eigen::Vector3d& trocar, const Eigen::Vector3d& across) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i : near) mean += node(x, i);
  mean /= std::max<double>(1, static_cast<double>(near.size()));
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int i : near) cov += (node(x, i) - mean) * (node(x, i) - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  clip.axis = near.size() >= 2 && es.info() == Eigen::Success ? es.eigenvectors().col(2).normalized()
                                                              : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d hint = across.norm() > 0 ? across : Eigen::Vector3d(tip - trocar);
  clip.across = perpendicular(clip.axis, hint);
}

// The jaws' frame and extent: their length across the structure (along `jaw`), their opening along the closing
// direction, the clip's width along the structure.
struct Jaws {
  Eigen::Vector3d jaw;
  double halfWidth, halfLength, opening;
};

// The nodes between the jaws; the clip's centre recentred on them across and along the jaws (a clip placed on the
// vessel's side closes on its middle).
std::vector<int> nodesBetweenJaws(const Eigen::VectorXd& x, const std::vector<int>& near, const std::vector<char>& fixed,
                                  const Clip& clip, const Jaws& j, Eigen::Vector3d& centre) {
  std::vector<int> between;
  for (int pass = 0; pass < 2; ++pass) {
    between.clear();
    for (int i : near) {
      const Eigen::Vector3d d = node(x, i) - centre;
      if (!fixed[static_cast<std::size_t>(i)] && std::abs(d.dot(clip.axis)) <= j.halfWidth &&
          std::abs(d.dot(j.jaw)) <= j.halfLength && std::abs(d.dot(clip.across)) <= j.opening)
        between.push_back(i);
    }
    if (between.empty()) break;
    Eigen::Vector3d m = Eigen::Vector3d::Zero();
    for (int i : between) m += node(x, i);
    m /= static_cast<double>(between.size());
    centre += (m - centre).dot(clip.across) * clip.across + (m - centre).dot(j.jaw) * j.jaw;
  }
  return between;
}

// How far the structure reaches from the clip's centre along the jaws.
double reachAlongJaws(const Eigen::VectorXd& x, const std::vector<int>& near, const Clip& clip, const Jaws& j,
                      const Eigen::Vector3d& centre) {
  double reaches = 0;
  for (int i : near) {
    const Eigen::Vector3d d = node(x, i) - centre;
    if (std::abs(d.dot(clip.axis)) <= j.halfWidth && std::abs(d.dot(clip.across)) <= j.opening)
      reaches = std::max(reaches, std::abs(d.dot(j.jaw)));
  }
  return reaches;
}

// The clip's nodes and their offsets across the jaws, closed to within half the gap (no further than the squeeze
// allows); the node nearest the centre is the anchor. Returns the widest offset, and the scale in `scale`.
double closeOnNodes(Clip& clip, const Eigen::VectorXd& x, const std::vector<int>& between,
                    const Eigen::Vector3d& centre, const ClipSettings& s, double& scale) {
  double widest = 0;
  std::vector<double> offset;
  for (int i : between) {
    offset.push_back((node(x, i) - centre).dot(clip.across));
    widest = std::max(widest, std::abs(offset.back()));
  }
  scale = widest > 0.5 * s.gap ? std::max(0.5 * s.gap / widest, std::min(1.0, s.minSqueeze)) : 1.0;
  std::size_t a = 0;
  for (std::size_t k = 1; k < between.size(); ++k)
    if (std::abs(offset[k]) < std::abs(offset[a])) a = k;
  clip.anchor = between[a];
  clip.anchorFrom = offset[a];
  clip.anchorTo = offset[a] * scale;
  for (std::size_t k = 0; k < between.size(); ++k) {
    if (k == a) continue;
    clip.nodes.push_back(between[k]);
    clip.from.push_back(offset[k]);
    clip.to.push_back(offset[k] * scale);
  }
  return widest;
}
}  // namespace

Clip placeClip(const Eigen::VectorXd& x, const std::vector<std::array<int, 4>>& tets, const std::vector<int>& labels,
               const std::vector<char>& fixed, const Eigen::Vector3d& tip, const Eigen::Vector3d& trocar,
               const Eigen::Vector3d& across, double reach, const ClipSettings& s, double time,
               const std::function<StructureKind(int)>& kindOf, std::string& message, int aimed) {
  Clip clip;
  clip.placedAt = time;
  clip.gap = s.gap;
  int nearest = nearestElement(x, tets, labels, tip, reach, kindOf);
  const std::string aimedNote = aimAt(x, tets, labels, tip, reach, aimed, nearest);
  if (nearest < 0 || !tip.allFinite()) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "The clip closed on nothing: no tissue within %.0f mm of the tip.", 1e3 * reach);
    message = buf;
    message += aimedNote;
    return clip;
  }
  clip.label = static_cast<std::size_t>(nearest) < labels.size() ? labels[static_cast<std::size_t>(nearest)] : 0;
  const double search = std::max(s.length, reach);
  const NearStructure structure = structureNearTip(x, tets, labels, clip.label, nearest, tip, search, s.width);
  const std::vector<int>& near = structure.near;
  const double edge = structure.edge;
  orientClip(clip, x, near, tip, trocar, across);
  // The jaws: their length across the structure, their opening along the closing direction (either side of the
  // centre: as wide as they are long, at least the reach they close within), the clip's width along the structure (at
  // least half an element edge).
  const Jaws jaws{clip.axis.cross(clip.across).normalized(), std::max(0.5 * s.width, 0.5 * edge), 0.5 * s.length,
                  std::max(s.length, reach)};
  Eigen::Vector3d centre = tip;
  const std::vector<int> between = nodesBetweenJaws(x, near, fixed, clip, jaws, centre);
  if (between.size() < 2) {
    message = "The clip closed on nothing: fewer than two free nodes of the tissue lie between its jaws.";
    message += aimedNote;
    return clip;
  }
  // Does the structure go on beyond the jaws (the clip does not close all of it)? Its nodes are where the mesh puts
  // them: within half an element edge past the jaws' ends it is taken as closed.
  const double reaches = reachAlongJaws(x, near, clip, jaws, centre);
  clip.spans = reaches <= jaws.halfLength + 0.5 * edge;
  double scale = 1.0;
  const double widest = closeOnNodes(clip, x, between, centre, s, scale);
  if (!clip.spans) {
    // Both lengths from the clip's centre (a person read "it reaches 8.2 mm from the clip's centre, beyond the 9 mm
    // jaws" as if it fitted: the 9 mm is end to end).
    char buf[280];
    std::snprintf(buf, sizeof buf,
                  "The clip does not span the structure: it reaches %.1f mm to one side of the clip's centre, and the "
                  "%.0f mm jaws %.1f mm (a longer clip: the Simulation panel's Clip length).",
                  1e3 * reaches, 1e3 * s.length, 0.5e3 * s.length);
    message = buf;
  }
  if (2 * widest * scale > s.gap * (1 + 1e-9)) {
    char buf[260];
    std::snprintf(buf, sizeof buf,
                  " The clip squeezes %.1f mm of tissue to %.1f mm, not to its %.1f mm gap: the mesh's elements there "
                  "(%.1f mm) are coarser than the structure, and closing them further would crush them.",
                  2e3 * widest, 2e3 * widest * scale, 1e3 * s.gap, 1e3 * edge);
    message += buf;
  }
  message += aimedNote;
  return clip;
}

void clipRows(const OperativeField& f, double time, double closeTime, std::vector<ScalarConstraint>& rows) {
  for (const Clip& c : f.clips) {
    if (c.anchor < 0) continue;
    const double s = closeTime > 0 ? std::clamp((time - c.placedAt) / closeTime, 0.0, 1.0) : 1.0;
    const double anchorAt = (1 - s) * c.anchorFrom + s * c.anchorTo;
    for (std::size_t k = 0; k < c.nodes.size(); ++k) {
      ScalarConstraint r;
      r.nodes = {c.nodes[k], c.anchor, -1, -1};
      r.weights = {1, -1, 0, 0};
      r.direction = c.across;
      r.value = (1 - s) * c.from[k] + s * c.to[k] - anchorAt;
      rows.push_back(r);
    }
  }
}

double settleHeldBackClip(Clip& c, const Eigen::VectorXd& x, double time, double closeTime, double tolerance) {
  if (c.anchor < 0) return -1;
  const double s = closeTime > 0 ? std::clamp((time - c.placedAt) / closeTime, 0.0, 1.0) : 1.0;
  const double anchorAt = (1 - s) * c.anchorFrom + s * c.anchorTo;
  const double anchor = node(x, c.anchor).dot(c.across);
  double off = 0, low = 0, high = 0;
  for (std::size_t k = 0; k < c.nodes.size(); ++k) {
    const double now = node(x, c.nodes[k]).dot(c.across) - anchor;
    off = std::max(off, std::abs(now - ((1 - s) * c.from[k] + s * c.to[k] - anchorAt)));
    low = std::min(low, now), high = std::max(high, now);
  }
  if (!(off > tolerance)) return -1;
  c.anchorFrom = c.anchorTo = 0;
  for (std::size_t k = 0; k < c.nodes.size(); ++k)
    c.from[k] = c.to[k] = node(x, c.nodes[k]).dot(c.across) - anchor;
  return high - low;
}

double bleedSpeed(StructureKind kind) {
  switch (kind) {
    case StructureKind::Artery:
      return 0.30;
    case StructureKind::PortalVein:
      return 0.15;
    case StructureKind::Vein:
    case StructureKind::Vessel:
      return 0.10;
    default:
      return 0;
  }
}

VesselPhysiology bleedingPhysiology(StructureKind kind) {
  constexpr double mmHg = 133.322, litrePerMinute = 1e-3 / 60;
  switch (kind) {
    case StructureKind::Artery:
      return {90 * mmHg, 4.5e-3, 0.35 * litrePerMinute};
    case StructureKind::PortalVein:
      return {8 * mmHg, 12e-3, 1.1 * litrePerMinute};
    case StructureKind::Vein:
    case StructureKind::Vessel:
      return {5 * mmHg, 10e-3, 0.5 * litrePerMinute};
    default:
      return {};
  }
}

double stumpBleedRate(StructureKind kind, double area) {
  const VesselPhysiology v = bleedingPhysiology(kind);
  if (!(area > 0) || !(v.trunkFlow > 0)) return 0;
  constexpr double dischargeCoefficient = 0.61, bloodDensity = 1060;  // kg/m^3
  const double orifice = dischargeCoefficient * area * std::sqrt(2 * v.pressure / bloodDensity);
  const double diameter = 2 * std::sqrt(area / std::numbers::pi);
  const double carried = v.trunkFlow * std::pow(std::min(1.0, diameter / v.trunkDiameter), 3);
  return std::min(orifice, carried);
}

int haemorrhageClass(double lost) {
  if (!(lost > 0)) return 0;
  const double ml = 1e6 * lost;
  return ml <= 750 ? 1 : ml <= 1500 ? 2 : ml <= 2000 ? 3 : 4;
}

std::string haemorrhageWords(int haemorrhageClass) {
  switch (haemorrhageClass) {
    case 1:
      return "up to 15 % of an adult's blood, a class I haemorrhage";
    case 2:
      return "more than 15 % of an adult's blood (750 mL), a class II haemorrhage";
    case 3:
      return "more than 30 % of an adult's blood (1,500 mL), a class III haemorrhage";
    case 4:
      return "more than 40 % of an adult's blood (2,000 mL), a class IV haemorrhage: life-threatening";
    default:
      return {};
  }
}

double boundToSupply(std::vector<Bleed>& bleeds, double supply) {
  double total = 0;
  for (const Bleed& b : bleeds)
    if (b.stoppedBy < 0) total += b.rate;
  if (!(total > supply) || !(supply >= 0)) return 1;
  const double factor = supply / total;
  for (Bleed& b : bleeds)
    if (b.stoppedBy < 0) b.rate *= factor;
  return factor;
}

std::vector<Bleed> findBleeds(const CutSurface& surface, const std::vector<std::array<int, 4>>& tets,
                              const std::vector<int>& labels, const std::vector<Clip>& clips,
                              const std::vector<Bleed>& previous, const std::function<StructureKind(int)>& kindOf,
                              double meanEdge, const BleedingSettings& bleeding) {
  std::vector<Bleed> out;
  const auto& rest = surface.rest;
  const std::size_t n = rest.size();
  // The cut faces of bleeding labels, by label.
  std::map<int, std::vector<std::size_t>> faces;
  std::map<int, double> speed;
  for (std::size_t k = 0; k < surface.triangles.size(); ++k) {
    if (!surface.cut[k] || k >= surface.labels.size()) continue;
    const int label = surface.labels[k];
    auto it = speed.find(label);
    if (it == speed.end()) it = speed.emplace(label, bleedSpeed(kindOf(label))).first;
    if (it->second > 0) faces[label].push_back(k);
  }
  for (const auto& [label, list] : faces) {
    // The pieces of this vessel (its elements sharing nodes): a clip stops a stump of its own piece only.
    UnionFind piece(n);
    for (std::size_t e = 0; e < tets.size(); ++e)
      if ((e < labels.size() ? labels[e] : 0) == label)
        for (int v = 1; v < 4; ++v) piece.join(tets[e][static_cast<std::size_t>(v)], tets[e][0]);
    // The stumps: the cut faces joined by their nodes, each side of the cut (by its normal) one stump.
    UnionFind joined(n);
    for (std::size_t k : list) {
      const auto& t = surface.triangles[k];
      joined.join(t[1], t[0]);
      joined.join(t[2], t[0]);
    }
    std::map<int, std::vector<std::size_t>> groups;
    for (std::size_t k : list) groups[joined.find(surface.triangles[k][0])].push_back(k);
    for (const auto& [root, group] : groups) {
      Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
      std::vector<Eigen::Vector3d> normal(group.size());
      std::vector<double> area(group.size());
      for (std::size_t g = 0; g < group.size(); ++g) {
        const auto& t = surface.triangles[group[g]];
        const Eigen::Vector3d w =
            (rest[static_cast<std::size_t>(t[1])] - rest[static_cast<std::size_t>(t[0])])
                .cross(rest[static_cast<std::size_t>(t[2])] - rest[static_cast<std::size_t>(t[0])]);
        area[g] = 0.5 * w.norm();
        normal[g] = area[g] > 0 ? Eigen::Vector3d(w.normalized()) : Eigen::Vector3d::Zero();
        scatter += area[g] * normal[g] * normal[g].transpose();
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(scatter);
      const Eigen::Vector3d d = es.eigenvectors().col(2);
      for (int side : {1, -1}) {
        Bleed b;
        b.label = label;
        Eigen::Vector3d sumN = Eigen::Vector3d::Zero(), sumC = Eigen::Vector3d::Zero();
        std::vector<int> nodes;
        for (std::size_t g = 0; g < group.size(); ++g) {
          if ((normal[g].dot(d) >= 0 ? 1 : -1) != side || !(area[g] > 0)) continue;
          const auto& t = surface.triangles[group[g]];
          b.area += area[g];
          sumN += area[g] * normal[g];
          sumC += area[g] *
                  (rest[static_cast<std::size_t>(t[0])] + rest[static_cast<std::size_t>(t[1])] +
                   rest[static_cast<std::size_t>(t[2])]) /
                  3.0;
          nodes.insert(nodes.end(), t.begin(), t.end());
        }
        if (!(b.area > 0)) continue;
        b.at = sumC / b.area;
        b.normal = sumN.norm() > 0 ? Eigen::Vector3d(sumN.normalized()) : Eigen::Vector3d(side * d);
        b.rate = bleeding.physiological ? stumpBleedRate(kindOf(label), b.area) : b.area * speed[label];
        double nearest = std::numeric_limits<double>::infinity();
        for (int v : nodes)
          if (const double dist = (rest[static_cast<std::size_t>(v)] - b.at).norm(); dist < nearest)
            nearest = dist, b.node = v;
        const int stumpPiece = piece.find(nodes.front());
        for (std::size_t c = 0; c < clips.size(); ++c) {
          const Clip& clip = clips[c];
          if (clip.label != label || clip.anchor < 0 || static_cast<std::size_t>(clip.anchor) >= n || !clip.spans)
            continue;
          if (piece.find(clip.anchor) == stumpPiece &&
              (rest[static_cast<std::size_t>(clip.anchor)] - b.at).dot(b.normal) < 0) {
            b.stoppedBy = static_cast<int>(c);
            break;
          }
        }
        for (const Bleed& p : previous)
          if (p.label == label && (p.at - b.at).norm() <= meanEdge && p.normal.dot(b.normal) > 0) {
            b.lost = p.lost;
            break;
          }
        out.push_back(b);
      }
    }
  }
  if (bleeding.physiological) boundToSupply(out, bleeding.organSupply);
  return out;
}

}  // namespace rehearse::simcore
