// `odvr stitch`: rig frames -> equirectangular frames (capture/stitcher.h), written as an MP4,
// a PNG directory or an EXR directory, with per-frame times.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <utility>

#include "app/cli/commands.h"
#include "capture/libav_video_writer.h"
#include "capture/rig.h"
#include "capture/source.h"
#include "capture/stitcher.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/srgb.h"
#include "core/statistics.h"
#include "engine/gl/context.h"
#include "engine/image/image_io.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;

struct StitchCommand {
  std::string rig, in, out, size = "2048x1024", device = "gpu", format = "exr";
  long frames = 0, start = 0;
  std::string scene_distance = "auto";  // "auto", or metres (0 = infinity)
  bool no_gains = false, no_fill = false, json = false;
};

cv::Mat ToBgr8(const sphere::EquirectImage& img) {
  cv::Mat out(img.height, img.width, CV_8UC3);
  for (int y = 0; y < img.height; ++y) {
    auto* row = out.ptr<cv::Vec3b>(y);
    for (int x = 0; x < img.width; ++x) {
      const float* p = img.at(x, y);
      for (int k = 0; k < 3; ++k) row[x][2 - k] = static_cast<unsigned char>(std::lround(255.0f * LinearToSrgb(p[k])));
    }
  }
  return out;
}

// How the scene distance was set: the value (metres, 0 = infinity) and, when chosen, every score.
nlohmann::json SceneDistanceJson(const capture::StitchOptions& options,
                                 const std::optional<capture::SceneDistanceChoice>& choice) {
  nlohmann::json j = {{"metres", options.scene_distance_m}, {"mode", choice ? "auto" : "given"}};
  if (choice) {
    nlohmann::json scores = nlohmann::json::array();
    for (std::size_t i = 0; i < choice->candidates_m.size(); ++i)
      scores.push_back({{"metres", choice->candidates_m[i]},
                        {"seam_rms", std::isfinite(choice->scores[i]) ? nlohmann::json(choice->scores[i]) : nullptr},
                        {"pixels", choice->samples[i]}});
    j["candidates"] = scores;
    j["frame_sets"] = choice->frame_sets;
    j["reason"] = choice->reason;
    j["ms"] = choice->ms;
  }
  return j;
}

// The rig's own image folders (rig.json "image_dir", relative to the rig file) when --in is not given.
std::unique_ptr<capture::Source> OpenInput(const StitchCommand& c, const capture::Rig& rig) {
  if (!c.in.empty()) return capture::OpenSource(c.in);
  std::vector<std::string> dirs;
  for (const auto& cam : rig.cameras) {
    if (cam.image_dir.empty())
      throw UsageError("--in", "not given, and the rig file names no image_dir for camera " + cam.name);
    dirs.push_back((rig.path.parent_path() / cam.image_dir).string());
  }
  return capture::OpenImageSequences(dirs, {});
}

