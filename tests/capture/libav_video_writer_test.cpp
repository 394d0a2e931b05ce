#include "capture/libav_video_writer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "capture/libav_video.h"
#include "core/error.h"
#include "tests/scratch_dir.h"

namespace odvr {
namespace {

// The fixture takes the class's name (ctest selects suites by the file's name): capture:: names the class.
using capture::DefaultCodecFor;
using capture::LibavVideoReader;
using capture::ProbeVideo;
using capture::StereoLayout;
using capture::VideoProbe;
using capture::VideoWriterOptions;

namespace fs = std::filesystem;

class LibavVideoWriter : public ::testing::Test {
 protected:
  odvr::testing::ScratchDir scratch_{"odvr_video_writer"};
  const fs::path& dir_ = scratch_.dir;
};

// Frame i: smooth colour ramps (what a street's sky and road are) and a bright square moving
// right by 4 px a frame (what the car is).
cv::Mat Pattern(int i, int width = 160, int height = 96) {
  cv::Mat image(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      image.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uchar>(255 * x / width), static_cast<uchar>(255 * y / height),
                                            static_cast<uchar>(128 + 60 * std::sin(0.1 * (x + y))));
  cv::rectangle(image, cv::Rect(8 + 4 * i, 30, 24, 24), cv::Scalar(250, 250, 250), cv::FILLED);
  return image;
}

double Psnr(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  diff.convertTo(diff, CV_64F);
  const cv::Scalar s = cv::mean(diff.mul(diff));
  const double mse = (s[0] + s[1] + s[2]) / 3;
  return 10 * std::log10(255.0 * 255.0 / std::max(mse, 1e-12));
}

TEST_F(LibavVideoWriter, EachCodecAndContainerReadsBackFrameForFrame) {
  struct Case {
    const char* file;
    const char* codec;  // asked for ("" by extension)
    const char* decoded_as;
    double min_psnr_db;
  };
  // At crf 20 the pattern comes back at 36.6 dB (x264) and 37.5 dB (x265), 40.5 dB through MJPEG's
  // quantiser 13, its sharp square edges limited by 4:2:0 chroma: floors 2-4 dB below. A writer
  // whose YUV matrix or range differed from the reader's would lose 6 dB or more.
  for (const Case& c : {Case{"a.mp4", "", "h264", 34}, Case{"b.mov", "", "h264", 34}, Case{"c.mkv", "h265", "hevc", 34},
                        Case{"d.avi", "", "mjpeg", 36}, Case{"e.mp4", "h265", "hevc", 34}}) {
    const fs::path path = dir_ / c.file;
    VideoWriterOptions o;
    o.width = 160;
    o.height = 96;
    o.fps = 30;
    o.codec = c.codec;
    {
      capture::LibavVideoWriter writer(path, o);
      for (int i = 0; i < 12; ++i) writer.Write(Pattern(i));
      writer.Finish();
      EXPECT_EQ(writer.frames_written(), 12);
    }
    const VideoProbe probe = ProbeVideo(path.string());
    EXPECT_EQ(probe.codec, c.decoded_as) << c.file;
    EXPECT_NEAR(probe.fps, 30, 1e-6) << c.file;
    LibavVideoReader reader(path.string());
    int frames = 0;
    double worst = 1e9;
    while (auto f = reader.Next()) {
      ASSERT_EQ(f->image.cols, 160) << c.file;
      worst = std::min(worst, Psnr(f->image, Pattern(static_cast<int>(f->index))));
      ++frames;
    }
    EXPECT_EQ(frames, 12) << c.file;
    EXPECT_GT(worst, c.min_psnr_db) << c.file;
    std::cout << "  " << c.file << " " << c.decoded_as << ": worst frame " << worst << " dB\n";
  }
}

TEST_F(LibavVideoWriter, A360VideoCarriesSphericalMetadataPlayersRead) {
  for (const char* file : {"pano.mp4", "pano.mkv"}) {
    VideoWriterOptions o;
    o.width = 128;
    o.height = 64;
    o.spherical_equirect = true;
    capture::LibavVideoWriter writer(dir_ / file, o);
    for (int i = 0; i < 3; ++i) writer.Write(Pattern(i, 128, 64));
    writer.Finish();
    const VideoProbe probe = ProbeVideo((dir_ / file).string());
    EXPECT_EQ(probe.projection, "equirectangular") << file;
    ASSERT_TRUE(probe.stereo) << file;
    EXPECT_EQ(*probe.stereo, StereoLayout::kMono) << file;
  }
  // Without the flag the file says nothing.
  VideoWriterOptions flat;
  flat.width = 128;
  flat.height = 64;
  capture::LibavVideoWriter writer(dir_ / "flat.mp4", flat);
  writer.Write(Pattern(0, 128, 64));
  writer.Finish();
  EXPECT_EQ(ProbeVideo((dir_ / "flat.mp4").string()).projection, "");
}

// The output of a shell command (stderr with it).
std::string Output(const std::string& command) {
  std::string text;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return text;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe)) text += buffer;
  ::pclose(pipe);
  return text;
}

// The mean volume in dB of `file`'s first `seconds` of sound, as ffmpeg's volumedetect measures it.
double MeanVolumeDb(const fs::path& file, double seconds) {
  const std::string text = Output("ffmpeg -hide_banner -nostats -i " + file.string() + " -t " +
                                  std::to_string(seconds) + " -vn -af volumedetect -f null -");
  const auto at = text.find("mean_volume: ");
  return at == std::string::npos ? NAN : std::stod(text.substr(at + 13));
}

