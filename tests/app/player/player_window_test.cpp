// `odvr play` in a real window under Xvfb, driven by real X input from xdotool (a mouse drag,
// the wheel, key presses), read back through its screenshots (F12) and its --trace lines.
// Each input step ends with F12, and the script waits for that screenshot's trace line before
// the next step: X delivers a client's events in order, so the screenshot shows every earlier
// input applied, and no step depends on a sleep being long enough.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "core/constants.h"
#include "tests/app/run_odvr.h"
#include "tests/app/scripted_window.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using odvr::testing::MissingWindowTool;
using odvr::testing::ScratchDir;
using odvr::testing::ScriptedWindow;

// The rig's 1 s street with its poses and car (media/demo), named: the car's place in these
// shots is measured for that clip, whichever clip odvr plays by default.
const fs::path kDemo = fs::path(ODVR_SOURCE_DIR) / "media" / "demo";
const std::string kDemoDrive = (kDemo / "street.mp4").string() + " --trajectory " +
                               (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() + " ";

cv::Mat Shot(const json& line) { return cv::imread(line["file"].get<std::string>()); }

double MeanAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  return cv::norm(a, b, cv::NORM_L1) / (static_cast<double>(a.total()) * a.channels());
}

// Where the patch of `before` centred at (x, y) best matches in `after`, as a shift in pixels.
cv::Point2d PatchShift(const cv::Mat& before, const cv::Mat& after, int x, int y, int half) {
  const cv::Mat patch = before(cv::Rect(x - half, y - half, 2 * half, 2 * half));
  cv::Mat score;
  cv::matchTemplate(after, patch, score, cv::TM_SQDIFF_NORMED);
  cv::Point best;
  cv::minMaxLoc(score, nullptr, nullptr, &best, nullptr);
  // A parabola through the best score and its neighbours: the shift to a tenth of a pixel.
  auto refine = [&](int at, int n, auto score_at) {
    if (at <= 0 || at >= n - 1) return 0.0;
    const double a = score_at(at - 1), b = score_at(at), c = score_at(at + 1);
    return a + c - 2 * b > 0 ? 0.5 * (a - c) / (a + c - 2 * b) : 0.0;
  };
  const double dx = refine(best.x, score.cols, [&](int i) { return double(score.at<float>(best.y, i)); });
  const double dy = refine(best.y, score.rows, [&](int i) { return double(score.at<float>(i, best.x)); });
  return {best.x + dx + half - x, best.y + dy + half - y};
}

// Pixels that differ between two screenshots by more than a little (8-bit, summed over channels).
cv::Mat Changed(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d, sum;
  cv::absdiff(a, b, d);
  cv::transform(d, sum, cv::Matx13f(1, 1, 1));
  return sum > 24;
}

double Number(const std::string& text, const std::string& after) {
  const auto at = text.find(after);
  return at == std::string::npos ? -1 : std::stod(text.substr(at + after.size()));
}

