// One equirectangular camera, no rig (issue: your own 360° video): the demo street's ground-truth
// panoramas (media/demo/pano, in the repository) tracked as a consumer 360° clip, against the
// truth, and the hard cases a handheld or car-mounted camera meets, each made from those frames:
// a tripod, a pure rotation across the seam, a stop at a light, a start that does not move, and
// the camera's own mount in the nadir.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/camera_model.h"

#include "capture/equirect_view.h"
#include "capture/source.h"
#include "core/error.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::tracking {
namespace {

namespace fs = std::filesystem;
const fs::path kDemo = fs::path(ODVR_SOURCE_DIR) / "media/demo";
constexpr double kDemoHeight = 2.027356;  // the demo rig's height above the road (trajectory_gt.json)

cv::Mat Pano(int index) {
  char name[32];
  std::snprintf(name, sizeof name, "%06d.png", index);
  const cv::Mat m = cv::imread((kDemo / "pano" / name).string(), cv::IMREAD_COLOR);
  EXPECT_FALSE(m.empty()) << name;
  return m;
}

// The frame with sensor noise of its own (a camera never records the same picture twice).
cv::Mat Noisy(const cv::Mat& image, int seed) {
  cv::Mat noise(image.size(), CV_16SC3);
  cv::theRNG().state = static_cast<std::uint64_t>(seed) + 1;
  cv::randn(noise, 0, 2.0);
  cv::Mat out;
  image.convertTo(out, CV_16SC3);
  out += noise;
  out.convertTo(out, CV_8UC3);
  return out;
}

struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& name) {
    dir = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() { fs::remove_all(dir); }
  void Write(int i, const cv::Mat& image) const {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", i);
    cv::imwrite((dir / name).string(), image);
  }
};

Reconstruction ReconstructClip(const fs::path& frames, double height_m, const cv::Mat& ignore = cv::Mat()) {
  auto source = capture::OpenEquirectView(capture::OpenSource(frames.string()), {});
  const capture::Rig rig = capture::EquirectCameraRig(512, 256, height_m);
  ReconstructionOptions options = OneCameraReconstructionOptions();
  options.rig_height_m = height_m;
  if (!ignore.empty()) options.ignore_masks = {ignore};
  return Reconstruct(rig, *source, options);
}

TrajectoryErrors Evaluate(const Reconstruction& r) {
  std::vector<TrajectoryPose> estimate;
  for (const auto& f : r.frames) estimate.push_back({f.index, f.timestamp, f.world_from_rig.Matrix()});
  return EvaluateTrajectory(estimate, LoadTrajectoryJson(kDemo / "trajectory_gt.json"));
}

TEST(EquirectReconstruction, DemoPanoramasGiveTheTrueTrajectoryAtMetricScale) {
  const Reconstruction r = ReconstructClip(kDemo / "pano", kDemoHeight);
  const TrajectoryErrors e = Evaluate(r);
  std::printf("demo panoramas (512x256, 24 frames, one camera): %s; %zu points, RMSE %.3f px; %s\n",
              e.Summary().c_str(), r.points.size(), r.rmse_px, r.road.message.c_str());
  for (const auto& w : r.warnings) std::printf("  warning: %s\n", w.c_str());
  ASSERT_EQ(r.frames.size(), 24u) << "every frame posed";
  EXPECT_EQ(e.matched, 24);
  EXPECT_TRUE(r.road.found);
  EXPECT_LT(e.ate_percent, 0.5);
  // 512 wide, the road a few pixels deep: 2.9 % here; the bench holds 1024-wide video to 3 %.
  EXPECT_LT(std::abs(e.scale - 1), 0.05) << "metric from the camera height alone";
}

TEST(EquirectReconstruction, WithoutACameraHeightTheTrajectoryIsUpToScaleAndSaysSo) {
  const Reconstruction r = ReconstructClip(kDemo / "pano", 0);
  const TrajectoryErrors e = Evaluate(r);
  std::printf("no camera height: %s\n", e.Summary().c_str());
  ASSERT_EQ(r.frames.size(), 24u);
  EXPECT_LT(e.ate_percent, 0.5) << "the shape is right once scaled";
  bool said = false;
  for (const auto& w : r.warnings) said |= w.find("up to scale") != std::string::npos;
  EXPECT_TRUE(said);
}

