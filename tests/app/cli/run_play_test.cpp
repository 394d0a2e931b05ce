// `odvr play` and `odvr export` in augmented mode, run as a user would: headless frames, a real
// window under Xvfb, an exported clip.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <utility>
#include <vector>

#include "tests/app/run_odvr.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using odvr::testing::RunOdvr;
const fs::path kDemo = fs::path(ODVR_SOURCE_DIR) / "media" / "demo";
const std::string kSmall = " --levels 3 --voxels 64 ";
// The rig's 1 s street with its poses and car: what these tests play, whatever `odvr` plays with
// no arguments.
const std::string kDemoDrive = " " + (kDemo / "street.mp4").string() + " --trajectory " +
                               (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() + " ";

fs::path TempDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// A clip and a car, no poses: play reconstructs the clip as one 360° camera first, into the
// user's cache, and the second time takes the poses from there.
TEST(RunPlayGL, CarWithoutTrajectoryReconstructsTheClipOnceAndStandsTheCarInIt) {
  const fs::path dir = TempDir("odvr_play_reconstructs");
  const std::string env = "XDG_CACHE_HOME=" + (dir / "cache").string();
  const std::string args = "play --headless --size 64x36 --frames 2 --json --camera-height 2.027356 --out " +
                           (dir / "frames").string() + kSmall + (kDemo / "street.mp4").string() + " --car " +
                           (kDemo / "car.glb").string();
  const auto first = RunOdvr(args, env);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_NE(first.err.find("reconstructed the camera's poses into " + (dir / "cache/odvr/reconstructions").string()),
            std::string::npos)
      << first.err;
  const auto j = nlohmann::json::parse(first.out);
  EXPECT_TRUE(j["augmented"].get<bool>());
  EXPECT_TRUE(fs::exists(fs::path(j["reconstruction"].get<std::string>()) / "trajectory.tum"));
  EXPECT_GT(j["frames"][0]["car_pixels"].get<int>(), 20) << "the car stands in the reconstructed street";
  const auto second = RunOdvr(args, env);
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_NE(second.err.find("the camera's poses from"), std::string::npos) << second.err;
  EXPECT_EQ(nlohmann::json::parse(second.out)["reconstruction"], j["reconstruction"]);
}

TEST(RunPlayGL, SupersampleOutOfRangeIsAUsageError) {
  const auto r = RunOdvr("play --headless --size 32x18 --trajectory " + (kDemo / "trajectory_gt.json").string() +
                         " --car " + (kDemo / "car.glb").string() + " --supersample 5" + kSmall);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--supersample"), std::string::npos) << r.err;
}

TEST(RunPlayGL, MissingCarModelIsAClearError) {
  const auto r = RunOdvr("play --headless --size 32x18 --trajectory " + (kDemo / "trajectory_gt.json").string() +
                         " --car /nonexistent/car.glb");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("/nonexistent/car.glb"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("car model not found"), std::string::npos) << r.err;
}

// No arguments but --headless: the demo with its car, to PNG frames, saying where.
TEST(RunPlayGL, HeadlessDemoWithTheCarAndAScriptedDrive) {
  const fs::path dir = TempDir("odvr_play_headless");
  const auto r =
      RunOdvr("play --headless --size 96x54 --drive W:0.2s --out " + dir.string() + kSmall + kDemoDrive + "--json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["augmented"].get<bool>());
  const auto& frames = j["frames"];
  ASSERT_EQ(frames.size(), 6u);  // 0.2 s at 25 fps, and the start
  for (const auto& f : frames) {
    EXPECT_TRUE(fs::exists(f["file"].get<std::string>()));
    EXPECT_GT(f["car_pixels"].get<int>(), 20);
  }
  // Accelerating from rest at 3.5 m/s²: 0.07 m after 0.2 s.
  const double moved = frames.back()["car_world_xz"][0].get<double>() - frames[0]["car_world_xz"][0].get<double>();
  EXPECT_NEAR(moved, 0.5 * 3.5 * 0.2 * 0.2, 0.01);
  for (const char* stage : {"decode", "lighting", "render", "composite", "total"})
    EXPECT_GE(j["median_ms"][stage].get<double>(), 0) << stage;
  EXPECT_GT(j["median_ms"]["render"].get<double>(), 0);

  const auto plain = RunOdvr("play --headless --size 96x54 --frames 1 --out " + dir.string() + kSmall + kDemoDrive);
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_NE(plain.out.find("no display: rendered 1 frames to " + dir.string()), std::string::npos) << plain.out;
  fs::remove_all(dir);
}

// No arguments: the 10 s drive (media/drive), its poses and its car, the frames where it says.
TEST(RunPlayGL, TheDefaultDemoIsTheTenSecondDrive) {
  const fs::path drive = fs::path(ODVR_SOURCE_DIR) / "media" / "drive";
  const fs::path dir = TempDir("odvr_play_default");
  const auto r = RunOdvr("play --headless --size 96x54 --frames 2 --out " + dir.string() + kSmall + "--json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(fs::path(j["video"].get<std::string>()), drive / "street.mp4");
  EXPECT_EQ(fs::path(j["trajectory"].get<std::string>()), drive / "trajectory_gt.json");
  ASSERT_EQ(j["frames"].size(), 2u);
  for (const auto& f : j["frames"]) EXPECT_GT(f["car_pixels"].get<int>(), 20);
  cv::VideoCapture clip((drive / "street.mp4").string());
  ASSERT_TRUE(clip.isOpened());
  EXPECT_GE(clip.get(cv::CAP_PROP_FRAME_WIDTH), 2048);
  EXPECT_GE(clip.get(cv::CAP_PROP_FRAME_COUNT) / clip.get(cv::CAP_PROP_FPS), 10.0) << "seconds of driving";
  fs::remove_all(dir);
}

// Nobody holds a key: the video plays and the car rides ahead of the camera (it stood on frame 0
// until W was pressed); held W stops the car at the end of the reconstructed street (it drove on
// to 165 m on a 35 m trajectory, 8 px tall).
TEST(RunPlayGL, TheDemoPlaysWithNoKeyAndTheCarStaysOnTheStreet) {
  const fs::path dir = TempDir("odvr_play_cruise");
  const auto r = RunOdvr("play --headless --size 96x54 --out " + dir.string() + kSmall + kDemoDrive + "--json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto& frames = j["frames"];
  ASSERT_EQ(frames.size(), 24u);  // every frame of the demo
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i]["view_frame"].get<int>(), static_cast<int>(i)) << "frame " << i;  // the video's rate
    EXPECT_GT(frames[i]["car_pixels"].get<int>(), 20) << "frame " << i;
  }
  // The car keeps its 6 m lead, moving with the camera (the demo's 0.36 m a frame), until it
  // reaches the street's end (8.28 m of path) and waits there while the video plays on.
  const auto x = [&](int i) { return frames[static_cast<std::size_t>(i)]["car_world_xz"][0].get<double>(); };
  EXPECT_NEAR(x(5) - x(0), 5 * 0.36, 0.05);
  EXPECT_FALSE(frames[5]["at_stretch_end"].get<bool>());
  EXPECT_NEAR(x(23) - x(0), 8.28 - 6, 0.1);
  EXPECT_TRUE(frames[23]["at_stretch_end"].get<bool>());

  // 12 s of full throttle: far past the demo's 8 m of street without the hold.
  const auto w = RunOdvr("play --headless --size 96x54 --drive W:12s --out " + (dir / "w").string() + kSmall +
                         kDemoDrive + "--json");
  ASSERT_EQ(w.exit_code, 0) << w.err;
  const auto driven_report = nlohmann::json::parse(w.out);
  const auto& driven = driven_report["frames"];
  const double start = driven[0]["car_world_xz"][0].get<double>();
  double furthest = start;
  for (const auto& f : driven) furthest = std::max(furthest, f["car_world_xz"][0].get<double>());
  EXPECT_LT(furthest - start, 8.28 - 6 + 5.0 + 0.5);  // to the path's end, the margin past it, a step
  EXPECT_TRUE(driven.back()["at_stretch_end"].get<bool>());
  EXPECT_GT(driven.back()["car_pixels"].get<int>(), 10);  // in view, not a speck
  fs::remove_all(dir);
}

// Leak checking is off for the windowed child only: under the sanitizer run, GLX/X11 driver code
// loaded through GLFW leaves allocations whose stacks LSan cannot name (so no suppression by
// library matches them); the headless paths, which share all of our code, stay checked.
std::string Xvfb(const std::string& args) {
  return "ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 xvfb-run -a -s \"-screen 0 1280x720x24\" " +
         std::string(ODVR_BINARY) + " " + args;
}

int RunShell(const std::string& cmd, std::string* out) {
  FILE* pipe = ::popen((cmd + " 2>&1").c_str(), "r");
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) out->append(buf, n);
  const int status = ::pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A real window: it shows what the headless path renders (the car included), and survives being
// resized to 1×1.
TEST(RunPlayGL, WindowUnderXvfbShowsTheCar) {
  if (std::system("command -v xvfb-run >/dev/null 2>&1") != 0) GTEST_SKIP() << "xvfb-run is not installed";
  const fs::path dir = TempDir("odvr_play_window");
  const std::string shot = (dir / "window.png").string();
  std::string log;
  // A script of no keys: the car stands (without one it would cruise with the video).
  ASSERT_EQ(
      RunShell(Xvfb("play --size 480x270 --quit-after 2 --drive -:0.01s --screenshot " + shot + kSmall + kDemoDrive),
               &log),
      0)
      << log;
  const cv::Mat window = cv::imread(shot);
  ASSERT_FALSE(window.empty()) << log;
  ASSERT_EQ(window.cols, 480);
  const auto h =
      RunOdvr("play --headless --size 480x270 --frames 1 --json --out " + dir.string() + kSmall + kDemoDrive);
  ASSERT_EQ(h.exit_code, 0) << h.err;
  const auto j = nlohmann::json::parse(h.out);
  const cv::Mat headless = cv::imread(j["frames"][0]["file"].get<std::string>());
  const double px = j["frames"][0]["car_pixel"][0], py = j["frames"][0]["car_pixel"][1];
  // The car stands still, so both show the same picture; the overlay covers the top ~100 rows.
  const cv::Rect around(static_cast<int>(px) - 30, static_cast<int>(py) - 10, 60, 30);
  ASSERT_TRUE((around & cv::Rect(0, 100, 480, 170)) == around);
  const double diff = cv::norm(window(around), headless(around), cv::NORM_L1) / (around.area() * 3.0);
  EXPECT_LT(diff, 3.0) << "mean 8-bit difference around the car";
  // And the car is there: its pixels differ from the bare panorama's.
  EXPECT_GT(j["frames"][0]["car_pixels"].get<int>(), 1000);

  log.clear();
  EXPECT_EQ(RunShell(Xvfb("play --size 64x36 --quit-after 2 --resize 1x1 --drive W:1s" + kSmall + kDemoDrive), &log), 0)
      << log;
  fs::remove_all(dir);
}

TEST(RunPlayGL, ExportWritesAClipAtomically) {
  const fs::path dir = TempDir("odvr_export");
  const fs::path out = dir / "clip.mp4";
  const auto r =
      RunOdvr("export --video " + (kDemo / "street.mp4").string() + " --trajectory " +
              (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() +
              " --drive W:0.2s --size 96x54 --out " + out.string() + " --levels 3 --voxels 64 --supersample 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("ETA"), std::string::npos) << r.err;
  cv::VideoCapture clip(out.string());
  ASSERT_TRUE(clip.isOpened());
  int frames = 0;
  cv::Mat f;
  while (clip.read(f)) {
    EXPECT_EQ(f.cols, 96);
    EXPECT_EQ(f.rows, 54);
    ++frames;
  }
  EXPECT_EQ(frames, 6);
  // H.264 by default for .mp4 (it was MPEG-4 Part 2), which every player and site takes.
  EXPECT_NE(r.out.find("(libx264, crf 20, silent)"), std::string::npos) << r.out;
  const auto js = RunOdvr("export --video " + (kDemo / "street.mp4").string() + " --trajectory " +
                          (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() +
                          " --frames 2 --size 64x36 --codec h265 --json --out " + (dir / "j.mkv").string() + kSmall);
  ASSERT_EQ(js.exit_code, 0) << js.err;
  const auto report = nlohmann::json::parse(js.out);
  EXPECT_EQ(report["frames"].get<int>(), 2);
  EXPECT_EQ(report["codec"].get<std::string>(), "libx265");
  EXPECT_TRUE(report["cruise"].get<bool>());
  EXPECT_EQ(report["frames_with_car"].get<int>(), 2);
  fs::remove(dir / "j.mkv");
  // --view turns the clip from the car: looking back, no frame shows it.
  const std::string base = "export --video " + (kDemo / "street.mp4").string() + " --trajectory " +
                           (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() +
                           " --frames 2 --size 64x36 --json --out " + (dir / "v.mp4").string() + kSmall;
  const auto back = RunOdvr(base + " --view 180,0,50");
  ASSERT_EQ(back.exit_code, 0) << back.err;
  EXPECT_EQ(nlohmann::json::parse(back.out)["frames_with_car"].get<int>(), 0);
  const auto aside = RunOdvr(base + " --view 10,-5");
  ASSERT_EQ(aside.exit_code, 0) << aside.err;
  EXPECT_EQ(nlohmann::json::parse(aside.out)["frames_with_car"].get<int>(), 2);
  fs::remove(dir / "v.mp4");
  for (const char* bad : {"90", "0,95", "0,0,200", "a,b"}) {
    const auto r_bad = RunOdvr(base + " --view " + bad);
    EXPECT_EQ(r_bad.exit_code, 2) << bad;
    EXPECT_NE(r_bad.err.find("--view"), std::string::npos) << r_bad.err;
  }
  const std::string probe = "ffprobe -v error -select_streams v:0 -show_entries stream=codec_name -of csv=p=0 " +
                            out.string() + " > " + (dir / "codec.txt").string();
  ASSERT_EQ(std::system(probe.c_str()), 0);
  std::ifstream codec(dir / "codec.txt");
  std::string name;
  codec >> name;
  EXPECT_EQ(name, "h264");
  fs::remove(dir / "codec.txt");
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1) << "a temporary was left beside the clip";
  fs::remove_all(dir);
}

// A recording with sound: the exported clip carries its sound, copied, as long as the pictures.
TEST(RunPlayGL, ExportCarriesTheRecordingsSound) {
  const fs::path dir = TempDir("odvr_export_audio");
  const fs::path recording = dir / "street_with_sound.mp4";
  const std::string make =
      "ffmpeg -v error -y -i " + (kDemo / "street.mp4").string() +
      " -f lavfi -i sine=frequency=440:sample_rate=48000:duration=10 -c:v copy -c:a aac -shortest " +
      recording.string();
  ASSERT_EQ(std::system(make.c_str()), 0) << make;
  const std::string common = "export --video " + recording.string() + " --trajectory " +
                             (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() +
                             " --frames 10 --size 64x36 --json" + kSmall;
  const auto with = RunOdvr(common + " --out " + (dir / "with.mp4").string());
  ASSERT_EQ(with.exit_code, 0) << with.err;
  EXPECT_EQ(nlohmann::json::parse(with.out)["audio"].get<std::string>(), "aac");
  const std::string probe =
      "ffprobe -v error -select_streams a:0 -show_entries stream=codec_name:format=duration "
      "-of default=nw=1 " +
      (dir / "with.mp4").string() + " > " + (dir / "probe.txt").string();
  ASSERT_EQ(std::system(probe.c_str()), 0);
  std::ifstream in(dir / "probe.txt");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("codec_name=aac"), std::string::npos) << text;
  const auto at = text.find("duration=");
  ASSERT_NE(at, std::string::npos) << text;
  EXPECT_NEAR(std::stod(text.substr(at + 9)), 10 / 25.0, 0.06) << "10 frames at the demo's 25 fps";

  const auto without = RunOdvr(common + " --no-audio --out " + (dir / "without.mp4").string());
  ASSERT_EQ(without.exit_code, 0) << without.err;
  EXPECT_EQ(nlohmann::json::parse(without.out)["audio"].get<std::string>(), "");
  // The demo has no sound: the clip is silent and a warning says why.
  const auto demo = RunOdvr("export --video " + (kDemo / "street.mp4").string() + " --trajectory " +
                            (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() +
                            " --frames 2 --size 64x36 --out " + (dir / "demo.mp4").string() + kSmall);
  ASSERT_EQ(demo.exit_code, 0) << demo.err;
  EXPECT_NE(demo.err.find("street.mp4 has no sound"), std::string::npos) << demo.err;
  EXPECT_NE(demo.out.find(", silent)"), std::string::npos) << demo.out;
  fs::remove_all(dir);
}

// --fps 0, -5 or nan became 25 and --frames 0 wrote the whole path: now usage errors.
TEST(RunPlay, ExportRefusesAFrameRateOrFrameCountItCannotHonour) {
  const std::string base = "export --video " + (kDemo / "street.mp4").string() + " --trajectory " +
                           (kDemo / "trajectory_gt.json").string() + " --car " + (kDemo / "car.glb").string() +
                           " --out /nonexistent/clip.mp4";
  // -1 is the command's own "not given"; 1e-9 passed and failed at the encoder, naming a temporary.
  for (const char* fps : {"0", "-5", "nan", "-1", "1e-9"}) {
    const auto r = RunOdvr(base + " --fps " + fps);
    EXPECT_EQ(r.exit_code, 2) << fps << ": " << r.err;
    EXPECT_NE(r.err.find("--fps"), std::string::npos) << r.err;
  }
  for (const char* frames : {"0", "-1"}) {
    const auto r = RunOdvr(base + " --frames " + frames);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("--frames"), std::string::npos) << r.err;
  }
  // A start that is no distance along the path became the default silently, in export and play;
  // so did play's --frames 0 ("all").
  const std::string play = "play --headless --out /nonexistent/frames " + (kDemo / "street.mp4").string() + " --car " +
                           (kDemo / "car.glb").string();
  for (const std::string& bad : {base + " --car-start nan", base + " --car-start -3", play + " --car-start nan",
                                 play + " --car-start -3", play + " --frames 0"}) {
    const auto r = RunOdvr(bad);
    EXPECT_EQ(r.exit_code, 2) << bad << "\n" << r.err;
    EXPECT_NE(r.err.find(bad.find("--frames") != std::string::npos ? "--frames" : "--car-start"), std::string::npos)
        << r.err;
  }
}

// A video whose every frame is undecodable (the demo clip with its media data zeroed): play and
// augmented play end with one line naming it, where they waited 5 s a frame and wrote black.
TEST(RunPlayGL, AVideoWithNoDecodableFrameFailsAtOnce) {
  const fs::path dir = TempDir("odvr_play_undecodable");
  std::ifstream in(kDemo / "street.mp4", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto mdat = bytes.find("mdat");
  ASSERT_NE(mdat, std::string::npos);
  for (std::size_t k = mdat + 68; k < bytes.size() && k < mdat + 600000; ++k) bytes[k] = '\0';
  const fs::path clip = dir / "undecodable.mp4";
  std::ofstream(clip, std::ios::binary) << bytes;
  const auto r =
      RunOdvr("play --headless --frames 3 --size 32x18 --out " + (dir / "out").string() + " " + clip.string());
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find(clip.string() + ": holds no decodable frame"), std::string::npos) << r.err;
  const auto a =
      RunOdvr("play --headless --frames 3 --size 32x18 --out " + (dir / "out").string() + " " + clip.string() +
              " --car " + (kDemo / "car.glb").string() + " --trajectory " + (kDemo / "trajectory_gt.json").string());
  EXPECT_EQ(a.exit_code, 1) << a.err;
  EXPECT_NE(a.err.find(clip.string()), std::string::npos) << a.err;
  fs::remove_all(dir);
}

// A stereo 360° video shows one eye, not both stacked: here a top-bottom clip whose top eye is
// red and bottom eye blue, told apart by its 1:1 shape (no metadata), then forced to "mono".
TEST(RunPlayGL, AStereoVideoShowsOneEyeNotBothStacked) {
  const fs::path dir = TempDir("odvr_play_stereo");
  const fs::path clip = dir / "tb.mp4";
  const std::string make =
      "ffmpeg -v error -y -f lavfi -i color=red:s=64x32 -f lavfi -i color=blue:s=64x32 "
      "-filter_complex vstack -frames:v 4 -c:v libx264 -pix_fmt yuv444p " +
      clip.string();
  ASSERT_EQ(std::system(make.c_str()), 0) << make;
  const std::string common = "play --headless --frames 2 --size 64x36 --fov 150 --pitch -60 " + clip.string();
  const auto r = RunOdvr(common + " --out " + (dir / "auto").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("tb.mp4: top-bottom stereo (by the frame's shape): showing the top eye, 64x32"),
            std::string::npos)
      << r.err;
  // Looking 60° down with a 150° view sees from the nadir to above the horizon: stacked eyes
  // would show blue below the horizon, one eye shows red throughout.
  const cv::Mat frame = cv::imread((dir / "auto" / "frame_000001.png").string());
  ASSERT_FALSE(frame.empty());
  const cv::Scalar mean = cv::mean(frame);  // B, G, R
  EXPECT_GT(mean[2], 150) << mean;
  EXPECT_LT(mean[0], 60) << mean;

  const auto mono = RunOdvr(common + " --stereo mono --out " + (dir / "mono").string());
  EXPECT_EQ(mono.exit_code, 1) << mono.err;
  EXPECT_NE(mono.err.find("a mono frame of 64x64 gives a 64x64 eye, not an equirectangular 2:1 image"),
            std::string::npos)
      << mono.err;
  const auto bad = RunOdvr(common + " --stereo diagonal --out " + (dir / "bad").string());
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_NE(bad.err.find("--stereo"), std::string::npos) << bad.err;
  fs::remove_all(dir);
}

// congo.mp4 says by its metadata that it is top-bottom stereo and equirectangular, each eye
// 1920x540: the eye's rows are resampled to 2:1 and the picture shows one eye.
TEST(RunPlayGL, AStereoVideoWithMetadataShowsItsTopEyeAt2To1) {
  const fs::path congo = fs::path(ODVR_SHARED_DIR) / "data/video360/congo.mp4";
  if (!fs::exists(congo)) GTEST_SKIP() << congo << " absent (../shared is not in a user's clone)";
  const fs::path dir = TempDir("odvr_play_congo");
  const auto r = RunOdvr("play --headless --frames 1 --size 96x54 --out " + dir.string() + " " + congo.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("congo.mp4: top-bottom stereo (by its metadata): showing the top eye, 1920x960 (its rows "
                       "resampled to 2:1"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(cv::imread((dir / "frame_000000.png").string()).empty());
  fs::remove_all(dir);
}

// A camera that never moves (every pose the demo's first, as a tripod reconstruction gives) put
// the car over the camera; it stands on the road ahead of it, as on a moving trajectory, and a
// warning naming the trajectory says why.
TEST(RunPlayGL, AStandingCameraGetsItsCarAheadNotOverIt) {
  const fs::path dir = TempDir("odvr_play_standing");
  auto trajectory = nlohmann::json::parse(std::ifstream(kDemo / "trajectory_gt.json"));
  const auto first = trajectory["frames"][0]["world_from_rig"];
  for (auto& f : trajectory["frames"]) {
    f["world_from_rig"] = first;
    f.erase("world_yup_from_rig");
  }
  std::ofstream(dir / "standing.json") << trajectory.dump();
  const auto r = RunOdvr("play --headless --size 96x54 --frames 1 --json --out " + (dir / "out").string() + kSmall +
                         (kDemo / "street.mp4").string() + " --car " + (kDemo / "car.glb").string() + " --trajectory " +
                         (dir / "standing.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto f = nlohmann::json::parse(r.out)["frames"][0];
  // The camera in odvr's Y-up world: (x, z_up, -y) of the Z-up pose.
  const double cx = first[0][3].get<double>(), cz = -first[1][3].get<double>();
  const double ahead = f["car_world_xz"][0].get<double>() - cx, aside = f["car_world_xz"][1].get<double>() - cz;
  std::printf("standing camera: the car %.2f m ahead, %.2f m aside, %d pixels\n", ahead, aside,
              f["car_pixels"].get<int>());
  EXPECT_GT(ahead, 4.0) << "along the camera's forward (+x)";
  EXPECT_LT(std::abs(aside), 0.5);
  EXPECT_GT(f["car_pixels"].get<int>(), 20);
  EXPECT_NE(r.err.find((dir / "standing.json").string() +
                       ": the camera moves 0.00 m in all (under 0.5 m): no road to drive on, so the car stands 6.0 m "
                       "ahead of the camera"),
            std::string::npos)
      << r.err;
  fs::remove_all(dir);
}

// The demo car moved 5 km off (under a root node of its own, translated): nothing of it is in view.
fs::path FarOffCar(const fs::path& dir) {
  std::ifstream in(kDemo / "car.glb", std::ios::binary);
  const std::string glb((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::uint32_t json_bytes = 0;
  std::memcpy(&json_bytes, glb.data() + 12, 4);
  auto j = nlohmann::json::parse(glb.substr(20, json_bytes));
  auto& scene = j["scenes"][j.value("scene", 0)];
  j["nodes"].push_back({{"translation", {5000.0, 0.0, 0.0}}, {"children", scene["nodes"]}});
  scene["nodes"] = {j["nodes"].size() - 1};
  std::string text = j.dump();
  text.append((4 - text.size() % 4) % 4, ' ');                                             // chunks are 4-byte aligned
  const std::uint32_t header[2] = {static_cast<std::uint32_t>(text.size()), 0x4E4F534Au};  // length, "JSON"
  std::string out =
      glb.substr(0, 12) + std::string(reinterpret_cast<const char*>(header), 8) + text + glb.substr(20 + json_bytes);
  const auto total = static_cast<std::uint32_t>(out.size());
  std::memcpy(out.data() + 8, &total, 4);
  const fs::path path = dir / "far.glb";
  std::ofstream(path, std::ios::binary) << out;
  return path;
}

// A car that draws nothing in view (5 km off) played and exported without a word: a warning
// names the model, once.
TEST(RunPlayGL, ACarThatCoversNoPixelIsAWarningNamingTheModel) {
  const fs::path dir = TempDir("odvr_play_unseen");
  const fs::path car = FarOffCar(dir);
  const std::string inputs = " --trajectory " + (kDemo / "trajectory_gt.json").string() + " --car " + car.string();
  const auto play = RunOdvr("play --headless --size 32x18 --frames 2 --out " + (dir / "out").string() + kSmall +
                            (kDemo / "street.mp4").string() + inputs);
  EXPECT_EQ(play.exit_code, 0) << play.err;
  const std::string said = car.string() + ": the car covers no pixel of the first frame";
  EXPECT_NE(play.err.find(said), std::string::npos) << play.err;
  EXPECT_EQ(play.err.find(said), play.err.rfind(said)) << "once";
  const auto clip = RunOdvr("export --video " + (kDemo / "street.mp4").string() + inputs +
                            " --frames 2 --size 32x18 --out " + (dir / "clip.mp4").string() + kSmall);
  EXPECT_EQ(clip.exit_code, 0) << clip.err;
  EXPECT_NE(clip.err.find("clip.mp4: the car (" + car.string() + ") covers no pixel in any of the 2 frames"),
            std::string::npos)
      << clip.err;
  fs::remove_all(dir);
}

// A pose far off the path (a fuzzed translation of 9.2e18, a jump of 200 m) sent the car there:
// refused, naming the frame.
TEST(RunPlayGL, AnOutlierPoseIsRefusedNamingItsFrame) {
  const fs::path dir = TempDir("odvr_play_outlier");
  const auto play_with = [&](const fs::path& trajectory) {
    return RunOdvr("play --headless --size 32x18 --frames 1 --out " + (dir / "out").string() + kSmall +
                   (kDemo / "street.mp4").string() + " --car " + (kDemo / "car.glb").string() + " --trajectory " +
                   trajectory.string());
  };
  for (const auto& [value, needle] : std::vector<std::pair<double, std::string>>{{9.2e18, "frame 7: the camera is"},
                                                                                 {200, "frame 7: the camera jumps"}}) {
    auto trajectory = nlohmann::json::parse(std::ifstream(kDemo / "trajectory_gt.json"));
    trajectory["frames"][7]["world_from_rig"][1][3] = value;
    std::ofstream(dir / "outlier.json") << trajectory.dump();
    const auto r = play_with(dir / "outlier.json");
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find((dir / "outlier.json").string() + ": " + needle), std::string::npos) << r.err;
  }
  // Two or three poses have no median step to compare with: a step faster than any vehicle
  // (900 km in a frame, or a middle pose 200 m off) is refused all the same.
  for (const auto& [poses, needle] : std::vector<std::pair<int, std::string>>{{2, "frame 1: the camera moves 900"},
                                                                              {3, "frame 1: the camera moves 20"}}) {
    auto trajectory = nlohmann::json::parse(std::ifstream(kDemo / "trajectory_gt.json"));
    trajectory["frames"].erase(trajectory["frames"].begin() + poses, trajectory["frames"].end());
    trajectory["frames"][1]["world_from_rig"][1][3] = poses == 2 ? 9e5 : 200.0;
    trajectory["frames"][1].erase("world_yup_from_rig");
    std::ofstream(dir / "short.json") << trajectory.dump();
    const auto r = play_with(dir / "short.json");
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find((dir / "short.json").string() + ": " + needle), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("faster than any vehicle"), std::string::npos) << r.err;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace odvr::app
