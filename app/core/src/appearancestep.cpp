#include "rehearse/app/appearancestep.hpp"
#include <rehearse/text_input.hpp>

#include <rehearse/imaging/render.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>

namespace rehearse::app {
namespace {

// What composition takes from the frame at rest: the background behind the organ and the albedo.
void restLayers(const AppearanceInput& in, const imaging::SurfaceGeometry& g, const imaging::Appearance& theta, const cv::Mat3b& diffuse,
                const cv::Mat1b& usable, cv::Mat3b& background, cv::Mat3f& albedo, double* inpaintMs = nullptr) {
  const auto t0 = std::chrono::steady_clock::now();
  background = imaging::inpaintRegion(in.frame, g.mask(), in.inpaint);
  if (inpaintMs) *inpaintMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  albedo = imaging::albedoRatio(diffuse, g, theta, usable);
}

// What Theta leaves of the frame on the organ (step 6 shows it): |frame - Theta rendered with albedo 1| x 3 there,
// black elsewhere; the organ's texture, specks, beads and wherever the model does not hold.
cv::Mat3b residualOn(const AppearanceInput& in, const imaging::Appearance& theta, const imaging::SurfaceGeometry& g) {
  const cv::Mat3b model =
      imaging::renderShaded(in.camera, in.pose, in.surface(), theta, cv::Mat3b(in.frame.size(), cv::Vec3b(0, 0, 0)), 1);
  cv::Mat3b residual;
  cv::absdiff(in.frame, model, residual);
  residual.convertTo(residual, CV_8UC3, 3.0);
  residual.setTo(cv::Scalar(0, 0, 0), ~g.mask());
  return residual;
}

// The organ's geometry at rest, refusing an organ the frame does not show.
imaging::SurfaceGeometry restGeometry(const AppearanceInput& in) {
  if (in.frame.empty()) throw rehearse::InputError("There is no frame to estimate the appearance from; grab a frame first (step 2).");
  if (in.frame.cols != in.camera.width || in.frame.rows != in.camera.height)
    throw rehearse::InputError("The frame is " + std::to_string(in.frame.cols) + "x" + std::to_string(in.frame.rows) + " but the camera is calibrated for " +
                              std::to_string(in.camera.width) + "x" + std::to_string(in.camera.height) + "; use the camera of this frame.");
  if (in.triangles.empty()) throw rehearse::InputError("The organ has no surface; load the organ first (step 1).");
  imaging::SurfaceGeometry g = imaging::surfaceGeometry(in.camera, in.pose, in.surface());
  if (cv::countNonZero(g.mask()) == 0) throw rehearse::InputError("The organ is not in the frame at this pose; align it first (step 4).");
  return g;
}

}  // namespace

AppearanceInput appearanceInputFromCase(const Case& c) {
  AppearanceInput in;
  in.camera = c.camera;
  in.pose = c.pose;
  // The organ's own surface when it has one (carried by the volume's nodes), else the volume's boundary.
  const std::vector<Eigen::Vector3d> visual =
      c.organ->visual ? c.organ->visual->map(c.shapeNodes()) : std::vector<Eigen::Vector3d>{};
  const auto& points = visual.empty() ? c.shapeNodes() : visual;
  in.vertices.reserve(3 * points.size());
  for (const auto& x : points) in.vertices.insert(in.vertices.end(), {x.x(), x.y(), x.z()});
  in.triangles = visual.empty() ? c.organ->surface : c.organ->visual->triangles;
  in.frame = c.frame;
  in.contour = c.contour;
  return in;
}

CutComposition makeCutCompositor(const imaging::Compositor& base, const Case& c, const simcore::CutSurface& cut) {
  const auto& volume = c.organ->volume;
  const std::size_t n0 = volume.points.size(), n = cut.rest.size();
  if (n < n0 || n0 == 0 || cut.triangles.empty() || cut.cut.size() != cut.triangles.size())
    throw rehearse::InputError("The cut organ is not this case's organ; it cannot be composited.");
  const auto& shape = c.shapeNodes();
  std::vector<Eigen::Vector3d> placed(shape.begin(), shape.end());
  if (n > n0) {
    // The cuts' new nodes: where they lie in the uncut organ at rest, carried to the shape the frame shows.
    const std::vector<Eigen::Vector3d> restOld(cut.rest.begin(), cut.rest.begin() + static_cast<std::ptrdiff_t>(n0));
    const std::vector<Eigen::Vector3d> restNew(cut.rest.begin() + static_cast<std::ptrdiff_t>(n0), cut.rest.end());
    const auto moved = simcore::mapEmbedded(simcore::embedPoints(restOld, volume.tets, restNew), placed);
    placed.insert(placed.end(), moved.begin(), moved.end());
  }
  CutComposition out;
  out.restVertices.reserve(3 * n);
  for (const auto& p : placed) out.restVertices.insert(out.restVertices.end(), {p.x(), p.y(), p.z()});
  // Preset interior colours, as albedo ratios against the surface's k_d (BGR): a liver's cut parenchyma is darker
  // and redder than its capsule, a cut vessel shows blood, a tumour is paler.
  const std::vector<cv::Vec3f> materials = {{0.60f, 0.60f, 0.80f}, {0.20f, 0.20f, 0.55f}, {1.25f, 1.25f, 1.15f}};
  std::vector<int> material(cut.triangles.size(), 0);
  for (std::size_t k = 0; k < material.size(); ++k) {
    if (!cut.cut[k]) continue;
    const int label = k < cut.labels.size() ? cut.labels[k] : kParenchymaLabel;
    material[k] = volume.labelIsVessel(label)                                      ? 2
                  : (label == kParenchymaLabel || volume.labelName(label).empty()) ? 1
                                                                                   : 3;
  }
  const SurfaceView rest{out.restVertices.data(), n, cut.triangles.front().data(), cut.triangles.size()};
  out.compositor = base.reshaped(rest, std::move(material), materials);
  out.said =
      "Cut faces take preset interior colours, not ones estimated from this frame: the parenchyma 80/60/60 % of the "
      "surface's red/green/blue, a vessel's blood 55/20/20 %, other inner structures paler.";
  if (c.appearance && c.appearance->textureOnly)
    out.said +=
        " The estimate explains too little of the frame's shading, so the cut faces' shading is only approximate.";
  return out;
}

std::shared_ptr<const AppearanceEstimate> estimateFromRun(const AppearanceOutput& out, const Case& c, imaging::InpaintMethod inpaint) {
  auto e = std::make_shared<AppearanceEstimate>();
  e->theta = out.fit.theta;
  e->highlightFound = out.fit.highlightFound;
  e->textureOnly = out.fit.textureOnly;
  e->ksMeasured = out.fit.ksMeasured;
  e->explained = out.fit.explained;
  e->smoothShare = out.fit.smoothShare;
  e->lightAtBound = out.fit.lightAtBound;
  e->checks = out.fit.checks;
  e->scopeExplained = out.fit.scopeExplained;
  e->sources = out.fit.sources;
  e->status = out.fit.status;
  e->turnSaid = out.turn.sentence;
  e->turned = out.turn.adopted;
  e->inpaint = imaging::inpaintMethodName(inpaint);
  e->stages = out.fit.stages;
  e->restPsnr = out.restPsnr;
  e->totalMs = out.totalMs;
  e->pose = out.turn.adopted ? out.turn.pose : c.pose;
  e->shapeDigest = c.shapeDigest();
  e->frameWidth = c.frame.cols;
  e->frameHeight = c.frame.rows;
  e->frameDigest = c.frameDigest();
  return e;
}

namespace {
using json = nlohmann::json;
json vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }
Eigen::Vector3d vec3(const json& j) {
  const Eigen::Vector3d v(j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>());
  if (!v.allFinite()) throw std::runtime_error("a vector holds a number that is not finite");
  return v;
}
}  // namespace

