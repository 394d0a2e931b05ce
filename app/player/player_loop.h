#pragma once
// The one player loop, in a window or headless, and the scene it plays: a recorded video
// (player.cpp), the car on a recorded street (augmented_player.cpp) or on a live rig
// (live_player.cpp). The loop owns the window, the free look, the overlay, screenshots, --trace and
// the headless frame files; a scene owns its clock, its keys, its picture and its figures.
#include <array>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "app/ar/car_controller.h"
#include "app/player/player.h"
#include "app/player/view_controller.h"

namespace odvr::app {

class PlayerScene {
 public:
  virtual ~PlayerScene() = default;

  // Window. GLFW's swap interval: 1 paces a video to the display, 0 lets a frame take what it takes.
  virtual int SwapInterval() const { return 0; }
  // A key pressed since the last loop, other than the loop's own (+/- zoom, F1, F12).
  virtual void Key(int glfw_key) { (void)glfw_key; }
  // dt seconds of wall time have passed; `held(key)` says whether a key is down (never while
  // ImGui takes text). `look` is the loop's free look, which a scene's keys may turn.
  virtual void Advance(double dt, const std::function<bool(int)>& held, ViewController* look) = 0;
  // Draws the scene as `look` sees it into the window's back buffer, width x height pixels.
  virtual void Draw(int width, int height, const ViewController& look) = 0;
  // The overlay's lines for the frame just drawn (shown, and printed by --trace), then the ImGui
  // controls and coloured lines under them.
  virtual std::vector<std::string> Overlay(const ViewState& look) const = 0;
  virtual void OverlayControls() {}
  // Further ImGui windows, drawn while the overlay is shown; `overlay` is its corners (x0 y0 x1 y1).
  virtual void Panels(int width, const std::array<int, 4>& overlay) { (void)width, (void)overlay; }
  // Whether the picture on screen is the one a screenshot asked for now should show (a paused
  // video's frame after a step or a seek arrives a few loops later).
  virtual bool ShowsTheAskedFrame() const { return true; }
  // The scene's fields of a --trace line, beside the loop's (event, file, size, look, overlay).
  virtual nlohmann::json Trace() const = 0;

  // The run is over (window closed, frames written): the scene writes its report.
  virtual void Finish() {}

  // Headless. The frames a run without --frames writes.
  virtual int HeadlessFrameCount() const = 0;
  // Frame i, seen with `look` (--yaw, --pitch, --fov), width x height, written to `png`.
  virtual void WriteHeadlessFrame(int i, int width, int height, const ViewState& look,
                                  const std::filesystem::path& png) = 0;
};

// The car's keys, WASD or the arrows, held on top of a scripted input.
CarInput WithHeldCarKeys(CarInput scripted, const std::function<bool(int)>& held);

using SceneFactory = std::function<std::unique_ptr<PlayerScene>()>;

// Opens a window titled `title`, makes the scene in its GL context and plays it until the window
// closes (or options.quit_after_s). Returns the frames shown.
long RunWindowLoop(const PlayerOptions& options, const std::string& title, const SceneFactory& make_scene);

// Makes the scene in a headless GL context and writes options.headless_frames frames (else the
// scene's count) to options.out_dir as frame_NNNNNN.png. Returns the frames written.
long RunHeadlessLoop(const PlayerOptions& options, const SceneFactory& make_scene);

// One of the two, filling what every player's report says of its run (PlayerReport, LiveReport):
// the mode, the frames shown and, headless, where they went.
template <typename Report>
void RunPlayerLoop(const PlayerOptions& options, bool window, const std::string& title, const SceneFactory& make_scene,
                   Report* report) {
  report->mode = window ? "window" : "headless";
  if (!window) report->output_dir = options.out_dir;
  report->frames_shown = window ? RunWindowLoop(options, title, make_scene) : RunHeadlessLoop(options, make_scene);
}

}  // namespace odvr::app
