#include "engine/lighting/peak_detector.h"

#include <spdlog/spdlog.h>
#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <numeric>
#include <optional>

#include "core/error.h"
#include "core/float4.h"
#include "core/parallel.h"
#include "engine/image/image_io.h"
#include "engine/sphere/equirect.h"

namespace odvr::lighting {
namespace {

double Luminance(const float* p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }
double Luminance(const double* p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

// sphere::EquirectPixelDirection of pixel row·w + col by table: each row's latitude and each
// column's longitude cosine and sine, computed as it computes them (the same directions), kept
// per thread for the last frame size. The fit took two sincos per direction, four per pixel:
// bridge.exr's 15 257-pixel bright component, fitted and then rejected as too broad, made its
// peaks at 2048 wide take 4.3 ms, 3.4 with the table.
class PixelDirections {
 public:
  static const PixelDirections& Of(int w, int h) {
    thread_local PixelDirections table;
    if (table.w_ != w || table.h_ != h) table = PixelDirections(w, h);
    return table;
  }
  glm::dvec3 operator()(int p) const {
    const glm::dvec2 lat = rows_[static_cast<std::size_t>(p / w_)], lon = cols_[static_cast<std::size_t>(p % w_)];
    return {lat.x * lon.x, lat.y, -lat.x * lon.y};
  }

 private:
  PixelDirections() = default;
  PixelDirections(int w, int h) : w_(w), h_(h) {
    for (int row = 0; row < h; ++row) {
      const double lat = kPi / 2 - kPi * (row + 0.5) / h;
      rows_.emplace_back(std::cos(lat), std::sin(lat));
    }
    for (int col = 0; col < w; ++col) {
      const double lon = kPi * (1.0 - 2.0 * (col + 0.5) / w);
      cols_.emplace_back(std::cos(lon), std::sin(lon));
    }
  }
  int w_ = 0, h_ = 0;
  std::vector<glm::dvec2> rows_, cols_;
};

// Fits one SG to pixels (with their excess energies): axis, λ from the spread, μ from the energy.
RgbSg FitSg(const std::vector<int>& pixels, const std::vector<glm::dvec3>& excess, const sphere::EquirectImage& f,
            double pixel_angle) {
  const PixelDirections& direction = PixelDirections::Of(f.width, f.height);
  glm::dvec3 axis(0), energy(0);
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const int p = pixels[i];
    const glm::dvec3 d = direction(p);
    const double e = excess[i].x + excess[i].y + excess[i].z;
    axis += e * d;
    energy += excess[i];
  }
  RgbSg g;
  if (glm::length(axis) == 0) return g;
  g.axis = glm::normalize(axis);
  double spread = 0, total = 0;
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const int p = pixels[i];
    const glm::dvec3 d = direction(p);
    const double e = excess[i].x + excess[i].y + excess[i].z;
    spread += e * (1 - glm::dot(d, g.axis));
    total += e;
  }
  spread = total > 0 ? spread / total : 0;
  g.lambda = std::min(1e7, 1.0 / (spread + pixel_angle * pixel_angle / 12));
  const double integral = Integral(Sg{g.axis, g.lambda, 1});
  g.amplitude = glm::vec3(energy / integral);
  return g;
}

// What one pass over the frame learns: the solid-angle-weighted mean luminance, the largest
// value, whether any value is NaN, Inf or negative, and per block×block block its largest value.
// A pixel's luminance and its smallest channel never exceed its largest channel, so a block
// whose largest value is not over the threshold holds no bright pixel by either test.
struct FrameScan {
  double mean = 0, max_value = 0;
  bool dirty = false;
  int block = 0, blocks_wide = 0, blocks_high = 0;
  std::vector<float> block_max;
};

// Three four-float vectors: four RGB pixels.
using simd::Load4;
using simd::V4;

void Store12(float* out, V4 a, V4 b, V4 c) {
  simd::Store4(out, a);
  simd::Store4(out + 4, b);
  simd::Store4(out + 8, c);
}

void Load12(const float* in, V4* a, V4* b, V4* c) {
  *a = Load4(in);
  *b = Load4(in + 4);
  *c = Load4(in + 8);
}

// The pass every frame pays for, so it is written for the compiler to vectorize: the interleaved
// RGB floats are taken eight pixels (24 floats) at a time into per-lane sums, minima and maxima,
// with no luminance and no division per pixel. Per pixel in double it took 1.5 ms of a
// 1024×512 frame's 2 ms detection (perf, sky.exr enlarged as the bench does).
//
// With `coarse`, the same pass also sums each row into the frame box-averaged by `coarse_factor`
// while the row is in cache, with DownsampleBox's own halves, so the result is that function's
// bit for bit.
//
// With `source`, `frame` is written first, row by row, as `source` box-averaged by
// `source_factor` (DownsampleBox's result bit for bit), each row scanned while in cache.
// Three 4-wide vectors hold four RGB pixels: lane j (0..11) holds channel j % 3. GCC's
// vector extension keeps them in registers; plain arrays of 12 lanes, vectorized by -O2, went
// through the stack on every pixel.
constexpr int kLanes = 12;

// What the rows of one band add to the scan: their share of the mean and the lane-wise minima.
struct BandScan {
  double mean = 0;
  V4 lo0{}, lo1{}, lo2{};
};

// Rows [row0, row1) of the scan below: a whole number of candidate blocks and coarse cells, so
// bands write disjoint parts of s->block_max, the coarse grid and (from `source`) the frame.
// `coarse_weights`, `source_weights`: sphere::BoxRowWeights of the frame's and the source's rows.
BandScan ScanRows(const sphere::EquirectImage& frame, const std::vector<double>& da, int row0, int row1, FrameScan* s,
                  int coarse_factor, sphere::EquirectImage* coarse, const std::vector<float>& coarse_weights,
                  const sphere::EquirectImage* source, int source_factor, const std::vector<float>& source_weights) {
  const int w = frame.width, block = s->block;
  std::vector<float> column;
  if (coarse) column.assign(3 * static_cast<std::size_t>(w), 0.f);
  // Lane-wise minima and sums live across blocks and are reduced once per row (sums) or per
  // band (minima): a per-block reduction into scalars was a chain of dependent loads and stores
  // that took as long as the block's pixels (perf annotate, 1024 wide).
  BandScan band;
  V4 lo0{}, lo1{}, lo2{};
  std::vector<float> source_column;
  if (source) source_column.resize(3 * static_cast<std::size_t>(source->width));
  for (int row = row0; row < row1; ++row) {
    if (source) {
      std::fill(source_column.begin(), source_column.end(), 0.f);
      for (int dy = 0; dy < source_factor; ++dy)
        sphere::AddBoxRow(source->at(0, row * source_factor + dy), source->width,
                          source_weights[static_cast<std::size_t>(row * source_factor + dy)], source_column.data());
      // The frame is the caller's to fill: written here, read just below.
      sphere::FoldBoxColumns(source_column.data(), source->width, source_factor, const_cast<float*>(frame.at(0, row)));
    }
    // Sums in float across one row (a few hundred values per lane at most widths), then double.
    V4 sum0{}, sum1{}, sum2{}, more0{}, more1{}, more2{};
    float* block_max = &s->block_max[static_cast<std::size_t>(row / block) * static_cast<std::size_t>(s->blocks_wide)];
    const float* p = frame.at(0, row);
    for (int bx = 0; bx < s->blocks_wide; ++bx) {
      const int n = 3 * std::min(block, w - bx * block);
      V4 hi0{}, hi1{}, hi2{};
      const auto take = [&](V4 a, V4 b, V4 c, V4& s0, V4& s1, V4& s2) {
        s0 += a;
        s1 += b;
        s2 += c;
        lo0 = lo0 < a ? lo0 : a;
        lo1 = lo1 < b ? lo1 : b;
        lo2 = lo2 < c ? lo2 : c;
        hi0 = hi0 > a ? hi0 : a;
        hi1 = hi1 > b ? hi1 : b;
        hi2 = hi2 > c ? hi2 : c;
      };
      int i = 0;
      // Eight pixels a step, the second four into their own sums: an add waits on the previous
      // one, a min or max hardly at all.
      for (; i + 2 * kLanes <= n; i += 2 * kLanes) {
        take(Load4(p + i), Load4(p + i + 4), Load4(p + i + 8), sum0, sum1, sum2);
        take(Load4(p + i + 12), Load4(p + i + 16), Load4(p + i + 20), more0, more1, more2);
      }
      if (i < n) {  // the block's last pixels, when its width is no multiple of 8
        float sum[kLanes], lo[kLanes], hi[kLanes];
        Store12(sum, sum0, sum1, sum2);
        Store12(lo, lo0, lo1, lo2);
        Store12(hi, hi0, hi1, hi2);
        for (; i < n; i += 3)
          for (int j = 0; j < 3; ++j) {
            const float v = p[i + j];
            sum[j] += v;
            lo[j] = lo[j] < v ? lo[j] : v;
            hi[j] = hi[j] > v ? hi[j] : v;
          }
        Load12(sum, &sum0, &sum1, &sum2);
        Load12(lo, &lo0, &lo1, &lo2);
        Load12(hi, &hi0, &hi1, &hi2);
      }
      p += n;
      // The block's maximum: lane-wise first, then across the four lanes.
      V4 m4 = hi0 > hi1 ? hi0 : hi1;
      m4 = m4 > hi2 ? m4 : hi2;
      const float m01 = m4[0] > m4[1] ? m4[0] : m4[1], m23 = m4[2] > m4[3] ? m4[2] : m4[3];
      const float m = m01 > m23 ? m01 : m23;
      block_max[bx] = block_max[bx] > m ? block_max[bx] : m;
    }
    float sum[kLanes];
    Store12(sum, sum0 + more0, sum1 + more1, sum2 + more2);
    double channel_sum[3] = {0, 0, 0};
    for (int j = 0; j < kLanes; ++j) channel_sum[j % 3] += sum[j];
    band.mean += Luminance(channel_sum) * da[static_cast<std::size_t>(row)];
    if (coarse) {
      sphere::AddBoxRow(frame.at(0, row), w, coarse_weights[static_cast<std::size_t>(row)], column.data());
      if (row % coarse_factor == coarse_factor - 1) {
        sphere::FoldBoxColumns(column.data(), w, coarse_factor, coarse->at(0, row / coarse_factor));
        std::fill(column.begin(), column.end(), 0.f);
      }
    }
  }
  band.lo0 = lo0;
  band.lo1 = lo1;
  band.lo2 = lo2;
  return band;
}

// One pass over the frame (see FrameScan), optionally making the frame from `source` (box-averaged
// by source_factor, row by row) and the frame's box-average by coarse_factor. Bands of rows run on
// `pool`; their sums are added in band order whatever the pool, so the result does not depend on it.
FrameScan Scan(const sphere::EquirectImage& frame, const std::vector<double>& da, int block, int coarse_factor = 1,
               sphere::EquirectImage* coarse = nullptr, const sphere::EquirectImage* source = nullptr,
               int source_factor = 1, ThreadPool* pool = nullptr) {
  FrameScan s;
  if (coarse) coarse->Reshape(frame.width / coarse_factor, frame.height / coarse_factor);  // every cell written
  const int w = frame.width, h = frame.height;
  s.block = block;
  s.blocks_wide = (w + block - 1) / block;
  s.blocks_high = (h + block - 1) / block;
  s.block_max.assign(static_cast<std::size_t>(s.blocks_wide) * static_cast<std::size_t>(s.blocks_high), 0.f);
  const int unit = std::lcm(block, coarse ? coarse_factor : 1);
  const int band_rows = unit * std::max(1, 64 / unit);
  const int bands = (h + band_rows - 1) / band_rows;
  std::vector<BandScan> results(static_cast<std::size_t>(bands));
  const std::vector<float> none;
  const std::vector<float>& coarse_weights = coarse ? sphere::BoxRowWeights(h, coarse_factor) : none;
  const std::vector<float>& source_weights = source ? sphere::BoxRowWeights(source->height, source_factor) : none;
  const auto run = [&](long begin, long end) {
    for (long b = begin; b < end; ++b)
      results[static_cast<std::size_t>(b)] =
          ScanRows(frame, da, static_cast<int>(b) * band_rows, std::min(h, static_cast<int>(b + 1) * band_rows), &s,
                   coarse_factor, coarse, coarse_weights, source, source_factor, source_weights);
  };
  if (pool)
    pool->ParallelFor(bands, run, 1);
  else
    run(0, bands);
  V4 lo0{}, lo1{}, lo2{};
  for (const BandScan& b : results) {
    s.mean += b.mean;
    lo0 = lo0 < b.lo0 ? lo0 : b.lo0;
    lo1 = lo1 < b.lo1 ? lo1 : b.lo1;
    lo2 = lo2 < b.lo2 ? lo2 : b.lo2;
  }
  s.mean /= 4 * kPi;
  float lo[kLanes], lowest = 0, highest = 0;
  Store12(lo, lo0, lo1, lo2);
  for (int j = 0; j < kLanes; ++j) lowest = lowest < lo[j] ? lowest : lo[j];
  for (const float m : s.block_max) highest = highest > m ? highest : m;
  s.max_value = highest;
  // A NaN makes its channel's sum NaN (the comparisons above skip it); an Inf makes it Inf.
  s.dirty = lowest < 0 || !std::isfinite(s.mean) || !(highest <= FLT_MAX);
  return s;
}

bool IsBright(const float* p, double threshold, bool ldr) {
  return ldr ? std::min({p[0], p[1], p[2]}) >= threshold : Luminance(p) > threshold;
}

// A zeroed byte per pixel, kept by each thread across frames (two fresh ones of 0.5 MB per
// 1024-wide frame were faulted in and given back every frame). Whoever marks pixels clears
// them again, also when it leaves by an exception; one PixelMarks at a time per thread.
class PixelMarks {
 public:
  explicit PixelMarks(std::size_t n) : marks_(Storage()) {
    if (marks_.size() < n) marks_.assign(n, 0);
  }
  ~PixelMarks() { Clear(); }
  PixelMarks(const PixelMarks&) = delete;
  PixelMarks& operator=(const PixelMarks&) = delete;
  unsigned char operator[](int p) const { return marks_[static_cast<std::size_t>(p)]; }
  void Set(int p, unsigned char v) {
    if (!marks_[static_cast<std::size_t>(p)]) marked_.push_back(p);
    marks_[static_cast<std::size_t>(p)] = v;
  }
  void Clear() {
    for (const int p : marked_) marks_[static_cast<std::size_t>(p)] = 0;
    marked_.clear();
  }