std::string appearanceEstimateToJson(const AppearanceEstimate& e) {
  json stages = json::array();
  for (const auto& s : e.stages) stages.push_back({{"name", s.name}, {"rms_levels", s.rms}, {"ms", s.ms}, {"pixels", s.pixels}});
  json r = json::array();
  for (int i = 0; i < 3; ++i) r.push_back(json::array({e.pose.R(i, 0), e.pose.R(i, 1), e.pose.R(i, 2)}));
  return json{{"light_position", vec(e.theta.lightPosition)},
              {"kd", vec(e.theta.kd)},
              {"ks", vec(e.theta.ks)},
              {"roughness", e.theta.roughness},
              {"falloff", e.theta.falloff},
              {"distant_light",
               e.theta.hasDistantLight() ? json{{"direction", vec(e.theta.roomDirection)}, {"kr", vec(e.theta.kr)}}
                                         : json(nullptr)},
              {"ambient", e.theta.hasAmbient() ? vec(e.theta.ka) : json(nullptr)},
              {"scope_explained", e.scopeExplained},
              {"second_sources",
               [&] {
                 json c = json::array();
                 for (const auto& k : e.sources)
                   c.push_back({{"name", k.name}, {"explained", k.explainedWith}, {"used", k.used}});
                 return c;
               }()},
              {"highlight_found", e.highlightFound},
              {"texture_only", e.textureOnly},
              {"ks_measured", {e.ksMeasured[0], e.ksMeasured[1], e.ksMeasured[2]}},
              {"explained", e.explained},
              {"smooth_share", e.smoothShare},
              {"light_at_bound", e.lightAtBound},
              {"checks",
               [&] {
                 json c = json::array();
                 for (const auto& k : e.checks)
                   c.push_back({{"without", k.part}, {"explained", k.explainedWithout}, {"holds", k.holds}});
                 return c;
               }()},
              {"status", e.status},
              {"turn_said", e.turnSaid},
              {"turned", e.turned},
              {"inpaint", e.inpaint},
              {"stages", stages},
              {"rest_psnr_db", e.restPsnr},
              {"total_ms", e.totalMs},
              {"fitted_on",
               {{"pose", {{"R", r}, {"t", vec(e.pose.t)}}},
                {"shape_digest", e.shapeDigest},
                {"frame_size", {e.frameWidth, e.frameHeight}},
                {"frame_digest", e.frameDigest}}}}
      .dump();
}

