#include "app/ar/frame_picker.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"

namespace odvr::app {
namespace {

// A straight path along +X, one frame every 0.5 m (street_a's spacing).
std::vector<glm::dvec3> StraightPath(int frames) {
  std::vector<glm::dvec3> p;
  for (int i = 0; i < frames; ++i) p.push_back({0.5 * i, 2.0, 0.0});
  return p;
}

TEST(FramePicker, NearestFrameIsTheSeedsRule) {
  FramePicker picker(StraightPath(40));
  EXPECT_EQ(picker.NearestFrame({5.1, 0, 0}), 10);
  EXPECT_EQ(picker.NearestFrame({-3, 0, 0}), 0);
  EXPECT_EQ(picker.NearestFrame({100, 0, 0}), 39);
}

TEST(FramePicker, LightWeightsAreInverseDistanceAndSumToOne) {
  FramePicker picker(StraightPath(40), {3, 6.0});
  const auto w = picker.LightWeights({5.25, 2.0, 0.0});  // halfway between frames 10 and 11
  ASSERT_EQ(w.size(), 3u);
  double sum = 0;
  for (const auto& [f, v] : w) sum += v;
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_NEAR(w[0].second, w[1].second, 1e-12);  // 10 and 11 equally near
  EXPECT_GT(w[1].second, w[2].second);
  // At a camera: that frame alone, no division by zero.
  const auto exact = picker.LightWeights({5.0, 2.0, 0.0});
  ASSERT_EQ(exact.size(), 1u);
  EXPECT_EQ(exact[0].first, 10);
}

TEST(FramePicker, ACarFarOffThePathStillGetsFiniteLight) {
  FramePicker picker(StraightPath(40));
  const auto w = picker.LightWeights({10, 2, 500});
  double sum = 0;
  for (const auto& [f, v] : w) {
    EXPECT_TRUE(std::isfinite(v));
    sum += v;
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_NEAR(w.front().second, 1.0 / 3, 1e-3);  // far away, the nearest frames weigh alike
}

TEST(FramePicker, ViewFrameTrailsTheCarAlongThePath) {
  FramePicker picker(StraightPath(40), {3, 6.0});
  EXPECT_EQ(picker.ViewFrame({15.0, 0, 1.0}), 18);  // 15 m − 6 m = 9 m → frame 18
  EXPECT_EQ(picker.ViewFrame({2.0, 0, 0}), 0);      // clamped at the start
  EXPECT_EQ(picker.ViewFrame({200, 0, 0}), 27);     // past the end: 19.5 − 6 = 13.5 m → frame 27
}

TEST(FramePicker, DuplicatedFramesAndASingleFrameWork) {
  auto path = StraightPath(5);
  path.insert(path.begin() + 2, path[2]);  // a duplicated frame: a zero-length segment
  FramePicker picker(path);
  EXPECT_NEAR(picker.ArcLengthOf({1.0, 2.0, 0.0}), 1.0, 1e-12);
  FramePicker single(std::vector<glm::dvec3>{{1, 2, 3}});
  EXPECT_EQ(single.ViewFrame({9, 9, 9}), 0);
  EXPECT_EQ(single.LightWeights({9, 9, 9}).size(), 1u);
}

TEST(FramePicker, BadTrajectoriesAreClearErrors) {
  EXPECT_THROW(FramePicker(std::vector<glm::dvec3>{}), Error);
  EXPECT_THROW(FramePicker(std::vector<glm::dvec3>{{0, std::nan(""), 0}}), Error);
  EXPECT_THROW(FramePicker(StraightPath(3), {0, 6.0}), Error);
}

TEST(FramePicker, SmootherApproachesTheTargetWithoutJumps) {
  LightWeightSmoother smoother(0.25);
  smoother.Update({{10, 1.0}}, 0.04);
  EXPECT_DOUBLE_EQ(smoother.weights().at(10), 1.0);
  // The car jumps to frame 20: the light moves over gradually.
  double previous = 1.0;
  for (int step = 0; step < 50; ++step) {
    const auto& w = smoother.Update({{20, 1.0}}, 0.04);
    const double w10 = w.count(10) ? w.at(10) : 0.0;
    EXPECT_LE(w10, previous + 1e-12);
    EXPECT_GE(previous - w10, 0.0);
    EXPECT_LT(previous - w10, 0.2);  // no pop: at most 1 − e^{−0.16} per 40 ms step
    double sum = 0;
    for (const auto& [f, v] : w) sum += v;
    EXPECT_NEAR(sum, 1.0, 1e-9);
    previous = w10;
  }
  EXPECT_EQ(smoother.weights().count(10), 0u);  // faded out and dropped
}

}  // namespace
}  // namespace odvr::app
