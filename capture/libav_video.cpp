#include "capture/libav_video.h"

#include <spdlog/spdlog.h>

#include <array>
#include <climits>
#include <cmath>
#include <filesystem>
#include <mutex>

#include "core/error.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/pixdesc.h>
#include <libavutil/spherical.h>
#include <libavutil/stereo3d.h>
#include <libswscale/swscale.h>
}

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;

// libav's log, one line at a time, to spdlog: warnings and errors only, as libav's own default
// would print them to stderr past the program's log. A line can arrive in pieces (a prefix, then
// the text), from any decoder thread: each thread assembles its own.
void LogToSpdlog(void* context, int level, const char* format, va_list args) {
  if (level > AV_LOG_WARNING) return;
  thread_local int print_prefix = 1;
  thread_local std::string pending;
  char piece[1024];
  const int length = av_log_format_line2(context, level, format, args, piece, sizeof piece, &print_prefix);
  pending += piece;
  const bool cut = length >= static_cast<int>(sizeof piece);  // an overlong line: log what fits
  if (pending.empty() || (pending.back() != '\n' && !cut)) return;
  if (pending.back() == '\n') pending.pop_back();
  if (level <= AV_LOG_ERROR)
    spdlog::error("libav: {}", pending);
  else
    spdlog::warn("libav: {}", pending);
  pending.clear();
}

struct FormatCloser {
  void operator()(AVFormatContext* f) const { avformat_close_input(&f); }
};
struct CodecCloser {
  void operator()(AVCodecContext* c) const { avcodec_free_context(&c); }
};
struct FrameFreer {
  void operator()(AVFrame* f) const { av_frame_free(&f); }
};
struct PacketFreer {
  void operator()(AVPacket* p) const { av_packet_free(&p); }
};
struct ScalerFreer {
  void operator()(SwsContext* s) const { sws_freeContext(s); }
};
using FormatPtr = std::unique_ptr<AVFormatContext, FormatCloser>;

// An opened container and the video stream odvr reads from it (not cover art).
struct Input {
  FormatPtr format;
  int stream = -1;
  AVStream* st() const { return format->streams[stream]; }
};

