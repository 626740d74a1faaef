#include "rehearse/app/recording.hpp"

#include "rehearse/app/review.hpp"

#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <algorithm>
#include <cctype>
#include <set>
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
          {"factorRefresh", static_cast<int>(s.factorRefresh)},
          {"linearisedTolerance", s.linearisedTolerance},
          {"strict", s.strict},
          {"inversionGuard", s.inversionGuard}};
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
  // Sessions recorded before these existed ran without the inversion guard and the strict/inexact choice (they were strict).
  s.linearisedTolerance = j.value("linearisedTolerance", s.linearisedTolerance);
  s.strict = j.value("strict", true);
  s.inversionGuard = j.value("inversionGuard", false);
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
    "CREATE TABLE IF NOT EXISTS rehearsal_checksums(session INTEGER NOT NULL, step INTEGER NOT NULL, checksum TEXT NOT NULL, PRIMARY KEY(session, step));"
    "CREATE TABLE IF NOT EXISTS rehearsal_setups(session INTEGER NOT NULL, hash TEXT NOT NULL, setup TEXT NOT NULL, PRIMARY KEY(session, hash));"
    "CREATE TABLE IF NOT EXISTS rehearsal_checkpoints(session INTEGER NOT NULL, step INTEGER NOT NULL, setup_hash TEXT NOT NULL, state BLOB NOT NULL, "
    "PRIMARY KEY(session, step));";

