#include "engine/lighting/overlap_bins.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <random>

#include "core/error.h"
#include "engine/lighting/sg.h"
#include "engine/sphere/healpix.h"

namespace odvr::lighting {
namespace {

// Σ over SRBFs (all, or the listed ones) of ∫ G_c G_b: what a lobe gathers from a lighting model
// whose amplitudes are all 1 (the worst case for what a list leaves out: nothing cancels).
double Gathered(const glm::dvec3& d, double lambda, int max_level, std::span<const int> only) {
  const Sg lobe{d, lambda, 1};
  double sum = 0;
  auto add = [&](int g) {
    const int s = SrbfLevelOf(g);
    if (s > max_level) return;
    const auto& hp = sphere::Healpix(s);
    sum += IntegralOfProduct(lobe, Sg{hp.centre(g - GlobalSrbfIndex(s, 0)), hp.Lambda(), 1});
  };
  if (only.empty()) {
    for (int g = 0; g < GlobalSrbfIndex(max_level + 1, 0); ++g) add(g);
  } else {
    for (int g : only) add(g);
  }
  return sum;
}

const OverlapBins& Bins() {
  static const OverlapBins bins;
  return bins;
}

TEST(OverlapBins, GlobalIndicesNameEachLevelInTurn) {
  EXPECT_EQ(GlobalSrbfIndex(0, 0), 0);
  EXPECT_EQ(GlobalSrbfIndex(1, 0), 12);
  EXPECT_EQ(GlobalSrbfIndex(2, 0), 60);
  EXPECT_EQ(GlobalSrbfIndex(4, 3071), 4091);  // the seed's 4092 SGs through level 4
  EXPECT_EQ(SrbfLevelOf(11), 0);
  EXPECT_EQ(SrbfLevelOf(12), 1);
  EXPECT_EQ(SrbfLevelOf(4091), 4);
}

TEST(OverlapBins, DepthFollowsTheSeedsTable) {
  // Table 4.2's "max Level" (1-based there) for BRDF λ 4, 16, 32, 128: levels 1, 2, 3, 4 here.
  EXPECT_EQ(OverlapBins::DepthFor(4, 5, 1.0 / 13), 1);
  EXPECT_EQ(OverlapBins::DepthFor(16, 5, 1.0 / 13), 2);
  EXPECT_EQ(OverlapBins::DepthFor(32, 5, 1.0 / 13), 3);
  EXPECT_EQ(OverlapBins::DepthFor(128, 5, 1.0 / 13), 4);
  EXPECT_EQ(OverlapBins::DepthFor(1e4, 5, 1.0 / 13), 4);
  EXPECT_EQ(OverlapBins::DepthFor(1e4, 6, 1.0 / 13), 5);
  EXPECT_EQ(OverlapBins::DepthFor(0.1, 5, 1.0 / 13), 0);
  // λ = 2 keeps level 1 where the seed stops at level 0: 2 / (22.55 + 2) = 8.1 % > 1/13.
  EXPECT_EQ(OverlapBins::DepthFor(2, 5, 1.0 / 13), 1);
}

// A lobe carrying only `share` of a pixel's shading (GGX's tail, 45 %) shows a level's detail at
// share × what it keeps of it: GGX α = 0.0625's tail at normal incidence (λ ≈ 32) keeps 8.1 % of
// level 3 (λ 362), but that is 3.7 % of the pixel, below 1/13.
TEST(OverlapBins, ALobeWithAShareOfTheShadingNeedsFewerLevels) {
  EXPECT_EQ(Bins().MaxLevel(32), 3);
  EXPECT_EQ(Bins().MaxLevel(32, 1.0), 3);
  EXPECT_EQ(Bins().MaxLevel(32, 0.45), 2);
  EXPECT_EQ(Bins().MaxLevel(128, 0.45), 3);  // level 4: 0.45 × 128 / (1449 + 128) = 3.7 %
  EXPECT_EQ(Bins().MaxLevel(1e4, 0.45), 4);
  EXPECT_EQ(Bins().MaxLevel(1e4, 0.05), 0);  // min_retention / share > 1: no level but the first
  EXPECT_EQ(Bins().MaxLevel(1e4, 0.0), 0);
}

TEST(OverlapBins, ListsLoseAtMostAFewThousandthsOfWhatALobeGathers) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> log_lambda(std::log(0.3), std::log(1e4));
  double worst = 0;
  for (int i = 0; i < 300; ++i) {
    const glm::dvec3 d = glm::normalize(glm::dvec3(normal(rng), normal(rng), normal(rng)));
    const double lambda = std::exp(log_lambda(rng));
    const int depth = Bins().MaxLevel(lambda);
    const auto list = Bins().Query(d, lambda);
    ASSERT_FALSE(list.empty());
    const double full = Gathered(d, lambda, depth, {});
    const double listed = Gathered(d, lambda, depth, list);
    ASSERT_LE(listed, full * (1 + 1e-12));
    worst = std::max(worst, 1 - listed / full);
  }
  std::printf("worst share of a lobe's gathered light left out by its list: %.2e\n", worst);
  EXPECT_LT(worst, 5e-3);
}

TEST(OverlapBins, PolesAndTheSeamFindTheirNeighbours) {
  for (const glm::dvec3 d : {glm::dvec3(0, 1, 0), glm::dvec3(0, -1, 0), glm::dvec3(-1, 0, 1e-9),
                             glm::dvec3(-1, 0, -1e-9), glm::dvec3(1, 0, -1e-9)}) {
    const double lambda = 300;
    const double full = Gathered(d, lambda, Bins().MaxLevel(lambda), {});
    const double listed = Gathered(d, lambda, Bins().MaxLevel(lambda), Bins().Query(d, lambda));
    EXPECT_GT(listed / full, 0.995) << d.x << " " << d.y << " " << d.z;
  }
}

TEST(OverlapBins, SharpLobesNeedFewSrbfsAndReportBesideTheSeed) {
  // Table 4.2 of the seed: mean overlapping SRBFs per bin for BRDF λ 2 … 512.
  const double seed[] = {60.00, 252.00, 311.55, 607.82, 181.83, 108.668, 70.4046};
  std::printf("bin λ     bins  mean list  max level  seed mean\n");
  double previous = 1e9;
  for (std::size_t k = 0; k < Bins().levels().size(); ++k) {
    const auto& l = Bins().levels()[k];
    std::printf("%6.1f %8d %10.1f %10d %10s\n", l.lambda, l.bins(), l.mean_list_length(), l.max_level,
                k == 0 ? "-" : std::to_string(seed[k - 1]).c_str());
    if (l.lambda >= 128) {
      EXPECT_LT(l.mean_list_length(), previous);  // the sharper, the fewer
      previous = l.mean_list_length();
    }
  }
  // A mirror-like lobe touches a few dozen of the 4092 SGs, not all of them.
  EXPECT_LT(Bins().levels().back().mean_list_length(), 150);
  std::printf("overlap bins: %.1f MiB, built in %.0f ms\n", Bins().bytes() / 1048576.0, Bins().build_ms());
}

TEST(OverlapBins, SharedBinsAreBuiltOncePerOptionSet) {
  OverlapBinOptions three;
  three.lighting_levels = 3;
  OverlapBinOptions loose = three;
  loose.cutoff = 1e-2;
  const auto a = OverlapBins::Shared(three);
  EXPECT_EQ(OverlapBins::Shared(three), a);
  const auto b = OverlapBins::Shared(loose);
  EXPECT_NE(b, a);
  EXPECT_EQ(b->options().cutoff, 1e-2);
  // The shared bins answer as bins built on their own do.
  const OverlapBins own(three);
  ASSERT_EQ(a->levels().size(), own.levels().size());
  for (std::size_t l = 0; l < own.levels().size(); ++l) {
    EXPECT_EQ(a->levels()[l].begin, own.levels()[l].begin);
    EXPECT_EQ(a->levels()[l].srbfs, own.levels()[l].srbfs);
  }
  // More option sets than are kept: the oldest is built again when asked for.
  for (int k = 1; k <= 8; ++k) {
    OverlapBinOptions other = three;
    other.min_retention = 1.0 / (13 + k);
    OverlapBins::Shared(other);
  }
  const auto again = OverlapBins::Shared(three);
  EXPECT_NE(again, a);
  EXPECT_EQ(again->levels()[2].srbfs, own.levels()[2].srbfs);
}

TEST(OverlapBins, BadOptionsAreClearErrors) {
  OverlapBinOptions o;
  o.bin_lambdas = {4, 2};
  EXPECT_THROW(OverlapBins{o}, Error);
  o = {};
  o.lighting_levels = 9;
  EXPECT_THROW(OverlapBins{o}, Error);
}

}  // namespace
}  // namespace odvr::lighting