TEST(EquirectReconstruction, ATripodClipStandsStillAndSaysSo) {
  Scratch s("odvr_equirect_tripod");
  for (int i = 0; i < 8; ++i) s.Write(i, Noisy(Pano(6), i));
  const Reconstruction r = ReconstructClip(s.dir, 1.5);
  ASSERT_EQ(r.frames.size(), 8u);
  bool said = false;
  for (const auto& w : r.warnings) said |= w.find("does not move") != std::string::npos;
  EXPECT_TRUE(said);
  double worst_deg = 0;
  for (const auto& f : r.frames) {
    EXPECT_NEAR(f.world_from_rig.translation.z(), 1.5, 1e-9) << "the camera stands at its height";
    EXPECT_LT(f.world_from_rig.translation.head<2>().norm(), 1e-9);
    worst_deg = std::max(worst_deg, Eigen::AngleAxisd(f.world_from_rig.rotation).angle() * 180 / M_PI);
  }
  std::printf("tripod: 8 frames at one position, rotation at most %.4f deg\n", worst_deg);
  EXPECT_LT(worst_deg, 0.1);
}

TEST(EquirectReconstruction, APureRotationAcrossTheSeamIsTrackedAsRotation) {
  // The camera turns 3.5 degrees a frame about the vertical (5 columns of 512): the picture
  // rolls, and what was at the seam crosses it.
  Scratch s("odvr_equirect_rotation");
  const cv::Mat base = Pano(6);
  constexpr int kStep = 5, kFrames = 12;
  for (int i = 0; i < kFrames; ++i) {
    cv::Mat rolled = base.clone();
    const int k = (i * kStep) % base.cols;
    if (k > 0) cv::hconcat(base.colRange(base.cols - k, base.cols), base.colRange(0, base.cols - k), rolled);
    s.Write(i, Noisy(rolled, i));
  }
  const Reconstruction r = ReconstructClip(s.dir, 1.5);
  ASSERT_EQ(r.frames.size(), static_cast<size_t>(kFrames));
  double worst = 0;
  for (int i = 0; i < kFrames; ++i) {
    // Rolling the image right by k columns is the camera turning left (counter-clockwise from above).
    const double expected = i * kStep * 360.0 / 512;
    const Eigen::Matrix3d& rot = r.frames[i].world_from_rig.rotation;
    const double yaw = std::atan2(rot(1, 0), rot(0, 0)) * 180 / M_PI;
    worst = std::max(worst, std::abs(std::remainder(yaw - expected, 360.0)));
  }
  std::printf("pure rotation, %d frames of %.2f deg: yaw error at most %.4f deg\n", kFrames, kStep * 360.0 / 512,
              worst);
  EXPECT_LT(worst, 0.1);
}

// The equirect image a camera turned by `cam0_from_cam` (OpenCV camera axes) sees of the scene
// `base` shows: each pixel's ray turned into the base camera's frame and sampled there.
cv::Mat Turned(const cv::Mat& base, const Eigen::Matrix3d& cam0_from_cam) {
  const capture::CameraModel model = capture::CameraModel::Equirectangular(base.cols, base.rows);
  cv::Mat map_x(base.size(), CV_32F), map_y(base.size(), CV_32F);
  for (int y = 0; y < base.rows; ++y)
    for (int x = 0; x < base.cols; ++x) {
      Eigen::Vector3d b;
      Eigen::Vector2d p(x, y);
      if (model.Unproject(Eigen::Vector2d(x, y), &b)) model.Project(cam0_from_cam * b, &p);
      map_x.at<float>(y, x) = static_cast<float>(p.x());
      map_y.at<float>(y, x) = static_cast<float>(p.y());
    }
  cv::Mat out;
  cv::remap(base, out, map_x, map_y, cv::INTER_CUBIC, cv::BORDER_WRAP);
  return out;
}

TEST(EquirectReconstruction, ARollCarriesFeaturesOverThePolesAndIsTrackedAsRotation) {
  // The camera rolls 3 degrees a frame about its forward axis: what was overhead sweeps sideways
  // through the zenith, where an equirect image stretches a point into a whole row.
  Scratch s("odvr_equirect_roll");
  const cv::Mat base = Pano(6);
  constexpr int kFrames = 10;
  constexpr double kStepDeg = 3;
  for (int i = 0; i < kFrames; ++i)
    s.Write(i, Noisy(Turned(base, Eigen::AngleAxisd(i * kStepDeg * M_PI / 180, Eigen::Vector3d::UnitZ()).matrix()), i));
  const Reconstruction r = ReconstructClip(s.dir, 1.5);
  ASSERT_EQ(r.frames.size(), static_cast<size_t>(kFrames));
  double worst_angle = 0, worst_axis = 0;
  for (int i = 1; i < kFrames; ++i) {
    const Eigen::AngleAxisd turn(r.frames[i].world_from_rig.rotation);
    worst_angle = std::max(worst_angle, std::abs(turn.angle() * 180 / M_PI - i * kStepDeg));
    worst_axis = std::max(worst_axis, 1 - std::abs(turn.axis().x()));  // the rig's x is forward
  }
  std::printf("roll over the poles, %d frames of %.0f deg: angle error at most %.4f deg, axis off forward by %.2e\n",
              kFrames, kStepDeg, worst_angle, worst_axis);
  // Measured: 0.12 deg short of 27 deg by frame 9, growing with the angle (0.4 %), whether the
  // polar rows take part or not; the yaw above, whole-pixel shifts, reads 0.003 deg.
  EXPECT_LT(worst_angle, 0.01 * kFrames * kStepDeg);
  EXPECT_LT(worst_axis, 1e-3);
}

