// `odvr export --projection equirect`: the augmented 360° video itself, run as a user would.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "capture/libav_video.h"
#include "tests/app/run_odvr.h"
#include "tests/scratch_dir.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using odvr::testing::ReadText;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;
const fs::path kDemo = fs::path(ODVR_SOURCE_DIR) / "media" / "demo";

// ffprobe's stream report of `clip`.
std::string Probe(const fs::path& clip) {
  const fs::path report = clip.string() + ".probe.txt";
  const std::string cmd = "ffprobe -v error -show_streams " + clip.string() + " > " + report.string();
  if (std::system(cmd.c_str()) != 0) return "";
  return ReadText(report);
}

// The 360° clip: the video's own frames at its size, the car composited into them, marked as
// equirectangular for 360° players; away from the car and its shadow, the recorded pixels.
TEST(RunExportGL, Equirect360ClipCarriesTheCarTheStreetAndTheSphericalMetadata) {
  const ScratchDir scratch("odvr_export_360");
  const fs::path& dir = scratch.dir;
  const fs::path out = dir / "drive360.mp4";
  const std::string base = "export --video " + (kDemo / "street.mp4").string() + " --trajectory " +
                           (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() +
                           " --levels 3 --voxels 64 --frames 2 --projection equirect --crf 0 ";
  const auto r = RunOdvr(base + "--json --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["projection"].get<std::string>(), "equirect");
  EXPECT_EQ(report["size"][0].get<int>(), 1024);  // the demo video's frame size
  EXPECT_EQ(report["size"][1].get<int>(), 512);
  EXPECT_EQ(report["frames_with_car"].get<int>(), 2);
  EXPECT_GE(report["cube_faces_per_frame"].get<double>(), 1.0);

  const std::string probe = Probe(out);
  EXPECT_NE(probe.find("side_data_type=Spherical Mapping"), std::string::npos) << probe;
  EXPECT_NE(probe.find("projection=equirectangular"), std::string::npos) << probe;
  EXPECT_NE(probe.find("nb_frames=2"), std::string::npos) << probe;

  // Frame 0 beside the recording's frame 0: the car changes a patch ahead; the sky, the street
  // behind the camera and the rest stay as recorded (x264 at crf 0 is lossless in YUV; the
  // conversions to and from RGB move a value by a step or two). Read by libav as the player does,
  // honouring each file's colour matrix (the clip's is tagged BT.709, the demo's is unspecified).
  const auto a_frame = capture::LibavVideoReader(out.string()).Next();
  const auto b_frame = capture::LibavVideoReader((kDemo / "street.mp4").string()).Next();
  ASSERT_TRUE(a_frame && b_frame);
  const cv::Mat &a = a_frame->image, &b = b_frame->image;
  ASSERT_EQ(a.size(), b.size());
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
  const int changed = cv::countNonZero(diff > 12);
  const cv::Rect behind(0, 0, a.cols / 4, a.rows);  // the quarter about the seam looks backward
  std::printf("360 clip frame 0: %d of %d pixels changed by more than 12 levels; %d behind the camera\n", changed,
              a.cols * a.rows, cv::countNonZero(diff(behind) > 12));
  EXPECT_GT(changed, 300);                   // the car
  EXPECT_LT(changed, a.cols * a.rows / 50);  // and nothing like the whole frame
  EXPECT_EQ(cv::countNonZero(diff(behind) > 12), 0);

  // A 360° clip looks every way and is twice as wide as high.
  const auto view = RunOdvr(base + "--view 10,0 --out " + (dir / "v.mp4").string());
  EXPECT_EQ(view.exit_code, 2) << view.err;
  EXPECT_NE(view.err.find("--view"), std::string::npos) << view.err;
  const auto size = RunOdvr(base + "--size 640x360 --out " + (dir / "s.mp4").string());
  EXPECT_EQ(size.exit_code, 2) << size.err;
  EXPECT_NE(size.err.find("twice as wide as high"), std::string::npos) << size.err;
  const auto small = RunOdvr(base + "--size 256x128 --json --out " + (dir / "small.mkv").string());
  ASSERT_EQ(small.exit_code, 0) << small.err;
  EXPECT_EQ(nlohmann::json::parse(small.out)["size"][0].get<int>(), 256);
  EXPECT_NE(Probe(dir / "small.mkv").find("projection=equirectangular"), std::string::npos);
}

}  // namespace
}  // namespace odvr::app
