#include "engine/lighting/residual_transform.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <type_traits>

#include "core/error.h"
#include "core/float4.h"
#include "core/timing.h"
#include "engine/image/image_io.h"
#include "engine/sphere/equirect.h"
#include "engine/sphere/healpix.h"
#include "engine/sphere/resample.h"

namespace odvr::lighting {
namespace {

using Clock = std::chrono::steady_clock;
// A NaN, Inf or negative value anywhere. Fixed-length lanes without an early exit, which GCC's
// -O2 vectorizes; std::any_of branched on every value of the frame. With the serial small passes
// below, the transform to 2 levels at 1024 wide went from 1.47 to 0.86 ms (`odvr bench light`,
// park and sunset; most of it was spent before the first level).
bool HasBadPixels(const float* v, std::size_t n) {
  constexpr int kLanes = 16;
  float lowest[kLanes] = {}, probe[kLanes] = {};
  std::size_t i = 0;
  for (; i + kLanes <= n; i += kLanes)
    for (int j = 0; j < kLanes; ++j) {
      lowest[j] = lowest[j] < v[i + j] ? lowest[j] : v[i + j];
      probe[j] += v[i + j] * 0.f;  // NaN for a NaN or an Inf, and it stays NaN
    }
  bool bad = false;
  for (; i < n; ++i) bad = bad || !(v[i] >= 0) || std::isinf(v[i]);
  for (int j = 0; j < kLanes; ++j) bad = bad || !(lowest[j] >= 0) || probe[j] != 0.f;
  return bad;
}

// The finest working grid as `factor`×`factor` box means of a clean input (DownsampleBox bit
// for bit), in row bands on the pool, each input row checked for bad pixels while it is in
// cache: at 2048 wide the frame is 25 MB, and the check and the box each read all of it on
// one thread. False when a pixel is bad (`out` is then not the grid).
bool DownsampleBoxIfClean(const sphere::EquirectImage& input, int factor, sphere::EquirectImage* out,
                          ThreadPool* pool) {
  out->Reshape(input.width / factor, input.height / factor);
  const std::vector<float>& weights = sphere::BoxRowWeights(input.height, factor);
  std::atomic<bool> bad{false};
  pool->ParallelFor(
      out->height,
      [&](long begin, long end) {
        std::vector<float> column(3 * static_cast<std::size_t>(input.width));
        bool band_bad = false;
        for (long row = begin; row < end; ++row) {
          std::fill(column.begin(), column.end(), 0.f);
          for (int dy = 0; dy < factor; ++dy) {
            const int source_row = static_cast<int>(row) * factor + dy;
            const float* in = input.at(0, source_row);
            band_bad = HasBadPixels(in, 3 * static_cast<std::size_t>(input.width)) || band_bad;
            sphere::AddBoxRow(in, input.width, weights[static_cast<std::size_t>(source_row)], column.data());
          }
          sphere::FoldBoxColumns(column.data(), input.width, factor, out->at(0, static_cast<int>(row)));
        }
        if (band_bad) bad = true;
      },
      8);
  return !bad;
}

// Below this many overlap entries a pass runs on the calling thread: the coarse levels' grids
// (64 wide) hold a few ten thousand entries, tens of microseconds of work, and waking the pool's
// threads for each of a level's passes is not free (see HasBadPixels for the figure).
constexpr long kSerialEntries = 1L << 16;

using simd::Load4;
using simd::Store4;
using simd::V4;
using I4 = int __attribute__((vector_size(16)));
// Lanes i0..i3 of the eight of (a, b): __builtin_shufflevector, which GCC (12 on) and clang share.
template <int i0, int i1, int i2, int i3>
V4 Shuffle(V4 a, V4 b) {
  return __builtin_shufflevector(a, b, i0, i1, i2, i3);
}
using D2 = double __attribute__((vector_size(16)));
D2 Low2(V4 v) { return __builtin_convertvector(__builtin_shufflevector(v, v, 0, 1), D2); }
D2 High2(V4 v) { return __builtin_convertvector(__builtin_shufflevector(v, v, 2, 3), D2); }

// Σ r G dA over SRBF c's runs (the weights `w`, G·dA or its partition share), per channel.
// Walks the runs (contiguous pixels and weights) four pixels at a time: the products G·dA·r in
// float, summed in double in four lanes per channel instead of one chain (the entry-by-entry
// walk was latency-bound on it), which moves μ by at most an ulp of float. `kWide` holds the
// twelve lanes in three 256-bit registers instead of six 128-bit ones: the same accumulators,
// added in the same order (the same bits), in half the adds, for the AVX2 instantiation below
// (the build targets plain x86-64).
using D4 = double __attribute__((vector_size(32)));
template <bool kWide>
[[gnu::always_inline]] inline glm::dvec3 WeightedSumOf(const LevelTables& t, const float* w, const float* r, long c) {
  // Lanes of the 12 floats of four RGB pixels: (r g)(b r)(g b)(r g)(b r)(g b).
  std::conditional_t<kWide, D4[3], D2[6]> lanes = {};
  double acc[3] = {0, 0, 0};
  for (int k = t.srbf_run_begin[static_cast<std::size_t>(c)]; k < t.srbf_run_begin[static_cast<std::size_t>(c) + 1];
       ++k) {
    const LevelTables::SrbfRun& run = t.srbf_runs[static_cast<std::size_t>(k)];
    const float* wr = w + run.entry;
    const float* p = r + 3 * static_cast<std::size_t>(run.pixel);
    int i = 0;
    for (; i + 4 <= run.length; i += 4) {
      const V4 w4 = Load4(wr + i);
      const V4 products[3] = {Load4(p + 3 * i) * __builtin_shufflevector(w4, w4, 0, 0, 0, 1),
                              Load4(p + 3 * i + 4) * __builtin_shufflevector(w4, w4, 1, 1, 2, 2),
                              Load4(p + 3 * i + 8) * __builtin_shufflevector(w4, w4, 2, 3, 3, 3)};
      for (int j = 0; j < 3; ++j) {
        if constexpr (kWide) {
          lanes[j] += __builtin_convertvector(products[j], D4);
        } else {
          lanes[2 * j] += Low2(products[j]);
          lanes[2 * j + 1] += High2(products[j]);
        }
      }
    }
    for (; i < run.length; ++i) {
      acc[0] += wr[i] * p[3 * i];
      acc[1] += wr[i] * p[3 * i + 1];
      acc[2] += wr[i] * p[3 * i + 2];
    }
  }
  // Lane l of the twelve: channel l % 3.
  const auto lane = [&](int l) { return kWide ? lanes[l / 4][l % 4] : lanes[l / 2][l % 2]; };
  acc[0] += (lane(0) + lane(3)) + (lane(6) + lane(9));
  acc[1] += (lane(1) + lane(4)) + (lane(7) + lane(10));
  acc[2] += (lane(2) + lane(5)) + (lane(8) + lane(11));
  return {acc[0], acc[1], acc[2]};
}

glm::dvec3 WeightedSum(const LevelTables& t, const float* w, const float* r, long c) {
  return WeightedSumOf<false>(t, w, r, c);
}
[[gnu::target("avx2")]] glm::dvec3 WeightedSumAvx2(const LevelTables& t, const float* w, const float* r, long c) {
  return WeightedSumOf<true>(t, w, r, c);
}

std::atomic<bool> use_avx2{__builtin_cpu_supports("avx2") != 0};

// μ_c = Σ r G dA / Σ G dA over R(c), optionally divided by S̄_c; one SRBF per index.
void Project(const LevelTables& t, const sphere::EquirectImage& residue, Normalization normalization,
             std::vector<glm::vec3>* mu, ThreadPool* pool) {
  const std::vector<float>& weights =
      normalization == Normalization::kPartition ? t.srbf_partition_weight : t.srbf_weight;
  const bool normalize = normalization == Normalization::kLocalSum;
  const int n = static_cast<int>(t.inv_weight_sum.size());
  mu->assign(static_cast<std::size_t>(n), glm::vec3(0));
  const float* r = residue.rgb.data();
  const bool avx2 = use_avx2;
  pool->ParallelFor(
      n,
      [&](long begin, long end) {
        for (long c = begin; c < end; ++c) {
          const glm::dvec3 sum = avx2 ? WeightedSumAvx2(t, weights.data(), r, c) : WeightedSum(t, weights.data(), r, c);
          double scale = t.inv_weight_sum[static_cast<std::size_t>(c)];
          if (normalize) scale /= t.local_sum[static_cast<std::size_t>(c)];
          (*mu)[static_cast<std::size_t>(c)] = glm::vec3(
              static_cast<float>(sum.x * scale), static_cast<float>(sum.y * scale), static_cast<float>(sum.z * scale));
        }
      },
      t.srbf_begin.back() < kSerialEntries ? n : 4);
}

// One row of Σ_c μ_c G_c into per-channel sums (`stride` floats apart, zeroed here): each of
// the row's runs adds μ_c·G four pixels at a time (the by-pixel walk gathered μ and chained
// every add on the last), SRBFs in the by-pixel lists' order, so every pixel's sum is the one
// that walk made (the padding adds +0). `kWide` takes two blocks at a time first, in 256-bit
// registers for the AVX2 instantiation: each pixel gets the same adds in the same order.
using V8 = float __attribute__((vector_size(32)));
template <bool kWide>
[[gnu::always_inline]] inline void RowSumsOf(const LevelTables& t, const std::vector<glm::vec3>& mu, long row,
                                             int stride, float* sums) {
  std::fill(sums, sums + 3 * static_cast<std::size_t>(stride), 0.f);
  for (int k = t.row_run_begin[static_cast<std::size_t>(row)]; k < t.row_run_begin[static_cast<std::size_t>(row) + 1];
       ++k) {
    const LevelTables::RowRun& run = t.row_runs[static_cast<std::size_t>(k)];
    const glm::vec3 m = mu[static_cast<std::size_t>(run.srbf)];
    const float* g = t.row_g.data() + run.entry;
    float* channel[3] = {sums + 4 * run.block, sums + 4 * run.block + stride, sums + 4 * run.block + 2 * stride};
    const int n = 4 * run.blocks;
    int i = 0;
    if constexpr (kWide) {
      for (; i + 8 <= n; i += 8) {
        V8 g8;
        std::memcpy(&g8, g + i, sizeof g8);
        for (int ch = 0; ch < 3; ++ch) {
          V8 s8;
          std::memcpy(&s8, channel[ch] + i, sizeof s8);
          s8 += m[ch] * g8;
          std::memcpy(channel[ch] + i, &s8, sizeof s8);
        }
      }
    }
    for (; i < n; i += 4) {
      const V4 g4 = Load4(g + i);
      for (int ch = 0; ch < 3; ++ch) Store4(channel[ch] + i, Load4(channel[ch] + i) + m[ch] * g4);
    }
  }
}

void RowSums(const LevelTables& t, const std::vector<glm::vec3>& mu, long row, int stride, float* sums) {
  RowSumsOf<false>(t, mu, row, stride, sums);
}
[[gnu::target("avx2")]] void RowSumsAvx2(const LevelTables& t, const std::vector<glm::vec3>& mu, long row, int stride,
                                         float* sums) {
  RowSumsOf<true>(t, mu, row, stride, sums);
}

// out = base + sign · sums for one row of `width` RGB pixels, back to interleaved RGB four
// pixels (12 floats) at a time; `out` may be `base`.
void AddRowSums(const float* sums, int stride, int width, float sign, const float* b, float* o) {
  const float* sr = sums;
  const float* sg = sr + stride;
  const float* sb = sg + stride;
  const V4 s4 = {sign, sign, sign, sign};
  int col = 0;
  for (; col + 4 <= width; col += 4) {
    const V4 r = Load4(sr + col), g = Load4(sg + col), bl = Load4(sb + col);
    const V4 rg_lo = Shuffle<0, 4, 1, 5>(r, g);                               // r0 g0 r1 g1
    const V4 rg_hi = Shuffle<2, 6, 3, 7>(r, g);                               // r2 g2 r3 g3
    const V4 a = Shuffle<0, 1, 4, 2>(rg_lo, bl);                              // r0 g0 b0 r1
    const V4 c = Shuffle<0, 5, 2, 3>(Shuffle<3, 0, 4, 5>(rg_lo, rg_hi), bl);  // g1 b1 r2 g2
    const V4 d = Shuffle<6, 2, 3, 7>(rg_hi, bl);                              // b2 r3 g3 b3
    const std::size_t i = 3 * static_cast<std::size_t>(col);
    Store4(o + i, Load4(b + i) + s4 * a);
    Store4(o + i + 4, Load4(b + i + 4) + s4 * c);
    Store4(o + i + 8, Load4(b + i + 8) + s4 * d);
  }
  for (; col < width; ++col) {
    const std::size_t i = 3 * static_cast<std::size_t>(col);
    o[i] = b[i] + sign * sr[col];
    o[i + 1] = b[i + 1] + sign * sg[col];
    o[i + 2] = b[i + 2] + sign * sb[col];
  }
}

// out(p) = base(p) + sign · Σ_c μ_c G_c(p) (sign −1 subtracts: the residue update; `out` may be
// `base`), row by row.
void Reconstruct(const LevelTables& t, const std::vector<glm::vec3>& mu, float sign, const sphere::EquirectImage& base,
                 sphere::EquirectImage* out, ThreadPool* pool) {
  const int width = t.width, stride = (width + 3) / 4 * 4;
  const bool avx2 = use_avx2;
  pool->ParallelFor(
      t.height,
      [&](long begin, long end) {
        std::vector<float> sums(3 * static_cast<std::size_t>(stride));
        for (long row = begin; row < end; ++row) {
          const std::size_t first = 3 * static_cast<std::size_t>(row) * width;
          (avx2 ? RowSumsAvx2 : RowSums)(t, mu, row, stride, sums.data());
          AddRowSums(sums.data(), stride, width, sign, base.rgb.data() + first, out->rgb.data() + first);
        }
      },
      t.srbf_begin.back() < kSerialEntries ? t.height : 4);
}

// residue = target − R_{<s}, R_{<s} = the constant plus every coarser level evaluated on this
// grid (`tables[l]`, `mu[l]`), made row by row in one pass: each row of R is the constant, then
// each level's row sums added in level order, as whole-grid passes per level add them, without
// writing R out and reading it back per level and again for the subtraction.
void ResidueOfCoarserLevels(const std::vector<const LevelTables*>& tables,
                            const std::vector<std::vector<glm::vec3>>& mu, glm::vec3 constant,
                            const sphere::EquirectImage& target, sphere::EquirectImage* residue, ThreadPool* pool) {
  const int width = target.width, stride = (width + 3) / 4 * 4;
  const bool avx2 = use_avx2;
  residue->Reshape(width, target.height);
  long entries = 0;
  for (const LevelTables* t : tables) entries += t->srbf_begin.back();
  pool->ParallelFor(
      target.height,
      [&](long begin, long end) {
        std::vector<float> sums(3 * static_cast<std::size_t>(stride)), recon(3 * static_cast<std::size_t>(width));
        for (long row = begin; row < end; ++row) {
          for (std::size_t i = 0; i < recon.size(); i += 3) {
            recon[i] = constant.x;
            recon[i + 1] = constant.y;
            recon[i + 2] = constant.z;
          }
          for (std::size_t l = 0; l < tables.size(); ++l) {
            (avx2 ? RowSumsAvx2 : RowSums)(*tables[l], mu[l], row, stride, sums.data());
            AddRowSums(sums.data(), stride, width, 1.0f, recon.data(), recon.data());
          }
          const std::size_t first = 3 * static_cast<std::size_t>(row) * width;
          const float* t = target.rgb.data() + first;
          float* r = residue->rgb.data() + first;
          for (std::size_t i = 0; i < recon.size(); ++i) r[i] = t[i] - recon[i];
        }
      },
      entries < kSerialEntries ? target.height : 4);
}

glm::dvec3 MeanOf(const sphere::EquirectImage& image) {
  glm::dvec3 sum(0);
  for (int row = 0; row < image.height; ++row) {
    const double da = sphere::EquirectPixelSolidAngle(row, image.width, image.height);
    for (int col = 0; col < image.width; ++col) {
      const float* p = image.at(col, row);
      sum += da * glm::dvec3(p[0], p[1], p[2]);
    }
  }
  return sum / (4 * kPi);
}

// out = a − b (`out` neither of them).
void Subtract(const sphere::EquirectImage& a, const sphere::EquirectImage& b, sphere::EquirectImage* out,
              ThreadPool* pool) {
  out->Reshape(a.width, a.height);
  const std::size_t row = 3 * static_cast<std::size_t>(a.width);
  pool->ParallelFor(
      a.height,
      [&](long begin, long end) {
        for (std::size_t i = static_cast<std::size_t>(begin) * row; i < static_cast<std::size_t>(end) * row; ++i)
          out->rgb[i] = a.rgb[i] - b.rgb[i];
      },
      16);
}

}  // namespace

void ResidualTransformOptions::Check() const {
  if (levels < 1 || levels > 6)
    throw Error("levels", "must be 1..6 (HEALPix levels 0..5), got " + std::to_string(levels));
  if (!(stop_threshold >= 0)) throw Error("threshold", "must be >= 0");
  if (!(keep_threshold >= 0)) throw Error("keep threshold", "must be >= 0");
  if (sweeps < 1 || sweeps > 16) throw Error("sweeps", "must be 1..16");
  if (fine_sweeps < 1 || fine_sweeps > 16) throw Error("fine sweeps", "must be 1..16");
  if (!(fine_relaxation > 0 && fine_relaxation < 2)) throw Error("fine relaxation", "must be in (0, 2)");
  if (base_width < 8 || base_width > 4096) throw Error("base width", "must be 8..4096");
  if (!(region_cutoff > 0 && region_cutoff < 0.5)) throw Error("region cutoff", "must be in (0, 0.5)");
  if (!(broad_region_cutoff > 0 && broad_region_cutoff < 0.5))
    throw Error("broad region cutoff", "must be in (0, 0.5)");
}

namespace {
constexpr int kBroadLevels = 3;  // levels 0–2: λ = 5.5, 22.6, 91.5 (level 3: 364.5)
}  // namespace

int SweepsOf(const ResidualTransformOptions& options, int level) {
  return level < kBroadLevels ? options.sweeps : options.fine_sweeps;
}

float RelaxationOf(const ResidualTransformOptions& options, int level) {
  return level < kBroadLevels ? 1.0f : static_cast<float>(options.fine_relaxation);
}

double RegionCutoffOf(const ResidualTransformOptions& options, int level) {
  return level < kBroadLevels ? options.broad_region_cutoff : options.region_cutoff;
}

std::size_t LevelTables::bytes() const {
  return sizeof(int) * (srbf_begin.size() + srbf_pixel.size() + pixel_begin.size() + pixel_srbf.size()) +
         sizeof(float) * (srbf_weight.size() + srbf_partition_weight.size() + inv_weight_sum.size() + local_sum.size() +
                          pixel_g.size() + pixel_solid_angle.size() + row_g.size()) +
         sizeof(int) * (srbf_run_begin.size() + row_run_begin.size()) + sizeof(SrbfRun) * srbf_runs.size() +
         sizeof(RowRun) * row_runs.size();
}

LevelTables BuildLevelTables(int level, int width, int height, double region_cutoff, ThreadPool* pool) {
  const auto& hp = sphere::Healpix(level);
  LevelTables t;
  t.level = level;
  t.width = width;
  t.height = height;
  t.lambda = hp.Lambda();
  t.pixel_solid_angle.resize(static_cast<std::size_t>(height));
  for (int row = 0; row < height; ++row)
    t.pixel_solid_angle[static_cast<std::size_t>(row)] =
        static_cast<float>(sphere::EquirectPixelSolidAngle(row, width, height));

  // Per SRBF, the pixels of its cap: rows within the cap's latitude range, and in each row the
  // columns within the cap's longitude half-width (all of them near a pole).
  const int n = hp.size();
  const double cos_max = 1.0 + std::log(region_cutoff) / t.lambda;
  std::vector<std::vector<std::pair<int, float>>> caps(static_cast<std::size_t>(n));
  pool->ParallelFor(
      n,
      [&](long begin, long end) {
        for (long c = begin; c < end; ++c) {
          const glm::dvec3 axis = hp.centre(static_cast<int>(c));
          const sphere::EquirectCap region(axis, cos_max, width, height);
          auto& cap = caps[static_cast<std::size_t>(c)];
          for (int row = region.first_row(); row <= region.last_row(); ++row) {
            const auto [start, count] = region.Columns(row);
            for (int k = 0; k < count; ++k) {
              const int col = ((start + k) % width + width) % width;
              const double g =
                  std::exp(t.lambda * (glm::dot(sphere::EquirectPixelDirection(col, row, width, height), axis) - 1.0));
              if (g >= region_cutoff) cap.emplace_back(row * width + col, static_cast<float>(g));
            }
          }
        }
      },
      1);

  // By-SRBF lists with G·dA weights.
  t.srbf_begin.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int c = 0; c < n; ++c)
    t.srbf_begin[static_cast<std::size_t>(c) + 1] =
        t.srbf_begin[static_cast<std::size_t>(c)] + static_cast<int>(caps[static_cast<std::size_t>(c)].size());
  const std::size_t entries = static_cast<std::size_t>(t.srbf_begin.back());
  t.srbf_pixel.resize(entries);
  t.srbf_weight.resize(entries);
  t.inv_weight_sum.assign(static_cast<std::size_t>(n), 0);
  std::vector<int> per_pixel(static_cast<std::size_t>(width) * height + 1, 0);
  for (int c = 0; c < n; ++c) {
    double sum = 0;
    std::size_t e = static_cast<std::size_t>(t.srbf_begin[static_cast<std::size_t>(c)]);
    for (const auto& [pixel, g] : caps[static_cast<std::size_t>(c)]) {
      const float w = g * t.pixel_solid_angle[static_cast<std::size_t>(pixel / width)];
      t.srbf_pixel[e] = pixel;
      t.srbf_weight[e] = w;
      sum += w;
      ++e;
      ++per_pixel[static_cast<std::size_t>(pixel) + 1];
    }
    // A cap with no pixel (a grid far too coarse for the level) contributes nothing.
    t.inv_weight_sum[static_cast<std::size_t>(c)] = sum > 0 ? static_cast<float>(1.0 / sum) : 0.f;
  }
  // Transpose into by-pixel lists.
  t.pixel_begin.assign(per_pixel.size(), 0);
  for (std::size_t p = 1; p < per_pixel.size(); ++p) t.pixel_begin[p] = t.pixel_begin[p - 1] + per_pixel[p];
  t.pixel_srbf.resize(entries);
  t.pixel_g.resize(entries);
  std::vector<int> fill(t.pixel_begin.begin(), t.pixel_begin.end() - 1);
  for (int c = 0; c < n; ++c)
    for (const auto& [pixel, g] : caps[static_cast<std::size_t>(c)]) {
      const int e = fill[static_cast<std::size_t>(pixel)]++;
      t.pixel_srbf[static_cast<std::size_t>(e)] = c;
      t.pixel_g[static_cast<std::size_t>(e)] = g;
    }
  // S(ω) = Σ_c G_c(ω) per pixel, then S̄_c, its G·dA-weighted mean over R(c).
  std::vector<float> sum_g(static_cast<std::size_t>(width) * height, 0);
  for (std::size_t p = 0; p < sum_g.size(); ++p)
    for (int e = t.pixel_begin[p]; e < t.pixel_begin[p + 1]; ++e) sum_g[p] += t.pixel_g[static_cast<std::size_t>(e)];
  t.srbf_partition_weight.resize(entries);
  for (std::size_t e = 0; e < entries; ++e) {
    const float sum = sum_g[static_cast<std::size_t>(t.srbf_pixel[e])];
    t.srbf_partition_weight[e] = sum > 0 ? t.srbf_weight[e] / sum : 0.f;
  }
  t.local_sum.assign(static_cast<std::size_t>(n), 1.f);
  for (int c = 0; c < n; ++c) {
    double num = 0, den = 0;
    for (int e = t.srbf_begin[static_cast<std::size_t>(c)]; e < t.srbf_begin[static_cast<std::size_t>(c) + 1]; ++e) {
      num += t.srbf_weight[static_cast<std::size_t>(e)] *
             sum_g[static_cast<std::size_t>(t.srbf_pixel[static_cast<std::size_t>(e)])];
      den += t.srbf_weight[static_cast<std::size_t>(e)];
    }
    if (den > 0) t.local_sum[static_cast<std::size_t>(c)] = static_cast<float>(num / den);
  }
  // Runs (see LevelTables): by SRBF, a new one wherever the next entry is not the next pixel;
  // by row, those cut at the rows' ends and bucketed per row, SRBFs ascending.
  t.srbf_run_begin.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int c = 0; c < n; ++c) {
    const std::size_t first_run = t.srbf_runs.size();
    t.srbf_run_begin[static_cast<std::size_t>(c)] = static_cast<int>(first_run);
    int e = t.srbf_begin[static_cast<std::size_t>(c)];
    for (const auto& [pixel, g] : caps[static_cast<std::size_t>(c)]) {
      if (t.srbf_runs.size() > first_run && t.srbf_runs.back().pixel + t.srbf_runs.back().length == pixel)
        ++t.srbf_runs.back().length;
      else
        t.srbf_runs.push_back({pixel, 1, e});
      ++e;
    }
  }
  t.srbf_run_begin.back() = static_cast<int>(t.srbf_runs.size());
  struct Piece {
    int row, srbf, col, length, entry;  // entry: by-SRBF entry of the first column
  };
  std::vector<Piece> pieces;
  std::vector<int> per_row(static_cast<std::size_t>(height) + 1, 0);
  for (int c = 0; c < n; ++c)
    for (int r = t.srbf_run_begin[static_cast<std::size_t>(c)]; r < t.srbf_run_begin[static_cast<std::size_t>(c) + 1];
         ++r) {
      const LevelTables::SrbfRun& run = t.srbf_runs[static_cast<std::size_t>(r)];
      for (int done = 0; done < run.length;) {
        const int pixel = run.pixel + done, row = pixel / width, col = pixel % width;
        const int length = std::min(run.length - done, width - col);
        pieces.push_back({row, c, col, length, run.entry + done});
        ++per_row[static_cast<std::size_t>(row) + 1];
        done += length;
      }
    }
  std::vector<float> srbf_g(entries);
  for (int c = 0; c < n; ++c) {
    std::size_t e = static_cast<std::size_t>(t.srbf_begin[static_cast<std::size_t>(c)]);
    for (const auto& cap : caps[static_cast<std::size_t>(c)]) srbf_g[e++] = cap.second;
  }
  t.row_run_begin.assign(per_row.size(), 0);
  for (std::size_t r = 1; r < per_row.size(); ++r) t.row_run_begin[r] = t.row_run_begin[r - 1] + per_row[r];
  std::vector<const Piece*> ordered(pieces.size());
  std::vector<int> row_fill(t.row_run_begin.begin(), t.row_run_begin.end() - 1);
  for (const Piece& piece : pieces)
    ordered[static_cast<std::size_t>(row_fill[static_cast<std::size_t>(piece.row)]++)] = &piece;
  t.row_runs.resize(pieces.size());
  for (std::size_t k = 0; k < ordered.size(); ++k) {
    const Piece& piece = *ordered[k];
    const int block = piece.col / 4, blocks = (piece.col + piece.length + 3) / 4 - block;
    const std::size_t entry = t.row_g.size();
    t.row_runs[k] = {piece.srbf, block, blocks, static_cast<int>(entry)};
    t.row_g.resize(entry + 4 * static_cast<std::size_t>(blocks), 0.f);
    std::copy_n(srbf_g.begin() + piece.entry, piece.length,
                t.row_g.begin() + static_cast<long>(entry) + piece.col - 4 * block);
  }
  return t;
}

