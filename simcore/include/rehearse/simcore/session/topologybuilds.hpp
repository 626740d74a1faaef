#pragma once
// Topology changes under way (session.hpp; the session's mechanism: topology.cpp): the change whose new body is being
// built on a second thread while the old body steps on, the builds a restore left behind, and the old bodies being
// destroyed on other threads. It only starts, holds and drops the builds; the session decides when one is swapped in.
//
// Locking: no lock of its own; it is the stepping thread's, guarded by the session's step mutex like the body. The
// threads it starts (std::async) share nothing with the session: a build gets copies of what it builds from, a
// retirement owns the old body it destroys.
#include <rehearse/simcore/session/body.hpp>
#include <rehearse/simcore/session/contact.hpp>

#include <Eigen/Core>

#include <future>
#include <memory>
#include <optional>
#include <vector>

namespace rehearse::simcore {

struct CutSurface;

/// A topology change (a cut, a tear, a burn) as its module computed it: the new body's setup and
/// how the state extends onto the new nodes. The session builds the new body (at once, or on the second thread while
/// the old one steps on) and swaps it in at a step boundary, carrying the state across (topology.cpp). A checkpoint
/// keeps a change still under way, so that a session restored from it builds the same body again.
/// Cut: the blade's sweep; Burn: the cautery relabels elements (no new node, no new face); Tear: an over-stretched
/// element split across its stretch (tearing.cpp; its events are said when it is asked for).
enum class ChangeKind { Cut, Burn, Tear };
struct TopologyChange {
  ChangeKind kind = ChangeKind::Cut;  ///< what words its events (a burn relabels elements: no new node, no new face)
  BodySetup setup;                    ///< the new body's setup (new mesh, topology + 1, the change's progress)
  std::vector<CutNode> newNodes;      ///< how the state extends onto the new nodes (each interpolated from old ones)
  std::vector<int> labels;     ///< element labels the change went through (a cut: its events, the vessels it cut)
  Eigen::VectorXd factorAt;    ///< the positions the new body's first factor is built at (asynchronous build)
  /// The nodes the instruments held and touched when it was asked for (their numbers stay: a change only adds
  /// nodes): their compliance blocks are solved with that first factor on the build's thread, not by the first step.
  std::vector<int> toolNodes;
  bool clearProgress = false;  ///< the instrument was withdrawn meanwhile: the new body starts without progress
  long applyAt = -1;  ///< the step boundary it replaces the body at (ToolSettings::cutLatencySteps); -1: when ready
  /// With applyAt: at that boundary if built by then, else at the first boundary after it is built (the asynchronous
  /// refresh's live run never waits; ToolSettings::tearWhenBuilt). The step it came in at is recorded (CutApplied),
  /// and a replay (the deferred refresh) applies it there; a synchronous run waits at applyAt as without it.
  bool late = false;
};

class TopologyBuilds {
 public:
  /// What the second thread builds: the new body (its first factor prepared), its cut surface and its contact surface.
  struct Built {
    std::unique_ptr<DeformableBody> body;
    std::shared_ptr<const CutSurface> surface;
    ContactSurface contact;
  };
  struct PendingChange : TopologyChange {
    std::future<Built> built;
  };

  bool underWay() const { return pending_.has_value(); }
  /// The change under way (null without one).
  PendingChange* pending() { return pending_ ? &*pending_ : nullptr; }
  const PendingChange* pending() const { return pending_ ? &*pending_ : nullptr; }
  /// Starts building `change`'s body on another thread (its cut surface against `uncut`, the uncut mesh's mean edge
  /// `meanEdge`): the change under way from now on.
  void launch(TopologyChange change, const BodySetup& uncut, double meanEdge);
  /// Whether the change under way has been built (or failed to), without waiting.
  bool ready() const;
  /// The change under way, taken (none after).
  PendingChange take();
  /// Drops the change under way (reset waits for its build, a restore leaves it to finish on its own thread).
  void drop(bool wait);
  /// Destroys an old body on another thread (an asynchronous refresh under way ends first); the ones done are let go.
  void retire(std::unique_ptr<DeformableBody> body);

 private:
  std::optional<PendingChange> pending_;
  std::vector<std::future<Built>> abandoned_;  ///< builds a restore left behind (waited for at the end)
  /// Old bodies being destroyed on another thread (an asynchronous refresh under way ends first).
  std::vector<std::future<void>> retired_;
};

}  // namespace rehearse::simcore