 private:
  static std::vector<unsigned char>& Storage() {
    thread_local std::vector<unsigned char> storage;
    return storage;
  }
  std::vector<unsigned char>& marks_;
  std::vector<int> marked_;
};

struct SortScratch {
  std::vector<int> counts, pixels;
};

// Ascending pixel indices (row·w + col). A large component is sorted by column then, stably, by
// row (two counting passes): std::sort of bridge.exr's 15 257-pixel overcast zenith, in the
// flood fill's order, was a quarter of its components' time. Both give the same order.
void SortPixels(int w, int h, std::vector<int>* pixels, SortScratch* scratch) {
  std::vector<int>& px = *pixels;
  if (px.size() < 1024) {
    std::sort(px.begin(), px.end());
    return;
  }
  std::vector<int>& out = scratch->pixels;
  std::vector<int>& counts = scratch->counts;
  out.resize(px.size());
  const auto pass = [&](int buckets, auto key, const std::vector<int>& from, std::vector<int>& to) {
    counts.assign(static_cast<std::size_t>(buckets) + 1, 0);
    for (int p : from) ++counts[static_cast<std::size_t>(key(p)) + 1];
    for (int b = 0; b < buckets; ++b) counts[static_cast<std::size_t>(b) + 1] += counts[static_cast<std::size_t>(b)];
    for (int p : from) to[static_cast<std::size_t>(counts[static_cast<std::size_t>(key(p))]++)] = p;
  };
  const auto column = [w](int p) { return p % w; };
  const auto row = [w](int p) { return p / w; };
  pass(w, column, px, out);
  pass(h, row, out, px);
}

// The bright pixels grouped into components, 8-connected on the sphere: joined across the ±180°
// seam, and all of row 0 (and of row h−1) joined at its pole. Each component's pixels
// (row·w + col) ascending; components in the order of their first candidate block.
//
// Only the pixels of candidate blocks, those whose brightest pixel is bright, are looked at: a
// sunny frame has a handful. Labelling the whole frame's mask (OpenCV, 8-connected), then
// walking every label for the seam, the poles and the pixel lists, took about half of the
// 8 ms a 1024×512 frame's detection took (perf on sky.exr enlarged as the bench does).
std::vector<std::vector<int>> Components(const sphere::EquirectImage& frame, const FrameScan& scan, double threshold,
                                         bool ldr) {
  const int w = frame.width, h = frame.height, block = scan.block;
  const auto candidate = [&](int bx, int by) {
    const std::size_t i =
        static_cast<std::size_t>(by) * static_cast<std::size_t>(scan.blocks_wide) + static_cast<std::size_t>(bx);
    // A luminance's weights sum to 1 only up to rounding: allow for a grey pixel's luminance
    // rounding above its channels.
    return ldr ? scan.block_max[i] >= threshold : scan.block_max[i] * (1 + 1e-9) > threshold;
  };
  const auto bright = [&](int p) { return IsBright(&frame.rgb[3 * static_cast<std::size_t>(p)], threshold, ldr); };
  const auto bright_in_row = [&](int row) {
    std::vector<int> px;
    for (int bx = 0; bx < scan.blocks_wide; ++bx)
      if (candidate(bx, row / block))
        for (int col = bx * block; col < std::min(w, (bx + 1) * block); ++col)
          if (bright(row * w + col)) px.push_back(row * w + col);
    return px;
  };
  const std::vector<int> top = bright_in_row(0), bottom = bright_in_row(h - 1);
  PixelMarks seen(frame.pixel_count());
  std::vector<int> stack;
  const auto push = [&](int q) {
    if (seen[q] || !bright(q)) return;
    seen.Set(q, 1);
    stack.push_back(q);
  };
  std::vector<std::vector<int>> components;
  SortScratch sort_scratch;
  for (int by = 0; by < scan.blocks_high; ++by)
    for (int bx = 0; bx < scan.blocks_wide; ++bx) {
      if (!candidate(bx, by)) continue;
      for (int row = by * block; row < std::min(h, (by + 1) * block); ++row)
        for (int col = bx * block; col < std::min(w, (bx + 1) * block); ++col) {
          const int seed = row * w + col;
          if (seen[seed] || !bright(seed)) continue;
          seen.Set(seed, 1);
          std::vector<int> pixels;
          stack.assign(1, seed);
          // The bright pixels of a pole row join a component once: pushing them again from each
          // of its pixels in that row made a bright zenith quadratic in the row's width (bridge.exr's
          // overcast sky: 1.4 of the detector's 2.5 ms).
          bool top_joined = false, bottom_joined = false;
          while (!stack.empty()) {
            const int p = stack.back();
            stack.pop_back();
            pixels.push_back(p);
            // The neighbours' columns wrapped by hand, as the ring's below, not by an integer
            // division each: BrightComponents on dawn.exr's 1784-pixel glow at 1024 wide (the scan
            // and this, one thread) 315 → 260–297 µs.
            const int r = p / w, c = p - r * w;
            const int left = c == 0 ? w - 1 : c - 1, right = c == w - 1 ? 0 : c + 1;
            for (int r2 = std::max(0, r - 1); r2 <= std::min(h - 1, r + 1); ++r2) {
              push(r2 * w + left);
              push(r2 * w + c);
              push(r2 * w + right);
            }
            if (r == 0 && !top_joined) {
              top_joined = true;
              for (int q : top) push(q);
            }
            if (r == h - 1 && !bottom_joined) {
              bottom_joined = true;
              for (int q : bottom) push(q);
            }
          }
          SortPixels(w, h, &pixels, &sort_scratch);
          components.push_back(std::move(pixels));
        }
    }
  return components;
}

std::vector<double> SolidAngles(int w, int h) {
  std::vector<double> da(static_cast<std::size_t>(h));
  for (int row = 0; row < h; ++row) da[static_cast<std::size_t>(row)] = sphere::EquirectPixelSolidAngle(row, w, h);
  return da;
}

// `owned`: null, or the mutable image `input` refers to (sanitized in place, moved into the
// Spread of pixel directions about their mean `axis`: the square root of the ratio of the two
// principal second moments in the tangent plane (1 for a disc, large for a line).
double Elongation(const std::vector<int>& pixels, const glm::dvec3& axis, int w, int h) {
  const glm::dvec3 t1 =
      glm::normalize(glm::cross(axis, std::abs(axis.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0)));
  const glm::dvec3 t2 = glm::cross(axis, t1);
  double sxx = 0, syy = 0, sxy = 0;
  const PixelDirections& direction = PixelDirections::Of(w, h);
  for (int p : pixels) {
    const glm::dvec3 d = direction(p);
    const double x = glm::dot(d, t1), y = glm::dot(d, t2);
    sxx += x * x;
    syy += y * y;
    sxy += x * y;
  }
  const double tr = sxx + syy, det = sxx * syy - sxy * sxy;
  const double disc = std::sqrt(std::max(0.0, tr * tr / 4 - det));
  const double l1 = tr / 2 + disc, l2 = std::max(tr / 2 - disc, 1e-30);
  return std::sqrt(l1 / l2);
}

// ∫ L(ω) max(0, ω·axis) dω over an equirect image: the irradiance on a surface facing `axis`.
glm::dvec3 Irradiance(const sphere::EquirectImage& image, const glm::dvec3& axis) {
  const int w = image.width, h = image.height;
  const PixelDirections& direction = PixelDirections::Of(w, h);
  glm::dvec3 sum(0);
  for (int row = 0; row < h; ++row) {
    glm::dvec3 sum_row(0);
    for (int col = 0; col < w; ++col) {
      const double cosine = glm::dot(direction(row * w + col), axis);
      if (cosine <= 0) continue;
      const float* v = image.at(col, row);
      sum_row += cosine * glm::dvec3(v[0], v[1], v[2]);
    }
    sum += sphere::EquirectPixelSolidAngle(row, w, h) * sum_row;
  }
  return sum;
}

// Whether a clipped component of an LDR frame has a sun's place and shape (PeakDetectorOptions'
// ldr_* gates but the ring's): above the horizon, compact and round.
bool CouldBeAnLdrSunByShape(const std::vector<int>& pixels, int w, int h, const PeakDetectorOptions& options) {
  const PixelDirections& direction = PixelDirections::Of(w, h);
  glm::dvec3 sum(0);
  for (int p : pixels) sum += direction(p);
  if (glm::length(sum) < 1e-12) return false;
  const glm::dvec3 axis = glm::normalize(sum);
  if (axis.y < std::sin(options.ldr_min_elevation_deg * kPi / 180)) return false;  // below the horizon
  const double cos_radius = std::cos(options.ldr_max_sun_radius_deg * kPi / 180);
  for (int p : pixels)
    if (glm::dot(direction(p), axis) < cos_radius) return false;                             // not compact
  return pixels.size() < 6 || Elongation(pixels, axis, w, h) <= options.ldr_max_elongation;  // round
}

// The mean luminance within `radius_deg` of a component's centre (by solid angle, its own pixels
// included): how much an LDR frame's clipped component glows. The sun brightens the sky around it
// (the circumsolar glow, a camera's bloom); a clipped highlight on a lamp post or a sign sits in a
// dark surround.
double GlowAround(const std::vector<int>& pixels, const sphere::EquirectImage& frame, double radius_deg) {
  const int w = frame.width, h = frame.height;
  const PixelDirections& direction = PixelDirections::Of(w, h);
  glm::dvec3 sum(0);
  for (int p : pixels) sum += direction(p);
  if (glm::length(sum) < 1e-12) return 0;
  const glm::dvec3 axis = glm::normalize(sum);
  const double radius = radius_deg * kPi / 180, cos_radius = std::cos(radius);
  const double lat = std::asin(std::clamp(axis.y, -1.0, 1.0));
  const int row_centre = static_cast<int>((kPi / 2 - lat) / kPi * h);
  const int half_rows = static_cast<int>(std::ceil(radius / kPi * h)) + 1;
  // Columns: a cap of angular radius r at latitude φ spans asin(sin r / cos φ) of longitude (the
  // whole row once it reaches a pole).
  const double cos_edge = std::cos(std::min(kPi / 2, std::abs(lat) + radius));
  const bool whole_rows = std::sin(radius) >= cos_edge;
  const int half_cols =
      whole_rows ? w : static_cast<int>(std::ceil(std::asin(std::sin(radius) / cos_edge) / (2 * kPi) * w)) + 1;
  const double lon = std::atan2(-axis.z, axis.x);
  const int col_centre = static_cast<int>((1 - lon / kPi) * w / 2);
  double weighted = 0, area = 0;
  for (int row = std::max(0, row_centre - half_rows); row <= std::min(h - 1, row_centre + half_rows); ++row) {
    const double da = sphere::EquirectPixelSolidAngle(row, w, h);
    for (int k = whole_rows ? 0 : -half_cols; k < (whole_rows ? w : half_cols + 1); ++k) {
      const int col = whole_rows ? k : ((col_centre + k) % w + w) % w;
      const int p = row * w + col;
      if (glm::dot(direction(p), axis) < cos_radius) continue;
      weighted += Luminance(frame.at(col, row)) * da;
      area += da;
    }
  }
  return area > 0 ? weighted / area : 0;
}

// Whether a clipped LDR component of a sun's shape stands out from its ring: not the clipped core
// of a larger blown-out area.
bool StandsOutFromItsRing(const glm::vec3& ring, const PeakDetectorOptions& options) {
  const float ring_level[3] = {ring.x, ring.y, ring.z};
  return Luminance(ring_level) <= options.ldr_max_ring_level * options.ldr_clip_level;
}

// residue). Without `keep_residue` the residue is left empty unless the frame is LDR.
PeakDetection Detect(const sphere::EquirectImage& input, sphere::EquirectImage* owned, bool keep_residue,
                     const PeakDetectorOptions& options, std::chrono::steady_clock::time_point start, int coarse_factor,
                     const sphere::EquirectImage* source = nullptr, int source_factor = 1, ThreadPool* pool = nullptr,
                     sphere::EquirectImage* coarse_storage = nullptr);

// The coarse cells holding a peak's pixels, recomputed from the frame with those pixels at
// min(I, b) (what the residue holds there) in DownsampleBox's order: `taken` lists (pixel, its
// ring level). The rest of the coarse grid, summed in the scan, is the residue's already.
void RefreshCoarse(const sphere::EquirectImage& frame, std::vector<std::pair<int, glm::vec3>> taken, int factor,
                   sphere::EquirectImage* coarse) {
  const int w = frame.width;
  const auto cell_of = [&](int p) { return (p / w / factor) * coarse->width + (p % w) / factor; };
  std::sort(taken.begin(), taken.end(),
            [&](const auto& a, const auto& b) { return cell_of(a.first) < cell_of(b.first); });
  std::vector<float> block(3 * static_cast<std::size_t>(factor) * static_cast<std::size_t>(factor));
  std::vector<float> column(3 * static_cast<std::size_t>(factor));
  const std::vector<float>& weights = sphere::BoxRowWeights(frame.height, factor);
  for (std::size_t i = 0; i < taken.size();) {
    const int cell = cell_of(taken[i].first);
    const int cr = cell / coarse->width, cc = cell % coarse->width;
    for (int dy = 0; dy < factor; ++dy)
      std::copy_n(frame.at(cc * factor, cr * factor + dy), 3 * factor,
                  &block[3 * static_cast<std::size_t>(dy * factor)]);
    for (; i < taken.size() && cell_of(taken[i].first) == cell; ++i) {
      const int p = taken[i].first;
      float* v = &block[3 * static_cast<std::size_t>((p / w - cr * factor) * factor + (p % w - cc * factor))];
      for (int k = 0; k < 3; ++k) v[k] = std::min(v[k], taken[i].second[k]);
    }
    std::fill(column.begin(), column.end(), 0.f);
    for (int dy = 0; dy < factor; ++dy)
      sphere::AddBoxRow(&block[3 * static_cast<std::size_t>(dy * factor)], factor,
                        weights[static_cast<std::size_t>(cr * factor + dy)], column.data());
    sphere::FoldBoxColumns(column.data(), factor, factor, coarse->at(cc, cr));
  }
}

}  // namespace

