#include <rehearse/simcore/session/session.hpp>
#include <rehearse/simcore/session/forceloop.hpp>

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
        for (int k = it->begin; k < it->end; ++k) it->box.extend(Eigen::Vector3d(x.segment<3>(3 * static_cast<Eigen::Index>(ids_[static_cast<std::size_t>(k)]))));
      } else {
        it->box.extend(nodes_[static_cast<std::size_t>(it->left)].box);
        it->box.extend(nodes_[static_cast<std::size_t>(it->right)].box);
      }
    }
  }
  /// Ids of the points within `r` of segment a-b.
  void query(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r, const Eigen::VectorXd& x, std::vector<int>& out) const {
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
    for (int k = begin; k < end; ++k) box.extend(Eigen::Vector3d(x.segment<3>(3 * static_cast<Eigen::Index>(ids_[static_cast<std::size_t>(k)]))));
    nodes_[static_cast<std::size_t>(index)].box = box;
    nodes_[static_cast<std::size_t>(index)].begin = begin;
    nodes_[static_cast<std::size_t>(index)].end = end;
    if (end - begin <= 8) return index;
    int axis = 0;
    box.sizes().maxCoeff(&axis);
    const int mid = (begin + end) / 2;
    std::nth_element(ids_.begin() + begin, ids_.begin() + mid, ids_.begin() + end,
                     [&](int p, int q) { return x[3 * static_cast<Eigen::Index>(p) + axis] < x[3 * static_cast<Eigen::Index>(q) + axis]; });
    const int l = split(begin, mid, x);
    const int r = split(mid, end, x);
    nodes_[static_cast<std::size_t>(index)].left = l;
    nodes_[static_cast<std::size_t>(index)].right = r;
    return index;
  }
  std::vector<int> ids_;
  std::vector<Node> nodes_;
};

namespace {

// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5), with its barycentric weights.
Eigen::Vector3d closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                  Eigen::Vector3d& w) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return w = {1, 0, 0}, a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return w = {0, 1, 0}, b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return w = {1 - v, v, 0}, a + v * ab;
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return w = {0, 0, 1}, c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double v = d2 / (d2 - d6);
    return w = {1 - v, 0, v}, a + v * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double v = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return w = {0, 1 - v, v}, b + v * (c - b);
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, u = vc * denom;
  return w = {1 - v - u, v, u}, a + v * ab + u * ac;
}

// Closest points of segments p1-q1 (parameter s) and p2-q2 (parameter t) (Ericson 5.1.9).
void closestSegmentSegment(const Eigen::Vector3d& p1, const Eigen::Vector3d& q1, const Eigen::Vector3d& p2, const Eigen::Vector3d& q2, double& s,
                           double& t) {
  const Eigen::Vector3d d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  if (a <= 1e-30 && e <= 1e-30) return void(s = t = 0);
  if (a <= 1e-30) {
    s = 0;
    t = std::clamp(f / e, 0.0, 1.0);
    return;
  }
  const double c = d1.dot(r);
  if (e <= 1e-30) {
    t = 0;
    s = std::clamp(-c / a, 0.0, 1.0);
    return;
  }
  const double b = d1.dot(d2), denom = a * e - b * b;
  s = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
  t = (b * s + f) / e;
  if (t < 0) {
    t = 0;
    s = std::clamp(-c / a, 0.0, 1.0);
  } else if (t > 1) {
    t = 1;
    s = std::clamp((b - c) / a, 0.0, 1.0);
  }
}

