// The central estimators on synthetic bearings over the whole sphere (a 360° camera): minimal and
// least-squares solutions against the true motion, through RANSAC with outliers, and the rig
// estimators' degeneracy on the same data, which is why the central ones exist.
#include "tracking/central_pose.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "tracking/ransac.h"

namespace odvr::tracking {
namespace {

constexpr double kFocal = 163;  // a 1024-wide equirect: pixels per radian

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180 / M_PI;
}

double RotationErrorDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() * 180 / M_PI;
}

// One equirect camera whose OpenCV axes sit in the rig frame as EquirectCameraRig puts them.
RigGeometry OneCamera() {
  RigGeometry g;
  Rigid3 c;
  c.rotation << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  g.rig_from_cam.push_back(c);
  g.focal_px.push_back(kFocal);
  return g;
}

struct Scene {
  Rigid3 rig1_from_rig2;
  std::vector<Eigen::Vector3d> points;  // in rig 1
  std::vector<RigBearingPair> pairs;
};

// Points 3-30 m away in every direction; rig 2 moved 0.5 m and turned 7 degrees. `noise_deg`
// perturbs each bearing; the first `outliers` pairs get a random second bearing.
Scene MakeScene(const RigGeometry& g, int n, double noise_deg, int outliers, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0, 1);
  std::uniform_real_distribution<double> depth(3, 30);
  Scene s;
  s.rig1_from_rig2.rotation = Eigen::AngleAxisd(7 * M_PI / 180, Eigen::Vector3d(0.2, 0.1, 1).normalized()).matrix();
  s.rig1_from_rig2.translation = Eigen::Vector3d(0.45, 0.1, 0.02);
  const Rigid3 cam_from_rig = g.rig_from_cam[0].Inverse();
  const Rigid3 rig2_from_rig1 = s.rig1_from_rig2.Inverse();
  auto jitter = [&](Eigen::Vector3d b) {
    return (b + noise_deg * M_PI / 180 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng))).normalized();
  };
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d x = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized() * depth(rng);
    s.points.push_back(x);
    const Eigen::Vector3d b1 = (cam_from_rig * x).normalized();
    Eigen::Vector3d b2 = (cam_from_rig * (rig2_from_rig1 * x)).normalized();
    if (i < outliers) b2 = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
    s.pairs.push_back({jitter(b1), jitter(b2), 0, 0});
  }
  return s;
}

// The candidate closest to the truth, and how close (rotation degrees, translation direction degrees).
std::pair<double, double> BestCandidate(const std::vector<Rigid3>& models, const Rigid3& truth) {
  double best_r = 1e9, best_t = 1e9;
  for (const auto& m : models) {
    const double r = RotationErrorDeg(m.rotation, truth.rotation);
    const double t = AngleDeg(m.translation, truth.translation);
    if (r + t < best_r + best_t) best_r = r, best_t = t;
  }
  return {best_r, best_t};
}

TEST(CentralPose, FivePointsAndEightPointsGiveTheTrueMotion) {
  const RigGeometry g = OneCamera();
  ASSERT_TRUE(g.central());
  const Scene s = MakeScene(g, 200, 0, 0, 1);
  const CentralRelativePoseEstimator estimator{&g, kFocal};
  const std::vector<RigBearingPair> five(s.pairs.begin(), s.pairs.begin() + 5);
  const auto [r5, t5] = BestCandidate(estimator.Estimate(five), s.rig1_from_rig2);
  const auto [r8, t8] = BestCandidate(estimator.Estimate(s.pairs), s.rig1_from_rig2);
  std::printf("noise-free: 5-point %.2e deg / %.2e deg, 8-point on 200: %.2e deg / %.2e deg\n", r5, t5, r8, t8);
  EXPECT_LT(r5, 1e-6);
  EXPECT_LT(t5, 1e-6);
  EXPECT_LT(r8, 1e-6);
  EXPECT_LT(t8, 1e-6);
}

