// The checkpoint codec of recordings: a checkpoint's state as bytes and back, its fields named once for both ways.
#include "recording_codec.hpp"

#include "rehearse/app/recording.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <optional>
#include <stdexcept>
#include <type_traits>

namespace rehearse::app {

// Fields a checkpoint carries: a new one must be named in checkpointFields too.
static_assert(sizeof(simcore::SimulationState::Lagged) == 64,
              "SimulationState::Lagged changed: record the new field in checkpointFields");
static_assert(sizeof(simcore::ToolState) == 344, "ToolState changed: record the new field in checkpointFields");
static_assert(sizeof(simcore::Clip) == 168 && sizeof(simcore::Bleed) == 96 && sizeof(simcore::OperativeField) == 120,
              "the operative field changed: record the new field in checkpointFields");

namespace {

constexpr std::uint32_t kCheckpointMagicV1 = 0x314B4352;  // "RCK1": before the contact's easing was kept
constexpr std::uint32_t kCheckpointMagicV2 =
    0x324B4352;  // "RCK2": + ToolState::easing and vesselsCut (now structuresCut), TopologyChange::applyAt
constexpr std::uint32_t kCheckpointMagicV3 = 0x334B4352;  // "RCK3": + ToolState::graspForce and released
constexpr std::uint32_t kCheckpointMagicV4 = 0x344B4352;  // "RCK4": + ToolState::jawTip and jawTool
constexpr std::uint32_t kCheckpointMagic =
    0x354B4352;  // "RCK5": + the operative field (clips, bleeding, blood lost, the cautery's heat), the change's kind
// "RCK6": RCK5's bytes followed by their FNV-1a 64 digest, so that a seek finds any changed byte before it restores the
// state (a byte changed inside a double decoded, and a seek restored it without a word: issue 60).
constexpr std::uint32_t kCheckpointMagicDigest = 0x364B4352;

std::uint64_t fnv1a(const char* p, std::size_t n) {
  std::uint64_t h = 1469598103934665603ull;
  for (std::size_t i = 0; i < n; ++i) h = (h ^ static_cast<unsigned char>(p[i])) * 1099511628211ull;
  return h;
}

// Bytes of a checkpoint's state: plain values in this machine's order (a recording replays on the build
// that made it), each array preceded by its length; reading checks every length against what is left.
// Writer and Reader are the two ways through checkpointFields (which names each field once): the same calls write
// a const checkpoint's fields or read them into a new one. `version` is the format's (1-5 for RCK1-RCK5; the writer
// writes RCK5's fields, the digest that makes them RCK6 is added after them); kReads guards what only reading does
// (the values older formats did not keep, the checks of what was read).
struct Writer {
  static constexpr bool kReads = false;
  static constexpr int version = 5;
  std::uint64_t setupHashValue = 0;
  std::uint64_t pendingSetupHash = 0;
  std::string b;

  template <class T>
  void pod(const T& v) {
    b.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void flag(bool v) { pod(static_cast<std::uint8_t>(v)); }
  template <class T>
  void i32(const T& v) {
    pod(static_cast<std::int32_t>(v));
  }
  template <class T>
  void i64(const T& v) {
    pod(static_cast<std::int64_t>(v));
  }
  template <class T>
  void f64(const T& v) {
    static_assert(std::is_same_v<T, double>);
    pod(v);
  }
  void v3(const Eigen::Vector3d& v) { b.append(reinterpret_cast<const char*>(v.data()), 3 * sizeof(double)); }
  void vec(const Eigen::VectorXd& v) {
    pod(static_cast<std::int64_t>(v.size()));
    b.append(reinterpret_cast<const char*>(v.data()), sizeof(double) * static_cast<std::size_t>(v.size()));
  }
  void raw(const void* from, std::size_t n) { b.append(static_cast<const char*>(from), n); }
  // An array's length (`each`: the least bytes an element takes, which reading checks).
  template <class C>
  std::size_t size(const C& c, std::size_t /*each*/) {
    pod(static_cast<std::int64_t>(c.size()));
    return c.size();
  }
  template <class C>
  void resize(const C&, std::size_t) {}
  template <class T>
  bool present(const std::optional<T>& o) {
    flag(o.has_value());
    return o.has_value();
  }
  // A setup by its hash (the recorder has them already).
  void setup(const simcore::BodySetup&, bool pending) { pod(pending ? pendingSetupHash : setupHashValue); }
  void changeKind(simcore::ChangeKind k) { pod(static_cast<std::uint8_t>(k)); }
};

struct Reader {
  static constexpr bool kReads = true;
  const char* p;
  const char* end;
  int version;
  const std::function<simcore::BodySetup(std::uint64_t)>& setupOf;