LevelGram BuildLevelGram(const LevelTables& t, Normalization normalization, ThreadPool* pool) {
  const int n = static_cast<int>(t.inv_weight_sum.size());
  const std::vector<float>& weights =
      normalization == Normalization::kPartition ? t.srbf_partition_weight : t.srbf_weight;
  std::vector<std::vector<std::pair<int, float>>> rows(static_cast<std::size_t>(n));
  pool->ParallelFor(
      n,
      [&](long begin, long end) {
        // M_cc' = scale_c Σ_{ω ∈ R(c)} w_c(ω) G_c'(ω): through each pixel of c's cap, every SRBF
        // covering it, summed densely and read out in column order.
        std::vector<double> sum(static_cast<std::size_t>(n), 0.0);
        std::vector<char> touched(static_cast<std::size_t>(n), 0);
        std::vector<int> columns;
        for (long c = begin; c < end; ++c) {
          for (int e = t.srbf_begin[static_cast<std::size_t>(c)]; e < t.srbf_begin[static_cast<std::size_t>(c) + 1];
               ++e) {
            const double w = weights[static_cast<std::size_t>(e)];
            const std::size_t p = static_cast<std::size_t>(t.srbf_pixel[static_cast<std::size_t>(e)]);
            for (int k = t.pixel_begin[p]; k < t.pixel_begin[p + 1]; ++k) {
              const std::size_t other = static_cast<std::size_t>(t.pixel_srbf[static_cast<std::size_t>(k)]);
              sum[other] += w * t.pixel_g[static_cast<std::size_t>(k)];
              if (!touched[other]) {
                touched[other] = 1;
                columns.push_back(static_cast<int>(other));
              }
            }
          }
          double scale = t.inv_weight_sum[static_cast<std::size_t>(c)];
          if (normalization == Normalization::kLocalSum) scale /= t.local_sum[static_cast<std::size_t>(c)];
          std::sort(columns.begin(), columns.end());
          auto& row = rows[static_cast<std::size_t>(c)];
          for (const int other : columns) {
            row.emplace_back(other, static_cast<float>(scale * sum[static_cast<std::size_t>(other)]));
            sum[static_cast<std::size_t>(other)] = 0;
            touched[static_cast<std::size_t>(other)] = 0;
          }
          columns.clear();
        }
      },
      1);
  LevelGram m;
  m.row_begin.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int c = 0; c < n; ++c)
    m.row_begin[static_cast<std::size_t>(c) + 1] =
        m.row_begin[static_cast<std::size_t>(c)] + static_cast<int>(rows[static_cast<std::size_t>(c)].size());
  m.column.reserve(static_cast<std::size_t>(m.row_begin.back()));
  m.value.reserve(static_cast<std::size_t>(m.row_begin.back()));
  for (const auto& row : rows)
    for (const auto& [column, value] : row) {
      m.column.push_back(column);
      m.value.push_back(value);
    }
  return m;
}

