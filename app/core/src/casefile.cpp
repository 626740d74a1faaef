// The case file: one SQLite database (schema in casefile.hpp), through SQLite's own library, the parts' checksums with
// OpenSSL's SHA-256; written to a temporary file beside the target, flushed, then renamed over it.
#include "rehearse/app/casefile.hpp"

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
namespace {

[[noreturn]] void fail(const std::string& message) { throw std::runtime_error(message); }

std::string fileName(const std::string& path) { return std::filesystem::path(path).filename().string(); }

// Why SQLite failed, in our words (its own text, e.g. "unable to open database file", names no cause a user can act
// on). `code` is SQLite's result code (primary or extended).
std::string sqlProblem(int code) {
  switch (code & 0xff) {
    case SQLITE_FULL: return "the disk is full";
    case SQLITE_READONLY: case SQLITE_PERM: return "the folder or file is read-only";
    case SQLITE_CANTOPEN: return "the file cannot be created there (a folder missing or not writable)";
    case SQLITE_IOERR: return "the disk reported an input/output error";
    case SQLITE_CORRUPT: case SQLITE_NOTADB: return "the file is damaged or not a database";
    case SQLITE_BUSY: case SQLITE_LOCKED: return "another program holds the file";
    default: return "the database reported error " + std::to_string(code & 0xff);
  }
}

std::string sha256(const std::string& data) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  if (EVP_Digest(data.data(), data.size(), md, &length, EVP_sha256(), nullptr) != 1)
    fail("The case's checksums cannot be computed (OpenSSL refused SHA-256).");
  return std::string(reinterpret_cast<const char*>(md), length);
}

// Now as ISO 8601 UTC with milliseconds ("2026-11-30T14:25:01.123Z"), as the case files have always said.
std::string utcNowWithMs() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[40];
  const std::size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  std::snprintf(buf + n, sizeof buf - n, ".%03dZ", static_cast<int>(ms));
  return buf;
}

std::string exactNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// One database connection, closed on every path; statements run to completion one at a time.
class Database {
 public:
  Database(const std::string& path, int flags) {
    code_ = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr);
    if (code_ == SQLITE_OK) sqlite3_extended_result_codes(db_, 1), sqlite3_busy_timeout(db_, 2000);
  }
  ~Database() { sqlite3_close(db_); }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;
  bool open() const { return code_ == SQLITE_OK; }
  int code() const { return code_; }
  // Runs `sql` (no result rows wanted); false with code() set when SQLite refused.
  bool exec(const char* sql) {
    code_ = sqlite3_exec(db_, sql, nullptr, nullptr, nullptr);
    return code_ == SQLITE_OK;
  }
  // Inserts one row of `texts` then `blobs` (bound in that order) through `sql`.
  bool insert(const char* sql, std::initializer_list<const std::string*> texts,
              std::initializer_list<const std::string*> blobs) {
    sqlite3_stmt* s = nullptr;
    code_ = sqlite3_prepare_v2(db_, sql, -1, &s, nullptr);
    if (code_ != SQLITE_OK) return false;
    int i = 1;
    for (const std::string* t : texts) sqlite3_bind_text64(s, i++, t->data(), t->size(), SQLITE_STATIC, SQLITE_UTF8);
    for (const std::string* b : blobs) sqlite3_bind_blob64(s, i++, b->data(), b->size(), SQLITE_STATIC);
    code_ = sqlite3_step(s);
    sqlite3_finalize(s);
    if (code_ == SQLITE_DONE) code_ = SQLITE_OK;
    return code_ == SQLITE_OK;
  }
  // The first row's columns of `sql` with `key` bound, as bytes; nullopt when there is no row or SQLite refused
  // (then code() says why).
  std::optional<std::vector<std::string>> row(const char* sql, const std::string& key, int columns) {
    sqlite3_stmt* s = nullptr;
    code_ = sqlite3_prepare_v2(db_, sql, -1, &s, nullptr);
    if (code_ != SQLITE_OK) return std::nullopt;
    sqlite3_bind_text64(s, 1, key.data(), key.size(), SQLITE_STATIC, SQLITE_UTF8);
    std::optional<std::vector<std::string>> out;
    code_ = sqlite3_step(s);
    if (code_ == SQLITE_ROW) {
      code_ = SQLITE_OK;
      out.emplace();
      for (int k = 0; k < columns; ++k) {
        const auto* p = static_cast<const char*>(sqlite3_column_blob(s, k));
        out->emplace_back(p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(s, k))) : std::string());
      }
    } else if (code_ == SQLITE_DONE) {
      code_ = SQLITE_OK;
    }
    sqlite3_finalize(s);
    return out;
  }
  std::optional<std::string> meta(const std::string& key) {
    auto r = row("SELECT value FROM meta WHERE key = ?", key, 1);
    if (!r) return std::nullopt;
    return r->front();
  }

 private:
  sqlite3* db_ = nullptr;
  int code_ = SQLITE_OK;
};

