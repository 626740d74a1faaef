#pragma once
// Headless command line (no Qt): rehearse phantom | mesh | info | --help | --version.
#include "rehearse/app/review.hpp"

#include <string>
#include <vector>

namespace rehearse::app {

/// Runs a command-line sub-command. Sets `handled` false when the arguments are for the GUI
/// (no arguments, `open CASE`, or GUI options), in which case nothing was done.
int runCli(const std::vector<std::string>& args, bool& handled);

std::string usage();

}  // namespace rehearse::app
