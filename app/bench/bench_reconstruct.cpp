// odvr bench reconstruct: our structure from motion (tracking/reconstruction.h) against
// the dataset's ground-truth rig poses, beside COLMAP 3.8 run through its command line on the same
// images on the same machine. ATE after a similarity alignment, RPE and, for our metric
// trajectory, the scale error without aligning scale (tracking/evaluation.h); time per stage.
// Writes a Markdown table, the raw rows (TSV), the per-stage times and the aligned trajectories
// (TSV), and a PNG of the trajectories seen from above.
//
// COLMAP gets what a user with a calibrated rig would give it: one OPENCV_FISHEYE camera per rig
// camera with the known intrinsics, held fixed by the mapper (ours holds them fixed too), CPU
// SIFT, sequential matching with an overlap of three rig frames, no loop detection.
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/bench/bench_reconstruct.h"
#include "app/bench/bench_sfm.h"
#include "app/flags/command_flags.h"
#include "capture/rig.h"
#include "capture/source.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Rig frames the sequential matcher compares each image with: its own frame's other cameras
// and the next two frames' (seconds of video at 25 fps are far more than the 60° between
// neighbouring cameras needs to overlap).
constexpr int kMatchFrames = 3;

std::vector<tracking::TrajectoryPose> GroundTruth(const fs::path& dataset) {
  const fs::path path = dataset / "trajectory_gt.json";
  if (!fs::exists(path)) throw UsageError("--dataset", dataset.string() + " has no trajectory_gt.json");
  return tracking::LoadTrajectoryJson(path);
}

void RunOurs(const BenchReconstructOptions& o, const capture::Rig& rig, long frames,
             const std::vector<tracking::TrajectoryPose>& truth, Results* out) {
  std::vector<std::string> dirs;
  for (const auto& cam : rig.cameras) dirs.push_back((fs::path(o.dataset) / cam.image_dir).string());
  OdvrRun run;
  run.method = "odvr";
  run.dataset = fs::path(o.dataset).filename().string();
  run.frames = frames;
  run.rig = rig;
  run.open = [dirs] { return capture::OpenImageSequences(dirs, {}); };
  RunOdvrReconstruction(run, truth, out);
}

// ---- COLMAP ----------------------------------------------------------------------------------

void RunColmapBench(const BenchReconstructOptions& o, const capture::Rig& rig, long frames,
                    const std::vector<tracking::TrajectoryPose>& truth, Results* out, BenchProgress* overall) {
  for (const auto& cam : rig.cameras)
    if (cam.model.type() != capture::CameraModelType::kFisheye)
      throw Error(rig.path.string(),
                  "camera " + cam.name + " is not a fisheye; this bench gives COLMAP OPENCV_FISHEYE");
  ColmapWorkspace ws("odvr_bench_colmap", o.keep_workspace);
  // Flat names that sort frame-major (f000012_cam3.jpg): the sequential matcher orders images by
  // name, so a rig frame's cameras and the next frames' come next to each other. (Per-camera
  // folders with single_camera_per_folder would sort camera-major and never match across
  // cameras.) One extraction per rig camera with single_camera gives each its own camera.
  const int cams = rig.camera_count();
  ColmapJob job;
  job.binary = FindColmap(o.colmap);
  job.method = "colmap";
  job.dataset = fs::path(o.dataset).filename().string();
  job.frames = frames;
  job.images = frames * cams;
  job.overlap = kMatchFrames * cams;
  job.overlap_what = fmt::format("{} rig frames", kMatchFrames);
  job.camera_what = "one OPENCV_FISHEYE camera per rig camera";
  for (int c = 0; c < cams; ++c) {
    const fs::path list = ws.dir / fmt::format("list{}.txt", c);
    std::ofstream names(list);
    for (long f = 0; f < frames; ++f) {
      const std::string name = fmt::format("f{:06d}_cam{}.jpg", f, c);
      const fs::path src = fs::absolute(fs::path(o.dataset) / rig.cameras[static_cast<std::size_t>(c)].image_dir /
                                        fmt::format("{:06d}.jpg", f));
      if (!fs::exists(src)) throw Error(src.string(), "missing rig image");
      fs::create_symlink(src, ws.dir / "images" / name);
      names << name << "\n";
    }
    // COLMAP's OPENCV_FISHEYE is the same Kannala-Brandt polynomial; its pixel centres sit at +0.5.
    const auto& k = rig.cameras[static_cast<std::size_t>(c)].model;
    const auto& d = k.distortion();
    job.extractions.push_back(
        {list, "OPENCV_FISHEYE",
         fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}", k.fx(), k.fy(), k.cx() + 0.5,
                     k.cy() + 0.5, d.size() > 0 ? d[0] : 0.0, d.size() > 1 ? d[1] : 0.0, d.size() > 2 ? d[2] : 0.0,
                     d.size() > 3 ? d[3] : 0.0),
         frames});
  }
  RunColmapJob(job, ws, rig, truth, out, overall);
}

