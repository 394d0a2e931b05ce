// The player's augmented mode: the car on the road of a recorded street (app/ar/augmented_scene.h),
// in a window driven by WASD/arrows or headless to PNG frames with a scripted drive.
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>

#include <spdlog/spdlog.h>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>

#include "app/ar/augmented_scene.h"
#include "app/ar/car_look.h"
#include "app/player/player.h"
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

AugmentedOptions SceneOptions(const PlayerOptions& o) {
  AugmentedOptions a;
  a.video = o.video;
  a.stereo = o.stereo;
  a.trajectory = o.trajectory;
  a.car = o.car;
  a.car_start_m = o.car_start_m;
  a.picker.view_distance_m = o.view_distance_m;
  a.lighting_levels = o.lighting_levels;
  a.voxel_resolution = o.voxels;
  a.supersample = o.supersample;
  a.shading_rate = o.shading_rate;
  a.vfov_deg = std::clamp(o.view.fov_deg, 30.0, 150.0);
  a.exposure = o.exposure;
  return a;
}

FrameTimings Timings(const AugmentedFrame& f) {
  FrameTimings t;
  t.decode_ms = f.ms.decode;
  t.lighting_ms = f.ms.lighting;
  t.render_ms = f.ms.render;
  t.readback_ms = f.ms.readback;
  t.composite_ms = f.ms.composite;
  t.total_ms = f.ms.total;
  return t;
}

AugmentedFrameRecord Record(const AugmentedFrame& f) {
  AugmentedFrameRecord r;
  r.view_frame = f.view_frame;
  r.light_frame = f.light_frame;
  r.car_x = f.car_position.x;
  r.car_z = f.car_position.z;
  r.car_px = f.car_in_front ? f.car_pixel.x : -1;
  r.car_py = f.car_in_front ? f.car_pixel.y : -1;
  r.car_pixels = f.car_pixels;
  r.at_stretch_end = f.at_stretch_end;
  return r;
}

void Medians(const std::vector<FrameTimings>& all, PlayerReport* report) {
  auto median = [&](double FrameTimings::*field) {
    std::vector<double> v;
    for (const auto& t : all) v.push_back(t.*field);
    return Median(v);
  };
  report->median.decode_ms = median(&FrameTimings::decode_ms);
  report->median.lighting_ms = median(&FrameTimings::lighting_ms);
  report->median.render_ms = median(&FrameTimings::render_ms);
  report->median.readback_ms = median(&FrameTimings::readback_ms);
  report->median.composite_ms = median(&FrameTimings::composite_ms);
  report->median.total_ms = median(&FrameTimings::total_ms);
  report->median_total_ms = report->median.total_ms;
  if (!all.empty()) report->last = all.back();
}

