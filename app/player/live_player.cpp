// The live player's loops (app/player/live_player.h): headless to PNG frames, or a window driven by
// WASD/arrows with the lost-camera messages in its overlay.
#define GLFW_INCLUDE_NONE
#include "app/player/live_player.h"
#include "app/ar/demo_media.h"

#include <GLFW/glfw3.h>
#include <imgui.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "app/player/view_controller.h"
#include "app/player/window_input.h"
#include "core/error.h"
#include "core/size_text.h"
#include "core/statistics.h"
#include "engine/gl/context.h"
#include "engine/gl/objects.h"
#include "engine/image/image_io.h"

namespace odvr::app {
namespace {

using Clock = std::chrono::steady_clock;

LiveSceneOptions SceneOptions(const LivePlayOptions& o) {
  const PlayerOptions& p = o.player;
  LiveSceneOptions s;
  s.rig = o.rig;
  s.source = o.source;
  s.car = o.no_car ? "" : p.car;
  if (p.car_start_m >= 0) s.car_ahead_m = p.car_start_m;
  std::tie(s.stitch_width, s.stitch_height) = ParseSize(o.stitch_size, "--stitch-size");
  if (o.stitch_device != "cpu" && o.stitch_device != "gpu")
    throw UsageError("--stitch-device", "expects cpu or gpu, got '" + o.stitch_device + "'");
  s.stitch_device = o.stitch_device == "gpu" ? capture::StitchDevice::kGpu : capture::StitchDevice::kCpu;
  s.lighting_levels = p.lighting_levels;
  s.voxel_resolution = p.voxels;
  s.supersample = p.supersample;
  s.shading_rate = p.shading_rate;
  s.vfov_deg = std::clamp(p.view.fov_deg, 30.0, 150.0);
  s.exposure = p.exposure;
  return s;
}

LiveFrameRecord Record(const LiveFrame& f) {
  LiveFrameRecord r;
  r.set_index = f.set_index;
  r.source_frame = f.source_frame;
  r.cameras_present = f.cameras_present;
  r.new_set = f.new_set;
  r.car_px = f.car_in_front ? f.car_pixel.x : -1;
  r.car_py = f.car_in_front ? f.car_pixel.y : -1;
  r.car_pixels = f.car_pixels;
  r.sets_skipped = f.sets_skipped;
  r.ms = f.ms;
  return r;
}

LiveTimings Medians(const std::vector<LiveTimings>& all) {
  auto median = [&](double LiveTimings::*field) {
    std::vector<double> v;
    for (const auto& t : all) v.push_back(t.*field);
    return Median(v);
  };
  LiveTimings m;
  for (auto field : {&LiveTimings::capture_wait, &LiveTimings::stitch, &LiveTimings::lighting, &LiveTimings::render,
                     &LiveTimings::readback, &LiveTimings::composite, &LiveTimings::total})
    m.*field = median(field);
  return m;
}

void Finish(const LiveScene& scene, const std::vector<LiveTimings>& all, LiveReport* report) {
  report->median = Medians(all);
  if (!all.empty()) report->last = all.back();
  report->lost_cameras = scene.lost_cameras();
  report->source_stats = scene.source_stats();
  report->source = scene.source_description();
}

LiveReport RunLiveHeadless(const LivePlayOptions& o) {
  const PlayerOptions& p = o.player;
  gl::HeadlessContext context;
  LiveScene scene(SceneOptions(o));
  const auto script = p.drive.empty() ? std::vector<DriveStep>{} : ParseDriveScript(p.drive);
  const double dt = 1.0 / 25;  // the script advances one rig frame per shown frame
  const int frames = p.headless_frames > 0 ? p.headless_frames : LivePlayOptions::kDefaultHeadlessFrames;
  LiveReport report;
  report.mode = "headless";
  report.output_dir = p.out_dir;
  std::filesystem::create_directories(p.out_dir);
  std::vector<LiveTimings> all;
  const AugmentedView view{p.view.yaw_deg, p.view.pitch_deg, 0, true};
  for (int i = 0; i < frames; ++i) {
    if (i > 0) scene.Drive(DriveInputAt(script, (i - 1) * dt), dt);
    const LiveFrame f = scene.Render(p.width, p.height, view);
    // Nobody watches a headless run: say each event once, where a user running it would look.
    for (auto& m : scene.TakeMessages()) {
      std::cerr << "odvr play --live: " << m << "\n";
      report.messages.push_back(std::move(m));
    }
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", i);
    const auto path = std::filesystem::path(p.out_dir) / name;
    image::SaveImage(path, f.image);
    all.push_back(f.ms);
    report.frames.push_back(Record(f));
    report.frames.back().file = path.string();
    ++report.frames_shown;
  }
  Finish(scene, all, &report);
  return report;
}

LiveReport RunLiveWindow(const LivePlayOptions& o) {
  const PlayerOptions& p = o.player;
  gl::WindowContext window(p.width, p.height, "odvr live — " + o.rig);
  GLFWwindow* w = window.window();
  LiveSceneOptions scene_options = SceneOptions(o);
  scene_options.composite_on_gpu = true;  // with the car: drawn where it was rendered, no read-back
  LiveScene scene(scene_options);
  const auto script = p.drive.empty() ? std::vector<DriveStep>{} : ParseDriveScript(p.drive);
  glfwSwapInterval(0);  // the cameras pace the loop

  ImGuiSession imgui(w);
  WindowInput input(w);

  LiveReport report;
  report.mode = "window";
  std::vector<LiveTimings> all;
  // The same free look as the other players, as an offset from looking at the car.
  ViewController look;
  look.Set({p.view.yaw_deg, p.view.pitch_deg, p.view.fov_deg});
  FramePresenter presenter;
  const auto start = Clock::now();
  auto previous = start;
  LiveFrame frame;
  while (!glfwWindowShouldClose(w)) {
    glfwPollEvents();
    const auto now = Clock::now();
    const double dt = std::chrono::duration<double>(now - previous).count();
    const double t = std::chrono::duration<double>(now - start).count();
    previous = now;
    const bool keys_free = !ImGui::GetIO().WantTextInput;
    auto held = [&](int a, int b) {
      return keys_free && (glfwGetKey(w, a) == GLFW_PRESS || glfwGetKey(w, b) == GLFW_PRESS);
    };
    CarInput car_input = DriveInputAt(script, t);
    car_input.forward |= held(GLFW_KEY_W, GLFW_KEY_UP);
    car_input.backward |= held(GLFW_KEY_S, GLFW_KEY_DOWN);
    car_input.left |= held(GLFW_KEY_A, GLFW_KEY_LEFT);
    car_input.right |= held(GLFW_KEY_D, GLFW_KEY_RIGHT);
    scene.Drive(car_input, dt);

    int fb_w = 0, fb_h = 0;
    glfwGetFramebufferSize(w, &fb_w, &fb_h);
    const WindowInput::Events in = input.Take();
    look.Drag(in.drag_dx, in.drag_dy, std::max(fb_h, 1));
    look.Scroll(in.scroll);
    for (const int key : in.keys) {
      if (key == GLFW_KEY_EQUAL || key == GLFW_KEY_KP_ADD) look.Scroll(1);
      if (key == GLFW_KEY_MINUS || key == GLFW_KEY_KP_SUBTRACT) look.Scroll(-1);
    }

    if (fb_w > 0 && fb_h > 0) {
      const int rw = std::max(fb_w, 16), rh = std::max(fb_h, 16);
      const AugmentedView view{look.state().yaw_deg, look.state().pitch_deg, look.state().fov_deg, true};
      frame = scene.Render(rw, rh, view);
      for (auto& m : scene.TakeMessages()) report.messages.push_back(std::move(m));
      all.push_back(frame.ms);
      report.frames.push_back(Record(frame));
      if (frame.image.empty())
        presenter.Show(scene.composite(), static_cast<float>(p.exposure), fb_w, fb_h);
      else
        presenter.Show(frame.image, fb_w, fb_h);

      imgui.NewFrame();
      ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
      ImGui::SetNextWindowBgAlpha(0.6f);
      ImGui::Begin("odvr live", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
      ImGui::Text("set %ld  cameras %d / %d   car %.1f km/h", frame.set_index, frame.cameras_present,
                  scene.rig().camera_count(), scene.car().state().speed_mps * 3.6);
      ImGui::Text("wait %.1f  stitch %.1f  lighting %.1f  render %.1f  composite %.1f ms", frame.ms.capture_wait,
                  frame.ms.stitch, frame.ms.lighting, frame.ms.render, frame.ms.composite);
      ImGui::Text("total %.1f ms  (%.1f fps)", frame.ms.total, frame.ms.total > 0 ? 1000 / frame.ms.total : 0.0);
      // Lost cameras stay listed for as long as they are gone; the latest event under them.
      for (const auto& cam : scene.lost_cameras())
        ImGui::TextColored(ImVec4(1, 0.4f, 0.2f, 1), "camera %s lost: playing on without it", cam.c_str());
      if (!report.messages.empty()) ImGui::TextColored(ImVec4(1, 0.7f, 0.2f, 1), "%s", report.messages.back().c_str());
      ImGui::Text("WASD/arrows drive, drag looks, wheel or +/- zooms, Esc quits");
      ImGui::End();
      imgui.Render();
    }
    ++report.frames_shown;
    const bool quitting = p.quit_after_s > 0 && t > p.quit_after_s;
    if (quitting && !p.screenshot.empty() && fb_w > 0 && fb_h > 0) WriteWindowScreenshot(p.screenshot, fb_w, fb_h);
    glfwSwapBuffers(w);
    if (quitting) glfwSetWindowShouldClose(w, GLFW_TRUE);
  }
  Finish(scene, all, &report);
  return report;
}

nlohmann::json TimingsJson(const LiveTimings& t) {
  return {{"capture_wait", t.capture_wait}, {"stitch", t.stitch},       {"lighting", t.lighting}, {"render", t.render},
          {"readback", t.readback},         {"composite", t.composite}, {"total", t.total}};
}

}  // namespace

LiveReport RunLivePlayer(const LivePlayOptions& options) {
  const PlayerOptions& p = options.player;
  if (p.width < 1 || p.height < 1 || p.width > 16384 || p.height > 16384)
    throw UsageError("--size", "must be between 1x1 and 16384x16384");
  if (p.headless_frames < 0) throw UsageError("--frames", "must be non-negative");
  return p.headless || !DisplayAvailable() ? RunLiveHeadless(options) : RunLiveWindow(options);
}

int RunLivePlay(LivePlayOptions o, bool json) {
  if (!o.no_car && o.player.car.empty()) {
    // The demo's car, as `odvr play` without arguments shows it.
    o.player.car = (std::filesystem::path(DefaultDemoVideo()).parent_path() / "car.glb").string();
  }
  const LiveReport r = RunLivePlayer(o);
  if (json) {
    nlohmann::json frames = nlohmann::json::array();
    for (const auto& f : r.frames)
      frames.push_back({{"set_index", f.set_index},
                        {"source_frame", f.source_frame},
                        {"cameras_present", f.cameras_present},
                        {"new_set", f.new_set},
                        {"car_pixel", {f.car_px, f.car_py}},
                        {"car_pixels", f.car_pixels},
                        {"file", f.file}});
    const auto& s = r.source_stats;
    nlohmann::json j{{"mode", r.mode},
                     {"live", true},
                     {"augmented", !o.no_car},
                     {"source", r.source},
                     {"size", {o.player.width, o.player.height}},
                     {"frames_shown", r.frames_shown},
                     {"output_dir", r.output_dir},
                     {"median_total_ms", r.median.total},
                     {"median_ms", TimingsJson(r.median)},
                     {"last_frame_ms", TimingsJson(r.last)},
                     {"messages", r.messages},
                     {"lost_cameras", r.lost_cameras},
                     {"source_stats",
                      {{"sets_delivered", s.sets_delivered},
                       {"frames_dropped", s.frames_dropped},
                       {"frames_out_of_sync", s.frames_out_of_sync},
                       {"corrupt_frames", s.corrupt_frames},
                       {"missing_frames", s.missing_frames}}},
                     {"frames", frames}};
    std::cout << j.dump(2) << "\n";
  } else if (r.mode == "headless") {
    std::cout << "no display: rendered " << r.frames_shown << " live frames from " << r.source << " to "
              << std::filesystem::absolute(r.output_dir).string() << " (median " << r.median.total
              << " ms per frame)\n";
  }
  return 0;
}

}  // namespace odvr::app
