#include "app/ar/frame_decoder.h"

#include <spdlog/spdlog.h>

#include "capture/equirect_view.h"
#include "core/error.h"

namespace odvr::app {

std::unique_ptr<capture::Source> OpenPlayableVideo(const std::string& video, const std::string& stereo) {
  std::unique_ptr<capture::Source> source = capture::OpenSource(video);
  if (source->camera_count() != 1)
    throw Error(video, "has " + std::to_string(source->camera_count()) +
                           " cameras: play an equirectangular video or stitch the rig first (odvr stitch)");
  std::optional<capture::StereoLayout> layout;
  if (stereo != "auto") layout = capture::ParseStereoLayout(stereo);
  // The eye at its own width (no cap): the player shows what the file holds.
  capture::EquirectClip clip =
      capture::OpenEquirectClip(std::move(source), video, layout, 0, 1 << 20, /*step=*/1, /*first=*/0);
  if (clip.layout != capture::StereoLayout::kMono || clip.eye_resampled)
    spdlog::info("{}: {} (by {}): showing the {} eye, {}x{}{}", video,
                 clip.layout == capture::StereoLayout::kMono ? "mono" : capture::ToString(clip.layout) + " stereo",
                 clip.layout_from, clip.layout == capture::StereoLayout::kSideBySide ? "left" : "top", clip.width,
                 clip.width / 2, clip.eye_resampled ? " (its rows resampled to 2:1, as its metadata asks)" : "");
  return std::move(clip.source);
}

FrameDecoder::FrameDecoder(std::unique_ptr<capture::Source> source, std::size_t queue_capacity)
    : source_(std::move(source)), capacity_(std::max<std::size_t>(queue_capacity, 2)) {
  if (!source_) throw Error("decoder", "no source");
  if (source_->live()) throw Error(source_->description(), "is live: the decoder plays recordings");
  frame_count_ = source_->frame_count();
  fps_ = source_->fps() > 0 ? source_->fps() : 25;
  camera_count_ = source_->camera_count();
  if (frame_count_ <= 0) throw Error(source_->description(), "reports no frames");
  thread_ = std::thread([this] { Run(); });
}

FrameDecoder::~FrameDecoder() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void FrameDecoder::Run() {
  for (;;) {
    long index;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] {
        return stop_ || seek_to_ >= 0 || (queue_.size() < capacity_ && (end_index_ < 0 || next_index_ < end_index_));
      });
      if (stop_) return;
      if (seek_to_ >= 0) {
        source_->Seek(seek_to_);
        next_index_ = seek_to_;
        seek_to_ = -1;
        queue_.clear();
      }
      index = next_index_;
    }
    const auto start = std::chrono::steady_clock::now();
    auto set = source_->Next(std::chrono::milliseconds(1000));  // decoding runs unlocked
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    auto events = source_->TakeEvents();
    {
      std::lock_guard lock(mutex_);
      for (auto& e : events) {
        spdlog::warn("{}", e.message);
        events_.push_back(std::move(e));
      }
      if (seek_to_ >= 0) continue;  // the player moved on while we decoded
      // A set whose every image is missing is a hole (corrupt frame): queued, the player keeps
      // the previous picture. Only the source running dry is the end.
      if (!set) {
        end_index_ = index;  // the real end (a truncated file ends before frame_count)
        if (index < frame_count_)
          spdlog::warn("{}: ends at frame {} of {}", source_->description(), index, frame_count_);
      } else {
        queue_.push_back({index, std::move(*set), ms});
        next_index_ = index + 1;
      }
    }
    changed_.notify_all();
  }
}

std::optional<DecodedFrame> FrameDecoder::Get(long index, std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  const auto deadline = std::chrono::steady_clock::now() + wait;
  for (;;) {
    if (end_index_ == 0) return std::nullopt;  // the stream ended before its first frame: none will come
    if (end_index_ >= 0) index = std::min(index, std::max(0L, end_index_ - 1));
    while (!queue_.empty() && queue_.front().index < index) queue_.pop_front();
    if (!queue_.empty() && queue_.front().index == index) {
      changed_.notify_all();  // room in the queue: decode on
      return queue_.front();  // kept queued: the player may show it again
    }
    if (seek_to_ < 0) {
      // The queue holds [front, next_index_): a frame behind it, or far ahead, needs a seek;
      // one just ahead only needs the thread to decode on.
      const long queued_from = queue_.empty() ? next_index_ : queue_.front().index;
      if (index < queued_from || index > next_index_ + static_cast<long>(capacity_)) seek_to_ = index;
    }
    changed_.notify_all();
    if (changed_.wait_until(lock, deadline) == std::cv_status::timeout) return std::nullopt;
  }
}

long FrameDecoder::available_frames() const {
  std::lock_guard lock(mutex_);
  return end_index_ >= 0 ? end_index_ : frame_count_;
}

std::vector<capture::SourceEvent> FrameDecoder::TakeEvents() {
  std::lock_guard lock(mutex_);
  return std::exchange(events_, {});
}

}  // namespace odvr::app