// The car's panel, a second ImGui window at the top right, collapsed at first (the picture stays
// clear): edits `look` and shows the light frame's figures. True when a control changed.
// `widgets` gets each checkbox's centre and the panel's corners in window pixels (--trace:
// scripted clicks find them there).
bool CarPanel(int window_width, int levels, bool open, const AugmentedFrame& frame, CarLook* look,
              std::map<std::string, std::array<int, 2>>* widgets) {
  ImGui::SetNextWindowPos(ImVec2(static_cast<float>(window_width) - 10, 10), ImGuiCond_FirstUseEver, ImVec2(1, 0));
  ImGui::SetNextWindowCollapsed(!open, ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.7f);
  const CarLook before = *look;
  widgets->clear();
  const auto centre = [&](const std::string& name) {
    const ImVec2 lo = ImGui::GetItemRectMin(), hi = ImGui::GetItemRectMax();
    (*widgets)[name] = {static_cast<int>(0.5f * (lo.x + hi.x)), static_cast<int>(0.5f * (lo.y + hi.y))};
  };
  if (ImGui::Begin("car", nullptr, ImGuiWindowFlags_AlwaysAutoResize)) {
    const ImVec2 at = ImGui::GetWindowPos(), size = ImGui::GetWindowSize();
    (*widgets)["window_min"] = {static_cast<int>(at.x), static_cast<int>(at.y)};
    (*widgets)["window_max"] = {static_cast<int>(at.x + size.x), static_cast<int>(at.y + size.y)};
    int model = static_cast<int>(look->model);
    ImGui::Combo("material", &model, "glTF (as modelled)\0Phong\0Cook-Torrance\0");
    look->model = static_cast<CarLook::Model>(model);
    auto slider = [](const char* label, double* v, float lo, float hi, const char* format, bool log = false) {
      float f = static_cast<float>(*v);
      if (ImGui::SliderFloat(label, &f, lo, hi, format, log ? ImGuiSliderFlags_Logarithmic : 0)) *v = f;
    };
    if (look->model != CarLook::Model::kGltf) {
      ImGui::ColorEdit3("colour", look->colour.data());
      slider("kd/ks mix (ks)", &look->ks, 0, 1, "%.2f");
      if (look->model == CarLook::Model::kPhong) slider("Phong n", &look->phong_n, 1, 5000, "%.0f", true);
      if (look->model == CarLook::Model::kCookTorrance) {
        slider("roughness", &look->roughness, 0.01f, 1, "%.2f");
        slider("Fresnel F0", &look->fresnel_f0, 0, 1, "%.2f");
      }
    }
    ImGui::Checkbox("peaks", &look->peaks);
    centre("peaks");
    ImGui::SameLine();
    ImGui::Checkbox("peak cones", &look->cones);
    centre("cones");
    for (int l = 0; l < std::min(levels, static_cast<int>(look->levels.size())); ++l) {
      if (l > 0) ImGui::SameLine();
      bool on = look->levels[static_cast<std::size_t>(l)];
      if (ImGui::Checkbox(("L" + std::to_string(l)).c_str(), &on)) look->levels[static_cast<std::size_t>(l)] = on;
      centre("L" + std::to_string(l));
    }
    ImGui::Text("decode %.1f  light %.1f  render %.1f  composite %.1f ms", frame.ms.decode, frame.ms.lighting,
                frame.ms.render, frame.ms.composite);
    // The light frame's model: what each level kept and the residue (mean |residual| over mean
    // radiance) it left, after the peaks were taken out.
    ImGui::Text("light frame %d: %d peaks", frame.light_frame, frame.light_peaks);
    for (const auto& l : frame.light_levels)
      ImGui::Text("L%d  %4d/%4d SRBFs  residue %.3f -> %.3f", l.level, l.srbfs_kept, l.srbfs_total, l.residue_before,
                  l.residue_after);
  }
  ImGui::End();
  return !(*look == before);
}

// A car that covers no pixel of the first frame (placed kilometres off, scaled to nothing, its
// triangles of no area) would play without a word: said once, naming the model.
void WarnIfTheCarIsUnseen(const AugmentedFrame& first, const std::string& car) {
  if (first.car_pixels == 0)
    spdlog::warn(
        "{}: the car covers no pixel of the first frame: it lies outside the view, or is too small or too far off "
        "to see",
        car);
}

}  // namespace

PlayerReport RunAugmentedHeadless(const PlayerOptions& o) {
  gl::HeadlessContext context;
  AugmentedScene scene(SceneOptions(o));
  const auto script = o.drive.empty() ? std::vector<DriveStep>{} : ParseDriveScript(o.drive);
  const double dt = 1.0 / (scene.fps() > 0 ? scene.fps() : 25.0);
  int frames = o.headless_frames;
  if (frames <= 0)
    frames = script.empty() ? static_cast<int>(scene.frames().size())
                            : std::max(1, static_cast<int>(std::ceil(DriveDuration(script) / dt - 1e-9)) + 1);
  PlayerReport report;
  report.mode = "headless";
  report.output_dir = o.out_dir;
  std::filesystem::create_directories(o.out_dir);
  std::vector<FrameTimings> all;
  const AugmentedView view{o.view.yaw_deg, o.view.pitch_deg, 0, true};
  for (int i = 0; i < frames; ++i) {
    // Frame i shows the car after i steps of the script; without one the video plays and the
    // car cruises ahead of the camera.
    if (i > 0 && script.empty()) scene.Cruise(dt);
    if (i > 0 && !script.empty()) scene.Drive(DriveInputAt(script, (i - 1) * dt), dt);
    const AugmentedFrame f = scene.Render(o.width, o.height, view, i > 0 ? dt : 0);
    if (i == 0) WarnIfTheCarIsUnseen(f, o.car);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", i);
    const auto path = std::filesystem::path(o.out_dir) / name;
    image::SaveImage(path, f.image);
    all.push_back(Timings(f));
    report.frames.push_back(Record(f));
    report.frames.back().file = path.string();
    ++report.frames_shown;
  }
  Medians(all, &report);
  return report;
}

