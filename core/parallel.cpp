#include "core/parallel.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <string>

#include "core/error.h"

namespace odvr {

namespace {

// How long a thread spins before it blocks: a worker between loops, the caller waiting for the
// workers. Waking a blocked worker took 20–25 µs on this project's 2-core VMs (a 33 µs loop ran
// in 40 µs on two threads), and the transform runs some 50 loops per frame, many of them that
// short; spinning 100 µs keeps a worker ready through the serial work between them and costs at
// most that much CPU per idle period.
constexpr auto kSpin = std::chrono::microseconds(100);

void Relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#else
  std::this_thread::yield();
#endif
}

// Spins until done() or kSpin has passed; true if done.
template <class Done>
bool SpinUntil(Done done) {
  const auto until = std::chrono::steady_clock::now() + kSpin;
  for (int i = 0;; ++i) {
    if (done()) return true;
    Relax();
    if ((i & 63) == 63 && std::chrono::steady_clock::now() > until) return done();
  }
}

}  // namespace

int DefaultThreadCount() {
  // ODVR_THREADS: another machine's thread count here (a 16-core GPU host's on a 2-core one),
  // or fewer threads beside other work.
  if (const char* env = std::getenv("ODVR_THREADS")) {
    char* end = nullptr;
    const long n = std::strtol(env, &end, 10);
    if (end != env && *end == '\0' && n >= 1 && n <= 1024) return static_cast<int>(n);
    throw Error("ODVR_THREADS", "must be a whole number from 1 to 1024, not '" + std::string(env) + "'");
  }
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

ThreadPool::ThreadPool(int threads) {
  if (threads <= 0) threads = DefaultThreadCount();
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

// Takes chunks until none are left; `lock` holds mutex_ on entry and on return.
void ThreadPool::RunChunks(std::unique_lock<std::mutex>& lock) {
  while (next_ < n_) {
    const long begin = next_;
    const long end = std::min(n_, begin + chunk_);
    next_ = end;
    const auto* body = body_;
    lock.unlock();
    (*body)(begin, end);
    lock.lock();
  }
}

void ThreadPool::WorkerLoop() {
  long seen = 0;
  for (;;) {
    const auto ready = [&] { return stop_.load(std::memory_order_acquire) || generation_.load() != seen; };
    SpinUntil(ready);
    std::unique_lock lock(mutex_);
    if (!ready()) {
      ++sleeping_;
      start_.wait(lock, ready);
      --sleeping_;
    }
    if (stop_) return;
    seen = generation_;
    ++active_;
    RunChunks(lock);
    if (--active_ == 0 && caller_waiting_) done_.notify_all();
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
  if (sleeping_ > 0) start_.notify_all();
  RunChunks(lock);
  --active_;
  // Every chunk is taken; wait for the workers still running theirs.
  lock.unlock();
  SpinUntil([&] { return active_.load() == 0; });
  lock.lock();
  caller_waiting_ = true;
  done_.wait(lock, [&] { return active_.load() == 0; });
  caller_waiting_ = false;
  body_ = nullptr;
}

}  // namespace odvr
