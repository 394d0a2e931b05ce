// `odvr reconstruct`: offline structure from motion of the calibrated rig (tracking/
// reconstruction.h) over per-camera image sequences; writes the trajectory, the COLMAP model, the
// road plane and a summary into --out, and with --ground-truth also the trajectory errors.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/commands.h"
#include "capture/equirect_view.h"
#include "capture/rig.h"
#include "capture/source.h"
#include "engine/core/error.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;

struct ReconstructCommand {
  std::string rig, frames, video, out = "reconstruction", ground_truth;
  long first = 0, count = 0, step = 1;
  double rig_height_m = 0;
  bool json = false;
  bool no_trifocal = false;
  // One equirectangular camera (no --rig): its clip or frames, and what to track in them.
  double camera_height_m = 0;
  std::string mask, stereo = "auto";
  int eye = 0, track_width = 1024;
  double nadir_cap_deg = 20;
};

// A one-camera clip as the tracker reads it: one eye, scaled to the tracking width, every
// step-th frame; the rig of that camera; the ignore mask (the user's, and a cap around the nadir
// where the operator or the mount is).
struct EquirectInput {
  std::unique_ptr<capture::Source> source;
  capture::Rig rig;
  cv::Mat ignore;
  std::string layout;
};

EquirectInput OpenEquirectClip(const ReconstructCommand& c) {
  const std::string& clip = c.video.empty() ? c.frames : c.video;
  const char* flag = c.video.empty() ? "--frames" : "--video";
  auto raw = capture::OpenSource(clip);
  if (raw->camera_count() != 1)
    throw UsageError(flag, clip + " holds " + std::to_string(raw->camera_count()) +
                               " cameras: a multi-camera recording needs its --rig");
  if (c.first > 0) raw->Seek(c.first);
  const auto first = raw->Next();
  if (!first || first->frames.front().image.empty()) throw Error(clip, "no decodable first frame");
  const cv::Mat& image = first->frames.front().image;
  capture::EquirectViewOptions view;
  view.layout =
      c.stereo == "auto" ? capture::GuessStereoLayout(image.cols, image.rows) : capture::ParseStereoLayout(c.stereo);
  int w = 0, h = 0;
  capture::EyeSize(view.layout, image.cols, image.rows, &w, &h);
  if (w != 2 * h)
    throw Error(clip, "a " + capture::ToString(view.layout) + " frame of " + std::to_string(image.cols) + "x" +
                          std::to_string(image.rows) + " gives a " + std::to_string(w) + "x" + std::to_string(h) +
                          " eye, not an equirectangular 2:1 image (--stereo names the layout)");
  view.eye = c.eye;
  view.width = std::min(c.track_width, w - w % 2);
  view.step = c.step;
  raw->Seek(c.first);
  EquirectInput in;
  in.layout = capture::ToString(view.layout);
  in.source = capture::OpenEquirectView(std::move(raw), view);
  in.rig = capture::EquirectCameraRig(view.width, view.width / 2, c.camera_height_m);
  in.ignore = cv::Mat::zeros(view.width / 2, view.width, CV_8U);
  if (!c.mask.empty()) {
    const cv::Mat mask = cv::imread(c.mask, cv::IMREAD_GRAYSCALE);
    if (mask.empty()) throw Error(c.mask, "cannot read the mask image");
    if (mask.cols != 2 * mask.rows)
      throw Error(c.mask, "is " + std::to_string(mask.cols) + "x" + std::to_string(mask.rows) +
                              ", not an equirectangular 2:1 mask");
    cv::Mat scaled;
    cv::resize(mask, scaled, in.ignore.size(), 0, 0, cv::INTER_AREA);
    in.ignore.setTo(255, scaled > 0);
  }
  // Rows whose elevation lies within nadir_cap_deg of straight down.
  const int cap_rows = static_cast<int>(std::ceil(c.nadir_cap_deg / 180.0 * in.ignore.rows));
  if (cap_rows > 0) in.ignore.rowRange(in.ignore.rows - std::min(cap_rows, in.ignore.rows), in.ignore.rows).setTo(255);
  return in;
}

std::unique_ptr<capture::Source> OpenFrames(const ReconstructCommand& c, const capture::Rig& rig) {
  if (!c.frames.empty()) return capture::OpenSource(c.frames);
  std::vector<std::string> dirs;
  for (const auto& cam : rig.cameras) {
    if (cam.image_dir.empty())
      throw UsageError("--frames", "not given, and the rig file names no image_dir for camera " + cam.name);
    dirs.push_back((rig.path.parent_path() / cam.image_dir).string());
  }
  return capture::OpenImageSequences(dirs, {});
}

