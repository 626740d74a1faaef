// rehearse appearance | compose: the light and reflectance estimated from the frame (step 6), the organ re-shaded in
// it.
#include "support.hpp"

#include "phantom/phantom.hpp"
#include "phantom/presets.hpp"
#include "rehearse/app/casefile.hpp"
#include "rehearse/app/casefolder.hpp"
#include "rehearse/app/elasticfit.hpp"
#include "rehearse/app/appearancestep.hpp"
#include "rehearse/app/gesture.hpp"
#include "rehearse/app/recording.hpp"
#include "rehearse/app/review.hpp"
#include "rehearse/app/materials.hpp"

#include <rehearse/imaging/camera.hpp>
#include <rehearse/imaging/contour.hpp>
#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/registration.hpp>
#include <rehearse/simcore/scene.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>
#include <rehearse/simcore/fem.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <nlohmann/json.hpp>

#include <opencv2/imgcodecs.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <iostream>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <unistd.h>

namespace rehearse::app::cli {

// Step 6's inputs: a case folder, or the organ, camera, pose and frame as files (each file overrides the
// case's part).
// `visual` receives the surface drawn when it is the organ's own (a case folder's, or --visual's), carried by
// the volume's nodes.
AppearanceInput appearanceInput(std::map<std::string, std::string>& o, const char* command,
                                std::shared_ptr<const VisualSurface>* visual = nullptr) {
  AppearanceInput in;
  bool haveSurface = false, havePose = false;
  simcore::Mesh volume;  // the organ's volume, when it has one (--visual is carried by it)
  std::shared_ptr<const VisualSurface> own;
  bool atCaseShape = false;  // in.vertices hold a case file's organ at the shape its frame shows (its own surface)
  if (o.count("case")) {
    std::vector<std::string> notes;
    const Case c = loadCase(o["case"], &notes);
    for (const auto& n : notes) std::fprintf(stderr, "rehearse: note: %s\n", n.c_str());
    if (c.organ->empty()) throw UsageError(o["case"] + " has no organ mesh");
    if (isCaseFile(o["case"])) {
      // A case file (as the GUI saves it): the organ at the shape its frame shows (the elastic fit's, else at rest),
      // drawn through its own surface, and its pose when aligned or placed by the elastic fit (otherwise only the
      // automatic first guess, which no fit should take as the organ's pose: --pose is then required).
      in = appearanceInputFromCase(c);
      in.contour = {};  // (its outline turns the organ only when --contour asks)
      havePose = c.poseDetermined();
      atCaseShape = true;
    } else {
      in.camera = c.camera;
      in.frame = c.frame;
      // A case folder stores no alignment: its pose is the automatic first guess, which no fit should take as the
      // organ's pose in the frame (it put the phantom's light 69 mm off): --pose is required with a case folder.
      const SurfaceView v = c.surfaceView();
      in.vertices.assign(v.vertices, v.vertices + 3 * v.vertexCount);
      in.triangles.resize(v.triangleCount);
      for (std::size_t t = 0; t < v.triangleCount; ++t)
        in.triangles[t] = {v.triangles[3 * t], v.triangles[3 * t + 1], v.triangles[3 * t + 2]};
    }
    volume = c.organ->volume;
    own = c.organ->visual;
    haveSurface = true;
  }
  if (o.count("mesh")) {
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    simcore::Mesh m = simcore::loadMesh(o["mesh"], lo);
    m.convertToMetres();
    // A size no organ has is a wrong unit (a millimetre file read as metres made a 22 m organ, fitted and written
    // without a word): refused with the likely unit.
    if (const double size = m.points.empty() ? 0.0 : m.bounds().sizes().maxCoeff(); size > 0)
      if (const simcore::OrganSize check = simcore::checkOrganSize(size, lo.unit); !check.organSized) {
        char text[300];
        std::snprintf(text, sizeof text, "With --unit %s the organ of %s would measure %.3g mm across; organs measure 10 to 1000 mm.",
                      lo.unit.c_str(), std::filesystem::path(o["mesh"]).filename().c_str(), size * 1e3);
        std::string give;
        for (std::size_t i = 0; i < check.likely.size(); ++i)
          give += std::string(i == 0 ? "" : " or ") + "--unit " + check.likely[i].first;
        throw UsageError(std::string(text) +
                         (check.likely.empty() ? " Check the file."
                                               : " It is probably in " + check.likelyText() + ": give " + give + "."));
      }
    in.triangles = m.isVolume() ? simcore::boundaryTriangles(m, false) : m.triangles;
    in.vertices.clear();
    for (const auto& p : m.points) in.vertices.insert(in.vertices.end(), {p.x(), p.y(), p.z()});
    volume = m.isVolume() ? std::move(m) : simcore::Mesh{};
    own.reset();
    haveSurface = true;
    atCaseShape = false;
  }
  if (o.count("visual")) {
    if (volume.tets.empty())
      throw UsageError(
          std::string(command) +
          " --visual needs the organ's volume (--mesh VOLUME or --case): its tetrahedra carry the surface");
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    if (o.count("visual-unit")) lo.unit = o["visual-unit"];
    std::string why;
    own = VisualSurface::make(volume, simcore::loadMesh(o["visual"], lo), &why);
    if (!own) throw simcore::MeshError(why);
    atCaseShape = false;
  }
  if (own && !atCaseShape) {  // the organ drawn through its own surface, at rest
    in.vertices.clear();
    for (const auto& p : own->points) in.vertices.insert(in.vertices.end(), {p.x(), p.y(), p.z()});
    in.triangles = own->triangles;
  }
  if (visual) *visual = own;
  if (o.count("image")) {
    in.frame = cv::imread(o["image"], cv::IMREAD_COLOR);
    if (in.frame.empty())
      throw simcore::MeshError("The image " + o["image"] + " cannot be read; give a PNG or JPEG frame.");
  }
  if (o.count("camera")) in.camera = imaging::loadCamera(o["camera"], in.frame.cols, in.frame.rows);
  if (o.count("pose")) in.pose = imaging::loadPose(o["pose"]), havePose = true;
  if (!haveSurface) throw UsageError(std::string(command) + " needs --case or --mesh");
  if (in.frame.empty()) throw UsageError(std::string(command) + " needs --image (or a --case with a frame)");
  if (in.camera.width == 0) throw UsageError(std::string(command) + " needs --camera (or a --case with one)");
  if (!havePose)
    throw UsageError(std::string(command) +
                     " needs --pose (the organ's pose in the camera; a case folder stores no alignment, and this case "
                     "file's organ was neither aligned nor fitted: align it in the window, steps 4 and 5, and save)");
  if (const std::string problem = in.camera.problem(); !problem.empty()) throw simcore::MeshError(problem);
  // A frame from a camera with lens distortion is undistorted first (every step works on the undistorted frame).
  if (o.count("image")) in.frame = imaging::undistortImage(in.frame, in.camera);
  if (o.count("inpaint")) in.inpaint = imaging::parseInpaintMethod(o["inpaint"]);
  return in;
}

int cmdAppearance(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, appearanceCommand());
  if (!o.count("out")) throw UsageError("appearance needs --out THETA.json");
  if (o.count("contour") && !o.count("turned-pose"))
    throw UsageError(
        "appearance --contour may turn the organ (the turn the outline leaves open): give --turned-pose P.json to "
        "receive the pose the light and reflectance were fitted at");
  if (o.count("turned-pose") && !o.count("contour"))
    throw UsageError("appearance --turned-pose needs --contour C.json: without an outline no turn is searched");
  AppearanceInput in = appearanceInput(o, "appearance");
  in.turnByShading = o.count("contour") > 0;
  if (in.turnByShading) {
    in.contour = imaging::loadContour(o["contour"]);
    if (in.contour.width > 0 && in.contour.width != in.camera.width)
      throw UsageError("the contour is drawn on a " + std::to_string(in.contour.width) + " px wide image, the camera's is " +
                       std::to_string(in.camera.width) + " px; give the outline of this frame");
  }
  const AppearanceOutput r = runAppearance(in);
  // The fit's verdict goes with it: a THETA that explains too little is marked so, and compose does not re-shade with it.
  imaging::AppearanceVerdict verdict;
  verdict.known = true;
  verdict.explained = r.fit.explained;
  verdict.reshade = !r.fit.textureOnly;
  verdict.said = r.fit.status;
  imaging::saveAppearance(r.fit.theta, o["out"], verdict);
  if (o.count("turned-pose")) imaging::savePose(r.turn.pose, o["turned-pose"]);
  if (o.count("background"))
    rehearse::writeFileAtomically(o["background"], [&] {
      std::vector<uchar> buf;
      cv::imencode(".png", r.background, buf);
      return std::string(buf.begin(), buf.end());
    }());
  if (o.count("diffuse")) {
    std::vector<uchar> buf;
    cv::imencode(".png", r.fit.separation.diffuse, buf);
    rehearse::writeFileAtomically(o["diffuse"], std::string(buf.begin(), buf.end()));
  }
  if (o.count("report")) {
    nlohmann::json stages = nlohmann::json::array();
    for (const auto& st : r.fit.stages)
      stages.push_back({{"stage", st.name}, {"rms_levels", st.rms}, {"ms", st.ms}, {"pixels", st.pixels}});
    stages.push_back(
        {{"stage", std::string("background (") + imaging::inpaintMethodName(in.inpaint) + ")"}, {"ms", r.inpaintMs}});
    writeReport(o["report"],
                {{"status", r.fit.status},
                 {"highlight_found", r.fit.highlightFound},
                 {"texture_only", r.fit.textureOnly},
                 {"explained", r.fit.explained},
                 {"reshade_trust", verdict.reshading().trust},
                 {"smooth_share", r.fit.smoothShare},
                 {"checks",
                  [&] {
                    nlohmann::json c = nlohmann::json::array();
                    for (const auto& k : r.fit.checks)
                      c.push_back({{"without", k.part}, {"explained", k.explainedWithout}, {"holds", k.holds}});
                    return c;
                  }()},
                 {"scope_explained", r.fit.scopeExplained},
                 {"second_sources",
                  [&] {
                    nlohmann::json c = nlohmann::json::array();
                    for (const auto& k : r.fit.sources)
                      c.push_back({{"name", k.name}, {"explained", k.explainedWith}, {"used", k.used}});
                    return c;
                  }()},
                 {"light_from_lens_mm", 1e3 * r.fit.theta.lightPosition.norm()},
                 {"light_at_bound", r.fit.lightAtBound},
                 {"highlights_disagree", r.fit.highlightsDisagree},
                 {"foreign_pixels", r.fit.foreign.empty() ? 0 : cv::countNonZero(r.fit.foreign)},
                 {"ks_measured", {r.fit.ksMeasured[0], r.fit.ksMeasured[1], r.fit.ksMeasured[2]}},
                 {"highlight_pixels", r.fit.separation.count},
                 {"rest_psnr_db", r.restPsnr},
                 {"total_ms", r.totalMs},
                 {"stages", stages},
                 {"turn",
                  {{"searched", r.turn.searched},
                   {"adopted", r.turn.adopted},
                   {"about_x_deg", r.turn.aboutXDeg},
                   {"about_y_deg", r.turn.aboutYDeg},
                   {"explained_before", r.turn.explainedBefore},
                   {"explained_after", r.turn.explainedAfter},
                   {"outline_before_px", r.turn.outlineBeforePx},
                   {"outline_after_px", r.turn.outlineAfterPx},
                   {"candidates", r.turn.candidates},
                   {"scored_before", r.turn.scoredBefore},
                   {"scored_best", r.turn.scoredBest},
                   {"ms", r.turn.ms},
                   {"said", r.turn.sentence}}}});
  }
  std::printf(
      "%s\nlight (%.1f, %.1f, %.1f) mm (%.1f mm from the lens), fall-off cos^%.2f, kd (%.4f, %.4f, %.4f), ks (%.4f, "
      "%.4f, "
      "%.4f), roughness %.3f; composed at rest: %.1f dB inside the organ; %.0f ms\n",
      r.fit.status.c_str(), 1e3 * r.fit.theta.lightPosition.x(), 1e3 * r.fit.theta.lightPosition.y(),
      1e3 * r.fit.theta.lightPosition.z(), 1e3 * r.fit.theta.lightPosition.norm(), r.fit.theta.falloff,
      r.fit.theta.kd.x(), r.fit.theta.kd.y(), r.fit.theta.kd.z(), r.fit.theta.ks.x(), r.fit.theta.ks.y(),
      r.fit.theta.ks.z(), r.fit.theta.roughness, r.restPsnr, r.totalMs);
  if (r.fit.theta.hasDistantLight())
    std::printf("second source: a distant light towards (%.3f, %.3f, %.3f) (camera frame), kr (%.4f, %.4f, %.4f)\n",
                r.fit.theta.roomDirection.x(), r.fit.theta.roomDirection.y(), r.fit.theta.roomDirection.z(),
                r.fit.theta.kr.x(), r.fit.theta.kr.y(), r.fit.theta.kr.z());
  if (r.fit.theta.hasAmbient())
    std::printf("second source: an ambient term, ka (%.4f, %.4f, %.4f)\n", r.fit.theta.ka.x(), r.fit.theta.ka.y(),
                r.fit.theta.ka.z());
  if (!r.turn.sentence.empty()) std::printf("%s\n", r.turn.sentence.c_str());
  if (!r.fit.textureOnly && verdict.reshading().trust < 1)
    std::printf("re-shading applies %d %% of the model's change to the frame's colours (it explained %d %%; in full "
                "from 90 %%)\n",
                imaging::trustPercent(verdict.reshading().trust), imaging::explainedPercent(r.fit.explained));
  // A fit too poor to re-shade is still written (texture mapping uses it), but says so with its own exit code.
  return r.fit.textureOnly ? 4 : 0;
}

