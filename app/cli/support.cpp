// What the sub-commands share: option parsing from their declarations, --help, number and list parsers, the organ
// model from its options, reports and the steps' outcomes.
#include "support.hpp"

#include <rehearse/simcore/input_ranges.hpp>
#include <rehearse/text_input.hpp>

#include "phantom/presets.hpp"
#include "rehearse/app/materials.hpp"

#include <rehearse/imaging/camera.hpp>
#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace rehearse::app::cli {

// A JSON report, written atomically (a reader never sees half of it).
void writeReport(const std::string& path, const nlohmann::json& report) {
  rehearse::writeFileAtomically(path, report.dump(2) + "\n");
}

Options parseOptions(const std::vector<std::string>& args, std::size_t from, const Command& command) {
  auto spec = [&command](const std::string& key) -> const OptionSpec* {
    for (const auto& o : command.options)
      if (o.name == key) return &o;
    return nullptr;
  };
  Options out;
  for (std::size_t i = from; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a.rfind("--", 0) != 0)
      throw UsageError("unexpected argument '" + a + "'; see 'rehearse " + command.name + " --help'");
    std::string key = a.substr(2), value;
    const auto eq = key.find('=');
    if (eq != std::string::npos) {
      value = key.substr(eq + 1);
      key = key.substr(0, eq);
    }
    const OptionSpec* o = spec(key);
    if (!o) throw UsageError("unknown option --" + key + "; see 'rehearse " + command.name + " --help'");
    if (eq == std::string::npos && !o->value.empty()) {
      if (i + 1 >= args.size()) throw UsageError("option --" + key + " needs a value (" + o->value + ")");
      value = args[++i];
    }
    out[key] = value;
  }
  return out;
}

std::vector<OptionSpec> joined(std::vector<OptionSpec> first, const std::vector<OptionSpec>& then) {
  first.insert(first.end(), then.begin(), then.end());
  return first;
}

const std::vector<OptionSpec>& modelOptions() {
  static const std::vector<OptionSpec> options = {
      {"scene", "S.json", "a scene file (mesh, materials, attachments, settings; README, File formats)"},
      {"preset", "NAME", "eye, kidney, liver, uterus or sofa-liver"},
      {"mesh", "FILE", "a volume or a closed surface (tetrahedralised)"},
      {"unit", "U", "m, dm, cm or mm: the mesh's length unit"},
      {"material", "LAW", "linear, corotational, stvk, neohookean or neohookean-split"},
      {"young", "PA", "Young's modulus of the parenchyma"},
      {"poisson", "NU", "Poisson's ratio"},
      {"density", "KG_M3", "the tissue's density"},
      {"vessel-young", "PA", "Young's modulus of the vessels (label 2), the parenchyma's law and density"},
      {"fixed-nodes", "NODES", "the held nodes: \"i j k\" or a file of indices"},
      {"gravity", "X,Y,Z", "m/s^2 in the model's frame"}};
  return options;
}

std::string commandHelp(const Command& c) {
  std::string out = "Usage:\n" + c.usage + "\nOptions:\n";
  std::size_t width = 0;
  for (const auto& o : c.options) width = std::max(width, o.name.size() + (o.value.empty() ? 0 : o.value.size() + 1));
  for (const auto& o : c.options) {
    std::string left = "--" + o.name + (o.value.empty() ? "" : " " + o.value);
    left.resize(width + 4, ' ');
    out += "  " + left + o.help + "\n";
  }
  std::string help = "--help";
  help.resize(width + 4, ' ');
  out += "  " + help + "this text\n";
  return out;
}

long parseCount(const std::string& s, const char* what, long lo, long hi) {
  try {
    std::size_t used = 0;
    long v = std::stol(s, &used);
    if (used != s.size() || v < lo || v > hi) throw std::out_of_range("");
    return v;
  } catch (const std::exception&) {
    throw UsageError(std::string(what) + " must be a whole number from " + std::to_string(lo) + " to " +
                     std::to_string(hi));
  }
}

double parseNumber(const std::string& s, const char* what) {
  try {
    std::size_t used = 0;
    double v = std::stod(s, &used);
    if (used != s.size() || !std::isfinite(v) || v <= 0) throw std::out_of_range("");
    return v;
  } catch (const std::exception&) {
    throw UsageError(std::string(what) + " must be a positive number");
  }
}