std::shared_ptr<const AppearanceEstimate> appearanceEstimateFromJson(const std::string& text) {
  if (const std::string why = jsonTextProblem(text, "the appearance estimate"); !why.empty()) throw std::runtime_error(why);
  const json j = json::parse(text);
  auto e = std::make_shared<AppearanceEstimate>();
  e->theta.lightPosition = vec3(j.at("light_position"));
  e->theta.kd = vec3(j.at("kd"));
  e->theta.ks = vec3(j.at("ks"));
  e->theta.roughness = j.at("roughness").get<double>();
  e->theta.falloff = j.value("falloff", 0.0);  // estimates from before the scope's fall-off: an isotropic light
  // A second source (estimates without one, or from before it: none).
  if (j.contains("distant_light") && !j.at("distant_light").is_null()) {
    e->theta.roomDirection = vec3(j.at("distant_light").at("direction"));
    e->theta.kr = vec3(j.at("distant_light").at("kr"));
  }
  if (j.contains("ambient") && !j.at("ambient").is_null()) e->theta.ka = vec3(j.at("ambient"));
  e->scopeExplained = j.value("scope_explained", j.value("explained", 0.0));
  if (j.contains("second_sources"))
    for (const auto& k : j.at("second_sources"))
      e->sources.push_back({k.at("name").get<std::string>(), k.at("explained").get<double>(), k.at("used").get<bool>()});
  if (const std::string why = imaging::appearanceProblem(e->theta, true); !why.empty()) throw std::runtime_error(why);
  e->highlightFound = j.value("highlight_found", false);
  e->textureOnly = j.value("texture_only", false);
  e->smoothShare = j.value("smooth_share", 0.0);
  e->lightAtBound = j.value("light_at_bound", false);
  if (j.contains("checks"))
    for (const auto& k : j.at("checks"))
      e->checks.push_back(
          {k.at("without").get<std::string>(), k.at("explained").get<double>(), k.at("holds").get<bool>()});
  const auto& m = j.at("ks_measured");
  for (std::size_t i = 0; i < 3; ++i) e->ksMeasured[i] = m.at(i).get<bool>();
  e->explained = j.value("explained", 0.0);
  e->status = j.value("status", std::string());
  e->turnSaid = j.value("turn_said", std::string());
  e->turned = j.value("turned", false);
  e->inpaint = j.value("inpaint", std::string("ns"));  // (an estimate saved before the method was kept: the default then)
  for (const auto& s : j.value("stages", json::array()))
    e->stages.push_back({s.at("name").get<std::string>(), s.at("rms_levels").get<double>(), s.at("ms").get<double>(), s.at("pixels").get<std::size_t>()});
  e->restPsnr = j.value("rest_psnr_db", 0.0);
  e->totalMs = j.value("total_ms", 0.0);
  const auto& on = j.at("fitted_on");
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) e->pose.R(i, k) = on.at("pose").at("R").at(i).at(k).get<double>();
  e->pose.t = vec3(on.at("pose").at("t"));
  e->shapeDigest = on.at("shape_digest").get<double>();
  e->frameWidth = on.at("frame_size").at(0).get<int>();
  e->frameHeight = on.at("frame_size").at(1).get<int>();
  e->frameDigest = on.at("frame_digest").get<double>();
  return e;
}

