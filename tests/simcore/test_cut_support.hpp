// The cut suite's shared checks: element volumes, connected groups, boundary faces and area, the mesh's validity
// (inverted elements, worst quality, total volume), the liver preset, a sweep across the settled organ's front and
// a blade sweep over a plane of the block.
#pragma once
#include <rehearse/simcore/cut.hpp>
#include <rehearse/simcore/session/session.hpp>

#include <Eigen/Geometry>

#include <array>
#include <cstddef>
#include <vector>

double volume(const std::vector<Eigen::Vector3d>& p, const std::array<int, 4>& t);

// Connected groups of elements (through shared nodes); returns the group of each element.
std::vector<int> components(std::size_t nodes, const std::vector<std::array<int, 4>>& tets, int* count);

// Faces used by one element (the boundary), and the count of faces used by more than two.
std::vector<std::array<int, 3>> boundaryFaces(const std::vector<std::array<int, 4>>& tets, int* overused);

double area(const std::vector<Eigen::Vector3d>& p, const std::vector<std::array<int, 3>>& tris);

struct Validity {
  std::size_t inverted = 0;
  double minQuality = 1, totalVolume = 0;
};
Validity validity(const std::vector<Eigen::Vector3d>& p, const std::vector<std::array<int, 4>>& tets);

double minQualityOf(const rehearse::simcore::Mesh& m);

rehearse::simcore::BodySetup liverSetup();

// A cut across the settled organ's front, left to right: the blade's tip at sweep pose k (0: the start,
// 10: the end), from the box of the positions it settled to.
struct FrontSweep {
  Eigen::Vector3d c, size;
  explicit FrontSweep(const std::vector<Eigen::Vector3d>& positions) {
    Eigen::AlignedBox3d box;
    for (const auto& p : positions) box.extend(p);
    c = box.center();
    size = box.sizes();
  }
  Eigen::Vector3d at(int k) const {
    return c + Eigen::Vector3d(-0.6 * size.x() + 0.06 * k * size.x(), 0.1 * size.y(), 0.3 * size.z());
  }
};

// A blade sweep covering the plane x = x0 over the block's section (y, z in [0, 0.02]).
rehearse::simcore::BladeSweep planeX(double x0, double y0 = -0.01, double y1 = 0.03);
