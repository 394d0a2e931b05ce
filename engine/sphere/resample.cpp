#include "engine/sphere/resample.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "engine/sphere/equirect.h"

namespace odvr::sphere {
namespace {

// Box filter taps along one axis: output i averages input x over [i·s, (i+1)·s), s = n_in / n_out,
// each input sample weighted by the part of it inside that interval. The same for every row (or
// column), so made once per call instead of per line.
struct BoxTaps {
  std::vector<int> begin, index;
  std::vector<float> weight;
};

BoxTaps MakeBoxTaps(int n_in, int n_out) {
  BoxTaps t;
  const double s = static_cast<double>(n_in) / n_out;
  t.begin.reserve(static_cast<std::size_t>(n_out) + 1);
  for (int i = 0; i < n_out; ++i) {
    t.begin.push_back(static_cast<int>(t.index.size()));
    const double x0 = i * s, x1 = (i + 1) * s;
    for (int x = static_cast<int>(std::floor(x0)); x < static_cast<int>(std::ceil(x1)) && x < n_in; ++x) {
      const double w = std::min<double>(x + 1, x1) - std::max<double>(x, x0);
      if (w <= 0) continue;
      t.index.push_back(x);
      t.weight.push_back(static_cast<float>(w / s));
    }
  }
  t.begin.push_back(static_cast<int>(t.index.size()));
  return t;
}

// cos θ(y0) − cos θ(y1) for the latitude band between image rows y0 < y1 (fractional, θ = π y /
// height): its area per radian of longitude. As a product of sines, accurate for thin bands.
double LatitudeBandArea(double y0, double y1, int height) {
  const double a = kPi * y0 / height, b = kPi * y1 / height;
  return 2 * std::sin(0.5 * (a + b)) * std::sin(0.5 * (b - a));
}

// One row of `width` RGB outputs, each the taps' weighted sum of the input row's pixels.
void BoxRow(const float* in, const BoxTaps& across, int width, float* out) {
  for (int i = 0; i < width; ++i) {
    float acc[3] = {0, 0, 0};
    for (int k = across.begin[static_cast<std::size_t>(i)]; k < across.begin[static_cast<std::size_t>(i) + 1]; ++k) {
      const float w = across.weight[static_cast<std::size_t>(k)];
      const float* p = in + 3 * across.index[static_cast<std::size_t>(k)];
      acc[0] += w * p[0];
      acc[1] += w * p[1];
      acc[2] += w * p[2];
    }
    out[3 * i] = acc[0];
    out[3 * i + 1] = acc[1];
    out[3 * i + 2] = acc[2];
  }
}

}  // namespace

EquirectImage ResampleArea(const EquirectImage& image, int width, int height, ThreadPool* pool) {
  if (width == image.width && height == image.height) return image;
  EquirectImage out;
  out.width = width;
  out.height = height;
  ResampleArea(image, &out, pool);
  return out;
}

void ResampleArea(const EquirectImage& image, EquirectImage* target, ThreadPool* pool) {
  const int width = target->width, height = target->height;
  if (width <= 0 || height <= 0) throw Error("resample", "target size must be positive");
  if (width > image.width || height > image.height) throw Error("resample", "area resampling only shrinks");
  EquirectImage& out = *target;
  if (width == image.width && height == image.height) {  // nothing to average: a copy
    out.rgb = image.rgb;
    return;
  }
  out.Reshape(width, height);
  const int n = 3 * image.width;
  const int factor = image.width / width;
  const bool whole_columns = image.width == factor * width;
  const BoxTaps across = MakeBoxTaps(image.width, width), down = MakeBoxTaps(image.height, height);
  // Each tap's weight: for integer factors DownsampleBox's (BoxRowWeights, the taps being each
  // block's rows in order), otherwise the area of the part of the input row's latitude band
  // inside the output row's, normalized per output row (within a row every pixel has the same
  // solid angle, so the columns are the plain box's). Coverage × the row's solid angle instead
  // misses a polar output row's energy by 2 % when it takes part of a row (200 to 72 wide).
  std::vector<float> tap_weight(down.weight.size());
  if (whole_columns && image.height == factor * height) {
    const std::vector<float>& by_row = BoxRowWeights(image.height, factor);
    for (std::size_t k = 0; k < tap_weight.size(); ++k) tap_weight[k] = by_row[static_cast<std::size_t>(down.index[k])];
  } else {
    const double sy = static_cast<double>(image.height) / height;
    for (int row = 0; row < height; ++row) {
      const auto first = static_cast<std::size_t>(down.begin[static_cast<std::size_t>(row)]);
      const auto last = static_cast<std::size_t>(down.begin[static_cast<std::size_t>(row) + 1]);
      std::vector<double> band(last - first);
      double total = 0;
      for (std::size_t k = first; k < last; ++k) {
        const int y = down.index[k];
        band[k - first] =
            LatitudeBandArea(std::max<double>(y, row * sy), std::min<double>(y + 1, (row + 1) * sy), image.height);
        total += band[k - first];
      }
      for (std::size_t k = first; k < last; ++k) tap_weight[k] = static_cast<float>(band[k - first] / total);
    }
  }
  auto rows = [&](long begin, long end) {
    std::vector<float> column(static_cast<std::size_t>(n));
    for (long row = begin; row < end; ++row) {
      std::fill(column.begin(), column.end(), 0.f);
      for (int k = down.begin[static_cast<std::size_t>(row)]; k < down.begin[static_cast<std::size_t>(row) + 1]; ++k)
        AddBoxRow(image.at(0, down.index[static_cast<std::size_t>(k)]), image.width,
                  tap_weight[static_cast<std::size_t>(k)], column.data());
      float* o = out.at(0, static_cast<int>(row));
      if (whole_columns)
        FoldBoxColumns(column.data(), image.width, factor, o);  // the rows' weights sum to one
      else
        BoxRow(column.data(), across, width, o);
    }
  };
  if (pool)
    pool->ParallelFor(height, rows, 8);
  else
    rows(0, height);
}

EquirectImage UpsampleBilinear(const EquirectImage& image, int width, int height) {
  if (width == image.width && height == image.height) return image;
  EquirectImage out(width, height);
  const double sx = static_cast<double>(image.width) / width, sy = static_cast<double>(image.height) / height;
  for (int row = 0; row < height; ++row) {
    const double y = (row + 0.5) * sy - 0.5;
    const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, image.height - 1);
    const int y1 = std::min(y0 + 1, image.height - 1);
    const float fy = static_cast<float>(std::clamp(y - y0, 0.0, 1.0));
    for (int col = 0; col < width; ++col) {
      const double x = (col + 0.5) * sx - 0.5;
      const int xf = static_cast<int>(std::floor(x));
      const float fx = static_cast<float>(x - xf);
      const int x0 = (xf % image.width + image.width) % image.width, x1 = (x0 + 1) % image.width;
      const float *a = image.at(x0, y0), *b = image.at(x1, y0), *c = image.at(x0, y1), *d = image.at(x1, y1);
      float* o = out.at(col, row);
      for (int k = 0; k < 3; ++k) o[k] = (1 - fy) * ((1 - fx) * a[k] + fx * b[k]) + fy * ((1 - fx) * c[k] + fx * d[k]);
    }
  }
  return out;
}

