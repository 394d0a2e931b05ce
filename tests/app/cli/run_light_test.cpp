// `odvr light` as a user runs it: the real binary on the real sky map.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/image/image_io.h"
#include "engine/lighting/sg_lighting.h"
#include "tests/app/run_odvr.h"

namespace {

using odvr::testing::CliRun;
using odvr::testing::Lines;
using odvr::testing::RunOdvr;

const std::string kSky = std::string(ODVR_SHARED_DIR) + "/data/env/sky.exr";

// Runs `odvr light` on sky.exr with --json and checks the report's shape; returns it.
nlohmann::json LightSky(const std::string& device, const std::string& out, const std::string& preview) {
  const CliRun r = RunOdvr("light " + kSky + " --json --device " + device + " --out " + out + " --preview " + preview);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  if (r.exit_code != 0) return {};
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("device").get<std::string>(), device);
  EXPECT_GT(j.at("total_ms").get<double>(), 0);
  EXPECT_GE(j.at("peaks").at("count").get<int>(), 1);
  const auto& levels = j.at("levels");
  EXPECT_GE(levels.size(), 3u);
  for (std::size_t i = 0; i < levels.size(); ++i) {
    const auto& l = levels[i];
    for (const char* key : {"level", "srbfs_total", "srbfs_kept", "lambda", "ms", "diffuse_error", "glossy20_error",
                            "glossy200_error", "rel_l2_error"})
      EXPECT_TRUE(l.contains(key)) << "level " << i << " lacks " << key;
    EXPECT_EQ(l.at("level").get<int>(), static_cast<int>(i));
    EXPECT_LE(l.at("srbfs_kept").get<int>(), l.at("srbfs_total").get<int>());
    EXPECT_EQ(l.at("srbfs_total").get<int>(), 12 << (2 * i));
    for (const char* key : {"diffuse_error", "glossy20_error", "glossy200_error", "rel_l2_error"}) {
      const double e = l.at(key).get<double>();
      EXPECT_TRUE(std::isfinite(e) && e >= 0) << key << " = " << e;
    }
  }
  return j;
}

TEST(RunLight, SkyMapJsonReportModelAndPreview) {
  if (!std::filesystem::exists(kSky)) GTEST_SKIP() << kSky << " is absent (the shared test data)";
  const std::string out = ::testing::TempDir() + "run_light_sky.json";
  const std::string preview = ::testing::TempDir() + "run_light_sky.exr";
  std::filesystem::remove(out);
  std::filesystem::remove(preview);
  const nlohmann::json j = LightSky("cpu", out, preview);
  ASSERT_FALSE(j.is_null());
  const auto& levels = j.at("levels");
  ASSERT_GE(levels.size(), 3u);
  for (const auto& l : levels)
    std::printf("level %d: %d/%d kept, lambda %.2f, %.2f ms, diffuse %.4f glossy20 %.4f glossy200 %.4f rel_l2 %.4f\n",
                l["level"].get<int>(), l["srbfs_kept"].get<int>(), l["srbfs_total"].get<int>(),
                l["lambda"].get<double>(), l["ms"].get<double>(), l["diffuse_error"].get<double>(),
                l["glossy20_error"].get<double>(), l["glossy200_error"].get<double>(), l["rel_l2_error"].get<double>());
  std::printf("peaks %d, total %.1f ms (first build %.1f ms)\n", j["peaks"]["count"].get<int>(),
              j["total_ms"].get<double>(), j["first_total_ms"].get<double>());
  // The reported build is the second, the overlap lists already made; the first's time is beside it.
  EXPECT_GT(j.at("first_total_ms").get<double>(), 0);
  double levels_ms = 0;
  for (const auto& l : levels) levels_ms += l.at("ms").get<double>();
  EXPECT_LE(levels_ms, j.at("total_ms").get<double>());
  // The target: diffuse error ≤ 1 % from level 2 on.
  for (std::size_t i = 2; i < levels.size(); ++i) EXPECT_LE(levels[i].at("diffuse_error").get<double>(), 0.01) << i;

  // The model the renderer loads, and the preview, are real files of what was reported.
  const auto model = odvr::lighting::SgLighting::Load(out);
  EXPECT_EQ(static_cast<int>(model.peaks.size()), j["peaks"]["count"].get<int>());
  EXPECT_EQ(model.sg_count(), j["sg_count"].get<int>());
  const auto recon = odvr::image::LoadImage(preview);
  EXPECT_EQ(recon.width, 512);
  EXPECT_EQ(recon.height, 256);
}