namespace {

// The outline's points' mean distance (pixels of `mask`) to the silhouette's edge in `mask`; infinite when the
// mask is empty.
double outlineDistance(const cv::Mat1b& mask, const std::vector<Eigen::Vector2d>& points) {
  cv::Mat1b eroded;
  cv::erode(mask, eroded, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)), cv::Point(-1, -1), 1,
            cv::BORDER_CONSTANT, cv::Scalar(0));
  const cv::Mat1b edge = mask & ~eroded;
  if (cv::countNonZero(edge) == 0) return std::numeric_limits<double>::infinity();
  cv::Mat1f d;
  cv::distanceTransform(~edge, d, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  double sum = 0;
  std::size_t n = 0;
  for (const auto& p : points) {
    const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
    if (x < 0 || y < 0 || x >= d.cols || y >= d.rows) continue;
    sum += d(y, x), ++n;
  }
  return n ? sum / static_cast<double>(n) : std::numeric_limits<double>::infinity();
}

// The outline's silhouette points in pixels of the camera scaled by `scale` (pixel centres kept).
std::vector<Eigen::Vector2d> outlinePoints(const imaging::Contour& contour, const imaging::Camera& camera, double scale) {
  std::vector<Eigen::Vector2d> out;
  const double toCamera = contour.width > 0 ? static_cast<double>(camera.width) / contour.width : 1.0;
  for (const auto& segment : contour.segments)
    if (segment.isSilhouette())
      for (const auto& p : segment.points) out.push_back(((toCamera * p).array() + 0.5) * scale - 0.5);
  return out;
}

std::string degrees(double d) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f\u00b0", std::abs(d));
  return text;
}

std::string turnText(double x, double y) {
  std::string text;
  if (std::abs(x) >= 0.05)
    text = degrees(x) + (x > 0 ? " about the camera's X axis (its top nearer)" : " about the camera's X axis (its top away)");
  if (std::abs(y) >= 0.05)
    text += std::string(text.empty() ? "" : " and ") + degrees(y) +
            (y > 0 ? " about its Y axis (its right side nearer)" : " about its Y axis (its left side nearer)");
  return text;
}