Eigen::Vector3d parseVector(const std::string& s, const char* what) {
  Eigen::Vector3d v;
  char c1 = 0, c2 = 0;
  std::istringstream in(s);
  if (!(in >> v.x() >> c1 >> v.y() >> c2 >> v.z()) || c1 != ',' || c2 != ',' || !v.allFinite())
    throw UsageError(std::string(what) + " must be three numbers separated by commas, such as 0,-9.81,0");
  return v;
}

// --fixed-nodes: a list of node indices ("3 39 64" or "3,39,64") or a file holding one; decided by content
// (a list of digits is never taken for a file name). Every token must be an index: nothing is dropped.
std::vector<int> parseNodes(const std::string& s) {
  const bool isList = !s.empty() && s.find_first_not_of("0123456789, \t\r\n") == std::string::npos;
  std::string text = s;
  if (!isList) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(s, ec))
      throw UsageError("--fixed-nodes takes node indices (\"3 39 64\") or a file of them; '" + s.substr(0, 40) +
                       (s.size() > 40 ? "...'" : "'") + " is neither");
    std::string why;
    if (!readTextInput(s, text, why)) throw UsageError("--fixed-nodes: " + why);
    if (const std::string deep = jsonTextProblem(text, s); !deep.empty()) throw UsageError("--fixed-nodes: " + deep);
    // A case folder's attachments.json ({"nodes": [...], "indexing": "0-based ..."}): its node list.
    if (text.find_first_not_of(" \t\r\n") != std::string::npos && text[text.find_first_not_of(" \t\r\n")] == '{') {
      const auto j = nlohmann::json::parse(text, nullptr, false);
      if (j.is_discarded() || !j.contains("nodes") || !j["nodes"].is_array())
        throw UsageError("--fixed-nodes: " + s + " is JSON but has no \"nodes\" list of node indices");
      std::vector<int> out;
      for (const auto& v : j["nodes"]) {
        if (!v.is_number_integer() || v.get<long long>() < 0)
          throw UsageError("--fixed-nodes: " + s + " lists something that is not a node index (0, 1, 2, ...)");
        out.push_back(v.get<int>());
      }
      return out;
    }
  }
  for (auto& ch : text)
    if (ch == ',') ch = ' ';
  std::vector<int> out;
  std::istringstream in(text);
  std::string tok;
  while (in >> tok) {
    if (tok.find_first_not_of("0123456789") != std::string::npos || tok.size() > 9)
      throw UsageError("--fixed-nodes holds '" + tok.substr(0, 20) + "', which is not a node index (0, 1, 2, ...)");
    out.push_back(std::stoi(tok));
  }
  return out;
}

// The organ model of a command: --scene, --preset or --mesh, then the material flags, --fixed-nodes and
// --gravity over it (shared by simulate and register).
// When `surfaceIn` is given and the organ came as a surface that was tetrahedralised, it receives that
// surface (in metres), so indices into it can be mapped onto the volume.
simcore::Scene modelFromOptions(Options& o, const char* command, simcore::Mesh* surfaceIn) {
  simcore::Scene p;
  p.defaultMaterial = {};
  if (o.count("scene")) {
    p = simcore::loadScene(o["scene"]);
    if (!p.mesh.isVolume()) p.mesh = simcore::tetrahedraliseSurface(p.mesh, {});
  } else if (o.count("preset")) {
    try {
      p = phantom::makePreset(o["preset"]);
    } catch (const simcore::MeshError& e) {
      throw UsageError(e.what());
    }
  } else if (o.count("mesh")) {
    simcore::LoadOptions lo;
    if (o.count("unit")) lo.unit = o["unit"];
    p.mesh = simcore::loadMesh(o["mesh"], lo);
    if (!p.mesh.isVolume()) {
      if (surfaceIn) {
        *surfaceIn = p.mesh;
        surfaceIn->convertToMetres();
      }
      simcore::TetrahedraliseOptions to;
      p.mesh = simcore::tetrahedraliseSurface(p.mesh, to);
    }
  } else {
    throw UsageError(std::string(command) + " needs --scene S.json, --preset NAME or --mesh FILE");
  }
  if (o.count("material")) p.defaultMaterial.model = simcore::materialModelFromString(o["material"]);
  if (o.count("young")) p.defaultMaterial.young = parseNumber(o["young"], "--young");
  if (o.count("poisson")) {
    try {
      p.defaultMaterial.poisson = std::stod(o["poisson"]);
    } catch (const std::exception&) {
      throw UsageError("--poisson must be a number in [0, 0.5)");
    }
  }
  if (o.count("density")) p.defaultMaterial.density = parseNumber(o["density"], "--density");
  if (o.count("vessel-young")) {
    // The case's vessel material as the GUI sets it (app::labelMaterials): the parenchyma's law and density.
    MaterialSettings m = materialFromScene(p);
    m.vesselYoung = parseNumber(o["vessel-young"], "--vessel-young");
    const LabelMaterials lm = labelMaterials(m);
    p.defaultMaterial = lm.fallback;
    p.materials = lm.byLabel;
  }
  if (o.count("fixed-nodes")) p.fixedNodes = parseNodes(o["fixed-nodes"]);
  if (o.count("gravity")) p.settings.gravity = parseVector(o["gravity"], "--gravity");
  return p;
}

