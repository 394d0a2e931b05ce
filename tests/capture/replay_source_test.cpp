// A recording replayed live (OpenReplay, "replay:DIR"): real capture threads and the shared
// live-source machinery, fed from the demo's six camera folders or a scratch copy with a camera
// that vanishes. No assertion depends on timing: only on which frames arrive, in what order.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture/source.h"
#include "core/error.h"
#include "tests/error_message.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;
using odvr::testing::ErrorMessageOf;
const fs::path kDemoRig = fs::path(ODVR_SOURCE_DIR) / "media/demo/rig";
constexpr int kDemoFrames = 24;

class ReplaySource : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("odvr_replay_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Camera c gets the demo's first frames[c] images of its camera c.
  void CopyDemo(const std::vector<int>& frames) {
    for (std::size_t c = 0; c < frames.size(); ++c) {
      const fs::path cam = dir_ / ("cam" + std::to_string(c));
      fs::create_directories(cam);
      for (int i = 0; i < frames[c]; ++i) {
        char name[16];
        std::snprintf(name, sizeof name, "%06d.jpg", i);
        fs::copy_file(kDemoRig / cam.filename() / name, cam / name);
      }
    }
  }

  // Sets until one with index >= `until`, with every event seen on the way.
  std::vector<FrameSet> Read(Source& source, long until, std::vector<SourceEvent>* events) {
    std::vector<FrameSet> sets;
    while (sets.empty() || sets.back().index < until) {
      auto set = source.Next(std::chrono::milliseconds(5000));
      for (auto& e : source.TakeEvents()) events->push_back(e);
      if (!set) {
        ADD_FAILURE() << "no frame set within 5 s after " << sets.size();
        break;
      }
      sets.push_back(std::move(*set));
    }
    return sets;
  }

  fs::path dir_;
};

TEST_F(ReplaySource, DeliversTheRecordingsImagesInSyncedSetsAndLoops) {
  SourceOptions options;
  options.fps = 50;
  options.queue_capacity = 64;  // keep every set: this test checks them all
  auto source = OpenSource("replay:" + kDemoRig.string(), options);
  EXPECT_TRUE(source->live());
  EXPECT_EQ(source->camera_count(), 6);
  EXPECT_EQ(source->fps(), 50);
  std::vector<SourceEvent> events;
  const auto sets = Read(*source, kDemoFrames + 1, &events);  // past the loop
  for (const auto& e : events) EXPECT_NE(e.kind, SourceEvent::Kind::kCameraLost) << e.message;
  for (const auto& set : sets) {
    ASSERT_EQ(set.frames.size(), 6u);
    EXPECT_EQ(set.missing_count(), 0) << "set " << set.index;
    for (const auto& f : set.frames) {
      EXPECT_EQ(f.index, set.frames[0].index);
      EXPECT_DOUBLE_EQ(f.timestamp_s, static_cast<double>(f.index) / 50);
    }
  }
  // The images are the recording's, frame k showing file k mod 24 (checked on two cameras).
  for (const auto& set : {sets.front(), sets.back()}) {
    for (const int c : {0, 4}) {
      char name[16];
      std::snprintf(name, sizeof name, "%06d.jpg", static_cast<int>(set.frames[0].index % kDemoFrames));
      const cv::Mat file = cv::imread((kDemoRig / ("cam" + std::to_string(c)) / name).string());
      const cv::Mat& got = set.frames[static_cast<std::size_t>(c)].image;
      ASSERT_EQ(got.size(), file.size());
      EXPECT_EQ(cv::norm(got, file, cv::NORM_INF), 0) << "set " << set.index << " camera " << c;
    }
  }
  EXPECT_GE(sets.back().frames[0].index, kDemoFrames);
}

TEST_F(ReplaySource, AShorterCameraIsLostOnceAndTheOthersGoOn) {
  CopyDemo({6, 2, 6});
  SourceOptions options;
  options.fps = 50;
  options.queue_capacity = 64;
  auto source = OpenSource("replay:" + dir_.string(), options);
  std::vector<SourceEvent> events;
  const auto sets = Read(*source, 8, &events);  // the loop starts again at 6
  int lost = 0;
  for (const auto& e : events) {
    if (e.kind != SourceEvent::Kind::kCameraLost) continue;
    ++lost;
    EXPECT_EQ(e.camera, 1);
    EXPECT_NE(e.message.find((dir_ / "cam1").string()), std::string::npos) << e.message;
    EXPECT_NE(e.message.find("no frame after 2"), std::string::npos) << e.message;
  }
  EXPECT_EQ(lost, 1);
  for (const auto& set : sets) {
    const long k = set.frames[0].index;
    EXPECT_FALSE(set.frames[0].image.empty()) << "set " << set.index;
    EXPECT_FALSE(set.frames[2].image.empty()) << "set " << set.index;
    EXPECT_EQ(set.frames[1].image.empty(), k >= 2) << "frame " << k;
  }
}

TEST_F(ReplaySource, AnUnreadableImageMidStreamLosesItsCamera) {
  CopyDemo({4, 4});
  std::ofstream(dir_ / "cam0" / "000002.jpg", std::ios::binary | std::ios::trunc) << "not a JPEG";
  SourceOptions options;
  options.fps = 50;
  options.queue_capacity = 64;
  auto source = OpenSource("replay:" + dir_.string(), options);
  std::vector<SourceEvent> events;
  const auto sets = Read(*source, 5, &events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, SourceEvent::Kind::kCameraLost);
  EXPECT_EQ(events[0].camera, 0);
  EXPECT_NE(events[0].message.find((dir_ / "cam0" / "000002.jpg").string()), std::string::npos) << events[0].message;
  EXPECT_TRUE(sets.back().frames[0].image.empty());
  EXPECT_FALSE(sets.back().frames[1].image.empty());
}

TEST_F(ReplaySource, ACameraThatCannotStartFailsTheOpen) {
  CopyDemo({2, 2});
  std::ofstream(dir_ / "cam1" / "000000.jpg", std::ios::binary | std::ios::trunc) << "not a JPEG";
  const std::string unreadable = ErrorMessageOf([&] { OpenSource("replay:" + dir_.string()); });
  EXPECT_NE(unreadable.find((dir_ / "cam1" / "000000.jpg").string()), std::string::npos) << unreadable;
  const std::string missing = ErrorMessageOf([&] { OpenSource("replay:/nonexistent/odvr_rig"); });
  EXPECT_NE(missing.find("/nonexistent/odvr_rig"), std::string::npos) << missing;
  const std::string empty_dir = ErrorMessageOf([&] {
    OpenReplay({(dir_ / "cam0").string(), (dir_ / "none").string()}, {});
  });
  EXPECT_NE(empty_dir.find((dir_ / "none").string()), std::string::npos) << empty_dir;
}

}  // namespace
}  // namespace odvr::capture
