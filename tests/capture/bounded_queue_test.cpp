#include "capture/bounded_queue.h"

#include <gtest/gtest.h>

#include <thread>

namespace odvr::capture {
namespace {

TEST(BoundedQueue, DropsTheOldestWhenFullAndCountsIt) {
  BoundedQueue<int> q(3);
  for (int i = 0; i < 5; ++i) q.Push(i);
  EXPECT_EQ(q.dropped(), 2);
  EXPECT_EQ(q.Pop(std::chrono::milliseconds(0)), 2);
  EXPECT_EQ(q.Pop(std::chrono::milliseconds(0)), 3);
  EXPECT_EQ(q.Pop(std::chrono::milliseconds(0)), 4);
  EXPECT_EQ(q.Pop(std::chrono::milliseconds(0)), std::nullopt);
}

TEST(BoundedQueue, CloseWakesAWaitingConsumer) {
  BoundedQueue<int> q(2);
  std::thread closer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    q.Close();
  });
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(q.Pop(std::chrono::seconds(10)), std::nullopt);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  closer.join();
  EXPECT_FALSE(q.Push(1));
}

TEST(BoundedQueue, ProducerAndConsumerThreadsLoseNothingWithinCapacity) {
  BoundedQueue<int> q(1000);
  std::thread producer([&] {
    for (int i = 0; i < 500; ++i) q.Push(i);
  });
  producer.join();
  long sum = 0;
  while (auto v = q.Pop(std::chrono::milliseconds(0))) sum += *v;
  EXPECT_EQ(sum, 499 * 500 / 2);
  EXPECT_EQ(q.dropped(), 0);
}

}  // namespace
}  // namespace odvr::capture
