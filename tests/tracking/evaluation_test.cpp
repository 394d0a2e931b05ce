// Trajectory errors: Umeyama recovers a known similarity, ATE follows added noise, the scale
// error of a stretched trajectory is what was applied, and bad trajectory files are named.
#include "tracking/evaluation.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>

#include "core/error.h"

namespace odvr::tracking {
namespace {

namespace fs = std::filesystem;
const fs::path kTruth = fs::path(ODVR_SHARED_DIR) / "data/street_a/trajectory_gt.json";

std::vector<TrajectoryPose> Transformed(const std::vector<TrajectoryPose>& in, const Similarity3& s) {
  std::vector<TrajectoryPose> out = in;
  for (auto& p : out) {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = s.rotation * p.world_from_rig.topLeftCorner<3, 3>();
    m.topRightCorner<3, 1>() = s.scale * s.rotation * p.world_from_rig.topRightCorner<3, 1>() + s.translation;
    p.world_from_rig = m;
  }
  return out;
}

TEST(Evaluation, UmeyamaRecoversASimilarity) {
  std::mt19937 rng(1);
  std::normal_distribution<double> g(0, 3);
  std::vector<Eigen::Vector3d> src, dst;
  Similarity3 truth;
  truth.scale = 0.37;
  truth.rotation = Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  truth.translation = Eigen::Vector3d(4, -2, 9);
  for (int i = 0; i < 20; ++i) {
    src.emplace_back(g(rng), g(rng), g(rng));
    dst.push_back(truth.scale * truth.rotation * src.back() + truth.translation);
  }
  const Similarity3 s = AlignUmeyama(src, dst, true);
  EXPECT_NEAR(s.scale, 0.37, 1e-12);
  EXPECT_LT((s.rotation - truth.rotation).norm(), 1e-12);
  EXPECT_LT((s.translation - truth.translation).norm(), 1e-11);
  EXPECT_THROW(AlignUmeyama({src[0], src[1]}, {dst[0], dst[1]}, true), Error);
}

TEST(Evaluation, StreetTruthAgainstAStretchedNoisyCopy) {
  if (!fs::exists(kTruth)) GTEST_SKIP() << kTruth << " absent";
  const auto truth = LoadTrajectoryJson(kTruth);
  ASSERT_EQ(truth.size(), 40u);
  // Identity: all errors zero.
  const TrajectoryErrors zero = EvaluateTrajectory(truth, truth);
  EXPECT_EQ(zero.matched, 40);
  EXPECT_NEAR(zero.length_m, 19.4, 0.3);
  EXPECT_LT(zero.ate_rmse_m, 1e-9);
  EXPECT_NEAR(zero.scale, 1, 1e-9);
  // Stretched by 2 %, turned and moved: ATE ~0 after the similarity, scale error 2 %, and the
  // rigid-only ATE shows the stretch.
  Similarity3 s;
  s.scale = 1.02;
  s.rotation = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  s.translation = Eigen::Vector3d(-25, 3, 0);
  const TrajectoryErrors stretched = EvaluateTrajectory(Transformed(truth, s), truth);
  std::cout << stretched.Summary() << "\n";
  EXPECT_LT(stretched.ate_rmse_m, 1e-9);
  EXPECT_NEAR(stretched.scale, 1.02, 1e-9);
  EXPECT_NEAR(stretched.scale_error, 0.02, 1e-9);
  EXPECT_GT(stretched.ate_rigid_rmse_m, 0.05);
  EXPECT_NEAR(stretched.rpe_translation_rmse_m, 0.02 * 0.497, 0.002);  // 2 % of a ~0.5 m step
  EXPECT_LT(stretched.rpe_rotation_rmse_deg, 1e-6);
  // 5 cm of position noise per axis: ATE ~ 5 sqrt(3) cm, a little less after the fit absorbs some.
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0, 0.05);
  auto noisy = truth;
  for (auto& p : noisy) p.world_from_rig.topRightCorner<3, 1>() += Eigen::Vector3d(g(rng), g(rng), g(rng));
  const TrajectoryErrors e = EvaluateTrajectory(noisy, truth);
  std::cout << e.Summary() << "\n";
  EXPECT_NEAR(e.ate_rmse_m, 0.05 * std::sqrt(3.0), 0.025);
  EXPECT_NEAR(e.ate_percent, 100 * e.ate_rmse_m / e.length_m, 1e-9);
}

// TUM, as odvr reconstruct writes it and other tools do: frames named by timestamp x fps, the
// same poses as the JSON it was written beside, and each malformed line named.
TEST(Evaluation, TumTrajectoriesReadBackAsTheirFramesAndNameTheirBadLines) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_evaluation_tum_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path demo = fs::path(ODVR_SOURCE_DIR) / "media/demo";
  const auto json = LoadTrajectoryJson(demo / "trajectory_gt.json");
  const auto tum = LoadTrajectory(demo / "trajectory_gt.tum", 25);
  ASSERT_EQ(tum.size(), json.size());
  for (size_t i = 0; i < tum.size(); ++i) {
    EXPECT_EQ(tum[i].index, json[i].index);
    EXPECT_LT((tum[i].world_from_rig - json[i].world_from_rig).norm(), 1e-5) << "frame " << i;
  }
  auto expect_error = [&](const std::string& text, const std::string& needle) {
    const fs::path p = dir / "t.tum";
    std::ofstream(p) << text;
    try {
      LoadTrajectory(p, 25);
      ADD_FAILURE() << "no error for " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error("# only a comment\n", "holds no pose");
  expect_error("0 1 2 3 0 0 0\n", "line 1: expected 8 numbers");
  expect_error("# header\n0 1 2 3 0 0 0 1 9\n", "line 2: more than 8 fields");
  expect_error("0 1 2 3 0 0 0 2\n", "line 1: the quaternion is not of unit length");
  expect_error("0 nan 2 3 0 0 0 1\n", "line 1");
  expect_error("1e300 0 0 0 0 0 0 1\n", "out of range");
  expect_error("0 0 0 0 0 0 0 1\n0.01 0 0 0 0 0 0 1\n", "line 2: a second pose for frame 0");
  EXPECT_THROW(LoadTrajectoryTum(demo / "trajectory_gt.tum", 0), Error);
  fs::remove_all(dir);
}

TEST(Evaluation, NamesTheFileAndTheProblem) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_evaluation_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  auto expect_error = [&](const std::string& text, const std::string& needle) {
    const fs::path p = dir / "t.json";
    std::ofstream(p) << text;
    try {
      LoadTrajectoryJson(p);
      ADD_FAILURE() << "no error for " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error("{", "not valid JSON");
  expect_error("{\"frames\": [{\"index\": 0}]}", "world_from_rig");
  expect_error("{\"frames\": [{\"index\": 0, \"world_from_rig\": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]}",
               "not a rigid transform");
  const std::string id = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
  expect_error(
      "{\"frames\": [{\"index\": 3, \"world_from_rig\": " + id + "}, {\"index\": 3, \"world_from_rig\": " + id + "}]}",
      "repeats");
  EXPECT_THROW(LoadTrajectoryJson(dir / "absent.json"), Error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace odvr::tracking
