#include "rehearse/app/elasticfit.hpp"

#include <rehearse/imaging/motion.hpp>
#include <rehearse/imaging/render.hpp>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rehearse::app {

FitInput fitInputFromCase(const Case& c) {
  FitInput in;
  in.organ = c.organ;
  in.attachments = c.attachments;
  in.materials = labelMaterials(c.material);
  in.contour = c.contour;
  in.camera = c.camera.pinhole();
  in.start = c.pose;
  in.gravityCamera = 9.81 * c.down;
  return in;
}

std::vector<imaging::Track> tracksOnOrgan(const cv::Mat3b& first, const imaging::Contour& firstContour,
                                          const cv::Mat3b& second) {
  cv::Mat1b mask(first.size(), 0);
  std::vector<std::vector<cv::Point>> polygons;
  for (const auto& seg : firstContour.segments)
    if (seg.isSilhouette() && seg.points.size() > 2) {
      polygons.emplace_back();
      for (const auto& p : seg.points)
        polygons.back().emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    }
  cv::fillPoly(mask, polygons, cv::Scalar(255));
  const int margin = std::max(3, first.cols / 100);
  cv::erode(mask, mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * margin + 1, 2 * margin + 1)));
  return imaging::trackFeatures(first, second, mask);
}

simcore::RegistrationFrame secondFrame(const Case& c, std::string* status) {
  if (c.frame2.empty()) throw rehearse::InputError("The case has no second frame.");
  if (c.frame2.size() != c.frame.size())
    throw rehearse::InputError("The second frame is not the first one's size; open a frame of the same video.");
  if (!(c.baselineMm > 0))
    throw rehearse::InputError(
        "The second frame needs how far the scope moved between the frames (mm, step 2): two frames give only the "
        "move's direction.");
  simcore::RegistrationFrame f;
  f.camera = c.camera.pinhole();
  for (const auto& seg : c.contour2.segments)
    if (seg.isSilhouette() && seg.points.size() > 1) f.contour.push_back(seg.points);
  if (f.contour.empty())
    throw rehearse::InputError("The second frame has no outline: sketch the organ's outline on it (step 3).");
  const imaging::CameraMotion m =
      imaging::estimateCameraMotion(c.camera, tracksOnOrgan(c.frame, c.contour, c.frame2), 1e-3 * c.baselineMm);
  if (!m.ok) throw rehearse::InputError("The second frame cannot be used: " + m.status + ".");
  f.motion = m.motion;
  f.motionDepthSigmaM = m.depthSigmaM;
  f.motionAtOneSigma = m.motionAtOneSigma;
  f.tracks = m.inliers;
  if (status) *status = m.status;
  return f;
}

simcore::FemModel fitModel(const FitInput& in) {
  if (!in.organ || in.organ->empty()) throw simcore::MeshError("The fit needs an organ volume; import or tetrahedralise a mesh first (step 1).");
  if (in.organ->volume.unitToMetre != 1.0) {
    simcore::Mesh metres = in.organ->volume;
    metres.convertToMetres();
    return simcore::FemModel::build(metres, in.materials.byLabel, in.materials.fallback, in.embedded);
  }
  return simcore::FemModel::build(in.organ->volume, in.materials.byLabel, in.materials.fallback, in.embedded);
}