void LevelGram::Residual(const std::vector<glm::vec3>& projected, const std::vector<glm::vec3>& mu,
                         std::vector<glm::vec3>* out, ThreadPool* pool) const {
  const long n = static_cast<long>(projected.size());
  out->resize(projected.size());
  const auto rows = [&](long begin, long end) {
    for (long c = begin; c < end; ++c) {
      glm::dvec3 sum(0.0);
      for (int k = row_begin[static_cast<std::size_t>(c)]; k < row_begin[static_cast<std::size_t>(c) + 1]; ++k)
        sum += static_cast<double>(value[static_cast<std::size_t>(k)]) *
               glm::dvec3(mu[static_cast<std::size_t>(column[static_cast<std::size_t>(k)])]);
      (*out)[static_cast<std::size_t>(c)] = glm::vec3(glm::dvec3(projected[static_cast<std::size_t>(c)]) - sum);
    }
  };
  // A level's rows hold a few dozen entries each: levels 0–3 (≤ 768 SRBFs) are quicker on the
  // calling thread than handed to the pool.
  if (pool && n > 1024)
    pool->ParallelFor(n, rows, 256);
  else
    rows(0, n);
}

std::size_t LevelGram::bytes() const {
  return sizeof(int) * (row_begin.size() + column.size()) + sizeof(float) * value.size();
}

