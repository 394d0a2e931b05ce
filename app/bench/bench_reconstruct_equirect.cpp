// odvr bench reconstruct --equirect: one consumer 360° camera, no rig. A street dataset's frames
// become the equirect videos a user would have, and odvr's one-camera structure from motion is
// scored against the ground truth beside COLMAP 3.8 on the same frames split into six 90° cube
// faces (how COLMAP users run 360° footage) and beside odvr's own rig mode on the rig's images:
//   (a) the dataset's ground-truth panoramas encoded as H.264 (crf 23): compression alone;
//   (b) the rig's six fisheyes stitched by odvr's stitcher, then encoded the same way: real seams,
//       exposure steps and the stitcher's parallax, as a 360° camera's own stitching leaves them.
// Each with --camera-height (metric from the road plane) and without (up to scale). Then the real
// clips of ../shared/data/video360 and the GoPro Fusion of ../shared/data/rig_fusion (a real moving
// two-fisheye rig, stitched first): every frame posed with its reprojection error, or why not.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "app/bench/bench_common.h"
#include "app/bench/bench_long_clip.h"
#include "app/bench/bench_sfm.h"
#include "capture/equirect_view.h"
#include "capture/stitcher.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "engine/image/image_io.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
constexpr int kMatchFrames = 3;      // COLMAP's sequential overlap, in frames (as the rig bench)
constexpr double kNadirCapDeg = 20;  // odvr reconstruct's default
constexpr const char* kStem = "tracking_equirect";

// A rig's image folders (one per camera, in the rig's order) stitched by odvr (CPU) at
// width x width/2, written as PNG frames, with the scene distance chosen from the frames as
// `odvr stitch` chooses it by default. Returns the choice.
capture::SceneDistanceChoice StitchRig(const capture::Rig& rig, const std::vector<std::string>& dirs, long frames,
                                       int width, const fs::path& out) {
  const std::string what = dirs.empty() ? std::string("the rig") : fs::path(dirs.front()).parent_path().string();
  auto source = capture::OpenImageSequences(dirs, {});
  capture::StitchOptions options;
  options.width = width;
  options.height = width / 2;
  auto choice = capture::ChooseSceneDistanceForRecording(rig, source.get(), 0, frames, options);
  if (!choice) throw Error(what, "the rig's image sequences cannot seek");
  options.scene_distance_m = choice->distance_m;
  capture::Stitcher stitcher(rig, options);
  fs::create_directories(out);
  for (long f = 0; f < frames; ++f) {
    auto set = source->Next();
    if (!set) throw Error(what, "the rig has only " + std::to_string(f) + " frames to stitch");
    image::SaveImage(out / fmt::format("{:06d}.png", f), stitcher.Stitch(*set).image);
  }
  return *choice;
}

OdvrRun EquirectRun(const std::string& method, const std::string& dataset, const fs::path& video, long frames,
                    int width, double camera_height_m) {
  OdvrRun run;
  run.method = method;
  run.dataset = dataset;
  run.frames = frames;
  run.rig = capture::EquirectCameraRig(width, width / 2, camera_height_m);
  run.open = [video, width] {
    capture::EquirectViewOptions view;
    view.width = width;
    return capture::OpenEquirectView(capture::OpenSource(video.string()), view);
  };
  run.options = tracking::OneCameraReconstructionOptions();
  run.options.rig_height_m = camera_height_m;
  run.options.ignore_masks = {capture::NadirCapMask(width, width / 2, kNadirCapDeg)};
  run.metric = camera_height_m > 0;
  return run;
}

