#pragma once
// Scene visibility as an occupancy volume (seed §4.3.1–4.3.2, DESIGN.md §5): the CPU reference
// of the GPU voxelizer and cone tracer (voxelizer_gpu.h). Both sides share every convention
// below, so a test can hold them to each other.
//
// Conventions:
// - The grid is a cube of resolution³ voxels (resolution a power of two), world-space
//   `origin` at its minimum corner, cubic voxels of side `voxel_size`. Voxel (x, y, z) covers
//   origin + voxel_size·[x, x+1]×[y, y+1]×[z, z+1]; index = x + R·(y + R·z).
// - Level 0 is binary (255 = some triangle overlaps the closed voxel box, touching included, so
//   a triangle on a voxel face marks both sides: conservative). Level l+1 is the mean of the
//   2×2×2 children of level l. Every level is stored as 8-bit unorm (0…255), like the GPU's
//   texture, the mean rounded to nearest: q = (Σ children + 4) / 8.
// - Beside the mean occupancy every voxel holds its opacity along each axis (the anisotropic
//   voxels of Crassin et al. 2011): the fraction of the lines parallel to that axis through it
//   that hit an occupied level-0 voxel. Level 0: the occupancy. Level l+1 along x: each of the
//   four pairs of children adjacent along x gives the larger of its two opacities, and the four
//   are averaged: q = (Σ max + 2) / 4. Why: only surfaces are voxelized, so a sheet one voxel
//   thick has mean occupancy 2^−l at level l although it stops every line across it; its
//   opacity across stays 1 at every level, along it 2^−l. Why the max and not a + b − ab: the
//   lines that two neighbours along an axis block are mostly the same ones (one surface
//   running on), and compositing them as independent would make a sheet seen edge-on denser
//   at every level.
//   The GPU keeps (occupancy, opacity x, y, z) in one rgba8 texel.
// - Sampling is GL's: trilinear between voxel centres within a level, linear between levels,
//   zero outside the cube (GL_CLAMP_TO_BORDER with a zero border).
#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

namespace odvr::scene {
struct GltfScene;
}

namespace odvr::visibility {

struct VoxelGridSpec {
  glm::dvec3 origin{0, 0, 0};  // world-space minimum corner
  double voxel_size = 1;       // metres, level 0
  int resolution = 64;         // voxels per side, a power of two in [kMinResolution, kMaxResolution]

  static constexpr int kMinResolution = 8;
  static constexpr int kMaxResolution = 512;

  // The cube around an axis-aligned box: centred on it, side the box's largest extent plus one
  // voxel of margin on each side, so that surfaces on the box's faces and points just off
  // them stay inside. An empty or flat box gets a side of at least `min_side`.
  static VoxelGridSpec Covering(const glm::dvec3& box_min, const glm::dvec3& box_max, int resolution,
                                double min_side = 1e-3);

