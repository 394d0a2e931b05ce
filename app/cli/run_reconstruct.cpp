// `odvr reconstruct`: offline structure from motion of the calibrated rig (tracking/
// reconstruction.h) over per-camera image sequences; writes the trajectory, the COLMAP model, the
// road plane and a summary into --out, and with --ground-truth also the trajectory errors.
#include <sys/resource.h>
#include <unistd.h>

#include <spdlog/spdlog.h>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/ar/clip_reconstruction.h"
#include "app/cli/commands.h"
#include "capture/equirect_view.h"
#include "capture/rig.h"
#include "capture/source.h"
#include "core/error.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;

struct ReconstructCommand {
  std::string rig, images, video, out = "reconstruction", ground_truth;
  std::string frames;  // --frames as typed: a count, or (as before it was --images) a folder
  long first = 0, count = 0, step = 1;
  double rig_height_m = 0;
  bool json = false;
  bool no_trifocal = false;
  // One equirectangular camera (no --rig): its clip or frames, and what to track in them.
  double camera_height_m = 0;
  std::string mask, stereo = "auto";
  int eye = 0, track_width = 1024;
  double nadir_cap_deg = 20;
  long chunk_frames = tracking::ReconstructionOptions().chunk_frames;
};

std::unique_ptr<capture::Source> OpenFrames(const ReconstructCommand& c, const capture::Rig& rig) {
  if (!c.images.empty()) return capture::OpenSource(c.images);
  std::vector<std::string> dirs;
  for (const auto& cam : rig.cameras) {
    if (cam.image_dir.empty())
      throw UsageError("--images", "not given, and the rig file names no image_dir for camera " + cam.name);
    dirs.push_back((rig.path.parent_path() / cam.image_dir).string());
  }
  return capture::OpenImageSequences(dirs, {});
}

// --frames is a count, as in play, stitch and export. It named the input folder before --images
// did: a folder given to it is still read as one, with a warning.
void ResolveFrameCount(ReconstructCommand* c) {
  if (c->frames.empty()) return;
  if (c->frames.find_first_not_of("0123456789") == std::string::npos && c->frames.size() < 10) {
    c->count = std::stol(c->frames);
    return;
  }
  if (!fs::exists(c->frames) || !c->images.empty())
    throw UsageError("--frames", "is how many frames to reconstruct, got '" + c->frames + "' (a folder is --images)");
  spdlog::warn("--frames {} is a folder: read as --images {} (--frames now counts frames)", c->frames, c->frames);
  c->images = c->frames;
}

int RunReconstruct(ReconstructCommand c) {
  ResolveFrameCount(&c);
  if (c.first < 0) throw UsageError("--first", "must not be negative");
  if (c.count < 0) throw UsageError("--frames", "must not be negative");
  if (c.count > 0 && c.count < 3) throw UsageError("--frames", "structure from motion needs at least 3 frames");
  if (c.rig_height_m < 0) throw UsageError("--rig-height", "must not be negative");
  if (!c.video.empty() && !c.images.empty()) throw UsageError("--video", "and --images name the same input: give one");
  if (c.rig.empty() && c.video.empty() && c.images.empty())
    throw UsageError("--video", "give a 360° clip (--video CLIP or --images DIR of equirect images) or a --rig");
  if (!c.rig.empty() && (c.camera_height_m > 0 || !c.mask.empty()))
    throw UsageError("--camera-height", "and --mask belong to one equirect camera (no --rig): a rig has --rig-height");

  nlohmann::json extra = nlohmann::json::object();
  tracking::Reconstruction r;
  if (c.rig.empty()) {
    ClipInput in;
    in.clip = c.video.empty() ? c.images : c.video;
    in.flag = c.video.empty() ? "--images" : "--video";
    in.camera_height_m = c.camera_height_m;
    in.mask = c.mask;
    if (c.stereo != "auto") in.stereo = capture::ParseStereoLayout(c.stereo);
    in.eye = c.eye;
    in.track_width = c.track_width;
    in.first = c.first;
    in.count = c.count;
    in.step = c.step;
    in.nadir_cap_deg = c.nadir_cap_deg;
    in.trifocal = !c.no_trifocal;
    in.chunk_frames = c.chunk_frames;
    ClipReconstruction clip =
        ReconstructClip(in, c.json ? tracking::ReconstructionCallbacks() : ConsoleProgress(c.count));
    r = std::move(clip.reconstruction);
    extra["input"] = clip.input;
  } else {
    const capture::Rig rig = capture::LoadRig(c.rig);
    auto source = OpenFrames(c, rig);
    if (c.first > 0) source->Seek(c.first);
    tracking::ReconstructionOptions options;
    options.rig_height_m = c.rig_height_m;
    options.max_frames = c.count;
    options.trifocal = !c.no_trifocal;
    options.chunk_frames = c.chunk_frames;
    CheckChunkFrames(c.chunk_frames);
    const long total = c.count > 0 ? c.count : std::max(0L, source->frame_count() - c.first);
    tracking::ReconstructionCallbacks callbacks;
    if (!c.json) {
      callbacks = ConsoleProgress(total);
      options.bundle.progress = callbacks.log;
    }
    r = tracking::Reconstruct(rig, *source, options, callbacks);
  }
  if (!c.json && ::isatty(STDERR_FILENO)) std::fprintf(stderr, "\r\033[K");
  // The process's peak resident memory so far: what a long clip costs (Linux reports kilobytes).
  rusage usage{};
  ::getrusage(RUSAGE_SELF, &usage);
  const double peak_memory_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;
  extra["peak_memory_mb"] = peak_memory_mb;
  std::string evaluation_line;
  if (!c.ground_truth.empty()) {
    std::vector<tracking::TrajectoryPose> estimate;
    for (const auto& f : r.frames) estimate.push_back({f.index, f.timestamp, f.world_from_rig.Matrix()});
    const auto e = tracking::EvaluateTrajectory(estimate, tracking::LoadTrajectoryJson(c.ground_truth));
    extra["evaluation"] = {{"ground_truth", c.ground_truth},
                           {"matched_frames", e.matched},
                           {"path_length_m", e.length_m},
                           {"ate_rmse_m", e.ate_rmse_m},
                           {"ate_percent_of_path", e.ate_percent},
                           {"ate_max_m", e.ate_max_m},
                           {"ate_rigid_rmse_m", e.ate_rigid_rmse_m},
                           {"scale", e.scale},
                           {"scale_error_percent", 100 * e.scale_error},
                           {"rpe_translation_rmse_m", e.rpe_translation_rmse_m},
                           {"rpe_rotation_rmse_deg", e.rpe_rotation_rmse_deg}};
    evaluation_line = e.Summary();
  }
  tracking::WriteReconstruction(r, c.out, extra.empty() ? "" : extra.dump());

  if (c.json) {
    nlohmann::json j = nlohmann::json::parse(tracking::ReconstructionSummaryJson(r));
    j["out"] = c.out;
    j.update(extra);
    std::cout << j.dump(2) << "\n";
  } else {
    for (const auto& w : r.warnings) std::cout << "warning: " << w << "\n";
    for (const auto& s : r.stages)
      std::printf("%-18s %8.2f s  %d %s\n", s.name.c_str(), s.seconds, s.inliers, s.what.c_str());
    std::printf(
        "reconstructed %zu frames, %zu points, reprojection RMSE %.3f px, scale x%.4f (%s), peak memory %.0f MB -> "
        "%s\n",
        r.frames.size(), r.points.size(), r.rmse_px, r.scale_applied, r.scale_source.c_str(), peak_memory_mb,
        c.out.c_str());
    if (!evaluation_line.empty()) std::printf("against %s: %s\n", c.ground_truth.c_str(), evaluation_line.c_str());
  }
  return 0;
}

}  // namespace

