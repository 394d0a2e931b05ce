// The stitcher: geometry against a synthetic world seen by a synthetic rig, gain compensation,
// the hard cases (±30 % exposure, a black camera, wrong sizes, a camera missing), the pull-push
// fill, the street_a ground truth, and the GPU path against the CPU reference.
#include "capture/stitcher.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <tuple>

#include "core/error.h"
#include "core/srgb.h"
#include "engine/image/image_io.h"
#include "engine/sphere/equirect.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/error_message.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;
using odvr::testing::ErrorMessageOf;
const fs::path kStreet = fs::path(ODVR_SHARED_DIR) / "data/street_a";
// street_a at 512x256 against the ground truth shrunk to that size (INTER_AREA), CPU path,
// frames 0 / 20, measured: PSNR (8-bit sRGB, valid mask) 26.76 / 26.18 dB with rays at infinity,
// 27.90 / 27.60 dB with rays meeting at 5 m; after a 1.5 px Gaussian on both 32.79 / 31.82 and
// 34.56 / 34.13 dB. The dataset's renders carry ~23 dB of Monte-Carlo noise each at 1024x512,
// which bounds the unblurred figures (shrinking and the even blend across overlaps average some
// of it away). Floors sit ~0.5 dB under the lower frame.
constexpr double kStreetPsnrFloorDb = 25.6;
constexpr double kStreetBlurredPsnrFloorDb = 31.3;
constexpr double kStreetPsnr5mFloorDb = 27.1;
constexpr double kStreetBlurredPsnr5mFloorDb = 33.6;
// The seams' PSNR gain of the chosen scene distance over infinity, frames 0 / 20 (both choose
// 8 m at 512x256), measured: 1.41 / 1.50 dB; the floor sits ~1 dB under the lower.
constexpr double kStreetChosenSeamGainDb = 0.5;

// Linear radiance of the synthetic world in odvr direction d: smooth bands plus finer detail,
// brighter towards the zenith like a sky, kept below 0.7 so a 1.3 gain does not clip.
Eigen::Vector3f World(const glm::dvec3& d) {
  const double a = 0.25 + 0.12 * std::sin(3 * d.x + 1) * std::cos(2 * d.z) + 0.08 * d.y;
  const double b = 0.05 * std::sin(17 * d.x) * std::sin(13 * d.z + 2 * d.y);
  return {static_cast<float>(a + b), static_cast<float>(0.9 * a - b), static_cast<float>(0.7 * a + 0.1 * d.y + 0.1)};
}

// The street_a rig layout (six equidistant fisheyes at 60° yaw steps, camera up = rig up, 0.08 m
// out) at a quarter of the resolution, built in code so the test needs no data files.
Rig SyntheticRig(int width = 120, int height = 160) {
  Rig rig;
  const double f = 229.18311805232932 * width / 480.0;
  for (int c = 0; c < 6; ++c) {
    const double yaw = c * kPi / 3;
    const Eigen::Vector3d forward(std::cos(yaw), std::sin(yaw), 0), up(0, 0, 1);
    const Eigen::Vector3d right = forward.cross(up);
    Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
    t.block<3, 1>(0, 0) = right;  // camera x right
    t.block<3, 1>(0, 1) = -up;    // camera y down
    t.block<3, 1>(0, 2) = forward;
    t.block<3, 1>(0, 3) = 0.08 * forward;
    rig.cameras.push_back({"cam" + std::to_string(c),
                           CameraModel::Fisheye(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0), t, ""});
  }
  return rig;
}

// What camera c of `rig` records of World() (at infinity) with exposure gain `gain`: 8-bit sRGB BGR.
cv::Mat RenderCamera(const Rig& rig, int c, double gain) {
  const RigCamera& cam = rig.cameras[static_cast<std::size_t>(c)];
  cv::Mat img(cam.model.height(), cam.model.width(), CV_8UC3, cv::Scalar(0, 0, 0));
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      Eigen::Vector3d b;
      if (!cam.model.Unproject({double(x), double(y)}, &b)) continue;
      const Eigen::Vector3d o = OdvrFromRig(cam.rig_from_cam.topLeftCorner<3, 3>() * b);
      const Eigen::Vector3f rgb = World({o.x(), o.y(), o.z()}) * static_cast<float>(gain);
      auto& px = img.at<cv::Vec3b>(y, x);
      for (int k = 0; k < 3; ++k) px[2 - k] = static_cast<unsigned char>(std::lround(255 * LinearToSrgb(rgb[k])));
    }
  return img;
}

std::vector<cv::Mat> RenderRig(const Rig& rig, const std::vector<double>& gains) {
  std::vector<cv::Mat> out;
  for (int c = 0; c < rig.camera_count(); ++c) out.push_back(RenderCamera(rig, c, gains[static_cast<std::size_t>(c)]));
  return out;
}