// An indoor LDR clip (a room of white grid lines, no sun): its clipped lines made 3 phantom suns
// of amplitude ~1900 (relative L2 error 44.5, diffuse error 206 % against 0.002 % without peaks).
TEST(RunLight, AnLdrRoomGrowsNoPhantomSun) {
  const std::string clip = std::string(ODVR_SHARED_DIR) + "/data/video360/testRoom1_1920Mono.mp4";
  if (!std::filesystem::exists(clip)) GTEST_SKIP() << clip << " absent (../shared is not in a user's clone)";
  const odvr::testing::ScratchDir d("run_light_room");
  const std::string frame = (d.dir / "room.png").string();
  ASSERT_EQ(std::system(("ffmpeg -v error -y -ss 3 -i " + clip + " -frames:v 1 " + frame).c_str()), 0);
  const CliRun r = RunOdvr("light " + frame + " --levels 3 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["peaks"]["count"].get<int>(), 0);
  // Its clipped grid-line crossings glow alike: none stands out as the sun.
  const auto glow = j["peaks"]["ldr_glow"];
  std::printf("room: glow of the two best LDR candidates %.4f, %.4f\n", glow[0].get<double>(), glow[1].get<double>());
  EXPECT_LT(glow[0].get<double>(), 1.5 * glow[1].get<double>());
  EXPECT_LT(j["diffuse_error"].get<double>(), 0.01);
  EXPECT_LT(j["rel_l2_error"].get<double>(), 1.0);
  const CliRun text = RunOdvr("light " + frame + " --levels 3");
  EXPECT_NE(text.out.find("LDR frame (no value above 1): no clipped region looks like a sun"), std::string::npos)
      << text.out;
}

TEST(RunLight, UnreadableFileIsExitOneWithOneLineNamingIt) {
  const std::string bad = ::testing::TempDir() + "run_light_not_an_image.exr";
  std::FILE* f = std::fopen(bad.c_str(), "w");
  ASSERT_TRUE(f);
  std::fputs("this is not an EXR file\n", f);
  std::fclose(f);
  for (const std::string& path : {bad, ::testing::TempDir() + "run_light_no_such_file.exr"}) {
    const CliRun r = RunOdvr("light " + path + " --json");
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_EQ(Lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
  }
}

TEST(RunLight, LevelsOutOfRangeIsAUsageError) {
  const CliRun r = RunOdvr("light " + kSky + " --levels 9");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_EQ(Lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("--levels"), std::string::npos) << r.err;
}

// The tuning flags (shared with bench light) reach the transform: without the coarse correction
// (5 levels on) none is run, the seed's single pass and plain normalization give another model; a value out of
// range or unknown is a usage error naming its flag.
TEST(RunLight, TuningFlagsReachTheTransform) {
  if (!std::filesystem::exists(kSky)) GTEST_SKIP() << kSky << " is absent (the shared test data)";
  const auto light = [](const std::string& flags) {
    const CliRun r = RunOdvr("light " + kSky + " --json --levels 5 --threshold 0 --no-peaks " + flags);
    EXPECT_EQ(r.exit_code, 0) << flags << ": " << r.err;
    return r.exit_code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json{};
  };
  const nlohmann::json plain = light(""), uncorrected = light("--no-coarse-correction"),
                       seed = light("--sweeps 1 --fine-sweeps 1 --normalization none");
  ASSERT_FALSE(plain.is_null() || uncorrected.is_null() || seed.is_null());
  EXPECT_GT(plain.at("correction_ms").get<double>(), 0);
  EXPECT_EQ(uncorrected.at("correction_ms").get<double>(), 0);
  EXPECT_NE(uncorrected.at("diffuse_error").get<double>(), plain.at("diffuse_error").get<double>());
  EXPECT_NE(seed.at("glossy20_error").get<double>(), uncorrected.at("glossy20_error").get<double>());
  for (const std::string flags : {"--normalization sideways", "--fine-sweeps 0", "--region-cutoff 0.9"}) {
    const CliRun r = RunOdvr("light " + kSky + " " + flags);
    EXPECT_EQ(r.exit_code, 2) << flags << ": " << r.err;
    EXPECT_EQ(Lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(flags.substr(0, flags.find(' '))), std::string::npos) << r.err;
  }
}

TEST(RunLight, GpuKeepsTheSameSrbfsAsCpu) {
  if (!std::filesystem::exists(kSky)) GTEST_SKIP() << kSky << " is absent (the shared test data)";
  try {
    odvr::gl::HeadlessContext probe;
  } catch (const odvr::Error& e) {
    GTEST_SKIP() << "no OpenGL 4.5 context here: " << e.what();
  }
  const std::string dir = ::testing::TempDir();
  const nlohmann::json cpu = LightSky("cpu", dir + "run_light_cpu.json", dir + "run_light_cpu.exr");
  const nlohmann::json gpu = LightSky("gpu", dir + "run_light_gpu.json", dir + "run_light_gpu.exr");
  ASSERT_FALSE(cpu.is_null());
  ASSERT_FALSE(gpu.is_null());
  ASSERT_EQ(gpu["levels"].size(), cpu["levels"].size());
  for (std::size_t i = 0; i < cpu["levels"].size(); ++i)
    EXPECT_EQ(gpu["levels"][i]["srbfs_kept"].get<int>(), cpu["levels"][i]["srbfs_kept"].get<int>()) << "level " << i;
  EXPECT_EQ(gpu["peaks"]["count"].get<int>(), cpu["peaks"]["count"].get<int>());
}

}  // namespace
