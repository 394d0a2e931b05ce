#pragma once
// Resampling equirect images between the working resolutions of the lighting levels.
#include "engine/sphere/equirect_image.h"

namespace odvr {
class ThreadPool;
}

namespace odvr::sphere {

// Resampling to any smaller size by the mean over each output pixel's footprint on the sphere: a
// separable box with fractional coverage, each source row weighted by its coverage times its
// solid angle. Σ value·dA over the sphere, and over every footprint, is kept (exactly for integer
// factors, where it is DownsampleBox bit for bit), for signed images too, so a sun's energy
// survives, and so does the integral of a residue of both signs (the coarse correction's).
// lighting_resample.comp does the same on the GPU.
EquirectImage ResampleArea(const EquirectImage& image, int width, int height, ThreadPool* pool = nullptr);
// The same into `target`, whose width and height say the size, its storage reused.
void ResampleArea(const EquirectImage& image, EquirectImage* target, ThreadPool* pool = nullptr);

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
// The same into `target` (not `image`), reusing its storage: the lighting transform magnifies into
// images it keeps across frames.
void MagnifyLagrange(const EquirectImage& image, int width, int height, EquirectImage* target,
                     ThreadPool* pool = nullptr);

}  // namespace odvr::sphere