namespace {

constexpr int kLagrangeTaps = 6;  // nodes −2 … 3 around the sample
constexpr int kLagrangeLeft = kLagrangeTaps / 2 - 1;

// The weights of nodes −2 … 3 for a sample at t ∈ [0, 1) past node 0.
std::array<float, kLagrangeTaps> LagrangeWeights(double t) {
  std::array<float, kLagrangeTaps> w{};
  for (int j = 0; j < kLagrangeTaps; ++j) {
    double l = 1;
    for (int m = 0; m < kLagrangeTaps; ++m)
      if (m != j) l *= (t - (m - kLagrangeLeft)) / static_cast<double>(j - m);
    w[static_cast<std::size_t>(j)] = static_cast<float>(l);
  }
  return w;
}

struct LagrangePlan {
  int factor = 1;
  std::vector<int> offset;  // per phase
  std::vector<std::array<float, kLagrangeTaps>> weights;
};

// Output rows [begin, end) of MagnifyLagrange: each down the columns into `column` (three pixels
// wrapped around either side), then each phase along it (contiguous floats, the taps three
// apart) into `across`, interleaved into the row. In vectors of V (the build's x86-64 does not
// vectorize these loops by itself), for a plain and an AVX2 function.
template <typename V>
[[gnu::always_inline]] inline void MagnifyRows(const EquirectImage& image, const LagrangePlan& plan, long begin,
                                               long end, EquirectImage* out) {
  constexpr int kPad = 3 * (kLagrangeTaps / 2);
  constexpr int kLanes = sizeof(V) / sizeof(float);
  const int w = image.width, h = image.height, n = 3 * w, factor = plan.factor;
  const int padded = (n + kLanes - 1) / kLanes * kLanes;
  std::vector<float> column(static_cast<std::size_t>(padded + 2 * kPad + kLanes)),
      across(static_cast<std::size_t>(padded));
  float* c = column.data() + kPad;
  V a, b;
  for (long row = begin; row < end; ++row) {
    const int r = static_cast<int>(row), phase_y = r % factor;
    const std::array<float, kLagrangeTaps>& wy = plan.weights[static_cast<std::size_t>(phase_y)];
    for (int k = 0; k < kLagrangeTaps; ++k) {
      int y = r / factor + plan.offset[static_cast<std::size_t>(phase_y)] - kLagrangeLeft + k, shift = 0;
      if (y < 0) y = -y - 1, shift = 3 * (w / 2);
      if (y >= h) y = 2 * h - y - 1, shift = 3 * (w / 2);
      // c[j] (+)= wk · in[(j + shift) mod n], in vectors where the source is contiguous.
      const float* in = image.at(0, y);
      const float wk = wy[static_cast<std::size_t>(k)];
      for (int part = 0; part < 2; ++part) {
        const int j0 = part == 0 ? 0 : n - shift, j1 = part == 0 ? n - shift : n;
        const float* src = part == 0 ? in + shift : in + shift - n;
        int j = j0;
        for (; j + kLanes <= j1; j += kLanes) {
          std::memcpy(&a, src + j, sizeof a);
          if (k == 0) {
            a *= wk;
          } else {
            std::memcpy(&b, c + j, sizeof b);
            a = b + wk * a;
          }
          std::memcpy(c + j, &a, sizeof a);
        }
        for (; j < j1; ++j) c[j] = k == 0 ? wk * src[j] : c[j] + wk * src[j];
      }
    }
    for (int j = 0; j < kPad; ++j) {
      column[static_cast<std::size_t>(j)] = c[n - kPad + j];
      c[n + j] = c[j];
    }
    float* o = out->at(0, r);
    for (int phase = 0; phase < factor; ++phase) {
      const std::array<float, kLagrangeTaps>& wx = plan.weights[static_cast<std::size_t>(phase)];
      const float* first = c + 3 * (plan.offset[static_cast<std::size_t>(phase)] - kLagrangeLeft);
      for (int j = 0; j < n; j += kLanes) {
        std::memcpy(&a, first + j, sizeof a);
        a *= wx[0];
        for (int k = 1; k < kLagrangeTaps; ++k) {
          std::memcpy(&b, first + j + 3 * k, sizeof b);
          a += wx[static_cast<std::size_t>(k)] * b;
        }
        std::memcpy(across.data() + j, &a, sizeof a);
      }
      for (int j = 0; j < w; ++j)
        for (int ch = 0; ch < 3; ++ch) o[3 * (factor * j + phase) + ch] = across[static_cast<std::size_t>(3 * j + ch)];
    }
  }
}

void MagnifyRowsPlain(const EquirectImage& image, const LagrangePlan& plan, long begin, long end, EquirectImage* out) {
  MagnifyRows<float __attribute__((vector_size(16)))>(image, plan, begin, end, out);
}
[[gnu::target("avx2")]] void MagnifyRowsAvx2(const EquirectImage& image, const LagrangePlan& plan, long begin, long end,
                                             EquirectImage* out) {
  MagnifyRows<float __attribute__((vector_size(32)))>(image, plan, begin, end, out);
}

}  // namespace

