#include "cli.hpp"

#include "phantom/phantom.hpp"

#include <rehearse/simcore/meshio.hpp>
#include <rehearse/simcore/quality.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>

#include <unistd.h>

#ifndef REHEARSE_VERSION
#define REHEARSE_VERSION "0.0.0"
#endif

namespace rehearse::app {
namespace {

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Parses "--key value" pairs after the sub-command; flags listed in `flags` take no value.
std::map<std::string, std::string> parseOptions(const std::vector<std::string>& args, std::size_t from,
                                                const std::vector<std::string>& allowed,
                                                const std::vector<std::string>& flags = {}) {
  std::map<std::string, std::string> out;
  for (std::size_t i = from; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + a + "'; see 'rehearse --help'");
    std::string key = a.substr(2), value;
    if (auto eq = key.find('='); eq != std::string::npos) {
      value = key.substr(eq + 1);
      key = key.substr(0, eq);
    } else if (std::find(flags.begin(), flags.end(), key) == flags.end()) {
      if (i + 1 >= args.size()) throw UsageError("option --" + key + " needs a value");
      value = args[++i];
    }
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end() &&
        std::find(flags.begin(), flags.end(), key) == flags.end())
      throw UsageError("unknown option --" + key + "; see 'rehearse --help'");
    out[key] = value;
  }
  return out;
}

long parseCount(const std::string& s, const char* what, long lo, long hi) {
  try {
    std::size_t used = 0;
    long v = std::stol(s, &used);
    if (used != s.size() || v < lo || v > hi) throw std::out_of_range("");
    return v;
  } catch (const std::exception&) {
    throw UsageError(std::string(what) + " must be a whole number from " + std::to_string(lo) + " to " + std::to_string(hi));
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

int cmdPhantom(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, {"out", "tets", "seed"});
  if (!o.count("out")) throw UsageError("phantom needs --out DIR");
  phantom::PhantomOptions po;
  if (o.count("tets")) po.targetTets = parseCount(o["tets"], "--tets", 100, 2'000'000);
  if (o.count("seed")) po.seed = static_cast<unsigned>(parseCount(o["seed"], "--seed", 0, 1'000'000));
  auto t0 = std::chrono::steady_clock::now();
  auto c = phantom::makePhantom(po);
  phantom::writeCaseDirectory(c, o["out"]);
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("phantom written to %s: %zu nodes, %zu tets, %zu surface triangles, %zu attachment nodes, frame %dx%d (%.2f s)\n",
              o["out"].c_str(), c.volume.points.size(), c.volume.tets.size(), c.surface.size(), c.attachments.size(),
              c.frame.cols, c.frame.rows, s);
  return 0;
}

int cmdMesh(const std::vector<std::string>& args) {
  auto o = parseOptions(args, 2, {"in", "out", "target-tets", "size", "unit"}, {"ascii", "allow-self-intersections"});
  if (!o.count("in") || !o.count("out")) throw UsageError("mesh needs --in SURFACE and --out VOLUME.msh|.vtk|.vtu");
  const std::string ext = std::filesystem::path(o["out"]).extension().string();
  if (ext != ".msh" && ext != ".vtk" && ext != ".vtu" && ext != ".mesh")
    throw UsageError("--out must end in .msh, .vtk, .vtu or .mesh");
  simcore::LoadOptions lo;
  if (o.count("unit")) lo.unit = o["unit"];
  std::vector<std::string> notes;
  auto input = simcore::loadMesh(o["in"], lo, &notes);
  simcore::Mesh volume;
  auto t0 = std::chrono::steady_clock::now();
  if (input.isVolume()) {
    volume = std::move(input);
    volume.triangles.clear();
    volume.triangleLabels.clear();
    notes.push_back("The input is already a volume mesh; it was converted, not re-meshed.");
  } else {
    simcore::TetrahedraliseOptions to;
    if (o.count("target-tets")) to.targetTets = parseCount(o["target-tets"], "--target-tets", 10, 5'000'000);
    if (o.count("size")) to.cellSize = parseNumber(o["size"], "--size") * 1e-3;
    to.allowSelfIntersections = o.count("allow-self-intersections") > 0;
    if (isatty(fileno(stderr)))
      to.progress = [](double f, const std::string& stage) { std::fprintf(stderr, "\r%3.0f%% %-40s", 100 * f, stage.c_str()); };
    volume = simcore::tetrahedraliseSurface(input, to, &notes);
  }
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (isatty(fileno(stderr))) std::fprintf(stderr, "\r%50s\r", "");
  simcore::saveMesh(volume, o["out"], o.count("ascii") > 0);
  for (const auto& n : notes) std::fprintf(stderr, "note: %s\n", n.c_str());
  std::printf("%s", simcore::formatQuality(simcore::computeQuality(volume)).c_str());
  std::printf("meshing time: %.3f s\nwritten: %s\n", s, o["out"].c_str());
  return 0;
}

int cmdInfo(const std::vector<std::string>& args) {
  if (args.size() < 3 || args[2].rfind("--", 0) == 0) throw UsageError("info needs a FILE");
  auto o = parseOptions(args, 3, {"unit"});
  simcore::LoadOptions lo;
  if (o.count("unit")) lo.unit = o["unit"];
  std::vector<std::string> notes;
  auto m = simcore::loadMesh(args[2], lo, &notes);
  auto q = simcore::computeQuality(m);
  if (!m.isVolume()) q.selfIntersections = simcore::countSelfIntersections(m);
  std::printf("file: %s\nkind: %s\nunit: %s (coordinates shown in mm)\n", args[2].c_str(),
              m.isVolume() ? "volume" : "surface", lo.unit.c_str());
  std::printf("%s", simcore::formatQuality(q).c_str());
  for (const auto& n : notes) std::printf("repaired on load: %s\n", n.c_str());
  return 0;
}

}  // namespace

