// Saving a case file: the temporary file's writer, one step per part of the case, then the flush and the rename.
#include "rehearse/app/casefile.hpp"
#include "casefile_parts.hpp"

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

// ---- Saving: the temporary file's writer, then one step per part of the case, in the order the rows are written. ----

// The temporary file being written: its database (the tables made, a transaction open), the save's time stamp (every
// row's saved_utc), and the refusal that removes the file.
class CaseWriter {
 public:
  CaseWriter(const std::string& path, const std::string& tmp)
      : path_(path), tmp_(tmp), db_(tmp, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE) {
    if (!db_.open()) fail("Cannot write " + path_ + ": " + sqlProblem(db_.code()) + "; choose another folder.");
    // The temporary file is renamed only once complete, so the journal can stay in memory.
    db_.exec("PRAGMA journal_mode=OFF");
    db_.exec("PRAGMA synchronous=OFF");
    if (!db_.exec("CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL)") ||
        !db_.exec("CREATE TABLE parts(name TEXT PRIMARY KEY, format TEXT NOT NULL, data BLOB NOT NULL, sha256 BLOB NOT "
                  "NULL, saved_utc TEXT NOT NULL)") ||
        !db_.exec("BEGIN"))
      refused();
    now_ = utcNowWithMs();
  }
  CaseWriter(const CaseWriter&) = delete;
  CaseWriter& operator=(const CaseWriter&) = delete;

  const std::string& now() const { return now_; }
  void meta(const std::string& k, const std::string& v) {
    if (!db_.insert("INSERT INTO meta(key, value) VALUES(?, ?)", {&k, &v}, {})) refused();
  }
  void part(const std::string& name, const std::string& format, const std::string& data) {
    const std::string sum = sha256(data);
    if (!db_.insert("INSERT INTO parts(name, format, saved_utc, data, sha256) VALUES(?, ?, ?, ?, ?)",
                    {&name, &format, &now_}, {&data, &sum}))
      refused();
  }
  void commit() {
    if (!db_.exec("COMMIT")) refused();
  }

 private:
  // SQLite refused a statement: the temporary file goes, the sentence says why.
  [[noreturn]] void refused() {
    const int code = db_.code();
    std::remove(tmp_.c_str());
    fail("Cannot write " + path_ + ": " + sqlProblem(code) + ".");
  }

  const std::string& path_;
  const std::string& tmp_;
  Database db_;
  std::string now_;
};

std::string pngBytes(const cv::Mat& image) {
  std::vector<uchar> png;
  cv::imencode(".png", image, png);
  return std::string(png.begin(), png.end());
}

// meta: the schema, the build, the case's name and when it was saved.
void writeHeader(CaseWriter& w, const Case& c) {
  w.meta("schema_version", std::to_string(kCaseSchemaVersion));
  w.meta("app_version", REHEARSE_VERSION);
  w.meta("name", c.name);
  w.meta("saved_utc", w.now());
}

// volume, labels, visual_surface: the organ's volume, its labels' names and its own surface (its embedding is remade
// on loading).
void writeOrgan(CaseWriter& w, const Case& c) {
  const simcore::Mesh& volume = c.organ->volume;
  if (volume.empty()) return;
  w.part("volume", "vtu", simcore::writeVtu(volume, false));
  json labels = json::array();
  for (const auto& [l, n] : volume.labelNames) labels.push_back({{"label", l}, {"name", n}});
  w.part("labels", "json", labels.dump());
  if (const auto& visual = c.organ->visual) {
    simcore::Mesh surface;
    surface.points = visual->points;
    surface.triangles = visual->triangles;
    w.part("visual_surface", "vtu", simcore::writeVtu(surface, false));
  }
}

// frame, raw_frame: the frame every step uses, and the one captured when it had to be undistorted.
void writeFrames(CaseWriter& w, const Case& c) {
  if (!c.frame.empty()) w.part("frame", "png", pngBytes(c.frame));
  if (!c.rawFrame.empty() && c.rawFrame.data != c.frame.data) w.part("raw_frame", "png", pngBytes(c.rawFrame));
}

