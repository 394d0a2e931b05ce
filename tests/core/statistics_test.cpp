#include "core/statistics.h"

#include <gtest/gtest.h>

namespace odvr {
namespace {

TEST(Statistics, MedianOfOddEvenAndNoValues) {
  EXPECT_EQ(Median({3, 1, 2}), 2);
  EXPECT_EQ(Median({4, 1, 3, 2}), 2.5);  // the mean of the middle two (the player's took the upper)
  EXPECT_EQ(Median({}), 0);
}

// numpy.quantile's default (linear between order statistics): the median at 0.5, the extremes
// at 0 and 1, and a 90th percentile between the two largest of ten.
TEST(Statistics, QuantileInterpolatesBetweenOrderStatistics) {
  const std::vector<double> ten = {10, 1, 9, 2, 8, 3, 7, 4, 6, 5};
  EXPECT_DOUBLE_EQ(Quantile(ten, 0.5), Median(ten));
  EXPECT_DOUBLE_EQ(Quantile(ten, 0.0), 1);
  EXPECT_DOUBLE_EQ(Quantile(ten, 1.0), 10);
  EXPECT_DOUBLE_EQ(Quantile(ten, 0.9), 9.1);  // 0.9 × 9 = 8.1: 9 + 0.1 (10 − 9)
  EXPECT_DOUBLE_EQ(Quantile({4.0}, 0.9), 4);
  EXPECT_EQ(Quantile({}, 0.5), 0);
}

}  // namespace
}  // namespace odvr
