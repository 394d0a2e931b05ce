// One eye of a 360° clip, as structure from motion reads it: the layout a frame's shape implies,
// the eye cropped, scaled and stepped, on real files written to a scratch folder.
#include "capture/equirect_view.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "core/error.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;

TEST(EquirectView, TheFramesShapeNamesTheLayout) {
  EXPECT_EQ(GuessStereoLayout(2048, 1024), StereoLayout::kMono);
  EXPECT_EQ(GuessStereoLayout(2048, 2048), StereoLayout::kTopBottom);
  EXPECT_EQ(GuessStereoLayout(4096, 1024), StereoLayout::kSideBySide);
  EXPECT_EQ(ParseStereoLayout("tb"), StereoLayout::kTopBottom);
  EXPECT_EQ(ParseStereoLayout("side-by-side"), StereoLayout::kSideBySide);
  EXPECT_THROW(ParseStereoLayout("anaglyph"), Error);
}

TEST(EquirectView, ItDeliversTheChosenEyeScaledAndEveryStepthFrame) {
  const fs::path dir = fs::temp_directory_path() / ("odvr_equirect_view_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // Top-bottom stereo, 64x64: the top eye grey level 10 * frame, the bottom 200.
  for (int i = 0; i < 6; ++i) {
    cv::Mat frame(64, 64, CV_8UC3, cv::Scalar(200, 200, 200));
    frame.rowRange(0, 32).setTo(cv::Scalar::all(10 * i));
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", i);
    cv::imwrite((dir / name).string(), frame);
  }
  EquirectViewOptions options;
  options.layout = StereoLayout::kTopBottom;
  options.width = 32;
  options.step = 2;
  auto top = OpenEquirectView(OpenSource(dir.string()), options);
  EXPECT_EQ(top->frame_count(), 3);
  std::vector<long> indices;
  while (auto set = top->Next()) {
    const cv::Mat& image = set->frames[0].image;
    ASSERT_EQ(image.cols, 32);
    ASSERT_EQ(image.rows, 16);
    EXPECT_EQ(image.at<cv::Vec3b>(8, 16)[0], 10 * set->frames[0].index);
    indices.push_back(set->frames[0].index);
  }
  EXPECT_EQ(indices, (std::vector<long>{0, 2, 4})) << "the video's own frame numbers";
  options.eye = 1;
  auto bottom = OpenEquirectView(OpenSource(dir.string()), options);
  EXPECT_EQ(bottom->Next()->frames[0].image.at<cv::Vec3b>(8, 16)[0], 200);
  fs::remove_all(dir);
}

TEST(EquirectView, OptionsOutOfRangeAreRefused) {
  EquirectViewOptions o;
  o.eye = 2;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.step = 0;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.width = 33;
  EXPECT_THROW(o.Check(), Error);
}

TEST(EquirectView, TheOneCameraRigLooksForwardWithItsCentreColumn) {
  const Rig rig = EquirectCameraRig(512, 256, 1.6);
  ASSERT_EQ(rig.camera_count(), 1);
  EXPECT_DOUBLE_EQ(rig.height_m, 1.6);
  // The camera's optical axis (OpenCV z), which the centre column sees, is the rig's x (forward);
  // image down (y) is the rig's -z.
  const Eigen::Matrix3d r = rig.cameras[0].rig_from_cam.topLeftCorner<3, 3>();
  EXPECT_TRUE(r.col(2).isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(r.col(1).isApprox(-Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(r.determinant(), 1, 1e-12);
}

}  // namespace
}  // namespace odvr::capture
