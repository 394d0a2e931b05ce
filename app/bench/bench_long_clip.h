#pragma once
// The long-clip part of `odvr bench reconstruct --equirect`: a street's panoramas played forwards
// and backwards into a clip many times its length (the camera drives the street to and fro), run
// through `odvr reconstruct` as a child process at two lengths, so that time and peak memory can
// be read against the clip's length: a reconstruction in chunks keeps memory flat and time linear.
#include <filesystem>
#include <string>
#include <vector>

#include "tracking/evaluation.h"

namespace odvr::app {

// Frames dir/%06d.png (0 .. frames-1) as an H.264 video at 25 fps, crf `crf`, yuv420p, by ffmpeg.
std::filesystem::path EncodeH264(const std::filesystem::path& frames_dir, long frames, int crf,
                                 const std::filesystem::path& out);

struct LongClipRow {
  long frames = 0, posed = 0, key_frames = 0, chunks = 0;
  double seconds = 0, peak_memory_mb = 0, ate_percent = 0, scale_error_percent = 0;
  std::string note;  // why a run failed
};

// Builds the clip (`longest` frames of `dataset`/pano, H.264 at `crf`) in `work` and reconstructs
// its first `lengths[i]` frames with the camera height `height_m`, each against the truth.
std::vector<LongClipRow> RunLongClips(const std::filesystem::path& dataset,
                                      const std::vector<tracking::TrajectoryPose>& truth,
                                      const std::vector<long>& lengths, int crf, double height_m,
                                      const std::filesystem::path& work);

// The markdown section of the rows: the table and what the longest says of a 10-minute clip.
std::string LongClipSection(const std::vector<LongClipRow>& rows, int crf);

}  // namespace odvr::app
