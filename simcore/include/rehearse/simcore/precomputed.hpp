#pragma once
// Precomputed linear elasticity (Cotin, Delingette and Ayache, IEEE TVCG 1999): the organ's static response to a
// unit load at each node an instrument can touch, computed once from the linear FEM's factorised stiffness, then
// every deformation and every tool force by superposition, fast enough for a haptic loop.
//
// With K the linear stiffness at rest (fixed nodes removed), the compliance column block C_:j = K^-1 e_j is the
// displacement of every node under a unit force at driven node j (3 columns: x, y, z), and u_g = K^-1 M g the sag
// under gravity. Displacements d imposed at driven nodes J (an instrument holding them):
//   C_JJ lambda = d - u_g[J],   u = u_g + C_:J lambda,   lambda: the instrument's force on the tissue at J (N),
// the exact linear static solution with every node of J held at once (the paper's correction for several
// simultaneous constraints, solved here as the small dense system C_JJ rather than iterated). Cost online:
// 3|J| x 3|J| once per change of J, then 3n x 3|J| per update; memory 9 x driven nodes x nodes numbers (stated by
// memoryBytes(); single precision halves it at the cost of about 1e-7 relative). Bounded further by keeping the
// responses at the driven nodes only (9 x driven^2 numbers, PrecomputeSettings::drivenRowsOnly): the instruments'
// forces and the surface's response come from them as before, the whole organ's displacement from the factorisation
// kept beside them (one back-solve, u = u_g + K^-1 F, exact to round-off).
//
// Linear elasticity: small strains, rotations not separated (a large rotation inflates the organ); the response is
// exact for that model only. A cut changes K: the precomputed responses no longer hold (the hybrid model's region).
#include <rehearse/simcore/constraint_solver.hpp>
#include <rehearse/simcore/fem.hpp>

#include <Eigen/Core>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::simcore {

struct PrecomputeSettings {
  bool singlePrecision = false;  ///< store the responses as float (half the memory, ~1e-7 relative)
  /// Store the responses at the driven nodes only (9 x driven^2 numbers instead of 9 x driven x nodes) and keep the
  /// factorisation for the inner nodes' displacement (a back-solve per update).
  bool drivenRowsOnly = false;
  int batch = 96;                ///< right-hand sides solved together (columns)
  /// The responses' memory allowed (bytes): a mesh whose 9 x driven x nodes numbers would take more is refused with a
  /// sentence instead of exhausting the machine (4 GB: a 20k-element organ's responses in single precision).
  std::size_t maxBytes = std::size_t(4) << 30;
  /// Called after each batch with the share done (0..1); false cancels (build then returns nothing, said).
  std::function<bool(double)> progress;
};

/// The multipliers (N) of a static model's constraint rows: W lambda = e on the rows that act, W (m/N) the rows'
/// compliance, e = value - G x0 (m) their gaps at the unconstrained answer. Bilateral rows always act, a unilateral
/// one while it pushes (lambda >= 0; where it does not, W lambda >= e): an active set on the dense W (the precomputed
/// and hybrid models'). False, with `why`, when the rows contradict one another or the set cycles.
bool settleRows(const std::vector<ScalarConstraint>& rows, const Eigen::MatrixXd& W, const Eigen::VectorXd& e,
                Eigen::VectorXd& lambda, std::string& why);

class PrecomputedElasticity {
 public:
  /// Builds the responses of `model`'s stiffness at rest (K = d^2E/dx^2 at the rest shape: the linear FEM's; the
  /// co-rotational law's is the same there, test_precomputed) with `fixed` nodes held (1: fixed) to unit forces at
  /// each of `driven` nodes (the surface nodes instruments touch, typically), and the sag under `gravity` (m/s^2) from
  /// the lumped masses. Nothing, with a sentence in `why`, when the stiffness is singular (no fixed node: a free body
  /// has no static response), a driven node is fixed or out of range, or the build was cancelled.
  static std::optional<PrecomputedElasticity> build(const FemModel& model, const std::vector<char>& fixed,
                                                    const std::vector<int>& driven, const Eigen::Vector3d& gravity,
                                                    const PrecomputeSettings& settings, std::string& why);

  std::size_t nodeCount() const { return nodes_; }
  bool drivenRowsOnly() const { return drivenOnly_; }
  bool singlePrecision() const { return single_; }
  const std::vector<int>& driven() const { return driven_; }
  /// The driven index of a node (-1 when it is not driven).
  int drivenIndex(int node) const;
  /// Bytes held by the responses (9 x driven x nodes numbers) and the sag.
  std::size_t memoryBytes() const;
  /// The sag under gravity alone (3n, m).
  const Eigen::VectorXd& sag() const { return sag_; }
  /// The 3x3 block of the compliance: the displacement of node i per unit force at driven index j (m/N); with driven
  /// rows only, node i must be driven too (zero otherwise).
  Eigen::Matrix3d response(int node, int drivenIdx) const;

  /// The responses as bytes (for the case file's cache; the factorisation of driven-rows-only responses is not in
  /// them), and back: nothing, with `why`, when the bytes are not such responses or not `model`'s (node count);
  /// driven-rows-only responses factorise `model`'s stiffness again.
  std::string toBytes() const;
  static std::optional<PrecomputedElasticity> fromBytes(const std::string& bytes, const FemModel& model,
                                                        std::string& why);

