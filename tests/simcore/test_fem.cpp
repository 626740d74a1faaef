// FEM element level: every material's stress against finite differences of its energy and its
// tangent against finite differences of its stress; assembled forces and stiffness against finite
// differences on a real mesh; the patch test; rotation invariance; agreement at small strain.
#include "test_support.hpp"

#include "phantom/phantom.hpp"

#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/integrator.hpp>

#include "fem_patch.hpp"  // simcore/src/physics: the nonlinear elimination's patch (issue 61)

#include <Eigen/SparseCholesky>

#include <random>

using namespace rehearse::simcore;

namespace {
const MaterialModel kModels[] = {MaterialModel::Linear, MaterialModel::Corotational, MaterialModel::StVK, MaterialModel::NeoHookean,
                                 MaterialModel::NeoHookeanSplit};

Eigen::Matrix3d randomMatrix(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Eigen::Matrix3d m;
  for (int i = 0; i < 9; ++i) m(i) = u(rng);
  return m;
}

// dW/dF by central differences of the energy density (step h in each entry of F).
Eigen::Matrix3d stressByDifferences(MaterialModel m, const Lame& p, const Eigen::Matrix3d& F, double h) {
  Eigen::Matrix3d fd;
  for (int i = 0; i < 9; ++i) {
    Eigen::Matrix3d Fp = F, Fm = F;
    Fp(i) += h;
    Fm(i) -= h;
    fd(i) = (energyDensity(m, p, Fp) - energyDensity(m, p, Fm)) / (2 * h);
  }
  return fd;
}

// Deformation gradients to test at: near identity, large rotation with stretch, strong compression,
// and (for the models defined there) inverted.
std::vector<Eigen::Matrix3d> testGradients(std::mt19937& rng) {
  std::vector<Eigen::Matrix3d> Fs;
  Fs.push_back(Eigen::Matrix3d::Identity() + randomMatrix(rng, 0.05));
  const Eigen::Matrix3d R = Eigen::AngleAxisd(2.5, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  Fs.push_back(R * (Eigen::Matrix3d::Identity() * 1.2 + randomMatrix(rng, 0.2)));
  Fs.push_back(Eigen::Vector3d(0.3, 1.4, 0.9).asDiagonal().toDenseMatrix() + randomMatrix(rng, 0.05));
  Eigen::Matrix3d inv = Eigen::Matrix3d::Identity() + randomMatrix(rng, 0.1);
  inv.col(2) *= -0.5;  // inverted: det < 0
  Fs.push_back(inv);
  return Fs;
}

// The phantom's vessel wall as its own surface (the faces between the vessels and the parenchyma, with only the points
// they use), shrunk by 10 % about its centre so its vertices fall inside tets.
template <class Case>
Mesh vesselWall(const Case& c) {
  Mesh wall;
  wall.points = c.volume.points;
  wall.unitToMetre = c.volume.unitToMetre;
  wall.triangles = c.innerSurface;
  wall.compact();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : wall.points) centre += p / wall.points.size();
  for (auto& p : wall.points) p = centre + 0.9 * (p - centre);
  return wall;
}
}  // namespace

class TestFem : public QObject {
  Q_OBJECT
 private slots:
  void stressIsEnergyGradient() {
    std::mt19937 rng(3);
    const Lame p = Lame::fromYoung(27e3, 0.4);
    for (auto m : kModels)
      for (const auto& F : testGradients(rng)) {
        if (m == MaterialModel::NeoHookeanSplit && F.determinant() <= 0) continue;  // not defined there
        const Eigen::Matrix3d P = firstPiola(m, p, F);
        const Eigen::Matrix3d fd = stressByDifferences(m, p, F, 1e-6);
        const double err = (fd - P).norm() / std::max(1.0, P.norm());
        QVERIFY2(err < 1e-6, qPrintable(QString("%1: relative error %2").arg(QString::fromStdString(toString(m))).arg(err)));
        QVERIFY(P.allFinite());
      }
  }

  void tangentIsStressDerivative() {
    std::mt19937 rng(5);
    const Lame p = Lame::fromYoung(250e3, 0.45);
    for (auto m : kModels)
      for (const auto& F : testGradients(rng)) {
        const Eigen::Matrix3d dF = randomMatrix(rng, 1.0);
        if (m == MaterialModel::NeoHookeanSplit && F.determinant() <= 0) continue;  // not defined there
        const double h = 1e-6;
        const Eigen::Matrix3d fd = (firstPiola(m, p, F + h * dF) - firstPiola(m, p, F - h * dF)) / (2 * h);
        const Eigen::Matrix3d an = firstPiolaDifferential(m, p, F, dF);
        const double err = (fd - an).norm() / std::max(1.0, an.norm());
        QVERIFY2(err < 1e-5, qPrintable(QString("%1: relative error %2").arg(QString::fromStdString(toString(m))).arg(err)));
      }
  }