  void need(std::size_t n) const {
    if (static_cast<std::size_t>(end - p) < n) throw std::runtime_error("a recorded checkpoint is cut short");
  }
  template <class T>
  T pod() {
    need(sizeof(T));
    T v;
    std::memcpy(&v, p, sizeof v);
    p += sizeof v;
    return v;
  }
  std::size_t count(std::size_t each) {
    const auto n = pod<std::int64_t>();
    if (n < 0 || static_cast<std::size_t>(n) > static_cast<std::size_t>(end - p) / each)
      throw std::runtime_error("a recorded checkpoint has a bad length");
    return static_cast<std::size_t>(n);
  }
  Eigen::VectorXd vec() {
    const std::size_t n = count(sizeof(double));
    Eigen::VectorXd v(static_cast<Eigen::Index>(n));
    if (n)
      std::memcpy(v.data(), p, n * sizeof(double));  // an empty vector has no storage (memcpy of null is undefined)
    p += n * sizeof(double);
    return v;
  }
  Eigen::Vector3d v3() {
    need(3 * sizeof(double));
    Eigen::Vector3d v;
    std::memcpy(v.data(), p, 3 * sizeof(double));
    p += 3 * sizeof(double);
    return v;
  }

  void flag(bool& v) { v = pod<std::uint8_t>() != 0; }
  template <class T>
  void i32(T& v) {
    v = static_cast<T>(pod<std::int32_t>());
  }
  template <class T>
  void i64(T& v) {
    v = static_cast<T>(pod<std::int64_t>());
  }
  template <class T>
  void f64(T& v) {
    static_assert(std::is_same_v<T, double>);
    v = pod<double>();
  }
  void v3(Eigen::Vector3d& v) { v = v3(); }
  void vec(Eigen::VectorXd& v) { v = vec(); }
  void raw(void* to, std::size_t n) {
    need(n);
    std::memcpy(to, p, n);
    p += n;
  }
  template <class C>
  std::size_t size(C& c, std::size_t each) {
    c.resize(count(each));
    return c.size();
  }
  template <class C>
  void resize(C& c, std::size_t n) {
    c.resize(n);
  }
  template <class T>
  bool present(std::optional<T>& o) {
    if (!pod<std::uint8_t>()) return false;
    o.emplace();
    return true;
  }
  void setup(simcore::BodySetup& s, bool /*pending*/) { s = setupOf(pod<std::uint64_t>()); }
  void changeKind(simcore::ChangeKind& k) {
    const auto kind = pod<std::uint8_t>();
    if (kind > static_cast<std::uint8_t>(simcore::ChangeKind::Tear))
      throw std::runtime_error("a recorded checkpoint's change under way is of an unknown kind");
    k = static_cast<simcore::ChangeKind>(kind);
  }
};

// The fields, in their order in the bytes. P, S, T, F, C: the simcore types, const when writing.
template <class Io, class P>
void progressFields(Io& io, P& p) {  // simcore::CutProgress
  io.size(p.pendingFaces, 3 * sizeof(std::int32_t));
  for (auto& f : p.pendingFaces)
    for (auto& n : f) io.i32(n);
  io.size(p.nodes, sizeof(std::int32_t));
  for (auto& n : p.nodes) io.i32(n);
  io.size(p.sweeps, 12 * sizeof(double));
  for (auto& w : p.sweeps)
    for (auto* v : {&w.a0, &w.b0, &w.a1, &w.b1}) io.v3(*v);
}

template <class Io, class S>
void stateFields(Io& io, S& s) {  // simcore::SimulationState
  io.vec(s.x);
  io.vec(s.v);
  io.f64(s.time);
  io.flag(s.lagged.valid);
  io.vec(s.lagged.at);
  io.f64(s.lagged.step);
  io.flag(s.lagged.refresh);
  io.flag(s.lagged.drift);
  io.flag(s.lagged.requested);
  io.vec(s.lagged.requestedAt);
  io.f64(s.lagged.requestedStep);
  io.vec(s.forces);
  io.flag(s.forcesValid);
}

// Sorted, distinct surface triangles, each held at a distance (m) that is a number.
void checkEasing(const std::vector<std::pair<int, double>>& easing) {
  for (std::size_t k = 0; k < easing.size(); ++k)
    if (easing[k].first < 0 || !std::isfinite(easing[k].second) || (k > 0 && easing[k].first <= easing[k - 1].first))
      throw std::runtime_error("a recorded checkpoint's contact is damaged");
}

template <class Io, class T>
void toolFields(Io& io, T& t) {  // simcore::ToolState
  io.v3(t.tip);
  io.flag(t.jawClosed);
  io.size(t.held, sizeof(std::int32_t));
  for (auto& n : t.held) io.i32(n);
  io.size(t.heldOffset, 3 * sizeof(double));
  for (auto& v : t.heldOffset) io.v3(v);
  io.flag(t.cutting);
  io.v3(t.cutFrom);
  io.v3(t.force);
  if (io.version >= 3) {
    io.v3(t.graspForce);
  } else if constexpr (Io::kReads) {
    // Before RCK3 the jaws' share was not kept apart: all of it (the next step computes both again).
    t.graspForce = t.held.empty() ? Eigen::Vector3d::Zero() : t.force;
  }
  io.raw(t.stiffness.data(), 9 * sizeof(double));
  io.flag(t.present);
  io.i32(t.contacts);
  io.i32(t.pierced);
  if (io.version >= 2) {
    io.size(t.easing, sizeof(std::int32_t) + sizeof(double));
    for (auto& [tri, keep] : t.easing) {
      io.i32(tri);
      io.f64(keep);
    }
    if constexpr (Io::kReads) checkEasing(t.easing);
    io.size(t.structuresCut, sizeof(std::int32_t));
    for (auto& l : t.structuresCut) io.i32(l);
  }
  if (io.version >= 3) {
    io.size(t.released, sizeof(std::int32_t));
    for (auto& n : t.released) io.i32(n);
  }
  if (io.version >= 4) {
    io.v3(t.jawTip);
    io.i32(t.jawTool);
    if constexpr (Io::kReads)
      if (!t.jawTip.allFinite()) throw std::runtime_error("a recorded checkpoint's jaws are not at a place");
  } else if constexpr (Io::kReads) {
    t.jawTip = t.tip;  // before RCK4 the jaws were wherever the tip was
  }
}

template <class Io, class F>
void operativeFieldFields(Io& io, F& f) {  // simcore::OperativeField, RCK5 on
  io.size(f.clips, 6 * sizeof(double) + 2 * sizeof(std::int32_t) + sizeof(std::int64_t));
  for (auto& k : f.clips) {
    io.v3(k.across);
    io.v3(k.axis);
    io.i32(k.label);
    io.i32(k.anchor);
    const std::size_t m = io.size(k.nodes, sizeof(std::int32_t) + 2 * sizeof(double));
    io.resize(k.from, m);
    io.resize(k.to, m);
    for (std::size_t i = 0; i < m; ++i) {
      io.i32(k.nodes[i]);
      io.f64(k.from[i]);
      io.f64(k.to[i]);
    }
    for (auto* v : {&k.anchorFrom, &k.anchorTo, &k.placedAt, &k.gap}) io.f64(*v);
    io.flag(k.spans);
  }
  io.size(f.bleeds, 2 * sizeof(std::int32_t) + 9 * sizeof(double));
  for (auto& b : f.bleeds) {
    io.i32(b.label);
    io.v3(b.at);
    io.v3(b.normal);
    io.i32(b.node);
    for (auto* v : {&b.area, &b.rate, &b.lost}) io.f64(*v);
    io.i32(b.stoppedBy);
  }
  io.f64(f.bloodLoss);
  io.flag(f.energy);
  io.size(f.heating, sizeof(std::int32_t) + sizeof(double));
  for (auto& [e, heat] : f.heating) {
    io.i32(e);
    io.f64(heat);
  }
  io.size(f.energyOn, sizeof(std::int32_t));
  for (auto& l : f.energyOn) io.i32(l);
  io.f64(f.energyTime);
}

template <class Io, class P>
void pendingChangeFields(Io& io, P& p) {  // simcore::TopologyChange
  io.setup(p.setup, true);
  if (io.version >= 5) io.changeKind(p.kind);  // before RCK5 every change was a cut
  progressFields(io, p.setup.cut);
  io.size(p.newNodes, 4 * sizeof(std::int32_t) + 4 * sizeof(double));
  for (auto& n : p.newNodes) {
    for (auto& f : n.from) io.i32(f);
    for (auto& w : n.weight) io.f64(w);
  }
  io.size(p.labels, sizeof(std::int32_t));
  for (auto& l : p.labels) io.i32(l);
  io.vec(p.factorAt);
  io.flag(p.clearProgress);
  if (io.version >= 2) {
    io.i64(p.applyAt);
    if constexpr (Io::kReads)
      if (p.applyAt < -1) throw std::runtime_error("a recorded checkpoint's cut under way is damaged");
  }
}

// Everything after the magic.
template <class Io, class C>
void checkpointFields(Io& io, C& c) {  // simcore::Checkpoint
  io.i64(c.step);
  io.setup(c.setup, false);
  progressFields(io, c.setup.cut);
  stateFields(io, c.state);
  toolFields(io, c.tool);
  if (io.version >= 5) operativeFieldFields(io, c.field);  // before RCK5: no clip, nothing bleeding
  if (io.present(c.restOfSweep)) {
    io.v3(c.restOfSweep->first);
    io.v3(c.restOfSweep->second);
  }
  if (io.present(c.pendingChange)) pendingChangeFields(io, *c.pendingChange);
}

// The digest first: a checkpoint whose bytes changed is refused before any of them is read as a state. RCK6's bytes
// come back as RCK5's (kept in `buffer`), older ones as they are.
const std::string& withoutDigest(const std::string& stored, std::string& buffer) {
  std::uint32_t first = 0;
  if (stored.size() >= sizeof first) std::memcpy(&first, stored.data(), sizeof first);
  if (first != kCheckpointMagicDigest) return stored;
  if (stored.size() < sizeof first + sizeof(std::uint64_t))
    throw std::runtime_error("a recorded checkpoint is truncated");
  std::uint64_t digest = 0;
  std::memcpy(&digest, stored.data() + stored.size() - sizeof digest, sizeof digest);
  if (fnv1a(stored.data(), stored.size() - sizeof digest) != digest)
    throw std::runtime_error("a recorded checkpoint's bytes do not match their digest (truncated or changed)");
  buffer = stored.substr(0, stored.size() - sizeof digest);
  std::memcpy(buffer.data(), &kCheckpointMagic, sizeof kCheckpointMagic);
  return buffer;
}

int formatVersion(std::uint32_t magic) {
  switch (magic) {
    case kCheckpointMagicV1: return 1;
    case kCheckpointMagicV2: return 2;
    case kCheckpointMagicV3: return 3;
    case kCheckpointMagicV4: return 4;
    case kCheckpointMagic: return 5;
    default: throw std::runtime_error("a recorded checkpoint is not in a known format");
  }
}

// The state's vectors against each other and the body's nodes; the body's node count.
std::size_t checkVectors(const simcore::Checkpoint& c) {
  const auto& s = c.state;
  if (s.v.size() != s.x.size() || (s.forcesValid && s.forces.size() != s.x.size()) ||
      (s.lagged.valid && s.lagged.at.size() != s.x.size()) ||
      (s.lagged.requested && s.lagged.requestedAt.size() != s.x.size()))
    throw std::runtime_error("a recorded checkpoint's vectors disagree in size");
  const std::size_t n = c.setup.rest.empty() ? c.setup.mesh.points.size() : c.setup.rest.size();
  if (static_cast<std::size_t>(s.x.size()) != 3 * n)
    throw std::runtime_error("a recorded checkpoint does not fit its body's nodes");
  return n;
}

// Node indices within the body (a damaged file must not reach the simulation as indices out of range) and the
// field's and the progress' numbers finite.
bool nodesAndFieldFit(const simcore::Checkpoint& c, std::size_t n) {
  const auto& t = c.tool;
  auto inRange = [n](int i) { return i >= 0 && static_cast<std::size_t>(i) < n; };
  bool ok = t.heldOffset.size() == t.held.size() && std::all_of(t.held.begin(), t.held.end(), inRange) &&
            std::all_of(t.released.begin(), t.released.end(), inRange) &&
            std::is_sorted(t.released.begin(), t.released.end()) &&
            std::all_of(c.setup.cut.nodes.begin(), c.setup.cut.nodes.end(), inRange);
  for (const auto& f : c.setup.cut.pendingFaces) ok = ok && std::all_of(f.begin(), f.end(), inRange);
  for (const auto& k : c.field.clips)
    ok = ok && inRange(k.anchor) && std::all_of(k.nodes.begin(), k.nodes.end(), inRange) && k.across.allFinite() &&
         k.axis.allFinite() && std::isfinite(k.anchorFrom) && std::isfinite(k.anchorTo) && std::isfinite(k.placedAt) &&
         std::isfinite(k.gap) && std::all_of(k.from.begin(), k.from.end(), [](double v) { return std::isfinite(v); }) &&
         std::all_of(k.to.begin(), k.to.end(), [](double v) { return std::isfinite(v); });
  for (const auto& b : c.field.bleeds)
    ok = ok && inRange(b.node) && b.at.allFinite() && b.normal.allFinite() && std::isfinite(b.area) &&
         std::isfinite(b.rate) && std::isfinite(b.lost) && b.stoppedBy >= -1 &&
         b.stoppedBy < static_cast<int>(c.field.clips.size());
  ok = ok && std::isfinite(c.field.bloodLoss) && std::isfinite(c.field.energyTime);
  const std::size_t elements = c.setup.mesh.tets.size();
  for (std::size_t k = 0; k < c.field.heating.size(); ++k)
    ok = ok && c.field.heating[k].first >= 0 && static_cast<std::size_t>(c.field.heating[k].first) < elements &&
         std::isfinite(c.field.heating[k].second) &&
         (k == 0 || c.field.heating[k].first > c.field.heating[k - 1].first);
  auto sweepsFinite = [](const simcore::CutProgress& p) {
    return std::all_of(p.sweeps.begin(), p.sweeps.end(), [](const auto& w) {
      return w.a0.allFinite() && w.b0.allFinite() && w.a1.allFinite() && w.b1.allFinite();
    });
  };
  return ok && sweepsFinite(c.setup.cut) && (!c.pendingChange || sweepsFinite(c.pendingChange->setup.cut));
}

void checkInstrument(const simcore::Checkpoint& c) {
  const auto& t = c.tool;
  if (!t.tip.allFinite() || !t.cutFrom.allFinite() || !t.force.allFinite() || !t.graspForce.allFinite() ||
      !t.stiffness.allFinite() || !std::isfinite(c.state.time) || t.contacts < 0 || t.pierced < 0 ||
      (c.restOfSweep && (!c.restOfSweep->first.allFinite() || !c.restOfSweep->second.allFinite())))
    throw std::runtime_error("a recorded checkpoint's instrument holds no number");
}

// The cut body's new nodes are made from the body's present nodes (n); the cut body has both.
void checkPendingChange(const simcore::TopologyChange& p, std::size_t n) {
  auto inRange = [n](int i) { return i >= 0 && static_cast<std::size_t>(i) < n; };
  const std::size_t m = p.setup.rest.empty() ? p.setup.mesh.points.size() : p.setup.rest.size();
  bool fits = m == n + p.newNodes.size() &&
              (p.factorAt.size() == 0 || static_cast<std::size_t>(p.factorAt.size()) == 3 * m) &&
              p.factorAt.allFinite();
  for (const auto& k : p.newNodes)
    for (std::size_t j = 0; j < 4; ++j)
      fits = fits && (k.from[j] == -1 || inRange(k.from[j])) && std::isfinite(k.weight[j]);
  auto inCut = [m](int i) { return i >= 0 && static_cast<std::size_t>(i) < m; };
  fits = fits && std::all_of(p.setup.cut.nodes.begin(), p.setup.cut.nodes.end(), inCut);
  for (const auto& f : p.setup.cut.pendingFaces) fits = fits && std::all_of(f.begin(), f.end(), inCut);
  if (!fits) throw std::runtime_error("a recorded checkpoint's cut under way does not fit its body");
}

}  // namespace

simcore::BodySetup sharedSetup(const simcore::BodySetup& s) {
  simcore::BodySetup o = s;
  o.cut.clear();
  return o;
}

namespace detail {
// The checkpoint's bytes with its setups' hashes (the recorder has them already).
std::string encodeCheckpoint(const simcore::Checkpoint& c, std::uint64_t setupHashValue,
                             std::uint64_t pendingSetupHash) {
  Writer o;
  o.setupHashValue = setupHashValue;
  o.pendingSetupHash = pendingSetupHash;
  o.pod(kCheckpointMagic);
  checkpointFields(o, c);
  // RCK6: the same bytes under their own magic, then their digest.
  std::memcpy(o.b.data(), &kCheckpointMagicDigest, sizeof kCheckpointMagicDigest);
  const std::uint64_t digest = fnv1a(o.b.data(), o.b.size());
  o.b.append(reinterpret_cast<const char*>(&digest), sizeof digest);
  return o.b;
}
}  // namespace detail

std::string encodeCheckpointState(const simcore::Checkpoint& c) {
  return detail::encodeCheckpoint(c, setupHash(c.setup), c.pendingChange ? setupHash(c.pendingChange->setup) : 0);
}

simcore::Checkpoint decodeCheckpointState(const std::string& stored,
                                          const std::function<simcore::BodySetup(std::uint64_t)>& setupOf) {
  std::string withDigestRemoved;
  const std::string& bytes = withoutDigest(stored, withDigestRemoved);
  simcore::Checkpoint c;
  Reader r{bytes.data(), bytes.data() + bytes.size(), 0, setupOf};
  r.version = formatVersion(r.pod<std::uint32_t>());
  checkpointFields(r, c);
  if (r.p != r.end) throw std::runtime_error("a recorded checkpoint has trailing bytes");
  const std::size_t n = checkVectors(c);
  if (!nodesAndFieldFit(c, n) || !c.state.x.allFinite() || !c.state.v.allFinite())
    throw std::runtime_error("a recorded checkpoint names nodes its body has not, or holds no number");
  checkInstrument(c);
  if (c.pendingChange) checkPendingChange(*c.pendingChange, n);
  return c;
}

}  // namespace rehearse::app
