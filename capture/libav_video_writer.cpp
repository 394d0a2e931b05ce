#include "capture/libav_video_writer.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cstdint>
#include <string>

#include "capture/libav_video.h"
#include "core/error.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/opt.h>
#include <libavutil/spherical.h>
#include <libavutil/stereo3d.h>
#include <libswscale/swscale.h>
}

namespace odvr::capture {
namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

void VideoWriterOptions::Check() const {
  if (width < 16 || height < 16 || width > 8192 || height > 8192 || width % 2 || height % 2)
    throw UsageError("video size", "must be even and between 16x16 and 8192x8192, got " + std::to_string(width) + "x" +
                                       std::to_string(height));
  if (!(fps >= kMinFps && fps <= kMaxFps))
    throw UsageError("--fps", fmt::format("must be in [{:g}, {:g}], got {:g}", kMinFps, kMaxFps, fps));
  if (!codec.empty() && codec != "h264" && codec != "h265" && codec != "mjpeg")
    throw UsageError("--codec", "\"" + codec + "\" is none of h264, h265, mjpeg");
  if (crf < 0 || crf > 51) throw UsageError("--crf", "must be in 0..51");
  if (!(audio_start_s >= 0 && audio_start_s < 1e7)) throw UsageError("audio start", "must be a time in seconds >= 0");
}

std::string DefaultCodecFor(const std::filesystem::path& path) {
  const std::string ext = Lower(path.extension().string());
  if (ext == ".avi") return "mjpeg";
  if (ext == ".mp4" || ext == ".mov" || ext == ".m4v" || ext == ".mkv") return "h264";
  throw UsageError("--out", "'" + path.string() + "': the clip must be .mp4, .mov, .m4v, .mkv or .avi");
}

struct LibavVideoWriter::Impl {
  std::string path;  // the file written
  std::string name;  // the file errors name: the output the user asked for
  VideoWriterOptions options;
  AVFormatContext* format = nullptr;
  AVCodecContext* encoder = nullptr;
  AVStream* stream = nullptr;
  SwsContext* scaler = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  long frames = 0;
  bool header_written = false, finished = false;
  std::string codec_name;
  // The audio copied: its input, its stream there and here, the input's pts of audio_start_s.
  AVFormatContext* audio_in = nullptr;
  int audio_in_index = -1;
  AVStream* audio_out = nullptr;
  AVPacket* audio_packet = nullptr;
  std::int64_t audio_start_pts = 0;
  bool audio_ended = false;
  std::string audio_codec, audio_dropped;

  [[noreturn]] void Fail(const std::string& what, int code) const {
    throw Error(name, what + (code < 0 ? ": " + LibavErrorText(code) : std::string()));
  }

  // Sends `input` (nullptr: drain) and writes every packet the encoder has ready.
  void Encode(AVFrame* input) {
    int rc = avcodec_send_frame(encoder, input);
    if (rc < 0) Fail("cannot encode frame " + std::to_string(frames), rc);
    while ((rc = avcodec_receive_packet(encoder, packet)) >= 0) {
      av_packet_rescale_ts(packet, encoder->time_base, stream->time_base);
      packet->stream_index = stream->index;
      const int wrote = av_interleaved_write_frame(format, packet);
      av_packet_unref(packet);
      if (wrote < 0) Fail("cannot write (disk full?)", wrote);
    }
    if (rc != AVERROR(EAGAIN) && rc != AVERROR_EOF) Fail("the encoder failed", rc);
  }