void PeakDetectorOptions::Check() const {
  if (!(threshold_factor > 1)) throw Error("peak threshold", "must exceed 1 (× the mean radiance)");
  if (!(max_area_fraction > 0 && max_area_fraction < 0.5)) throw Error("peak area", "must be in (0, 0.5)");
  if (max_sgs_per_peak < 1 || max_sgs_per_peak > 3) throw Error("SGs per peak", "must be 1..3");
  if (max_peaks < 0) throw Error("max peaks", "must be >= 0");
  if (!(min_contrast >= 1)) throw Error("peak contrast", "must be at least 1 (× the surrounding level)");
  if (!(min_lambda >= 0)) throw Error("peak minimum lambda", "must be >= 0");
  if (candidate_block < 1) throw Error("peak candidate block", "must be at least 1 pixel");
  if (!(ldr_max_sun_radius_deg > 0 && ldr_max_sun_radius_deg < 90))
    throw Error("LDR sun radius", "must be in (0, 90) degrees");
  if (!(ldr_max_elongation >= 1)) throw Error("LDR sun elongation", "must be at least 1");
  if (!(ldr_max_ring_level > 0 && ldr_max_ring_level <= 1)) throw Error("LDR sun ring level", "must be in (0, 1]");
  if (ldr_max_suns < 0) throw Error("LDR suns", "must be >= 0");
  if (!(ldr_glow_radius_deg > 0 && ldr_glow_radius_deg < 90))
    throw Error("LDR glow radius", "must be in (0, 90) degrees");
  if (!(ldr_min_glow_margin >= 1)) throw Error("LDR glow margin", "must be at least 1");
  if (!(ldr_min_elevation_deg >= -90 && ldr_min_elevation_deg < 90))
    throw Error("LDR sun elevation", "must be in [-90, 90) degrees");
}

