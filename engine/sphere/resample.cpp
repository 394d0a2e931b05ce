#include "engine/sphere/resample.h"

#include <algorithm>
#include <cmath>

#include "engine/core/error.h"

namespace odvr::sphere {
namespace {

// Box filter along one axis: out[i] averages in[x] over [i·s, (i+1)·s), s = n_in / n_out.
void ResampleLine(const float* in, int n_in, int stride_in, float* out, int n_out, int stride_out) {
  const double s = static_cast<double>(n_in) / n_out;
  for (int i = 0; i < n_out; ++i) {
    const double x0 = i * s, x1 = (i + 1) * s;
    double acc[3] = {0, 0, 0};
    for (int x = static_cast<int>(std::floor(x0)); x < static_cast<int>(std::ceil(x1)) && x < n_in; ++x) {
      const double w = std::min<double>(x + 1, x1) - std::max<double>(x, x0);
      const float* p = in + static_cast<std::ptrdiff_t>(x) * stride_in;
      acc[0] += w * p[0];
      acc[1] += w * p[1];
      acc[2] += w * p[2];
    }
    float* o = out + static_cast<std::ptrdiff_t>(i) * stride_out;
    for (int k = 0; k < 3; ++k) o[k] = static_cast<float>(acc[k] / s);
  }
}

}  // namespace

EquirectImage ResampleArea(const EquirectImage& image, int width, int height) {
  if (width <= 0 || height <= 0) throw Error("resample", "target size must be positive");
  if (width == image.width && height == image.height) return image;
  if (width > image.width || height > image.height) throw Error("resample", "area resampling only shrinks");
  if (image.width % width == 0 && image.height % height == 0 && image.width / width == image.height / height)
    return DownsampleBox(image, image.width / width);
  EquirectImage horizontal(width, image.height);
  for (int row = 0; row < image.height; ++row)
    ResampleLine(image.at(0, row), image.width, 3, horizontal.at(0, row), width, 3);
  EquirectImage out(width, height);
  for (int col = 0; col < width; ++col)
    ResampleLine(horizontal.at(col, 0), image.height, 3 * width, out.at(col, 0), height, 3 * width);
  return out;
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

}  // namespace odvr::sphere