int RunReconstruct(const ReconstructCommand& c) {
  if (c.first < 0) throw UsageError("--first", "must not be negative");
  if (c.count < 0) throw UsageError("--count", "must not be negative");
  if (c.count > 0 && c.count < 3) throw UsageError("--count", "structure from motion needs at least 3 frames");
  if (c.rig_height_m < 0) throw UsageError("--rig-height", "must not be negative");
  if (!(c.camera_height_m >= 0)) throw UsageError("--camera-height", "must not be negative");
  if (c.step < 1) throw UsageError("--step", "must be at least 1");
  if (c.track_width < 64 || c.track_width % 2 != 0) throw UsageError("--track-width", "must be even and >= 64");
  if (!(c.nadir_cap_deg >= 0 && c.nadir_cap_deg < 90)) throw UsageError("--nadir-cap", "must be in [0, 90) degrees");
  if (c.eye != 0 && c.eye != 1) throw UsageError("--eye", "must be 0 (top/left) or 1 (bottom/right)");
  if (!c.video.empty() && !c.frames.empty()) throw UsageError("--video", "and --frames name the same input: give one");
  if (c.rig.empty() && c.video.empty() && c.frames.empty())
    throw UsageError("--video", "give a 360° clip (--video CLIP or --frames DIR of equirect images) or a --rig");
  if (!c.rig.empty() && (c.camera_height_m > 0 || !c.mask.empty()))
    throw UsageError("--camera-height", "and --mask belong to one equirect camera (no --rig): a rig has --rig-height");

  tracking::ReconstructionOptions options;
  capture::Rig rig;
  std::unique_ptr<capture::Source> source;
  std::string layout;
  if (c.rig.empty()) {
    EquirectInput in = OpenEquirectClip(c);
    rig = in.rig;
    source = std::move(in.source);
    options.ignore_masks = {in.ignore};
    options.rig_height_m = c.camera_height_m;
    layout = in.layout;
  } else {
    rig = capture::LoadRig(c.rig);
    source = OpenFrames(c, rig);
    if (c.first > 0) source->Seek(c.first);
    options.rig_height_m = c.rig_height_m;
  }
  options.max_frames = c.count;
  options.trifocal = !c.no_trifocal;
  const long total = c.count > 0 ? c.count : std::max(0L, source->frame_count() - c.first);
  const bool tty = ::isatty(STDERR_FILENO);
  const auto t_start = std::chrono::steady_clock::now();
  std::string last_stage;
  tracking::ReconstructionCallbacks callbacks;
  if (!c.json) {
    callbacks.log = [tty](const std::string& line) {
      if (tty) std::fprintf(stderr, "\r\033[K");
      std::fprintf(stderr, "%s\n", line.c_str());
    };
    options.bundle.progress = callbacks.log;
    callbacks.progress = [&, tty, total](const std::string& stage, int done, int stage_total) {
      if (stage_total <= 0) stage_total = static_cast<int>(total);
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
      static auto stage_start = t_start;
      if (stage != last_stage) {
        stage_start = std::chrono::steady_clock::now();
        last_stage = stage;
      }
      const double in_stage = std::chrono::duration<double>(std::chrono::steady_clock::now() - stage_start).count();
      const double eta = done > 0 && stage_total > done ? in_stage / done * (stage_total - done) : 0.0;
      // On a terminal one line rewrites itself; in a log every 10th frame and the last get a line.
      if (tty)
        std::fprintf(stderr, "\r\033[K%s %d/%d, %.0f s elapsed, stage ETA %.0f s", stage.c_str(), done, stage_total,
                     elapsed, eta);
      else if (done % 10 == 0 || done == stage_total)
        std::fprintf(stderr, "%s %d/%d, %.0f s elapsed, stage ETA %.0f s\n", stage.c_str(), done, stage_total, elapsed,
                     eta);
    };
  }
  const tracking::Reconstruction r = tracking::Reconstruct(rig, *source, options, callbacks);
  if (!c.json && tty) std::fprintf(stderr, "\r\033[K");

  nlohmann::json extra = nlohmann::json::object();
  if (c.rig.empty())
    extra["input"] = {{"clip", c.video.empty() ? c.frames : c.video},
                      {"layout", layout},
                      {"eye", c.eye},
                      {"tracking_width", rig.cameras[0].model.width()},
                      {"step", c.step},
                      {"camera_height_m", c.camera_height_m},
                      {"mask", c.mask},
                      {"nadir_cap_deg", c.nadir_cap_deg},
                      {"metric", c.camera_height_m > 0 && r.road.found}};
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
    std::printf("reconstructed %zu frames, %zu points, reprojection RMSE %.3f px, scale x%.4f (%s) -> %s\n",
                r.frames.size(), r.points.size(), r.rmse_px, r.scale_applied, r.scale_source.c_str(), c.out.c_str());
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
  sub->add_option("--frames", c->frames,
                  "Without --rig: a folder of equirect images. With it: per-camera image folders (a folder holding "
                  "cam0, cam1, ...) or videos (default: the rig file's image_dir)");
  sub->add_option("--camera-height", c->camera_height_m,
                  "One camera: its height above the road in metres, for metric scale (without it the trajectory is "
                  "up to scale)");
  sub->add_option("--mask", c->mask,
                  "One camera: an equirect PNG, white where the image is not the world (car roof, operator, tripod)");
  sub->add_option("--nadir-cap", c->nadir_cap_deg, "One camera: degrees around straight down never tracked")
      ->capture_default_str();
  sub->add_option("--stereo", c->stereo, "One camera: auto (by the frame's shape), mono, top-bottom, side-by-side")
      ->capture_default_str();
  sub->add_option("--eye", c->eye, "One camera, stereo: 0 the top/left eye, 1 the other")->capture_default_str();
  sub->add_option("--track-width", c->track_width, "One camera: frames are scaled down to this width for tracking")
      ->capture_default_str();
  sub->add_option("--step", c->step, "One camera: track every step-th frame")->capture_default_str();
  sub->add_option("--out", c->out, "Output folder")->capture_default_str();
  sub->add_option("--first", c->first, "First frame of the recording");
  sub->add_option("--count", c->count, "Frames to reconstruct (default: all)");
  sub->add_option("--rig-height", c->rig_height_m, "Rig height above the road in metres (default: the rig file's)");
  sub->add_option("--ground-truth", c->ground_truth,
                  "trajectory_gt.json to evaluate against (ATE, RPE, scale error; added to summary.json)");
  sub->add_flag("--no-trifocal", c->no_trifocal,
                "Skip the trifocal check of the tracks (faster; the bundle adjustment's outlier test remains)");
  sub->add_flag("--json", c->json, "Print the summary as JSON (no progress output)");
  return [c] { return RunReconstruct(*c); };
}

}  // namespace odvr::app