std::vector<std::vector<int>> BrightComponents(const sphere::EquirectImage& frame, double threshold, bool ldr,
                                               int candidate_block) {
  if (candidate_block < 1) throw Error("peak candidate block", "must be at least 1 pixel");
  if (frame.empty()) return {};
  return Components(frame, Scan(frame, SolidAngles(frame.width, frame.height), candidate_block), threshold, ldr);
}

PeakDetection DetectPeaks(const sphere::EquirectImage& frame, const PeakDetectorOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  return Detect(frame, nullptr, true, options, start, 1);
}

PeakDetection DetectPeaks(sphere::EquirectImage&& frame, const PeakDetectorOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  return Detect(frame, &frame, true, options, start, 1);
}

PeakDetection DetectPeaksToCoarseGrid(const sphere::EquirectImage& frame, int coarse_factor,
                                      const PeakDetectorOptions& options, int frame_factor,
                                      sphere::EquirectImage* grid_storage, ThreadPool* pool,
                                      sphere::EquirectImage* coarse_storage) {
  const auto start = std::chrono::steady_clock::now();
  if (frame_factor < 1 || frame.width % frame_factor || frame.height % frame_factor)
    throw Error("peak detection", "frame factor " + std::to_string(frame_factor) + " does not divide " +
                                      std::to_string(frame.width) + "x" + std::to_string(frame.height));
  const int w = frame.width / frame_factor, h = frame.height / frame_factor;
  if (coarse_factor < 2 || w % coarse_factor || h % coarse_factor)
    throw Error("peak detection", "coarse factor " + std::to_string(coarse_factor) + " does not divide " +
                                      std::to_string(w) + "x" + std::to_string(h));
  if (frame_factor == 1)
    return Detect(frame, nullptr, false, options, start, coarse_factor, nullptr, 1, pool, coarse_storage);
  sphere::EquirectImage local;
  sphere::EquirectImage& grid = grid_storage ? *grid_storage : local;
  // Filled by the scan. Kept by the caller across frames, its pages are not faulted in (and
  // given back) for every frame: at 2048 wide that was a millisecond of the build.
  if (grid.width != w || grid.height != h || grid.rgb.size() != 3 * static_cast<std::size_t>(w) * h)
    grid = sphere::EquirectImage(w, h);
  return Detect(grid, &grid, false, options, start, coarse_factor, &frame, frame_factor, pool, coarse_storage);
}