// The stitcher's options from the command's flags, checked; --scene-distance auto leaves the
// distance for ChooseSceneDistance.
capture::StitchOptions StitchOptionsFor(const StitchCommand& c) {
  capture::StitchOptions options;
  std::tie(options.width, options.height) = ParseSize(c.size);
  if (c.device != "gpu" && c.device != "cpu")
    throw UsageError("--device", "expects gpu or cpu, got '" + c.device + "'");
  options.device = c.device == "gpu" ? capture::StitchDevice::kGpu : capture::StitchDevice::kCpu;
  options.compensate_gains = !c.no_gains;
  options.fill_unseen = !c.no_fill;
  if (c.scene_distance != "auto") {
    std::size_t used = 0;
    try {
      options.scene_distance_m = std::stod(c.scene_distance, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != c.scene_distance.size())
      throw UsageError("--scene-distance", "expects auto or metres (0 = infinity), got '" + c.scene_distance + "'");
    if (!(options.scene_distance_m >= 0) || !std::isfinite(options.scene_distance_m))
      throw UsageError("--scene-distance", "must be auto, 0 (infinity) or a positive distance");
  }
  options.Check();
  return options;
}

// --scene-distance auto: chosen once for the clip, from frames spread over a recording, or from
// the first frame set of a live source, which is then kept in `first_set` to be stitched first.
capture::SceneDistanceChoice ChooseDistance(const StitchCommand& c, const capture::Rig& rig, capture::Source* source,
                                            const capture::StitchOptions& options,
                                            std::optional<capture::FrameSet>* first_set) {
  auto choice = capture::ChooseSceneDistanceForRecording(rig, source, c.start, c.frames, options);
  if (choice) return *choice;
  *first_set = source->Next();
  std::vector<std::vector<cv::Mat>> sets;
  if (*first_set) {
    std::vector<cv::Mat>& images = sets.emplace_back();
    for (const auto& f : (*first_set)->frames) images.push_back(f.image);
  }
  return capture::ChooseSceneDistance(rig, sets, options);
}

int RunStitch(const StitchCommand& c) {
  capture::StitchOptions options = StitchOptionsFor(c);
  const bool auto_distance = c.scene_distance == "auto";
  if (c.frames < 0) throw UsageError("--frames", "must not be negative");
  if (c.start < 0) throw UsageError("--first", "must not be negative");

  std::string ext = fs::path(c.out).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  const bool video = ext == ".mp4";
  if (!video && c.format != "png" && c.format != "exr")
    throw UsageError("--format", "expects png or exr, got '" + c.format + "'");

  const capture::Rig rig = capture::LoadRig(c.rig);
  auto source = OpenInput(c, rig);
  if (source->camera_count() != rig.camera_count())
    throw Error(c.in.empty() ? c.rig : c.in, "delivers " + std::to_string(source->camera_count()) +
                                                 " cameras but the rig " + c.rig + " describes " +
                                                 std::to_string(rig.camera_count()));
  if (c.start > 0) source->Seek(c.start);

  std::optional<gl::HeadlessContext> context;
  if (options.device == capture::StitchDevice::kGpu) {
    try {
      context.emplace();
    } catch (const Error& e) {
      throw Error("--device gpu", std::string("no OpenGL 4.5 context (") + e.what() + "); use --device cpu");
    }
  }
  std::optional<capture::SceneDistanceChoice> choice;
  std::optional<capture::FrameSet> first_set;
  if (auto_distance) {
    choice = ChooseDistance(c, rig, source.get(), options, &first_set);
    options.scene_distance_m = choice->distance_m;
    if (!c.json) std::cout << choice->Summary() << "\n";
  }
  capture::Stitcher stitcher(rig, options);
  const bool progress = !c.json && ::isatty(STDERR_FILENO);
  const long total = c.frames > 0 ? c.frames : std::max(0L, source->frame_count() - c.start);

  nlohmann::json per_frame = nlohmann::json::array();
  std::vector<double> ms;
  long events = 0;
  const auto t_start = std::chrono::steady_clock::now();

  // One frame at a time: stitch, write, report. `sink` writes the frame (video or file).
  auto loop = [&](const std::function<void(long, const capture::StitchedFrame&)>& sink) {
    long done = 0;
    while (c.frames == 0 || done < c.frames) {
      auto set = first_set ? std::exchange(first_set, std::nullopt) : source->Next();
      if (!set) break;
      for (const auto& e : source->TakeEvents()) {
        ++events;
        spdlog::warn("{}", e.message);
      }
      const capture::StitchedFrame f = stitcher.Stitch(*set);
      sink(done, f);
      ms.push_back(f.report.ms_total);
      per_frame.push_back({{"index", c.start + done},
                           {"ms", f.report.ms_total},
                           {"valid_fraction", f.report.valid_fraction},
                           {"gains", f.report.gains},
                           {"cameras_used", f.report.camera_used}});
      if (!c.json) std::cout << "frame " << c.start + done << ": " << f.report.Summary() << "\n";
      ++done;
      if (progress && total > 0) {
        const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
        std::fprintf(stderr, "\rstitching %ld/%ld, ETA %.0f s   ", done, total,
                     elapsed / done * static_cast<double>(std::max(0L, total - done)));
      }
    }
    if (progress) std::fprintf(stderr, "\n");
  };

  if (video) {
    if (fs::path(c.out).has_parent_path()) fs::create_directories(fs::path(c.out).parent_path());
    WriteFileAtomically(c.out, [&](const fs::path& tmp) {
      std::unique_ptr<capture::LibavVideoWriter> writer;
      loop([&](long, const capture::StitchedFrame& f) {
        if (!writer) {
          // H.264 marked as a 360° equirectangular video (Spherical Video V2), as VLC and
          // YouTube expect of a panorama.
          capture::VideoWriterOptions o;
          o.width = f.image.width;
          o.height = f.image.height;
          o.fps = source->fps() > 0 ? source->fps() : 25;
          o.codec = "h264";
          o.spherical_equirect = true;
          writer = std::make_unique<capture::LibavVideoWriter>(tmp, o, c.out);
        }
        writer->Write(ToBgr8(f.image));
      });
      if (!writer) throw Error(c.in.empty() ? c.rig : c.in, "delivered no frames to stitch");
      writer->Finish();
      capture::CheckWrittenVideo(tmp, c.out, static_cast<long>(ms.size()));
    });
  } else {
    fs::create_directories(c.out);
    loop([&](long i, const capture::StitchedFrame& f) {
      char name[32];
      std::snprintf(name, sizeof name, "%06ld.%s", c.start + i, c.format.c_str());
      image::SaveImage(fs::path(c.out) / name, f.image);
    });
    if (ms.empty()) throw Error(c.in.empty() ? c.rig : c.in, "delivered no frames to stitch");
  }

  const double median = Median(ms);
  const auto stats = source->stats();
  if (c.json) {
    std::cout << nlohmann::json{{"rig", c.rig},
                                {"output", c.out},
                                {"device", c.device},
                                {"size", {options.width, options.height}},
                                {"frames", ms.size()},
                                {"lut_build_ms", stitcher.lut_build_ms()},
                                {"scene_distance", SceneDistanceJson(options, choice)},
                                {"median_ms", median},
                                {"drops",
                                 {{"dropped", stats.frames_dropped},
                                  {"missing", stats.missing_frames},
                                  {"corrupt", stats.corrupt_frames},
                                  {"out_of_sync", stats.frames_out_of_sync},
                                  {"events", events}}},
                                {"per_frame", per_frame}}
                     .dump(2)
              << "\n";
  } else {
    std::cout << "stitched " << ms.size() << " frames to " << c.out << " on the " << c.device << " (scene distance "
              << (options.scene_distance_m > 0 ? fmt::format("{:g} m", options.scene_distance_m) : "infinity")
              << (choice ? ", chosen" : "") << ", median " << median << " ms per frame, lookup table "
              << stitcher.lut_build_ms() << " ms; missing " << stats.missing_frames << ", corrupt "
              << stats.corrupt_frames << ", dropped " << stats.frames_dropped << ")\n";
  }
  return 0;
}

}  // namespace

