#include "engine/sphere/equirect_image.h"

#include <algorithm>
#include <map>
#include <string>
#include <utility>

#include "core/error.h"
#include "core/float4.h"
#include "engine/sphere/equirect.h"

namespace odvr::sphere {

const std::vector<float>& BoxRowWeights(int height, int factor) {
  if (factor < 1 || height % factor)
    throw Error("downsample",
                "factor " + std::to_string(factor) + " does not divide " + std::to_string(height) + " rows");
  // Every frame asks for the same few: made once per thread (2 000 rows' cosines were 0.1 ms of
  // the peak detector's pass at 2048 wide).
  thread_local std::map<std::pair<int, int>, std::vector<float>> made;
  std::vector<float>& weights = made[{height, factor}];
  if (!weights.empty()) return weights;
  weights.resize(static_cast<std::size_t>(height));
  for (int first = 0; first < height; first += factor) {
    double block = 0;
    for (int row = first; row < first + factor; ++row) block += EquirectPixelSolidAngle(row, 1, height);
    for (int row = first; row < first + factor; ++row)
      weights[static_cast<std::size_t>(row)] = static_cast<float>(EquirectPixelSolidAngle(row, 1, height) / block);
  }
  return weights;
}

void AddBoxRow(const float* __restrict row, int width, float weight, float* __restrict column) {
  // Fixed-length inner loops without aliasing: what GCC's -O2 cost model vectorizes.
  const int n = 3 * width;
  int i = 0;
  for (; i + 16 <= n; i += 16)
    for (int j = 0; j < 16; ++j) column[i + j] += weight * row[i + j];
  for (; i < n; ++i) column[i] += weight * row[i];
}

void FoldBoxColumns(const float* column, int width, int factor, float* out_row) {
  const float scale = 1.0f / static_cast<float>(factor);
  // Four floats from each of the block's pixels: lanes 0-2 sum its RGB in the scalar loop's
  // order (from 0, dx ascending), lane 3 (the next pixel's red) is overwritten by the next
  // store. Scalar, the fold of a 2048-wide frame to 512 was 3 % of the 5-level transform. The
  // last pixel stays scalar: its loads and store would reach one float past the row.
  const int n = width / factor;
  const simd::V4 scale4 = {scale, scale, scale, scale};
  for (int col = 0; col + 1 < n; ++col) {
    simd::V4 acc = {0.f, 0.f, 0.f, 0.f};
    for (int dx = 0; dx < factor; ++dx) acc += simd::Load4(column + 3 * (col * factor + dx));
    simd::Store4(out_row + 3 * col, acc * scale4);
  }
  for (int col = std::max(0, n - 1); col < n; ++col)
    for (int k = 0; k < 3; ++k) {
      float acc = 0.f;
      for (int dx = 0; dx < factor; ++dx) acc += column[3 * (col * factor + dx) + k];
      out_row[3 * col + k] = acc * scale;
    }
}

EquirectImage DownsampleBox(const EquirectImage& image, int factor) {
  if (factor <= 1) return image;
  if (image.width % factor || image.height % factor)
    throw Error("downsample", "factor " + std::to_string(factor) + " does not divide " + std::to_string(image.width) +
                                  "x" + std::to_string(image.height));
  EquirectImage out(image.width / factor, image.height / factor);
  const std::vector<float>& weights = BoxRowWeights(image.height, factor);
  std::vector<float> column(3 * static_cast<std::size_t>(image.width));
  for (int row = 0; row < out.height; ++row) {
    std::fill(column.begin(), column.end(), 0.f);
    for (int dy = 0; dy < factor; ++dy)
      AddBoxRow(image.at(0, row * factor + dy), image.width, weights[static_cast<std::size_t>(row * factor + dy)],
                column.data());
    FoldBoxColumns(column.data(), image.width, factor, out.at(0, row));
  }
  return out;
}

}  // namespace odvr::sphere
