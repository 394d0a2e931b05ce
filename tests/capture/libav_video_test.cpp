#include "capture/libav_video.h"

#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "capture/source.h"
#include "core/error.h"
#include "core/timing.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const fs::path kStreet = fs::path(ODVR_SOURCE_DIR) / "media/demo/street.mp4";
const fs::path kVideo360 = fs::path(ODVR_SHARED_DIR) / "data/video360";

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

class LibavVideo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("odvr_libav_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(LibavVideo, DecodesEveryFrameOfTheDemoClipInOrder) {
  LibavVideoReader reader(kStreet.string());
  EXPECT_EQ(reader.width(), 1024);
  EXPECT_EQ(reader.height(), 512);
  EXPECT_DOUBLE_EQ(reader.fps(), 25);
  EXPECT_EQ(reader.frame_count(), 24);
  EXPECT_TRUE(reader.probe().frame_count_exact);
  EXPECT_EQ(reader.probe().codec, "h264");
  long n = 0;
  while (auto frame = reader.Next()) {
    EXPECT_EQ(frame->index, n);
    EXPECT_NEAR(frame->timestamp_s, n / 25.0, 1e-6);
    EXPECT_EQ(frame->image.cols, 1024);
    EXPECT_EQ(frame->image.rows, 512);
    EXPECT_EQ(frame->image.type(), CV_8UC3);
    EXPECT_FALSE(frame->concealed);
    ++n;
  }
  EXPECT_EQ(n, 24);  // B-frames held in the decoder at the end come out too
  EXPECT_EQ(reader.skipped_frames(), 0);
  EXPECT_EQ(reader.read_error(), "");
  EXPECT_FALSE(reader.Next());  // and stays over
}

TEST_F(LibavVideo, SeekDeliversExactlyTheFrameSequentialDecodingGave) {
  LibavVideoReader reader(kStreet.string());
  std::vector<cv::Mat> frames;
  while (auto frame = reader.Next()) frames.push_back(frame->image);
  ASSERT_EQ(frames.size(), 24u);
  // Backwards, forwards, to the ends, and to the frame already next.
  for (long n : {12L, 5L, 23L, 0L, 17L, 18L, 1L, 1L, 22L}) {
    ASSERT_TRUE(reader.Seek(n)) << n;
    auto frame = reader.Next();
    ASSERT_TRUE(frame) << n;
    EXPECT_EQ(frame->index, n);
    EXPECT_NEAR(frame->timestamp_s, n / 25.0, 1e-6);
    EXPECT_TRUE(SameImage(frame->image, frames[n])) << "frame " << n;
    if (n + 1 < 24) {
      auto after = reader.Next();
      ASSERT_TRUE(after) << n;
      EXPECT_EQ(after->index, n + 1);
      EXPECT_TRUE(SameImage(after->image, frames[n + 1])) << "frame " << n + 1;
    }
  }
  EXPECT_FALSE(reader.Seek(30));  // past the end
  EXPECT_FALSE(reader.Next());
  ASSERT_TRUE(reader.Seek(3));  // and back
  auto frame = reader.Next();
  ASSERT_TRUE(frame);
  EXPECT_TRUE(SameImage(frame->image, frames[3]));
}

// congo.mp4 has keyframes at frames 0 and 251 only: a seek past 251 starts there, not at 0.
TEST_F(LibavVideo, SeeksFromAKeyframeInsideTheStream) {
  const fs::path congo = kVideo360 / "congo.mp4";
  if (!fs::exists(congo)) GTEST_SKIP() << congo << " absent (../shared is not in a user's clone)";
  LibavVideoReader reader(congo.string());
  const std::vector<long> wanted = {249, 250, 251, 252, 260, 275};
  std::map<long, cv::Mat> frames;
  long n = 0;
  for (; n <= wanted.back(); ++n) {
    auto frame = reader.Next();
    ASSERT_TRUE(frame) << n;
    ASSERT_EQ(frame->index, n);
    if (std::find(wanted.begin(), wanted.end(), n) != wanted.end()) frames[n] = frame->image;
  }
  for (long target : {260L, 251L, 250L, 275L, 252L, 249L}) {
    const auto start = Clock::now();
    ASSERT_TRUE(reader.Seek(target)) << target;
    auto frame = reader.Next();
    ASSERT_TRUE(frame) << target;
    EXPECT_EQ(frame->index, target);
    EXPECT_NEAR(frame->timestamp_s, target * 30618.0 / 917425.0, 1e-6);
    EXPECT_TRUE(SameImage(frame->image, frames[target])) << "frame " << target;
    std::printf("libav_video: congo.mp4 Seek(%ld) + Next: %.0f ms\n", target, MsSince(start));
  }
}