namespace {

// Σ (|r|+|g|+|b|) dA and Σ (r²+g²+b²) dA in one read of the image, each row summed in eight
// double lanes per measure: one chain per row was latency-bound, and the transform takes both
// measures of two residues per level. The lanes change only the double summation order. `kWide`
// holds the lanes in 256-bit registers (the AVX2 instantiation): the same accumulators added in
// the same order, so the same bits; with four 128-bit lanes per measure these sums were 5 % of
// the 5-level transform's time at 2048 wide.
struct AbsAndSquareSums {
  double abs = 0, square = 0;
};

template <bool kWide>
[[gnu::always_inline]] inline AbsAndSquareSums RowAbsAndSquareSumsOf(const float* p, int n) {
  std::conditional_t<kWide, D4[2], D2[4]> abs_lanes = {}, square_lanes = {};
  constexpr int kMask = 0x7fffffff;
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    for (int half = 0; half < 2; ++half) {
      const V4 v = Load4(p + i + 4 * half);
      const V4 a = reinterpret_cast<V4>(reinterpret_cast<I4>(v) & I4{kMask, kMask, kMask, kMask});
      if constexpr (kWide) {
        const D4 ad = __builtin_convertvector(a, D4), vd = __builtin_convertvector(v, D4);
        abs_lanes[half] += ad;
        square_lanes[half] += vd * vd;
      } else {
        abs_lanes[2 * half] += Low2(a);
        abs_lanes[2 * half + 1] += High2(a);
        const D2 lo = Low2(v), hi = High2(v);
        square_lanes[2 * half] += lo * lo;
        square_lanes[2 * half + 1] += hi * hi;
      }
    }
  }
  // Lane l of the eight, in the order of the floats of each group of eight.
  const auto lane = [](const auto& lanes, int l) { return kWide ? lanes[l / 4][l % 4] : lanes[l / 2][l % 2]; };
  AbsAndSquareSums sums;
  for (int l = 0; l < 8; ++l) {
    sums.abs += lane(abs_lanes, l);
    sums.square += lane(square_lanes, l);
  }
  for (; i < n; ++i) {
    sums.abs += std::abs(p[i]);
    sums.square += static_cast<double>(p[i]) * p[i];
  }
  return sums;
}

