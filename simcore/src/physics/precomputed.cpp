// Precomputed linear elasticity: the responses built from one factorisation, and the superposition (precomputed.hpp).
#include <rehearse/simcore/precomputed.hpp>

#include <rehearse/simcore/linear_solver.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace rehearse::simcore {

struct PrecomputedElasticity::Factor {
  std::mutex mutex;
  CholmodSolver chol;
  Eigen::VectorXd x;  ///< the back-solve's result (reused)
};

bool PrecomputedElasticity::factorise(const FemModel& model, const std::vector<char>& fixed, Factor& f) {
  // K at rest with the fixed nodes' rows and columns replaced by the identity (their displacement is then zero for
  // any load that is zero there).
  Eigen::SparseMatrix<double> K = elasticStiffness(model, model.restVector());
  for (int c = 0; c < K.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it) {
      const bool rowFixed = fixed[static_cast<std::size_t>(it.row() / 3)] != 0;
      const bool colFixed = fixed[static_cast<std::size_t>(it.col() / 3)] != 0;
      if (rowFixed || colFixed) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
    }
  return f.chol.factorise(K);
}

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
  const std::size_t rowCount = settings.drivenRowsOnly ? 3 * driven.size() : 3 * n;
  const double bytes = 3.0 * static_cast<double>(driven.size()) * static_cast<double>(rowCount) *
                       (settings.singlePrecision ? sizeof(float) : sizeof(double));
  if (bytes > static_cast<double>(settings.maxBytes)) {
    char said[260];
    std::snprintf(said, sizeof said,
                  "The responses would take %.1f GB (%zu surface nodes x %zu %s x 9 numbers), over the %.1f GB "
                  "allowed: use single precision or a coarser mesh.",
                  bytes / (1u << 30), driven.size(), rowCount / 3, settings.drivenRowsOnly ? "surface nodes" : "nodes",
                  static_cast<double>(settings.maxBytes) / (1u << 30));
    why = said;
    return std::nullopt;
  }
  p.factor_ = std::make_shared<Factor>();
  CholmodSolver& chol = p.factor_->chol;
  if (!factorise(model, fixed, *p.factor_)) {
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
  p.drivenOnly_ = settings.drivenRowsOnly;
  p.single_ = settings.singlePrecision;
  const std::size_t columns = 3 * driven.size();
  (p.single_ ? p.c32_.resize(columns * rowCount) : p.c64_.resize(columns * rowCount));
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
      const std::size_t at = (c0 + c) * rowCount;
      if (p.drivenOnly_) {
        for (std::size_t j = 0; j < driven.size(); ++j)
          for (std::size_t a = 0; a < 3; ++a) {
            const double v = src[3 * static_cast<std::size_t>(driven[j]) + a];
            if (p.single_)
              p.c32_[at + 3 * j + a] = static_cast<float>(v);
            else
              p.c64_[at + 3 * j + a] = v;
          }
      } else if (p.single_) {
        std::transform(src, src + dofs, p.c32_.begin() + static_cast<std::ptrdiff_t>(at),
                       [](double v) { return static_cast<float>(v); });
      } else {
        std::copy(src, src + dofs, p.c64_.begin() + static_cast<std::ptrdiff_t>(at));
      }
    }
    if (settings.progress && !settings.progress(static_cast<double>(c0 + nc) / static_cast<double>(columns))) {
      why = "The precomputation was cancelled; the model keeps what it had.";
      return std::nullopt;
    }
  }
  p.fixed_ = fixed;
  if (!p.drivenOnly_) p.factor_.reset();  // every node's response is stored: the factor is not needed online
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
  // The kept factor: its entries (double) and their row indices (int).
  const std::size_t factor = factor_ ? factor_->chol.factorEntries() * (sizeof(double) + sizeof(int)) : 0;
  return factor + c64_.size() * sizeof(double) + c32_.size() * sizeof(float) +
         static_cast<std::size_t>(sag_.size()) * sizeof(double) + selfStiffness_.size() * sizeof(Eigen::Matrix3d) +
         drivenOf_.size() * sizeof(int) + driven_.size() * sizeof(int);
}

