#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/quality.hpp>

#include "fem_patch.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
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

// Hessian of the spring energy k/2 (|d| - L)^2 with respect to d.
Eigen::Matrix3d springHessian(const EmbeddedSpring& s, const Eigen::Vector3d& d) {
  const double l = d.norm();
  if (!(l > 1e-12 * std::max(s.restLength, 1e-12))) return s.stiffness * Eigen::Matrix3d::Identity();
  const Eigen::Vector3d n = d / l;
  return s.stiffness * ((1 - s.restLength / l) * Eigen::Matrix3d::Identity() + (s.restLength / l) * n * n.transpose());
}

Eigen::Vector3d springVector(const EmbeddedSpring& s, const Eigen::VectorXd& x) {
  Eigen::Vector3d d = Eigen::Vector3d::Zero();
  for (int k = 0; k < 8; ++k) d += s.weights[k] * x.segment<3>(3 * s.nodes[k]);
  return d;
}

// Adds per-element 3x3 blocks (columns: the vectors for nodes 1..3; node 0 takes minus their sum) into
// the nodal vector `out`, in element order (the same sum on every run, whatever the thread count).
void scatterElementVectors(const FemModel& m, const double* buf, Eigen::VectorXd& out) {
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const Eigen::Map<const Eigen::Matrix3d> H(buf + 9 * e);
    const auto& t = m.tets[e];
    for (int k = 0; k < 3; ++k) {
      out.segment<3>(3 * t[k + 1]) += H.col(k);
      out.segment<3>(3 * t[0]) -= H.col(k);
    }
  }
}

// The embedded springs' and the anchors' forces -dE/dx added to f.
void addSpringForces(const FemModel& m, const Eigen::VectorXd& x, Eigen::VectorXd& f) {
  for (const auto& a : m.anchors) f.segment<3>(3 * a.node) -= a.stiffness * (x.segment<3>(3 * a.node) - a.at);
  for (const auto& sp : m.springs) {
    const Eigen::Vector3d d = springVector(sp, x);
    const double l = d.norm();
    if (!(l > 0)) continue;
    const Eigen::Vector3d g = sp.stiffness * (l - sp.restLength) / l * d;  // dE/d(p - q)
    for (int k = 0; k < 8; ++k) f.segment<3>(3 * sp.nodes[k]) -= sp.weights[k] * g;
  }
}

}  // namespace

SurfaceEmbedding embedPoints(const FemModel& m, const std::vector<Eigen::Vector3d>& points) {
  return embedPoints(m.rest, m.tets, points);
}

std::vector<Eigen::Vector3d> mapEmbedded(const SurfaceEmbedding& e, const Eigen::VectorXd& x) {
  std::vector<Eigen::Vector3d> out(e.nodes.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i].setZero();
    for (int k = 0; k < 4; ++k) out[i] += e.weights[i][k] * x.segment<3>(3 * e.nodes[i][k]);
  }
  return out;
}

std::vector<Eigen::Vector3d> mapEmbedded(const FemModel& m, std::size_t which, const Eigen::VectorXd& x) {
  const SurfaceEmbedding& e = m.embeddings.at(which);
  std::vector<Eigen::Vector3d> out(e.nodes.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i].setZero();
    for (int k = 0; k < 4; ++k) out[i] += e.weights[i][k] * x.segment<3>(3 * e.nodes[i][k]);
  }
  return out;
}

