// The command line's dispatcher (no Qt): `rehearse NAME ...` runs the sub-command declared under that name (one file
// per family in this folder: cmd_case, cmd_simulate, cmd_register, cmd_appearance, cmd_gesture, cmd_replay, cmd_device;
// what they share in support.hpp); `rehearse --help` lists them all, `rehearse NAME --help` one with its options.
//
// Adding a sub-command: write `int cmdName(const std::vector<std::string>& args)` and its `const Command&
// nameCommand()` (usage block, options with a line of help each) in its family's file, declare the latter in
// support.hpp and list it in commands() below; its options are parsed from that one declaration.
#include "cli.hpp"

#include "rehearse_revision.hpp"
#include "support.hpp"

#include <rehearse/imaging/appearance_fit.hpp>
#include <rehearse/simcore/tetrahedralise.hpp>
#include <rehearse/simcore/registration.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>

#ifndef REHEARSE_VERSION
#define REHEARSE_VERSION "0.0.0"
#endif

namespace rehearse::app {

namespace cli {
const std::vector<const Command*>& commands() {
  static const std::vector<const Command*> all = {&phantomCommand(),  &meshCommand(),     &infoCommand(),
                                                  &simulateCommand(), &registerCommand(), &appearanceCommand(),
                                                  &composeCommand(),  &gestureCommand(),  &replayCommand(),
                                                  &publishCommand(),  &deviceCommand()};
  return all;
}
}  // namespace cli

std::string usage() {
  std::string out = "Rehearse " REHEARSE_VERSION
                    " - intra-operative surgical gesture rehearsal\n\n"
                    "Usage:\n"
                    "  rehearse                         start the GUI on the built-in phantom case\n"
                    "  rehearse open [CASE]             start the GUI on a case file (.rehearse) or folder (none: the\n"
                    "                                   built-in case; what a double-click on a case file runs)\n";
  for (const cli::Command* c : cli::commands()) out += c->usage;
  return out +
         "  rehearse --help | --version      (the version with its git revision)\n\n"
         "GUI options: --screenshot PNG (save the window and quit), --software (no OpenGL), --opengl (OpenGL even\n"
         "  through a software rasteriser such as llvmpipe, which is otherwise not used), --language fr|en (the\n"
         "  interface's language; by default the system's), --no-recover (do not offer the autosaved case)\n"
         "Mesh formats: .msh (Gmsh 1, 2.2, 4.1), .vtk (legacy), .vtu, .mesh (Medit), .obj .stl .ply .off .gltf .glb.\n"
         "Segmentations (label images): .nrrd .nhdr .nii .nii.gz .mha .mhd .inr .inr.gz.\n"
         "Lengths are metres unless --unit says otherwise.\n";
}

int runCli(const std::vector<std::string>& args, bool& handled) {
  handled = true;
  if (args.size() < 2 || args[1] == "open" ||
      (args[1].rfind("--", 0) == 0 && args[1] != "--help" && args[1] != "--version" && args[1] != "-h")) {
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
      std::printf("rehearse %s (%s)\n", REHEARSE_VERSION, REHEARSE_REVISION);
      return 0;
    }
    for (const cli::Command* c : cli::commands()) {
      if (c->name != cmd) continue;
      // `rehearse NAME --help`: its usage and its declared options.
      if (std::find(args.begin() + 2, args.end(), "--help") != args.end() ||
          std::find(args.begin() + 2, args.end(), "-h") != args.end()) {
        std::printf("%s", cli::commandHelp(*c).c_str());
        return 0;
      }
      return c->run(args);
    }
    throw cli::UsageError("unknown command '" + cmd + "'; see 'rehearse --help'");
  } catch (const cli::UsageError& e) {
    std::fprintf(stderr, "rehearse: %s\n", e.what());
    return 2;
  } catch (const imaging::AppearanceCancelled&) {
    std::fprintf(stderr, "rehearse: cancelled\n");
    return 130;
  } catch (const simcore::Cancelled&) {
    std::fprintf(stderr, "rehearse: cancelled\n");
    return 130;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "rehearse: error: out of memory; try a smaller mesh or target\n");
    return 1;
  } catch (const std::filesystem::filesystem_error& e) {
    // In our words, not the library's ("filesystem error: status: ... [path]").
    std::fprintf(stderr, "rehearse: error: cannot access %s: %s\n", e.path1().string().c_str(),
                 e.code().message().c_str());
    return 1;
  } catch (const nlohmann::json::exception& e) {
    std::fprintf(stderr,
                 "rehearse: error: a JSON input is not in the expected form (%s); see \"File formats\" in the README\n",
                 e.what());
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