// The closest points of segment s0-s1 (the instrument's axis) and triangle abc: `onAxis`, `onTriangle` with
// its barycentric weights `w`. False when the segment passes through the triangle (no direction apart).
bool closestAxisTriangle(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                         const Eigen::Vector3d& c, Eigen::Vector3d& onAxis, Eigen::Vector3d& onTriangle, Eigen::Vector3d& w) {
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double ds0 = n.dot(s0 - a), ds1 = n.dot(s1 - a);
  if (ds0 * ds1 < 0) {  // crosses the plane: inside the triangle?
    const double t = ds0 / (ds0 - ds1);
    const Eigen::Vector3d x = s0 + t * (s1 - s0);
    Eigen::Vector3d wx;
    if ((closestOnTriangle(x, a, b, c, wx) - x).squaredNorm() <= 1e-24 * std::max(1.0, n.norm())) return false;
  }
  double best = std::numeric_limits<double>::infinity();
  auto consider = [&](const Eigen::Vector3d& pa, const Eigen::Vector3d& pt, const Eigen::Vector3d& wt) {
    const double d = (pa - pt).squaredNorm();
    if (d < best) best = d, onAxis = pa, onTriangle = pt, w = wt;
  };
  Eigen::Vector3d wt;
  for (const Eigen::Vector3d* e : {&s0, &s1}) {
    const Eigen::Vector3d q = closestOnTriangle(*e, a, b, c, wt);
    consider(*e, q, wt);
  }
  const std::array<const Eigen::Vector3d*, 3> v{&a, &b, &c};
  for (int k = 0; k < 3; ++k) {
    double s, t;
    closestSegmentSegment(s0, s1, *v[static_cast<std::size_t>(k)], *v[static_cast<std::size_t>((k + 1) % 3)], s, t);
    Eigen::Vector3d wk = Eigen::Vector3d::Zero();
    wk[k] = 1 - t;
    wk[(k + 1) % 3] = t;
    consider(s0 + s * (s1 - s0), (1 - t) * *v[static_cast<std::size_t>(k)] + t * *v[static_cast<std::size_t>((k + 1) % 3)], wk);
  }
  return best > 0;
}

}  // namespace

ContactSurface contactSurface(const std::vector<Eigen::Vector3d>& rest, const std::vector<std::array<int, 4>>& tets);
std::shared_ptr<const CutSurface> makeCutSurface(const BodySetup& uncutSetup, const Mesh& cutMesh, double meanEdge);

namespace {
// The default trocar: above the organ towards the camera, twice its radius from its centre.
Eigen::Vector3d defaultTrocar(const std::vector<Eigen::Vector3d>& rest) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : rest) c += p;
  c /= static_cast<double>(std::max<std::size_t>(1, rest.size()));
  double r = 0;
  for (const auto& p : rest) r = std::max(r, (p - c).norm());
  return c + 2 * r * Eigen::Vector3d(0, -1, -2).normalized();
}
}  // namespace

Session::Session(BodySetup setup) : setup_(std::move(setup)), started_(std::chrono::steady_clock::now()) {
  body_ = makeFemBody(setup_);
  if (!setup_.tools.trocar) setup_.tools.trocar = defaultTrocar(body_->restPositions());
  {
    // The cut's quality floor: the stated one, or half the uncut mesh's worst element when that is poorer.
    const auto& rest = body_->restPositions();
    double worst = 1;
    for (const auto& t : body_->tetrahedra())
      worst = std::min(worst, tetShapeQuality(rest[static_cast<std::size_t>(t[0])], rest[static_cast<std::size_t>(t[1])], rest[static_cast<std::size_t>(t[2])],
                                              rest[static_cast<std::size_t>(t[3])]));
    setup_.tools.cut.minQuality = std::min(setup_.tools.cut.minQuality, 0.5 * worst);
  }
  tets_ = std::make_shared<const std::vector<std::array<int, 4>>>(body_->tetrahedra());
  uncut_ = setup_;
  {
    const auto& rest = body_->restPositions();
    double sum = 0;
    std::size_t count = 0;
    for (const auto& t : body_->tetrahedra())
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) sum += (rest[static_cast<std::size_t>(t[static_cast<std::size_t>(a)])] - rest[static_cast<std::size_t>(t[static_cast<std::size_t>(b)])]).norm(), ++count;
    meanEdge_ = count ? sum / static_cast<double>(count) : 0;
  }
  state_ = body_->initialState();
  updateSurfaceNodes();
  StepReport rest;
  rest.ok = true;
  rest.outcome = StepStatus::Converged;  // no step taken: nothing left unsolved
  publish(rest, {});
  thread_ = std::thread([this] { run(); });
}

Session::~Session() {
  {
    std::lock_guard<std::mutex> lock(mailboxMutex_);
    quit_ = true;
    playing_ = false;
  }
  wake_.notify_all();
  thread_.join();
}

