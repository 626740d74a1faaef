// The cut's third stage, the separation: the split's pieces and new nodes written into the mesh, each element's
// side of the cut, the faces between the two sides that open, and their nodes duplicated per group of elements
// still connected; then what stays pending for the next update, the nodes on the cut, and the result.
#include "cut_stages.hpp"
#include <rehearse/simcore/words.hpp>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <numeric>

namespace rehearse::simcore::detail {

// Assemble: replaced elements give their first piece their index, the rest are appended.
// Each element's side of the cut: a piece its own; an element left whole the side of its nodes off the cut
// (0 when it straddles the plane outside the quad, or lies flat on the cut: decided below).
void TetCutter::assemble() {
  const std::size_t nt = in.nt;
  auto& side = sep.side;
  auto& parentOf = sep.parentOf;
  auto& flat = sep.flat;
  side.assign(nt, 0);
  parentOf.assign(nt, -1);
  flat.assign(nt, 0);
  for (std::size_t t = 0; t < nt; ++t) {
    if (built.replaced[t]) continue;
    int sd = 0;
    bool mixed = false;
    for (int k = 0; k < 4; ++k) {
      const std::size_t i = static_cast<std::size_t>(tetNode(t, k));
      if (crossing.zero[i]) continue;
      const int sg = plane.dist[i] > 0 ? 1 : -1;
      mixed = mixed || (sd != 0 && sg != sd);
      sd = sg;
    }
    side[t] = mixed ? 0 : sd;
    flat[t] = !mixed && sd == 0;
  }
  {
    std::vector<char> first(nt, 1);
    for (const Piece& p : built.pieces) {
      const std::size_t t = static_cast<std::size_t>(p.parent);
      if (first[t]) {
        in.tets[t] = p.n;
        side[t] = p.side;
        parentOf[t] = p.parent;
        first[t] = 0;
      } else {
        in.tets.push_back(p.n);
        in.labels.push_back(in.labels[t]);
        side.push_back(p.side);
        parentOf.push_back(p.parent);
        flat.push_back(0);
      }
    }
  }
  in.rest.insert(in.rest.end(), built.newRest.begin(), built.newRest.end());
  in.current.insert(in.current.end(), built.newCurrent.begin(), built.newCurrent.end());
  r.newNodes = built.newNodes;
  r.duplicateOf.assign(built.newNodes.size(), -1);
}

// Separation: faces between the two sides; each of their nodes is duplicated per group of its
// elements still connected through faces that were not separated.
// Here: the nodes on the cut, their elements, and those elements' faces with the one or two elements holding each.
void TetCutter::collectFaces() {
  const auto& tets = in.tets;
  const auto& zero = crossing.zero;
  std::vector<char> onCut(in.rest.size(), 0);
  for (std::size_t i = 0; i < zero.size(); ++i) onCut[i] = zero[i];
  for (std::size_t i = zero.size(); i < in.rest.size(); ++i) onCut[i] = 1;
  // Faces of earlier cuts that have not opened yet (still shared): they separate too once the cut around
  // them is complete.
  for (const FaceKey& k : built.pendingIn)
    for (int v : k.n) onCut[static_cast<std::size_t>(v)] = 1;
  for (const FaceKey& k : built.pendingNew)
    for (int v : k.n) onCut[static_cast<std::size_t>(v)] = 1;
  sep.incident.assign(in.rest.size(), {});
  for (std::size_t t = 0; t < tets.size(); ++t) {
    const auto& e = tets[t];
    bool any = false;
    for (int k = 0; k < 4; ++k) any = any || onCut[static_cast<std::size_t>(e[static_cast<std::size_t>(k)])];
    if (!any) continue;
    for (int k = 0; k < 4; ++k)
      if (onCut[static_cast<std::size_t>(e[static_cast<std::size_t>(k)])])
        sep.incident[static_cast<std::size_t>(e[static_cast<std::size_t>(k)])].push_back(static_cast<int>(t));
    for (const auto& f : kFaces) {
      auto [it, inserted] =
          sep.faces.try_emplace(faceKey(e[static_cast<std::size_t>(f[0])], e[static_cast<std::size_t>(f[1])],
                                        e[static_cast<std::size_t>(f[2])]),
                                std::array<int, 2>{static_cast<int>(t), -1});
      if (!inserted) it->second[1] = static_cast<int>(t);
    }
  }
}

// Elements flat on the cut (all four nodes on it) join the side most of their neighbours are on, else the
// side their centre is on (a lone flat element must not become a piece of its own).
void TetCutter::settleFlatElements() {
  const auto& tets = in.tets;
  const auto& faces = sep.faces;
  auto& side = sep.side;
  for (int pass = 0; pass < 2; ++pass)
    for (std::size_t t = 0; t < tets.size(); ++t) {
      if (!sep.flat[t]) continue;
      int vote = 0;
      const auto& e = tets[t];
      for (const auto& f : kFaces) {
        const auto it = faces.find(faceKey(e[static_cast<std::size_t>(f[0])], e[static_cast<std::size_t>(f[1])],
                                           e[static_cast<std::size_t>(f[2])]));
        if (it == faces.end() || it->second[1] < 0) continue;
        vote += side[static_cast<std::size_t>(it->second[0] == static_cast<int>(t) ? it->second[1] : it->second[0])];
      }
      if (vote != 0)
        side[t] = vote > 0 ? 1 : -1;
      else if (pass == 1) {
        V3 c = V3::Zero();
        for (int k : e) c += 0.25 * in.current[static_cast<std::size_t>(k)];
        side[t] = plane.normal.dot(c - plane.origin) >= 0 ? 1 : -1;
      }
    }
}

// The faces that open: between elements on the two sides, and pending faces of earlier cuts still shared.
void TetCutter::chooseCutFaces() {
  const auto& side = sep.side;
  const auto& parentOf = sep.parentOf;
  const auto& current = in.current;
  for (const auto& [key, pair] : sep.faces) {
    if (pair[1] < 0) continue;
    const int s0 = side[static_cast<std::size_t>(pair[0])], s1 = side[static_cast<std::size_t>(pair[1])];
    if (s0 * s1 >= 0) continue;
    // Within one split element always; elsewhere where the blade passed (not beyond the cut's front).
    const bool sameParent = parentOf[static_cast<std::size_t>(pair[0])] >= 0 &&
                            parentOf[static_cast<std::size_t>(pair[0])] == parentOf[static_cast<std::size_t>(pair[1])];
    if (sameParent ||
        insideSwept((current[static_cast<std::size_t>(key.n[0])] + current[static_cast<std::size_t>(key.n[1])] +
                     current[static_cast<std::size_t>(key.n[2])]) /
                    3.0)) {
      sep.cutFaces.insert(key);
      sep.cutLabels.push_back(in.labels[static_cast<std::size_t>(pair[0])]);
      sep.cutLabels.push_back(in.labels[static_cast<std::size_t>(pair[1])]);
    }
  }
  for (const auto* set : {&built.pendingIn, &built.pendingNew})
    for (const FaceKey& k : *set) {
      const auto it = sep.faces.find(k);
      if (it != sep.faces.end() && it->second[1] >= 0) sep.cutFaces.insert(k);
    }
  r.separatedFaces = sep.cutFaces.size();
}

// Every node on an opened face is duplicated per group of its elements (beyond the first), then the copies are
// placed where their originals are.
void TetCutter::duplicateNodes() {
  std::vector<char> onSeparated(in.rest.size(), 0);
  for (const auto& k : sep.cutFaces)
    for (int v : k.n) onSeparated[static_cast<std::size_t>(v)] = 1;
  for (std::size_t v = 0; v < in.rest.size(); ++v) {
    if (!onSeparated[v]) continue;
    duplicateNode(v);
  }
  placeCopies();
}

// Node v's elements grouped by the faces through v that stay shared; group 0 keeps v, each other group gets a
// new copy of it.
void TetCutter::duplicateNode(std::size_t v) {
  const int n0 = in.n0;
  auto& replacements = sep.replacements;
  const auto& inc = sep.incident[v];
  std::vector<int> parent(inc.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x)
      x = parent[static_cast<std::size_t>(x)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
    return x;
  };
  auto localOf = [&](int t) { return static_cast<int>(std::find(inc.begin(), inc.end(), t) - inc.begin()); };
  for (std::size_t a = 0; a < inc.size(); ++a) {
    const auto& e = in.tets[static_cast<std::size_t>(inc[a])];
    for (const auto& f : kFaces) {
      const int x = e[static_cast<std::size_t>(f[0])], y = e[static_cast<std::size_t>(f[1])],
                z = e[static_cast<std::size_t>(f[2])];
      if (x != static_cast<int>(v) && y != static_cast<int>(v) && z != static_cast<int>(v)) continue;
      const FaceKey key = faceKey(x, y, z);
      if (sep.cutFaces.count(key)) continue;
      const auto& pair = sep.faces.at(key);
      if (pair[1] < 0) continue;
      const int other = pair[0] == inc[a] ? pair[1] : pair[0];
      const int lb = localOf(other);
      if (lb < static_cast<int>(inc.size())) parent[static_cast<std::size_t>(find(static_cast<int>(a)))] = find(lb);
    }
  }
  std::vector<int> roots;
  for (std::size_t a = 0; a < inc.size(); ++a) {
    const int root = find(static_cast<int>(a));
    auto it = std::find(roots.begin(), roots.end(), root);
    if (it == roots.end()) {
      roots.push_back(root);
      it = roots.end() - 1;
    }
    const auto group = it - roots.begin();
    if (group == 0) continue;
    replacements.push_back({inc[a], static_cast<int>(v), -static_cast<int>(group)});  // group index, resolved below
  }
  // New nodes for groups 1..: a copy of v.
  std::vector<int> copyIndex(roots.size(), static_cast<int>(v));
  for (std::size_t g = 1; g < roots.size(); ++g) {
    CutNode c;
    if (static_cast<int>(v) < n0) {
      c.from = {static_cast<int>(v), -1, -1, -1};
      c.weight = {1, 0, 0, 0};
      r.duplicateOf.push_back(static_cast<int>(v));
    } else {
      c = built.newNodes[v - static_cast<std::size_t>(n0)];
      r.duplicateOf.push_back(-1);
    }
    copyIndex[g] = n0 + static_cast<int>(r.newNodes.size());
    r.newNodes.push_back(c);
    ++r.duplicatedNodes;
  }
  for (auto& rep : replacements)
    if (rep.from == static_cast<int>(v) && rep.to < 0) rep.to = copyIndex[static_cast<std::size_t>(-rep.to)];
}

void TetCutter::placeCopies() {
  const auto& rest = in.rest;
  const auto& current = in.current;
  for (std::size_t k = built.newNodes.size(); k < r.newNodes.size(); ++k) {
    // The copies' positions: their originals'.
    const CutNode& c = r.newNodes[k];
    V3 pr = V3::Zero(), pc = V3::Zero();
    for (int j = 0; j < 4; ++j)
      if (c.from[static_cast<std::size_t>(j)] >= 0) {
        pr +=
            c.weight[static_cast<std::size_t>(j)] * rest[static_cast<std::size_t>(c.from[static_cast<std::size_t>(j)])];
        pc += c.weight[static_cast<std::size_t>(j)] *
              current[static_cast<std::size_t>(c.from[static_cast<std::size_t>(j)])];
      }
    in.rest.push_back(pr);
    in.current.push_back(pc);
  }
}

// The elements on the far side of an opened face take the copies of its nodes.
void TetCutter::renameNodes() {
  for (const auto& rep : sep.replacements)
    sep.renamed[(static_cast<std::uint64_t>(rep.tet) << 32) | static_cast<std::uint32_t>(rep.from)] = rep.to;
  if (in.pending) updatePending();
  for (const auto& rep : sep.replacements)
    for (auto& n : in.tets[static_cast<std::size_t>(rep.tet)])
      if (n == rep.from) n = rep.to;
}

// What stays pending: cut faces whose two elements still share all three nodes (at the cut's front),
// and earlier pending faces away from this cut.
void TetCutter::updatePending() {
  auto* pending = in.pending;
  pending->clear();
  auto name = [&](int t, int v) {
    const auto it = sep.renamed.find((static_cast<std::uint64_t>(t) << 32) | static_cast<std::uint32_t>(v));
    return it == sep.renamed.end() ? v : it->second;
  };
  for (const FaceKey& k : sep.cutFaces) {
    const auto& pair = sep.faces.at(k);
    const FaceKey a = faceKey(name(pair[0], k.n[0]), name(pair[0], k.n[1]), name(pair[0], k.n[2]));
    const FaceKey b = faceKey(name(pair[1], k.n[0]), name(pair[1], k.n[1]), name(pair[1], k.n[2]));
    if (a == b) pending->push_back(a.n);
  }
  for (const FaceKey& k : built.pendingIn)
    if (!sep.faces.count(k)) pending->push_back(k.n);
  std::sort(pending->begin(), pending->end());
}

// On the cut now: what was, the snapped nodes, the new edge points, and every copy of them.
void TetCutter::updateCutNodes() {
  if (!in.cutNodes) return;
  const auto& zero = crossing.zero;
  const auto& newNodes = built.newNodes;
  std::vector<char> on(in.rest.size(), 0);
  for (int i : *in.cutNodes)
    if (i >= 0 && static_cast<std::size_t>(i) < on.size()) on[static_cast<std::size_t>(i)] = 1;
  for (std::size_t i = 0; i < zero.size(); ++i) on[i] = on[i] || zero[i];
  for (std::size_t k = 0; k < r.newNodes.size(); ++k) {
    const bool edgePointCopy =
        k >= newNodes.size() && r.duplicateOf[k] < 0 && r.newNodes[k].from[1] >= 0 && r.newNodes[k].from[2] < 0;
    const bool edgePoint = k < newNodes.size() && newNodes[k].from[2] < 0;
    const bool copyOfOn =
        k >= newNodes.size() && r.duplicateOf[k] >= 0 && on[static_cast<std::size_t>(r.duplicateOf[k])];
    if (edgePoint || edgePointCopy || copyOfOn) on[static_cast<std::size_t>(in.n0) + k] = 1;
  }
  in.cutNodes->clear();
  for (std::size_t i = 0; i < on.size(); ++i)
    if (on[i]) in.cutNodes->push_back(static_cast<int>(i));
}

// The result: the labels on the opened faces, whether anything changed, and one sentence saying what.
CutResult TetCutter::finish() {
  auto& cutLabels = sep.cutLabels;
  std::sort(cutLabels.begin(), cutLabels.end());
  cutLabels.erase(std::unique(cutLabels.begin(), cutLabels.end()), cutLabels.end());
  r.cutLabels = cutLabels;
  r.changed = !built.pieces.empty() || r.duplicatedNodes > 0;
  if (in.progress && r.changed) in.progress->sweeps.push_back(in.blade);
  char buf[240];
  std::snprintf(buf, sizeof buf,
                "Cut: %s split and %zu refined, %s separated, %s duplicated.",
                quantity(r.splitElements, "element", "elements").c_str(), r.refinedElements,
                quantity(r.separatedFaces, "face", "faces").c_str(), quantity(r.duplicatedNodes, "node", "nodes").c_str());
  r.status = buf;
  if (!r.changed)
    r.status = !crossing.crossedAny
                   ? (r.skippedInverted
                          ? "The blade crossed only tissue crushed inside out, which cannot be cut; nothing was cut."
                          : "The blade crossed no tissue.")
                   : "The blade only grazed the tissue (it touched it without passing through); nothing was cut: draw it across the tissue again, a little deeper.";
  return std::move(r);
}

}  // namespace rehearse::simcore::detail
