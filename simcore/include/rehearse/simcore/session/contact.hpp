#pragma once
// Contact between an instrument's shaft and the organ's surface (simcore, no Qt): the broad phase (a bounding-volume
// hierarchy over the surface nodes, refitted to the deformed positions before each query), the closest points of the
// shaft's axis and a surface triangle, and the unilateral constraint rows that keep the surface out of the shaft (a
// capsule from the tip towards the trocar). The session calls shaftContact at each step an instrument is in the
// scene; test_contact checks each part alone against brute force.
#include <rehearse/simcore/constraint_solver.hpp>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <utility>
#include <vector>

namespace rehearse::simcore {

/// The boundary contact acts on: its triangles (outward), its nodes, and each node's triangles.
struct ContactSurface {
  std::vector<std::array<int, 3>> triangles;
  std::vector<int> nodes;
  std::vector<int> first, ofNode;  ///< node i's triangles: ofNode[first[i] .. first[i + 1])
};
/// The boundary of a tet mesh as a contact surface.
ContactSurface contactSurface(const std::vector<Eigen::Vector3d>& rest, const std::vector<std::array<int, 4>>& tets);

// A bounding-volume hierarchy over points (the surface nodes), built once per topology and refitted to the
// deformed positions before each query: the tool's capsule finds the nodes it holds inside.
class PointBvh {
 public:
  void build(const std::vector<int>& ids, const Eigen::VectorXd& x) {
    ids_ = ids;
    nodes_.clear();
    if (!ids_.empty()) split(0, static_cast<int>(ids_.size()), x);
  }
  void refit(const Eigen::VectorXd& x) {
    for (auto it = nodes_.rbegin(); it != nodes_.rend(); ++it) {
      it->box.setEmpty();
      if (it->left < 0) {
        for (int k = it->begin; k < it->end; ++k)
          it->box.extend(
              Eigen::Vector3d(x.segment<3>(3 * static_cast<Eigen::Index>(ids_[static_cast<std::size_t>(k)]))));
      } else {
        it->box.extend(nodes_[static_cast<std::size_t>(it->left)].box);
        it->box.extend(nodes_[static_cast<std::size_t>(it->right)].box);
      }
    }
  }
  /// Ids of the points within `r` of segment a-b.
  void query(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r, const Eigen::VectorXd& x,
             std::vector<int>& out) const {
    if (nodes_.empty()) return;
    Eigen::AlignedBox3d seg(a.cwiseMin(b), a.cwiseMax(b));
    seg.min().array() -= r;
    seg.max().array() += r;
    std::vector<int> stack{0};
    while (!stack.empty()) {
      const Node& n = nodes_[static_cast<std::size_t>(stack.back())];
      stack.pop_back();
      if (!n.box.intersects(seg)) continue;
      if (n.left >= 0) {
        stack.push_back(n.left);
        stack.push_back(n.right);
        continue;
      }
      for (int k = n.begin; k < n.end; ++k) {
        const int id = ids_[static_cast<std::size_t>(k)];
        const Eigen::Vector3d p = x.segment<3>(3 * static_cast<Eigen::Index>(id));
        const Eigen::Vector3d d = b - a;
        const double t = d.squaredNorm() > 0 ? std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
        if ((p - (a + t * d)).squaredNorm() < r * r) out.push_back(id);
      }
    }
  }

 private:
  struct Node {
    Eigen::AlignedBox3d box;
    int begin = 0, end = 0, left = -1, right = -1;
  };
  int split(int begin, int end, const Eigen::VectorXd& x) {
    const int index = static_cast<int>(nodes_.size());
    nodes_.push_back({});
    Eigen::AlignedBox3d box;
    for (int k = begin; k < end; ++k)
      box.extend(Eigen::Vector3d(x.segment<3>(3 * static_cast<Eigen::Index>(ids_[static_cast<std::size_t>(k)]))));
    nodes_[static_cast<std::size_t>(index)].box = box;
    nodes_[static_cast<std::size_t>(index)].begin = begin;
    nodes_[static_cast<std::size_t>(index)].end = end;
    if (end - begin <= 8) return index;
    int axis = 0;
    box.sizes().maxCoeff(&axis);
    const int mid = (begin + end) / 2;
    std::nth_element(ids_.begin() + begin, ids_.begin() + mid, ids_.begin() + end, [&](int p, int q) {
      return x[3 * static_cast<Eigen::Index>(p) + axis] < x[3 * static_cast<Eigen::Index>(q) + axis];
    });
    const int l = split(begin, mid, x);
    const int r = split(mid, end, x);
    nodes_[static_cast<std::size_t>(index)].left = l;
    nodes_[static_cast<std::size_t>(index)].right = r;
    return index;
  }
  std::vector<int> ids_;
  std::vector<Node> nodes_;
};

/// Closest point of triangle abc to p, with its barycentric weights `w`.
Eigen::Vector3d closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  const Eigen::Vector3d& c, Eigen::Vector3d& w);
/// The closest points of segment s0-s1 (the instrument's axis) and triangle abc: `onAxis`, `onTriangle` with
/// its barycentric weights `w`. False when the segment passes through the triangle (no direction apart).
bool closestAxisTriangle(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1, const Eigen::Vector3d& a,
                         const Eigen::Vector3d& b, const Eigen::Vector3d& c, Eigen::Vector3d& onAxis,
                         Eigen::Vector3d& onTriangle, Eigen::Vector3d& w);

/// What one contact detection found.
struct ShaftContactStats {
  int rows = 0;      ///< unilateral constraints made (touching or within half the radius more)
  int contacts = 0;  ///< triangles touching the shaft (held at its surface) or inside it
  int pierced = 0;   ///< triangles the shaft's axis passes through (no side to push them to)
};
/// The surface's triangles near the shaft (a capsule of `radius` from `tip` to `trocar`) kept out of it: one unilateral
/// row per distinct closest point, at the point's barycentric weights, along the direction from the axis (a point on
/// the axis: the triangle's inward normal), appended to `rows`. Triangles with a node in `held` (the jaws hold it) or
/// in `released` (let go, still inside the shaft: the tissue leaves the open jaws) are skipped; `released` loses the
/// nodes that are out of the shaft. With `depenetrationSpeed` > 0, triangles found inside the shaft when `seed` is
/// true are held where they are (`easing`, sorted by triangle) instead of pushed to the radius at once. `fixed`: the
/// attachments (a triangle of fixed nodes only cannot move). `bvh` is refitted to `x` first.
ShaftContactStats shaftContact(const ContactSurface& surface, PointBvh& bvh, const Eigen::VectorXd& x,
                               const std::vector<char>& fixed, const Eigen::Vector3d& tip,
                               const Eigen::Vector3d& trocar, double radius, double depenetrationSpeed,
                               const std::vector<int>& held, std::vector<int>& released,
                               std::vector<std::pair<int, double>>& easing, bool seed,
                               std::vector<ScalarConstraint>& rows);

}  // namespace rehearse::simcore
