#include "rehearse/app/recording.hpp"

#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <cstring>
#include <ctime>
#include <stdexcept>

namespace rehearse::app {
namespace {

using nlohmann::json;

// A field added to these structs must be recorded too: these sizes stop the build until encodeSetup knows it.
static_assert(sizeof(simcore::MaterialParams) == 32, "MaterialParams changed: record the new field in encodeSetup/decodeSetup");
static_assert(sizeof(simcore::CutSettings) == 32, "CutSettings changed: record the new field in encodeSetup/decodeSetup");

std::uint64_t fnv(std::uint64_t h, const void* data, std::size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 1099511628211ULL;
  }
  return h;
}

json vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }
Eigen::Vector3d vec(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

json material(const simcore::MaterialParams& m) {
  return {{"model", static_cast<int>(m.model)}, {"young", m.young}, {"poisson", m.poisson}, {"density", m.density}};
}
simcore::MaterialParams material(const json& j) {
  simcore::MaterialParams m;
  m.model = static_cast<simcore::MaterialModel>(j.at("model").get<int>());
  m.young = j.at("young");
  m.poisson = j.at("poisson");
  m.density = j.at("density");
  return m;
}

json settings(const simcore::SimulationSettings& s) {
  return {{"timeStep", s.timeStep},
          {"gravity", vec(s.gravity)},
          {"rayleighMass", s.rayleighMass},
          {"rayleighStiffness", s.rayleighStiffness},
          {"maxNewtonIterations", s.maxNewtonIterations},
          {"tolerance", s.tolerance},
          {"staticStepTolerance", s.staticStepTolerance},
          {"staticChord", s.staticChord},
          {"lineSearch", s.lineSearch},
          {"solver", static_cast<int>(s.solver)},
          {"simplicialFactor", s.simplicialFactor},
          {"cgMaxIterations", s.cgMaxIterations},
          {"cgTolerance", s.cgTolerance},
          {"maxRetries", s.maxRetries},
          {"method", static_cast<int>(s.method)},
          {"attachments", static_cast<int>(s.attachments)},
          {"gaussSeidelIterations", s.gaussSeidelIterations},
          {"gaussSeidelTolerance", s.gaussSeidelTolerance},
          {"reportEnergy", s.reportEnergy},
          {"refreshResidual", s.refreshResidual},
          {"factorRefresh", static_cast<int>(s.factorRefresh)}};
}
simcore::SimulationSettings settings(const json& j) {
  simcore::SimulationSettings s;
  s.timeStep = j.at("timeStep");
  s.gravity = vec(j.at("gravity"));
  s.rayleighMass = j.at("rayleighMass");
  s.rayleighStiffness = j.at("rayleighStiffness");
  s.maxNewtonIterations = j.at("maxNewtonIterations");
  s.tolerance = j.at("tolerance");
  s.staticStepTolerance = j.at("staticStepTolerance");
  s.staticChord = j.at("staticChord");
  s.lineSearch = j.at("lineSearch");
  s.solver = static_cast<simcore::LinearSolverKind>(j.at("solver").get<int>());
  s.simplicialFactor = j.at("simplicialFactor");
  s.cgMaxIterations = j.at("cgMaxIterations");
  s.cgTolerance = j.at("cgTolerance");
  s.maxRetries = j.at("maxRetries");
  s.method = static_cast<simcore::NewtonMethod>(j.at("method").get<int>());
  s.attachments = static_cast<simcore::AttachmentMode>(j.at("attachments").get<int>());
  s.gaussSeidelIterations = j.at("gaussSeidelIterations");
  s.gaussSeidelTolerance = j.at("gaussSeidelTolerance");
  s.reportEnergy = j.at("reportEnergy");
  s.refreshResidual = j.at("refreshResidual");
  s.factorRefresh = static_cast<simcore::FactorRefresh>(j.at("factorRefresh").get<int>());
  return s;
}

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

// One prepared statement, finalised on every path.
struct Statement {
  sqlite3_stmt* s = nullptr;
  Statement(sqlite3* db, const char* sql) {
    if (sqlite3_prepare_v2(db, sql, -1, &s, nullptr) != SQLITE_OK) throw std::runtime_error(std::string("the recording store cannot be read: ") + sqlite3_errmsg(db));
  }
  ~Statement() { sqlite3_finalize(s); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  void text(int i, const std::string& v) { sqlite3_bind_text(s, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT); }
  std::string column(int i) const {
    const auto* t = sqlite3_column_text(s, i);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
};

constexpr const char* kSchema =
    "CREATE TABLE IF NOT EXISTS rehearsal_sessions(id INTEGER PRIMARY KEY AUTOINCREMENT, trainee TEXT, started_utc TEXT, case_name TEXT, "
    "scene_version TEXT, app_version TEXT, notes TEXT, setup TEXT NOT NULL, time_step REAL, checksum_every INTEGER, steps INTEGER DEFAULT 0, "
    "complete INTEGER DEFAULT 0);"
    "CREATE TABLE IF NOT EXISTS rehearsal_events(session INTEGER NOT NULL, seq INTEGER NOT NULL, step INTEGER NOT NULL, event TEXT NOT NULL, "
    "PRIMARY KEY(session, seq));"
    "CREATE TABLE IF NOT EXISTS rehearsal_checksums(session INTEGER NOT NULL, step INTEGER NOT NULL, checksum TEXT NOT NULL, PRIMARY KEY(session, step));";

sqlite3* openStore(const std::string& path, bool create) {
  sqlite3* db = nullptr;
  const int flags = create ? SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE : SQLITE_OPEN_READONLY;
  if (sqlite3_open_v2(path.c_str(), &db, flags, nullptr) != SQLITE_OK) {
    const std::string why = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    throw std::runtime_error("cannot open " + path + " for recordings: " + why);
  }
  sqlite3_busy_timeout(db, 5000);
  return db;
}

bool hasTable(sqlite3* db, const char* name) {
  Statement q(db, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?");
  q.text(1, name);
  return sqlite3_step(q.s) == SQLITE_ROW;
}

}  // namespace

std::uint64_t stateChecksum(const simcore::SimulationState& s) {
  std::uint64_t h = 14695981039346656037ULL;
  h = fnv(h, s.x.data(), sizeof(double) * static_cast<std::size_t>(s.x.size()));
  h = fnv(h, s.v.data(), sizeof(double) * static_cast<std::size_t>(s.v.size()));
  return fnv(h, &s.time, sizeof s.time);
}

std::string encodeSetup(const simcore::BodySetup& s) {
  if (!s.cut.sweeps.empty() || !s.cut.nodes.empty() || !s.cut.pendingFaces.empty())
    throw std::runtime_error("a recording starts from a body without a cut in progress");
  json j;
  json pts = json::array(), tets = json::array(), tris = json::array(), names = json::array();
  for (const auto& p : s.mesh.points) pts.push_back(vec(p));
  for (const auto& t : s.mesh.tets) tets.push_back(t);
  for (const auto& t : s.mesh.triangles) tris.push_back(t);
  for (const auto& [label, name] : s.mesh.labelNames) names.push_back({label, name});
  j["mesh"] = {{"points", pts}, {"tets", tets}, {"tetLabels", s.mesh.tetLabels}, {"triangles", tris}, {"triangleLabels", s.mesh.triangleLabels},
               {"labelNames", names}, {"unitToMetre", s.mesh.unitToMetre}};
  json rest = json::array();
  for (const auto& p : s.rest) rest.push_back(vec(p));
  j["rest"] = rest;
  j["fixedNodes"] = s.fixedNodes;
  j["material"] = material(s.material);
  json byLabel = json::array();
  for (const auto& [label, m] : s.byLabel) byLabel.push_back({{"label", label}, {"material", material(m)}});
  j["byLabel"] = byLabel;
  j["settings"] = settings(s.settings);
  const auto& t = s.tools;
  j["tools"] = {{"graspRadius", t.graspRadius}, {"maxGraspForce", t.maxGraspForce}, {"bladeLength", t.bladeLength}, {"toolRadius", t.toolRadius},
                {"cut", {{"snap", t.cut.snap}, {"minQuality", t.cut.minQuality}, {"minVolumeFraction", t.cut.minVolumeFraction}, {"snapFront", t.cut.snapFront}}}};
  if (t.trocar) j["tools"]["trocar"] = vec(*t.trocar);
  j["topology"] = s.topology;
  j["format"] = "rehearse-setup-1";
  return j.dump();
}

simcore::BodySetup decodeSetup(const std::string& text) {
  try {
    const json j = json::parse(text);
    if (j.value("format", "") != "rehearse-setup-1") throw std::runtime_error("unknown format");
    simcore::BodySetup s;
    const auto& m = j.at("mesh");
    for (const auto& p : m.at("points")) s.mesh.points.push_back(vec(p));
    for (const auto& t : m.at("tets")) s.mesh.tets.push_back(t.get<std::array<int, 4>>());
    s.mesh.tetLabels = m.at("tetLabels").get<std::vector<int>>();
    for (const auto& t : m.at("triangles")) s.mesh.triangles.push_back(t.get<std::array<int, 3>>());
    s.mesh.triangleLabels = m.at("triangleLabels").get<std::vector<int>>();
    for (const auto& n : m.at("labelNames")) s.mesh.labelNames.emplace_back(n.at(0).get<int>(), n.at(1).get<std::string>());
    s.mesh.unitToMetre = m.at("unitToMetre");
    for (const auto& p : j.at("rest")) s.rest.push_back(vec(p));
    s.fixedNodes = j.at("fixedNodes").get<std::vector<int>>();
    s.material = material(j.at("material"));
    for (const auto& b : j.at("byLabel")) s.byLabel[b.at("label").get<int>()] = material(b.at("material"));
    s.settings = settings(j.at("settings"));
    const auto& t = j.at("tools");
    s.tools.graspRadius = t.at("graspRadius");
    s.tools.maxGraspForce = t.at("maxGraspForce");
    s.tools.bladeLength = t.at("bladeLength");
    s.tools.toolRadius = t.at("toolRadius");
    s.tools.cut.snap = t.at("cut").at("snap");
    s.tools.cut.minQuality = t.at("cut").at("minQuality");
    s.tools.cut.minVolumeFraction = t.at("cut").at("minVolumeFraction");
    s.tools.cut.snapFront = t.at("cut").at("snapFront");
    if (t.contains("trocar")) s.tools.trocar = vec(t.at("trocar"));
    s.topology = j.at("topology");
    return s;
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("the recorded setup cannot be read (") + e.what() + ")");
  }
}

std::string encodeEvent(const simcore::InputEvent& e) {
  return json{{"kind", static_cast<int>(e.kind)}, {"wallTime", e.wallTime}, {"step", e.step}, {"tool", e.tool}, {"label", e.label},
              {"position", vec(e.position)}, {"vector", vec(e.vector)}, {"on", e.on}, {"name", e.name}, {"value", e.value}}
      .dump();
}

simcore::InputEvent decodeEvent(const std::string& text) {
  try {
    const json j = json::parse(text);
    simcore::InputEvent e;
    e.kind = static_cast<simcore::InputKind>(j.at("kind").get<int>());
    e.wallTime = j.at("wallTime");
    e.step = j.at("step");
    e.tool = j.at("tool");
    e.label = j.at("label");
    e.position = vec(j.at("position"));
    e.vector = vec(j.at("vector"));
    e.on = j.at("on");
    e.name = j.at("name");
    e.value = j.at("value");
    return e;
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("a recorded event cannot be read (") + e.what() + ")");
  }
}

struct Recorder::Statements {
  Statement event, checksum, steps;
  explicit Statements(sqlite3* db)
      : event(db, "INSERT INTO rehearsal_events(session, seq, step, event) VALUES(?, ?, ?, ?)"),
        checksum(db, "INSERT OR REPLACE INTO rehearsal_checksums(session, step, checksum) VALUES(?, ?, ?)"),
        steps(db, "UPDATE rehearsal_sessions SET steps = ? WHERE id = ?") {}
};

Recorder::Recorder(const std::string& path, const SessionMeta& meta, const simcore::BodySetup& setup, int checksumEvery)
    : every_(std::max(1, checksumEvery)), lastCommit_(std::chrono::steady_clock::now()) {
  const std::string setupText = encodeSetup(setup);
  db_ = openStore(path, true);
  try {
    exec("PRAGMA journal_mode=WAL");
    exec("PRAGMA synchronous=NORMAL");
    exec(kSchema);
    exec("BEGIN");
    Statement q(db_, "INSERT INTO rehearsal_sessions(trainee, started_utc, case_name, scene_version, app_version, notes, setup, time_step, checksum_every) "
                     "VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?)");
    q.text(1, meta.trainee);
    q.text(2, utcNow());
    q.text(3, meta.caseName);
    q.text(4, meta.sceneVersion);
    q.text(5, meta.appVersion);
    q.text(6, meta.notes);
    q.text(7, setupText);
    sqlite3_bind_double(q.s, 8, setup.settings.timeStep);
    sqlite3_bind_int(q.s, 9, every_);
    if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("cannot record into ") + path + ": " + sqlite3_errmsg(db_));
    id_ = sqlite3_last_insert_rowid(db_);
    commitIfDue(true);  // the session is listed from the start
    statements_ = std::make_unique<Statements>(db_);
  } catch (...) {
    statements_.reset();
    sqlite3_close(db_);
    throw;
  }
}