simcore::RegistrationResult runElasticFit(const FitInput& in, const FitProgress& progress) {
  const simcore::FemModel model = fitModel(in);
  const auto segments = imaging::silhouetteSegments(in.contour);
  simcore::RegistrationOptions o;
  o.rigidPrepass = in.rigidPrepass;
  o.elastic = in.elastic;
  o.maxIterations = in.maxIterations;
  o.gravityCamera = in.gravityCamera;
  o.frames = in.frames;
  o.toleranceMm = in.toleranceMm;
  for (const auto& s : imaging::anatomicalSegments(in.contour)) o.curves.push_back({s.modelVertices, s.points, s.type});
  if (segments.empty() && o.curves.empty())
    throw simcore::MeshError("The contour has no silhouette segment and no ridge or ligament with its curve on the organ.");
  o.onIteration = progress;
  simcore::RegistrationResult r;
  try {
    r = simcore::registerToContour(model, in.attachments, in.settings, in.organ->surface, segments, in.start, in.camera, o);
  } catch (const simcore::MeshError& e) {
    // The fit's own iterations took an organ that started in front of the camera behind it: said as that, not as a
    // placement to correct (a person's check read "The organ is behind the camera" for an organ 400-500 mm in front).
    simcore::RegistrationResult atStart;
    atStart.x = model.restVector();
    atStart.pose = in.start;
    if (std::string(e.what()).find("behind the camera") == std::string::npos ||
        !fittedShapeProblem(model, in.organ->surface, atStart).empty())
      throw;
    throw simcore::MeshError(
        "its iterations moved the organ behind the camera from where it started in front of it: place the organ "
        "nearer its outline (step 4), or fit without the rigid pre-pass, then fit again.");
  }
  // A person's check on the patient liver (the automatic placement, then the first fit): the fit said "converged" with
  // the organ crossing the image plane and an element folded flat; Keep Fit took it, and step 7 could not start
  // ("Tetrahedron 1702 is flat in the rest shape").
  if (r.ok && !r.cancelled) {
    if (std::string why = fittedShapeProblem(model, in.organ->surface, r); !why.empty()) {
      r.ok = false;
      r.converged = false;
      r.status = std::move(why);
    } else if (const std::string turned = insideOutElements(model, r); !turned.empty()) {
      r.status += "; " + turned;
    }
  } else if (!r.ok && !r.cancelled && r.status.rfind("failed: ", 0) == 0) {
    // Said once ("The fit failed: ..." is the window's), with what to change.
    r.status = r.status.substr(8) +
               "; place the organ nearer its outline (step 4) or hold it by more attachments, then fit again";
  }
  return r;
}

namespace {
// The elements of a fitted shape (x, 3n) flat as FemModel::build finds them (which a simulation started from the shape
// refuses), and those turned inside out against the rest shape (the sign of the rest volume lost; the simulation takes
// such an element at rest as it is).
struct ElementTurns {
  int flat = 0, firstFlat = -1, insideOut = 0, firstInsideOut = -1;
};
ElementTurns elementTurns(const simcore::FemModel& model, const Eigen::VectorXd& x) {
  ElementTurns out;
  for (std::size_t e = 0; e < model.tets.size(); ++e) {
    const auto& t = model.tets[e];
    Eigen::Matrix3d rest, now;
    for (int k = 0; k < 3; ++k) {
      rest.col(k) = model.rest[static_cast<std::size_t>(t[k + 1])] - model.rest[static_cast<std::size_t>(t[0])];
      now.col(k) = x.segment<3>(3 * static_cast<Eigen::Index>(t[k + 1])) - x.segment<3>(3 * static_cast<Eigen::Index>(t[0]));
    }
    const double volume = now.determinant() / 6.0;
    const double scale = std::pow(now.colwise().norm().maxCoeff(), 3);
    if (!(std::abs(volume) > 1e-12 * scale)) {
      if (out.firstFlat < 0) out.firstFlat = static_cast<int>(e);
      ++out.flat;
    } else if (volume * rest.determinant() < 0) {
      if (out.firstInsideOut < 0) out.firstInsideOut = static_cast<int>(e);
      ++out.insideOut;
    }
  }
  return out;
}
}  // namespace

