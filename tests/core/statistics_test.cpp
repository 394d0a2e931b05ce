#include "core/statistics.h"

#include <gtest/gtest.h>

namespace odvr {
namespace {

TEST(Statistics, MedianOfOddEvenAndNoValues) {
  EXPECT_EQ(Median({3, 1, 2}), 2);
  EXPECT_EQ(Median({4, 1, 3, 2}), 2.5);  // the mean of the middle two (the player's took the upper)
  EXPECT_EQ(Median({}), 0);
}

}  // namespace
}  // namespace odvr
