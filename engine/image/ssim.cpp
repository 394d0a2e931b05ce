#include "engine/image/ssim.h"

#include <array>
#include <cmath>
#include <string>

#include "core/error.h"

namespace odvr::image {

double MeanSsim(const std::vector<float>& a, const std::vector<float>& b, int width, int height,
                const std::vector<float>& mask, double dynamic_range) {
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  if (width <= 0 || height <= 0 || a.size() != n || b.size() != n || (!mask.empty() && mask.size() != n))
    throw Error("ssim", "images of " + std::to_string(a.size()) + " and " + std::to_string(b.size()) +
                            " values (mask " + std::to_string(mask.size()) + ") for " + std::to_string(width) + "x" +
                            std::to_string(height));
  if (!(dynamic_range > 0)) throw Error("ssim", "the dynamic range must be positive");
  constexpr int kRadius = 5;
  std::array<double, 2 * kRadius + 1> g{};
  for (int k = -kRadius; k <= kRadius; ++k)
    g[static_cast<std::size_t>(k + kRadius)] = std::exp(-k * k / (2 * 1.5 * 1.5));
  const double c1 = std::pow(0.01 * dynamic_range, 2), c2 = std::pow(0.03 * dynamic_range, 2);
  double sum = 0;
  long count = 0;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * width + x;
      if (!mask.empty() && !(mask[i] > 0.5f)) continue;
      double wsum = 0, ma = 0, mb = 0, aa = 0, bb = 0, ab = 0;
      for (int dy = -kRadius; dy <= kRadius; ++dy) {
        const int yy = y + dy;
        if (yy < 0 || yy >= height) continue;
        for (int dx = -kRadius; dx <= kRadius; ++dx) {
          const int xx = x + dx;
          if (xx < 0 || xx >= width) continue;
          const double w = g[static_cast<std::size_t>(dy + kRadius)] * g[static_cast<std::size_t>(dx + kRadius)];
          const std::size_t j = static_cast<std::size_t>(yy) * width + xx;
          const double va = a[j], vb = b[j];
          wsum += w;
          ma += w * va;
          mb += w * vb;
          aa += w * va * va;
          bb += w * vb * vb;
          ab += w * va * vb;
        }
      }
      ma /= wsum;
      mb /= wsum;
      const double va = std::max(0.0, aa / wsum - ma * ma), vb = std::max(0.0, bb / wsum - mb * mb);
      const double cov = ab / wsum - ma * mb;
      sum += ((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
      ++count;
    }
  if (count == 0) throw Error("ssim", "the mask selects no pixel");
  return sum / static_cast<double>(count);
}

}  // namespace odvr::image
