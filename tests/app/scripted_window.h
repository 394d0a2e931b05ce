#pragma once
// `odvr play` in a real window under Xvfb, driven by real X input from xdotool (a mouse drag,
// the wheel, key presses), read back through its screenshots (F12) and its --trace lines.
// Each input step ends with F12, and the script waits for that screenshot's trace line before
// the next step: X delivers a client's events in order, so the screenshot shows every earlier
// input applied, and no step depends on a sleep being long enough.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/app/run_odvr.h"

namespace odvr::testing {

// The first of the tools a scripted window needs that is not installed ("" when all are).
inline std::string MissingWindowTool() {
  for (const char* tool : {"xvfb-run", "xdotool"})
    if (std::system(("command -v " + std::string(tool) + " >/dev/null 2>&1").c_str()) != 0) return tool;
  return "";
}

// One player under its own Xvfb server. Shot(input) sends `input` (xdotool commands; $W is the
// player's window) followed by F12; Run() returns the trace lines: [0] "ready", then one per Shot.
class ScriptedWindow {
 public:
  ScriptedWindow(std::filesystem::path dir, std::string play_args)
      : dir_(std::move(dir)), args_(std::move(play_args)) {}
  void Shot(const std::string& input) { steps_.push_back(input); }

  std::vector<nlohmann::json> Run() {
    std::ostringstream s;
    s << "set -u\ncd '" << dir_.string()
      << "'\n"
      // Leak checking off for the player only, as in RunPlayGL: GLX driver allocations.
      << "ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 " << ODVR_BINARY << " play " << args_
      << " --trace --screenshot '" << (dir_ / "final.png").string() << "' >trace.jsonl 2>player.log &\n"
      << "P=$!\n"
      << "fail() { echo \"FAIL: $*\"; cat player.log; kill $P 2>/dev/null; exit 3; }\n"
      // Polls for the player's answer; the bound (120 s) only matters when it never comes.
      << "await() { for i in $(seq 6000); do\n"
      << "  [ \"$(grep -c '^{' trace.jsonl)\" -ge \"$1\" ] && return 0\n"
      << "  kill -0 $P 2>/dev/null || fail \"the player exited before trace line $1\"\n"
      << "  sleep 0.02; done; fail \"no trace line $1\"; }\n"
      << "await 1\n"
      << "W=$(xdotool search --sync --onlyvisible --name '^odvr' | head -1)\n"
      << "[ -n \"$W\" ] || fail 'no odvr window'\n"
      << "xdotool windowfocus $W\n";
    for (std::size_t i = 0; i < steps_.size(); ++i)
      s << "xdotool " << steps_[i] << " key F12 || fail 'xdotool: " << i << "'\nawait " << i + 2 << "\n";
    s << "xdotool key Escape\nwait $P\necho \"player exit $?\"\n";
    const std::filesystem::path script = dir_ / "drive.sh";
    std::ofstream(script) << s.str();
    // Key auto-repeat pushed 30 s out: on a loaded machine the server can see a key held past its
    // 660 ms delay between xdotool's press and release. (It was first taken for why '.' '.' ','
    // read frame + 2 in one CI run; the cause was the screenshot not waiting for the seek back,
    // see shot 13 of PlayerWindowGL.DragWheelAndKeysTurnZoomAndStepTheView.)
    const std::string cmd = "xvfb-run -a -s '-screen 0 1280x720x24 -ardelay 30000' bash '" + script.string() + "' 2>&1";
    FILE* pipe = ::popen(cmd.c_str(), "r");
    char buf[4096];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) log_.append(buf, n);
    ::pclose(pipe);
    std::vector<nlohmann::json> lines;
    std::istringstream trace(odvr::testing::ReadText(dir_ / "trace.jsonl"));
    for (std::string line; std::getline(trace, line);)
      if (!line.empty() && line[0] == '{') lines.push_back(nlohmann::json::parse(line));
    return lines;
  }
  const std::string& log() const { return log_; }

 private:
  std::filesystem::path dir_;
  std::string args_;
  std::vector<std::string> steps_;
  std::string log_;
};

}  // namespace odvr::testing