// The plain player (the demo street, no car): the view turns with a drag by the angle the
// dragged pixels subtend, pitch stops at ±90°, yaw never stops, the wheel and +/- zoom within
// 30–150°, space/./, drive playback, and the overlay shows the frame's timings.
TEST(PlayerWindowGL, DragWheelAndKeysTurnZoomAndStepTheView) {
  if (const std::string tool = MissingWindowTool(); !tool.empty()) GTEST_SKIP() << tool << " is not installed";
  ScratchDir scratch("odvr_player_window");
  const int w = 480, h = 270;
  ScriptedWindow window(scratch.dir, "--no-car --size 480x270 --fov 90");
  // 1: paused, overlay hidden: the bare picture.          2: dragged 40 px right.
  window.Shot("mousemove --window $W 240 200 key space F1");
  window.Shot("mousedown 1 mousemove --window $W 280 200 mouseup 1");
  // 3–6: dragged 200 px down three times, then 200 px up.
  for (int i = 0; i < 3; ++i)
    window.Shot("mousemove --window $W 240 30 mousedown 1 mousemove --window $W 240 230 mouseup 1");
  window.Shot("mousemove --window $W 240 230 mousedown 1 mousemove --window $W 240 30 mouseup 1");
  // 7: three drags of 200 px left (200° of yaw).
  window.Shot(
      "mousemove --window $W 440 200 mousedown 1 mousemove --window $W 240 200 mouseup 1 "
      "mousemove --window $W 440 200 mousedown 1 mousemove --window $W 240 200 mouseup 1 "
      "mousemove --window $W 440 200 mousedown 1 mousemove --window $W 240 200 mouseup 1");
  // 8: pitch back to level (drag 70 px up). 9: five wheel steps up. 10: 40 more. 11: 60 down.
  window.Shot("mousemove --window $W 240 100 mousedown 1 mousemove --window $W 240 30 mouseup 1");
  window.Shot("click --repeat 5 --delay 10 4");
  window.Shot("click --repeat 40 --delay 5 4");
  window.Shot("click --repeat 60 --delay 5 5");
  // 12: the '=' key zooms in a step. 13: '.' steps a frame, twice; ',' back once, right before
  // the screenshot: the decoder has dropped the frame behind by then and seeks back for it, and
  // the screenshot must wait for it (CI under ASan once shot the frame ',' had left). 14: overlay on.
  window.Shot("key equal");
  window.Shot("key --delay 300 period period key --delay 1 comma");
  window.Shot("key F1");
  const auto t = window.Run();
  ASSERT_EQ(t.size(), 15u) << window.log();
  EXPECT_NE(window.log().find("player exit 0"), std::string::npos) << window.log();
  for (std::size_t i = 1; i < t.size(); ++i) ASSERT_TRUE(fs::exists(t[i]["file"].get<std::string>())) << i;
  ASSERT_FALSE(t[1]["playing"].get<bool>());
  const long frame = t[1]["frame"].get<long>();
  for (std::size_t i = 2; i <= 12; ++i) EXPECT_EQ(t[i]["frame"].get<long>(), frame) << "paused, shot " << i;

  // The drag: 40 px at 90° over 270 px turns the view 13.33° left, and the picture's centre
  // moves right by f·tan(13.33°) with f = 135 px / tan(45°).
  const double turn = 40.0 * 90 / h;
  EXPECT_NEAR(t[2]["yaw"].get<double>() - t[1]["yaw"].get<double>(), -turn, 1e-9);
  const double expected_px = (h / 2.0) / std::tan(45 * kPi / 180) * std::tan(turn * kPi / 180);
  const cv::Point2d shift = PatchShift(Shot(t[1]), Shot(t[2]), w / 2, h / 2, 32);
  EXPECT_NEAR(shift.x, expected_px, 2.0) << "expected " << expected_px << " px";
  EXPECT_NEAR(shift.y, 0, 1.0);
  std::printf("drag 40 px: yaw %.2f deg, picture moved %.1f px (expected %.2f)\n",
              t[2]["yaw"].get<double>() - t[1]["yaw"].get<double>(), shift.x, expected_px);

  // Pitch: +66.7°, then stopped at 90° (a third drag changes nothing, pixels included), and a
  // drag back up counts from 90°, not from the 200° dragged.
  EXPECT_NEAR(t[3]["pitch"].get<double>(), 200.0 * 90 / h, 1e-9);
  EXPECT_DOUBLE_EQ(t[4]["pitch"].get<double>(), 90.0);
  EXPECT_DOUBLE_EQ(t[5]["pitch"].get<double>(), 90.0);
  EXPECT_LT(MeanAbsDiff(Shot(t[4]), Shot(t[5])), 0.01);
  EXPECT_NEAR(t[6]["pitch"].get<double>(), 90 - 200.0 * 90 / h, 1e-9);
  EXPECT_GT(MeanAbsDiff(Shot(t[5]), Shot(t[6])), 5.0);

  // Yaw: 200° more, through ±180° (reported wrapped).
  const double yaw = std::remainder(t[7]["yaw"].get<double>() - (t[2]["yaw"].get<double>() + 3 * 200.0 * 90 / h), 360);
  EXPECT_NEAR(yaw, 0, 1e-9) << t[7]["yaw"];
  EXPECT_NEAR(t[8]["pitch"].get<double>(), 90 - 270.0 * 90 / h, 1e-9);

  // Zoom: five wheel steps up narrow the view to 90·0.95⁵; the picture's middle grows by
  // tan(45°)/tan(fov/2), which the screenshots show.
  const double fov = 90 * std::pow(0.95, 5);
  EXPECT_NEAR(t[9]["fov"].get<double>(), fov, 1e-9);
  const double scale = std::tan(45 * kPi / 180) / std::tan(fov / 2 * kPi / 180);
  const cv::Rect middle(w / 2 - 60, h / 2 - 40, 120, 80);
  cv::Mat grown, same;
  cv::resize(Shot(t[8]), grown, {}, scale, scale, cv::INTER_LINEAR);
  const cv::Rect grown_middle(grown.cols / 2 - 60, grown.rows / 2 - 40, 120, 80);
  const double err_scaled = MeanAbsDiff(grown(grown_middle), Shot(t[9])(middle));
  const double err_unscaled = MeanAbsDiff(Shot(t[8])(middle), Shot(t[9])(middle));
  EXPECT_LT(err_scaled, 0.5 * err_unscaled);
  std::printf("zoom to %.2f deg: middle vs x%.3f-scaled before %.2f, vs unscaled %.2f (mean 8-bit)\n", fov, scale,
              err_scaled, err_unscaled);
  EXPECT_DOUBLE_EQ(t[10]["fov"].get<double>(), 30.0);
  EXPECT_DOUBLE_EQ(t[11]["fov"].get<double>(), 150.0);
  EXPECT_NEAR(t[12]["fov"].get<double>(), 150 * 0.95, 1e-9);

  // Frame stepping while paused.
  EXPECT_EQ(t[13]["frame"].get<long>(), frame + 1);
  EXPECT_FALSE(t[13]["playing"].get<bool>());

  // The overlay: its lines name the frame and the stage timings of the frame shown, and turning
  // it on changes the top-left corner of the picture and nothing else.
  ASSERT_TRUE(t[14]["overlay_shown"].get<bool>());
  const auto& overlay = t[14]["overlay"];
  ASSERT_GE(overlay.size(), 3u);
  const std::string timings = overlay[1].get<std::string>();
  EXPECT_NEAR(Number(timings, "decode "), t[14]["ms"]["decode"].get<double>(), 0.006) << timings;
  EXPECT_NEAR(Number(timings, "render "), t[14]["ms"]["render"].get<double>(), 0.006) << timings;
  EXPECT_GT(t[14]["ms"]["render"].get<double>(), 0);
  EXPECT_NE(overlay[0].get<std::string>().find("frame " + std::to_string(frame + 1)), std::string::npos) << overlay;
  const cv::Mat changed = Changed(Shot(t[13]), Shot(t[14]));
  const cv::Rect box = cv::boundingRect(changed);
  EXPECT_GT(cv::countNonZero(changed), 2000);
  EXPECT_LE(box.x, 12);
  EXPECT_LE(box.y, 12);
  EXPECT_LT(box.br().y, h * 3 / 4) << "the overlay sits at the top";
  std::printf("overlay: %d pixels changed within %dx%d at (%d,%d): \"%s\"\n", cv::countNonZero(changed), box.width,
              box.height, box.x, box.y, timings.c_str());
}

