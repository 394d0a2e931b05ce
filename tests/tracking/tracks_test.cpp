// KLT tracks on the street_a fisheye frames (lengths, coverage, the forward-backward check) and on
// a synthetic sequence of known sub-pixel shifts (accuracy).
#include "tracking/tracks.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "capture/rig.h"
#include "core/error.h"

namespace odvr::tracking {
namespace {

namespace fs = std::filesystem;
const fs::path kStreet = fs::path(ODVR_SHARED_DIR) / "data/street_a";

// A user's clone has no ../shared: each test on street_a's frames skips, saying so.
#define SKIP_WITHOUT_STREET_A() \
  if (!fs::exists(kStreet / "rig.json")) GTEST_SKIP() << kStreet << " absent (no ../shared data)"

capture::CameraModel Cam0() { return capture::LoadRig(kStreet / "rig.json").cameras[0].model; }

cv::Mat Cam0Frame(int i) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.jpg", i);
  const cv::Mat image = cv::imread((kStreet / "rig/cam0" / name).string(), cv::IMREAD_COLOR);
  if (image.empty()) ADD_FAILURE() << "cannot read " << (kStreet / "rig/cam0" / name);
  return image;
}

TEST(Tracks, StreetCam0TenFramesGivesLongTracksThatCoverTheImage) {
  SKIP_WITHOUT_STREET_A();
  KltTracker tracker(Cam0());
  for (int i = 0; i < 10; ++i) tracker.AddFrame(Cam0Frame(i));
  std::cout << tracker.BriefReport() << "\n";
  for (const auto& s : tracker.stats())
    std::cout << "  frame " << s.frame << ": continued " << s.continued << ", lost LK " << s.lost_lk << ", lost FB "
              << s.lost_forward_backward << ", new " << s.detected << ", active " << s.active << ", cells "
              << s.covered_cells << "\n";
  const auto& stats = tracker.stats();
  EXPECT_GE(stats.front().detected, 250);
  EXPECT_GE(stats.back().active, 200);
  EXPECT_GE(stats.back().covered_cells, 0.55);
  // Tracks alive from frame 0 through 9: the long ones the seed asks for.
  int full_length = 0;
  for (const Track& t : tracker.tracks()) full_length += t.length() == 10;
  std::cout << full_length << " tracks span all 10 frames\n";
  EXPECT_GE(full_length, 80);
  EXPECT_GE(tracker.MeanTrackLength(), 3.2);
  // Every observation: consecutive frames, on the mask, bearing = the model's bearing of the pixel.
  const capture::CameraModel model = Cam0();
  for (const Track& t : tracker.tracks()) {
    for (int k = 0; k < t.length(); ++k) {
      const TrackObservation& o = t.observations[k];
      if (k > 0) {
        ASSERT_EQ(o.frame, t.observations[k - 1].frame + 1);
      }
      Eigen::Vector3d b;
      ASSERT_TRUE(model.Unproject(o.pixel, &b));
      ASSERT_LT((b - o.bearing).norm(), 1e-12);
      ASSERT_NE(tracker.mask().at<uint8_t>(static_cast<int>(std::lround(o.pixel.y())),
                                           static_cast<int>(std::lround(o.pixel.x()))),
                0);
    }
  }
}

TEST(Tracks, ForwardBackwardCheckRejectsTracksIntoNoise) {
  SKIP_WITHOUT_STREET_A();
  // Frame 1 with a block of random noise: LK still "finds" something for the corners under it,
  // but tracking back does not return to the start.
  const cv::Mat frame0 = Cam0Frame(0);
  cv::Mat frame1 = Cam0Frame(1);
  const cv::Rect block(140, 200, 200, 240);
  cv::Mat noise(block.size(), CV_8UC3);
  cv::randu(noise, 0, 256);
  noise.copyTo(frame1(block));
  auto inside = [&](const Eigen::Vector2d& p) {
    return block.contains(cv::Point(static_cast<int>(p.x()), static_cast<int>(p.y())));
  };
  auto run = [&](double max_fb_px, const cv::Mat& next, int* inside_started, int* inside_survived, int* outside_started,
                 int* outside_survived) {
    KltOptions options;
    options.max_forward_backward_px = max_fb_px;
    KltTracker tracker(Cam0(), options);
    tracker.AddFrame(frame0);
    tracker.AddFrame(next);
    *inside_started = *inside_survived = *outside_started = *outside_survived = 0;
    for (const Track& t : tracker.tracks()) {
      if (t.observations.front().frame != 0) continue;
      // Shrunk by the LK window: corners near the block's edge see partly real texture.
      const bool deep = inside(t.observations.front().pixel + Eigen::Vector2d(12, 12)) &&
                        inside(t.observations.front().pixel - Eigen::Vector2d(12, 12));
      const bool far = !inside(t.observations.front().pixel + Eigen::Vector2d(12, 12)) &&
                       !inside(t.observations.front().pixel - Eigen::Vector2d(12, 12)) &&
                       !inside(t.observations.front().pixel + Eigen::Vector2d(12, -12)) &&
                       !inside(t.observations.front().pixel + Eigen::Vector2d(-12, 12));
      if (deep) {
        ++*inside_started;
        *inside_survived += t.length() == 2;
      } else if (far) {
        ++*outside_started;
        *outside_survived += t.length() == 2;
      }
    }
  };
  int in_started, in_survived, out_started, out_survived;
  run(1.0, frame1, &in_started, &in_survived, &out_started, &out_survived);
  // The same corners into the untouched frame 1: the survival rate away from the noise.
  int clean_in_started, clean_in_survived, clean_out_started, clean_out_survived;
  run(1.0, Cam0Frame(1), &clean_in_started, &clean_in_survived, &clean_out_started, &clean_out_survived);
  std::cout << "clean frame: " << clean_in_survived << "/" << clean_in_started << " in the block, "
            << clean_out_survived << "/" << clean_out_started << " outside\n";
  std::cout << "FB 1 px: inside noise " << in_survived << "/" << in_started << " survive, outside " << out_survived
            << "/" << out_started << "\n";
  ASSERT_GE(in_started, 20);
  EXPECT_LE(in_survived, 0.05 * in_started);
  EXPECT_GE(clean_in_survived, 0.5 * clean_in_started);
  EXPECT_GE(out_survived, 0.95 * clean_out_survived);
  // Without the check (a threshold no track exceeds) the tracks into noise mostly survive: the
  // check, not LK's own status, is what removed them.
  int in_started_off, in_survived_off, out_started_off, out_survived_off;
  run(1e6, frame1, &in_started_off, &in_survived_off, &out_started_off, &out_survived_off);
  std::cout << "FB off: inside noise " << in_survived_off << "/" << in_started_off << " survive\n";
  EXPECT_GE(in_survived_off, 0.5 * in_started_off);
}

TEST(Tracks, SubPixelShiftsAreTrackedToATenthOfAPixel) {
  SKIP_WITHOUT_STREET_A();
  // A textured image (street frame, slightly blurred so bilinear resampling is close to exact)
  // shifted by known sub-pixel amounts; LK must report those shifts.
  cv::Mat base;
  cv::GaussianBlur(Cam0Frame(0), base, cv::Size(0, 0), 1.2);
  const std::vector<Eigen::Vector2d> shifts = {{0, 0}, {0.37, -0.21}, {0.81, -0.55}, {1.43, -0.62}, {1.9, -1.13}};
  KltTracker tracker(Cam0());
  for (const auto& s : shifts) {
    cv::Mat shifted;
    const cv::Mat m = (cv::Mat_<double>(2, 3) << 1, 0, s.x(), 0, 1, s.y());
    cv::warpAffine(base, shifted, m, base.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
    tracker.AddFrame(shifted);
  }
  double sum_sq = 0, worst = 0;
  int n = 0;
  for (const Track& t : tracker.tracks()) {
    if (t.observations.front().frame != 0) continue;
    for (const TrackObservation& o : t.observations) {
      const Eigen::Vector2d expected = t.observations.front().pixel + shifts[o.frame];
      const double e = (o.pixel - expected).norm();
      sum_sq += e * e;
      worst = std::max(worst, e);
      ++n;
    }
  }
  const double rms = std::sqrt(sum_sq / n);
  std::cout << n << " observations, displacement error RMS " << rms << " px, worst " << worst << " px\n";
  ASSERT_GE(n, 1000);
  EXPECT_LT(rms, 0.1);
}

TEST(Tracks, BadFramesAndOptionsAreOneLineErrors) {
  SKIP_WITHOUT_STREET_A();
  KltTracker tracker(Cam0());
  try {
    tracker.AddFrame(cv::Mat(100, 100, CV_8UC3, cv::Scalar(0)));
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("klt frame 0: image is 100x100 but the camera model is fisheye 480x640"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(tracker.AddFrame(cv::Mat()), Error);
  KltOptions options;
  options.window_px = 20;
  try {
    KltTracker bad(Cam0(), options);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "klt window_px: must be odd and >= 5");
  }
  // A black frame: no corners, no tracks, no crash.
  KltTracker dark(Cam0());
  EXPECT_EQ(dark.AddFrame(cv::Mat(640, 480, CV_8UC3, cv::Scalar(0))).detected, 0);
  EXPECT_EQ(dark.AddFrame(cv::Mat(640, 480, CV_8UC3, cv::Scalar(0))).active, 0);
}

}  // namespace
}  // namespace odvr::tracking
