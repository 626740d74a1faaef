// The codecs of recorded rehearsals' setups and events (JSON) and their validation (checkpoints as bytes:
// recording_checkpoint.cpp): no SQLite and no simulation here, so that the fuzzers (tests/fuzz) build them alone.
#include "recording_codec.hpp"

#include "rehearse/app/recording.hpp"

#include <rehearse/simcore/input_ranges.hpp>
#include <rehearse/text_input.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <stdexcept>

namespace rehearse::app {
namespace {

using nlohmann::json;

// Why a recorded text could not be read, in words a person can act on: the JSON library's error without its
// "[json.exception...]" tag, a parse error as where it is (not the damaged bytes it read, which may not even be
// UTF-8), other bytes outside printable ASCII as '?', at most 160 characters.
std::string readableReason(const std::exception& e) {
  if (const auto* p = dynamic_cast<const json::parse_error*>(&e))
    return "its text is not valid JSON at byte " + std::to_string(p->byte);
  std::string why = e.what();
  if (why.rfind("[json.exception.", 0) == 0)
    if (const std::size_t end = why.find("] "); end != std::string::npos) why.erase(0, end + 2);
  for (char& c : why)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
  if (why.size() > 160) why = why.substr(0, 157) + "...";
  return why;
}

// A field added to these structs must be recorded too: these sizes stop the build until encodeSetup knows it.
static_assert(sizeof(simcore::MaterialParams) == 40,
              "MaterialParams changed: record the new field in encodeSetup/decodeSetup");
static_assert(sizeof(simcore::CutSettings) == 32,
              "CutSettings changed: record the new field in encodeSetup/decodeSetup");
static_assert(sizeof(simcore::ClipSettings) == 40,
              "ClipSettings changed: record the new field in encodeSetup/decodeSetup");
static_assert(sizeof(simcore::CauterySettings) == 24,
              "CauterySettings changed: record the new field in encodeSetup/decodeSetup");

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
// Integers from untrusted JSON: a float or a number out of range is refused (a cast of either is undefined).
long long asInteger(const json& j, long long lo, long long hi) {
  if (!j.is_number_integer()) throw std::runtime_error("a whole number was expected");
  if (j.is_number_unsigned() ? j.get<unsigned long long>() > static_cast<unsigned long long>(hi)
                             : (j.get<long long>() < lo || j.get<long long>() > hi))
    throw std::runtime_error("a whole number is out of range");
  return j.get<long long>();
}
int asInt(const json& j) { return static_cast<int>(asInteger(j, INT32_MIN, INT32_MAX)); }
std::vector<int> asInts(const json& j) {
  std::vector<int> out;
  out.reserve(j.size());
  for (const auto& v : j) out.push_back(asInt(v));
  return out;
}
template <std::size_t N>
std::array<int, N> asIntArray(const json& j) {
  if (!j.is_array() || j.size() != N) throw std::runtime_error("an index tuple has the wrong length");
  std::array<int, N> a;
  for (std::size_t i = 0; i < N; ++i) a[i] = asInt(j[i]);
  return a;
}

json material(const simcore::MaterialParams& m) {
  json j = {{"model", static_cast<int>(m.model)}, {"young", m.young}, {"poisson", m.poisson}, {"density", m.density}};
  if (m.tearStrain != 0) j["tearStrain"] = m.tearStrain;  // (setups recorded before it existed keep their hash)
  return j;
}
simcore::MaterialParams material(const json& j) {
  simcore::MaterialParams m;
  m.model = static_cast<simcore::MaterialModel>(asInt(j.at("model")));
  m.young = j.at("young");
  m.poisson = j.at("poisson");
  m.density = j.at("density");
  m.tearStrain = j.value("tearStrain", 0.0);
  return m;
}

json settings(const simcore::SimulationSettings& s) {
  json j = {{"timeStep", s.timeStep},
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
  // Written only when on: setups recorded before it keep their text and hash, and replay without it.
  if (s.chordAcceleration) j["chordAcceleration"] = true;
  if (s.checkedProjection) j["checkedProjection"] = true;
  if (s.heldBackStop) j["heldBackStop"] = true;
  if (s.localElimination) j["localElimination"] = true;
  if (s.volumeBarrier > 0) j["volumeBarrier"] = s.volumeBarrier;
  if (s.accuracyPosition > 0) {
    j["accuracyPosition"] = s.accuracyPosition;
    j["accuracyForce"] = s.accuracyForce;
  }
  return j;
}
simcore::SimulationSettings settings(const json& j) {
  simcore::SimulationSettings s;
  s.timeStep = j.at("timeStep");
  s.gravity = vec(j.at("gravity"));
  s.rayleighMass = j.at("rayleighMass");
  s.rayleighStiffness = j.at("rayleighStiffness");
  s.maxNewtonIterations = asInt(j.at("maxNewtonIterations"));
  s.tolerance = j.at("tolerance");
  s.staticStepTolerance = j.at("staticStepTolerance");
  s.staticChord = j.at("staticChord");
  s.lineSearch = j.at("lineSearch");
  s.solver = static_cast<simcore::LinearSolverKind>(asInt(j.at("solver")));
  s.simplicialFactor = j.at("simplicialFactor");
  s.cgMaxIterations = asInt(j.at("cgMaxIterations"));
  s.cgTolerance = j.at("cgTolerance");
  s.maxRetries = asInt(j.at("maxRetries"));
  s.method = static_cast<simcore::NewtonMethod>(asInt(j.at("method")));
  s.attachments = static_cast<simcore::AttachmentMode>(asInt(j.at("attachments")));
  s.gaussSeidelIterations = asInt(j.at("gaussSeidelIterations"));
  s.gaussSeidelTolerance = j.at("gaussSeidelTolerance");
  s.reportEnergy = j.at("reportEnergy");
  s.refreshResidual = j.at("refreshResidual");
  s.factorRefresh = static_cast<simcore::FactorRefresh>(asInt(j.at("factorRefresh")));
  // Sessions recorded before these existed ran without the inversion guard and the strict/inexact choice (they were
  // strict).
  s.linearisedTolerance = j.value("linearisedTolerance", s.linearisedTolerance);
  s.strict = j.value("strict", true);
  s.inversionGuard = j.value("inversionGuard", false);
  s.chordAcceleration = j.value("chordAcceleration", false);
  s.checkedProjection = j.value("checkedProjection", false);
  s.heldBackStop = j.value("heldBackStop", false);
  s.localElimination = j.value("localElimination", false);
  s.volumeBarrier = j.value("volumeBarrier", 0.0);  // none before it existed
  s.accuracyPosition = j.value("accuracyPosition", 0.0);  // the residual alone decided before it existed
  s.accuracyForce = j.value("accuracyForce", s.accuracyForce);
  return s;
}

}  // namespace

std::uint64_t stateChecksum(const simcore::SimulationState& s) {
  std::uint64_t h = 14695981039346656037ULL;
  h = fnv(h, s.x.data(), sizeof(double) * static_cast<std::size_t>(s.x.size()));
  h = fnv(h, s.v.data(), sizeof(double) * static_cast<std::size_t>(s.v.size()));
  return fnv(h, &s.time, sizeof s.time);
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
  if (!s.start.empty()) arr(s.start);  // (setups recorded before it existed keep their hash)
  if (!s.tearFrom.empty()) {           // (likewise)
    static constexpr char kTag[] = "tearFrom";
    h = fnv(h, kTag, sizeof kTag);
    arr(s.tearFrom);
  }
  arr(s.fixedNodes);
  // The supports field by field (a NodeAnchor has padding); none for setups recorded before they existed.
  for (const auto& a : s.supports) {
    h = fnv(h, &a.node, sizeof a.node);
    h = fnv(h, a.at.data(), 3 * sizeof(double));
    h = fnv(h, &a.stiffness, sizeof a.stiffness);
  }
  // The small rest through its text (materials, settings, tools, topology).
  simcore::BodySetup light;
  light.material = s.material;
  light.byLabel = s.byLabel;
  light.settings = s.settings;
  light.tools = s.tools;
  light.topology = s.topology;
  light.model = s.model;
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
  j["mesh"] = {{"points", pts},
               {"tets", tets},
               {"tetLabels", s.mesh.tetLabels},
               {"triangles", tris},
               {"triangleLabels", s.mesh.triangleLabels},
               {"labelNames", names},
               {"unitToMetre", s.mesh.unitToMetre}};
  json rest = json::array();
  for (const auto& p : s.rest) rest.push_back(vec(p));
  j["rest"] = rest;
  if (!s.start.empty()) {
    json start = json::array();
    for (const auto& p : s.start) start.push_back(vec(p));
    j["start"] = start;
  }
  if (!s.tearFrom.empty()) {  // (setups recorded before it existed keep their text)
    json from = json::array();
    for (const auto& p : s.tearFrom) from.push_back(vec(p));
    j["tearFrom"] = from;
  }
  j["fixedNodes"] = s.fixedNodes;
  if (!s.supports.empty()) {  // (setups recorded before the supports existed keep their text)
    json nodes = json::array(), at = json::array(), stiffness = json::array();
    for (const auto& a : s.supports) {
      nodes.push_back(a.node);
      at.push_back(vec(a.at));
      stiffness.push_back(a.stiffness);
    }
    j["supports"] = {{"nodes", nodes}, {"at", at}, {"stiffness", stiffness}};
  }
  j["material"] = material(s.material);
  json byLabel = json::array();
  for (const auto& [label, m] : s.byLabel) byLabel.push_back({{"label", label}, {"material", material(m)}});
  j["byLabel"] = byLabel;
  j["settings"] = settings(s.settings);
  const auto& t = s.tools;
  j["tools"] = {{"graspRadius", t.graspRadius},
                {"maxGraspForce", t.maxGraspForce},
                {"bladeLength", t.bladeLength},
                {"toolRadius", t.toolRadius},
                {"depenetrationSpeed", t.depenetrationSpeed},
                {"cutLatencySteps", t.cutLatencySteps},
                {"jawsKeepTheirHold", t.jawsKeepTheirHold},
                {"cut",
                 {{"snap", t.cut.snap},
                  {"minQuality", t.cut.minQuality},
                  {"minVolumeFraction", t.cut.minVolumeFraction},
                  {"snapFront", t.cut.snapFront}}}};
  // Written only where it differs from the cut's (the text of every setup from before it existed stays as it was).
  if (t.tearLatencySteps != t.cutLatencySteps) j["tools"]["tearLatencySteps"] = t.tearLatencySteps;
  // Written only when on (setups recorded before it existed let go after a whole step: their text stays as it was).
  if (t.slipAtLimit) j["tools"]["slipAtLimit"] = true;
  if (t.slipResolved) j["tools"]["slipResolved"] = true;  // (and those before it slipped a first order past)
  // (likewise: setups recorded before it existed refused a tear their element could not make alone)
  if (t.tearThroughNeighbours) j["tools"]["tearThroughNeighbours"] = true;
  // (likewise: setups recorded before it existed waited for a tear's body at its boundary)
  if (t.tearWhenBuilt) j["tools"]["tearWhenBuilt"] = true;
  if (t.tearOnlyUnderLoad) j["tools"]["tearOnlyUnderLoad"] = true;  // (likewise: they tore whatever stretched them)
  if (t.tearOnlyWhilePulled) j["tools"]["tearOnlyWhilePulled"] = true;  // (likewise: and while the jaws held still)
  if (t.tearRemovesElements) j["tools"]["tearRemovesElements"] = true;  // (likewise: their tears re-meshed)
  if (t.bladeReachesTheSurface) j["tools"]["bladeReachesTheSurface"] = true;  // (likewise: their blade's length only)
  if (t.trocar) j["tools"]["trocar"] = vec(*t.trocar);
  if (!(t.clip == simcore::ClipSettings{}))  // (setups recorded before the clip applier keep their text and hash)
    j["tools"]["clip"] = {
        {"length", t.clip.length}, {"width", t.clip.width}, {"gap", t.clip.gap}, {"closeTime", t.clip.closeTime}};
  // (written only when not the default, so that setups recorded before it was written keep their text and hash; a
  // replay of those with another squeeze diverged: a script's clip_min_squeeze was not recorded)
  if (t.clip.minSqueeze != simcore::ClipSettings{}.minSqueeze) j["tools"]["clip"]["minSqueeze"] = t.clip.minSqueeze;
  // Written only when physiological (the setups recorded before it existed bled by area: their text stays as it was).
  if (t.bleeding.physiological)
    j["tools"]["bleeding"] = {{"physiological", true}, {"organSupply", t.bleeding.organSupply}};
  if (!(t.cautery == simcore::CauterySettings{}))
    j["tools"]["cautery"] = {
        {"radius", t.cautery.radius}, {"burnTime", t.cautery.burnTime}, {"stiffening", t.cautery.stiffening}};
  j["topology"] = s.topology;
  // The deformable model, when not the FEM (setups recorded before it existed, all FEM, keep their bytes and hash).
  if (s.model != simcore::BodyModel::Fem) j["model"] = simcore::bodyModelName(s.model);
  // The hybrid model's FEM region as it had grown (a checkpoint's or a cut body's setup: a restore builds the same).
  if (s.model == simcore::BodyModel::Hybrid && !s.regionCentres.empty()) {
    j["regionCentres"] = json::array();
    for (const auto& c : s.regionCentres) j["regionCentres"].push_back(vec(c));
  }
  j["format"] = "rehearse-setup-1";
  return j.dump();
}

namespace {
RecordedNumerics recordedNumerics(const json& j) {
  RecordedNumerics n;
  if (!j.is_object() || !j.contains("recorded_with") || !j["recorded_with"].is_object()) return n;
  const json& r = j["recorded_with"];
  auto text = [&](const char* key) {
    return r.contains(key) && r[key].is_string() ? r[key].get<std::string>().substr(0, 512) : std::string();
  };
  n.kernel = text("kernel");
  n.build = text("build");
  return n;
}
}  // namespace

simcore::BodySetup decodeSetup(const std::string& text, RecordedNumerics* numerics) {
  if (const std::string why = jsonTextProblem(text, "a recorded setup", std::size_t{1} << 30); !why.empty())
    throw std::runtime_error(why);
  try {
    const json j = json::parse(text);
    if (j.value("format", "") != "rehearse-setup-1") throw std::runtime_error("unknown format");
    if (numerics) *numerics = recordedNumerics(j);
    simcore::BodySetup s;
    const auto& m = j.at("mesh");
    for (const auto& p : m.at("points")) s.mesh.points.push_back(vec(p));
    for (const auto& t : m.at("tets")) s.mesh.tets.push_back(asIntArray<4>(t));
    s.mesh.tetLabels = asInts(m.at("tetLabels"));
    for (const auto& t : m.at("triangles")) s.mesh.triangles.push_back(asIntArray<3>(t));
    s.mesh.triangleLabels = asInts(m.at("triangleLabels"));
    for (const auto& n : m.at("labelNames")) s.mesh.labelNames.emplace_back(asInt(n.at(0)), n.at(1).get<std::string>());
    s.mesh.unitToMetre = m.at("unitToMetre");
    for (const auto& p : j.at("rest")) s.rest.push_back(vec(p));
    if (j.contains("start"))
      for (const auto& p : j.at("start")) s.start.push_back(vec(p));
    if (j.contains("tearFrom"))
      for (const auto& p : j.at("tearFrom")) s.tearFrom.push_back(vec(p));
    s.fixedNodes = asInts(j.at("fixedNodes"));
    if (j.contains("supports")) {
      const auto& sp = j.at("supports");
      const std::vector<int> nodes = asInts(sp.at("nodes"));
      const auto& at = sp.at("at");
      const auto& stiffness = sp.at("stiffness");
      if (at.size() != nodes.size() || stiffness.size() != nodes.size())
        throw std::runtime_error("the supports' nodes, points and stiffnesses differ in number");
      for (std::size_t k = 0; k < nodes.size(); ++k) {
        simcore::NodeAnchor a;
        a.node = nodes[k];
        a.at = vec(at.at(k));
        a.stiffness = stiffness.at(k).get<double>();
        s.supports.push_back(a);
      }
    }
    s.material = material(j.at("material"));
    for (const auto& b : j.at("byLabel")) s.byLabel[asInt(b.at("label"))] = material(b.at("material"));
    s.settings = settings(j.at("settings"));
    const auto& t = j.at("tools");
    s.tools.graspRadius = t.at("graspRadius");
    s.tools.maxGraspForce = t.at("maxGraspForce");
    s.tools.bladeLength = t.at("bladeLength");
    s.tools.toolRadius = t.at("toolRadius");
    s.tools.depenetrationSpeed =
        t.value("depenetrationSpeed", 0.0);  // recorded before it existed: contact pushed out at once
    s.tools.cutLatencySteps =
        t.contains("cutLatencySteps") ? asInt(t.at("cutLatencySteps")) : -1;  // ... and cuts applied as they were
    s.tools.tearLatencySteps =  // ... and tears at the cut's latency, as they were
        t.contains("tearLatencySteps") ? asInt(t.at("tearLatencySteps")) : s.tools.cutLatencySteps;
    s.tools.jawsKeepTheirHold = t.value("jawsKeepTheirHold", false);          // ... and the jaws followed every tip
    s.tools.slipAtLimit = t.value("slipAtLimit", false);  // ... and the jaws let go after a whole step's pull
    s.tools.slipResolved = t.value("slipResolved", false);  // ... the held-back step's force as it came out
    s.tools.tearThroughNeighbours = t.value("tearThroughNeighbours", false);  // ... and tears were the element's alone
    s.tools.tearOnlyUnderLoad = t.value("tearOnlyUnderLoad", false);  // ... made whatever stretched the tissue
    s.tools.tearOnlyWhilePulled = t.value("tearOnlyWhilePulled", false);  // ... and while the jaws held still
    s.tools.tearRemovesElements = t.value("tearRemovesElements", false);  // ... split across the stretch, re-meshed
    s.tools.tearWhenBuilt = t.value("tearWhenBuilt", false);  // ... and waited for a tear's body at its boundary
    s.tools.bladeReachesTheSurface = t.value("bladeReachesTheSurface", false);  // ... and cut the blade's length only
    s.tools.cut.snap = t.at("cut").at("snap");
    s.tools.cut.minQuality = t.at("cut").at("minQuality");
    s.tools.cut.minVolumeFraction = t.at("cut").at("minVolumeFraction");
    s.tools.cut.snapFront = t.at("cut").at("snapFront");
    if (t.contains("trocar")) s.tools.trocar = vec(t.at("trocar"));
    if (t.contains("clip")) {
      const auto& c = t.at("clip");
      s.tools.clip.length = c.at("length");
      s.tools.clip.width = c.at("width");
      s.tools.clip.gap = c.at("gap");
      s.tools.clip.closeTime = c.at("closeTime");
      s.tools.clip.minSqueeze = c.value("minSqueeze", simcore::ClipSettings{}.minSqueeze);
    }
    s.tools.bleeding.physiological = false;  // recorded before it existed: a stump bled its area times a speed
    if (t.contains("bleeding")) {
      s.tools.bleeding.physiological = t.at("bleeding").at("physiological");
      s.tools.bleeding.organSupply = t.at("bleeding").at("organSupply");
    }
    if (t.contains("cautery")) {
      const auto& c = t.at("cautery");
      s.tools.cautery.radius = c.at("radius");
      s.tools.cautery.burnTime = c.at("burnTime");
      s.tools.cautery.stiffening = c.at("stiffening");
    }
    s.topology = asInt(j.at("topology"));
    if (j.contains("model")) s.model = simcore::bodyModelFromString(j.at("model").get<std::string>());
    if (j.contains("regionCentres"))
      for (const auto& c : j.at("regionCentres")) {
        s.regionCentres.push_back(vec(c));
        if (!s.regionCentres.back().allFinite()) throw std::runtime_error("a region centre is not a point");
        if (s.regionCentres.size() > 100000) throw std::runtime_error("too many region centres");
      }
    if (const std::string why = setupProblem(s); !why.empty()) throw std::runtime_error(why);
    return s;
  } catch (const std::exception& e) {
    throw std::runtime_error("the recorded setup cannot be read (" + readableReason(e) + ")");
  }
}

std::string encodeEvent(const simcore::InputEvent& e) {
  return json{{"kind", static_cast<int>(e.kind)},
              {"wallTime", e.wallTime},
              {"step", e.step},
              {"tool", e.tool},
              {"label", e.label},
              {"position", vec(e.position)},
              {"vector", vec(e.vector)},
              {"on", e.on},
              {"name", e.name},
              {"value", e.value}}
      .dump();
}

simcore::InputEvent decodeEvent(const std::string& text) {
  if (const std::string why = jsonTextProblem(text, "a recorded event", std::size_t{1} << 20); !why.empty())
    throw std::runtime_error(why);
  try {
    const json j = json::parse(text);
    simcore::InputEvent e;
    e.kind = static_cast<simcore::InputKind>(asInt(j.at("kind")));
    e.wallTime = j.at("wallTime");
    e.step = static_cast<long>(asInteger(j.at("step"), -1, 1LL << 40));
    e.tool = asInt(j.at("tool"));
    e.label = asInt(j.at("label"));
    e.position = vec(j.at("position"));
    e.vector = vec(j.at("vector"));
    e.on = j.at("on");
    e.name = j.at("name");
    e.value = j.at("value");
    if (const std::string why = eventProblem(e); !why.empty()) throw std::runtime_error(why);
    return e;
  } catch (const std::exception& e) {
    throw std::runtime_error("a recorded event cannot be read (" + readableReason(e) + ")");
  }
}

namespace {
bool finite(double v) { return std::isfinite(v); }
bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }
std::string materialProblem(const simcore::MaterialParams& m, const std::string& whose) {
  const int model = static_cast<int>(m.model);
  if (model < 0 || model > static_cast<int>(simcore::MaterialModel::NeoHookeanSplit))
    return whose + " has an unknown material law (" + std::to_string(model) + ")";
  if (!finite(m.young) || m.young <= 0) return whose + "'s Young's modulus is not a positive number";
  if (!finite(m.poisson) || m.poisson <= -1 || m.poisson >= 0.5) return whose + "'s Poisson ratio is outside (-1, 0.5)";
  if (!finite(m.density) || m.density <= 0) return whose + "'s density is not a positive number";
  if (!finite(m.tearStrain) || m.tearStrain < 0 || m.tearStrain > 10)
    return whose + "'s tear strain is outside [0, 10] (0: it does not tear)";
  return {};
}
template <class Enum>
bool inEnum(Enum e, Enum last) {
  const int v = static_cast<int>(e);
  return v >= 0 && v <= static_cast<int>(last);
}
}  // namespace

std::string setupProblem(const simcore::BodySetup& s) {
  const auto& m = s.mesh;
  const std::size_t n = m.points.size();
  if (n == 0 || m.tets.empty()) return "the body has no nodes or no elements";
  if (!s.rest.empty() && s.rest.size() != n)
    return "the body's rest positions (" + std::to_string(s.rest.size()) + ") do not match its nodes (" +
           std::to_string(n) + ")";
  if (!s.start.empty() && s.start.size() != n)
    return "the body's start positions (" + std::to_string(s.start.size()) + ") do not match its nodes (" +
           std::to_string(n) + ")";
  if (!s.tearFrom.empty() && s.tearFrom.size() != n)
    return "the positions the body's tears are measured from (" + std::to_string(s.tearFrom.size()) +
           ") do not match its nodes (" + std::to_string(n) + ")";
  if (!std::all_of(s.tearFrom.begin(), s.tearFrom.end(), [](const Eigen::Vector3d& p) { return finite(p); }))
    return "a node's position is not a number";
  if (!std::all_of(m.points.begin(), m.points.end(), [](const Eigen::Vector3d& p) { return finite(p); }) ||
      !std::all_of(s.rest.begin(), s.rest.end(), [](const Eigen::Vector3d& p) { return finite(p); }) ||
      !std::all_of(s.start.begin(), s.start.end(), [](const Eigen::Vector3d& p) { return finite(p); }))
    return "a node's position is not a number";
  auto inRange = [n](int i) { return i >= 0 && static_cast<std::size_t>(i) < n; };
  for (std::size_t e = 0; e < m.tets.size(); ++e)
    if (!std::all_of(m.tets[e].begin(), m.tets[e].end(), inRange))
      return "element " + std::to_string(e) + " names a node the body has not";
  for (std::size_t e = 0; e < m.triangles.size(); ++e)
    if (!std::all_of(m.triangles[e].begin(), m.triangles[e].end(), inRange))
      return "surface triangle " + std::to_string(e) + " names a node the body has not";
  if (!m.tetLabels.empty() && m.tetLabels.size() != m.tets.size())
    return "the element labels do not match the elements";
  if (!m.triangleLabels.empty() && m.triangleLabels.size() != m.triangles.size())
    return "the triangle labels do not match the triangles";
  if (!std::all_of(s.fixedNodes.begin(), s.fixedNodes.end(), inRange))
    return "an attachment names a node the body has not";
  for (const auto& a : s.supports)
    if (!inRange(a.node) || !a.at.allFinite() || !finite(a.stiffness) || a.stiffness < 0)
      return "a support names a node the body has not or is not a finite spring";
  if (!finite(m.unitToMetre) || m.unitToMetre <= 0) return "the mesh's unit is not a positive number";
  if (auto p = materialProblem(s.material, "the organ"); !p.empty()) return p;
  for (const auto& [label, mat] : s.byLabel)
    if (auto p = materialProblem(mat, "label " + std::to_string(label)); !p.empty()) return p;
  const auto& t = s.settings;
  if (!finite(t.timeStep) || t.timeStep <= 0 || t.timeStep > 10) return "the time step is not between 0 and 10 s";
  if (!finite(t.gravity) || !finite(t.rayleighMass) || !finite(t.rayleighStiffness) || t.rayleighMass < 0 ||
      t.rayleighStiffness < 0)
    return "gravity or damping is not a number (or negative damping)";
  if (t.maxNewtonIterations < 1 || t.maxNewtonIterations > 10000 || t.cgMaxIterations < 0 ||
      t.cgMaxIterations > 1000000 || t.maxRetries < 0 || t.maxRetries > 60 || t.gaussSeidelIterations < 0 ||
      t.gaussSeidelIterations > 1000000)
    return "an iteration count of the solver is out of range";
  if (!finite(t.tolerance) || t.tolerance <= 0 || !finite(t.cgTolerance) || t.cgTolerance < 0 ||
      !finite(t.staticStepTolerance) || !finite(t.gaussSeidelTolerance) || !finite(t.refreshResidual) ||
      !finite(t.linearisedTolerance) || t.linearisedTolerance <= 0)
    return "a tolerance of the solver is not a positive number";
  if (!inEnum(t.solver, simcore::LinearSolverKind::Dense) || !inEnum(t.method, simcore::NewtonMethod::NewtonKrylov) ||
      !inEnum(t.attachments, simcore::AttachmentMode::Lagrange) ||
      !inEnum(t.factorRefresh, simcore::FactorRefresh::Deferred))
    return "the solver, method, attachment or refresh setting is not one this version knows";
  if (!(t.volumeBarrier >= 0 && t.volumeBarrier < 1))
    return "the volume barrier is not a volume ratio from 0 up to, not including, 1";
  const auto& tool = s.tools;
  for (double v : {tool.graspRadius, tool.maxGraspForce, tool.bladeLength, tool.toolRadius, tool.depenetrationSpeed,
                   tool.cut.snap, tool.cut.minQuality, tool.cut.minVolumeFraction, tool.clip.length, tool.clip.width,
                   tool.clip.gap, tool.clip.closeTime})
    if (!finite(v) || v < 0) return "an instrument setting is not a non-negative number";
  if (tool.trocar && !finite(*tool.trocar)) return "the trocar is not a point";
  if (!(tool.clip.minSqueeze >= 0 && tool.clip.minSqueeze <= 1)) return "the clip's least squeeze is outside [0, 1]";
  if (const std::string why = simcore::cauteryProblem(tool.cautery); !why.empty()) return why;
  if (!(tool.bleeding.organSupply >= 0 && tool.bleeding.organSupply <= 1e-3))
    return "the organ's blood supply is not a flow between 0 and 60 L/min";
  if (tool.cutLatencySteps < -1 || tool.cutLatencySteps > 1000)
    return "the cut's latency is not between -1 and 1000 steps";
  if (tool.tearLatencySteps < -1 || tool.tearLatencySteps > 1000)
    return "the tear's latency is not between -1 and 1000 steps";
  if (s.topology < 0) return "the topology version is negative";
  // The ranges every input path holds (a run inside the old ones could be set never to end).
  if (const std::string why = simcore::settingsProblem(t); !why.empty()) return why;
  if (auto p = simcore::materialRangeProblem(s.material, "the organ"); !p.empty()) return p;
  for (const auto& [label, mat] : s.byLabel)
    if (auto p = simcore::materialRangeProblem(mat, "label " + std::to_string(label)); !p.empty()) return p;
  return {};
}

std::string eventProblem(const simcore::InputEvent& e) {
  if (!inEnum(e.kind, simcore::InputKind::Energy))
    return "an event of an unknown kind (" + std::to_string(static_cast<int>(e.kind)) + ")";
  if (!finite(e.wallTime) || !finite(e.position) || !finite(e.vector) || !finite(e.value))
    return "an event holds no number";
  if (e.step < 0) return "an event has no step";
  if (e.tool < 0 || e.tool > 1000) return "an event names an unknown instrument";
  if (e.kind == simcore::InputKind::Parameter) {
    const std::string& k = e.name;
    const double v = e.value;
    if (k == "young") {
      if (!(v > 0 || (e.label > 0 && v == 0))) return "a recorded Young's modulus is not positive";
    } else if (k == "poisson") {
      if (!(v > -1 && v < 0.5)) return "a recorded Poisson ratio is outside (-1, 0.5)";
    } else if (k == "density") {
      if (!(v > 0)) return "a recorded density is not positive";
    } else if (k == "dt") {
      if (!(v > 0 && v <= 10)) return "a recorded time step is not between 0 and 10 s";
    } else if (k == "clip_length") {
      if (!(v >= 0.001 && v <= 0.05)) return "a recorded clip length is not between 1 and 50 mm";
    } else if (k == "tear_strain") {
      if (!(v >= 0 && v <= 10)) return "a recorded tear strain is not between 0 and 10";
    } else if (k == "grasp_radius") {
      if (!(v > 0 && v <= 0.1)) return "a recorded grasp radius is not between 0 and 0.1 m";
    } else if (k == "method") {
      if (!(v >= 0 && v <= static_cast<int>(simcore::NewtonMethod::NewtonKrylov) && v == std::floor(v)))
        return "a recorded method is not one this version knows";
    } else if (k == "model") {
      if (!(v >= 0 && v <= static_cast<int>(simcore::MaterialModel::NeoHookeanSplit) && v == std::floor(v)))
        return "a recorded material law is not one this version knows";
    } else {
      return "a recorded parameter '" + k + "' is not one this version knows";
    }
    if (e.label < 0) return "a recorded parameter names a negative label";
  }
  return {};
}

std::string withRecordedNumerics(const std::string& setupText, const RecordedNumerics& n) {
  // Spliced in before the object's closing brace: the setup (a whole mesh) is not parsed and printed again on the
  // stepping thread.
  const auto close = setupText.find_last_of('}');
  if (close == std::string::npos) throw std::runtime_error("a setup text is not a JSON object");
  const json with = {{"kernel", n.kernel}, {"build", n.build}};
  return setupText.substr(0, close) + ",\"recorded_with\":" + with.dump(-1, ' ', false, json::error_handler_t::replace) +
         setupText.substr(close);
}

std::string newSessionUuid() {
  std::random_device rd;
  char buf[33];
  for (int i = 0; i < 4; ++i) std::snprintf(buf + 8 * i, 9, "%08x", static_cast<unsigned>(rd()));
  return std::string(buf, 32);
}

}  // namespace rehearse::app
