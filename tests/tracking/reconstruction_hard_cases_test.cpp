// The hard cases for structure from motion that cannot give a trajectory, each built
// from street_a's frames with a subset of cameras (to stay quick under sanitizers): the run stops
// with an error that names the cause. The cases with a bad part of the input that the rest
// carries are in reconstruction_degraded_input_test.cpp.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>
#include <random>

#include "capture/rig.h"
#include "tests/tracking/reconstruction_frames.h"
#include "tracking/reconstruction.h"

namespace odvr::tracking {
namespace {

using testing::ExpectError;
using testing::Frames;
using testing::HaveStreet;
using testing::kFront;
using testing::Original;
using testing::StreetDir;

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
  const capture::Rig rig = capture::LoadRig(StreetDir() / "rig.json");
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