namespace {

// Only the brightest components are worth a peak: rank by rough energy first, so a noisy frame
// with thousands of bright specks costs no more than a clean one. In an LDR frame a component
// below the horizon or spread wide cannot be a sun (whatever its ring): it is left out before the
// ranking, or a street's clipped lane markings and kerbs crowd out a one-pixel sun. Keeps the
// 2 × most + 2 brightest, brightest first; sets out->ldr_glow in an LDR frame.
std::vector<std::vector<int>> RankComponents(std::vector<std::vector<int>> components,
                                             const sphere::EquirectImage& frame, const std::vector<double>& da,
                                             const PeakDetectorOptions& options, int most, PeakDetection* out) {
  const int w = frame.width, h = frame.height;
  std::vector<std::pair<double, std::size_t>> rough;
  for (std::size_t i = 0; i < components.size(); ++i) {
    if (components[i].empty()) continue;
    double e = 0;
    if (out->ldr) {
      // Clipped pixels all read 1, so an LDR component ranks by its glow instead of its energy.
      if (!CouldBeAnLdrSunByShape(components[i], w, h, options)) continue;
      e = GlowAround(components[i], frame, options.ldr_glow_radius_deg);
    } else {
      for (int p : components[i])
        e += Luminance(&frame.rgb[3 * static_cast<std::size_t>(p)]) * da[static_cast<std::size_t>(p / w)];
    }
    rough.emplace_back(e, i);
  }
  std::sort(rough.rbegin(), rough.rend());
  // The sun is one of a kind: where the clipped candidates glow alike (the crossings of a white
  // room's grid lines, a row of windows) none of them is taken for it.
  if (out->ldr && !rough.empty()) {
    out->ldr_glow = {rough[0].first, rough.size() >= 2 ? rough[1].first : 0.0};
    if (rough.size() >= 2 && !(rough[0].first >= options.ldr_min_glow_margin * rough[1].first)) rough.clear();
  }
  if (rough.size() > static_cast<std::size_t>(2 * most + 2)) rough.resize(static_cast<std::size_t>(2 * most + 2));
  std::vector<std::vector<int>> ranked;
  for (const auto& [e, i] : rough) ranked.push_back(std::move(components[i]));
  return ranked;
}

// A component's surrounding level: the mean of the one-pixel ring around it. `in` marks the
// component's pixels (1) and its ring (2), and is cleared again.
glm::vec3 RingMean(const std::vector<int>& pixels, const sphere::EquirectImage& frame, PixelMarks* in) {
  const int w = frame.width, h = frame.height;
  for (int p : pixels) in->Set(p, 1);
  glm::dvec3 ring(0);
  int ring_n = 0;
  for (int p : pixels) {
    const int row = p / w, col = p % w;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int r2 = row + dr;
        if (r2 < 0 || r2 >= h) continue;
        // Wrapped by hand: two integer divisions per neighbour were most of this loop's time.
        const int c2 = col + dc < 0 ? col + dc + w : (col + dc >= w ? col + dc - w : col + dc);
        const int q = r2 * w + c2;
        if ((*in)[q]) continue;
        in->Set(q, 2);  // count each ring pixel once
        const float* v = frame.at(c2, r2);
        ring += glm::dvec3(v[0], v[1], v[2]);
        ++ring_n;
      }
  }
  in->Clear();
  return ring_n ? glm::vec3(ring / double(ring_n)) : glm::vec3(0);
}

