// The rig calibration file: both layouts, the datasets' rig.json, and one-line errors that
// name the file for every malformed input.
#include "capture/rig.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "tests/error_message.h"

namespace odvr::capture {
namespace {

namespace fs = std::filesystem;
using odvr::testing::ErrorMessageOf;

const fs::path kStreetRig = fs::path(ODVR_SHARED_DIR) / "data/street_a/rig.json";

nlohmann::json StreetRigJson() {
  std::ifstream in(kStreetRig);
  return nlohmann::json::parse(in);
}

// The message of the odvr::Error `f` throws; fails the test when it throws nothing.
// A scratch folder per test; the suite must be named Rig (ctest filters on it), so no fixture.
struct TempDir {
  TempDir() {
    dir = fs::temp_directory_path() / ("odvr_rig_" + std::to_string(::getpid()) + "_" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir);
  }
  ~TempDir() { fs::remove_all(dir); }
  fs::path Write(const std::string& name, const std::string& text) const {
    const fs::path p = dir / name;
    std::ofstream(p) << text;
    return p;
  }
  // Loading `text` fails with one line that names the file and contains `needle`.
  void ExpectError(const std::string& text, const std::string& needle) const {
    const fs::path p = Write("bad.json", text);
    const std::string msg = ErrorMessageOf([&] { LoadRig(p); });
    EXPECT_EQ(msg.rfind(p.string() + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(needle), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
  fs::path dir;
};

TEST(Rig, ReadsTheStreetDatasetRigJson) {
  if (!fs::exists(kStreetRig)) GTEST_SKIP() << kStreetRig << " absent (no ../shared data)";
  const Rig rig = LoadRig(kStreetRig);
  ASSERT_EQ(rig.camera_count(), 6);
  EXPECT_NEAR(rig.height_m, 2.064687, 1e-9);
  for (int c = 0; c < 6; ++c) {
    const RigCamera& cam = rig.cameras[static_cast<std::size_t>(c)];
    EXPECT_EQ(cam.name, "cam" + std::to_string(c));
    EXPECT_EQ(cam.image_dir, "rig/cam" + std::to_string(c));
    EXPECT_EQ(cam.model.type(), CameraModelType::kFisheye);
    EXPECT_EQ(cam.model.width(), 480);
    EXPECT_EQ(cam.model.height(), 640);
    // The optical axis (camera +z) points at yaw 60 c degrees in the rig's horizontal plane,
    // and the camera sits 0.08 m out along it (README: conventions).
    const Eigen::Vector3d axis = cam.rig_from_cam.topLeftCorner<3, 3>() * Eigen::Vector3d::UnitZ();
    const double yaw = std::atan2(axis.y(), axis.x()) * 180 / M_PI;
    EXPECT_NEAR(std::remainder(yaw - 60.0 * c, 360.0), 0, 1e-6);
    EXPECT_NEAR(axis.z(), 0, 1e-9);
    EXPECT_NEAR((cam.rig_from_cam.topRightCorner<3, 1>() - 0.08 * axis).norm(), 0, 1e-8);
    // Camera up (-y) is rig up (+z).
    EXPECT_NEAR((cam.rig_from_cam.topLeftCorner<3, 3>() * -Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitZ()).norm(),
                0, 1e-9);
  }
}

TEST(Rig, RigFrameToOdvrFrameFollowsTheEquirectConvention) {
  // Rig forward/left/up -> odvr +X / -Z / +Y.
  EXPECT_EQ(OdvrFromRig({1, 0, 0}), Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(OdvrFromRig({0, 1, 0}), Eigen::Vector3d(0, 0, -1));
  EXPECT_EQ(OdvrFromRig({0, 0, 1}), Eigen::Vector3d(0, 1, 0));
  const Eigen::Vector3d v(0.3, -1.2, 2.5);
  EXPECT_EQ(RigFromOdvr(OdvrFromRig(v)), v);
}

TEST(Rig, SaveThenLoadRoundTripsEveryModel) {
  const TempDir t;
  Rig rig;
  rig.height_m = 1.75;
  RigCamera a{"front", CameraModel::Pinhole(640, 480, 500, 501, 320.5, 240.5, {-0.1, 0.02, 0.001, -0.002, 0.003}),
              Eigen::Matrix4d::Identity(), "front"};
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  pose.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  pose.topRightCorner<3, 1>() = Eigen::Vector3d(0.1, -0.2, 0.05);
  RigCamera b{"fish", CameraModel::Fisheye(1568, 1504, 420.5, 421, 785.2, 751.9, {0.02, -0.004, 0.001, -0.0002}), pose,
              ""};
  RigCamera c{"pano", CameraModel::Equirectangular(2048, 1024), Eigen::Matrix4d::Identity(), ""};
  rig.cameras = {a, b, c};
  const fs::path p = t.dir / "rig.json";
  SaveRig(p, rig);
  const Rig back = LoadRig(p);
  ASSERT_EQ(back.camera_count(), 3);
  EXPECT_EQ(back.height_m, 1.75);
  for (int i = 0; i < 3; ++i) {
    const auto& x = rig.cameras[static_cast<std::size_t>(i)];
    const auto& y = back.cameras[static_cast<std::size_t>(i)];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.model.Describe(), y.model.Describe());
    EXPECT_EQ(x.model.distortion(), y.model.distortion());
    EXPECT_LT((x.rig_from_cam - y.rig_from_cam).norm(), 1e-15);
  }
  EXPECT_EQ(back.cameras[0].image_dir, "front");
}

// config/demo_rig.json is the demo rig in our own layout: the same cameras as the dataset-style
// media/demo/rig.json, and its image folders resolve to the demo's images.
TEST(Rig, TheConfigDemoRigIsTheMediaDemoRig) {
  const fs::path source(ODVR_SOURCE_DIR);
  const Rig config = LoadRig(source / "config/demo_rig.json");
  const Rig media = LoadRig(source / "media/demo/rig.json");
  ASSERT_EQ(config.camera_count(), 6);
  ASSERT_EQ(config.camera_count(), media.camera_count());
  EXPECT_DOUBLE_EQ(config.height_m, media.height_m);
  for (int i = 0; i < config.camera_count(); ++i) {
    const auto& a = config.cameras[static_cast<std::size_t>(i)];
    const auto& b = media.cameras[static_cast<std::size_t>(i)];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.model.Describe(), b.model.Describe());
    EXPECT_LT((a.rig_from_cam - b.rig_from_cam).norm(), 1e-12);
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.3, -0.2, 1), Eigen::Vector3d(1, 0.5, 0.2)}) {
      Eigen::Vector2d pa, pb;
      ASSERT_EQ(a.model.Project(p, &pa), b.model.Project(p, &pb));
      EXPECT_LT((pa - pb).norm(), 1e-12);
    }
    EXPECT_TRUE(fs::is_directory(config.path.parent_path() / a.image_dir)) << a.image_dir;
    EXPECT_EQ(fs::canonical(config.path.parent_path() / a.image_dir),
              fs::canonical(media.path.parent_path() / b.image_dir));
  }
}

// config/gopro_fusion_5_2k.json is the GoPro Fusion of ../shared/data/rig_fusion: two
// equidistant fisheyes back to back, each 190° wide, so their optical axes are opposite and
// level, a ray 95° off an axis lands on that lens's image circle (radius 1335 and 1338 px, from
// the data's parameter file), the lenses are centimetres apart and the height is unknown.
TEST(Rig, TheGoProFusionRigHasTwoOppositeFisheyes) {
  const Rig rig = LoadRig(fs::path(ODVR_SOURCE_DIR) / "config/gopro_fusion_5_2k.json");
  ASSERT_EQ(rig.camera_count(), 2);
  EXPECT_EQ(rig.height_m, 0) << "no height: the trajectory is up to scale";
  const double radius[2] = {1335, 1338};
  Eigen::Vector3d axis[2];
  for (int i = 0; i < 2; ++i) {
    const RigCamera& cam = rig.cameras[static_cast<std::size_t>(i)];
    EXPECT_EQ(cam.model.type(), CameraModelType::kFisheye) << cam.name;
    EXPECT_EQ(cam.model.width(), 2704);
    EXPECT_EQ(cam.model.height(), 2624);
    axis[i] = cam.rig_from_cam.topLeftCorner<3, 3>() * Eigen::Vector3d::UnitZ();
    EXPECT_NEAR(axis[i].z(), 0, 1e-9) << cam.name << ": level";
    const double a = 95 * M_PI / 180;
    Eigen::Vector2d px;
    ASSERT_TRUE(cam.model.Project({std::sin(a), 0, std::cos(a)}, &px));
    EXPECT_NEAR((px - Eigen::Vector2d(cam.model.cx(), cam.model.cy())).norm(), radius[i], 1e-3) << cam.name;
  }
  EXPECT_NEAR(axis[0].x(), 1, 1e-9) << "cam0 looks forward";
  EXPECT_NEAR(axis[0].dot(axis[1]), -1, 1e-9) << "the back lens looks the other way";
  // Up stays up: the back lens is turned about the up axis, not flipped.
  for (const auto& cam : rig.cameras)
    EXPECT_NEAR((cam.rig_from_cam.topLeftCorner<3, 3>() * Eigen::Vector3d::UnitY()).z(), -1, 1e-9) << cam.name;
  const double baseline = (rig.cameras[0].rig_from_cam - rig.cameras[1].rig_from_cam).topRightCorner<3, 1>().norm();
  EXPECT_GT(baseline, 0);
  EXPECT_LT(baseline, 0.05);
  const fs::path shared_frames = fs::path(ODVR_SHARED_DIR) / "data/rig_fusion/5_2k/directory";
  if (!fs::is_directory(shared_frames)) return;
  EXPECT_EQ(fs::canonical(rig.path.parent_path() / rig.cameras[0].image_dir), fs::canonical(shared_frames / "FR"));
  EXPECT_EQ(fs::canonical(rig.path.parent_path() / rig.cameras[1].image_dir), fs::canonical(shared_frames / "BK"));
}

TEST(Rig, ReadsKalibrStylePinholeEquidistantAsFisheye) {
  const TempDir t;
  const fs::path p = t.Write("kalibr.json", R"({
    "rig_height_m": 2.0,
    "cam0": {"camera_model": "pinhole", "distortion_model": "equidistant", "intrinsics": [300, 301, 319.5, 239.5],
             "distortion_coeffs": [0.01, 0.002, 0, 0], "resolution": [640, 480],
             "T_rig_cam": [[0,0,1,0.1],[-1,0,0,0],[0,-1,0,0],[0,0,0,1]]},
    "cam1": {"camera_model": "pinhole", "distortion_model": "radtan", "intrinsics": [500, 500, 319.5, 239.5],
             "distortion_coeffs": [-0.2, 0.05, 0.001, 0.001], "resolution": [640, 480],
             "T_cam_rig": [[0,-1,0,0],[0,0,-1,0],[1,0,0,-0.1],[0,0,0,1]]}})");
  const Rig rig = LoadRig(p);
  ASSERT_EQ(rig.camera_count(), 2);
  EXPECT_EQ(rig.cameras[0].model.type(), CameraModelType::kFisheye);
  EXPECT_EQ(rig.cameras[1].model.type(), CameraModelType::kPinhole);
  EXPECT_EQ(rig.cameras[1].model.distortion()[0], -0.2);
  // T_cam_rig is inverted into rig_from_cam: both cameras sit at +0.1 m forward.
  EXPECT_NEAR((rig.cameras[1].rig_from_cam - rig.cameras[0].rig_from_cam).norm(), 0, 1e-12);
}

