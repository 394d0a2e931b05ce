#pragma once
// A small persistent thread pool for data-parallel loops (the lighting transform runs a few
// of them per level, per frame: spawning threads each time would cost more than the work).
// Each index is processed by exactly one thread, so per-index results are deterministic.
#include <atomic>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace odvr {

// The hardware's thread count, or ODVR_THREADS when set (odvr::Error when it is not 1..1024).
int DefaultThreadCount();

class ThreadPool {
 public:
  explicit ThreadPool(int threads = 0);  // 0 = DefaultThreadCount()
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return static_cast<int>(workers_.size()) + 1; }
  // Calls body(begin, end) on contiguous chunks covering [0, n); the caller's thread works too.
  void ParallelFor(long n, const std::function<void(long begin, long end)>& body, long min_chunk = 64);

 private:
  void WorkerLoop();
  void RunChunks(std::unique_lock<std::mutex>& lock);
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  const std::function<void(long, long)>* body_ = nullptr;
  long n_ = 0, next_ = 0, chunk_ = 1;
  // Written under mutex_; atomic so that spinning threads can watch them without it.
  std::atomic<long> generation_{0};
  std::atomic<int> active_{0};
  std::atomic<bool> stop_{false};
  int sleeping_ = 0;  // workers blocked on start_ (under mutex_)
  bool caller_waiting_ = false;
};

}  // namespace odvr
