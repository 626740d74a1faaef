// rehearse: GUI by default, command-line sub-commands for headless work.
#include "cli.hpp"

#include <cstdio>
#include <string>
#include <vector>

#ifdef REHEARSE_WITH_GUI
#include "rehearse/ui/gui.hpp"
#endif

int main(int argc, char** argv) {
  std::vector<std::string> args(argv, argv + argc);
  bool handled = false;
  int code = rehearse::app::runCli(args, handled);
  if (handled) return code;
#ifdef REHEARSE_WITH_GUI
  return rehearse::ui::runGui(argc, argv);
#else
  std::fprintf(stderr,
               "rehearse: error: this build has no GUI (configured with REHEARSE_BUILD_GUI=OFF); use a sub-command, "
               "see --help\n");
  return 2;
#endif
}