AbsAndSquareSums RowAbsAndSquareSums(const float* p, int n) { return RowAbsAndSquareSumsOf<false>(p, n); }
[[gnu::target("avx2")]] AbsAndSquareSums RowAbsAndSquareSumsAvx2(const float* p, int n) {
  return RowAbsAndSquareSumsOf<true>(p, n);
}

// The rows on the pool when there is one (the rest of the transform's passes are, and a serial
// pass leaves the other core idle), added up in row order either way, so the same sums.
AbsAndSquareSums SphereAbsAndSquareSums(const sphere::EquirectImage& image, ThreadPool* pool = nullptr) {
  std::vector<AbsAndSquareSums> rows(static_cast<std::size_t>(image.height));
  const auto row_sums = use_avx2 ? RowAbsAndSquareSumsAvx2 : RowAbsAndSquareSums;
  const auto body = [&](long begin, long end) {
    for (long row = begin; row < end; ++row)
      rows[static_cast<std::size_t>(row)] = row_sums(image.at(0, static_cast<int>(row)), image.width * 3);
  };
  if (pool && image.pixel_count() * 3 >= static_cast<std::size_t>(kSerialEntries))
    pool->ParallelFor(image.height, body, 8);
  else
    body(0, image.height);
  AbsAndSquareSums total;
  for (int row = 0; row < image.height; ++row) {
    const double da = sphere::EquirectPixelSolidAngle(row, image.width, image.height);
    total.abs += rows[static_cast<std::size_t>(row)].abs * da;
    total.square += rows[static_cast<std::size_t>(row)].square * da;
  }
  return total;
}