// One round of the search of the turn the outline leaves open (ShadingTurn), from `in.pose` whose fit is `first` and
// geometry `current`; the outline is held to how well `registered` (the pose as registered) met it. `progress` takes
// shares of the round (0..1).
ShadingTurn searchTurn(const AppearanceInput& in, const imaging::SurfaceGeometry& current, const Pose& registered,
                       const imaging::AppearanceFitResult& first, const imaging::AppearanceFitOptions& fitOptions,
                       const std::function<bool(double, const std::string&)>& progress,
                       imaging::AppearanceFitResult* turnedFit) {
  const auto t0 = std::chrono::steady_clock::now();
  ShadingTurn turn;
  turn.pose = in.pose;
  // The turn is judged by what the scope's light alone explains (AppearanceFitResult::scopeExplained): a second source
  // (a distant light) can stand in for a wrong orientation of the organ's normals, so the full fits' shares would hide
  // the turn the shading asks for.
  turn.explainedBefore = turn.explainedAfter = first.scopeExplained;
  const std::vector<Eigen::Vector2d> full = outlinePoints(in.contour, in.camera, 1.0);
  if (full.size() < 10) {
    turn.sentence = "The turn the outline leaves open was not searched: there is no silhouette outline (step 3) to keep the organ on.";
    return turn;
  }
  turn.searched = true;
  turn.outlineBeforePx = turn.outlineAfterPx = outlineDistance(current.mask(), full);
  // The working camera, at most 960 px wide.
  const double scale = std::min(1.0, 960.0 / in.camera.width);
  imaging::Camera small = in.camera;
  small.width = std::max(1, static_cast<int>(std::lround(in.camera.width * scale)));
  small.height = std::max(1, static_cast<int>(std::lround(in.camera.height * scale)));
  small.K(0, 0) *= scale, small.K(1, 1) *= scale, small.K(0, 1) *= scale;
  small.K(0, 2) = (in.camera.K(0, 2) + 0.5) * scale - 0.5;
  small.K(1, 2) = (in.camera.K(1, 2) + 0.5) * scale - 0.5;
  const cv::Size size(small.width, small.height);
  cv::Mat3b diffuse;
  cv::resize(first.separation.diffuse, diffuse, size, 0, 0, cv::INTER_AREA);
  // The pixels the shading is compared on: the registered organ's usable ones of its colour, away from highlights.
  cv::Mat1b base = first.usable.clone();
  if (!first.foreign.empty()) base &= ~first.foreign;
  if (first.separation.count > 0) {
    cv::Mat1b grown;
    cv::dilate(first.separation.highlights, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)));
    base.setTo(0, grown);
  }
  cv::resize(base, base, size, 0, 0, cv::INTER_NEAREST);
  const std::vector<Eigen::Vector2d> points = outlinePoints(in.contour, in.camera, scale);
  const SurfaceView surface = in.surface();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < surface.vertexCount; ++i)
    centre += in.pose.apply(Eigen::Vector3d(surface.vertices[3 * i], surface.vertices[3 * i + 1], surface.vertices[3 * i + 2]));
  centre /= static_cast<double>(std::max<std::size_t>(1, surface.vertexCount));
  auto turned = [&](double ax, double ay) {
    const Eigen::Matrix3d Q = (Eigen::AngleAxisd(ax * M_PI / 180, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(ay * M_PI / 180, Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    return in.pose.turnedAbout(Q, centre);
  };
  // The outline holds the organ as well as it was drawn: a turn may move its silhouette off the outline by half a pixel
  // and half the registered pose's own distance to it (a hand's outline the fit met to 2.4 px allows 1.7 px more; an
  // exact one met to 0.6 px, 0.8 px).
  constexpr double kMaxDeg = 15;
  const double anchor = outlineDistance(imaging::renderMask(small, registered, surface), points) / scale;
  const double allowed = anchor + 0.5 + 0.5 * anchor;
  std::map<std::pair<long, long>, double> scored;  // (x, y) in 1/1000 degree -> share (-inf: off the outline)
  auto score = [&](double ax, double ay) {
    const std::pair<long, long> key{std::lround(ax * 1000), std::lround(ay * 1000)};
    if (const auto it = scored.find(key); it != scored.end()) return it->second;
    double share = -std::numeric_limits<double>::infinity();
    try {
      const imaging::SurfaceGeometry g = imaging::surfaceGeometry(small, turned(ax, ay), surface);
      const cv::Mat1b mask = g.mask();
      const double distance = outlineDistance(mask, points) / scale;
      if (distance <= allowed || key == std::pair<long, long>{0, 0}) {
        cv::Mat1b inner;
        cv::erode(mask, inner, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)));
        share = imaging::diffuseShareAt(diffuse, g, base & inner, first.scopeTheta, 1500, 40);
        ++turn.candidates;
      }
    } catch (const rehearse::InputError&) {
    }
    scored[key] = share;
    return share;
  };
  auto say = [&](double share, const char* what) {
    if (progress && !progress(share, what)) throw imaging::AppearanceCancelled();
  };
  say(0.0, "settling the turn the outline leaves open");
  double bestX = 0, bestY = 0, best = score(0, 0);
  const double registeredShare = best;
  int k = 0;
  for (double ax = -10; ax <= 10; ax += 5)
    for (double ay = -10; ay <= 10; ay += 5) {
      say(0.6 * (k++) / 25.0, "settling the turn the outline leaves open");
      if (const double v = score(ax, ay); v > best) best = v, bestX = ax, bestY = ay;
    }
  for (double step = 2.5; step >= 0.6; step /= 2) {
    for (bool moved = true; moved;) {
      moved = false;
      say(0.6 + 0.3 * (2.5 - step) / 1.9, "settling the turn the outline leaves open");
      const double cx = bestX, cy = bestY;
      for (const auto& [dx, dy] : {std::pair{step, 0.0}, {-step, 0.0}, {0.0, step}, {0.0, -step}}) {
        const double ax = cx + dx, ay = cy + dy;
        if (std::abs(ax) > kMaxDeg || std::abs(ay) > kMaxDeg) continue;
        if (const double v = score(ax, ay); v > best + 1e-4) best = v, bestX = ax, bestY = ay, moved = true;
      }
    }
  }
  turn.aboutXDeg = bestX, turn.aboutYDeg = bestY;
  turn.scoredBefore = registeredShare, turn.scoredBest = best;
  auto finish = [&] {
    turn.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return turn;
  };
  char text[400];
  if ((bestX == 0 && bestY == 0) || best < registeredShare + 0.02) {
    std::snprintf(text, sizeof text,
                  "The shading asks for no turn of the organ: of %d turns that keep it on the outline, none explains "
                  "clearly more of it.",
                  turn.candidates);
    turn.sentence = text;
    return finish();
  }
  // The working resolution's share is within a few points of the full fit's: far below what re-shading needs, no
  // turn is worth a full fit.
  if (best < fitOptions.poorShare - 0.1) {
    std::snprintf(text, sizeof text,
                  "The organ was left where it was registered: no turn that keeps it on the outline lets the light "
                  "explain enough of the shading (at best %.0f %%, of %d turns).",
                  100 * std::max(best, 0.0), turn.candidates);
    turn.sentence = text;
    return finish();
  }
  say(0.9, "fitting the appearance at the turned pose");
  const Pose pose = turned(bestX, bestY);
  const imaging::SurfaceGeometry g = imaging::surfaceGeometry(in.camera, pose, surface);
  const double outline = outlineDistance(g.mask(), full);
  imaging::AppearanceFitResult refit = imaging::fitAppearance(in.frame, g, fitOptions);
  turn.explainedAfter = refit.scopeExplained;
  turn.outlineAfterPx = outline;
  // (The outline was held at the working resolution, where the turn was chosen; `outline` is reported.)
  if (refit.scopeExplained >= first.scopeExplained + 0.03 && refit.explained >= fitOptions.poorShare) {
    turn.adopted = true;
    turn.pose = pose;
    *turnedFit = std::move(refit);
  } else {
    std::snprintf(text, sizeof text,
                  "The organ was left where it was: turned %s the scope's light explains %.0f %% of the shading (here "
                  "%.0f %%), too little to move it for.",
                  turnText(bestX, bestY).c_str(), 100 * refit.scopeExplained, 100 * first.scopeExplained);
    turn.sentence = text;
  }
  return finish();
}

}  // namespace

