#pragma once
// The parameterized mesh (issue 37; the older simulators' haptic-rate surface model): the organ's surface resampled on
// an m x n grid (a geometry image, Gu, Gortler and Hoppe 2002) through CGAL's surface parameterization (the closed
// surface cut to a disk along a seam tree from its two farthest ends, mapped onto the unit square: discrete authalic,
// conformal or mean-value), then deformed by a Gaussian free-form deformation over the grid around the vertex nearest
// the tool (its grid neighbourhood, across the seam too, weighted by the rest distance),
// with the paper's two controls (the radius of influence and the largest displacement), and the tool's force from
// Hertz's contact law, F_n = 4/3 sqrt(r) E* d^(3/2) along the surface normal (r the tool tip's radius, E* the
// effective modulus, d the depth), and a linear tangential spring F_t = k d_t that slips past Coulomb's cone.
//
// It gives up accuracy for speed: no volume, no equilibrium, the force a contact law rather than the organ's
// response; an update costs the vertices within the radius (microseconds). Units: SI (metres, newtons, pascals).
#include <rehearse/simcore/mesh.hpp>

#include <Eigen/Core>

#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rehearse::simcore {

/// How the surface, cut to a disk, is mapped onto the square: CGAL's discrete authalic map (keeps areas), its discrete
/// conformal map (keeps angles), mean value coordinates (never folds, whatever the triangles' shape), the mean-value
/// map reweighted to spread its geometric stretch (Stretch: Yoshizawa, Belyaev and Seidel 2004, minimising Sander et
/// al.'s L2 stretch, the measure Gu, Gortler and Hoppe's geometry images use; its weights stay positive, so it never
/// folds either), or the best of them (Best: the one whose grid lies nearest the surface).
enum class SurfaceMap { Authalic, Conformal, MeanValue, Stretch, Best };
/// "authalic", "conformal", "mean value", "stretch-minimising", "best".
const char* surfaceMapName(SurfaceMap map);

struct GeometryImageSettings {
  int size = 81;  ///< grid points along each side (the paper's 81 x 81)
  SurfaceMap map = SurfaceMap::Best;
  /// Branches added to the seam, one at a time, towards the surface's point farthest from the grid (Gu, Gortler and
  /// Hoppe's refinement); the candidate nearest the surface is kept.
  int seamBranches = 3;
  /// The grid grows (by half the start each time, up to maxSize) while the chosen candidate's grid lies farther from
  /// the surface than `tolerance` of its size (the bounding box's diagonal): a protrusion the map squeezes into a few
  /// cells gets more of them. maxSize = size: the grid stays as asked.
  int maxSize = 161;
  double tolerance = 0.01;
  /// Told the share done (0..1) after each candidate; false cancels (nothing is made, `why` says so).
  std::function<bool(double)> progress;
};

/// A surface resampled on a size x size grid over the unit square: point (i, j) at parameter (u, v) = (j, i) / (size -
/// 1), row-major. The grid's border runs along the seam (each side of it twice), so the surface it makes is closed in
/// space though its border is not stitched.
struct GeometryImage {
  int size = 0;
  std::vector<Eigen::Vector3d> points;    ///< size^2, row-major
  std::vector<Eigen::Vector3d> normals;   ///< outward unit normals of the original surface at the samples
  int seamEdges = 0;                      ///< edges of the original surface the seam follows
  SurfaceMap map = SurfaceMap::Authalic;  ///< the map used
  int unplaced = 0;       ///< grid points no parameter triangle held (placed on the nearest): 0 normally
  int droppedPieces = 0;  ///< pieces of the surface left out (the largest is the organ)
  /// Stretch map: the reweighting rounds kept and the surface's L2 stretch (1: none) before and after them.
  int stretchRounds = 0;
  double stretchBefore = 0, stretchAfter = 0;
  int filledHoles = 0;    ///< small holes (under 15 % of the size around) closed before the cut
  double hausdorff = -1;  ///< m: the grid's distance to the surface it resampled (CGAL's, 20,000 samples)
  double extent = 0;      ///< m: that surface's size (its bounding box's diagonal)
  /// The surface it resampled: the input's largest piece with its small holes closed (for the reconstruction's check).
  std::vector<Eigen::Vector3d> sourcePoints;
  std::vector<std::array<int, 3>> sourceTriangles;
  int index(int i, int j) const { return i * size + j; }
  /// Two triangles per grid cell, outward as the original surface.
  std::vector<std::array<int, 3>> triangles() const;
};

/// Resamples a closed triangle surface (one genus-0 component: an organ) on a grid: its largest piece, small holes
/// closed (both counted); the seam between the surface's ends along each of its principal axes, the map(s) asked for,
/// and the candidate whose grid lies nearest the surface kept (Hausdorff distance). Nothing, with a sentence in `why`,
/// when that is not closed and without handles, or the parameterization fails (CGAL's error said).
std::optional<GeometryImage> makeGeometryImage(const std::vector<Eigen::Vector3d>& points,
                                               const std::vector<std::array<int, 3>>& triangles,
                                               const GeometryImageSettings& settings, std::string& why);