Recorder::~Recorder() {
  if (!db_) return;
  try {
    commitIfDue(true);
  } catch (...) {
  }
  sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr);
  statements_.reset();  // finalised before the connection closes
  sqlite3_close(db_);
}

void Recorder::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string why = err ? err : "unknown error";
    sqlite3_free(err);
    throw std::runtime_error("the recording store refused a write: " + why);
  }
}

void Recorder::commitIfDue(bool force) {
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - lastCommit_ < std::chrono::milliseconds(500)) return;
  exec("COMMIT");
  exec("BEGIN");
  lastCommit_ = now;
}

void Recorder::afterStep(long step, const std::vector<simcore::InputEvent>& recorded, const simcore::SimulationState& state) {
  if (recorded.size() > written_) {
    Statement& q = statements_->event;
    for (; written_ < recorded.size(); ++written_) {
      sqlite3_reset(q.s);
      sqlite3_bind_int64(q.s, 1, id_);
      sqlite3_bind_int64(q.s, 2, static_cast<sqlite3_int64>(written_));
      sqlite3_bind_int64(q.s, 3, recorded[written_].step);
      q.text(4, encodeEvent(recorded[written_]));
      if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused an event: ") + sqlite3_errmsg(db_));
    }
  }
  if (step % every_ == 0) {
    Statement& q = statements_->checksum;
    sqlite3_reset(q.s);
    sqlite3_bind_int64(q.s, 1, id_);
    sqlite3_bind_int64(q.s, 2, step);
    q.text(3, std::to_string(stateChecksum(state)));
    if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a checksum: ") + sqlite3_errmsg(db_));
  }
  {
    Statement& q = statements_->steps;
    sqlite3_reset(q.s);
    sqlite3_bind_int64(q.s, 1, step);
    sqlite3_bind_int64(q.s, 2, id_);
    if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a step: ") + sqlite3_errmsg(db_));
  }
  commitIfDue(false);
}

