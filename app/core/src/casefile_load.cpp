// Loading a case file: its reader, then one step per part of the case; a damaged part is named and left out.
#include "rehearse/app/casefile.hpp"
#include "casefile_parts.hpp"
#include "recording_store.hpp"

#include <rehearse/app/appearancestep.hpp>
#include <rehearse/app/casefolder.hpp>
#include <rehearse/app/incorrect_actions.hpp>
#include <rehearse/app/materials.hpp>
#include <rehearse/app/recording.hpp>
#include <rehearse/imaging/camera.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/precomputed.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <openssl/evp.h>
#include <sqlite3.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <stdexcept>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

using nlohmann::json;

namespace rehearse::app {
using namespace casefile_parts;
namespace {

// ---- Loading: the file's reader, then one step per part of the case, in the order each needs the ones before. ----

// What each part is called in messages ("<what> not loaded: ...").
std::string partTitle(const char* part) {
  static const std::map<std::string, std::string> partName = {{"volume", "Organ mesh"},
                                                              {"labels", "Organ labels"},
                                                              {"frame", "Frame"},
                                                              {"raw_frame", "Captured frame"},
                                                              {"camera", "Camera"},
                                                              {"attachments", "Attachments"},
                                                              {"pose", "Pose"},
                                                              {"contour", "Contour"},
                                                              {"second_frame", "Second frame"},
                                                              {"second_frame_move", "Second frame's move"},
                                                              {"second_contour", "Second frame's contour"},
                                                              {"elastic_fit", "Elastic fit"},
                                                              {"ground_truth", "Ground truth"},
                                                              {"landmarks", "Landmark pairs"},
                                                              {"appearance", "Appearance"},
                                                              {"visual_surface", "Organ surface"},
                                                              {"precomputed_responses", "Precomputed responses"}};
  const auto named = partName.find(part);
  return named != partName.end() ? named->second : std::string(part);
}

// A file that is not there or not an SQLite database is refused before it is opened.
void refuseNotACaseFile(const std::string& path) {
  if (!std::filesystem::exists(path)) fail("The case file " + path + " does not exist; check the path.");
  if (!isCaseFile(path)) fail(fileName(path) + " is not a Rehearse case file (it is not an SQLite database).");
}

// The case file being read: its database (a schema this build reads), whether its parts carry checksums, and the notes
// on the parts that could not be read.
class CaseReader {
 public:
  CaseReader(const std::string& path, std::vector<std::string>* notes)
      : db_(path, detail::readingFlags(path)), notes_(notes) {
    const std::string name = fileName(path);
    if (!db_.open()) fail(name + " cannot be opened: " + sqlProblem(db_.code()) + ".");
    const auto versionText = db_.meta("schema_version");
    if (!versionText) {
      // A file only 'rehearse gesture --record' wrote holds recorded sessions and no case (a helper was told it was
      // damaged although it replays): said as what it is.
      if (db_.row("SELECT name FROM sqlite_master WHERE type = 'table' AND name = ?", "rehearsal_sessions", 1))
        fail(name + " holds recorded sessions but no case (as 'rehearse gesture --record' writes them); replay them "
                    "with 'rehearse replay " + name + "'.");
      fail(name + " is damaged or not a Rehearse case (no schema version).");
    }
    const int version = std::atoi(versionText->c_str());
    if (version < 1) fail(name + " has an unknown schema version.");
    if (version > kCaseSchemaVersion)
      fail(name + " was saved by a newer Rehearse (schema " + std::to_string(version) + ", this one reads up to " +
           std::to_string(kCaseSchemaVersion) + "); update Rehearse to open it.");
    // Migrations: schema 1 has no checksums (its parts are read as they are); the parts it lacks are simply
    // absent. Nothing is written back: the next save writes the current schema.
    checksums_ = version >= 2;
  }
  CaseReader(const CaseReader&) = delete;
  CaseReader& operator=(const CaseReader&) = delete;

  std::optional<std::string> meta(const std::string& key) { return db_.meta(key); }
  void note(const std::string& s) {
    if (notes_) notes_->push_back(s);
  }
  // A part's data; empty when it is absent, or (said in a note) unreadable or no longer matching its checksum.
  std::string read(const char* part) {
    const std::string what = partTitle(part);
    const auto r = checksums_ ? db_.row("SELECT data, sha256 FROM parts WHERE name = ?", part, 2)
                              : db_.row("SELECT data FROM parts WHERE name = ?", part, 1);
    if (db_.code() != SQLITE_OK) {
      note(what + " not loaded: it could not be read (" + sqlProblem(db_.code()) + ").");
      return {};
    }
    if (!r) return {};
    if (checksums_ && sha256(r->at(0)) != r->at(1)) {
      note(what + " not loaded: the stored data is damaged (it no longer matches its checksum).");
      return {};
    }
    return r->at(0);
  }