Eigen::Matrix3d PrecomputedElasticity::response(int node, int drivenIdx) const {
  const int row = drivenOnly_ ? drivenIndex(node) : node;
  Eigen::Matrix3d r = Eigen::Matrix3d::Zero();
  if (row < 0) return r;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      r(a, b) = entry(3 * static_cast<std::size_t>(row) + static_cast<std::size_t>(a),
                      3 * static_cast<std::size_t>(drivenIdx) + static_cast<std::size_t>(b));
  return r;
}

bool PrecomputedElasticity::displace(const Eigen::VectorXd& F, Eigen::VectorXd& u, std::string& why) const {
  if (!drivenOnly_) {
    for (std::size_t j = 0; j < driven_.size(); ++j)
      for (int a = 0; a < 3; ++a)
        addColumn(3 * j + static_cast<std::size_t>(a), F(3 * static_cast<Eigen::Index>(driven_[j]) + a), u);
    return true;
  }
  if (F.isZero(0)) return true;
  std::lock_guard<std::mutex> lock(factor_->mutex);
  if (!factor_->chol.solve(F, factor_->x)) {
    why = "The back-solve for the organ's inner nodes failed.";
    return false;
  }
  u += factor_->x;
  return true;
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
  // u += C_:J lambda, a column at a time (contiguous), or by the back-solve.
  Eigen::VectorXd F = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(3 * nodes_));
  for (std::size_t k = 0; k < m; ++k)
    F.segment<3>(3 * static_cast<Eigen::Index>(held[k])) = lambda.segment<3>(3 * static_cast<Eigen::Index>(k));
  if (!displace(F, u, why)) return false;
  if (forces)
    for (std::size_t k = 0; k < m; ++k) (*forces)[k] = lambda.segment<3>(3 * static_cast<Eigen::Index>(k));
  return true;
}

void PrecomputedElasticity::addColumn(std::size_t col, double w, Eigen::VectorXd& u) const {
  if (w == 0) return;
  const Eigen::Index dofs = static_cast<Eigen::Index>(3 * nodes_);
  const std::size_t at = col * rows();
  if (single_)
    u += w * Eigen::Map<const Eigen::VectorXf>(c32_.data() + at, dofs).cast<double>();
  else
    u += w * Eigen::Map<const Eigen::VectorXd>(c64_.data() + at, dofs);
}

bool settleRows(const std::vector<ScalarConstraint>& rows, const Eigen::MatrixXd& W, const Eigen::VectorXd& e,
                Eigen::VectorXd& lambda, std::string& why) {
  const Eigen::Index m = static_cast<Eigen::Index>(rows.size());
  lambda.setZero(m);
  if (m == 0) return true;
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
  return true;
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
    e(r) = cr.value - constraintValue(cr, at);
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
  if (!settleRows(rows, W, e, lambda, why)) return false;
  // u = u0 + C G^T lambda: each row's force spread on its driven nodes.
  Eigen::VectorXd F = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(3 * nodes_));
  for (Eigen::Index r = 0; r < m; ++r) {
    const auto& cr = rows[static_cast<std::size_t>(r)];
    if (lambda(r) == 0) continue;
    for (int k = 0; k < 4; ++k)
      if (drivenIndex(node(cr, k)) >= 0) F.segment<3>(3 * node(cr, k)) += lambda(r) * weight(cr, k) * cr.direction;
  }
  return displace(F, u, why);
}

Eigen::Vector3d PrecomputedElasticity::forceAt(int drivenIdx, const Eigen::Vector3d& d) const {
  const int node = driven_[static_cast<std::size_t>(drivenIdx)];
  return selfStiffness_[static_cast<std::size_t>(drivenIdx)] *
         (d - sag_.segment<3>(3 * static_cast<Eigen::Index>(node)));
}

Eigen::Matrix3d PrecomputedElasticity::stiffnessAt(int drivenIdx) const {
  return selfStiffness_[static_cast<std::size_t>(drivenIdx)];
}

// ------------------------------------------------------------------------------------------ bytes, key, cache

namespace {
constexpr char kMagic[8] = {'R', 'H', 'P', 'R', 'E', 'C', '0', '1'};

template <class T>
void put(std::string& out, const T* data, std::size_t count) {
  out.append(reinterpret_cast<const char*>(data), count * sizeof(T));
}
template <class T>
bool take(const std::string& in, std::size_t& at, T* data, std::size_t count) {
  const std::size_t bytes = count * sizeof(T);
  if (count > (in.size() - std::min(at, in.size())) / sizeof(T)) return false;
  std::memcpy(static_cast<void*>(data), in.data() + at, bytes);
  at += bytes;
  return true;
}

// FNV-1a over bytes.
struct Hasher {
  std::uint64_t h = 1469598103934665603ull;
  template <class T>
  void add(const T* data, std::size_t count) {
    const auto* b = reinterpret_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < count * sizeof(T); ++i) h = (h ^ b[i]) * 1099511628211ull;
  }
};
}  // namespace