FemModel FemModel::build(const Mesh& mesh, const std::map<int, MaterialParams>& byLabel, const MaterialParams& fallback,
                         const std::vector<EmbeddedSurface>& embedded) {
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
  // Embedded surfaces: locate their vertices, then one spring per edge, k = sqrt(3)/4 E t (the
  // spring network that matches a membrane of thickness t under uniform stretch, Van Gelder 1998).
  for (const auto& es : embedded) {
    if (es.surface.triangles.empty()) throw MeshError("The embedded surface '" + es.name + "' has no triangles.");
    if (!(es.young > 0) || !(es.thickness > 0))
      throw MeshError("The embedded surface '" + es.name + "' needs a positive Young's modulus and wall thickness.");
    std::vector<Eigen::Vector3d> pts;
    for (const auto& p : es.surface.points) pts.push_back(p * es.surface.unitToMetre);
    SurfaceEmbedding emb = embedPoints(m.rest, m.tets, pts);
    emb.name = es.name;
    emb.triangles = es.surface.triangles;
    std::vector<std::pair<int, int>> edges;
    for (const auto& t : es.surface.triangles)
      for (int k = 0; k < 3; ++k) edges.emplace_back(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    const double k = std::sqrt(3.0) / 4 * es.young * es.thickness;
    for (const auto& [a, b] : edges) {
      if (a < 0 || b >= static_cast<int>(pts.size())) throw MeshError("The embedded surface '" + es.name + "' has an invalid triangle.");
      EmbeddedSpring sp;
      for (int q = 0; q < 4; ++q) {
        sp.nodes[q] = emb.nodes[a][q];
        sp.weights[q] = emb.weights[a][q];
        sp.nodes[4 + q] = emb.nodes[b][q];
        sp.weights[4 + q] = -emb.weights[b][q];
      }
      sp.stiffness = k;
      sp.restLength = (pts[a] - pts[b]).norm();
      if (sp.restLength > 0) m.springs.push_back(sp);
    }
    m.embeddings.push_back(std::move(emb));
  }
  // Sparsity pattern and element slots, computed once per topology (a cut builds a new model). Built at the
  // level of nodes (a node pair couples a 3x3 block), 9x fewer entries to sort than dof triplets: the
  // pattern and the slots are most of a cut's body rebuild (bench_rehearsal).
  const Eigen::Index n3 = static_cast<Eigen::Index>(3 * m.rest.size());
  const int nn = static_cast<int>(m.rest.size());
  std::vector<std::pair<int, int>> pairs;  // (column node, row node)
  pairs.reserve(m.tets.size() * 16 + m.springs.size() * 64 + m.rest.size());
  for (const auto& t : m.tets)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) pairs.emplace_back(t[b], t[a]);
  for (const auto& sp : m.springs)
    for (int a = 0; a < 8; ++a)
      for (int b = 0; b < 8; ++b) pairs.emplace_back(sp.nodes[b], sp.nodes[a]);
  for (int i = 0; i < nn; ++i) pairs.emplace_back(i, i);
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  std::vector<int> first(static_cast<std::size_t>(nn) + 1, 0);  // each column node's row nodes: pairs[first[c] .. first[c + 1])
  for (const auto& pr : pairs) ++first[static_cast<std::size_t>(pr.first) + 1];
  for (int c = 0; c < nn; ++c) first[static_cast<std::size_t>(c) + 1] += first[static_cast<std::size_t>(c)];
  m.pattern.resize(n3, n3);
  m.pattern.resizeNonZeros(static_cast<Eigen::Index>(9 * pairs.size()));
  int* outer = m.pattern.outerIndexPtr();
  int* inner = m.pattern.innerIndexPtr();
  std::fill(m.pattern.valuePtr(), m.pattern.valuePtr() + 9 * pairs.size(), 0.0);
  for (int c = 0; c < nn; ++c) {
    const int b = first[static_cast<std::size_t>(c)], e = first[static_cast<std::size_t>(c) + 1];
    for (int j = 0; j < 3; ++j) {
      const int col = 3 * c + j, start = 9 * b + 3 * (e - b) * j;
      outer[col] = start;
      for (int k = b; k < e; ++k)
        for (int i = 0; i < 3; ++i) inner[start + 3 * (k - b) + i] = 3 * pairs[static_cast<std::size_t>(k)].second + i;
    }
  }
  outer[n3] = static_cast<int>(9 * pairs.size());
  // The slot of dof (3 r + i, 3 c + j): the column's start plus the row node's place among the column node's.
  auto nodeSlot = [&](int r, int c) {
    const auto* b = pairs.data() + first[static_cast<std::size_t>(c)];
    const auto* e = pairs.data() + first[static_cast<std::size_t>(c) + 1];
    return static_cast<int>(std::lower_bound(b, e, std::make_pair(c, r)) - b);
  };
  auto slotOf = [&](int row, int col) { return outer[col] + 3 * nodeSlot(row / 3, col / 3) + row % 3; };
  m.elementSlots.resize(m.tets.size());
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const auto& t = m.tets[e];
    for (int cb = 0; cb < 4; ++cb)
      for (int rb = 0; rb < 4; ++rb) {
        const int place = nodeSlot(t[rb], t[cb]);
        for (int j = 0; j < 3; ++j)
          for (int i = 0; i < 3; ++i) m.elementSlots[e][12 * (3 * cb + j) + 3 * rb + i] = outer[3 * t[cb] + j] + 3 * place + i;
      }
  }
  m.springSlots.resize(m.springs.size());
  for (std::size_t e = 0; e < m.springs.size(); ++e) {
    const auto& sp = m.springs[e];
    for (int c = 0; c < 24; ++c)
      for (int r = 0; r < 24; ++r) m.springSlots[e][24 * c + r] = slotOf(3 * sp.nodes[r / 3] + r % 3, 3 * sp.nodes[c / 3] + c % 3);
  }
  m.diagonalSlot.resize(n3);
  for (Eigen::Index i = 0; i < n3; ++i) m.diagonalSlot[i] = slotOf(static_cast<int>(i), static_cast<int>(i));
  return m;
}