int cmdCompose(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, composeCommand());
  for (const char* need : {"theta", "out"})
    if (!o.count(need)) throw UsageError(std::string("compose needs --") + need);
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".png" && ext != ".jpg" && ext != ".jpeg") throw UsageError("--out must end in .png or .jpg");
  std::shared_ptr<const VisualSurface> visual;
  const AppearanceInput in = appearanceInput(o, "compose", &visual);
  imaging::AppearanceVerdict verdict;
  const imaging::Appearance theta = imaging::loadAppearance(o["theta"], &verdict);
  // A fit that explained too little does not re-shade (issue 65): the frame's texture is drawn instead, and said so.
  const bool untrusted = verdict.known && !verdict.reshade;
  const bool textureOnly = o.count("texture-only") > 0 || untrusted;
  // Re-shaded as far as the fit earned it (imaging::reshadeTrust): the model's change applied at that share.
  const imaging::Reshading how = textureOnly ? imaging::Reshading{true, 0.0} : verdict.reshading();
  std::vector<double> deformed;
  if (o.count("deformed")) {
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    simcore::Mesh d = simcore::loadMesh(o["deformed"], lo);
    d.convertToMetres();
    if (visual) {  // the volume's nodes moved: its own surface follows them
      d.points = visual->map(d.points);
      if (d.points.empty())
        throw simcore::MeshError("The deformed organ (" + o["deformed"] +
                                 ") has another node count than the organ's volume; it must be that mesh, moved.");
    }
    for (const auto& p : d.points) deformed.insert(deformed.end(), {p.x(), p.y(), p.z()});
  }
  if (!o.count("view-camera") && (o.count("view-pose") || o.count("view-image")))
    throw UsageError("--view-pose and --view-image draw a novel view: they need --view-camera");
  cv::Mat3b j;
  if (o.count("view-camera")) {
    // A novel view: the organ through another camera at another pose, lit by that scope (its undistorted view).
    if (!o.count("view-pose")) throw UsageError("--view-camera needs --view-pose (the organ's pose in that camera)");
    cv::Mat3b viewImage;
    if (o.count("view-image")) {
      viewImage = cv::imread(o["view-image"], cv::IMREAD_COLOR);
      if (viewImage.empty())
        throw simcore::MeshError("The image " + o["view-image"] + " cannot be read; give a PNG or JPEG frame.");
    }
    const imaging::Camera view = imaging::loadCamera(o["view-camera"], viewImage.cols, viewImage.rows);
    if (const std::string problem = view.problem(); !problem.empty())
      throw simcore::MeshError("The view's camera: " + problem);
    viewImage = imaging::undistortImage(viewImage, view);
    try {
      j = composeNovelViewWithTheta(in, theta, view, imaging::loadPose(o["view-pose"]), viewImage, deformed, how).image;
    } catch (const rehearse::InputError& e) {
      // The view's own pose named by its file (a person looked for which of two poses was meant).
      const std::string why = e.what();
      if (why.find("the view's pose") == std::string::npos) throw;
      throw rehearse::InputError(why.substr(0, why.find_last_not_of('.') + 1) + " (--view-pose " +
                                std::filesystem::path(o["view-pose"]).filename().string() + ").");
    }
  } else {
    j = composeWithTheta(in, theta, deformed, how);
  }
  const std::string thetaName = std::filesystem::path(o["theta"]).filename().string();
  // A verdict whose own sentence gives another share than its number was edited (a person set 95 % in a THETA whose
  // sentence said 36 %, and it was re-shaded in full without a word): said, the number taken.
  if (verdict.known) {
    static const std::regex said("explains ([0-9]+) %");
    std::smatch m;
    if (std::regex_search(verdict.said, m, said) && std::abs(std::stoi(m[1].str()) - imaging::explainedPercent(verdict.explained)) > 1)
      std::printf("note: %s says the fit explained %d %% of the organ's shading, but its sentence says %s %% (edited?); "
                  "the number is taken\n",
                  thetaName.c_str(), imaging::explainedPercent(verdict.explained), m[1].str().c_str());
  }
  if (untrusted) {
    if (verdict.explained >= 0.5)
      std::printf("not re-shaded: %s is marked texture only (its \"reshade\" is false, though it says the fit explained "
                  "%d %% of the organ's shading); the frame's own colours are drawn instead\n",
                  thetaName.c_str(), imaging::explainedPercent(verdict.explained));
    else
      std::printf("not re-shaded: the fit behind %s is marked texture only (it explained %d %% of the organ's shading); "
                  "the frame's own colours are drawn instead\n",
                  thetaName.c_str(), imaging::explainedPercent(verdict.explained));
  } else if (textureOnly) {
    std::printf("texture only, as --texture-only asks: the frame's own colours follow the tissue\n");
  } else if (!textureOnly && imaging::trustPercent(how.trust) == 0) {
    std::printf("not re-shaded where the frame saw the tissue: the fit behind %s explained %d %% of the organ's shading, "
                "too little for the model to change the frame's colours (it starts above 50 %%, in full from 90 %%); "
                "the frame's own colours are drawn there\n",
                std::filesystem::path(o["theta"]).filename().c_str(), imaging::explainedPercent(verdict.explained));
  } else if (!textureOnly && how.trust < 1) {
    std::printf("re-shaded at %d %% of the model's change: the fit behind %s explained %d %% of the organ's shading "
                "(in full from 90 %%); the rest of each colour is the frame's own\n",
                imaging::trustPercent(how.trust), std::filesystem::path(o["theta"]).filename().c_str(),
                imaging::explainedPercent(verdict.explained));
  } else if (!verdict.known && !textureOnly) {
    std::printf("re-shaded with %s as given: it carries no fit's verdict (written by hand, or before 'rehearse "
                "appearance' kept one)\n",
                std::filesystem::path(o["theta"]).filename().c_str());
  } else if (!textureOnly) {
    std::printf("re-shaded in full: the fit behind %s explained %d %% of the organ's shading (in full from 90 %%)\n",
                thetaName.c_str(), imaging::explainedPercent(verdict.explained));
  }
  std::vector<uchar> buf;
  cv::imencode(ext, j, buf);
  rehearse::writeFileAtomically(o["out"], std::string(buf.begin(), buf.end()));
  std::printf("written: %s\n", o["out"].c_str());
  return 0;
}