/// The symmetric Hausdorff distance (m) between two triangle surfaces, approximated by CGAL from `samples` points on
/// each (Polygon_mesh_processing::approximate_symmetric_Hausdorff_distance). -1 when either is not a polygon mesh.
double surfaceHausdorff(const std::vector<Eigen::Vector3d>& pointsA, const std::vector<std::array<int, 3>>& trianglesA,
                        const std::vector<Eigen::Vector3d>& pointsB, const std::vector<std::array<int, 3>>& trianglesB,
                        int samples = 100000);

/// Hertz's normal force (N) of a rigid sphere of radius `r` (m) pressed `depth` (m) into an elastic half-space of
/// effective modulus `effectiveModulus` (Pa): 4/3 sqrt(r) E* d^(3/2); 0 for depth <= 0.
double hertzForce(double r, double effectiveModulus, double depth);
/// E* of a rigid tool on tissue of Young's modulus E and Poisson's ratio nu: E / (1 - nu^2).
double rigidToolModulus(double youngModulus, double poisson);

struct FfdSettings {
  double radius = 0.02;           ///< m: the deformation's reach (its weight 1.1 % there, nothing past it)
  double maxDisplacement = 0.02;  ///< m: the largest displacement the deformation makes (the tool goes no further)
  double youngModulus = 4000;     ///< Pa (E* from it and nu for Hertz's law)
  double poisson = 0.45;
  double toolRadius = 0.005;         ///< m: the tool tip's radius (Hertz's r)
  double tangentialStiffness = 100;  ///< N/m: F_t = k d_t while the tip sticks
  double friction = 0.4;             ///< Coulomb: the tip slides (its anchor follows) when |F_t| > mu F_n
};

/// The parameterized mesh with Gaussian FFD and Hertz contact. Not thread-safe; one tool.
class ParameterizedMesh {
 public:
  ParameterizedMesh(GeometryImage image, const FfdSettings& settings);
  const GeometryImage& image() const { return image_; }
  const FfdSettings& settings() const { return settings_; }
  /// The deformed surface (same indices as image().points).
  const std::vector<Eigen::Vector3d>& positions() const { return x_; }
  /// The vertex nearest `p` (rest positions): a walk over grid neighbours from the last one found (a tool moves
  /// little between haptic updates), a full search the first time or when the walk ends farther than two grid steps.
  int nearestVertex(const Eigen::Vector3d& p);
  /// Metres per grid step at a vertex (the mean distance to its grid neighbours at rest).
  double gridStep(int vertex) const { return step_[static_cast<std::size_t>(vertex)]; }

  struct Contact {
    bool touching = false;
    int vertex = -1;
    double depth = 0;      ///< m: how far the tip is below the rest surface along the normal
    bool clamped = false;  ///< the tip went past maxDisplacement: the surface stopped there
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< N: the tissue's force on the tool (normal + tangential)
    double normalForce = 0, tangentialForce = 0;      ///< N: magnitudes
  };
  /// A poke: the tool's tip at `tip`. Below the rest surface at the nearest vertex it deforms the surface (the nearest
  /// vertex follows the tip, at most maxDisplacement; its neighbourhood on the grid, the vertices joined to it within
  /// the radius, across the seam too, by the Gaussian weight of their rest distance to it) and returns Hertz's force;
  /// above it the surface is at rest and nothing touches.
  Contact poke(const Eigen::Vector3d& tip);
  /// A pull: `vertex` held and displaced by `displacement` from rest (a grasp), the neighbourhood by the Gaussian
  /// weight; the force is Hertz's law on the displacement's length, against it (the model's contact law used for
  /// traction too: the model gives up accuracy there).
  Contact hold(int vertex, const Eigen::Vector3d& displacement);
  /// Back to rest; the next contact starts afresh (no tangential anchor).
  void release();
  /// The Gaussian weight at a distance `s` (m) from the tool's vertex: exp(-s^2 / (2 sigma^2)) with sigma = radius / 3
  /// (1.1 % at the radius), 0 past the radius.
  double weight(double s) const;

 private:
  void deform(int vertex, const Eigen::Vector3d& displacement);
  GeometryImage image_;
  FfdSettings settings_;
  std::vector<Eigen::Vector3d> x_;
  std::vector<double> step_;
  std::vector<int> touched_;             ///< vertices the last deformation moved
  std::vector<unsigned> seen_;  ///< per vertex: the deformation's stamp when reached (no allocation per update)
  std::vector<int> queue_;
  unsigned stamp_ = 0;
  std::vector<std::vector<int>> twins_;  ///< per border vertex: the border vertices at its place (across the seam)
  int last_ = -1;
  bool anchored_ = false;
  Eigen::Vector3d anchor_ = Eigen::Vector3d::Zero();
};

}  // namespace rehearse::simcore
