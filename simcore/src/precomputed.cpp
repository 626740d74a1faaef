// Precomputed linear elasticity: the responses built from one factorisation, and the superposition (precomputed.hpp).
#include <rehearse/simcore/precomputed.hpp>

#include <rehearse/simcore/linear_solver.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cstdio>

namespace rehearse::simcore {

std::optional<PrecomputedElasticity> PrecomputedElasticity::build(const FemModel& model, const std::vector<char>& fixed,
                                                                  const std::vector<int>& driven,
                                                                  const Eigen::Vector3d& gravity,
                                                                  const PrecomputeSettings& settings,
                                                                  std::string& why) {
  const std::size_t n = model.nodeCount();
  if (fixed.size() != n) {
    why = "The fixed-node mask does not match the mesh's nodes.";
    return std::nullopt;
  }
  if (std::find(fixed.begin(), fixed.end(), 1) == fixed.end()) {
    why =
        "Nothing holds the organ (no fixed node): a free body has no static response to precompute; attach it "
        "first.";
    return std::nullopt;
  }
  PrecomputedElasticity p;
  p.nodes_ = n;
  p.driven_ = driven;
  p.drivenOf_.assign(n, -1);
  for (std::size_t j = 0; j < driven.size(); ++j) {
    const int v = driven[j];
    if (v < 0 || static_cast<std::size_t>(v) >= n) {
      why = "Driven node " + std::to_string(v) + " is not a node of the mesh.";
      return std::nullopt;
    }
    if (fixed[static_cast<std::size_t>(v)]) {
      why = "Driven node " + std::to_string(v) + " is fixed: an instrument cannot move an attachment.";
      return std::nullopt;
    }
    if (p.drivenOf_[static_cast<std::size_t>(v)] >= 0) {
      why = "Driven node " + std::to_string(v) + " is listed twice.";
      return std::nullopt;
    }
    p.drivenOf_[static_cast<std::size_t>(v)] = static_cast<int>(j);
  }
  const double bytes = 9.0 * static_cast<double>(driven.size()) * static_cast<double>(n) *
                       (settings.singlePrecision ? sizeof(float) : sizeof(double));
  if (bytes > static_cast<double>(settings.maxBytes)) {
    char said[240];
    std::snprintf(said, sizeof said,
                  "The responses would take %.1f GB (%zu surface nodes x %zu nodes x 9 numbers), over the %.1f GB "
                  "allowed: use single precision or a coarser mesh.",
                  bytes / (1u << 30), driven.size(), n, static_cast<double>(settings.maxBytes) / (1u << 30));
    why = said;
    return std::nullopt;
  }
  // K at rest with the fixed nodes' rows and columns replaced by the identity (their displacement is then zero for
  // any load that is zero there), factorised once.
  Eigen::SparseMatrix<double> K = elasticStiffness(model, model.restVector());
  for (int c = 0; c < K.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it) {
      const bool rowFixed = fixed[static_cast<std::size_t>(it.row() / 3)] != 0;
      const bool colFixed = fixed[static_cast<std::size_t>(it.col() / 3)] != 0;
      if (rowFixed || colFixed) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
    }
  CholmodSolver chol;
  if (!chol.factorise(K)) {
    why =
        "The stiffness is singular with these attachments (a part of the organ is held by nothing, or the material "
        "is degenerate): no static response to precompute.";
    return std::nullopt;
  }
  const Eigen::Index dofs = static_cast<Eigen::Index>(3 * n);
  Eigen::VectorXd fg = Eigen::VectorXd::Zero(dofs);
  for (std::size_t i = 0; i < n; ++i)
    if (!fixed[i])
      fg.segment<3>(3 * static_cast<Eigen::Index>(i)) = model.lumpedMass(static_cast<Eigen::Index>(i)) * gravity;
  if (!chol.solve(fg, p.sag_)) {
    why = "The solve for the sag under gravity failed.";
    return std::nullopt;
  }
  p.single_ = settings.singlePrecision;
  const std::size_t columns = 3 * driven.size();
  (p.single_ ? p.c32_.resize(columns * static_cast<std::size_t>(dofs))
             : p.c64_.resize(columns * static_cast<std::size_t>(dofs)));
  const std::size_t batch = static_cast<std::size_t>(std::max(1, settings.batch));
  Eigen::MatrixXd B, X;
  for (std::size_t c0 = 0; c0 < columns; c0 += batch) {
    const std::size_t nc = std::min(batch, columns - c0);
    B.setZero(dofs, static_cast<Eigen::Index>(nc));
    for (std::size_t c = 0; c < nc; ++c) {
      const std::size_t col = c0 + c;
      B(3 * static_cast<Eigen::Index>(driven[col / 3]) + static_cast<Eigen::Index>(col % 3),
        static_cast<Eigen::Index>(c)) = 1.0;
    }
    if (!chol.solve(B, X)) {
      why = "A solve for the responses failed.";
      return std::nullopt;
    }
    for (std::size_t c = 0; c < nc; ++c) {
      const double* src = X.col(static_cast<Eigen::Index>(c)).data();
      const std::size_t at = (c0 + c) * static_cast<std::size_t>(dofs);
      if (p.single_)
        std::transform(src, src + dofs, p.c32_.begin() + static_cast<std::ptrdiff_t>(at),
                       [](double v) { return static_cast<float>(v); });
      else
        std::copy(src, src + dofs, p.c64_.begin() + static_cast<std::ptrdiff_t>(at));
    }
    if (settings.progress && !settings.progress(static_cast<double>(c0 + nc) / static_cast<double>(columns))) {
      why = "The precomputation was cancelled; the model keeps what it had.";
      return std::nullopt;
    }
  }
  p.fixed_ = fixed;
  p.selfStiffness_.resize(driven.size());
  for (std::size_t j = 0; j < driven.size(); ++j)
    p.selfStiffness_[j] = p.response(driven[j], static_cast<int>(j)).inverse();
  return p;
}

int PrecomputedElasticity::drivenIndex(int node) const {
  return node >= 0 && static_cast<std::size_t>(node) < drivenOf_.size() ? drivenOf_[static_cast<std::size_t>(node)]
                                                                        : -1;
}

std::size_t PrecomputedElasticity::memoryBytes() const {
  return c64_.size() * sizeof(double) + c32_.size() * sizeof(float) +
         static_cast<std::size_t>(sag_.size()) * sizeof(double) + selfStiffness_.size() * sizeof(Eigen::Matrix3d) +
         drivenOf_.size() * sizeof(int) + driven_.size() * sizeof(int);
}

Eigen::Matrix3d PrecomputedElasticity::response(int node, int drivenIdx) const {
  Eigen::Matrix3d r;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      r(a, b) = entry(3 * static_cast<std::size_t>(node) + static_cast<std::size_t>(a),
                      3 * static_cast<std::size_t>(drivenIdx) + static_cast<std::size_t>(b));
  return r;
}

bool PrecomputedElasticity::solve(const std::vector<int>& held, const std::vector<Eigen::Vector3d>& displacement,
                                  Eigen::VectorXd& u, std::vector<Eigen::Vector3d>* forces, std::string& why) const {
  if (held.size() != displacement.size()) {
    why = "One displacement per held node is needed.";
    return false;
  }
  const std::size_t m = held.size();
  std::vector<int> idx(m);
  for (std::size_t k = 0; k < m; ++k) {
    idx[k] = drivenIndex(held[k]);
    if (idx[k] < 0) {
      why = "Node " + std::to_string(held[k]) +
            " has no precomputed response (it is not on the surface the "
            "responses were computed for).";
      return false;
    }
    for (std::size_t l = 0; l < k; ++l)
      if (held[l] == held[k]) {
        why = "Node " + std::to_string(held[k]) + " is held twice.";
        return false;
      }
  }
  u = sag_;
  if (forces) forces->assign(m, Eigen::Vector3d::Zero());
  if (m == 0) return true;
  // C_JJ lambda = d - u_g[J]
  const Eigen::Index M = static_cast<Eigen::Index>(3 * m);
  Eigen::MatrixXd A(M, M);
  Eigen::VectorXd b(M);
  for (std::size_t k = 0; k < m; ++k) {
    b.segment<3>(3 * static_cast<Eigen::Index>(k)) =
        displacement[k] - sag_.segment<3>(3 * static_cast<Eigen::Index>(held[k]));
    for (std::size_t l = 0; l < m; ++l)
      A.block<3, 3>(3 * static_cast<Eigen::Index>(k), 3 * static_cast<Eigen::Index>(l)) = response(held[k], idx[l]);
  }
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
  const Eigen::VectorXd lambda = ldlt.solve(b);
  if (ldlt.info() != Eigen::Success || !lambda.allFinite()) {
    why = "The held nodes' responses are singular together.";
    return false;
  }
  // u += C_:J lambda, a column at a time (contiguous).
  for (std::size_t k = 0; k < m; ++k)
    for (int a = 0; a < 3; ++a)
      addColumn(3 * static_cast<std::size_t>(idx[k]) + static_cast<std::size_t>(a),
                lambda(3 * static_cast<Eigen::Index>(k) + a), u);
  if (forces)
    for (std::size_t k = 0; k < m; ++k) (*forces)[k] = lambda.segment<3>(3 * static_cast<Eigen::Index>(k));
  return true;
}

void PrecomputedElasticity::addColumn(std::size_t col, double w, Eigen::VectorXd& u) const {
  if (w == 0) return;
  const Eigen::Index dofs = static_cast<Eigen::Index>(3 * nodes_);
  const std::size_t at = col * static_cast<std::size_t>(dofs);
  if (single_)
    u += w * Eigen::Map<const Eigen::VectorXf>(c32_.data() + at, dofs).cast<double>();
  else
    u += w * Eigen::Map<const Eigen::VectorXd>(c64_.data() + at, dofs);
}

bool PrecomputedElasticity::solveConstraints(const std::vector<ScalarConstraint>& rows, const Eigen::VectorXd& base,
                                             const Eigen::VectorXd& u0, Eigen::VectorXd& u, Eigen::VectorXd& lambda,
                                             Eigen::MatrixXd* Wout, std::string& why) const {
  const Eigen::Index m = static_cast<Eigen::Index>(rows.size());
  u = u0;
  lambda.setZero(m);
  if (Wout) Wout->resize(m, m);
  if (m == 0) return true;
  auto node = [](const ScalarConstraint& r, int k) { return r.nodes[static_cast<std::size_t>(k)]; };
  auto weight = [](const ScalarConstraint& r, int k) { return r.weights[static_cast<std::size_t>(k)]; };
  // Each row's force acts on its driven nodes (a fixed node's share goes to the attachment); every node must be one.
  for (const auto& r : rows)
    for (int k = 0; k < 4; ++k) {
      const int v = node(r, k);
      if (v < 0 || weight(r, k) == 0) continue;
      if (static_cast<std::size_t>(v) >= nodes_ || (drivenIndex(v) < 0 && !fixed_[static_cast<std::size_t>(v)])) {
        why = "An instrument acts on node " + std::to_string(v) +
              ", which has no precomputed response (inside the organ: the responses are the surface's).";
        return false;
      }
    }
  // W(r, c) = sum over r's free nodes i and c's driven nodes j of w_ri w_cj d_r^T C(i, j) d_c; e = value - G (base+u0).
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(m, m);
  Eigen::VectorXd e(m);
  const Eigen::VectorXd at = base + u0;
  for (Eigen::Index r = 0; r < m; ++r) {
    const auto& cr = rows[static_cast<std::size_t>(r)];
    double g = 0;
    for (int k = 0; k < 4; ++k)
      if (node(cr, k) >= 0) g += weight(cr, k) * cr.direction.dot(at.segment<3>(3 * node(cr, k)));
    e(r) = cr.value - g;
    for (Eigen::Index c = 0; c < m; ++c) {
      const auto& cc = rows[static_cast<std::size_t>(c)];
      double w = 0;
      for (int k = 0; k < 4; ++k) {
        const int i = node(cr, k);
        if (i < 0 || fixed_[static_cast<std::size_t>(i)]) continue;
        for (int l = 0; l < 4; ++l)
          if (const int j = drivenIndex(node(cc, l)); j >= 0)
            w += weight(cr, k) * weight(cc, l) * cr.direction.dot(response(i, j) * cc.direction);
      }
      W(r, c) = w;
    }
  }
  W = (0.5 * (W + W.transpose())).eval();
  if (Wout) *Wout = W;
  // Active set: bilateral rows always; a unilateral row while it pushes (lambda > 0), added back when violated.
  std::vector<char> active(static_cast<std::size_t>(m));
  for (Eigen::Index r = 0; r < m; ++r)
    active[static_cast<std::size_t>(r)] = !rows[static_cast<std::size_t>(r)].unilateral || e(r) > 0;
  const double scale = std::max(1e-12, e.cwiseAbs().maxCoeff());
  bool settled = false;
  for (int it = 0; it < 4 * static_cast<int>(m) + 4 && !settled; ++it) {
    std::vector<Eigen::Index> a;
    for (Eigen::Index r = 0; r < m; ++r)
      if (active[static_cast<std::size_t>(r)]) a.push_back(r);
    lambda.setZero(m);
    if (!a.empty()) {
      const Eigen::Index k = static_cast<Eigen::Index>(a.size());
      Eigen::MatrixXd Wa(k, k);
      Eigen::VectorXd ea(k);
      for (Eigen::Index i = 0; i < k; ++i) {
        ea(i) = e(a[static_cast<std::size_t>(i)]);
        for (Eigen::Index j = 0; j < k; ++j)
          Wa(i, j) = W(a[static_cast<std::size_t>(i)], a[static_cast<std::size_t>(j)]);
      }
      // Redundant rows (two holds of one node along one direction) make W_a singular: the pivoted LDL^T leaves their
      // share at zero.
      const Eigen::VectorXd la = Wa.ldlt().solve(ea);
      if (!la.allFinite()) {
        why = "The instruments' constraints contradict one another.";
        return false;
      }
      for (Eigen::Index i = 0; i < k; ++i) lambda(a[static_cast<std::size_t>(i)]) = la(i);
    }
    // The most negative unilateral multiplier leaves; else the most violated inactive unilateral row enters.
    Eigen::Index worst = -1;
    double worstValue = 0;
    for (Eigen::Index r = 0; r < m; ++r)
      if (rows[static_cast<std::size_t>(r)].unilateral && active[static_cast<std::size_t>(r)] && lambda(r) < worstValue)
        worst = r, worstValue = lambda(r);
    if (worst >= 0) {
      active[static_cast<std::size_t>(worst)] = 0;
      continue;
    }
    const Eigen::VectorXd gap = W * lambda - e;  // >= 0 where a unilateral row holds
    for (Eigen::Index r = 0; r < m; ++r)
      if (rows[static_cast<std::size_t>(r)].unilateral && !active[static_cast<std::size_t>(r)] &&
          gap(r) < -1e-12 * scale && gap(r) < worstValue)
        worst = r, worstValue = gap(r);
    if (worst >= 0)
      active[static_cast<std::size_t>(worst)] = 1;
    else
      settled = true;
  }
  if (!settled) {
    why = "The instruments' contacts did not settle (their active set cycled).";
    return false;
  }
  // u = u0 + C G^T lambda: each row's force spread on its driven nodes.
  for (Eigen::Index r = 0; r < m; ++r) {
    const auto& cr = rows[static_cast<std::size_t>(r)];
    if (lambda(r) == 0) continue;
    for (int k = 0; k < 4; ++k)
      if (const int j = drivenIndex(node(cr, k)); j >= 0) {
        const Eigen::Vector3d f = lambda(r) * weight(cr, k) * cr.direction;
        for (int a = 0; a < 3; ++a) addColumn(3 * static_cast<std::size_t>(j) + static_cast<std::size_t>(a), f(a), u);
      }
  }
  return true;
}

Eigen::Vector3d PrecomputedElasticity::forceAt(int drivenIdx, const Eigen::Vector3d& d) const {
  const int node = driven_[static_cast<std::size_t>(drivenIdx)];
  return selfStiffness_[static_cast<std::size_t>(drivenIdx)] *
         (d - sag_.segment<3>(3 * static_cast<Eigen::Index>(node)));
}

Eigen::Matrix3d PrecomputedElasticity::stiffnessAt(int drivenIdx) const {
  return selfStiffness_[static_cast<std::size_t>(drivenIdx)];
}

}  // namespace rehearse::simcore
