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
#include <memory>
#include <nlohmann/json.hpp>

#include "app/ar/augmented_scene.h"
#include "app/ar/car_look.h"
#include "app/player/player.h"
#include "app/player/player_loop.h"
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

// The car on a recorded street: without a script the video plays and the car cruises ahead of
// the camera until a key (WASD, arrows) takes the wheel; space pauses, C hides the car.
class AugmentedPlayerScene : public PlayerScene {
 public:
  AugmentedPlayerScene(const PlayerOptions& options, bool window, PlayerReport* report)
      : options_(options),
        scene_(Options(options, window)),
        script_(options.drive.empty() ? std::vector<DriveStep>{} : ParseDriveScript(options.drive)),
        cruising_(script_.empty()),
        report_(report) {}

  void Key(int key) override {
    if (key == GLFW_KEY_SPACE) paused_ = !paused_;
    if (key == GLFW_KEY_C) draw_car_ = !draw_car_;
  }

  // Paused, the car and its light stand still: the picture only changes with the look.
  void Advance(double wall_dt, const std::function<bool(int)>& held, ViewController*) override {
    dt_ = paused_ ? 0.0 : wall_dt;
    const CarInput input = WithHeldCarKeys(DriveInputAt(script_, drive_t_), held);
    drive_t_ += dt_;
    if (input.forward || input.backward || input.left || input.right) cruising_ = false;
    if (cruising_)
      scene_.Cruise(dt_);
    else
      scene_.Drive(input, dt_);
  }

  // Rendered at the window's size (at least the renderer's smallest useful picture, which a tiny
  // window shows scaled down) and drawn where it was rendered: no read-back, no upload.
  void Draw(int width, int height, const ViewController& look) override {
    const ViewState& l = look.state();
    Show(scene_.Render(std::max(width, 16), std::max(height, 16), {l.yaw_deg, l.pitch_deg, l.fov_deg, draw_car_}, dt_));
    presenter_.Show(scene_.composite(), static_cast<float>(options_.exposure), width, height);
  }

  std::vector<std::string> Overlay(const ViewState& look) const override {
    const AugmentedFrame& f = frame_;
    std::vector<std::string> lines = {
        Printf("frame %d (light %d)   car %.1f km/h%s%s", f.view_frame, f.light_frame, scene_.car_speed_mps() * 3.6,
               cruising_ ? "  cruising" : "", paused_ ? "  (paused)" : ""),
        Printf("decode %.1f  lighting %.1f  render %.1f  composite %.1f ms", f.ms.decode, f.ms.lighting, f.ms.render,
               f.ms.composite),
        Printf("total %.1f ms (%.1f fps)  yaw %.0f pitch %.0f fov %.0f", f.ms.total,
               f.ms.total > 0 ? 1000 / f.ms.total : 0.0, look.yaw_deg, look.pitch_deg, look.fov_deg),
        "WASD drive, drag look, wheel zoom, space pause, C car, F1 panel, F12 shot"};
    if (f.at_stretch_end) lines.push_back("the end of the reconstructed street: no frame shows beyond it");
    return lines;
  }

  void Panels(int width, const std::array<int, 4>& overlay) override {
    CarLook look = scene_.look();
    if (CarPanel(width, options_.lighting_levels, options_.panel, frame_, &look, &panel_widgets_)) scene_.SetLook(look);
    panel_widgets_["overlay_min"] = {overlay[0], overlay[1]};
    panel_widgets_["overlay_max"] = {overlay[2], overlay[3]};
  }

  nlohmann::json Trace() const override {
    const CarState& car = scene_.car().state();
    const AugmentedFrame& f = frame_;
    return {{"view_frame", f.view_frame},
            {"light_frame", f.light_frame},
            {"paused", paused_},
            {"draw_car", draw_car_},
            {"car_world_xz", {car.position.x, car.position.z}},
            {"car_speed_mps", car.speed_mps},
            {"car_pixel", {f.car_in_front ? f.car_pixel.x : -1, f.car_in_front ? f.car_pixel.y : -1}},
            {"car_pixels", f.car_pixels},
            {"at_stretch_end", f.at_stretch_end},
            {"look",
             {{"model", static_cast<int>(scene_.look().model)},
              {"levels", scene_.look().levels},
              {"peaks", scene_.look().peaks},
              {"cones", scene_.look().cones}}},
            {"panel", panel_widgets_},
            {"ms",
             {{"decode", f.ms.decode},
              {"lighting", f.ms.lighting},
              {"render", f.ms.render},
              {"readback", f.ms.readback},
              {"composite", f.ms.composite},
              {"total", f.ms.total}}}};
  }

  // The video's frames; with a script, as many as it lasts.
  int HeadlessFrameCount() const override {
    if (script_.empty()) return static_cast<int>(scene_.frames().size());
    return std::max(1, static_cast<int>(std::ceil(DriveDuration(script_) / HeadlessDt() - 1e-9)) + 1);
  }

  // Frame i shows the car after i steps of the script; without one the video plays and the car
  // cruises ahead of the camera.
  void WriteHeadlessFrame(int i, int width, int height, const ViewState& look,
                          const std::filesystem::path& png) override {
    const double dt = HeadlessDt();
    if (i > 0 && script_.empty()) scene_.Cruise(dt);
    if (i > 0 && !script_.empty()) scene_.Drive(DriveInputAt(script_, (i - 1) * dt), dt);
    Show(scene_.Render(width, height, {look.yaw_deg, look.pitch_deg, 0, true}, i > 0 ? dt : 0));
    image::SaveImage(png, frame_.image);
    report_->frames.back().file = png.string();
  }

  void Finish() override { Medians(all_, report_); }

 private:
  static AugmentedOptions Options(const PlayerOptions& o, bool window) {
    AugmentedOptions a = SceneOptions(o);
    a.composite_on_gpu = window;  // drawn where it was rendered: no read-back, no upload
    return a;
  }
  double HeadlessDt() const { return 1.0 / (scene_.fps() > 0 ? scene_.fps() : 25.0); }

  // Keeps the frame's figures; the first frame warns when the car is out of sight.
  void Show(AugmentedFrame frame) {
    frame_ = std::move(frame);
    if (all_.empty()) WarnIfTheCarIsUnseen(frame_, options_.car);
    all_.push_back(Timings(frame_));
    report_->frames.push_back(Record(frame_));
  }

  const PlayerOptions& options_;
  AugmentedScene scene_;
  std::vector<DriveStep> script_;
  bool cruising_;
  PlayerReport* report_;
  bool paused_ = false, draw_car_ = true;
  double dt_ = 0, drive_t_ = 0;  // drive_t_: the script's clock, which stops while paused
  FramePresenter presenter_;
  AugmentedFrame frame_;
  std::vector<FrameTimings> all_;
  std::map<std::string, std::array<int, 2>> panel_widgets_;
};

}  // namespace

PlayerReport RunAugmentedPlayer(const PlayerOptions& options, bool window) {
  PlayerReport report;
  const SceneFactory make = [&] { return std::make_unique<AugmentedPlayerScene>(options, window, &report); };
  RunPlayerLoop(options, window, "odvr — " + options.video, make, &report);
  return report;
}

}  // namespace odvr::app
