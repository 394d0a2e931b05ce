#include "app/ar/clip_reconstruction.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/image_file.h"
#include "capture/source.h"
#include "core/error.h"

namespace odvr::app {

namespace fs = std::filesystem;

void ClipInput::Check() const {
  if (clip.empty()) throw UsageError(flag, "names no clip");
  if (!(camera_height_m >= 0)) throw UsageError("--camera-height", "must not be negative");
  if (first < 0) throw UsageError("--first", "must not be negative");
  if (count < 0 || (count > 0 && count < 3))
    throw UsageError("--frames", "structure from motion needs at least 3 frames");
  if (step < 1) throw UsageError("--step", "must be at least 1");
  if (track_width < 64 || track_width % 2 != 0) throw UsageError("--track-width", "must be even and >= 64");
  if (!(nadir_cap_deg >= 0 && nadir_cap_deg < 90)) throw UsageError("--nadir-cap", "must be in [0, 90) degrees");
  if (eye != 0 && eye != 1) throw UsageError("--eye", "must be 0 (top/left) or 1 (bottom/right)");
  CheckChunkFrames(chunk_frames);
}

void CheckChunkFrames(long chunk_frames) {
  const long least = 4L * tracking::ReconstructionOptions().chunk_overlap;
  if (chunk_frames != 0 && chunk_frames < least)
    throw UsageError("--chunk-frames", "must be 0 (the clip in one piece) or at least " + std::to_string(least));
}

namespace {

// The user's mask (white: not the world) scaled to the tracking size, and the nadir cap.
cv::Mat IgnoreMask(const ClipInput& in, int width) {
  cv::Mat ignore = capture::NadirCapMask(width, width / 2, in.nadir_cap_deg);
  if (in.mask.empty()) return ignore;
  std::string problem;
  const cv::Mat mask = capture::ReadImageFile(in.mask, cv::IMREAD_GRAYSCALE, &problem);
  if (mask.empty()) throw Error(in.mask, "cannot read the mask image: " + problem);
  if (mask.cols != 2 * mask.rows)
    throw Error(in.mask, "is " + std::to_string(mask.cols) + "x" + std::to_string(mask.rows) +
                             ", not an equirectangular 2:1 mask");
  cv::Mat scaled;
  cv::resize(mask, scaled, ignore.size(), 0, 0, cv::INTER_AREA);
  ignore.setTo(255, scaled > 0);
  return ignore;
}

}  // namespace

ClipReconstruction ReconstructClip(const ClipInput& in, const tracking::ReconstructionCallbacks& callbacks) {
  in.Check();
  auto raw = capture::OpenSource(in.clip);
  if (raw->camera_count() != 1)
    throw UsageError(in.flag, in.clip + " holds " + std::to_string(raw->camera_count()) +
                                  " cameras: a multi-camera recording needs its --rig");
  capture::EquirectClip opened =
      capture::OpenEquirectClip(std::move(raw), in.clip, in.stereo, in.eye, in.track_width, in.step, in.first);
  const int width = opened.width;
  tracking::ReconstructionOptions options = tracking::OneCameraReconstructionOptions();
  options.ignore_masks = {IgnoreMask(in, width)};
  options.rig_height_m = in.camera_height_m;
  options.max_frames = in.count;
  options.trifocal = in.trifocal;
  options.chunk_frames = in.chunk_frames;
  if (callbacks.log) options.bundle.progress = callbacks.log;
  ClipReconstruction out;
  out.reconstruction = tracking::Reconstruct(capture::EquirectCameraRig(width, width / 2, in.camera_height_m),
                                             *opened.source, options, callbacks);
  out.input = {{"clip", in.clip},
               {"layout", capture::ToString(opened.layout)},
               {"eye", in.eye},
               {"tracking_width", width},
               {"step", in.step},
               {"camera_height_m", in.camera_height_m},
               {"mask", in.mask},
               {"nadir_cap_deg", in.nadir_cap_deg},
               {"metric", in.camera_height_m > 0 && out.reconstruction.road.found}};
  return out;
}

tracking::ReconstructionCallbacks ConsoleProgress(long total_frames) {
  struct State {
    bool tty = ::isatty(STDERR_FILENO) != 0;
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now(), stage_start = start;
    std::string stage;
  };
  auto state = std::make_shared<State>();
  const auto seconds = [](std::chrono::steady_clock::time_point since) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
  };
  tracking::ReconstructionCallbacks callbacks;
  callbacks.log = [state](const std::string& line) {
    if (state->tty) std::fprintf(stderr, "\r\033[K");
    std::fprintf(stderr, "%s\n", line.c_str());
  };
  callbacks.progress = [state, seconds, total_frames](const std::string& stage, int done, int stage_total) {
    if (stage_total <= 0) stage_total = static_cast<int>(total_frames);
    if (stage != state->stage) {
      state->stage = stage;
      state->stage_start = std::chrono::steady_clock::now();
    }
    const double in_stage = seconds(state->stage_start);
    const double eta = done > 0 && stage_total > done ? in_stage / done * (stage_total - done) : 0.0;
    // On a terminal one line rewrites itself; in a log every 10th frame and the last get a line.
    if (state->tty)
      std::fprintf(stderr, "\r\033[K%s %d/%d, %.0f s elapsed, stage ETA %.0f s", stage.c_str(), done, stage_total,
                   seconds(state->start), eta);
    else if (done % 10 == 0 || done == stage_total)
      std::fprintf(stderr, "%s %d/%d, %.0f s elapsed, stage ETA %.0f s\n", stage.c_str(), done, stage_total,
                   seconds(state->start), eta);
  };
  return callbacks;
}