TEST_F(LibavVideo, DecodesAllNinetyFramesOfTheIcelandTransportStream) {
  const fs::path iceland = kVideo360 / "iceland0.ts";
  if (!fs::exists(iceland)) GTEST_SKIP() << iceland << " absent (../shared is not in a user's clone)";
  auto source = OpenSource(iceland.string());
  ASSERT_EQ(source->frame_count(), 90);  // an estimate (MPEG-TS counts no frames): 3.003 s at 29.97 fps
  EXPECT_NEAR(source->fps(), 30000.0 / 1001.0, 1e-9);
  std::vector<SourceEvent> events;
  std::map<long, cv::Mat> kept;
  long n = 0;
  while (auto set = source->Next()) {
    const Frame& frame = set->frames[0];
    EXPECT_EQ(frame.index, n);
    EXPECT_NEAR(frame.timestamp_s, n * 1001.0 / 30000.0, 1e-6);
    EXPECT_EQ(frame.image.cols, 2048);
    EXPECT_EQ(frame.image.rows, 2048);
    if (n == 40 || n == 89) kept[n] = frame.image;
    for (auto& e : source->TakeEvents()) events.push_back(e);
    ++n;
  }
  for (auto& e : source->TakeEvents()) events.push_back(e);
  EXPECT_EQ(n, 90);
  for (const auto& e : events) ADD_FAILURE() << "unexpected event: " << e.message;
  EXPECT_EQ(source->stats().corrupt_frames, 0);
  // MPEG-TS has no keyframe index and this stream one keyframe: seeks decode from the start.
  for (long target : {40L, 89L}) {
    ASSERT_TRUE(source->Seek(target));
    auto set = source->Next();
    ASSERT_TRUE(set);
    EXPECT_EQ(set->frames[0].index, target);
    EXPECT_TRUE(SameImage(set->frames[0].image, kept[target])) << "frame " << target;
  }
}

TEST_F(LibavVideo, ProbeReadsStereoAndSphericalMetadata) {
  const VideoProbe street = ProbeVideo(kStreet.string());
  EXPECT_EQ(street.width, 1024);
  EXPECT_EQ(street.frame_count, 24);
  EXPECT_FALSE(street.stereo);  // the demo clip carries no st3d/sv3d
  EXPECT_EQ(street.projection, "");

  const fs::path congo = kVideo360 / "congo.mp4", iceland = kVideo360 / "iceland0.ts";
  if (!fs::exists(congo) || !fs::exists(iceland)) GTEST_SKIP() << kVideo360 << " absent (not in a user's clone)";
  // congo.mp4 carries st3d (top-bottom) and sv3d (equirectangular, no rotation), as ffprobe
  // -show_entries stream_side_data shows.
  const VideoProbe c = ProbeVideo(congo.string());
  EXPECT_EQ(c.width, 1920);
  EXPECT_EQ(c.height, 1080);
  EXPECT_NEAR(c.fps, 917425.0 / 30618.0, 1e-9);
  EXPECT_EQ(c.frame_count, 300);
  EXPECT_TRUE(c.frame_count_exact);
  EXPECT_EQ(c.codec, "h264");
  ASSERT_TRUE(c.stereo);
  EXPECT_EQ(*c.stereo, StereoLayout::kTopBottom);
  EXPECT_FALSE(c.stereo_inverted);
  EXPECT_EQ(c.projection, "equirectangular");
  EXPECT_EQ(c.yaw_deg, 0);
  EXPECT_EQ(c.pitch_deg, 0);
  EXPECT_EQ(c.roll_deg, 0);
  // iceland0.ts is top-bottom stereo by its 1:1 shape only: the stream carries no stereo or
  // spherical side data (nor frame-packing SEI), so the probe says nothing.
  const VideoProbe i = ProbeVideo(iceland.string());
  EXPECT_EQ(i.width, 2048);
  EXPECT_EQ(i.height, 2048);
  EXPECT_EQ(i.frame_count, 90);
  EXPECT_FALSE(i.frame_count_exact);
  EXPECT_FALSE(i.stereo);
  EXPECT_EQ(i.projection, "");
  EXPECT_EQ(GuessStereoLayout(i.width, i.height), StereoLayout::kTopBottom);
}