TEST(EquirectReconstruction, AVehicleCrossingTheViewDoesNotDragTheTrajectory) {
  // A textured vehicle 80x36 px drives across the street ahead, 14 px a frame, against the
  // camera's own motion: its corners track well and move with it, not with the scene.
  Scratch s("odvr_equirect_vehicle");
  cv::Mat vehicle(36, 80, CV_8UC3);
  cv::theRNG().state = 11;
  cv::randu(vehicle, 0, 255);
  cv::GaussianBlur(vehicle, vehicle, cv::Size(0, 0), 1.2);
  for (int i = 0; i < 24; ++i) {
    cv::Mat frame = Pano(i);
    vehicle.copyTo(frame(cv::Rect(100 + 14 * i, 140, vehicle.cols, vehicle.rows)));
    s.Write(i, frame);
  }
  const Reconstruction r = ReconstructClip(s.dir, kDemoHeight);
  const TrajectoryErrors e = Evaluate(r);
  std::printf("a vehicle crossing the view: %s\n", e.Summary().c_str());
  ASSERT_EQ(r.frames.size(), 24u);
  EXPECT_LT(e.ate_percent, 0.5);
}

TEST(EquirectReconstruction, AStopAtALightKeepsEveryFramePosedWhereTheCameraStood) {
  Scratch s("odvr_equirect_stop");
  int n = 0;
  std::vector<long> truth_index;
  for (int i = 0; i < 24; ++i) {
    s.Write(n++, Pano(i));
    if (i == 11)
      for (int k = 0; k < 6; ++k) s.Write(n++, Noisy(Pano(11), k));
  }
  const Reconstruction r = ReconstructClip(s.dir, kDemoHeight);
  ASSERT_EQ(r.frames.size(), 30u) << "every frame posed";
  const Eigen::Vector3d stop = r.frames[11].world_from_rig.translation;
  double worst_stop = 0;
  for (int k = 12; k < 18; ++k)
    worst_stop = std::max(worst_stop, (r.frames[k].world_from_rig.translation - stop).norm());
  const double step = (r.frames[19].world_from_rig.translation - r.frames[18].world_from_rig.translation).norm();
  int stopped_keys = 0, interpolated = 0;
  for (int k = 12; k < 18; ++k) stopped_keys += r.frames[k].key;
  for (const auto& f : r.frames) interpolated += f.interpolated;
  std::printf(
      "stop-and-go: the 6 stopped frames within %.4f m of the stop, %d of them key frames; a moving step "
      "%.3f m\n",
      worst_stop, stopped_keys, step);
  // Standing still adds no depth: the stop's frames are posed against the map, not adjusted in it,
  // each within a tenth of a moving step of where the camera stopped.
  EXPECT_LT(worst_stop, 0.1 * step);
  EXPECT_EQ(stopped_keys, 0);
  EXPECT_EQ(interpolated, 0) << "each stopped frame sees the map";
  EXPECT_NEAR(step, 0.36, 0.03) << "9 m/s at 25 fps";
}

