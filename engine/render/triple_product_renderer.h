#pragma once
// The renderer of seed §4.5 (DESIGN.md §5): a glTF model shaded by the spherical-Gaussian triple
// product of lighting × BRDF lobes × cone-traced visibility, casting a shadow on a ground plane
// that acts as a shadow catcher, composited over a background.
//
// Stages per frame: voxelize the model (visibility), rasterize a G-buffer (position, shading
// normal, base colour, metallic, roughness, coverage), shade (a compute pass, or the CPU
// reference on the same G-buffer), composite.
//
// The estimator (per pixel; every SG of unit amplitude, μ folded into the weights):
//   L_o = Σ_k w_k ⊙ [ Σ_j μ_j ∫G_k G_j · s_kj  +  Σ_p μ_p ∫G_k G_p · v_p ]
// - k runs over the BRDF lobes (material/brdf.h: f·cos ≈ Σ w_k G_k), j over the lighting SGs
//   the overlap bins list for lobe k (lighting/overlap_bins.h) plus the constant term, p over
//   the peaks, each traced as one extra cone of its own half-value angle (v_p its visibility).
// - s_kj is the visible share of the product P_kj = G_k G_j over the lobe's cones
//   (visibility/cones.h: one cone for a sharp lobe, hexagonal rings for a broad one), each cone
//   i an SG V_i of eq. 4.12 with traced visibility v_i:
//     s_kj = Σ_i v_i ∫P_kj V_i / Σ_i ∫P_kj V_i.
//   The seed's sum Σ_i v_i ∫G_k G_j V_i is this without the denominator; the cones' SGs do not
//   sum to one over the lobe (they overlap and leave gaps), so without it an unoccluded pixel
//   would not reproduce the unshadowed integral. With it, all v_i = 1 gives exactly
//   μ_j ∫G_k G_j, and a light SG sharper than the cones takes the visibility of the cone(s) it
//   falls in, so a small light casts a directional shadow through a broad lobe.
// - GGX's tail SG (material::Lobe::tail_share, the broad part of D) is the one exception: j
//   stops at the deepest level whose detail it shows at its share of the pixel
//   (OverlapBins::MaxLevel(λ, share)), and s_kj is the lobe's own share s_k (P_kj = G_k). Lit
//   like the other lobes it made the glossy paints' shading much slower for no accuracy this
//   rule loses.
// - Ground (y = 0, Lambertian, within ground_half_size of the model's centre): the same sums
//   for the clamped-cosine lobe around +Y, shadowed over unshadowed, per channel: the shadow
//   ratio. Its lobe, cones and lighting weights are the same at every ground pixel, so the sums
//   collapse to one per cone, computed once per render (render_shade.comp's ground table): a
//   ground pixel costs its cones, not cones × SGs. The model is voxelized alone, so the ground
//   never shadows itself, and the car's cones do not see the ground: light from below the
//   horizon comes from the environment's lower half (the real road in a street panorama), which
//   stands in for the ground's bounce, darkened where the car shadows the ground
//   (ground_shadows_bounce).
// - Composite = background × shadow ratio, then the car layer (alpha = coverage) over it.
//
// Conventions: world frame +Y up, metres (DESIGN.md §3); the camera is OpenCV's (x right,
// y down, z forward), square pixels, principal point at the image centre; every layer is
// stored top row first. Lighting SG axes are in the lighting's own frame (an equirect frame's,
// engine/sphere/equirect.h) and `world_from_lighting` rotates them into the world; the overlap
// bins are queried in the lighting frame.
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <string>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/lighting/sg_lighting.h"
#include "engine/material/brdf.h"
#include "engine/render/pinhole_camera.h"
#include "engine/sphere/equirect_image.h"
#include "engine/visibility/cones.h"
#include "engine/visibility/voxel_grid.h"

namespace odvr::scene {
struct GltfScene;
}