// ---- report ----------------------------------------------------------------------------------

const MethodRow* Find(const Results& r, const std::string& method) {
  for (const auto& m : r.rows)
    if (m.method == method) return &m;
  return nullptr;
}

std::string Targets(const Results& r) {
  const MethodRow* ours = Find(r, "odvr");
  const MethodRow* colmap = Find(r, "colmap");
  std::ostringstream md;
  md << "\n## Targets, from the rows above\n\n";
  const auto verdict = [](bool met) { return met ? "met" : "not met"; };
  if (!ours || !std::isfinite(ours->ate_percent)) {
    md << "**Not measured:** odvr has no trajectory in this table" << (ours ? " (" + ours->note + ")" : "") << ".\n";
    return md.str();
  }
  const bool ate_ok = ours->ate_percent <= 1.0;
  md << "- **ATE ≤ 1 % of the trajectory length: " << verdict(ate_ok) << ".** odvr's ATE is " << Num(ours->ate_m, 4)
     << " m = " << Num(ours->ate_percent, 3) << " % of the " << Num(ours->length_m, 2) << " m path (" << ours->matched
     << " frames).\n";
  if (colmap && std::isfinite(colmap->ate_m)) {
    const bool below = ours->ate_m < colmap->ate_m;
    md << "- **ATE below COLMAP's on the same sequence: " << verdict(below) << ".** " << Num(ours->ate_m, 4)
       << " m against " << Num(colmap->ate_m, 4) << " m (" << fmt::format("{:.2f}", ours->ate_m / colmap->ate_m)
       << "×)";
    if (colmap->matched != ours->matched)
      md << "; COLMAP's figure is over the " << colmap->matched << " frames it posed, odvr's over " << ours->matched;
    md << ".\n";
    const bool faster = ours->seconds < colmap->seconds;
    md << "- **In less time than COLMAP: " << verdict(faster) << ".** " << Num(ours->seconds, 1) << " s against "
       << Num(colmap->seconds, 1) << " s ("
       << (faster ? fmt::format("{:.1f}× faster", colmap->seconds / ours->seconds)
                  : fmt::format("{:.1f}× slower", ours->seconds / colmap->seconds))
       << ").\n";
  } else {
    md << "- **ATE below COLMAP's, in less time: not measured**"
       << (colmap ? " (COLMAP: " + colmap->note + ")" : " (run without --no-colmap)") << ".\n";
  }
  const bool scale_ok = ours->scale_error_percent <= 3.0;
  md << "- **Metric scale within 3 % of the truth: " << verdict(scale_ok) << ".** The metric trajectory is "
     << Num(ours->scale, 4) << "× the true length (" << Num(ours->scale_error_percent, 2)
     << " % off), with no scale aligned; its ATE after a rigid alignment alone is " << Num(ours->ate_rigid_m, 4)
     << " m.\n";
  return md.str();
}