std::string PrecomputedElasticity::toBytes() const {
  std::string out;
  out.reserve(64 + c64_.size() * 8 + c32_.size() * 4 + nodes_ * 30);
  out.append(kMagic, sizeof kMagic);
  const std::uint64_t head[4] = {nodes_, driven_.size(), single_ ? 1u : 0u, drivenOnly_ ? 1u : 0u};
  put(out, head, 4);
  put(out, driven_.data(), driven_.size());
  put(out, fixed_.data(), fixed_.size());
  put(out, sag_.data(), static_cast<std::size_t>(sag_.size()));
  if (single_)
    put(out, c32_.data(), c32_.size());
  else
    put(out, c64_.data(), c64_.size());
  return out;
}

std::optional<PrecomputedElasticity> PrecomputedElasticity::fromBytes(const std::string& bytes, const FemModel& model,
                                                                      std::string& why) {
  why = "The stored responses are damaged or not this organ's; they will be computed again.";
  if (bytes.size() < sizeof kMagic + 32 || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0) return std::nullopt;
  std::size_t at = sizeof kMagic;
  std::uint64_t head[4];
  if (!take(bytes, at, head, 4)) return std::nullopt;
  if (head[0] != model.nodeCount() || head[1] > head[0] || head[2] > 1 || head[3] > 1) return std::nullopt;
  PrecomputedElasticity p;
  p.nodes_ = head[0];
  p.single_ = head[2] == 1;
  p.drivenOnly_ = head[3] == 1;
  p.driven_.resize(head[1]);
  p.fixed_.resize(p.nodes_);
  p.sag_.resize(static_cast<Eigen::Index>(3 * p.nodes_));
  if (!take(bytes, at, p.driven_.data(), p.driven_.size()) || !take(bytes, at, p.fixed_.data(), p.fixed_.size()) ||
      !take(bytes, at, p.sag_.data(), 3 * p.nodes_))
    return std::nullopt;
  const std::size_t values = 3 * p.driven_.size() * p.rows();
  // The rest of the bytes must be exactly the responses (checked before anything that size is allocated: damaged
  // counts must not ask for gigabytes).
  if ((bytes.size() - at) / (p.single_ ? sizeof(float) : sizeof(double)) != values ||
      (bytes.size() - at) % (p.single_ ? sizeof(float) : sizeof(double)) != 0)
    return std::nullopt;
  if (p.single_) {
    p.c32_.resize(values);
    if (!take(bytes, at, p.c32_.data(), values)) return std::nullopt;
  } else {
    p.c64_.resize(values);
    if (!take(bytes, at, p.c64_.data(), values)) return std::nullopt;
  }
  // Every number finite (a writer's fault under a matching checksum must not turn into NaN positions later).
  const bool finite = p.single_ ? std::all_of(p.c32_.begin(), p.c32_.end(), [](float v) { return std::isfinite(v); })
                                : std::all_of(p.c64_.begin(), p.c64_.end(), [](double v) { return std::isfinite(v); });
  if (at != bytes.size() || !p.sag_.allFinite() || !finite) return std::nullopt;
  p.drivenOf_.assign(p.nodes_, -1);
  for (std::size_t j = 0; j < p.driven_.size(); ++j) {
    const int v = p.driven_[j];
    if (v < 0 || static_cast<std::size_t>(v) >= p.nodes_ || p.drivenOf_[static_cast<std::size_t>(v)] >= 0 ||
        p.fixed_[static_cast<std::size_t>(v)])
      return std::nullopt;
    p.drivenOf_[static_cast<std::size_t>(v)] = static_cast<int>(j);
  }
  if (p.drivenOnly_) {
    p.factor_ = std::make_shared<Factor>();
    if (!factorise(model, p.fixed_, *p.factor_)) {
      why = "The stored responses' organ cannot be factorised; they will be computed again.";
      return std::nullopt;
    }
  }
  p.selfStiffness_.resize(p.driven_.size());
  for (std::size_t j = 0; j < p.driven_.size(); ++j) {
    p.selfStiffness_[j] = p.response(p.driven_[j], static_cast<int>(j)).inverse();
    if (!p.selfStiffness_[j].allFinite()) return std::nullopt;
  }
  why.clear();
  return p;
}

