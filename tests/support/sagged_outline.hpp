#pragma once
// The assistant's contour for a GUI test: the outline of the case's organ sagging under 2 g sideways (a deformation
// the elastic fit must find), seen at the ground-truth pose; every third point of the mask's outer border. Empty when
// the sag does not solve or the organ is not in view.
#include "rehearse/app/case.hpp"

#include <rehearse/imaging/contour.hpp>
#include <rehearse/imaging/render.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/integrator.hpp>

inline rehearse::imaging::ContourSegment saggedOutline(const rehearse::app::Case& c) {
  using namespace rehearse;
  const simcore::FemModel model =
      simcore::FemModel::build(c.organ->volume, {}, {simcore::MaterialModel::Corotational, 27e3, 0.4, 1000});
  simcore::SimulationSettings load;
  load.gravity = c.groundTruth->pose.R.transpose() * Eigen::Vector3d(2 * 9.81, 0, 0);
  simcore::Integrator sag(model, c.attachments, load);
  auto sagged = sag.initialState();
  imaging::ContourSegment seg;
  if (!sag.solveStatic(sagged).ok) return seg;
  SurfaceView deformed = c.surfaceView();
  deformed.vertices = sagged.x.data();
  const auto borders = imaging::maskOutlines(imaging::renderMask(c.camera, c.groundTruth->pose, deformed));
  if (borders.empty()) return seg;
  for (std::size_t i = 0; i < borders.front().size(); i += 3) seg.points.push_back(borders.front()[i]);
  return seg;
}