void WriteReport(const Results& r, const BenchReconstructOptions& o) {
  const fs::path dir = o.out_dir;
  fs::create_directories(dir);
  WriteResults(r, dir, "tracking");
  const MethodRow* any = r.rows.empty() ? nullptr : &r.rows.front();
  const long cameras = any && any->frames > 0 ? any->images_total / any->frames : 6;
  std::ostringstream md;
  md << "# Tracking: the rig's trajectory against the ground truth, beside COLMAP\n\n"
     << "Made by `odvr bench reconstruct`";
  std::vector<std::string> machines;
  for (const auto& m : r.rows)
    if (std::find(machines.begin(), machines.end(), m.machine) == machines.end()) machines.push_back(m.machine);
  if (machines.size() == 1) {
    md << " on " << machines[0];
  } else {
    for (const auto& m : r.rows) md << (&m == &r.rows.front() ? "; " : ", ") << m.method << " on " << m.machine;
  }
  md << ". Dataset `" << (any ? any->dataset : "?") << "`, " << (any ? any->frames : 0) << " rig frames of " << cameras
     << " cameras (street_*: 480×640 equidistant fisheyes, 120°×160° each, 60° apart, 25 fps). Errors are "
        "against `trajectory_gt.json` (the rig centre's pose per frame), computed by tracking/evaluation.h:\n\n"
     << "- **ATE**: RMSE of the rig positions after the similarity (Umeyama) alignment that best maps the "
        "estimate onto the truth; also as % of the true path length over the frames scored.\n"
     << "- **RPE**: RMSE of the error of each frame-to-frame motion (translation in metres, rotation in degrees).\n"
     << "- **Scale error**: how much longer or shorter the metric trajectory is than the truth, with no scale "
        "aligned (the one error a similarity alignment hides). COLMAP has no metric scale: its trajectory is "
        "brought into metres by the similarity alignment before its RPE is computed, and its scale error is n/a.\n\n"
     << "Methods (both on all cores, on the same JPEGs; the time is wall-clock, from the images on disk to the "
        "poses):\n\n"
     << "- `odvr`: tracking::Reconstruct with its default options: per-camera KLT tracks, cross-camera SIFT "
        "links, non-central relative and absolute pose, Ceres bundle adjustment of the rig poses with the "
        "calibration fixed, metric scale from the road plane and the rig height in rig.json.\n"
     << "- `colmap`: COLMAP 3.8 (Debian, no CUDA) through its command line: `feature_extractor` (CPU SIFT, one "
        "OPENCV_FISHEYE camera per rig camera with the known intrinsics, k1..k4 = 0, principal point +0.5 px for "
        "COLMAP's pixel-corner origin), `sequential_matcher` (CPU; each image against the next "
     << kMatchFrames * cameras << " in frame-major order: the rest of its rig frame and the next " << kMatchFrames - 1
     << "; no quadratic overlap, no loop detection), `mapper` (CPU; intrinsics held fixed, as odvr holds them; the "
        "largest model is scored), `model_converter` to text. COLMAP knows nothing of the rig: each frame's rig "
        "pose is the average of the poses its registered cameras imply through T_rig_cam (the 0.08 m offsets "
        "scaled into COLMAP's units by the median ratio of the camera spacings). OPENCV_FISHEYE models angles "
        "below 90° only; the image corners reach 100°, so features there are lost or wrong for COLMAP, not for "
        "odvr.\n\n"
     << "| method | seconds | frames posed | images registered | points | ATE (m) | ATE (% of path) | ATE max (m) | "
        "RPE (m) | RPE (°) | scale error |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& m : r.rows)
    md << "| " << m.method << " | " << Num(m.seconds, 1) << " | " << m.frames_posed << "/" << m.frames << " | "
       << m.images_registered << "/" << m.images_total << " | " << m.points << " | " << Num(m.ate_m, 4) << " | "
       << Num(m.ate_percent, 3) << " | " << Num(m.ate_max_m, 4) << " | " << Num(m.rpe_m, 4) << " | "
       << Num(m.rpe_deg, 3) << " | "
       << (std::isfinite(m.scale_error_percent) ? Num(m.scale_error_percent, 2) + " %" : std::string("n/a")) << " |\n";
  md << "\n";
  for (const auto& m : r.rows)
    if (!m.note.empty()) md << "- `" << m.method << "`: " << m.note << ".\n";
  md << "\nTime per stage (seconds):\n\n| method | stage | seconds | |\n|---|---|---|---|\n";
  for (const auto& s : r.stages)
    md << "| " << s.method << " | " << s.stage << " | " << Num(s.seconds, 2) << " | " << s.detail << " |\n";
  md << Targets(r)
     << "\nEvery figure is in `tracking.tsv` (per-stage times in `tracking_stages.tsv`, the aligned positions in "
        "`tracking_paths.tsv`). The plot shows the trajectories from above in the ground truth's world, each "
        "estimate after the similarity alignment its ATE is computed with; below, each frame's position error after "
        "that alignment (log scale).\n\n"
        "![Trajectories seen from above](tracking.png)\n";
  WriteTextAtomically(dir / "tracking.md", md.str());

  WriteTrajectoryPlot(r, dir, "tracking", "bench reconstruct");
}

}  // namespace

