#include "app/player/player_loop.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "app/player/window_input.h"
#include "core/size_text.h"
#include "engine/gl/context.h"

namespace odvr::app {
namespace {

using Clock = std::chrono::steady_clock;

// The overlay window at the top left: the scene's lines, then its controls. Returns its corners.
std::array<int, 4> DrawOverlay(const std::vector<std::string>& lines, PlayerScene* scene) {
  ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.6f);
  ImGui::Begin("odvr", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  for (const auto& line : lines) ImGui::TextUnformatted(line.c_str());
  scene->OverlayControls();
  const ImVec2 at = ImGui::GetWindowPos(), size = ImGui::GetWindowSize();
  ImGui::End();
  return {static_cast<int>(at.x), static_cast<int>(at.y), static_cast<int>(at.x + size.x),
          static_cast<int>(at.y + size.y)};
}

// What a --trace line says about the loop; the scene adds its own fields.
nlohmann::json TraceLine(bool ready, const std::string& shot, int width, int height, const ViewState& look,
                         bool overlay_shown, const std::vector<std::string>& overlay, const PlayerScene& scene) {
  nlohmann::json j{{"event", ready ? "screenshot" : "ready"},
                   {"file", shot},
                   {"size", {width, height}},
                   {"yaw", look.yaw_deg},
                   {"pitch", look.pitch_deg},
                   {"fov", look.fov_deg},
                   {"overlay_shown", overlay_shown},
                   {"overlay", overlay}};
  j.update(scene.Trace());
  return j;
}

}  // namespace

CarInput WithHeldCarKeys(CarInput input, const std::function<bool(int)>& held) {
  input.forward |= held(GLFW_KEY_W) || held(GLFW_KEY_UP);
  input.backward |= held(GLFW_KEY_S) || held(GLFW_KEY_DOWN);
  input.left |= held(GLFW_KEY_A) || held(GLFW_KEY_LEFT);
  input.right |= held(GLFW_KEY_D) || held(GLFW_KEY_RIGHT);
  return input;
}

long RunWindowLoop(const PlayerOptions& options, const std::string& title, const SceneFactory& make_scene) {
  gl::WindowContext window(options.width, options.height, title);
  GLFWwindow* w = window.window();
  const std::unique_ptr<PlayerScene> scene = make_scene();
  glfwSwapInterval(scene->SwapInterval());
  std::pair<int, int> resize{0, 0};
  if (!options.resize.empty()) resize = ParseSize(options.resize, "--resize");

  ImGuiSession imgui(w);
  WindowInput input(w);
  ViewController look;
  look.Set(options.view);
  long frames_shown = 0;
  bool show_overlay = true, ready = false, resized = false;
  int shots = 0;
  bool screenshot_pending = false;  // F12 pressed, the shot not yet taken
  auto screenshot_requested = Clock::now();
  const auto start = Clock::now();
  auto previous = start;
  std::vector<std::string> overlay;
  while (!glfwWindowShouldClose(w)) {
    glfwPollEvents();
    const auto now = Clock::now();
    const double dt = std::chrono::duration<double>(now - previous).count();
    const double t = std::chrono::duration<double>(now - start).count();
    previous = now;

    // Input: drag to look, scroll or +/- to zoom, F1 the overlay, F12 a screenshot; the rest is
    // the scene's.
    int fb_w = 0, fb_h = 0;
    glfwGetFramebufferSize(w, &fb_w, &fb_h);
    const WindowInput::Events in = input.Take();
    look.Drag(in.drag_dx, in.drag_dy, std::max(fb_h, 1));
    look.Scroll(in.scroll);
    for (const int key : in.keys) {
      if (key == GLFW_KEY_EQUAL || key == GLFW_KEY_KP_ADD) {
        look.Scroll(1);
      } else if (key == GLFW_KEY_MINUS || key == GLFW_KEY_KP_SUBTRACT) {
        look.Scroll(-1);
      } else if (key == GLFW_KEY_F1) {
        show_overlay = !show_overlay;
      } else if (key == GLFW_KEY_F12) {
        if (!screenshot_pending) screenshot_requested = Clock::now();
        screenshot_pending = true;
      } else {
        scene->Key(key);
      }
    }
    const bool keys_free = !ImGui::GetIO().WantTextInput;
    scene->Advance(
        dt, [&](int key) { return keys_free && glfwGetKey(w, key) == GLFW_PRESS; }, &look);

    // A minimized or 1x1 window still runs the loop; it just draws nothing worth seeing.
    if (fb_w > 0 && fb_h > 0) {
      scene->Draw(fb_w, fb_h, look);
      overlay = scene->Overlay(look.state());
      imgui.NewFrame();
      if (show_overlay) scene->Panels(fb_w, DrawOverlay(overlay, scene.get()));
      imgui.Render();
    }
    ++frames_shown;
    if (resize.first > 0 && !resized && t > 0.5 * options.quit_after_s) {
      glfwSetWindowSize(w, resize.first, resize.second);
      resized = true;
    }
    const bool quitting = options.quit_after_s > 0 && t > options.quit_after_s;
    if (quitting && !options.screenshot.empty() && fb_w > 0 && fb_h > 0)
      WriteWindowScreenshot(options.screenshot, fb_w, fb_h);
    // A screenshot shows the frame the scene was asked for: a paused video waits for the decoder to
    // bring it, which a step back (a seek) can take longer than a loop: CI under ASan shot frame 11
    // after '.' '.' ',' from 9, frame 10 arriving a loop later. After 5 s (a frame that never
    // comes) it shows what is on screen.
    const bool frame_shown =
        scene->ShowsTheAskedFrame() || Clock::now() - screenshot_requested > std::chrono::seconds(5);
    std::string shot;
    if (screenshot_pending && frame_shown && fb_w > 0 && fb_h > 0) {
      screenshot_pending = false;
      shot = ScreenshotPath(options.screenshot, ++shots);
      WriteWindowScreenshot(shot, fb_w, fb_h);
      if (!options.trace) spdlog::info("screenshot: {}", shot);
    }
    glfwSwapBuffers(w);
    // After the swap: a test that waits for "ready" sends its input to a window that is showing.
    if (options.trace && (!ready || !shot.empty()) && fb_w > 0 && fb_h > 0) {
      PrintTrace(TraceLine(ready, shot, fb_w, fb_h, look.state(), show_overlay, overlay, *scene).dump());
      ready = true;
    }
    if (quitting) glfwSetWindowShouldClose(w, GLFW_TRUE);
  }
  scene->Finish();
  return frames_shown;
}

long RunHeadlessLoop(const PlayerOptions& options, const SceneFactory& make_scene) {
  gl::HeadlessContext context;
  const std::unique_ptr<PlayerScene> scene = make_scene();
  std::filesystem::create_directories(options.out_dir);
  const int frames = options.headless_frames > 0 ? options.headless_frames : scene->HeadlessFrameCount();
  for (int i = 0; i < frames; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", i);
    scene->WriteHeadlessFrame(i, options.width, options.height, options.view,
                              std::filesystem::path(options.out_dir) / name);
  }
  scene->Finish();
  return frames;
}

}  // namespace odvr::app