void setVolumeBarrier(FemModel& m, double J) {
  for (std::size_t e = 0; e < m.lame.size(); ++e)
    if (m.model[e] == MaterialModel::Corotational) m.lame[e].barrier = J;
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
      std::plus<double>()) + [&] {
        double e = 0;
        for (const auto& sp : m.springs) {
          const double l = springVector(sp, x).norm() - sp.restLength;
          e += 0.5 * sp.stiffness * l * l;
        }
        for (const auto& a : m.anchors) e += 0.5 * a.stiffness * (x.segment<3>(3 * a.node) - a.at).squaredNorm();
        return e;
      }();
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
  scatterElementVectors(m, buf, f);
  addSpringForces(m, x, f);
}

void prepareTangentState(const FemModel& m, const Eigen::VectorXd& x, TangentState& state, Eigen::VectorXd* forces) {
  state.F.resize(m.tets.size());
  state.cache.resize(m.tets.size());
  thread_local std::vector<double> buffer;
  if (forces) buffer.resize(m.tets.size() * 9);
  double* const buf = buffer.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.tets.size(), 128), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t e = r.begin(); e < r.end(); ++e) {
      state.F[e] = deformationGradient(m, e, x);
      state.cache[e] = prepareTangent(m.model[e], state.F[e]);
      if (forces)
        Eigen::Map<Eigen::Matrix3d>(buf + 9 * e) =
            -m.restVolume[e] * firstPiola(m.model[e], m.lame[e], state.F[e], state.cache[e]) * m.Bm[e].transpose();
    }
  });
  if (forces) {
    Eigen::VectorXd& f = *forces;
    if (f.size() != x.size()) f.resize(x.size());
    f.setZero();
    scatterElementVectors(m, buf, f);
    addSpringForces(m, x, f);
  }
  state.springHessian.resize(m.springs.size());
  for (std::size_t i = 0; i < m.springs.size(); ++i) state.springHessian[i] = springHessian(m.springs[i], springVector(m.springs[i], x));
}