namespace odvr::render {

// Replaces the glTF materials whose name contains `material` (case-insensitive; empty: every
// material) by the sum of `brdfs` (one or two terms). The whole material: a replaced one emits
// nothing (the others keep their glTF emission).
struct MaterialOverride {
  std::string material;
  std::vector<material::Brdf> brdfs;
};

// RenderOptions::supersample's bound (render_resolve.comp's weight table holds 3 × this).
inline constexpr int kMaxSupersample = 4;
// A still's samples per pixel along each axis (`odvr render`, `odvr bench render --set`): a pixel
// integrates what it covers, as a camera's does, so every pixel whose samples disagree
// (RenderOptions::supersample_contrast) is shaded 3×3 and resolved with Cycles' filter: with the
// filter reaching into the neighbours, 3×3 measures better than 2×2 for half again the shading
// (decision 42). The players keep RenderOptions' 1 and shade at their own rate.
inline constexpr int kStillSupersample = 3;

// 45°: the cap holding half of a cosine-weighted hemisphere's irradiance (sin² 45° = 1/2).
inline constexpr double kGroundLitHalfAngle = 0.78539816339744831;

struct RenderOptions {
  int lighting_levels = 5;     // HEALPix levels 0..N−1 of the lighting that are used (1..6)
  int cone_rings = 1;          // per broad lobe: 0 → 1 cone, 1 → 7, 2 → 19, 3 → 37
  int voxel_resolution = 128;  // 64..512, a power of two
  bool peak_cones = true;      // each peak its own visibility cone (sharp sun shadows)
  // Each peak's visibility from rays against the triangles (a BVH, visibility/triangle_bvh.h)
  // instead of its cone through the voxels. A peak's cone starts a few voxels out
  // (ConeTraceOptions::start_offset_voxels) and sees occluders fattened by the conservative
  // voxelization, so it lets a sun through a recess whose lip is nearer than its first sample and
  // shades the edge of a shadow too wide; a ray does neither, and a sun's disc is narrow enough for
  // one (a peak wider than 1°, a lamp, takes seven: detail::PeakRayDirections). The ground's lit
  // fraction under the car (ground_shadows_bounce) takes the same rays from the ground, so the
  // shadow the car sees in its bounce is the one drawn on the catcher. On by default: against the
  // Cycles references it lowers the car's and the shadow's error on most scenes for little shading
  // time under a sun. Off: each peak's cone, as the seed.
  bool exact_peak_shadows = true;
  // The G-buffer's shading normal tilted toward the face's own, where the view mirrored about it
  // would leave below the face, just enough that it leaves at a grazing height
  // (render_gbuffer.frag), as Cycles bends the normal of every closure. At a car's outline smooth
  // normals turn away from the camera faster than its triangles do: the view mirrored about them
  // dives into the car, and the diffuse paints' retro-reflection and the glossy paints' Fresnel
  // both read off there. On by default: it lowers the car's error against the Cycles references on
  // all but one scene. Off: the interpolated normal as it is.
  bool valid_reflection_normals = true;
  // One bounce of the car's specular light on itself: where a term's specular lobes are occluded
  // (their cones meet the car; a GGX tail's as much as its peak's), a ray along their
  // occlusion-weighted mean direction finds the car
  // surface they see, which is shaded for the view back along it — its specular lobes only, under
  // the peaks (each shadowed from there as the pixel's own), the constant and the lighting's
  // levels 0–1 — and seen through the occluded part of the lobes. With exact_peak_shadows the ray
  // is cast against the triangles (their BVH): a hit the camera sees takes the G-buffer's material
  // there (its textures), one it does not (a recess's inner wall, a wheel arch's far side) its
  // triangle's interpolated normal and its material's factors times their textures' means.
  // Without it the G-buffer is marched instead, and what the camera does not see reflects
  // nothing. Cycles with one bounce is within its noise of the references, and without the car's
  // light on itself the glossy paints read dark; the diffuse bounce gives back little of it, so the
  // hit's diffuse lobe is left out.
  bool specular_bounce = true;
  // The car's diffuse light on itself, every bounce: where a clamped-cosine (diffuse) lobe's cones
  // meet the car, the occluded part of the lobe sees car surfaces, not black. They are taken to
  // be like the shaded point: its diffuse albedo a, its visible share v of the sky, under the
  // lighting's mean radiance L̄ (π L̄ is the mean irradiance over all orientations). Their
  // radiance L_o then solves L_o = a (v L̄ + (1 − v) L_o): L_o = a v L̄ / (1 − a (1 − v)), so a
  // white car in a uniform sky (a white furnace) reads L̄ in its recesses too, as it must.
  // A convex car loses nothing to itself and gains nothing; a concave one's wheel arches, sills,
  // grilles and bumpers, which Cycles' diffuse bounces light, read dark without it.
  bool ambient_bounce = true;
  double bounce_step_voxels = 1.0;       // the march's step, in level-0 voxels
  int bounce_steps = 64;                 // and its length in steps
  double bounce_thickness_voxels = 1.5;  // a sample this far behind the G-buffer's surface hits it
  bool ground = true;                    // the shadow catcher
  double ground_half_size = 30;          // metres around the model's centre (Cycles' 60 m catcher)
  // Light from below the horizon stands for the ground's bounce (see above); the car's shadow
  // darkens that bounce. Per lobe, the cones whose axes meet the ground within the catcher take off
  // the ground's radiance (the lighting's cosine-weighted mean below the horizon) times their
  // visibility and the ground's shadowed fraction there: one cone straight up of
  // kGroundLitHalfAngle for the broad light, each traced peak's own cone (its rays with
  // exact_peak_shadows) for its share (detail::GroundLitFraction). Not by scaling every lighting
  // SG's share in those cones: wherever the SGs carry the lighting across the horizon, that takes
  // the sky's light too. On because Cycles' catcher is shadowed where the car sees it: with the
  // unshadowed stand-in the glossy studio scene lands far off its reference.
  bool ground_shadows_bounce = true;
  // That lit fraction read bilinearly from a grid of at most this many texels along each side
  // (detail::GroundLitMapLayoutFor), traced once per render at each texel, instead of traced from
  // every point where a car cone meets the ground (0). The per-point traces are a visible share of
  // the shading time; the grid saves most of it and leaves the error against Cycles where it was.
  int ground_lit_map_texels = 128;
  std::vector<MaterialOverride> materials;
  visibility::ConeSubsampleOptions cones;  // `rings` is taken from cone_rings
  visibility::ConeTraceOptions trace;
  double overlap_min_retention = 1.0 / 13;  // overlap bins' depth rule
  // The overlap bins' overlap rule (lighting::OverlapBinOptions::cutoff, whose 1e-3 reproduces the
  // seed's Table 4.2): an SRBF lights a lobe where their product's integral is at least this
  // fraction of its value with the axes aligned. 1e-2 drops many SGs per car pixel, and shading
  // time with them, while leaving the error against Cycles where it was.
  double overlap_cutoff = 1e-2;
  // Each lobe lit only by the lighting levels the depth rule gives its own λ
  // (lighting::OverlapBins::MaxLevel), not by every level of its bin's list, which goes as deep as
  // the sharpest lobe the bin serves: a broad lobe would otherwise sum many SGs too fine to show in
  // it.
  bool depth_per_lobe = true;
  // Car cones start this many level-0 voxels off the surface along its normal (beside
  // trace.start_offset_voxels along the cone): a conservative voxelization marks the surface's own
  // voxels and their neighbours, and a wide cone near the horizon would otherwise see them. 2 is
  // the smallest offset at which a Lambertian sphere under a constant sky keeps nearly all its
  // light.
  double surface_offset_voxels = 2.0;
  // How BRDFs become lobes; the GPU pass and the CPU reference implement every mode. The default,
  // chosen by `odvr bench render`: the anisotropic split with the
  // cosine at each lobe's axis, which against Cycles takes the glossy paints' error down the most
  // for a moderate cost in shade time. The cosine as an SG is worse: M at a broad lobe's axis
  // carries 1/cos θ_i uncancelled, which the rough paints show.
  material::LobeOptions lobes{material::CosineTerm::kAtLobeAxis, material::WarpMode::kAnisotropicSplit};
  // > 0: the shading stage is instead the brute-force Monte-Carlo baseline (render_mc.comp, GPU
  // only, needs SetEnvironment): this many samples per pixel of the environment map itself,
  // importance-sampled by its luminance, the cosine and the GGX NDF (one-sample MIS), each with a
  // shadow ray marched through the same voxel volume. The lighting model is then unused.
  int monte_carlo_samples = 0;
  unsigned monte_carlo_seed = 1;
  // The Monte-Carlo baseline's shadow rays against the triangles themselves (a BVH,
  // visibility/triangle_bvh.h) instead of through the voxels; the ground's lit fraction stays the
  // voxel cones'. For attribution: the same estimator with both tells what the voxels cost.
  bool monte_carlo_exact_visibility = false;
  // Shaded samples per output pixel along each axis (1..4): the G-buffer and the shading run at k×
  // the camera's size and each layer is resolved to it with Cycles' default pixel filter
  // (Blackman-Harris reaching ±1.5 px: the neighbours' samples weigh in, as Cycles' do), so panel
  // edges, spokes and highlights narrower than a pixel are averaged over it instead of
  // point-sampled. Against the Cycles references k = 2 helps the glossy paints most and the
  // diffuse ones a little.
  int supersample = 1;
  // With supersample > 1, each pixel's other samples are shaded only where it needs them
  // (render_flag.comp): where its samples see different surfaces (coverage, material, a normal
  // turning past 25°) or where the car's luminance at the samples nearest the pixels' centres bends
  // across it (|Y₋ + Y₊ − 2Y₀| along a row, column or diagonal) by more than this fraction of the
  // largest (the shadow ratio: by more than this); elsewhere that one sample stands for the pixel.
  // 0: every sample of every pixel. The default keeps every reference's error at the every-sample
  // one's for much less shading; the Monte-Carlo baseline
  // always shades every sample.
  double supersample_contrast = 0.05;
  // 1 shades every pixel. 2 shades one pixel of each 2×2 block (its lower right), then every pixel
  // of the blocks that need it — by render_flag.comp's tests at supersample_contrast, and where a
  // neighbouring block's shaded pixel, which the fill reads, sees another surface — and fills the
  // other blocks' pixels midway between shaded ones (render_fill.comp): a smooth body costs a
  // quarter, and the error against Cycles stays where it was.
  // Only without supersampling and the Monte-Carlo baseline; a block an odd width or height cuts is
  // shaded whole. RenderCounts' per-car-pixel means then count a filled pixel's work as 0.
  int shading_rate = 1;
  // What a GPU render reads back. true: every layer (car, shadow, background, composite) and the
  // counts per shaded sample, summed on the CPU. false: the composite alone and the counts summed
  // on the GPU (render_counts.comp); RenderResult's other layers stay empty. A player shows only
  // the composite: the other layers and the per-sample counts are 5× its bytes to bring over a
  // GPU's bus every frame (RenderTimings::readback says what it cost).
  bool read_layers = true;
  // With read_layers off: false leaves the composite on the GPU too (composite_texture()), for a
  // window that draws it from there; RenderResult::composite stays empty.
  bool read_composite = true;
  // GPU shading: invocations per pixel (1, 2 or 4), each shading every L-th of the pixel's lobes,
  // summed in shared memory (render_shade.comp). The same picture within float rounding; more lanes
  // shorten a pixel's serial chain and add the lanes' repeated set-up and registers, so they pay
  // only where the GPU would otherwise sit idle. 0 (the default): each render picks
  // (ShadeLanesFor), from the size of its first shading pass and the device.
  int shade_lanes = 0;
  void Check() const;  // throws odvr::Error naming the field
};

enum class ShadeDevice { kGpu, kCpu };

// Per shaded sample: with RenderOptions::supersample k, k² of them per output pixel.
// RenderOptions::shade_lanes 0: 4 lanes where a render's first shading pass covers at most
// kAutoShadeLanesMaxPixels pixels (blocks at shading rate 2) on a GPU, where one invocation per
// pixel leaves most of it idle and a pixel's serial chain sets the time; 1 on larger passes (the
// GPU full) and on a CPU rasterizer, whose threads are full at any size. The bound lies between
// pass sizes measured to favour either.
inline constexpr long long kAutoShadeLanesMaxPixels = 1 << 16;
int ShadeLanesFor(long long first_pass_pixels, bool software_renderer);

struct RenderCounts {
  int lighting_sgs = 0;  // SGs of the model used (constant, kept SRBFs, peaks)
  int peaks = 0;         // peak SGs (each one extra cone when peak_cones)
  int car_pixels = 0;
  int ground_pixels = 0;  // ground pixels where the car occludes something
  double lobes_per_car_pixel = 0;
  double cones_per_car_pixel = 0;    // traced, lobe cones and peak cones
  double sgs_per_car_pixel = 0;      // lighting SGs touched, summed over the lobes
  double triples_per_car_pixel = 0;  // lobe × cone × SG integrals evaluated (0 where unoccluded)
  int pixels_sampled_fully = 0;      // supersample > 1: pixels whose every sample was shaded;
                                     // shading_rate 2: pixels shaded (the rest were filled)
  int shade_lanes = 0;               // GPU shading: invocations per pixel it ran with (0 on the CPU)
  long long cones_total = 0;         // over every pixel, ground included
  long long triples_total = 0;       // a ground pixel counts its cones' weighted sum (the ground table)
};

struct RenderTimings {  // milliseconds, measured after glFinish
  double voxelize = 0, gbuffer = 0, shade = 0, composite = 0, total = 0;
  double readback = 0;  // GPU shading: the results to the CPU (RenderOptions::read_layers says which)
  // GPU shading: the same stages by the GPU's own clock (GL timestamps around each), which leaves
  // out what the driver and the waits add; -1 on the CPU path.
  double gpu_voxelize = -1, gpu_gbuffer = -1, gpu_shade = -1, gpu_composite = -1;
};

struct RenderResult {
  sphere::EquirectImage car;         // linear radiance where covered, 0 elsewhere
  std::vector<float> car_alpha;      // coverage, width × height
  sphere::EquirectImage shadow;      // per-channel ratio, 1 where there is no shadow
  std::vector<float> ground_mask;    // 1 on ground-plane pixels
  sphere::EquirectImage background;  // what the car is composited over
  sphere::EquirectImage composite;
  // supersample > 1: 1 where every sample of the pixel was shaded (RenderOptions::
  // supersample_contrast), width × height; shading_rate 2: 1 where the pixel was shaded, 0 where
  // it was filled; empty otherwise.
  std::vector<std::uint8_t> sampled_fully;
  RenderCounts counts;
  RenderTimings ms;
};

class TripleProductRenderer {
 public:
  // The brightest peaks get a cone each (render_shade.comp's kMaxPeaks); fainter ones are
  // shadowed through the lobes' cones like every other SG.
  static constexpr int kMaxPeakCones = 8;
  static constexpr int kTermsPerMaterial = 2;