// COLMAP on the video's frames split into cube faces of width/4 (90° each), all one PINHOLE
// camera with the known focal, fixed; each frame's pose from its registered faces.
void RunColmapFaces(const EquirectBenchOptions& o, const std::string& method, const std::string& dataset,
                    const fs::path& video, long frames, const std::vector<tracking::TrajectoryPose>& truth,
                    Results* out, BenchProgress* overall) {
  ColmapWorkspace ws("odvr_bench_colmap_faces", o.keep_workspace);
  const capture::RigCamera equirect = capture::EquirectCameraRig(o.width, o.width / 2, 0).cameras[0];
  const int size = o.width / 4;
  capture::Rig faces;
  faces.cameras = capture::CubeFaceCameras(equirect, size);
  ColmapJob job;
  job.binary = FindColmap(o.colmap);
  job.method = method;
  job.dataset = dataset;
  job.frames = frames;
  job.images = frames * 6;
  job.overlap = kMatchFrames * 6;
  job.overlap_what = fmt::format("{} frames of 6 faces", kMatchFrames);
  job.camera_what = fmt::format("one PINHOLE camera for every face, {}x{}, f = {} px", size, size, size / 2);
  const fs::path list = ws.dir / "list.txt";
  std::ofstream names(list);
  capture::EquirectViewOptions view;
  view.width = o.width;
  auto source = capture::OpenEquirectView(capture::OpenSource(video.string()), view);
  for (long f = 0; f < frames; ++f) {
    auto set = source->Next();
    if (!set || set->frames[0].image.empty())
      throw Error(video.string(), "delivered " + std::to_string(f) + " frames, fewer than the " +
                                      std::to_string(frames) + " asked for");
    for (int k = 0; k < 6; ++k) {
      const std::string name = fmt::format("f{:06d}_cam{}.jpg", set->frames[0].index, k);
      cv::imwrite((ws.dir / "images" / name).string(),
                  capture::CubeFaceImage(set->frames[0].image, equirect, faces.cameras[k]),
                  {cv::IMWRITE_JPEG_QUALITY, 95});
      names << name << "\n";
    }
  }
  names.close();
  // COLMAP's pixel origin is the first pixel's corner: its principal point is ours + 0.5.
  job.extractions.push_back(
      {list, "PINHOLE", fmt::format("{0},{0},{1},{1}", size / 2.0, (size - 1) / 2.0 + 0.5), job.images});
  RunColmapJob(job, ws, faces, truth, out, overall);
}

// A real clip: frames posed, reprojection RMSE, time, or the reason it failed.
struct ClipRow {
  std::string clip, layout;
  long frames = 0, posed = 0, points = 0;
  double seconds = kNaN, rmse_px = kNaN;
  std::string note;
};

ClipRow RunClip(const fs::path& clip, int width, long max_frames) {
  ClipRow row;
  row.clip = clip.filename().string();
  const auto t0 = std::chrono::steady_clock::now();
  try {
    capture::EquirectClip opened =
        capture::OpenEquirectClip(capture::OpenSource(clip.string()), clip.string(), std::nullopt, 0, width, 1, 0);
    row.layout = capture::ToString(opened.layout);
    auto& source = opened.source;
    tracking::ReconstructionOptions options = tracking::OneCameraReconstructionOptions();
    options.max_frames = max_frames;
    options.ignore_masks = {capture::NadirCapMask(opened.width, opened.width / 2, kNadirCapDeg)};
    const tracking::Reconstruction r =
        tracking::Reconstruct(capture::EquirectCameraRig(opened.width, opened.width / 2, 0), *source, options);
    row.seconds = RoundTo(SecondsSince(t0), 1e2);
    row.frames = static_cast<long>(r.frames.size() + r.dropped_frames.size());
    for (const auto& f : r.frames) row.posed += f.world_from_rig.AllFinite() ? 1 : 0;
    row.points = static_cast<long>(r.points.size());
    row.rmse_px = RoundTo(r.rmse_px, 1e3);
    for (const auto& w : r.warnings) row.note += (row.note.empty() ? "" : "; ") + w;
  } catch (const std::exception& e) {
    row.seconds = RoundTo(SecondsSince(t0), 1e2);
    row.note = std::string("failed: ") + e.what();
  }
  return row;
}