namespace {
// out = K v from per-element first Piola differentials dP(e, dF) and per-spring Hessians (the one pass over the
// elements that applyStiffness and applyStiffnessPair share: elements in parallel into a buffer, then a serial
// scatter).
template <class ElementDifferential, class SpringHessian>
void applyTangent(const FemModel& m, const Eigen::VectorXd& v, Eigen::VectorXd& out, ElementDifferential dP,
                  SpringHessian hessian, double anchorScale) {
  if (out.size() != v.size()) out.resize(v.size());
  out.setZero();
  thread_local std::vector<double> buffer;
  buffer.resize(m.tets.size() * 9);
  double* const buf = buffer.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.tets.size(), 128), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t e = r.begin(); e < r.end(); ++e) {
      const Eigen::Matrix3d dF = deformationGradient(m, e, v);  // the gradient of the direction field
      Eigen::Map<Eigen::Matrix3d>(buf + 9 * e) = m.restVolume[e] * dP(e, dF) * m.Bm[e].transpose();  // d(dE/dx_{1..3})
    }
  });
  scatterElementVectors(m, buf, out);
  for (std::size_t i = 0; i < m.springs.size(); ++i) {
    const auto& sp = m.springs[i];
    const Eigen::Vector3d hd = hessian(i) * springVector(sp, v);
    for (int k = 0; k < 8; ++k) out.segment<3>(3 * sp.nodes[k]) += sp.weights[k] * hd;
  }
  for (const auto& a : m.anchors) out.segment<3>(3 * a.node) += (anchorScale * a.stiffness) * v.segment<3>(3 * a.node);
}
}  // namespace

void applyStiffness(const FemModel& m, const TangentState& state, const Eigen::VectorXd& v, Eigen::VectorXd& out) {
  applyTangent(
      m, v, out,
      [&](std::size_t e, const Eigen::Matrix3d& dF) {
        return firstPiolaDifferential(m.model[e], m.lame[e], state.F[e], state.cache[e], dF);
      },
      [&](std::size_t i) -> const Eigen::Matrix3d& { return state.springHessian[i]; }, 1.0);
}

void applyStiffnessPair(const FemModel& m, const TangentState& atA, double a, const TangentState& atB, double b,
                        const Eigen::VectorXd& v, Eigen::VectorXd& out) {
  applyTangent(
      m, v, out,
      [&](std::size_t e, const Eigen::Matrix3d& dF) -> Eigen::Matrix3d {
        return a * firstPiolaDifferential(m.model[e], m.lame[e], atA.F[e], atA.cache[e], dF) +
               b * firstPiolaDifferential(m.model[e], m.lame[e], atB.F[e], atB.cache[e], dF);
      },
      [&](std::size_t i) -> Eigen::Matrix3d { return a * atA.springHessian[i] + b * atB.springHessian[i]; }, a + b);
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
// F and its tangent cache are the caller's (stressTangentDefinite reads the same ones).
void elementStiffness(const FemModel& m, std::size_t e, const Eigen::Matrix3d& F, const TangentCache& cache,
                      double* out) {
  const Eigen::Matrix3d BmT = m.Bm[e].transpose();
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

// Projected Newton's element tangent: the 12x12 matrix with its negative eigenvalues set to zero, only where the
// element's stress tangent dP/dF (9x9) is not positive definite (a Cholesky fails). Where it is, the matrix
// V G^T (dP/dF) G is positive semi-definite already and stays as elementStiffness wrote it: the eigen-decomposition
// runs for the few inverted or strongly compressed elements, not for all (where it changed only rounding).
void projectElementTangent(double* out) {
  Eigen::Map<Eigen::Matrix<double, 12, 12>> Ke(out);
  const Eigen::Matrix<double, 12, 12> sym = 0.5 * (Ke + Ke.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eig(sym);
  if (eig.eigenvalues().minCoeff() < 0)
    Ke = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
}
bool stressTangentDefinite(const FemModel& m, std::size_t e, const Eigen::Matrix3d& F, const TangentCache& cache) {
  Eigen::Matrix<double, 9, 9> H;
  for (int j = 0; j < 9; ++j) {
    Eigen::Matrix3d dF = Eigen::Matrix3d::Zero();
    dF(j % 3, j / 3) = 1.0;
    const Eigen::Matrix3d dP = firstPiolaDifferential(m.model[e], m.lame[e], F, cache, dF);
    H.col(j) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dP.data());
  }
  return Eigen::LLT<Eigen::Matrix<double, 9, 9>>(0.5 * (H + H.transpose())).info() == Eigen::Success;
}
}  // namespace

void assembleStiffness(const FemModel& m, const Eigen::VectorXd& x, Eigen::SparseMatrix<double>& K,
                       TangentProjection projection) {
  const bool projectDefinite = projection != TangentProjection::None;
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
    for (long e = r.begin(); e < r.end(); ++e) {
      const auto i = static_cast<std::size_t>(e);
      const Eigen::Matrix3d F = deformationGradient(m, i, x);
      const TangentCache cache = prepareTangent(m.model[i], F);
      elementStiffness(m, i, F, cache, buf + 144 * e);
      if (projection == TangentProjection::Checked) {
        if (!stressTangentDefinite(m, i, F, cache)) projectElementTangent(buf + 144 * e);
      } else if (projectDefinite) {
        projectElementTangent(buf + 144 * e);  // every element, as sessions recorded before Checked ran
      }
    }
  });
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const double* b = buffer.data() + 144 * e;
    const auto& slot = m.elementSlots[e];
    for (int i = 0; i < 144; ++i) values[slot[i]] += b[i];
  }
  for (std::size_t e = 0; e < m.springs.size(); ++e) {
    const auto& sp = m.springs[e];
    Eigen::Matrix3d H = springHessian(sp, springVector(sp, x));
    if (projectDefinite) {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(H);
      H = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
    }
    const auto& slot = m.springSlots[e];
    for (int c = 0; c < 24; ++c)
      for (int r = 0; r < 24; ++r) values[slot[24 * c + r]] += sp.weights[r / 3] * sp.weights[c / 3] * H(r % 3, c % 3);
  }
  for (const auto& a : m.anchors)
    for (int d = 0; d < 3; ++d) values[m.diagonalSlot[static_cast<std::size_t>(3 * a.node + d)]] += a.stiffness;
}

