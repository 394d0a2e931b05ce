#pragma once
// A linear-light float RGB image, rows top first. As an equirectangular frame it follows
// engine/sphere/equirect.h (row 0 at the zenith, the centre column forward).
#include <cstddef>
#include <vector>

namespace odvr::sphere {

struct EquirectImage {
  int width = 0, height = 0;
  std::vector<float> rgb;  // width * height * 3

  EquirectImage() = default;
  EquirectImage(int w, int h, float fill = 0.f)
      : width(w), height(h), rgb(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3, fill) {}

  std::size_t pixel_count() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(height); }
  float* at(int col, int row) { return &rgb[3 * (static_cast<std::size_t>(row) * width + col)]; }
  const float* at(int col, int row) const { return &rgb[3 * (static_cast<std::size_t>(row) * width + col)]; }
  bool empty() const { return width == 0 || height == 0; }
};

// Averages f×f blocks (f must divide both sides): energy-preserving for equirect maps up to the
// per-row solid-angle change inside a block, which is second order.
EquirectImage DownsampleBox(const EquirectImage& image, int factor);
// DownsampleBox's two halves, for a caller that streams the rows itself (the peak detector's
// pass) and must get its result bit for bit: `column` (3·width floats, zero to start) sums a
// block's `factor` rows in order; FoldBoxColumns then sums each block's `factor` columns of it
// in order, scales, and writes the output row. Summing down the columns first lets the per-row
// half vectorize; summing each block pixel by pixel was latency-bound (a 1024-wide frame to 64
// took 1 ms).
void AddBoxRow(const float* row, int width, float* column);
void FoldBoxColumns(const float* column, int width, int factor, float* out_row);

}  // namespace odvr::sphere
