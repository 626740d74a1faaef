#pragma once
// The stages of cutTetrahedra (issue 63: "cutting: blade, split, separate"), private to simcore. One cut update
// is a TetCutter: its data members are what one stage hands the next, its member functions the stages, which
// cutTetrahedra (cut.cpp) calls in order:
//  - the blade (cut_blade.cpp): the blade's plane, the elements whose crossing lies in the swept quad (or in what
//    this continuous cut swept before), and the nodes the cut passes through (snapping);
//  - the split (cut_split.cpp): a point on every crossed edge and the touched elements re-meshed into pieces,
//    snapping more until every piece meets the stated quality and volume (or refusing the cut);
//  - the separation (cut_separate.cpp): the pieces written into the mesh, the faces between the two sides, their
//    nodes duplicated per group of elements still connected, then the progress and the result.
// Everything is public so that a test can run the stages one at a time and look at the state between them.
#include <rehearse/simcore/cut.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

namespace rehearse::simcore::detail {
using V3 = Eigen::Vector3d;

inline std::uint64_t edgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
}

struct FaceKey {
  std::array<int, 3> n;
  bool operator==(const FaceKey&) const = default;
};
struct FaceHash {
  std::size_t operator()(const FaceKey& k) const {
    std::uint64_t h = static_cast<std::uint32_t>(k.n[0]);
    h = h * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint32_t>(k.n[1]);
    h = h * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint32_t>(k.n[2]);
    return static_cast<std::size_t>(h ^ (h >> 29));
  }
};
inline FaceKey faceKey(int a, int b, int c) {
  std::array<int, 3> n{a, b, c};
  std::sort(n.begin(), n.end());
  return {n};
}

