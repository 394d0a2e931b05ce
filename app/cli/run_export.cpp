// odvr export: an augmented clip — the car driven along a scripted path through the recorded
// street, rendered frame by frame and written as a video (H.264, H.265 or MJPEG through libav),
// atomically.
#include <spdlog/spdlog.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "app/ar/augmented_scene.h"
#include "app/cli/commands.h"
#include "capture/libav_video_writer.h"
#include "capture/source.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/srgb.h"
#include "core/timing.h"
#include "engine/gl/context.h"
#include "engine/image/image_io.h"

namespace odvr::app {
namespace {

struct ExportCommand {
  AugmentedOptions scene;
  std::string path;  // the drive script; empty: the car cruises ahead of the camera
  std::string out;
  std::string size;  // "" : 1280x720 flat, the video's frame size as a panorama
  std::string projection = "flat";
  int frames = -1;    // -1: the drive path's duration
  double fps = -1;    // -1: the video's
  std::string codec;  // capture::VideoWriterOptions::codec: "" by the extension
  int crf = 20;
  bool no_audio = false;
  bool json = false;
  std::string view;  // "YAW,PITCH[,FOV]" degrees on top of looking at the car
};

// --view YAW,PITCH[,FOV]: where the clip looks, turned from the car (positive: right, up), and its
// vertical field of view.
AugmentedView ParseExportView(const std::string& text) {
  AugmentedView view;
  if (text.empty()) return view;
  double v[3] = {0, 0, 0};
  char tail = 0;
  const int n = std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &v[0], &v[1], &v[2], &tail);
  if ((n != 2 && n != 3) || !std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
    throw UsageError("--view", "expects YAW,PITCH or YAW,PITCH,FOV in degrees, got '" + text + "'");
  if (std::abs(v[1]) > 89) throw UsageError("--view", "pitch must be within ±89 degrees, got " + text);
  if (n == 3 && !(v[2] >= 10 && v[2] <= 150))
    throw UsageError("--view", "the field of view must be 10-150 degrees, got " + text);
  view.yaw_deg = v[0];
  view.pitch_deg = v[1];
  if (n == 3) view.vfov_deg = v[2];
  return view;
}

std::pair<int, int> ParseExportSize(const std::string& text) {
  int a = 0, b = 0;
  char x = 0;
  if (std::sscanf(text.c_str(), "%d%c%d", &a, &x, &b) != 3 || (x != 'x' && x != 'X') || a < 16 || b < 16 || a > 8192 ||
      b > 8192 || a % 2 || b % 2)
    throw UsageError("--size", "expects even WIDTHxHEIGHT between 16x16 and 8192x8192, got '" + text + "'");
  return {a, b};
}

int RunExport(ExportCommand& c) {
  const bool equirect = c.projection == "equirect";
  if (equirect && !c.view.empty())
    throw UsageError("--view", "looks one way; --projection equirect writes every direction");
  auto [width, height] = ParseExportSize(c.size.empty() ? (equirect ? "16x16" : "1280x720") : c.size);
  if (equirect && !c.size.empty() && width != 2 * height)
    throw UsageError("--size", "a 360° clip is twice as wide as high, got " + c.size);
  if (equirect && c.size.empty()) width = height = 0;  // the video's, known once a frame is decoded
  capture::VideoWriterOptions video;
  video.spherical_equirect = equirect;
  video.codec = c.codec.empty() ? capture::DefaultCodecFor(c.out) : c.codec;
  video.crf = c.crf;
  // --path is a drive script, or a file holding one.
  std::string script_text = c.path;
  if (!c.path.empty() && std::filesystem::is_regular_file(c.path)) {
    std::ifstream in(c.path);
    std::stringstream ss;
    ss << in.rdbuf();
    script_text = ss.str();
    script_text.erase(std::remove_if(script_text.begin(), script_text.end(), ::isspace), script_text.end());
  }
  const auto script = script_text.empty() ? std::vector<DriveStep>{} : ParseDriveScript(script_text);
  if (c.frames == 0 || c.frames < -1) throw UsageError("--frames", "must be at least 1");
  const AugmentedView view = ParseExportView(c.view);

  gl::HeadlessContext context;
  c.scene.equirect_output = equirect;
  AugmentedScene scene(c.scene);
  const double fps = c.fps > 0 ? c.fps : (scene.fps() > 0 ? scene.fps() : 25.0);
  video.fps = fps;
  // The recording's sound from the first frame shown: the cruise advances the video by 1/fps a
  // frame, so sound and pictures stay in step (a drive moves the view along the street instead).
  if (!c.no_audio && std::filesystem::is_regular_file(c.scene.video) && scene.fps() > 0) {
    video.audio_from = c.scene.video;
    video.audio_start_s = static_cast<double>(scene.frames().front()) / scene.fps();
  }
  const double dt = 1.0 / fps;
  // By default the drive's duration, or without one the trajectory's stretch of the video.
  const int frames = c.frames > 0     ? c.frames
                     : script.empty() ? static_cast<int>(scene.frames().back() - scene.frames().front() + 1)
                                      : std::max(1, static_cast<int>(std::ceil(DriveDuration(script) / dt - 1e-9)) + 1);
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  // The first frame is rendered before the writer opens: a 360° clip takes its size from it.
  std::vector<double> face_counts;
  const auto render = [&](int i) {
    if (i > 0 && script.empty()) scene.Cruise(dt);
    if (i > 0 && !script.empty()) scene.Drive(DriveInputAt(script, (i - 1) * dt), dt);
    AugmentedFrame f =
        equirect ? scene.RenderEquirect(width, i > 0 ? dt : 0) : scene.Render(width, height, view, i > 0 ? dt : 0);
    if (equirect) face_counts.push_back(f.cube_faces_rendered);
    return f;
  };
  AugmentedFrame first = render(0);
  width = first.image.width;
  height = first.image.height;
  if (equirect && (width > 8192 || width % 2 || height % 2))
    throw Error(c.scene.video, "a 360° clip of its frame size (" + std::to_string(width) + "x" +
                                   std::to_string(height) + ") cannot be written: give --size");
  video.width = width;
  video.height = height;
  video.Check();
  std::vector<std::uint8_t> bgr(static_cast<std::size_t>(width) * height * 3);
  std::string encoder, audio;
  int frames_with_car = 0;
  WriteFileAtomically(c.out, [&](const std::filesystem::path& tmp) {
    capture::LibavVideoWriter writer(tmp, video, c.out);
    encoder = writer.codec_name();
    audio = writer.audio_codec();
    // A recording without sound makes a silent clip as a matter of course; sound that cannot be
    // kept (a codec the container does not hold) is a loss to warn of.
    if (!writer.audio_dropped().empty()) {
      spdlog::warn("{}: {}", c.out, writer.audio_dropped());
    } else if (!video.audio_from.empty() && audio.empty()) {
      spdlog::info("{}: silent: {} has no sound", c.out, video.audio_from);
    }
    for (int i = 0; i < frames; ++i) {
      const AugmentedFrame f = i == 0 ? std::move(first) : render(i);
      frames_with_car += f.car_pixels > 0;
      for (std::size_t p = 0; p < f.image.pixel_count(); ++p)
        for (int ch = 0; ch < 3; ++ch) {
          const float v = LinearToSrgb(std::clamp(f.image.rgb[3 * p + static_cast<std::size_t>(ch)], 0.f, 1.f));
          bgr[3 * p + static_cast<std::size_t>(2 - ch)] = static_cast<std::uint8_t>(std::lround(255 * v));
        }
      writer.Write(cv::Mat(height, width, CV_8UC3, bgr.data()));
      const double elapsed = SecondsSince(start);
      const double eta = elapsed / (i + 1) * (frames - i - 1);
      std::fprintf(stderr, "\rexport: frame %d/%d (view %d)  %.2f s/frame  ETA %.0f s   ", i + 1, frames, f.view_frame,
                   elapsed / (i + 1), eta);
    }
    std::fprintf(stderr, "\n");
    writer.Finish();
    capture::CheckWrittenVideo(tmp, c.out, frames);
  });
  const double elapsed = SecondsSince(start);
  // The clip is written, but a user who asked for a car and sees none deserves to hear why.
  if (frames_with_car == 0)
    spdlog::warn(
        "{}: the car ({}) covers no pixel in any of the {} frames: it lies outside the view (see --view and "
        "--car-start), or is too small or too far off to see",
        c.out, c.scene.car, frames);
  double faces_mean = 0;
  for (const double n : face_counts) faces_mean += n / static_cast<double>(face_counts.size());
  if (c.json) {
    nlohmann::json report{{"output", c.out},
                          {"frames", frames},
                          {"size", {width, height}},
                          {"fps", fps},
                          {"codec", encoder},
                          {"crf", c.crf},
                          {"seconds", elapsed},
                          {"cruise", script.empty()},
                          {"audio", audio},
                          {"frames_with_car", frames_with_car},
                          {"projection", c.projection}};
    if (equirect) report["cube_faces_per_frame"] = faces_mean;
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << c.out << ": " << frames << " frames " << width << "x" << height << " at " << fps << " fps (" << encoder
              << ", crf " << c.crf << (audio.empty() ? ", silent" : ", " + audio + " audio copied") << ") in "
              << elapsed << " s";
    if (equirect)
      std::cout << "; 360° with spherical metadata, the car rendered on " << faces_mean << " cube faces a frame";
    std::cout << "\n";
  }
  return 0;
}

}  // namespace

CommandFn AddExport(CLI::App* sub) {
  auto c = std::make_shared<ExportCommand>();
  auto& s = c->scene;
  sub->add_option("--video", s.video, "Equirectangular video or image sequence")->required();
  sub->add_option("--stereo", s.stereo, "A stereo 360° video uses one eye: auto, mono, top-bottom, side-by-side")
      ->check(CLI::IsMember({"auto", "mono", "top-bottom", "side-by-side", "tb", "sbs"}))
      ->capture_default_str();
  sub->add_option("--trajectory", s.trajectory, "Camera poses: odvr reconstruct's trajectory.json or trajectory.tum")
      ->required();
  sub->add_option("--car", s.car, "The car: glTF 2.0 (.glb/.gltf)")->required();
  sub->add_option("--drive,--path", c->path,
                  "The drive: keys and durations, e.g. \"W:2s,A:1s\", or a file holding that (default: the car "
                  "cruises ahead of the camera through the whole trajectory)");
  // Checked where given: the scene takes a negative start for "not given" (the view distance).
  sub->add_option("--car-start", s.car_start_m, "Car's start: arc length along the camera path in metres")
      ->check(FiniteNumberIn(0, kFarthestCarStartM));
  sub->add_option("--out", c->out,
                  "The clip: .mp4, .mov, .m4v, .mkv (H.264 unless --codec says otherwise), .avi (MJPEG)")
      ->required();
  sub->add_option("--codec", c->codec, "h264, h265 or mjpeg (default: by the extension)")
      ->check(CLI::IsMember({"h264", "h265", "mjpeg"}));
  sub->add_option("--crf", c->crf,
                  "Quality: x264/x265's constant rate factor, 0 (lossless) to 51; 18-23 look like the source")
      ->check(CLI::Range(0, 51))
      ->capture_default_str();
  sub->add_option("--projection", c->projection,
                  "flat: a camera's view of the car (--view, --fov); equirect: the augmented 360° video itself, "
                  "every direction, with spherical metadata so that 360° players and sites show it as such")
      ->check(CLI::IsMember({"flat", "equirect"}))
      ->capture_default_str();
  sub->add_option("--size", c->size,
                  "WIDTHxHEIGHT, even (default: 1280x720; with --projection equirect the video's frame size, "
                  "one eye of a stereo video)");
  // Checked where given: -1 stands for "not given" in ExportCommand.
  sub->add_option("--frames", c->frames, "Frames to write (default: the path's duration)")->check(CLI::PositiveNumber);
  sub->add_option("--fps", c->fps, "Frame rate (default: the video's)")
      ->check(FiniteNumberIn(capture::kMinFps, capture::kMaxFps));
  sub->add_option("--view", c->view,
                  "YAW,PITCH[,FOV]: where the clip looks, in degrees turned from the car (positive: right, up), "
                  "and its vertical field of view (default: at the car, 70)");
  sub->add_flag("--no-audio", c->no_audio, "Leave the clip silent (by default the video's sound is copied)");
  sub->add_flag("--json", c->json, "Print a JSON report");
  sub->add_option("--levels", s.lighting_levels, "Car light: HEALPix levels (1..6)")->capture_default_str();
  sub->add_option("--voxels", s.voxel_resolution, "Visibility grid per side (64, 128, 256)")->capture_default_str();
  sub->add_option("--supersample", s.supersample,
                  "KxK samples per pixel where a pixel needs them (1..4; K² the car's shading at most)")
      ->capture_default_str();
  sub->add_option("--fov", s.vfov_deg, "Vertical field of view, degrees")->capture_default_str();
  return [c] { return RunExport(*c); };
}

}  // namespace odvr::app
