#pragma once
// What the registration's translation units share (registration.cpp and the stages' files, contour_registration.hpp:
// the fit; registration_silhouette.cpp: the silhouette, its distances and the contour's residuals;
// registration_pose.cpp: the pose and sag refinement). Internal to simcore.
#include <rehearse/simcore/registration.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace rehearse::simcore::detail {

void checkCamera(const Pinhole& c);
// "0.57 px", for statuses.
std::string pixels(double px);
// Closest point of segment [a, b] to p: returns the parameter in [0, 1].
double closestParameter(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p);
// The silhouette's edges on a uniform grid of their boxes, for nearest-edge queries: the same answer as trying every
// edge (the nearest, the first in the silhouette's order among equally near ones), in time that grows with the
// distance searched rather than the number of edges (a fit asks for every contour point, hundreds of times).
class SilhouetteGrid {
 public:
  explicit SilhouetteGrid(const std::vector<SilhouetteEdge>& edges);
  // The nearest edge whose normal is within `minDot` of `normal` (|dot| >= minDot; any edge when `normal` is zero):
  // its index (-1: none), its distance (px) and the nearest point's parameter along it (SilhouetteEdge::nearest).
  int nearest(const Eigen::Vector2d& p, const Eigen::Vector2d& normal, double minDot, double& distance,
              double& t) const;
  double distance(const Eigen::Vector2d& p) const;

 private:
  const std::vector<SilhouetteEdge>& edges_;
  Eigen::Vector2d origin_ = Eigen::Vector2d::Zero();
  double cell_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<int> start_, items_;  // the edges in each cell (row-major), compressed
};

// Mean, RMS and largest of a run of distances.
struct ResidualSum {
  Residual2D r;
  double sum = 0, sum2 = 0;
  void add(double d) {
    sum += d;
    sum2 += d * d;
    r.hausdorff = std::max(r.hausdorff, d);
    ++r.points;
  }
  Residual2D result() const {
    Residual2D out = r;
    if (out.points) {
      out.mean = sum / out.points;
      out.rms = std::sqrt(sum2 / out.points);
    }
    return out;
  }
};

// The nearest point of a polyline to p, and whether it is one of the polyline's ends.
struct Foot {
  Eigen::Vector2d point = Eigen::Vector2d::Zero(), normal = Eigen::Vector2d::Zero();
  double distance = std::numeric_limits<double>::infinity();
  bool atEnd = false;
};
Foot nearestOnPolyline(const std::vector<Eigen::Vector2d>& line, const Eigen::Vector2d& p);

struct Binding {
  int a, b;
  double t;                                          // along the edge
  Eigen::Vector2d contour;                           // the contour point
  double distance;                                   // px
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();  // unit normal of the contour there (for sliding)
  Eigen::Vector3d bulge = Eigen::Vector3d::Zero();   // the edge's bulge (SilhouetteEdge::bulge)
  int view = 0;                                      // the frame its contour point is in (View)
  // A surface point instead (`surfacePoint`): node a held near a point seen in two frames (triangulated, first camera
  // frame), across the surface only: the residual is `pxPerMetre` (n . (node - target)), n the surface's normal at the
  // node (model frame, turned with the pose).
  bool surfacePoint = false;
  Eigen::Vector3d target = Eigen::Vector3d::Zero(), surfaceNormal = Eigen::Vector3d::Zero();
  double pxPerMetre = 0;
};

// A frame the fit sees the organ in: its camera, and the camera's motion from the first frame's (first camera frame
// -> this one's; identity for the first). A point q of the first camera frame is at motion.apply(q) in this one.
struct View {
  Pinhole camera;
  Pose motion;
};
// The pose model -> this frame's camera, from the pose model -> the first frame's camera.
inline Pose viewPose(const View& v, const Pose& pose) {
  Pose out;
  out.R = v.motion.R * pose.R;
  out.t = v.motion.R * pose.t + v.motion.t;
  return out;
}
Eigen::Vector3d point(const Eigen::VectorXd& x, const Binding& b);

/// The pose (and, when U has columns, the sag with it) refined onto the bindings (registration_pose.cpp): the bound
/// point is base + U a, seen in its binding's view; Levenberg-Marquardt with a prior (a - a0)' P (a - a0) on the load.
void refinePoseAndSag(const Eigen::VectorXd& base, const Eigen::MatrixXd& U, const std::vector<Binding>& bindings,
                      const std::vector<View>& views, bool pointToLine, Pose& pose, Eigen::Vector3d& a,
                      const Eigen::Vector3d& a0, const Eigen::Matrix3d& prior);
/// Gauss-Newton's information matrix of the same problem at (pose, a): J'J of the bindings' residuals (px) in the
/// rotation increment (rad, camera frame), the translation (m) and, when U has columns, the load (m/s^2), with the
/// prior added; `residuals` gets each contour binding's residual (px: along the contour normal when sliding, else its
/// length; surface points' are not among them).
Eigen::MatrixXd poseSagInformation(const Eigen::VectorXd& base, const Eigen::MatrixXd& U,
                                   const std::vector<Binding>& bindings, const std::vector<View>& views,
                                   bool pointToLine, const Pose& pose, const Eigen::Vector3d& a,
                                   const Eigen::Matrix3d& prior, std::vector<double>& residuals);
// The pose alone, the shape x as it is.
Pose refinePose(const Eigen::VectorXd& x, const std::vector<Binding>& bindings, Pose pose,
                const std::vector<View>& views, bool pointToLine);

}  // namespace rehearse::simcore::detail