  // `model` placed by `world_from_model` (a rigid or scaled transform; the ground is y = 0 of the
  // world). Needs a current OpenGL 4.5 context; uploads the meshes and textures. Throws
  // odvr::Error for bad options or an override the renderer cannot shade (anisotropic Ward).
  TripleProductRenderer(const scene::GltfScene& model, const glm::dmat4& world_from_model, RenderOptions options);
  ~TripleProductRenderer();
  TripleProductRenderer(const TripleProductRenderer&) = delete;
  TripleProductRenderer& operator=(const TripleProductRenderer&) = delete;

  // The lighting (levels beyond options.lighting_levels are ignored).
  void SetLighting(const lighting::SgLighting& lighting, const glm::dmat3& world_from_lighting = glm::dmat3(1.0));
  // The background: an equirect frame in the lighting's frame (rotated by world_from_lighting),
  // or an image of exactly the output size.
  void SetEnvironment(const sphere::EquirectImage& equirect);
  void SetBackgroundImage(const sphere::EquirectImage& image);
  // The background only (the Monte-Carlo baseline's environment stays): an equirect frame seen
  // through the camera on the GPU, turned into the world by SetBackgroundRotation (until then, or
  // after a SetEnvironment, by the lighting's rotation).
  void SetBackgroundEquirect(const sphere::EquirectImage& equirect);
  void SetBackgroundRotation(const glm::dmat3& world_from_background);

  // draw_model false: the background alone, through the same composite (a player hiding the car).
  RenderResult Render(const PinholeCamera& camera, ShadeDevice device = ShadeDevice::kGpu, bool draw_model = true);
  // The shading lanes a GPU render of `camera`'s size runs with (RenderOptions::shade_lanes), and
  // their program compiled now, so that a timed render does not compile it.
  int PrepareShading(const PinholeCamera& camera);

  // Between frames (the player's panel): the material overrides, as options.materials, and
  // whether peaks get their own cones. Throws odvr::Error for an override it cannot shade.
  void SetMaterials(std::vector<MaterialOverride> overrides);
  void SetPeakCones(bool on) { options_.peak_cones = on; }

  const RenderOptions& options() const { return options_; }
  // The model's triangles in the world (three vertices each), and the grid that holds them.
  const std::vector<glm::vec3>& world_triangles() const;
  const visibility::VoxelGridSpec& voxel_spec() const;
  int peaks_without_cone() const;  // beyond kMaxPeakCones
  // The last GPU render's composite: RGBA32F at the output size, linear RGB, rows top first (row
  // 0 of the texture is the picture's top row); empty before the first render.
  const gl::Texture& composite_texture() const;

 private:
  struct Impl;
  RenderOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace odvr::render
