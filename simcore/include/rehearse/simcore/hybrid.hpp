#pragma once
// The hybrid model's core (Cotin, Delingette and Ayache, The Visual Computer 2000; issue 37): the organ split into a
// region simulated by the FEM (where the instrument works and a cut may go: its elements can change) and the rest,
// represented by its precomputed responses to forces at the nodes the two parts share (the interface). Static and
// linear (the linear law's stiffness at rest), it is exactly the whole organ's linear static solution:
//
//   the rest's equilibrium with the interface force lambda acting on it:  K_P u_P = f_P + lambda  =>
//     u_P = u_P^g + C_PG lambda   (C = K_P^-1's columns at the interface, u^g its sag under its own weight),
//   at the interface u_G = u_G^g + C_GG lambda  =>  lambda = S (u_G - u_G^g),  S = C_GG^-1 (dense, interface-sized),
//   the region's:  K_R u_R + S u_G = f_R + S u_G^g + f_tool   (the rest's stiffness condensed onto the interface),
//
// so a step solves the region's system alone (its own elements plus the dense interface block) and the rest follows by
// superposition of the precomputed responses. Gravity is split without overlap: the rest carries its own nodes'
// weight, the region every node it touches (the equations are linear: any split of the load gives the same answer).
// What the region's elements become (a cut) changes only K_R; the responses of the rest stay valid while the cut stays
// inside the region (not built yet: the region's re-meshing by a cut, and its growth, are the next part).
#include <rehearse/simcore/constraint_solver.hpp>
#include <rehearse/simcore/fem.hpp>

#include <Eigen/Core>

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::simcore {

class HybridElasticity {
 public:
  /// Splits `model` (its stiffness at rest: the linear law's) into the elements marked in `region` (1: the FEM part)
  /// and the rest, with `fixed` nodes (1) held, and precomputes the rest's responses at the interface and its sag under
  /// `gravity`. A piece of the rest that no attachment holds joins the region (absorbedElements). With `previous` (the
  /// same organ before its region changed: a cut), the rest's responses are kept when the rest is unchanged. Nothing,
  /// with a sentence in `why`, when the region is empty or is every element, the rest is not held by a fixed node (a
  /// free part has no static response), or a stiffness is singular.
  static std::optional<HybridElasticity> build(const FemModel& model, const std::vector<char>& fixed,
                                               const std::vector<char>& region, const Eigen::Vector3d& gravity,
                                               std::string& why, const HybridElasticity* previous = nullptr);
  /// Whether build() kept `previous`'s responses of the rest (its elements, nodes and interface unchanged: a cut, and
  /// the region's growth with it, stayed away from the rest); otherwise they were computed again.
  bool reusedRest() const { return reused_; }
  /// Pieces of the organ no attachment holds (cut off): a static model cannot let them fall, so they are held where
  /// they are at rest (their nodes fixed: fixedNodes()). 0 normally.
  std::size_t freePieces() const { return freePieces_; }
  /// The nodes held: the attachments and the free pieces' nodes (1).
  const std::vector<char>& fixedNodes() const;
  HybridElasticity(HybridElasticity&&) noexcept;
  HybridElasticity& operator=(HybridElasticity&&) noexcept;
  ~HybridElasticity();

  std::size_t regionNodes() const { return regionNodes_.size(); }
  std::size_t interfaceNodes() const { return interface_.size(); }
  std::size_t restNodes() const { return restNodes_.size(); }
  /// Elements of the rest that joined the region because no attachment held their piece of the rest.
  std::size_t absorbedElements() const { return absorbed_; }
  /// Bytes held by the rest's responses (3 rest nodes x 3 interface numbers) and the condensed block.
  std::size_t memoryBytes() const;
  /// Whether a node belongs to the region (an instrument may hold it).
  bool inRegion(int node) const;

  /// The static displacement u (3n, m, from rest) with node held[k] (each in the region, not fixed, no repeats)
  /// displaced by displacement[k] from rest, under gravity; `forces` (optional): the instrument's force on the tissue
  /// at each held node (N). False, with `why`, when a held node is outside the region, fixed or repeated.
  bool solve(const std::vector<int>& held, const std::vector<Eigen::Vector3d>& displacement, Eigen::VectorXd& u,
             std::vector<Eigen::Vector3d>* forces, std::string& why) const;

  /// The static displacement u (3n, m, from `base`) under the instruments' constraint rows (bilateral holds, unilateral
  /// contacts, clips: PrecomputedElasticity::solveConstraints's contract), their multipliers `lambda` (N) and the rows'
  /// compliance `W` (m/N, optional): one solve of the region's system per row (its factorisation kept), an active set
  /// on W (settleRows), the rest by its responses. `withSag`: base is the rest shape and the organ's sag under gravity
  /// is added; otherwise base is already the equilibrium (the registered shape) and only the instruments' share is.
  /// False, with `why`, when a row's free node is outside the region or the rows contradict one another.
  bool solveRows(const std::vector<ScalarConstraint>& rows, const Eigen::VectorXd& base, bool withSag,
                 Eigen::VectorXd& u, Eigen::VectorXd& lambda, Eigen::MatrixXd* W, std::string& why) const;

 private:
  HybridElasticity();
  bool factorFor(const std::vector<int>& held, std::string& why) const;  ///< the region's factor for these held nodes
  void expand(const Eigen::VectorXd& uR, Eigen::VectorXd& u) const;      ///< the region's solution -> the whole organ
  struct Parts;
  std::unique_ptr<Parts> p_;
  std::vector<int> regionNodes_, interface_, restNodes_;
  std::size_t absorbed_ = 0;
  bool reused_ = false;
  std::size_t freePieces_ = 0;
};

}  // namespace rehearse::simcore