// Bytes of a checkpoint's state: plain values in this machine's order (a recording replays on the build
// that made it), each array preceded by its length; reading checks every length against what is left.
struct Bytes {
  std::string b;
  template <class T>
  void pod(const T& v) {
    b.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void vec(const Eigen::VectorXd& v) {
    pod(static_cast<std::int64_t>(v.size()));
    b.append(reinterpret_cast<const char*>(v.data()), sizeof(double) * static_cast<std::size_t>(v.size()));
  }
  void v3(const Eigen::Vector3d& v) { b.append(reinterpret_cast<const char*>(v.data()), 3 * sizeof(double)); }
};
struct Reader {
  const char* p;
  const char* end;
  void need(std::size_t n) const {
    if (static_cast<std::size_t>(end - p) < n) throw std::runtime_error("a recorded checkpoint is cut short");
  }
  template <class T>
  T pod() {
    need(sizeof(T));
    T v;
    std::memcpy(&v, p, sizeof v);
    p += sizeof v;
    return v;
  }
  std::size_t count(std::size_t each) {
    const auto n = pod<std::int64_t>();
    if (n < 0 || static_cast<std::size_t>(n) > static_cast<std::size_t>(end - p) / each) throw std::runtime_error("a recorded checkpoint has a bad length");
    return static_cast<std::size_t>(n);
  }
  Eigen::VectorXd vec() {
    const std::size_t n = count(sizeof(double));
    Eigen::VectorXd v(static_cast<Eigen::Index>(n));
    std::memcpy(v.data(), p, n * sizeof(double));
    p += n * sizeof(double);
    return v;
  }
  Eigen::Vector3d v3() {
    need(3 * sizeof(double));
    Eigen::Vector3d v;
    std::memcpy(v.data(), p, 3 * sizeof(double));
    p += 3 * sizeof(double);
    return v;
  }
};
constexpr std::uint32_t kCheckpointMagic = 0x314B4352;  // "RCK1"

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

// Fields a checkpoint carries: a new one must be written too.
static_assert(sizeof(simcore::SimulationState::Lagged) == 64, "SimulationState::Lagged changed: record the new field in encodeCheckpointState");
static_assert(sizeof(simcore::ToolState) == 224, "ToolState changed: record the new field in encodeCheckpointState");

namespace {
void writeProgress(Bytes& o, const simcore::CutProgress& p) {
  o.pod(static_cast<std::int64_t>(p.pendingFaces.size()));
  for (const auto& f : p.pendingFaces)
    for (int n : f) o.pod(static_cast<std::int32_t>(n));
  o.pod(static_cast<std::int64_t>(p.nodes.size()));
  for (int n : p.nodes) o.pod(static_cast<std::int32_t>(n));
  o.pod(static_cast<std::int64_t>(p.sweeps.size()));
  for (const auto& w : p.sweeps)
    for (const auto* v : {&w.a0, &w.b0, &w.a1, &w.b1}) o.v3(*v);
}
simcore::CutProgress readProgress(Reader& r) {
  simcore::CutProgress p;
  p.pendingFaces.resize(r.count(3 * sizeof(std::int32_t)));
  for (auto& f : p.pendingFaces)
    for (int& n : f) n = r.pod<std::int32_t>();
  p.nodes.resize(r.count(sizeof(std::int32_t)));
  for (int& n : p.nodes) n = r.pod<std::int32_t>();
  p.sweeps.resize(r.count(12 * sizeof(double)));
  for (auto& w : p.sweeps)
    for (auto* v : {&w.a0, &w.b0, &w.a1, &w.b1}) *v = r.v3();
  return p;
}
}  // namespace

simcore::BodySetup sharedSetup(const simcore::BodySetup& s) {
  simcore::BodySetup o = s;
  o.cut.clear();
  return o;
}

namespace {
// The checkpoint's bytes with its setups' hashes (the recorder has them already).
std::string encodeCheckpoint(const simcore::Checkpoint& c, std::uint64_t setupHashValue, std::uint64_t pendingSetupHash) {
  Bytes o;
  o.pod(kCheckpointMagic);
  o.pod(static_cast<std::int64_t>(c.step));
  o.pod(setupHashValue);
  writeProgress(o, c.setup.cut);
  const auto& s = c.state;
  o.vec(s.x);
  o.vec(s.v);
  o.pod(s.time);
  o.pod(static_cast<std::uint8_t>(s.lagged.valid));
  o.vec(s.lagged.at);
  o.pod(s.lagged.step);
  o.pod(static_cast<std::uint8_t>(s.lagged.refresh));
  o.pod(static_cast<std::uint8_t>(s.lagged.drift));
  o.pod(static_cast<std::uint8_t>(s.lagged.requested));
  o.vec(s.lagged.requestedAt);
  o.pod(s.lagged.requestedStep);
  o.vec(s.forces);
  o.pod(static_cast<std::uint8_t>(s.forcesValid));
  const auto& t = c.tool;
  o.v3(t.tip);
  o.pod(static_cast<std::uint8_t>(t.jawClosed));
  o.pod(static_cast<std::int64_t>(t.held.size()));
  for (int n : t.held) o.pod(static_cast<std::int32_t>(n));
  o.pod(static_cast<std::int64_t>(t.heldOffset.size()));
  for (const auto& v : t.heldOffset) o.v3(v);
  o.pod(static_cast<std::uint8_t>(t.cutting));
  o.v3(t.cutFrom);
  o.v3(t.force);
  o.b.append(reinterpret_cast<const char*>(t.stiffness.data()), 9 * sizeof(double));
  o.pod(static_cast<std::uint8_t>(t.present));
  o.pod(static_cast<std::int32_t>(t.contacts));
  o.pod(static_cast<std::int32_t>(t.pierced));
  o.pod(static_cast<std::uint8_t>(c.restOfSweep.has_value()));
  if (c.restOfSweep) {
    o.v3(c.restOfSweep->first);
    o.v3(c.restOfSweep->second);
  }
  o.pod(static_cast<std::uint8_t>(c.pendingCut.has_value()));
  if (const auto& p = c.pendingCut) {
    o.pod(pendingSetupHash);
    writeProgress(o, p->setup.cut);
    o.pod(static_cast<std::int64_t>(p->newNodes.size()));
    for (const auto& n : p->newNodes) {
      for (int f : n.from) o.pod(static_cast<std::int32_t>(f));
      for (double w : n.weight) o.pod(w);
    }
    o.pod(static_cast<std::int64_t>(p->cutLabels.size()));
    for (int l : p->cutLabels) o.pod(static_cast<std::int32_t>(l));
    o.vec(p->factorAt);
    o.pod(static_cast<std::uint8_t>(p->clearProgress));
  }
  return o.b;
}
}  // namespace

std::string encodeCheckpointState(const simcore::Checkpoint& c) {
  return encodeCheckpoint(c, setupHash(c.setup), c.pendingCut ? setupHash(c.pendingCut->setup) : 0);
}

simcore::Checkpoint decodeCheckpointState(const std::string& bytes, const std::function<simcore::BodySetup(std::uint64_t)>& setupOf) {
  simcore::Checkpoint c;
  Reader r{bytes.data(), bytes.data() + bytes.size()};
  if (r.pod<std::uint32_t>() != kCheckpointMagic) throw std::runtime_error("a recorded checkpoint is not in a known format");
  c.step = static_cast<long>(r.pod<std::int64_t>());
  c.setup = setupOf(r.pod<std::uint64_t>());
  c.setup.cut = readProgress(r);
  auto& s = c.state;
  s.x = r.vec();
  s.v = r.vec();
  s.time = r.pod<double>();
  s.lagged.valid = r.pod<std::uint8_t>() != 0;
  s.lagged.at = r.vec();
  s.lagged.step = r.pod<double>();
  s.lagged.refresh = r.pod<std::uint8_t>() != 0;
  s.lagged.drift = r.pod<std::uint8_t>() != 0;
  s.lagged.requested = r.pod<std::uint8_t>() != 0;
  s.lagged.requestedAt = r.vec();
  s.lagged.requestedStep = r.pod<double>();
  s.forces = r.vec();
  s.forcesValid = r.pod<std::uint8_t>() != 0;
  auto& t = c.tool;
  t.tip = r.v3();
  t.jawClosed = r.pod<std::uint8_t>() != 0;
  t.held.resize(r.count(sizeof(std::int32_t)));
  for (auto& n : t.held) n = r.pod<std::int32_t>();
  t.heldOffset.resize(r.count(3 * sizeof(double)));
  for (auto& v : t.heldOffset) v = r.v3();
  t.cutting = r.pod<std::uint8_t>() != 0;
  t.cutFrom = r.v3();
  t.force = r.v3();
  r.need(9 * sizeof(double));
  std::memcpy(t.stiffness.data(), r.p, 9 * sizeof(double));
  r.p += 9 * sizeof(double);
  t.present = r.pod<std::uint8_t>() != 0;
  t.contacts = r.pod<std::int32_t>();
  t.pierced = r.pod<std::int32_t>();
  if (r.pod<std::uint8_t>()) {
    const Eigen::Vector3d from = r.v3();
    c.restOfSweep = std::make_pair(from, r.v3());
  }
  if (r.pod<std::uint8_t>()) {
    simcore::PendingCutInput p;
    p.setup = setupOf(r.pod<std::uint64_t>());
    p.setup.cut = readProgress(r);
    p.newNodes.resize(r.count(4 * sizeof(std::int32_t) + 4 * sizeof(double)));
    for (auto& n : p.newNodes) {
      for (int& f : n.from) f = r.pod<std::int32_t>();
      for (double& w : n.weight) w = r.pod<double>();
    }
    p.cutLabels.resize(r.count(sizeof(std::int32_t)));
    for (int& l : p.cutLabels) l = r.pod<std::int32_t>();
    p.factorAt = r.vec();
    p.clearProgress = r.pod<std::uint8_t>() != 0;
    c.pendingCut = std::move(p);
  }
  if (r.p != r.end) throw std::runtime_error("a recorded checkpoint has trailing bytes");
  if (s.v.size() != s.x.size() || (s.forcesValid && s.forces.size() != s.x.size()) || (s.lagged.valid && s.lagged.at.size() != s.x.size()) ||
      (s.lagged.requested && s.lagged.requestedAt.size() != s.x.size()))
    throw std::runtime_error("a recorded checkpoint's vectors disagree in size");
  // Node indices within the body (a damaged file must not reach the simulation as indices out of range).
  const std::size_t n = c.setup.rest.empty() ? c.setup.mesh.points.size() : c.setup.rest.size();
  if (static_cast<std::size_t>(s.x.size()) != 3 * n) throw std::runtime_error("a recorded checkpoint does not fit its body's nodes");
  auto inRange = [n](int i) { return i >= 0 && static_cast<std::size_t>(i) < n; };
  bool ok = t.heldOffset.size() == t.held.size() && std::all_of(t.held.begin(), t.held.end(), inRange) &&
            std::all_of(c.setup.cut.nodes.begin(), c.setup.cut.nodes.end(), inRange);
  for (const auto& f : c.setup.cut.pendingFaces) ok = ok && std::all_of(f.begin(), f.end(), inRange);
  if (!ok || !s.x.allFinite() || !s.v.allFinite()) throw std::runtime_error("a recorded checkpoint names nodes its body has not, or holds no number");
  return c;
}

std::uint64_t setupHash(const simcore::BodySetup& s) {
  std::uint64_t h = 14695981039346656037ULL;
  auto arr = [&h](const auto& v) {
    const std::size_t n = v.size();
    h = fnv(h, &n, sizeof n);
    if (n) h = fnv(h, v.data(), n * sizeof(v[0]));
  };
  arr(s.mesh.points);
  arr(s.mesh.tets);
  arr(s.mesh.tetLabels);
  arr(s.mesh.triangles);
  arr(s.mesh.triangleLabels);
  arr(s.rest);
  arr(s.fixedNodes);
  // The small rest through its text (materials, settings, tools, topology).
  simcore::BodySetup light;
  light.material = s.material;
  light.byLabel = s.byLabel;
  light.settings = s.settings;
  light.tools = s.tools;
  light.topology = s.topology;
  light.mesh.unitToMetre = s.mesh.unitToMetre;
  light.mesh.labelNames = s.mesh.labelNames;
  const std::string text = encodeSetup(light);
  return fnv(h, text.data(), text.size());
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
  Statement event, checksum, steps, setup, checkpoint;
  explicit Statements(sqlite3* db)
      : event(db, "INSERT INTO rehearsal_events(session, seq, step, event) VALUES(?, ?, ?, ?)"),
        checksum(db, "INSERT OR REPLACE INTO rehearsal_checksums(session, step, checksum) VALUES(?, ?, ?)"),
        steps(db, "UPDATE rehearsal_sessions SET steps = ? WHERE id = ?"),
        setup(db, "INSERT OR IGNORE INTO rehearsal_setups(session, hash, setup) VALUES(?, ?, ?)"),
        checkpoint(db, "INSERT OR REPLACE INTO rehearsal_checkpoints(session, step, setup_hash, state) VALUES(?, ?, ?, ?)") {}
};

Recorder::Recorder(const std::string& path, const SessionMeta& meta, const simcore::BodySetup& setup, int checksumEvery, int checkpointEvery)
    : every_(std::max(1, checksumEvery)), checkpointEvery_(std::max(1, checkpointEvery)), lastCommit_(std::chrono::steady_clock::now()) {
  path_ = path;
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

std::string Recorder::path() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return path_;
}

void Recorder::reopen(const std::string& path) {
  std::lock_guard<std::mutex> lock(mutex_);
  // The old file was replaced: what it still holds uncommitted goes with it.
  sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr);
  statements_.reset();
  sqlite3_close(db_);
  db_ = openStore(path, true);
  path_ = path;
  exec("PRAGMA journal_mode=WAL");
  exec("PRAGMA synchronous=NORMAL");
  exec(kSchema);
  {
    Statement q(db_, "SELECT COUNT(*) FROM rehearsal_events WHERE session = ?");
    sqlite3_bind_int64(q.s, 1, id_);
    long copied = sqlite3_step(q.s) == SQLITE_ROW ? static_cast<long>(sqlite3_column_int64(q.s, 0)) : 0;
    Statement s(db_, "SELECT 1 FROM rehearsal_sessions WHERE id = ?");
    sqlite3_bind_int64(s.s, 1, id_);
    if (sqlite3_step(s.s) != SQLITE_ROW) throw std::runtime_error("the saved case " + path + " lost the recorded session " + std::to_string(id_));
    written_ = std::min(written_, static_cast<std::size_t>(copied));  // events are written in order: the copy holds a prefix
  }
  statements_ = std::make_unique<Statements>(db_);
  exec("BEGIN");
  for (const auto& [step, sum] : checksumsWritten_) {
    Statement& q = statements_->checksum;
    sqlite3_reset(q.s);
    sqlite3_bind_int64(q.s, 1, id_);
    sqlite3_bind_int64(q.s, 2, step);
    q.text(3, std::to_string(sum));
    if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a checksum: ") + sqlite3_errmsg(db_));
  }
  setupsWritten_.clear();  // a checkpoint after this one writes its setup again when the copy missed it (INSERT OR IGNORE)
  if (finished_) {
    Statement q(db_, "UPDATE rehearsal_sessions SET steps = ?, complete = 1 WHERE id = ?");
    sqlite3_bind_int64(q.s, 1, lastStep_);
    sqlite3_bind_int64(q.s, 2, id_);
    sqlite3_step(q.s);
  }
  commitIfDue(true);
}