// The GoPro Fusion of ../shared/data/rig_fusion/5_2k: a real moving two-fisheye rig, no ground
// truth. Its frame pairs are stitched as case (b) stitches the street rig (same stitcher, size
// and automatic scene distance; calibration config/gopro_fusion_5_2k.json), then tracked as one
// equirect camera without a height from the PNG frames, as `odvr reconstruct --images DIR` reads
// them. Always a row: absent data, a failed stitch or unposed frames are its note.
ClipRow RunFusionRig(const fs::path& data, int width, long max_frames, const fs::path& work) {
  const fs::path frames_dir = data / "rig_fusion" / "5_2k" / "directory";
  ClipRow row;
  if (!fs::is_directory(frames_dir)) {
    row.note = "skipped: " + frames_dir.string() + " is absent";
  } else {
    try {
      const capture::Rig rig = capture::LoadRig(fs::path(ODVR_SOURCE_DIR) / "config" / "gopro_fusion_5_2k.json");
      // The rig file names each camera's folder relative to itself; the bench reads the folders of
      // those names beside --dataset, so another data folder works the same.
      std::vector<std::string> dirs;
      for (const auto& cam : rig.cameras) dirs.push_back((frames_dir / fs::path(cam.image_dir).filename()).string());
      long frames = static_cast<long>(capture::ImageFiles(dirs.front()).size());
      if (max_frames > 0) frames = std::min(frames, max_frames);  // as many as the other clips give
      const fs::path stitched = work / "rig_fusion";
      const auto choice = StitchRig(rig, dirs, frames, capture::StitchOptions().width, stitched);
      std::cout << "rig_fusion/5_2k stitched: " << choice.Summary() << "\n";
      row = RunClip(stitched, width, max_frames);
    } catch (const std::exception& e) {
      row.note = std::string("failed: ") + e.what();
    }
  }
  row.clip = "rig_fusion/5_2k (stitched)";
  row.layout = "two fisheyes";
  return row;
}

const MethodRow* Row(const Results& r, const std::string& method) {
  for (const auto& m : r.rows)
    if (m.method == method) return &m;
  return nullptr;
}

std::string Targets(const Results& r, const std::vector<std::string>& inputs) {
  std::ostringstream md;
  const auto verdict = [](bool met) { return met ? "met" : "not met"; };
  md << "\n## Targets, from the rows above\n\n";
  for (const auto& in : inputs) {
    const MethodRow* ours = Row(r, "odvr, " + in);
    const MethodRow* colmap = Row(r, "colmap faces, " + in);
    if (!ours || !std::isfinite(ours->ate_percent)) {
      md << "- **" << in << ": not measured** (" << (ours ? ours->note : "no row") << ").\n";
      continue;
    }
    md << "- **" << in << ", every frame posed: " << verdict(ours->frames_posed == ours->frames) << "** ("
       << ours->frames_posed << "/" << ours->frames
       << "). **ATE ≤ 0.1 % of the path: " << verdict(ours->ate_percent <= 0.1) << "** (" << Num(ours->ate_percent, 3)
       << " %). **Metric scale within 3 % "
       << "from the camera height alone: " << verdict(ours->scale_error_percent <= 3) << "** ("
       << Num(ours->scale_error_percent, 2) << " %).";
    if (colmap && std::isfinite(colmap->ate_m)) {
      const double speed = colmap->seconds / ours->seconds;
      md << " **ATE below COLMAP's cube faces at ≥ 10× its speed: "
         << verdict(ours->ate_m < colmap->ate_m && speed >= 10) << "** (" << Num(ours->ate_m, 4) << " m against "
         << Num(colmap->ate_m, 4) << " m, " << fmt::format("{:.1f}", speed) << "× its speed).";
    } else {
      md << " COLMAP: " << (colmap ? colmap->note : "not run on this input (or --no-colmap)") << ".";
    }
    md << "\n";
  }
  return md.str();
}

