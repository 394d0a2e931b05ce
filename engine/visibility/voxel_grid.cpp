#include "engine/visibility/voxel_grid.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <glm/geometric.hpp>
#include <string>

#include "core/error.h"
#include "engine/scene/gltf_scene.h"

namespace odvr::visibility {
namespace {

bool Finite(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Akenine-Möller, "Fast 3D triangle-box overlap testing" (2001), in voxel units: the box is
// centre c, half-size 0.5. Thirteen axes: the three box normals, the triangle's normal and the
// nine cross products of box and triangle edges. Comparisons are strict, so touching counts as
// overlapping (the conservative choice; voxelize.comp makes the same one).
bool TriangleOverlapsVoxel(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& centre) {
  constexpr double h = 0.5;
  const glm::dvec3 v0 = a - centre, v1 = b - centre, v2 = c - centre;
  const glm::dvec3 e[3] = {v1 - v0, v2 - v1, v0 - v2};
  // Edge axes: axis = unit_i × e_j. Projections of the vertices and the box radius on it.
  for (int i = 0; i < 3; ++i) {
    for (const auto& edge : e) {
      glm::dvec3 axis(0);
      axis[(i + 1) % 3] = -edge[(i + 2) % 3];
      axis[(i + 2) % 3] = edge[(i + 1) % 3];
      const double p0 = glm::dot(axis, v0), p1 = glm::dot(axis, v1), p2 = glm::dot(axis, v2);
      const double r = h * (std::abs(axis.x) + std::abs(axis.y) + std::abs(axis.z));
      if (std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r) return false;
    }
  }
  for (int i = 0; i < 3; ++i)
    if (std::min({v0[i], v1[i], v2[i]}) > h || std::max({v0[i], v1[i], v2[i]}) < -h) return false;
  const glm::dvec3 n = glm::cross(e[0], e[1]);
  const double r = h * (std::abs(n.x) + std::abs(n.y) + std::abs(n.z));
  return std::abs(glm::dot(n, v0)) <= r;
}

}  // namespace

VoxelGridSpec VoxelGridSpec::Covering(const glm::dvec3& box_min, const glm::dvec3& box_max, int resolution,
                                      double min_side) {
  VoxelGridSpec s;
  s.resolution = resolution;
  const bool empty = !(box_min.x <= box_max.x && box_min.y <= box_max.y && box_min.z <= box_max.z);
  const glm::dvec3 centre = empty ? glm::dvec3(0) : 0.5 * (box_min + box_max);
  const glm::dvec3 extent = empty ? glm::dvec3(0) : box_max - box_min;
  const double largest = std::max({extent.x, extent.y, extent.z, min_side});
  // One voxel of margin each side: side = largest + 2·side/R.
  const double side = resolution > 2 ? largest * resolution / (resolution - 2.0) : largest;
  s.voxel_size = side / resolution;
  s.origin = centre - glm::dvec3(0.5 * side);
  return s;
}

void VoxelGridSpec::Check() const {
  if (resolution < kMinResolution || resolution > kMaxResolution || !std::has_single_bit(unsigned(resolution)))
    throw Error("voxel resolution", "must be a power of two in [" + std::to_string(kMinResolution) + ", " +
                                        std::to_string(kMaxResolution) + "], got " + std::to_string(resolution));
  if (!(voxel_size > 0) || !std::isfinite(voxel_size))
    throw Error("voxel size", "must be positive and finite, got " + std::to_string(voxel_size));
  if (!Finite(origin)) throw Error("voxel origin", "must be finite");
}

int VoxelGridSpec::levels() const { return std::countr_zero(unsigned(resolution)) + 1; }

void ConeTraceOptions::Check() const {
  if (!(start_offset_voxels >= 0) || !std::isfinite(start_offset_voxels))
    throw Error("cone start_offset_voxels", "must be finite and ≥ 0");
  if (!(step_scale >= 0.05 && step_scale <= 4)) throw Error("cone step_scale", "must be in [0.05, 4]");
  if (!(max_distance >= 0) || !std::isfinite(max_distance)) throw Error("cone max_distance", "must be finite and ≥ 0");
  if (!(opaque_threshold > 0 && opaque_threshold <= 1)) throw Error("cone opaque_threshold", "must be in (0, 1]");
  if (!(partial_opacity_exponent > 0 && partial_opacity_exponent <= 1))
    throw Error("cone partial_opacity_exponent", "must be in (0, 1]");
}

std::vector<glm::vec3> TriangleSoup(const scene::GltfScene& scene) {
  std::vector<glm::vec3> out;
  out.reserve(3 * scene.triangle_count());
  for (const auto& p : scene.primitives)
    for (std::uint32_t i : p.indices) out.push_back(p.positions.at(i));
  return out;
}

VoxelGrid::VoxelGrid(const VoxelGridSpec& spec) : spec_(spec) {
  spec_.Check();
  for (int l = 0; l < spec_.levels(); ++l) {
    const std::size_t r = static_cast<std::size_t>(spec_.resolution >> l);
    levels_.emplace_back(r * r * r, std::uint8_t{0});
    opacity_.emplace_back(3 * r * r * r, std::uint8_t{0});
  }
}

void VoxelGrid::Clear() {
  for (auto& l : levels_) std::fill(l.begin(), l.end(), std::uint8_t{0});
  for (auto& l : opacity_) std::fill(l.begin(), l.end(), std::uint8_t{0});
}

std::size_t VoxelGrid::OccupiedCount() const {
  return static_cast<std::size_t>(std::count_if(levels_[0].begin(), levels_[0].end(), [](auto v) { return v != 0; }));
}

void VoxelGrid::Voxelize(std::span<const glm::vec3> vertices) {
  if (vertices.size() % 3 != 0)
    throw Error("voxelize", std::to_string(vertices.size()) + " vertices is not a whole number of triangles");
  const int res = spec_.resolution;
  auto& grid = levels_[0];
  for (std::size_t t = 0; t < vertices.size(); t += 3) {
    // Voxel units: voxel (x, y, z) is the box [x, x+1]×[y, y+1]×[z, z+1].
    glm::dvec3 q[3];
    for (int k = 0; k < 3; ++k) q[k] = (glm::dvec3(vertices[t + k]) - spec_.origin) / spec_.voxel_size;
    if (!Finite(q[0]) || !Finite(q[1]) || !Finite(q[2])) continue;
    const glm::dvec3 lo = glm::min(q[0], glm::min(q[1], q[2])), hi = glm::max(q[0], glm::max(q[1], q[2]));
    glm::ivec3 first, last;
    bool outside = false;
    for (int i = 0; i < 3; ++i) {
      // ceil(lo) − 1 and floor(hi) include the voxels beyond a face the triangle touches.
      first[i] = static_cast<int>(std::max(0.0, std::ceil(lo[i]) - 1));
      last[i] = static_cast<int>(std::min(res - 1.0, std::floor(hi[i])));
      if (lo[i] > res || hi[i] < 0 || first[i] > last[i]) outside = true;
    }
    if (outside) continue;
    // Dominant-axis walk (as voxelize.comp): columns along w, the axis the normal is closest
    // to; the plane crosses at most ⌈(|n_u|+|n_v|)/|n_w|⌉+1 ≤ 3 voxels of a column, so only
    // those get the full test. A degenerate triangle (n = 0) walks its whole box.
    const glm::dvec3 n = glm::cross(q[1] - q[0], q[2] - q[0]);
    const glm::dvec3 an = glm::abs(n);
    const int w = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
    const int u = (w + 1) % 3, v = (w + 2) % 3;
    const double d = glm::dot(n, q[0]);
    for (int i = first[u]; i <= last[u]; ++i) {
      for (int j = first[v]; j <= last[v]; ++j) {
        int k0 = first[w], k1 = last[w];
        if (an[w] > 0) {
          const double wc = (d - n[u] * (i + 0.5) - n[v] * (j + 0.5)) / n[w];
          const double half = 0.5 * (an[u] + an[v]) / an[w] + 1e-3;  // slack: the SAT decides
          k0 = std::max(k0, static_cast<int>(std::ceil(wc - half)) - 1);
          k1 = std::min(k1, static_cast<int>(std::floor(wc + half)));
        }
        for (int k = k0; k <= k1; ++k) {
          glm::ivec3 c;
          c[u] = i;
          c[v] = j;
          c[w] = k;
          const std::size_t index = static_cast<std::size_t>(c.x) +
                                    static_cast<std::size_t>(res) * (c.y + static_cast<std::size_t>(res) * c.z);
          if (grid[index]) continue;
          if (TriangleOverlapsVoxel(q[0], q[1], q[2], glm::dvec3(c) + 0.5)) grid[index] = 255;
        }
      }
    }
  }
}

void VoxelGrid::BuildMips() {
  {
    const auto& occ = levels_[0];
    auto& op = opacity_[0];
    for (std::size_t i = 0; i < occ.size(); ++i) op[3 * i] = op[3 * i + 1] = op[3 * i + 2] = occ[i];
  }
  for (int l = 1; l < levels(); ++l) {
    const std::size_t r = static_cast<std::size_t>(LevelResolution(l)), rp = 2 * r;
    const auto& src = levels_[static_cast<std::size_t>(l - 1)];
    const auto& src_op = opacity_[static_cast<std::size_t>(l - 1)];
    auto& dst = levels_[static_cast<std::size_t>(l)];
    auto& dst_op = opacity_[static_cast<std::size_t>(l)];
    auto child = [&](std::size_t x, std::size_t y, std::size_t z, std::size_t c) {
      return (2 * x + (c & 1)) + rp * ((2 * y + ((c >> 1) & 1)) + rp * (2 * z + (c >> 2)));
    };
    for (std::size_t z = 0; z < r; ++z)
      for (std::size_t y = 0; y < r; ++y)
        for (std::size_t x = 0; x < r; ++x) {
          unsigned sum = 0;
          for (std::size_t c = 0; c < 8; ++c) sum += src[child(x, y, z, c)];
          const std::size_t i = x + r * (y + r * z);
          dst[i] = static_cast<std::uint8_t>((sum + 4) / 8);
          // Along axis k the children c and c | bit(k) (bit k of c clear) lie on the same lines.
          for (unsigned k = 0; k < 3; ++k) {
            const unsigned bit = 1u << k;
            unsigned pairs = 0;
            for (unsigned c = 0; c < 8; ++c)
              if (!(c & bit))
                pairs += std::max(src_op[3 * child(x, y, z, c) + k], src_op[3 * child(x, y, z, c | bit) + k]);
            dst_op[3 * i + k] = static_cast<std::uint8_t>((pairs + 2) / 4);
          }
        }
  }
}

double VoxelGrid::Texel(int level, int x, int y, int z) const {
  const int r = LevelResolution(level);
  if (x < 0 || y < 0 || z < 0 || x >= r || y >= r || z >= r) return 0;
  const std::size_t ur = static_cast<std::size_t>(r);
  return levels_[static_cast<std::size_t>(level)][static_cast<std::size_t>(x) + ur * (y + ur * z)] / 255.0;
}

template <class TexelFn>
double VoxelGrid::Trilinear(const glm::dvec3& p, int level, TexelFn&& texel) const {
  // GL: texel coordinate u·size − 0.5, u the normalized position in the cube.
  const glm::dvec3 g = (p - spec_.origin) / (spec_.voxel_size * (1 << level)) - 0.5;
  const glm::dvec3 b = glm::floor(g), t = g - b;
  const glm::ivec3 i(b);
  const int r = LevelResolution(level);
  double s = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = c >> 2;
    const double wgt = (dx ? t.x : 1 - t.x) * (dy ? t.y : 1 - t.y) * (dz ? t.z : 1 - t.z);
    const int x = i.x + dx, y = i.y + dy, z = i.z + dz;
    if (wgt > 0 && x >= 0 && y >= 0 && z >= 0 && x < r && y < r && z < r) s += wgt * texel(level, x, y, z);
  }
  return s;
}

double VoxelGrid::Sample(const glm::dvec3& p, double lod) const {
  lod = std::clamp(lod, 0.0, levels() - 1.0);
  const int l0 = static_cast<int>(std::floor(lod));
  const int l1 = std::min(l0 + 1, levels() - 1);
  const double f = lod - l0;
  auto texel = [&](int level, int x, int y, int z) { return Texel(level, x, y, z); };
  const double s0 = Trilinear(p, l0, texel);
  return f > 0 && l1 != l0 ? s0 + f * (Trilinear(p, l1, texel) - s0) : s0;
}

glm::dvec3 VoxelGrid::SampleOpacity(const glm::dvec3& p, double lod) const {
  lod = std::clamp(lod, 0.0, levels() - 1.0);
  const int l0 = static_cast<int>(std::floor(lod));
  const int l1 = std::min(l0 + 1, levels() - 1);
  const double f = lod - l0;
  glm::dvec3 out;
  for (int k = 0; k < 3; ++k) {
    auto texel = [&](int level, int x, int y, int z) {
      const std::size_t r = static_cast<std::size_t>(LevelResolution(level));
      return opacity_[static_cast<std::size_t>(level)][3 * (x + r * (y + r * z)) + static_cast<std::size_t>(k)] / 255.0;
    };
    const double s0 = Trilinear(p, l0, texel);
    out[k] = f > 0 && l1 != l0 ? s0 + f * (Trilinear(p, l1, texel) - s0) : s0;
  }
  return out;
}

double VoxelGrid::TraceCone(const ConeQuery& query, const ConeTraceOptions& options) const {
  options.Check();
  const glm::dvec3 o(query.origin);
  glm::dvec3 dir(query.direction);
  const double alpha = query.half_angle;
  if (!Finite(o) || !Finite(dir) || !(glm::length(dir) > 0))
    throw Error("cone query", "origin and direction must be finite, the direction non-zero");
  if (!(alpha >= 0 && alpha <= kMaxConeHalfAngle))
    throw Error("cone half_angle",
                "must be in [0, " + std::to_string(kMaxConeHalfAngle) + "] rad, got " + std::to_string(alpha));
  dir = glm::normalize(dir);
  const double s0 = spec_.voxel_size;
  // Where the ray is inside the cube (slab test); the cone's footprint is sampled only there.
  double t_enter = 0, t_exit = 1e300;
  for (int i = 0; i < 3; ++i) {
    const double lo = spec_.origin[i], hi = lo + spec_.side();
    if (dir[i] == 0) {
      if (o[i] < lo || o[i] > hi) return 1;
      continue;
    }
    double a = (lo - o[i]) / dir[i], b = (hi - o[i]) / dir[i];
    if (a > b) std::swap(a, b);
    t_enter = std::max(t_enter, a);
    t_exit = std::min(t_exit, b);
  }
  // Samples sit on texel centres of their level along the dominant axis m of the direction,
  // one texel apart: a sheet across m is then read at full strength once instead of being
  // smeared by the trilinear filter over the neighbouring samples (with a smeared 1-voxel sheet
  // the product of the samples' transmittances never falls below e^-2, a leak). Across m
  // the filter still averages the footprint. Crossing one texel along m crosses |d_k| / |d_m|
  // texels along axis k, so the transmittance of a sample is Π_k (1 − α_k)^(κ |d_k| / |d_m|),
  // κ = partial_opacity_exponent.
  const int m = std::abs(dir.x) >= std::abs(dir.y) && std::abs(dir.x) >= std::abs(dir.z)
                    ? 0
                    : (std::abs(dir.y) >= std::abs(dir.z) ? 1 : 2);
  glm::dvec3 exponent;
  for (int k = 0; k < 3; ++k) exponent[k] = options.partial_opacity_exponent * std::abs(dir[k]) / std::abs(dir[m]);
  const double sign_m = dir[m] > 0 ? 1 : -1;
  const double ratio = 2 * std::tan(alpha);  // diameter per unit distance
  const double t_end = options.max_distance > 0 ? std::min(t_exit, options.max_distance) : t_exit;
  double t = std::max(options.start_offset_voxels * s0, t_enter);
  double occlusion = 0;
  while (occlusion < options.opaque_threshold) {
    const double diameter = std::max(ratio * t, s0);
    int level =
        std::clamp(static_cast<int>(std::floor(std::log2(options.step_scale * diameter / s0) + 0.5)), 0, levels() - 1);
    double ts = 0;
    for (;; --level) {
      const double voxel = s0 * (1 << level);
      // The next texel centre along m, at most a third of a texel behind t. t is a texel face
      // of the previous sample's level, so g is a multiple of 1/2 or 1/4 and would sit on a
      // rounding boundary if rounded at an integer; 1/3 keeps single and double precision
      // (GPU and CPU) on the same centre.
      const double g = (o[m] + t * dir[m] - spec_.origin[m]) / voxel - 0.5;
      const double c = dir[m] > 0 ? std::ceil(g - 1.0 / 3) : std::floor(g + 1.0 / 3);
      ts = (spec_.origin[m] + (c + 0.5) * voxel - o[m]) / dir[m];
      // A texel whose near face is not a voxel past the origin holds the origin's own surface
      // and would occlude the cone with it: take a finer level there.
      const double near_face = (spec_.origin[m] + (c + 0.5 - 0.5 * sign_m) * voxel - o[m]) * sign_m;
      if (level == 0 || near_face >= s0) break;
    }
    if (!(ts < t_end)) break;
    const glm::dvec3 axis_opacity = SampleOpacity(o + ts * dir, level);
    double transmit = 1;
    for (int k = 0; k < 3; ++k)
      if (exponent[k] > 0 && axis_opacity[k] > 0)
        transmit *= axis_opacity[k] >= 1 ? 0 : std::pow(1 - axis_opacity[k], exponent[k]);
    occlusion += (1 - occlusion) * (1 - transmit);
    t = ts + 0.5 * s0 * (1 << level) / std::abs(dir[m]);
  }
  return std::clamp(1 - occlusion, 0.0, 1.0);
}

}  // namespace odvr::visibility
