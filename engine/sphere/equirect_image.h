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
  // Makes this a w × h image whose every pixel the caller writes next: the storage is reused as
  // it is, neither given back nor zeroed (images kept across frames by the lighting passes).
  void Reshape(int w, int h) {
    width = w;
    height = h;
    rgb.resize(pixel_count() * 3);
  }
};

// The mean of each f×f block over the sphere (f must divide both sides): each row weighted by its
// solid angle, so Σ value·dA over every block, and over the sphere, is kept exactly, for signed
// images too. The plain mean weighs a block's rows alike: near a pole, where a row's solid angle
// grows from nothing, that moved a bright zenith's energy (bridge.exr's overcast sky, 1024 wide to
// the 128-wide grid of level 2: the diffuse error of 3 levels 0.0186, least squares on that grid
// 0.0187; weighted, 0.0040 and 0.0029).
EquirectImage DownsampleBox(const EquirectImage& image, int factor);
// Each row's weight in its block of `factor` rows of an equirect image `height` rows high: its
// solid angle over the block's (the weights of a block sum to 1). Kept per thread.
const std::vector<float>& BoxRowWeights(int height, int factor);
// DownsampleBox's two halves, for a caller that streams the rows itself (the peak detector's
// pass) and must get its result bit for bit: `column` (3·width floats, zero to start) sums a
// block's `factor` rows in order, each times its BoxRowWeights weight; FoldBoxColumns then sums
// each block's `factor` columns of it in order, divides by `factor` and writes the output row.
// Summing down the columns first lets the per-row half vectorize; summing each block pixel by
// pixel was latency-bound.
void AddBoxRow(const float* row, int width, float weight, float* column);
void FoldBoxColumns(const float* column, int width, int factor, float* out_row);

}  // namespace odvr::sphere