namespace {
// The organ, camera, pose and frame both commands take (appearanceInput), and how the organ is removed from the frame.
const std::vector<OptionSpec>& frameInputOptions() {
  static const std::vector<OptionSpec> options = {
      {"case", "CASE",
       "a case file (.rehearse, as the GUI saves it: its organ at its fitted shape, camera, frame and aligned pose) or "
       "a case folder (its organ, camera and frame; it stores no pose: give --pose); the files below override them"},
      {"mesh", "M", "the organ"},
      {"unit", "U", "m, dm, cm or mm: the mesh's length unit"},
      {"camera", "CAM", "the camera"},
      {"pose", "P.json", "the organ's pose (model to camera)"},
      {"image", "FRAME", "the endoscope frame"},
      {"inpaint", "I", "telea, ns, shiftmap or fsr: how the organ is removed from the frame"},
      {"visual", "SURFACE", "draw the organ through this surface (its own, finer), carried by the volume's tetrahedra"},
      {"visual-unit", "U", "the --visual surface's length unit (else --unit's)"}};
  return options;
}
}  // namespace

const Command& appearanceCommand() {
  static const Command command{
      "appearance",
      "  rehearse appearance --case CASE | --mesh M [--unit u] --camera CAM --pose P.json --image FRAME --out "
      "THETA.json\n"
      "                [--visual SURFACE [--visual-unit u]] [--report R.json] [--inpaint telea|ns|shiftmap|fsr] "
      "[--background IB.png] "
      "[--diffuse ID.png]\n"
      "                [--contour C.json --turned-pose P2.json]\n"
      "                                   estimate the light and the organ's reflectance from the frame (step 6);\n"
      "                                   exit 4 when the model explains too little (texture mapping only)\n",
      joined(frameInputOptions(), {{"out", "THETA.json", "the estimated light and reflectance"},
                                   {"report", "R.json", "what the frame did and did not determine"},
                                   {"background", "IB.png", "write the frame without the organ"},
                                   {"diffuse", "ID.png", "write the organ's diffuse albedo"},
                                   {"contour", "C.json",
                                    "the outline sketched on the frame: also settle by the shading the turn it leaves "
                                    "open"},
                                   {"turned-pose", "P2.json",
                                    "with --contour: write the pose the estimate was fitted at (turned or not)"}}),
      cmdAppearance};
  return command;
}

