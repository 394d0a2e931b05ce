#pragma once
// The multiscale residual transform (seed §4.4.1.2, eq. 4.17–4.18, Algorithms 1–3;
// DESIGN.md §4): an equirect frame becomes a constant plus SGs on the HEALPix levels, coarse to
// fine, each level fitting what the coarser ones left.
//
// Per level s with lobe λ_s, on a working grid that resolves its lobes (32·2^s pixels wide, at least 64,
// capped at the input's width):
//   residue   r_s = I_s − R_{<s}            (I_s: the input area-resampled to the grid,
//                                            R_{<s}: the reconstruction of the coarser levels)
//   amplitude μ_c = Σ_{ω∈R(c)} r_s(ω) G_c(ω) dA(ω) / Σ_{ω∈R(c)} G_c(ω) dA(ω)      (eq. 4.17)
//   residue   r_{s+1} = r_s − Σ_c μ_c G_c                                          (eq. 4.18)
// R(c) is the cap where G_c > 1e-3 (1e-5 for the broad levels 0–2), and both sums run over precomputed overlap lists
// (per SRBF its pixels, per pixel its SRBFs), built once per grid, never all SRBFs for every pixel.
//
// The known trap: one level's Gaussians do not sum to one (0.6–1.3 with the seed's λ), so the
// plain weighted mean overshoots a bright region's energy and the finer levels then chase the
// overshoot (the diffuse error rises from level 3 to 4). Two fixes are options, measured by
// `odvr bench light`: dividing μ_c by the local sum of the level's Gaussians S̄_c (the
// G·dA-weighted mean over R(c) of S(ω) = Σ_c' G_c'(ω)), so a constant residue is reproduced; and
// extra sweeps that refit the remaining residue (μ += projection(r − L_s)/S̄), a Richardson
// iteration towards the level's least-squares fit.
//
// It models only what the frame needs: the constant term takes the mean first, SRBFs with a
// negligible |μ| are dropped, a level that does not reduce the mean absolute residue is
// rejected, and the transform stops once that residue falls below a fraction of the mean
// radiance.
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>

#include "core/parallel.h"
#include "engine/lighting/sg_lighting.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::lighting {

// The step of the coarse correction's refits (ResidualTransformOptions::coarse_correction).
inline constexpr float kCoarseCorrectionStep = 0.7f;

// kNone: eq. 4.17 as written. kLocalSum: μ_c / S̄_c. kPartition: each pixel's residue is shared
// among the SRBFs covering it in proportion to G_c(ω)/S(ω) (a partition of unity), so a level
// conserves the residue's energy exactly: Σ_c μ_c Σ_ω G_c dA = Σ_ω r dA.
enum class Normalization { kNone, kLocalSum, kPartition };