Eigen::SparseMatrix<double> elasticStiffness(const FemModel& m, const Eigen::VectorXd& x) {
  Eigen::SparseMatrix<double> K = m.pattern;
  assembleStiffness(m, x, K);
  return K;
}

namespace {
Eigen::Matrix3d deformation(const FemModel& m, std::size_t e, const Eigen::VectorXd& x) {
  const auto& t = m.tets[e];
  Eigen::Matrix3d Ds;
  for (int k = 0; k < 3; ++k) Ds.col(k) = x.segment<3>(3 * t[k + 1]) - x.segment<3>(3 * t[0]);
  return Ds * m.Bm[e];
}
// Sum of the elementwise product of cof(A) with B: d/ds det(A + s B) at s = 0.
double cofactorDot(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  return A.col(1).cross(A.col(2)).dot(B.col(0)) + A.col(2).cross(A.col(0)).dot(B.col(1)) + A.col(0).cross(A.col(1)).dot(B.col(2));
}
}  // namespace

VolumeRatios volumeRatios(const FemModel& m, const Eigen::VectorXd& x, std::vector<int>* inverted) {
  VolumeRatios out;
  if (inverted) inverted->clear();
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const double J = deformation(m, e, x).determinant();
    if (!(J > 0)) {
      ++out.inverted;
      if (inverted) inverted->push_back(static_cast<int>(e));
    }
    if (out.smallestElement < 0 || J < out.smallest || std::isnan(J)) {
      out.smallest = J;
      out.smallestElement = static_cast<int>(e);
    }
  }
  return out;
}

bool guardsInversion(MaterialModel m) {
  return m == MaterialModel::Linear || m == MaterialModel::Corotational || m == MaterialModel::NeoHookeanSplit;
}

