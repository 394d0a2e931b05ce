// Camera models: round trips, Jacobians against finite differences, agreement with OpenCV's
// own projection functions, and the conventions the models promise (camera frame, equirect).
#include "capture/camera_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <random>

#include "core/error.h"
#include "engine/sphere/equirect.h"

namespace odvr::capture {
namespace {

std::vector<CameraModel> Models() {
  return {
      CameraModel::Pinhole(640, 480, 500, 505, 319.5, 241.2),
      CameraModel::Pinhole(640, 480, 450, 452, 322.1, 238.7, {-0.28, 0.09, 0.0012, -0.0007, -0.012}),
      CameraModel::Fisheye(480, 640, 229.18311805232932, 229.18311805232932, 239.5, 319.5),
      CameraModel::Fisheye(1568, 1504, 420.5, 421.0, 785.2, 751.9, {0.021, -0.0043, 0.0011, -0.0002}),
      CameraModel::Equirectangular(1024, 512),
  };
}

// Random unit bearings the model can see and whose pixel lands on the image.
std::vector<Eigen::Vector3d> VisibleBearings(const CameraModel& m, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  std::vector<Eigen::Vector3d> out;
  while (static_cast<int>(out.size()) < n) {
    Eigen::Vector3d b(g(rng), g(rng), g(rng));
    b.normalize();
    Eigen::Vector2d px;
    if (m.Project(b, &px) && m.InImage(px)) out.push_back(b);
  }
  return out;
}

TEST(CameraModel, BearingPixelBearingRoundTrip) {
  for (const auto& m : Models()) {
    SCOPED_TRACE(m.Describe());
    double worst = 0;
    for (const auto& b : VisibleBearings(m, 2000, 7)) {
      Eigen::Vector2d px;
      ASSERT_TRUE(m.Project(3.7 * b, &px));  // the length of the point must not matter
      Eigen::Vector3d back;
      ASSERT_TRUE(m.Unproject(px, &back)) << px.transpose();
      EXPECT_NEAR(back.norm(), 1.0, 1e-12);
      worst = std::max(worst, (back - b).norm());
    }
    EXPECT_LT(worst, 1e-9);
  }
}

TEST(CameraModel, PixelBearingPixelRoundTripOverTheImage) {
  for (const auto& m : Models()) {
    SCOPED_TRACE(m.Describe());
    double worst = 0;
    int checked = 0;
    for (double v = -0.5; v <= m.height() - 0.5; v += m.height() / 37.0) {
      for (double u = -0.5; u <= m.width() - 0.5; u += m.width() / 41.0) {
        Eigen::Vector3d b;
        if (!m.Unproject({u, v}, &b)) continue;
        Eigen::Vector2d px;
        ASSERT_TRUE(m.Project(b, &px));
        worst = std::max(worst, (px - Eigen::Vector2d(u, v)).norm());
        ++checked;
      }
    }
    // Strong barrel distortion leaves the pinhole's far corners outside its invertible region.
    EXPECT_GT(checked, 1000);
    EXPECT_LT(worst, 1e-7);
  }
}

TEST(CameraModel, JacobiansMatchCentralDifferences) {
  for (const auto& m : Models()) {
    SCOPED_TRACE(m.Describe());
    for (const auto& b : VisibleBearings(m, 300, 11)) {
      const Eigen::Vector3d p = 2.5 * b;
      Eigen::Vector2d px;
      Eigen::Matrix<double, 2, 3> j;
      if (!m.Project(p, &px, &j)) continue;  // equirect poles have no Jacobian
      Eigen::Matrix<double, 2, 3> fd;
      const double h = 1e-6;
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d dp = Eigen::Vector3d::Zero();
        dp[k] = h;
        Eigen::Vector2d a, c;
        ok = ok && m.Project(p + dp, &a) && m.Project(p - dp, &c);
        fd.col(k) = (a - c) / (2 * h);
      }
      // Central differences straddling the equirect seam jump by W: skip those.
      if (!ok || std::abs(fd(0, 0)) > 1e5 || std::abs(fd(0, 2)) > 1e5) continue;
      EXPECT_LT((fd - j).norm(), 1e-5 * std::max(1.0, j.norm())) << "p=" << p.transpose() << "\nJ=\n"
                                                                 << j << "\nfd=\n"
                                                                 << fd;
    }
  }
}

TEST(CameraModel, FisheyeJacobianOnTheOpticalAxisIsTheLimit) {
  const auto m = CameraModel::Fisheye(480, 640, 229.2, 230.1, 239.5, 319.5, {0.1, 0.01, 0, 0});
  Eigen::Vector2d px;
  Eigen::Matrix<double, 2, 3> j;
  ASSERT_TRUE(m.Project({0, 0, 2}, &px, &j));
  EXPECT_NEAR(px.x(), 239.5, 1e-12);
  EXPECT_NEAR(px.y(), 319.5, 1e-12);
  Eigen::Vector2d a;
  ASSERT_TRUE(m.Project({1e-5, 0, 2}, &a));
  EXPECT_NEAR(j(0, 0), (a.x() - px.x()) / 1e-5, 1e-3);
  EXPECT_NEAR(j(1, 1), 230.1 / 2, 1e-9);
}

TEST(CameraModel, FisheyeAgreesWithOpenCvFisheyeProjectPoints) {
  const cv::Matx33d k(420.5, 0, 785.2, 0, 421.0, 751.9, 0, 0, 1);
  const cv::Vec4d d(0.021, -0.0043, 0.0011, -0.0002);
  const auto m = CameraModel::Fisheye(1568, 1504, 420.5, 421.0, 785.2, 751.9, {d[0], d[1], d[2], d[3]});
  std::vector<cv::Point3d> pts;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  // cv::fisheye uses atan(r) and only covers theta < 90 deg: stay in front of the camera.
  while (pts.size() < 500) {
    cv::Point3d p(u(rng), u(rng), 0.05 + std::abs(u(rng)));
    pts.push_back(p * 3.0);
  }
  std::vector<cv::Point2d> cv_px;
  cv::fisheye::projectPoints(pts, cv_px, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, d);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    Eigen::Vector2d px;
    ASSERT_TRUE(m.Project({pts[i].x, pts[i].y, pts[i].z}, &px));
    EXPECT_NEAR(px.x(), cv_px[i].x, 1e-6);
    EXPECT_NEAR(px.y(), cv_px[i].y, 1e-6);
  }
}