// camera: the intrinsics and, when told, which way is down.
void writeCamera(CaseWriter& w, const Case& c) {
  if (c.camera.width <= 0) return;
  const auto& k = c.camera;
  json cam = {{"K", {{k.K(0, 0), k.K(0, 1), k.K(0, 2)}, {k.K(1, 0), k.K(1, 1), k.K(1, 2)}, {k.K(2, 0), k.K(2, 1), k.K(2, 2)}}},
              {"distortion", k.distortion},
              {"width", k.width},
              {"height", k.height}};
  if (c.down.norm() > 0) cam["down"] = {c.down.x(), c.down.y(), c.down.z()};
  w.part("camera", "json", cam.dump());
}

// attachments, pose: the held nodes and the organ's placement.
void writePlacement(CaseWriter& w, const Case& c) {
  w.part("attachments", "json", json{{"nodes", c.attachments}}.dump());
  if (c.hasPose) w.part("pose", "json", json{{"pose", poseJson(c.pose)}, {"aligned", c.poseAligned}}.dump());
}

// meta: where the organ's mesh came from and its unit.
void writeMeshSource(CaseWriter& w, const Case& c) {
  if (!c.organ->source.empty()) w.meta("mesh_source", c.organ->source);
  w.meta("mesh_source_unit_m", exactNumber(c.organ->sourceUnitToMetre));
}

// material: the tissue's law, its parameters and where gravity points.
void writeMaterial(CaseWriter& w, const Case& c) {
  const auto& m = c.material;
  w.part("material", "json",
         json{{"model", simcore::toString(m.model)},
              {"young", m.young},
              {"poisson", m.poisson},
              {"density", m.density},
              {"vessel_young", m.vesselYoung},
              {"vessel_poisson", m.vesselPoisson},
              {"tear_strain", m.tearStrain},
              {"support_modulus", m.supportModulus},
              {"gravity", gravityWord(m.gravity)}}
             .dump());
}

// incorrect_actions, contour: the trainer's rules and the sketched outline.
void writeRulesAndContour(CaseWriter& w, const Case& c) {
  if (!c.incorrectActions.empty()) w.part("incorrect_actions", "json", c.incorrectActions);
  if (!c.contour.segments.empty()) w.part("contour", "json", imaging::contourToJson(c.contour));
}

// second_frame, second_frame_move, second_contour: the second frame (issue 38), how far the scope moved and its
// outline.
void writeSecondFrame(CaseWriter& w, const Case& c) {
  if (c.frame2.empty()) return;
  w.part("second_frame", "png", pngBytes(c.frame2));
  w.part("second_frame_move", "json", json{{"baseline_mm", c.baselineMm}}.dump());
  if (!c.contour2.segments.empty()) w.part("second_contour", "json", imaging::contourToJson(c.contour2));
}

// landmarks: step 4's pairs.
void writeLandmarks(CaseWriter& w, const Case& c) {
  if (c.landmarks.empty()) return;
  json pairs = json::array();
  for (const auto& l : c.landmarks)
    pairs.push_back({{"model", {l.model.x(), l.model.y(), l.model.z()}}, {"image", {l.image.x(), l.image.y()}}, {"has_image", l.hasImage}});
  w.part("landmarks", "json", json{{"pairs", pairs}, {"unit", "m (model), px (image)"}}.dump());
}

// elastic_fit, appearance: steps 5 and 6's results.
void writeFitAndAppearance(CaseWriter& w, const Case& c) {
  if (c.fit) {
    json pts = json::array();
    for (const auto& x : c.fit->nodes) pts.push_back({x.x(), x.y(), x.z()});
    w.part("elastic_fit", "json", json{{"positions", pts}, {"status", c.fit->status}}.dump());
  }
  if (c.appearance) w.part("appearance", "json", appearanceEstimateToJson(*c.appearance));
}