namespace {
// One element's limit along x + s dx on [0, 1] (1 when it does not limit the move): the first root of its cubic.
double elementInversionLimit(const FemModel& m, std::size_t e, const Eigen::VectorXd& x, const Eigen::VectorXd& dx,
                             const Eigen::VectorXd& reference, bool own, const InversionFloor& f) {
  constexpr double L = 1.0;
  if (!guardsInversion(m.model[e])) return L;
  const Eigen::Matrix3d F = deformation(m, e, x);
  const double J = F.determinant();
  const double start = own ? J : deformation(m, e, reference).determinant();
  if (!(J > 0) || !(start > 0)) return L;  // inverted already: its law pushes it back, nothing to keep
  // Below the floor at the start already (a state given so, or a guarded move stopped there): it may not shrink.
  const double floor = start > f.smallest ? std::max(f.eta * start, f.smallest) : (1 - 1e-9) * start;
  const Eigen::Matrix3d G = deformation(m, e, dx);
  // p(s) = det(F + s G) - floor = c0 + c1 s + c2 s^2 + c3 s^3 on [0, L]: its first root is this element's limit.
  double c0 = J - floor;
  const double c1 = cofactorDot(F, G), c2 = cofactorDot(G, F), c3 = G.determinant();
  double elementLimit = L;
  if (!(c0 > 0)) {
    // At its floor (an earlier move stopped there): it may grow, not shrink.
    if (c1 < 0 || (c1 == 0 && c2 < 0)) elementLimit = 0;
    c0 = 0;
  }
  if (elementLimit > 0 && c0 - std::abs(c1) * L - std::abs(c2) * L * L - std::abs(c3) * L * L * L <= 0) {
    auto p = [&](double s) { return c0 + s * (c1 + s * (c2 + s * c3)); };
    // Monotone pieces between the roots of p'(s) = c1 + 2 c2 s + 3 c3 s^2; the first piece whose end is not positive
    // holds the root.
    double cuts[4] = {0, L, L, L};
    int n = 1;
    const double a = 3 * c3, b = 2 * c2, c = c1;
    if (a != 0) {
      const double disc = b * b - 4 * a * c;
      if (disc >= 0) {
        const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
        double r1 = q != 0 ? q / a : 0, r2 = q != 0 ? c / q : 0;
        if (r1 > r2) std::swap(r1, r2);
        for (double r : {r1, r2})
          if (r > 0 && r < L) cuts[n++] = r;
      }
    } else if (b != 0) {
      const double r = -c / b;
      if (r > 0 && r < L) cuts[n++] = r;
    }
    cuts[n++] = L;
    for (int k = 1; k < n; ++k) {
      double lo = cuts[k - 1], hi = cuts[k];
      if (p(hi) > 0) continue;
      for (int it = 0; it < 100 && hi - lo > 1e-14; ++it) {
        const double mid = 0.5 * (lo + hi);
        (p(mid) > 0 ? lo : hi) = mid;
      }
      elementLimit = lo;  // p(lo) > 0 (or lo = 0 at the floor): the element keeps its floor up to here
      break;
    }
  }
  return elementLimit;
}
}  // namespace

double inversionFreeStep(const FemModel& m, const Eigen::VectorXd& x, const Eigen::VectorXd& dx,
                         const InversionFloor& f, std::vector<int>* limiting) {
  if (limiting) limiting->clear();
  const Eigen::VectorXd& reference = f.reference && f.reference->size() == x.size() ? *f.reference : x;
  const bool own = &reference == &x;
  // The elements in parallel into a buffer (each its own limit), then a serial pass in element order: the same
  // answer and list every run. The calling thread's buffer is reused between calls (no allocation once sized).
  thread_local std::vector<double> buffer;
  buffer.resize(m.tets.size());
  double* const limits = buffer.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.tets.size(), 256),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t e = r.begin(); e < r.end(); ++e)
                        limits[e] = elementInversionLimit(m, e, x, dx, reference, own, f);
                    });
  double limit = 1.0;
  for (std::size_t e = 0; e < m.tets.size(); ++e)
    if (limits[e] < 1.0) {
      limit = std::min(limit, limits[e]);
      if (limiting) limiting->push_back(static_cast<int>(e));
    }
  return limit;
}

}  // namespace rehearse::simcore

