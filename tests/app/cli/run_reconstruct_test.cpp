// `odvr reconstruct` run as a user would on street_a: outputs, their schema and the trajectory's
// error against the ground truth; bad input ends in one clear line and a non-zero exit.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::CliRun;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;

namespace fs = std::filesystem;
const fs::path kStreet = fs::path(ODVR_SHARED_DIR) / "data/street_a";

int DataLines(const fs::path& p) {
  std::ifstream in(p);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) n += !line.empty() && line[0] != '#';
  return n;
}

TEST(RunReconstruct, StreetSixFramesWritesEveryOutputAndMeetsTheTargets) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent";
  const ScratchDir t{"odvr_run_reconstruct"};
  const fs::path out = t.dir / "rec";
  const CliRun r = RunOdvr("reconstruct --rig " + (kStreet / "rig.json").string() + " --images " +
                           (kStreet / "rig").string() + " --first 2 --frames 6 --out " + out.string() +
                           " --ground-truth " + (kStreet / "trajectory_gt.json").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << "--json must keep stderr quiet: " << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames"].get<int>(), 6);
  EXPECT_EQ(j["first_index"].get<int>(), 2);
  EXPECT_LT(j["reprojection_rmse_px"].get<double>(), 1.0);
  const auto& e = j["evaluation"];
  std::cout << e.dump() << "\n";
  EXPECT_EQ(e["matched_frames"].get<int>(), 6);
  EXPECT_LT(e["ate_percent_of_path"].get<double>(), 1.0);
  EXPECT_LT(e["scale_error_percent"].get<double>(), 3.0);
  ASSERT_GE(j["stages"].size(), 5u);
  for (const auto& s : j["stages"]) EXPECT_GE(s["seconds"].get<double>(), 0) << s.dump();

  for (const char* f : {"trajectory.json", "trajectory.tum", "cameras.txt", "images.txt", "points3D.txt",
                        "road_plane.json", "summary.json"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  std::ifstream tj(out / "trajectory.json");
  const auto traj = nlohmann::json::parse(tj);
  ASSERT_EQ(traj["frames"].size(), 6u);
  EXPECT_EQ(traj["frames"][0]["index"].get<int>(), 2);
  EXPECT_NEAR(traj["frames"][0]["timestamp"].get<double>(), 0.08, 1e-9);
  EXPECT_EQ(traj["frames"][0]["world_from_rig"].size(), 4u);
  // The world's road is z = 0, so the rig stands at its height; Y-up has it in y.
  EXPECT_NEAR(traj["frames"][0]["world_from_rig"][2][3].get<double>(), 2.0647, 0.05);
  EXPECT_NEAR(traj["frames"][0]["world_yup_from_rig"][1][3].get<double>(), 2.0647, 0.05);
  EXPECT_EQ(DataLines(out / "trajectory.tum"), 6);
  EXPECT_EQ(DataLines(out / "cameras.txt"), 6);
  EXPECT_EQ(DataLines(out / "images.txt"), 2 * 36);
  EXPECT_GT(DataLines(out / "points3D.txt"), 500);
  std::ifstream cams(out / "cameras.txt");
  std::stringstream text;
  text << cams.rdbuf();
  EXPECT_NE(text.str().find("1 OPENCV_FISHEYE 480 640 229.18"), std::string::npos) << text.str();
  std::ifstream sj(out / "summary.json");
  EXPECT_TRUE(nlohmann::json::parse(sj).contains("evaluation"));
}

TEST(RunReconstruct, NoTrifocalSkipsTheCheck) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent";
  const ScratchDir t{"odvr_run_reconstruct_no_trifocal"};
  const CliRun r =
      RunOdvr("reconstruct --rig " + (kStreet / "rig.json").string() + " --images " + (kStreet / "rig").string() +
              " --frames 3 --no-trifocal --json --out " + (t.dir / "rec").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_FALSE(j["trifocal"]["enabled"].get<bool>());
  EXPECT_EQ(j["trifocal"]["track_triples_tested"].get<long>(), 0);
  EXPECT_EQ(j["trifocal"]["observations_after"], j["trifocal"]["observations_before"]);
  for (const auto& s : j["stages"]) EXPECT_NE(s["name"], "trifocal");
  EXPECT_EQ(j["frames"].get<int>(), 3);
}

TEST(RunReconstruct, TooFewFramesIsAUsageError) {
  const CliRun r = RunOdvr("reconstruct --rig " + (kStreet / "rig.json").string() + " --frames 2");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--frames: structure from motion needs at least 3 frames"), std::string::npos) << r.err;
  const CliRun words = RunOdvr("reconstruct --rig " + (kStreet / "rig.json").string() + " --frames six");
  EXPECT_EQ(words.exit_code, 2);
  EXPECT_NE(words.err.find("(a folder is --images)"), std::string::npos) << words.err;
}

TEST(RunReconstruct, CameraCountMismatchNamesBothSides) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent";
  const CliRun r = RunOdvr("reconstruct --rig " + (kStreet / "rig.json").string() + " --images " +
                           (kStreet / "rig/cam0").string() + " --count 3");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("delivers 1 cameras but the rig file"), std::string::npos) << r.err;
}

