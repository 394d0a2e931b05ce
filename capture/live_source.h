#pragma once
// Shared machinery of live sources: one capture thread per device pushes timestamped frames;
// a FrameSetAssembler groups them; Next() waits for the next set. A device that fails
// mid-stream is marked lost and the others go on.
#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "capture/frame_set_assembler.h"
#include "capture/source.h"

namespace odvr::capture {

class LiveSource : public Source {
 public:
  LiveSource(int camera_count, const SourceOptions& options);
  ~LiveSource() override;

  bool live() const override { return true; }
  std::optional<FrameSet> Next(std::chrono::milliseconds timeout) override;
  std::vector<SourceEvent> TakeEvents() override;
  SourceStats stats() const override;

 protected:
  // Called from capture threads.
  void Deliver(Frame frame);
  void Lose(int camera, const std::string& why);
  // Derived classes start their threads/callbacks here and stop them in Stop().
  void AddThread(std::thread thread) { threads_.push_back(std::move(thread)); }
  void StopThreads();
  bool stopping() const { return stopping_.load(); }

 private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  FrameSetAssembler assembler_;
  std::deque<FrameSet> sets_;
  std::size_t capacity_;
  long dropped_sets_ = 0;
  std::vector<std::thread> threads_;
  std::atomic<bool> stopping_{false};
  int camera_count_;
  int lost_count_ = 0;
};

}  // namespace odvr::capture
