#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "capture/source.h"
#include "core/error.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;

const fs::path kStreetRig = fs::path(ODVR_SHARED_DIR) / "data/street_a/rig";

class FileSources : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("odvr_sources_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A small synthetic rig recording: `cameras` cameras × `frames` frames of 32×24 JPEGs.
  void WriteSequences(int cameras, int frames) {
    for (int c = 0; c < cameras; ++c) {
      fs::create_directories(dir_ / ("cam" + std::to_string(c)));
      for (int i = 0; i < frames; ++i) {
        cv::Mat img(24, 32, CV_8UC3, cv::Scalar(10 * c, 5 * i, 100));
        char name[32];
        std::snprintf(name, sizeof name, "%06d.jpg", i);
        cv::imwrite((dir_ / ("cam" + std::to_string(c)) / name).string(), img);
      }
    }
  }

  fs::path WriteVideo(const std::string& name, int frames) {
    const fs::path path = dir_ / name;
    cv::VideoWriter writer(path.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25,
                           cv::Size(64, 32));
    EXPECT_TRUE(writer.isOpened());
    for (int i = 0; i < frames; ++i) {
      cv::Mat img(32, 64, CV_8UC3, cv::Scalar(i * 8 % 256, 128, 50));
      cv::putText(img, std::to_string(i), {4, 24}, cv::FONT_HERSHEY_SIMPLEX, 0.6, {255, 255, 255});
      writer.write(img);
    }
    return path;
  }

  fs::path dir_;
};

TEST_F(FileSources, ReadsTheStreetRigAsSixSynchronizedCameras) {
  if (!fs::exists(kStreetRig)) GTEST_SKIP() << "needs ../shared/data/street_a (absent in a user's clone)";
  auto source = OpenSource(kStreetRig.string());
  ASSERT_EQ(source->camera_count(), 6);
  EXPECT_FALSE(source->live());
  int sets = 0;
  while (auto set = source->Next()) {
    EXPECT_EQ(set->missing_count(), 0);
    EXPECT_EQ(set->frames[3].image.cols, 480);
    EXPECT_EQ(set->frames[3].image.rows, 640);
    EXPECT_NEAR(set->timestamp_s, sets / 25.0, 1e-9);
    if (++sets == 3) break;  // decoding all 240 images is not the point
  }
  EXPECT_EQ(sets, 3);
}

TEST_F(FileSources, ACameraThatEndsEarlyIsReportedLostAndTheRestGoOn) {
  WriteSequences(3, 6);
  for (int i = 3; i < 6; ++i) fs::remove(dir_ / "cam1" / (std::string("00000") + char('0' + i) + ".jpg"));
  auto source = OpenSource(dir_.string());
  int sets = 0, lost_events = 0;
  while (auto set = source->Next()) {
    EXPECT_EQ(set->frames[1].image.empty(), sets >= 3) << sets;
    EXPECT_FALSE(set->frames[0].image.empty());
    for (const auto& e : source->TakeEvents()) lost_events += e.kind == SourceEvent::Kind::kCameraLost && e.camera == 1;
    ++sets;
  }
  EXPECT_EQ(sets, 6);
  EXPECT_EQ(lost_events, 1);  // reported once, not per frame
}

TEST_F(FileSources, CorruptAndWrongSizedImagesAreSkippedWithAnEvent) {
  WriteSequences(2, 4);
  std::ofstream(dir_ / "cam0" / "000001.jpg", std::ios::trunc) << "not a jpeg";
  cv::imwrite((dir_ / "cam1" / "000002.jpg").string(), cv::Mat(10, 10, CV_8UC3, cv::Scalar(1, 2, 3)));
  auto source = OpenSource(dir_.string());
  std::vector<SourceEvent> events;
  int sets = 0;
  while (auto set = source->Next()) {
    if (sets == 1) {
      EXPECT_TRUE(set->frames[0].image.empty());
    }
    if (sets == 2) {
      EXPECT_TRUE(set->frames[1].image.empty());
    }
    for (auto& e : source->TakeEvents()) events.push_back(e);
    ++sets;
  }
  EXPECT_EQ(sets, 4);
  EXPECT_EQ(source->stats().corrupt_frames, 2);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_NE(events[0].message.find("000001.jpg"), std::string::npos) << events[0].message;
  EXPECT_NE(events[1].message.find("differs"), std::string::npos) << events[1].message;
}