int RunBenchReconstruct(const BenchReconstructOptions& o) {
  if (o.equirect) {
    if (o.colmap_only || o.report_only) throw UsageError("--equirect", "runs whole: no --colmap-only, --report-only");
    EquirectBenchOptions e;
    e.dataset = o.dataset;
    e.colmap = o.colmap;
    e.out_dir = o.out_dir;
    e.frames = o.frames;
    e.no_colmap = o.no_colmap;
    e.keep_workspace = o.keep_workspace;
    e.crf = o.crf;
    e.width = o.track_width;
    e.clip_frames = o.clip_frames;
    e.long_frames = o.long_frames;
    return RunBenchReconstructEquirect(e);
  }
  if (o.no_colmap && o.colmap_only) throw UsageError("--no-colmap", "contradicts --colmap-only");
  if (o.frames < 0 || (o.frames > 0 && o.frames < 3)) throw UsageError("--frames", "needs at least 3 frames (0: all)");
  if (o.report_only) {
    Results r = ReadResults(o.out_dir, "tracking");
    WriteReport(r, o);
    std::cout << "bench reconstruct: rewrote " << o.out_dir << "/tracking.md and tracking.png from the TSVs\n";
    return 0;
  }
  const fs::path dataset = o.dataset;
  if (!fs::exists(dataset / "rig.json"))
    throw UsageError("--dataset", dataset.string() + " has no rig.json (is ../shared/data present?)");
  const capture::Rig rig = capture::LoadRig(dataset / "rig.json");
  const auto truth = GroundTruth(dataset);
  // Frames: the ground truth's, as many as asked for.
  long frames = static_cast<long>(truth.size());
  if (o.frames > 0) {
    if (o.frames > frames)
      throw UsageError("--frames", fmt::format("{} has {} frames of ground truth, fewer than {}", dataset.string(),
                                               frames, o.frames));
    frames = o.frames;
  }
  const bool run_colmap = !o.no_colmap, run_ours = !o.colmap_only;
  if (run_colmap) FindColmap(o.colmap);  // before minutes of our own run

  Results results;
  const std::string name = dataset.filename().string();
  // Rows of the method not run now are kept from the last run on the same frames.
  if (!run_colmap || !run_ours) {
    std::error_code ec;
    std::optional<Results> old_results;
    if (fs::exists(fs::path(o.out_dir) / "tracking.tsv", ec)) try {
        old_results = ReadResults(o.out_dir, "tracking");
      } catch (const Error& e) {
        spdlog::warn("bench reconstruct: the last table is not kept: {}", e.what());
      }
    if (old_results) {
      const Results& old = *old_results;
      const std::string kept = run_ours ? "colmap" : "odvr";
      for (const auto& m : old.rows)
        if (m.method == kept && m.dataset == name && m.frames == frames) {
          results.rows.push_back(m);
          for (const auto& s : old.stages)
            if (s.method == kept) results.stages.push_back(s);
          for (const auto& p : old.paths)
            if (p.method == kept) results.paths.push_back(p);
        }
    }
  }
  for (const auto& p : truth)
    if (p.index < frames) results.paths.push_back({"ground truth", p.index, p.world_from_rig.block<3, 1>(0, 3)});

  BenchProgress overall("bench reconstruct", (run_ours ? 1 : 0) + (run_colmap ? 4 : 0));
  if (run_ours) {
    RunOurs(o, rig, frames, truth, &results);
    overall.Step("odvr reconstruct");
  }
  if (run_colmap) RunColmapBench(o, rig, frames, truth, &results, &overall);
  std::stable_sort(results.rows.begin(), results.rows.end(),
                   [](const MethodRow& a, const MethodRow& b) { return a.method > b.method; });  // odvr first
  std::stable_sort(results.stages.begin(), results.stages.end(),
                   [](const StageRow& a, const StageRow& b) { return a.method > b.method; });
  WriteReport(results, o);
  for (const auto& m : results.rows)
    std::cout << fmt::format("{}: {} s, {}/{} frames posed, ATE {} m ({} %), RPE {} m / {} deg, scale error {} %\n",
                             m.method, Num(m.seconds, 1), m.frames_posed, m.frames, Num(m.ate_m, 4),
                             Num(m.ate_percent, 3), Num(m.rpe_m, 4), Num(m.rpe_deg, 3), Num(m.scale_error_percent, 2));
  std::cout << "bench reconstruct: wrote " << o.out_dir << "/tracking.md, tracking.tsv, tracking.png\n";
  return 0;
}

