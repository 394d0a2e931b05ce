#include "capture/live_source.h"

namespace odvr::capture {

LiveSource::LiveSource(int camera_count, const SourceOptions& options)
    : assembler_(camera_count, FrameSetAssemblerOptions{options.sync_tolerance_s, options.stall_s, 8}),
      capacity_(options.queue_capacity ? options.queue_capacity : 1),
      camera_count_(camera_count) {}

LiveSource::~LiveSource() { StopThreads(); }

void LiveSource::StopThreads() {
  stopping_ = true;
  for (auto& t : threads_)
    if (t.joinable()) t.join();
  threads_.clear();
  ready_.notify_all();
}

void LiveSource::Deliver(Frame frame) {
  {
    std::lock_guard lock(mutex_);
    assembler_.Push(std::move(frame));
    while (auto set = assembler_.TryPop()) {
      if (sets_.size() == capacity_) {  // the consumer is behind: keep the newest
        sets_.pop_front();
        ++dropped_sets_;
      }
      sets_.push_back(std::move(*set));
    }
  }
  ready_.notify_one();
}

void LiveSource::Lose(int camera, const std::string& why) {
  {
    std::lock_guard lock(mutex_);
    assembler_.MarkLost(camera, why);
    ++lost_count_;
  }
  ready_.notify_all();
}

std::optional<FrameSet> LiveSource::Next(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  ready_.wait_for(lock, timeout, [&] { return !sets_.empty() || lost_count_ >= camera_count_ || stopping_; });
  if (sets_.empty()) return std::nullopt;
  FrameSet set = std::move(sets_.front());
  sets_.pop_front();
  return set;
}

std::vector<SourceEvent> LiveSource::TakeEvents() {
  std::lock_guard lock(mutex_);
  auto events = assembler_.TakeEvents();
  if (dropped_sets_ > 0) {
    events.push_back({SourceEvent::Kind::kDroppedFrames, -1, -1,
                      std::to_string(dropped_sets_) + " frame set(s) dropped: the consumer is behind"});
  }
  return events;
}

SourceStats LiveSource::stats() const {
  std::lock_guard lock(mutex_);
  SourceStats s = assembler_.stats();
  s.frames_dropped += dropped_sets_ * camera_count_;
  return s;
}

}  // namespace odvr::capture
