#include "engine/core/parallel.h"

#include <algorithm>

namespace odvr {

ThreadPool::ThreadPool(int threads) {
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (int i = 1; i < threads; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  start_.notify_all();
  for (auto& w : workers_) w.join();
}

void ThreadPool::WorkerLoop() {
  long seen = 0;
  for (;;) {
    std::unique_lock lock(mutex_);
    start_.wait(lock, [&] { return stop_ || generation_ != seen; });
    if (stop_) return;
    seen = generation_;
    ++active_;
    while (next_ < n_) {
      const long begin = next_;
      const long end = std::min(n_, begin + chunk_);
      next_ = end;
      const auto* body = body_;
      lock.unlock();
      (*body)(begin, end);
      lock.lock();
    }
    if (--active_ == 0) done_.notify_all();
  }
}

void ThreadPool::ParallelFor(long n, const std::function<void(long, long)>& body, long min_chunk) {
  if (n <= 0) return;
  if (workers_.empty() || n <= min_chunk) {
    body(0, n);
    return;
  }
  std::unique_lock lock(mutex_);
  body_ = &body;
  n_ = n;
  next_ = 0;
  chunk_ = std::max(min_chunk, n / (8L * size()));
  ++generation_;
  ++active_;  // this thread
  start_.notify_all();
  while (next_ < n_) {
    const long begin = next_;
    const long end = std::min(n_, begin + chunk_);
    next_ = end;
    lock.unlock();
    body(begin, end);
    lock.lock();
  }
  --active_;
  done_.wait(lock, [&] { return active_ == 0; });
  body_ = nullptr;
}

}  // namespace odvr
