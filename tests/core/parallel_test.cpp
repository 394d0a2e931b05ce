#include "core/parallel.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <numeric>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "core/error.h"

namespace odvr {
namespace {

// Counts how often each index of [0, n) was visited; plain ints, so a chunk that is not
// finished (or not visible) when ParallelFor returns shows up as a wrong count.
std::vector<int> Visit(ThreadPool& pool, long n, long min_chunk) {
  std::vector<int> visits(static_cast<std::size_t>(n), 0);
  pool.ParallelFor(
      n,
      [&](long begin, long end) {
        for (long i = begin; i < end; ++i) ++visits[static_cast<std::size_t>(i)];
      },
      min_chunk);
  return visits;
}

bool EachOnce(const std::vector<int>& visits) {
  for (const int v : visits)
    if (v != 1) return false;
  return true;
}

// ODVR_THREADS sets the default pool's size; anything but a whole number in 1..1024 is an error
// that names the variable and the value.
TEST(Parallel, OdvrThreadsSetsThePoolSizeAndRejectsBadValues) {
  const char* before = std::getenv("ODVR_THREADS");
  const std::string saved = before ? before : "";
  setenv("ODVR_THREADS", "3", 1);
  EXPECT_EQ(ThreadPool().size(), 3);
  for (const char* bad : {"0", "abc", "2x", "", "5000"}) {
    setenv("ODVR_THREADS", bad, 1);
    try {
      ThreadPool pool;
      ADD_FAILURE() << "'" << bad << "' was taken";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("ODVR_THREADS"), std::string::npos) << e.what();
    }
  }
  if (before)
    setenv("ODVR_THREADS", saved.c_str(), 1);
  else
    unsetenv("ODVR_THREADS");
  EXPECT_EQ(ThreadPool().size(), DefaultThreadCount());
}

TEST(Parallel, BackToBackLoopsVisitEveryIndexExactlyOnce) {
  // Loops following each other within the workers' spin (the transform's pattern), of sizes
  // below, at and above a chunk, on more threads than cores too.
  for (const int threads : {1, 2, 5}) {
    ThreadPool pool(threads);
    std::mt19937 rng(7);
    int wrong = 0;
    for (int call = 0; call < 3000; ++call) {
      const long n = std::uniform_int_distribution<long>(1, 4000)(rng);
      const long min_chunk = std::uniform_int_distribution<long>(1, 300)(rng);
      if (!EachOnce(Visit(pool, n, min_chunk))) ++wrong;
    }
    EXPECT_EQ(wrong, 0) << threads << " threads";
  }
}

TEST(Parallel, WorkersThatFellAsleepAreWokenForTheNextLoop) {
  ThreadPool pool(3);
  for (int call = 0; call < 5; ++call) {
    // Longer than a worker spins before it blocks.
    std::this_thread::sleep_for(std::chrono::milliseconds(3));
    const std::vector<int> visits = Visit(pool, 100000, 16);
    EXPECT_TRUE(EachOnce(visits));
  }
}

TEST(Parallel, EveryThreadTakesPartInALongLoop) {
  ThreadPool pool(2);
  std::vector<std::thread::id> owner(64);
  pool.ParallelFor(
      64,
      [&](long begin, long end) {
        // Long enough per chunk that the caller cannot take every chunk before the worker wakes.
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        for (long i = begin; i < end; ++i) owner[static_cast<std::size_t>(i)] = std::this_thread::get_id();
      },
      4);
  int by_caller = 0;
  for (const auto& id : owner) by_caller += id == std::this_thread::get_id();
  EXPECT_GT(by_caller, 0);
  EXPECT_LT(by_caller, 64);
}

TEST(Parallel, DestroyedWhileItsWorkersSpinOrSleep) {
  for (const int idle_ms : {0, 5}) {
    const auto start = std::chrono::steady_clock::now();
    {
      ThreadPool pool(4);
      EXPECT_TRUE(EachOnce(Visit(pool, 10000, 8)));
      std::this_thread::sleep_for(std::chrono::milliseconds(idle_ms));
    }
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2)) << idle_ms;
  }
}

}  // namespace
}  // namespace odvr
