#pragma once
// Video files encoded with libav (libavcodec, libavformat, libswscale): H.264 and H.265 as every
// player and site takes them, or Motion JPEG. The container follows the file's extension.
#include <filesystem>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <string>

namespace odvr::capture {

// The frame rates written. Below one frame in 100 s a clip is a slide show that players and
// libav's timestamps handle badly; above 1000 no display shows the frames.
constexpr double kMinFps = 0.01, kMaxFps = 1000;

struct VideoWriterOptions {
  int width = 0, height = 0;  // even, for 4:2:0 chroma
  double fps = 25;
  // "h264" (libx264), "h265" (libx265) or "mjpeg"; "" picks by the file's extension: MJPEG for
  // .avi, H.264 for the rest (.mp4, .mov, .m4v, .mkv).
  std::string codec;
  // Constant rate factor of x264/x265 (0 lossless .. 51; 18-23 looks like the source), or the
  // MJPEG quantiser's equivalent.
  int crf = 20;
  // Google's Spherical Video V2 metadata (sv3d, and st3d: mono) marking the video as a 360°
  // equirectangular one, so that players and sites show it as 360°. MP4/MOV and Matroska.
  bool spherical_equirect = false;
  // Sound: the first audio stream of this file, copied as it is (no re-encoding), from
  // `audio_start_s` of it for as long as the video written lasts, so that a clip made from a
  // recording keeps the recording's sound in step with its pictures. Empty: silent. A file with
  // no audio leaves the clip silent; so does audio the container cannot hold (audio_dropped() says so).
  std::string audio_from;
  double audio_start_s = 0;
  void Check() const;  // throws odvr::UsageError naming the field
};

// The codec VideoWriterOptions::codec "" means for `path`'s extension; throws odvr::UsageError for
// an extension no codec is written into.
std::string DefaultCodecFor(const std::filesystem::path& path);

class LibavVideoWriter {
 public:
  // Opens `path` for writing (the container by its extension). Errors name `name` (the output the
  // user asked for, when `path` is its temporary; `path` itself when empty): odvr::Error when
  // libav has no such container or encoder, or cannot open the file.
  LibavVideoWriter(const std::filesystem::path& path, const VideoWriterOptions& options, const std::string& name = "");
  // Without Finish() the file is left unfinished (no trailer): the caller discards it.
  ~LibavVideoWriter();
  LibavVideoWriter(const LibavVideoWriter&) = delete;
  LibavVideoWriter& operator=(const LibavVideoWriter&) = delete;

  // One 8-bit BGR frame of the options' size, shown for 1/fps. Throws odvr::Error naming the file
  // when encoding or writing fails (a full disk).
  void Write(const cv::Mat& bgr);
  // Drains the encoder and writes the container's trailer; any failure is an odvr::Error.
  void Finish();
  long frames_written() const;
  const std::string& codec_name() const;  // libavcodec's encoder name: libx264, libx265, mjpeg
  // The audio codec copied ("aac", "opus", ...), or "" when the clip is silent.
  const std::string& audio_codec() const;
  // Why the source's audio was left out ("" when it was copied, or when the source has none): a
  // codec the container cannot hold.
  const std::string& audio_dropped() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace odvr::capture