double MeanAbsOf(const AbsAndSquareSums& s) { return s.abs / 3.0 / (4 * kPi); }
double RmsOf(const AbsAndSquareSums& s) { return std::sqrt(s.square / 3.0 / (4 * kPi)); }

}  // namespace

double RmsRadiance(const sphere::EquirectImage& image) { return RmsOf(SphereAbsAndSquareSums(image)); }

bool UseAvx2Passes(bool enable) { return use_avx2.exchange(enable && __builtin_cpu_supports("avx2")); }

double MeanAbsRadiance(const sphere::EquirectImage& image) { return MeanAbsOf(SphereAbsAndSquareSums(image)); }

ResidualTransform::ResidualTransform(ResidualTransformOptions options)
    : options_(options), pool_(std::make_unique<ThreadPool>(options.threads)) {
  options_.Check();
}

void CheckTransformInput(int width, int height) {
  if (width < 8 || height < 4)
    throw Error("lighting input", "is " + std::to_string(width) + "x" + std::to_string(height) +
                                      ": an equirect frame needs at least 8x4 pixels");
  const double aspect = static_cast<double>(width) / height;
  if (aspect < 1.9 || aspect > 2.1)
    throw Error("lighting input", "is " + std::to_string(width) + "x" + std::to_string(height) +
                                      ": an equirect frame is twice as wide as high");
}

std::pair<int, int> WorkingGrid(const ResidualTransformOptions& options, int level, int input_width, int input_height) {
  // At least 64 columns: level 0's lobes (λ = 5.5) span the sphere, and a 32-wide grid
  // integrates them 2.4 % off in energy; finer levels need two pixels per σ, which 32·2^s gives.
  const int w = std::min(input_width, std::max(std::min(64, input_width), options.base_width << level));
  const int h = std::max(1, static_cast<int>(std::lround(static_cast<double>(input_height) * w / input_width)));
  return {w, h};
}

void ResampleToGrid(const sphere::EquirectImage& input, sphere::EquirectImage* target, ThreadPool* pool) {
  const int box = input.width / target->width;
  if (box > 1 && input.width == box * target->width && input.height == box * target->height &&
      DownsampleBoxIfClean(input, box, target, pool))
    return;
  if (!HasBadPixels(input.rgb.data(), input.rgb.size())) {
    sphere::ResampleArea(input, target, pool);
    return;
  }
  sphere::EquirectImage clean = input;
  const auto [bad, negative] = image::SanitizePixels(&clean);
  spdlog::warn("lighting input: clamped {} NaN/Inf and {} negative pixels to 0", bad, negative);
  sphere::ResampleArea(clean, target, pool);
}

std::pair<int, int> ResidualTransform::GridOf(int level, int input_width, int input_height) const {
  return WorkingGrid(options_, level, input_width, input_height);
}

const LevelTables& ResidualTransform::Tables(int level, int width, int height) {
  std::lock_guard lock(mutex_);
  auto& slot = tables_[{level, width, height}];
  if (!slot) {
    const auto start = Clock::now();
    slot = std::make_unique<LevelTables>(
        BuildLevelTables(level, width, height, RegionCutoffOf(options_, level), pool_.get()));
    spdlog::debug("lighting: overlap lists of level {} on {}x{} built in {:.1f} ms ({:.1f} MiB)", level, width, height,
                  MsSince(start), slot->bytes() / 1048576.0);
  }
  return *slot;
}

const LevelGram& ResidualTransform::Gram(int level, int width, int height) {
  const LevelTables& t = Tables(level, width, height);
  std::lock_guard lock(mutex_);
  auto& slot = grams_[{level, width, height}];
  if (!slot) {
    const auto start = Clock::now();
    slot = std::make_unique<LevelGram>(BuildLevelGram(t, options_.normalization, pool_.get()));
    spdlog::debug("lighting: projection of level {}'s reconstruction on {}x{} built in {:.1f} ms ({:.2f} MiB)", level,
                  width, height, MsSince(start), slot->bytes() / 1048576.0);
  }
  return *slot;
}