AppearanceOutput runAppearance(const AppearanceInput& input) {
  const auto t0 = std::chrono::steady_clock::now();
  auto since = [](auto a) { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count(); };
  const imaging::SurfaceGeometry registered = restGeometry(input);
  AppearanceOutput out;
  imaging::AppearanceFitOptions o;
  const bool search = input.turnByShading;
  const double fitShare = search ? 0.45 : 0.8;
  o.progress = [&](double share, const std::string& what) { return !input.progress || input.progress(fitShare * share, what); };
  out.fit = imaging::fitAppearance(input.frame, registered, o);
  out.turn.pose = input.pose;
  AppearanceInput in = input;  // at the turned pose once one is adopted
  std::optional<imaging::SurfaceGeometry> turnedGeometry;
  if (search) {
    // Rounds of up to 15 degrees each, from where the last one turned the organ, while each is taken.
    imaging::AppearanceFitOptions quiet = o;
    constexpr int kRounds = 3;
    ShadingTurn& total = out.turn;
    for (int round = 0; round < kRounds; ++round) {
      const double from = 0.45 + 0.35 * round / kRounds, span = 0.35 / kRounds;
      quiet.progress = [&](double share, const std::string& what) {
        return !input.progress || input.progress(from + span * (0.8 + 0.2 * share), what);
      };
      imaging::AppearanceFitResult refit;
      const ShadingTurn t = searchTurn(
          in, turnedGeometry ? *turnedGeometry : registered, input.pose, out.fit, quiet,
          [&](double share, const std::string& what) { return !input.progress || input.progress(from + span * 0.8 * share, what); },
          &refit);
      if (round == 0) total = t;
      else total.candidates += t.candidates, total.ms += t.ms;
      if (!t.adopted) break;
      total.adopted = true;
      total.pose = t.pose;
      total.explainedAfter = t.explainedAfter;
      total.outlineAfterPx = t.outlineAfterPx;
      total.scoredBest = t.scoredBest;
      out.fit = std::move(refit);
      in.pose = t.pose;
      turnedGeometry = imaging::surfaceGeometry(in.camera, in.pose, in.surface());
    }
    if (total.adopted) {
      // The whole turn as angles about the camera's X and Y axes (R = Rx(a) Ry(b) up to a small turn about Z).
      const Eigen::Matrix3d Q = total.pose.R * input.pose.R.transpose();
      total.aboutYDeg = std::asin(std::clamp(Q(0, 2), -1.0, 1.0)) * 180 / M_PI;
      total.aboutXDeg = std::atan2(-Q(1, 2), Q(2, 2)) * 180 / M_PI;
      char text[500];
      std::snprintf(text, sizeof text,
                    "The organ was turned %s, a turn the outline leaves open: the scope's light then explains %.0f %% instead "
                    "of %.0f %%, the outline %.1f px from its silhouette (was %.1f px). Undo puts it back.",
                    turnText(total.aboutXDeg, total.aboutYDeg).c_str(), 100 * total.explainedAfter, 100 * total.explainedBefore, total.outlineAfterPx,
                    total.outlineBeforePx);
      total.sentence = text;
    }
  }
  const imaging::SurfaceGeometry& g = turnedGeometry ? *turnedGeometry : registered;
  if (in.progress && !in.progress(0.8, "filling the background behind the organ")) throw imaging::AppearanceCancelled();
  restLayers(in, g, out.fit.theta, out.fit.separation.diffuse, out.fit.usable, out.background, out.albedo, &out.inpaintMs);
  const cv::Mat3b rest = composeAppearance(in, out.fit.theta, out.background, out.albedo, imaging::Reshading::of(out.fit.explained, out.fit.textureOnly), {}, 1);  // the rim is not measured: no supersampling
  cv::Mat1b inner;
  cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  out.restPsnr = imaging::psnr(in.frame, rest, inner);
  out.residual = residualOn(in, out.fit.theta, g);
  out.totalMs = since(t0);
  if (in.progress) in.progress(1.0, "done");
  return out;
}

