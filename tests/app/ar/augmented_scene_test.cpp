#include "app/ar/augmented_scene.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <random>

#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/sphere/equirect.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
const fs::path kDemo = fs::path(ODVR_SOURCE_DIR) / "media" / "demo";

TEST(AugmentedScene, ParsesDriveScripts) {
  const auto s = ParseDriveScript("W:2s,A:500ms,WD:0.25,-:1s");
  ASSERT_EQ(s.size(), 4u);
  EXPECT_TRUE(s[0].input.forward && !s[0].input.left);
  EXPECT_DOUBLE_EQ(s[1].seconds, 0.5);
  EXPECT_TRUE(s[2].input.forward && s[2].input.right);
  EXPECT_FALSE(s[3].input.forward || s[3].input.backward || s[3].input.left || s[3].input.right);
  EXPECT_DOUBLE_EQ(DriveDuration(s), 3.75);
  EXPECT_TRUE(DriveInputAt(s, 1.99).forward);
  EXPECT_TRUE(DriveInputAt(s, 2.1).left);
  EXPECT_FALSE(DriveInputAt(s, 10).forward);
  EXPECT_THROW(ParseDriveScript("X:1s"), UsageError);
  EXPECT_THROW(ParseDriveScript("W2s"), UsageError);
  EXPECT_THROW(ParseDriveScript("W:-1s"), UsageError);
  EXPECT_THROW(ParseDriveScript("W:1s,,A:1s"), UsageError);
}

// The car's light is a blend of neighbouring frames' models; the models are linear in their
// amplitudes, so the blend must evaluate to the weighted sum everywhere.
TEST(AugmentedScene, BlendOfTwoFramesLightingIsTheWeightedSum) {
  lighting::SgLighting a, b;
  a.constant = {0.2f, 0.3f, 0.4f};
  b.constant = {1.0f, 0.5f, 0.0f};
  a.levels.push_back({1, 20.0, {0, 5, 17}, {{1, 2, 3}, {0.5f, 0.5f, 0.5f}, {2, 0, 1}}});
  b.levels.push_back({1, 20.0, {5, 30}, {{1, 1, 1}, {0, 3, 0}}});
  b.levels.push_back({2, 80.0, {100}, {{4, 4, 4}}});
  a.peaks.push_back({glm::normalize(glm::dvec3(0.3, 0.9, 0.1)), 3000, {500, 400, 300}});
  b.peaks.push_back({glm::normalize(glm::dvec3(0.35, 0.88, 0.1)), 2500, {450, 420, 310}});
  const double wa = 0.3, wb = 0.7;
  const auto blend = lighting::SgLighting::Blend({{&a, wa}, {&b, wb}});
  std::mt19937 rng(3);
  std::normal_distribution<double> n;
  double worst = 0;
  for (int i = 0; i < 2000; ++i) {
    glm::dvec3 d(n(rng), n(rng), n(rng));
    if (i == 0) d = a.peaks[0].axis;  // where the peaks matter most
    d = glm::normalize(d);
    const glm::vec3 got = blend.Evaluate(d);
    const glm::vec3 want = float(wa) * a.Evaluate(d) + float(wb) * b.Evaluate(d);
    for (int c = 0; c < 3; ++c)
      worst = std::max(worst, std::abs(double(got[c] - want[c])) / (1e-3 + std::abs(want[c])));
  }
  EXPECT_LT(worst, 1e-5);
}

TEST(AugmentedScene, ScriptedDriveCoversTheDistanceOfItsAcceleration) {
  CarLimits limits;
  CarController car({{0, 1, 0}, 0}, limits);
  const auto script = ParseDriveScript("W:2s");
  const double dt = 0.02;
  for (double t = 0; t < 2 - 1e-9; t += dt) car.Step(DriveInputAt(script, t), dt);
  // Constant acceleration a from rest: a t² / 2 = 7 m at 3.5 m/s², straight ahead.
  EXPECT_NEAR(car.state().position.x, 0.5 * limits.acceleration_mps2 * 4, 0.08);
  EXPECT_NEAR(car.state().position.z, 0, 1e-9);
  EXPECT_NEAR(car.state().speed_mps, limits.acceleration_mps2 * 2, 1e-6);
}

// --- GL: the demo street with its car, rendered small -------------------------------------

AugmentedOptions DemoOptions() {
  AugmentedOptions o;
  o.video = (kDemo / "street.mp4").string();
  o.trajectory = (kDemo / "trajectory_gt.json").string();
  o.car = (kDemo / "car.glb").string();
  o.lighting_levels = 3;
  o.lighting_width = 128;
  o.voxel_resolution = 64;
  o.cone_rings = 0;
  return o;
}

