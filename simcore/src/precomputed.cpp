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
  const Eigen::Index dofs = static_cast<Eigen::Index>(3 * nodes_);
  for (std::size_t k = 0; k < m; ++k)
    for (int a = 0; a < 3; ++a) {
      const double w = lambda(3 * static_cast<Eigen::Index>(k) + a);
      const std::size_t col = 3 * static_cast<std::size_t>(idx[k]) + static_cast<std::size_t>(a);
      if (single_)
        u += w *
             Eigen::Map<const Eigen::VectorXf>(c32_.data() + col * static_cast<std::size_t>(dofs), dofs).cast<double>();
      else
        u += w * Eigen::Map<const Eigen::VectorXd>(c64_.data() + col * static_cast<std::size_t>(dofs), dofs);
    }
  if (forces)
    for (std::size_t k = 0; k < m; ++k) (*forces)[k] = lambda.segment<3>(3 * static_cast<Eigen::Index>(k));
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