std::string fittedShapeProblem(const simcore::FemModel& model, const std::vector<std::array<int, 3>>& surface,
                               const simcore::RegistrationResult& r) {
  const std::size_t n = model.nodeCount();
  if (static_cast<std::size_t>(r.x.size()) != 3 * n) return {};
  auto at = [&](int i) -> Eigen::Vector3d { return r.x.segment<3>(3 * static_cast<Eigen::Index>(i)); };
  std::vector<char> onSurface(n, 0);
  for (const auto& t : surface)
    for (int v : t)
      if (v >= 0 && static_cast<std::size_t>(v) < n) onSurface[static_cast<std::size_t>(v)] = 1;
  int behind = 0, surfaceNodes = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!onSurface[i]) continue;
    ++surfaceNodes;
    const Eigen::Vector3d p = r.pose.apply(at(static_cast<int>(i)));
    if (!(p.z() > 1e-6) || !p.allFinite()) ++behind;  // (registerToContour's own test of a node in front)
  }
  char text[400];
  if (behind > 0) {
    std::snprintf(text, sizeof text,
                  "the organ came out crossing the camera's image plane (%d of its %d surface nodes at or behind the "
                  "camera), so the fit is not kept: place the organ in front of the camera, nearer its outline (step "
                  "4), then fit again.",
                  behind, surfaceNodes);
    return text;
  }
  const ElementTurns turns = elementTurns(model, r.x);
  if (turns.flat == 0) return {};
  std::snprintf(text, sizeof text,
                "%d of the organ's %zu elements came out flat (element %d first), a shape the organ cannot be "
                "simulated in, so the fit is not kept: place the organ nearer its outline (step 4) or hold it by more "
                "attachments, then fit again.",
                turns.flat, model.tets.size(), turns.firstFlat);
  return text;
}

std::string insideOutElements(const simcore::FemModel& model, const simcore::RegistrationResult& r) {
  if (static_cast<std::size_t>(r.x.size()) != 3 * model.nodeCount()) return {};
  const ElementTurns turns = elementTurns(model, r.x);
  if (turns.insideOut == 0) return {};
  char text[300];
  std::snprintf(text, sizeof text,
                "%d of the organ's %zu elements came out inside out (element %d first): the simulation takes them as "
                "they are; a placement nearer the outline (step 4) avoids it",
                turns.insideOut, model.tets.size(), turns.firstInsideOut);
  return text;
}

std::string uncertaintySentence(const simcore::RegistrationUncertainty& u) {
  if (!u.computed) return "no uncertainty was estimated (it comes from the rigid stage, which did not run)";
  if (!std::isfinite(u.surfaceMm))
    return "the contour does not constrain " + u.weakest + ": the fit's depth there is not determined";
  char text[200];
  std::snprintf(text, sizeof text, "the surface may be up to %.1f mm from where the fit put it (inner targets %.1f mm)",
                u.surfaceMm, u.targetMm);
  std::string out = text;
  if (u.motionMm > 0) {
    std::snprintf(text, sizeof text, ", %.1f mm of it from the estimated camera motion", u.motionMm);
    out += text;
  }
  return out + "; weakest: " + u.weakest;
}

std::vector<std::vector<Eigen::Vector2d>> boundOutlines(const Case& c, const simcore::RegistrationResult& r) {
  std::vector<std::vector<Eigen::Vector2d>> out;
  if (!c.organ || c.organ->surface.empty() || !c.camera.problem().empty()) return out;
  for (const auto& end : r.uncertainty.ends) {
    if (end.x.size() != static_cast<Eigen::Index>(3 * c.organ->volume.points.size())) return {};
    SurfaceView view = c.organ->volume.surfaceView();
    view.vertices = end.x.data();
    view.triangles = c.organ->surface.front().data();
    view.triangleCount = c.organ->surface.size();
    for (std::size_t i = 0; i < view.vertexCount; ++i)
      if (!(end.pose.apply(view.vertex(i)).z() > 1e-3)) return {};  // (a far end behind the camera: not drawn)
    auto outlines = imaging::maskOutlines(imaging::renderMask(c.camera, end.pose, view));
    if (outlines.empty()) continue;
    // The outer outline: the longest.
    out.push_back(*std::max_element(outlines.begin(), outlines.end(),
                                    [](const auto& a, const auto& b) { return a.size() < b.size(); }));
  }
  return out;
}

std::shared_ptr<const ElasticFit> toCasePart(const simcore::RegistrationResult& r) {
  auto f = std::make_shared<ElasticFit>();
  f->nodes.resize(static_cast<std::size_t>(r.x.size() / 3));
  for (std::size_t i = 0; i < f->nodes.size(); ++i) f->nodes[i] = r.x.segment<3>(3 * static_cast<Eigen::Index>(i));
  f->status = r.status;
  return f;
}

}  // namespace rehearse::app