// Centroid of the pixels that differ by more than a threshold (linear, summed over channels),
// leaving out the shadow: pixels that only darkened, by the same factor in every channel (the
// composite multiplies the background by the shadow ratio), within 8 %.
glm::dvec2 ChangedCentroid(const sphere::EquirectImage& with, const sphere::EquirectImage& without, int* count,
                           int* shadow) {
  glm::dvec2 sum(0);
  *count = *shadow = 0;
  for (int y = 0; y < with.height; ++y)
    for (int x = 0; x < with.width; ++x) {
      const float* p = with.at(x, y);
      const float* q = without.at(x, y);
      if (std::abs(p[0] - q[0]) + std::abs(p[1] - q[1]) + std::abs(p[2] - q[2]) <= 0.02f) continue;
      float lo = 1e9f, hi = -1e9f;
      for (int c = 0; c < 3; ++c) {
        const float r = p[c] / std::max(q[c], 1e-4f);
        lo = std::min(lo, r);
        hi = std::max(hi, r);
      }
      if (hi <= 1.0f && hi - lo < 0.08f * std::max(hi, 1e-3f)) {
        ++*shadow;
        continue;
      }
      sum += glm::dvec2(x + 0.5, y + 0.5);
      ++*count;
    }
  return *count ? sum / double(*count) : glm::dvec2(-1);
}

fs::path TempDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

TEST(AugmentedSceneGL, CarAppearsWhereItsProjectionSaysAndMovesWithTheDrive) {
  gl::HeadlessContext context;
  AugmentedScene scene(DemoOptions());
  const int w = 192, h = 108;
  AugmentedView with, without;
  without.draw_car = false;
  // Looking 12° to the right, so that the car is off the image centre.
  with.yaw_deg = without.yaw_deg = 12;
  auto check = [&](const char* when) {
    const AugmentedFrame a = scene.Render(w, h, with, 0.04);
    const AugmentedFrame b = scene.Render(w, h, without, 0.04);
    int changed = 0, shadow = 0;
    const glm::dvec2 c = ChangedCentroid(a.image, b.image, &changed, &shadow);
    EXPECT_GT(a.car_pixels, 150) << when;
    EXPECT_GT(changed, a.car_pixels / 2) << when;
    EXPECT_GT(shadow, 0) << when;
    EXPECT_NEAR(c.x, a.car_pixel.x, 3.0) << when;
    // The near rear of the car fills more of its silhouette than the far front: the centroid sits
    // a little below the box centre seen from 2 m up.
    EXPECT_NEAR(c.y, a.car_pixel.y, 5.0) << when;
    std::printf(
        "%s: car centre projected at (%.1f, %.1f), changed pixels' centroid (%.1f, %.1f), %d changed, "
        "%d shadow, %d car pixels, view frame %d, light frame %d\n",
        when, a.car_pixel.x, a.car_pixel.y, c.x, c.y, changed, shadow, a.car_pixels, a.view_frame, a.light_frame);
    return a;
  };
  const AugmentedFrame start = check("start");
  EXPECT_LT(start.car_pixel.x, w / 2 - 10);  // turned right: the car is left of centre
  const auto script = ParseDriveScript("W:1.2s,A:0.4s");
  for (double t = 0; t < DriveDuration(script); t += 0.04) scene.Drive(DriveInputAt(script, t), 0.04);
  const AugmentedFrame moved = check("after W:1.2s,A:0.4s");
  // 3.5 m/s² for 1.2 s, then rolling: about 2.5 m + 1.6 m forward.
  EXPECT_GT(moved.car_position.x - start.car_position.x, 3.0);
  EXPECT_GT(moved.view_frame, start.view_frame);  // the viewer follows the car
  EXPECT_GT(moved.light_frame, start.light_frame);
}

void WriteTrajectory(const fs::path& out, int first, int last, double shift_x = 0) {
  std::ifstream in(kDemo / "trajectory_gt.json");
  nlohmann::json j = nlohmann::json::parse(in);
  nlohmann::json frames = nlohmann::json::array();
  const auto& src = j["frames"];
  for (int i = first; i <= last; ++i) {
    auto f = src[static_cast<std::size_t>(std::min<int>(i, static_cast<int>(src.size()) - 1))];
    f["index"] = i;
    if (i >= static_cast<int>(src.size()))
      f["world_from_rig"][0][3] = f["world_from_rig"][0][3].get<double>() + shift_x * (i - src.size() + 1);
    frames.push_back(f);
  }
  j["frames"] = frames;
  std::ofstream(out) << j.dump();
}