// One 360° camera and no rig: the demo's equirect clip (in the repository) from the command line
// to a trajectory that play reads back as TUM, with a COLMAP model of six cube faces.
TEST(RunReconstructGL, OneCameraClipToTumTrajectoryThatPlayReads) {
  const fs::path demo = fs::path(ODVR_SOURCE_DIR) / "media/demo";
  const ScratchDir t{"odvr_run_reconstruct_video"};
  const fs::path out = t.dir / "rec";
  const CliRun r =
      RunOdvr("reconstruct --video " + (demo / "street.mp4").string() + " --camera-height 2.027356 --out " +
              out.string() + " --ground-truth " + (demo / "trajectory_gt.json").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  std::printf("demo clip, one camera: ATE %.3f %% of the path, scale error %.2f %%, %d points\n",
              j["evaluation"]["ate_percent_of_path"].get<double>(),
              j["evaluation"]["scale_error_percent"].get<double>(), j["points"].get<int>());
  EXPECT_EQ(j["frames"].get<int>(), 24) << "every frame posed";
  EXPECT_EQ(j["key_frames"].get<int>(), 24) << "a car at 9 m/s: every frame adds parallax";
  EXPECT_EQ(j["interpolated_frames"].get<int>(), 0);
  EXPECT_GT(j["peak_memory_mb"].get<double>(), 0);
  EXPECT_EQ(j["input"]["layout"], "mono");
  EXPECT_TRUE(j["input"]["metric"].get<bool>());
  EXPECT_LT(j["evaluation"]["ate_percent_of_path"].get<double>(), 0.5);
  EXPECT_LT(j["evaluation"]["scale_error_percent"].get<double>(), 5);
  EXPECT_EQ(DataLines(out / "trajectory.tum"), 24);
  EXPECT_EQ(DataLines(out / "cameras.txt"), 6) << "the equirect camera as six cube faces";
  EXPECT_EQ(DataLines(out / "images.txt"), 24 * 6 * 2);

  const CliRun play =
      RunOdvr("play --headless --size 64x36 --frames 2 --trajectory " + (out / "trajectory.tum").string() + " --car " +
              (demo / "car.glb").string() + " --levels 3 --voxels 64 --out " + (t.dir / "frames").string() +
              " --json " + (demo / "street.mp4").string());
  ASSERT_EQ(play.exit_code, 0) << play.err;
  const auto pj = nlohmann::json::parse(play.out);
  EXPECT_GT(pj["frames"][0]["car_pixels"].get<int>(), 10) << "the car stands in the reconstructed scene";
}

TEST(RunReconstruct, OneCameraNeedsAClipAndRefusesRigOptions) {
  const CliRun none = RunOdvr("reconstruct --camera-height 1.5");
  EXPECT_EQ(none.exit_code, 2);
  EXPECT_NE(none.err.find("--video"), std::string::npos) << none.err;
  const CliRun chunks = RunOdvr("reconstruct --video x.mp4 --chunk-frames 10");
  EXPECT_EQ(chunks.exit_code, 2);
  EXPECT_NE(chunks.err.find("--chunk-frames: must be 0 (the clip in one piece) or at least 80"), std::string::npos)
      << chunks.err;
  const CliRun mixed = RunOdvr("reconstruct --rig x.json --camera-height 1.5");
  EXPECT_EQ(mixed.exit_code, 2);
  EXPECT_NE(mixed.err.find("--rig-height"), std::string::npos) << mixed.err;
  // A folder given to --frames, as before --images named it: still read, with a warning.
  const CliRun multi = RunOdvr("reconstruct --frames " + (fs::path(ODVR_SOURCE_DIR) / "media/demo/rig").string());
  EXPECT_EQ(multi.exit_code, 2);
  EXPECT_NE(multi.err.find("read as --images"), std::string::npos) << multi.err;
  EXPECT_NE(multi.err.find("holds 6 cameras: a multi-camera recording needs its --rig"), std::string::npos)
      << multi.err;
}

}  // namespace