namespace rehearse::simcore::detail {
namespace {
void addToPatch(const NodePatch& p, int node, const Eigen::Vector3d& v, Eigen::VectorXd& out) {
  const int l = p.local[static_cast<std::size_t>(node)];
  if (l >= 0) out.segment<3>(3 * l) += v;
}
// An element's 3x3 block (columns: nodes 1..3; node 0 takes minus their sum) onto the patch's rows, as
// scatterElementVectors does onto the model's.
void addElementToPatch(const FemModel& m, const NodePatch& p, std::size_t e, const Eigen::Matrix3d& H, Eigen::VectorXd& out) {
  const auto& t = m.tets[e];
  for (int k = 0; k < 3; ++k) {
    addToPatch(p, t[k + 1], H.col(k), out);
    addToPatch(p, t[0], -H.col(k), out);
  }
}
}  // namespace

void completePatch(const FemModel& m, NodePatch& p) {
  p.local.assign(m.nodeCount(), -1);
  for (std::size_t i = 0; i < p.nodes.size(); ++i) p.local[static_cast<std::size_t>(p.nodes[i])] = static_cast<int>(i);
  auto in = [&](int n) { return n >= 0 && p.local[static_cast<std::size_t>(n)] >= 0; };
  p.elements.clear();
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const auto& t = m.tets[e];
    if (in(t[0]) || in(t[1]) || in(t[2]) || in(t[3])) p.elements.push_back(static_cast<int>(e));
  }
  p.springs.clear();
  for (std::size_t i = 0; i < m.springs.size(); ++i)
    for (int k = 0; k < 8; ++k)
      if (m.springs[i].weights[k] != 0 && in(m.springs[i].nodes[k])) {
        p.springs.push_back(static_cast<int>(i));
        break;
      }
  p.anchors.clear();
  for (std::size_t i = 0; i < m.anchors.size(); ++i)
    if (in(m.anchors[i].node)) p.anchors.push_back(static_cast<int>(i));
}

void patchForces(const FemModel& m, const NodePatch& p, const Eigen::VectorXd& x, Eigen::VectorXd& fB) {
  fB.setZero(3 * static_cast<Eigen::Index>(p.nodes.size()));
  auto add = [&](int node, const Eigen::Vector3d& v) { addToPatch(p, node, v, fB); };
  for (int e : p.elements) {
    const auto i = static_cast<std::size_t>(e);
    addElementToPatch(m, p, i,
                      -m.restVolume[i] * firstPiola(m.model[i], m.lame[i], deformationGradient(m, i, x)) * m.Bm[i].transpose(),
                      fB);
  }
  for (int a : p.anchors) {
    const NodeAnchor& an = m.anchors[static_cast<std::size_t>(a)];
    add(an.node, -an.stiffness * (x.segment<3>(3 * an.node) - an.at));
  }
  for (int i : p.springs) {
    const EmbeddedSpring& sp = m.springs[static_cast<std::size_t>(i)];
    const Eigen::Vector3d d = springVector(sp, x);
    const double l = d.norm();
    if (!(l > 0)) continue;
    const Eigen::Vector3d g = sp.stiffness * (l - sp.restLength) / l * d;
    for (int k = 0; k < 8; ++k) add(sp.nodes[k], -sp.weights[k] * g);
  }
}

double patchEnergy(const FemModel& m, const NodePatch& p, const Eigen::VectorXd& x) {
  double e = 0;
  for (int t : p.elements) {
    const auto i = static_cast<std::size_t>(t);
    e += m.restVolume[i] * energyDensity(m.model[i], m.lame[i], deformationGradient(m, i, x));
  }
  for (int i : p.springs) {
    const EmbeddedSpring& sp = m.springs[static_cast<std::size_t>(i)];
    const double l = springVector(sp, x).norm() - sp.restLength;
    e += 0.5 * sp.stiffness * l * l;
  }
  for (int a : p.anchors) {
    const NodeAnchor& an = m.anchors[static_cast<std::size_t>(a)];
    e += 0.5 * an.stiffness * (x.segment<3>(3 * an.node) - an.at).squaredNorm();
  }
  return e;
}