  void OpenEncoder() {
    const std::string codec = options.codec.empty() ? DefaultCodecFor(path) : options.codec;
    const char* encoder_name = codec == "h264" ? "libx264" : codec == "h265" ? "libx265" : "mjpeg";
    const AVCodec* found = avcodec_find_encoder_by_name(encoder_name);
    if (!found) Fail(std::string("this libavcodec has no ") + encoder_name + " encoder", 0);
    codec_name = encoder_name;
    encoder = avcodec_alloc_context3(found);
    encoder->width = options.width;
    encoder->height = options.height;
    encoder->time_base = av_inv_q(av_d2q(options.fps, 100000));
    encoder->framerate = av_d2q(options.fps, 100000);
    encoder->pix_fmt = codec == "mjpeg" ? AV_PIX_FMT_YUVJ420P : AV_PIX_FMT_YUV420P;
    // BT.709, limited range for H.264/H.265 (what players assume for HD); MJPEG is JPEG's
    // full-range BT.601.
    encoder->colorspace = codec == "mjpeg" ? AVCOL_SPC_BT470BG : AVCOL_SPC_BT709;
    encoder->color_primaries = AVCOL_PRI_BT709;
    encoder->color_trc = AVCOL_TRC_BT709;
    encoder->color_range = codec == "mjpeg" ? AVCOL_RANGE_JPEG : AVCOL_RANGE_MPEG;
    encoder->gop_size = std::max(1, static_cast<int>(2 * options.fps));  // a keyframe every 2 s: seekable
    if (format->oformat->flags & AVFMT_GLOBALHEADER) encoder->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    AVDictionary* settings = nullptr;
    if (codec == "mjpeg") {
      // The quantiser from the CRF scale: 20 ↔ qscale 3 (near transparent), 51 ↔ 31.
      const int q = std::clamp(2 + options.crf * 29 / 51, 2, 31);
      encoder->flags |= AV_CODEC_FLAG_QSCALE;
      encoder->global_quality = FF_QP2LAMBDA * q;
    } else {
      av_dict_set(&settings, "crf", std::to_string(options.crf).c_str(), 0);
      av_dict_set(&settings, "preset", "medium", 0);
      if (codec == "h265") av_dict_set(&settings, "x265-params", "log-level=error", 0);
    }
    const int rc = avcodec_open2(encoder, found, &settings);
    av_dict_free(&settings);
    if (rc < 0) Fail(std::string("cannot open the ") + encoder_name + " encoder", rc);
  }

  void AddSphericalMetadata() {
    // sv3d: equirectangular, no rotation, the whole sphere; st3d: mono.
    std::size_t size = 0;
    AVSphericalMapping* spherical = av_spherical_alloc(&size);
    spherical->projection = AV_SPHERICAL_EQUIRECTANGULAR;
    if (av_stream_add_side_data(stream, AV_PKT_DATA_SPHERICAL, reinterpret_cast<std::uint8_t*>(spherical), size) < 0) {
      av_free(spherical);
      Fail("cannot add spherical metadata", 0);
    }
    AVStereo3D* stereo = av_stereo3d_alloc();
    stereo->type = AV_STEREO3D_2D;
    if (av_stream_add_side_data(stream, AV_PKT_DATA_STEREO3D, reinterpret_cast<std::uint8_t*>(stereo),
                                sizeof(AVStereo3D)) < 0) {
      av_free(stereo);
      Fail("cannot add stereo metadata", 0);
    }
  }

  // Opens options.audio_from's first audio stream and adds its copy to the output, before the
  // header is written. A source without audio, or with audio this container cannot hold, is
  // not an error: the clip is silent (audio_dropped says why for the second).
  void OpenAudio() {
    const std::string source = options.audio_from;
    int rc = avformat_open_input(&audio_in, source.c_str(), nullptr, nullptr);
    if (rc < 0) throw Error(source, "cannot open for its audio: " + LibavErrorText(rc));
    rc = avformat_find_stream_info(audio_in, nullptr);
    if (rc < 0) throw Error(source, "cannot read its streams: " + LibavErrorText(rc));
    audio_in_index = av_find_best_stream(audio_in, AVMEDIA_TYPE_AUDIO, -1, -1, nullptr, 0);
    if (audio_in_index < 0) return;  // a recording without sound
    const AVStream* in = audio_in->streams[audio_in_index];
    const AVCodecID id = in->codecpar->codec_id;
    if (avformat_query_codec(format->oformat, id, FF_COMPLIANCE_NORMAL) != 1) {
      audio_dropped = std::string("the ") + format->oformat->name + " container cannot hold " + avcodec_get_name(id) +
                      " audio: the clip is silent (MP4, MOV or MKV take AAC)";
      audio_in_index = -1;
      return;
    }
    audio_out = avformat_new_stream(format, nullptr);
    if (!audio_out) Fail("cannot add an audio stream", 0);
    rc = avcodec_parameters_copy(audio_out->codecpar, in->codecpar);
    if (rc < 0) Fail("cannot copy the audio stream's parameters", rc);
    audio_out->codecpar->codec_tag = 0;  // the source container's tag may mean nothing in this one
    audio_out->time_base = in->time_base;
    audio_codec = avcodec_get_name(id);
    audio_packet = av_packet_alloc();
    const std::int64_t first = in->start_time == AV_NOPTS_VALUE ? 0 : in->start_time;
    audio_start_pts = first + av_rescale_q(static_cast<std::int64_t>(options.audio_start_s * AV_TIME_BASE),
                                           AV_TIME_BASE_Q, in->time_base);
    if (options.audio_start_s > 0) {
      const std::int64_t target = av_rescale_q(audio_start_pts, in->time_base, AV_TIME_BASE_Q);
      rc = avformat_seek_file(audio_in, -1, INT64_MIN, target, target, 0);
      if (rc < 0) throw Error(source, "cannot seek its audio to " + std::to_string(options.audio_start_s) + " s");
    }
  }

