#include "rehearse/app/case.hpp"

#include "phantom/phantom.hpp"
#include "rehearse/app/materials.hpp"

#include <algorithm>
#include <cstdio>

namespace rehearse::app {

std::shared_ptr<const VisualSurface> VisualSurface::make(const simcore::Mesh& volume, const simcore::Mesh& surface,
                                                         std::string* why) {
  auto refuse = [&](const std::string& s) {
    if (why) *why = s;
    return std::shared_ptr<const VisualSurface>();
  };
  if (surface.triangles.empty() || surface.points.empty())
    return refuse("The organ's surface has no triangles; the views draw the simulation mesh's boundary.");
  if (volume.tets.empty()) return refuse("There is no volume mesh to carry the organ's surface.");
  simcore::Mesh s = surface;
  s.convertToMetres();
  for (const auto& t : s.triangles)
    for (int v : t)
      if (v < 0 || v >= static_cast<int>(s.points.size()))
        return refuse("The organ's surface has a triangle with a vertex it does not have.");
  auto out = std::make_shared<VisualSurface>();
  try {
    out->embedding = simcore::embedPoints(volume.points, volume.tets, s.points);
  } catch (const std::exception& e) {  // the organ itself stays usable: drawn through its boundary
    return refuse(std::string(e.what()) + " The views draw the simulation mesh's boundary.");
  }
  const double size = volume.bounds().sizes().maxCoeff();
  if (out->embedding.farthestOutside > 0.05 * size) {
    char text[256];
    std::snprintf(text, sizeof text,
                  "The organ's surface lies up to %.1f mm outside its volume mesh (%.0f mm across): it is not that "
                  "mesh's surface, so "
                  "the views draw the simulation mesh's boundary.",
                  out->embedding.farthestOutside * 1e3, size * 1e3);
    return refuse(text);
  }
  out->points = std::move(s.points);
  out->triangles = std::move(s.triangles);
  out->nodeCount = volume.points.size();
  return out;
}

std::vector<Eigen::Vector3d> VisualSurface::map(const std::vector<Eigen::Vector3d>& nodes) const {
  if (nodes.size() != nodeCount) return {};
  return simcore::mapEmbedded(embedding, nodes);
}

std::size_t VisualSurface::bytes() const {
  return points.size() * (sizeof(Eigen::Vector3d) + sizeof(std::array<int, 4>) + sizeof(Eigen::Vector4d)) +
         triangles.size() * sizeof(std::array<int, 3>);
}

std::shared_ptr<const Organ> Organ::fromVolume(simcore::Mesh volume, std::string source, double sourceUnitToMetre,
                                               const simcore::Mesh* visualSurface, std::string* why) {
  auto o = std::make_shared<Organ>();
  o->volume = std::move(volume);
  o->source = std::move(source);
  o->sourceUnitToMetre = sourceUnitToMetre > 0 ? sourceUnitToMetre : 1.0;
  o->quality = simcore::computeQuality(o->volume);
  o->centreOfGravity = phantom::centreOfGravity(o->volume);
  if (o->volume.tets.empty()) return o;
  if (visualSurface) o->visual = VisualSurface::make(o->volume, *visualSurface, why);
  o->surface = simcore::boundaryTriangles(o->volume, false);
  // Faces of the other labels (interfaces carry the inner label): the structures drawn through the organ.
  std::vector<int> labels;
  const auto faces = simcore::boundaryTriangles(o->volume, true, &labels);
  for (std::size_t i = 0; i < faces.size(); ++i)
    if (labels[i] != kParenchymaLabel) {
      o->innerSurface.push_back(faces[i]);
      o->innerSurfaceLabels.push_back(labels[i]);
    }
  return o;
}

const std::vector<Eigen::Vector3d>& Case::shapeNodes() const { return hasFit() ? fit->nodes : organ->volume.points; }

double Case::shapeDigest() const {
  // Weighted by position in the list, so that swapped or moved nodes change it (a checksum, not a hash:
  // enough to see that the shape is another one).
  double sum = 0;
  const auto& nodes = shapeNodes();
  for (std::size_t i = 0; i < nodes.size(); ++i) sum += (1.0 + 1e-3 * static_cast<double>(i % 997)) * (nodes[i].x() + 2 * nodes[i].y() + 3 * nodes[i].z());
  return sum + static_cast<double>(nodes.size());
}

double Case::frameDigest() const {
  if (frame.empty()) return 0;
  // A 64 x 36 grid of pixels, weighted by place: another frame of the same size changes it, and it costs
  // microseconds (appearanceCurrent is asked on every edit, on the GUI thread).
  double w = 0;
  for (int gy = 0; gy < 36; ++gy)
    for (int gx = 0; gx < 64; ++gx) {
      const int y = (2 * gy + 1) * frame.rows / 72, x = (2 * gx + 1) * frame.cols / 128;
      const cv::Vec3b p = frame(y, x);
      w += (1.0 + (gx + 3 * gy) % 13) * (p[0] + 3.0 * p[1] + 7.0 * p[2]);
    }
  return w;
}

bool Case::appearanceCurrent() const {
  if (!appearance || !hasPose || frame.empty()) return false;
  const auto& a = *appearance;
  const bool samePose = (a.pose.R - pose.R).norm() < 1e-9 && (a.pose.t - pose.t).norm() < 1e-9;
  const double shape = shapeDigest(), image = frameDigest();
  return samePose && std::abs(a.shapeDigest - shape) <= 1e-9 * std::max(1.0, std::abs(shape)) && a.frameWidth == frame.cols && a.frameHeight == frame.rows &&
         std::abs(a.frameDigest - image) <= 1e-9 * std::max(1.0, std::abs(image));
}

SurfaceView Case::surfaceView() const {
  SurfaceView v = organ->volume.surfaceView();
  if (hasFit()) v.vertices = fit->nodes.front().data();
  v.triangles = organ->surface.empty() ? nullptr : organ->surface.front().data();
  v.triangleCount = organ->surface.size();
  return v;
}

Pose Case::automaticPose() const {
  Pose p;
  const Eigen::Vector3d cog = organ->centreOfGravity;
  const auto& volume = organ->volume;
  const double size = volume.points.empty() ? 0.1 : volume.bounds().sizes().maxCoeff();
  const double fx = camera.width > 0 ? camera.fx() : 1000.0, width = camera.width > 0 ? camera.width : 1280.0;
  double depth = std::max(0.02, size * fx / (0.6 * width));
  p.t = Eigen::Vector3d(0, 0, depth) - cog;
  // A large, deep or tall organ at that depth can still overflow the image (its near side is closer than
  // its centre; a 16:9 image is lower than wide): move it away until all of it projects inside the middle
  // 90 % of the image both ways.
  if (camera.width > 0 && camera.height > 0 && !volume.points.empty()) {
    const Pinhole cam = camera.pinhole();
    for (int i = 0; i < 60; ++i) {
      Eigen::AlignedBox2d box;
      bool inFront = true;
      for (const auto& x : volume.points) {
        const Eigen::Vector3d xc = p.apply(x);
        if (xc.z() < 0.01) {
          inFront = false;
          break;
        }
        box.extend(cam.project(xc));
      }
      if (inFront && box.min().x() >= 0.05 * camera.width && box.max().x() <= 0.95 * camera.width &&
          box.min().y() >= 0.05 * camera.height && box.max().y() <= 0.95 * camera.height)
        break;
      depth *= 1.1;
      p.t = Eigen::Vector3d(0, 0, depth) - cog;
    }
  }
  return p;
}

void Case::setOrgan(std::shared_ptr<const Organ> o) {
  organ = o ? std::move(o) : std::make_shared<Organ>();
  attachments.clear();
  landmarks.clear();  // their model points were on the old organ
  fit.reset();
  groundTruth.reset();
  material = defaultMaterial(*organ);
  pose = automaticPose();
  hasPose = !organ->empty();
  poseAligned = false;
}

std::size_t Case::ownBytes() const {
  std::size_t bytes = sizeof(Case) + name.size() + attachments.size() * sizeof(int) + landmarks.size() * sizeof(LandmarkPair);
  for (const auto* k : {&contour, &contour2})
    for (const auto& s : k->segments)
      bytes += sizeof(s) + s.points.size() * sizeof(Eigen::Vector2d) + s.modelVertices.size() * sizeof(int);
  return bytes;
}

std::size_t Case::sharedBytes() const {
  const auto& v = organ->volume;
  std::size_t bytes = v.points.size() * sizeof(Eigen::Vector3d) +
                      v.tets.size() * (sizeof(std::array<int, 4>) + sizeof(int)) +
                      v.triangles.size() * (sizeof(std::array<int, 3>) + sizeof(int)) +
                      (organ->surface.size() + organ->innerSurface.size()) * sizeof(std::array<int, 3>) +
                      organ->innerSurfaceLabels.size() * sizeof(int) + (organ->visual ? organ->visual->bytes() : 0);
  if (fit) bytes += fit->nodes.size() * sizeof(Eigen::Vector3d);
  if (appearance) bytes += sizeof(AppearanceEstimate) + appearance->status.size();
  bytes +=
      frame.total() * frame.elemSize() + rawFrame.total() * rawFrame.elemSize() + frame2.total() * frame2.elemSize();
  return bytes;
}

Case caseFromPhantom(const phantom::Phantom& p) {
  Case c;
  c.name = p.name;
  c.organ = Organ::fromVolume(p.volume);
  c.attachments = p.attachments;
  c.material = defaultMaterial(*c.organ);
  c.camera = p.camera;
  c.frame = p.frame;
  auto truth = std::make_shared<GroundTruth>();
  truth->pose = p.truePose;
  truth->appearance = p.trueAppearance;
  for (const auto& s : p.vesselTree) {
    truth->vesselAxes.emplace_back(s.a, s.b);
    truth->vesselRadii.push_back(s.radius);
  }
  c.groundTruth = truth;
  c.pose = c.automaticPose();
  c.hasPose = !c.organ->empty();
  return c;
}

void undistortFrame(Case& k) {
  if (k.rawFrame.empty()) return;
  k.frame = imaging::undistortImage(k.rawFrame, k.camera);
}

}  // namespace rehearse::app