// RMS error (linear) of the stitched valid pixels against scale * World().
double RmsAgainstWorld(const StitchedFrame& f, double scale = 1) {
  double sum = 0;
  long n = 0;
  for (int row = 0; row < f.image.height; ++row)
    for (int col = 0; col < f.image.width; ++col) {
      const std::size_t p = static_cast<std::size_t>(row) * f.image.width + col;
      if (!f.valid[p]) continue;
      const Eigen::Vector3f w =
          World(sphere::EquirectPixelDirection(col, row, f.image.width, f.image.height)) * static_cast<float>(scale);
      for (int k = 0; k < 3; ++k) sum += std::pow(f.image.at(col, row)[k] - w[k], 2);
      ++n;
    }
  return std::sqrt(sum / (3.0 * std::max(1L, n)));
}

StitchOptions SmallOptions(int w = 256, int h = 128) {
  StitchOptions o;
  o.width = w;
  o.height = h;
  return o;
}

TEST(Stitcher, LookupTableEntriesPointBackAtTheirPixelsBearing) {
  const Rig rig = SyntheticRig();
  const StitchLut lut = BuildStitchLut(rig, SmallOptions());
  ASSERT_EQ(lut.offsets.size(), lut.pixel_count() + 1);
  EXPECT_EQ(lut.offsets.back(), lut.entries.size());
  double worst = 0;
  for (int row = 0; row < lut.height; row += 3)
    for (int col = 0; col < lut.width; col += 5) {
      const std::size_t p = static_cast<std::size_t>(row) * lut.width + col;
      const glm::dvec3 d = sphere::EquirectPixelDirection(col, row, lut.width, lut.height);
      const Eigen::Vector3d want = RigFromOdvr({d.x, d.y, d.z});
      for (auto e = lut.offsets[p]; e < lut.offsets[p + 1]; ++e) {
        const auto& entry = lut.entries[e];
        const RigCamera& cam = rig.cameras[entry.camera];
        Eigen::Vector3d b;
        ASSERT_TRUE(cam.model.Unproject({entry.u, entry.v}, &b));
        worst = std::max(worst, (cam.rig_from_cam.topLeftCorner<3, 3>() * b - want).norm());
        EXPECT_GT(entry.weight, 0.f);
        EXPECT_LE(entry.weight, 1.f);
      }
    }
  EXPECT_LT(worst, 1e-5);  // float pixel coordinates
  // Around the horizon every direction is seen by two cameras (120° fields at 60° steps).
  const int row = lut.height / 2;
  for (int col = 0; col < lut.width; ++col) {
    const std::size_t p = static_cast<std::size_t>(row) * lut.width + col;
    EXPECT_GE(lut.offsets[p + 1] - lut.offsets[p], 1u);
  }
  EXPECT_GT(lut.gain_pixels.size(), 200u);
}

TEST(Stitcher, SyntheticRigReproducesTheWorldItSaw) {
  const Rig rig = SyntheticRig();
  Stitcher stitcher(rig, SmallOptions());
  const StitchedFrame f = stitcher.Stitch(RenderRig(rig, std::vector<double>(6, 1.0)));
  EXPECT_GT(f.report.valid_fraction, 0.85);
  EXPECT_LT(f.report.valid_fraction, 1.0);
  // The zenith and nadir rows are beyond every camera (their fields end ~80° up and down).
  for (int col = 0; col < f.image.width; ++col) {
    EXPECT_EQ(f.valid[static_cast<std::size_t>(col)], 0);
    EXPECT_EQ(f.valid[f.valid.size() - 1 - static_cast<std::size_t>(col)], 0);
  }
  for (double g : f.report.gains) EXPECT_NEAR(g, 1.0, 0.01);
  // 8-bit quantization and bilinear resampling of 120x160 images: ~0.4 % of the signal.
  EXPECT_LT(RmsAgainstWorld(f), 0.004) << f.report.Summary();
}

TEST(Stitcher, ExposureDifferencesOfThirtyPercentAreCompensated) {
  const Rig rig = SyntheticRig();
  const std::vector<double> exposure{1.3, 0.7, 1.0, 1.3, 0.7, 1.15};
  const auto images = RenderRig(rig, exposure);
  Stitcher stitcher(rig, SmallOptions());
  const StitchedFrame f = stitcher.Stitch(images);
  // Gains undo the exposures up to one common scale.
  std::vector<double> products;
  for (int c = 0; c < 6; ++c) products.push_back(f.report.gains[c] * exposure[c]);
  const double common = std::accumulate(products.begin(), products.end(), 0.0) / 6;
  for (double p : products) EXPECT_NEAR(p / common, 1.0, 0.02) << f.report.Summary();
  // The common scale is the prior's: argmin_c sum_i (1 - c / e_i)^2 = sum(1 / e) / sum(1 / e^2).
  double s1 = 0, s2 = 0;
  for (double e : exposure) {
    s1 += 1 / e;
    s2 += 1 / (e * e);
  }
  EXPECT_NEAR(common, s1 / s2, 0.02);
  const double compensated = RmsAgainstWorld(f, common);

  StitchOptions off = SmallOptions();
  off.compensate_gains = false;
  Stitcher plain(rig, off);
  const double uncompensated = RmsAgainstWorld(plain.Stitch(images), common);
  EXPECT_LT(compensated, 0.01);
  EXPECT_LT(compensated, uncompensated / 4) << compensated << " vs " << uncompensated;
}