  /// The static displacement u (3n, m, from rest) with node held[k] displaced by displacement[k] from rest (each a
  /// driven node, no repeats) under gravity; `forces` (optional): the instrument's force on the tissue at each held
  /// node (N). False, with `why`, when a node is not driven or repeated.
  bool solve(const std::vector<int>& held, const std::vector<Eigen::Vector3d>& displacement, Eigen::VectorXd& u,
             std::vector<Eigen::Vector3d>* forces, std::string& why) const;

  /// The static displacement u (3n, from `base`: the rest shape with the sag, or the registered shape that is the
  /// equilibrium) under the instruments' constraints (ScalarConstraint rows on absolute positions: bilateral holds
  /// and unilateral contacts, each node of them driven or fixed), their multipliers `lambda` (N, along each row's
  /// direction; >= 0 for the unilateral ones, complementary to their gap): W lambda = value - G (base + u0) with W =
  /// G C G^T solved by an active set on the dense W (the small system of the rows), u = u0 + C G^T lambda; `u0` the
  /// displacement of `base` itself (the sag, or zero). False, with `why`, when a row's node has no response or the
  /// rows contradict one another.
  bool solveConstraints(const std::vector<ScalarConstraint>& rows, const Eigen::VectorXd& base,
                        const Eigen::VectorXd& u0, Eigen::VectorXd& u, Eigen::VectorXd& lambda, Eigen::MatrixXd* W,
                        std::string& why) const;

  /// The force (N) on the tissue at one held driven node displaced `d` from rest, alone (the haptic loop's update:
  /// f = C_jj^-1 (d - u_g[j])), and the node's stiffness C_jj^-1 (N/m).
  Eigen::Vector3d forceAt(int drivenIdx, const Eigen::Vector3d& d) const;
  Eigen::Matrix3d stiffnessAt(int drivenIdx) const;

 private:
  std::size_t nodes_ = 0;
  std::vector<int> driven_;
  std::vector<int> drivenOf_;  ///< node -> driven index or -1
  // Column-major 3n x 3|driven|: column 3j + a is the displacement under a unit force along axis a at driven j.
  std::vector<double> c64_;
  std::vector<float> c32_;
  bool single_ = false;
  Eigen::VectorXd sag_;
  std::vector<Eigen::Matrix3d> selfStiffness_;  ///< C_jj^-1 per driven node
  std::vector<char> fixed_;
  bool drivenOnly_ = false;
  /// The factorised stiffness (driven rows only: the inner nodes' displacement), shared by copies, one solve at a time.
  struct Factor;
  std::shared_ptr<Factor> factor_;
  std::size_t rows() const { return drivenOnly_ ? 3 * driven_.size() : 3 * nodes_; }
  /// u += C F for forces F (3n) at driven nodes: superposed column by column, or (driven rows only) one back-solve.
  bool displace(const Eigen::VectorXd& F, Eigen::VectorXd& u, std::string& why) const;
  /// u += w * (column 3j + a of C), all rows stored
  void addColumn(std::size_t col, double w, Eigen::VectorXd& u) const;
  double entry(std::size_t row, std::size_t col) const {
    const std::size_t i = col * rows() + row;
    return single_ ? static_cast<double>(c32_[i]) : c64_[i];
  }
  static bool factorise(const FemModel& model, const std::vector<char>& fixed, Factor& f);
};

/// A key for a build's inputs (rest shape, elements, materials, masses, fixed and driven nodes, gravity, storage):
/// equal keys build equal responses.
std::uint64_t precomputeKey(const FemModel& model, const std::vector<char>& fixed, const std::vector<int>& driven,
                            const Eigen::Vector3d& gravity, const PrecomputeSettings& settings);

/// The responses built in this process, by key, so that a session reset, a replay's restore or the same organ opened
/// again does not compute them again; the least recently used go past `limitBytes` (1 GB). Thread-safe. The case
/// file saves the entries its organ uses and puts them back when it opens (ui/casefile).
class ResponseCache {
 public:
  static ResponseCache& shared();
  std::shared_ptr<const PrecomputedElasticity> find(std::uint64_t key);
  void put(std::uint64_t key, std::shared_ptr<const PrecomputedElasticity> responses);
  /// Every entry, most recently used first.
  std::vector<std::pair<std::uint64_t, std::shared_ptr<const PrecomputedElasticity>>> entries() const;
  /// Responses as a case file stored them (PrecomputedElasticity::toBytes), read back by the body that needs them
  /// (it has the model fromBytes checks them against); `stored` says whether bytes are held for a key.
  void offerBytes(std::uint64_t key, std::shared_ptr<const std::string> bytes);
  std::shared_ptr<const std::string> storedBytes(std::uint64_t key) const;
  void clear();
  std::size_t limitBytes = std::size_t(1) << 30;

 private:
  mutable std::mutex mutex_;
  std::vector<std::pair<std::uint64_t, std::shared_ptr<const PrecomputedElasticity>>> entries_;  ///< MRU first
  std::vector<std::pair<std::uint64_t, std::shared_ptr<const std::string>>> bytes_;  ///< the case file's, a few
};

/// The responses for a build's inputs: from the cache, from bytes a case file stored (checked), or built (and put in
/// the cache); `from` says which ("cache", "case file", "built"). Nothing, with `why`, as build().
std::shared_ptr<const PrecomputedElasticity> precomputedFor(const FemModel& model, const std::vector<char>& fixed,
                                                            const std::vector<int>& driven,
                                                            const Eigen::Vector3d& gravity,
                                                            const PrecomputeSettings& settings, std::uint64_t& key,
                                                            std::string& from, std::string& why);

}  // namespace rehearse::simcore