// Where the car is in a screenshot: the pixels that change when it is hidden (C), car and shadow.
struct CarInShot {
  int pixels = 0;
  cv::Rect box;
  cv::Point2d centroid;
  bool at_projection = false;  // the projected centre is one of them
};
CarInShot FindCar(const json& shown, const json& hidden) {
  const cv::Mat changed = Changed(Shot(shown), Shot(hidden));
  CarInShot c;
  c.pixels = cv::countNonZero(changed);
  c.box = cv::boundingRect(changed);
  const cv::Moments m = cv::moments(changed, true);
  if (m.m00 > 0) c.centroid = {m.m10 / m.m00, m.m01 / m.m00};
  const int px = static_cast<int>(shown["car_pixel"][0].get<double>());
  const int py = static_cast<int>(shown["car_pixel"][1].get<double>());
  c.at_projection = cv::Rect(0, 0, changed.cols, changed.rows).contains({px, py}) && changed.at<uchar>(py, px) != 0;
  return c;
}

// The demo with its car: the car is drawn where the player says it projects, W drives it down
// the street (the view following), and the overlay shows the augmented stages' timings.
TEST(PlayerWindowGL, CarAppearsAtItsProjectionAndDrivesWithW) {
  if (const std::string tool = MissingWindowTool(); !tool.empty()) GTEST_SKIP() << tool << " is not installed";
  ScratchDir scratch("odvr_player_window_car");
  // Looking 15° right of the car, so that it stands left of the middle.
  // A script of no keys: the car stands until W is pressed, instead of cruising with the video.
  ScriptedWindow window(scratch.dir, kDemoDrive + "--size 480x270 --levels 3 --voxels 64 --yaw 15 --drive -:0.01s");
  window.Shot("mousemove --window $W 470 260 key F1");  // 1: overlay off, the car at rest
  window.Shot("key space c");                           // 2: paused, the car hidden
  window.Shot("key c space keydown w");                 // 3: driving
  window.Shot("sleep 1 keyup w key space");             // 4: a second of W later, paused
  window.Shot("key c");                                 // 5: the car hidden
  window.Shot("key c F1");                              // 6: the overlay back
  const auto t = window.Run();
  ASSERT_EQ(t.size(), 7u) << window.log();
  EXPECT_NE(window.log().find("player exit 0"), std::string::npos) << window.log();

  EXPECT_EQ(t[1]["car_speed_mps"].get<double>(), 0.0);
  EXPECT_GT(t[3]["car_speed_mps"].get<double>(), 0.0);
  const double moved = std::hypot(t[4]["car_world_xz"][0].get<double>() - t[1]["car_world_xz"][0].get<double>(),
                                  t[4]["car_world_xz"][1].get<double>() - t[1]["car_world_xz"][1].get<double>());
  // W is held for a second of wall time, but the car steps at most 0.1 s per frame (a stalled frame
  // must not launch it), so how far it gets depends on the frame rate: 3.8–9.4 m at ~10 fps, 1.3 m
  // at the sanitizer build's ~1 fps. Any frame that saw W moves it by at least 3.5 cm.
  EXPECT_GT(moved, 0.03);
  EXPECT_GE(t[4]["view_frame"].get<int>(), t[1]["view_frame"].get<int>()) << "the viewer follows the car forward";
  EXPECT_EQ(t[4]["car_world_xz"], t[5]["car_world_xz"]) << "paused";

  for (const auto& [shown, hidden] : {std::pair{1, 2}, std::pair{4, 5}}) {
    const CarInShot car = FindCar(t[shown], t[hidden]);
    const double px = t[shown]["car_pixel"][0].get<double>(), py = t[shown]["car_pixel"][1].get<double>();
    EXPECT_LT(px, 240) << "15° right of the car puts it left of the middle";
    EXPECT_TRUE(car.at_projection) << "shot " << shown;
    EXPECT_TRUE(car.box.contains(cv::Point(static_cast<int>(px), static_cast<int>(py)))) << "shot " << shown;
    // The shadow, cast toward the viewer's feet, pulls the centroid down but hardly sideways.
    EXPECT_NEAR(car.centroid.x, px, 0.2 * car.box.width) << "shot " << shown;
    EXPECT_GT(car.pixels, 0.8 * t[shown]["car_pixels"].get<int>()) << "shot " << shown;
    std::printf("shot %d: car projected at (%.1f, %.1f), drawn: %d px in %dx%d at (%d,%d), centroid (%.1f, %.1f)\n",
                shown, px, py, car.pixels, car.box.width, car.box.height, car.box.x, car.box.y, car.centroid.x,
                car.centroid.y);
  }
  std::printf("W for 1 s: car moved %.2f m, view frame %d -> %d\n", moved, t[1]["view_frame"].get<int>(),
              t[4]["view_frame"].get<int>());

  const auto& overlay = t[6]["overlay"];
  ASSERT_GE(overlay.size(), 2u);
  const std::string timings = overlay[1].get<std::string>();
  for (const char* stage : {"lighting", "render", "composite"})
    EXPECT_NEAR(Number(timings, std::string(stage) + " "), t[6]["ms"][stage].get<double>(), 0.06) << timings;
  EXPECT_GT(t[6]["ms"]["render"].get<double>(), 0);
  EXPECT_GT(cv::countNonZero(Changed(Shot(t[5]), Shot(t[6]))(cv::Rect(0, 0, 200, 60))), 500) << "overlay drawn";
  std::printf("overlay: \"%s\"\n", timings.c_str());
}