CommandFn AddReconstruct(CLI::App* sub) {
  auto c = std::make_shared<ReconstructCommand>();
  sub->add_option("--video", c->video,
                  "A 360° clip from one camera (equirectangular MP4, MOV, MKV, TS; mono, or stereo of which one eye "
                  "is used): no --rig needed");
  sub->add_option("--rig", c->rig, "Rig calibration (config/*.json or a dataset's rig.json) for a multi-camera rig");
  sub->add_option("--images", c->images,
                  "Without --rig: a folder of equirect images. With it: per-camera image folders (a folder holding "
                  "cam0, cam1, ...) or videos (default: the rig file's image_dir)");
  sub->add_option("--camera-height", c->camera_height_m,
                  "One camera: its height above the road in metres, for metric scale (without it the trajectory is "
                  "up to scale)");
  sub->add_option("--mask", c->mask,
                  "One camera: an equirect PNG, white where the image is not the world (car roof, operator, tripod)");
  sub->add_option("--nadir-cap", c->nadir_cap_deg, "One camera: degrees around straight down never tracked")
      ->capture_default_str();
  sub->add_option("--stereo", c->stereo,
                  "One camera: auto (the file's metadata, else the frame's shape), mono, top-bottom, side-by-side")
      ->capture_default_str();
  sub->add_option("--eye", c->eye, "One camera, stereo: 0 the top/left eye, 1 the other")->capture_default_str();
  sub->add_option("--track-width", c->track_width, "One camera: frames are scaled down to this width for tracking")
      ->capture_default_str();
  sub->add_option("--step", c->step, "One camera: track every step-th frame")->capture_default_str();
  sub->add_option("--out", c->out, "Output folder")->capture_default_str();
  sub->add_option("--first", c->first, "First frame of the recording");
  sub->add_option("--frames,--count", c->frames, "How many frames to reconstruct (default: all)");
  sub->add_option("--rig-height", c->rig_height_m, "Rig height above the road in metres (default: the rig file's)");
  sub->add_option("--ground-truth", c->ground_truth,
                  "trajectory_gt.json to evaluate against (ATE, RPE, scale error; added to summary.json)");
  sub->add_option("--chunk-frames", c->chunk_frames,
                  "A longer clip is reconstructed in chunks of this many frames, each chained to the one before by "
                  "the frames they share: memory stays that of one chunk (0: in one piece)")
      ->capture_default_str();
  sub->add_flag("--no-trifocal", c->no_trifocal,
                "Skip the trifocal check of the tracks (faster; the bundle adjustment's outlier test remains)");
  sub->add_flag("--json", c->json, "Print the summary as JSON (no progress output)");
  return [c] { return RunReconstruct(*c); };
}

}  // namespace odvr::app