void fsyncPath(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), flags);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

json poseJson(const Pose& p) {
  return {{"R", {{p.R(0, 0), p.R(0, 1), p.R(0, 2)}, {p.R(1, 0), p.R(1, 1), p.R(1, 2)}, {p.R(2, 0), p.R(2, 1), p.R(2, 2)}}},
          {"t", {p.t.x(), p.t.y(), p.t.z()}},
          {"unit", "m"}};
}
Pose poseFrom(const json& j) {
  Pose p;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) p.R(r, k) = j.at("R").at(r).at(k).get<double>();
    p.t[r] = j.at("t").at(r).get<double>();
  }
  return p;
}
json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d vec3(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

// The case file's words for where gravity points (material.json's "gravity").
const char* gravityWord(GravityChoice g) {
  switch (g) {
    case GravityChoice::DownInTheImage:
      return "down in the image";
    case GravityChoice::Off:
      return "off";
    case GravityChoice::IntoTheScene:
      break;
  }
  return "into the scene";
}


}  // namespace

bool isCaseFile(const std::string& path) {
  struct stat st {};
  if (path.empty() || ::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  std::ifstream f(path, std::ios::binary);
  char header[16] = {};
  return f.read(header, sizeof header) && std::memcmp(header, "SQLite format 3\0", 16) == 0;
}

// SQLite's blobs stop at 1 GB: the precomputed responses are kept with the case up to half that.
constexpr std::size_t kMaxStoredResponses = std::size_t(512) << 20;

void saveCaseFile(const Case& c, const std::string& path, const std::string& recordingsFrom, std::uint64_t responseKey) {
  const std::string tmp = path + ".saving-" + std::to_string(::getpid());
  std::remove(tmp.c_str());
  {
    Database db(tmp, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    if (!db.open()) fail("Cannot write " + path + ": " + sqlProblem(db.code()) + "; choose another folder.");
    auto refused = [&] {
      const int code = db.code();
      std::remove(tmp.c_str());
      fail("Cannot write " + path + ": " + sqlProblem(code) + ".");
    };
    // The temporary file is renamed only once complete, so the journal can stay in memory.
    db.exec("PRAGMA journal_mode=OFF");
    db.exec("PRAGMA synchronous=OFF");
    if (!db.exec("CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL)") ||
        !db.exec("CREATE TABLE parts(name TEXT PRIMARY KEY, format TEXT NOT NULL, data BLOB NOT NULL, sha256 BLOB NOT "
                 "NULL, saved_utc TEXT NOT NULL)") ||
        !db.exec("BEGIN"))
      refused();
    const std::string now = utcNowWithMs();
    auto meta = [&](const std::string& k, const std::string& v) {
      if (!db.insert("INSERT INTO meta(key, value) VALUES(?, ?)", {&k, &v}, {})) refused();
    };
    meta("schema_version", std::to_string(kCaseSchemaVersion));
    meta("app_version", REHEARSE_VERSION);
    meta("name", c.name);
    meta("saved_utc", now);
    auto part = [&](const std::string& name, const std::string& format, const std::string& data) {
      const std::string sum = sha256(data);
      if (!db.insert("INSERT INTO parts(name, format, saved_utc, data, sha256) VALUES(?, ?, ?, ?, ?)",
                     {&name, &format, &now}, {&data, &sum}))
        refused();
    };
    const simcore::Mesh& volume = c.organ->volume;
    if (!volume.empty()) {
      part("volume", "vtu", simcore::writeVtu(volume, false));
      json labels = json::array();
      for (const auto& [l, n] : volume.labelNames) labels.push_back({{"label", l}, {"name", n}});
      part("labels", "json", labels.dump());
      if (const auto& visual = c.organ->visual) {  // the organ's own surface (its embedding is remade on loading)
        simcore::Mesh surface;
        surface.points = visual->points;
        surface.triangles = visual->triangles;
        part("visual_surface", "vtu", simcore::writeVtu(surface, false));
      }
    }
    if (!c.frame.empty()) {
      std::vector<uchar> png;
      cv::imencode(".png", c.frame, png);
      part("frame", "png", std::string(png.begin(), png.end()));
    }
    if (!c.rawFrame.empty() && c.rawFrame.data != c.frame.data) {
      std::vector<uchar> png;
      cv::imencode(".png", c.rawFrame, png);
      part("raw_frame", "png", std::string(png.begin(), png.end()));
    }
    if (c.camera.width > 0) {
      const auto& k = c.camera;
      json cam = {{"K", {{k.K(0, 0), k.K(0, 1), k.K(0, 2)}, {k.K(1, 0), k.K(1, 1), k.K(1, 2)}, {k.K(2, 0), k.K(2, 1), k.K(2, 2)}}},
                  {"distortion", k.distortion},
                  {"width", k.width},
                  {"height", k.height}};
      if (c.down.norm() > 0) cam["down"] = {c.down.x(), c.down.y(), c.down.z()};
      part("camera", "json", cam.dump());
    }
    part("attachments", "json", json{{"nodes", c.attachments}}.dump());
    if (c.hasPose) part("pose", "json", json{{"pose", poseJson(c.pose)}, {"aligned", c.poseAligned}}.dump());
    if (!c.organ->source.empty()) meta("mesh_source", c.organ->source);
    meta("mesh_source_unit_m", exactNumber(c.organ->sourceUnitToMetre));
    {
      const auto& m = c.material;
      part("material", "json",
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
    if (!c.incorrectActions.empty()) part("incorrect_actions", "json", c.incorrectActions);
    if (!c.contour.segments.empty()) part("contour", "json", imaging::contourToJson(c.contour));
    if (!c.frame2.empty()) {  // the second frame (issue 38), its outline and how far the scope moved
      std::vector<uchar> png;
      cv::imencode(".png", c.frame2, png);
      part("second_frame", "png", std::string(png.begin(), png.end()));
      part("second_frame_move", "json", json{{"baseline_mm", c.baselineMm}}.dump());
      if (!c.contour2.segments.empty()) part("second_contour", "json", imaging::contourToJson(c.contour2));
    }
    if (!c.landmarks.empty()) {
      json pairs = json::array();
      for (const auto& l : c.landmarks)
        pairs.push_back({{"model", {l.model.x(), l.model.y(), l.model.z()}}, {"image", {l.image.x(), l.image.y()}}, {"has_image", l.hasImage}});
      part("landmarks", "json", json{{"pairs", pairs}, {"unit", "m (model), px (image)"}}.dump());
    }
    if (c.fit) {
      json pts = json::array();
      for (const auto& x : c.fit->nodes) pts.push_back({x.x(), x.y(), x.z()});
      part("elastic_fit", "json", json{{"positions", pts}, {"status", c.fit->status}}.dump());
    }
    if (c.appearance) part("appearance", "json", appearanceEstimateToJson(*c.appearance));
    if (c.groundTruth) {
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
      part("ground_truth", "json", gt.dump());
    }
    if (responseKey != 0)
      if (const auto r = simcore::ResponseCache::shared().find(responseKey);
          r && r->memoryBytes() <= kMaxStoredResponses) {  // (larger ones are built again when the case opens)
        std::string data(reinterpret_cast<const char*>(&responseKey), sizeof responseKey);
        data += r->toBytes();
        part("precomputed_responses", "bin", data);
      }
    if (!db.exec("COMMIT")) refused();
  }
  // Rehearsals recorded into the case (issue 16) are carried into the new file.
  if (!recordingsFrom.empty() && isCaseFile(recordingsFrom)) {
    try {
      copyRecordings(recordingsFrom, tmp);
    } catch (const std::runtime_error& e) {
      std::remove(tmp.c_str());
      fail("Cannot save " + path + ": " + e.what() + ". The previous file is unchanged.");
    }
  }
  fsyncPath(tmp, O_RDONLY);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    fail("Cannot replace " + path + "; check that the folder is writable. The previous file is unchanged.");
  }
  const std::filesystem::path target = std::filesystem::absolute(path);
  fsyncPath(target.parent_path().string(), O_RDONLY | O_DIRECTORY);
  // Temporary files left by saves that were killed (their process is gone) are removed.
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

Case loadCaseFile(const std::string& path, std::vector<std::string>* notes) {
  const std::string name = fileName(path);
  if (!std::filesystem::exists(path)) fail("The case file " + path + " does not exist; check the path.");
  if (!isCaseFile(path)) fail(name + " is not a Rehearse case file (it is not an SQLite database).");
  Database db(path, SQLITE_OPEN_READONLY);
  if (!db.open()) fail(name + " cannot be opened: " + sqlProblem(db.code()) + ".");
  const auto versionText = db.meta("schema_version");
  if (!versionText) fail(name + " is damaged or not a Rehearse case (no schema version).");
  const int version = std::atoi(versionText->c_str());
  if (version < 1) fail(name + " has an unknown schema version.");
  if (version > kCaseSchemaVersion)
    fail(name + " was saved by a newer Rehearse (schema " + std::to_string(version) + ", this one reads up to " +
         std::to_string(kCaseSchemaVersion) + "); update Rehearse to open it.");
  // Migrations: schema 1 has no checksums (its parts are read as they are); the parts it lacks are simply
  // absent. Nothing is written back: the next save writes the current schema.
  const bool checksums = version >= 2;
  Case c;
  if (auto n = db.meta("name")) c.name = *n;
  auto note = [&](const std::string& s) {
    if (notes) notes->push_back(s);
  };
  // What each part is called in messages ("<what> not loaded: ...").
  const std::map<std::string, std::string> partName = {{"volume", "Organ mesh"},
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
  auto read = [&](const char* part) -> std::string {
    const auto named = partName.find(part);
    const std::string what = named != partName.end() ? named->second : std::string(part);
    const auto r = checksums ? db.row("SELECT data, sha256 FROM parts WHERE name = ?", part, 2)
                             : db.row("SELECT data FROM parts WHERE name = ?", part, 1);
    if (db.code() != SQLITE_OK) {
      note(what + " not loaded: it could not be read (" + sqlProblem(db.code()) + ").");
      return {};
    }
    if (!r) return {};
    if (checksums && sha256(r->at(0)) != r->at(1)) {
      note(what + " not loaded: the stored data is damaged (it no longer matches its checksum).");
      return {};
    }
    return r->at(0);
  };
  if (std::string r = read("precomputed_responses"); r.size() > sizeof(std::uint64_t)) {
    std::uint64_t key = 0;
    std::memcpy(&key, r.data(), sizeof key);
    simcore::ResponseCache::shared().offerBytes(
        key, std::make_shared<const std::string>(r.substr(sizeof key)));
  }
  if (std::string v = read("volume"); !v.empty()) {
    try {
      simcore::Mesh volume = simcore::parseVtu(std::string_view(v));
      simcore::validateMesh(volume, "the organ mesh");
      if (std::string l = read("labels"); !l.empty())
        for (const auto& e : json::parse(l)) volume.setLabelName(e.at("label").get<int>(), e.at("name").get<std::string>());
      // The organ's own surface, drawn in the composited view: without it (older files, or damaged) the
      // simulation mesh's boundary is drawn, and the note says so.
      simcore::Mesh visual;
      if (std::string vs = read("visual_surface"); !vs.empty()) {
        try {
          visual = simcore::parseVtu(std::string_view(vs));
          simcore::validateMesh(visual, "the organ's surface");
        } catch (const std::exception& e) {
          visual = {};
          note("Organ surface not loaded: " + std::string(e.what()) + " The simulation mesh's boundary is drawn instead.");
        }
      }
      std::string why;
      c.organ = Organ::fromVolume(std::move(volume), {}, 1.0, visual.triangles.empty() ? nullptr : &visual, &why);
      if (!why.empty()) note("Organ surface not used: " + why);
    } catch (const std::exception& e) {
      c.organ = std::make_shared<Organ>();
      note("Organ mesh not loaded: " + std::string(e.what()));
    }
  }
  if (std::string f = read("frame"); !f.empty()) {
    cv::Mat raw(1, static_cast<int>(f.size()), CV_8U, f.data());
    c.frame = cv::imdecode(raw, cv::IMREAD_COLOR);
    if (c.frame.empty()) note("Frame not loaded: the stored image is damaged.");
  }
  if (std::string f = read("raw_frame"); !f.empty()) {
    cv::Mat raw(1, static_cast<int>(f.size()), CV_8U, f.data());
    c.rawFrame = cv::imdecode(raw, cv::IMREAD_COLOR);
    if (c.rawFrame.empty()) note("Captured frame not loaded: the stored image is damaged.");
  }
  if (std::string k = read("camera"); !k.empty()) {
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
      note("Camera not loaded: " + std::string(e.what()));
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
      note("Which way is down not loaded: " + std::string(e.what()));
    }
  }
  if (c.camera.width == 0 && !c.frame.empty()) c.camera = imaging::Camera::defaultFor(c.frame.cols, c.frame.rows);
  if (std::string a = read("attachments"); !a.empty()) {
    try {
      const json j = json::parse(a);
      for (const auto& n : j.at("nodes")) {
        const int v = n.get<int>();
        if (v < 0 || v >= static_cast<int>(c.organ->volume.points.size())) throw std::out_of_range("node index out of range");
        c.attachments.push_back(v);
      }
    } catch (const std::exception& e) {
      c.attachments.clear();
      note("Attachments not loaded: " + std::string(e.what()));
    }
  }
  if (std::string p = read("pose"); !p.empty()) {
    try {
      const json j = json::parse(p);
      c.pose = poseFrom(j.at("pose"));
      c.poseAligned = j.value("aligned", false);
      c.hasPose = true;
    } catch (const std::exception& e) {
      note("Pose not loaded: " + std::string(e.what()));
    }
  }
  if (!c.hasPose && !c.organ->empty()) {
    c.pose = c.automaticPose();
    c.hasPose = true;
  }
  if (!c.organ->empty()) {
    auto organ = std::make_shared<Organ>(*c.organ);  // once, while loading
    if (const auto source = db.meta("mesh_source")) organ->source = *source;
    if (const auto unitText = db.meta("mesh_source_unit_m")) {  // absent in older files: metres
      char* end = nullptr;
      const double unit = std::strtod(unitText->c_str(), &end);
      if (end != unitText->c_str() && unit > 0 && std::isfinite(unit)) organ->sourceUnitToMetre = unit;
    }
    c.organ = organ;
  }
  if (std::string m = read("material"); !m.empty()) {
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
      note("Material not loaded (the default is used): " + std::string(e.what()));
    }
  } else if (!c.organ->empty()) {
    c.material = defaultMaterial(*c.organ);  // cases saved before the material was part of them
  }
  if (std::string r = read("incorrect_actions"); !r.empty()) {
    try {
      parseActionRules(r);
      c.incorrectActions = r;
    } catch (const std::exception& e) {
      note("The trainer's incorrect-action rules were not loaded (the defaults are used): " + std::string(e.what()));
    }
  }
  if (std::string k = read("contour"); !k.empty()) {
    try {
      c.contour = imaging::parseContour(k, "the case's contour");
    } catch (const std::exception& e) {
      c.contour = {};
      note("Contour not loaded: " + std::string(e.what()));
    }
  }
  if (std::string f = read("second_frame"); !f.empty()) {
    cv::Mat raw(1, static_cast<int>(f.size()), CV_8U, f.data());
    c.frame2 = cv::imdecode(raw, cv::IMREAD_COLOR);
    if (c.frame2.empty()) note("Second frame not loaded: the stored image is damaged.");
  }
  if (std::string k = read("second_frame_move"); !k.empty() && !c.frame2.empty()) {
    try {
      c.baselineMm = json::parse(k).at("baseline_mm").get<double>();
      if (!(c.baselineMm >= 0 && c.baselineMm < 1e4)) throw std::runtime_error("not a distance in mm");
    } catch (const std::exception& e) {
      c.baselineMm = 0;
      note("Second frame's move not loaded: " + std::string(e.what()));
    }
  }
  if (std::string k = read("second_contour"); !k.empty() && !c.frame2.empty()) {
    try {
      c.contour2 = imaging::parseContour(k, "the second frame's contour");
    } catch (const std::exception& e) {
      c.contour2 = {};
      note("Second frame's contour not loaded: " + std::string(e.what()));
    }
  }
  if (std::string l = read("landmarks"); !l.empty()) {
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
      note("Landmark pairs not loaded: " + std::string(e.what()));
    }
  }
  if (std::string f = read("elastic_fit"); !f.empty()) {
    try {
      const json j = json::parse(f);
      auto fit = std::make_shared<ElasticFit>();
      for (const auto& p : j.at("positions")) fit->nodes.emplace_back(p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>());
      fit->status = j.value("status", std::string());
      if (fit->nodes.size() != c.organ->volume.points.size()) throw std::runtime_error("it does not match the organ mesh");
      c.fit = fit;
    } catch (const std::exception& e) {
      note("Elastic fit not loaded: " + std::string(e.what()));
    }
  }
  if (std::string a = read("appearance"); !a.empty()) {
    try {
      c.appearance = appearanceEstimateFromJson(a);
    } catch (const std::exception& e) {
      note("Appearance not loaded: " + std::string(e.what()));
    }
  }
  if (std::string g = read("ground_truth"); !g.empty()) {
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
      note("Ground truth not loaded: " + std::string(e.what()));
    }
  }
  return c;
}

Case loadCase(const std::string& path, std::vector<std::string>* notes) {
  if (std::filesystem::is_directory(path)) return loadCaseDirectory(path, notes);
  if (isCaseFile(path)) return loadCaseFile(path, notes);
  if (!std::filesystem::exists(path)) fail("The case " + path + " does not exist; give a .rehearse case file or a case folder.");
  fail(fileName(path) + " is not a case: give a .rehearse case file (as the GUI saves) or a case folder (as 'rehearse "
       "phantom --out DIR' writes).");
}

}  // namespace rehearse::app
