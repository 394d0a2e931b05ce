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
#include "app/flags/command_flags.h"
#include "core/size_text.h"

namespace odvr::app {

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

// The farthest --car-start along a camera path: no pose lies beyond 1000 km (augmented_scene.cpp).
constexpr double kFarthestCarStartM = 1e6;

// Runs the whole command line; what main() returns. Errors end here as one line on stderr:
// exit 2 for usage errors (unknown command, bad flag or value), 1 for everything else.
int Main(int argc, char** argv);

}  // namespace odvr::app