// ground_truth: the pose, appearance and vessel tree a synthetic case was made with.
void writeGroundTruth(CaseWriter& w, const Case& c) {
  if (!c.groundTruth) return;
  const GroundTruth& t = *c.groundTruth;
  json tree = json::array();
  for (std::size_t i = 0; i < t.vesselAxes.size(); ++i)
    tree.push_back({{"a", vec(t.vesselAxes[i].first)}, {"b", vec(t.vesselAxes[i].second)}, {"radius", t.vesselRadii[i]}});
  const auto& a = t.appearance;
  json gt = {{"pose", poseJson(t.pose)},
             {"appearance",
              {{"light_position", vec(a.lightPosition)},
               {"kd", vec(a.kd)},
               {"ks", vec(a.ks)},
               {"roughness", a.roughness},
               {"falloff", a.falloff}}},
             {"vessel_tree", tree}};
  w.part("ground_truth", "json", gt.dump());
}

// SQLite's blobs stop at 1 GB: the precomputed responses are kept with the case up to half that.
constexpr std::size_t kMaxStoredResponses = std::size_t(512) << 20;

// precomputed_responses: their key then their bytes (larger ones are built again when the case opens).
void writeResponses(CaseWriter& w, std::uint64_t responseKey) {
  if (responseKey == 0) return;
  if (const auto r = simcore::ResponseCache::shared().find(responseKey); r && r->memoryBytes() <= kMaxStoredResponses) {
    std::string data(reinterpret_cast<const char*>(&responseKey), sizeof responseKey);
    data += r->toBytes();
    w.part("precomputed_responses", "bin", data);
  }
}

// Rehearsals recorded into the case (issue 16) are carried into the new file.
void carryRecordings(const std::string& recordingsFrom, const std::string& tmp, const std::string& path) {
  if (recordingsFrom.empty() || !isCaseFile(recordingsFrom)) return;
  try {
    copyRecordings(recordingsFrom, tmp);
  } catch (const std::runtime_error& e) {
    std::remove(tmp.c_str());
    fail("Cannot save " + path + ": " + e.what() + ". The previous file is unchanged.");
  }
}

// The complete temporary file flushed, renamed over the target and the folder flushed; the target's absolute path.
std::filesystem::path replaceWith(const std::string& tmp, const std::string& path) {
  fsyncPath(tmp, O_RDONLY);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    fail("Cannot replace " + path + "; check that the folder is writable. The previous file is unchanged.");
  }
  const std::filesystem::path target = std::filesystem::absolute(path);
  fsyncPath(target.parent_path().string(), O_RDONLY | O_DIRECTORY);
  return target;
}

// Temporary files left by saves that were killed (their process is gone) are removed.
void removeAbandonedSaves(const std::filesystem::path& target) {
  const std::string prefix = target.filename().string() + ".saving-";
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(target.parent_path(), ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0 || !entry.is_regular_file(ec)) continue;
    const std::string digits = name.substr(prefix.size());
    if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const long pid = std::strtol(digits.c_str(), nullptr, 10);
    if (pid != ::getpid() && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)
      std::filesystem::remove(entry.path(), ec);
  }
}

}  // namespace

void saveCaseFile(const Case& c, const std::string& path, const std::string& recordingsFrom, std::uint64_t responseKey) {
  const std::string tmp = path + ".saving-" + std::to_string(::getpid());
  std::remove(tmp.c_str());
  {
    CaseWriter w(path, tmp);
    writeHeader(w, c);
    writeOrgan(w, c);
    writeFrames(w, c);
    writeCamera(w, c);
    writePlacement(w, c);
    writeMeshSource(w, c);
    writeMaterial(w, c);
    writeRulesAndContour(w, c);
    writeSecondFrame(w, c);
    writeLandmarks(w, c);
    writeFitAndAppearance(w, c);
    writeGroundTruth(w, c);
    writeResponses(w, responseKey);
    w.commit();
  }  // (closed before the recordings are copied into it)
  carryRecordings(recordingsFrom, tmp, path);
  removeAbandonedSaves(replaceWith(tmp, path));
}

}  // namespace rehearse::app