TEST(Rig, MalformedFilesFailWithOneLineNamingTheFile) {
  const TempDir t;
  t.ExpectError("{ \"cameras\": [ {", "not valid JSON");
  // A number beyond double's range: the JSON parser's out_of_range, found by mutating the demo rig.
  t.ExpectError("{\"rig_height_m\": 1e3080}", "not valid JSON");
  t.ExpectError("[1, 2]", "not a JSON object");
  t.ExpectError("{\"rig_height_m\": 2}", "no cameras");
  t.ExpectError("{\"cameras\": 3}", "\"cameras\" is not an array");
  const std::string good_t = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
  auto fish = [&](const std::string& extra, const std::string& pose) {
    return "{\"model\": \"opencv_fisheye\", \"width\": 480, \"height\": 640, \"fx\": 229, \"fy\": 229, \"cx\": 239.5, "
           "\"cy\": 319.5" +
           extra + ", \"T_rig_cam\": " + pose + "}";
  };
  t.ExpectError("{\"cameras\": [" + fish("", "[[1,0,0],[0,1,0],[0,0,1]]") + "]}", "not a 4x4 matrix");
  t.ExpectError("{\"cameras\": [" + fish("", "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]]") + "]}", "last row");
  t.ExpectError("{\"cameras\": [" + fish("", "[[1,0,0,0],[0,1,0,0],[0,0,2,0],[0,0,0,1]]") + "]}", "not orthonormal");
  t.ExpectError("{\"cameras\": [" + fish("", "[[1,0,0,0],[0,1,0,0],[0,0,-1,0],[0,0,0,1]]") + "]}", "determinant");
  t.ExpectError("{\"cameras\": [" + fish("", "[[1,0,0,0],[0,1,0,0],[0,0,1,\"x\"],[0,0,0,1]]") + "]}", "4x4");
  t.ExpectError("{\"cameras\": [{\"model\": \"opencv_fisheye\", \"width\": 480, \"T_rig_cam\": " + good_t + "}]}",
                "missing \"height\"");
  t.ExpectError("{\"cameras\": [" + fish(", \"id\": 0", good_t) + ", " + fish(", \"id\": 2", good_t) + "]}",
                "camera 1 is missing");
  t.ExpectError("{\"cameras\": [" + fish(", \"id\": 0", good_t) + ", " + fish(", \"id\": 0", good_t) + "]}",
                "appears twice");
  t.ExpectError("{\"cam0\": {\"camera_model\": \"omni-equirect\", \"resolution\": [64, 32], \"T_rig_cam\": " + good_t +
                    "}, \"cam2\": {\"camera_model\": \"omni-equirect\", \"resolution\": [64, 32], \"T_rig_cam\": " +
                    good_t + "}}",
                "camera 1 is missing");
  t.ExpectError("{\"camera_count\": 2, \"cameras\": [" + fish("", good_t) + "]}", "\"camera_count\" says 2");
  t.ExpectError(
      "{\"cameras\": [{\"model\": \"mei\", \"width\": 4, \"height\": 4, \"fx\": 1, \"fy\": 1, \"cx\": 0, "
      "\"cy\": 0, \"T_rig_cam\": " +
          good_t + "}]}",
      "unknown model \"mei\"");
  t.ExpectError(
      "{\"cameras\": [{\"model\": \"opencv_fisheye\", \"width\": -4, \"height\": 4, \"fx\": 1, \"fy\": 1, "
      "\"cx\": 0, \"cy\": 0, \"T_rig_cam\": " +
          good_t + "}]}",
      "positive integer");
  t.ExpectError("{\"cameras\": [" + fish(", \"fx\": -3", good_t) + "]}", "must be positive");
  t.ExpectError(
      "{\"cam0\": {\"camera_model\": \"pinhole\", \"distortion_model\": \"radtan\", \"intrinsics\": [1, 1, 0], "
      "\"resolution\": [4, 4], \"T_rig_cam\": " +
          good_t + "}}",
      "\"intrinsics\" has 3 values, expected 4");
}

TEST(Rig, TheStreetRigWithACameraRemovedIsRejected) {
  const TempDir t;
  if (!fs::exists(kStreetRig)) GTEST_SKIP() << kStreetRig << " absent (no ../shared data)";
  auto j = StreetRigJson();
  j["cameras"].erase(3);
  const fs::path p = t.Write("five.json", j.dump());
  const std::string msg = ErrorMessageOf([&] { LoadRig(p); });
  EXPECT_NE(msg.find(p.string()), std::string::npos);
  EXPECT_NE(msg.find("camera 3 is missing"), std::string::npos) << msg;
}

TEST(Rig, MissingFileIsAnError) {
  const TempDir t;
  const std::string msg = ErrorMessageOf([&] { LoadRig(t.dir / "nope.json"); });
  EXPECT_NE(msg.find("nope.json: no such rig file"), std::string::npos) << msg;
}

}  // namespace
}  // namespace odvr::capture
