// The hard cases for structure from motion, each built from street_a's frames with a
// subset of cameras (to stay quick under sanitizers): the run either gives finite poses within
// measured bounds or stops with an error that names the cause.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <functional>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "capture/source.h"
#include "engine/core/error.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::tracking {
namespace {

namespace fs = std::filesystem;
const fs::path kStreet = fs::path(ODVR_SHARED_DIR) / "data/street_a";

std::string Name(long index) {
  char name[32];
  std::snprintf(name, sizeof name, "%06ld.jpg", index);
  return name;
}

cv::Mat Original(int camera, int index) {
  const cv::Mat m =
      cv::imread((kStreet / "rig" / ("cam" + std::to_string(camera)) / Name(index)).string(), cv::IMREAD_COLOR);
  EXPECT_FALSE(m.empty()) << "camera " << camera << " frame " << index;
  return m;
}

// A scratch folder per camera; make(camera, index) gives the image of output frame `index`
// (an empty Mat leaves the file out).
struct Frames {
  Frames(const std::string& tag, const std::vector<int>& cameras, int count,
         const std::function<cv::Mat(int camera, int index)>& make) {
    dir = fs::temp_directory_path() / ("odvr_hard_" + tag + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    const capture::Rig full = capture::LoadRig(kStreet / "rig.json");
    for (int c : cameras) {
      const fs::path cam = dir / full.cameras[c].name;
      fs::create_directories(cam);
      dirs.push_back(cam.string());
      rig.cameras.push_back(full.cameras[c]);
      for (int i = 0; i < count; ++i) {
        const cv::Mat image = make(c, i);
        if (!image.empty()) cv::imwrite((cam / Name(i)).string(), image, {cv::IMWRITE_JPEG_QUALITY, 95});
      }
    }
    rig.height_m = full.height_m;
    rig.path = kStreet / "rig.json";
  }
  ~Frames() { fs::remove_all(dir); }

  Reconstruction Run() const {
    auto source = capture::OpenImageSequences(dirs, {});
    return Reconstruct(rig, *source, ReconstructionOptions());
  }

  fs::path dir;
  std::vector<std::string> dirs;
  capture::Rig rig;
};

void ExpectError(const std::function<void()>& run, const std::vector<std::string>& needles) {
  try {
    run();
    ADD_FAILURE() << "no error; expected one saying '" << needles.front() << "'";
  } catch (const Error& e) {
    std::cout << "error: " << e.what() << "\n";
    for (const auto& n : needles) EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << e.what();
  }
}

TrajectoryErrors Evaluate(const Reconstruction& r, bool skip_duplicates = false) {
  std::vector<TrajectoryPose> estimate;
  for (const auto& f : r.frames) {
    EXPECT_TRUE(f.world_from_rig.AllFinite()) << "frame " << f.index;
    if (skip_duplicates && f.duplicate_of >= 0) continue;
    estimate.push_back({f.index, f.timestamp, f.world_from_rig.Matrix()});
  }
  const TrajectoryErrors e = EvaluateTrajectory(estimate, LoadTrajectoryJson(kStreet / "trajectory_gt.json"));
  for (const auto& s : r.stages) std::cout << s.name << ": " << s.inliers << " " << s.what << "\n";
  for (const auto& w : r.warnings) std::cout << "warning: " << w << "\n";
  std::cout << e.Summary() << "\n";
  return e;
}

bool HaveStreet() { return fs::exists(kStreet / "rig.json"); }

// The front three cameras: enough overlap for links, a third of the work.
const std::vector<int> kFront = {0, 1, 5};

TEST(ReconstructionHardCases, SequenceShorterThanThreeFrames) {
  if (!HaveStreet()) GTEST_SKIP();
  const Frames f("short", kFront, 2, Original);
  ExpectError([&] { f.Run(); }, {"only 2 distinct frame set", "need at least 3"});
}

TEST(ReconstructionHardCases, RigFileContradictsTheImageSize) {
  if (!HaveStreet()) GTEST_SKIP();
  Frames f("size", kFront, 3, Original);
  const auto& m = f.rig.cameras[1].model;
  f.rig.cameras[1].model = capture::CameraModel::Fisheye(640, 480, m.fx(), m.fy(), 319.5, 239.5);
  ExpectError([&] { f.Run(); }, {"camera cam1", "images are 480x640", "says 640x480"});
}

TEST(ReconstructionHardCases, StaticCamera) {
  if (!HaveStreet()) GTEST_SKIP();
  // Frame 0 again and again, each with its own sensor noise (so no frame is an exact duplicate).
  std::mt19937 rng(3);
  const Frames f("static", kFront, 4, [&](int c, int) {
    cv::Mat image = Original(c, 0), noise(image.size(), CV_16SC3);
    cv::randn(noise, 0, 2);
    cv::Mat out;
    image.convertTo(out, CV_16SC3);
    out += noise;
    out.convertTo(out, CV_8UC3);
    return out;
  });
  ExpectError([&] { f.Run(); }, {"does not move enough", "static camera or a pure rotation"});
}

TEST(ReconstructionHardCases, PureRotation) {
  if (!HaveStreet()) GTEST_SKIP();
  // Frame 0 seen by the rig turned about its vertical axis by 1.5 degrees per frame: every pixel's
  // ray is turned and looked up in the same camera's frame 0 (the cameras' 8 cm offsets move by
  // 2 mm, far below a pixel's worth of parallax).
  const capture::Rig rig = capture::LoadRig(kStreet / "rig.json");
  const Frames f("rotation", kFront, 4, [&](int c, int k) {
    const auto& model = rig.cameras[c].model;
    const Eigen::Matrix3d r = rig.cameras[c].rig_from_cam.topLeftCorner<3, 3>();
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(k * 1.5 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Matrix3d cam0_from_camk = r.transpose() * turn * r;
    cv::Mat map_x(model.height(), model.width(), CV_32F, cv::Scalar(-1)), map_y = map_x.clone();
    for (int y = 0; y < model.height(); ++y)
      for (int x = 0; x < model.width(); ++x) {
        Eigen::Vector3d b;
        Eigen::Vector2d p;
        if (!model.Unproject(Eigen::Vector2d(x, y), &b) || !model.Project(cam0_from_camk * b, &p)) continue;
        map_x.at<float>(y, x) = static_cast<float>(p.x());
        map_y.at<float>(y, x) = static_cast<float>(p.y());
      }
    cv::Mat out;
    cv::remap(Original(c, 0), out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
    return out;
  });
  ExpectError([&] { f.Run(); }, {"does not move enough", "pure rotation"});
}

TEST(ReconstructionHardCases, OneCameraBlack) {
  if (!HaveStreet()) GTEST_SKIP();
  const Frames f("black", {0, 1, 3, 5}, 6, [](int c, int k) {
    cv::Mat image = Original(c, k);
    if (c == 3) image.setTo(0);
    return image;
  });
  const Reconstruction r = f.Run();
  ASSERT_EQ(r.frames.size(), 6u);
  ASSERT_EQ(r.tracks_per_camera.size(), 4u);
  EXPECT_EQ(r.tracks_per_camera[2], 0);  // cam3 is the third camera of this rig
  bool warned = false;
  for (const auto& w : r.warnings) warned = warned || w.find("camera cam3 produced no tracks") != std::string::npos;
  EXPECT_TRUE(warned);
  EXPECT_TRUE(r.road.found) << r.road.message;
  const TrajectoryErrors e = Evaluate(r);
  EXPECT_LT(e.scale_error, 0.03);  // measured 1.8 % (14 road points from three cameras)
  EXPECT_LT(e.ate_percent, 0.3);   // measured 0.08 %
}

TEST(ReconstructionHardCases, DroppedAndDuplicatedFrames) {
  if (!HaveStreet()) GTEST_SKIP();
  // Frame 3 is missing from every camera, frame 5 from cam1 only, and frame 7 repeats frame 6.
  const Frames f("dropped", kFront, 9, [](int c, int k) {
    if (k == 3 || (k == 5 && c == 1)) return cv::Mat();
    return Original(c, k == 7 ? 6 : k);
  });
  const Reconstruction r = f.Run();
  std::vector<long> indices;
  for (const auto& fr : r.frames) indices.push_back(fr.index);
  EXPECT_EQ(indices, (std::vector<long>{0, 1, 2, 4, 5, 6, 7, 8}));
  EXPECT_EQ(r.dropped_frames, std::vector<long>{3});
  const ReconstructedFrame& dup = r.frames[6];
  EXPECT_EQ(dup.index, 7);
  ASSERT_EQ(dup.duplicate_of, 5);
  EXPECT_EQ((dup.world_from_rig.translation - r.frames[5].world_from_rig.translation).norm(), 0.0);
  const TrajectoryErrors e = Evaluate(r, /*skip_duplicates=*/true);
  EXPECT_EQ(e.matched, 7);
  EXPECT_LT(e.ate_percent, 0.3);    // measured 0.08 %
  EXPECT_LT(e.scale_error, 0.015);  // measured 0.01 %
  for (const auto& fr : r.frames)
    if (fr.duplicate_of < 0) {
      EXPECT_GT(fr.inliers, 100) << "frame " << fr.index;
    }
}

TEST(ReconstructionHardCases, TexturelessStretch) {
  if (!HaveStreet()) GTEST_SKIP();
  const Frames f("textureless", kFront, 5, [](int c, int k) {
    if (k == 3 || k == 4) return cv::Mat(640, 480, CV_8UC3, cv::Scalar(128, 128, 128));
    return Original(c, k);
  });
  ExpectError([&] { f.Run(); }, {"frame 3: cannot be registered", "textureless"});
}

}  // namespace
}  // namespace odvr::tracking
