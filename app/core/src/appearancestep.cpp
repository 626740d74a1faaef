#include "rehearse/app/appearancestep.hpp"
#include <rehearse/text_input.hpp>

#include <rehearse/imaging/render.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>

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
  if (in.frame.empty()) throw imaging::InputError("There is no frame to estimate the appearance from; grab a frame first (step 2).");
  if (in.frame.cols != in.camera.width || in.frame.rows != in.camera.height)
    throw imaging::InputError("The frame is " + std::to_string(in.frame.cols) + "x" + std::to_string(in.frame.rows) + " but the camera is calibrated for " +
                              std::to_string(in.camera.width) + "x" + std::to_string(in.camera.height) + "; use the camera of this frame.");
  if (in.triangles.empty()) throw imaging::InputError("The organ has no surface; load the organ first (step 1).");
  imaging::SurfaceGeometry g = imaging::surfaceGeometry(in.camera, in.pose, in.surface());
  if (cv::countNonZero(g.mask()) == 0) throw imaging::InputError("The organ is not in the frame at this pose; align it first (step 4).");
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
  return in;
}

CutComposition makeCutCompositor(const imaging::Compositor& base, const Case& c, const simcore::CutSurface& cut) {
  const auto& volume = c.organ->volume;
  const std::size_t n0 = volume.points.size(), n = cut.rest.size();
  if (n < n0 || n0 == 0 || cut.triangles.empty() || cut.cut.size() != cut.triangles.size())
    throw imaging::InputError("The cut organ is not this case's organ; it cannot be composited.");
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
  e->status = out.fit.status;
  e->inpaint = imaging::inpaintMethodName(inpaint);
  e->stages = out.fit.stages;
  e->restPsnr = out.restPsnr;
  e->totalMs = out.totalMs;
  e->pose = c.pose;
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
  e->inpaint = j.value("inpaint", std::string("ns"));
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

AppearanceOutput runAppearance(const AppearanceInput& in) {
  const auto t0 = std::chrono::steady_clock::now();
  auto since = [](auto a) { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count(); };
  const imaging::SurfaceGeometry g = restGeometry(in);
  AppearanceOutput out;
  imaging::AppearanceFitOptions o;
  o.progress = [&](double share, const std::string& what) { return !in.progress || in.progress(0.8 * share, what); };
  out.fit = imaging::fitAppearance(in.frame, g, o);
  if (in.progress && !in.progress(0.8, "filling the background behind the organ")) throw imaging::AppearanceCancelled();
  restLayers(in, g, out.fit.theta, out.fit.separation.diffuse, out.fit.usable, out.background, out.albedo, &out.inpaintMs);
  const cv::Mat3b rest = composeAppearance(in, out.fit.theta, out.background, out.albedo, out.fit.textureOnly, {}, 1);  // the rim is not measured: no supersampling
  cv::Mat1b inner;
  cv::erode(g.mask(), inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  out.restPsnr = imaging::psnr(in.frame, rest, inner);
  out.residual = residualOn(in, out.fit.theta, g);
  out.totalMs = since(t0);
  if (in.progress) in.progress(1.0, "done");
  return out;
}

cv::Mat3b composeAppearance(const AppearanceInput& in, const imaging::Appearance& theta, const cv::Mat3b& background, const cv::Mat3f& albedo,
                            bool textureOnly, const std::vector<double>& deformedVertices, int supersampling) {
  if (!deformedVertices.empty() && deformedVertices.size() != in.vertices.size())
    throw imaging::InputError("The deformed organ has " + std::to_string(deformedVertices.size() / 3) + " nodes, the registered one " +
                              std::to_string(in.vertices.size() / 3) + "; they must be the same mesh in the same order.");
  imaging::CompositionInput c = compositionInput(in, AppearanceLayers{{}, background, albedo, {}}, theta, textureOnly);
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

imaging::CompositionInput compositionInput(const AppearanceInput& in, const AppearanceLayers& layers, const imaging::Appearance& theta, bool textureOnly) {
  imaging::CompositionInput c;
  c.camera = in.camera;
  c.pose = in.pose;
  c.rest = c.deformed = in.surface();
  c.frame = in.frame;
  c.background = layers.background;
  c.albedo = layers.albedo;
  c.theta = theta;
  c.textureOnly = textureOnly;
  return c;
}

std::unique_ptr<imaging::Compositor> makeCompositor(const AppearanceInput& in, const AppearanceLayers& layers, const imaging::Appearance& theta, bool textureOnly) {
  return std::make_unique<imaging::Compositor>(compositionInput(in, layers, theta, textureOnly));
}

cv::Mat3b composeWithTheta(const AppearanceInput& in, const imaging::Appearance& theta, const std::vector<double>& deformedVertices) {
  const AppearanceLayers layers = appearanceLayers(in, theta);
  return composeAppearance(in, theta, layers.background, layers.albedo, false, deformedVertices);
}

imaging::NovelView composeNovelViewWithTheta(const AppearanceInput& in, const imaging::Appearance& theta,
                                             const imaging::Camera& viewCamera, const Pose& viewPose,
                                             const cv::Mat3b& viewImage, const std::vector<double>& deformedVertices,
                                             bool textureOnly) {
  if (!deformedVertices.empty() && deformedVertices.size() != in.vertices.size())
    throw imaging::InputError("The deformed organ has " + std::to_string(deformedVertices.size() / 3) +
                              " nodes, the registered one " + std::to_string(in.vertices.size() / 3) +
                              "; they must be the same mesh in the same order.");
  const AppearanceLayers layers = appearanceLayers(in, theta);
  return imaging::composeNovelView(compositionInput(in, layers, theta, textureOnly), viewCamera, viewPose, viewImage,
                                   deformedVertices);
}

}  // namespace rehearse::app