TEST(Stitcher, ABlackCameraIsLeftOutAndTheOthersStillStitch) {
  const Rig rig = SyntheticRig();
  auto images = RenderRig(rig, {1.1, 0.9, 1.0, 1.0, 1.05, 0.95});
  images[2].setTo(cv::Scalar(0, 0, 0));
  Stitcher stitcher(rig, SmallOptions());
  const StitchedFrame f = stitcher.Stitch(images);
  EXPECT_FALSE(f.report.camera_used[2]);
  EXPECT_EQ(f.report.gains[2], 1.0);  // never solved from a zero mean, never driven to the clamp
  for (int c : {0, 1, 3, 4, 5}) {
    EXPECT_TRUE(f.report.camera_used[c]);
    EXPECT_GT(f.report.gains[c], 0.8);
    EXPECT_LT(f.report.gains[c], 1.25);
  }
  // Its neighbours cover its horizontal span: the valid area shrinks only at the top and bottom.
  EXPECT_GT(f.report.valid_fraction, 0.7);
  EXPECT_NE(f.report.Summary().find("unused cameras (missing or black): 2"), std::string::npos);
  // No black hole where camera 2 looked (yaw 120°): the stitched horizon there is the world.
  const int col = static_cast<int>(std::lround(f.image.width * (0.5 - 120.0 / 360.0)));
  const float* px = f.image.at(col, f.image.height / 2);
  EXPECT_GT(px[0], 0.05f);
  EXPECT_LT(RmsAgainstWorld(f), 0.03);

  // A missing frame (empty image) is handled the same way.
  images[2] = cv::Mat();
  const StitchedFrame g = stitcher.Stitch(images);
  EXPECT_FALSE(g.report.camera_used[2]);
  EXPECT_EQ(g.report.gains[2], 1.0);
}

TEST(Stitcher, AnImageOfTheWrongSizeIsAClearError) {
  const Rig rig = SyntheticRig();
  auto images = RenderRig(rig, std::vector<double>(6, 1.0));
  cv::resize(images[1], images[1], cv::Size(100, 100));
  Stitcher stitcher(rig, SmallOptions(64, 32));
  const std::string msg = ErrorMessageOf([&] { stitcher.Stitch(images); });
  EXPECT_NE(msg.find("camera 1 (cam1)"), std::string::npos) << msg;
  EXPECT_NE(msg.find("100x100"), std::string::npos) << msg;
  EXPECT_NE(msg.find("120x160"), std::string::npos) << msg;
}

TEST(Stitcher, AFrameSetWithACameraMissingIsAClearError) {
  const Rig rig = SyntheticRig();
  auto images = RenderRig(rig, std::vector<double>(6, 1.0));
  images.pop_back();
  Stitcher stitcher(rig, SmallOptions(64, 32));
  const std::string msg = ErrorMessageOf([&] { stitcher.Stitch(images); });
  EXPECT_NE(msg.find("5 camera images"), std::string::npos) << msg;
  EXPECT_NE(msg.find("describes 6"), std::string::npos) << msg;
  // A rig without cameras cannot stitch at all.
  EXPECT_THROW(Stitcher(Rig{}, SmallOptions(64, 32)), Error);
  StitchOptions bad = SmallOptions(0, 32);
  EXPECT_THROW(Stitcher(rig, bad), UsageError);
}

TEST(Stitcher, SolveGainsRecoversRatiosAndIgnoresUnusableCameras) {
  // Three cameras in a ring seeing a surface of intensity 0.4 through exposures e_i; camera 3 is
  // unusable and reports garbage means.
  const std::vector<double> e{1.2, 0.8, 1.0, 0.0};
  std::vector<std::vector<double>> n(4, std::vector<double>(4, 0.0)), m = n;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      if (i != j) {
        n[i][j] = 1000;
        m[i][j] = 0.4 * e[i];
      }
  StitchOptions o;
  const auto g = SolveGains(n, m, {true, true, true, false}, o);
  EXPECT_EQ(g[3], 1.0);
  // The prior (sigma_g = 0.5 against sigma_n = 7.8 % of the mean) shrinks ratios by ~0.3 %.
  EXPECT_NEAR(g[0] * 1.2 / (g[1] * 0.8), 1.0, 6e-3);
  EXPECT_NEAR(g[2] * 1.0 / (g[1] * 0.8), 1.0, 6e-3);
  // A tighter prior (OpenCV's sigma_g = 0.1) shrinks them more: the prior is doing its job.
  StitchOptions tight;
  tight.gain_sigma_g = 0.1;
  const auto gt = SolveGains(n, m, {true, true, true, false}, tight);
  EXPECT_GT(std::abs(gt[0] * 1.2 / (gt[1] * 0.8) - 1), std::abs(g[0] * 1.2 / (g[1] * 0.8) - 1));
  // With no overlaps at all every gain stays 1.
  std::vector<std::vector<double>> zero(4, std::vector<double>(4, 0.0));
  for (double x : SolveGains(zero, zero, {true, true, true, true}, o)) EXPECT_EQ(x, 1.0);
}