Input OpenInput(const std::string& path) {
  RouteLibavLog();
  if (!fs::exists(path)) throw Error(path, "no such video file");
  AVFormatContext* raw = nullptr;
  int rc = avformat_open_input(&raw, path.c_str(), nullptr, nullptr);
  if (rc < 0) throw Error(path, "not a video libav can read (" + LibavErrorText(rc) + ")");
  Input in{FormatPtr(raw)};
  rc = avformat_find_stream_info(in.format.get(), nullptr);
  if (rc < 0) throw Error(path, "cannot read its stream parameters (" + LibavErrorText(rc) + ")");
  auto usable = [&](int i) {
    const AVStream* st = in.format->streams[i];
    return st->codecpar->codec_type == AVMEDIA_TYPE_VIDEO && !(st->disposition & AV_DISPOSITION_ATTACHED_PIC);
  };
  in.stream = av_find_best_stream(in.format.get(), AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
  if (in.stream < 0 || !usable(in.stream)) {
    in.stream = -1;
    for (unsigned i = 0; i < in.format->nb_streams && in.stream < 0; ++i)
      if (usable(static_cast<int>(i))) in.stream = static_cast<int>(i);
  }
  if (in.stream < 0) throw Error(path, "has no video stream");
  if (in.st()->codecpar->width <= 0 || in.st()->codecpar->height <= 0)
    throw Error(path, "its video stream has no frame size");
  return in;
}

// avg_frame_rate, else r_frame_rate, else 25: the first that is a plausible rate.
AVRational FrameRate(const AVStream* st) {
  for (AVRational r : {st->avg_frame_rate, st->r_frame_rate})
    if (r.num > 0 && r.den > 0 && av_q2d(r) < 1000) return r;
  return {25, 1};
}

void ReadSideData(const AVStream* st, VideoProbe* probe) {
  std::size_t size = 0;
  if (const auto* s = reinterpret_cast<const AVStereo3D*>(av_stream_get_side_data(st, AV_PKT_DATA_STEREO3D, &size));
      s && size >= sizeof(AVStereo3D)) {
    if (s->type == AV_STEREO3D_2D) probe->stereo = StereoLayout::kMono;
    if (s->type == AV_STEREO3D_TOPBOTTOM) probe->stereo = StereoLayout::kTopBottom;
    if (s->type == AV_STEREO3D_SIDEBYSIDE) probe->stereo = StereoLayout::kSideBySide;
    probe->stereo_inverted = (s->flags & AV_STEREO3D_FLAG_INVERT) != 0;
  }
  if (const auto* m =
          reinterpret_cast<const AVSphericalMapping*>(av_stream_get_side_data(st, AV_PKT_DATA_SPHERICAL, &size));
      m && size >= sizeof(AVSphericalMapping)) {
    if (m->projection == AV_SPHERICAL_EQUIRECTANGULAR) probe->projection = "equirectangular";
    if (m->projection == AV_SPHERICAL_CUBEMAP) probe->projection = "cubemap";
    if (m->projection == AV_SPHERICAL_EQUIRECTANGULAR_TILE) probe->projection = "equirectangular-tile";
    // The angles are 16.16 fixed point.
    probe->yaw_deg = m->yaw / 65536.0;
    probe->pitch_deg = m->pitch / 65536.0;
    probe->roll_deg = m->roll / 65536.0;
  }
}

VideoProbe Describe(const Input& in) {
  const AVStream* st = in.st();
  VideoProbe p;
  p.width = st->codecpar->width;
  p.height = st->codecpar->height;
  p.fps = av_q2d(FrameRate(st));
  p.codec = avcodec_get_name(st->codecpar->codec_id);
  if (st->nb_frames > 0) {
    p.frame_count = static_cast<long>(st->nb_frames);
    p.frame_count_exact = true;
  } else {
    double duration_s = 0;
    if (st->duration != AV_NOPTS_VALUE)
      duration_s = static_cast<double>(st->duration) * av_q2d(st->time_base);
    else if (in.format->duration != AV_NOPTS_VALUE)
      duration_s = static_cast<double>(in.format->duration) / AV_TIME_BASE;
    p.frame_count = std::max(0L, std::lround(duration_s * p.fps));
  }
  ReadSideData(st, &p);
  return p;
}

// The deprecated full-range "yuvj" formats become their plain twins with the range set
// explicitly, which is what swscale wants (it warns about them otherwise).
AVPixelFormat PlainFormat(AVPixelFormat f, bool* full_range) {
  switch (f) {
    case AV_PIX_FMT_YUVJ420P:
      *full_range = true;
      return AV_PIX_FMT_YUV420P;
    case AV_PIX_FMT_YUVJ422P:
      *full_range = true;
      return AV_PIX_FMT_YUV422P;
    case AV_PIX_FMT_YUVJ444P:
      *full_range = true;
      return AV_PIX_FMT_YUV444P;
    case AV_PIX_FMT_YUVJ440P:
      *full_range = true;
      return AV_PIX_FMT_YUV440P;
    case AV_PIX_FMT_YUVJ411P:
      *full_range = true;
      return AV_PIX_FMT_YUV411P;
    default:
      return f;
  }
}

constexpr long kUnknownIndex = LONG_MIN;
// A decoder that fails this many times in a row is not recovering: the stream is over.
constexpr int kMaxConsecutiveErrors = 256;

}  // namespace

std::string LibavErrorText(int code) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(code, text, sizeof text);
  return text;
}

// The callback is process-wide (OpenCV's FFmpeg backend shares the same libav): set it once.
void RouteLibavLog() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_callback(LogToSpdlog); });
}

VideoProbe ProbeVideo(const std::string& path) { return Describe(OpenInput(path)); }

