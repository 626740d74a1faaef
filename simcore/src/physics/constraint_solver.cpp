#include <rehearse/simcore/constraint_solver.hpp>

#include <rehearse/simcore/mesh.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace rehearse::simcore {
namespace {
// H's row of one constraint applied to a 3n vector (or a column view: no temporary).
template <typename Vec>
double applyRow(const ScalarConstraint& c, const Vec& v) {
  double out = 0;
  for (int k = 0; k < 4; ++k)
    if (c.nodes[k] >= 0) out += c.weights[k] * c.direction.dot(v.template segment<3>(3 * c.nodes[k]));
  return out;
}
}  // namespace

double constraintValue(const ScalarConstraint& c, const Eigen::VectorXd& x) { return applyRow(c, x); }

Eigen::Vector3d toolForceOf(const std::vector<ScalarConstraint>& c, const Eigen::VectorXd& lambda, bool holdsOnly) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  if (lambda.size() < static_cast<Eigen::Index>(c.size())) return sum;
  const Eigen::Index first = lambda.size() - static_cast<Eigen::Index>(c.size());
  // A constraint's force on the body is its multiplier along its direction, spread over its nodes by its weights (a
  // triangle's barycentric ones sum to 1).
  for (std::size_t k = 0; k < c.size(); ++k) {
    if (holdsOnly && c[k].unilateral) continue;
    const double spread = c[k].weights[0] + c[k].weights[1] + c[k].weights[2] + c[k].weights[3];
    sum += lambda[first + static_cast<Eigen::Index>(k)] * spread * c[k].direction;
  }
  return sum;
}

void validateConstraint(const ScalarConstraint& c, std::size_t nodes) {
  bool any = false;
  for (int k = 0; k < 4; ++k) {
    if (c.nodes[k] < 0) continue;
    if (c.nodes[k] >= static_cast<int>(nodes))
      throw MeshError("A constraint refers to node " + std::to_string(c.nodes[k]) +
                      ", which does not exist (the mesh has " + std::to_string(nodes) + " nodes).");
    any = true;
  }
  if (!any || !c.direction.allFinite() || c.direction.norm() == 0 || !std::isfinite(c.value))
    throw MeshError("A constraint has no node, a zero or non-finite direction, or a non-finite value.");
}

void ConstraintSolver::setConstraints(std::vector<ScalarConstraint> constraints, const std::vector<char>& fixed) {
  for (const auto& c : constraints) validateConstraint(c, fixed.size());
  // H (hence A^-1 H^T and W) depends on the rows' nodes, weights and directions and on the fixed nodes, not on the
  // values: a grasp pulled along keeps its W (a multi-column solve per step saved, 14 % of a chord step's time on
  // the patient liver at 16k tets).
  const auto sameRow = [](const ScalarConstraint& a, const ScalarConstraint& b) {
    return a.nodes == b.nodes && a.weights == b.weights && a.direction == b.direction && a.unilateral == b.unilateral;
  };
  const bool sameRows = constraints.size() == constraints_.size() && fixed == fixed_ &&
                        std::equal(constraints.begin(), constraints.end(), constraints_.begin(), sameRow);
  constraints_ = std::move(constraints);
  if (!sameRows) {
    fixed_ = fixed;
    schurValid_ = false;
  }
}

double ConstraintSolver::violation(const Eigen::VectorXd& x) const {
  double worst = 0;
  for (const auto& c : constraints_) {
    const double g = applyRow(c, x) - c.value;
    worst = std::max(worst, c.unilateral ? std::max(0.0, -g) : std::abs(g));
  }
  return worst;
}

bool ConstraintSolver::fixActiveSet() {
  const Eigen::Index m = size();
  if (!schurValid_ || W_.rows() != m || lambda_.size() != m) return false;
  fixedSet_.clear();
  if (fixedSet_.capacity() < static_cast<std::size_t>(m)) fixedSet_.reserve(static_cast<std::size_t>(m));
  for (Eigen::Index i = 0; i < m; ++i)
    if (!constraints_[static_cast<std::size_t>(i)].unilateral || lambda_[i] > 0) fixedSet_.push_back(i);
  const auto k = static_cast<Eigen::Index>(fixedSet_.size());
  if (fixedW_.rows() != k) fixedW_.resize(k, k);
  for (Eigen::Index i = 0; i < k; ++i)
    for (Eigen::Index j = 0; j < k; ++j)
      fixedW_(i, j) = W_(fixedSet_[static_cast<std::size_t>(i)], fixedSet_[static_cast<std::size_t>(j)]);
  if (k > 0) fixedFactor_.compute(fixedW_);  // pivoted: redundant constraints leave zero pivots, their y zero
  if (fixedT_.size() != k) fixedT_.resize(k);
  if (fixedY_.size() != k) fixedY_.resize(k);
  return true;
}

