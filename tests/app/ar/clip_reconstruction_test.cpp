// The cache key of a clip's reconstruction (app/ar/clip_reconstruction.h): the same clip, options
// and program find the same poses; a different program (a rebuilt or upgraded odvr), a rewritten
// clip or another option does not reuse them.
#include "app/ar/clip_reconstruction.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

namespace odvr::app {
namespace {

namespace fs = std::filesystem;

class ClipReconstruction : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("odvr_clip_key_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "clip.mp4") << "a clip";
    std::ofstream(dir_ / "odvr_a") << "one build";
    std::ofstream(dir_ / "odvr_b") << "another build";
    in_.clip = (dir_ / "clip.mp4").string();
  }
  void TearDown() override { fs::remove_all(dir_); }
  // Moves a file's time on by a second, as a rebuild or a rewrite would.
  void Touch(const fs::path& p) { fs::last_write_time(p, fs::last_write_time(p) + std::chrono::seconds(1)); }

  fs::path dir_;
  ClipInput in_;
};

TEST_F(ClipReconstruction, TheKeyChangesWithTheProgramTheClipAndTheOptions) {
  const std::string key = ClipCacheKey(in_, dir_ / "odvr_a");
  EXPECT_EQ(key.size(), 16u);
  EXPECT_EQ(ClipCacheKey(in_, dir_ / "odvr_a"), key);  // the same run again: the cache is found
  EXPECT_NE(ClipCacheKey(in_, dir_ / "odvr_b"), key);  // another program

  Touch(dir_ / "odvr_a");  // the same program file, rebuilt
  const std::string rebuilt = ClipCacheKey(in_, dir_ / "odvr_a");
  EXPECT_NE(rebuilt, key);

  Touch(dir_ / "clip.mp4");  // the clip rewritten
  const std::string rewritten = ClipCacheKey(in_, dir_ / "odvr_a");
  EXPECT_NE(rewritten, rebuilt);

  ClipInput higher = in_;
  higher.camera_height_m = 1.6;
  EXPECT_NE(ClipCacheKey(higher, dir_ / "odvr_a"), rewritten);
}

}  // namespace
}  // namespace odvr::app