EquirectImage MagnifyLagrange(const EquirectImage& image, int width, int height, ThreadPool* pool) {
  EquirectImage out;
  MagnifyLagrange(image, width, height, &out, pool);
  return out;
}

void MagnifyLagrange(const EquirectImage& image, int width, int height, EquirectImage* target, ThreadPool* pool) {
  if (target == &image) throw Error("resample", "magnification cannot write over its input");
  if (width < image.width || height < image.height) throw Error("resample", "magnification only enlarges");
  const int factor = width / image.width;
  if (width != factor * image.width || height != factor * image.height || image.width % 2 != 0 ||
      image.width < kLagrangeTaps || image.height < kLagrangeTaps / 2) {
    *target = UpsampleBilinear(image, width, height);
    return;
  }
  if (factor == 1) {
    *target = image;
    return;
  }
  // Output sample f·j + φ lies at input coordinate j + (φ + 0.5)/f − 0.5: its nodes start
  // kLagrangeLeft before j + offset[φ], with weights[φ], along either axis.
  LagrangePlan plan;
  plan.factor = factor;
  for (int phase = 0; phase < factor; ++phase) {
    const double x = (phase + 0.5) / factor - 0.5;
    plan.offset.push_back(static_cast<int>(std::floor(x)));
    plan.weights.push_back(LagrangeWeights(x - std::floor(x)));
  }
  // Every pixel is written below: the storage is reused as it is, not zeroed.
  EquirectImage& out = *target;
  out.Reshape(width, height);
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  const auto rows = [&](long begin, long end) {
    (avx2 ? MagnifyRowsAvx2 : MagnifyRowsPlain)(image, plan, begin, end, &out);
  };
  if (pool)
    pool->ParallelFor(out.height, rows, 8);
  else
    rows(0, out.height);
}

}  // namespace odvr::sphere