bool ConstraintSolver::projectedSolve(CholmodSolver& factor, const Eigen::VectorXd& r, Eigen::VectorXd& z,
                                      Eigen::VectorXd& y) {
  const Eigen::Index m = size();
  if (y.size() != m) y.resize(m);
  y.setZero();
  if (!factor.solve(r, z)) return false;
  const auto k = static_cast<Eigen::Index>(fixedSet_.size());
  if (m == 0 || k == 0) return z.allFinite();
  if (A_.rows() != r.size() || fixedT_.size() != k) return false;
  for (Eigen::Index i = 0; i < k; ++i)
    fixedT_[i] = A_.col(fixedSet_[static_cast<std::size_t>(i)]).dot(r);  // H_a A^-1 r
  fixedY_ = fixedFactor_.solve(fixedT_);
  for (Eigen::Index i = 0; i < k; ++i) {
    const Eigen::Index c = fixedSet_[static_cast<std::size_t>(i)];
    y[c] = fixedY_[i];
    z.noalias() -= fixedY_[i] * A_.col(c);
  }
  return z.allFinite() && y.allFinite();
}

bool NodeCompliance::prepare(CholmodSolver& factor, const std::vector<ScalarConstraint>& rows,
                             const std::vector<char>& fixed) {
  rowNodes_.clear();
  for (const auto& c : rows)
    for (int node : c.nodes)
      if (node >= 0) rowNodes_.push_back(node);
  return prepare(factor, rowNodes_, fixed);
}

bool NodeCompliance::prepare(CholmodSolver& factor, const std::vector<int>& want, const std::vector<char>& fixed) {
  const std::size_t nodes = fixed.size();
  const auto n3 = static_cast<Eigen::Index>(3 * nodes);
  if (factor_ != &factor || factorisations_ != factor.factorisations() || slotOf_.size() != nodes ||
      cols_.rows() != n3) {
    slotOf_.assign(nodes, -1);
    slotNodes_.clear();
    factor_ = &factor;
    factorisations_ = factor.factorisations();
  }
  auto wanted = [&](int node) {
    return node >= 0 && static_cast<std::size_t>(node) < nodes && !fixed[static_cast<std::size_t>(node)];
  };
  const auto capacity = std::max<std::size_t>(16, (24u << 20) / (sizeof(double) * 9 * std::max<std::size_t>(nodes, 1)));
  std::size_t missing = 0;  // an upper bound (a node in two rows counts twice)
  for (int node : want) missing += wanted(node) && slotOf_[static_cast<std::size_t>(node)] < 0;
  if (slotNodes_.size() + missing > capacity) {
    for (int node : slotNodes_) slotOf_[static_cast<std::size_t>(node)] = -1;
    slotNodes_.clear();
  }
  // The missing nodes get their slots first, then their blocks are solved together (each alone: solveUnitBlocks).
  newNodes_.clear();
  newSlots_.clear();
  for (int node : want) {
    if (!wanted(node) || slotOf_[static_cast<std::size_t>(node)] >= 0) continue;
    const auto slot = static_cast<int>(slotNodes_.size());
    slotOf_[static_cast<std::size_t>(node)] = slot;
    slotNodes_.push_back(node);
    newNodes_.push_back(node);
    newSlots_.push_back(slot);
  }
  if (newNodes_.empty()) return true;
  const auto needed = 3 * static_cast<Eigen::Index>(slotNodes_.size());
  if (cols_.rows() != n3 || cols_.cols() < needed) {
    // Grown by doubling (it allocates only then), up to the bound; rows on more nodes than the bound still get a
    // block each (the bound only decides when to start again).
    const Eigen::Index cols =
        std::max<Eigen::Index>(needed, std::min<Eigen::Index>(3 * static_cast<Eigen::Index>(capacity), 2 * cols_.cols()));
    if (cols_.rows() != n3)
      cols_.resize(n3, std::max<Eigen::Index>(cols, 24));
    else
      cols_.conservativeResize(Eigen::NoChange, cols);
  }
  if (factor.solveUnitBlocks(newNodes_.data(), newSlots_.data(), newNodes_.size(), cols_)) return true;
  for (int node : newNodes_) slotOf_[static_cast<std::size_t>(node)] = -1;  // not solved: not kept
  slotNodes_.resize(slotNodes_.size() - newNodes_.size());
  return false;
}