void ResidualTransform::CorrectCoarserLevels(const sphere::EquirectImage& leftover, int input_width, int input_height,
                                             float keep, SgLighting* model) {
  // The two levels below the finest, finest first, on the grid of the upper one (see
  // coarse_correction): the first refits the residue, the second what the first left.
  const int finest = static_cast<int>(model->levels.size()) - 1;
  const int upper = finest - 1, lower = std::max(0, finest - 2);
  const auto [w, h] = GridOf(upper, input_width, input_height);
  std::lock_guard lock(correction_mutex_);
  // Kept across frames: a fresh image each frame costs its page faults and zeroing, which on
  // this machine took longer than the restriction itself.
  sphere::EquirectImage& residue = correction_residue_;
  residue.Reshape(w, h);
  sphere::ResampleArea(leftover, &residue, pool_.get());  // a copy when the grids agree
  std::vector<glm::vec3> delta;
  for (int l = upper; l >= lower; --l) {
    const LevelTables& t = Tables(l, w, h);
    Project(t, residue, options_.normalization, &delta, pool_.get());
    for (glm::vec3& d : delta) d *= kCoarseCorrectionStep;
    if (l > lower) Reconstruct(t, delta, -1.0f, residue, &residue, pool_.get());
    AddRefit(delta, keep, &model->levels[static_cast<std::size_t>(l)]);
  }
}

void AddRefit(const std::vector<glm::vec3>& delta, float keep, SgLevel* level) {
  std::vector<glm::vec3> mu = delta;
  for (std::size_t k = 0; k < level->indices.size(); ++k)
    mu[static_cast<std::size_t>(level->indices[k])] += level->amplitudes[k];
  level->indices.clear();
  level->amplitudes.clear();
  for (std::size_t c = 0; c < mu.size(); ++c) {
    const glm::vec3 m = mu[c];
    if (std::max({std::abs(m.x), std::abs(m.y), std::abs(m.z)}) < keep) continue;
    level->indices.push_back(static_cast<int>(c));
    level->amplitudes.push_back(m);
  }
}

SgLighting ResidualTransform::Run(const sphere::EquirectImage& input, TransformReport* report_out) {
  return Run(input, nullptr, report_out);
}

SgLighting ResidualTransform::Run(sphere::EquirectImage&& input, TransformReport* report_out) {
  return Run(input, &input, report_out);
}

// Working grids, finest first, each resampled from the next finer one (area-preserving).
void ResidualTransform::PrepareGrids(const sphere::EquirectImage& input, sphere::EquirectImage* owned) {
  Scratch& scratch = scratch_;
  const int levels = options_.levels;
  std::vector<sphere::EquirectImage>& grids = scratch.grids;
  grids.resize(static_cast<std::size_t>(levels));
  const int input_w = input.width, input_h = input.height;
  const auto [finest_w, finest_h] = GridOf(levels - 1, input_w, input_h);
  // The builder hands over the detector's grid, already the finest: taken, not copied (the
  // caller gets the previous frame's storage back, to fill next time).
  if (owned && input.width == finest_w && input.height == finest_h &&
      !HasBadPixels(input.rgb.data(), input.rgb.size())) {
    std::swap(grids.back(), *owned);
  } else {
    grids.back().Reshape(finest_w, finest_h);
    ResampleToGrid(input, &grids.back(), pool_.get());
  }
  for (int s = levels - 2; s >= 0; --s) {
    const auto [w, h] = GridOf(s, input_w, input_h);
    const sphere::EquirectImage& finer = grids[static_cast<std::size_t>(s) + 1];
    sphere::EquirectImage& grid = grids[static_cast<std::size_t>(s)];
    // Halving (the grids are 32·2^s wide) in row bands on the pool, DownsampleBox bit for bit.
    const int factor = finer.width / w;
    if (!(factor > 1 && finer.width == factor * w && finer.height == factor * h &&
          DownsampleBoxIfClean(finer, factor, &grid, pool_.get()))) {
      grid.Reshape(w, h);
      sphere::ResampleArea(finer, &grid, pool_.get());
    }
  }
}

// The level's amplitudes (eq. 4.17), refitted by the extra sweeps, then the keep rule; *kept
// counts the SRBFs left.
std::vector<glm::vec3> ResidualTransform::FitLevel(const LevelTables& t, const sphere::EquirectImage& residue, int s,
                                                   float keep, int* kept) {
  std::vector<glm::vec3> mu;
  Project(t, residue, options_.normalization, &mu, pool_.get());
  if (const int sweeps = SweepsOf(options_, s); sweeps > 1) {
    // Each refit is μ += ω P(r − R(μ)) = ω (P(r) − Mμ) (LevelGram): on the amplitudes, where
    // reconstructing and projecting the grid again took two thirds of level 4's time at 2048
    // wide (three sweeps), for the same μ but for float rounding.
    const LevelGram& gram = Gram(s, residue.width, residue.height);
    const std::vector<glm::vec3> projected = mu;
    std::vector<glm::vec3> delta;
    const float step = RelaxationOf(options_, s);
    for (int sweep = 1; sweep < sweeps; ++sweep) {
      gram.Residual(projected, mu, &delta, pool_.get());
      for (std::size_t c = 0; c < mu.size(); ++c) mu[c] += step * delta[c];
    }
  }
  // Model only what the frame needs: drop negligible SRBFs before the one reconstruction, so
  // what the level leaves keeps their share.
  for (glm::vec3& m : mu) {
    if (std::max({std::abs(m.x), std::abs(m.y), std::abs(m.z)}) < keep)
      m = glm::vec3(0);
    else
      ++*kept;
  }
  return mu;
}

namespace {

// A fitted level as the model keeps it: the SRBFs the keep rule left.
SgLevel KeptLevel(int s, double lambda, const std::vector<glm::vec3>& mu) {
  SgLevel level;
  level.level = s;
  level.lambda = lambda;
  for (std::size_t c = 0; c < mu.size(); ++c) {
    if (mu[c] == glm::vec3(0)) continue;
    level.indices.push_back(static_cast<int>(c));
    level.amplitudes.push_back(mu[c]);
  }
  return level;
}

}  // namespace