cv::Mat3b composeAppearance(const AppearanceInput& in, const imaging::Appearance& theta, const cv::Mat3b& background, const cv::Mat3f& albedo,
                            imaging::Reshading how, const std::vector<double>& deformedVertices, int supersampling) {
  if (!deformedVertices.empty() && deformedVertices.size() != in.vertices.size())
    throw rehearse::InputError("The deformed organ has " + std::to_string(deformedVertices.size() / 3) + " nodes, the registered one " +
                              std::to_string(in.vertices.size() / 3) + "; they must be the same mesh in the same order.");
  imaging::CompositionInput c = compositionInput(in, AppearanceLayers{{}, background, albedo, {}}, theta, how);
  if (!deformedVertices.empty()) c.deformed.vertices = deformedVertices.data();
  return imaging::compose(c, supersampling);
}

AppearanceLayers appearanceLayers(const AppearanceInput& in, const imaging::Appearance& theta) {
  const imaging::SurfaceGeometry g = restGeometry(in);
  const cv::Mat1b usable = imaging::usablePixels(in.frame, g.mask());
  AppearanceLayers layers;
  layers.diffuse = imaging::separateSpecular(in.frame, usable).diffuse;
  restLayers(in, g, theta, layers.diffuse, usable, layers.background, layers.albedo);
  layers.residual = residualOn(in, theta, g);
  return layers;
}