TEST(CentralPose, RansacFindsTheMotionThroughOutliersAndNoise) {
  const RigGeometry g = OneCamera();
  // 0.05 degrees is a third of a pixel at 1024 wide; 30 % outliers.
  const Scene s = MakeScene(g, 400, 0.05, 120, 2);
  RansacOptions ro;
  ro.max_residual = 2.0;
  ro.random_seed = 3;
  const auto result = Ransac<CentralRelativePoseEstimator>(ro, {&g, kFocal}).Estimate(s.pairs);
  ASSERT_TRUE(result.success) << result.BriefReport();
  int right = 0, wrong = 0;
  for (int i = 0; i < 400; ++i) (i < 120 ? wrong : right) += result.inlier_mask[i];
  const double r = RotationErrorDeg(result.model.rotation, s.rig1_from_rig2.rotation);
  const double t = AngleDeg(result.model.translation, s.rig1_from_rig2.translation);
  std::printf("%s; %d of 280 inliers kept, %d of 120 outliers let in; rotation off by %.4f deg, heading %.3f deg\n",
              result.BriefReport().c_str(), right, wrong, r, t);
  EXPECT_GE(right, 270);
  EXPECT_LE(wrong, 3);
  // The 8-point refit minimises an algebraic error, not the angles: its heading is a degree or so
  // off at this noise (the bundle adjustment refines it); a wrong decomposition is off by tens.
  EXPECT_LT(r, 0.2);
  EXPECT_LT(t, 3);
  EXPECT_NEAR(result.model.translation.norm(), 1, 1e-9) << "a central camera's translation has unit length";
}

TEST(CentralPose, TheRigSolverCannotSeeACentralCamerasMotion) {
  // The 17-point solver on the same noise-free data: its translation is unobservable (the camera
  // offsets are zero), the reason the one-camera path needs its own solver.
  const RigGeometry g = OneCamera();
  const Scene s = MakeScene(g, 200, 0, 0, 4);
  RansacOptions ro;
  ro.max_residual = 2.0;
  const auto rig = Ransac<RigRelativePoseEstimator>(ro, {&g, kFocal}).Estimate(s.pairs);
  const auto central = Ransac<CentralRelativePoseEstimator>(ro, {&g, kFocal}).Estimate(s.pairs);
  std::printf("17-point: %s; central: %s\n", rig.BriefReport().c_str(), central.BriefReport().c_str());
  EXPECT_EQ(central.num_inliers, 200);
  EXPECT_LT(rig.num_inliers, 100);
}

TEST(CentralPose, AbsolutePoseFromThreePointsAndFromMany) {
  const RigGeometry g = OneCamera();
  std::mt19937 rng(5);
  std::normal_distribution<double> normal(0, 1);
  Rigid3 world_from_rig;
  world_from_rig.rotation = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.1, -0.3, 1).normalized()).matrix();
  world_from_rig.translation = Eigen::Vector3d(12, -3, 1.6);
  const Rigid3 cam_from_world = g.rig_from_cam[0].Inverse() * world_from_rig.Inverse();
  std::vector<RigBearingPoint> data;
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d x =
        world_from_rig * (Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized() * (4 + 10 * (i % 5)));
    data.push_back({(cam_from_world * x).normalized(), 0, x});
  }
  const CentralAbsolutePoseEstimator estimator{&g, kFocal};
  double best = 1e9;
  for (const auto& m : estimator.Estimate({data[0], data[1], data[2]}))
    best = std::min(best, (m.translation - world_from_rig.translation).norm() +
                              RotationErrorDeg(m.rotation, world_from_rig.rotation));
  EXPECT_LT(best, 1e-6) << "P3P";
  const auto many = estimator.Estimate(data);
  ASSERT_EQ(many.size(), 1u);
  EXPECT_LT((many[0].translation - world_from_rig.translation).norm(), 1e-6) << "EPnP";
  Rigid3 off = many[0];
  off.translation += Eigen::Vector3d(0.3, -0.2, 0.1);
  const Rigid3 refined = RefineCentralAbsolutePose(g, data, off);
  EXPECT_LT((refined.translation - world_from_rig.translation).norm(), 1e-6) << "refinement";
}

TEST(CentralPose, CamerasSharingOneCentreAwayFromTheOriginAreCentral) {
  // Two cameras back to back sharing a centre 10 cm ahead of the rig origin (a two-fisheye 360°
  // camera): central; moved apart, not.
  RigGeometry g = OneCamera();
  g.rig_from_cam[0].translation = Eigen::Vector3d(0.1, 0, 0);
  Rigid3 second = g.rig_from_cam[0];
  second.rotation = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).matrix() * second.rotation;
  g.rig_from_cam.push_back(second);
  g.focal_px.push_back(kFocal);
  ASSERT_TRUE(g.central());
  RigGeometry apart = g;
  apart.rig_from_cam[1].translation.x() = -0.1;
  EXPECT_FALSE(apart.central());
}

TEST(CentralPose, BestRotationUndoesARotation) {
  std::mt19937 rng(6);
  std::normal_distribution<double> normal(0, 1);
  const Eigen::Matrix3d r = Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  std::vector<Eigen::Vector3d> a, b;
  for (int i = 0; i < 20; ++i) {
    b.push_back(Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized());
    a.push_back(r * b.back());
  }
  EXPECT_LT(RotationErrorDeg(BestRotation(a, b), r), 1e-9);
}

}  // namespace
}  // namespace odvr::tracking