TEST(Stitcher, FillUnseenKeepsValidPixelsAndFillsFromTheBorder) {
  sphere::EquirectImage img(64, 32);
  std::vector<std::uint8_t> valid(img.pixel_count(), 0);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.2f, 0.6f);
  for (int row = 6; row < 26; ++row)
    for (int col = 0; col < 64; ++col) {
      valid[static_cast<std::size_t>(row) * 64 + col] = 1;
      for (int k = 0; k < 3; ++k) img.at(col, row)[k] = u(rng);
    }
  const sphere::EquirectImage before = img;
  FillUnseen(&img, valid);
  for (std::size_t p = 0; p < img.pixel_count(); ++p) {
    for (int k = 0; k < 3; ++k) {
      if (valid[p]) {
        EXPECT_EQ(img.rgb[3 * p + k], before.rgb[3 * p + k]);
      } else {
        // A convex combination of valid values: never darker than the darkest, never brighter.
        EXPECT_GE(img.rgb[3 * p + k], 0.2f - 1e-5f);
        EXPECT_LE(img.rgb[3 * p + k], 0.6f + 1e-5f);
      }
    }
  }
  // A constant valid region fills with that constant.
  sphere::EquirectImage flat(50, 25);  // odd sizes exercise the wrap and the clamped pull
  std::vector<std::uint8_t> band(flat.pixel_count(), 0);
  for (int row = 10; row < 14; ++row)
    for (int col = 0; col < 50; ++col) {
      band[static_cast<std::size_t>(row) * 50 + col] = 1;
      for (int k = 0; k < 3; ++k) flat.at(col, row)[k] = 0.37f;
    }
  FillUnseen(&flat, band);
  for (float v : flat.rgb) EXPECT_NEAR(v, 0.37f, 1e-6f);
}

TEST(Stitcher, UnseenCapsAreFilledWithoutDarkeningTheFrame) {
  const Rig rig = SyntheticRig();
  Stitcher stitcher(rig, SmallOptions());
  const StitchedFrame f = stitcher.Stitch(RenderRig(rig, std::vector<double>(6, 1.0)));
  // The filled zenith cap is near the world's own brightness there, far from black.
  double filled = 0, truth = 0;
  int n = 0;
  for (int row = 0; row < 6; ++row)
    for (int col = 0; col < f.image.width; ++col) {
      if (f.valid[static_cast<std::size_t>(row) * f.image.width + col]) continue;
      filled += f.image.at(col, row)[1];
      truth += World(sphere::EquirectPixelDirection(col, row, f.image.width, f.image.height))[1];
      ++n;
    }
  ASSERT_GT(n, 0);
  EXPECT_NEAR(filled / n, truth / n, 0.15 * truth / n);
}

TEST(Stitcher, FeatherIsFlatInsideItsMarginAndZeroAtTheImageEdge) {
  // 100 x 200 image, margin 0.2: the ramp spans 10 px in x and 20 px in y from the outer edge.
  EXPECT_FLOAT_EQ(FeatherWeight(49.5, 99.5, 100, 200, 0.2), 1.f);
  EXPECT_FLOAT_EQ(FeatherWeight(9.5, 99.5, 100, 200, 0.2), 1.f);
  EXPECT_NEAR(FeatherWeight(4.5, 99.5, 100, 200, 0.2), 0.5f, 1e-6f);
  EXPECT_NEAR(FeatherWeight(4.5, 9.5, 100, 200, 0.2), 0.25f, 1e-6f);
  EXPECT_FLOAT_EQ(FeatherWeight(-0.5, 99.5, 100, 200, 0.2), 0.f);
  EXPECT_FLOAT_EQ(FeatherWeight(49.5, 199.5, 100, 200, 0.2), 0.f);
  // Margin 1 is a tent over the whole image.
  EXPECT_NEAR(FeatherWeight(24.5, 99.5, 100, 200, 1.0), 0.5f, 1e-6f);
  StitchOptions bad;
  bad.feather_margin = 0;
  EXPECT_THROW(bad.Check(), UsageError);
}