void WriteEquirectReport(const Results& r, const std::vector<ClipRow>& clips, const std::vector<LongClipRow>& long_rows,
                         const std::vector<std::string>& inputs, const capture::SceneDistanceChoice& stitch_distance,
                         const EquirectBenchOptions& o) {
  const fs::path dir = o.out_dir;
  fs::create_directories(dir);
  WriteResults(r, dir, kStem);
  std::ostringstream md;
  md << "# Tracking one 360° camera: equirect videos against the ground truth, beside COLMAP\n\n"
     << "Made by `odvr bench reconstruct --equirect` on " << MachineNow() << ". Dataset `"
     << fs::path(o.dataset).filename().string() << "`, " << (r.rows.empty() ? 0 : r.rows.front().frames)
     << " frames at 25 fps. The inputs a user would have, made from it:\n\n"
     << "- `gt H.264`: its ground-truth equirect panoramas encoded by ffmpeg (libx264, crf " << o.crf
     << ", yuv420p): compression alone.\n"
     << "- `stitched H.264`: its six fisheyes stitched by odvr's stitcher (CPU) at `odvr stitch`'s default size, "
     << capture::StitchOptions().width << "×" << capture::StitchOptions().height
     << " and its scene distance chosen from the frames as `odvr stitch` chooses it by default ("
     << stitch_distance.Summary() << "), encoded the same way: seams, exposure steps and the stitcher's parallax. "
     << "odvr tracks it at " << o.width << " wide, as it does a consumer camera's 5.7K clip.\n"
     << "- `stitched H.264 tracked at " << capture::StitchOptions().width
     << "`: the same video tracked at its full width (odvr alone): what the tracking width trades, speed against "
        "error.\n\n"
     << "Methods, each timed from the video on disk to the poses, on all cores:\n\n"
     << "- `odvr`: `odvr reconstruct --video` as a user runs it: frames scaled to " << o.width
     << " wide, one equirect camera (central solvers), a " << kNadirCapDeg
     << "° nadir cap masked, `--camera-height` from the dataset's rig height; `no height`: the same "
        "without it (up to scale: its scale error is n/a).\n"
     << "- `colmap faces`: COLMAP 3.8 (Debian, CPU) on the same decoded frames split into six 90° cube faces of "
     << o.width / 4 << "×" << o.width / 4
     << " (JPEG q95), one PINHOLE camera with the known focal held fixed, sequential matching over " << kMatchFrames
     << " frames of faces, the largest model scored; each frame's pose is the mean of its registered faces' "
        "(they share one centre). Its scale is arbitrary: aligned by the similarity, scale error n/a.\n"
     << "- `odvr rig`: odvr's rig mode on the rig's own six fisheye JPEGs (the calibrated rig it was built "
        "for).\n\n"
     << "ATE: RMSE of the positions after the similarity alignment, also in % of the path; RPE: per frame-to-frame "
        "motion; scale error: the metric trajectory's length against the truth's with no scale aligned.\n\n"
     << "| method | seconds | frames posed | points | ATE (m) | ATE (% of path) | ATE max (m) | RPE (m) | RPE (°) | "
        "scale error |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& m : r.rows)
    md << "| " << m.method << " | " << Num(m.seconds, 1) << " | " << m.frames_posed << "/" << m.frames << " | "
       << m.points << " | " << Num(m.ate_m, 4) << " | " << Num(m.ate_percent, 3) << " | " << Num(m.ate_max_m, 4)
       << " | " << Num(m.rpe_m, 4) << " | " << Num(m.rpe_deg, 3) << " | "
       << (std::isfinite(m.scale_error_percent) ? Num(m.scale_error_percent, 2) + " %" : std::string("n/a")) << " |\n";
  md << "\n";
  for (const auto& m : r.rows)
    if (!m.note.empty()) md << "- `" << m.method << "`: " << m.note << ".\n";
  md << Targets(r, inputs);
  md << "\n## Real clips (`../shared/data/video360`): no ground truth\n\n"
     << "Each as `odvr reconstruct --video` reads it (stereo by the frame's shape, one eye, " << o.width
     << " wide at most, no camera height), the first " << o.clip_frames
     << " frames. `rig_fusion/5_2k (stitched)` is a real moving two-fisheye rig, a GoPro Fusion "
        "(`../shared/data/rig_fusion/5_2k`, calibrated by `config/gopro_fusion_5_2k.json` from the fisheye "
        "circles its data gives): its frame pairs stitched as `stitched H.264` is stitched (odvr's stitcher, "
     << capture::StitchOptions().width << "×" << capture::StitchOptions().height
     << ", the scene distance chosen from the frames), then tracked the same way from the PNG frames, as "
        "`odvr reconstruct --images DIR` reads them (its seconds: the tracking alone, as for the clips).\n\n"
     << "| clip | layout | seconds | frames posed | points | reprojection RMSE (px) | note "
        "|\n|---|---|---|---|---|---|---|\n";
  for (const auto& c : clips)
    md << "| " << c.clip << " | " << c.layout << " | " << Num(c.seconds, 1) << " | " << c.posed << "/" << c.frames
       << " | " << c.points << " | " << Num(c.rmse_px, 3) << " | " << c.note << " |\n";
  if (!long_rows.empty()) md << LongClipSection(long_rows, o.crf);
  md << "\nTime per stage (seconds):\n\n| method | stage | seconds | |\n|---|---|---|---|\n";
  for (const auto& s : r.stages)
    md << "| " << s.method << " | " << s.stage << " | " << Num(s.seconds, 2) << " | " << s.detail << " |\n";
  md << "\nEvery figure is in `" << kStem << ".tsv` (stages in `" << kStem << "_stages.tsv`, aligned positions in `"
     << kStem << "_paths.tsv`).\n\n![Trajectories seen from above](" << kStem << ".png)\n";
  WriteTextAtomically(dir / (std::string(kStem) + ".md"), md.str());
  WriteTrajectoryPlot(r, dir, kStem, "bench reconstruct --equirect");
}

}  // namespace