  // Copies the source's audio packets that start before `until_s` of the clip (the time of the
  // video written so far), shifted so that audio_start_s of the source plays at the clip's 0.
  void CopyAudioUntil(double until_s) {
    if (audio_in_index < 0 || audio_ended) return;
    const AVRational in_tb = audio_in->streams[audio_in_index]->time_base;
    const std::int64_t until =
        audio_start_pts + av_rescale_q(static_cast<std::int64_t>(until_s * AV_TIME_BASE), AV_TIME_BASE_Q, in_tb);
    for (;;) {
      if (!audio_packet->data) {  // nothing held back from the last call
        const int rc = av_read_frame(audio_in, audio_packet);
        if (rc == AVERROR_EOF) {
          audio_ended = true;
          return;
        }
        if (rc < 0) throw Error(options.audio_from, "cannot read its audio: " + LibavErrorText(rc));
        if (audio_packet->stream_index != audio_in_index) {
          av_packet_unref(audio_packet);
          continue;
        }
      }
      const std::int64_t pts = audio_packet->pts != AV_NOPTS_VALUE ? audio_packet->pts : audio_packet->dts;
      if (pts == AV_NOPTS_VALUE || pts < audio_start_pts) {  // before the clip's start (or untimed)
        av_packet_unref(audio_packet);
        continue;
      }
      if (pts >= until) return;  // held for the next call
      audio_packet->pts = pts - audio_start_pts;
      audio_packet->dts = audio_packet->dts == AV_NOPTS_VALUE ? audio_packet->pts : audio_packet->dts - audio_start_pts;
      av_packet_rescale_ts(audio_packet, in_tb, audio_out->time_base);
      audio_packet->stream_index = audio_out->index;
      audio_packet->pos = -1;
      const int wrote = av_interleaved_write_frame(format, audio_packet);  // takes the packet's data
      av_packet_unref(audio_packet);
      if (wrote < 0) Fail("cannot write audio (disk full?)", wrote);
    }
  }

