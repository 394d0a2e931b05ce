#include "engine/sphere/equirect_image.h"

#include "engine/core/error.h"

namespace odvr::sphere {

EquirectImage DownsampleBox(const EquirectImage& image, int factor) {
  if (factor <= 1) return image;
  if (image.width % factor || image.height % factor)
    throw Error("downsample", "factor " + std::to_string(factor) + " does not divide " + std::to_string(image.width) +
                                  "x" + std::to_string(image.height));
  EquirectImage out(image.width / factor, image.height / factor);
  const float scale = 1.0f / static_cast<float>(factor * factor);
  for (int row = 0; row < out.height; ++row) {
    float* dst_row = out.at(0, row);
    for (int dy = 0; dy < factor; ++dy) {
      const float* src = image.at(0, row * factor + dy);
      for (int col = 0; col < out.width; ++col) {
        float* d = dst_row + 3 * col;
        for (int dx = 0; dx < factor; ++dx, src += 3) {
          d[0] += src[0];
          d[1] += src[1];
          d[2] += src[2];
        }
      }
    }
    for (int i = 0; i < out.width * 3; ++i) dst_row[i] *= scale;
  }
  return out;
}

}  // namespace odvr::sphere