void refuseOutOfRange(const simcore::SimulationSettings& settings, const simcore::MaterialParams& fallback,
                      const std::map<int, simcore::MaterialParams>& byLabel) {
  if (const std::string why = simcore::settingsProblem(settings); !why.empty()) throw UsageError(why);
  if (const std::string why = simcore::materialRangeProblem(fallback, "the organ"); !why.empty()) throw UsageError(why);
  for (const auto& [label, m] : byLabel)
    if (const std::string why = simcore::materialRangeProblem(m, "label " + std::to_string(label)); !why.empty())
      throw UsageError(why);
}

constexpr simcore::StepStatus kStatuses[] = {simcore::StepStatus::Converged, simcore::StepStatus::Inexact,
                                             simcore::StepStatus::Inverted, simcore::StepStatus::Failed,
                                             simcore::StepStatus::Refused};

// {"converged": n, "inexact": n, ...}: the reports' "statuses".
nlohmann::json statusCounts(const std::vector<const simcore::StepReport*>& reports) {
  nlohmann::json counts = nlohmann::json::object();
  for (auto s : kStatuses) {
    std::size_t k = 0;
    for (const auto* r : reports) k += r->outcome == s;
    counts[toString(s)] = k;
  }
  return counts;
}

// The steps' outcomes counted, on stdout always ("statuses: ..."), on stderr when one did not converge, and the exit
// code: 0 when every step converged, 3 when a step failed (rolled back) or was refused, 5 when every step advanced but
// some ended inexact or with inverted elements.
int statusSummary(const std::vector<const simcore::StepReport*>& reports) {
  std::array<std::size_t, 5> n{};
  std::size_t mostInverted = 0;
  double largestResidual = 0, smallestJ = 1;
  for (const auto* r : reports) {
    ++n[static_cast<std::size_t>(r->outcome)];
    mostInverted = std::max(mostInverted, static_cast<std::size_t>(r->invertedElements));
    if (std::isfinite(r->residual)) largestResidual = std::max(largestResidual, r->residual);
    smallestJ = std::min(smallestJ, r->minVolumeRatio);
  }
  using S = simcore::StepStatus;
  std::string line = "statuses: ";
  for (S s : kStatuses)
    if (n[static_cast<std::size_t>(s)] || s == S::Converged)
      line += (line.size() > 10 ? ", " : "") + std::to_string(n[static_cast<std::size_t>(s)]) + " " + toString(s);
  char figures[160];
  std::snprintf(figures, sizeof figures,
                "; largest relative residual %.3g, at most %zu inverted elements, smallest volume ratio %.3g",
                largestResidual, mostInverted, smallestJ);
  line += figures;
  std::printf("%s\n", line.c_str());
  const std::size_t failed = n[static_cast<std::size_t>(S::Failed)] + n[static_cast<std::size_t>(S::Refused)];
  const std::size_t loose = n[static_cast<std::size_t>(S::Inexact)] + n[static_cast<std::size_t>(S::Inverted)];
  if (failed || loose) {
    const simcore::StepReport* first = nullptr;
    for (const auto* r : reports)
      if (r->outcome != S::Converged) {
        first = r;
        break;
      }
    std::fprintf(stderr, "rehearse: %zu of %zu steps did not converge (%s); the first: %s\n", failed + loose,
                 reports.size(), line.c_str() + 10, simcore::statusSentence(*first).c_str());
  }
  return failed ? 3 : loose ? 5 : 0;
}

}  // namespace rehearse::app::cli
