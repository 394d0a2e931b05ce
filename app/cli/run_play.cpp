#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "app/ar/clip_reconstruction.h"
#include "app/cli/commands.h"
#include "app/player/live_player.h"
#include "app/player/player.h"
#include "core/error.h"

namespace odvr::app {
namespace {

// A handheld or helmet 360° camera's height, when the user gives none: the car's size then
// depends on it, so play says it assumed it.
constexpr double kAssumedCameraHeightM = 1.6;

struct PlayCommand {
  PlayerOptions options;
  double camera_height_m = 0;
  std::string size = "1280x720";
  CLI::Option* size_option = nullptr;
  CLI::Option* out_option = nullptr;
  bool json = false;
  bool no_car = false;
  bool live = false;
  LivePlayOptions live_options;  // its `player` is filled from `options` at run time
};

int RunPlay(PlayCommand& c) {
  // Headless frames come from the renderer on whatever GL there is, often llvmpipe, where a
  // 1280x720 car frame takes seconds: unless asked, render the demo's files at a quarter of that.
  if (c.size_option->count() == 0 && (c.options.headless || !DisplayAvailable())) c.size = "640x360";
  std::tie(c.options.width, c.options.height) = ParseSize(c.size);
  // Headless frames go where --out says, else to the temporary directory: never into whatever
  // folder the command was run from (the source tree, when the README's demo command runs it).
  if (c.out_option->count() == 0)
    c.options.out_dir = (std::filesystem::temp_directory_path() / "odvr_play_frames").string();
  if (c.live) {
    if (!c.options.video.empty()) throw UsageError("--live", "plays the rig's cameras, not a video: drop the video");
    if (!c.options.trajectory.empty())
      throw UsageError("--trajectory", "has no place in live mode: the rig stands still, the car --car-start m ahead");
    c.live_options.player = c.options;
    c.live_options.no_car = c.no_car;
    return RunLivePlay(c.live_options, c.json);
  }
  if (!c.live_options.rig.empty() || !c.live_options.source.empty())
    throw UsageError(c.live_options.rig.empty() ? "--source" : "--rig", "belongs to live mode: add --live");
  if (c.options.video.empty()) {
    // No video: the demo, with its trajectory and car unless --no-car.
    c.options.video = DefaultDemoVideo();
    const auto demo = std::filesystem::path(c.options.video).parent_path();
    if (!c.no_car && c.options.trajectory.empty()) c.options.trajectory = (demo / "trajectory_gt.json").string();
    if (!c.no_car && c.options.car.empty()) c.options.car = (demo / "car.glb").string();
    // Headless, nobody holds the keys: the car cruises ahead of the camera as the video plays.
  }
  std::string reconstruction;  // the cached reconstruction the trajectory came from, if any
  if (!c.options.car.empty() && c.options.trajectory.empty()) {
    // A clip and a car, no poses: reconstruct the clip as one 360° camera first (once: cached).
    ClipInput in;
    in.clip = c.options.video;
    if (c.options.stereo != "auto") in.stereo = capture::ParseStereoLayout(c.options.stereo);
    in.camera_height_m = c.camera_height_m > 0 ? c.camera_height_m : kAssumedCameraHeightM;
    if (!(c.camera_height_m > 0))
      std::fprintf(stderr, "odvr play: no --camera-height: assuming the camera %.1f m above the road\n",
                   kAssumedCameraHeightM);
    bool reused = false;
    const std::filesystem::path dir = CachedClipReconstruction(in, &reused);
    std::fprintf(stderr, "odvr play: %s %s\n",
                 reused ? "the camera's poses from" : "reconstructed the camera's poses into", dir.string().c_str());
    c.options.trajectory = (dir / "trajectory.json").string();
    reconstruction = dir.string();
  }
  if (!c.options.trajectory.empty() && c.options.car.empty())
    throw UsageError("--trajectory", "needs --car (a glTF 2.0 model)");
  const PlayerReport r = RunPlayer(c.options);
  if (c.json) {
    nlohmann::json j{{"mode", r.mode},
                     {"augmented", !c.options.trajectory.empty()},
                     {"video", c.options.video},
                     {"trajectory", c.options.trajectory},
                     {"reconstruction", reconstruction},
                     {"size", {c.options.width, c.options.height}},
                     {"frames_shown", r.frames_shown},
                     {"output_dir", r.output_dir},
                     {"median_total_ms", r.median_total_ms},
                     {"median_ms",
                      {{"decode", r.median.decode_ms},
                       {"lighting", r.median.lighting_ms},
                       {"render", r.median.render_ms},
                       {"readback", r.median.readback_ms},
                       {"composite", r.median.composite_ms},
                       {"total", r.median.total_ms}}},
                     {"last_frame_ms",
                      {{"decode", r.last.decode_ms},
                       {"upload", r.last.upload_ms},
                       {"lighting", r.last.lighting_ms},
                       {"render", r.last.render_ms},
                       {"readback", r.last.readback_ms},
                       {"composite", r.last.composite_ms},
                       {"total", r.last.total_ms}}}};
    nlohmann::json frames = nlohmann::json::array();
    for (const auto& f : r.frames)
      frames.push_back({{"view_frame", f.view_frame},
                        {"light_frame", f.light_frame},
                        {"car_world_xz", {f.car_x, f.car_z}},
                        {"car_pixel", {f.car_px, f.car_py}},
                        {"car_pixels", f.car_pixels},
                        {"at_stretch_end", f.at_stretch_end},
                        {"file", f.file}});
    j["frames"] = frames;
    std::cout << j.dump(2) << "\n";
  } else if (r.mode == "headless") {
    std::cout << "no display: rendered " << r.frames_shown << " frames to "
              << std::filesystem::absolute(r.output_dir).string() << " (median " << r.median_total_ms
              << " ms per frame)\n";
  }
  return 0;
}

}  // namespace

CommandFn AddPlay(CLI::App* sub) {
  auto c = std::make_shared<PlayCommand>();
  auto& o = c->options;
  sub->add_option("video,--video", o.video, "Equirectangular video or image sequence (default: the demo in media/)");
  c->size_option =
      sub->add_option("--size", c->size, "Window size WIDTHxHEIGHT (headless default: 640x360)")->capture_default_str();
  sub->add_flag("--headless", o.headless, "Render frames to PNG files instead of opening a window");
  // Checked where given: 0 stands for "all" in PlayerOptions.
  sub->add_option("--frames", o.headless_frames, "Headless: how many frames (default: all)")
      ->check(CLI::PositiveNumber);
  c->out_option = sub->add_option("--out", o.out_dir,
                                  "Headless: output directory (default: odvr_play_frames in the temporary directory)");
  sub->add_option("--stereo", o.stereo,
                  "A stereo 360° video shows one eye: auto (the file's metadata, else the frame's shape: 1:1 "
                  "top-bottom, 4:1 side by side), mono, top-bottom, side-by-side")
      ->check(CLI::IsMember({"auto", "mono", "top-bottom", "side-by-side", "tb", "sbs"}))
      ->capture_default_str();
  sub->add_option("--exposure", o.exposure, "Exposure multiplier")->capture_default_str();
  sub->add_option("--yaw", o.view.yaw_deg, "Initial view yaw in degrees (positive: right)")->capture_default_str();
  sub->add_option("--pitch", o.view.pitch_deg, "Initial view pitch in degrees (positive: up)")->capture_default_str();
  sub->add_option("--fov", o.view.fov_deg, "Initial vertical field of view in degrees (30-150)")->capture_default_str();
  AddSetFlag(sub, "--no-loop", &o.loop, false, "Stop at the end instead of looping");
  sub->add_option("--quit-after", o.quit_after_s, "Window: close after this many seconds");
  sub->add_option("--screenshot", o.screenshot, "Window: save the last frame shown to this PNG");
  sub->add_option("--trajectory", o.trajectory,
                  "Augmented mode: camera poses placing the car (odvr reconstruct's trajectory.json or .tum)");
  sub->add_option("--car", o.car,
                  "Augmented mode: the car, a glTF 2.0 model (.glb/.gltf); without --trajectory the video is "
                  "reconstructed first as one 360° camera (once: cached in ~/.cache/odvr)");
  sub->add_option("--camera-height", c->camera_height_m,
                  "Without --trajectory: the camera's height above the road in metres (default: assumed 1.6)");
  // Checked where given: a negative start stands for "not given" (the view distance).
  sub->add_option("--car-start", o.car_start_m, "Car's start: arc length along the camera path in metres")
      ->check(FiniteNumberIn(0, kFarthestCarStartM));
  sub->add_option("--view-distance", o.view_distance_m, "The viewer's frame trails the car by this many metres")
      ->capture_default_str();
  sub->add_option("--drive", o.drive,
                  "Scripted keys, e.g. \"W:2s,A:1s,-:0.5s\" (W/A/S/D, - none); without it the car cruises ahead "
                  "of the camera as the video plays, until a key takes the wheel");
  sub->add_option("--levels", o.lighting_levels, "Car light: HEALPix levels (1..6)")->capture_default_str();
  sub->add_option("--voxels", o.voxels, "Car visibility grid per side (64, 128, 256)")->capture_default_str();
  sub->add_option("--supersample", o.supersample,
                  "Car: KxK samples per pixel where a pixel needs them (1..4; K² the car's shading at most)")
      ->capture_default_str();
  sub->add_option("--shading-rate", o.shading_rate,
                  "Car: 2 shades one pixel of each smooth 2x2 block and fills the rest, 1 every pixel")
      ->check(CLI::IsMember({1, 2}))
      ->capture_default_str();
  sub->add_flag("--no-car", c->no_car, "Play the demo without its car");
  sub->add_option("--resize", o.resize, "Window: resize to WxH halfway through --quit-after (tests)");
  sub->add_flag("--panel", o.panel, "Window: open the car's material and light panel at the start");
  sub->add_flag("--trace", o.trace, "Window: a JSON line on stdout when ready and per F12 screenshot (tests)");
  sub->add_flag("--json", c->json, "Print a JSON report");
  sub->add_flag("--live", c->live, "Live: the rig's cameras stitched and relit every frame (needs --rig)");
  sub->add_option("--rig", c->live_options.rig, "Live: the rig calibration (config/demo_rig.json, rig.json)");
  sub->add_option("--source", c->live_options.source,
                  "Live: the cameras (v4l2:/dev/video0,..., libcamera:, replay:DIR); default: the rig's image_dir "
                  "folders replayed live");
  sub->add_option("--stitch-size", c->live_options.stitch_size, "Live: stitched panorama WIDTHxHEIGHT")
      ->capture_default_str();
  sub->add_option("--stitch-device", c->live_options.stitch_device, "Live: stitch on cpu or gpu")
      ->capture_default_str();
  sub->footer(
      "Keys in the window, free look:\n"
      "  drag, arrows   look around          +/-, wheel   zoom             Space   pause\n"
      "  . ,            step a frame         ] [          speed x2, x0.5\n"
      "  F1             overlay              F12          screenshot       Q, Esc  quit\n"
      "With --car:\n"
      "  W A S D, arrows  drive (the first key takes the wheel from the cruise)    drag  look around\n"
      "  C  car on/off    +/-, wheel  zoom    Space  pause    F1  overlay    F12  screenshot    Q, Esc  quit\n"
      "Examples:\n"
      "  odvr play clip.mp4                      free look in a 360° video (mono or stereo)\n"
      "  odvr play clip.mp4 --car car.glb        drive a car in it: reconstructed first, once\n"
      "  odvr play --headless --frames 25        the demo with its car, as PNG frames");
  return [c] { return RunPlay(*c); };
}

}  // namespace odvr::app