struct ResidualTransformOptions {
  int levels = 5;                // HEALPix levels 0..levels−1 (5: 4092 SGs, the seed's deepest)
  double stop_threshold = 0.01;  // stop when mean |residue| < this × mean radiance
  double keep_threshold = 1e-3;  // drop SRBFs whose max |μ| < this × mean radiance
  bool constant_term = true;
  Normalization normalization = Normalization::kPartition;
  int sweeps = 2;  // eq. 4.17 passes per level of λ < 300 (levels 0–2); 1 is the seed's single pass
  // Passes at the levels narrower than the glossy-200 lobe (λ ≥ 300: levels 3–5). Each pass refits
  // what the level left (a Richardson step towards the level's partition-weighted fit). Two leave
  // the glossy-200 error well above the least-squares optimum's on most maps; four bring it near;
  // three over-relaxed ones (below) do as well as four (`odvr bench light --fine-sweeps`).
  int fine_sweeps = 3;
  // The step of those refits at the fine levels: μ += ω · projection(r − L_s)/S̄. The
  // partition-weighted projection of a level's own reconstruction shrinks it, so the iteration
  // converges for ω well above 1 and over-relaxing moves faster towards the same fit. 1.7 with
  // three passes matches four plain passes for one pass less per fine level; two passes lose
  // accuracy on the sunny maps, and more than three buy little now that a sweep is a sparse product
  // (LevelGram), not a pass over the grid.
  double fine_relaxation = 1.7;
  // Working width of level s: base_width·2^s (at least 64, at most the input's). 32 puts level 4 (σ
  // = 1.5°) on a 512-wide grid, two pixels per σ: the narrowest schedule whose convolved errors
  // match the wider ones', for far less time.
  int base_width = 32;
  int threads = 0;  // CPU threads (0: all cores)
  double region_cutoff = 1e-3;
  // The cap of the broad levels (λ < 300: levels 0–2). A cap cut at 1e-3 leaves 0.1 % of each SG's
  // energy outside it, 20–100° from its centre for these lobes; the finer levels never see it
  // (their residue is computed from the same caps), yet the model, evaluated as whole SGs, holds
  // it. Cut at 1e-5 there, the glossy-20 errors of the maps that showed it fall to near the
  // optimum; the finer levels' caps lie within 11° of their centres, and a deeper cut there changes
  // nothing that matters.
  double broad_region_cutoff = 1e-5;
  // R_{<s} on level s's grid: every coarser level evaluated there (true), or the coarser grid's
  // reconstruction magnified plus level s−1 evaluated (false). Each level fits the magnification's
  // error of the coarser ones, which the model (evaluated exactly) does not contain: magnified
  // bilinearly, that bias held the diffuse and glossy-20 errors far above the least-squares
  // optimum. Through six samples per axis (sphere::MagnifyLagrange) the error of level s−2's
  // Gaussians, 4.3 coarse pixels per σ, falls to float's floor, and every error stays close to the
  // exact evaluation's for less time: evaluating the coarser levels on the finest grid is a large
  // share of level 4's work.
  bool exact_reconstruction = false;
  // After the last level, the two levels below it refit what every level left (a multigrid
  // V-cycle's restriction leg, finer first, each refitting what the other left): a level's fit
  // leaves a low-frequency error in its residue that the finer levels' narrow lobes do not take
  // back, so an added level can raise a glossy error while the least-squares optimum's falls; the
  // refit takes it to the optimum. The choices:
  //  - on the upper level's grid, the residue restricted by solid angle. Levels 0–1 refitting on
  //    their own 64-wide grid made errors worse: a coarse pixel's weight stands for a footprint over
  //    which both the residue (of either sign, as large as the radiance near a lamp) and the SRBF
  //    vary, an error far above the low-frequency part being sought; on a finer grid they help, for
  //    several times the time;
  //  - the refit steps at kCoarseCorrectionStep, not 1: full steps overshoot.
  // It costs a small fraction of a frame (levels 3 and 2 on level 3's grid), and runs from 5 levels
  // on (CoarseCorrectionApplies).
  bool coarse_correction = true;
  void Check() const;  // throws odvr::Error
};

struct LevelReport {
  int level = 0;
  int srbfs_total = 0;
  int srbfs_kept = 0;
  double lambda = 0;
  int width = 0, height = 0;  // working grid
  double ms = 0;
  double residue_before = 0;  // mean |residue| / mean radiance, entering the level
  double residue_after = 0;   // and leaving it
};

struct TransformReport {
  std::vector<LevelReport> levels;
  double mean_radiance = 0;
  int input_width = 0, input_height = 0;  // the image the transform was given
  double prepare_ms = 0;                  // resampling the input to the working grids
  double correction_ms = 0;               // the coarser levels' refit (coarse_correction)
  double total_ms = 0;
  std::string stop_reason;
  std::string device = "cpu";
  // GPU: the levels whose passes ran; those queued after the transform stopped are gated off
  // (ResidualTransformGpu). 0 on the CPU, which never starts a level after a stop.
  int gpu_levels_run = 0;
};