void Session::post(InputEvent e) {
  if (e.wallTime == 0) e.wallTime = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  std::lock_guard<std::mutex> lock(mailboxMutex_);
  mailbox_.push_back(std::move(e));
}

void Session::play() {
  {
    std::lock_guard<std::mutex> lock(mailboxMutex_);
    playing_ = true;
  }
  wake_.notify_all();
}

void Session::pause() {
  playing_ = false;
  wake_.notify_all();
}

void Session::stepOnce() {
  {
    std::lock_guard<std::mutex> lock(mailboxMutex_);
    playing_ = false;
    ++pendingSteps_;
  }
  wake_.notify_all();
}

void Session::reset() {
  {
    std::lock_guard<std::mutex> lock(mailboxMutex_);
    playing_ = false;
    pendingReset_ = true;
  }
  wake_.notify_all();
}

ToolForceModel Session::toolForce() const {
  const std::array<double, 18> v = toolForce_.load();
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
  std::lock_guard<std::mutex> lock(mailboxMutex_);
  return snapshot_;
}

void Session::setPublishedCallback(std::function<void()> f) {
  std::lock_guard<std::mutex> lock(mailboxMutex_);
  published_ = std::move(f);
}

void Session::setPublishStress(bool on) {
  publishStress_ = on;
  {
    std::lock_guard<std::mutex> lock(mailboxMutex_);
    republish_ = true;
  }
  wake_.notify_all();
}

void Session::rebuildBody() {
  // A parameter edit: a new body with the same nodes; the state (positions, velocities, time) carries over,
  // the lagged factor is rebuilt at the next step (the old one belongs to the old parameters).
  auto body = makeFemBody(setup_);
  body_ = std::move(body);
  state_.lagged.valid = false;
  state_.forcesValid = false;
  updateToolConstraints();
}