// An elongated component as k SGs: k-means on its pixels' directions, seeded along its extent,
// then one SG fitted to each cluster's excess.
std::vector<RgbSg> SplitIntoSgs(const std::vector<int>& pixels, const std::vector<glm::dvec3>& excess,
                                const sphere::EquirectImage& frame, double pixel_angle, int k) {
  std::vector<glm::dvec3> dirs(pixels.size());
  const PixelDirections& direction = PixelDirections::Of(frame.width, frame.height);
  for (std::size_t i = 0; i < pixels.size(); ++i) dirs[i] = direction(pixels[i]);
  std::vector<glm::dvec3> centres;
  for (int j = 0; j < k; ++j)
    centres.push_back(dirs[(pixels.size() - 1) * static_cast<std::size_t>(j) / static_cast<std::size_t>(k - 1)]);
  std::vector<int> assign(pixels.size(), 0);
  for (int it = 0; it < 10; ++it) {
    for (std::size_t i = 0; i < dirs.size(); ++i) {
      int best = 0;
      for (int j = 1; j < k; ++j)
        if (glm::dot(dirs[i], centres[static_cast<std::size_t>(j)]) >
            glm::dot(dirs[i], centres[static_cast<std::size_t>(best)]))
          best = j;
      assign[i] = best;
    }
    std::vector<glm::dvec3> sums(static_cast<std::size_t>(k), glm::dvec3(0));
    for (std::size_t i = 0; i < dirs.size(); ++i) sums[static_cast<std::size_t>(assign[i])] += dirs[i];
    for (int j = 0; j < k; ++j)
      if (glm::length(sums[static_cast<std::size_t>(j)]) > 0)
        centres[static_cast<std::size_t>(j)] = glm::normalize(sums[static_cast<std::size_t>(j)]);
  }
  std::vector<RgbSg> sgs;
  for (int j = 0; j < k; ++j) {
    std::vector<int> px;
    std::vector<glm::dvec3> ex;
    for (std::size_t i = 0; i < pixels.size(); ++i)
      if (assign[i] == j) {
        px.push_back(pixels[i]);
        ex.push_back(excess[i]);
      }
    if (!px.empty()) sgs.push_back(FitSg(px, ex, frame, pixel_angle));
  }
  return sgs;
}

