// The trifocal tensor on synthetic three-view scenes (random points, three known calibrated
// cameras): exact recovery without noise, transfer at the noise level with noise, and the RANSAC
// estimator separating 30 % outliers from the inliers.
#include "tracking/trifocal.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <iostream>
#include <random>

#include "core/error.h"
#include "tracking/ransac.h"

namespace odvr::tracking {
namespace {

// A focal length to express normalized-coordinate noise in pixels: 0.5 px at f = 500 px.
constexpr double kFocalPx = 500.0;

struct Scene {
  Eigen::Matrix3d R21, R31;
  Eigen::Vector3d t21, t31;
  std::vector<PointTriple> triples;
  std::vector<PointTriple> clean;  // before noise and outliers
  std::vector<char> is_inlier;
};

Eigen::Matrix3d Rotation(double rx, double ry, double rz) {
  return (Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

// Three frames of a camera moving forward and sideways with a little rotation, as consecutive
// frames of a rig camera do; points 3-15 m ahead, all inside a +-45 degree field of view.
Scene MakeScene(int n, double noise_px, double outlier_ratio, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> g(0, noise_px / kFocalPx);
  Scene s;
  s.R21 = Rotation(0.01, -0.03, 0.005);
  s.t21 = Eigen::Vector3d(-0.3, 0.02, -0.5);
  s.R31 = Rotation(0.015, -0.07, 0.01);
  s.t31 = Eigen::Vector3d(-0.55, 0.05, -1.1);
  const int outliers = static_cast<int>(outlier_ratio * n);
  while (static_cast<int>(s.triples.size()) < n) {
    const Eigen::Vector3d p1(6 * u(rng), 3 * u(rng), 9 + 6 * u(rng));
    const Eigen::Vector3d p2 = s.R21 * p1 + s.t21, p3 = s.R31 * p1 + s.t31;
    PointTriple c{p1.hnormalized(), p2.hnormalized(), p3.hnormalized()};
    if (c.x1.cwiseAbs().maxCoeff() > 1 || c.x2.cwiseAbs().maxCoeff() > 1 || c.x3.cwiseAbs().maxCoeff() > 1) continue;
    const bool inlier = static_cast<int>(s.triples.size()) >= outliers;
    PointTriple t = c;
    t.x1 += Eigen::Vector2d(g(rng), g(rng));
    t.x2 += Eigen::Vector2d(g(rng), g(rng));
    t.x3 += Eigen::Vector2d(g(rng), g(rng));
    if (!inlier) {
      // A bad track: the point jumps in view 2, in view 3 or in both, by 10-150 px, as a KLT
      // track that slid onto another corner does.
      std::uniform_real_distribution<double> jump(10 / kFocalPx, 150 / kFocalPx);
      std::uniform_real_distribution<double> angle(0, 2 * M_PI);
      const int which = static_cast<int>(s.triples.size()) % 3;
      const double a = angle(rng), b = angle(rng);
      if (which != 1) t.x2 += jump(rng) * Eigen::Vector2d(std::cos(a), std::sin(a));
      if (which != 0) t.x3 += jump(rng) * Eigen::Vector2d(std::cos(b), std::sin(b));
    }
    s.triples.push_back(t);
    s.clean.push_back(c);
    s.is_inlier.push_back(inlier);
  }
  return s;
}

TEST(Trifocal, GroundTruthTensorSatisfiesIncidenceAndTransfersExactly) {
  const Scene s = MakeScene(50, 0, 0, 1);
  const TrifocalTensor truth = TrifocalTensor::FromRelativePoses(s.R21, s.t21, s.R31, s.t31);
  for (const auto& p : s.clean) {
    // [x2]x (sum_i x1^i T_i) [x3]x = 0 (H&Z 15.7).
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    for (int i = 0; i < 3; ++i) m += p.x1.homogeneous()(i) * truth.slices()[i];
    const Eigen::Vector3d h2 = p.x2.homogeneous(), h3 = p.x3.homogeneous();
    Eigen::Matrix3d s2, s3;
    s2 << 0, -h2.z(), h2.y(), h2.z(), 0, -h2.x(), -h2.y(), h2.x(), 0;
    s3 << 0, -h3.z(), h3.y(), h3.z(), 0, -h3.x(), -h3.y(), h3.x(), 0;
    EXPECT_LT((s2 * m * s3).norm(), 1e-12);
    EXPECT_LT(truth.TransferError(p), 1e-12);
    EXPECT_LT(truth.ReprojectionError(p), 1e-12);
    EXPECT_NEAR(p.x2.homogeneous().dot(truth.F21() * p.x1.homogeneous()), 0, 1e-12);
    EXPECT_NEAR(p.x3.homogeneous().dot(truth.F31() * p.x1.homogeneous()), 0, 1e-12);
  }
  // The epipoles are the images of camera 1's centre: t21 and t31 up to scale.
  EXPECT_NEAR(std::abs(truth.epipole2().dot(s.t21.normalized())), 1, 1e-12);
  EXPECT_NEAR(std::abs(truth.epipole3().dot(s.t31.normalized())), 1, 1e-12);
}

TEST(Trifocal, LinearSolverRecoversTheTensorUpToScaleWithoutNoise) {
  const Scene poses = MakeScene(1, 0, 0, 2);
  const TrifocalTensor truth = TrifocalTensor::FromRelativePoses(poses.R21, poses.t21, poses.R31, poses.t31);
  for (int n : {7, 8, 20, 200}) {
    const Scene s = MakeScene(n, 0, 0, 2);
    TrifocalTensor estimate;
    ASSERT_TRUE(EstimateTrifocalLinear(s.triples, &estimate)) << n << " points";
    // Both scaled to unit norm with the same sign: equal to 1e-9 (the SVD works at ~1e-15; the
    // normalization and 7-point conditioning cost a few digits).
    EXPECT_LT((estimate.Normalized() - truth.Normalized()).norm(), 1e-9) << n << " points";
    for (const auto& p : s.triples) {
      EXPECT_LT(estimate.TransferError(p) * kFocalPx, 1e-6);
      EXPECT_LT(estimate.ReprojectionError(p) * kFocalPx, 1e-6);
    }
  }
}

// RMS over `triples` of a residual in pixels.
template <class F>
double RmsPx(const std::vector<PointTriple>& triples, const std::vector<char>& use, F residual) {
  double sum_sq = 0;
  int n = 0;
  for (size_t i = 0; i < triples.size(); ++i) {
    if (!use[i]) continue;
    sum_sq += std::pow(residual(triples[i]), 2);
    ++n;
  }
  return std::sqrt(sum_sq / n) * kFocalPx;
}

TEST(Trifocal, NoisyInliersTransferAtTheNoiseLevel) {
  const double noise_px = 0.5;
  const Scene s = MakeScene(300, noise_px, 0, 3);
  TrifocalTensor estimate;
  ASSERT_TRUE(EstimateTrifocalLinear(s.triples, &estimate));
  const std::vector<char> all(s.triples.size(), 1);
  // The tensor's own error: how far the noise-free points are from consistent with it.
  const double clean_reprojection =
      RmsPx(s.clean, all, [&](const PointTriple& p) { return estimate.ReprojectionError(p); });
  const double clean_transfer = RmsPx(s.clean, all, [&](const PointTriple& p) { return estimate.TransferError(p); });
  // The residual of the noisy data: the noise itself, what RANSAC's threshold is set against.
  const double noisy_reprojection =
      RmsPx(s.triples, all, [&](const PointTriple& p) { return estimate.ReprojectionError(p); });
  const double noisy_transfer = RmsPx(s.triples, all, [&](const PointTriple& p) { return estimate.TransferError(p); });
  std::cout << "noise " << noise_px << " px: clean reprojection " << clean_reprojection << " px, clean transfer "
            << clean_transfer << " px, noisy reprojection " << noisy_reprojection << " px, noisy transfer "
            << noisy_transfer << " px\n";
  // Measured: 0.28, 0.45, 0.89, 1.75 px. The tensor from 300 points is better than one point's
  // noise; the residuals of the data are the noise (the reprojection residual is the largest of
  // three views, hence above sigma sqrt(2) = 0.71 px); transfer amplifies it near the epipole.
  EXPECT_LT(clean_reprojection, 0.75 * noise_px);
  EXPECT_LT(clean_transfer, noise_px);
  EXPECT_GT(noisy_reprojection, noise_px);
  EXPECT_LT(noisy_reprojection, 2.5 * noise_px);
  EXPECT_LT(noisy_transfer, 5 * noise_px);
}

TEST(Trifocal, RansacSeparatesThirtyPercentOutliers) {
  const double noise_px = 0.5;
  for (unsigned seed : {10u, 11u, 12u}) {
    const Scene s = MakeScene(400, noise_px, 0.3, seed);
    RansacOptions options;
    options.max_residual = 3.0 / kFocalPx;  // 3 px: 6 sigma of the noise
    options.random_seed = seed;
    const auto report = Ransac<TrifocalEstimator>(options).Estimate(s.triples);
    ASSERT_TRUE(report.success) << report.BriefReport();
    int tp = 0, fp = 0, fn = 0;
    for (size_t i = 0; i < s.triples.size(); ++i) {
      tp += report.inlier_mask[i] && s.is_inlier[i];
      fp += report.inlier_mask[i] && !s.is_inlier[i];
      fn += !report.inlier_mask[i] && s.is_inlier[i];
    }
    const double precision = static_cast<double>(tp) / (tp + fp), recall = static_cast<double>(tp) / (tp + fn);
    EXPECT_GE(precision, 0.95) << report.BriefReport();
    EXPECT_GE(recall, 0.95) << report.BriefReport();
    // The consensus tensor against the noise-free points: measured 0.21, 0.25, 0.32 px for these
    // seeds, the same as the linear fit on exactly the true inliers (LO converged to it).
    double sum_sq = 0;
    int n = 0;
    for (size_t i = 0; i < s.triples.size(); ++i) {
      if (!s.is_inlier[i]) continue;
      sum_sq += std::pow(report.model.ReprojectionError(s.clean[i]), 2);
      ++n;
    }
    const double rms_px = std::sqrt(sum_sq / n) * kFocalPx;
    EXPECT_LT(rms_px, 0.8 * noise_px) << "seed " << seed << ": reprojection RMS vs truth " << rms_px << " px";
    std::cout << "seed " << seed << ": " << report.BriefReport() << ", precision " << precision << ", recall " << recall
              << ", reprojection RMS vs truth " << rms_px << " px\n";
  }
}

TEST(Trifocal, DegenerateAndTooFewTriplesAreRefused) {
  Scene s = MakeScene(10, 0, 0, 4);
  std::vector<PointTriple> six(s.triples.begin(), s.triples.begin() + 6);
  TrifocalTensor t;
  try {
    EstimateTrifocalLinear(six, &t);
    ADD_FAILURE() << "no error for 6 triples";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("trifocal tensor: needs at least 7 point triples, got 6"), std::string::npos);
  }
  // All points the same: no normalization, no tensor.
  std::vector<PointTriple> same(10, s.triples[0]);
  EXPECT_FALSE(EstimateTrifocalLinear(same, &t));
  EXPECT_TRUE(TrifocalEstimator().Estimate(same).empty());
  // A NaN coordinate (a lost track) is refused rather than spread through the SVD.
  s.triples[3].x2.x() = std::nan("");
  EXPECT_FALSE(EstimateTrifocalLinear(s.triples, &t));
}

}  // namespace
}  // namespace odvr::tracking