// Bilinear sample of a panorama at continuous pixel coordinates (centres at +0.5), wrapping in x.
glm::vec3 SamplePanorama(const sphere::EquirectImage& pano, glm::dvec2 at) {
  const double u = at.x - 0.5, v = std::clamp(at.y - 0.5, 0.0, pano.height - 1.0);
  const int x0 = static_cast<int>(std::floor(u)), y0 = std::min(static_cast<int>(v), pano.height - 2);
  const float fx = static_cast<float>(u - x0), fy = static_cast<float>(v - y0);
  const auto px = [&](int x, int y) {
    const float* p = pano.at(((x % pano.width) + pano.width) % pano.width, y);
    return glm::vec3(p[0], p[1], p[2]);
  };
  return glm::mix(glm::mix(px(x0, y0), px(x0 + 1, y0), fx), glm::mix(px(x0, y0 + 1), px(x0 + 1, y0 + 1), fx), fy);
}

// The augmented 360° frame seen through the flat view's camera is the flat view: the car, its
// shadow and the street where they are not, within resampling. The car and its shadow are rendered
// on the cube faces they reach: with the broad light's cones (cone_rings 1) the car's soft shadow
// reaches past the face ahead onto the faces below and beside, which the second view looks into.
TEST(AugmentedSceneGL, The360FrameSeenThroughTheFlatCameraIsTheFlatFrame) {
  gl::HeadlessContext context;
  AugmentedOptions options = DemoOptions();
  options.cone_rings = 1;
  options.equirect_output = true;
  AugmentedScene scene(options);
  const AugmentedFrame pano = scene.RenderEquirect(1024, 0);
  ASSERT_EQ(pano.image.width, 1024);
  ASSERT_EQ(pano.image.height, 512);
  EXPECT_GE(pano.cube_faces_rendered, 2);
  EXPECT_GT(pano.car_pixels, 500);
  for (const auto& [yaw, pitch] : {std::pair{0.0, -25.0}, std::pair{70.0, -70.0}}) {
    AugmentedView view, bare;
    view.yaw_deg = bare.yaw_deg = yaw;
    view.pitch_deg = bare.pitch_deg = pitch;
    view.vfov_deg = bare.vfov_deg = 100;
    bare.draw_car = false;
    const AugmentedFrame street = scene.Render(256, 144, bare, 0);
    const AugmentedFrame flat = scene.Render(256, 144, view, 0);
    EXPECT_EQ(pano.view_frame, flat.view_frame);
    // Mean |difference| over the view, over the pixels the car or its shadow changes there, and over
    // those its shadow alone darkens (each channel by about the same ratio): a face left out where
    // the shadow reaches shows there.
    double diff = 0, changed_diff = 0, shadow_diff = 0;
    int changed = 0, shadowed = 0;
    const render::PinholeCamera& camera = scene.last_camera();
    for (int y = 0; y < camera.height; ++y)
      for (int x = 0; x < camera.width; ++x) {
        const glm::dvec2 at = sphere::EquirectPixel(pano.pano_from_car * camera.Ray(x + 0.5, y + 0.5), 1024, 512);
        const glm::vec3 seen = SamplePanorama(pano.image, at);
        const float *f = flat.image.at(x, y), *b = street.image.at(x, y);
        const double e = (std::abs(seen.x - f[0]) + std::abs(seen.y - f[1]) + std::abs(seen.z - f[2])) / 3;
        diff += e;
        if (std::abs(f[0] - b[0]) + std::abs(f[1] - b[1]) + std::abs(f[2] - b[2]) > 0.01) changed_diff += e, ++changed;
        const float ratio = f[1] / std::max(b[1], 1e-4f);
        if (ratio < 0.99f && std::abs(f[0] / std::max(b[0], 1e-4f) - ratio) < 0.02f &&
            std::abs(f[2] / std::max(b[2], 1e-4f) - ratio) < 0.02f)
          shadow_diff += e, ++shadowed;
      }
    diff /= camera.width * camera.height;
    changed_diff /= std::max(changed, 1);
    shadow_diff /= std::max(shadowed, 1);
    std::printf(
        "view yaw %.0f pitch %.0f: mean |360 frame - flat frame| %.5f, %.5f over the %d pixels the car or its "
        "shadow changes, %.5f over the %d its shadow darkens (linear); %d cube faces\n",
        yaw, pitch, diff, changed_diff, changed, shadow_diff, shadowed, pano.cube_faces_rendered);
    EXPECT_GT(changed, 300);
    EXPECT_GT(shadowed, 300);
    EXPECT_LT(diff, 0.01);
    EXPECT_LT(changed_diff, 0.03);
    EXPECT_LT(shadow_diff, 0.001);
  }
}

