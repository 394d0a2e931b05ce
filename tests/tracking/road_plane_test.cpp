// Metric scale from a synthetic road: points on the road, kerbs, facades and noise, reconstructed
// in an arbitrary unit; the fitted plane must give back the unit.
#include "tracking/road_plane.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <iostream>
#include <random>

namespace odvr::tracking {
namespace {

constexpr double kHeight = 2.064687;

// A street in metres, then expressed in a world `units_per_metre` times larger, tilted and moved
// (a reconstruction's own frame).
struct Street {
  std::vector<Eigen::Vector3d> points;
  std::vector<Rigid3> poses;
};

Street MakeStreet(double units_per_metre, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> g(0, 1);
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.4).normalized()).toRotationMatrix();
  const Eigen::Vector3d shift(3, -1, 7);
  auto to_world = [&](const Eigen::Vector3d& m) {
    Eigen::Vector3d w = tilt * m;
    return (units_per_metre * w + shift).eval();
  };
  Street s;
  for (int f = 0; f < 10; ++f) {
    Rigid3 p;
    p.rotation = tilt * Eigen::AngleAxisd(0.01 * g(rng), Eigen::Vector3d::UnitY()).toRotationMatrix();
    p.translation = to_world(Eigen::Vector3d(0.5 * f, 0.05 * g(rng), kHeight));
    s.poses.push_back(p);
  }
  for (int i = 0; i < 400; ++i)  // road, 1 cm noise
    s.points.push_back(to_world(Eigen::Vector3d(-6 + 17 * u(rng), -3.5 + 7 * u(rng), 0.01 * g(rng))));
  for (int i = 0; i < 150; ++i)  // sidewalks 15 cm up
    s.points.push_back(to_world(Eigen::Vector3d(-6 + 17 * u(rng), (i % 2 ? 1 : -1) * (3.6 + 2 * u(rng)), 0.15)));
  for (int i = 0; i < 300; ++i)  // facades
    s.points.push_back(to_world(Eigen::Vector3d(-6 + 17 * u(rng), (i % 2 ? 1 : -1) * 6, 10 * u(rng))));
  for (int i = 0; i < 100; ++i)  // mismatches anywhere below the rig
    s.points.push_back(to_world(Eigen::Vector3d(-6 + 17 * u(rng), -6 + 12 * u(rng), 2 * u(rng) - 1)));
  return s;
}

TEST(RoadPlane, GivesTheScaleThatPutsTheRigAtItsHeight) {
  for (double units : {0.37, 1.0, 4.2}) {
    const Street s = MakeStreet(units, 4);
    const RoadPlane plane = FitRoadPlane(s.points, s.poses, kHeight);
    std::cout << units << " units/m: " << plane.message << ", scale " << plane.scale << ", rms "
              << plane.rms_distance / units << " m\n";
    ASSERT_TRUE(plane.found) << plane.message;
    EXPECT_NEAR(plane.scale * units, 1.0, 0.004);
    EXPECT_NEAR(plane.rig_height / units, kHeight, 0.008);
    EXPECT_LT(plane.rms_distance / units, 0.02);
    EXPECT_GE(plane.inliers, 120);  // the road within the lane corridor below the rig
    // The normal points up the street's own z axis, towards the rig.
    EXPECT_GT(plane.Distance(s.poses[0].translation), 0);
    EXPECT_GT(plane.normal.dot(s.poses[0].rotation.col(2)), 0.999);
  }
}

TEST(RoadPlane, SaysWhyWhenNothingLiesBelowTheRig) {
  Street s = MakeStreet(1.0, 2);
  std::vector<Eigen::Vector3d> above;
  for (const auto& x : s.points)
    if ((s.poses[0].Inverse() * x).z() > 0) above.push_back(x);
  const RoadPlane plane = FitRoadPlane(above, s.poses, kHeight);
  EXPECT_FALSE(plane.found);
  EXPECT_EQ(plane.scale, 0);
  EXPECT_NE(plane.message.find("below the rig"), std::string::npos) << plane.message;
  EXPECT_FALSE(FitRoadPlane(s.points, {}, kHeight).found);
}

}  // namespace
}  // namespace odvr::tracking
