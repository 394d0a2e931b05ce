// `odvr play --live`, run as a user would: the demo rig's six cameras replayed live, stitched,
// relit and composited headless; a camera vanishing mid-stream; the window under Xvfb.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tests/app/run_odvr.h"
#include "tests/app/scripted_window.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using odvr::testing::ReadText;
using odvr::testing::RunOdvr;
using odvr::testing::ScratchDir;
const fs::path kDemo = fs::path(ODVR_SOURCE_DIR) / "media" / "demo";
const std::string kRig = (fs::path(ODVR_SOURCE_DIR) / "config" / "demo_rig.json").string();
constexpr int kDemoFrames = 24;
// Measured (160x90, 90° fov, forward, frames 0-5): the live frames against the ground-truth
// panoramas of the same recording frames through the recorded player, 27.8-29.2 dB; the same
// frames turned 90° away score 10.7-10.8 dB.
constexpr double kLivePsnrFloorDb = 25.0;

double Psnr(const cv::Mat& a, const cv::Mat& b) {
  const double mse = cv::norm(a, b, cv::NORM_L2SQR) / (static_cast<double>(a.total()) * a.channels());
  return 10 * std::log10(255.0 * 255.0 / std::max(mse, 1e-12));
}

TEST(RunPlayLive, RigAndSourceBelongToLiveMode) {
  const auto r = RunOdvr("play --headless --rig " + kRig);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--live"), std::string::npos) << r.err;
  const auto no_rig = RunOdvr("play --headless --live");
  EXPECT_EQ(no_rig.exit_code, 2) << no_rig.err;
  EXPECT_NE(no_rig.err.find("--rig"), std::string::npos) << no_rig.err;
}

TEST(RunPlayLiveGL, ARigThatNamesNoCamerasNeedsASource) {
  ScratchDir scratch("odvr_live_rig");
  auto rig = nlohmann::json::parse(ReadText(kRig));
  for (auto& [key, value] : rig.items())
    if (value.is_object()) value.erase("image_dir");
  const fs::path bare = scratch.dir / "rig.json";
  std::ofstream(bare) << rig.dump(1);
  const auto r = RunOdvr("play --headless --live --no-car --size 32x18 --frames 1 --rig " + bare.string());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--source"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(bare.string()), std::string::npos) << r.err;
}