struct LibavVideoReader::Impl {
  std::string path;
  VideoProbe probe;
  Input in;
  std::unique_ptr<AVCodecContext, CodecCloser> codec;
  std::unique_ptr<AVPacket, PacketFreer> packet{av_packet_alloc()};
  std::unique_ptr<AVFrame, FrameFreer> frame{av_frame_alloc()};
  std::unique_ptr<SwsContext, ScalerFreer> scaler;
  std::array<int, 5> scaler_key{};  // width, height, format, colour matrix, full range
  AVRational time_base{1, 1}, rate{25, 1};
  int64_t origin = AV_NOPTS_VALUE;    // the pts of frame 0
  bool draining = false;              // the empty packet that flushes the decoder went in
  long last_index = -1;               // of the last frame out of the decoder; kUnknownIndex after a seek
  long packet_index = kUnknownIndex;  // of the last packet read, by its pts
  bool pending = false;               // `frame` holds a decoded frame Next() has not delivered
  long pending_index = 0;
  bool pending_key = false;
  long next_index = 0;       // what Next() delivers next, as far as known
  bool seek_failed = false;  // the container's seek once landed where decoding could not start
  long skipped = 0;
  std::string read_error;

  void Open(Input input) {
    in = std::move(input);
    const AVStream* st = in.st();
    const AVCodec* decoder = avcodec_find_decoder(st->codecpar->codec_id);
    if (!decoder) throw Error(path, "libavcodec has no decoder for its video codec '" + probe.codec + "'");
    codec.reset(avcodec_alloc_context3(decoder));
    if (!codec) throw Error(path, "out of memory for a decoder");
    int rc = avcodec_parameters_to_context(codec.get(), st->codecpar);
    if (rc < 0) throw Error(path, "cannot set up its '" + probe.codec + "' decoder (" + LibavErrorText(rc) + ")");
    codec->pkt_timebase = st->time_base;
    codec->thread_count = 0;  // one per core
    codec->thread_type = FF_THREAD_FRAME | FF_THREAD_SLICE;
    rc = avcodec_open2(codec.get(), decoder, nullptr);
    if (rc < 0) throw Error(path, "cannot open its '" + probe.codec + "' decoder (" + LibavErrorText(rc) + ")");
    time_base = st->time_base;
    rate = FrameRate(st);
    if (origin == AV_NOPTS_VALUE) origin = st->start_time;
    draining = pending = false;
    last_index = -1;
    packet_index = kUnknownIndex;
    next_index = 0;
    read_error.clear();
  }

  int64_t PtsOf(long index) const {
    return (origin == AV_NOPTS_VALUE ? 0 : origin) + av_rescale_q(index, av_inv_q(rate), time_base);
  }
  long IndexOf(int64_t pts) const {
    return static_cast<long>(av_rescale_q(pts - (origin == AV_NOPTS_VALUE ? 0 : origin), time_base, av_inv_q(rate)));
  }

  // Sends the decoder the next packet of the video stream, or at the end of the input the empty
  // packet that drains it. Any read error ends the input as the end of the file does (as the
  // ffmpeg tool treats it): the frames decoded so far stand. A packet the decoder rejects is
  // skipped and counted.
  void Feed() {
    while (true) {
      const int rc = av_read_frame(in.format.get(), packet.get());
      if (rc < 0) {
        if (rc != AVERROR_EOF) read_error = LibavErrorText(rc);
        avcodec_send_packet(codec.get(), nullptr);
        draining = true;
        return;
      }
      if (packet->stream_index != in.stream) {
        av_packet_unref(packet.get());
        continue;
      }
      const int64_t t = packet->pts != AV_NOPTS_VALUE ? packet->pts : packet->dts;
      if (t != AV_NOPTS_VALUE) packet_index = IndexOf(t);
      const int sent = avcodec_send_packet(codec.get(), packet.get());
      av_packet_unref(packet.get());
      if (sent < 0 && sent != AVERROR(EAGAIN)) {
        ++skipped;
        continue;
      }
      return;
    }
  }

  // The next frame out of the decoder into `frame`, numbered; false once the stream is over.
  bool Decode() {
    int errors = 0;
    while (true) {
      const int rc = avcodec_receive_frame(codec.get(), frame.get());
      if (rc == 0) {
        Number();
        return true;
      }
      if (rc == AVERROR_EOF) return false;
      if (rc != AVERROR(EAGAIN)) {
        ++skipped;
        if (++errors > kMaxConsecutiveErrors) return false;
        continue;
      }
      if (draining) return false;
      Feed();
    }
  }