TEST(CameraModel, PinholeAgreesWithOpenCvProjectPoints) {
  const cv::Matx33d k(450, 0, 322.1, 0, 452, 238.7, 0, 0, 1);
  const std::array<double, 5> d{-0.28, 0.09, 0.0012, -0.0007, -0.012};
  const auto m = CameraModel::Pinhole(640, 480, 450, 452, 322.1, 238.7, d);
  std::vector<cv::Point3d> pts;
  for (const auto& b : VisibleBearings(m, 500, 5)) pts.emplace_back(b.x(), b.y(), b.z());
  std::vector<cv::Point2d> cv_px;
  cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, std::vector<double>(d.begin(), d.end()), cv_px);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    Eigen::Vector2d px;
    ASSERT_TRUE(m.Project({pts[i].x, pts[i].y, pts[i].z}, &px));
    EXPECT_NEAR(px.x(), cv_px[i].x, 1e-6);
    EXPECT_NEAR(px.y(), cv_px[i].y, 1e-6);
  }
  // Undistortion agrees with cv::undistortPoints too.
  std::vector<cv::Point2d> norm;
  cv::undistortPoints(cv_px, norm, k, std::vector<double>(d.begin(), d.end()), cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-14));
  for (std::size_t i = 0; i < pts.size(); ++i) {
    Eigen::Vector3d b;
    ASSERT_TRUE(m.Unproject({cv_px[i].x, cv_px[i].y}, &b));
    EXPECT_NEAR(b.x() / b.z(), norm[i].x, 1e-6);
    EXPECT_NEAR(b.y() / b.z(), norm[i].y, 1e-6);
  }
}

