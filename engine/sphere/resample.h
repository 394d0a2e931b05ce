#pragma once
// Resampling equirect images between the working resolutions of the lighting levels.
#include "engine/sphere/equirect_image.h"

namespace odvr::sphere {

// Area-weighted resampling to any smaller size (separable box with fractional coverage):
// preserves the mean of every region, so a sun's energy survives downsampling.
EquirectImage ResampleArea(const EquirectImage& image, int width, int height);

// Bilinear magnification with longitude wrap-around (the seam is continuous) and clamped rows.
EquirectImage UpsampleBilinear(const EquirectImage& image, int width, int height);

}  // namespace odvr::sphere
