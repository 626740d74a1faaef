#include "phantom/phantom.hpp"

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/quality.hpp>

#include <cmath>
#include <numbers>

namespace rehearse::phantom {
namespace {

// Approximate signed distance to an axis-aligned ellipsoid (metres; negative inside).
double ellipsoid(const Eigen::Vector3d& p, const Eigen::Vector3d& c, const Eigen::Vector3d& r) {
  const Eigen::Vector3d q = (p - c).cwiseQuotient(r);
  return (q.norm() - 1.0) * r.minCoeff();
}

double smoothMin(double a, double b, double k) {
  const double h = std::clamp(0.5 + 0.5 * (b - a) / k, 0.0, 1.0);
  return b * (1 - h) + a * h - k * h * (1 - h);
}

double segmentDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

// Organ signed distance: a large right lobe and a tapering left lobe blended smoothly, with a concave
// inferior face and gentle surface undulation. Model frame: x to the patient's left, y inferior, z posterior.
double organDistance(const Eigen::Vector3d& p) {
  double right = ellipsoid(p, {0.028, 0.0, 0.0}, {0.058, 0.042, 0.034});
  double left = ellipsoid(p, {-0.040, -0.010, 0.002}, {0.052, 0.026, 0.019});
  double d = smoothMin(right, left, 0.018);
  // Inferior (visceral) concavity: subtract a flat ellipsoid below.
  double notch = ellipsoid(p, {0.010, 0.052, 0.004}, {0.070, 0.022, 0.050});
  d = std::max(d, -notch + 0.002);
  d += 0.0015 * std::sin(55 * p.x() + 1.3) * std::sin(47 * p.z() + 0.4) + 0.001 * std::sin(70 * p.y() + 2.0);
  return d;
}

}  // namespace

std::vector<VesselSegment> phantomVesselTree() {
  // A portal-like tree entering at the hilum (inferior, posterior) and branching into both lobes.
  const Eigen::Vector3d hilum(0.012, 0.016, 0.008), fork(0.006, 0.002, 0.004);
  const Eigen::Vector3d rightA(0.045, -0.004, 0.002), rightB(0.030, -0.012, -0.004), leftA(-0.040, -0.008, 0.003);
  return {
      {hilum, fork, 0.0055},
      {fork, rightA, 0.0045},
      {rightA, {0.068, -0.010, 0.000}, 0.0035},
      {rightA, {0.058, 0.012, 0.006}, 0.0035},
      {fork, rightB, 0.0040},
      {rightB, {0.040, -0.028, -0.006}, 0.0032},
      {fork, leftA, 0.0042},
      {leftA, {-0.072, -0.012, 0.002}, 0.0032},
      {leftA, {-0.055, 0.000, 0.003}, 0.0030},
  };
}

int phantomLabel(const Eigen::Vector3d& p) {
  if (organDistance(p) > 0) return 0;
  static const auto tree = phantomVesselTree();
  for (const auto& s : tree)
    if (segmentDistance(p, s.a, s.b) < s.radius) return kVesselLabel;
  return kParenchymaLabel;
}

Eigen::Vector3d centreOfGravity(const simcore::Mesh& volume) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double total = 0;
  for (const auto& t : volume.tets) {
    const auto &a = volume.points[t[0]], &b = volume.points[t[1]], &c = volume.points[t[2]], &d = volume.points[t[3]];
    const double v = std::abs(simcore::tetVolume(a, b, c, d));
    sum += v * (a + b + c + d) / 4.0;
    total += v;
  }
  if (total > 0) return sum / total;
  if (volume.points.empty()) return Eigen::Vector3d::Zero();
  return volume.bounds().center();
}

Eigen::Vector3d Phantom::centreOfGravity() const { return phantom::centreOfGravity(volume); }

Phantom makePhantom(const PhantomOptions& options) {
  Phantom c;
  c.name = kBuiltInName;
  c.vesselTree = phantomVesselTree();
  // 1. Volume mesh of the labelled implicit organ.
  simcore::TetrahedraliseOptions mo = options.meshing;
  mo.targetTets = options.targetTets;
  mo.seed = options.seed;
  const Eigen::AlignedBox3d bounds(Eigen::Vector3d(-0.105, -0.055, -0.045), Eigen::Vector3d(0.095, 0.055, 0.045));
  const double volumeEstimate = 4.16e-4;  // m^3, measured on this shape (416 cm^3)
  c.volume = simcore::tetrahedraliseImplicit(phantomLabel, bounds, mo, volumeEstimate);
  c.volume.setLabelName(kParenchymaLabel, "parenchyma");
  c.volume.setLabelName(kVesselLabel, "vessels");
  c.surface = simcore::boundaryTriangles(c.volume, false);
  {
    std::vector<int> labels;
    const auto faces = simcore::boundaryTriangles(c.volume, true, &labels);
    for (std::size_t i = 0; i < faces.size(); ++i)
      if (labels[i] == kVesselLabel) c.innerSurface.push_back(faces[i]);
  }

  // 2. Ligament attachments: surface nodes near the superior-posterior (coronary ligament) band.
  std::vector<char> onSurface(c.volume.points.size(), 0);
  for (const auto& t : c.surface)
    for (int v : t) onSurface[v] = 1;
  const Eigen::Vector3d la(-0.030, -0.030, 0.018), lb(0.050, -0.030, 0.018);
  for (std::size_t i = 0; i < c.volume.points.size(); ++i) {
    const auto& p = c.volume.points[i];
    const Eigen::Vector3d ab = lb - la;
    const double t = std::clamp((p - la).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    if (onSurface[i] && (p - (la + t * ab)).norm() < 0.016 && p.z() > 0.004) c.attachments.push_back(static_cast<int>(i));
  }

  // 3. Camera, pose and light (the ground truth).
  c.camera.width = options.width;
  c.camera.height = options.height;
  const double f = 1050.0 * options.width / 1280.0;
  c.camera.K << f, 0, (options.width - 1) / 2.0, 0, f, (options.height - 1) / 2.0, 0, 0, 1;
  const double deg = std::numbers::pi / 180.0;
  c.truePose.R = (Eigen::AngleAxisd(-8 * deg, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(12 * deg, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(-22 * deg, Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
  c.truePose.t = Eigen::Vector3d(-0.006, 0.004, 0.195);
  c.trueAppearance.lightPosition = Eigen::Vector3d(0.012, -0.010, 0.0);
  c.trueAppearance.kd = Eigen::Vector3d(0.0290, 0.0112, 0.0090);
  c.trueAppearance.ks = Eigen::Vector3d(0.0120, 0.0115, 0.0110);
  c.trueAppearance.roughness = 0.09;

  // 4. The frame: tissue background, the organ rendered with the known appearance, scope vignette.
  if (options.meshing.progress) options.meshing.progress(0.95, "rendering the frame");
  cv::Mat3b background = imaging::makeTissueBackground(options.width, options.height, options.seed);
  c.frame = imaging::renderShaded(c.camera, c.truePose, c.surfaceView(), c.trueAppearance, background, 2);
  imaging::applyScopeVignette(c.frame);
  return c;
}

}  // namespace rehearse::phantom
