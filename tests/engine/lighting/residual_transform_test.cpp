#include "engine/lighting/residual_transform.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <tuple>

#include "core/error.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_errors.h"
#include "engine/lighting/reference_fits.h"
#include "engine/sphere/healpix.h"
#include "engine/sphere/resample.h"
#include "tests/engine/lighting/lighting_test_maps.h"

namespace odvr::lighting {
namespace {

using odvr::testing::AddDisc;
using odvr::testing::AngleDeg;
using odvr::testing::SkyMap;

// "diffuse glossy20 glossy200", for a failure's trace.
std::string Describe(const LightingErrors& e) {
  return std::to_string(e.diffuse) + " " + std::to_string(e.glossy20) + " " + std::to_string(e.glossy200);
}

TEST(ResidualTransform, ConstantFrameIsOneSgToOneThousandth) {
  const sphere::EquirectImage frame(128, 64, 0.7f);
  ResidualTransform t;
  TransformReport report;
  const SgLighting m = t.Run(frame, &report);
  EXPECT_LE(m.sg_count(), 12);
  const auto recon = m.Reconstruct(128, 64);
  for (float v : recon.rgb) EXPECT_NEAR(v, 0.7f, 0.7e-3f);
  EXPECT_LE(report.levels.size(), 1u);  // a uniform sky ends after (at most) one level
}

TEST(ResidualTransform, BlackFrameGivesAnEmptyModel) {
  ResidualTransform t;
  TransformReport report;
  const SgLighting m = t.Run(sphere::EquirectImage(64, 32), &report);
  EXPECT_EQ(m.sg_count(), 0);
  EXPECT_EQ(report.stop_reason, "the frame is black");
}

TEST(ResidualTransform, SmoothSkyStopsEarlyAndReconstructsWell) {
  // An overcast sky: brighter towards the zenith, no hard horizon (a sharp edge needs fine levels).
  sphere::EquirectImage sky(256, 128);
  for (int row = 0; row < 128; ++row)
    for (int col = 0; col < 256; ++col) {
      const auto d = sphere::EquirectPixelDirection(col, row, 256, 128);
      float* p = sky.at(col, row);
      p[0] = static_cast<float>(0.5 + 0.3 * d.y + 0.05 * d.x);
      p[1] = static_cast<float>(0.55 + 0.35 * d.y);
      p[2] = static_cast<float>(0.6 + 0.4 * d.y - 0.05 * d.z);
    }
  ResidualTransformOptions o;
  o.stop_threshold = 0.01;
  ResidualTransform t(o);
  TransformReport report;
  const SgLighting m = t.Run(sky, &report);
  EXPECT_LE(report.levels.size(), 3u) << report.stop_reason;  // models only what the sky needs
  EXPECT_LT(report.levels.back().residue_after, 0.01);
  LightingErrorEvaluator ev(sky);
  EXPECT_LT(ev.Evaluate(m).diffuse, 0.01);
}

TEST(ResidualTransform, DroppedSrbfsGiveTheirShareBackToTheResidue) {
  // A level that drops negligible SRBFs leaves their share in the residue: the residue it
  // reports must be that of the kept SRBFs alone. At
  // level 0 (λ 5.5) every cap covers the whole sphere, so the model's own reconstruction on the
  // level's 64 × 32 grid is the reference.
  sphere::EquirectImage frame = SkyMap(128, 64);
  AddDisc(&frame, {0.3, 0.6, -0.5}, 0.15, 40.f);
  ResidualTransformOptions o;
  o.levels = 1;
  o.keep_threshold = 0.6;  // drops the SRBFs away from the sun and the sky's bright half
  o.stop_threshold = 0;
  TransformReport report;
  const SgLighting model = ResidualTransform(o).Run(frame, &report);
  ASSERT_EQ(report.levels.size(), 1u) << report.stop_reason;
  const LevelReport& level = report.levels[0];
  ASSERT_EQ(level.width, 64);
  EXPECT_GT(level.srbfs_kept, 0);
  EXPECT_LT(level.srbfs_kept, level.srbfs_total);
  const sphere::EquirectImage target = sphere::ResampleArea(frame, 64, 32);
  const sphere::EquirectImage recon = model.Reconstruct(64, 32);
  sphere::EquirectImage left(64, 32);
  for (std::size_t i = 0; i < left.rgb.size(); ++i) left.rgb[i] = target.rgb[i] - recon.rgb[i];
  const double expected = MeanAbsRadiance(left) / MeanAbsRadiance(target);
  EXPECT_NEAR(level.residue_after, expected, 1e-4 * expected);
}

TEST(ResidualTransform, NoErrorGrowsWhenALevelIsAddedEvenWithAnUntreatedSun) {
  // The trap of the issue: without peaks, eq. 4.17 as written overshoots the sun's energy. The
  // default (partition-of-unity) projection must make every convolved error fall level by level.
  auto frame = SkyMap(256, 128);
  AddDisc(&frame, {0.3, 0.8, -0.4}, 0.02, 2e3f);
  LightingErrorEvaluator ev(frame);
  LightingErrors previous{1e9, 1e9, 1e9, 1e9};
  for (int levels = 1; levels <= 5; ++levels) {
    ResidualTransformOptions o;
    o.levels = levels;
    o.stop_threshold = 0;
    o.keep_threshold = 0;
    ResidualTransform t(o);
    const LightingErrors e = ev.Evaluate(t.Run(frame));
    EXPECT_LE(e.diffuse, previous.diffuse * 1.02 + 1e-4) << levels;
    EXPECT_LE(e.glossy20, previous.glossy20 * 1.02 + 1e-4) << levels;
    EXPECT_LE(e.glossy200, previous.glossy200 * 1.02 + 1e-4) << levels;
    previous = e;
  }
  EXPECT_LT(previous.diffuse, 0.02);
}

TEST(ResidualTransform, MagnifiedReconstructionComesAsCloseToTheLeastSquaresOptimumAsExactOne) {
  // Each level fits the error of the coarser levels' reconstruction on its grid, which the model
  // (evaluated exactly) does not contain. Magnified bilinearly, that bias held the diffuse and
  // glossy-20 errors at 5-20x the optimum on the same basis; through six samples per axis (the
  // default) it leaves the errors where evaluating every coarser level on the grid puts them
  // (the target: within 1.5x of the optimum).
  const std::string path = std::string(ODVR_SHARED_DIR) + "/data/env/venice.exr";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent (the shared test data)";
  // Halved (area-preserving) to keep the least-squares fit fast: level 3 still has its 2 px per σ.
  const sphere::EquirectImage frame = sphere::ResampleArea(image::LoadImage(path), 256, 128);
  LightingErrorEvaluator ev(frame);
  const LightingErrors ls = ev.Evaluate(LeastSquaresSgFit(frame, 4));
  ResidualTransformOptions o;
  o.levels = 4;
  o.stop_threshold = 0;
  ASSERT_FALSE(o.exact_reconstruction);
  const LightingErrors magnified = ev.Evaluate(ResidualTransform(o).Run(frame));
  o.exact_reconstruction = true;
  const LightingErrors exact = ev.Evaluate(ResidualTransform(o).Run(frame));
  SCOPED_TRACE("least squares " + Describe(ls) + ", magnified " + Describe(magnified) + ", exact " + Describe(exact));
  for (const LightingErrors& e : {magnified, exact}) {
    EXPECT_LE(e.diffuse, 1.5 * ls.diffuse);
    EXPECT_LE(e.glossy20, 1.5 * ls.glossy20);
  }
  EXPECT_NEAR(magnified.diffuse, exact.diffuse, 0.01 * exact.diffuse);
  EXPECT_NEAR(magnified.glossy20, exact.glossy20, 0.01 * exact.glossy20);
  EXPECT_NEAR(magnified.glossy200, exact.glossy200, 0.01 * exact.glossy200);

  // Two more measured causes of the gap: a single plain refit at the fine levels (λ ≥ 300) left the
  // glossy-200 error 4x the optimum here (0.018 against 0.0044; four plain passes: 0.0078, three
  // over-relaxed ones, the default: 0.0057), and the
  // broad levels' caps cut at 1e-3 drop 0.1 % of each SG's energy far from its centre, where no
  // finer level sees it, yet the model (whole SGs) holds it (glossy-20 0.00046 against 0.00039).
  o.fine_sweeps = o.sweeps;
  o.fine_relaxation = 1;
  const LightingErrors one_refit = ev.Evaluate(ResidualTransform(o).Run(frame));
  o.broad_region_cutoff = o.region_cutoff;
  const LightingErrors narrow_caps = ev.Evaluate(ResidualTransform(o).Run(frame));
  SCOPED_TRACE("exact " + std::to_string(exact.glossy200) + ", one refit " + std::to_string(one_refit.glossy20) + " " +
               std::to_string(one_refit.glossy200) + ", narrow caps " + std::to_string(narrow_caps.glossy20));
  EXPECT_LE(exact.glossy200, 2 * ls.glossy200);
  EXPECT_LT(exact.glossy200, 0.5 * one_refit.glossy200);
  EXPECT_LT(one_refit.glossy20, 0.9 * narrow_caps.glossy20);
}

TEST(ResidualTransform, CoarseCorrectionTakesBackTheLowFrequencyErrorOfTheFinestLevel) {
  // hall's ceiling lamps: level 4's fit left a low-frequency error that raised the glossy-20
  // error above level 3's and held the diffuse and glossy-20 errors at ~3x the optimum on the same
  // basis; the two levels below it refitting what every level left take them to the optimum.
  const std::string path = std::string(ODVR_SHARED_DIR) + "/data/env/hall.exr";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent (the shared test data)";
  const sphere::EquirectImage frame = image::LoadImage(path);
  LightingErrorEvaluator ev(frame);
  const LightingErrors ls = ev.Evaluate(LeastSquaresSgFit(frame, 5));
  ResidualTransformOptions o;
  o.levels = 5;
  o.stop_threshold = 0;
  ASSERT_TRUE(o.coarse_correction);
  TransformReport report;
  const SgLighting corrected_model = ResidualTransform(o).Run(frame, &report);
  const LightingErrors corrected = ev.Evaluate(corrected_model);
  o.coarse_correction = false;
  const LightingErrors plain = ev.Evaluate(ResidualTransform(o).Run(frame));
  o.levels = 4;
  const LightingErrors four_levels = ev.Evaluate(ResidualTransform(o).Run(frame));
  SCOPED_TRACE("least squares " + Describe(ls) + ", corrected " + Describe(corrected) + ", plain " + Describe(plain) +
               ", 4 levels glossy-20 " + std::to_string(four_levels.glossy20));
  EXPECT_GT(plain.glossy20, four_levels.glossy20);  // the trap: a level added, an error grown
  EXPECT_GT(plain.diffuse, 2 * ls.diffuse);
  EXPECT_GT(plain.glossy20, 2 * ls.glossy20);
  EXPECT_LT(corrected.glossy20, four_levels.glossy20);
  EXPECT_LE(corrected.diffuse, 1.5 * ls.diffuse);
  EXPECT_LE(corrected.glossy20, 1.5 * ls.glossy20);
  EXPECT_LE(corrected.glossy200, 1.5 * ls.glossy200);
  EXPECT_GT(report.correction_ms, 0.0);
  for (const SgLevel& level : corrected_model.levels)
    for (const glm::vec3& a : level.amplitudes) ASSERT_TRUE(std::isfinite(a.x + a.y + a.z));
}

TEST(ResidualTransform, OverRelaxedFineSweepsReachTheFitOfMoreSweeps) {
  // The refitting passes are a Richardson iteration whose operator shrinks what it is given, so
  // a step over 1 converges faster to the same fixed point: the fine levels' amplitudes after
  // three passes at the default step must lie closer to those of 16 passes than four plain
  // passes do (one pass less per fine level), and 16 passes at a step near 2 must neither
  // diverge nor land elsewhere.
  auto frame = SkyMap(512, 256);
  AddDisc(&frame, {0.3, 0.8, -0.4}, 0.02, 300.f);
  AddDisc(&frame, {-0.6, 0.1, 0.7}, 0.05, 40.f);
  AddDisc(&frame, {0.1, -0.3, -0.9}, 0.1, 8.f);
  const auto fine_amplitudes = [&](int sweeps, double step) {
    ResidualTransformOptions o;
    o.stop_threshold = 0;
    o.keep_threshold = 0;  // every SRBF kept: the runs' amplitudes line up
    o.fine_sweeps = sweeps;
    o.fine_relaxation = step;
    const SgLighting m = ResidualTransform(o).Run(frame);
    std::vector<float> mu;
    for (const SgLevel& level : m.levels)
      if (level.level >= 3)
        for (const glm::vec3& a : level.amplitudes) mu.insert(mu.end(), {a.x, a.y, a.z});
    return mu;
  };
  const auto distance = [](const std::vector<float>& a, const std::vector<float>& b) {
    EXPECT_EQ(a.size(), b.size());
    double d = 0, n = 0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
      d += (a[i] - b[i]) * static_cast<double>(a[i] - b[i]);
      n += b[i] * static_cast<double>(b[i]);
    }
    return std::sqrt(d / n);
  };
  const std::vector<float> converged = fine_amplitudes(16, 1.0);
  const double relaxed = distance(fine_amplitudes(3, ResidualTransformOptions{}.fine_relaxation), converged),
               four = distance(fine_amplitudes(4, 1.0), converged),
               near_two = distance(fine_amplitudes(16, 1.9), converged);
  SCOPED_TRACE("from 16 passes: 3 relaxed " + std::to_string(relaxed) + ", 4 plain " + std::to_string(four) +
               ", 16 at 1.9 " + std::to_string(near_two));
  EXPECT_EQ(ResidualTransformOptions{}.fine_sweeps, 3);
  EXPECT_LT(relaxed, four);
  EXPECT_LT(near_two, 0.5 * relaxed);
}

TEST(ResidualTransform, Avx2PassesGiveTheSameBitsAsThe128BitOnes) {
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "this CPU has no AVX2: only the 128-bit passes run here";
  sphere::EquirectImage frame = SkyMap(1024, 512);
  AddDisc(&frame, {0.3, 0.8, -0.5}, 0.02, 20000.f);
  ResidualTransformOptions options;
  options.stop_threshold = 0;
  ResidualTransform transform(options);
  const SgLighting wide = transform.Run(frame);
  EXPECT_TRUE(UseAvx2Passes(false));
  const SgLighting narrow = transform.Run(frame);
  EXPECT_FALSE(UseAvx2Passes(true));
  ASSERT_EQ(wide.levels.size(), 5u);
  ASSERT_EQ(narrow.levels.size(), wide.levels.size());
  for (std::size_t l = 0; l < wide.levels.size(); ++l) {
    ASSERT_EQ(narrow.levels[l].indices, wide.levels[l].indices);
    for (std::size_t i = 0; i < wide.levels[l].amplitudes.size(); ++i)
      ASSERT_EQ(narrow.levels[l].amplitudes[i], wide.levels[l].amplitudes[i]) << "level " << l << " srbf " << i;
  }
}

TEST(ResidualTransform, TakingTheInputAsTheFinestGridChangesNothing) {
  // A 512-wide frame is level 4's grid: the rvalue overload takes its storage instead of copying.
  sphere::EquirectImage frame = SkyMap(512, 256);
  AddDisc(&frame, {-0.2, 0.4, 0.9}, 0.03, 5000.f);
  ResidualTransformOptions options;
  options.stop_threshold = 0;
  ResidualTransform transform(options);
  const SgLighting copied = transform.Run(frame);
  sphere::EquirectImage moved_frame = frame;
  const SgLighting moved = transform.Run(std::move(moved_frame));
  ASSERT_EQ(copied.levels.size(), 5u);
  ASSERT_EQ(moved.levels.size(), copied.levels.size());
  EXPECT_EQ(moved.constant, copied.constant);
  for (std::size_t l = 0; l < copied.levels.size(); ++l) {
    ASSERT_EQ(moved.levels[l].indices, copied.levels[l].indices);
    for (std::size_t i = 0; i < copied.levels[l].amplitudes.size(); ++i)
      ASSERT_EQ(moved.levels[l].amplitudes[i], copied.levels[l].amplitudes[i]) << "level " << l << " srbf " << i;
  }
}

TEST(ResidualTransform, PartitionProjectionConservesEnergyAtEveryLevel) {
  auto frame = SkyMap(128, 64);
  AddDisc(&frame, {-0.5, 0.5, 0.2}, 0.05, 500.f);
  for (int levels = 1; levels <= 4; ++levels) {
    ResidualTransformOptions o;
    o.levels = levels;
    o.stop_threshold = 0;
    o.keep_threshold = 0;
    ResidualTransform t(o);
    const SgLighting m = t.Run(frame);
    double model_energy = 4 * kPi * m.constant.x, frame_energy = 0;
    for (const auto& g : m.ToSgs())
      if (g.lambda > 0) model_energy += g.amplitude.x * Integral(Sg{g.axis, g.lambda, 1});
    for (int row = 0; row < 64; ++row)
      for (int col = 0; col < 128; ++col)
        frame_energy += frame.at(col, row)[0] * sphere::EquirectPixelSolidAngle(row, 128, 64);
    // The Gaussians' tails beyond the 1e-3 cut-off and the grid's quadrature leave a few 0.1 %.
    EXPECT_NEAR(model_energy / frame_energy, 1.0, 0.01) << levels;
  }
}

TEST(ResidualTransform, BrightSpotsAtTheSeamAndThePolesLandWhereTheyAre) {
  for (const glm::dvec3 spot : {glm::dvec3(-1, 0.05, 0.0), glm::dvec3(0, 1, 0), glm::dvec3(0, -1, 0)}) {
    auto frame = SkyMap(256, 128);
    AddDisc(&frame, spot, 0.08, 30.f);
    ResidualTransformOptions o;
    o.stop_threshold = 0;
    ResidualTransform t(o);
    const SgLighting m = t.Run(frame);
    // The brightest direction of the model, searched on level-4 centres.
    double best = -1;
    glm::dvec3 best_dir(0);
    for (const auto& d : sphere::Healpix(4).centres()) {
      const glm::vec3 v = m.Evaluate(d);
      if (v.x > best) {
        best = v.x;
        best_dir = d;
      }
    }
    EXPECT_LT(AngleDeg(best_dir, glm::normalize(spot)), 3.0) << spot.x << "," << spot.y;
    EXPECT_GT(best, 15.0);
    for (float v : m.Reconstruct(64, 32).rgb) EXPECT_TRUE(std::isfinite(v));
  }
}

TEST(ResidualTransform, NanInfAndNegativePixelsNeverReachTheModel) {
  auto frame = SkyMap(128, 64);
  frame.at(3, 3)[0] = std::nanf("");
  frame.at(100, 40)[1] = INFINITY;
  frame.at(50, 20)[2] = -3894.f;
  ResidualTransform t;
  const SgLighting m = t.Run(frame);
  for (const auto& g : m.ToSgs()) {
    EXPECT_TRUE(std::isfinite(g.amplitude.x) && std::isfinite(g.amplitude.y) && std::isfinite(g.amplitude.z));
  }
  for (float v : m.Reconstruct(64, 32).rgb) EXPECT_TRUE(std::isfinite(v));
}

// The scan for bad values works on 16 values at a time and then the rest: one bad value in any
// lane, or among the last values of a frame whose size is no multiple of 16, is still found
// and treated as 0 (the model equals that of the frame with a 0 there).
// Each bad value at each index gives the same model as a 0 there, to the bit.
void ExpectBadValuesTreatedAsZero(const ResidualTransformOptions& options, const sphere::EquirectImage& clean,
                                  std::initializer_list<std::size_t> indices, std::initializer_list<float> bads) {
  ResidualTransform t(options);
  for (const std::size_t index : indices)
    for (const float bad : bads) {
      auto dirty = clean;
      dirty.rgb[index] = bad;
      auto zeroed = clean;
      zeroed.rgb[index] = 0.f;
      const auto a = t.Run(dirty).ToSgs(), b = t.Run(zeroed).ToSgs();
      ASSERT_EQ(a.size(), b.size()) << index << " " << bad;
      for (std::size_t k = 0; k < a.size(); ++k)
        ASSERT_EQ(a[k].amplitude, b[k].amplitude) << index << " " << bad << " sg " << k;
    }
}

TEST(ResidualTransform, OneBadValueAnywhereIsTreatedAsZero) {
  const auto clean = SkyMap(130, 65);  // 3·130·65 = 25350 values: 6 past the last full 16
  const std::size_t n = clean.rgb.size();
  ResidualTransformOptions options;
  options.levels = 2;
  ExpectBadValuesTreatedAsZero(options, clean, {0, 7, 16 * 800 + 13, n - 6, n - 1},
                               {std::nanf(""), INFINITY, -INFINITY, -1e6f});
}

// A frame that is a whole multiple of the finest grid is box-averaged in row bands on the pool,
// its rows checked for bad values as they are read: one in the first or last row of a band, or
// the frame's very last value, is still found and treated as 0.
TEST(ResidualTransform, OneBadValueIsFoundWhileTheFrameIsBoxAveraged) {
  const auto clean = SkyMap(512, 256);  // 2 levels: a 64-wide finest grid, 8x8 boxes
  const std::size_t n = clean.rgb.size(), row = 3 * 512;
  ResidualTransformOptions options;
  options.levels = 2;
  options.threads = 2;
  ExpectBadValuesTreatedAsZero(options, clean, {5, 64 * row - 1, 64 * row + 700, 200 * row + 9, n - 1},
                               {std::nanf(""), -INFINITY, -2.f});
}

TEST(ResidualTransform, TinyAndNonEquirectInputsAreClearErrors) {
  ResidualTransform t;
  EXPECT_THROW(t.Run(sphere::EquirectImage(1, 1, 1.f)), Error);
  EXPECT_THROW(t.Run(sphere::EquirectImage(100, 100, 1.f)), Error);
  ResidualTransformOptions bad;
  bad.levels = 9;
  EXPECT_THROW(ResidualTransform{bad}, Error);
}

TEST(ResidualTransform, OverlapListsCoverEveryPixelAndEverySrbf) {
  ThreadPool pool(1);
  const LevelTables t = BuildLevelTables(2, 128, 64, 1e-3, &pool);
  EXPECT_EQ(t.srbf_begin.size(), 192u + 1);
  for (std::size_t c = 0; c < 192; ++c) EXPECT_GT(t.srbf_begin[c + 1], t.srbf_begin[c]);
  for (std::size_t p = 0; p + 1 < t.pixel_begin.size(); ++p) EXPECT_GT(t.pixel_begin[p + 1], t.pixel_begin[p]);
  // Each pixel's partition weights over its SRBFs sum to its solid angle.
  std::vector<double> share(128 * 64, 0);
  for (std::size_t e = 0; e < t.srbf_pixel.size(); ++e)
    share[static_cast<std::size_t>(t.srbf_pixel[e])] += t.srbf_partition_weight[e];
  for (int row = 0; row < 64; ++row)
    EXPECT_NEAR(share[static_cast<std::size_t>(row) * 128], sphere::EquirectPixelSolidAngle(row, 128, 64), 1e-9);
}

// The refitting sweeps run on the amplitudes (P(r − R(μ)) = P(r) − Mμ), so M must be the
// projection of the reconstruction: here each written out from the overlap lists for a random μ
// (R through the by-pixel lists, P through the by-SRBF ones with each normalization's weights), on
// a broad level and on level 4's own grid.
TEST(ResidualTransform, GramIsTheProjectionOfTheReconstruction) {
  ThreadPool pool(2);
  for (const auto& [level, width, cutoff] : {std::tuple{2, 128, 1e-5}, std::tuple{4, 512, 1e-3}}) {
    const int height = width / 2;
    const LevelTables t = BuildLevelTables(level, width, height, cutoff, &pool);
    const std::size_t n = t.inv_weight_sum.size();
    std::vector<glm::vec3> mu(n);
    unsigned state = 12345;
    const auto uniform = [&] {
      state = state * 1664525u + 1013904223u;
      return static_cast<float>(state >> 8) / 16777216.f - 0.3f;  // [-0.3, 0.7): both signs
    };
    for (glm::vec3& m : mu) m = {uniform(), uniform(), uniform()};
    // R(μ) per pixel.
    std::vector<glm::dvec3> image(static_cast<std::size_t>(width) * height, glm::dvec3(0));
    for (std::size_t p = 0; p < image.size(); ++p)
      for (int k = t.pixel_begin[p]; k < t.pixel_begin[p + 1]; ++k)
        image[p] += static_cast<double>(t.pixel_g[static_cast<std::size_t>(k)]) *
                    glm::dvec3(mu[static_cast<std::size_t>(t.pixel_srbf[static_cast<std::size_t>(k)])]);
    for (const Normalization normalization :
         {Normalization::kPartition, Normalization::kLocalSum, Normalization::kNone}) {
      const LevelGram gram = BuildLevelGram(t, normalization, &pool);
      const std::vector<float>& weights =
          normalization == Normalization::kPartition ? t.srbf_partition_weight : t.srbf_weight;
      std::vector<glm::vec3> minus_m_mu;
      gram.Residual(std::vector<glm::vec3>(n, glm::vec3(0)), mu, &minus_m_mu, &pool);
      double largest = 0, worst = 0;
      for (std::size_t c = 0; c < n; ++c) {
        glm::dvec3 projected(0);
        for (int e = t.srbf_begin[c]; e < t.srbf_begin[c + 1]; ++e)
          projected += static_cast<double>(weights[static_cast<std::size_t>(e)]) *
                       image[static_cast<std::size_t>(t.srbf_pixel[static_cast<std::size_t>(e)])];
        projected *= t.inv_weight_sum[c];
        if (normalization == Normalization::kLocalSum) projected /= t.local_sum[c];
        for (int ch = 0; ch < 3; ++ch) {
          largest = std::max(largest, std::abs(projected[ch]));
          worst = std::max(worst, std::abs(projected[ch] + minus_m_mu[c][ch]));
        }
      }
      SCOPED_TRACE("level " + std::to_string(level) + ", normalization " +
                   std::to_string(static_cast<int>(normalization)));
      EXPECT_GT(largest, 0.1);
      EXPECT_LT(worst, 1e-5 * largest);  // float storage of M and of the result
      // Each row holds the SRBFs whose caps meet: itself among them, and far fewer than all.
      for (std::size_t c = 0; c < n; ++c) {
        const auto first = gram.column.begin() + gram.row_begin[c], last = gram.column.begin() + gram.row_begin[c + 1];
        ASSERT_TRUE(std::binary_search(first, last, static_cast<int>(c))) << c;
      }
      if (level == 4) {
        EXPECT_LT(gram.column.size(), 64 * n);
      }
    }
  }
}

}  // namespace
}  // namespace odvr::lighting
