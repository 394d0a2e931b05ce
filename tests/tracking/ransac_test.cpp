// The generic RANSAC on the simplest estimator there is, a 2D line: the consensus set against the
// known inliers, the adaptive stopping rule, seeds, the LO refit and the options' checks.
#include "tracking/ransac.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

namespace odvr::tracking {
namespace {

// A line a x + b y + c = 0 with (a, b) a unit normal, so the residual is a distance.
struct LineEstimator {
  using Datum = Eigen::Vector2d;
  using Model = Eigen::Vector3d;
  static constexpr int kMinimalSample = 2;

  // Total least squares: the normal is the direction of least spread about the centroid; for two
  // points that is exactly the line through them.
  std::vector<Model> Estimate(const std::vector<Datum>& data) const {
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (const auto& p : data) centroid += p;
    centroid /= static_cast<double>(data.size());
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    for (const auto& p : data) scatter += (p - centroid) * (p - centroid).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scatter);
    if (eig.eigenvalues()(1) < 1e-18) return {};  // coincident points: no line
    const Eigen::Vector2d normal = eig.eigenvectors().col(0);
    return {Model(normal.x(), normal.y(), -normal.dot(centroid))};
  }

  void Residuals(const std::vector<Datum>& data, const Model& line, std::vector<double>* r) const {
    r->resize(data.size());
    for (size_t i = 0; i < data.size(); ++i) (*r)[i] = std::abs(line.head<2>().dot(data[i]) + line.z());
  }
};

struct LineData {
  std::vector<Eigen::Vector2d> points;
  std::vector<char> is_inlier;
  Eigen::Vector3d line;  // unit normal form
};

// Points on y = 0.3 x + 1 with Gaussian noise `sigma`, and uniform outliers in [-10, 10]^2 that
// lie at least 10 sigma from the line, so the true consensus set is unambiguous.
LineData MakeLine(int n, double outlier_ratio, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-10, 10);
  std::normal_distribution<double> g(0, sigma);
  LineData d;
  d.line = Eigen::Vector3d(0.3, -1, 1) / std::hypot(0.3, 1.0);
  for (int i = 0; i < n; ++i) {
    const bool inlier = i >= static_cast<int>(outlier_ratio * n);
    Eigen::Vector2d p;
    if (inlier) {
      const double x = u(rng);
      p = Eigen::Vector2d(x + g(rng), 0.3 * x + 1 + g(rng));
    } else {
      do p = Eigen::Vector2d(u(rng), u(rng));
      while (std::abs(d.line.head<2>().dot(p) + d.line.z()) < 10 * sigma);
    }
    d.points.push_back(p);
    d.is_inlier.push_back(inlier);
  }
  return d;
}

double AngleBetweenLinesDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.head<2>().normalized().dot(b.head<2>().normalized())))) * 180 / M_PI;
}

TEST(Ransac, FindsTheLineAndExactlyItsInliersAmongFortyPercentOutliers) {
  const double sigma = 0.01;
  const LineData d = MakeLine(500, 0.4, sigma, 7);
  RansacOptions options;
  options.max_residual = 4 * sigma;
  const auto report = Ransac<LineEstimator>(options).Estimate(d.points);
  ASSERT_TRUE(report.success) << report.BriefReport();
  int true_pos = 0, false_pos = 0, false_neg = 0;
  for (size_t i = 0; i < d.points.size(); ++i) {
    true_pos += report.inlier_mask[i] && d.is_inlier[i];
    false_pos += report.inlier_mask[i] && !d.is_inlier[i];
    false_neg += !report.inlier_mask[i] && d.is_inlier[i];
  }
  EXPECT_EQ(false_pos, 0);            // outliers lie >= 10 sigma off the line
  EXPECT_LE(false_neg, 300 * 0.001);  // a 4-sigma cut of a 2D Gaussian's normal component
  EXPECT_EQ(report.num_inliers, true_pos);
  EXPECT_LT(AngleBetweenLinesDeg(report.model, d.line), 0.05);
  // The consensus line passes through the true one at x = 0 to within the noise.
  EXPECT_NEAR(-report.model.z() / report.model.y(), 1.0, 3 * sigma);
}

