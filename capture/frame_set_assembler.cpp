#include "capture/frame_set_assembler.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace odvr::capture {

void FrameSetAssemblerOptions::Check() const {
  if (!(tolerance_s > 0)) throw Error("sync tolerance", "must be positive");
  if (!(stall_s > tolerance_s)) throw Error("stall timeout", "must exceed the sync tolerance");
  if (max_pending_per_camera == 0) throw Error("max pending frames", "must be at least 1");
}

FrameSetAssembler::FrameSetAssembler(int camera_count, FrameSetAssemblerOptions options)
    : camera_count_(camera_count),
      options_(options),
      pending_(static_cast<std::size_t>(camera_count)),
      lost_(static_cast<std::size_t>(camera_count), false),
      last_seen_s_(static_cast<std::size_t>(camera_count), -std::numeric_limits<double>::infinity()) {
  if (camera_count <= 0) throw Error("frame sets", "need at least one camera");
  options_.Check();
}

void FrameSetAssembler::Push(Frame frame) {
  if (frame.camera < 0 || frame.camera >= camera_count_) throw Error("frame sets", "camera index out of range");
  const auto c = static_cast<std::size_t>(frame.camera);
  if (!std::isfinite(frame.timestamp_s)) {
    ++stats_.corrupt_frames;
    events_.push_back({SourceEvent::Kind::kCorruptFrame, frame.camera, frame.index, "frame without a valid timestamp"});
    return;
  }
  if (lost_[c]) {  // a camera that comes back is welcome again
    lost_[c] = false;
  }
  last_seen_s_[c] = frame.timestamp_s;
  first_seen_s_ = std::min(first_seen_s_, frame.timestamp_s);
  auto& queue = pending_[c];
  if (queue.size() == options_.max_pending_per_camera) {
    queue.pop_front();
    ++stats_.frames_dropped;
  }
  queue.push_back(std::move(frame));
}

void FrameSetAssembler::MarkLost(int camera, const std::string& why) {
  const auto c = static_cast<std::size_t>(camera);
  if (lost_[c]) return;
  lost_[c] = true;
  events_.push_back({SourceEvent::Kind::kCameraLost, camera, -1, why});
}

std::optional<FrameSet> FrameSetAssembler::TryPop() { return Assemble(false); }
std::optional<FrameSet> FrameSetAssembler::Flush() { return Assemble(true); }

std::vector<SourceEvent> FrameSetAssembler::TakeEvents() { return std::exchange(events_, {}); }

std::optional<FrameSet> FrameSetAssembler::Assemble(bool flushing) {
  for (;;) {
    // The newest among the oldest pending frames: no earlier instant can still be completed.
    double reference = -std::numeric_limits<double>::infinity();
    double newest_anywhere = -std::numeric_limits<double>::infinity();
    bool any = false;
    for (int c = 0; c < camera_count_; ++c) {
      const auto& q = pending_[static_cast<std::size_t>(c)];
      if (q.empty()) continue;
      any = true;
      reference = std::max(reference, q.front().timestamp_s);
      newest_anywhere = std::max(newest_anywhere, q.back().timestamp_s);
    }
    if (!any) return std::nullopt;

    // Cameras with nothing pending: wait for them, unless they are lost, the stream has ended,
    // or they have been silent for longer than the stall timeout while the others moved on.
    for (int c = 0; c < camera_count_; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      if (!pending_[cu].empty() || lost_[cu] || flushing) continue;
      const double silent_since = std::max(last_seen_s_[cu], first_seen_s_);
      if (newest_anywhere - silent_since <= options_.stall_s) return std::nullopt;
      MarkLost(c, "camera " + std::to_string(c) + " delivered no frame for more than " +
                      std::to_string(options_.stall_s) + " s");
    }

    // Drop frames too old to have a partner at `reference`.
    bool dropped = false;
    for (int c = 0; c < camera_count_; ++c) {
      auto& q = pending_[static_cast<std::size_t>(c)];
      while (!q.empty() && q.front().timestamp_s < reference - options_.tolerance_s) {
        events_.push_back({SourceEvent::Kind::kOutOfSync, c, q.front().index,
                           "frame at " + std::to_string(q.front().timestamp_s) + " s has no partner within " +
                               std::to_string(options_.tolerance_s) + " s"});
        q.pop_front();
        ++stats_.frames_out_of_sync;
        dropped = true;
      }
    }
    if (dropped) continue;  // the reference may have moved

    FrameSet set;
    set.index = next_set_index_++;
    set.frames.resize(static_cast<std::size_t>(camera_count_));
    double sum = 0;
    int n = 0;
    for (int c = 0; c < camera_count_; ++c) {
      auto& q = pending_[static_cast<std::size_t>(c)];
      Frame& slot = set.frames[static_cast<std::size_t>(c)];
      slot.camera = c;
      if (!q.empty()) {
        slot = std::move(q.front());
        q.pop_front();
        sum += slot.timestamp_s;
        ++n;
      } else {
        slot.timestamp_s = reference;
        ++stats_.missing_frames;
      }
    }
    set.timestamp_s = n ? sum / n : reference;
    ++stats_.sets_delivered;
    return set;
  }
}

}  // namespace odvr::capture
