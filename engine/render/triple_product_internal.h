#pragma once
// Internals shared by TripleProductRenderer's passes (engine/render/passes/) and its CPU
// reference (triple_product_reference.cpp). Not part of the engine's API.
#include <algorithm>
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <glm/vec2.hpp>
#include <memory>
#include <numbers>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/lighting/overlap_bins.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/visibility/triangle_bvh.h"
#include "engine/visibility/voxel_grid.h"

namespace odvr::render {
class GpuModel;
}  // namespace odvr::render

namespace odvr::render::detail {

// Where an exact ray against the triangles starts: this many level-0 voxels off the surface along
// its normal, past the surface's own triangles (the Monte-Carlo shader's shadow rays, the peaks'
// with RenderOptions::exact_peak_shadows, the bounce's march). In voxels, not metres, so that a
// model renders alike at any scale: a fixed length that clears a car's own triangles spans a
// crease on a toy-sized model and lets the crease see past its occluders.
inline constexpr double kExactRayOffsetVoxels = 1.0 / 32;
inline float ExactRayOffset(double voxel_size) { return static_cast<float>(kExactRayOffsetVoxels * voxel_size); }

// RenderOptions::exact_peak_shadows: a peak wider than kPeakRingMinHalfAngle (its half-value
// angle; 1°: the maps' suns are 0.4–0.6°, the studio's key light 2°) is sampled by its axis and
// six rays around it at kPeakRingScale half-value angles, their visibilities averaged: the
// ring's second moment, (6/7) r², is the SG's 2/λ at r ≈ 1.3 half-value angles, so a lamp casts
// a penumbra as wide as its own. A narrower peak is one ray. PeakRayDirections gives the rays
// (render_shade.comp's tracePeakCones builds the same).
inline constexpr double kPeakRingMinHalfAngle = std::numbers::pi / 180;
inline constexpr double kPeakRingScale = 1.3;
std::vector<glm::dvec3> PeakRayDirections(const glm::dvec3& axis, double lambda);

// The invocations (per lane) of the first shading pass of a width×height render, as Render
// dispatches it: the 2×2 blocks at shading rate 2, the pixels' centre samples when supersampling
// adaptively, every sample otherwise. What RenderOptions::shade_lanes 0 picks its lanes by.
long long FirstShadingPassPixels(const RenderOptions& options, int width, int height);

// The render's counts summed over its shaded samples (RenderCounts before the means).
struct CountSums {
  long long car = 0, ground = 0, pixels_sampled_fully = 0;
  long long lobes = 0, cones = 0, sgs = 0, triples = 0;  // over car samples
  long long cones_total = 0, triples_total = 0;          // over every sample
};

constexpr int kCountTotals = 15;  // render_counts.comp's per-group totals

// The lighting as the shading stage reads it: SRBFs by global index (lighting/overlap_bins.h),
// amplitude 0 where the model kept none, axes already rotated into the world.
// Half-value angle of an SG (π when it never falls to 1/2), as render_shade.comp computes it.
double HalfValueAngle(double lambda);

struct PreparedLighting {
  glm::vec3 constant{0};
  std::vector<lighting::RgbSg> srbfs;
  std::vector<lighting::RgbSg> peaks;  // brightest first; the first kMaxPeakCones get cones
  glm::dmat3 env_from_world{1.0};
  int sg_count = 0;
  // The ground's irradiance shares of the peaks that get cones (RenderOptions::
  // ground_shadows_bounce): ΣE over the channels, the rest lights the ground through one cone up.
  std::vector<double> ground_peak_share;
  // The lighting's cosine-weighted mean radiance below the horizon: the ground's unshadowed
  // bounce, of which the car's shadow takes its share (RenderOptions::ground_shadows_bounce).
  // Apart: the part of the peaks that get cones, which are shadowed by their own cones alone.
  glm::vec3 ground_radiance{0};
  glm::vec3 ground_radiance_traced_peaks{0};
  // The lighting's mean radiance over the whole sphere, (1/4π) ∫ L: a surface of any orientation,
  // unshadowed, receives π times it on average (RenderOptions::ambient_bounce).
  glm::vec3 mean_radiance{0};
  glm::vec3 GroundRadiance(bool peak_cones) const {
    return glm::max(ground_radiance + (peak_cones ? glm::vec3(0) : ground_radiance_traced_peaks), glm::vec3(0));
  }
};

// RenderOptions::specular_bounce: the surface a specular lobe sees is lit by the constant, the
// peaks and the SRBFs of this many levels (0–1: 60 SGs over the whole sphere, where the bins give
// a pixel's own lobes hundreds).
inline constexpr int kBounceLevels = 2;
// Bounce sums are kept per material term (render_shade.comp's kBounceTerms).
inline constexpr int kBounceTerms = TripleProductRenderer::kTermsPerMaterial;
inline int BounceSrbfCount(const PreparedLighting& l) {
  return std::min(lighting::GlobalSrbfIndex(kBounceLevels, 0), static_cast<int>(l.srbfs.size()));
}

// The ground's lit fraction at q (y = 0) for the bounce the car sees there: the up cone for the
// broad light and each traced peak's visibility, weighted by their shares of the ground's
// irradiance. `trace(origin, axis, half_angle)` is the cone tracer; `peak(q, k, half_angle)` peak
// k's visibility from q (its cone, or its rays with RenderOptions::exact_peak_shadows).
template <class Trace, class Peak>
double GroundLitFraction(const glm::dvec3& q, const PreparedLighting& l, bool peak_cones, double up_half_angle,
                         double max_half_angle, const Trace& trace, const Peak& peak) {
  double rest = 1.0, lit = 0.0;
  for (std::size_t k = 0; peak_cones && k < l.ground_peak_share.size(); ++k) {
    const double share = l.ground_peak_share[k];
    if (share <= 0) continue;
    lit += share * peak(q, k, std::min(HalfValueAngle(l.peaks[k].lambda), max_half_angle));
    rest -= share;
  }
  return lit + std::max(rest, 0.0) * trace(q, glm::dvec3(0, 1, 0), up_half_angle);
}
// The same with every peak's own cone.
template <class Trace>
double GroundLitFraction(const glm::dvec3& q, const PreparedLighting& l, bool peak_cones, double up_half_angle,
                         double max_half_angle, const Trace& trace) {
  return GroundLitFraction(q, l, peak_cones, up_half_angle, max_half_angle, trace,
                           [&](const glm::dvec3& o, std::size_t k, double a) { return trace(o, l.peaks[k].axis, a); });
}

// RenderOptions::ground_lit_map_texels: GroundLitFraction on a grid over the ground, read
// bilinearly between texel centres. A trace sees the voxels only where its axis enters the voxel
// cube, so the fraction is exactly 1 outside the cube's footprint (the up cone) and outside the
// cube's shadow along each traced peak's axis: the grid covers the rectangle around those, within
// the catcher, with one texel beyond it on each side (1 there, so the reads fade to 1 at its edge).
struct GroundLitMapLayout {
  glm::dvec2 origin{0};       // xz of texel (0, 0)'s centre
  double spacing = 0;         // metres between texel centres: the voxel size, or more for a long shadow
  int width = 0, height = 0;  // texels along x and z; 0: no grid, every point lit
  std::size_t texels() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(height); }
};
GroundLitMapLayout GroundLitMapLayoutFor(const visibility::VoxelGridSpec& spec, const PreparedLighting& l,
                                         bool peak_cones, const glm::dvec2& ground_centre, double ground_half_size,
                                         int max_texels);
