// The GPU path of the residual transform against the CPU path on the same frames: the same
// levels, the same SRBFs kept, the amplitudes within 1e-4 of the largest amplitude of their
// level (float sums in a different order on the two sides; the decisions must not differ).
#include "engine/lighting/residual_transform_gpu.h"

#include <gtest/gtest.h>

#include <limits>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "core/error.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/lighting/residual_transform.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/lighting/lighting_test_maps.h"

namespace odvr::lighting {
namespace {

using odvr::testing::AddDisc;
using odvr::testing::SkyMap;
using ResidualTransformGpuGL = odvr::testing::GlTest;

constexpr double kRelTolerance = 1e-4;  // of the level's largest |amplitude| channel

double MaxAbs(const glm::vec3& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

// The GPU model and report must be the CPU's: same decisions, amplitudes to kRelTolerance.
void ExpectSameTransform(const SgLighting& cpu, const TransformReport& cpu_report, const SgLighting& gpu,
                         const TransformReport& gpu_report) {
  EXPECT_EQ(gpu_report.device, "gpu");
  EXPECT_EQ(gpu_report.stop_reason, cpu_report.stop_reason);
  // Both ran the coarse correction, or neither did (its refit is in the amplitudes compared below).
  EXPECT_EQ(gpu_report.correction_ms > 0, cpu_report.correction_ms > 0);
  EXPECT_NEAR(gpu_report.mean_radiance, cpu_report.mean_radiance, 1e-5 * cpu_report.mean_radiance);
  const double constant_scale = std::max(1e-12, MaxAbs(cpu.constant));
  EXPECT_LT(MaxAbs(gpu.constant - cpu.constant), 1e-5 * constant_scale);
  ASSERT_EQ(gpu_report.levels.size(), cpu_report.levels.size());
  for (std::size_t i = 0; i < cpu_report.levels.size(); ++i) {
    const LevelReport &c = cpu_report.levels[i], &g = gpu_report.levels[i];
    EXPECT_EQ(g.level, c.level);
    EXPECT_EQ(g.srbfs_total, c.srbfs_total);
    EXPECT_EQ(g.srbfs_kept, c.srbfs_kept) << "level " << c.level;
    EXPECT_EQ(g.width, c.width);
    EXPECT_EQ(g.height, c.height);
    EXPECT_DOUBLE_EQ(g.lambda, c.lambda);
    EXPECT_NEAR(g.residue_before, c.residue_before, 1e-5 + 1e-4 * c.residue_before) << "level " << c.level;
    EXPECT_NEAR(g.residue_after, c.residue_after, 1e-5 + 1e-4 * c.residue_after) << "level " << c.level;
  }
  ASSERT_EQ(gpu.levels.size(), cpu.levels.size());
  for (std::size_t i = 0; i < cpu.levels.size(); ++i) {
    const SgLevel &c = cpu.levels[i], &g = gpu.levels[i];
    EXPECT_EQ(g.level, c.level);
    ASSERT_EQ(g.indices, c.indices) << "level " << c.level << ": different SRBFs kept";
    double largest = 0, worst = 0;
    for (const auto& a : c.amplitudes) largest = std::max(largest, MaxAbs(a));
    for (std::size_t k = 0; k < c.amplitudes.size(); ++k)
      worst = std::max(worst, MaxAbs(g.amplitudes[k] - c.amplitudes[k]));
    EXPECT_LE(worst, kRelTolerance * largest) << "level " << c.level << ": largest |amplitude| " << largest;
  }
}

void ExpectGpuMatchesCpu(const sphere::EquirectImage& frame, const ResidualTransformOptions& options) {
  ResidualTransform cpu(options);
  ResidualTransformGpu gpu(options);
  TransformReport cpu_report, gpu_report;
  const SgLighting cpu_model = cpu.Run(frame, &cpu_report);
  const SgLighting gpu_model = gpu.Run(frame, &gpu_report);
  ExpectSameTransform(cpu_model, cpu_report, gpu_model, gpu_report);
}

sphere::EquirectImage SunnySky(int w, int h) {
  auto frame = SkyMap(w, h);
  AddDisc(&frame, {0.3, 0.8, -0.4}, 0.03, 2e3f);
  AddDisc(&frame, {-0.9, 0.1, 0.5}, 0.1, 5.f);  // a lit facade: a second, dimmer feature
  return frame;
}

TEST_F(ResidualTransformGpuGL, SunnySkyMatchesCpuWithEveryNormalization) {
  const auto frame = SunnySky(256, 128);
  for (const Normalization n : {Normalization::kPartition, Normalization::kLocalSum, Normalization::kNone}) {
    SCOPED_TRACE(static_cast<int>(n));
    ResidualTransformOptions o;
    o.normalization = n;
    ExpectGpuMatchesCpu(frame, o);
  }
}

TEST_F(ResidualTransformGpuGL, MagnifiedReconstructionMatchesCpu) {
  // The cheaper option: the coarser grid's reconstruction magnified, all levels kept.
  ResidualTransformOptions o;
  o.stop_threshold = 0;
  o.exact_reconstruction = false;
  ResidualTransform cpu(o);
  TransformReport report;
  cpu.Run(SunnySky(256, 128), &report);
  ASSERT_EQ(report.levels.size(), 5u) << report.stop_reason;
  EXPECT_GT(report.correction_ms, 0.0);  // the comparison covers the coarse correction
  ExpectGpuMatchesCpu(SunnySky(256, 128), o);
}

TEST_F(ResidualTransformGpuGL, BuilderStartingFromTheDetectorsCoarseGridMatchesCpu) {
  // LightingBuilder hands the transform the detector's coarse grid (the finest working grid)
  // instead of the residue: the GPU path then resamples that grid onto itself, and must still
  // be the CPU's, which starts from the residue when the fusion is off.
  auto frame = SunnySky(1024, 512);
  for (int levels : {2, 3}) {
    SCOPED_TRACE(levels);
    LightingOptions o;
    o.transform.levels = levels;
    o.transform.stop_threshold = 0;
    LightingBuilder fused(o);
    ASSERT_GT(fused.FusedFactor(frame.width, frame.height), 1);
    o.fuse_coarse_grid = false;
    LightingBuilder plain(o);
    ResidualTransformGpu gpu(o.transform);
    LightingReport cpu_report, gpu_report;
    const SgLighting cpu_model = plain.Build(frame, &cpu_report);
    const SgLighting gpu_model = fused.Build(frame, &gpu_report, &gpu);
    ASSERT_EQ(gpu_report.peak_detection.peaks.size(), 1u);
    ExpectSameTransform(cpu_model, cpu_report.transform, gpu_model, gpu_report.transform);
  }
}

TEST_F(ResidualTransformGpuGL, BuilderWithoutPeaksHandsTheGpuTheFinestGridAndMatchesCpu) {
  // Without peaks the builder area-resamples a frame wider than the peak grid straight to the
  // transform's finest grid for the GPU (the CPU path takes the frame whole): the same model,
  // bad pixels clamped before they are averaged as the CPU does (not a NaN spread over a block).
  auto frame = SunnySky(2048, 1024);
  frame.rgb[3 * (300 * 2048 + 700)] = std::numeric_limits<float>::quiet_NaN();
  frame.rgb[3 * (301 * 2048 + 701) + 1] = -50.f;
  frame.rgb[3 * (900 * 2048 + 5) + 2] = std::numeric_limits<float>::infinity();
  for (int levels : {3, 5}) {
    SCOPED_TRACE(levels);
    LightingOptions o;
    o.detect_peaks = false;
    o.transform.levels = levels;
    o.transform.stop_threshold = 0;
    LightingBuilder cpu(o), builder(o);
    ASSERT_GT(builder.FusedFactor(o.peak_grid_width, o.peak_grid_width / 2), 1);
    ResidualTransformGpu gpu(o.transform);
    LightingReport cpu_report, gpu_report;
    const SgLighting cpu_model = cpu.Build(frame, &cpu_report);
    const SgLighting gpu_model = builder.Build(frame, &gpu_report, &gpu);
    ASSERT_EQ(gpu_report.transform.levels.size(), static_cast<std::size_t>(levels));
    // The GPU was given the transform's finest grid (at least 64 wide), not the frame or the
    // 1024-wide peak grid; the CPU the frame whole.
    EXPECT_EQ(gpu_report.transform.input_width, std::max(64, 32 << (levels - 1)));
    EXPECT_EQ(gpu_report.transform.input_height, gpu_report.transform.input_width / 2);
    EXPECT_EQ(cpu_report.transform.input_width, 2048);
    ExpectSameTransform(cpu_model, cpu_report.transform, gpu_model, gpu_report.transform);
  }
}

TEST_F(ResidualTransformGpuGL, AllLevelsAndOneSweepMatchCpu) {
  // No stop rule and no keep rule: every level of both paths, amplitudes compared one by one,
  // and the seed's single pass per level.
  ResidualTransformOptions o;
  o.stop_threshold = 0;
  o.keep_threshold = 0;
  o.sweeps = 1;
  o.fine_sweeps = 1;
  ResidualTransform cpu(o);
  TransformReport report;
  cpu.Run(SunnySky(256, 128), &report);
  ASSERT_EQ(report.levels.size(), 5u) << report.stop_reason;  // the comparison covers every level
  ExpectGpuMatchesCpu(SunnySky(256, 128), o);
}

TEST_F(ResidualTransformGpuGL, RealSkyMapMatchesCpu) {
  const std::filesystem::path path = ODVR_SHARED_DIR "/data/env/sky.exr";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent (the shared test data)";
  const sphere::EquirectImage frame = image::LoadImage(path);
  ASSERT_EQ(frame.width, 512);
  ResidualTransformOptions o;
  ResidualTransform cpu(o);
  TransformReport report;
  cpu.Run(frame, &report);
  EXPECT_GE(report.levels.size(), 4u) << "a sunny map should need the fine levels: " << report.stop_reason;
  ExpectGpuMatchesCpu(frame, o);
}

TEST_F(ResidualTransformGpuGL, GridsThatAreNotPowersOfTwoMatchCpu) {
  // 200×100: fractional box weights in the area resampling; 234×120 (not exactly 2:1): rounded
  // grid heights; 128×64: grids capped at the input width, so the upsampling is an identity.
  for (const auto& [w, h] : {std::pair{200, 100}, std::pair{234, 120}, std::pair{128, 64}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    auto frame = SkyMap(w, h);
    AddDisc(&frame, {-1, 0.05, 0.0}, 0.08, 30.f);  // straddles the seam
    ResidualTransformOptions o;
    o.stop_threshold = 0;
    ExpectGpuMatchesCpu(frame, o);
  }
}

TEST_F(ResidualTransformGpuGL, ATextureOnTheGpuGivesTheSameModelAsTheImage) {
  const auto frame = SunnySky(256, 128);
  // The player's layout: RGBA half floats would lose the sun, so the frame is float RGBA here;
  // the transform reads .rgb of level 0 whatever the format.
  std::vector<float> rgba(frame.pixel_count() * 4, 1.f);
  for (std::size_t p = 0; p < frame.pixel_count(); ++p) std::copy_n(&frame.rgb[3 * p], 3, &rgba[4 * p]);
  gl::Texture texture = gl::Texture::Create2D(GL_RGBA32F, frame.width, frame.height);
  texture.Upload2D(GL_RGBA, GL_FLOAT, rgba.data());
  ResidualTransformGpu gpu;
  TransformReport from_image, from_texture;
  const SgLighting a = gpu.Run(frame, &from_image);
  const SgLighting b = gpu.Run(texture, &from_texture);
  ExpectSameTransform(a, from_image, b, from_texture);
  // A texture handed over by name (no size in the wrapper) works too.
  gl::Texture wrapped = gl::Texture::wrap(texture.id(), GL_TEXTURE_2D);
  const SgLighting c = gpu.Run(wrapped, nullptr);
  wrapped.release();
  ExpectSameTransform(a, from_image, c, from_texture);
}

TEST_F(ResidualTransformGpuGL, BlackFrameGivesAnEmptyModel) {
  ResidualTransformGpu gpu;
  TransformReport report;
  const SgLighting m = gpu.Run(sphere::EquirectImage(64, 32), &report);
  EXPECT_EQ(m.sg_count(), 0);
  EXPECT_EQ(report.stop_reason, "the frame is black");
  EXPECT_EQ(report.device, "gpu");
}

TEST_F(ResidualTransformGpuGL, ConstantFrameAsOnCpu) {
  const sphere::EquirectImage frame(128, 64, 0.7f);
  ResidualTransformGpu gpu;
  TransformReport report;
  const SgLighting m = gpu.Run(frame, &report);
  EXPECT_LE(m.sg_count(), 12);
  for (float v : m.Reconstruct(128, 64).rgb) EXPECT_NEAR(v, 0.7f, 0.7e-3f);
  ResidualTransform cpu;
  TransformReport cpu_report;
  ExpectSameTransform(cpu.Run(frame, &cpu_report), cpu_report, m, report);
}

// The GPU queues every level and lets lighting_gate.comp stop the ones after a stop: each way a
// transform ends must give the CPU's model and report, and one transform object must go on
// working after a frame that stopped early (the gate opens again for the next frame and for the
// coarse correction). Fine noise around a constant stops once a level leaves less than the
// threshold (after level 3, measured); a constant frame's level 0 has nothing left to reduce
// after the constant term, so it is rejected; the sunny sky uses every level.
TEST_F(ResidualTransformGpuGL, EveryWayTheLevelsEndMatchesCpu) {
  sphere::EquirectImage noisy(64, 32, 1.f);
  unsigned state = 12345u;
  for (float& v : noisy.rgb) {
    state = state * 1664525u + 1013904223u;
    v = 1.f + 0.05f * (static_cast<float>(state >> 8) / 16777216.f - 0.5f);
  }
  ResidualTransformGpu gpu;
  ResidualTransform cpu;
  std::vector<std::string> reasons;
  std::vector<int> levels_run;
  for (const sphere::EquirectImage& frame :
       {noisy, sphere::EquirectImage(128, 64, 0.7f), SunnySky(256, 128), noisy, SunnySky(256, 128)}) {
    TransformReport gpu_report, cpu_report;
    const SgLighting g = gpu.Run(frame, &gpu_report);
    ExpectSameTransform(cpu.Run(frame, &cpu_report), cpu_report, g, gpu_report);
    reasons.push_back(gpu_report.stop_reason);
    levels_run.push_back(gpu_report.gpu_levels_run);
    for (const LevelReport& l : gpu_report.levels) EXPECT_GT(l.ms, 0.0) << "level " << l.level << " timed";
  }
  for (std::size_t i = 0; i < reasons.size(); ++i)
    std::printf("stop: %s; levels run on the GPU %d\n", reasons[i].c_str(), levels_run[i]);
  EXPECT_NE(reasons[0].find("below threshold after level"), std::string::npos) << reasons[0];
  EXPECT_EQ(reasons[1], "level 0 does not reduce the residue");
  EXPECT_EQ(reasons[2], "maximum level reached");
  // The gate: the levels after the stop did not run.
  EXPECT_EQ(levels_run[0], 4);
  EXPECT_EQ(levels_run[1], 1);
  EXPECT_EQ(levels_run[2], 5);
}

TEST_F(ResidualTransformGpuGL, NanInfAndNegativePixelsAreClampedAsOnCpu) {
  auto frame = SunnySky(256, 128);
  frame.at(3, 3)[0] = std::nanf("");
  frame.at(100, 40)[1] = INFINITY;
  frame.at(101, 40)[2] = -INFINITY;
  frame.at(50, 20)[2] = -3894.f;
  ResidualTransformGpu gpu;
  const SgLighting m = gpu.Run(frame);
  for (const auto& g : m.ToSgs())
    ASSERT_TRUE(std::isfinite(g.amplitude.x) && std::isfinite(g.amplitude.y) && std::isfinite(g.amplitude.z));
  ExpectGpuMatchesCpu(frame, {});
  // Clamping to 0 is what happened: the same frame cleaned first gives the same model.
  auto clean = frame;
  image::SanitizePixels(&clean);
  TransformReport dirty_report, clean_report;
  const SgLighting dirty_model = gpu.Run(frame, &dirty_report);
  ExpectSameTransform(dirty_model, dirty_report, gpu.Run(clean, &clean_report), clean_report);
}

TEST_F(ResidualTransformGpuGL, TinyAndNonEquirectInputsAreClearErrors) {
  ResidualTransformGpu gpu;
  EXPECT_THROW(gpu.Run(sphere::EquirectImage(1, 1, 1.f)), Error);
  EXPECT_THROW(gpu.Run(sphere::EquirectImage(100, 100, 1.f)), Error);
  ResidualTransformOptions bad;
  bad.sweeps = 0;
  EXPECT_THROW(ResidualTransformGpu{bad}, Error);
  // After a refused frame the next good one still runs.
  TransformReport report;
  gpu.Run(SunnySky(128, 64), &report);
  EXPECT_FALSE(report.levels.empty());
}

}  // namespace
}  // namespace odvr::lighting
