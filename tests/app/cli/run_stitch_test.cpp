// `odvr stitch` run as a user would, on two frames of ../shared/data/street_a.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::CliRun;
using odvr::testing::Lines;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;

namespace fs = std::filesystem;
const fs::path kStreet = fs::path(ODVR_SHARED_DIR) / "data/street_a";

TEST(RunStitch, StitchesTwoStreetFramesToPngOnTheCpu) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const ScratchDir t{"odvr_run_stitch"};
  const fs::path out = t.dir / "pano";
  const CliRun r = RunOdvr("stitch --rig " + (kStreet / "rig.json").string() + " --in " + (kStreet / "rig").string() +
                           " --out " + out.string() + " --format png --size 512x256 --device cpu --frames 2 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames"].get<int>(), 2);
  ASSERT_EQ(j["per_frame"].size(), 2u);
  for (const auto& f : j["per_frame"]) {
    EXPECT_GT(f["ms"].get<double>(), 0);
    EXPECT_GT(f["valid_fraction"].get<double>(), 0.85);
    EXPECT_EQ(f["gains"].size(), 6u);
  }
  for (const char* name : {"000000.png", "000001.png"}) {
    const cv::Mat img = cv::imread((out / name).string());
    ASSERT_FALSE(img.empty()) << name;
    EXPECT_EQ(img.cols, 512);
    EXPECT_EQ(img.rows, 256);
    EXPECT_GT(cv::mean(img)[1], 20);  // an image, not black
  }
  EXPECT_FALSE(fs::exists(out / "000002.png"));
  // By default the scene distance is chosen from the frames (both of them), every candidate
  // scored; street_a's facades stand 5 to 15 m away.
  const auto& d = j["scene_distance"];
  EXPECT_EQ(d["mode"], "auto");
  EXPECT_EQ(d["frame_sets"].get<int>(), 2);
  EXPECT_GE(d["metres"].get<double>(), 5) << d.dump();
  EXPECT_LE(d["metres"].get<double>(), 20) << d.dump();
  EXPECT_EQ(d["reason"], "");
  EXPECT_EQ(d["candidates"].size(), 8u);
  for (const auto& c : d["candidates"]) EXPECT_GT(c["seam_rms"].get<double>(), 0) << d.dump();
}

TEST(RunStitch, AGivenSceneDistanceIsKept) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const ScratchDir t{"odvr_run_stitch"};
  const CliRun r = RunOdvr("stitch --rig " + (kStreet / "rig.json").string() + " --out " + (t.dir / "p").string() +
                           " --format png --size 256x128 --device cpu --frames 1 --scene-distance 0 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["scene_distance"]["mode"], "given");
  EXPECT_EQ(j["scene_distance"]["metres"].get<double>(), 0);
  EXPECT_FALSE(j["scene_distance"].contains("candidates"));
}

TEST(RunStitch, WritesAnMp4FromTheRigFilesOwnImageFolders) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const ScratchDir t{"odvr_run_stitch"};
  const fs::path out = t.dir / "street.mp4";
  // No --in: the rig file's image_dir entries name the camera folders.
  const CliRun r = RunOdvr("stitch --rig " + (kStreet / "rig.json").string() + " --out " + out.string() +
                           " --size 256x128 --device cpu --frames 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("stitched 2 frames"), std::string::npos) << r.out;
  EXPECT_GT(fs::file_size(out), 1000u);
}

TEST(RunStitch, BadInputsEndInOneLine) {
  const ScratchDir t{"odvr_run_stitch"};
  const CliRun no_rig = RunOdvr("stitch --rig " + (t.dir / "missing.json").string() + " --in . --out " +
                                (t.dir / "o").string() + " --device cpu");
  EXPECT_EQ(no_rig.exit_code, 1);
  EXPECT_NE(no_rig.err.find("missing.json"), std::string::npos) << no_rig.err;
  EXPECT_EQ(std::count(no_rig.err.begin(), no_rig.err.end(), '\n'), 1) << no_rig.err;

  const CliRun bad_size = RunOdvr("stitch --rig x.json --out o --size 12by3");
  EXPECT_EQ(bad_size.exit_code, 2);
  EXPECT_NE(bad_size.err.find("--size"), std::string::npos) << bad_size.err;

  // 0 stands for "all" inside the command: given, it is a usage error, not every frame.
  const CliRun no_frames = RunOdvr("stitch --rig x.json --out o --frames 0");
  EXPECT_EQ(no_frames.exit_code, 2);
  EXPECT_NE(no_frames.err.find("--frames"), std::string::npos) << no_frames.err;

  const CliRun bad_distance = RunOdvr("stitch --rig x.json --out o --scene-distance far");
  EXPECT_EQ(bad_distance.exit_code, 2);
  EXPECT_NE(bad_distance.err.find("--scene-distance"), std::string::npos) << bad_distance.err;
  EXPECT_NE(bad_distance.err.find("'far'"), std::string::npos) << bad_distance.err;

  if (!fs::exists(kStreet / "rig.json")) return;
  // Five camera folders for a six-camera rig.
  for (int c = 0; c < 5; ++c)
    fs::create_directory_symlink(kStreet / "rig" / ("cam" + std::to_string(c)), t.dir / ("cam" + std::to_string(c)));
  const CliRun five = RunOdvr("stitch --rig " + (kStreet / "rig.json").string() + " --in " + t.dir.string() +
                              " --out " + (t.dir / "o").string() + " --device cpu --frames 1");
  EXPECT_EQ(five.exit_code, 1);
  EXPECT_NE(five.err.find("delivers 5 cameras"), std::string::npos) << five.err;
}

}  // namespace
