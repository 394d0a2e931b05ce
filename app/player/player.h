#pragma once
// `odvr play`: the 360° frame around the viewer with free look, playback controls and an
// overlay of per-stage timings. With a display it opens a GLFW window; without one it renders
// frames to PNG files and says where.
#include <string>
#include <vector>

#include "app/player/view_controller.h"

namespace odvr::app {

struct PlayerOptions {
  std::string video;            // anything capture::OpenSource accepts (an equirect video, image sequence)
  std::string stereo = "auto";  // OpenPlayableVideo's layout: auto, mono, top-bottom, side-by-side
  int width = 1280, height = 720;
  bool headless = false;                     // forced headless; also chosen when no display is available
  int headless_frames = 0;                   // 0 = every frame of the video
  std::string out_dir = "odvr_play_frames";  // run_play's default is the temporary directory's
  double exposure = 1.0;
  bool loop = true;
  ViewState view;
  double quit_after_s = 0;  // window mode: close by itself after this long (tests, demos)
  std::string screenshot;   // window mode: PNG of the last frame shown before quitting
  // Augmented mode (a car on the road), when `trajectory` is set (app/ar/augmented_scene.h).
  std::string trajectory, car;
  double car_start_m = -1;     // arc length along the camera path; < 0: the view distance
  double view_distance_m = 6;  // the viewer trails the car by this much
  std::string drive;           // scripted keys, e.g. "W:2s,A:1s" (headless, tests, demos)
  int lighting_levels = 4;     // HEALPix levels of the car's light
  int voxels = 64;             // visibility grid per side
  int supersample = 1;         // the car's samples per pixel along each axis (adaptive, 1..4)
  // render::RenderOptions::shading_rate for the car: 2 shades one pixel of each smooth 2×2 block
  // (a frame's time, not its picture: its error moves by a fraction of a per cent); 1 with
  // supersample > 1.
  int shading_rate = 2;
  bool panel = false;  // window, augmented: the car panel starts open
  bool trace = false;  // window: a JSON line on stdout when ready and per F12 screenshot
  std::string resize;  // window: WxH to resize to halfway through --quit-after (tests)
  void Check() const;  // throws odvr::UsageError
};

// Per-stage milliseconds of the last frame (the overlay and --json).
struct FrameTimings {
  double decode_ms = 0, upload_ms = 0, render_ms = 0, total_ms = 0;
  double lighting_ms = 0, readback_ms = 0, composite_ms = 0;  // augmented mode
};

// Augmented mode, per shown frame (for --json and the tests).
struct AugmentedFrameRecord {
  int view_frame = 0, light_frame = 0;
  double car_x = 0, car_z = 0;      // world (Y up)
  double car_px = -1, car_py = -1;  // projection of the car's centre
  int car_pixels = 0;
  bool at_stretch_end = false;  // AugmentedFrame::at_stretch_end
  std::string file;             // headless PNG
};

struct PlayerReport {
  long frames_shown = 0;
  std::string mode;  // "window" or "headless"
  std::string output_dir;
  double median_total_ms = 0;
  FrameTimings last;
  FrameTimings median;  // per stage
  std::vector<AugmentedFrameRecord> frames;
};

PlayerReport RunPlayer(const PlayerOptions& options);
// The car on the recorded street (app/player/augmented_player.cpp), in a window or headless: what
// RunPlayer plays when a trajectory is set.
PlayerReport RunAugmentedPlayer(const PlayerOptions& options, bool window);

// True when a window can be opened (an X or Wayland display is set).
bool DisplayAvailable();

}  // namespace odvr::app
