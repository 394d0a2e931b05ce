#pragma once
// Video files decoded with libav (libavformat, libavcodec, libswscale) into 8-bit BGR frames.
// Frames are numbered by their presentation time, so an index means the same frame after a seek
// as in a decode from the start, and Seek(n) delivers exactly the frame that sequential decoding
// gave as frame n. Damage is survived: a packet or frame the decoder rejects is skipped and
// counted, and the stream goes on. libav's own log goes to spdlog (warnings and errors only).
#include <memory>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>

#include "capture/equirect_view.h"

namespace odvr::capture {

// What a video file says about its video stream, read from the container without decoding.
struct VideoProbe {
  int width = 0, height = 0;
  double fps = 25;  // the stream's average frame rate, else its base rate, else 25
  // The container's own count (MP4's sample table) when it has one: frame_count_exact. Otherwise
  // duration × fps rounded, an estimate that can be off by a frame (MPEG-TS, raw streams).
  long frame_count = 0;
  bool frame_count_exact = false;
  std::string codec;  // libavcodec's name: "h264", "hevc", "mjpeg", ...
  // The container's stereo 3D side data (MP4 st3d, Matroska StereoMode; not H.264 frame-packing
  // SEI, which libav attaches to frames): nullopt when the file says nothing, or names a packing
  // odvr does not play (frame sequence, checkerboard, ...).
  std::optional<StereoLayout> stereo;
  bool stereo_inverted = false;  // the right eye is the top (or left) one
  // Spherical Video V2 (sv3d): "equirectangular", "cubemap", "equirectangular-tile"; "" when the
  // file says nothing. The orientation is the projection's yaw, pitch, roll in degrees.
  std::string projection;
  double yaw_deg = 0, pitch_deg = 0, roll_deg = 0;
};

// Sends libav's own log (process-wide) to spdlog: warnings and errors, one line each. Idempotent.
void RouteLibavLog();
// libav's text for one of its negative error codes ("No space left on device").
std::string LibavErrorText(int code);

// Throws odvr::Error naming `path` when it is missing, not a video libav can read, or has no
// video stream.
VideoProbe ProbeVideo(const std::string& path);

struct VideoFrame {
  long index = 0;          // presentation order from the stream's start (frame 0)
  double timestamp_s = 0;  // presentation time from the stream's start
  cv::Mat image;           // 8-bit BGR, width × height
  bool concealed = false;  // the decoder hit errors and patched this frame from its neighbours
};

class LibavVideoReader {
 public:
  // Throws odvr::Error naming `path` as ProbeVideo does, and when libavcodec has no decoder for
  // the stream's codec.
  explicit LibavVideoReader(const std::string& path);
  ~LibavVideoReader();
  LibavVideoReader(LibavVideoReader&&) noexcept;
  LibavVideoReader& operator=(LibavVideoReader&&) noexcept;

  const std::string& path() const;
  const VideoProbe& probe() const;
  int width() const { return probe().width; }
  int height() const { return probe().height; }
  double fps() const { return probe().fps; }
  long frame_count() const { return probe().frame_count; }  // see VideoProbe::frame_count

  // The next frame in presentation order; nullopt once the stream is over (the decoder drained,
  // so the last frames are not lost). Indices rise strictly; a frame skipped as undecodable
  // leaves a gap. Throws odvr::Error when libswscale cannot convert the frame's pixel format.
  std::optional<VideoFrame> Next();
  // Makes frame `frame` (clamped at 0) the next one Next() delivers: from the keyframe at or
  // before it, decoding forward. False when the stream ends before it (Next() then returns
  // nullopt). When the stream has no frame `frame` (a gap), the next frame after it follows.
  // Without a keyframe index (MPEG-TS) a backward seek decodes from the file's start. Throws
  // odvr::Error when the file, reopened for that, no longer opens.
  bool Seek(long frame);

  // Packets and frames the decoder rejected and the reader skipped, since opening.
  long skipped_frames() const;
  // Why the demuxer stopped early ("" when the input simply ended).
  const std::string& read_error() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace odvr::capture