TEST_F(LibavVideoWriter, TheRecordingsSoundIsCopiedFromTheFirstFrameShown) {
  if (std::system("command -v ffmpeg >/dev/null 2>&1") != 0) GTEST_SKIP() << "ffmpeg is not installed";
  // 3 s of a recording whose sound is silent for 1 s, then a 440 Hz tone: AAC in MP4, as cameras write.
  const fs::path source = dir_ / "recording.mp4";
  const std::string make =
      "ffmpeg -v error -y -f lavfi -i testsrc=size=64x32:rate=25:duration=3 -f lavfi -i "
      "\"aevalsrc=if(lt(t\\,1)\\,0\\,0.5*sin(2*PI*440*t)):s=48000:d=3\" -c:v libx264 -c:a aac "
      "-shortest " +
      source.string();
  ASSERT_EQ(std::system(make.c_str()), 0) << make;

  for (const char* file : {"late.mp4", "late.mkv"}) {
    VideoWriterOptions o;
    o.width = 128;
    o.height = 64;
    o.audio_from = source.string();
    o.audio_start_s = 1.2;  // inside the tone
    capture::LibavVideoWriter writer(dir_ / file, o);
    for (int i = 0; i < 25; ++i) writer.Write(Pattern(i, 128, 64));
    writer.Finish();
    EXPECT_EQ(writer.audio_codec(), "aac") << file;
    EXPECT_EQ(writer.audio_dropped(), "") << file;
    const std::string probe = Output(
        "ffprobe -v error -select_streams a:0 -show_entries format=duration:stream=codec_name "
        "-of default=nw=1 " +
        (dir_ / file).string());
    EXPECT_NE(probe.find("codec_name=aac"), std::string::npos) << file << ": " << probe;
    const auto at = probe.find("duration=");
    ASSERT_NE(at, std::string::npos) << probe;
    // 25 frames at 25 fps: one second, to within an AAC frame (21 ms) and the encoder's priming.
    EXPECT_NEAR(std::stod(probe.substr(at + 9)), 1.0, 0.06) << file;
    const double loud = MeanVolumeDb(dir_ / file, 0.5);
    std::printf("%s: mean volume of its first 0.5 s %.1f dB\n", file, loud);
    EXPECT_GT(loud, -15.0) << file << ": the tone from 1.2 s of the recording starts the clip";
  }
  // From the recording's start: the clip's first half second is the recording's silence.
  VideoWriterOptions early;
  early.width = 128;
  early.height = 64;
  early.audio_from = source.string();
  capture::LibavVideoWriter writer(dir_ / "early.mp4", early);
  for (int i = 0; i < 25; ++i) writer.Write(Pattern(i, 128, 64));
  writer.Finish();
  const double quiet = MeanVolumeDb(dir_ / "early.mp4", 0.5);
  EXPECT_LT(quiet, -60.0);

  // A recording with no sound: a silent clip, and nothing reported dropped.
  const fs::path mute = dir_ / "mute.mp4";
  ASSERT_EQ(
      std::system(("ffmpeg -v error -y -f lavfi -i testsrc=size=64x32:rate=25:duration=1 -c:v libx264 " + mute.string())
                      .c_str()),
      0);
  VideoWriterOptions silent = early;
  silent.audio_from = mute.string();
  capture::LibavVideoWriter quiet_writer(dir_ / "silent.mp4", silent);
  quiet_writer.Write(Pattern(0, 128, 64));
  quiet_writer.Finish();
  EXPECT_EQ(quiet_writer.audio_codec(), "");
  EXPECT_EQ(quiet_writer.audio_dropped(), "") << "nothing was lost";
}

TEST_F(LibavVideoWriter, FailuresAreErrorsNamingTheFile) {
  VideoWriterOptions o;
  o.width = 160;
  o.height = 96;
  // A full disk: /dev/full takes the open and fails every write (reached through a link whose
  // name gives libav its container).
  const fs::path full = dir_ / "full.avi";
  fs::create_symlink("/dev/full", full);
  try {
    VideoWriterOptions mjpeg = o;
    mjpeg.codec = "mjpeg";
    capture::LibavVideoWriter writer(full, mjpeg);
    for (int i = 0; i < 40; ++i) writer.Write(Pattern(i));
    writer.Finish();
    ADD_FAILURE() << "writing to /dev/full succeeded";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(full.string()), std::string::npos) << what;
    EXPECT_NE(what.find("No space left on device"), std::string::npos) << what;
  }
  EXPECT_THROW(capture::LibavVideoWriter(dir_ / "no" / "such" / "dir.mp4", o), Error);
  // Written to a temporary for an output (WriteFileAtomically), errors name the output.
  try {
    capture::LibavVideoWriter writer(dir_ / "no" / "such" / ".clip.tmp1.mp4", o, "clip.mp4");
    ADD_FAILURE() << "opened a file in no folder";
  } catch (const Error& e) {
    EXPECT_EQ(e.where(), "clip.mp4") << e.what();
  }
  EXPECT_THROW(capture::LibavVideoWriter(dir_ / "x.xyz",
                                         [&] {
                                           VideoWriterOptions m = o;
                                           m.codec = "h264";
                                           return m;
                                         }()),
               Error);
  EXPECT_THROW(DefaultCodecFor("clip.gif"), UsageError);
  VideoWriterOptions odd = o;
  odd.width = 161;
  EXPECT_THROW(odd.Check(), UsageError);
  VideoWriterOptions fps = o;
  for (const double bad : {std::nan(""), 1e-9, 0.0, 1001.0}) {
    fps.fps = bad;
    EXPECT_THROW(fps.Check(), UsageError) << bad;
  }
  // A frame of another size is refused; an unfinished writer closes without a crash.
  capture::LibavVideoWriter writer(dir_ / "partial.mp4", o);
  EXPECT_THROW(writer.Write(Pattern(0, 80, 48)), Error);
  writer.Write(Pattern(0));
}

}  // namespace
}  // namespace odvr
