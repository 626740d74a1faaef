// The precomputed suite's shared parts (see test_precomputed_support.hpp).
#include "test_precomputed_support.hpp"

#include <Eigen/SparseCholesky>

#include <algorithm>

using namespace rehearse::simcore;

MaterialParams material(MaterialModel law, double poisson) {
  MaterialParams m;
  m.model = law;
  m.young = 27e3;
  m.poisson = poisson;
  m.density = 1079;
  return m;
}

Eigen::VectorXd directSolve(const FemModel& model, const std::vector<char>& fixed, const std::vector<int>& held,
                            const std::vector<Eigen::Vector3d>& d, std::vector<Eigen::Vector3d>* reaction) {
  const Eigen::Index n = static_cast<Eigen::Index>(model.nodeCount());
  const Eigen::SparseMatrix<double> K = elasticStiffness(model, model.restVector());
  Eigen::VectorXd fg = Eigen::VectorXd::Zero(3 * n), u = Eigen::VectorXd::Zero(3 * n);
  for (Eigen::Index i = 0; i < n; ++i) fg.segment<3>(3 * i) = model.lumpedMass(i) * kGravity;
  std::vector<char> known(static_cast<std::size_t>(n), 0);
  for (Eigen::Index i = 0; i < n; ++i) known[static_cast<std::size_t>(i)] = fixed[static_cast<std::size_t>(i)];
  for (std::size_t k = 0; k < held.size(); ++k) {
    known[static_cast<std::size_t>(held[k])] = 1;
    u.segment<3>(3 * held[k]) = d[k];
  }
  std::vector<Eigen::Index> freeOf(static_cast<std::size_t>(3 * n), -1);
  Eigen::Index nf = 0;
  for (Eigen::Index r = 0; r < 3 * n; ++r)
    if (!known[static_cast<std::size_t>(r / 3)]) freeOf[static_cast<std::size_t>(r)] = nf++;
  std::vector<Eigen::Triplet<double>> t;
  Eigen::VectorXd b = Eigen::VectorXd::Zero(nf);
  for (Eigen::Index r = 0; r < 3 * n; ++r)
    if (freeOf[static_cast<std::size_t>(r)] >= 0) b(freeOf[static_cast<std::size_t>(r)]) = fg(r);
  for (int c = 0; c < K.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it) {
      const Eigen::Index fr = freeOf[static_cast<std::size_t>(it.row())],
                         fc = freeOf[static_cast<std::size_t>(it.col())];
      if (fr < 0) continue;
      if (fc >= 0)
        t.emplace_back(fr, fc, it.value());
      else
        b(fr) -= it.value() * u(it.col());
    }
  Eigen::SparseMatrix<double> A(nf, nf);
  A.setFromTriplets(t.begin(), t.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
  const Eigen::VectorXd x = ldlt.solve(b);
  for (Eigen::Index r = 0; r < 3 * n; ++r)
    if (freeOf[static_cast<std::size_t>(r)] >= 0) u(r) = x(freeOf[static_cast<std::size_t>(r)]);
  if (reaction) {
    const Eigen::VectorXd r = K * u - fg;
    reaction->clear();
    for (int h : held) reaction->push_back(r.segment<3>(3 * h));
  }
  return u;
}

double relative(const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return (a - b).norm() / b.norm(); }

std::vector<Eigen::Vector3d> spreadPull(std::size_t count) {
  std::vector<Eigen::Vector3d> d;
  for (std::size_t k = 0; k < count; ++k)
    d.push_back(Eigen::Vector3d(0.010, -0.004, 0.002) + 0.0005 * static_cast<double>(k) * Eigen::Vector3d::UnitZ());
  return d;
}

std::pair<double, double> largestDifference(const std::vector<Eigen::Vector3d>& force,
                                            const std::vector<Eigen::Vector3d>& reference) {
  double difference = 0, largest = 0;
  for (std::size_t k = 0; k < reference.size(); ++k) {
    difference = std::max(difference, (force[k] - reference[k]).norm());
    largest = std::max(largest, reference[k].norm());
  }
  return {difference, largest};
}