CommandFn AddBenchReconstruct(CLI::App* sub) {
  auto o = std::make_shared<BenchReconstructOptions>();
  sub->add_option("--dataset", o->dataset, "A street_* dataset (rig.json, rig/, trajectory_gt.json)")
      ->capture_default_str();
  sub->add_option("--frames", o->frames, "Rig frames from the first (0: all the ground truth has)")
      ->capture_default_str();
  sub->add_flag("--no-colmap", o->no_colmap,
                "Run odvr only (COLMAP's rows from the last run on the same frames are kept)");
  sub->add_flag("--colmap-only", o->colmap_only, "Run COLMAP only (odvr's rows from the last run are kept)");
  sub->add_flag("--report-only", o->report_only, "Rewrite the table and plot from the TSVs in --out");
  sub->add_option("--colmap", o->colmap, "The COLMAP binary")->capture_default_str();
  sub->add_flag("--keep-workspace", o->keep_workspace, "Keep COLMAP's temporary workspace (database, models, log)");
  sub->add_option("--out", o->out_dir, "Where the table, TSVs and plot go (docs/benchmarks: the committed pages)")
      ->capture_default_str();
  sub->add_flag("--equirect", o->equirect,
                "One 360° camera: the dataset's panoramas and its stitched rig as H.264 videos, odvr against COLMAP "
                "on cube faces and odvr's rig mode, then the real clips beside the dataset (tracking_equirect.md)");
  sub->add_option("--crf", o->crf, "--equirect: H.264 quality of the videos made")->capture_default_str();
  sub->add_option("--track-width", o->track_width, "--equirect: tracking width")->capture_default_str();
  sub->add_option("--clip-frames", o->clip_frames, "--equirect: frames of each real clip")->capture_default_str();
  sub->add_option("--long-frames", o->long_frames,
                  "--equirect: the long clip's length, also run at a third of it, for time and memory against "
                  "length (0: none)")
      ->capture_default_str();
  return [o] { return RunBenchReconstruct(*o); };
}

}  // namespace odvr::app
