#include "capture/frame_set_assembler.h"

#include <gtest/gtest.h>

#include "core/error.h"

namespace odvr::capture {
namespace {

Frame At(int camera, double t) {
  Frame f;
  f.camera = camera;
  f.timestamp_s = t;
  f.image = cv::Mat(2, 2, CV_8UC3, cv::Scalar(camera));
  return f;
}

TEST(FrameSetAssembler, GroupsFramesWithinTheTolerance) {
  FrameSetAssembler a(3, {0.005, 0.5, 8});
  // Three cameras at 25 fps with ±2 ms jitter, arriving interleaved.
  for (int k = 0; k < 4; ++k) {
    a.Push(At(0, k * 0.04 + 0.001));
    a.Push(At(2, k * 0.04 - 0.002));
    a.Push(At(1, k * 0.04));
  }
  for (int k = 0; k < 4; ++k) {
    auto set = a.TryPop();
    ASSERT_TRUE(set) << k;
    EXPECT_EQ(set->missing_count(), 0);
    EXPECT_NEAR(set->timestamp_s, k * 0.04, 0.003);
  }
  EXPECT_FALSE(a.TryPop());
  EXPECT_EQ(a.stats().frames_out_of_sync, 0);
}

TEST(FrameSetAssembler, DropsFramesOutOfSyncBeyondTheTolerance) {
  FrameSetAssembler a(2, {0.005, 0.5, 8});
  a.Push(At(0, 0.000));
  a.Push(At(1, 0.020));  // 20 ms later: camera 0's frame has no partner
  a.Push(At(0, 0.021));
  auto set = a.TryPop();
  ASSERT_TRUE(set);
  EXPECT_NEAR(set->timestamp_s, 0.0205, 1e-9);
  EXPECT_EQ(a.stats().frames_out_of_sync, 1);
  const auto events = a.TakeEvents();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, SourceEvent::Kind::kOutOfSync);
  EXPECT_EQ(events[0].camera, 0);
}

TEST(FrameSetAssembler, ASilentCameraIsDeclaredLostAndTheOthersGoOn) {
  FrameSetAssembler a(2, {0.005, 0.2, 16});
  for (int k = 0; k < 3; ++k) {
    a.Push(At(0, k * 0.04));
    a.Push(At(1, k * 0.04));
  }
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(a.TryPop());
  // Camera 1 stops; camera 0 runs on.
  int delivered = 0;
  for (int k = 3; k < 15; ++k) {
    a.Push(At(0, k * 0.04));
    while (auto set = a.TryPop()) {
      ++delivered;
      EXPECT_TRUE(set->frames[1].image.empty());
      EXPECT_FALSE(set->frames[0].image.empty());
    }
  }
  EXPECT_TRUE(a.lost(1));
  EXPECT_GE(delivered, 6);  // after ~0.2 s of silence every new frame makes a set
  bool reported = false;
  for (const auto& e : a.TakeEvents()) reported |= e.kind == SourceEvent::Kind::kCameraLost && e.camera == 1;
  EXPECT_TRUE(reported);
  // It comes back: sets are complete again.
  a.Push(At(0, 0.60));
  a.Push(At(1, 0.60));
  std::optional<FrameSet> last;
  while (auto set = a.TryPop()) last = std::move(set);
  ASSERT_TRUE(last);
  EXPECT_EQ(last->missing_count(), 0);
}

TEST(FrameSetAssembler, WaitsForASlowCameraWithinTheStallTime) {
  FrameSetAssembler a(2, {0.005, 0.5, 16});
  a.Push(At(0, 0.00));
  a.Push(At(0, 0.04));
  EXPECT_FALSE(a.TryPop());  // camera 1 is late, not lost
  a.Push(At(1, 0.001));
  EXPECT_TRUE(a.TryPop());
}

TEST(FrameSetAssembler, BadOptionsAndCamerasAreClearErrors) {
  EXPECT_THROW(FrameSetAssembler(0), Error);
  EXPECT_THROW(FrameSetAssembler(2, {0.0, 0.5, 8}), Error);
  FrameSetAssembler a(2);
  EXPECT_THROW(a.Push(At(5, 0)), Error);
  Frame nan_frame = At(0, std::nan(""));
  a.Push(nan_frame);  // counted as corrupt, not grouped
  EXPECT_EQ(a.stats().corrupt_frames, 1);
}

}  // namespace
}  // namespace odvr::capture