int RunBenchReconstructEquirect(const EquirectBenchOptions& o) {
  if (o.width < 256 || o.width % 8 != 0) throw UsageError("--track-width", "must be a multiple of 8, at least 256");
  if (o.crf < 0 || o.crf > 51) throw UsageError("--crf", "must be in 0..51");
  if (o.long_frames != 0 && o.long_frames < 9)
    throw UsageError("--long-frames", "must be 0 (no long clip) or at least 9 (its third is reconstructed too)");
  const fs::path dataset = o.dataset;
  if (!fs::exists(dataset / "rig.json") || !fs::is_directory(dataset / "pano"))
    throw UsageError("--dataset", dataset.string() + " has no rig.json and pano/ (is ../shared/data present?)");
  const capture::Rig rig = capture::LoadRig(dataset / "rig.json");
  const auto truth = tracking::LoadTrajectoryJson(dataset / "trajectory_gt.json");
  long frames = static_cast<long>(truth.size());
  if (o.frames > 0) frames = std::min(frames, o.frames);
  if (frames < 3) throw UsageError("--frames", "needs at least 3 frames");
  if (!o.no_colmap) FindColmap(o.colmap);
  const double height = rig.height_m;
  const std::string name = dataset.filename().string();

  const fs::path work = fs::temp_directory_path() / fmt::format("odvr_bench_equirect_{}", ::getpid());
  fs::create_directories(work);
  struct Cleanup {
    fs::path dir;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } cleanup{work};
  BenchProgress overall("bench reconstruct --equirect", 3 + (o.no_colmap ? 0 : 8) + (o.long_frames > 0 ? 1 : 0));
  // (b) is the rig stitched as `odvr stitch` makes it by default (StitchOptions' size, the scene
  // distance chosen from the frames), then tracked at --track-width, as a user's 5.7K clip is; a
  // second row tracks it at the stitched width: the speed/accuracy trade of the tracking width
  // (odvr alone: COLMAP's cost is the cube faces, not this).
  struct Input {
    std::string label;
    fs::path video;
    int width = 0;
    bool colmap = true;
  };
  const int stitched_width = capture::StitchOptions().width;
  capture::SceneDistanceChoice stitch_distance;
  const fs::path stitched = [&] {
    std::vector<std::string> dirs;
    for (const auto& cam : rig.cameras) dirs.push_back((dataset / cam.image_dir).string());
    stitch_distance = StitchRig(rig, dirs, frames, stitched_width, work / "stitched");
    std::cout << "stitched H.264: " << stitch_distance.Summary() << "\n";
    return EncodeH264(work / "stitched", frames, o.crf, work / "stitched.mp4");
  }();
  std::vector<Input> inputs = {
      {"gt H.264", EncodeH264(dataset / "pano", frames, o.crf, work / "gt.mp4"), o.width, true},
      {"stitched H.264", stitched, o.width, true}};
  if (stitched_width != o.width)
    inputs.push_back({fmt::format("stitched H.264 tracked at {}", stitched_width), stitched, stitched_width, false});
  overall.Step("inputs encoded");

  Results results;
  for (const auto& p : truth)
    if (p.index < frames) results.paths.push_back({"ground truth", p.index, p.world_from_rig.block<3, 1>(0, 3)});
  std::vector<std::string> labels;
  for (const Input& in : inputs) {
    labels.push_back(in.label);
    RunOdvrReconstruction(EquirectRun("odvr, " + in.label, name, in.video, frames, in.width, height), truth, &results);
    if (!in.colmap) continue;
    RunOdvrReconstruction(EquirectRun("odvr, " + in.label + ", no height", name, in.video, frames, in.width, 0), truth,
                          &results);
    if (!o.no_colmap) RunColmapFaces(o, "colmap faces, " + in.label, name, in.video, frames, truth, &results, &overall);
  }
  overall.Step("odvr and COLMAP on the videos");
  OdvrRun rig_run;
  rig_run.method = "odvr rig";
  rig_run.dataset = name;
  rig_run.frames = frames;
  rig_run.rig = rig;
  rig_run.open = [dataset, rig] {
    std::vector<std::string> dirs;
    for (const auto& cam : rig.cameras) dirs.push_back((dataset / cam.image_dir).string());
    return capture::OpenImageSequences(dirs, {});
  };
  RunOdvrReconstruction(rig_run, truth, &results);
  overall.Step("odvr rig");

  std::vector<ClipRow> clips;
  const fs::path video360 = dataset.parent_path() / "video360";
  for (const char* clip : {"gopro_max_moving", "iceland0.ts", "testRoom1_1920Mono.mp4", "congo.mp4"})
    if (fs::exists(video360 / clip)) clips.push_back(RunClip(video360 / clip, o.width, o.clip_frames));
  clips.push_back(RunFusionRig(dataset.parent_path(), o.width, o.clip_frames, work));
  std::vector<LongClipRow> long_rows;
  if (o.long_frames > 0) {
    long_rows = RunLongClips(dataset, truth, {o.long_frames / 3, o.long_frames}, o.crf, height, work);
    overall.Step("the long clip");
  }
  WriteEquirectReport(results, clips, long_rows, labels, stitch_distance, o);
  for (const auto& m : results.rows)
    std::cout << fmt::format("{}: {} s, {}/{} frames posed, ATE {} m ({} %), scale error {} %\n", m.method,
                             Num(m.seconds, 1), m.frames_posed, m.frames, Num(m.ate_m, 4), Num(m.ate_percent, 3),
                             Num(m.scale_error_percent, 2));
  for (const auto& c : clips)
    std::cout << fmt::format("{} ({}): {}/{} frames posed, RMSE {} px, {} s{}\n", c.clip, c.layout, c.posed, c.frames,
                             Num(c.rmse_px, 3), Num(c.seconds, 1), c.note.empty() ? "" : "; " + c.note);
  for (const auto& l : long_rows)
    std::cout << fmt::format(
        "long clip, {} frames: {} s, {}/{} posed, {} key frames, {} chunk(s), peak {} MB, ATE {} % "
        "{}\n",
        l.frames, Num(l.seconds, 1), l.posed, l.frames, l.key_frames, l.chunks, Num(l.peak_memory_mb, 0),
        Num(l.ate_percent, 3), l.note);
  std::cout << "bench reconstruct --equirect: wrote " << o.out_dir << "/" << kStem << ".md, .tsv, .png\n";
  return 0;
}

}  // namespace odvr::app