// The demo rig's cameras, stitched live: the background matches the ground-truth panorama of the
// recording frame shown, seen through the recorded player at the same view; the car stands ahead.
TEST(RunPlayLiveGL, HeadlessDemoRigStitchesTheStreetAndStandsTheCarOnIt) {
  ScratchDir scratch("odvr_live_demo");
  const fs::path live = scratch.dir / "live", truth = scratch.dir / "truth", turned = scratch.dir / "turned";
  const auto r = RunOdvr("play --live --rig " + kRig + " --headless --no-car --size 160x90 --frames 3 --json --out " +
                         live.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["live"].get<bool>());
  ASSERT_EQ(j["frames"].size(), 3u);
  for (const char* stage : {"capture_wait", "stitch", "lighting", "render", "composite", "total"})
    EXPECT_GE(j["median_ms"][stage].get<double>(), 0) << stage;
  EXPECT_GT(j["median_ms"]["stitch"].get<double>(), 0);

  const std::string gt = "play --headless --size 160x90 --frames " + std::to_string(kDemoFrames) + " " +
                         (kDemo / "pano").string() + " --out ";
  ASSERT_EQ(RunOdvr(gt + truth.string()).exit_code, 0);
  ASSERT_EQ(RunOdvr(gt + turned.string() + " --yaw 90").exit_code, 0);
  long previous = -1;
  for (const auto& f : j["frames"]) {
    EXPECT_EQ(f["cameras_present"].get<int>(), 6);
    const long k = f["source_frame"].get<long>();
    EXPECT_GT(k, previous) << "a live view moves on";
    previous = k;
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06ld.png", k % kDemoFrames);
    const cv::Mat shown = cv::imread(f["file"].get<std::string>());
    ASSERT_EQ(shown.cols, 160);
    const double psnr = Psnr(shown, cv::imread((truth / name).string()));
    const double psnr_turned = Psnr(shown, cv::imread((turned / name).string()));
    std::printf("live frame of recording frame %ld: PSNR %.2f dB against the truth, %.2f dB turned 90°\n",
                k % kDemoFrames, psnr, psnr_turned);
    EXPECT_GT(psnr, kLivePsnrFloorDb);
    EXPECT_GT(psnr, psnr_turned + 6);
  }

  // With the car: on the road ahead, below the horizon and centred, and drawn; the street behind
  // it now comes through the renderer's composite on the GPU, so above the horizon (where neither
  // the car nor its shadow reaches) the frame is the recording's as the CPU path shows it.
  const auto c = RunOdvr("play --live --rig " + kRig + " --headless --size 160x90 --frames 2 --levels 3 --json --out " +
                         live.string());
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const auto cj = nlohmann::json::parse(c.out);
  const cv::Rect sky(0, 0, 160, 36);
  for (const auto& f : cj["frames"]) {
    EXPECT_GT(f["car_pixels"].get<int>(), 150);
    EXPECT_NEAR(f["car_pixel"][0].get<double>(), 80, 1);
    EXPECT_GT(f["car_pixel"][1].get<double>(), 45 + 5) << "below the horizon";
    EXPECT_LT(f["car_pixel"][1].get<double>(), 90);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06ld.png", f["source_frame"].get<long>() % kDemoFrames);
    const cv::Mat shown = cv::imread(f["file"].get<std::string>());
    ASSERT_EQ(shown.cols, 160);
    const double psnr = Psnr(shown(sky), cv::imread((truth / name).string())(sky));
    const double psnr_turned = Psnr(shown(sky), cv::imread((turned / name).string())(sky));
    std::printf("with the car, above the horizon: PSNR %.2f dB against the truth, %.2f dB turned 90°\n", psnr,
                psnr_turned);
    EXPECT_GT(psnr, kLivePsnrFloorDb);
    EXPECT_GT(psnr, psnr_turned + 6);
  }
  EXPECT_GT(cj["median_ms"]["lighting"].get<double>(), 0);
}

