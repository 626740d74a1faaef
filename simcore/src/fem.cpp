#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/quality.hpp>

#include <Eigen/LU>

#include <cmath>

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
  return m;
}

Eigen::VectorXd FemModel::restVector() const {
  Eigen::VectorXd x(3 * rest.size());
  for (std::size_t i = 0; i < rest.size(); ++i) x.segment<3>(3 * i) = rest[i];
  return x;
}

double elasticEnergy(const FemModel& m, const Eigen::VectorXd& x) {
  double e = 0;
  for (std::size_t t = 0; t < m.tets.size(); ++t)
    e += m.restVolume[t] * energyDensity(m.model[t], m.lame[t], deformationGradient(m, t, x));
  return e;
}

Eigen::VectorXd elasticForces(const FemModel& m, const Eigen::VectorXd& x) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(x.size());
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const Eigen::Matrix3d P = firstPiola(m.model[e], m.lame[e], deformationGradient(m, e, x));
    // dE/dx_{1..3} = V P Bm^T (columns); node 0 balances them.
    const Eigen::Matrix3d H = -m.restVolume[e] * P * m.Bm[e].transpose();
    const auto& t = m.tets[e];
    for (int k = 0; k < 3; ++k) {
      f.segment<3>(3 * t[k + 1]) += H.col(k);
      f.segment<3>(3 * t[0]) -= H.col(k);
    }
  }
  return f;
}

Eigen::SparseMatrix<double> elasticStiffness(const FemModel& m, const Eigen::VectorXd& x) {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(m.tets.size() * 144);
  for (std::size_t e = 0; e < m.tets.size(); ++e) {
    const auto& t = m.tets[e];
    const Eigen::Matrix3d F = deformationGradient(m, e, x);
    const Eigen::Matrix3d BmT = m.Bm[e].transpose();
    const TangentCache cache = prepareTangent(m.model[e], F);
    for (int a = 0; a < 4; ++a)
      for (int d = 0; d < 3; ++d) {
        // Direction: node a moves along axis d.
        Eigen::Matrix3d dDs = Eigen::Matrix3d::Zero();
        if (a == 0) dDs.row(d).setConstant(-1.0);
        else dDs(d, a - 1) = 1.0;
        const Eigen::Matrix3d dP = firstPiolaDifferential(m.model[e], m.lame[e], F, cache, dDs * m.Bm[e]);
        const Eigen::Matrix3d dH = m.restVolume[e] * dP * BmT;  // change of dE/dx_{1..3}
        const int col = 3 * t[a] + d;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int k = 0; k < 3; ++k) {
          for (int r = 0; r < 3; ++r) triplets.emplace_back(3 * t[k + 1] + r, col, dH(r, k));
          sum += dH.col(k);
        }
        for (int r = 0; r < 3; ++r) triplets.emplace_back(3 * t[0] + r, col, -sum[r]);
      }
  }
  Eigen::SparseMatrix<double> K(x.size(), x.size());
  K.setFromTriplets(triplets.begin(), triplets.end());
  return K;
}

}  // namespace rehearse::simcore