const Command& composeCommand() {
  static const Command command{
      "compose",
      "  rehearse compose --case CASE | --mesh M [--unit u] --camera CAM --pose P.json --image FRAME --theta "
      "THETA.json\n"
      "                [--visual SURFACE [--visual-unit u]] [--deformed DEFORMED.vtu|.vtk] --out J.png [--inpaint "
      "telea|ns|shiftmap|fsr]\n"
      "                [--view-camera CAM2 --view-pose P2.json [--view-image IMG2]] [--texture-only]\n"
      "                                   the organ (deformed: its nodes in the input order) re-shaded in the "
      "frame,\n"
      "                                   or through another camera (a novel view, lit by that scope); a THETA "
      "whose fit\n"
      "                                   explained too little (texture only) draws the frame's colours, not "
      "re-shaded\n",
      joined(frameInputOptions(),
             {{"theta", "THETA.json", "the appearance (rehearse appearance --out)"},
              {"deformed", "D.vtu", "the deformed organ (nodes in the input order)"},
              {"view-camera", "CAM2", "draw a novel view through this camera (undistorted)"},
              {"view-pose", "P2.json", "the organ's pose in the view's camera (model to camera)"},
              {"view-image", "IMG2", "draw the novel view over this frame of the view's camera (else black)"},
              {"texture-only", "", "draw the fitted frame's colours instead of re-shading (the comparison)"},
              {"out", "J.png", "the composited image"}}),
      cmdCompose};
  return command;
}

}  // namespace rehearse::app::cli