  // Throws odvr::Error naming the field when the spec is unusable.
  void Check() const;
  int levels() const;  // log2(resolution) + 1: the last level is one voxel
  double side() const { return voxel_size * resolution; }
};

// Every triangle of a scene as three consecutive world-space vertices (the voxelizer's input).
std::vector<glm::vec3> TriangleSoup(const scene::GltfScene& scene);

// One query of the cone tracer: unit direction, half-angle in [0, kMaxConeHalfAngle].
struct ConeQuery {
  glm::vec3 origin{0, 0, 0};
  glm::vec3 direction{0, 0, 1};
  float half_angle = 0.1f;  // radians
};

// Wider cones than this are not traced (the footprint, 2 t tan α, would explode); a broad lobe
// is split into narrower cones by cones.h first.
inline constexpr double kMaxConeHalfAngle = 1.3;  // ≈ 74.5°

struct ConeTraceOptions {
  // The first sample is this many level-0 voxels from the origin: the origin's own surface
  // marks its voxel and the conservative neighbour, and the trilinear filter spreads them by one
  // more, so a cone starting inside that band sees itself — most of all a grazing one, which
  // stays near its own surface for several voxels. Against the Cycles references every car and
  // shadow error falls as the offset grows to 4, for both shaders, so the contact shadows it skips
  // are not missed there.
  double start_offset_voxels = 4.0;
  // The voxel of a sample's mip level as a fraction of the cone's diameter there (rounded to a
  // level); samples are one such voxel apart along the direction's dominant axis. At 0.5 the
  // trilinear footprint, a voxel around the sample, is about the cone's own.
  double step_scale = 0.5;
  // Transmittance of one voxel of opacity α is (1 − α)^κ. A fully opaque voxel stops the cone
  // whatever κ; κ < 1 lets a partly covered voxel block less than its coverage, because successive
  // samples along a cone see the same occluder (the bottom, side and top of a wall cover the same
  // rays) while compositing treats them as independent, and because the conservative voxelization
  // marks every voxel a surface touches, so partial coverage overstates the surface's. With a
  // wall's edge across the 7 cones of an SG lobe (cones_test) 0.5 is nearer the ray-cast truth than
  // 1; against the Cycles references 0.3 beat 0.5 on the cars and the shadows, and lower values
  // made the shadows worse again.
  double partial_opacity_exponent = 0.3;
  // Tracing stops here (metres from the origin); 0 = where the ray leaves the grid.
  double max_distance = 0;
  // Accumulated occlusion at which the cone counts as blocked and tracing stops early.
  double opaque_threshold = 0.99;
  void Check() const;
};

class VoxelGrid {
 public:
  explicit VoxelGrid(const VoxelGridSpec& spec);  // empty; throws odvr::Error on a bad spec

  // Marks every level-0 voxel that a triangle overlaps (Akenine-Möller's separating-axis test);
  // adds to what is there. Parts of triangles outside the cube are ignored. Then call BuildMips.
  // `vertices` holds three per triangle; a trailing partial triangle throws odvr::Error.
  void Voxelize(std::span<const glm::vec3> vertices);
  void Clear();
  void BuildMips();

  const VoxelGridSpec& spec() const { return spec_; }
  int levels() const { return static_cast<int>(levels_.size()); }
  int LevelResolution(int level) const { return spec_.resolution >> level; }
  const std::vector<std::uint8_t>& Level(int level) const { return levels_[static_cast<std::size_t>(level)]; }
  // Opacity along x, y, z per voxel, interleaved (3 per voxel, same voxel order as Level).
  const std::vector<std::uint8_t>& Opacity(int level) const { return opacity_[static_cast<std::size_t>(level)]; }
  std::size_t OccupiedCount() const;  // level-0 voxels marked

  // Mean occupancy in [0, 1] at world point p, level-of-detail `lod` (continuous; clamped to
  // [0, levels−1]), filtered as GL's LINEAR_MIPMAP_LINEAR with a zero border.
  double Sample(const glm::dvec3& p, double lod) const;
  // Opacity in [0, 1] along x, y and z at p, filtered as Sample.
  glm::dvec3 SampleOpacity(const glm::dvec3& p, double lod) const;

  // Visibility in [0, 1] along a cone: front-to-back α-compositing of the directional opacity
  // sampled at the mip level whose voxel matches the cone's footprint (seed §4.3.2). Throws odvr::Error for
  // a non-finite query or a half-angle outside [0, kMaxConeHalfAngle].
  double TraceCone(const ConeQuery& query, const ConeTraceOptions& options = {}) const;

 private:
  double Texel(int level, int x, int y, int z) const;  // zero outside
  // Trilinear at one level of `texel(level, x, y, z)`.
  template <class TexelFn>
  double Trilinear(const glm::dvec3& p, int level, TexelFn&& texel) const;
  VoxelGridSpec spec_;
  std::vector<std::vector<std::uint8_t>> levels_;
  std::vector<std::vector<std::uint8_t>> opacity_;
};

}  // namespace odvr::visibility