bool ConstraintSolver::solve(CholmodSolver& factor, const Eigen::VectorXd& x, double s, Eigen::VectorXd& dx,
                             int& sweeps, const Eigen::VectorXd* carried) {
  const Eigen::Index m = size();
  if (m == 0) return true;
  const Eigen::Index n3 = dx.size();
  if (!schurValid_ || W_.rows() != m || Ht_.rows() != n3 || schurFactor_ != &factor ||
      schurFactorisations_ != factor.factorisations() || schurDirect_ != directColumns) {
    if (Ht_.rows() != n3 || Ht_.cols() != m) Ht_.resize(n3, m);
    if (A_.rows() != n3 || A_.cols() != m) A_.resize(n3, m);
    Ht_.setZero();
    A_.setZero();
    for (Eigen::Index i = 0; i < m; ++i) {
      const auto& c = constraints_[static_cast<std::size_t>(i)];
      for (int k = 0; k < 4; ++k) {
        const int node = c.nodes[k];
        if (node < 0 || fixed_[static_cast<std::size_t>(node)]) continue;
        Ht_.col(i).segment<3>(3 * node) += c.weights[k] * c.direction;
      }
    }
    if (directColumns) {
      // A^-1 H^T in one solve of H^T's m columns (see directColumns).
      if (!factor.solve(Ht_, A_)) return false;
    } else {
      // A^-1 H^T by columns from the nodes' compliance blocks A^-1 [e_x e_y e_z] (each solved once per factor, alone:
      // the same bits whenever it is solved): a contact row that slides over the same triangles, or a grasp row whose
      // value changes, needs no new solve. A multi-column solve per step and contact set was most of a touching
      // step's time (57 % of the samples on BodyParts3D's liver at 17k tets; issue 34).
      if (!compliance_.prepare(factor, constraints_, fixed_)) return false;
      for (Eigen::Index i = 0; i < m; ++i) {
        const auto& c = constraints_[static_cast<std::size_t>(i)];
        for (int k = 0; k < 4; ++k) {
          const int node = c.nodes[k];
          if (node < 0 || fixed_[static_cast<std::size_t>(node)]) continue;
          A_.col(i).noalias() += compliance_.block(node) * (c.weights[k] * c.direction);
        }
      }
    }
    if (W_.rows() != m) W_.resize(m, m);
    for (Eigen::Index i = 0; i < m; ++i)
      for (Eigen::Index j = 0; j < m; ++j) W_(i, j) = applyRow(constraints_[static_cast<std::size_t>(i)], A_.col(j));
    for (Eigen::Index i = 0; i < m; ++i)  // symmetric up to round-off: made exactly so, in place
      for (Eigen::Index j = i + 1; j < m; ++j) W_(i, j) = W_(j, i) = 0.5 * (W_(i, j) + W_(j, i));
    schurValid_ = true;
    schurDirect_ = directColumns;
    schurFactor_ = &factor;
    schurFactorisations_ = factor.factorisations();
    WfactorValid_ = false;
  }
  if (e_.size() != m) e_.resize(m);
  if (Wlambda_.size() != m) Wlambda_.resize(m);
  if (lambda_.size() != m || !lambda_.allFinite()) lambda_.setZero(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const auto& c = constraints_[static_cast<std::size_t>(i)];
    e_[i] = (c.value - applyRow(c, x)) / s - applyRow(c, dx);
  }
  const bool carry = carried && carried->size() == m;
  if (carry) e_.noalias() += W_ * *carried;
  // Projected Gauss-Seidel, warm-started from the previous multipliers. An ill-conditioned W (many
  // close attachments on a body with nothing else holding it) can stall it: bilateral constraints then
  // take a dense LDL^T of W (m x m, small), unilateral ones keep the best Gauss-Seidel iterate.
  int sweep = 0;
  bool converged = false, unilateral = false, triedActiveSet = false;
  activeSetIterations_ = 0;
  for (const auto& c : constraints_) unilateral |= c.unilateral;
  for (; sweep < gaussSeidelIterations; ++sweep) {
    if (unilateral && !triedActiveSet && sweep == activeSetAfterSweeps) {
      triedActiveSet = true;
      if (activeSet()) {
        converged = true;
        break;
      }
    }
    double change = 0, size = 0;
    for (Eigen::Index i = 0; i < m; ++i) {
      const double d = W_(i, i);
      if (!(d > 0)) continue;
      double li = lambda_[i] + (e_[i] - W_.row(i).dot(lambda_)) / d;
      if (constraints_[static_cast<std::size_t>(i)].unilateral) li = std::max(0.0, li);
      change = std::max(change, std::abs(li - lambda_[i]));
      size = std::max(size, std::abs(li));
      lambda_[i] = li;
    }
    if (!std::isfinite(change)) return false;
    if (change <= gaussSeidelTolerance * std::max(size, 1e-300)) {
      ++sweep;
      converged = true;
      break;
    }
  }
  sweeps += sweep;
  // Converged by its step size is not converged by its residual when W is ill-conditioned.
  if (converged && !unilateral) {
    Wlambda_.noalias() = W_ * lambda_;  // sized once: no temporary
    Wlambda_ -= e_;
    converged =
        Wlambda_.norm() <= 1e-12 * std::max(e_.norm(), 1e-300) *
                               std::max(1.0, W_.diagonal().maxCoeff() / std::max(W_.diagonal().minCoeff(), 1e-300));
  }
  if (!converged && !unilateral) {
    // Rank-deficient W (redundant constraints) is fine here: the pivoted LDL^T leaves the multipliers of
    // zero pivots at zero. Factorised once per W (the lagged methods keep W for many iterations).
    if (!WfactorValid_) {
      Wfactor_.compute(W_);
      WfactorValid_ = true;
    }
    lambda_ = Wfactor_.solve(e_);
    if (!lambda_.allFinite()) return false;
  }
  dx.noalias() += A_ * lambda_;
  if (carry) dx.noalias() -= A_ * *carried;
  return dx.allFinite();
}