PlayerReport RunAugmentedWindow(const PlayerOptions& o) {
  gl::WindowContext window(o.width, o.height, "odvr — " + o.video);
  GLFWwindow* w = window.window();
  AugmentedOptions scene_options = SceneOptions(o);
  scene_options.composite_on_gpu = true;  // drawn where it was rendered: no read-back, no upload
  AugmentedScene scene(scene_options);
  const auto script = o.drive.empty() ? std::vector<DriveStep>{} : ParseDriveScript(o.drive);
  std::pair<int, int> resize{0, 0};
  if (!o.resize.empty()) resize = ParseSize(o.resize, "--resize");
  glfwSwapInterval(0);  // the frame takes what it takes; vsync would only add to it

  ImGuiSession imgui(w);
  WindowInput input(w);

  PlayerReport report;
  report.mode = "window";
  std::vector<FrameTimings> all;
  // The look is an offset from looking at the car: the same free look as the plain player.
  ViewController look;
  look.Set({o.view.yaw_deg, o.view.pitch_deg, o.view.fov_deg});
  bool draw_car = true, show_overlay = true, paused = false, ready = false, resized = false;
  int shots = 0;
  FramePresenter presenter;
  const auto start = Clock::now();
  auto previous = start;
  double drive_t = 0;  // the script's clock: it stops while paused
  bool cruising = script.empty();
  AugmentedFrame frame;
  std::vector<std::string> overlay;
  std::map<std::string, std::array<int, 2>> panel_widgets;
  while (!glfwWindowShouldClose(w)) {
    glfwPollEvents();
    const auto now = Clock::now();
    const double wall_dt = std::chrono::duration<double>(now - previous).count();
    const double t = std::chrono::duration<double>(now - start).count();
    previous = now;

    int fb_w = 0, fb_h = 0;
    glfwGetFramebufferSize(w, &fb_w, &fb_h);
    const WindowInput::Events in = input.Take();
    look.Drag(in.drag_dx, in.drag_dy, std::max(fb_h, 1));
    look.Scroll(in.scroll);
    bool screenshot = false;
    for (const int key : in.keys) {
      if (key == GLFW_KEY_SPACE) paused = !paused;
      if (key == GLFW_KEY_C) draw_car = !draw_car;
      if (key == GLFW_KEY_EQUAL || key == GLFW_KEY_KP_ADD) look.Scroll(1);
      if (key == GLFW_KEY_MINUS || key == GLFW_KEY_KP_SUBTRACT) look.Scroll(-1);
      if (key == GLFW_KEY_F1) show_overlay = !show_overlay;
      if (key == GLFW_KEY_F12) screenshot = true;
    }
    // Paused, the car and its light stand still: the picture only changes with the look.
    const double dt = paused ? 0.0 : wall_dt;
    const bool keys_free = !ImGui::GetIO().WantTextInput;
    auto held = [&](int a, int b) {
      return keys_free && (glfwGetKey(w, a) == GLFW_PRESS || glfwGetKey(w, b) == GLFW_PRESS);
    };
    CarInput car_input = DriveInputAt(script, drive_t);
    drive_t += dt;
    car_input.forward |= held(GLFW_KEY_W, GLFW_KEY_UP);
    car_input.backward |= held(GLFW_KEY_S, GLFW_KEY_DOWN);
    car_input.left |= held(GLFW_KEY_A, GLFW_KEY_LEFT);
    car_input.right |= held(GLFW_KEY_D, GLFW_KEY_RIGHT);
    // Without a script the video plays and the car cruises ahead of the camera until a key
    // takes the wheel.
    if (car_input.forward || car_input.backward || car_input.left || car_input.right) cruising = false;
    if (cruising)
      scene.Cruise(dt);
    else
      scene.Drive(car_input, dt);

    if (fb_w > 0 && fb_h > 0) {
      // The renderer's smallest useful picture; a tiny window shows it scaled down.
      const int rw = std::max(fb_w, 16), rh = std::max(fb_h, 16);
      const AugmentedView view{look.state().yaw_deg, look.state().pitch_deg, look.state().fov_deg, draw_car};
      frame = scene.Render(rw, rh, view, dt);
      if (all.empty()) WarnIfTheCarIsUnseen(frame, o.car);
      all.push_back(Timings(frame));
      report.frames.push_back(Record(frame));
      presenter.Show(scene.composite(), static_cast<float>(o.exposure), fb_w, fb_h);

      overlay = {Printf("frame %d (light %d)   car %.1f km/h%s%s", frame.view_frame, frame.light_frame,
                        scene.car_speed_mps() * 3.6, cruising ? "  cruising" : "", paused ? "  (paused)" : ""),
                 Printf("decode %.1f  lighting %.1f  render %.1f  composite %.1f ms", frame.ms.decode,
                        frame.ms.lighting, frame.ms.render, frame.ms.composite),
                 Printf("total %.1f ms (%.1f fps)  yaw %.0f pitch %.0f fov %.0f", frame.ms.total,
                        frame.ms.total > 0 ? 1000 / frame.ms.total : 0.0, look.state().yaw_deg, look.state().pitch_deg,
                        look.state().fov_deg),
                 "WASD drive, drag look, wheel zoom, space pause, C car, F1 panel, F12 shot"};
      if (frame.at_stretch_end) overlay.push_back("the end of the reconstructed street: no frame shows beyond it");
      imgui.NewFrame();
      if (show_overlay) {
        ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
        ImGui::SetNextWindowBgAlpha(0.6f);
        ImGui::Begin("odvr", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
        for (const auto& line : overlay) ImGui::TextUnformatted(line.c_str());
        const ImVec2 at = ImGui::GetWindowPos(), size = ImGui::GetWindowSize();
        ImGui::End();
        CarLook car_look = scene.look();
        if (CarPanel(fb_w, o.lighting_levels, o.panel, frame, &car_look, &panel_widgets)) scene.SetLook(car_look);
        panel_widgets["overlay_min"] = {static_cast<int>(at.x), static_cast<int>(at.y)};
        panel_widgets["overlay_max"] = {static_cast<int>(at.x + size.x), static_cast<int>(at.y + size.y)};
      }
      imgui.Render();
    }
    ++report.frames_shown;
    if (resize.first > 0 && !resized && t > 0.5 * o.quit_after_s) {
      glfwSetWindowSize(w, resize.first, resize.second);
      resized = true;
    }
    const bool quitting = o.quit_after_s > 0 && t > o.quit_after_s;
    if (quitting && !o.screenshot.empty() && fb_w > 0 && fb_h > 0) WriteWindowScreenshot(o.screenshot, fb_w, fb_h);
    std::string shot;
    if (screenshot && fb_w > 0 && fb_h > 0) {
      shot = ScreenshotPath(o.screenshot, ++shots);
      WriteWindowScreenshot(shot, fb_w, fb_h);
      if (!o.trace) std::fprintf(stderr, "screenshot: %s\n", shot.c_str());
    }
    glfwSwapBuffers(w);
    if (o.trace && (!ready || !shot.empty()) && fb_w > 0 && fb_h > 0) {
      const CarState& car = scene.car().state();
      nlohmann::json j{
          {"event", ready ? "screenshot" : "ready"},
          {"file", shot},
          {"size", {fb_w, fb_h}},
          {"view_frame", frame.view_frame},
          {"light_frame", frame.light_frame},
          {"paused", paused},
          {"draw_car", draw_car},
          {"yaw", look.state().yaw_deg},
          {"pitch", look.state().pitch_deg},
          {"fov", look.state().fov_deg},
          {"car_world_xz", {car.position.x, car.position.z}},
          {"car_speed_mps", car.speed_mps},
          {"car_pixel", {frame.car_in_front ? frame.car_pixel.x : -1, frame.car_in_front ? frame.car_pixel.y : -1}},
          {"car_pixels", frame.car_pixels},
          {"at_stretch_end", frame.at_stretch_end},
          {"overlay_shown", show_overlay},
          {"overlay", overlay},
          {"look",
           {{"model", static_cast<int>(scene.look().model)},
            {"levels", scene.look().levels},
            {"peaks", scene.look().peaks},
            {"cones", scene.look().cones}}},
          {"panel", panel_widgets},
          {"ms",
           {{"decode", frame.ms.decode},
            {"lighting", frame.ms.lighting},
            {"render", frame.ms.render},
            {"readback", frame.ms.readback},
            {"composite", frame.ms.composite},
            {"total", frame.ms.total}}}};
      PrintTrace(j.dump());
      ready = true;
    }
    if (quitting) glfwSetWindowShouldClose(w, GLFW_TRUE);
  }
  Medians(all, &report);
  return report;
}

}  // namespace odvr::app
