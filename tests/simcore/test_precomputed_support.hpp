// The precomputed suite's shared parts: the organ it meshes (its fixed and driven nodes), gravity, the material,
// the direct static solution it is checked against, a grasp's pull and the largest difference of two force lists.
#pragma once
#include <rehearse/simcore/fem.hpp>

#include <Eigen/Core>

#include <cstddef>
#include <utility>
#include <vector>

struct Organ {
  rehearse::simcore::Mesh mesh;
  std::vector<char> fixed;
  std::vector<int> driven;  ///< the surface nodes that are not fixed
};

inline const Eigen::Vector3d kGravity(0, 9.81, 0);  // down the image, as realorgan.hpp hangs the organs

rehearse::simcore::MaterialParams material(rehearse::simcore::MaterialModel law, double poisson);

// The direct static solution: K u = f_g with u given at the fixed nodes (0) and the held ones (their displacement);
// the reaction at the held nodes is (K u - f_g) there.
Eigen::VectorXd directSolve(const rehearse::simcore::FemModel& model, const std::vector<char>& fixed,
                            const std::vector<int>& held, const std::vector<Eigen::Vector3d>& d,
                            std::vector<Eigen::Vector3d>* reaction);

double relative(const Eigen::VectorXd& a, const Eigen::VectorXd& b);

// A grasp's pull of `count` held nodes: each displaced alike and a little apart (m).
std::vector<Eigen::Vector3d> spreadPull(std::size_t count);

// The largest difference between two lists of forces (N), and the largest of the reference's.
std::pair<double, double> largestDifference(const std::vector<Eigen::Vector3d>& force,
                                            const std::vector<Eigen::Vector3d>& reference);
