#pragma once
// Synthetic equirect maps for the lighting tests: a sky, a sun disc, spots anywhere.
#include <glm/geometric.hpp>

#include "engine/sphere/equirect.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::testing {

// Sky brighter towards the zenith, darker ground: a smooth, non-constant base.
inline sphere::EquirectImage SkyMap(int w, int h) {
  sphere::EquirectImage img(w, h);
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const auto d = sphere::EquirectPixelDirection(col, row, w, h);
      float* p = img.at(col, row);
      const float up = static_cast<float>(std::max(0.0, d.y));
      p[0] = 0.3f + 0.5f * up;
      p[1] = 0.35f + 0.6f * up;
      p[2] = 0.4f + 0.9f * up;
      if (d.y < 0) p[0] = p[1] = p[2] = 0.15f;
    }
  return img;
}

// Adds a disc of angular radius `radius_rad` and radiance `value` around `axis`.
inline void AddDisc(sphere::EquirectImage* img, glm::dvec3 axis, double radius_rad, float value) {
  axis = glm::normalize(axis);
  const double cos_r = std::cos(radius_rad);
  for (int row = 0; row < img->height; ++row)
    for (int col = 0; col < img->width; ++col)
      if (glm::dot(sphere::EquirectPixelDirection(col, row, img->width, img->height), axis) >= cos_r) {
        float* p = img->at(col, row);
        p[0] = p[1] = p[2] = value;
      }
}

inline double AngleDeg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) * 180.0 / kPi;
}

}  // namespace odvr::testing
