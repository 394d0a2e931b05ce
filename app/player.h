#pragma once
// `odvr play`: the 360° frame around the viewer with free look, playback controls and an
// overlay of per-stage timings. With a display it opens a GLFW window; without one it renders
// frames to PNG files and says where.
#include <string>

#include "app/view_controller.h"

namespace odvr::app {

struct PlayerOptions {
  std::string video;  // anything capture::OpenSource accepts (an equirect video, image sequence)
  int width = 1280, height = 720;
  bool headless = false;    // forced headless; also chosen when no display is available
  int headless_frames = 0;  // 0 = every frame of the video
  std::string out_dir = "odvr_play_frames";
  double exposure = 1.0;
  bool loop = true;
  ViewState view;
  double quit_after_s = 0;  // window mode: close by itself after this long (tests, demos)
  std::string screenshot;   // window mode: PNG of the last frame shown before quitting
  void Check() const;       // throws odvr::UsageError
};

// Per-stage milliseconds of the last frame (the overlay and --json).
struct FrameTimings {
  double decode_ms = 0, upload_ms = 0, render_ms = 0, total_ms = 0;
};

struct PlayerReport {
  long frames_shown = 0;
  std::string mode;  // "window" or "headless"
  std::string output_dir;
  double median_total_ms = 0;
  FrameTimings last;
};

PlayerReport RunPlayer(const PlayerOptions& options);

// True when a window can be opened (an X or Wayland display is set).
bool DisplayAvailable();

}  // namespace odvr::app
