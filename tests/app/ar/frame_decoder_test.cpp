#include "app/ar/frame_decoder.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "core/error.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;

// An image sequence whose frame i is a flat grey of value i, so a decoded frame says its index.
fs::path WriteNumberedFrames(int frames) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_decoder_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (int i = 0; i < frames; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", i);
    cv::imwrite((dir / name).string(), cv::Mat(8, 16, CV_8UC3, cv::Scalar(i, i, i)));
  }
  return dir;
}

int ValueOf(const DecodedFrame& f) { return f.set.frames[0].image.at<cv::Vec3b>(0, 0)[0]; }

TEST(FrameDecoder, DeliversFramesInOrderAndSeeksBothWays) {
  const auto dir = WriteNumberedFrames(40);
  FrameDecoder decoder(capture::OpenSource(dir.string()), 4);
  EXPECT_EQ(decoder.frame_count(), 40);
  for (long i : {0L, 1L, 2L, 5L, 30L, 3L, 39L, 0L}) {
    auto f = decoder.Get(i, std::chrono::seconds(5));
    ASSERT_TRUE(f) << i;
    EXPECT_EQ(f->index, i);
    EXPECT_EQ(ValueOf(*f), i);
  }
  fs::remove_all(dir);
}

TEST(FrameDecoder, ATruncatedVideoStopsAtItsLastGoodFrame) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_decoder_video_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path video = dir / "clip.avi";
  {
    cv::VideoWriter writer(video.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25,
                           cv::Size(32, 16));
    for (int i = 0; i < 40; ++i) writer.write(cv::Mat(16, 32, CV_8UC3, cv::Scalar(i * 6, i * 6, i * 6)));
  }
  fs::resize_file(video, fs::file_size(video) / 2);  // the download broke off halfway
  FrameDecoder decoder(capture::OpenSource(video.string()), 3);
  std::optional<DecodedFrame> last;
  for (long i = 0; i < decoder.frame_count(); ++i) {
    auto f = decoder.Get(i, std::chrono::seconds(5));
    ASSERT_TRUE(f) << i;  // past the real end the last good frame comes back, never nothing
    last = f;
  }
  EXPECT_LT(decoder.available_frames(), 40);
  EXPECT_GE(decoder.available_frames(), 5);
  EXPECT_EQ(last->index, decoder.available_frames() - 1);
  EXPECT_FALSE(last->set.frames[0].image.empty());
  fs::remove_all(dir);
}

TEST(FrameDecoder, ACorruptFrameInTheMiddleIsAHoleNotTheEnd) {
  const auto dir = WriteNumberedFrames(12);
  {
    FILE* f = std::fopen((dir / "000005.png").c_str(), "w");
    std::fputs("corrupt", f);
    std::fclose(f);
  }
  FrameDecoder decoder(capture::OpenSource(dir.string()), 3);
  auto hole = decoder.Get(5, std::chrono::seconds(5));
  ASSERT_TRUE(hole);
  EXPECT_TRUE(hole->set.frames[0].image.empty());
  auto after = decoder.Get(11, std::chrono::seconds(5));
  ASSERT_TRUE(after);
  EXPECT_EQ(ValueOf(*after), 11);
  EXPECT_EQ(decoder.available_frames(), 12);
  EXPECT_FALSE(decoder.TakeEvents().empty());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace odvr::app
