// DLT triangulation from bearings: exact without noise, a depth error that follows the noise
// and the baseline, and refusals for parallel rays, too few views and points behind cameras.
#include "tracking/triangulation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <iostream>
#include <random>

#include "core/error.h"

namespace odvr::tracking {
namespace {

CamFromWorld LookingFrom(const Eigen::Vector3d& center, double yaw) {
  CamFromWorld pose;
  pose.rotation = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix().transpose();
  pose.translation = -pose.rotation * center;
  return pose;
}

Eigen::Vector3d Bearing(const CamFromWorld& pose, const Eigen::Vector3d& x) { return (pose * x).normalized(); }

// A bearing perturbed by an angle of `sigma` radians per axis (tangent-plane Gaussian).
Eigen::Vector3d Perturbed(const Eigen::Vector3d& b, double sigma, std::mt19937* rng) {
  std::normal_distribution<double> g(0, sigma);
  const Eigen::Vector3d u = b.unitOrthogonal(), v = b.cross(u);
  return (b + g(*rng) * u + g(*rng) * v).normalized();
}

TEST(Triangulation, ExactBearingsGiveThePointForTwoToSixViews) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int views = 2; views <= 6; ++views) {
    for (int trial = 0; trial < 20; ++trial) {
      const Eigen::Vector3d x(5 * u(rng), 2 * u(rng), 10 + 5 * u(rng));
      std::vector<CamFromWorld> poses;
      std::vector<Eigen::Vector3d> bearings;
      for (int v = 0; v < views; ++v) {
        poses.push_back(LookingFrom(Eigen::Vector3d(0.5 * v, 0.1 * u(rng), 0.8 * v), 0.05 * u(rng)));
        bearings.push_back(Bearing(poses.back(), x));
      }
      TriangulatedPoint p;
      ASSERT_TRUE(TriangulateDlt(bearings, poses, &p));
      EXPECT_LT((p.point - x).norm(), 1e-9 * x.norm());
      EXPECT_LT(p.max_angular_error_rad, 1e-10);
      EXPECT_TRUE(p.in_front);
      EXPECT_GT(p.parallax_deg, 0.1);
    }
  }
  // Symmetric pair: the rays to (0.5, 0, 10) from x = 0 and x = 1 meet at 2 atan(0.05).
  std::vector<CamFromWorld> pair = {LookingFrom({0, 0, 0}, 0), LookingFrom({1, 0, 0}, 0.1)};
  const Eigen::Vector3d x(0.5, 0, 10);
  TriangulatedPoint p;
  ASSERT_TRUE(TriangulateDlt({Bearing(pair[0], x), Bearing(pair[1], x)}, pair, &p));
  EXPECT_NEAR(p.parallax_deg, 2 * std::atan(0.05) * 180 / M_PI, 1e-9);
}

TEST(Triangulation, WorksForBearingsBehindTheImagePlane) {
  // A 360-degree camera sees points behind it; no "z = 1" division may be hidden anywhere.
  const Eigen::Vector3d x(1, 0.5, -8);
  std::vector<CamFromWorld> poses = {LookingFrom({0, 0, 0}, 0), LookingFrom({1.5, 0, 0}, 0.3)};
  std::vector<Eigen::Vector3d> bearings = {Bearing(poses[0], x), Bearing(poses[1], x)};
  TriangulatedPoint p;
  ASSERT_TRUE(TriangulateDlt(bearings, poses, &p));
  EXPECT_LT((p.point - x).norm(), 1e-9);
  EXPECT_TRUE(p.in_front);
}

TEST(Triangulation, NoiseOfHalfAPixelGivesTheExpectedDepthError) {
  // street_a's fisheye: f = 229.18 px, so 0.5 px is 2.2 mrad. Two views 1 m apart, points 10 m
  // away: depth error ~ z^2 sigma / b = 100 * 0.0022 / 1 ~ 0.2 m per view's noise.
  const double sigma = 0.5 / 229.18;
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1, 1);
  double sum_sq = 0, angular_sum = 0;
  const int trials = 500;
  for (int trial = 0; trial < trials; ++trial) {
    const Eigen::Vector3d x(3 * u(rng), u(rng), 10);
    std::vector<CamFromWorld> poses = {LookingFrom({0, 0, 0}, 0), LookingFrom({1, 0, 0}, 0)};
    std::vector<Eigen::Vector3d> bearings = {Perturbed(Bearing(poses[0], x), sigma, &rng),
                                             Perturbed(Bearing(poses[1], x), sigma, &rng)};
    TriangulatedPoint p;
    ASSERT_TRUE(TriangulateDlt(bearings, poses, &p));
    sum_sq += (p.point - x).squaredNorm();
    angular_sum += p.max_angular_error_rad;
  }
  const double rms = std::sqrt(sum_sq / trials);
  std::cout << "0.5 px noise, 1 m baseline, 10 m depth: position RMS " << rms << " m, mean angular error "
            << angular_sum / trials / sigma << " sigma\n";
  // Two rays' noise across the baseline: sqrt(2) z^2 sigma / b = 0.31 m (first order).
  EXPECT_GT(rms, 0.15);
  EXPECT_LT(rms, 0.45);
  EXPECT_LT(angular_sum / trials, 2 * sigma);
}

TEST(Triangulation, RefusesParallelRaysAndBadInput) {
  const Eigen::Vector3d x(0, 0, 10);
  // Two cameras at the same centre: every depth fits.
  std::vector<CamFromWorld> same = {LookingFrom({0, 0, 0}, 0), LookingFrom({0, 0, 0}, 0.2)};
  TriangulatedPoint p;
  EXPECT_FALSE(TriangulateDlt({Bearing(same[0], x), Bearing(same[1], x)}, same, &p));
  // Parallel rays from distinct centres: the point is at infinity.
  std::vector<CamFromWorld> apart = {LookingFrom({0, 0, 0}, 0), LookingFrom({1, 0, 0}, 0)};
  EXPECT_FALSE(TriangulateDlt({Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, 1)}, apart, &p));
  // A point behind both cameras along negated bearings triangulates but is flagged.
  const Eigen::Vector3d y(0.3, 0.1, 6);
  ASSERT_TRUE(TriangulateDlt({-Bearing(apart[0], y), -Bearing(apart[1], y)}, apart, &p));
  EXPECT_FALSE(p.in_front);
  try {
    TriangulateDlt({Eigen::Vector3d(0, 0, 1)}, {apart[0]}, &p);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "triangulation: needs at least 2 views, got 1");
  }
  EXPECT_THROW(TriangulateDlt({Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, 1)}, {apart[0]}, &p), Error);
}

}  // namespace
}  // namespace odvr::tracking
