// The hybrid model as a deformable body (issue 37; hybrid.hpp): quasi-static, each step the linear static answer of the
// whole organ under the instruments' rows, the FEM region's system solved with the rest condensed onto their interface.
// The region is the elements within kRegionRadius of its centres: at first the surface's point nearest the trocar
// (where the instruments come in), then every node an instrument acts on outside it (the region grows there at once,
// the rest's responses computed again) and the new nodes of a cut (carried to the cut body by carryInto, with the old
// responses, which the new body keeps when the cut left the rest as it was).
#include <rehearse/simcore/hybrid.hpp>
#include <rehearse/simcore/session/body.hpp>

#include "staticbody.hpp"

#include <chrono>
#include <cstdio>

namespace rehearse::simcore {
namespace {

constexpr double kRegionRadius = 0.03;  // m

class HybridBody final : public StaticBody {
 public:
  explicit HybridBody(const BodySetup& s) : StaticBody(s), gravity_(s.settings.gravity) {
    if (std::find(fixed_.begin(), fixed_.end(), 1) == fixed_.end())
      throw MeshError("The hybrid model cannot be built: Nothing holds the organ (attach it first).");
    centres_ = s.regionCentres;
    if (centres_.empty()) {
      // Where the instruments come in: the surface's node nearest the trocar.
      const Eigen::Vector3d trocar = s.tools.trocar ? *s.tools.trocar : defaultTrocar(model_.rest);
      std::vector<char> on(model_.nodeCount(), 0);
      for (const auto& t : boundaryTriangles(restMesh(s), false))
        for (int v : t) on[static_cast<std::size_t>(v)] = 1;
      double best = std::numeric_limits<double>::infinity();
      Eigen::Vector3d at = model_.rest.empty() ? Eigen::Vector3d::Zero() : model_.rest[0];
      for (std::size_t v = 0; v < on.size(); ++v)
        if (on[v] && (model_.rest[v] - trocar).norm() < best)
          best = (model_.rest[v] - trocar).norm(), at = model_.rest[v];
      centres_.push_back(at);
    }
    std::string why;
    if (!rebuild(s.hybridBefore.get(), why)) throw MeshError("The hybrid model cannot be built: " + why);
    // Where it is at t = 0: the registered shape (the equilibrium), or the rest shape with its sag under gravity.
    u0_.setZero(base_.size());
    Eigen::VectorXd lambda;
    if (!started_ && !elastic_->solveRows({}, base_, true, u0_, lambda, nullptr, why))
      throw MeshError("The hybrid model cannot be built: " + why);
  }
  void setToolConstraints(std::vector<ScalarConstraint> c) override {
    rows_ = std::move(c);
    // Nodes the instruments act on outside the region: the region grows around them (one centre per node farther than
    // half the radius from the centres already there).
    growWhy_.clear();
    bool grow = false;
    for (const auto& r : rows_)
      for (int k = 0; k < 4; ++k) {
        const int v = r.nodes[static_cast<std::size_t>(k)];
        if (v < 0 || static_cast<std::size_t>(v) >= model_.nodeCount() || r.weights[static_cast<std::size_t>(k)] == 0 ||
            elastic_->fixedNodes()[static_cast<std::size_t>(v)] || elastic_->inRegion(v))
          continue;
        grow = addCentre(model_.rest[static_cast<std::size_t>(v)]) || grow;
      }
    if (!grow) return;
    const auto before = centres_;
    if (!rebuild(elastic_.get(), growWhy_)) centres_ = before;  // the step says why (the row is outside the region)
    ++growths_;
  }
  std::string buildNote() const override {
    char said[400];
    std::snprintf(said, sizeof said,
                  "The hybrid model: a FEM region of %zu of %zu elements (%zu nodes) around %zu point%s, the rest's "
                  "responses at %zu interface nodes (%.0f MB), %s in %.2f s.",
                  regionElements_, model_.tets.size(), elastic_->regionNodes(), centres_.size(),
                  centres_.size() == 1 ? "" : "s", elastic_->interfaceNodes(), elastic_->memoryBytes() / 1e6,
                  elastic_->reusedRest() ? "kept from the body before" : "computed", buildSeconds_);
    return said;
  }
  void carryInto(BodySetup& next) const override {
    next.regionCentres = centres_;
    // The new nodes a cut made (past this body's count) join the region: later cuts there keep the rest's responses.
    try {
      const Mesh mesh = restMesh(next);
      for (std::size_t v = model_.nodeCount(); v < mesh.points.size(); ++v) {
        const Eigen::Vector3d& p = mesh.points[v];
        if (std::all_of(next.regionCentres.begin(), next.regionCentres.end(),
                        [&](const Eigen::Vector3d& c) { return (c - p).norm() > 0.5 * kRegionRadius; }))
          next.regionCentres.push_back(p);
      }
    } catch (const MeshError&) {  // the next setup's own build says what is wrong with it
    }
    next.hybridBefore = elastic_;
  }

 private:
  bool addCentre(const Eigen::Vector3d& p) {
    for (const auto& c : centres_)
      if ((c - p).norm() <= 0.5 * kRegionRadius) return false;
    centres_.push_back(p);
    return true;
  }
  bool rebuild(const HybridElasticity* previous, std::string& why) {
    const auto began = std::chrono::steady_clock::now();
    std::vector<char> region(model_.tets.size(), 0);
    for (std::size_t e = 0; e < model_.tets.size(); ++e) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int v : model_.tets[e]) c += 0.25 * model_.rest[static_cast<std::size_t>(v)];
      for (const auto& centre : centres_)
        if ((c - centre).norm() <= kRegionRadius) {
          region[e] = 1;
          break;
        }
    }
    auto built = HybridElasticity::build(model_, fixed_, region, gravity_, why, previous);
    if (!built) return false;
    elastic_ = std::make_shared<const HybridElasticity>(std::move(*built));
    regionElements_ =
        static_cast<std::size_t>(std::count(region.begin(), region.end(), 1)) + elastic_->absorbedElements();
    buildSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count();
    return true;
  }
  bool solveRows(Eigen::VectorXd& u, std::string& why) override {
    if (!elastic_->solveRows(rows_, base_, !started_, u, lambda_, &W_, why)) {
      if (!growWhy_.empty()) why += " (the region could not grow there: " + growWhy_ + ")";
      return false;
    }
    return true;
  }

  Eigen::Vector3d gravity_;
  std::vector<Eigen::Vector3d> centres_;
  std::shared_ptr<const HybridElasticity> elastic_;
  std::size_t regionElements_ = 0;
  double buildSeconds_ = 0;
  std::string growWhy_;
  int growths_ = 0;
};

}  // namespace

std::unique_ptr<DeformableBody> makeHybridBody(const BodySetup& setup) { return std::make_unique<HybridBody>(setup); }

}  // namespace rehearse::simcore
