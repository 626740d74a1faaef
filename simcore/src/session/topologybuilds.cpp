#include <rehearse/simcore/session/session.hpp>
#include <rehearse/simcore/session/topologybuilds.hpp>

#include <chrono>

namespace rehearse::simcore {

void TopologyBuilds::launch(TopologyChange change, const BodySetup& uncut, double meanEdge) {
  PendingChange p;
  static_cast<TopologyChange&>(p) = std::move(change);
  p.built = std::async(std::launch::async,
                       [setup = p.setup, at = p.factorAt, nodes = p.toolNodes, uncut = uncut, edge = meanEdge]() {
                         Built b;
                         b.body = makeBody(setup);
                         b.body->prepareFactor(at, nodes);
                         b.surface = makeCutSurface(uncut, setup.mesh, edge);
                         b.contact = contactSurface(b.body->restPositions(), b.body->tetrahedra());
                         return b;
                       });
  pending_ = std::move(p);
}

bool TopologyBuilds::ready() const {
  return pending_->built.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
}

TopologyBuilds::PendingChange TopologyBuilds::take() {
  PendingChange p = std::move(*pending_);
  pending_.reset();
  return p;
}

void TopologyBuilds::drop(bool wait) {
  if (!pending_) return;
  if (wait) {
    pending_->built.wait();
  } else {  // not waited for: it finishes on its own thread
    for (auto it = abandoned_.begin(); it != abandoned_.end();)
      it = it->wait_for(std::chrono::seconds(0)) == std::future_status::ready ? abandoned_.erase(it) : it + 1;
    abandoned_.push_back(std::move(pending_->built));
  }
  pending_.reset();
}

void TopologyBuilds::retire(std::unique_ptr<DeformableBody> body) {
  for (auto it = retired_.begin(); it != retired_.end();)
    it = it->wait_for(std::chrono::seconds(0)) == std::future_status::ready ? retired_.erase(it) : it + 1;
  if (!body) return;
  std::shared_ptr<DeformableBody> old(std::move(body));
  retired_.push_back(std::async(std::launch::async, [old]() mutable { old.reset(); }));
}

}  // namespace rehearse::simcore
