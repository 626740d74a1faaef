#pragma once
// The case with the simulation's nodes as its shape (as an elastic fit's), for the views that draw a case: the live
// overlay (liveoverlay.cpp) and the 3D view while rehearsing (mainwindow_docks.cpp). Uncut only: a cut organ has nodes
// the case's surface does not (the caller draws the cut surface, or says the view shows the organ at rest).
#include "rehearse/ui/organglview.hpp"
#include "rehearse/ui/organview.hpp"

#include <rehearse/app/case.hpp>

#include <memory>
#include <vector>

namespace rehearse::ui {

/// `c` with `positions` (camera frame, one per node of the case's organ) as its shape.
inline app::Case simulatedCase(const app::Case& c, const std::vector<Eigen::Vector3d>& positions) {
  app::Case live(c);
  auto fit = std::make_shared<app::ElasticFit>();
  fit->nodes.reserve(positions.size());
  for (const auto& x : positions) fit->nodes.push_back(c.pose.R.transpose() * (x - c.pose.t));
  fit->status = "simulated";
  live.fit = fit;
  return live;
}

/// Shows `c` in an organ view (the OpenGL one or the CPU one; anything else is left alone).
inline void showInOrganView(QWidget* view, std::shared_ptr<const app::Case> c) {
  if (auto* gl = qobject_cast<OrganGLView*>(view))
    gl->setCase(std::move(c));
  else if (auto* cpu = qobject_cast<OrganView*>(view))
    cpu->setCase(std::move(c));
}

}  // namespace rehearse::ui
