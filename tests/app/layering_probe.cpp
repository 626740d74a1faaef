// Links simcore, imaging and the phantom only: ldd on this binary must show no Qt library.
#include "phantom/phantom.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/meshio.hpp>

#include <cstdio>

int main() {
  rehearse::simcore::Mesh m;
  auto cam = rehearse::imaging::Camera::defaultFor(64, 48);
  std::printf("%zu %d %d\n", m.points.size(), cam.width, rehearse::phantom::phantomLabel(Eigen::Vector3d::Zero()));
  return 0;
}
