#pragma once
// Resampling equirect images between the working resolutions of the lighting levels.
#include "engine/sphere/equirect_image.h"

namespace odvr {
class ThreadPool;
}

namespace odvr::sphere {

// Area-weighted resampling to any smaller size (separable box with fractional coverage):
// preserves the mean of every region, so a sun's energy survives downsampling.
EquirectImage ResampleArea(const EquirectImage& image, int width, int height);

// The same box, each source row weighted by its solid angle: for integer factors Σ value·dA over
// the sphere, and over every output pixel's footprint, is preserved exactly, for signed images
// too (a row split between two outputs is shared by its coverage). The plain box averages a
// footprint's rows alike, which shifts the integral of an image whose rows near a pole differ (a
// residue of both signs around a sun: by 3.6 % of bridge's mean radiance from 512 to 64 wide).
// lighting_resample.comp's SOLID_ANGLE variant does the same.
EquirectImage ResampleSolidAngle(const EquirectImage& image, int width, int height, ThreadPool* pool = nullptr);
// The same into `target`, whose width and height say the size, its storage reused.
void ResampleSolidAngle(const EquirectImage& image, EquirectImage* target, ThreadPool* pool = nullptr);

// Bilinear magnification with longitude wrap-around (the seam is continuous) and clamped rows.
EquirectImage UpsampleBilinear(const EquirectImage& image, int width, int height);

// Magnification to width × height, interpolating through the six nearest samples along each axis
// (Lagrange, degree 5): longitude wraps around the seam, and the rows beyond a pole are those next
// to it half a turn away. A Gaussian of σ = 4.3 input pixels (the finest in the lighting
// transform's magnified reconstructions) comes out within 2.5e-5 of its peak, where the bilinear
// magnification is 9e-3 off (2.7e-2 at a pole). Where the size is not an integer multiple of the
// image's, or the image is narrower than 6 pixels, of odd width or under 3 rows, it is
// UpsampleBilinear's (lighting_upsample.comp makes the same choice).
EquirectImage MagnifyLagrange(const EquirectImage& image, int width, int height, ThreadPool* pool = nullptr);

}  // namespace odvr::sphere