void Recorder::finish(long steps) {
  Statement q(db_, "UPDATE rehearsal_sessions SET steps = ?, complete = 1 WHERE id = ?");
  sqlite3_bind_int64(q.s, 1, steps);
  sqlite3_bind_int64(q.s, 2, id_);
  if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused the session's end: ") + sqlite3_errmsg(db_));
  commitIfDue(true);
}

std::vector<RecordingSummary> listRecordings(const std::string& path) {
  sqlite3* db = openStore(path, false);
  std::vector<RecordingSummary> out;
  try {
    if (hasTable(db, "rehearsal_sessions")) {
      Statement q(db, "SELECT id, trainee, started_utc, case_name, scene_version, app_version, notes, steps, complete FROM rehearsal_sessions ORDER BY id");
      int rc;
      while ((rc = sqlite3_step(q.s)) == SQLITE_ROW) {
        RecordingSummary r;
        r.id = sqlite3_column_int64(q.s, 0);
        r.meta = {q.column(1), q.column(3), q.column(4), q.column(5), q.column(6)};
        r.startedUtc = q.column(2);
        r.steps = static_cast<long>(sqlite3_column_int64(q.s, 7));
        r.complete = sqlite3_column_int(q.s, 8) != 0;
        out.push_back(std::move(r));
      }
      if (rc != SQLITE_DONE) throw std::runtime_error(std::string("the recordings in ") + path + " cannot be read: " + sqlite3_errmsg(db));
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  return out;
}

Recording loadRecording(const std::string& path, std::int64_t id) {
  Recording r;
  bool found = false;
  for (auto& s : listRecordings(path))
    if (s.id == id) {
      r.summary = std::move(s);
      found = true;
    }
  if (!found) throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
  sqlite3* db = openStore(path, false);
  try {
    {
      Statement q(db, "SELECT setup, checksum_every FROM rehearsal_sessions WHERE id = ?");
      sqlite3_bind_int64(q.s, 1, id);
      if (sqlite3_step(q.s) != SQLITE_ROW) throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
      r.setup = decodeSetup(q.column(0));
      r.checksumEvery = sqlite3_column_int(q.s, 1);
    }
    {
      Statement q(db, "SELECT event FROM rehearsal_events WHERE session = ? ORDER BY seq");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) r.events.push_back(decodeEvent(q.column(0)));
    }
    {
      Statement q(db, "SELECT step, checksum FROM rehearsal_checksums WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) r.checksums[static_cast<long>(sqlite3_column_int64(q.s, 0))] = std::stoull(q.column(1));
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  // A session cut short: its last checksum bounds what can be verified.
  if (!r.checksums.empty()) r.summary.steps = std::max(r.summary.steps, r.checksums.rbegin()->first);
  return r;
}

int copyRecordings(const std::string& from, const std::string& to) {
  int sessions = 0;
  {
    sqlite3* src = openStore(from, false);
    const bool has = hasTable(src, "rehearsal_sessions");
    if (has) {
      Statement q(src, "SELECT COUNT(*) FROM rehearsal_sessions");
      if (sqlite3_step(q.s) == SQLITE_ROW) sessions = sqlite3_column_int(q.s, 0);
    }
    sqlite3_close(src);
    if (!has) return 0;
  }
  sqlite3* db = openStore(to, true);
  auto run = [&](const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string why = err ? err : "unknown error";
      sqlite3_free(err);
      sqlite3_close(db);
      throw std::runtime_error("the recorded sessions could not be carried into the saved case: " + why);
    }
  };
  std::string quoted;
  for (char ch : from) {
    quoted += ch;
    if (ch == '\'') quoted += '\'';
  }
  run(kSchema);
  run("ATTACH DATABASE '" + quoted + "' AS prev");
  run("BEGIN");
  run("INSERT INTO rehearsal_sessions SELECT * FROM prev.rehearsal_sessions");
  run("INSERT INTO rehearsal_events SELECT * FROM prev.rehearsal_events");
  run("INSERT INTO rehearsal_checksums SELECT * FROM prev.rehearsal_checksums");
  run("COMMIT");
  run("DETACH DATABASE prev");
  sqlite3_close(db);
  return sessions;
}

VerifyResult verifyRecording(const Recording& r) { return replayRecording(r).verify; }

ReplayResult replayRecording(const Recording& r, double forceThresholdN) {
  ReplayResult out;
  VerifyResult& v = out.verify;
  SessionMetrics& m = out.metrics;
  m.forceThresholdN = forceThresholdN;
  const long steps = r.summary.complete || r.checksums.empty() ? r.summary.steps : r.checksums.rbegin()->first;
  double time = 0;  // simulated (the time step may be edited during the session: each step's own length counts)
  bool seen = false;
  Eigen::Vector3d first = Eigen::Vector3d::Zero(), last = Eigen::Vector3d::Zero();
  double forceSum = 0;
  long forceSteps = 0;
  simcore::replaySession(r.setup, r.events, steps, [&](long step, const simcore::Session& session) {
    ++v.steps;
    if (const auto it = r.checksums.find(step); it != r.checksums.end()) {
      ++v.checked;
      if (stateChecksum(session.state()) != it->second) {
        ++v.mismatches;
        if (v.firstMismatch < 0) v.firstMismatch = step;
      }
    }
    const auto snap = session.snapshot();
    const auto& tool = snap->tool;
    if (tool.present) {
      if (!seen) first = last = tool.tip;
      m.pathLengthM += (tool.tip - last).norm();
      last = tool.tip;
      seen = true;
    }
    const double f = tool.force.norm();
    m.maxForceN = std::max(m.maxForceN, f);
    if (f > 0) {
      forceSum += f;
      ++forceSteps;
    }
    if (f > forceThresholdN) m.timeOverThresholdS += snap->time - time;
    time = snap->time;
    for (const auto& e : snap->events) {
      m.grasps += e == "grasp";
      m.slips += e == "slip";
      m.cuts += e == "cut";
      m.vesselCuts += e == "vessel cut";
    }
  });
  m.durationS = time;
  m.meanForceN = forceSteps ? forceSum / static_cast<double>(forceSteps) : 0;
  m.economy = m.pathLengthM > 0 ? (last - first).norm() / m.pathLengthM : 0;
  return out;
}

}  // namespace rehearse::app
