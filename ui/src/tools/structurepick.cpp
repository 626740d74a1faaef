// The vessel or duct under a frame pixel, as the view draws it: the elements labelled with it (the overlay draws a
// structure as the boundary of its labelled elements), crossed by the view ray. A person aims at what is drawn; a test
// on the structure's nodes alone (3 mm from the ray) missed a trunk whose nodes lie farther apart than that.
#include "tools.hpp"

#include "rehearse/simcore/session/field.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <limits>

namespace rehearse::ui::tools {
namespace {

/// The parameters t between which the line o + t d is inside the tetrahedron `x`, from t = 0 on; none when it misses.
std::optional<std::pair<double, double>> rayThrough(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                                    const std::array<Eigen::Vector3d, 4>& x) {
  Eigen::Matrix3d m;
  m << x[1] - x[0], x[2] - x[0], x[3] - x[0];
  const double det = m.determinant();
  const double scale = (x[1] - x[0]).norm() * (x[2] - x[0]).norm() * (x[3] - x[0]).norm();
  if (!(std::abs(det) > 1e-12 * scale) || !std::isfinite(det)) return std::nullopt;  // flat or broken: not aimed at
  const Eigen::Matrix3d inv = m.inverse();
  // Barycentric coordinates along the ray: l(t) = alpha + beta t, all four non-negative inside.
  const Eigen::Vector3d alpha = inv * (o - x[0]), beta = inv * d;
  double lo = 0, hi = std::numeric_limits<double>::infinity();
  auto keep = [&](double a, double b) {  // a + b t >= 0
    if (std::abs(b) < 1e-300) return a >= 0;
    const double t = -a / b;
    if (b > 0)
      lo = std::max(lo, t);
    else
      hi = std::min(hi, t);
    return lo <= hi;
  };
  for (int k = 0; k < 3; ++k)
    if (!keep(alpha[k], beta[k])) return std::nullopt;
  if (!keep(1 - alpha.sum(), -beta.sum())) return std::nullopt;
  return std::make_pair(lo, hi);
}

}  // namespace

std::optional<StructureUnder> structureUnder(const FrameView& view, const Eigen::Vector2d& f, double from, double to) {
  return structureAlong(view, Eigen::Vector3d::Zero(), pointAtDepth(view, f, 1.0), from, to);  // (t: camera depth)
}

std::optional<StructureUnder> structureAlong(const FrameView& view, const Eigen::Vector3d& origin,
                                             const Eigen::Vector3d& direction, double from, double to) {
  const auto& c = view.caseData();
  if (!c || !c->organ) return std::nullopt;
  const simcore::Mesh& names = c->organ->volume;
  const auto& live = view.liveShape();
  // The elements as the simulation has them now (after a cut or a burn); the organ's own before the first frame.
  const std::vector<std::array<int, 4>>& tets = view.liveTets() ? *view.liveTets() : names.tets;
  const std::vector<int>& labels = view.liveLabels() ? *view.liveLabels() : names.tetLabels;
  if (labels.size() != tets.size()) return std::nullopt;
  // Each clampable structure's crossings along the ray, then the shallowest structure entered between from and to.
  std::vector<std::pair<int, std::pair<double, double>>> crossings;
  // Each label's kind found once a call (Mesh::labelKind parses its name: per element, on every move of a scissors
  // stroke over a 17k-element organ, on the GUI thread).
  std::vector<std::pair<int, bool>> clampable;
  auto isClampable = [&](int label) {
    for (const auto& [l, yes] : clampable)
      if (l == label) return yes;
    const simcore::StructureKind k = names.labelKind(label);
    clampable.emplace_back(label, simcore::isVessel(k) || k == simcore::StructureKind::BileDuct);
    return clampable.back().second;
  };
  for (std::size_t e = 0; e < tets.size(); ++e) {
    const int label = simcore::unburntLabel(labels[e]);
    if (label == 0 || !isClampable(label)) continue;
    std::array<Eigen::Vector3d, 4> x;
    bool inside = true;
    for (int v = 0; v < 4; ++v) {
      const auto i = static_cast<std::size_t>(tets[e][static_cast<std::size_t>(v)]);
      if (i >= live.size()) {
        inside = false;
        break;
      }
      x[static_cast<std::size_t>(v)] = live[i];
    }
    if (!inside) continue;
    if (const auto span = rayThrough(origin, direction, x); span && span->second >= from && span->first <= to)
      crossings.push_back({label, *span});
  }
  if (crossings.empty()) return std::nullopt;
  std::sort(crossings.begin(), crossings.end(),
            [](const auto& a, const auto& b) { return a.second.first < b.second.first; });
  StructureUnder out;
  out.label = crossings.front().first;
  out.entry = std::max(from, crossings.front().second.first);
  out.exit = crossings.front().second.second;
  // The structure's elements along the ray one after another (0.1 mm of slack between neighbours' faces).
  for (const auto& [label, span] : crossings)
    if (label == out.label && span.first <= out.exit + 1e-4) out.exit = std::max(out.exit, span.second);
  out.name = simcore::structureWords(names.labelKind(out.label), names.labelName(out.label));
  return out;
}

}  // namespace rehearse::ui::tools