TEST(EquirectReconstruction, AClipWhoseFirstFramesDoNotMoveStartsWhereItMoves) {
  Scratch s("odvr_equirect_late_start");
  for (int k = 0; k < 12; ++k) s.Write(k, Noisy(Pano(0), k));
  for (int i = 1; i < 24; ++i) s.Write(11 + i, Pano(i));
  const Reconstruction r = ReconstructClip(s.dir, kDemoHeight);
  ASSERT_EQ(r.frames.size(), 35u) << "every frame posed";
  double worst = 0;
  for (int k = 1; k < 12; ++k)
    worst = std::max(worst, (r.frames[k].world_from_rig.translation - r.frames[0].world_from_rig.translation).norm());
  // Frame 11 is the truth's frame 0 (its last still copy), 11 + i the truth's frame i.
  std::vector<TrajectoryPose> moving;
  for (int k = 11; k < 35; ++k) moving.push_back({k - 11, 0, r.frames[k].world_from_rig.Matrix()});
  const TrajectoryErrors e = EvaluateTrajectory(moving, LoadTrajectoryJson(kDemo / "trajectory_gt.json"));
  int still_keys = 0;
  for (int k = 0; k < 11; ++k) still_keys += r.frames[k].key;
  std::printf(
      "late start: the 12 still frames within %.4f m of each other, %d key frame(s) among the first 11; "
      "moving: %s\n",
      worst, still_keys, e.Summary().c_str());
  EXPECT_LT(worst, 0.03) << "a tenth of a moving step (0.36 m)";
  EXPECT_EQ(still_keys, 1) << "frame 0 alone: the still copies after it add no parallax";
  EXPECT_LT(e.ate_percent, 0.5);
  EXPECT_LT(std::abs(e.scale - 1), 0.1);
}

TEST(EquirectReconstruction, TheCamerasMountInTheNadirIsMaskedOut) {
  // A textured mount fixed to the camera (it moves with it) fills the bottom 50 degrees: tracked,
  // it pulls the motion towards standing still; masked, the street alone is tracked.
  Scratch s("odvr_equirect_mount");
  cv::Mat mount(256 * 50 / 180, 512, CV_8UC3);
  cv::theRNG().state = 7;
  cv::randu(mount, 0, 255);
  cv::GaussianBlur(mount, mount, cv::Size(0, 0), 1.5);
  for (int i = 0; i < 24; ++i) {
    cv::Mat frame = Pano(i);
    mount.copyTo(frame.rowRange(256 - mount.rows, 256));
    s.Write(i, frame);
  }
  cv::Mat ignore = cv::Mat::zeros(256, 512, CV_8U);
  ignore.rowRange(256 - mount.rows - 2, 256).setTo(255);
  const Reconstruction masked = ReconstructClip(s.dir, 0, ignore);
  const TrajectoryErrors e = Evaluate(masked);
  std::printf("mount in the nadir, masked: %s\n", e.Summary().c_str());
  ASSERT_EQ(masked.frames.size(), 24u);
  EXPECT_LT(e.ate_percent, 0.5);
}

// A clip longer than a chunk is reconstructed a chunk at a time, each chained to the one before by
// the frames they share: every frame posed once, in order, the trajectory still the true one.
TEST(EquirectReconstruction, ALongClipIsReconstructedInChainedChunks) {
  const capture::Rig rig = capture::EquirectCameraRig(512, 256, kDemoHeight);
  ReconstructionOptions options = OneCameraReconstructionOptions();
  options.rig_height_m = kDemoHeight;
  options.chunk_frames = 12;  // frames 0-11, 9-20, 18-23
  options.chunk_overlap = 3;
  auto source = capture::OpenEquirectView(capture::OpenSource((kDemo / "pano").string()), {});
  const Reconstruction r = Reconstruct(rig, *source, options);
  const TrajectoryErrors e = Evaluate(r);
  std::printf("24 frames in chunks of 12 overlapping by 3: %s\n", e.Summary().c_str());
  ASSERT_EQ(r.frames.size(), 24u);
  for (size_t i = 0; i < r.frames.size(); ++i) EXPECT_EQ(r.frames[i].index, static_cast<long>(i));
  const auto chunks = std::find_if(r.stages.begin(), r.stages.end(), [](const auto& s) { return s.name == "chunks"; });
  ASSERT_NE(chunks, r.stages.end());
  EXPECT_EQ(chunks->inliers, 3) << chunks->what;
  for (const auto& p : r.points)
    for (const auto& o : p.observations) ASSERT_LT(o.frame, 24);
  EXPECT_LT(e.ate_percent, 1.0);
  EXPECT_LT(std::abs(e.scale - 1), 0.05) << "each chunk metric from the camera height";

  options.max_frames = 20;
  source = capture::OpenEquirectView(capture::OpenSource((kDemo / "pano").string()), {});
  EXPECT_EQ(Reconstruct(rig, *source, options).frames.size(), 20u) << "a frame count ends the last chunk";
}

TEST(EquirectReconstruction, AWrongSizedMaskIsAOneLineError) {
  try {
    ReconstructClip(kDemo / "pano", 0, cv::Mat::zeros(10, 20, CV_8U));
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("klt mask: is 20x10 but the camera model is equirectangular 512x256"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace odvr::tracking
