// The precomputed linear elasticity as a deformable body (issue 37; precomputed.hpp): quasi-static, each step the
// exact linear static solution under the instruments' constraints by superposition of the responses computed when the
// body is built. The velocities are the positions' change over the step (for what reads them); no inertia, no damping.
#include <rehearse/simcore/precomputed.hpp>
#include <rehearse/simcore/session/body.hpp>

#include "staticbody.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>

namespace rehearse::simcore {
namespace {

constexpr double kAllRowsBytes = 256e6;

class PrecomputedBody final : public StaticBody {
 public:
  explicit PrecomputedBody(const BodySetup& s) : StaticBody(s) {
    std::vector<int> driven;
    {
      std::vector<char> on(model_.nodeCount(), 0);
      for (const auto& t : boundaryTriangles(restMesh(s), false))
        for (int v : t) on[static_cast<std::size_t>(v)] = 1;
      for (std::size_t i = 0; i < on.size(); ++i)
        if (on[i] && !fixed_[i]) driven.push_back(static_cast<int>(i));
    }
    const auto began = std::chrono::steady_clock::now();
    std::string why;
    PrecomputeSettings ps;
    // Every node's response while that takes at most kAllRowsBytes; past it the surface's only, the inner nodes'
    // displacement then by a back-solve per step (memory bounded by 9 x surface^2 numbers plus the factor).
    ps.drivenRowsOnly =
        9.0 * static_cast<double>(driven.size()) * static_cast<double>(model_.nodeCount()) * sizeof(double) >
        kAllRowsBytes;
    ps.progress = s.buildProgress;
    response_ = precomputedFor(model_, fixed_, driven, s.settings.gravity, ps, key_, from_, why);
    if (!response_) throw MeshError("The precomputed model cannot be built: " + why);
    buildSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count();
    u0_ = started_ ? Eigen::VectorXd::Zero(base_.size()) : response_->sag();
  }
  std::string buildNote() const override {
    char said[320];
    const std::size_t at = response_->drivenRowsOnly() ? response_->driven().size() : response_->nodeCount();
    const char* where = response_->drivenRowsOnly() ? "surface nodes (the inner ones by a back-solve)" : "nodes";
    if (from_ == "built")
      std::snprintf(said, sizeof said,
                    "The precomputed model's responses to each of %zu surface nodes at %zu %s were computed in %.1f s "
                    "(%.0f MB).",
                    response_->driven().size(), at, where, buildSeconds_, response_->memoryBytes() / 1e6);
    else
      std::snprintf(said, sizeof said,
                    "The precomputed model's responses to each of %zu surface nodes at %zu %s were taken from the "
                    "%s (%.0f MB, %.1f s).",
                    response_->driven().size(), at, where, from_ == "cache" ? "last build" : from_.c_str(),
                    response_->memoryBytes() / 1e6, buildSeconds_);
    return said;
  }
  std::uint64_t responseKey() const override { return key_; }

 private:
  bool solveRows(Eigen::VectorXd& u, std::string& why) override {
    return response_->solveConstraints(rows_, base_, u0_, u, lambda_, &W_, why);
  }

  std::shared_ptr<const PrecomputedElasticity> response_;
  std::uint64_t key_ = 0;
  std::string from_;  ///< "built", "cache" or "case file"
  double buildSeconds_ = 0;
};

}  // namespace

std::unique_ptr<DeformableBody> makePrecomputedBody(const BodySetup& setup) {
  return std::make_unique<PrecomputedBody>(setup);
}

}  // namespace rehearse::simcore
