// A case as a folder of ordinary files (what `rehearse phantom --out DIR` writes and `rehearse open DIR` reads).
#include "rehearse/app/casefolder.hpp"

#include <rehearse/text_input.hpp>
#include "rehearse/app/materials.hpp"

#include <rehearse/simcore/meshio.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;
using nlohmann::json;

namespace rehearse::app {
namespace {

std::string objText(const simcore::Mesh& m, const std::vector<std::array<int, 3>>& tris, const char* comment) {
  // Only the points the triangles use, renumbered.
  std::vector<int> index(m.points.size(), -1);
  std::string out = std::string("# ") + comment + " (metres, written by Rehearse)\n";
  char buf[128];
  int next = 0;
  std::string faces;
  for (const auto& t : tris) {
    faces += "f";
    for (int v : t) {
      if (index[v] < 0) {
        index[v] = ++next;
        const auto& p = m.points[v];
        std::snprintf(buf, sizeof buf, "v %.9g %.9g %.9g\n", p.x(), p.y(), p.z());
        out += buf;
      }
      faces += " " + std::to_string(index[v]);
    }
    faces += "\n";
  }
  return out + faces;
}

json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d vec3(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

}  // namespace

void writeCaseDirectory(const Case& c, const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw rehearse::InputError("Cannot create the folder " + dir + " (" + ec.message() + ").");
  auto path = [&](const char* f) { return (fs::path(dir) / f).string(); };
  const simcore::Mesh& volume = c.organ->volume;
  try {
    simcore::saveMesh(volume, path("organ.vtu"));
    simcore::saveMesh(volume, path("organ.msh"));
  } catch (const simcore::MeshError& e) {
    throw rehearse::InputError(e.what());
  }
  rehearse::writeFileAtomically(path("organ_surface.obj"), objText(volume, c.organ->surface, "organ outer surface"));
  std::vector<int> labels;
  auto all = simcore::boundaryTriangles(volume, true, &labels);
  std::vector<std::array<int, 3>> vessel;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (labels[i] == kVesselLabel) vessel.push_back(all[i]);
  rehearse::writeFileAtomically(path("vessels_surface.obj"), objText(volume, vessel, "vessel tree surface"));
  if (const auto& visual = c.organ->visual) {  // the organ's own surface, drawn in the composited view
    simcore::Mesh surface;
    surface.points = visual->points;
    surface.triangles = visual->triangles;
    rehearse::writeFileAtomically(path("organ_visual.obj"),
                                 objText(surface, surface.triangles, "organ's own surface, drawn over the volume"));
  }
  imaging::saveCamera(c.camera, path("camera.yaml"));
  std::vector<uchar> png;
  if (!cv::imencode(".png", c.frame, png)) throw rehearse::InputError("The frame could not be encoded as PNG.");
  rehearse::writeFileAtomically(path("frame.png"), std::string(png.begin(), png.end()));
  rehearse::writeFileAtomically(path("attachments.json"), json{{"nodes", c.attachments}, {"indexing", "0-based, organ.vtu node order"}}.dump() + "\n");

  json manifest;
  manifest["format"] = "rehearse-case-folder";
  manifest["version"] = 1;
  manifest["name"] = c.name;
  manifest["unit"] = "m";
  manifest["files"] = {{"volume", "organ.vtu"}, {"volume_msh", "organ.msh"}, {"surface", "organ_surface.obj"},
                       {"vessels", "vessels_surface.obj"}, {"camera", "camera.yaml"}, {"frame", "frame.png"},
                       {"attachments", "attachments.json"}};
  if (c.organ->visual) manifest["files"]["visual"] = "organ_visual.obj";
  json labelsJson = json::array();
  for (const auto& [l, n] : volume.labelNames) labelsJson.push_back({{"label", l}, {"name", n}});
  manifest["labels"] = labelsJson;
  if (c.groundTruth) {
    const GroundTruth& gt = *c.groundTruth;
    imaging::savePose(gt.pose, path("pose.json"));
    imaging::saveAppearance(gt.appearance, path("appearance.json"));
    json tree = json::array();
    for (std::size_t i = 0; i < gt.vesselAxes.size(); ++i)
      tree.push_back({{"a", vec(gt.vesselAxes[i].first)}, {"b", vec(gt.vesselAxes[i].second)}, {"radius", gt.vesselRadii[i]}});
    manifest["ground_truth"] = {{"pose", "pose.json"}, {"appearance", "appearance.json"}, {"vessel_tree", tree},
                                {"note", "frame.png was rendered from organ_surface.obj at pose.json with appearance.json"}};
  }
  rehearse::writeFileAtomically(path("case.json"), manifest.dump(2) + "\n");
}

Case loadCaseDirectory(const std::string& dir, std::vector<std::string>* notes) {
  auto path = [&](const std::string& f) { return (fs::path(dir) / f).string(); };
  std::string manifestText, unreadable;
  if (!fs::exists(path("case.json")))
    throw rehearse::InputError(dir + " is not a case folder (it has no case.json); choose a folder written by 'rehearse phantom'.");
  if (!readTextInput(path("case.json"), manifestText, unreadable, std::size_t{1} << 20))
    throw rehearse::InputError("The case folder's manifest: " + unreadable + ".");
  if (const std::string why = jsonTextProblem(manifestText, "case.json in " + dir); !why.empty())
    throw rehearse::InputError(why + "; the case folder is damaged.");
  json manifest;
  try {
    manifest = json::parse(manifestText);
  } catch (const std::exception&) {
    throw rehearse::InputError("case.json in " + dir + " is not valid JSON; the case folder is damaged.");
  }
  if (manifest.value("format", "") != "rehearse-case-folder")
    throw rehearse::InputError("case.json in " + dir + " is not a Rehearse case manifest.");
  Case c;
  c.name = manifest.value("name", fs::path(dir).filename().string());
  auto note = [&](const std::string& s) {
    if (notes) notes->push_back(s);
  };
  const json files = manifest.value("files", json::object());
  // Each part loads on its own: a damaged part is reported and the rest stays usable.
  try {
    simcore::Mesh volume = simcore::loadMesh(path(files.value("volume", "organ.vtu")));
    for (const auto& l : manifest.value("labels", json::array())) volume.setLabelName(l.at("label").get<int>(), l.at("name").get<std::string>());
    simcore::Mesh visual;  // the organ's own surface, when the folder has one
    if (files.contains("visual")) {
      try {
        visual = simcore::loadMesh(path(files.value("visual", "organ_visual.obj")), {"m"});
      } catch (const std::exception& e) {
        note(std::string("Organ surface not loaded: ") + e.what() +
             " The simulation mesh's boundary is drawn instead.");
      }
    }
    std::string why;
    c.organ = Organ::fromVolume(std::move(volume), {}, 1.0, visual.triangles.empty() ? nullptr : &visual, &why);
    if (!why.empty()) note("Organ surface not used: " + why);
    c.material = defaultMaterial(*c.organ);
  } catch (const std::exception& e) {
    note(std::string("Organ mesh not loaded: ") + e.what());
  }
  try {
    c.camera = imaging::loadCamera(path(files.value("camera", "camera.yaml")));
  } catch (const std::exception& e) {
    note(std::string("Camera not loaded: ") + e.what());
  }
  c.frame = cv::imread(path(files.value("frame", "frame.png")), cv::IMREAD_COLOR);
  if (c.frame.empty()) note("Frame not loaded: " + files.value("frame", "frame.png") + " is missing or not an image.");
  else if (c.camera.width == 0) c.camera = imaging::Camera::defaultFor(c.frame.cols, c.frame.rows);
  // The ligaments: every node index a whole number naming a node of the organ, or the attachments are not loaded and
  // the note says why (a command that simulates the case refuses it: the organ would hang from nothing).
  {
    const std::string name = files.value("attachments", "attachments.json");
    std::string text, why;
    if (!readTextInput(path(name), text, why)) {
      note("Attachments not loaded: " + why + ".");
    } else if (const std::string deep = jsonTextProblem(text, name); !deep.empty()) {
      note("Attachments not loaded: " + deep + ".");
    } else {
      try {
        const json parsed = json::parse(text);  // keep it alive: the loop below iterates into it
        const std::size_t n = c.organ ? c.organ->volume.points.size() : 0;
        std::vector<int> nodes;
        for (const auto& v : parsed.at("nodes")) {
          if (!v.is_number_integer()) throw std::runtime_error("a node index that is not a whole number");
          const auto k = v.get<std::int64_t>();
          if (k < 0 || static_cast<std::uint64_t>(k) >= n)
            throw std::runtime_error("node " + std::to_string(k) + ", which the organ (" + std::to_string(n) +
                                     " nodes) has not");
          nodes.push_back(static_cast<int>(k));
        }
        c.attachments = std::move(nodes);
      } catch (const json::exception&) {
        note("Attachments not loaded: " + name + " is not a {\"nodes\": [...]} list of node indices.");
      } catch (const std::exception& e) {
        note("Attachments not loaded: " + name + " names " + e.what() + ".");
      }
    }
  }
  if (!c.organ->volume.empty()) {
    c.pose = c.automaticPose();
    c.hasPose = true;
  }
  if (manifest.contains("ground_truth")) {
    try {
      const auto& gt = manifest["ground_truth"];
      auto truth = std::make_shared<GroundTruth>();
      truth->pose = imaging::loadPose(path(gt.value("pose", "pose.json")));
      truth->appearance = imaging::loadAppearance(path(gt.value("appearance", "appearance.json")));
      for (const auto& s : gt.value("vessel_tree", json::array())) {
        truth->vesselAxes.emplace_back(vec3(s.at("a")), vec3(s.at("b")));
        truth->vesselRadii.push_back(s.at("radius").get<double>());
      }
      c.groundTruth = truth;
    } catch (const std::exception& e) {
      note(std::string("Ground truth not loaded: ") + e.what());
    }
  }
  return c;
}

}  // namespace rehearse::app
