#pragma once
// Exact rays against the scene's triangles: a bounding-volume hierarchy that the shaders traverse
// (shaders/triangle_bvh.glsl) where a cone through the voxels is too coarse — the peaks' shadow
// rays and the specular bounce's ray (render_shade.comp), and the Monte-Carlo baseline's shadow
// rays (render_mc.comp), which tell how much of the error against Cycles the voxels cost.
//
// Layout, shared with the shader: node i is two vec4s, (box min, a) and (box max, count) with a
// and count stored as int bits (glm::intBitsToFloat). count > 0: a leaf holding triangles
// [a, a + count) of triangles(); count = 0: an interior node whose children are a and a + 1.
// triangles() holds three vec4 vertices (w = 1) per triangle, reordered so leaves are contiguous;
// source_triangles() maps them back to the input's order.
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <span>
#include <vector>

namespace odvr::visibility {

class TriangleBvh {
 public:
  // `vertices`: three per triangle (world space); a trailing partial triangle throws odvr::Error.
  // Non-finite triangles are dropped.
  explicit TriangleBvh(std::span<const glm::vec3> vertices);

  // Whether the ray o + t d, t in (t_min, t_max), hits a triangle (either side). d need not be
  // unit length; t is in its units.
  bool Occluded(const glm::vec3& o, const glm::vec3& d, float t_min, float t_max) const;

  // The nearest triangle the ray o + t d, t in (t_min, t_max), hits (either side): its index in
  // triangles() order, t, and the barycentrics (u, v) of vertices 1 and 2.
  struct Hit {
    int triangle = -1;
    float t = 0, u = 0, v = 0;
  };
  bool ClosestHit(const glm::vec3& o, const glm::vec3& d, float t_min, float t_max, Hit* hit) const;

  const std::vector<glm::vec4>& nodes() const { return nodes_; }          // 2 per node
  const std::vector<glm::vec4>& triangles() const { return triangles_; }  // 3 per triangle
  std::size_t triangle_count() const { return triangles_.size() / 3; }
  // Per triangle of triangles(): its index in the constructor's `vertices` (non-finite ones dropped).
  const std::vector<int>& source_triangles() const { return source_; }

  static constexpr int kLeafSize = 4;
  static constexpr int kMaxDepth = 48;  // the shader's traversal stack holds this many

 private:
  // Occluded (any_hit: the first hit found) and ClosestHit (the nearest) share this traversal.
  bool Trace(const glm::vec3& o, const glm::vec3& d, float t_min, float t_max, bool any_hit, Hit* hit) const;

  std::vector<glm::vec4> nodes_, triangles_;
  std::vector<int> source_;
};

}  // namespace odvr::visibility