TEST(AugmentedSceneGL, TrajectoryShorterOrLongerThanTheVideo) {
  gl::HeadlessContext context;
  const fs::path dir = TempDir("odvr_aug_traj");
  {
    auto o = DemoOptions();
    o.trajectory = (dir / "short.json").string();
    WriteTrajectory(o.trajectory, 0, 9);
    AugmentedScene scene(o);
    EXPECT_EQ(scene.frames().size(), 10u);
    scene.PlaceCar(100);  // past the end of the poses: clamped
    const auto f = scene.Render(64, 36, {}, 0.04);
    EXPECT_LE(f.view_frame, 9);
    EXPECT_LE(f.light_frame, 9);
  }
  {
    auto o = DemoOptions();
    o.trajectory = (dir / "long.json").string();
    WriteTrajectory(o.trajectory, 0, 39, 0.36);
    AugmentedScene scene(o);
    EXPECT_EQ(scene.frames().size(), 24u);  // the video has 24 frames; poses beyond are unused
    scene.PlaceCar(1000);
    const auto f = scene.Render(64, 36, {}, 0.04);
    EXPECT_EQ(f.light_frame, 23);
  }
  {
    auto o = DemoOptions();
    o.trajectory = (dir / "none.json").string();
    WriteTrajectory(o.trajectory, 30, 39, 0.36);
    try {
      AugmentedScene scene(o);
      ADD_FAILURE() << "a trajectory sharing no frame with the video was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("shares no frame"), std::string::npos) << e.what();
    }
  }
  fs::remove_all(dir);
}

TEST(AugmentedSceneGL, CarOffThePathIsLitByTheNearestFrames) {
  gl::HeadlessContext context;
  AugmentedScene scene(DemoOptions());
  const glm::dvec3 far = scene.car().state().position + glm::dvec3(3, 0, -25);  // 25 m left, into the buildings
  scene.TeleportCar(far);
  const auto f = scene.Render(64, 36, {}, 1.0);
  double sum = 0;
  for (const auto& [frame, w] : f.light_weights) {
    sum += w;
    EXPECT_GE(frame, 0);
    EXPECT_LT(frame, 24);
  }
  EXPECT_NEAR(sum, 1.0, 1e-9);
  EXPECT_EQ(f.light_frame,
            scene.frames()[static_cast<std::size_t>(scene.picker().NearestFrame(far + glm::dvec3(0, 2.027, 0)))]);
  EXPECT_NEAR(f.car_position.z, far.z, 1e-9);
  for (float v : f.image.rgb) ASSERT_TRUE(std::isfinite(v));
}

// The demo's video is 8-bit: its sun is one clipped pixel at 1024 wide. The players light the car
// from frames at CarRendering's lighting width, where that pixel is still clipped (averaged to 256
// wide with its ring it was not, and the car cast no sun shadow), and the frame's one sun is where
// Blender put it (media/demo/scene.json), seen from the rig of that frame (trajectory_gt.json).
TEST(AugmentedSceneGL, TheDemoVideosClippedSunIsTheCarsSun) {
  gl::HeadlessContext context;
  AugmentedOptions o = DemoOptions();
  o.lighting_width = CarRendering{}.lighting_width;
  o.lighting_levels = CarRendering{}.lighting_levels;
  AugmentedScene scene(o);
  std::ifstream scene_file(kDemo / "scene.json"), trajectory_file(kDemo / "trajectory_gt.json");
  const auto sun_json = nlohmann::json::parse(scene_file)["sun"]["direction_world"];
  const auto pose = nlohmann::json::parse(trajectory_file)["frames"][2]["world_from_rig"];
  const glm::dvec3 sun_world(sun_json[0].get<double>(), sun_json[1].get<double>(), sun_json[2].get<double>());
  glm::dvec3 sun_rig(0);  // Rᵀ d, Blender's Z-up rig frame
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) sun_rig[i] += pose[j][i].get<double>() * sun_world[j];
  const glm::dvec3 sun(sun_rig.x, sun_rig.z, -sun_rig.y);  // odvr's Y-up frame
  const lighting::SgLighting& light = scene.FrameLighting(2);
  ASSERT_EQ(light.peaks.size(), 1u);
  EXPECT_LT(std::acos(std::min(1.0, glm::dot(glm::normalize(light.peaks[0].axis), sun))) * 180 / 3.14159265358979, 0.5);
}