struct Candidate {
  DetectedPeak peak;
  std::vector<int> pixels;
  glm::vec3 background;
};

// A ranked component as a peak: none for what is not a light (too large, too little contrast
// with its ring, too broad), else its excess over the ring fitted by one SG, or by up to
// max_sgs_per_peak when it is elongated.
std::optional<Candidate> MakeCandidate(std::vector<int> pixels, const sphere::EquirectImage& frame,
                                       const std::vector<double>& da, const PeakDetectorOptions& options, bool ldr,
                                       double pixel_angle, PixelMarks* in) {
  const int w = frame.width, h = frame.height;
  if (pixels.empty()) return std::nullopt;
  double area = 0;
  for (int p : pixels) area += da[static_cast<std::size_t>(p / w)];
  if (area > options.max_area_fraction * 4 * kPi) return std::nullopt;  // a bright wall, not a light
  Candidate c;
  c.background = RingMean(pixels, frame, in);
  const auto value = [&](int p) { return &frame.rgb[3 * static_cast<std::size_t>(p)]; };
  // A light stands out from what surrounds it; a glow only a few times its ring (dawn.exr's
  // reddened sky around the sun, 4× its ring) is smooth enough for the hierarchy, and 1–3 SGs
  // fitted to its irregular shape put its light in the wrong places (glossy200 error 0.008
  // without peaks, 0.052 with). A clipped LDR sun's contrast is lost with its intensity.
  // Judged before the per-pixel excess, which a glow would only throw away.
  if (!ldr) {
    double brightest = 0;
    for (int p : pixels) brightest = std::max(brightest, Luminance(value(p)));
    const float ring_level[3] = {c.background.x, c.background.y, c.background.z};
    if (brightest < options.min_contrast * Luminance(ring_level)) return std::nullopt;
  } else if (!StandsOutFromItsRing(c.background, options)) {  // its shape was judged before the ranking
    return std::nullopt;
  }
  std::vector<glm::dvec3> excess(pixels.size());
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const int p = pixels[i];
    const float* v = value(p);
    excess[i] = glm::max(glm::dvec3(v[0], v[1], v[2]) - glm::dvec3(c.background), glm::dvec3(0)) *
                da[static_cast<std::size_t>(p / w)];
    c.peak.energy += excess[i];
  }
  c.peak.pixels = static_cast<int>(pixels.size());
  if (c.peak.energy == glm::dvec3(0)) return std::nullopt;

  // Elongated? Principal axes of the pixel directions about the mean: split by k-means.
  const RgbSg whole = FitSg(pixels, excess, frame, pixel_angle);
  // A component as broad as one SG of the hierarchy's level 3 (λ 364.5) is what levels 0–3
  // resolve; as free SGs fitted to its irregular shape it puts light in the wrong places. Judged
  // on the one SG of the whole component: judged on the SGs after the split, lobby.exr's window
  // (one SG of λ 229, three of 1600–2000) stayed a peak and raised glossy200 by 17 %.
  if (whole.lambda < options.min_lambda) return std::nullopt;
  int k = 1;
  if (options.max_sgs_per_peak > 1 && pixels.size() >= 6) {
    const double ratio = Elongation(pixels, whole.axis, w, h);
    if (ratio > options.elongation_for_split)
      k = std::min(options.max_sgs_per_peak, ratio > 2 * options.elongation_for_split ? 3 : 2);
  }
  c.peak.sgs = k == 1 ? std::vector<RgbSg>{whole} : SplitIntoSgs(pixels, excess, frame, pixel_angle, k);
  c.pixels = std::move(pixels);
  return c;
}

