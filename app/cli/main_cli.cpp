#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>

#include "app/cli/commands.h"
#include "core/error.h"

namespace odvr::app {

const std::vector<CommandSpec>& Commands() {
  static const std::vector<CommandSpec> commands = {
      {"info", "Print the OpenGL context, its compute limits and library versions", AddInfo},
      {"play", "Play a 360° video with free look (headless: render frames to PNG)", AddPlay},
      {"stitch", "Stitch rig frames into equirectangular frames (GPU or CPU), with per-frame times", AddStitch},
      {"light", "Turn an equirect frame into the multiscale SG lighting model, with its errors", AddLight},
      {"render", "Render a glTF car lit by an equirect frame (SG triple product), with its shadow, over the frame",
       AddRender},
      {"reconstruct", "Structure from motion of the rig: trajectory, sparse model, road plane, metric scale",
       AddReconstruct},
      {"export", "Write an augmented clip: the car driven along a path through the video, lit by it", AddExport},
      {"bench", "Benchmarks: speed beside error, as tables and plots (in ./odvr-bench unless --out says)", AddBench},
  };
  return commands;
}

namespace {

std::string OneLine(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  std::replace(text.begin(), text.end(), '\n', ' ');
  return text;
}

void SetUpLogging(bool verbose, bool quiet) {
  auto logger = spdlog::stderr_color_mt("odvr");
  logger->set_pattern("%^[%l]%$ %v");
  spdlog::set_default_logger(logger);
  spdlog::set_level(quiet ? spdlog::level::err : verbose ? spdlog::level::debug : spdlog::level::info);
}

}  // namespace

int Main(int argc, char** argv) {
  CLI::App app{"odvr: an augmented-reality 360° video player that lights a virtual car with the video's own light",
               "odvr"};
  app.set_version_flag("--version", ODVR_VERSION);
  bool verbose = false, quiet = false;
  app.add_flag("-v,--verbose", verbose, "Log more (debug level)");
  app.add_flag("-q,--quiet", quiet, "Log errors only");
  app.footer(
      "Examples:\n"
      "  odvr                                   play the demo street with its car\n"
      "  odvr clip.mp4                          play a 360° video (mono or stereo), free look\n"
      "  odvr play clip.mp4 --car car.glb       drive a car in it: the clip is reconstructed first, once\n"
      "  odvr reconstruct --video clip.mp4 --camera-height 1.6 --out recon/\n"
      "  odvr export --video clip.mp4 --trajectory recon/trajectory.json --car car.glb --out drive.mp4\n"
      "odvr COMMAND --help shows a command's options and their defaults.");
  app.fallthrough();
  app.require_subcommand(0, 1);

  std::vector<std::pair<CLI::App*, CommandFn>> runners;
  for (const auto& spec : Commands()) {
    CLI::App* sub = app.add_subcommand(spec.name, spec.summary);
    runners.emplace_back(sub, spec.add(sub));
  }

  // `odvr clip.mp4` plays the clip, as `mpv clip.mp4` does: a first argument that is no command
  // but an existing file or folder is `play`'s video. CLI11 would call any other unknown command
  // an "unexpected argument"; say what it is.
  std::vector<char*> args(argv, argv + argc);
  static char play_name[] = "play";
  if (argc > 1 && argv[1][0] != '-') {
    const std::string name = argv[1];
    const bool known = std::any_of(Commands().begin(), Commands().end(), [&](const auto& c) { return c.name == name; });
    std::error_code ec;
    if (!known && std::filesystem::exists(name, ec)) {
      args.insert(args.begin() + 1, play_name);
    } else if (!known) {
      std::string list;
      for (const auto& c : Commands()) list += (list.empty() ? "" : ", ") + c.name;
      std::cerr << "odvr: '" << name << "' is neither a command nor a file to play (commands: " << list
                << "; see odvr --help)\n";
      return 2;
    }
  }

  try {
    app.parse(static_cast<int>(args.size()), args.data());
  } catch (const CLI::Success& e) {
    return app.exit(e);  // --help, --version
  } catch (const CLI::ParseError& e) {
    std::cerr << "odvr: " << OneLine(e.what()) << " (see odvr --help)\n";
    return 2;
  }
  SetUpLogging(verbose, quiet);

  try {
    for (auto& [sub, run] : runners) {
      if (sub->parsed()) return run();
    }
    // No command: play the default demo, as the README's first command does.
    CLI::App* play = app.get_subcommand("play");
    for (auto& [sub, run] : runners)
      if (sub == play) return run();
    std::cout << app.help();
    return 0;
  } catch (const UsageError& e) {
    std::cerr << "odvr: " << OneLine(e.what()) << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "odvr: error: " << OneLine(e.what()) << "\n";
    return 1;
  }
}

}  // namespace odvr::app