// The hard case: the rig's cameras vanishing in live mode. cam3's recording stops after 3 frames
// of 8 (unplugged), cam5's frame 4 is unreadable (a dying device); the player says each once,
// naming the camera, and plays on to the frames asked for.
TEST(RunPlayLiveGL, CamerasVanishingMidStreamAreSaidOnceAndPlayGoesOn) {
  ScratchDir scratch("odvr_live_vanish");
  const fs::path rec = scratch.dir / "rec";
  for (int c = 0; c < 6; ++c) {
    const std::string cam = "cam" + std::to_string(c);
    fs::create_directories(rec / cam);
    for (int i = 0; i < (c == 3 ? 3 : 8); ++i) {
      char name[16];
      std::snprintf(name, sizeof name, "%06d.jpg", i);
      fs::copy_file(kDemo / "rig" / cam / name, rec / cam / name);
    }
  }
  std::ofstream(rec / "cam5" / "000004.jpg", std::ios::binary | std::ios::trunc) << "truncated";
  const fs::path out = scratch.dir / "out";
  const auto r = RunOdvr("play --live --rig " + kRig + " --source replay:" + rec.string() +
                         " --headless --size 64x36 --frames 6 --levels 3 --json --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames_shown"].get<int>(), 6);
  for (const auto& f : j["frames"]) EXPECT_TRUE(fs::exists(f["file"].get<std::string>()));
  // Each shown frame takes a newer set than the last: the sixth shows frame 5 or later.
  EXPECT_EQ(j["frames"].back()["cameras_present"].get<int>(), 4);
  EXPECT_EQ(j["lost_cameras"], nlohmann::json({"cam3", "cam5"}));
  auto count = [&](const std::string& what) {
    int n = 0;
    for (std::size_t at = r.err.find(what); at != std::string::npos; at = r.err.find(what, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count("camera cam3 lost"), 1) << r.err;
  EXPECT_EQ(count("camera cam5 lost"), 1) << r.err;
  EXPECT_EQ(count("lost"), 2) << r.err;
  EXPECT_NE(r.err.find((rec / "cam5" / "000004.jpg").string()), std::string::npos) << r.err;
  EXPECT_GT(j["frames"].back()["car_pixels"].get<int>(), 10);
}

// Every camera gone (each one's frame 2 unreadable): the last picture stays, play goes on.
TEST(RunPlayLiveGL, EveryCameraVanishingLeavesTheLastPicture) {
  ScratchDir scratch("odvr_live_all_gone");
  const fs::path rec = scratch.dir / "rec";
  for (int c = 0; c < 6; ++c) {
    const std::string cam = "cam" + std::to_string(c);
    fs::create_directories(rec / cam);
    for (const char* name : {"000000.jpg", "000001.jpg", "000003.jpg"})
      fs::copy_file(kDemo / "rig" / cam / name, rec / cam / name);
    std::ofstream(rec / cam / "000002.jpg") << "gone";
  }
  const auto r = RunOdvr("play --live --rig " + kRig + " --source replay:" + rec.string() +
                         " --headless --no-car --size 32x18 --frames 4 --json --out " + (scratch.dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames_shown"].get<int>(), 4);
  EXPECT_EQ(j["lost_cameras"].size(), 6u);
  EXPECT_FALSE(j["frames"].back()["new_set"].get<bool>());
  EXPECT_LE(j["frames"].back()["source_frame"].get<long>(), 1);
  EXPECT_NE(r.err.find("no camera left: showing the last picture"), std::string::npos) << r.err;
}

TEST(RunPlayLiveGL, WindowUnderXvfbShowsTheLiveStreet) {
  if (std::system("command -v xvfb-run >/dev/null 2>&1") != 0) GTEST_SKIP() << "xvfb-run is not installed";
  ScratchDir scratch("odvr_live_window");
  const std::string shot = (scratch.dir / "window.png").string();
  const std::string cmd = "ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 xvfb-run -a -s \"-screen 0 640x360x24\" " +
                          std::string(ODVR_BINARY) + " play --live --rig " + kRig +
                          " --size 160x90 --levels 3 --quit-after 1.5 --screenshot " + shot + " >/dev/null 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const cv::Mat window = cv::imread(shot);
  ASSERT_EQ(window.cols, 160);
  cv::Scalar mean, stddev;
  cv::meanStdDev(window, mean, stddev);
  EXPECT_GT(stddev[0], 10) << "a street, not a blank window";
}

// The live scene in the one player loop: the loop's keys (+ zooms, F1 hides the overlay, F12
// shoots) and its --trace work here as in the recorded players, the scene's figures in the line.
TEST(RunPlayLiveGL, TheLiveWindowTakesTheLoopsKeysAndTracesItsScene) {
  if (const std::string tool = odvr::testing::MissingWindowTool(); !tool.empty()) GTEST_SKIP() << tool << " is missing";
  ScratchDir scratch("odvr_live_scripted");
  odvr::testing::ScriptedWindow window(scratch.dir, "--live --rig " + kRig + " --size 320x180 --levels 3 --fov 90");
  window.Shot("key plus");
  window.Shot("key F1");
  const auto lines = window.Run();
  ASSERT_EQ(lines.size(), 3u) << window.log();
  EXPECT_EQ(lines[0]["event"], "ready");
  for (const auto& line : lines) {
    EXPECT_EQ(line["cameras_present"].get<int>(), 6) << line.dump();
    EXPECT_GE(line["set_index"].get<long>(), 0);
    EXPECT_EQ(line["overlay"][0].get<std::string>().rfind("set ", 0), 0u) << line["overlay"][0];
  }
  EXPECT_LT(lines[1]["fov"].get<double>(), lines[0]["fov"].get<double>());  // + zoomed in
  EXPECT_TRUE(lines[1]["overlay_shown"].get<bool>());
  EXPECT_FALSE(lines[2]["overlay_shown"].get<bool>());
  EXPECT_TRUE(fs::exists(lines[2]["file"].get<std::string>()));
}

}  // namespace
}  // namespace odvr::app