std::uint64_t precomputeKey(const FemModel& model, const std::vector<char>& fixed, const std::vector<int>& driven,
                            const Eigen::Vector3d& gravity, const PrecomputeSettings& settings) {
  Hasher h;
  for (const auto& p : model.rest) h.add(p.data(), 3);
  h.add(model.tets.data(), model.tets.size());
  for (const auto& l : model.lame) h.add(&l.mu, 1), h.add(&l.lambda, 1);
  h.add(model.lumpedMass.data(), static_cast<std::size_t>(model.lumpedMass.size()));
  h.add(fixed.data(), fixed.size());
  h.add(driven.data(), driven.size());
  h.add(gravity.data(), 3);
  const char flags[2] = {settings.singlePrecision, settings.drivenRowsOnly};
  h.add(flags, 2);
  return h.h;
}

ResponseCache& ResponseCache::shared() {
  static ResponseCache cache;
  return cache;
}

std::shared_ptr<const PrecomputedElasticity> ResponseCache::find(std::uint64_t key) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = std::find_if(entries_.begin(), entries_.end(), [&](const auto& e) { return e.first == key; });
  if (it == entries_.end()) return nullptr;
  std::rotate(entries_.begin(), it, it + 1);  // most recently used first
  return entries_.front().second;
}

void ResponseCache::put(std::uint64_t key, std::shared_ptr<const PrecomputedElasticity> responses) {
  if (!responses) return;
  std::lock_guard<std::mutex> lock(mutex_);
  std::erase_if(entries_, [&](const auto& e) { return e.first == key; });
  entries_.insert(entries_.begin(), {key, std::move(responses)});
  std::size_t total = 0;
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    total += entries_[i].second->memoryBytes();
    if (i > 0 && total > limitBytes) {  // the newest stays whatever its size
      entries_.resize(i);
      break;
    }
  }
}

std::vector<std::pair<std::uint64_t, std::shared_ptr<const PrecomputedElasticity>>> ResponseCache::entries() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return entries_;
}

void ResponseCache::offerBytes(std::uint64_t key, std::shared_ptr<const std::string> bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::erase_if(bytes_, [&](const auto& e) { return e.first == key; });
  if (!bytes) return;
  bytes_.insert(bytes_.begin(), {key, std::move(bytes)});
  if (bytes_.size() > 4) bytes_.resize(4);  // the cases opened last
}

std::shared_ptr<const std::string> ResponseCache::storedBytes(std::uint64_t key) const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& e : bytes_)
    if (e.first == key) return e.second;
  return nullptr;
}

void ResponseCache::clear() {
  std::lock_guard<std::mutex> lock(mutex_);
  entries_.clear();
  bytes_.clear();
}

std::shared_ptr<const PrecomputedElasticity> precomputedFor(const FemModel& model, const std::vector<char>& fixed,
                                                            const std::vector<int>& driven,
                                                            const Eigen::Vector3d& gravity,
                                                            const PrecomputeSettings& settings, std::uint64_t& key,
                                                            std::string& from, std::string& why) {
  ResponseCache& cache = ResponseCache::shared();
  key = precomputeKey(model, fixed, driven, gravity, settings);
  if (auto hit = cache.find(key)) {
    from = "cache";
    return hit;
  }
  if (const auto bytes = cache.storedBytes(key)) {
    std::string bad;
    if (auto p = PrecomputedElasticity::fromBytes(*bytes, model, bad)) {
      auto shared = std::make_shared<const PrecomputedElasticity>(std::move(*p));
      cache.put(key, shared);
      from = "case file";
      return shared;
    }
    cache.offerBytes(key, nullptr);  // damaged: built again below
  }
  auto built = PrecomputedElasticity::build(model, fixed, driven, gravity, settings, why);
  if (!built) return nullptr;
  auto shared = std::make_shared<const PrecomputedElasticity>(std::move(*built));
  cache.put(key, shared);
  from = "built";
  return shared;
}

}  // namespace rehearse::simcore