TEST(Ransac, StopsEarlyWhenInliersDominateAndRunsLongerWhenTheyDoNot) {
  RansacOptions options;
  options.max_residual = 0.04;
  options.confidence = 0.99;
  const auto easy = Ransac<LineEstimator>(options).Estimate(MakeLine(400, 0.1, 0.01, 3).points);
  const auto hard = Ransac<LineEstimator>(options).Estimate(MakeLine(400, 0.7, 0.01, 3).points);
  ASSERT_TRUE(easy.success && hard.success);
  // 90 % inliers, sample of 2: log(0.01) / log(1 - 0.81) = 2.8 -> 3 iterations once found.
  EXPECT_LE(easy.iterations, 5);
  // 30 % inliers: log(0.01) / log(1 - 0.09) = 48.8 -> 49.
  EXPECT_GE(hard.iterations, 40);
  EXPECT_LE(hard.iterations, 60);
}

TEST(Ransac, IterationCountFollowsTheFischlerBollesFormula) {
  EXPECT_EQ(RansacIterationsNeeded(0.5, 2, 0.99, 100000), 17);  // log 0.01 / log 0.75 = 16.0078
  EXPECT_EQ(RansacIterationsNeeded(0.5, 7, 0.99, 100000), 588);
  EXPECT_EQ(RansacIterationsNeeded(1.0, 7, 0.99, 100000), 1);
  EXPECT_EQ(RansacIterationsNeeded(0.0, 7, 0.99, 1234), 1234);
  EXPECT_EQ(RansacIterationsNeeded(0.01, 7, 0.999, 1234), 1234);
}

TEST(Ransac, TheSameSeedDrawsTheSameSamples) {
  const LineData d = MakeLine(300, 0.5, 0.02, 11);
  RansacOptions options;
  options.max_residual = 0.08;
  options.local_optimization = false;  // otherwise the refit hides different minimal samples
  options.random_seed = 42;
  const auto a = Ransac<LineEstimator>(options).Estimate(d.points);
  const auto b = Ransac<LineEstimator>(options).Estimate(d.points);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.inlier_mask, b.inlier_mask);
  EXPECT_EQ(a.model, b.model);
  // Other seeds pick other minimal samples, hence (almost surely) other lines.
  int different = 0;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    options.random_seed = seed;
    different += Ransac<LineEstimator>(options).Estimate(d.points).model != a.model;
  }
  EXPECT_GE(different, 4);
}

TEST(Ransac, LocalOptimizationRefitsOnTheConsensusSet) {
  // A minimal two-point line carries both points' noise; the refit on ~300 inliers averages it.
  double error_plain = 0, error_lo = 0;
  int improvements = 0;
  for (unsigned seed = 0; seed < 10; ++seed) {
    const LineData d = MakeLine(500, 0.4, 0.05, 100 + seed);
    RansacOptions options;
    options.max_residual = 0.2;
    options.random_seed = seed;
    options.local_optimization = false;
    error_plain += AngleBetweenLinesDeg(Ransac<LineEstimator>(options).Estimate(d.points).model, d.line);
    options.local_optimization = true;
    const auto lo = Ransac<LineEstimator>(options).Estimate(d.points);
    error_lo += AngleBetweenLinesDeg(lo.model, d.line);
    improvements += lo.local_optimizations;
  }
  EXPECT_GT(improvements, 0);
  EXPECT_LT(error_lo, 0.5 * error_plain) << "mean angle error LO " << error_lo / 10 << " deg, plain "
                                         << error_plain / 10 << " deg";
}

TEST(Ransac, FailsCleanlyWithTooFewOrDegenerateData) {
  RansacOptions options;
  const auto one = Ransac<LineEstimator>(options).Estimate({Eigen::Vector2d(1, 2)});
  EXPECT_FALSE(one.success);
  EXPECT_EQ(one.num_inliers, 0);
  EXPECT_EQ(one.inlier_mask.size(), 1u);
  // All points coincide: every sample is degenerate, no model is ever made.
  const auto same = Ransac<LineEstimator>(options).Estimate(std::vector<Eigen::Vector2d>(20, Eigen::Vector2d(1, 2)));
  EXPECT_FALSE(same.success);
  EXPECT_EQ(same.iterations, options.max_iterations);
}

TEST(Ransac, OptionsCheckNamesTheBadParameter) {
  auto message = [](RansacOptions o) {
    try {
      o.Check();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  RansacOptions o;
  EXPECT_EQ(message(o), "");
  o.confidence = 1.0;
  EXPECT_NE(message(o).find("ransac confidence"), std::string::npos);
  o = RansacOptions();
  o.max_residual = -1;
  EXPECT_NE(message(o).find("ransac max_residual"), std::string::npos);
  o = RansacOptions();
  o.min_iterations = 50;
  o.max_iterations = 10;
  EXPECT_NE(message(o).find("ransac max_iterations"), std::string::npos);
  EXPECT_THROW(Ransac<LineEstimator>{o}, Error);
}

}  // namespace
}  // namespace odvr::tracking