void Session::updateToolConstraints() {
  std::vector<ScalarConstraint> c;
  if (tool_.jawClosed) {
    // Each held node keeps its place relative to the tip: three bilateral constraints along the body
    // frame's axes per node.
    for (std::size_t k = 0; k < tool_.held.size(); ++k)
      for (int axis = 0; axis < 3; ++axis) {
        ScalarConstraint s;
        s.nodes = {tool_.held[k], -1, -1, -1};
        s.weights = {1, 0, 0, 0};
        s.direction = Eigen::Vector3d::Unit(axis);
        s.value = (tool_.tip + tool_.heldOffset[k])[axis];
        c.push_back(s);
      }
  }
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
  if (tool_.present && !tool_.cutting && setup_.tools.toolRadius > 0 && bvh_ && !contact_.nodes.empty() && setup_.tools.trocar) {
    ++contactQueries_;
    bvh_->refit(state_.x);
    auto X = [&](int i) { return Eigen::Vector3d(state_.x.segment<3>(3 * static_cast<Eigen::Index>(i))); };
    double longest = 0;
    for (const auto& t : contact_.triangles)
      for (int k = 0; k < 3; ++k) longest = std::max(longest, (X(t[static_cast<std::size_t>(k)]) - X(t[static_cast<std::size_t>((k + 1) % 3)])).squaredNorm());
    longest = std::sqrt(longest);
    const Eigen::Vector3d a = tool_.tip, b = *setup_.tools.trocar;
    const double r = setup_.tools.toolRadius, reach = 1.5 * r;
    // Let-go tissue out of the shaft is ordinary tissue again.
    std::erase_if(tool_.released, [&](int i) {
      const Eigen::Vector3d ab = b - a;
      const double u = ab.squaredNorm() > 0 ? std::clamp((X(i) - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
      return (X(i) - (a + u * ab)).norm() >= r;
    });
    std::vector<int> near;
    bvh_->query(a, b, reach + longest, state_.x, near);
    std::vector<int> tris;
    for (int i : near)
      for (int k = contact_.first[static_cast<std::size_t>(i)]; k < contact_.first[static_cast<std::size_t>(i) + 1]; ++k)
        tris.push_back(contact_.ofNode[static_cast<std::size_t>(k)]);
    std::sort(tris.begin(), tris.end());
    tris.erase(std::unique(tris.begin(), tris.end()), tris.end());
    const auto& fixed = body_->fixedMask();
    std::set<std::vector<std::pair<int, double>>> seen;
    for (int k : tris) {
      const auto& t = contact_.triangles[static_cast<std::size_t>(k)];
      bool anyFree = false, holdsHeld = false;
      for (int v : t) {
        anyFree |= !fixed[static_cast<std::size_t>(v)];
        holdsHeld |= std::find(tool_.held.begin(), tool_.held.end(), v) != tool_.held.end() ||
                     std::binary_search(tool_.released.begin(), tool_.released.end(), v);
      }
      if (!anyFree || holdsHeld) continue;
      Eigen::Vector3d onAxis = Eigen::Vector3d::Zero(), onTriangle = Eigen::Vector3d::Zero(), w = Eigen::Vector3d::Zero();
      if (!closestAxisTriangle(a, b, X(t[0]), X(t[1]), X(t[2]), onAxis, onTriangle, w)) {
        ++tool_.pierced;  // the shaft passes through it: no side to push it to
        continue;
      }
      Eigen::Vector3d n = onTriangle - onAxis;
      double d = n.norm();
      if (d > reach) continue;
      if (!(d > 1e-3 * r)) {
        // On the axis (tissue the jaws just let go of sits at the tip): the direction from the axis is noise, so
        // the surface is pushed along its own inward normal, from where it is (eased out like tissue inside).
        n = -(X(t[1]) - X(t[0])).cross(X(t[2]) - X(t[0]));
        if (!(n.norm() > 0)) continue;  // a collapsed triangle: no side to push it to
        n *= 1e-3 * r / n.norm();
        d = 1e-3 * r;
      }
      // The closest point on a vertex or an edge is shared by the triangles around it: one constraint each
      // (redundant copies make the Schur complement singular and Gauss-Seidel slow).
      std::array<std::pair<int, double>, 3> key{};
      int used = 0;
      for (int q = 0; q < 3; ++q)
        if (w[q] > 1e-12) key[static_cast<std::size_t>(used++)] = {t[static_cast<std::size_t>(q)], w[q]};
      std::sort(key.begin(), key.begin() + used);
      if (!seen.insert(std::vector<std::pair<int, double>>(key.begin(), key.begin() + used)).second) continue;
      ScalarConstraint sc;
      for (int q = 0; q < used; ++q) {
        sc.nodes[static_cast<std::size_t>(q)] = key[static_cast<std::size_t>(q)].first;
        sc.weights[static_cast<std::size_t>(q)] = key[static_cast<std::size_t>(q)].second;
      }
      sc.direction = n / d;
      // Surface inside the shaft when it became free to touch it is held where it is and eased out (easing), not
      // pushed to the radius in one step.
      double keep = r;
      if (setup_.tools.depenetrationSpeed > 0) {
        auto it = std::lower_bound(tool_.easing.begin(), tool_.easing.end(), std::make_pair(k, -1.0));
        if (it != tool_.easing.end() && it->first == k) {
          keep = std::min(r, it->second);
        } else if (seedEasing_ && d < r) {
          tool_.easing.insert(it, {k, d});
          keep = d;
        }
      }
      sc.value = sc.direction.dot(onAxis) + keep;
      sc.unilateral = true;
      c.push_back(sc);
      ++contactConstraints_;
      if (d <= r * (1 + 1e-3)) ++tool_.contacts;  // touching (held at the shaft's surface) or inside
    }
  }
  seedEasing_ = false;
  body_->setToolConstraints(std::move(c));
}

ContactSurface contactSurface(const std::vector<Eigen::Vector3d>& rest, const std::vector<std::array<int, 4>>& tets) {
  ContactSurface c;
  std::vector<char> on(rest.size(), 0);
  Mesh m;
  m.points = rest;
  m.tets = tets;
  c.triangles = boundaryTriangles(m, false);
  for (const auto& t : c.triangles)
    for (int v : t) on[static_cast<std::size_t>(v)] = 1;
  // Each node's triangles (compressed rows): contact finds triangles through their nodes.
  c.first.assign(on.size() + 1, 0);
  for (const auto& t : c.triangles)
    for (int v : t) ++c.first[static_cast<std::size_t>(v) + 1];
  for (std::size_t i = 0; i < on.size(); ++i) c.first[i + 1] += c.first[i];
  c.ofNode.assign(static_cast<std::size_t>(c.first.back()), 0);
  std::vector<int> fill(c.first.begin(), c.first.end() - 1);
  for (std::size_t k = 0; k < c.triangles.size(); ++k)
    for (int v : c.triangles[k]) c.ofNode[static_cast<std::size_t>(fill[static_cast<std::size_t>(v)]++)] = static_cast<int>(k);
  for (std::size_t i = 0; i < on.size(); ++i)
    if (on[i]) c.nodes.push_back(static_cast<int>(i));
  return c;
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
  // A cut being built elsewhere is applied before anything that rebuilds the body or cuts again.
  if ((e.kind == InputKind::Cut && e.on) || e.kind == InputKind::Parameter || e.kind == InputKind::Gravity) finishPendingCut(true, message);
  switch (e.kind) {
    case InputKind::ToolPose:
      // The blade's sweep since the cut last changed the tissue: a sweep too thin to cross whole elements
      // grows until it does.
      // Applied once the blade has moved an element's edge, so that it splits elements rather than only
      // snapping to their nodes.
      if (tool_.cutting && e.position.allFinite() && (e.position - tool_.cutFrom).norm() >= 2 * meanEdge_ && cut(tool_.cutFrom, e.position, message))
        tool_.cutFrom = e.position;
      if (!tool_.released.empty() && e.position != tool_.tip) {
        tool_.released.clear();  // the instrument moves on: what it let go of is touched like any tissue (eased out)
        seedEasing_ = true;
      }
      tool_.tip = e.position;
      if (!tool_.present) seedEasing_ = true;
      tool_.present = true;
      break;
    case InputKind::Jaw:
      tool_.jawClosed = e.on;
      tool_.released = tool_.held;
      std::sort(tool_.released.begin(), tool_.released.end());
      tool_.held.clear();
      tool_.heldOffset.clear();
      tool_.force.setZero();
      tool_.graspForce.setZero();
      if (e.on) {
        // Grasp every free node within the grasp radius of the tip (the bite), the nearest first.
        const double r2 = setup_.tools.graspRadius * setup_.tools.graspRadius;
        const auto& fixed = body_->fixedMask();
        std::vector<std::pair<double, int>> near;
        for (std::size_t i = 0; i < body_->nodeCount(); ++i) {
          const double d = (state_.x.segment<3>(3 * static_cast<Eigen::Index>(i)) - tool_.tip).squaredNorm();
          if (d <= r2 && !fixed[i]) near.emplace_back(d, static_cast<int>(i));
        }
        std::sort(near.begin(), near.end());
        for (const auto& [d, i] : near) {
          tool_.held.push_back(i);
          tool_.heldOffset.push_back(state_.x.segment<3>(3 * static_cast<Eigen::Index>(i)) - tool_.tip);
        }
        if (!near.empty()) {
          events_.push_back("grasp");
        } else {
          message = "The jaws closed on nothing: no tissue within " + std::to_string(static_cast<int>(std::lround(1e3 * setup_.tools.graspRadius))) +
                    " mm of the tip.";
        }
      } else {
        events_.push_back("release");
        seedEasing_ = true;  // the tissue the jaws held may be inside the shaft
      }
      break;
    case InputKind::Cut:
      if (!e.on && pendingCut_) {
        // Withdrawn while the last cut's body is being built: the rest of the sweep is cut once it is in (no wait).
        if (tool_.cutting && (tool_.tip - tool_.cutFrom).norm() > 0) restOfSweep_ = std::make_pair(tool_.cutFrom, tool_.tip);
        else pendingCut_->clearProgress = true;
        tool_.cutting = false;
        tool_.cutFrom = tool_.tip;
        break;
      }
      if (!e.on && tool_.cutting && (tool_.tip - tool_.cutFrom).norm() > 0) cut(tool_.cutFrom, tool_.tip, message);  // the rest of the sweep
      if (tool_.cutting != e.on) seedEasing_ = true;  // contact resumes (or stops) with the blade
      if (e.on && !tool_.cutting) {  // a new stroke
        tool_.vesselsCut.clear();
        stroke_ = {};
        stroke_.open = true;
        stroke_.piecesBefore = connectedPieces(body_->tetrahedra(), body_->nodeCount());
      }
      tool_.cutting = e.on;
      tool_.cutFrom = tool_.tip;
      // A new cut starts from nothing; what did not open of the last one stays closed.
      if (pendingCut_) pendingCut_->clearProgress = true;
      else setup_.cut.clear();
      break;
    case InputKind::Parameter: {
      BodySetup before = setup_;
      if (e.label > 0 && (e.name == "young" || e.name == "poisson")) {
        // One label's own material (e.g. the vessels'), starting from the parenchyma's when it had none.
        if (e.name == "young" && e.value == 0) {
          setup_.byLabel.erase(e.label);
        } else {
          auto it = setup_.byLabel.try_emplace(e.label, setup_.material).first;
          (e.name == "young" ? it->second.young : it->second.poisson) = e.value;
        }
      } else if (e.name == "young") setup_.material.young = e.value;
      else if (e.name == "poisson") setup_.material.poisson = e.value;
      else if (e.name == "density") setup_.material.density = e.value;
      else if (e.name == "dt") setup_.settings.timeStep = e.value;
      else if (e.name == "method") setup_.settings.method = static_cast<NewtonMethod>(std::clamp(static_cast<int>(e.value), 0, 3));
      else if (e.name == "model" && e.value >= 0 && e.value <= static_cast<int>(MaterialModel::NeoHookeanSplit))
        setup_.material.model = static_cast<MaterialModel>(static_cast<int>(e.value));
      else if (e.name == "model") {
        message = "Unknown material law " + std::to_string(e.value) + "; it was not applied.";
        break;
      }
      else {
        message = "Unknown parameter '" + e.name + "'; it was not applied.";
        break;
      }
      for (auto& [label, m] : setup_.byLabel) {
        m.model = setup_.material.model;
        m.density = setup_.material.density;
      }
      try {
        rebuildBody();
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
      if (pendingCut_ && pendingCut_->applyAt < 0) finishPendingCut(true, message);
      break;
  }
  if (e.kind == InputKind::ToolPose || e.kind == InputKind::Jaw) updateToolConstraints();  // rebuildBody did it for the others
}

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
    if (r.duplicateOf[k] >= 0 && fixed[static_cast<std::size_t>(r.duplicateOf[k])]) next.fixedNodes.push_back(static_cast<int>(n + k));
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
    if (setup_.mesh.labelIsVessel(label) && std::find(tool_.vesselsCut.begin(), tool_.vesselsCut.end(), label) == tool_.vesselsCut.end()) {
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
    if (cut(from, to, message) && pendingCut_) pendingCut_->clearProgress = true;
    else setup_.cut.clear();
  }
  return true;
}

std::size_t connectedPieces(const std::vector<std::array<int, 4>>& tets, std::size_t nodes) {
  std::vector<int> parent(nodes);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i) i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
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
    m = "The cut is done: " + std::to_string(s.separatedFaces) + " face(s) opened and " + std::to_string(s.split) + " element(s) split in " +
        std::to_string(s.updates) + " update(s); ";
    m += pieces > s.piecesBefore ? "the organ came apart (" + std::to_string(pieces) + " pieces, " + std::to_string(s.piecesBefore) + " before)."
                                 : "the organ is still in " + std::string(pieces == 1 ? "one piece" : std::to_string(pieces) + " pieces") +
                                       " (the cut did not go through).";
    if (s.skippedInverted > 0)
      m += " " + std::to_string(s.skippedInverted) + " crossed element(s) were inverted and not cut: tissue still joins there.";
    if (!s.lastRefusal.empty()) m += " The stroke's last sweep was not cut: " + s.lastRefusal;
  }
  if (!message.empty()) message += " ";
  message += m;
}

void Session::retire(std::unique_ptr<DeformableBody> body) {
  for (auto it = retired_.begin(); it != retired_.end();)
    it = it->wait_for(std::chrono::seconds(0)) == std::future_status::ready ? retired_.erase(it) : it + 1;
  if (!body) return;
  std::shared_ptr<DeformableBody> old(std::move(body));
  retired_.push_back(std::async(std::launch::async, [old]() mutable { old.reset(); }));
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
    return std::array<long, 3>{static_cast<long>(std::floor(p.x() / cell)), static_cast<long>(std::floor(p.y() / cell)), static_cast<long>(std::floor(p.z() / cell))};
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
    const Eigen::Vector3d c = (rest[static_cast<std::size_t>(t[0])] + rest[static_cast<std::size_t>(t[1])] + rest[static_cast<std::size_t>(t[2])]) / 3.0;
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

StepReport Session::advance() {
  std::lock_guard<std::mutex> stepLock(stepMutex_);
  // The events due at this boundary, in the order they were posted.
  std::vector<InputEvent> due;
  {
    std::lock_guard<std::mutex> lock(mailboxMutex_);
    for (auto it = mailbox_.begin(); it != mailbox_.end();) {
      if (it->step < 0 || it->step <= steps_) {
        due.push_back(std::move(*it));
        it = mailbox_.erase(it);
      } else {
        ++it;
      }
    }
  }
  std::string message;
  // A cut whose body was built on another thread replaces the body as soon as it is ready (recorded, so that
  // a replay applies it at the same boundary; the replay itself waits for the recording's word).
  const bool cutDue = pendingCut_ && (pendingCut_->applyAt >= 0 ? steps_ >= pendingCut_->applyAt
                                                                 : setup_.settings.factorRefresh == FactorRefresh::Asynchronous);
  if (cutDue && finishPendingCut(pendingCut_->applyAt >= 0, message)) {
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
  if (stroke_.open && !tool_.cutting && !pendingCut_ && !restOfSweep_) finishStroke(message);
  if (tool_.present && setup_.tools.toolRadius > 0) updateToolConstraints();  // contacts move with the tissue: detected at every step
  const StepReport rep = body_->step(state_);
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
  if ((!tool_.held.empty() || contactConstraints_ > 0) && rep.ok) {
    tool_.force = body_->toolForce();
    tool_.graspForce = tool_.held.empty() ? Eigen::Vector3d::Zero() : body_->toolForce(true);
    tool_.stiffness = body_->toolStiffness();
    // Pulled harder than the jaws can hold: the tissue slips out (the jaws stay closed, holding nothing). The
    // jaws' own share decides: the shaft pressing on the tissue does not open them.
    if (!tool_.held.empty() && tool_.graspForce.norm() > setup_.tools.maxGraspForce) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "The tissue slipped out of the grasper at %.1f N (the scene's maximum grasp force is %.1f N).", tool_.graspForce.norm(),
                    setup_.tools.maxGraspForce);
      message = buf;
      tool_.released = tool_.held;  // the tissue leaves the jaws
      std::sort(tool_.released.begin(), tool_.released.end());
      tool_.held.clear();
      tool_.heldOffset.clear();
      tool_.stiffness.setZero();  // nothing held: the force does not follow the tool any more
      tool_.graspForce.setZero();
      events_.push_back("slip");
      updateToolConstraints();
    }
  } else if (tool_.held.empty() && contactConstraints_ == 0) {
    tool_.force.setZero();
    tool_.graspForce.setZero();
    tool_.stiffness.setZero();
  }
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

Checkpoint Session::checkpointLocked() const {
  Checkpoint c{steps_, setup_, state_, tool_, std::nullopt, restOfSweep_};
  if (pendingCut_) c.pendingCut = static_cast<const PendingCutInput&>(*pendingCut_);
  return c;
}

Checkpoint StepRecord::checkpoint() const { return session->checkpointLocked(); }

void Session::setStepHook(std::function<void(const StepRecord&)> f) {
  std::lock_guard<std::mutex> lock(stepMutex_);
  stepHook_ = std::move(f);
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
  s->material = setup_.material;
  s->message = message;
  s->events = std::move(events);
  s->mass = body_->mass();
  s->elements = body_->tetrahedra().size();
  s->tets = tets_;
  s->surface = setup_.topology > 0 ? surface_ : nullptr;
  s->trocar = *setup_.tools.trocar;
  if (publishStress_) body_->stress(state_, s->stress);
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
    toolForce_.store(v);
  }
  std::function<void()> callback;
  {
    std::lock_guard<std::mutex> lock(mailboxMutex_);
    snapshot_ = std::move(s);
    callback = published_;
  }
  if (callback) callback();
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
  if (pendingCut_) {  // a cut of the state left behind: not waited for (it finishes on its own thread)
    for (auto it = abandonedCuts_.begin(); it != abandonedCuts_.end();)
      it = it->wait_for(std::chrono::seconds(0)) == std::future_status::ready ? abandonedCuts_.erase(it) : it + 1;
    abandonedCuts_.push_back(std::move(pendingCut_->built));
    pendingCut_.reset();
  }
  restOfSweep_ = c.restOfSweep;
  stroke_ = {};
  setup_ = c.setup;
  body_ = makeFemBody(setup_);
  tets_ = std::make_shared<const std::vector<std::array<int, 4>>>(body_->tetrahedra());
  surface_.reset();
  if (setup_.topology > 0) updateCutSurface();
  state_ = c.state;
  body_->requestAgain(state_);
  updateSurfaceNodes();
  tool_ = c.tool;
  steps_ = c.step;
  if (c.pendingCut) {  // the cut under way is built again from the same inputs (the same body)
    PendingCut p;
    static_cast<PendingCutInput&>(p) = *c.pendingCut;
    launchCutBuild(p);
    pendingCut_ = std::move(p);
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
    bool doReset = false, doStep = false;
    {
      std::unique_lock<std::mutex> lock(mailboxMutex_);
      wake_.wait(lock, [this] { return quit_ || playing_ || pendingSteps_ > 0 || pendingReset_ || republish_; });
      if (quit_) return;
      if (republish_ && !playing_ && pendingSteps_ == 0 && !pendingReset_) {
        republish_ = false;
        lock.unlock();
        std::lock_guard<std::mutex> stepLock(stepMutex_);
        const auto last = snapshot();
        publish(last->report, last->message);
        continue;
      }
      republish_ = false;
      doReset = pendingReset_;
      pendingReset_ = false;
      if (!doReset && pendingSteps_ > 0) {
        --pendingSteps_;
        doStep = true;
      }
    }
    if (doReset) {
      std::lock_guard<std::mutex> stepLock(stepMutex_);
      if (pendingCut_) {
        pendingCut_->built.wait();
        pendingCut_.reset();
      }
      restOfSweep_.reset();
      stroke_ = {};
      if (setup_.topology != uncut_.topology) {
        // Back to the organ before any cut (parameter edits stay).
        setup_.mesh = uncut_.mesh;
        setup_.rest = uncut_.rest;
        setup_.fixedNodes = uncut_.fixedNodes;
        setup_.topology = uncut_.topology;
        setup_.cut = uncut_.cut;
        body_ = makeFemBody(setup_);
        tets_ = std::make_shared<const std::vector<std::array<int, 4>>>(body_->tetrahedra());
        surface_.reset();
      }
      state_ = body_->initialState();
      updateSurfaceNodes();
      steps_ = 0;
      tool_ = {};
      updateToolConstraints();
      StepReport rest;
      rest.ok = true;
      rest.outcome = StepStatus::Converged;  // no step taken: nothing left unsolved
      publish(rest, {});
      wasPlaying = false;
      continue;
    }
    const bool play = playing_ && !doStep;
    if (play && !wasPlaying) {
      playStart = clock::now();
      simAtStart = state().time;
    }
    wasPlaying = play;
    const StepReport rep = advance();
    if (!rep.ok) {
      playing_ = false;  // the step was rolled back; the snapshot's status says why
      wasPlaying = false;
      continue;
    }
    if (play) {
      // Real time: wait while the simulation is ahead of the wall clock (woken early by pause or quit).
      const double ahead = (state().time - simAtStart) - std::chrono::duration<double>(clock::now() - playStart).count();
      if (ahead > 0) {
        std::unique_lock<std::mutex> lock(mailboxMutex_);
        wake_.wait_for(lock, std::chrono::duration<double>(std::min(ahead, 1.0)), [this] { return quit_ || !playing_ || pendingReset_; });
      }
    }
  }
}

BodySetup replaySetup(BodySetup setup) {
  if (setup.settings.factorRefresh == FactorRefresh::Asynchronous) setup.settings.factorRefresh = FactorRefresh::Deferred;
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