std::string usage() {
  return "Rehearse " REHEARSE_VERSION
         " - intra-operative surgical gesture rehearsal\n\n"
         "Usage:\n"
         "  rehearse                         start the GUI on the built-in phantom case\n"
         "  rehearse open CASE               start the GUI on a case folder\n"
         "  rehearse phantom --out DIR [--tets N] [--seed S]\n"
         "                                   write the built-in phantom case as ordinary files\n"
         "  rehearse mesh --in SURFACE --out VOLUME.msh|.vtk|.vtu [--target-tets N] [--size MM]\n"
         "                [--unit m|dm|cm|mm] [--ascii] [--allow-self-intersections]\n"
         "                                   tetrahedralise a closed surface (inner closed parts become labels)\n"
         "  rehearse info FILE [--unit m|dm|cm|mm]\n"
         "                                   node, element and label counts, bounds and quality\n"
         "  rehearse --help | --version\n\n"
         "GUI options: --screenshot PNG (save the window and quit), --software (no OpenGL)\n"
         "Mesh formats: .msh (Gmsh 1, 2.2, 4.1), .vtk (legacy), .vtu, .mesh (Medit), .obj .stl .ply .off .gltf .glb.\n"
         "Lengths are metres unless --unit says otherwise.\n";
}

int runCli(const std::vector<std::string>& args, bool& handled) {
  handled = true;
  if (args.size() < 2 || args[1] == "open" || (args[1].rfind("--", 0) == 0 && args[1] != "--help" && args[1] != "--version" &&
                                               args[1] != "-h")) {
    handled = false;
    return 0;
  }
  const std::string& cmd = args[1];
  try {
    if (cmd == "--help" || cmd == "-h" || cmd == "help") {
      std::printf("%s", usage().c_str());
      return 0;
    }
    if (cmd == "--version") {
      std::printf("rehearse %s\n", REHEARSE_VERSION);
      return 0;
    }
    if (cmd == "phantom") return cmdPhantom(args);
    if (cmd == "mesh") return cmdMesh(args);
    if (cmd == "info") return cmdInfo(args);
    throw UsageError("unknown command '" + cmd + "'; see 'rehearse --help'");
  } catch (const UsageError& e) {
    std::fprintf(stderr, "rehearse: %s\n", e.what());
    return 2;
  } catch (const simcore::Cancelled&) {
    std::fprintf(stderr, "rehearse: cancelled\n");
    return 130;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "rehearse: error: out of memory; try a smaller mesh or target\n");
    return 1;
  } catch (const std::exception& e) {
    std::string msg = e.what();
    for (auto& ch : msg)
      if (ch == '\n') ch = ' ';
    std::fprintf(stderr, "rehearse: error: %s\n", msg.c_str());
    return 1;
  }
}

}  // namespace rehearse::app
