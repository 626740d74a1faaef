#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/quality.hpp>

#include <Eigen/LU>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <functional>

namespace rehearse::simcore {
namespace {

Eigen::Matrix3d deformationGradient(const FemModel& m, std::size_t e, const Eigen::VectorXd& x) {
  const auto& t = m.tets[e];
  Eigen::Matrix3d Ds;
  const Eigen::Vector3d x0 = x.segment<3>(3 * t[0]);
  for (int k = 0; k < 3; ++k) Ds.col(k) = x.segment<3>(3 * t[k + 1]) - x0;
  return Ds * m.Bm[e];
}

}  // namespace

FemModel FemModel::build(const Mesh& mesh, const std::map<int, MaterialParams>& byLabel, const MaterialParams& fallback) {
  if (mesh.tets.empty()) throw MeshError("The mesh has no tetrahedra; tetrahedralise the surface first.");
  FemModel m;
  m.rest.reserve(mesh.points.size());
  for (const auto& p : mesh.points) m.rest.push_back(p * mesh.unitToMetre);
  m.tets = mesh.tets;
  m.lumpedMass = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m.rest.size()));
  for (std::size_t e = 0; e < mesh.tets.size(); ++e) {
    const auto& t = mesh.tets[e];
    Eigen::Matrix3d Dm;
    for (int k = 0; k < 3; ++k) Dm.col(k) = m.rest[t[k + 1]] - m.rest[t[0]];
    const double vol = Dm.determinant() / 6.0;
    const double scale = std::pow(Dm.colwise().norm().maxCoeff(), 3);
    if (!(std::abs(vol) > 1e-12 * scale))
      throw MeshError("Tetrahedron " + std::to_string(e) + " is flat in the rest shape; repair or re-mesh the organ.");
    m.Bm.push_back(Dm.inverse());
    m.restVolume.push_back(std::abs(vol));
    const int label = mesh.tetLabels.empty() ? 0 : mesh.tetLabels[e];
    const auto it = byLabel.find(label);
    const MaterialParams& p = it != byLabel.end() ? it->second : fallback;
    if (!(p.young > 0) || !(p.poisson >= 0 && p.poisson < 0.5) || !(p.density > 0))
      throw MeshError("Material of label " + std::to_string(label) +
                      " is invalid: Young's modulus and density must be positive and Poisson's ratio in [0, 0.5).");
    m.model.push_back(p.model);
    m.lame.push_back(Lame::fromYoung(p.young, p.poisson));
    for (int v : t) m.lumpedMass[v] += p.density * std::abs(vol) / 4.0;
  }
  // Sparsity pattern and element slots, computed once (the topology does not change while simulating).
  const Eigen::Index n3 = static_cast<Eigen::Index>(3 * m.rest.size());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(m.tets.size() * 144);
  for (const auto& t : m.tets)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) triplets.emplace_back(3 * t[a] + i, 3 * t[b] + j, 0.0);
  for (Eigen::Index i = 0; i < n3; ++i) triplets.emplace_back(i, i, 0.0);
  m.pattern.resize(n3, n3);
  m.pattern.setFromTriplets(triplets.begin(), triplets.end());
  m.pattern.makeCompressed();
  auto slotOf = [&](int row, int col) {
    const int* inner = m.pattern.innerIndexPtr();
    const int begin = m.pattern.outerIndexPtr()[col], end = m.pattern.outerIndexPtr()[col + 1];
    return static_cast<int>(std::lower_bound(inner + begin, inner + end, row) - inner);
  };
  m.elementSlots.resize(m.tets.size());
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const auto& t = m.tets[e];
    for (int c = 0; c < 12; ++c)
      for (int r = 0; r < 12; ++r) m.elementSlots[e][12 * c + r] = slotOf(3 * t[r / 3] + r % 3, 3 * t[c / 3] + c % 3);
  }
  m.diagonalSlot.resize(n3);
  for (Eigen::Index i = 0; i < n3; ++i) m.diagonalSlot[i] = slotOf(static_cast<int>(i), static_cast<int>(i));
  return m;
}

Eigen::VectorXd FemModel::restVector() const {
  Eigen::VectorXd x(3 * rest.size());
  for (std::size_t i = 0; i < rest.size(); ++i) x.segment<3>(3 * i) = rest[i];
  return x;
}

double elasticEnergy(const FemModel& m, const Eigen::VectorXd& x) {
  // Deterministic parallel sum (the same value on every run, whatever the thread count).
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, m.tets.size(), 256), 0.0,
      [&](const tbb::blocked_range<std::size_t>& r, double e) {
        for (std::size_t t = r.begin(); t < r.end(); ++t)
          e += m.restVolume[t] * energyDensity(m.model[t], m.lame[t], deformationGradient(m, t, x));
        return e;
      },
      std::plus<double>());
}

void elasticForces(const FemModel& m, const Eigen::VectorXd& x, Eigen::VectorXd& f) {
  if (f.size() != x.size()) f.resize(x.size());
  f.setZero();
  // Element forces in parallel into a buffer, then a serial scatter (fixed order). The calling thread's
  // buffer is reused between calls; the pointer (not the thread_local) goes to the workers.
  thread_local std::vector<double> buffer;
  buffer.resize(m.tets.size() * 9);
  double* const buf = buffer.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.tets.size(), 128), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t e = r.begin(); e < r.end(); ++e) {
      const Eigen::Matrix3d P = firstPiola(m.model[e], m.lame[e], deformationGradient(m, e, x));
      // dE/dx_{1..3} = V P Bm^T (columns); node 0 balances them.
      Eigen::Map<Eigen::Matrix3d>(buf + 9 * e) = -m.restVolume[e] * P * m.Bm[e].transpose();
    }
  });
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const Eigen::Map<const Eigen::Matrix3d> H(buf + 9 * e);
    const auto& t = m.tets[e];
    for (int k = 0; k < 3; ++k) {
      f.segment<3>(3 * t[k + 1]) += H.col(k);
      f.segment<3>(3 * t[0]) -= H.col(k);
    }
  }
}

