#pragma once
// What the sub-commands share (one file per sub-command family beside this one, cli.cpp dispatches): a
// sub-command's declaration (its usage block, its options with a line of help each: the parser accepts exactly
// those and `rehearse NAME --help` prints them), the option parser, number and list parsers, the organ model from
// its options, reports and the summary of the steps' outcomes.
#include "rehearse/app/review.hpp"

#include <rehearse/simcore/integrator.hpp>
#include <rehearse/simcore/mesh.hpp>
#include <rehearse/simcore/scene.hpp>

#include <nlohmann/json_fwd.hpp>

#include <Eigen/Core>

#include <cstddef>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace rehearse::app::cli {

/// A mistake in the command line (exit 2, with the sentence).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One option of a sub-command, declared once.
struct OptionSpec {
  std::string name;   ///< without the leading dashes
  std::string value;  ///< the value's placeholder ("FILE", "N"); empty for a flag (it takes no value)
  std::string help;   ///< one line
};

/// How a sub-command runs.
using CommandRun = std::function<int(const std::vector<std::string>& args)>;

/// A sub-command: its block of `rehearse --help` (synopsis and description), its options and what runs it.
struct Command {
  std::string name;
  std::string usage;  ///< the lines `rehearse --help` shows for it (each "  ...\n")
  std::vector<OptionSpec> options;
  CommandRun run;
};

/// Option lists one after the other (shared groups and a command's own).
std::vector<OptionSpec> joined(std::vector<OptionSpec> first, const std::vector<OptionSpec>& then);

/// The options every command that builds an organ model takes (--scene, --preset, --mesh, the material...).
const std::vector<OptionSpec>& modelOptions();

/// The sub-commands, in the order `rehearse --help` lists them.
const std::vector<const Command*>& commands();
/// `rehearse NAME --help`: the command's usage block and one line per option.
std::string commandHelp(const Command& c);

using Options = std::map<std::string, std::string>;
/// Parses "--key value" (or "--key=value") pairs from args[from] on; only the command's declared options, a flag
/// without a value.
Options parseOptions(const std::vector<std::string>& args, std::size_t from, const Command& command);

long parseCount(const std::string& s, const char* what, long lo, long hi);
double parseNumber(const std::string& s, const char* what);
Eigen::Vector3d parseVector(const std::string& s, const char* what);
/// --fixed-nodes: a list of node indices ("3 39 64" or "3,39,64") or a file holding one.
std::vector<int> parseNodes(const std::string& s);
/// The organ model of a command: --scene, --preset or --mesh, then the material flags, --fixed-nodes and --gravity.
simcore::Scene modelFromOptions(Options& o, const char* command, simcore::Mesh* surfaceIn = nullptr);

/// A JSON report, written atomically (a reader never sees half of it).
void writeReport(const std::string& path, const nlohmann::json& report);
/// {"converged": n, "inexact": n, ...}: the reports' "statuses".
nlohmann::json statusCounts(const std::vector<const simcore::StepReport*>& reports);
/// The steps' outcomes on stdout (and stderr when one did not converge); the exit code (0, 3 or 5).
int statusSummary(const std::vector<const simcore::StepReport*>& reports);
/// Settings and materials outside the ranges every input path holds them to (simcore/input_ranges.hpp): a
/// UsageError with the sentence.
void refuseOutOfRange(const simcore::SimulationSettings& settings, const simcore::MaterialParams& fallback,
                      const std::map<int, simcore::MaterialParams>& byLabel);

// The commands, one declaration each (in their family's file).
const Command& phantomCommand();
const Command& meshCommand();
const Command& infoCommand();
const Command& simulateCommand();
const Command& registerCommand();
const Command& appearanceCommand();
const Command& composeCommand();
const Command& gestureCommand();
const Command& replayCommand();
const Command& publishCommand();
const Command& deviceCommand();

}  // namespace rehearse::app::cli
