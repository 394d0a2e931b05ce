#pragma once
// The table of odvr subcommands. Each Add<X> declares its options on `sub` and returns the
// function that runs it: a thin wrapper over library calls, returning the process exit code.
#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <tuple>  // std::tie for ParseSize
#include <utility>
#include <vector>

#include "app/ar/demo_media.h"
#include "core/size_text.h"

namespace odvr::app {

using CommandFn = std::function<int()>;

struct CommandSpec {
  std::string name;
  std::string summary;
  std::function<CommandFn(CLI::App* sub)> add;
};

const std::vector<CommandSpec>& Commands();

CommandFn AddInfo(CLI::App* sub);
CommandFn AddPlay(CLI::App* sub);
CommandFn AddStitch(CLI::App* sub);
CommandFn AddLight(CLI::App* sub);
CommandFn AddRender(CLI::App* sub);
CommandFn AddReconstruct(CLI::App* sub);
CommandFn AddBench(CLI::App* sub);
CommandFn AddExport(CLI::App* sub);
CommandFn AddBenchLight(CLI::App* sub);
CommandFn AddBenchRender(CLI::App* sub);
CommandFn AddBenchStitch(CLI::App* sub);
CommandFn AddBenchReconstruct(CLI::App* sub);
CommandFn AddBenchPlayer(CLI::App* sub);
CommandFn AddBenchDecode(CLI::App* sub);

// --cones (1, 7, 19 or 37) as the renderer's hexagonal rings (0-3); throws UsageError otherwise.
int ConeRingsForCount(int cones);

// A flag that sets *value to `set_to`. Where CLI11's "!--flag" form prints "--flag{false}" in
// --help, this reads as the plain flag it is; a switch with an on and an off name is two of them.
CLI::Option* AddSetFlag(CLI::App* sub, const std::string& name, bool* value, bool set_to, const std::string& help);

// A command-line number in [min, max], finite: CLI::Range lets "nan" through (every comparison with
// it is false), and a value the command then took for "not given" used to pass silently.
CLI::Validator FiniteNumberIn(double min, double max);

// The farthest --car-start along a camera path: no pose lies beyond 1000 km (augmented_scene.cpp).
constexpr double kFarthestCarStartM = 1e6;

// Runs the whole command line; what main() returns. Errors end here as one line on stderr:
// exit 2 for usage errors (unknown command, bad flag or value), 1 for everything else.
int Main(int argc, char** argv);

}  // namespace odvr::app
