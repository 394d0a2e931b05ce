#pragma once
// Overlap bins (seed §4.4.2, Table 4.2; DESIGN.md §4): for a BRDF lobe of a given sharpness and
// direction, the lighting SRBFs that matter to it, precomputed once so the renderer iterates only
// over those and never over all 4092 SGs per pixel.
//
// Two rules decide what matters, both read off the closed-form SG integrals:
// - Depth. A lobe of sharpness λ_b blurs a level-s Gaussian (λ_s) to λ_b/(λ_s + λ_b) of its
//   peak, so a level whose detail keeps less than `min_retention` of itself after that blur adds
//   nothing the image can show: max level = the deepest s with λ_b/(λ_s + λ_b) ≥ min_retention.
//   The default 1/13 reproduces the seed's column "max Level" except at λ_b = 2, where it keeps
//   one level more (the seed's own rule is not stated).
// - Overlap. SRBF c overlaps the lobe at direction d when ∫G_c G_b ≥ `cutoff` × its value with
//   the axes aligned; a bin stands for every direction within its cell, so the angle used is the
//   true one less the cell's radius (conservative, as in the seed).
//
// Bins: per bin level a lobe sharpness λ_b (the seed's 2, 4, 16, 32, 128, 256, 512, plus 0.5 for
// lobes broader than any) and a θ×φ grid of (n+1)×2n directions whose spacing is half the
// lobe's half-value angle (n ≥ 4; the seed's (n+1)×(2n+1) repeats the seam column). A query
// takes the bin level with the largest λ_b not above the lobe's and the nearest grid direction.
// A bin level serves lobes from its λ_b up to the next level's, so its lists use the broadest
// (λ_b: a sharper lobe overlaps fewer SRBFs) and go as deep as the sharpest needs: a superset.
//
// SRBFs are named by a global index over the levels: g = 4(4^s − 1) + i for nested index i at
// level s (level 0: 0..11, level 1: 12..59, ...), independent of which SRBFs a frame kept.
#include <glm/vec3.hpp>
#include <memory>
#include <span>
#include <vector>

namespace odvr::lighting {

struct OverlapBinOptions {
  int lighting_levels = 5;          // HEALPix levels 0..lighting_levels−1
  double min_retention = 1.0 / 13;  // depth rule
  double cutoff = 1e-3;             // overlap rule, relative to the aligned product integral
  std::vector<double> bin_lambdas = {0.5, 2, 4, 16, 32, 128, 256, 512};
  void Check() const;  // throws odvr::Error
  bool operator==(const OverlapBinOptions&) const = default;
};

inline int GlobalSrbfIndex(int level, int index) { return 4 * ((1 << (2 * level)) - 1) + index; }
inline int SrbfLevelOf(int global) {
  int s = 0;
  while (GlobalSrbfIndex(s + 1, 0) <= global) ++s;
  return s;
}

struct OverlapBinLevel {
  double lambda = 0;       // the lobe sharpness this level stands for
  int n = 0;               // θ steps (n+1 nodes, pole to pole); φ has 2n nodes
  int max_level = 0;       // deepest lighting level in the lists (what the sharpest lobe served needs)
  std::vector<int> begin;  // per bin, into `srbfs`; size bins()+1
  std::vector<int> srbfs;  // global SRBF indices, sorted
  int bins() const { return (n + 1) * 2 * n; }
  double mean_list_length() const;
  std::size_t bytes() const;
};

class OverlapBins {
 public:
  explicit OverlapBins(OverlapBinOptions options = {});
  // The bins for `options`, built once per process and shared (the last few option sets are
  // kept): they depend on nothing else, and building them (about half a second) each time a
  // test, a bench row or the player makes a renderer would dominate small renders.
  static std::shared_ptr<const OverlapBins> Shared(const OverlapBinOptions& options);

  // The SRBFs (global indices) that a lobe of sharpness `lambda` around unit `direction` needs.
  std::span<const int> Query(const glm::dvec3& direction, double lambda) const;
  // The deepest lighting level that lobe needs. A lobe that carries only `share` of a pixel's
  // shading (GGX's tail, material::Lobe::tail_share) shows a level's detail at `share` times what
  // it keeps of it, so the depth rule asks min_retention / share of it.
  int MaxLevel(double lambda, double share = 1) const;

  const std::vector<OverlapBinLevel>& levels() const { return levels_; }
  const OverlapBinOptions& options() const { return options_; }
  std::size_t bytes() const;
  double build_ms() const { return build_ms_; }

  // The deepest level the depth rule keeps for a lobe of sharpness `lambda`.
  static int DepthFor(double lambda, int lighting_levels, double min_retention);

 private:
  const OverlapBinLevel& LevelFor(double lambda) const;
  int BinOf(const OverlapBinLevel& level, const glm::dvec3& direction) const;

  OverlapBinOptions options_;
  std::vector<OverlapBinLevel> levels_;
  double build_ms_ = 0;
};

// Direction of bin node (t, p) of a grid with n θ steps: θ = π t / n from +Y, φ = π p / n.
glm::dvec3 OverlapBinDirection(int t, int p, int n);

}  // namespace odvr::lighting
