// The parameterized mesh as a deformable body (issue 37; paramesh.hpp): the organ's surface (its shape at t = 0)
// resampled on an 81 x 81 geometry image, deformed by the Gaussian free-form deformation around the grasp (the held
// nodes' centre follows the jaws) or, without one, around the instrument's deepest contact; the tool's force from
// Hertz's law. The tetrahedral mesh is drawn: each node follows its nearest grid point by the deformation's Gaussian
// weight of its distance to it (about 1 on the surface). Geometric: no equilibrium, so every step says
// "inexact" with how far the holds are from where the instruments put them; it cannot cut, tear, clip or burn (the
// session refuses those with a sentence).
#include <rehearse/simcore/paramesh.hpp>
#include <rehearse/simcore/session/body.hpp>

#include "staticbody.hpp"

#include <Eigen/Eigenvalues>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

namespace rehearse::simcore {
namespace {

class FfdBody final : public StaticBody {
 public:
  explicit FfdBody(const BodySetup& s) : StaticBody(s) {
    const auto began = std::chrono::steady_clock::now();
    // The surface at t = 0 (its nodes compacted: the geometry image takes one closed surface).
    const auto tris = boundaryTriangles(restMesh(s), false);
    std::vector<int> slot(model_.nodeCount(), -1);
    std::vector<Eigen::Vector3d> points;
    std::vector<std::array<int, 3>> surface;
    for (const auto& t : tris) {
      std::array<int, 3> c{};
      for (int k = 0; k < 3; ++k) {
        const auto v = static_cast<std::size_t>(t[static_cast<std::size_t>(k)]);
        if (slot[v] < 0) slot[v] = static_cast<int>(points.size()), points.push_back(base_.segment<3>(3 * v));
        c[static_cast<std::size_t>(k)] = slot[v];
      }
      surface.push_back(c);
    }
    std::string why;
    GeometryImageSettings gs;
    // The paper's 81 x 81 (growing the grid for a protruding organ takes up to half a minute, during which the session
    // would not step): the build note says how far this one lies from the surface instead.
    gs.maxSize = gs.size;
    gs.progress = s.buildProgress;  // (the GUI's progress dialog with its Cancel)
    auto image = makeGeometryImage(points, surface, gs, why);
    if (!image) throw MeshError("The FFD model cannot be built: " + why);
    FfdSettings fs;
    fs.youngModulus = s.material.young;
    fs.poisson = s.material.poisson;
    if (s.tools.toolRadius > 0) fs.toolRadius = s.tools.toolRadius;
    mesh_ = std::make_unique<ParameterizedMesh>(std::move(*image), fs);
    // Each node's nearest grid point and the Gaussian weight of its distance to it (about 1 on the surface, less
    // inside: the deformation fades into the volume as it does along the surface).
    const auto& grid = mesh_->image().points;
    bound_.assign(model_.nodeCount(), 0);
    boundWeight_.assign(model_.nodeCount(), 0);
    for (std::size_t v = 0; v < model_.nodeCount(); ++v) {
      const Eigen::Vector3d p = base_.segment<3>(3 * static_cast<Eigen::Index>(v));
      double best = std::numeric_limits<double>::infinity();
      for (std::size_t g = 0; g < grid.size(); ++g)
        if (const double d = (grid[g] - p).squaredNorm(); d < best) best = d, bound_[v] = static_cast<int>(g);
      boundWeight_[v] = mesh_->weight(std::sqrt(best));
    }
    buildSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count();
    u0_.setZero(base_.size());  // (it starts at rest: the surface as built)
  }
  StepReport step(SimulationState& state) override {
    StepReport rep = StaticBody::step(state);
    if (!rep.ok) return rep;
    // Never "converged": the deformation is geometric. Said with how far the holds are from the instruments' aim.
    const bool inverted = rep.outcome == StepStatus::Inverted;
    rep.outcome = inverted ? StepStatus::Inverted : StepStatus::Inexact;
    char said[400];
    std::snprintf(
        said, sizeof said,
        "%s: the FFD model's deformation is geometric (no equilibrium); the instruments' constraints are met "
        "within %.1f mm%s%s",
        inverted ? "inverted" : "inexact", 1e3 * rep.constraintViolation,
        contact_.clamped ? "; the tool went past the largest displacement (20 mm): the surface stopped there" : "",
        inverted ? ("; " + std::to_string(rep.invertedElements) +
                    (rep.invertedElements == 1 ? " element" : " elements") + " inside out")
                       .c_str()
                 : "");
    rep.status = said;
    return rep;
  }
  Eigen::Vector3d toolForce(bool) const override { return force_; }
  Eigen::Matrix3d toolStiffness() const override {
    // Hertz's law along the displacement: dF/dd = 2 sqrt(r) E* sqrt(d).
    // (Past the largest displacement the surface stops: the force no longer changes.)
    if (!contact_.touching || !(contact_.depth > 0) || contact_.clamped) return Eigen::Matrix3d::Zero();
    const FfdSettings& f = mesh_->settings();
    const double k =
        2 * std::sqrt(f.toolRadius) * rigidToolModulus(f.youngModulus, f.poisson) * std::sqrt(contact_.depth);
    const Eigen::Vector3d n = force_.normalized();
    return k * n * n.transpose();
  }
  Eigen::Vector3d appliedForce(const std::vector<int>& nodes, const SimulationState&, const Eigen::VectorXd&,
                               double) const override {
    // The tool's force spread evenly over the nodes it acts on (the model has no nodal forces of its own).
    if (acting_.empty()) return Eigen::Vector3d::Zero();
    std::size_t in = 0;
    for (int v : acting_) in += std::find(nodes.begin(), nodes.end(), v) != nodes.end();
    return force_ * (static_cast<double>(in) / static_cast<double>(acting_.size()));
  }
  std::string buildNote() const override {
    const GeometryImage& im = mesh_->image();
    char said[480];
    std::snprintf(
        said, sizeof said,
        "The FFD model: the surface on a %d x %d geometry image (%s map, %d seam edges; it lies %.1f mm = %.1f %% "
        "of the organ's size from the surface), deformed within %.0f mm of the instrument, built in %.1f s.",
        im.size, im.size, surfaceMapName(im.map), im.seamEdges, 1e3 * im.hausdorff,
        im.extent > 0 ? 100 * im.hausdorff / im.extent : 0.0, 1e3 * mesh_->settings().radius, buildSeconds_);
    return said;
  }

