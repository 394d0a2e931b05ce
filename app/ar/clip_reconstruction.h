#pragma once
// One 360° camera's clip to its trajectory: what `odvr reconstruct --video` runs, and what
// `odvr play CLIP --car CAR` runs first (once, cached) when it is given no trajectory.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "capture/equirect_view.h"
#include "tracking/reconstruction.h"

namespace odvr::app {

struct ClipInput {
  std::string clip;                             // a video, or a folder of equirect images
  std::string flag = "--video";                 // the option that named it, for usage errors
  double camera_height_m = 0;                   // above the road; 0: up to scale
  std::string mask;                             // equirect PNG, white where the image is not the world
  std::optional<capture::StereoLayout> stereo;  // none: the frame's shape decides
  int eye = 0, track_width = 1024;
  long first = 0, count = 0, step = 1;
  double nadir_cap_deg = 20;
  bool trifocal = true;
  long chunk_frames = tracking::ReconstructionOptions().chunk_frames;  // 0: the clip in one piece
  // Throws UsageError naming the option of the first bad field.
  void Check() const;
};

struct ClipReconstruction {
  tracking::Reconstruction reconstruction;
  nlohmann::json input;  // what was read and how: summary.json's "input"
};

// Throws UsageError for a multi-camera source, odvr::Error for a clip it cannot read.
ClipReconstruction ReconstructClip(const ClipInput& in, const tracking::ReconstructionCallbacks& callbacks);

// Throws UsageError naming --chunk-frames unless it is 0 or long enough for chunks to overlap.
void CheckChunkFrames(long chunk_frames);

// Progress on stderr as odvr reconstruct prints it: a line that rewrites itself on a terminal,
// a line per 10 frames in a log; stage lines and bundle adjustment iterations through `log`.
tracking::ReconstructionCallbacks ConsoleProgress(long total_frames);

// The key of `in`'s cached reconstruction when `program` makes it: a hash of the clip's (and the
// mask's) path, size and time, every option, and the program file's path, size and time.
std::string ClipCacheKey(const ClipInput& in, const std::filesystem::path& program);

// The folder holding `in`'s reconstruction in the user's cache ($XDG_CACHE_HOME or ~/.cache,
// odvr/reconstructions/<clip>-<ClipCacheKey with the running executable>), made on a miss:
// reconstructed into a temporary folder renamed into place, so an interrupted run leaves no half
// set. `reused`: whether it was there.
std::filesystem::path CachedClipReconstruction(const ClipInput& in, bool* reused);

}  // namespace odvr::app
