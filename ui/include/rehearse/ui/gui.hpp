#pragma once
namespace rehearse::ui {
/// Starts the GUI: `rehearse [open CASE] [--screenshot PNG] [--software]`. Returns the exit code.
int runGui(int argc, char** argv);
}  // namespace rehearse::ui
