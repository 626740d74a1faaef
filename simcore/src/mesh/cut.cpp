// Cutting a tetrahedral mesh (see rehearse/simcore/cut.hpp): the public helpers and cutTetrahedra, which runs
// the cut's stages in order (cut_stages.hpp): the blade (cut_blade.cpp), the split (cut_split.cpp) and the
// separation (cut_separate.cpp).
#include <rehearse/simcore/cut.hpp>

#include "cut_stages.hpp"

#include <cmath>
#include <utility>

namespace rehearse::simcore {
namespace {
using V3 = Eigen::Vector3d;
}  // namespace

double tetShapeQuality(const V3& a, const V3& b, const V3& c, const V3& d) {
  const double l2 = ((b - a).squaredNorm() + (c - a).squaredNorm() + (d - a).squaredNorm() + (c - b).squaredNorm() +
                     (d - b).squaredNorm() + (d - c).squaredNorm()) /
                    6.0;
  if (!(l2 > 0)) return 0;
  return 6.0 * std::sqrt(2.0) * std::abs(detail::signedVolume(a, b, c, d)) / (l2 * std::sqrt(l2));
}

void extendByCut(Eigen::VectorXd& v, const std::vector<CutNode>& newNodes) {
  const Eigen::Index n0 = v.size() / 3;
  v.conservativeResize(3 * (n0 + static_cast<Eigen::Index>(newNodes.size())));
  for (std::size_t k = 0; k < newNodes.size(); ++k) {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int j = 0; j < 4; ++j)
      if (newNodes[k].from[static_cast<std::size_t>(j)] >= 0)
        p += newNodes[k].weight[static_cast<std::size_t>(j)] *
             v.segment<3>(3 * static_cast<Eigen::Index>(newNodes[k].from[static_cast<std::size_t>(j)]));
    v.segment<3>(3 * (n0 + static_cast<Eigen::Index>(k))) = p;
  }
}

CutResult cutTetrahedra(std::vector<V3>& rest, std::vector<V3>& current, std::vector<std::array<int, 4>>& tets,
                        std::vector<int>& labels, const BladeSweep& blade, const CutSettings& s,
                        CutProgress* progress) {
  detail::TetCutter cut(rest, current, tets, labels, blade, s, progress);
  // The blade: its plane, the elements it crosses and the nodes the cut passes through. Each stage that can
  // end the cut has said why in the result's status.
  if (!cut.inputsMatch() || !cut.placeBlade()) return std::move(cut.r);
  cut.findCrossed();
  cut.growAlongSweeps();
  if (!cut.anythingToCut()) return std::move(cut.r);
  cut.snapNearNodes();
  cut.snapFront();
  // The split: new nodes on the crossed edges and the touched elements re-meshed, within the quality bounds.
  if (!cut.splitElements()) return std::move(cut.r);
  // The separation: the pieces into the mesh, then the two sides apart where the blade passed.
  cut.assemble();
  cut.collectFaces();
  cut.settleFlatElements();
  cut.chooseCutFaces();
  cut.duplicateNodes();
  cut.renameNodes();
  cut.updateCutNodes();
  return cut.finish();
}

}  // namespace rehearse::simcore