// --supersample 2 (RenderOptions::supersample, adaptive): the car's light is the same, its
// outline and highlights are averaged over the pixel, and more samples than pixels are shaded but
// fewer than four per pixel. 5 per axis is a usage error.
TEST(AugmentedSceneGL, SupersampledCarKeepsItsLightAndSoftensItsOutline) {
  gl::HeadlessContext context;
  const int w = 192, h = 108;
  AugmentedView with, without;
  without.draw_car = false;
  AugmentedFrame frames[2], background;
  for (int k = 1; k <= 2; ++k) {
    auto o = DemoOptions();
    o.supersample = k;
    AugmentedScene scene(o);
    frames[k - 1] = scene.Render(w, h, with, 0.04);
    if (k == 1) background = scene.Render(w, h, without, 0.04);
  }
  double added[2] = {0, 0};
  int moved = 0, car = 0;
  for (std::size_t i = 0; i < background.image.rgb.size(); i += 3) {
    double y[3];
    for (int j = 0; j < 3; ++j) {
      const float* c = j < 2 ? &frames[j].image.rgb[i] : &background.image.rgb[i];
      y[j] = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    }
    added[0] += y[0] - y[2];
    added[1] += y[1] - y[2];
    car += std::abs(y[0] - y[2]) > 0.02 * std::max(y[2], 1e-3);
    moved += std::abs(y[1] - y[0]) > 0.02 * std::max(y[0], 1e-3);
  }
  std::printf(
      "car samples %d (1x1) and %d (2x2), %d pixels changed by the car, %d moved by supersampling; the "
      "car's added luminance %.2f and %.2f\n",
      frames[0].car_pixels, frames[1].car_pixels, car, moved, added[0], added[1]);
  EXPECT_GT(frames[1].car_pixels, frames[0].car_pixels);
  EXPECT_LT(frames[1].car_pixels, 4 * frames[0].car_pixels);
  EXPECT_GT(moved, 0);
  EXPECT_LT(moved, car);
  EXPECT_NEAR(added[1], added[0], 0.05 * std::abs(added[0]));
  auto bad = DemoOptions();
  bad.supersample = 5;
  try {
    AugmentedScene scene(bad);
    ADD_FAILURE() << "no error for --supersample 5";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("--supersample"), std::string::npos) << e.what();
  }
}

TEST(AugmentedSceneGL, MissingCarModelIsAClearError) {
  gl::HeadlessContext context;
  auto o = DemoOptions();
  o.car = "/nonexistent/car.glb";
  try {
    AugmentedScene scene(o);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/nonexistent/car.glb"), std::string::npos) << what;
    EXPECT_NE(what.find("car model not found"), std::string::npos) << what;
  }
}

TEST(AugmentedSceneGL, TruncatedVideoShowsItsLastGoodFrames) {
  gl::HeadlessContext context;
  const fs::path dir = TempDir("odvr_aug_trunc");
  const fs::path video = dir / "street.mp4";
  fs::copy_file(kDemo / "street.mp4", video, fs::copy_options::overwrite_existing);
  fs::resize_file(video, fs::file_size(video) / 2);  // the download broke off halfway
  auto o = DemoOptions();
  o.video = video.string();
  try {
    AugmentedScene scene(o);
    scene.PlaceCar(1000);  // the car at the end of the path, beyond what the file holds
    AugmentedFrame last;
    // The decoder thread finds the real end on its own time: render until it has.
    for (int i = 0; i < 3 || (i < 40 && scene.video_frames() >= 24); ++i) last = scene.Render(64, 36, {}, 0.04);
    last = scene.Render(64, 36, {}, 0.04);
    // Once the decoder has found the real end, nothing past it is shown or lights the car.
    // (Under load it may not have found it yet; the frames shown are then still real ones.)
    EXPECT_LT(last.view_frame, std::min<long>(scene.video_frames(), 24));
    EXPECT_LT(last.light_frame, std::min<long>(scene.video_frames(), 24));
    EXPECT_GT(last.car_pixels, 0);
  } catch (const Error& e) {
    // A file cut before its first decodable frame may only fail with a clear message.
    ADD_FAILURE() << "truncated video: " << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace odvr::app
