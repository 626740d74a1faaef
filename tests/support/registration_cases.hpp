#pragma once
// The registration suites' cases: the phantom's outline in its frame, the organ model, an elastic deformation sideways
// (a known displacement the fit must recover), its front ridge as an anatomical curve, a pose offset about the organ.
#include "test_support.hpp"
#include "calculix.hpp"
#include "realorgan.hpp"
#include <rehearse/app/elasticfit.hpp>

#include "phantom/phantom.hpp"
#include <rehearse/app/casefolder.hpp>

#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/registration.hpp>

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QProcess>

#include <filesystem>
#include <map>
#include <set>

#include <QStandardPaths>

using namespace rehearse;
using namespace rehearse::simcore;

namespace {
// The organ's outline in the frame: the outer border of its rendered mask (pixel centres).
inline std::vector<std::vector<Eigen::Vector2d>> outline(const phantom::Phantom& c, const Pose& pose,
                                                         const SurfaceView& surface) {
  return imaging::maskOutlines(imaging::renderMask(c.camera, pose, surface));
}

// The organ deformed by 3 g sideways in the image (a load the registration does not know), static.
struct Deformed {
  Eigen::VectorXd x;                                  // nodes, model frame
  std::vector<double> vertices;                       // the same, for a SurfaceView
  std::vector<std::vector<Eigen::Vector2d>> contour;  // its outline at the true pose
};
inline Deformed deformSideways(const phantom::Phantom& c, const FemModel& m) {
  SimulationSettings load;
  load.gravity = c.truePose.R.transpose() * Eigen::Vector3d(9.81 * 3, 0, 0);
  Integrator in(m, c.attachments, load);
  auto truth = in.initialState();
  if (!in.solveStatic(truth).ok) return {};
  Deformed d{truth.x, std::vector<double>(truth.x.data(), truth.x.data() + truth.x.size()), {}};
  SurfaceView deformed = c.surfaceView();
  deformed.vertices = d.vertices.data();
  d.contour = outline(c, c.truePose, deformed);
  return d;
}

inline FemModel organModel(const phantom::Phantom& c) {
  return FemModel::build(c.volume, {{2, {MaterialModel::Corotational, 620e3, 0.45, 1000}}},
                         {MaterialModel::Corotational, 27e3, 0.4, 1000});
}

// A ridge-like curve down the organ's visible side, across the sideways sag of deformSideways (a curve
// along the sag would only slide along itself): in 25 px rows across its middle columns at the true pose,
// the surface node nearest the camera; the image curve is where those nodes project in `truth`.
inline AnatomicalCurve frontRidge(const phantom::Phantom& c, const FemModel& m, const Eigen::VectorXd& truth) {
  const Pinhole cam = c.camera.pinhole();
  std::vector<char> onSurface(m.nodeCount(), 0);
  for (const auto& t : c.surface)
    for (int v : t) onSurface[v] = 1;
  double columnSum = 0;
  int count = 0;
  for (std::size_t i = 0; i < m.nodeCount(); ++i)
    if (onSurface[i]) {
      columnSum += cam.project(c.truePose.apply(m.rest[i])).x();
      ++count;
    }
  const double column = columnSum / count;
  std::map<int, std::pair<double, int>> rows;  // row -> (depth, node)
  for (std::size_t i = 0; i < m.nodeCount(); ++i) {
    if (!onSurface[i]) continue;
    const Eigen::Vector3d q = c.truePose.apply(m.rest[i]);
    const Eigen::Vector2d uv = cam.project(q);
    if (std::abs(uv.x() - column) > 30) continue;
    auto [it, added] = rows.try_emplace(static_cast<int>(uv.y() / 25), q.z(), static_cast<int>(i));
    if (!added && q.z() < it->second.first) it->second = {q.z(), static_cast<int>(i)};
  }
  AnatomicalCurve ridge;
  for (const auto& [row, dn] : rows) {
    ridge.nodes.push_back(dn.second);
    ridge.image.push_back(cam.project(c.truePose.apply(truth.segment<3>(3 * dn.second))));
  }
  return ridge;
}

inline Pose offset(const Pose& p, const Eigen::Vector3d& move, const Eigen::Vector3d& axis, double degrees,
                   const Eigen::Vector3d& centre) {
  // Rotation about the camera axis `axis` through the organ's centre (camera frame), then a translation.
  Pose q =
      p.turnedAbout(Eigen::AngleAxisd(degrees * M_PI / 180, axis.normalized()).toRotationMatrix(), p.apply(centre));
  q.t += move;
  return q;
}
}  // namespace
