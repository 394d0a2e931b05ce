#pragma once
// A source of frame sets from N cameras: recorded image sequences, video files, an
// equirectangular video (N = 1), or live V4L2 / libcamera devices. Every source reports what
// went wrong as events the caller can survive (a camera lost, a corrupt frame) and fails with
// an odvr::Error only when it cannot start at all.
#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame.h"

namespace odvr::capture {

class Source {
 public:
  virtual ~Source() = default;
  virtual int camera_count() const = 0;
  virtual std::string description() const = 0;
  // The next frame set; nullopt at the end of a recording, or for a live source when nothing
  // arrived within `timeout` (then check events: every camera may be gone).
  virtual std::optional<FrameSet> Next(std::chrono::milliseconds timeout = std::chrono::milliseconds(1000)) = 0;
  // Live sources never end by themselves; recordings do.
  virtual bool live() const = 0;
  // Recordings: the next set delivered is frame `frame` (clamped); false for live sources.
  virtual bool Seek(long frame) {
    (void)frame;
    return false;
  }
  // Frames in a recording (0 when unknown or live).
  virtual long frame_count() const { return 0; }
  virtual double fps() const { return 0; }
  virtual std::vector<SourceEvent> TakeEvents() = 0;
  virtual SourceStats stats() const = 0;
};

struct SourceOptions {
  double fps = 25;  // timestamps of image sequences (index / fps)
  double sync_tolerance_s = 0.010;
  double stall_s = 0.5;
  std::size_t queue_capacity = 4;
  int width = 0, height = 0;  // live devices: requested size (0 = the device's default)
  std::string pixel_format;   // V4L2: "MJPG" or "YUYV" (empty = MJPG if offered, else YUYV)
};

// Per-camera image-sequence directories (the layout of ../shared/data/street_*: camC/NNNNNN.jpg).
std::unique_ptr<Source> OpenImageSequences(const std::vector<std::string>& camera_dirs, const SourceOptions& options);
// One video file per camera, or a single equirectangular video.
std::unique_ptr<Source> OpenVideoFiles(const std::vector<std::string>& paths, const SourceOptions& options);
// Live V4L2 devices (/dev/videoN), one capture thread each.
std::unique_ptr<Source> OpenV4l2(const std::vector<std::string>& devices, const SourceOptions& options);
// Live libcamera cameras by id (empty: every camera libcamera lists).
std::unique_ptr<Source> OpenLibcamera(const std::vector<std::string>& camera_ids, const SourceOptions& options);

// Recorded per-camera image sequences replayed as if live: one capture thread per camera
// delivers its images paced at options.fps on the steady clock, looping the recording. A camera
// whose sequence is shorter than the others', or whose image cannot be read, is lost mid-stream
// (as an unplugged device is) and stays lost; the others go on. Rehearses a rig without it.
std::unique_ptr<Source> OpenReplay(const std::vector<std::string>& camera_dirs, const SourceOptions& options);

// The camera folders of a recording: `dir`'s subfolders that hold images, sorted (cam0, cam1,
// ...), else `dir` itself. Throws odvr::Error when `dir` is not a directory.
std::vector<std::string> CameraDirectories(const std::string& dir);
// The image files (.jpg, .png, .exr, ...) directly in `dir`, sorted by name.
std::vector<std::filesystem::path> ImageFiles(const std::string& dir);

// Opens what `spec` names: a directory (its camera subdirectories cam0.., or the directory itself
// if it holds images), a video file, comma-separated video files, "v4l2:/dev/video0,/dev/video1"
// "libcamera:[id,id]" or "replay:DIR" (DIR's camera folders, or comma-separated camera folders,
// replayed live: OpenReplay). Throws odvr::Error naming `spec` when it is none of these.
std::unique_ptr<Source> OpenSource(const std::string& spec, const SourceOptions& options = {});

// A video just written, read back: FFmpeg's muxer reports no error when the disk fills, and
// leaves a file without its index. Throws odvr::Error naming `name` (the user's output, not the
// temporary) when `file` cannot be opened or holds fewer than `expected_frames` frames.
void CheckWrittenVideo(const std::filesystem::path& file, const std::string& name, long expected_frames);

}  // namespace odvr::capture