  // Numbers `frame` by its presentation time: (pts - frame 0's pts) × fps, rounded. Numbers rise
  // strictly, so duplicate or missing timestamps fall back to the previous frame's number + 1.
  void Number() {
    const int64_t pts = frame->best_effort_timestamp;
    // A stream without a start time, or whose first frame comes before it: frame 0 is the first.
    if (pts != AV_NOPTS_VALUE && last_index == -1 && next_index == 0 && (origin == AV_NOPTS_VALUE || pts < origin))
      origin = pts;
    long index = kUnknownIndex;
    if (pts != AV_NOPTS_VALUE) index = IndexOf(pts);
    if (last_index != kUnknownIndex && (index == kUnknownIndex || index <= last_index)) index = last_index + 1;
    last_index = index;
    pending = true;
    pending_index = index;
    pending_key = frame->key_frame != 0;
  }

  cv::Mat ToBgr() {
    bool full_range = frame->color_range == AVCOL_RANGE_JPEG;
    const AVPixelFormat format = PlainFormat(static_cast<AVPixelFormat>(frame->format), &full_range);
    // The frame's own YUV matrix; an unlabelled one gets BT.601, swscale's default and what
    // players assume.
    int matrix = frame->colorspace;
    if (matrix == AVCOL_SPC_UNSPECIFIED || matrix == AVCOL_SPC_RGB) matrix = SWS_CS_DEFAULT;
    const std::array<int, 5> key = {frame->width, frame->height, format, matrix, full_range ? 1 : 0};
    if (!scaler || key != scaler_key) {
      scaler.reset(sws_getContext(frame->width, frame->height, format, frame->width, frame->height, AV_PIX_FMT_BGR24,
                                  SWS_BICUBIC, nullptr, nullptr, nullptr));
      if (!scaler) {
        const char* name = av_get_pix_fmt_name(format);
        throw Error(path, std::string("libswscale cannot convert its pixel format ") + (name ? name : "?") + " to BGR");
      }
      // BGR is full range; brightness, contrast and saturation stay neutral.
      sws_setColorspaceDetails(scaler.get(), sws_getCoefficients(matrix), key[4], sws_getCoefficients(SWS_CS_DEFAULT),
                               1, 0, 1 << 16, 1 << 16);
      scaler_key = key;
    }
    cv::Mat bgr(frame->height, frame->width, CV_8UC3);
    uint8_t* dst[4] = {bgr.data, nullptr, nullptr, nullptr};
    int dst_stride[4] = {static_cast<int>(bgr.step), 0, 0, 0};
    sws_scale(scaler.get(), frame->data, frame->linesize, 0, frame->height, dst, dst_stride);
    return bgr;
  }

  // Decodes forward until frame `target` is pending (or the first frame after it, where the
  // stream has a gap). With `from_seek`, the decoder restarted where the container's seek landed:
  // that only counts when a keyframe at or before the target comes out before the target does.
  // Returns false when it does not (the caller rewinds) or the stream ends first.
  bool DecodeUntil(long target, bool from_seek, bool* landed) {
    bool key_seen = !from_seek;
    *landed = true;
    while (true) {
      if (!pending && !Decode()) {
        *landed = !from_seek || key_seen;
        return false;
      }
      if (pending_index == kUnknownIndex) {
        *landed = false;
        return false;
      }
      if (pending_key && pending_index <= target) key_seen = true;
      if (pending_index >= target) {
        *landed = key_seen;
        return key_seen;
      }
      pending = false;
      if (from_seek && !key_seen && packet_index != kUnknownIndex && packet_index > target + SeekOvershoot()) {
        *landed = false;
        return false;
      }
    }
  }

  // After a seek, the decoder is given up on when packets this many frames past the target went
  // in and no keyframe at or before the target came out: the container landed where the decoder
  // cannot start. The margin covers B-frame reordering and the frame a frame-threaded decoder
  // holds back per thread.
  long SeekOvershoot() const { return 8 + codec->has_b_frames + std::max(1, codec->thread_count); }