inline double signedVolume(const V3& a, const V3& b, const V3& c, const V3& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

inline constexpr std::array<std::array<int, 3>, 4> kFaces{{{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};

// A convex polygon in cyclic order, triangulated as a fan from its first vertex in `before`'s order (for a
// quad: the diagonal from it). `before` orders by rest position (then node number), so two elements sharing
// the polygon triangulate it alike, and so do the two sides of a separated face (equal places, other numbers).
template <class Before>
void triangulate(const std::vector<int>& poly, std::vector<std::array<int, 3>>& out, const Before& before) {
  const std::size_t n = poly.size();
  if (n < 3) return;
  const std::size_t m = static_cast<std::size_t>(std::min_element(poly.begin(), poly.end(), before) - poly.begin());
  for (std::size_t k = 1; k + 1 < n; ++k) out.push_back({poly[m], poly[(m + k) % n], poly[(m + k + 1) % n]});
}

struct Piece {
  std::array<int, 4> n;
  int parent;
  int side;  // +1 / -1 a side of a separated element, 0 a refined one
};

// Element `tet` takes node `to` for node `from` (a copy of it on the element's side of the cut).
struct Replacement {
  int tet, from, to;
};

// The parts of one face of an element on either side of its edge points, each with its side (0: on the cut).
using FaceParts = std::vector<std::pair<std::vector<int>, int>>;

class TetCutter {
 public:
  TetCutter(std::vector<V3>& rest, std::vector<V3>& current, std::vector<std::array<int, 4>>& tets,
            std::vector<int>& labels, const BladeSweep& blade, const CutSettings& settings, CutProgress* progress);

  // The blade (cut_blade.cpp). A stage returning false has put why the cut stops in r.status.
  bool inputsMatch();
  bool placeBlade();
  void findCrossed();
  void growAlongSweeps();
  bool anythingToCut();
  void snapNearNodes();
  void snapFront();
  bool insideQuad(const V3& p) const;
  bool insideSwept(const V3& p) const;
  bool crossingCentre(std::size_t t, V3& centre) const;
  double cuttableVolume(std::size_t t) const;

  // The split (cut_split.cpp).
  bool splitElements();
  void startSplit();
  void placeEdgePoints();
  void remeshElements();
  void remeshElement(std::size_t t);
  std::vector<int> cutPolygon(std::size_t t) const;
  void faceParts(int a, int b, int c, FaceParts& out) const;
  void cone(std::size_t t, const std::vector<std::vector<int>>& polys, const std::vector<int>& verts, int side);
  struct PieceCheck {
    std::unordered_set<int> failing;  ///< elements with a piece below the bounds
    double minQ = 1, minFraction = 1;
  };
  PieceCheck checkPieces();
  void snapFailing(const std::unordered_set<int>& failing);
  int sigma(int i) const;
  int pointOn(int i, int j) const;
  const V3& restOf(int i) const;
  const V3& currentOf(int i) const;
  std::array<double, 4> weightsIn(std::size_t t, int node) const;
  bool before(int x, int y) const;

  // The separation (cut_separate.cpp).
  void assemble();
  void collectFaces();
  void settleFlatElements();
  void chooseCutFaces();
  void duplicateNodes();
  void duplicateNode(std::size_t v);
  void placeCopies();
  void renameNodes();
  void updatePending();
  void updateCutNodes();
  CutResult finish();

  int tetNode(std::size_t t, int k) const { return in.tets[t][static_cast<std::size_t>(k)]; }

  /// What the caller passed: the mesh, cut in place (grown and re-meshed from the separation on), the blade, the
  /// settings and the continuous cut's state (pending faces and nodes on the cut: null without progress).
  struct Input {
    std::vector<V3>& rest;
    std::vector<V3>& current;
    std::vector<std::array<int, 4>>& tets;
    std::vector<int>& labels;
    const BladeSweep& blade;
    const CutSettings& settings;
    CutProgress* progress;
    std::vector<std::array<int, 3>>* pending;
    std::vector<int>* cutNodes;
    int n0;          ///< nodes before the cut: new nodes are numbered from here
    std::size_t nt;  ///< elements before the cut
  } in;

  /// The blade's plane and quad (a0, b0, b1, a1).
  struct Plane {
    std::array<V3, 4> quad;
    V3 normal;                 ///< unit
    V3 origin;                 ///< the quad's centre
    std::vector<double> dist;  ///< per node: signed distance from the plane, current positions
  } plane;

  /// What the blade crosses.
  struct Crossing {
    std::vector<char> candidate;  ///< per element: to be cut
    std::vector<char> relevant;   ///< per node: of a candidate
    std::vector<double> restVol;  ///< per element: a candidate's rest volume (the split fills in the others')
    std::vector<char> zero;       ///< per node: the cut passes through it (snapped, or on the cut already)
    bool crossedAny = false;
  } crossing;

  /// The mesh being built by the split: new nodes (numbered from n0) and pieces, not yet in the caller's mesh.
  struct Built {
    std::vector<CutNode> newNodes;
    std::vector<V3> newRest, newCurrent;
    std::vector<Piece> pieces;
    std::vector<char> replaced;                                   ///< per element: re-meshed
    std::vector<char> split;                                      ///< per element: separated into two sides
    std::unordered_map<std::uint64_t, int> edgePoint;             ///< crossed edge -> its new node
    std::unordered_set<FaceKey, FaceHash> pendingIn, pendingNew;  ///< pending faces: as given, and their pieces
  } built;

  /// The separation, over the grown mesh.
  struct Separation {
    std::vector<int> side, parentOf;  ///< per element: its side of the cut, the element it is a piece of (else -1)
    std::vector<char> flat;           ///< per element: left whole with all its nodes on the cut
    std::unordered_map<FaceKey, std::array<int, 2>, FaceHash> faces;  ///< faces of elements on the cut: their elements
    std::vector<std::vector<int>> incident;                           ///< per node on the cut: its elements
    std::unordered_set<FaceKey, FaceHash> cutFaces;                   ///< the faces that open
    std::vector<int> cutLabels;
    std::vector<Replacement> replacements;
    std::unordered_map<std::uint64_t, int> renamed;  ///< (element, old node) -> new node
  } sep;

  CutResult r;
};

}  // namespace rehearse::simcore::detail