// The linear complementarity problem W lambda - e = w, lambda_u >= 0, w_u >= 0, lambda_u w_u = 0 (w = 0 for
// bilateral rows) by an active set: the active rows (bilateral, and unilateral ones pushing) solved exactly
// with a dense LDL^T of their block; unilateral rows whose multiplier came out negative leave the set, then
// rows that the solution violates join it. Starts from Gauss-Seidel's iterate (its positive multipliers), so a
// few iterations suffice. True with lambda_ set when no row changed; false (lambda_ untouched) otherwise.
bool ConstraintSolver::activeSet() {
  const Eigen::Index m = size();
  active_.assign(static_cast<std::size_t>(m), 0);
  for (Eigen::Index i = 0; i < m; ++i)
    active_[static_cast<std::size_t>(i)] = !constraints_[static_cast<std::size_t>(i)].unilateral || lambda_[i] > 0;
  const double scale = std::max(e_.cwiseAbs().maxCoeff(), 1e-300);
  const double tolerance = 1e-10 * scale;
  if (candidate_.size() != m) candidate_.resize(m);
  for (int it = 0; it < 4 + static_cast<int>(m); ++it) {
    ++activeSetIterations_;
    activeIndex_.clear();
    for (Eigen::Index i = 0; i < m; ++i)
      if (active_[static_cast<std::size_t>(i)] && W_(i, i) > 0) activeIndex_.push_back(i);
    const auto k = static_cast<Eigen::Index>(activeIndex_.size());
    candidate_.setZero();
    if (k > 0) {
      Wa_.resize(k, k);
      ea_.resize(k);
      for (Eigen::Index a = 0; a < k; ++a) {
        ea_[a] = e_[activeIndex_[static_cast<std::size_t>(a)]];
        for (Eigen::Index b = 0; b < k; ++b)
          Wa_(a, b) = W_(activeIndex_[static_cast<std::size_t>(a)], activeIndex_[static_cast<std::size_t>(b)]);
      }
      WaFactor_.compute(Wa_);
      la_ = WaFactor_.solve(ea_);
      if (!la_.allFinite()) return false;
      for (Eigen::Index a = 0; a < k; ++a) candidate_[activeIndex_[static_cast<std::size_t>(a)]] = la_[a];
    }
    bool changed = false;
    for (Eigen::Index a = 0; a < k; ++a) {  // pulling contacts leave first
      const Eigen::Index i = activeIndex_[static_cast<std::size_t>(a)];
      if (constraints_[static_cast<std::size_t>(i)].unilateral && candidate_[i] < 0) {
        active_[static_cast<std::size_t>(i)] = 0;
        changed = true;
      }
    }
    if (!changed) {
      for (Eigen::Index i = 0; i < m; ++i) {
        if (active_[static_cast<std::size_t>(i)] || !(W_(i, i) > 0)) continue;
        if (e_[i] - W_.row(i).dot(candidate_) > tolerance) {  // a contact the solution pushes into: it joins
          active_[static_cast<std::size_t>(i)] = 1;
          changed = true;
        }
      }
    }
    if (!changed) {
      lambda_ = candidate_;
      return true;
    }
  }
  return false;
}

}  // namespace rehearse::simcore