TEST_F(FileSources, ATruncatedJpegIsACorruptFrameNotGreyRows) {
  WriteSequences(1, 3);
  const fs::path frame = dir_ / "cam0" / "000001.jpg";
  cv::Mat noise(24, 32, CV_8UC3);  // the camera's size: only the cut is wrong with it
  cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::imwrite(frame.string(), noise);
  fs::resize_file(frame, fs::file_size(frame) / 2);
  auto source = OpenSource(dir_.string());
  int sets = 0;
  std::vector<SourceEvent> events;
  while (auto set = source->Next()) {
    EXPECT_EQ(set->frames[0].image.empty(), sets == 1) << "set " << sets;
    for (auto& e : source->TakeEvents()) events.push_back(e);
    ++sets;
  }
  EXPECT_EQ(sets, 3);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_NE(events[0].message.find("000001.jpg: truncated JPEG"), std::string::npos) << events[0].message;
}

TEST_F(FileSources, ReadsVideoFilesFrameByFrameWithTimestamps) {
  const auto a = WriteVideo("a.avi", 10), b = WriteVideo("b.avi", 10);
  auto source = OpenSource(a.string() + "," + b.string());
  ASSERT_EQ(source->camera_count(), 2);
  int sets = 0;
  while (auto set = source->Next()) {
    EXPECT_EQ(set->missing_count(), 0);
    EXPECT_NEAR(set->frames[0].timestamp_s, sets / 25.0, 0.021);
    ++sets;
  }
  EXPECT_EQ(sets, 10);
}

TEST_F(FileSources, ATruncatedOrCorruptVideoEndsCleanlyWithoutACrash) {
  const auto good = WriteVideo("good.avi", 30);
  // Corrupt 2 kB in the middle of the file, and make a truncated copy.
  const auto size = fs::file_size(good);
  fs::copy_file(good, dir_ / "corrupt.avi");
  {
    std::fstream f(dir_ / "corrupt.avi", std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(size / 2));
    const std::string garbage(2048, '\x5a');
    f.write(garbage.data(), static_cast<std::streamsize>(garbage.size()));
  }
  fs::copy_file(good, dir_ / "truncated.avi");
  fs::resize_file(dir_ / "truncated.avi", size / 2);

  for (const char* name : {"corrupt.avi", "truncated.avi"}) {
    std::unique_ptr<Source> source;
    try {
      source = OpenSource((dir_ / name).string());
    } catch (const Error& e) {  // refusing the file outright is fine, if it says which
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      continue;
    }
    int sets = 0;
    while (auto set = source->Next()) {
      EXPECT_FALSE(set->frames[0].image.empty());
      ++sets;
    }
    EXPECT_GE(sets, 10) << name;  // the frames before the damage are all there
    EXPECT_LE(sets, 30) << name;
  }
}

TEST_F(FileSources, OneCorruptFrameInsideAVideoCostsAtMostThatFrame) {
  const auto path = WriteVideo("one_bad.avi", 30);
  // Garble the entropy-coded data of frame 15 only: the 16th JPEG start-of-image marker, past its
  // headers; the AVI index and chunk sizes stay intact, so the demuxer still finds every frame.
  std::string bytes;
  {
    std::ifstream f(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(f), {});
  }
  std::size_t soi = 0;
  for (int k = 0; k <= 15; ++k) {
    soi = bytes.find("\xFF\xD8\xFF", k == 0 ? 0 : soi + 3);
    ASSERT_NE(soi, std::string::npos) << "frame " << k;
  }
  const std::size_t sos = bytes.find("\xFF\xDA", soi);  // start of scan: the pixels follow
  ASSERT_NE(sos, std::string::npos);
  for (std::size_t i = sos + 16; i < sos + 216 && i < bytes.size(); ++i) bytes[i] = static_cast<char>(0xFF ^ (i * 37));
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }

  auto source = OpenSource(path.string());
  int sets = 0;
  cv::Mat last;
  while (auto set = source->Next()) {
    ASSERT_FALSE(set->frames[0].image.empty());
    last = set->frames[0].image;
    ++sets;
  }
  // The frame is skipped (or decoded with garbage in it): the stream goes on past it.
  EXPECT_GE(sets, 29);
  EXPECT_LE(sets, 30);
  ASSERT_FALSE(last.empty());
  EXPECT_NEAR(last.at<cv::Vec3b>(28, 60)[0], 29 * 8 % 256, 8);  // the last frame is frame 29
}

TEST_F(FileSources, BadSpecsAreOneLineErrorsNamingThePath) {
  try {
    OpenSource((dir_ / "nope.mp4").string());
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nope.mp4"), std::string::npos);
  }
  std::ofstream(dir_ / "text.mp4") << "hello";
  EXPECT_THROW(OpenSource((dir_ / "text.mp4").string()), Error);
  fs::create_directories(dir_ / "empty");
  EXPECT_THROW(OpenSource((dir_ / "empty").string()), Error);
}

}  // namespace
}  // namespace odvr::capture