TEST_F(LibavVideo, ATruncatedCopyEndsEarlyWithOneClearEvent) {
  const fs::path cut = dir_ / "street_half.mp4";
  fs::copy_file(kStreet, cut);
  fs::resize_file(cut, fs::file_size(kStreet) / 2);  // as `head -c` leaves a broken download
  auto source = OpenSource(cut.string());
  EXPECT_EQ(source->frame_count(), 24);  // what the intact header announces
  std::vector<SourceEvent> lost;
  int sets = 0, corrupt = 0;
  long last = -1;
  auto take_events = [&] {
    for (auto& e : source->TakeEvents()) {
      if (e.kind == SourceEvent::Kind::kCameraLost) lost.push_back(e);
      corrupt += e.kind == SourceEvent::Kind::kCorruptFrame;
    }
  };
  while (auto set = source->Next()) {
    EXPECT_FALSE(set->frames[0].image.empty());
    // The cut leaves B-frames without their references: gaps, never disorder.
    EXPECT_GT(set->frames[0].index, last);
    last = set->frames[0].index;
    take_events();
    ASSERT_LT(++sets, 100);  // never more than the file holds
  }
  take_events();
  EXPECT_GE(sets, 1);
  EXPECT_LT(last + 1, 24);
  ASSERT_EQ(lost.size(), 1u);
  EXPECT_NE(lost[0].message.find("street_half.mp4"), std::string::npos) << lost[0].message;
  EXPECT_NE(lost[0].message.find("stream ends after " + std::to_string(last + 1) + " of 24 frames (truncated?)"),
            std::string::npos)
      << lost[0].message;
  EXPECT_FALSE(source->Next());  // over, and stays over
  std::printf("libav_video: street.mp4 cut in half: %d frames up to frame %ld, %d corrupt-frame events, \"%s\"\n", sets,
              last, corrupt, lost[0].message.c_str());
}

// A minimal PCM WAV: a readable file with an audio stream and no video.
void WriteWav(const fs::path& path) {
  auto u32 = [](std::ofstream& f, std::uint32_t v) { f.write(reinterpret_cast<const char*>(&v), 4); };
  auto u16 = [](std::ofstream& f, std::uint16_t v) { f.write(reinterpret_cast<const char*>(&v), 2); };
  const std::uint32_t samples = 8000;
  std::ofstream f(path, std::ios::binary);
  f.write("RIFF", 4);
  u32(f, 36 + samples * 2);
  f.write("WAVEfmt ", 8);
  u32(f, 16);
  u16(f, 1);  // PCM
  u16(f, 1);  // mono
  u32(f, 8000);
  u32(f, 16000);
  u16(f, 2);
  u16(f, 16);
  f.write("data", 4);
  u32(f, samples * 2);
  const std::string silence(samples * 2, '\0');
  f.write(silence.data(), static_cast<std::streamsize>(silence.size()));
}

TEST_F(LibavVideo, FilesThatAreNotVideoAreErrorsNamingTheFile) {
  const fs::path text = dir_ / "notes.mp4", audio = dir_ / "tone.wav", missing = dir_ / "nope.mp4";
  std::ofstream(text) << "this is a text file, not a video\n";
  WriteWav(audio);
  const std::pair<fs::path, std::string> cases[] = {
      {text, "not a video"}, {audio, "has no video stream"}, {missing, "no such video file"}};
  for (const auto& [path, reason] : cases) {
    for (int probe_only = 0; probe_only < 2; ++probe_only) {
      try {
        if (probe_only)
          ProbeVideo(path.string());
        else
          LibavVideoReader reader(path.string());
        ADD_FAILURE() << path << " opened";
      } catch (const Error& e) {
        EXPECT_EQ(e.where(), path.string());
        EXPECT_NE(e.reason().find(reason), std::string::npos) << e.what();
        EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
      }
    }
  }
  try {
    OpenSource(text.string());
    ADD_FAILURE() << "opened";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("notes.mp4"), std::string::npos) << e.what();
  }
}

