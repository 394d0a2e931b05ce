#pragma once
// `odvr play --live --rig RIG [--source SPEC]`: the live player (app/ar/live_scene.h) in a window,
// or headless to PNG frames as the recorded player does. A lost camera is said in the overlay
// (window) or on stderr once per event (headless), and the player goes on with the others.
#include <string>
#include <vector>

#include "app/ar/live_scene.h"
#include "app/player/player.h"

namespace odvr::app {

struct LivePlayOptions {
  // Reused from the recorded player: size, headless, frames, out_dir, exposure, view,
  // quit_after_s, screenshot, car, car_start_m (metres ahead of the rig), drive, levels, voxels.
  PlayerOptions player;
  std::string rig, source;
  std::string stitch_size = "1024x512";
  // The CPU stitcher by default: a software rasterizer, where no GPU is, runs the GPU path as
  // compute shaders on the same cores, with the cost of the emulation on top.
  std::string stitch_device = "cpu";
  bool no_car = false;
  static constexpr int kDefaultHeadlessFrames = 25;  // a live source never ends: one second's worth
};

struct LiveFrameRecord {
  long set_index = -1, source_frame = -1;
  int cameras_present = 0;
  bool new_set = false;
  double car_px = -1, car_py = -1;
  int car_pixels = 0;
  long sets_skipped = 0;  // older sets passed over to show the newest
  LiveTimings ms;
  std::string file;  // headless PNG
};

struct LiveReport {
  std::string mode;  // "window" or "headless"
  std::string output_dir, source;
  long frames_shown = 0;
  LiveTimings median, last;
  std::vector<LiveFrameRecord> frames;
  std::vector<std::string> messages;  // every event said, in order
  std::vector<std::string> lost_cameras;
  capture::SourceStats source_stats;
};

LiveReport RunLivePlayer(const LivePlayOptions& options);
// Runs it and prints as `odvr play` does (a line, or with `json` a JSON report); returns 0.
int RunLivePlay(LivePlayOptions options, bool json);

}  // namespace odvr::app