 private:
  bool solveRows(Eigen::VectorXd& u, std::string& why) override {
    lambda_.setZero(static_cast<Eigen::Index>(rows_.size()));
    W_.resize(0, 0);
    acting_.clear();
    // The holds: each held node's target from its bilateral rows (three directions: solved; fewer: along them).
    std::map<int, std::pair<Eigen::Matrix3d, Eigen::Vector3d>> held;
    for (const auto& r : rows_) {
      if (r.unilateral) continue;
      int nodes = 0, v = -1;
      double w = 0;
      for (int k = 0; k < 4; ++k)
        if (r.nodes[static_cast<std::size_t>(k)] >= 0 && r.weights[static_cast<std::size_t>(k)] != 0)
          ++nodes, v = r.nodes[static_cast<std::size_t>(k)], w = r.weights[static_cast<std::size_t>(k)];
      if (nodes != 1) {
        why = "the FFD model holds single nodes only (a clip joins two: choose the FEM or the hybrid model)";
        return false;
      }
      auto& [A, b] = held.try_emplace(v, Eigen::Matrix3d::Zero(), Eigen::Vector3d::Zero()).first->second;
      A += w * w * r.direction * r.direction.transpose();
      b += w * r.value * r.direction;
    }
    Eigen::Vector3d from = Eigen::Vector3d::Zero(), to = Eigen::Vector3d::Zero();
    int count = 0;
    for (const auto& [v, Ab] : held) {
      const Eigen::Vector3d rest = base_.segment<3>(3 * v);
      // Along the rows' directions the target, across them the shape at t = 0: rest + A^+ (b - A rest).
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(Ab.first);
      const Eigen::Vector3d r = es.eigenvectors().transpose() * (Ab.second - Ab.first * rest);
      Eigen::Vector3d step = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k)
        if (es.eigenvalues()(k) > 1e-12 * es.eigenvalues().cwiseAbs().maxCoeff())
          step += es.eigenvectors().col(k) * (r(k) / es.eigenvalues()(k));
      const Eigen::Vector3d target = rest + step;
      from += rest, to += target, ++count;
      acting_.push_back(v);
    }
    if (count > 0) {
      from /= count, to /= count;
      contact_ = mesh_->hold(mesh_->nearestVertex(from), to - from);
    } else {
      // The deepest contact row, as a poke of its heaviest node (the instrument pushes there).
      double deepest = 0;
      const ScalarConstraint* at = nullptr;
      for (const auto& r : rows_) {
        if (!r.unilateral) continue;
        const double g = constraintValue(r, base_);
        if (r.value - g > deepest) deepest = r.value - g, at = &r;
      }
      if (at) {
        int v = -1;
        double heaviest = 0;
        for (int k = 0; k < 4; ++k)
          if (at->nodes[static_cast<std::size_t>(k)] >= 0 &&
              std::abs(at->weights[static_cast<std::size_t>(k)]) > heaviest)
            heaviest = std::abs(at->weights[static_cast<std::size_t>(k)]), v = at->nodes[static_cast<std::size_t>(k)];
        acting_.push_back(v);
        contact_ = mesh_->hold(mesh_->nearestVertex(base_.segment<3>(3 * v)), deepest * at->direction);
      } else {
        mesh_->release();
        contact_ = {};
      }
    }
    force_ = -contact_.force;  // the tool's on the tissue
    const auto& x = mesh_->positions();
    const auto& x0 = mesh_->image().points;
    u.setZero(base_.size());
    for (std::size_t v = 0; v < bound_.size(); ++v) {
      const auto g = static_cast<std::size_t>(bound_[v]);
      if (boundWeight_[v] > 0 && !fixed_[v])
        u.segment<3>(3 * static_cast<Eigen::Index>(v)) = boundWeight_[v] * (x[g] - x0[g]);
    }
    return true;
  }

  std::unique_ptr<ParameterizedMesh> mesh_;
  std::vector<int> bound_;
  std::vector<double> boundWeight_;
  double buildSeconds_ = 0;
  ParameterizedMesh::Contact contact_;
  Eigen::Vector3d force_ = Eigen::Vector3d::Zero();
  std::vector<int> acting_;
};

}  // namespace

std::unique_ptr<DeformableBody> makeFfdBody(const BodySetup& setup) { return std::make_unique<FfdBody>(setup); }

}  // namespace rehearse::simcore