// libav's complaints reach the program's log (spdlog), one line each, not stderr past it.
TEST_F(LibavVideo, LibavLogLinesGoToSpdlog) {
  const fs::path text = dir_ / "notes.mp4";
  std::ofstream(text) << "this is a text file, not a video\n";
  std::ostringstream log;
  auto previous = spdlog::default_logger();
  spdlog::set_default_logger(
      std::make_shared<spdlog::logger>("capture", std::make_shared<spdlog::sinks::ostream_sink_mt>(log)));
  ::testing::internal::CaptureStderr();
  EXPECT_THROW(ProbeVideo(text.string()), Error);
  const std::string stderr_text = ::testing::internal::GetCapturedStderr();
  spdlog::set_default_logger(previous);
  EXPECT_NE(log.str().find("libav: [mov,mp4"), std::string::npos) << log.str();
  EXPECT_NE(log.str().find("moov atom not found"), std::string::npos) << log.str();
  EXPECT_EQ(log.str().find("moov atom not found\n\n"), std::string::npos) << "one line per message";
  EXPECT_EQ(stderr_text, "");
}

struct DecodeRun {
  int frames = 0;
  int failures = 0;
  double ms_per_frame = 0;
};

DecodeRun DecodeWithLibav(const fs::path& path, int limit) {
  DecodeRun run;
  const auto start = Clock::now();
  LibavVideoReader reader(path.string());
  while (run.frames < limit && reader.Next()) ++run.frames;
  run.failures = static_cast<int>(reader.skipped_frames());
  run.ms_per_frame = MsSince(start) / std::max(1, run.frames);
  return run;
}

// As the OpenCV path before libav read: a failed read() is a skipped frame, 8 in a row the end.
DecodeRun DecodeWithOpenCv(const fs::path& path, int limit) {
  DecodeRun run;
  const auto start = Clock::now();
  cv::VideoCapture capture(path.string(), cv::CAP_FFMPEG);
  cv::Mat image;
  int in_a_row = 0;
  while (run.frames < limit && in_a_row < 8) {
    if (capture.read(image) && !image.empty()) {
      ++run.frames;
      in_a_row = 0;
    } else {
      ++run.failures;
      ++in_a_row;
    }
  }
  run.failures -= in_a_row;  // the reads past the end
  run.ms_per_frame = MsSince(start) / std::max(1, run.frames);
  return run;
}

// Decode time per frame (opening included, BGR out) for the demo clip and each clip in
// ../shared/data/video360, libav against OpenCV's VideoCapture, which odvr used before.
// The first 90 frames of each: all of iceland0.ts, where OpenCV loses most of them.
TEST_F(LibavVideo, DecodeTimePerClipAgainstOpenCv) {
  std::vector<fs::path> clips = {kStreet};
  if (fs::is_directory(kVideo360))
    for (const auto& e : fs::directory_iterator(kVideo360))
      if (e.path().extension() == ".mp4" || e.path().extension() == ".ts") clips.push_back(e.path());
  std::sort(clips.begin() + 1, clips.end());
  constexpr int kLimit = 90;
  for (const auto& clip : clips) {
    const VideoProbe probe = ProbeVideo(clip.string());
    const int expected = static_cast<int>(std::min<long>(kLimit, probe.frame_count));
    const DecodeRun libav = DecodeWithLibav(clip, kLimit);
    const DecodeRun opencv = DecodeWithOpenCv(clip, kLimit);
    std::printf(
        "libav_video: %-24s %4dx%-4d of %3ld frames, first %d: libav %3d frames %2d skipped %6.2f ms/frame | "
        "OpenCV %3d frames %2d failed reads %6.2f ms/frame\n",
        clip.filename().c_str(), probe.width, probe.height, probe.frame_count, expected, libav.frames, libav.failures,
        libav.ms_per_frame, opencv.frames, opencv.failures, opencv.ms_per_frame);
    EXPECT_EQ(libav.frames, expected) << clip;
    EXPECT_EQ(libav.failures, 0) << clip;
  }
  if (clips.size() == 1) std::printf("libav_video: %s absent: timed the demo clip only\n", kVideo360.c_str());
}

}  // namespace
}  // namespace odvr::capture