void patchStiffness(const FemModel& m, const NodePatch& p, const Eigen::VectorXd& x, TangentProjection projection,
                    double scale, std::vector<Eigen::Triplet<double>>& out) {
  double Ke[144];
  for (int e : p.elements) {
    const auto i = static_cast<std::size_t>(e);
    const Eigen::Matrix3d F = deformationGradient(m, i, x);
    const TangentCache cache = prepareTangent(m.model[i], F);
    elementStiffness(m, i, F, cache, Ke);
    if (projection == TangentProjection::Checked) {
      if (!stressTangentDefinite(m, i, F, cache)) projectElementTangent(Ke);
    } else if (projection != TangentProjection::None) {
      projectElementTangent(Ke);
    }
    const auto& t = m.tets[i];
    for (int c = 0; c < 12; ++c) {
      const int lc = p.local[static_cast<std::size_t>(t[c / 3])];
      if (lc < 0) continue;
      for (int r = 0; r < 12; ++r) {
        const int lr = p.local[static_cast<std::size_t>(t[r / 3])];
        if (lr >= 0) out.emplace_back(3 * lr + r % 3, 3 * lc + c % 3, scale * Ke[12 * c + r]);
      }
    }
  }
  for (int i : p.springs) {
    const EmbeddedSpring& sp = m.springs[static_cast<std::size_t>(i)];
    Eigen::Matrix3d H = springHessian(sp, springVector(sp, x));
    if (projection != TangentProjection::None) {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(H);
      H = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
    }
    for (int c = 0; c < 8; ++c) {
      const int lc = p.local[static_cast<std::size_t>(sp.nodes[c])];
      if (lc < 0 || sp.weights[c] == 0) continue;
      for (int r = 0; r < 8; ++r) {
        const int lr = p.local[static_cast<std::size_t>(sp.nodes[r])];
        if (lr < 0 || sp.weights[r] == 0) continue;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            out.emplace_back(3 * lr + a, 3 * lc + b, scale * sp.weights[r] * sp.weights[c] * H(a, b));
      }
    }
  }
  for (int a : p.anchors) {
    const NodeAnchor& an = m.anchors[static_cast<std::size_t>(a)];
    const int l = p.local[static_cast<std::size_t>(an.node)];
    for (int d = 0; d < 3; ++d) out.emplace_back(3 * l + d, 3 * l + d, scale * an.stiffness);
  }
}

void patchStiffnessProduct(const FemModel& m, const NodePatch& p, const TangentState& at, const Eigen::VectorXd& v,
                           Eigen::VectorXd& outB) {
  outB.setZero(3 * static_cast<Eigen::Index>(p.nodes.size()));
  auto add = [&](int node, const Eigen::Vector3d& w) { addToPatch(p, node, w, outB); };
  for (int e : p.elements) {
    const auto i = static_cast<std::size_t>(e);
    const Eigen::Matrix3d dF = deformationGradient(m, i, v);
    addElementToPatch(
        m, p, i,
        m.restVolume[i] * firstPiolaDifferential(m.model[i], m.lame[i], at.F[i], at.cache[i], dF) * m.Bm[i].transpose(),
        outB);
  }
  for (int i : p.springs) {
    const EmbeddedSpring& sp = m.springs[static_cast<std::size_t>(i)];
    const Eigen::Vector3d hd = at.springHessian[static_cast<std::size_t>(i)] * springVector(sp, v);
    for (int k = 0; k < 8; ++k) add(sp.nodes[k], sp.weights[k] * hd);
  }
  for (int a : p.anchors) {
    const NodeAnchor& an = m.anchors[static_cast<std::size_t>(a)];
    add(an.node, an.stiffness * v.segment<3>(3 * an.node));
  }
}

}  // namespace rehearse::simcore::detail