TEST(CameraModel, StreetRigFisheyeSeesBehindItsImagePlaneAtTheCorners) {
  // street_a: equidistant r = f theta; the corners reach theta = 100 deg (rig.json).
  const auto m = CameraModel::Fisheye(480, 640, 229.18311805232932, 229.18311805232932, 239.5, 319.5);
  Eigen::Vector3d b;
  ASSERT_TRUE(m.Unproject({-0.5, -0.5}, &b));
  EXPECT_LT(b.z(), 0);
  EXPECT_NEAR(std::acos(b.z()) * 180 / kPi, 100.0, 0.05);
  EXPECT_LT(b.x(), 0);  // top-left: left (-x) and up (-y) in the OpenCV camera frame
  EXPECT_LT(b.y(), 0);
  ASSERT_TRUE(m.Unproject({239.5, 319.5}, &b));
  EXPECT_NEAR((b - Eigen::Vector3d(0, 0, 1)).norm(), 0, 1e-12);
  // 60 deg to the right lands at r = f * pi / 3.
  Eigen::Vector2d px;
  ASSERT_TRUE(m.Project({std::sin(kPi / 3), 0, std::cos(kPi / 3)}, &px));
  EXPECT_NEAR(px.x(), 239.5 + 229.18311805232932 * kPi / 3, 1e-9);
}

TEST(CameraModel, FoldingDistortionLimitsTheField) {
  // theta_d = theta (1 - 0.2 theta^2) stops growing at theta = sqrt(1 / 0.6).
  const auto fish = CameraModel::Fisheye(1000, 1000, 300, 300, 499.5, 499.5, {-0.2, 0, 0, 0});
  EXPECT_NEAR(fish.max_theta(), std::sqrt(1 / 0.6), 2e-4);
  Eigen::Vector2d px;
  const double t = fish.max_theta() + 0.05;
  EXPECT_FALSE(fish.Project({std::sin(t), 0, std::cos(t)}, &px));
  Eigen::Vector3d b;
  EXPECT_FALSE(fish.Unproject({499.5 + 300 * 1.0, 499.5}, &b));  // beyond theta_d(max) = 0.86

  // Strong barrel distortion on a pinhole folds back too; points past the fold are not seen.
  const auto pin = CameraModel::Pinhole(640, 480, 300, 300, 319.5, 239.5, {-0.4, 0, 0, 0, 0});
  EXPECT_NEAR(std::tan(pin.max_theta()), std::sqrt(1 / 1.2), 1e-3);
  EXPECT_FALSE(pin.Project({1.2, 0, 1}, &px));
  EXPECT_TRUE(pin.Project({0.8, 0, 1}, &px));
  // Behind a pinhole: never.
  EXPECT_FALSE(pin.Project({0, 0, -1}, &px));
}

TEST(CameraModel, EquirectangularFollowsTheOdvrConvention) {
  const int w = 1024, h = 512;
  const auto m = CameraModel::Equirectangular(w, h);
  Eigen::Vector3d b;
  // The centre of the image looks forward (+z), the middle of the top edge up (-y), a quarter
  // to the right looks right (+x).
  ASSERT_TRUE(m.Unproject({w / 2.0 - 0.5, h / 2.0 - 0.5}, &b));
  EXPECT_NEAR((b - Eigen::Vector3d(0, 0, 1)).norm(), 0, 1e-12);
  ASSERT_TRUE(m.Unproject({w / 2.0 - 0.5, -0.5}, &b));
  EXPECT_NEAR((b - Eigen::Vector3d(0, -1, 0)).norm(), 0, 1e-12);
  ASSERT_TRUE(m.Unproject({0.75 * w - 0.5, h / 2.0 - 0.5}, &b));
  EXPECT_NEAR((b - Eigen::Vector3d(1, 0, 0)).norm(), 0, 1e-12);
  // And pixel (col, row) is the direction engine/sphere/equirect.h gives, in the camera frame.
  for (int row = 0; row < h; row += 37) {
    for (int col = 0; col < w; col += 53) {
      const glm::dvec3 d = sphere::EquirectPixelDirection(col, row, w, h);
      ASSERT_TRUE(m.Unproject({double(col), double(row)}, &b));
      EXPECT_NEAR((b - Eigen::Vector3d(d.z, -d.y, d.x)).norm(), 0, 1e-12);
    }
  }
  EXPECT_FALSE(m.Unproject({10, h + 1.0}, &b));
}

TEST(CameraModel, RejectsEmptyImagesAndBadFocalLengths) {
  EXPECT_THROW(CameraModel::Pinhole(0, 480, 500, 500, 0, 0), Error);
  EXPECT_THROW(CameraModel::Fisheye(480, 640, -1, 229, 0, 0), Error);
  EXPECT_THROW(CameraModel::Fisheye(480, 640, std::nan(""), 229, 0, 0), Error);
  EXPECT_THROW(CameraModel::Equirectangular(10, -2), Error);
}

}  // namespace
}  // namespace odvr::capture