  // The container's index entry for the keyframe at or before `target`: MP4's sync samples,
  // Matroska's cues, AVI's idx1. nullptr without an index (MPEG-TS, raw streams), or once a seek
  // through it landed where decoding could not start.
  const AVIndexEntry* KeyframeBefore(long target) {
    if (seek_failed) return nullptr;
    return avformat_index_get_entry_from_timestamp(in.st(), PtsOf(target), AVSEEK_FLAG_BACKWARD);
  }

  // Decoding on from where the reader is is the way to a frame ahead of it when its keyframe is
  // already behind, and whenever there is no keyframe index to seek by (the other way then is
  // decoding from the start).
  bool DecodeOnIsCheaper(long target) {
    if (target < next_index) return false;
    const AVIndexEntry* key = KeyframeBefore(target);
    return !key || key->timestamp <= PtsOf(next_index);
  }

  bool Seek(long target) {
    target = std::max(0L, target);
    bool landed = false;
    if (DecodeOnIsCheaper(target)) return Settle(DecodeUntil(target, false, &landed));
    if (KeyframeBefore(target)) {
      if (av_seek_frame(in.format.get(), in.stream, PtsOf(target), AVSEEK_FLAG_BACKWARD) >= 0) {
        avcodec_flush_buffers(codec.get());
        draining = pending = false;
        last_index = kUnknownIndex;
        packet_index = kUnknownIndex;
        read_error.clear();
        const bool found = DecodeUntil(target, true, &landed);
        if (landed) return Settle(found);
      }
      seek_failed = true;  // the index misled once: later seeks in this file go the safe way
    }
    // No keyframe index to seek by (MPEG-TS seeks by a timestamp search that lands on any
    // packet), or the seek went wrong: open the file afresh and decode forward from frame 0, as
    // sequential decoding does. Costs time in proportion to `target`.
    spdlog::debug("{}: seek to frame {} decodes forward from the start", path, target);
    Open(OpenInput(path));
    return Settle(DecodeUntil(target, false, &landed));
  }

  bool Settle(bool found) {
    next_index = found ? pending_index : last_index == kUnknownIndex ? 0 : last_index + 1;
    return found;
  }
};

LibavVideoReader::LibavVideoReader(const std::string& path) : impl_(std::make_unique<Impl>()) {
  Input input = OpenInput(path);
  impl_->path = path;
  impl_->probe = Describe(input);
  impl_->Open(std::move(input));
}

LibavVideoReader::~LibavVideoReader() = default;
LibavVideoReader::LibavVideoReader(LibavVideoReader&&) noexcept = default;
LibavVideoReader& LibavVideoReader::operator=(LibavVideoReader&&) noexcept = default;

const std::string& LibavVideoReader::path() const { return impl_->path; }
const VideoProbe& LibavVideoReader::probe() const { return impl_->probe; }
long LibavVideoReader::skipped_frames() const { return impl_->skipped; }
const std::string& LibavVideoReader::read_error() const { return impl_->read_error; }

std::optional<VideoFrame> LibavVideoReader::Next() {
  Impl& d = *impl_;
  if (!d.pending && !d.Decode()) return std::nullopt;
  d.pending = false;
  VideoFrame out;
  out.index = d.pending_index;
  const int64_t pts = d.frame->best_effort_timestamp;
  out.timestamp_s = pts != AV_NOPTS_VALUE && d.origin != AV_NOPTS_VALUE
                        ? static_cast<double>(pts - d.origin) * av_q2d(d.time_base)
                        : static_cast<double>(out.index) / av_q2d(d.rate);
  out.concealed = d.frame->decode_error_flags != 0 || (d.frame->flags & AV_FRAME_FLAG_CORRUPT) != 0;
  out.image = d.ToBgr();
  d.next_index = out.index + 1;
  return out;
}

bool LibavVideoReader::Seek(long frame) { return impl_->Seek(frame); }

}  // namespace odvr::capture