TEST(Stitcher, CamerasAreSampledAtHalfResolutionOnlyWhereTheOutputMinifiesThem) {
  // Cameras of 120x160 with f = 57.3 px: 1 / f = 0.0175 rad per pixel at their centre.
  const Rig rig = SyntheticRig();
  const auto levels = [&](int width, StitchOptions::Prefilter p) {
    StitchOptions o = SmallOptions(width, width / 2);
    o.prefilter = p;
    return BuildStitchLut(rig, o).level;
  };
  using P = StitchOptions::Prefilter;
  EXPECT_EQ(levels(256, P::kAuto), std::vector<std::uint8_t>(6, 1));  // 0.0245 rad per output pixel
  EXPECT_EQ(levels(512, P::kAuto), std::vector<std::uint8_t>(6, 0));  // 0.0123
  EXPECT_EQ(levels(512, P::kOn), std::vector<std::uint8_t>(6, 1));
  EXPECT_EQ(levels(256, P::kOff), std::vector<std::uint8_t>(6, 0));
}

TEST(Stitcher, CameraMeansAreExactAtEitherLevelWithOddImageSizes) {
  // Odd sizes: the half-resolution level repeats the last column and row in its box averages,
  // which must not count twice in the mean used to find black frames.
  const Rig rig = SyntheticRig(121, 161);
  const auto images = RenderRig(rig, {1.2, 0.8, 1.0, 1.1, 0.9, 1.0});
  for (const auto p : {StitchOptions::Prefilter::kOn, StitchOptions::Prefilter::kOff}) {
    StitchOptions o = SmallOptions(64, 32);
    o.prefilter = p;
    Stitcher stitcher(rig, o);
    const StitchedFrame f = stitcher.Stitch(images);
    for (int c = 0; c < 6; ++c) {
      double sum = 0;
      for (int y = 0; y < images[c].rows; ++y)
        for (int x = 0; x < images[c].cols; ++x)
          for (int k = 0; k < 3; ++k) sum += SrgbToLinear(images[c].at<cv::Vec3b>(y, x)[k] / 255.0f);
      const double want = sum / (3.0 * images[c].total());
      EXPECT_NEAR(f.report.camera_mean[c], want, 1e-5 * want) << "camera " << c;
    }
  }
}

TEST(Stitcher, StitchingIntoAReusedFrameMatchesAFreshOne) {
  const Rig rig = SyntheticRig();
  StitchOptions o = SmallOptions(96, 48);
  o.fill_unseen = false;  // unseen pixels must then come out black, not the last frame's values
  Stitcher stitcher(rig, o);
  const auto bright = RenderRig(rig, std::vector<double>(6, 1.3));
  auto dark = RenderRig(rig, std::vector<double>(6, 0.6));
  dark[1].setTo(cv::Scalar(0, 0, 0));  // fewer pixels seen than in the frame before
  StitchedFrame reused;
  stitcher.Stitch(bright, &reused);
  stitcher.Stitch(dark, &reused);
  const StitchedFrame fresh = stitcher.Stitch(dark);
  EXPECT_EQ(reused.valid, fresh.valid);
  EXPECT_EQ(reused.image.rgb, fresh.image.rgb);
  EXPECT_EQ(reused.report.gains, fresh.report.gains);
  EXPECT_LT(reused.report.valid_fraction, 0.99);
}

// ../shared/data/street_a: six rendered fisheyes vs the ground-truth panorama from the rig centre.
std::vector<cv::Mat> LoadStreetFrame(int frame) {
  std::vector<cv::Mat> images;
  char name[32];
  std::snprintf(name, sizeof name, "%06d.jpg", frame);
  for (int c = 0; c < 6; ++c)
    images.push_back(cv::imread((kStreet / "rig" / ("cam" + std::to_string(c)) / name).string(), cv::IMREAD_COLOR));
  return images;
}

cv::Mat ToBgr8ForTest(const sphere::EquirectImage& img) {
  cv::Mat out(img.height, img.width, CV_8UC3);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int k = 0; k < 3; ++k)
        out.at<cv::Vec3b>(y, x)[2 - k] = static_cast<unsigned char>(std::lround(255 * LinearToSrgb(img.at(x, y)[k])));
  return out;
}

// PSNR in 8-bit sRGB (as the dataset's README reports it) over the valid mask.
double PsnrSrgbOverValid(const StitchedFrame& f, const cv::Mat& truth_bgr) {
  double se = 0;
  long n = 0;
  for (int row = 0; row < f.image.height; ++row)
    for (int col = 0; col < f.image.width; ++col) {
      if (!f.valid[static_cast<std::size_t>(row) * f.image.width + col]) continue;
      const auto& t = truth_bgr.at<cv::Vec3b>(row, col);
      for (int k = 0; k < 3; ++k) {
        const double s = std::lround(255 * LinearToSrgb(f.image.at(col, row)[k]));
        se += std::pow(s - t[2 - k], 2);
      }
      ++n;
    }
  return 10 * std::log10(255.0 * 255.0 / (se / (3.0 * n)));
}