CommandFn AddStitch(CLI::App* sub) {
  auto c = std::make_shared<StitchCommand>();
  sub->add_option("--rig", c->rig, "Rig calibration (config/*.json or a dataset's rig.json)")->required();
  sub->add_option("--in", c->in,
                  "Frames: per-camera image folders, videos, v4l2:/libcamera: (default: the rig file's image_dir)");
  sub->add_option("--out", c->out, "OUT.mp4, or a directory for PNG/EXR frames")->required();
  sub->add_option("--format", c->format, "Frame format when --out is a directory: exr or png")->capture_default_str();
  sub->add_option("--size", c->size, "Output equirect size WIDTHxHEIGHT")->capture_default_str();
  sub->add_option("--device", c->device, "gpu (GLSL compute) or cpu (multithreaded reference)")->capture_default_str();
  // Checked where given: 0 stands for "all" in StitchCommand.
  sub->add_option("--frames", c->frames, "Stitch at most this many frames (default: all)")->check(CLI::PositiveNumber);
  sub->add_option("--first,--start", c->start, "First frame of a recording");
  sub->add_option("--scene-distance", c->scene_distance,
                  "Metres at which camera rays meet (0 = infinity), or auto: the candidate (2 to 40 m, infinity) "
                  "whose seams disagree least on frames spread over the clip")
      ->capture_default_str();
  sub->add_flag("--no-gains", c->no_gains, "Do not compensate the cameras' exposure differences");
  sub->add_flag("--no-fill", c->no_fill, "Leave unseen directions (zenith, nadir) black");
  sub->add_flag("--json", c->json, "Print a JSON report");
  return [c] { return RunStitch(*c); };
}

}  // namespace odvr::app