// Bilinear between the texels' centres (texel (i, j) at texels[j · width + i]); 1 outside the grid.
double SampleGroundLitMap(const GroundLitMapLayout& layout, const std::vector<float>& texels, double x, double z);

// Per material: the BRDF terms of an override; or, for a glTF material, the metallic-roughness
// that the G-buffer holds (from_gbuffer) followed by `terms` (its sheen, when it has one).
struct MaterialTermList {
  bool from_gbuffer = false;
  std::vector<material::Brdf> terms;
};
using MaterialTerms = std::vector<MaterialTermList>;

// One frame's G-buffer, read back: RGBA float per pixel, top row first (render_gbuffer.frag).
struct GBuffer {
  int width = 0, height = 0;
  std::vector<float> position;  // xyz, material index + 1 (0: empty)
  std::vector<float> normal;    // xyz, roughness
  std::vector<float> base;      // rgb, metallic
  std::vector<float> emission;  // rgb: the radiance the surface emits, 0 (render_gbuffer.frag's outEmission)
};

// Per-pixel counters, as render_shade.comp writes them: lobes, cones, triple products, SGs.
struct PixelCounts {
  unsigned lobes = 0, cones = 0, triples = 0, sgs = 0;
};

struct ReferenceInputs {
  const GBuffer* gbuffer = nullptr;
  PinholeCamera camera;
  const MaterialTerms* materials = nullptr;
  const PreparedLighting* lighting = nullptr;
  const lighting::OverlapBins* bins = nullptr;
  const visibility::VoxelGrid* grid = nullptr;   // nullptr: nothing occludes
  const visibility::TriangleBvh* bvh = nullptr;  // RenderOptions::exact_peak_shadows: the peaks' rays
  const GpuModel* model = nullptr;               // with bvh: what its hits are shaded with (bvh_shading)
  RenderOptions options;
  glm::dvec2 ground_centre{0, 0};  // xz
  // Filled by ShadeReference (RenderOptions::ground_lit_map_texels): the ground's lit fraction at
  // each texel of its grid, as render_shade.comp's pass uGroundTablePass == 2 writes it.
  GroundLitMapLayout ground_lit_map;
  std::vector<float> ground_lit_texels;
};