void Recorder::afterStep(long step, const std::vector<simcore::InputEvent>& recorded, const simcore::SimulationState& state) {
  std::lock_guard<std::mutex> lock(mutex_);
  afterStepLocked(step, recorded, state);
}

void Recorder::afterStepLocked(long step, const std::vector<simcore::InputEvent>& recorded, const simcore::SimulationState& state) {
  lastStep_ = step;
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
    const std::uint64_t sum = stateChecksum(state);
    Statement& q = statements_->checksum;
    sqlite3_reset(q.s);
    sqlite3_bind_int64(q.s, 1, id_);
    sqlite3_bind_int64(q.s, 2, step);
    q.text(3, std::to_string(sum));
    if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a checksum: ") + sqlite3_errmsg(db_));
    checksumsWritten_.emplace_back(step, sum);
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

void Recorder::afterStep(const simcore::StepRecord& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  afterStepLocked(r.step, *r.recorded, *r.state);
  // Every `checkpointEvery` steps, and just after the body changed (a cut applied: seeking past it then starts
  // after it instead of building the cut body again).
  bool changed = false;
  for (const auto& e : r.snapshot->events) changed |= e == "cut";
  if (r.step - lastCheckpoint_ >= checkpointEvery_ || changed) {
    const simcore::Checkpoint c = r.checkpoint();
    auto store = [this](const simcore::BodySetup& s) {
      const std::uint64_t h = setupHash(s);  // the mesh is copied and encoded only for a setup not written yet
      if (std::find(setupsWritten_.begin(), setupsWritten_.end(), h) != setupsWritten_.end()) return h;
      Statement& q = statements_->setup;
      sqlite3_reset(q.s);
      sqlite3_bind_int64(q.s, 1, id_);
      q.text(2, std::to_string(h));
      q.text(3, encodeSetup(sharedSetup(s)));
      if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a setup: ") + sqlite3_errmsg(db_));
      setupsWritten_.push_back(h);
      return h;
    };
    const std::uint64_t h = store(c.setup);
    const std::uint64_t pending = c.pendingCut ? store(c.pendingCut->setup) : 0;
    const std::string bytes = encodeCheckpoint(c, h, pending);
    Statement& q = statements_->checkpoint;
    sqlite3_reset(q.s);
    sqlite3_bind_int64(q.s, 1, id_);
    sqlite3_bind_int64(q.s, 2, r.step);
    q.text(3, std::to_string(h));
    sqlite3_bind_blob(q.s, 4, bytes.data(), static_cast<int>(bytes.size()), SQLITE_TRANSIENT);
    if (sqlite3_step(q.s) != SQLITE_DONE) throw std::runtime_error(std::string("the recording store refused a checkpoint: ") + sqlite3_errmsg(db_));
    lastCheckpoint_ = r.step;
    ++checkpoints_;
  }
}

void Recorder::finish(long steps) {
  std::lock_guard<std::mutex> lock(mutex_);
  finished_ = true;
  lastStep_ = steps;
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
    if (hasTable(db, "rehearsal_checkpoints")) {
      Statement q(db, "SELECT step FROM rehearsal_checkpoints WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) r.checkpointSteps.push_back(static_cast<long>(sqlite3_column_int64(q.s, 0)));
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  // A session cut short: its last checksum bounds what can be verified.
  if (!r.checksums.empty()) r.summary.steps = std::max(r.summary.steps, r.checksums.rbegin()->first);
  r.path = path;
  return r;
}

RecordingRows loadRecordingRows(const std::string& path, std::int64_t id) {
  RecordingRows rows;
  sqlite3* db = openStore(path, false);
  try {
    {
      Statement q(db, "SELECT setup FROM rehearsal_sessions WHERE id = ?");
      sqlite3_bind_int64(q.s, 1, id);
      if (sqlite3_step(q.s) != SQLITE_ROW) throw std::runtime_error(path + " has no recorded session " + std::to_string(id));
      rows.setup = q.column(0);
    }
    {
      Statement q(db, "SELECT seq, step, event FROM rehearsal_events WHERE session = ? ORDER BY seq");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW)
        rows.events.emplace_back(static_cast<long>(sqlite3_column_int64(q.s, 0)), static_cast<long>(sqlite3_column_int64(q.s, 1)), q.column(2));
    }
    {
      Statement q(db, "SELECT step, checksum FROM rehearsal_checksums WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) rows.checksums.emplace_back(static_cast<long>(sqlite3_column_int64(q.s, 0)), q.column(1));
    }
    if (hasTable(db, "rehearsal_setups")) {
      Statement q(db, "SELECT hash, setup FROM rehearsal_setups WHERE session = ?");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) rows.setups.emplace_back(q.column(0), q.column(1));
    }
    if (hasTable(db, "rehearsal_checkpoints")) {
      Statement q(db, "SELECT step, setup_hash, state FROM rehearsal_checkpoints WHERE session = ? ORDER BY step");
      sqlite3_bind_int64(q.s, 1, id);
      while (sqlite3_step(q.s) == SQLITE_ROW) {
        RecordingRows::CheckpointRow c;
        c.step = static_cast<long>(sqlite3_column_int64(q.s, 0));
        c.setupHash = q.column(1);
        const auto* blob = static_cast<const char*>(sqlite3_column_blob(q.s, 2));
        c.state.assign(blob ? blob : "", static_cast<std::size_t>(sqlite3_column_bytes(q.s, 2)));
        rows.checkpoints.push_back(std::move(c));
      }
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  return rows;
}

simcore::Checkpoint loadCheckpoint(const std::string& path, std::int64_t id, long step) {
  sqlite3* db = openStore(path, false);
  simcore::Checkpoint c;
  try {
    std::string bytes;
    {
      Statement q(db, "SELECT state FROM rehearsal_checkpoints WHERE session = ? AND step = ?");
      sqlite3_bind_int64(q.s, 1, id);
      sqlite3_bind_int64(q.s, 2, step);
      if (sqlite3_step(q.s) != SQLITE_ROW)
        throw std::runtime_error(path + " has no checkpoint at step " + std::to_string(step) + " of session " + std::to_string(id));
      const auto* blob = static_cast<const char*>(sqlite3_column_blob(q.s, 0));
      bytes.assign(blob ? blob : "", static_cast<std::size_t>(sqlite3_column_bytes(q.s, 0)));
    }
    c = decodeCheckpointState(bytes, [&](std::uint64_t hash) {
      Statement q(db, "SELECT setup FROM rehearsal_setups WHERE session = ? AND hash = ?");
      sqlite3_bind_int64(q.s, 1, id);
      q.text(2, std::to_string(hash));
      if (sqlite3_step(q.s) != SQLITE_ROW)
        throw std::runtime_error(path + ": the checkpoint at step " + std::to_string(step) + " names a setup that is missing");
      return decodeSetup(q.column(0));
    });
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  if (c.step != step) throw std::runtime_error(path + ": the checkpoint at step " + std::to_string(step) + " holds another step");
  return c;
}

Replayer::Replayer(Recording r) : rec_(std::move(r)) {
  steps_ = rec_.summary.complete || rec_.checksums.empty() ? rec_.summary.steps : rec_.checksums.rbegin()->first;
  startAt(nullptr);
  start_ = session_->checkpoint();
}

Replayer::~Replayer() = default;

long Replayer::step() const { return session_->snapshot()->step; }

void Replayer::startAt(const simcore::Checkpoint* c) {
  if (!c) {
    session_ = std::make_unique<simcore::Session>(simcore::replaySetup(rec_.setup));
  } else {
    simcore::Checkpoint d = *c;
    d.setup = simcore::replaySetup(std::move(d.setup));
    if (d.pendingCut) d.pendingCut->setup = simcore::replaySetup(std::move(d.pendingCut->setup));
    session_->discardPending();
    session_->restore(d);
  }
  const long from = c ? c->step : 0;
  for (const auto& e : rec_.events)
    if (e.step >= from) session_->post(e);
}

void Replayer::seek(long target) {
  target = std::clamp(target, 0L, steps_);
  const long now = step();
  long best = 0;  // the nearest checkpoint at or before the target (0: the start)
  for (long s : rec_.checkpointSteps)
    if (s <= target && s > best) best = s;
  if (now <= target && now >= best) {
    lastSeekFrom_ = -1;  // onwards from here
  } else if (best > 0) {
    auto it = cache_.find(best);
    if (it == cache_.end())
      it = cache_.emplace(best, rec_.checkpointSource ? rec_.checkpointSource(best) : loadCheckpoint(rec_.path, rec_.summary.id, best)).first;
    startAt(&it->second);
    lastSeekFrom_ = best;
  } else {
    startAt(&start_);
    lastSeekFrom_ = 0;
  }
  while (step() < target) session_->advance();
}

void Replayer::advance() {
  if (step() < steps_) session_->advance();
}

std::shared_ptr<const simcore::Snapshot> Replayer::snapshot() const { return session_->snapshot(); }
simcore::SimulationState Replayer::state() const { return session_->state(); }

std::string loadCaseThresholds(const std::string& path) {
  sqlite3* db = openStore(path, false);
  std::string out;
  if (hasTable(db, "rehearsal_thresholds")) {
    Statement q(db, "SELECT json FROM rehearsal_thresholds WHERE id = 1");
    if (sqlite3_step(q.s) == SQLITE_ROW) out = q.column(0);
  }
  sqlite3_close(db);
  return out;
}

void saveCaseThresholds(const std::string& path, const std::string& json) {
  sqlite3* db = openStore(path, true);
  char* err = nullptr;
  int rc = sqlite3_exec(db, "CREATE TABLE IF NOT EXISTS rehearsal_thresholds(id INTEGER PRIMARY KEY CHECK(id = 1), json TEXT NOT NULL)", nullptr, nullptr, &err);
  if (rc == SQLITE_OK) {
    Statement q(db, "INSERT OR REPLACE INTO rehearsal_thresholds(id, json) VALUES(1, ?)");
    q.text(1, json);
    rc = sqlite3_step(q.s) == SQLITE_DONE ? SQLITE_OK : SQLITE_ERROR;
  }
  const std::string why = err ? err : sqlite3_errmsg(db);
  sqlite3_free(err);
  sqlite3_close(db);
  if (rc != SQLITE_OK) throw std::runtime_error("the thresholds could not be kept in " + path + ": " + why);
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
  {
    sqlite3* src = openStore(from, false);
    const bool has = hasTable(src, "rehearsal_checkpoints") && hasTable(src, "rehearsal_setups");
    const bool thresholds = hasTable(src, "rehearsal_thresholds");
    sqlite3_close(src);
    if (has) {
      run("INSERT INTO rehearsal_setups SELECT * FROM prev.rehearsal_setups");
      run("INSERT INTO rehearsal_checkpoints SELECT * FROM prev.rehearsal_checkpoints");
    }
    if (thresholds) {
      run("CREATE TABLE IF NOT EXISTS rehearsal_thresholds(id INTEGER PRIMARY KEY CHECK(id = 1), json TEXT NOT NULL)");
      run("INSERT OR REPLACE INTO rehearsal_thresholds SELECT * FROM prev.rehearsal_thresholds");
    }
  }
  run("COMMIT");
  run("DETACH DATABASE prev");
  sqlite3_close(db);
  return sessions;
}

VerifyResult verifyRecording(const Recording& r) { return replayRecording(r).verify; }

ReplayResult replayRecording(const Recording& r, double forceThresholdN) {
  ReplayOptions o;
  o.forceThresholdN = forceThresholdN;
  return replayRecording(r, o);
}

namespace {
double distanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double len2 = d.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * d)).norm();
}
}  // namespace

ReplayResult replayRecording(const Recording& r, const ReplayOptions& options) {
  const double forceThresholdN = options.forceThresholdN;
  ReplayResult out;
  VerifyResult& v = out.verify;
  SessionMetrics& m = out.metrics;
  m.forceThresholdN = forceThresholdN;
  // What this session cannot say, in words.
  int tumourLabel = 0;
  for (const auto& [label, name] : r.setup.mesh.labelNames) {
    std::string lower = name;
    for (auto& ch : lower) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (lower.find("tumour") != std::string::npos || lower.find("tumor") != std::string::npos) tumourLabel = label;
  }
  if (tumourLabel) m.tumourBreaches = 0;
  else m.tumourWhy = "the case marks no tumour (no element label named tumour)";
  m.attachmentsWhy = "the model's attachments cannot tear (they are fixed nodes)";
  if (!options.plannedCut) m.cutDeviationWhy = "the case has no planned cut line";
  double deviationSum = 0;
  long cuttingSteps = 0;
  std::vector<Eigen::Vector3d> rest = r.setup.rest.empty() ? r.setup.mesh.points : r.setup.rest;
  bool wasCutting = false;
  double previousForce = 0;
  Eigen::Vector3d lastCut = Eigen::Vector3d::Zero();
  const long steps = r.summary.complete || r.checksums.empty() ? r.summary.steps : r.checksums.rbegin()->first;
  double time = 0;  // simulated (the time step may be edited during the session: each step's own length counts)
  bool seen = false;
  Eigen::Vector3d first = Eigen::Vector3d::Zero(), last = Eigen::Vector3d::Zero();
  double forceSum = 0;
  long forceSteps = 0;
  // An instrument swapped for another (grasper -> hook): the tip's jump between them is not a path travelled.
  std::set<long> swapped;  // steps whose snapshot shows the new instrument's first pose
  double straight = 0;     // the straight distances of the instruments swapped out
  {
    int lastTool = -1;
    for (const auto& e : r.events)
      if (e.kind == simcore::InputKind::ToolPose) {
        if (lastTool >= 0 && e.tool != lastTool) swapped.insert(e.step + 1);
        lastTool = e.tool;
      }
  }
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
      if (swapped.count(step)) {  // economy per instrument: its own straight distance
        straight += (last - first).norm();
        first = last = tool.tip;
      }
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
    const bool over = f > forceThresholdN;
    if (over) m.timeOverThresholdS += snap->time - time;
    const bool overBefore = previousForce > forceThresholdN;
    previousForce = f;
    time = snap->time;
    for (const auto& e : snap->events) {
      m.grasps += e == "grasp";
      m.slips += e == "slip";
      m.cuts += e == "cut";
      m.vesselCuts += e == "vessel cut";
      if (tumourLabel && e == "cut through label " + std::to_string(tumourLabel)) ++*m.tumourBreaches;
    }
    if (tool.present && tool.cutting) {
      if (wasCutting) m.cutLengthM += (tool.tip - lastCut).norm();
      lastCut = tool.tip;
      if (options.plannedCut) {
        const double d = distanceToSegment(tool.tip, options.plannedCut->first, options.plannedCut->second);
        deviationSum += d;
        ++cuttingSteps;
        m.cutDeviationMaxM = std::max(m.cutDeviationMaxM.value_or(0.0), d);
      }
    }
    wasCutting = tool.present && tool.cutting;
    double strain = 0;
    if (options.strain) {
      const auto& restNow = snap->surface ? snap->surface->rest : rest;
      strain = snap->tets ? maxGreenStrain(restNow, snap->positions, *snap->tets) : 0;
      m.maxStrain = std::max(m.maxStrain.value_or(0.0), strain);
    }
    if (options.timeline) {
      TimelineSample t;
      t.step = step;
      t.time = snap->time;
      t.toolPresent = tool.present;
      t.tip = tool.tip;
      t.force = f;
      t.strain = strain;
      t.holding = !tool.held.empty();
      t.cutting = tool.cutting;
      t.newInstrument = swapped.count(step) > 0;
      t.events = snap->events;
      if (over && !overBefore) t.events.push_back("force over threshold");
      out.timeline.push_back(std::move(t));
    }
  });
  if (options.plannedCut) {
    if (cuttingSteps) m.cutDeviationMeanM = deviationSum / static_cast<double>(cuttingSteps);
    else m.cutDeviationWhy = "the blade never cut";
  }
  m.durationS = time;
  m.meanForceN = forceSteps ? forceSum / static_cast<double>(forceSteps) : 0;
  m.economy = m.pathLengthM > 0 ? (straight + (last - first).norm()) / m.pathLengthM : 0;
  return out;
}

}  // namespace rehearse::app
