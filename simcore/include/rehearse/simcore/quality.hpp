#pragma once
// Mesh quality reports and the repairs the importer makes (one sentence each).
#include <rehearse/simcore/mesh.hpp>

#include <string>
#include <vector>

namespace rehearse::simcore {

struct LabelStats {
  int label = 0;
  std::string name;
  std::size_t count = 0;  // elements with this label
  double volume = 0;      // m^3 (tets) or area m^2 (surface parts)
};

struct QualityReport {
  std::size_t points = 0, triangles = 0, tets = 0;
  std::vector<LabelStats> labels;
  Eigen::AlignedBox3d bounds;         // metres
  double volume = 0;                  // m^3: sum of tet volumes, or volume enclosed by a closed surface
  double minDihedralDeg = 0, maxDihedralDeg = 0;  // tets only
  double worstAspectRatio = 0;        // circumradius / (3 inradius): 1 for a regular tet, large for slivers
  double meanEdge = 0;                // metres
  std::size_t inverted = 0;           // tets with negative signed volume
  std::size_t degenerate = 0;         // tets (or triangles) with (near) zero volume (area)
  // Surfaces only:
  std::size_t borderEdges = 0, nonManifoldEdges = 0;
  bool closed = false;
  long selfIntersections = -1;        // triangle pairs; -1 when not computed
};

/// Quality of a mesh in metres (the mesh must already be converted with convertToMetres()).
QualityReport computeQuality(const Mesh& mesh);

/// Multi-line human-readable report (mm, mm^3 / cm^3, degrees).
std::string formatQuality(const QualityReport& q);

/// Repairs of a volume mesh done on import: flips inverted tets (a consistent clockwise file
/// convention or individual flips) and drops degenerate ones. Returns one sentence per repair made.
std::vector<std::string> repairVolume(Mesh& mesh);

/// Signed volume of tet (a,b,c,d): positive when d is on the side of (b-a)x(c-a).
double tetVolume(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d);

}  // namespace rehearse::simcore
