// `odvr reconstruct`: offline structure from motion of the calibrated rig (tracking/
// reconstruction.h) over per-camera image sequences; writes the trajectory, the COLMAP model, the
// road plane and a summary into --out, and with --ground-truth also the trajectory errors.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "capture/rig.h"
#include "capture/source.h"
#include "engine/core/error.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;

struct ReconstructCommand {
  std::string rig, frames, out = "reconstruction", ground_truth;
  long first = 0, count = 0;
  double rig_height_m = 0;
  bool json = false;
  bool no_trifocal = false;
};

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
  const capture::Rig rig = capture::LoadRig(c.rig);
  auto source = OpenFrames(c, rig);
  if (c.first > 0) source->Seek(c.first);

  tracking::ReconstructionOptions options;
  options.max_frames = c.count;
  options.rig_height_m = c.rig_height_m;
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
  sub->add_option("--rig", c->rig, "Rig calibration (config/*.json or a dataset's rig.json)")->required();
  sub->add_option("--frames", c->frames,
                  "Per-camera image folders (a folder holding cam0, cam1, ...) or videos (default: the rig file's "
                  "image_dir)");
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