// One HEALPix level's overlap lists on one working grid (built once, reused every frame).
struct LevelTables {
  int level = 0, width = 0, height = 0;
  double lambda = 0;
  // By SRBF: pixels of R(c) with weights G·dA, and 1/Σ G·dA, and S̄_c.
  std::vector<int> srbf_begin, srbf_pixel;
  std::vector<float> srbf_weight, inv_weight_sum, local_sum;
  std::vector<float> srbf_partition_weight;  // G·dA / S(ω)
  // By pixel: the SRBFs whose cap covers it, with G.
  std::vector<int> pixel_begin, pixel_srbf;
  std::vector<float> pixel_g;
  std::vector<float> pixel_solid_angle;  // per row
  // The same lists as runs of consecutive pixels: a cap covers an interval of each row, so the
  // CPU's passes can read pixels and weights contiguously instead of gathering one entry at a
  // time, in the same order per SRBF and per pixel as the lists above (the same sums).
  // By SRBF: runs of pixel indices [pixel, pixel + length), weights at srbf entries
  // [entry, entry + length).
  struct SrbfRun {
    int pixel, length, entry;
  };
  std::vector<int> srbf_run_begin;
  std::vector<SrbfRun> srbf_runs;
  // By row: each row's runs [row_run_begin[row], row_run_begin[row + 1]), SRBFs ascending (the
  // by-pixel lists' order), each covering the four-column blocks [block, block + blocks) with
  // G at row_g[entry...], zero on the block's columns outside the cap: whole aligned blocks
  // let the adds run four pixels at a time without a store half-overlapping the next load.
  struct RowRun {
    int srbf, block, blocks, entry;
  };
  std::vector<int> row_run_begin;
  std::vector<RowRun> row_runs;
  std::vector<float> row_g;
  std::size_t bytes() const;
};

// A level's projection of its own reconstruction, M = P∘R on its working grid (P: eq. 4.17's
// weighted mean with the transform's normalization; R: Σ_c μ_c G_c): row c holds, for every SRBF
// c' whose cap meets c's, what P_c takes from G_c'. The refitting sweeps need
// P(r − R(μ)) = P(r) − Mμ, so with M they run on the level's amplitudes (a few dozen entries per
// SRBF) instead of reconstructing and projecting the whole grid once per sweep.
struct LevelGram {
  std::vector<int> row_begin, column;  // CSR: row c's entries [row_begin[c], row_begin[c + 1]), columns ascending
  std::vector<float> value;
  // out_c = projected_c − Σ_c' M_cc' μ_c' (sums in double).
  void Residual(const std::vector<glm::vec3>& projected, const std::vector<glm::vec3>& mu, std::vector<glm::vec3>* out,
                ThreadPool* pool) const;
  std::size_t bytes() const;
};

// M of `t` (its own grid) for `normalization`, from its by-SRBF and by-pixel lists.
LevelGram BuildLevelGram(const LevelTables& t, Normalization normalization, ThreadPool* pool);

class ResidualTransform {
 public:
  explicit ResidualTransform(ResidualTransformOptions options = {});

  // `input` is linear RGB; NaN/Inf/negative pixels are treated as 0 (and counted in the log).
  // Throws odvr::Error for an input too small for the transform (< 8×4) or not about 2:1.
  SgLighting Run(const sphere::EquirectImage& input, TransformReport* report = nullptr);
  // The same, free to take the input's storage as its finest working grid.
  SgLighting Run(sphere::EquirectImage&& input, TransformReport* report = nullptr);

  const ResidualTransformOptions& options() const { return options_; }
  // Working grid of level s for an input of the given size.
  std::pair<int, int> GridOf(int level, int input_width, int input_height) const;
  const LevelTables& Tables(int level, int width, int height);
  // Tables(level, width, height)'s LevelGram under the transform's normalization, built once.
  const LevelGram& Gram(int level, int width, int height);
  // The transform's threads, for the builder's other per-frame passes.
  ThreadPool* pool() { return pool_.get(); }