  void Open() {
    int rc = avformat_alloc_output_context2(&format, nullptr, nullptr, path.c_str());
    if (rc < 0 || !format) Fail("libav writes no container for this extension", rc);
    OpenEncoder();
    stream = avformat_new_stream(format, nullptr);
    if (!stream) Fail("cannot add a video stream", 0);
    stream->time_base = encoder->time_base;
    stream->avg_frame_rate = encoder->framerate;
    rc = avcodec_parameters_from_context(stream->codecpar, encoder);
    if (rc < 0) Fail("cannot set the stream's parameters", rc);
    // hvc1: the HEVC tag Apple's players want in MP4/MOV (hev1 is the default).
    if (codec_name == "libx265" && format->oformat->codec_tag) stream->codecpar->codec_tag = MKTAG('h', 'v', 'c', '1');
    if (options.spherical_equirect) AddSphericalMetadata();
    if (!options.audio_from.empty()) OpenAudio();
    rc = avio_open(&format->pb, path.c_str(), AVIO_FLAG_WRITE);
    if (rc < 0) Fail("cannot open for writing", rc);
    AVDictionary* muxer = nullptr;
    // MP4/MOV: the index at the front, so that a browser or player starts before the whole file
    // arrives; "unofficial" lets libav write the spherical boxes, which are Google's, not ISO's.
    av_dict_set(&muxer, "movflags", "+faststart", 0);
    if (options.spherical_equirect) av_dict_set(&muxer, "strict", "unofficial", 0);
    rc = avformat_write_header(format, &muxer);
    av_dict_free(&muxer);
    if (rc < 0) Fail("cannot write the container's header", rc);
    header_written = true;
    scaler = sws_getContext(options.width, options.height, AV_PIX_FMT_BGR24, options.width, options.height,
                            encoder->pix_fmt, SWS_BICUBIC, nullptr, nullptr, nullptr);
    if (!scaler) Fail("libswscale cannot convert BGR to the encoder's format", 0);
    // sRGB frames are full-range RGB; H.264/H.265 get limited-range BT.709 YUV.
    const bool full_range = encoder->color_range == AVCOL_RANGE_JPEG;
    sws_setColorspaceDetails(scaler, sws_getCoefficients(SWS_CS_DEFAULT), 1,
                             sws_getCoefficients(full_range ? SWS_CS_ITU601 : SWS_CS_ITU709), full_range ? 1 : 0, 0,
                             1 << 16, 1 << 16);
    frame = av_frame_alloc();
    packet = av_packet_alloc();
    frame->format = encoder->pix_fmt;
    frame->width = options.width;
    frame->height = options.height;
    rc = av_frame_get_buffer(frame, 0);
    if (rc < 0) Fail("cannot allocate a frame", rc);
  }

  ~Impl() {
    if (header_written && !finished) av_write_trailer(format);  // leave a closed file to discard
    if (format && format->pb) avio_closep(&format->pb);
    avformat_free_context(format);
    avcodec_free_context(&encoder);
    sws_freeContext(scaler);
    av_frame_free(&frame);
    av_packet_free(&packet);
    av_packet_free(&audio_packet);
    avformat_close_input(&audio_in);
  }
};

LibavVideoWriter::LibavVideoWriter(const std::filesystem::path& path, const VideoWriterOptions& options,
                                   const std::string& name)
    : impl_(std::make_unique<Impl>()) {
  options.Check();
  RouteLibavLog();
  impl_->path = path.string();
  impl_->name = name.empty() ? path.string() : name;
  impl_->options = options;
  impl_->Open();
}

LibavVideoWriter::~LibavVideoWriter() = default;

void LibavVideoWriter::Write(const cv::Mat& bgr) {
  Impl& im = *impl_;
  if (im.finished) throw Error(im.name, "written to after Finish()");
  if (bgr.type() != CV_8UC3 || bgr.cols != im.options.width || bgr.rows != im.options.height)
    throw Error(im.name, "a frame of " + std::to_string(bgr.cols) + "x" + std::to_string(bgr.rows) +
                             " (8-bit BGR expected, " + std::to_string(im.options.width) + "x" +
                             std::to_string(im.options.height) + ")");
  const int rc = av_frame_make_writable(im.frame);
  if (rc < 0) im.Fail("cannot reuse the frame buffer", rc);
  const std::uint8_t* source[1] = {bgr.data};
  const int stride[1] = {static_cast<int>(bgr.step[0])};
  sws_scale(im.scaler, source, stride, 0, bgr.rows, im.frame->data, im.frame->linesize);
  im.frame->pts = im.frames;
  im.Encode(im.frame);
  ++im.frames;
  im.CopyAudioUntil(static_cast<double>(im.frames) / im.options.fps);
}

void LibavVideoWriter::Finish() {
  Impl& im = *impl_;
  if (im.finished) return;
  im.Encode(nullptr);
  im.CopyAudioUntil(static_cast<double>(im.frames) / im.options.fps);
  im.finished = true;
  int rc = av_write_trailer(im.format);
  if (rc < 0) im.Fail("cannot write the container's trailer (disk full?)", rc);
  rc = avio_closep(&im.format->pb);
  if (rc < 0) im.Fail("cannot close (disk full?)", rc);
}

long LibavVideoWriter::frames_written() const { return impl_->frames; }
const std::string& LibavVideoWriter::codec_name() const { return impl_->codec_name; }
const std::string& LibavVideoWriter::audio_codec() const { return impl_->audio_codec; }
const std::string& LibavVideoWriter::audio_dropped() const { return impl_->audio_dropped; }

}  // namespace odvr::capture