  // Projected Newton's tangent (TangentProjection::Checked): on one element deformed by each test gradient, against a
  // reference made here from finite differences of the stress: dP/dF column by column, mapped to the 12 nodal moves,
  // the element matrix's negative eigenvalues set to zero. Where dP/dF is positive definite the element's matrix is the
  // unprojected one bit for bit. On the phantom with 2 mm of noise (inverted slivers), the projected tangent plus the
  // mass matrix over a 1 s step factorises where the unprojected one does not, for both projections.
  void checkedProjectionClampsIndefiniteElements() {
    std::mt19937 rng(7);
    const MaterialParams params{MaterialModel::Corotational, 250e3, 0.45, 1000};
    const Lame p = Lame::fromYoung(params.young, params.poisson);
    int clamped = 0, kept = 0;
    for (auto model : kModels)
      for (const auto& F : testGradients(rng)) {
        if (model == MaterialModel::NeoHookeanSplit && F.determinant() <= 0) continue;  // not defined there
        rehearse::simcore::Mesh tet;
        tet.points = {{0, 0, 0}, {0.01, 0, 0}, {0.002, 0.012, 0}, {0.003, 0.002, 0.009}};
        tet.tets = {{0, 1, 2, 3}};
        tet.tetLabels = {1};
        MaterialParams mp = params;
        mp.model = model;
        const FemModel m = FemModel::build(tet, {}, mp);
        Eigen::VectorXd x(12);
        for (int i = 0; i < 4; ++i) x.segment<3>(3 * i) = F * tet.points[static_cast<std::size_t>(i)];
        Eigen::SparseMatrix<double> K, Kp;
        assembleStiffness(m, x, K);
        assembleStiffness(m, x, Kp, TangentProjection::Checked);
        // The reference: dP/dF by central differences of P, symmetrised; G from the rest edges.
        Eigen::Matrix<double, 9, 9> H;
        const double h = 1e-7;
        for (int j = 0; j < 9; ++j) {
          Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
          E(j % 3, j / 3) = h;
          const Eigen::Matrix3d dP = (firstPiola(model, p, F + E) - firstPiola(model, p, F - E)) / (2 * h);
          H.col(j) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dP.data());
        }
        H = (0.5 * (H + H.transpose())).eval();
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> eig(H);
        const bool definite = eig.eigenvalues().minCoeff() > 1e-6 * eig.eigenvalues().cwiseAbs().maxCoeff();
        Eigen::Matrix3d Dm;
        for (int c = 0; c < 3; ++c) Dm.col(c) = tet.points[static_cast<std::size_t>(c + 1)] - tet.points[0];
        const Eigen::Matrix3d Bm = Dm.inverse();
        Eigen::Matrix<double, 9, 12> G = Eigen::Matrix<double, 9, 12>::Zero();
        for (int a = 0; a < 4; ++a)
          for (int d = 0; d < 3; ++d) {
            const Eigen::RowVector3d row = a == 0 ? Eigen::RowVector3d(-Bm.colwise().sum()) : Eigen::RowVector3d(Bm.row(a - 1));
            Eigen::Matrix3d dF = Eigen::Matrix3d::Zero();
            dF.row(d) = row;  // moving node a along axis d by one changes row d of F by that row of Bm
            G.col(3 * a + d) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dF.data());
          }
        const double volume = std::abs(Dm.determinant()) / 6;
        const Eigen::Matrix<double, 12, 12> unclamped = volume * G.transpose() * H * G;
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> element(unclamped);
        const Eigen::Matrix<double, 12, 12> reference =
            definite ? unclamped
                     : Eigen::Matrix<double, 12, 12>(element.eigenvectors() *
                                                     element.eigenvalues().cwiseMax(0.0).asDiagonal() *
                                                     element.eigenvectors().transpose());
        const Eigen::Matrix<double, 12, 12> projected = Eigen::MatrixXd(Kp), plain = Eigen::MatrixXd(K);
        const double err = (projected - reference).norm() / reference.norm();
        const double smallest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>>(projected).eigenvalues().minCoeff();
        qInfo("%s, det F %.2f: dP/dF's smallest eigenvalue %.3g kPa, %s; against the reference %.1e; smallest "
              "eigenvalue of the element's matrix %.3g N/m",
              toString(model).c_str(), F.determinant(), 1e-3 * eig.eigenvalues().minCoeff(),
              definite ? "kept" : "clamped", err, smallest);
        QVERIFY2(err < 1e-5, qPrintable(QString::number(err)));
        QVERIFY(smallest > -1e-9 * projected.norm());
        if (definite) {
          QVERIFY((projected - plain).cwiseAbs().maxCoeff() == 0);
          ++kept;
        } else {
          ++clamped;
        }
      }
    QVERIFY(clamped >= 3 && kept >= 3);  // both branches met
    // The whole phantom, noisy, with the mass matrix over a time step of 1 s added (the rigid motions need it).
    auto c = rehearse::phantom::makePhantom();
    std::mt19937 noise(13);
    std::normal_distribution<double> n(0, 1);
    const FemModel m = FemModel::build(c.volume, {}, params);
    Eigen::VectorXd x = m.restVector();
    for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += 0.002 * n(noise);
    auto factorises = [&](TangentProjection projection) {
      Eigen::SparseMatrix<double> K;
      assembleStiffness(m, x, K, projection);
      for (Eigen::Index i = 0; i < K.rows(); ++i) K.coeffRef(i, i) += m.lumpedMass[i / 3];
      Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> llt(K);
      return llt.info() == Eigen::Success;
    };
    QVERIFY(!factorises(TangentProjection::None));
    QVERIFY(factorises(TangentProjection::Checked));
    QVERIFY(factorises(TangentProjection::Element));
  }

  // All nonlinear models are invariant to rotation: no stress in a rigidly rotated element.
  void rigidRotationIsStressFree() {
    const Lame p = Lame::fromYoung(1e6, 0.3);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(3.0, Eigen::Vector3d(0.3, 0.4, 1).normalized()).toRotationMatrix();
    for (auto m : {MaterialModel::Corotational, MaterialModel::StVK, MaterialModel::NeoHookean})
      QVERIFY2(firstPiola(m, p, R).norm() < 1e-6, qPrintable(QString::fromStdString(toString(m))));
    // The linear model is not: a 180 degree rotation looks like a huge strain to it (why "large" exists).
    QVERIFY(firstPiola(MaterialModel::Linear, p, R).norm() > 1e5);
  }

  // The polar decomposition F = R S (Higham's scaled Newton, then Newton-Schulz; issue 34) against the one from Eigen's
  // SVD (R = U V^T, S = V Sigma V^T, det R = +1): strains from 1e-6 to 3x, any rotation, nearly flat and inverted
  // elements (the SVD fallback), 2,000 draws each.
  void polarDecompositionMatchesTheSvd() {
    std::mt19937 rng(34);
    std::uniform_real_distribution<double> u(-1, 1);
    for (double strain : {1e-6, 1e-3, 0.05, 0.3, 1.0, 3.0})
      for (int k = 0; k < 2000; ++k) {
        const Eigen::Matrix3d Q =
            Eigen::AngleAxisd(3.14159 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized())
                .toRotationMatrix();
        Eigen::Matrix3d D;
        for (int i = 0; i < 9; ++i) D(i / 3, i % 3) = u(rng);
        Eigen::Matrix3d F = Q * (Eigen::Matrix3d::Identity() + strain * D);
        if (k % 50 == 0) F.col(2) = 0.4 * F.col(0) - 0.7 * F.col(1) + 1e-9 * F.col(2);  // nearly flat
        if (k % 50 == 1) F.col(0) = -F.col(0);                                          // inverted
        Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
        Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
        Eigen::Vector3d sigma = svd.singularValues();
        if ((U * V.transpose()).determinant() < 0) {  // the reflection goes into the smallest singular value
          U.col(2) *= -1;
          sigma[2] *= -1;
        }
        const Eigen::Matrix3d Rref = U * V.transpose(), Sref = V * sigma.asDiagonal() * V.transpose();
        Eigen::Matrix3d R, S;
        polarDecomposition(F, R, S);
        // Well separated singular values fix R to round-off; the nearly flat ones fix it only up to the conditioning.
        const double gap = std::min(std::abs(sigma[0] + sigma[1]), std::abs(sigma[1] + sigma[2])) / sigma[0];
        const double tol = 1e-13 / std::max(gap, 1e-9);
        QVERIFY2((R - Rref).norm() < tol, qPrintable(QString("strain %1 draw %2: |R - R_svd| = %3 (tolerance %4)")
                                                         .arg(strain)
                                                         .arg(k)
                                                         .arg((R - Rref).norm())
                                                         .arg(tol)));
        QVERIFY((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-14);
        QVERIFY(R.determinant() > 0);
        QVERIFY((S - Sref).norm() < 1e-12 * std::max(1.0, F.norm()) / std::max(gap, 1e-3));
      }
  }

  // At small strain every model is linear elasticity with the same E and nu.
  void smallStrainAgreement() {
    std::mt19937 rng(9);
    const Lame p = Lame::fromYoung(3e3, 0.3);
    const Eigen::Matrix3d H = randomMatrix(rng, 1.0);
    const double eps = 1e-6;
    const Eigen::Matrix3d ref = firstPiola(MaterialModel::Linear, p, Eigen::Matrix3d::Identity() + eps * H) / eps;
    for (auto m : kModels) {
      const Eigen::Matrix3d P = firstPiola(m, p, Eigen::Matrix3d::Identity() + eps * H) / eps;
      QVERIFY2((P - ref).norm() / ref.norm() < 1e-4, qPrintable(QString::fromStdString(toString(m))));
    }
  }

  // Assembled forces and stiffness on the phantom's mesh (two materials, 1000:1) against finite differences.
  void assemblyAgainstFiniteDifferences() {
    auto c = rehearse::phantom::makePhantom();
    std::mt19937 rng(13);
    std::normal_distribution<double> n(0, 1);
    for (auto model : kModels) {
      MaterialParams soft{model, 27e3, 0.4, 1000}, stiff{model, 27e6, 0.45, 1100};
      FemModel m = FemModel::build(c.volume, {{1, soft}, {2, stiff}}, soft);
      Eigen::VectorXd x = m.restVector();
      // 2 mm noise (it inverts the phantom's smallest slivers), or for the split Neo-Hookean, which is not
      // defined for inverted elements, a smooth 2 mm field.
      for (Eigen::Index i = 0; i < x.size(); ++i)
        x[i] += model == MaterialModel::NeoHookeanSplit ? 0.002 * std::sin(20 * m.rest[i / 3][(i + 1) % 3] + i % 3) : 0.002 * n(rng);
      const Eigen::VectorXd f = elasticForces(m, x);
      Eigen::VectorXd v(x.size());
      for (Eigen::Index i = 0; i < v.size(); ++i) v[i] = n(rng);
      const double h = 1e-7;
      // Directional derivative of the energy equals -f.v; of the forces equals -K v.
      const double dE = (elasticEnergy(m, x + h * v) - elasticEnergy(m, x - h * v)) / (2 * h);
      QVERIFY2(std::abs(dE + f.dot(v)) / std::max(1.0, std::abs(dE)) < 1e-5, qPrintable(QString::fromStdString(toString(model))));
      const Eigen::SparseMatrix<double> K = elasticStiffness(m, x);
      const Eigen::VectorXd df = (elasticForces(m, x + h * v) - elasticForces(m, x - h * v)) / (2 * h);
      const Eigen::VectorXd Kv = K * v;
      const double err = (df + Kv).norm() / Kv.norm();
      qInfo("%s: |df + K v| / |K v| = %.2e", toString(model).c_str(), err);
      QVERIFY(err < 1e-5);
      const Eigen::SparseMatrix<double> Kt = K.transpose();
      QVERIFY((K - Kt).norm() / K.norm() < 1e-12);  // symmetric
      // The matrix-free product (Rayleigh damping) equals the assembled one.
      TangentState ts;
      prepareTangentState(m, x, ts);
      Eigen::VectorXd Kv2;
      applyStiffness(m, ts, v, Kv2);
      QVERIFY2((Kv2 - Kv).norm() / Kv.norm() < 1e-12, qPrintable(QString::number((Kv2 - Kv).norm() / Kv.norm())));
    }
  }

  // Von Mises under small uniaxial stretch equals the axial stress E * eps (linear material, nu = 0.3).
  void vonMisesUniaxial() {
    auto c = rehearse::phantom::makePhantom();
    const double E = 27e3, nu = 0.3, eps = 1e-4;
    FemModel m = FemModel::build(c.volume, {}, {MaterialModel::Linear, E, nu, 1000});
    // Uniaxial stress: stretch x by eps, contract y and z by nu eps.
    Eigen::VectorXd x = m.restVector();
    for (std::size_t i = 0; i < m.nodeCount(); ++i) {
      x[3 * i] *= 1 + eps;
      x[3 * i + 1] *= 1 - nu * eps;
      x[3 * i + 2] *= 1 - nu * eps;
    }
    std::vector<double> vm;
    vonMisesStress(m, x, vm);
    QCOMPARE(vm.size(), m.tets.size());
    for (double v : vm) QVERIFY2(std::abs(v - E * eps) < 1e-3 * E * eps, qPrintable(QString::number(v)));
    // A rigid rotation of the corotational model: no stress.
    FemModel co = FemModel::build(c.volume, {}, {MaterialModel::Corotational, E, nu, 1000});
    const Eigen::Matrix3d R = Eigen::AngleAxisd(1.0, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    for (std::size_t i = 0; i < co.nodeCount(); ++i) x.segment<3>(3 * i) = R * co.rest[i];
    vonMisesStress(co, x, vm);
    for (double v : vm) QVERIFY(v < 1e-9 * E);
  }

  // Embedded inner surfaces: the mapping is exact for affine motion (both ways of the bi-directional
  // mapping: positions down, forces up through J^T, checked against finite differences of the energy),
  // and the embedded wall stiffens the organ.
  void embeddedSurfaces() {
    auto c = rehearse::phantom::makePhantom();
    QVERIFY(!c.innerSurface.empty());
    const Mesh wall = vesselWall(c);
    Mesh organ = c.volume;
    std::fill(organ.tetLabels.begin(), organ.tetLabels.end(), 1);  // no vessel label: the wall carries it
    const MaterialParams soft{MaterialModel::Linear, 27e3, 0.4, 1000};
    const FemModel m = FemModel::build(organ, {}, soft, {{wall, 620e3, 1e-3, "vessels"}});
    QCOMPARE(m.embeddings.size(), std::size_t(1));
    QVERIFY(!m.springs.empty());
    qInfo("vessel wall: %zu vertices, %zu springs, %zu outside the volume", wall.points.size(), m.springs.size(), m.embeddings[0].outside);
    QVERIFY(m.embeddings[0].outside < wall.points.size() / 50);
    // Positions down: exact at rest and under an affine map.
    std::vector<Eigen::Vector3d> mapped = mapEmbedded(m, 0, m.restVector());
    double worst = 0;
    for (std::size_t i = 0; i < mapped.size(); ++i) worst = std::max(worst, (mapped[i] - wall.points[i] * organ.unitToMetre).norm());
    QVERIFY2(worst < 1e-12, qPrintable(QString::number(worst)));
    Eigen::Matrix3d A;
    A << 1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.2;
    const Eigen::Vector3d b(0.01, -0.02, 0.03);
    Eigen::VectorXd x = m.restVector();
    for (std::size_t i = 0; i < m.nodeCount(); ++i) x.segment<3>(3 * i) = A * m.rest[i] + b;
    mapped = mapEmbedded(m, 0, x);
    worst = 0;
    for (std::size_t i = 0; i < mapped.size(); ++i) worst = std::max(worst, (mapped[i] - (A * wall.points[i] * organ.unitToMetre + b)).norm());
    QVERIFY2(worst < 1e-12, qPrintable(QString::number(worst)));
    // Forces up and stiffness: finite differences of the energy (springs included).
    std::mt19937 rng(5);
    std::normal_distribution<double> n(0, 1);
    x = m.restVector();
    for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += 0.002 * n(rng);
    Eigen::VectorXd v(x.size());
    for (Eigen::Index i = 0; i < v.size(); ++i) v[i] = n(rng);
    const double h = 1e-7;
    const Eigen::VectorXd f = elasticForces(m, x);
    const double dE = (elasticEnergy(m, x + h * v) - elasticEnergy(m, x - h * v)) / (2 * h);
    QVERIFY(std::abs(dE + f.dot(v)) / std::abs(dE) < 1e-6);
    const Eigen::SparseMatrix<double> K = elasticStiffness(m, x);
    const Eigen::VectorXd df = (elasticForces(m, x + h * v) - elasticForces(m, x - h * v)) / (2 * h);
    const Eigen::VectorXd Kv = K * v;
    QVERIFY2((df + Kv).norm() / Kv.norm() < 1e-5, qPrintable(QString::number((df + Kv).norm() / Kv.norm())));
    TangentState ts;
    prepareTangentState(m, x, ts);
    Eigen::VectorXd Kv2;
    applyStiffness(m, ts, v, Kv2);
    QVERIFY((Kv2 - Kv).norm() / Kv.norm() < 1e-12);
    // The springs' share of the stiffness is J^T K_s J: compare with the model without the wall.
    const FemModel bare = FemModel::build(organ, {}, soft);
    const Eigen::VectorXd springPart = K * v - elasticStiffness(bare, x) * v;
    QVERIFY(springPart.norm() > 1e-3 * Kv.norm());
  }

  // Issue 61: a patch of nodes (SimulationSettings::localElimination) has exactly the whole model's rows there: its
  // forces, its block of the stiffness (plain and projected), its rows of a tangent product, and the change of the
  // energy when only its nodes move. On the phantom with its vessel wall (springs), anchors on some nodes, a random
  // deformation and one element pushed inside out (the projection's case).
  void aPatchHasTheModelsRows() {
    auto c = rehearse::phantom::makePhantom();
    const Mesh wall = vesselWall(c);
    Mesh organ = c.volume;
    FemModel m = FemModel::build(organ, {}, {MaterialModel::Corotational, 27e3, 0.45, 1000}, {{wall, 620e3, 1e-3, "vessels"}});
    std::mt19937 rng(11);
    std::normal_distribution<double> n(0, 1);
    Eigen::VectorXd x = m.restVector();
    for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += 0.001 * n(rng);
    // The nodes within 25 mm of a node, and anchors on every third node of the model.
    const Eigen::Vector3d at = m.rest[static_cast<std::size_t>(c.volume.points.size() / 3)];
    detail::NodePatch p;
    for (std::size_t i = 0; i < m.nodeCount(); ++i)
      if ((m.rest[i] - at).norm() < 0.025) p.nodes.push_back(static_cast<int>(i));
    for (std::size_t i = 0; i < m.nodeCount(); i += 3) m.anchors.push_back({static_cast<int>(i), m.rest[i], 50.0});
    // One element of the patch inside out: its fourth node through the face of the other three.
    const auto& tet = m.tets[static_cast<std::size_t>([&] {
      for (std::size_t e = 0; e < m.tets.size(); ++e)
        if (std::find(p.nodes.begin(), p.nodes.end(), m.tets[e][3]) != p.nodes.end()) return e;
      return std::size_t(0);
    }())];
    const Eigen::Vector3d face = (x.segment<3>(3 * tet[0]) + x.segment<3>(3 * tet[1]) + x.segment<3>(3 * tet[2])) / 3;
    x.segment<3>(3 * tet[3]) = face - 0.5 * (x.segment<3>(3 * tet[3]) - face);
    detail::completePatch(m, p);
    const auto B = static_cast<Eigen::Index>(p.nodes.size());
    QVERIFY2(B > 20 && !p.springs.empty() && !p.anchors.empty(),
             qPrintable(QString("%1 nodes, %2 springs, %3 anchors").arg(B).arg(p.springs.size()).arg(p.anchors.size())));
    auto rows = [&](const Eigen::VectorXd& full) {
      Eigen::VectorXd out(3 * B);
      for (Eigen::Index l = 0; l < B; ++l) out.segment<3>(3 * l) = full.segment<3>(3 * p.nodes[static_cast<std::size_t>(l)]);
      return out;
    };
    Eigen::VectorXd fB;
    detail::patchForces(m, p, x, fB);
    const Eigen::VectorXd f = rows(elasticForces(m, x));
    QVERIFY2((fB - f).norm() <= 1e-12 * f.norm(), qPrintable(QString::number((fB - f).norm() / f.norm())));
    for (TangentProjection projection : {TangentProjection::None, TangentProjection::Checked}) {
      Eigen::SparseMatrix<double> K = m.pattern;
      assembleStiffness(m, x, K, projection);
      std::vector<Eigen::Triplet<double>> t;
      detail::patchStiffness(m, p, x, projection, 2.0, t);
      Eigen::SparseMatrix<double> KB(3 * B, 3 * B);
      KB.setFromTriplets(t.begin(), t.end());
      Eigen::MatrixXd block(3 * B, 3 * B);
      for (Eigen::Index a = 0; a < 3 * B; ++a)
        for (Eigen::Index b = 0; b < 3 * B; ++b)
          block(a, b) = K.coeff(3 * p.nodes[static_cast<std::size_t>(a / 3)] + a % 3, 3 * p.nodes[static_cast<std::size_t>(b / 3)] + b % 3);
      const double off = (Eigen::MatrixXd(KB) - 2.0 * block).norm() / (2.0 * block.norm());
      QVERIFY2(off < 1e-12, qPrintable(QString("projection %1: %2").arg(static_cast<int>(projection)).arg(off)));
    }
    TangentState ts;
    prepareTangentState(m, x, ts);
    Eigen::VectorXd v(x.size()), Kv, KvB;
    for (Eigen::Index i = 0; i < v.size(); ++i) v[i] = n(rng);
    applyStiffness(m, ts, v, Kv);
    detail::patchStiffnessProduct(m, p, ts, v, KvB);
    QVERIFY2((KvB - rows(Kv)).norm() <= 1e-12 * rows(Kv).norm(), qPrintable(QString::number((KvB - rows(Kv)).norm())));
    // Only the patch's nodes moved: the model's energy changes by what the patch's energy does.
    Eigen::VectorXd y = x;
    for (int node : p.nodes) y.segment<3>(3 * node) += 0.0005 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    const double whole = elasticEnergy(m, y) - elasticEnergy(m, x), part = detail::patchEnergy(m, p, y) - detail::patchEnergy(m, p, x);
    QVERIFY2(std::abs(whole - part) <= 1e-9 * std::abs(whole), qPrintable(QString("%1 J against %2 J").arg(whole).arg(part)));
  }

  // Patch test: under any affine deformation the forces on interior nodes vanish.
  void patchTest() {
    auto c = rehearse::phantom::makePhantom();
    std::vector<char> boundary(c.volume.points.size(), 0);
    for (const auto& t : c.surface)
      for (int v : t) boundary[v] = 1;
    Eigen::Matrix3d A;
    A << 1.1, 0.2, -0.05, 0.03, 0.9, 0.1, -0.1, 0.05, 1.05;
    const Eigen::Vector3d b(0.01, -0.02, 0.03);
    for (auto model : kModels) {
      FemModel m = FemModel::build(c.volume, {}, {model, 5e3, 0.35, 1000});
      Eigen::VectorXd x(3 * m.nodeCount());
      for (std::size_t i = 0; i < m.nodeCount(); ++i) x.segment<3>(3 * i) = A * m.rest[i] + b;
      const Eigen::VectorXd f = elasticForces(m, x);
      double interior = 0, boundaryMax = 0;
      for (std::size_t i = 0; i < m.nodeCount(); ++i) {
        const double fi = f.segment<3>(3 * i).norm();
        if (boundary[i]) boundaryMax = std::max(boundaryMax, fi);
        else interior = std::max(interior, fi);
      }
      qInfo("%s: largest interior force %.2e N, largest boundary force %.2e N", toString(model).c_str(), interior, boundaryMax);
      QVERIFY(interior < 1e-9 * boundaryMax);
    }
  }

  void invalidInputIsRefused() {
    Mesh flat;
    flat.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    flat.tets = {{0, 1, 2, 3}};
    flat.tetLabels = {1};
    QVERIFY_THROWS_EXCEPTION(MeshError, FemModel::build(flat, {}, {}));
    Mesh ok = flat;
    ok.points[3] = {0, 0, 1};
    QVERIFY_THROWS_EXCEPTION(MeshError, FemModel::build(ok, {}, {MaterialModel::Linear, 1e3, 0.5, 1000}));
    QVERIFY_THROWS_EXCEPTION(MeshError, FemModel::build(ok, {}, {MaterialModel::Linear, -1, 0.3, 1000}));
    QVERIFY_THROWS_EXCEPTION(MeshError, FemModel::build(Mesh{}, {}, {}));
    QVERIFY_THROWS_EXCEPTION(MeshError, materialModelFromString("rubber"));
    const auto m = FemModel::build(ok, {}, {MaterialModel::Linear, 1e3, 0.3, 1000});
    QVERIFY(std::abs(m.lumpedMass.sum() - 1000.0 / 6.0) < 1e-12);
  }

  // The corotational law's volume barrier (Lame::barrier; sessions set it: SimulationSettings::volumeBarrier). For
  // crushed elements (J from 0.02 to 0.28, rotated and sheared) its stress is its energy's gradient and its tangent the
  // stress's derivative (central differences), with and without a prepared tangent; at and above its J it changes not a
  // bit. And a tet whose apex is pushed towards its base by 1.5 times what the plain law resists at flat: the plain law
  // has no open equilibrium (its balance (2 mu + lambda)(s - 1) = -f a / V gives s = -0.5, inverted; the inversion guard
  // stops the solve at its floor, not converged), while with the barrier the static solve converges with the element
  // open (the apex slides aside as it sinks: a sheared rest, not the straight one), where the potential is stationary
  // by central differences of the energy alone and least.
  void volumeBarrierHoldsACrushedElement() {
    std::mt19937 rng(23);
    Lame plain = Lame::fromYoung(27e3, 0.4), p = plain;
    p.barrier = 0.3;
    const MaterialModel m = MaterialModel::Corotational;
    for (double s : {0.02, 0.1, 0.28}) {
      const Eigen::Matrix3d Q1 = Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, -0.5).normalized()).toRotationMatrix();
      const Eigen::Matrix3d Q2 = Eigen::AngleAxisd(-0.7, Eigen::Vector3d(0.3, -1, 2).normalized()).toRotationMatrix();
      Eigen::Matrix3d F = Q1 * Eigen::Vector3d(1.1, 0.9, s).asDiagonal().toDenseMatrix() * Q2;
      F += 0.01 * s * randomMatrix(rng, 1.0);  // a little shear
      QVERIFY(F.determinant() > 0 && F.determinant() < 0.3);
      const Eigen::Matrix3d P = firstPiola(m, p, F);
      QVERIFY(P.allFinite());
      QVERIFY((P - firstPiola(m, plain, F)).norm() > 1e-3 * P.norm());  // the barrier acts here
      QVERIFY((P - firstPiola(m, p, F, prepareTangent(m, F))).norm() <= 1e-12 * P.norm());
      const double h = 1e-7 * s;
      const Eigen::Matrix3d fd = stressByDifferences(m, p, F, h);
      QVERIFY2((fd - P).norm() < 1e-6 * P.norm(), qPrintable(QString("J %1: stress error %2").arg(F.determinant()).arg((fd - P).norm() / P.norm())));
      const Eigen::Matrix3d dF = randomMatrix(rng, 1.0);
      const Eigen::Matrix3d fdP = (firstPiola(m, p, F + h * dF) - firstPiola(m, p, F - h * dF)) / (2 * h);
      for (const Eigen::Matrix3d& an : {firstPiolaDifferential(m, p, F, dF), firstPiolaDifferential(m, p, F, prepareTangent(m, F), dF)})
        QVERIFY2((fdP - an).norm() < 1e-5 * an.norm(), qPrintable(QString("J %1: tangent error %2").arg(F.determinant()).arg((fdP - an).norm() / an.norm())));
    }
    for (const auto& F : testGradients(rng))
      if (F.determinant() >= 0.3) {
        QVERIFY(firstPiola(m, p, F) == firstPiola(m, plain, F));
        QVERIFY(energyDensity(m, p, F) == energyDensity(m, plain, F));
      }
    // The pushed tet: base nodes fixed, the apex pushed straight down by 1.5 times what the plain law resists at flat.
    const double a = 0.01;
    rehearse::simcore::Mesh tet;
    tet.points = {{0, 0, 0}, {a, 0, 0}, {0, a, 0}, {0, 0, a}};
    tet.tets = {{0, 1, 2, 3}};
    tet.tetLabels = {1};
    const double V = a * a * a / 6, force = 1.5 * (2 * plain.mu + plain.lambda) * V / a;
    for (bool withBarrier : {false, true}) {
      FemModel model = FemModel::build(tet, {}, {MaterialModel::Corotational, 27e3, 0.4, 1000});
      if (withBarrier) model.lame[0].barrier = 0.3;
      SimulationSettings settings;
      settings.gravity.setZero();
      settings.tolerance = 1e-8;
      settings.maxNewtonIterations = 200;
      settings.strict = false;
      Integrator integrator(model, {0, 1, 2}, settings);
      SimulationState state = integrator.initialState();
      Eigen::VectorXd push = Eigen::VectorXd::Zero(12);
      push[11] = -force;
      const StepReport r = integrator.solveStatic(state, push);
      Eigen::Matrix3d Ds;
      for (int k = 0; k < 3; ++k) Ds.col(k) = state.x.segment<3>(3 * (k + 1)) - state.x.head<3>();
      const double J = Ds.determinant() / (a * a * a);
      qInfo("%s: %s, J %.4g", withBarrier ? "with the barrier" : "the plain law", r.status.c_str(), J);
      if (!withBarrier) {  // the plain law cannot hold it open: its flat element resists less than the push
        QVERIFY2(r.outcome != StepStatus::Converged || J <= 0,
                 qPrintable(QString("plain law: %1 at J %2").arg(QString::fromStdString(r.status)).arg(J)));
        continue;
      }
      QVERIFY2(r.outcome == StepStatus::Converged, r.status.c_str());
      QVERIFY2(J > 0.01 && J < 0.3, qPrintable(QString("J %1").arg(J)));
      // At rest where the potential E(x) - f.x is stationary and least: its gradient at the apex by central
      // differences of the energy alone (not the forces the solve used) is the push to 1e-6, and no small move of the
      // apex lowers it.
      auto potential = [&](const Eigen::VectorXd& y) { return elasticEnergy(model, y) - push.dot(y); };
      for (int i = 9; i < 12; ++i) {
        const double h = 1e-8 * a;
        Eigen::VectorXd yp = state.x, ym = state.x;
        yp[i] += h;
        ym[i] -= h;
        const double g = (potential(yp) - potential(ym)) / (2 * h);
        QVERIFY2(std::abs(g) < 1e-6 * force, qPrintable(QString("dPotential/dx%1 = %2 N (push %3 N)").arg(i).arg(g).arg(force)));
      }
      for (int k = 0; k < 20; ++k) {
        Eigen::VectorXd y = state.x;
        y.tail<3>() += 1e-4 * a * Eigen::Vector3d(randomMatrix(rng, 1.0).col(0)).normalized();
        QVERIFY(potential(y) > potential(state.x));
      }
    }
  }

  // The inversion guard: along x + s dx up to the returned s, every guarded element keeps det F >= eta det F(x)
  // (checked by sampling det along the path, 65 points per element), the bound is tight (some element sits at
  // eta det F(x) when s < 1), unguarded laws never limit, and volumeRatios counts the elements a hand-made
  // reflection turned inside out.
  void inversionGuard() {
    auto c = rehearse::phantom::makePhantom();
    std::mt19937 rng(17);
    std::normal_distribution<double> n(0, 1);
    const double eta = 0.1;
    int limited = 0;
    for (auto model : {MaterialModel::Corotational, MaterialModel::Linear, MaterialModel::NeoHookeanSplit}) {
      const FemModel m = FemModel::build(c.volume, {}, {model, 3e3, 0.45, 1000});
      for (int trial = 0; trial < 6; ++trial) {
        const Eigen::VectorXd x = m.restVector();
        Eigen::VectorXd dx(x.size());
        const double size = 0.002 * (1 << trial);  // 2 mm to 64 mm random node moves
        for (Eigen::Index i = 0; i < dx.size(); ++i) dx[i] = size * n(rng);
        const double s = inversionFreeStep(m, x, dx, {nullptr, eta, 0.0});
        QVERIFY(s >= 0 && s <= 1);
        double tightest = 1e300;
        for (std::size_t e = 0; e < m.tets.size(); ++e) {
          auto det = [&](double t) {
            Eigen::Matrix3d Ds;
            for (int k = 0; k < 3; ++k)
              Ds.col(k) = (x + t * dx).segment<3>(3 * m.tets[e][k + 1]) - (x + t * dx).segment<3>(3 * m.tets[e][0]);
            return Ds.determinant();
          };
          const double d0 = det(0);
          for (int k = 0; k <= 64; ++k) QVERIFY2(det(s * k / 64.0) >= eta * d0 * (1 - 1e-9), qPrintable(QString("element %1 at s %2").arg(e).arg(s * k / 64.0)));
          tightest = std::min(tightest, det(s) / d0);
        }
        if (s < 1) {
          ++limited;
          QVERIFY2(std::abs(tightest - eta) < 1e-6, qPrintable(QString::number(tightest)));
        } else {
          QVERIFY(tightest >= eta);
        }
      }
      // StVK is not guarded: nothing limits its moves.
      const FemModel st = FemModel::build(c.volume, {}, {MaterialModel::StVK, 3e3, 0.45, 1000});
      Eigen::VectorXd big(st.restVector().size());
      for (Eigen::Index i = 0; i < big.size(); ++i) big[i] = 0.05 * n(rng);
      QCOMPARE(inversionFreeStep(st, st.restVector(), big, {nullptr, eta, 0.0}), 1.0);
    }
    QVERIFY(limited >= 6);  // the larger moves were limited
    // Five elements reflected through one of their nodes: five inverted (by construction), none at rest.
    const FemModel m = FemModel::build(c.volume, {}, {MaterialModel::Corotational, 3e3, 0.45, 1000});
    Eigen::VectorXd x = m.restVector();
    QCOMPARE(volumeRatios(m, x).inverted, 0);
    QVERIFY(std::abs(volumeRatios(m, x).smallest - 1) < 1e-12);
    std::vector<int> chosen;
    for (std::size_t e = 0; e < m.tets.size() && chosen.size() < 5; e += 97) {
      bool shares = false;  // elements sharing no node, so each reflection inverts exactly its own element and maybe neighbours
      for (int o : chosen)
        for (int a : m.tets[e])
          for (int b : m.tets[o]) shares |= a == b;
      if (!shares) chosen.push_back(static_cast<int>(e));
    }
    // Reflect each chosen element's fourth node through the plane of the other three: its J becomes exactly -1.
    for (int e : chosen) {
      const auto& t = m.tets[e];
      const Eigen::Vector3d a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), cc = x.segment<3>(3 * t[2]);
      const Eigen::Vector3d nrm = (b - a).cross(cc - a).normalized();
      Eigen::Vector3d p = x.segment<3>(3 * t[3]);
      p -= 2 * nrm.dot(p - a) * nrm;
      x.segment<3>(3 * t[3]) = p;
    }
    std::vector<int> inverted;
    const auto r = volumeRatios(m, x, &inverted);
    for (int e : chosen) QVERIFY(std::find(inverted.begin(), inverted.end(), e) != inverted.end());
    QCOMPARE(r.inverted, static_cast<int>(inverted.size()));
    QVERIFY(std::abs(r.smallest + 1) < 1e-9 || r.smallest < -1);
  }
};

QTEST_GUILESS_MAIN(TestFem)
#include "test_fem.moc"