// The x y of a panel widget in the player's last trace line (a shell expression for a step).
std::string PanelWidget(const std::string& name) {
  return "$(tail -n1 trace.jsonl | grep -o '\"" + name + "\":\\[[^]]*' | cut -d[ -f2 | tr , ' ')";
}

// The car panel under real clicks: xdotool clicks its L0 checkbox (found through the trace), the
// light's level 0 is left out and the car as drawn changes; a second click brings it back. The
// screenshots compared are taken with the panel and overlay hidden (F1), the whole picture clear.
TEST(PlayerWindowGL, ClickOnThePanelsLevelCheckboxChangesTheCar) {
  if (const std::string tool = MissingWindowTool(); !tool.empty()) GTEST_SKIP() << tool << " is not installed";
  ScratchDir scratch("odvr_player_window_panel");
  ScriptedWindow window(scratch.dir,
                        kDemoDrive + "--size 480x270 --levels 3 --voxels 64 --yaw 15 --panel --drive -:0.01s");
  window.Shot("mousemove --window $W 5 265 key space F1");  // 1: paused, nothing over the picture
  // ImGui toggles a checkbox on the frame that sees the release, and the scene renders the new
  // look on the frame after: a screenshot in between.
  for (int i = 0; i < 2; ++i) {
    window.Shot("key F1");  // 2, 6: the panel, its widgets' places in the trace
    window.Shot("mousemove --window $W " + PanelWidget("L0") + " click 1");
    window.Shot("");
    window.Shot("mousemove --window $W 5 265 key F1");  // 5, 9: hidden again
  }
  const auto t = window.Run();
  ASSERT_EQ(t.size(), 10u) << window.log();
  EXPECT_NE(window.log().find("player exit 0"), std::string::npos) << window.log();
  EXPECT_TRUE(t[1]["look"]["levels"][0].get<bool>());
  EXPECT_FALSE(t[5]["look"]["levels"][0].get<bool>());
  EXPECT_TRUE(t[5]["look"]["levels"][1].get<bool>());
  EXPECT_TRUE(t[9]["look"]["levels"][0].get<bool>());
  EXPECT_EQ(t[5]["car_world_xz"], t[1]["car_world_xz"]) << "paused";
  for (int i : {1, 5, 9}) EXPECT_FALSE(t[i]["overlay_shown"].get<bool>());

  const cv::Mat off = Changed(Shot(t[1]), Shot(t[5]));
  const int changed = cv::countNonZero(off), back = cv::countNonZero(Changed(Shot(t[1]), Shot(t[9])));
  const cv::Moments m = cv::moments(off, true);
  const double px = t[5]["car_pixel"][0].get<double>(), py = t[5]["car_pixel"][1].get<double>();
  EXPECT_GT(changed, 100);
  EXPECT_EQ(back, 0);
  ASSERT_GT(m.m00, 0);
  EXPECT_NEAR(m.m10 / m.m00, px, 30) << "the change is on the car";
  EXPECT_NEAR(m.m01 / m.m00, py, 30) << "the change is on the car";
  std::printf(
      "L0 clicked at (%d, %d): %d pixels changed, centroid (%.0f, %.0f), car at (%.0f, %.0f); clicked "
      "again: %d\n",
      t[2]["panel"]["L0"][0].get<int>(), t[2]["panel"]["L0"][1].get<int>(), changed, m.m10 / m.m00, m.m01 / m.m00, px,
      py, back);
}

}  // namespace
}  // namespace odvr::app