std::string ClipCacheKey(const ClipInput& in, const fs::path& program) {
  std::error_code ec;
  const fs::path clip = fs::absolute(in.clip);
  std::string key = clip.string();
  for (const fs::path& p : {clip, in.mask.empty() ? fs::path() : fs::absolute(in.mask), program}) {
    if (p.empty()) continue;
    const auto size = fs::is_regular_file(p, ec) ? fs::file_size(p, ec) : 0;
    const auto time = fs::last_write_time(p, ec).time_since_epoch().count();
    key += "|" + p.string() + "|" + std::to_string(size) + "|" + std::to_string(time);
  }
  char options[256];
  std::snprintf(options, sizeof options, "|h%.6f|s%s|e%d|w%d|f%ld|c%ld|t%ld|n%.3f|%d|k%ld", in.camera_height_m,
                in.stereo ? capture::ToString(*in.stereo).c_str() : "auto", in.eye, in.track_width, in.first, in.count,
                in.step, in.nadir_cap_deg, in.trifocal ? 1 : 0, in.chunk_frames);
  key += options;
  char hex[24];
  std::snprintf(hex, sizeof hex, "%016zx", std::hash<std::string>{}(key));
  return hex;
}

fs::path CachedClipReconstruction(const ClipInput& in, bool* reused) {
  in.Check();
  std::error_code ec;
  const fs::path clip = fs::absolute(in.clip);
  if (!fs::exists(clip)) throw Error(in.clip, "no such file or folder");
  // The running program is part of the key: a rebuilt or upgraded odvr may track differently,
  // and poses it did not make must not stand its car in the street.
  const std::string hex = ClipCacheKey(in, fs::read_symlink("/proc/self/exe", ec));
  const char* xdg = std::getenv("XDG_CACHE_HOME");
  const char* home = std::getenv("HOME");
  const fs::path root = xdg && *xdg     ? fs::path(xdg)
                        : home && *home ? fs::path(home) / ".cache"
                                        : fs::temp_directory_path();
  const fs::path dir = root / "odvr" / "reconstructions" / (clip.filename().string() + "-" + hex);
  *reused = fs::exists(dir / "trajectory.json", ec);
  if (*reused) return dir;
  const fs::path tmp = dir.string() + ".tmp" + std::to_string(::getpid());
  fs::remove_all(tmp, ec);
  try {
    const ClipReconstruction r = ReconstructClip(in, ConsoleProgress(in.count));
    tracking::WriteReconstruction(r.reconstruction, tmp, nlohmann::json{{"input", r.input}}.dump());
    fs::create_directories(dir.parent_path());
    fs::rename(tmp, dir, ec);
    if (ec && !fs::exists(dir / "trajectory.json"))
      throw Error(dir.string(), "cannot move the reconstruction into place: " + ec.message());
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  fs::remove_all(tmp, ec);  // another run put its own in place first
  return dir;
}

}  // namespace odvr::app
