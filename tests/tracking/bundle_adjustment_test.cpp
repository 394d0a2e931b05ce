// Rig bundle adjustment on a synthetic street: six cameras as street_a's rig, a rig driving
// forward past facades and over a road, bearings with pixel noise; perturbed poses and points
// must come back to the truth, and the problem's gauge and inputs are checked.
#include "tracking/bundle_adjustment.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <iostream>
#include <random>

#include "core/error.h"

namespace odvr::tracking {
namespace {

// street_a's rig: camera c looks at yaw 60 c degrees, 8 cm out from the centre, upright.
RigGeometry StreetRig() {
  RigGeometry rig;
  for (int c = 0; c < 6; ++c) {
    const double yaw = c * M_PI / 3;
    const Eigen::Vector3d forward(std::cos(yaw), std::sin(yaw), 0);
    const Eigen::Vector3d right(std::sin(yaw), -std::cos(yaw), 0);
    Rigid3 p;
    p.rotation.col(0) = right;                      // camera x: right
    p.rotation.col(1) = Eigen::Vector3d(0, 0, -1);  // camera y: down
    p.rotation.col(2) = forward;                    // camera z: optical axis
    p.translation = 0.08 * forward;
    rig.rig_from_cam.push_back(p);
    rig.focal_px.push_back(229.18);
  }
  return rig;
}

Rigid3 RigPose(double x, double yaw, double height) {
  Rigid3 p;
  p.rotation = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.translation = Eigen::Vector3d(x, 0.1 * std::sin(x), height);
  return p;
}

// The observation of `x` by camera c of `pose`, if that camera sees it within 95 degrees of its axis.
bool Observe(const RigGeometry& rig, const Rigid3& pose, int c, const Eigen::Vector3d& x, double noise_px,
             std::mt19937* rng, Eigen::Vector3d* bearing) {
  const Eigen::Vector3d in_cam = rig.rig_from_cam[c].Inverse() * (pose.Inverse() * x);
  const Eigen::Vector3d b = in_cam.normalized();
  if (b.z() < std::cos(95 * M_PI / 180) || in_cam.norm() > 40) return false;
  std::normal_distribution<double> g(0, noise_px / rig.focal_px[c]);
  const Eigen::Vector3d u = b.unitOrthogonal(), v = b.cross(u);
  *bearing = (b + g(*rng) * u + g(*rng) * v).normalized();
  return true;
}

struct Scene {
  BundleAdjustmentProblem problem;
  std::vector<Rigid3> true_poses;
  std::vector<Eigen::Vector3d> true_points;
};

Scene MakeScene(int frames, double noise_px, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Scene s;
  s.problem.rig = StreetRig();
  for (int f = 0; f < frames; ++f) s.true_poses.push_back(RigPose(0.5 * f, 0.02 * std::sin(f), 2.06));
  for (int i = 0; i < 600; ++i) {
    const double x = -10 + 0.5 * frames + 20 * u(rng);
    const int kind = i % 3;
    if (kind == 0) s.true_points.emplace_back(x, -7 + 14 * u(rng), 0);            // road
    if (kind == 1) s.true_points.emplace_back(x, 6 + 0.2 * u(rng), 8 * u(rng));   // left facade
    if (kind == 2) s.true_points.emplace_back(x, -6 - 0.2 * u(rng), 8 * u(rng));  // right facade
  }
  std::vector<char> seen(s.true_points.size(), 0);
  for (int i = 0; i < static_cast<int>(s.true_points.size()); ++i)
    for (int f = 0; f < frames; ++f)
      for (int c = 0; c < 6; ++c) {
        Eigen::Vector3d b;
        if (!Observe(s.problem.rig, s.true_poses[f], c, s.true_points[i], noise_px, &rng, &b)) continue;
        s.problem.observations.push_back({f, c, i, b});
      }
  s.problem.world_from_rig = s.true_poses;
  s.problem.points = s.true_points;
  s.problem.pose_constant.assign(frames, 0);
  s.problem.pose_constant[0] = 1;
  return s;
}

TEST(BundleAdjustment, RecoversPerturbedRigPosesAndPoints) {
  Scene s = MakeScene(8, 0.5, 3);
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0, 1);
  for (size_t f = 1; f < s.problem.world_from_rig.size(); ++f) {
    Rigid3& p = s.problem.world_from_rig[f];
    p.rotation = Eigen::AngleAxisd(0.01 * g(rng), Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized()) * p.rotation;
    p.translation += 0.05 * Eigen::Vector3d(g(rng), g(rng), g(rng));
  }
  for (auto& x : s.problem.points) x += 0.05 * x.norm() / 10 * Eigen::Vector3d(g(rng), g(rng), g(rng));
  std::vector<std::string> lines;
  BundleAdjustmentOptions options;
  options.progress = [&](const std::string& line) { lines.push_back(line); };
  const BundleAdjustmentReport report = AdjustBundle(options, &s.problem);
  std::cout << s.problem.observations.size() << " observations; " << report.message << "\nRMSE "
            << report.initial_rmse_px << " -> " << report.final_rmse_px << " px in " << report.seconds << " s\n";
  ASSERT_TRUE(report.converged);
  EXPECT_EQ(static_cast<int>(lines.size()), report.iterations);
  EXPECT_NE(lines.front().find("bundle adjustment iter"), std::string::npos);
  EXPECT_GT(report.initial_rmse_px, 3.0);
  // 0.5 px noise per axis: the RMS of the 2D residual after the fit is about 0.5 sqrt(2) * (1 - dof/n).
  EXPECT_LT(report.final_rmse_px, 0.75);
  EXPECT_GT(report.final_rmse_px, 0.5);
  double max_pos = 0, max_rot = 0;
  for (size_t f = 0; f < s.true_poses.size(); ++f) {
    max_pos = std::max(max_pos, (s.problem.world_from_rig[f].translation - s.true_poses[f].translation).norm());
    max_rot = std::max(
        max_rot,
        Eigen::AngleAxisd(s.problem.world_from_rig[f].rotation.transpose() * s.true_poses[f].rotation).angle() * 180 /
            M_PI);
  }
  std::cout << "max pose error " << max_pos * 1000 << " mm, " << max_rot << " deg\n";
  // The first pose is the gauge and stays exact; the scale rests on the 8 cm camera offsets
  // only, which is what limits the positions.
  EXPECT_EQ((s.problem.world_from_rig[0].translation - s.true_poses[0].translation).norm(), 0.0);
  EXPECT_LT(max_pos, 0.03);
  EXPECT_LT(max_rot, 0.05);
}

TEST(BundleAdjustment, RobustLossKeepsOutliersFromDraggingThePoses) {
  Scene s = MakeScene(6, 0.3, 5);
  std::mt19937 rng(2);
  std::uniform_int_distribution<size_t> pick(0, s.problem.observations.size() - 1);
  for (int i = 0; i < static_cast<int>(s.problem.observations.size()) / 10; ++i) {
    auto& o = s.problem.observations[pick(rng)];
    o.bearing = (o.bearing + Eigen::Vector3d(0.05, -0.04, 0.03)).normalized();  // ~15 px off
  }
  for (size_t f = 1; f < s.problem.world_from_rig.size(); ++f) s.problem.world_from_rig[f].translation.x() += 0.03;
  const BundleAdjustmentReport report = AdjustBundle(BundleAdjustmentOptions(), &s.problem);
  ASSERT_TRUE(report.converged);
  double max_pos = 0;
  for (size_t f = 0; f < s.true_poses.size(); ++f)
    max_pos = std::max(max_pos, (s.problem.world_from_rig[f].translation - s.true_poses[f].translation).norm());
  std::cout << "10 % outliers: max pose error " << max_pos * 1000 << " mm\n";
  EXPECT_LT(max_pos, 0.03);
}

TEST(BundleAdjustment, RejectsAFloatingGaugeAndBadIndices) {
  Scene s = MakeScene(3, 0.5, 1);
  s.problem.pose_constant.assign(3, 0);
  EXPECT_THROW(AdjustBundle(BundleAdjustmentOptions(), &s.problem), Error);
  s.problem.pose_constant[0] = 1;
  s.problem.observations.push_back({7, 0, 0, Eigen::Vector3d::UnitZ()});
  try {
    AdjustBundle(BundleAdjustmentOptions(), &s.problem);
    FAIL() << "no error for frame 7 of 3";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("out of range"), std::string::npos) << e.what();
  }
  BundleAdjustmentOptions bad;
  bad.loss_scale_px = 0;
  EXPECT_THROW(bad.Check(), Error);
}

}  // namespace
}  // namespace odvr::tracking