// The shading stage on the CPU (multithreaded): fills result->car, car_alpha, shadow,
// ground_mask and `counts` (one per pixel).
void ShadeReference(const ReferenceInputs& in, RenderResult* result, std::vector<PixelCounts>* counts);

// RenderOptions::supersample: output pixel X gathers the shaded samples x = kX + j,
// j ∈ [−k, 2k), with weight W[j + k]·W[i + k] (rows alike); W is the Blackman-Harris window over
// offsets (x + ½)/k − (X + ½) in (−1.5, 1.5) output pixels, 0 outside it — Cycles' default pixel
// filter: its filter_width 1.5 is the window's half-width, Cycles doubling a Blackman-Harris
// width before tabulating it (film.cpp's filter_table). render_resolve.comp reads the same table.
std::vector<float> SupersampleWeights(int k);

// The resolve on the CPU, as render_resolve.comp does it: `shaded` holds car, car_alpha, shadow
// and ground_mask at k× `width` × `height`; `out` gets them at the output size. The car's
// radiance is averaged over its coverage (alpha-weighted), the shadow ratio over the samples the
// car leaves uncovered, so the composite blends at the car's edge as at k× and resolved.
// With `flags` (RenderOptions::supersample_contrast), a pixel whose flag is 0 had only its sample
// nearest the centre, (k/2, k/2), shaded: it stands for every sample of that pixel.
void ResolveSupersampled(const RenderResult& shaded, int k, int width, int height, RenderResult* out,
                         const std::vector<std::uint8_t>* flags = nullptr);

// The shading normals' cosine beyond which a pixel's samples see different surfaces.
inline constexpr float kSupersampleNormalCos = 0.9f;

// render_flag.comp on the CPU: 1 for each output pixel whose k×k samples of `g` differ in
// coverage or material or turn their normal past kSupersampleNormalCos, or where the centre
// samples' car luminance in `shaded` bends across it along a row, column or diagonal by more than
// `contrast` of the largest of the three, or their shadow ratio by more than `contrast`.
// neighbour_reps (RenderOptions::shading_rate 2, k = 2 over 2×2 blocks): also where the left,
// upper or upper-left block's centre sample sees another surface, and on the top and left edges.
std::vector<std::uint8_t> FlagPixels(const GBuffer& g, const RenderResult& shaded, int k, int width, int height,
                                     float contrast, bool neighbour_reps = false);

// render_fill.comp on the CPU (RenderOptions::shading_rate 2): in each block whose flag is 0 the
// pixels other than its lower right are overwritten by the mean of the shaded pixels around them.
void FillHalfRate(const std::vector<std::uint8_t>& block_flags, RenderResult* r);

// RenderOptions::shading_rate 2: 1 for each pixel that was shaded (the lower right of every 2×2
// block, every pixel of a flagged block), 0 for the filled ones.
std::vector<std::uint8_t> HalfRateShaded(const std::vector<std::uint8_t>& block_flags, int w, int h);

}  // namespace odvr::render::detail