void prepareTangentState(const FemModel& m, const Eigen::VectorXd& x, TangentState& state) {
  state.F.resize(m.tets.size());
  state.cache.resize(m.tets.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.tets.size(), 128), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t e = r.begin(); e < r.end(); ++e) {
      state.F[e] = deformationGradient(m, e, x);
      state.cache[e] = prepareTangent(m.model[e], state.F[e]);
    }
  });
}

void applyStiffness(const FemModel& m, const TangentState& state, const Eigen::VectorXd& v, Eigen::VectorXd& out) {
  if (out.size() != v.size()) out.resize(v.size());
  out.setZero();
  thread_local std::vector<double> buffer;
  buffer.resize(m.tets.size() * 9);
  double* const buf = buffer.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.tets.size(), 128), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t e = r.begin(); e < r.end(); ++e) {
      const Eigen::Matrix3d dF = deformationGradient(m, e, v);  // the gradient of the direction field
      const Eigen::Matrix3d dP = firstPiolaDifferential(m.model[e], m.lame[e], state.F[e], state.cache[e], dF);
      Eigen::Map<Eigen::Matrix3d>(buf + 9 * e) = m.restVolume[e] * dP * m.Bm[e].transpose();  // d(dE/dx_{1..3})
    }
  });
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const Eigen::Map<const Eigen::Matrix3d> H(buf + 9 * e);
    const auto& t = m.tets[e];
    for (int k = 0; k < 3; ++k) {
      out.segment<3>(3 * t[k + 1]) += H.col(k);
      out.segment<3>(3 * t[0]) -= H.col(k);
    }
  }
}

void vonMisesStress(const FemModel& m, const Eigen::VectorXd& x, std::vector<double>& out) {
  out.resize(m.tets.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.tets.size(), 256), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t e = r.begin(); e < r.end(); ++e) {
      const Eigen::Matrix3d F = deformationGradient(m, e, x);
      const Eigen::Matrix3d P = firstPiola(m.model[e], m.lame[e], F);
      const double J = F.determinant();
      Eigen::Matrix3d sigma = J > 1e-6 ? Eigen::Matrix3d(P * F.transpose() / J) : P;
      sigma = 0.5 * (sigma + sigma.transpose()).eval();
      const Eigen::Matrix3d dev = sigma - sigma.trace() / 3 * Eigen::Matrix3d::Identity();
      out[e] = std::sqrt(1.5 * dev.squaredNorm());
    }
  });
}

Eigen::VectorXd elasticForces(const FemModel& m, const Eigen::VectorXd& x) {
  Eigen::VectorXd f;
  elasticForces(m, x, f);
  return f;
}

namespace {
// 12x12 element stiffness, column-major (column = the moving dof: node a, axis d).
void elementStiffness(const FemModel& m, std::size_t e, const Eigen::VectorXd& x, double* out) {
  const Eigen::Matrix3d F = deformationGradient(m, e, x);
  const Eigen::Matrix3d BmT = m.Bm[e].transpose();
  const TangentCache cache = prepareTangent(m.model[e], F);
  for (int a = 0; a < 4; ++a)
    for (int d = 0; d < 3; ++d) {
      Eigen::Matrix3d dDs = Eigen::Matrix3d::Zero();
      if (a == 0) dDs.row(d).setConstant(-1.0);
      else dDs(d, a - 1) = 1.0;
      const Eigen::Matrix3d dP = firstPiolaDifferential(m.model[e], m.lame[e], F, cache, dDs * m.Bm[e]);
      const Eigen::Matrix3d dH = m.restVolume[e] * dP * BmT;  // change of dE/dx_{1..3}
      double* col = out + 12 * (3 * a + d);
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k) {
        for (int r = 0; r < 3; ++r) col[3 * (k + 1) + r] = dH(r, k);
        sum += dH.col(k);
      }
      for (int r = 0; r < 3; ++r) col[r] = -sum[r];
    }
}
}  // namespace

void assembleStiffness(const FemModel& m, const Eigen::VectorXd& x, Eigen::SparseMatrix<double>& K) {
  if (K.nonZeros() != m.pattern.nonZeros() || K.rows() != m.pattern.rows()) K = m.pattern;
  double* values = K.valuePtr();
  std::fill(values, values + K.nonZeros(), 0.0);
  // Elements in parallel into a buffer, then a serial scatter (no write conflicts, same result every run).
  // The calling thread's buffer is reused between calls; the pointer (not the thread_local) goes to the workers.
  thread_local std::vector<double> buffer;
  buffer.resize(m.tets.size() * 144);
  double* const buf = buffer.data();
  const auto count = static_cast<long>(m.tets.size());
  tbb::parallel_for(tbb::blocked_range<long>(0, count, 64), [&](const tbb::blocked_range<long>& r) {
    for (long e = r.begin(); e < r.end(); ++e) elementStiffness(m, static_cast<std::size_t>(e), x, buf + 144 * e);
  });
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const double* b = buffer.data() + 144 * e;
    const auto& slot = m.elementSlots[e];
    for (int i = 0; i < 144; ++i) values[slot[i]] += b[i];
  }
}

Eigen::SparseMatrix<double> elasticStiffness(const FemModel& m, const Eigen::VectorXd& x) {
  Eigen::SparseMatrix<double> K = m.pattern;
  assembleStiffness(m, x, K);
  return K;
}

}  // namespace rehearse::simcore