// The same after a Gaussian (sigma 1.5 px) on both, over the valid mask shrunk by 4 px: the
// renders' Monte-Carlo noise (README: ~23 dB per image) averages out and geometry, parallax and
// exposure errors remain.
double PsnrSrgbBlurred(const StitchedFrame& f, const cv::Mat& truth_bgr) {
  cv::Mat mine = ToBgr8ForTest(f.image), a, b;
  cv::GaussianBlur(mine, a, cv::Size(0, 0), 1.5);
  cv::GaussianBlur(truth_bgr, b, cv::Size(0, 0), 1.5);
  cv::Mat mask(f.image.height, f.image.width, CV_8U, const_cast<std::uint8_t*>(f.valid.data()));
  cv::Mat eroded;
  cv::erode(mask, eroded, cv::Mat::ones(9, 9, CV_8U));
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  diff.convertTo(diff, CV_64FC3);
  diff = diff.mul(diff);
  const cv::Scalar se = cv::sum(diff.reshape(3, f.image.height).clone().setTo(cv::Scalar::all(0), eroded == 0));
  const double n = cv::countNonZero(eroded);
  return 10 * std::log10(255.0 * 255.0 / ((se[0] + se[1] + se[2]) / (3.0 * n)));
}

TEST(Stitcher, StreetRigMatchesTheGroundTruthPanorama) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const Rig rig = LoadRig(kStreet / "rig.json");
  // Half the panorama's size: the geometry, parallax and exposure errors this test is about are
  // all still visible, at a quarter of the cost (this suite runs under ASan in CI).
  StitchOptions o;
  o.width = 512;
  o.height = 256;
  Stitcher stitcher(rig, o);
  StitchOptions no_gain = o;
  no_gain.compensate_gains = false;
  Stitcher plain(rig, no_gain);
  // Rays meeting at 5 m (the facades' distance) undo much of the 0.08 m parallax.
  StitchOptions near = o;
  near.scene_distance_m = 5;
  Stitcher at5(rig, near);
  for (int frame : {0, 20}) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", frame);
    cv::Mat truth = cv::imread((kStreet / "pano" / name).string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(truth.empty());
    cv::resize(truth, truth, cv::Size(o.width, o.height), 0, 0, cv::INTER_AREA);
    const auto images = LoadStreetFrame(frame);
    const StitchedFrame f = stitcher.Stitch(images);
    const double psnr = PsnrSrgbOverValid(f, truth);
    const double psnr_plain = PsnrSrgbOverValid(plain.Stitch(images), truth);
    const double blurred = PsnrSrgbBlurred(f, truth);
    std::printf("street_a frame %d: PSNR %.2f dB, blurred %.2f dB (no gain compensation %.2f dB), %s\n", frame, psnr,
                blurred, psnr_plain, f.report.Summary().c_str());
    const StitchedFrame f5 = at5.Stitch(images);
    const double psnr5 = PsnrSrgbOverValid(f5, truth), blurred5 = PsnrSrgbBlurred(f5, truth);
    std::printf("  scene distance 5 m: PSNR %.2f dB, blurred %.2f dB\n", psnr5, blurred5);
    EXPECT_GT(psnr5, kStreetPsnr5mFloorDb);
    EXPECT_GT(blurred5, kStreetBlurredPsnr5mFloorDb);
    EXPECT_GT(blurred, kStreetBlurredPsnrFloorDb);
    EXPECT_GT(psnr, psnr_plain);  // compensation helps even against a gain-1 truth
    EXPECT_GT(psnr, kStreetPsnrFloorDb);
    EXPECT_GT(f.report.valid_fraction, 0.85);
    // The rig's gains (rig.json) are undone up to a common scale.
    const std::vector<double> truth_gain{1.123, 0.9632, 1.128, 1.1273, 1.0496, 0.9367};
    std::vector<double> p;
    for (int c = 0; c < 6; ++c) p.push_back(f.report.gains[c] * truth_gain[c]);
    const auto [lo, hi] = std::minmax_element(p.begin(), p.end());
    EXPECT_LT(*hi / *lo, 1.05) << f.report.Summary();
  }
}

// What camera c of `rig` records of World() painted on a sphere of radius `radius` around the
// rig centre (each camera sees it from its own centre, so the rays meet at `radius`), gain 1.
cv::Mat RenderCameraOnSphere(const Rig& rig, int c, double radius) {
  const RigCamera& cam = rig.cameras[static_cast<std::size_t>(c)];
  const Eigen::Vector3d centre = cam.rig_from_cam.topRightCorner<3, 1>();
  cv::Mat img(cam.model.height(), cam.model.width(), CV_8UC3, cv::Scalar(0, 0, 0));
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      Eigen::Vector3d b;
      if (!cam.model.Unproject({double(x), double(y)}, &b)) continue;
      const Eigen::Vector3d r = (cam.rig_from_cam.topLeftCorner<3, 3>() * b).normalized();
      const double along = centre.dot(r);
      const double s = -along + std::sqrt(along * along - centre.squaredNorm() + radius * radius);
      const Eigen::Vector3d o = OdvrFromRig((centre + s * r).normalized());
      const Eigen::Vector3f rgb = World({o.x(), o.y(), o.z()});
      auto& px = img.at<cv::Vec3b>(y, x);
      for (int k = 0; k < 3; ++k) px[2 - k] = static_cast<unsigned char>(std::lround(255 * LinearToSrgb(rgb[k])));
    }
  return img;
}

