#include "engine/visibility/triangle_bvh.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <numeric>
#include <string>

#include "core/error.h"

namespace odvr::visibility {
namespace {

struct Box {
  glm::vec3 lo{1e30f}, hi{-1e30f};
  void Extend(const glm::vec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
};

float AsFloat(int v) {
  float f;
  std::memcpy(&f, &v, sizeof f);
  return f;
}
int AsInt(float f) {
  int v;
  std::memcpy(&v, &f, sizeof v);
  return v;
}

// Möller–Trumbore, both sides; the shader's test is the same. On a hit, *t_out, *u_out, *v_out.
bool HitsTriangle(const glm::vec3& o, const glm::vec3& d, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c,
                  float t_min, float t_max, float* t_out, float* u_out, float* v_out) {
  const glm::vec3 e1 = b - a, e2 = c - a, p = glm::cross(d, e2);
  const float det = glm::dot(e1, p);
  if (det == 0.f) return false;
  const float inv = 1.f / det;
  const glm::vec3 s = o - a;
  const float u = glm::dot(s, p) * inv;
  if (u < 0.f || u > 1.f) return false;
  const glm::vec3 q = glm::cross(s, e1);
  const float v = glm::dot(d, q) * inv;
  if (v < 0.f || u + v > 1.f) return false;
  const float t = glm::dot(e2, q) * inv;
  if (!(t > t_min && t < t_max)) return false;
  *t_out = t;
  *u_out = u;
  *v_out = v;
  return true;
}

bool HitsBox(const glm::vec3& o, const glm::vec3& inv_d, const glm::vec3& lo, const glm::vec3& hi, float t_min,
             float t_max) {
  const glm::vec3 a = (lo - o) * inv_d, b = (hi - o) * inv_d;
  const glm::vec3 near = glm::min(a, b), far = glm::max(a, b);
  const float t0 = std::max({near.x, near.y, near.z, t_min}), t1 = std::min({far.x, far.y, far.z, t_max});
  return t0 <= t1;
}

}  // namespace

TriangleBvh::TriangleBvh(std::span<const glm::vec3> vertices) {
  if (vertices.size() % 3 != 0)
    throw Error("triangle bvh", std::to_string(vertices.size()) + " vertices is not a whole number of triangles");
  std::vector<std::size_t> tris;
  std::vector<glm::vec3> centroid(vertices.size() / 3);
  for (std::size_t t = 0; t < vertices.size() / 3; ++t) {
    bool finite = true;
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i) finite = finite && std::isfinite(vertices[3 * t + k][i]);
    if (!finite) continue;
    tris.push_back(t);
    centroid[t] = (vertices[3 * t] + vertices[3 * t + 1] + vertices[3 * t + 2]) / 3.f;
  }
  struct Task {
    std::size_t node, begin, end;
    int depth;
  };
  nodes_.resize(2);
  std::vector<Task> stack{{0, 0, tris.size(), 0}};
  while (!stack.empty()) {
    const Task task = stack.back();
    stack.pop_back();
    Box box, cbox;
    for (std::size_t i = task.begin; i < task.end; ++i) {
      for (int k = 0; k < 3; ++k) box.Extend(vertices[3 * tris[i] + k]);
      cbox.Extend(centroid[tris[i]]);
    }
    const std::size_t count = task.end - task.begin;
    const glm::vec3 ext = cbox.hi - cbox.lo;
    const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    // A leaf when small, at the stack's depth, or when the centroids coincide (no split helps).
    if (count <= static_cast<std::size_t>(kLeafSize) || task.depth + 1 >= kMaxDepth || !(ext[axis] > 0)) {
      const int first = static_cast<int>(triangles_.size() / 3);
      for (std::size_t i = task.begin; i < task.end; ++i) {
        for (int k = 0; k < 3; ++k) triangles_.emplace_back(vertices[3 * tris[i] + k], 1.f);
        source_.push_back(static_cast<int>(tris[i]));
      }
      nodes_[2 * task.node] = glm::vec4(box.lo, AsFloat(first));
      nodes_[2 * task.node + 1] = glm::vec4(box.hi, AsFloat(static_cast<int>(count)));
      continue;
    }
    const std::size_t mid = task.begin + count / 2;
    std::nth_element(tris.begin() + static_cast<long>(task.begin), tris.begin() + static_cast<long>(mid),
                     tris.begin() + static_cast<long>(task.end),
                     [&](std::size_t a, std::size_t b) { return centroid[a][axis] < centroid[b][axis]; });
    const std::size_t left = nodes_.size() / 2;
    nodes_.resize(nodes_.size() + 4);
    nodes_[2 * task.node] = glm::vec4(box.lo, AsFloat(static_cast<int>(left)));
    nodes_[2 * task.node + 1] = glm::vec4(box.hi, AsFloat(0));
    stack.push_back({left, task.begin, mid, task.depth + 1});
    stack.push_back({left + 1, mid, task.end, task.depth + 1});
  }
}

bool TriangleBvh::Occluded(const glm::vec3& o, const glm::vec3& d, float t_min, float t_max) const {
  Hit hit;
  return Trace(o, d, t_min, t_max, true, &hit);
}

bool TriangleBvh::ClosestHit(const glm::vec3& o, const glm::vec3& d, float t_min, float t_max, Hit* hit) const {
  return Trace(o, d, t_min, t_max, false, hit);
}

bool TriangleBvh::Trace(const glm::vec3& o, const glm::vec3& d, float t_min, float t_max, bool any_hit,
                        Hit* hit) const {
  *hit = Hit{};
  if (triangles_.empty()) return false;
  const glm::vec3 inv(1.f / d.x, 1.f / d.y, 1.f / d.z);
  int stack[kMaxDepth + 1];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const int node = stack[--top];
    const glm::vec4 lo = nodes_[2 * static_cast<std::size_t>(node)],
                    hi = nodes_[2 * static_cast<std::size_t>(node) + 1];
    // t_max shrinks to the nearest hit so far: farther boxes are skipped.
    if (!HitsBox(o, inv, glm::vec3(lo), glm::vec3(hi), t_min, t_max)) continue;
    const int a = AsInt(lo.w), count = AsInt(hi.w);
    if (count == 0) {
      stack[top++] = a;
      stack[top++] = a + 1;
      continue;
    }
    for (int t = a; t < a + count; ++t) {
      const std::size_t i = 3 * static_cast<std::size_t>(t);
      float th = 0, u = 0, v = 0;
      if (HitsTriangle(o, d, glm::vec3(triangles_[i]), glm::vec3(triangles_[i + 1]), glm::vec3(triangles_[i + 2]),
                       t_min, t_max, &th, &u, &v)) {
        *hit = Hit{t, th, u, v};
        if (any_hit) return true;
        t_max = th;
      }
    }
  }
  return hit->triangle >= 0;
}

}  // namespace odvr::visibility
