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
#include <memory>
#include <nlohmann/json.hpp>

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

// The car on a live rig: the newest set of the cameras' frames stitched, the car driven by WASD or
// the arrows; lost cameras are said in the overlay (window) or on stderr once per event (headless).
class LivePlayerScene : public PlayerScene {
 public:
  LivePlayerScene(const LivePlayOptions& options, bool window, LiveReport* report)
      : options_(options),
        scene_(Options(options, window)),
        script_(options.player.drive.empty() ? std::vector<DriveStep>{} : ParseDriveScript(options.player.drive)),
        report_(report) {}

  void Advance(double dt, const std::function<bool(int)>& held, ViewController*) override {
    const CarInput input = WithHeldCarKeys(DriveInputAt(script_, drive_t_), held);
    drive_t_ += dt;
    scene_.Drive(input, dt);
  }

  void Draw(int width, int height, const ViewController& look) override {
    const ViewState& l = look.state();
    Show(scene_.Render(std::max(width, 16), std::max(height, 16), {l.yaw_deg, l.pitch_deg, l.fov_deg, true}));
    for (auto& m : scene_.TakeMessages()) report_->messages.push_back(std::move(m));
    if (frame_.image.empty())
      presenter_.Show(scene_.composite(), static_cast<float>(options_.player.exposure), width, height);
    else
      presenter_.Show(frame_.image, width, height);
  }

  std::vector<std::string> Overlay(const ViewState&) const override {
    const LiveFrame& f = frame_;
    return {Printf("set %ld  cameras %d / %d   car %.1f km/h", f.set_index, f.cameras_present,
                   scene_.rig().camera_count(), scene_.car().state().speed_mps * 3.6),
            Printf("wait %.1f  stitch %.1f  lighting %.1f  render %.1f  composite %.1f ms", f.ms.capture_wait,
                   f.ms.stitch, f.ms.lighting, f.ms.render, f.ms.composite),
            Printf("total %.1f ms  (%.1f fps)", f.ms.total, f.ms.total > 0 ? 1000 / f.ms.total : 0.0),
            "WASD/arrows drive, drag looks, wheel or +/- zooms, F1 panel, F12 shot, Esc quits"};
  }

  // Lost cameras stay listed for as long as they are gone; the latest event under them.
  void OverlayControls() override {
    for (const auto& camera : scene_.lost_cameras())
      ImGui::TextColored(ImVec4(1, 0.4f, 0.2f, 1), "camera %s lost: playing on without it", camera.c_str());
    if (!report_->messages.empty())
      ImGui::TextColored(ImVec4(1, 0.7f, 0.2f, 1), "%s", report_->messages.back().c_str());
  }

  nlohmann::json Trace() const override {
    const LiveFrame& f = frame_;
    return {{"set_index", f.set_index},
            {"cameras_present", f.cameras_present},
            {"lost_cameras", scene_.lost_cameras()},
            {"car_pixel", {f.car_in_front ? f.car_pixel.x : -1, f.car_in_front ? f.car_pixel.y : -1}},
            {"car_pixels", f.car_pixels}};
  }

  int HeadlessFrameCount() const override { return LivePlayOptions::kDefaultHeadlessFrames; }

  // The script advances one rig frame per shown frame. Nobody watches a headless run: each event
  // is said once, where a user running it would look.
  void WriteHeadlessFrame(int i, int width, int height, const ViewState& look,
                          const std::filesystem::path& png) override {
    const double dt = 1.0 / 25;
    if (i > 0) scene_.Drive(DriveInputAt(script_, (i - 1) * dt), dt);
    Show(scene_.Render(width, height, {look.yaw_deg, look.pitch_deg, 0, true}));
    for (auto& m : scene_.TakeMessages()) {
      std::cerr << "odvr play --live: " << m << "\n";
      report_->messages.push_back(std::move(m));
    }
    image::SaveImage(png, frame_.image);
    report_->frames.back().file = png.string();
  }

  void Finish() override {
    report_->median = Medians(all_);
    if (!all_.empty()) report_->last = all_.back();
    report_->lost_cameras = scene_.lost_cameras();
    report_->source_stats = scene_.source_stats();
    report_->source = scene_.source_description();
  }

 private:
  static LiveSceneOptions Options(const LivePlayOptions& o, bool window) {
    LiveSceneOptions s = SceneOptions(o);
    s.composite_on_gpu = window;  // with the car: drawn where it was rendered, no read-back
    return s;
  }

  void Show(LiveFrame frame) {
    frame_ = std::move(frame);
    all_.push_back(frame_.ms);
    report_->frames.push_back(Record(frame_));
  }

  const LivePlayOptions& options_;
  LiveScene scene_;
  std::vector<DriveStep> script_;
  LiveReport* report_;
  double drive_t_ = 0;
  FramePresenter presenter_;
  LiveFrame frame_;
  std::vector<LiveTimings> all_;
};

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
  const bool window = !p.headless && DisplayAvailable();
  LiveReport report;
  const SceneFactory make = [&] { return std::make_unique<LivePlayerScene>(options, window, &report); };
  RunPlayerLoop(p, window, "odvr live — " + options.rig, make, &report);
  return report;
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