 private:
  SgLighting Run(const sphere::EquirectImage& input, sphere::EquirectImage* owned, TransformReport* report);
  // scratch_.grids for `input` (see Run), its storage taken from `owned` where it can be.
  void PrepareGrids(const sphere::EquirectImage& input, sphere::EquirectImage* owned);
  std::vector<glm::vec3> FitLevel(const LevelTables& t, const sphere::EquirectImage& residue, int s, float keep,
                                  int* kept);
  // coarse_correction: `leftover` is what every level left, on the grid of the finest level it was
  // computed for; the two levels below the finest kept one refit it.
  void CorrectCoarserLevels(const sphere::EquirectImage& leftover, int input_width, int input_height, float keep,
                            SgLighting* model);
  ResidualTransformOptions options_;
  std::unique_ptr<ThreadPool> pool_;
  std::mutex mutex_;
  std::map<std::tuple<int, int, int>, std::unique_ptr<LevelTables>> tables_;
  std::map<std::tuple<int, int, int>, std::unique_ptr<LevelGram>> grams_;
  std::mutex correction_mutex_;
  sphere::EquirectImage correction_residue_;
  // Run's images, kept across frames (see CorrectCoarserLevels).
  struct Scratch {
    std::vector<sphere::EquirectImage> grids;
    sphere::EquirectImage recon, magnified, residue, remaining, carried, leftover;
  };
  std::mutex run_mutex_;
  Scratch scratch_;
};

// The pieces of the transform's definition that the CPU and GPU paths share, so that their
// grids and decisions cannot drift apart.
// Throws odvr::Error for an input too small for the transform (< 8×4) or not about 2:1.
void CheckTransformInput(int width, int height);
// Working grid of level s: base_width·2^s wide (at least 64), capped at the input's width, the input's aspect.
std::pair<int, int> WorkingGrid(const ResidualTransformOptions& options, int level, int input_width, int input_height);

// `input` area-resampled to `target`'s size on `pool`, as the transform makes its finest grid:
// box means in row bands where the size divides evenly and no pixel is bad; otherwise NaN, Inf
// and negative values clamped to 0 first (with a warning), so that a bad pixel stays one pixel
// instead of a block of NaN or a mean of both signs.
void ResampleToGrid(const sphere::EquirectImage& input, sphere::EquirectImage* target, ThreadPool* pool);
// A level is kept only when it keeps an SRBF and lowers the residue's energy (RMS): eq. 4.17 is
// a local least-squares estimate, so a level that does not is fitting nothing the frame has.
inline bool LevelReducesResidue(double rms_before, double rms_after, int kept) {
  return rms_after < rms_before && kept > 0;
}

// Projection passes and cap cut-off of HEALPix level s (sweeps / fine_sweeps, region_cutoff /
// broad_region_cutoff): the levels of λ < 300 are 0–2.
int SweepsOf(const ResidualTransformOptions& options, int level);
// The step of the refitting passes of HEALPix level s (fine_relaxation at levels 3–5, else 1).
float RelaxationOf(const ResidualTransformOptions& options, int level);
double RegionCutoffOf(const ResidualTransformOptions& options, int level);

// Whether the coarse correction runs after `kept_levels` levels (0..kept_levels−1) were kept: not
// once the residue fell below the stop threshold (`converged`: nothing left to refit), and only
// when the finest kept level is one of the narrow ones (level 4 up, λ ≥ 1449). With 3 or 4 levels
// the refit levels work on a 64- or 128-wide grid, too coarse for the low-frequency error: there it
// moved the errors either way, as many maps worse as better.
inline bool CoarseCorrectionApplies(const ResidualTransformOptions& options, int kept_levels, bool converged) {
  return options.coarse_correction && !converged && kept_levels >= 5;
}

// The coarse correction's refit `delta` (one per SRBF of the level) added to a level's amplitudes,
// which then pass the keep rule again (|μ| below `keep` in every channel: dropped): an SRBF
// dropped before may now matter, and one kept may now be negligible.
void AddRefit(const std::vector<glm::vec3>& delta, float keep, SgLevel* level);

// The CPU passes run in 256-bit registers where the CPU has AVX2 (the build targets plain
// x86-64), else in 128-bit ones, with the same sums in the same order. false forces the 128-bit
// code, so that tests can hold the two to the same bits; returns whether AVX2 was in use.
bool UseAvx2Passes(bool enable);

// Builds the overlap lists of HEALPix `level` on a width×height grid.
LevelTables BuildLevelTables(int level, int width, int height, double region_cutoff, ThreadPool* pool);

// Solid-angle-weighted mean of (|r|+|g|+|b|)/3 over the sphere, and the RMS of the channels.
double MeanAbsRadiance(const sphere::EquirectImage& image);
double RmsRadiance(const sphere::EquirectImage& image);

}  // namespace odvr::lighting