PeakDetection Detect(const sphere::EquirectImage& input, sphere::EquirectImage* owned, bool keep_residue,
                     const PeakDetectorOptions& options, std::chrono::steady_clock::time_point start, int coarse_factor,
                     const sphere::EquirectImage* source, int source_factor, ThreadPool* pool,
                     sphere::EquirectImage* coarse_storage) {
  options.Check();
  PeakDetection out;
  if (coarse_factor > 1 && coarse_storage) out.coarse = std::move(*coarse_storage);
  const int w = input.width, h = input.height;
  if (w < 4 || h < 2) throw Error("peak detection", "frame too small");
  const std::vector<double> da = SolidAngles(w, h);
  sphere::EquirectImage* coarse = coarse_factor > 1 ? &out.coarse : nullptr;
  FrameScan scan = Scan(input, da, options.candidate_block, coarse_factor, coarse, source, source_factor, pool);
  // One NaN would make the mean radiance NaN and cost the frame its sun; an Inf would set the
  // threshold to Inf. Bad pixels are 0 here, as they are in the transform.
  sphere::EquirectImage copy;
  if (scan.dirty) {
    if (!owned) {
      copy = input;
      owned = &copy;
    }
    const auto [bad, negative] = image::SanitizePixels(owned);
    spdlog::warn("peak detection input: clamped {} NaN/Inf and {} negative pixels to 0", bad, negative);
    scan = Scan(*owned, da, options.candidate_block, coarse_factor, coarse, nullptr, 1, pool);
  }
  const sphere::EquirectImage& frame = owned ? *owned : input;
  // The residue, when one is kept: the caller's image moved, or a copy of the frame.
  const auto take_residue = [&]() -> sphere::EquirectImage {
    if (owned) return std::move(*owned);
    return frame;
  };
  const double mean = scan.mean;
  out.ldr = scan.max_value <= 1.0 + 1e-4;
  out.threshold = out.ldr ? options.ldr_clip_level : options.threshold_factor * mean;
  const auto finish = [&] {
    if (keep_residue) out.residue = take_residue();
    out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return std::move(out);
  };
  if (!(mean > 0)) return finish();
  std::vector<std::vector<int>> components = Components(frame, scan, out.threshold, out.ldr);
  if (components.empty()) return finish();

  const int most = out.ldr ? std::min(options.max_peaks, options.ldr_max_suns) : options.max_peaks;
  components = RankComponents(std::move(components), frame, da, options, most, &out);

  const double pixel_angle = kPi / h;
  std::vector<Candidate> candidates;
  PixelMarks in(frame.pixel_count());
  for (auto& pixels : components)
    if (auto c = MakeCandidate(std::move(pixels), frame, da, options, out.ldr, pixel_angle, &in))
      candidates.push_back(std::move(*c));
  // The brightest first (an LDR frame's: the most glowing, the ranking's order); keep max_peaks.
  if (!out.ldr)
    std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
      return a.peak.energy.x + a.peak.energy.y + a.peak.energy.z > b.peak.energy.x + b.peak.energy.y + b.peak.energy.z;
    });
  if (static_cast<int>(candidates.size()) > most) candidates.resize(static_cast<std::size_t>(most));

  // An LDR sun's energy is judged against the sky's irradiance: from the coarse grid when there is
  // one (the residue box-averaged: the cosine varies by a cell's width in it), else from the
  // residue, kept then. A frame-sized copy costs its page faults on every frame (more than the
  // whole detection at 1024 wide), the coarse grid is there anyway.
  keep_residue = keep_residue || (out.ldr && !coarse);
  std::vector<std::pair<int, glm::vec3>> taken;
  if (coarse && !keep_residue)
    for (const auto& c : candidates)
      for (int p : c.pixels) taken.emplace_back(p, c.background);
  if (!taken.empty()) RefreshCoarse(frame, std::move(taken), coarse_factor, coarse);
  if (keep_residue) out.residue = take_residue();

  for (auto& c : candidates) {
    // The peak holds Σ max(I − b, 0) dA, so the residue keeps min(I, b) per channel: the two then
    // add up to the frame exactly. Setting the pixels to b instead raised every pixel darker than
    // the ring (in any channel) to b, light that was in neither: on park.exr the ring's blue is
    // 17.8 while a luminance-thresholded component holds pixels far below it, which added 2 % of
    // the map's blue energy at the sun and made the diffuse error 5× that of no peaks.
    for (int p : c.pixels) {
      if (!keep_residue) break;  // the coarse grid got the same above
      float* r = out.residue.at(p % w, p / w);
      r[0] = std::min(r[0], c.background.x);
      r[1] = std::min(r[1], c.background.y);
      r[2] = std::min(r[2], c.background.z);
    }
    if (coarse && keep_residue) {
      std::vector<std::pair<int, glm::vec3>> pixels;
      for (int p : c.pixels) pixels.emplace_back(p, c.background);
      RefreshCoarse(out.residue, std::move(pixels), coarse_factor, coarse);
    }
    if (out.ldr) {
      // Clipped: scale the peak so its irradiance on a surface facing it is the prior ratio
      // times the sky's (the residue's) irradiance on that surface.
      const glm::dvec3 axis = c.peak.sgs.front().axis;
      const glm::dvec3 target = options.ldr_sun_to_sky_ratio * Irradiance(keep_residue ? out.residue : *coarse, axis);
      glm::dvec3 current(0);
      for (const auto& g : c.peak.sgs) current += glm::dvec3(g.amplitude) * Integral(Sg{g.axis, g.lambda, 1});
      for (auto& g : c.peak.sgs)
        for (int ch = 0; ch < 3; ++ch)
          if (current[ch] > 0) g.amplitude[ch] = static_cast<float>(g.amplitude[ch] * target[ch] / current[ch]);
      c.peak.energy = target;
      c.peak.estimated_from_clipped_ldr = true;
    }
    out.peaks.push_back(std::move(c.peak));
  }
  out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace

}  // namespace odvr::lighting
