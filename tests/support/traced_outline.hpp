#pragma once
// The outline of the organ a frame shows, traced as a hand would for a test or a benchmark of step 6 (issue 62): the
// silhouette of `surface` at `pose`, every sixth border pixel, in two pieces with a gap of a tenth of the outline
// between them, each point off the border by a normal deviate of 2 px (seeded: the same outline on every run).
#include <rehearse/imaging/contour.hpp>
#include <rehearse/imaging/render.hpp>

#include <random>

inline rehearse::imaging::Contour handTracedOutline(const rehearse::imaging::Camera& camera, const rehearse::Pose& pose,
                                                    const rehearse::SurfaceView& surface) {
  using namespace rehearse;
  imaging::Contour contour;
  const auto borders = imaging::maskOutlines(imaging::renderMask(camera, pose, surface));
  if (borders.empty()) return contour;
  const auto& b = borders.front();
  contour.width = camera.width, contour.height = camera.height;
  contour.segments.resize(2);
  std::mt19937 rng(11);
  std::normal_distribution<double> n01;
  for (std::size_t i = 0; i < b.size(); i += 6) {
    if (i > b.size() * 45 / 100 && i < b.size() * 55 / 100) continue;
    const Eigen::Vector2d along = b[(i + 2) % b.size()] - b[(i + b.size() - 2) % b.size()];
    const Eigen::Vector2d normal = Eigen::Vector2d(along.y(), -along.x()).normalized();
    contour.segments[i < b.size() / 2 ? 0 : 1].points.push_back(b[i] + 2 * n01(rng) * normal);
  }
  return contour;
}