imaging::CompositionInput compositionInput(const AppearanceInput& in, const AppearanceLayers& layers, const imaging::Appearance& theta, imaging::Reshading how) {
  imaging::CompositionInput c;
  c.camera = in.camera;
  c.pose = in.pose;
  c.rest = c.deformed = in.surface();
  c.frame = in.frame;
  c.background = layers.background;
  c.albedo = layers.albedo;
  c.theta = theta;
  c.textureOnly = how.textureOnly;
  c.trust = how.textureOnly ? 0.0 : how.trust;
  return c;
}

std::unique_ptr<imaging::Compositor> makeCompositor(const AppearanceInput& in, const AppearanceLayers& layers, const imaging::Appearance& theta, imaging::Reshading how) {
  return std::make_unique<imaging::Compositor>(compositionInput(in, layers, theta, how));
}

cv::Mat3b composeWithTheta(const AppearanceInput& in, const imaging::Appearance& theta,
                           const std::vector<double>& deformedVertices, imaging::Reshading how) {
  const AppearanceLayers layers = appearanceLayers(in, theta);
  return composeAppearance(in, theta, layers.background, layers.albedo, how, deformedVertices);
}

imaging::NovelView composeNovelViewWithTheta(const AppearanceInput& in, const imaging::Appearance& theta,
                                             const imaging::Camera& viewCamera, const Pose& viewPose,
                                             const cv::Mat3b& viewImage, const std::vector<double>& deformedVertices,
                                             imaging::Reshading how) {
  if (!deformedVertices.empty() && deformedVertices.size() != in.vertices.size())
    throw rehearse::InputError("The deformed organ has " + std::to_string(deformedVertices.size() / 3) +
                              " nodes, the registered one " + std::to_string(in.vertices.size() / 3) +
                              "; they must be the same mesh in the same order.");
  const AppearanceLayers layers = appearanceLayers(in, theta);
  return imaging::composeNovelView(compositionInput(in, layers, theta, how), viewCamera, viewPose, viewImage,
                                   deformedVertices);
}

}  // namespace rehearse::app