SgLighting ResidualTransform::Run(const sphere::EquirectImage& input, sphere::EquirectImage* owned,
                                  TransformReport* report_out) {
  const auto start = Clock::now();
  CheckTransformInput(input.width, input.height);
  TransformReport report;
  SgLighting model;
  // One run at a time: the images below are kept across frames (a fresh 512×256 image per pass
  // was zeroed on the calling thread while the pool waited), and the pool takes one caller anyway.
  std::lock_guard run_lock(run_mutex_);
  Scratch& scratch = scratch_;

  // `input` may be `*owned`, whose storage is swapped for a grid below: its size, kept here.
  const int levels = options_.levels;
  const int input_w = input.width, input_h = input.height;
  PrepareGrids(input, owned);
  std::vector<sphere::EquirectImage>& grids = scratch.grids;
  report.prepare_ms = MsSince(start);
  report.input_width = input_w;
  report.input_height = input_h;

  const sphere::EquirectImage& finest = grids.back();
  report.mean_radiance = MeanAbsOf(SphereAbsAndSquareSums(finest, pool_.get()));
  if (!(report.mean_radiance > 0)) {
    report.stop_reason = "the frame is black";
    report.total_ms = MsSince(start);
    if (report_out) *report_out = report;
    return model;
  }

  // The constant term: the solid-angle-weighted mean (an SG with λ = 0).
  if (options_.constant_term) model.constant = glm::vec3(MeanOf(finest));

  // R: reconstruction of everything fitted so far, on the current level's grid.
  const auto [w0, h0] = GridOf(0, input_w, input_h);
  sphere::EquirectImage& recon = scratch.recon;
  recon.Reshape(w0, h0);
  for (std::size_t i = 0; i < recon.rgb.size(); i += 3) {
    recon.rgb[i] = model.constant.x;
    recon.rgb[i + 1] = model.constant.y;
    recon.rgb[i + 2] = model.constant.z;
  }
  std::vector<glm::vec3> previous_mu;
  std::vector<std::vector<glm::vec3>> all_mu;
  int previous_level = -1;
  const float keep = static_cast<float>(options_.keep_threshold * report.mean_radiance);

  // The residue a kept level left, on its grid: the next level's residue when it works on the
  // same grid (levels 0 and 1 share a 64-wide one), which then need not be evaluated again.
  sphere::EquirectImage& carried = scratch.carried;
  // What every kept level left, for the coarse correction: the last kept level's residue, or
  // the residue entering a rejected level (on that finer grid).
  sphere::EquirectImage& leftover = scratch.leftover;
  bool has_carried = false, has_leftover = false;
  sphere::EquirectImage& residue = scratch.residue;
  sphere::EquirectImage& remaining = scratch.remaining;
  bool converged = false;
  for (int s = 0; s < levels; ++s) {
    const auto level_start = Clock::now();
    const auto [w, h] = GridOf(s, input_w, input_h);
    const bool same_grid =
        options_.exact_reconstruction && s > 0 && has_carried && carried.width == w && carried.height == h;
    if (s > 0 && !same_grid && !options_.exact_reconstruction) {
      // R_{<s} on this grid: the coarser reconstruction magnified plus the previous level
      // evaluated here (see exact_reconstruction).
      sphere::MagnifyLagrange(recon, w, h, &scratch.magnified, pool_.get());
      std::swap(recon, scratch.magnified);
      Reconstruct(Tables(previous_level, w, h), previous_mu, 1.0f, recon, &recon, pool_.get());
    }
    const sphere::EquirectImage& target = grids[static_cast<std::size_t>(s)];
    if (same_grid) {
      std::swap(residue, carried);
      has_carried = false;
    } else if (options_.exact_reconstruction && s > 0) {
      // R_{<s} on this grid: every coarser level evaluated here (their overlap lists on this
      // grid are built once, like the level's own).
      std::vector<const LevelTables*> coarser;
      for (std::size_t l = 0; l < all_mu.size(); ++l) coarser.push_back(&Tables(static_cast<int>(l), w, h));
      ResidueOfCoarserLevels(coarser, all_mu, model.constant, target, &residue, pool_.get());
    } else {
      Subtract(target, recon, &residue, pool_.get());
    }
    const AbsAndSquareSums sums_before = SphereAbsAndSquareSums(residue, pool_.get());
    const double before = MeanAbsOf(sums_before) / report.mean_radiance;
    const double rms_before = RmsOf(sums_before);
    if (before < options_.stop_threshold && s > 0) {
      report.stop_reason = "residue below threshold before level " + std::to_string(s);
      converged = true;
      break;
    }

    const LevelTables& t = Tables(s, w, h);
    int kept = 0;
    std::vector<glm::vec3> mu = FitLevel(t, residue, s, keep, &kept);
    remaining.Reshape(w, h);
    Reconstruct(t, mu, -1.0f, residue, &remaining, pool_.get());
    const AbsAndSquareSums sums_after = SphereAbsAndSquareSums(remaining, pool_.get());
    const double after = MeanAbsOf(sums_after) / report.mean_radiance;
    // The rejection rule looks at the RMS: the mean |residue| may rise when a sun's energy is
    // spread (it is the stop rule's measure, the seed's "average value of the residue").
    const double rms_after = RmsOf(sums_after);
    LevelReport lr;
    lr.level = s;
    lr.srbfs_total = t.level == s ? static_cast<int>(mu.size()) : 0;
    lr.srbfs_kept = kept;
    lr.lambda = t.lambda;
    lr.width = w;
    lr.height = h;
    lr.residue_before = before;
    if (!LevelReducesResidue(rms_before, rms_after, kept)) {
      // The level would not help: leave it out and stop, finer levels would only fit noise.
      lr.srbfs_kept = 0;
      lr.residue_after = before;
      lr.ms = MsSince(level_start);
      report.levels.push_back(lr);
      report.stop_reason = "level " + std::to_string(s) + " does not reduce the residue";
      std::swap(leftover, residue);
      has_leftover = true;
      break;
    }
    lr.residue_after = after;
    model.levels.push_back(KeptLevel(s, t.lambda, mu));
    if (options_.exact_reconstruction) all_mu.push_back(mu);
    previous_mu = std::move(mu);
    previous_level = s;
    std::swap(carried, remaining);
    has_carried = true;
    lr.ms = MsSince(level_start);
    report.levels.push_back(lr);
    if (after < options_.stop_threshold) {
      report.stop_reason = "residue below threshold after level " + std::to_string(s);
      break;
    }
  }
  if (report.stop_reason.empty()) report.stop_reason = "maximum level reached";
  if (CoarseCorrectionApplies(options_, static_cast<int>(model.levels.size()), converged)) {
    const auto correction_start = Clock::now();
    CorrectCoarserLevels(has_leftover ? leftover : carried, input_w, input_h, keep, &model);
    report.correction_ms = MsSince(correction_start);
  }

  report.total_ms = MsSince(start);
  if (report_out) *report_out = report;
  return model;
}

}  // namespace odvr::lighting