TEST(Stitcher, SceneDistanceIsChosenWhereTheSceneIs) {
  const Rig rig = SyntheticRig(240, 320);
  for (const double radius : {3.0, 8.0}) {
    std::vector<cv::Mat> images;
    for (int c = 0; c < 6; ++c) images.push_back(RenderCameraOnSphere(rig, c, radius));
    const SceneDistanceChoice choice = ChooseSceneDistance(rig, {images}, SmallOptions());
    std::printf("world at %.0f m: %s\n", radius, choice.Summary().c_str());
    EXPECT_EQ(choice.distance_m, radius) << choice.Summary();
    EXPECT_TRUE(choice.reason.empty()) << choice.Summary();
    ASSERT_EQ(choice.scores.size(), choice.candidates_m.size());
    // The chosen distance stitches the world closer to the truth than infinity does.
    StitchOptions at = SmallOptions(), far = SmallOptions();
    at.scene_distance_m = choice.distance_m;
    const double chosen = RmsAgainstWorld(Stitcher(rig, at).Stitch(images));
    const double infinity = RmsAgainstWorld(Stitcher(rig, far).Stitch(images));
    std::printf("  RMS against the world: %.5f chosen, %.5f at infinity\n", chosen, infinity);
    EXPECT_LT(chosen, infinity);
  }
}

TEST(Stitcher, SceneDistanceKeepsInfinityWithoutEvidence) {
  const Rig rig = SyntheticRig();
  // Textureless: every camera sees the same grey, so no distance aligns anything.
  const std::vector<cv::Mat> grey(6, cv::Mat(160, 120, CV_8UC3, cv::Scalar(120, 120, 120)));
  SceneDistanceChoice c = ChooseSceneDistance(rig, {grey}, SmallOptions());
  EXPECT_EQ(c.distance_m, 0);
  EXPECT_NE(c.reason.find("within rounding"), std::string::npos) << c.Summary();
  // Grey plus independent noise per camera: the scores differ by noise alone.
  std::vector<cv::Mat> noisy;
  cv::RNG rng(7);
  for (int k = 0; k < 6; ++k) {
    cv::Mat n(160, 120, CV_8UC3);
    rng.fill(n, cv::RNG::NORMAL, cv::Scalar::all(120), cv::Scalar::all(6));
    noisy.push_back(n);
  }
  c = ChooseSceneDistance(rig, {noisy}, SmallOptions());
  std::printf("noise alone: %s\n", c.Summary().c_str());
  EXPECT_EQ(c.distance_m, 0);
  EXPECT_NE(c.reason.find("no distance lowers"), std::string::npos) << c.Summary();
  // One camera left: nothing overlaps.
  auto images = RenderRig(rig, std::vector<double>(6, 1.0));
  for (int k = 1; k < 6; ++k) images[static_cast<std::size_t>(k)].setTo(cv::Scalar(0, 0, 0));
  c = ChooseSceneDistance(rig, {images}, SmallOptions());
  EXPECT_EQ(c.distance_m, 0);
  EXPECT_NE(c.reason.find("usable pixels"), std::string::npos) << c.Summary();
  // No frame set at all.
  c = ChooseSceneDistance(rig, {}, SmallOptions());
  EXPECT_EQ(c.distance_m, 0);
  EXPECT_FALSE(c.reason.empty());
  // Bad search settings are usage errors.
  SceneDistanceSearch bad;
  bad.candidates_m = {5, -1};
  EXPECT_THROW(ChooseSceneDistance(rig, {images}, SmallOptions(), bad), UsageError);
}

// PSNR (8-bit sRGB) against the truth over the seams: the pixels two or more cameras see.
double PsnrSrgbOverSeams(const Stitcher& stitcher, const StitchedFrame& f, const cv::Mat& truth_bgr) {
  StitchedFrame seams = f;
  const StitchLut& lut = stitcher.lut();
  for (std::size_t p = 0; p < lut.pixel_count(); ++p) seams.valid[p] = lut.offsets[p + 1] - lut.offsets[p] >= 2;
  return PsnrSrgbOverValid(seams, truth_bgr);
}