 private:
  Database db_;
  std::vector<std::string>* notes_;
  bool checksums_ = false;
};

// precomputed_responses: offered to the cache (the body that needs them checks them).
void readResponses(CaseReader& in) {
  if (std::string r = in.read("precomputed_responses"); r.size() > sizeof(std::uint64_t)) {
    std::uint64_t key = 0;
    std::memcpy(&key, r.data(), sizeof key);
    simcore::ResponseCache::shared().offerBytes(
        key, std::make_shared<const std::string>(r.substr(sizeof key)));
  }
}

// volume, labels, visual_surface: the organ.
void readOrgan(CaseReader& in, Case& c) {
  std::string v = in.read("volume");
  if (v.empty()) return;
  try {
    simcore::Mesh volume = simcore::parseVtu(std::string_view(v));
    simcore::validateMesh(volume, "the organ mesh");
    if (std::string l = in.read("labels"); !l.empty())
      for (const auto& e : json::parse(l)) volume.setLabelName(e.at("label").get<int>(), e.at("name").get<std::string>());
    // The organ's own surface, drawn in the composited view: without it (older files, or damaged) the
    // simulation mesh's boundary is drawn, and the note says so.
    simcore::Mesh visual;
    if (std::string vs = in.read("visual_surface"); !vs.empty()) {
      try {
        visual = simcore::parseVtu(std::string_view(vs));
        simcore::validateMesh(visual, "the organ's surface");
      } catch (const std::exception& e) {
        visual = {};
        in.note("Organ surface not loaded: " + std::string(e.what()) + " The simulation mesh's boundary is drawn instead.");
      }
    }
    std::string why;
    c.organ = Organ::fromVolume(std::move(volume), {}, 1.0, visual.triangles.empty() ? nullptr : &visual, &why);
    if (!why.empty()) in.note("Organ surface not used: " + why);
  } catch (const std::exception& e) {
    c.organ = std::make_shared<Organ>();
    in.note("Organ mesh not loaded: " + std::string(e.what()));
  }
}

// A stored PNG decoded (empty when damaged).
cv::Mat decodedImage(std::string& bytes) {
  cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8U, bytes.data());
  return cv::imdecode(raw, cv::IMREAD_COLOR);
}

// frame, raw_frame.
void readFrames(CaseReader& in, Case& c) {
  if (std::string f = in.read("frame"); !f.empty()) {
    c.frame = decodedImage(f);
    if (c.frame.empty()) in.note("Frame not loaded: the stored image is damaged.");
  }
  if (std::string f = in.read("raw_frame"); !f.empty()) {
    c.rawFrame = decodedImage(f);
    if (c.rawFrame.empty()) in.note("Captured frame not loaded: the stored image is damaged.");
  }
}

// camera: the intrinsics and which way is down (each said on its own when it cannot be read); without a camera, the
// frame's default one.
void readCamera(CaseReader& in, Case& c) {
  if (std::string k = in.read("camera"); !k.empty()) {
    try {
      auto j = json::parse(k);
      for (int r = 0; r < 3; ++r)
        for (int col = 0; col < 3; ++col) c.camera.K(r, col) = j.at("K").at(r).at(col).get<double>();
      for (int i = 0; i < 5; ++i) c.camera.distortion[i] = j.at("distortion").at(i).get<double>();
      c.camera.width = j.at("width").get<int>();
      c.camera.height = j.at("height").get<int>();
      if (auto p = c.camera.problem(); !p.empty()) throw std::runtime_error(p);
    } catch (const std::exception& e) {
      c.camera = {};
      in.note("Camera not loaded: " + std::string(e.what()));
    }
    try {  // which way is down, told on the fit page (its own part of the camera's record)
      const auto j = json::parse(k);
      if (j.contains("down")) {
        const Eigen::Vector3d d(j.at("down").at(0).get<double>(), j.at("down").at(1).get<double>(), j.at("down").at(2).get<double>());
        if (!(d.allFinite() && d.norm() > 0.5 && d.norm() < 2)) throw std::runtime_error("it is not a direction");
        c.down = d.normalized();
      }
    } catch (const std::exception& e) {
      c.down.setZero();
      in.note("Which way is down not loaded: " + std::string(e.what()));
    }
  }
  if (c.camera.width == 0 && !c.frame.empty()) c.camera = imaging::Camera::defaultFor(c.frame.cols, c.frame.rows);
}

// attachments: node indices of the organ.
void readAttachments(CaseReader& in, Case& c) {
  if (std::string a = in.read("attachments"); !a.empty()) {
    try {
      const json j = json::parse(a);
      for (const auto& n : j.at("nodes")) {
        const int v = n.get<int>();
        if (v < 0 || v >= static_cast<int>(c.organ->volume.points.size())) throw std::out_of_range("node index out of range");
        c.attachments.push_back(v);
      }
    } catch (const std::exception& e) {
      c.attachments.clear();
      in.note("Attachments not loaded: " + std::string(e.what()));
    }
  }
}

// pose: the stored one, else the automatic one of an organ.
void readPose(CaseReader& in, Case& c) {
  if (std::string p = in.read("pose"); !p.empty()) {
    try {
      const json j = json::parse(p);
      c.pose = poseFrom(j.at("pose"));
      c.poseAligned = j.value("aligned", false);
      c.hasPose = true;
    } catch (const std::exception& e) {
      in.note("Pose not loaded: " + std::string(e.what()));
    }
  }
  if (!c.hasPose && !c.organ->empty()) {
    c.pose = c.automaticPose();
    c.hasPose = true;
  }
}

// meta: where the organ's mesh came from and its unit (absent in older files: metres).
void readMeshSource(CaseReader& in, Case& c) {
  if (c.organ->empty()) return;
  auto organ = std::make_shared<Organ>(*c.organ);  // once, while loading
  if (const auto source = in.meta("mesh_source")) organ->source = *source;
  if (const auto unitText = in.meta("mesh_source_unit_m")) {
    char* end = nullptr;
    const double unit = std::strtod(unitText->c_str(), &end);
    if (end != unitText->c_str() && unit > 0 && std::isfinite(unit)) organ->sourceUnitToMetre = unit;
  }
  c.organ = organ;
}

// material: the stored one (the default when it cannot be read), or the organ's default in cases saved before the
// material was part of them.
void readMaterial(CaseReader& in, Case& c) {
  if (std::string m = in.read("material"); !m.empty()) {
    try {
      const json j = json::parse(m);
      MaterialSettings s;
      s.model = simcore::materialModelFromString(j.at("model").get<std::string>());
      s.young = j.at("young").get<double>();
      s.poisson = j.at("poisson").get<double>();
      s.density = j.at("density").get<double>();
      s.vesselYoung = j.value("vessel_young", 0.0);
      s.vesselPoisson = j.value("vessel_poisson", 0.45);
      s.tearStrain = j.value("tear_strain", 0.0);
      if (!(s.tearStrain >= 0 && s.tearStrain <= 10)) throw std::runtime_error("its tear strain is outside [0, 10]");
      s.supportModulus = j.value("support_modulus", s.supportModulus);  // (cases saved before it: the default)
      if (!(s.supportModulus >= 0 && s.supportModulus <= 1e9))
        throw std::runtime_error("its support modulus is outside [0, 1e9] Pa/m");
      if (j.contains("gravity")) {  // (cases saved before it: into the scene)
        const json& g = j.at("gravity");
        bool known = false;
        for (const auto choice : {GravityChoice::IntoTheScene, GravityChoice::DownInTheImage,
                                  GravityChoice::Off})
          if (g.is_string() && g.get<std::string>() == gravityWord(choice)) s.gravity = choice, known = true;
        if (!known)
          throw std::runtime_error("its gravity is not one of \"into the scene\", \"down in the image\" or \"off\"");
      }
      c.material = s;
    } catch (const std::exception& e) {
      in.note("Material not loaded (the default is used): " + std::string(e.what()));
    }
  } else if (!c.organ->empty()) {
    c.material = defaultMaterial(*c.organ);
  }
}

// incorrect_actions, contour: the trainer's rules (the defaults when they cannot be read) and the sketched outline.
void readRulesAndContour(CaseReader& in, Case& c) {
  if (std::string r = in.read("incorrect_actions"); !r.empty()) {
    try {
      parseActionRules(r);
      c.incorrectActions = r;
    } catch (const std::exception& e) {
      in.note("The trainer's incorrect-action rules were not loaded (the defaults are used): " + std::string(e.what()));
    }
  }
  if (std::string k = in.read("contour"); !k.empty()) {
    try {
      c.contour = imaging::parseContour(k, "the case's contour");
    } catch (const std::exception& e) {
      c.contour = {};
      in.note("Contour not loaded: " + std::string(e.what()));
    }
  }
}

// second_frame, second_frame_move, second_contour: the move and the outline only with the frame.
void readSecondFrame(CaseReader& in, Case& c) {
  if (std::string f = in.read("second_frame"); !f.empty()) {
    c.frame2 = decodedImage(f);
    if (c.frame2.empty()) in.note("Second frame not loaded: the stored image is damaged.");
  }
  if (std::string k = in.read("second_frame_move"); !k.empty() && !c.frame2.empty()) {
    try {
      c.baselineMm = json::parse(k).at("baseline_mm").get<double>();
      if (!(c.baselineMm >= 0 && c.baselineMm < 1e4)) throw std::runtime_error("not a distance in mm");
    } catch (const std::exception& e) {
      c.baselineMm = 0;
      in.note("Second frame's move not loaded: " + std::string(e.what()));
    }
  }
  if (std::string k = in.read("second_contour"); !k.empty() && !c.frame2.empty()) {
    try {
      c.contour2 = imaging::parseContour(k, "the second frame's contour");
    } catch (const std::exception& e) {
      c.contour2 = {};
      in.note("Second frame's contour not loaded: " + std::string(e.what()));
    }
  }
}

// landmarks: step 4's pairs.
void readLandmarks(CaseReader& in, Case& c) {
  if (std::string l = in.read("landmarks"); !l.empty()) {
    try {
      const json j = json::parse(l);
      for (const auto& p : j.at("pairs")) {
        LandmarkPair pair;
        pair.model = vec3(p.at("model"));
        pair.image = {p.at("image").at(0).get<double>(), p.at("image").at(1).get<double>()};
        pair.hasImage = p.at("has_image").get<bool>();
        if (!pair.model.allFinite() || !pair.image.allFinite()) throw std::runtime_error("a pair holds a number that is not finite");
        c.landmarks.push_back(pair);
      }
    } catch (const std::exception& e) {
      c.landmarks.clear();
      in.note("Landmark pairs not loaded: " + std::string(e.what()));
    }
  }
}

// elastic_fit, appearance: steps 5 and 6's results (a fit only for the organ it was made on).
void readFitAndAppearance(CaseReader& in, Case& c) {
  if (std::string f = in.read("elastic_fit"); !f.empty()) {
    try {
      const json j = json::parse(f);
      auto fit = std::make_shared<ElasticFit>();
      for (const auto& p : j.at("positions")) fit->nodes.emplace_back(p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>());
      fit->status = j.value("status", std::string());
      if (fit->nodes.size() != c.organ->volume.points.size()) throw std::runtime_error("it does not match the organ mesh");
      c.fit = fit;
    } catch (const std::exception& e) {
      in.note("Elastic fit not loaded: " + std::string(e.what()));
    }
  }
  if (std::string a = in.read("appearance"); !a.empty()) {
    try {
      c.appearance = appearanceEstimateFromJson(a);
    } catch (const std::exception& e) {
      in.note("Appearance not loaded: " + std::string(e.what()));
    }
  }
}

// ground_truth: what a synthetic case was made with.
void readGroundTruth(CaseReader& in, Case& c) {
  if (std::string g = in.read("ground_truth"); !g.empty()) {
    try {
      const json j = json::parse(g);
      auto t = std::make_shared<GroundTruth>();
      t->pose = poseFrom(j.at("pose"));
      const auto& a = j.at("appearance");
      t->appearance.lightPosition = vec3(a.at("light_position"));
      t->appearance.kd = vec3(a.at("kd"));
      t->appearance.ks = vec3(a.at("ks"));
      t->appearance.roughness = a.at("roughness").get<double>();
      t->appearance.falloff = a.value("falloff", 0.0);
      for (const auto& s : j.at("vessel_tree")) {
        t->vesselAxes.emplace_back(vec3(s.at("a")), vec3(s.at("b")));
        t->vesselRadii.push_back(s.at("radius").get<double>());
      }
      c.groundTruth = t;
    } catch (const std::exception& e) {
      in.note("Ground truth not loaded: " + std::string(e.what()));
    }
  }
}

}  // namespace

Case loadCaseFile(const std::string& path, std::vector<std::string>* notes) {
  refuseNotACaseFile(path);
  CaseReader in(path, notes);
  Case c;
  if (auto n = in.meta("name")) c.name = *n;
  readResponses(in);
  readOrgan(in, c);
  readFrames(in, c);
  readCamera(in, c);       // (its default from the frame)
  readAttachments(in, c);  // (checked against the organ)
  readPose(in, c);         // (the organ's automatic one when none is stored)
  readMeshSource(in, c);
  readMaterial(in, c);     // (the organ's default when none is stored)
  readRulesAndContour(in, c);
  readSecondFrame(in, c);
  readLandmarks(in, c);
  readFitAndAppearance(in, c);  // (a fit checked against the organ)
  readGroundTruth(in, c);
  return c;
}

}  // namespace rehearse::app