TEST(Stitcher, StreetSceneDistanceLowersTheSeamErrorAgainstTheGroundTruth) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const Rig rig = LoadRig(kStreet / "rig.json");
  StitchOptions o;
  o.width = 512;
  o.height = 256;
  Stitcher far(rig, o);
  for (int frame : {0, 20}) {
    const auto images = LoadStreetFrame(frame);
    const SceneDistanceChoice choice = ChooseSceneDistance(rig, {images}, o);
    std::printf("street_a frame %d: %s\n", frame, choice.Summary().c_str());
    // The street's facades and parked cars stand 5 to 15 m from the rig.
    EXPECT_GE(choice.distance_m, 5) << choice.Summary();
    EXPECT_LE(choice.distance_m, 20) << choice.Summary();
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", frame);
    cv::Mat truth = cv::imread((kStreet / "pano" / name).string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(truth.empty());
    cv::resize(truth, truth, cv::Size(o.width, o.height), 0, 0, cv::INTER_AREA);
    StitchOptions chosen_options = o;
    chosen_options.scene_distance_m = choice.distance_m;
    Stitcher chosen(rig, chosen_options);
    const StitchedFrame a = chosen.Stitch(images), b = far.Stitch(images);
    const double seams_chosen = PsnrSrgbOverSeams(chosen, a, truth), seams_far = PsnrSrgbOverSeams(far, b, truth);
    const double all_chosen = PsnrSrgbOverValid(a, truth), all_far = PsnrSrgbOverValid(b, truth);
    std::printf("  PSNR over the seams %.2f dB chosen, %.2f dB at infinity; over the frame %.2f / %.2f dB\n",
                seams_chosen, seams_far, all_chosen, all_far);
    EXPECT_GT(seams_chosen, seams_far + kStreetChosenSeamGainDb);
    EXPECT_GT(all_chosen, all_far);
  }
}

using StitcherGL = odvr::testing::GlTest;

double MaxDiff(const sphere::EquirectImage& a, const sphere::EquirectImage& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) m = std::max(m, double(std::abs(a.rgb[i] - b.rgb[i])));
  return m;
}

TEST_F(StitcherGL, GpuPathMatchesTheCpuReference) {
  // Both levels, and odd image sizes (the half-resolution level's repeated last column and row).
  for (const auto& [w, h, prefilter] :
       {std::tuple{120, 160, StitchOptions::Prefilter::kAuto}, std::tuple{121, 161, StitchOptions::Prefilter::kOn},
        std::tuple{121, 161, StitchOptions::Prefilter::kOff}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    const Rig rig = SyntheticRig(w, h);
    auto images = RenderRig(rig, {1.3, 0.7, 1.0, 1.3, 0.7, 1.15});
    images[4].setTo(cv::Scalar(0, 0, 0));     // the black-camera path too
    StitchOptions o = SmallOptions(150, 75);  // odd pyramid sizes: 75, 19, 5, 3
    o.prefilter = prefilter;
    Stitcher cpu(rig, o);
    o.device = StitchDevice::kGpu;
    Stitcher gpu(rig, o);
    const StitchedFrame a = cpu.Stitch(images), b = gpu.Stitch(images);
    ASSERT_EQ(a.valid, b.valid);
    EXPECT_EQ(a.report.gains, b.report.gains);  // both from the same CPU estimate
    // Same inputs (the sRGB table), same expressions; float rounding and fused multiply-adds
    // differ: 1e-5 absolute on values ~0.3.
    EXPECT_LT(MaxDiff(a.image, b.image), 1e-5);
    o.fill_unseen = false;
    Stitcher gpu_nofill(rig, o);
    o.device = StitchDevice::kCpu;
    Stitcher cpu_nofill(rig, o);
    EXPECT_LT(MaxDiff(cpu_nofill.Stitch(images).image, gpu_nofill.Stitch(images).image), 1e-5);
  }
}

TEST_F(StitcherGL, GpuPathMatchesTheCpuOnTheStreetRig) {
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)";
  const Rig rig = LoadRig(kStreet / "rig.json");
  StitchOptions o;
  o.width = 256;
  o.height = 128;
  Stitcher cpu(rig, o);
  o.device = StitchDevice::kGpu;
  Stitcher gpu(rig, o);
  const auto images = LoadStreetFrame(10);
  const StitchedFrame a = cpu.Stitch(images), b = gpu.Stitch(images);
  ASSERT_EQ(a.valid, b.valid);
  EXPECT_LT(MaxDiff(a.image, b.image), 1e-5);
  std::printf("street_a 256x128: CPU %.1f ms, GPU (llvmpipe here) %.1f ms\n", a.report.ms_total, b.report.ms_total);
  // The GPU warp's parts: the upload and the read-back inside its wall time, the passes' own
  // clock within it too (they run between the two); none of them on the CPU path.
  const StitchReport& g = b.report;
  EXPECT_GT(g.ms_upload, 0);
  EXPECT_GT(g.ms_gpu_passes, 0);
  EXPECT_GT(g.ms_readback, 0);
  EXPECT_LE(g.ms_upload + g.ms_readback, g.ms_warp);
  EXPECT_LE(g.ms_gpu_passes, g.ms_warp);
  EXPECT_EQ(a.report.ms_upload + a.report.ms_gpu_passes + a.report.ms_readback, 0);
}

}  // namespace
}  // namespace odvr::capture
