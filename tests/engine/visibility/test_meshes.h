#pragma once
// Small triangle soups (three vertices per triangle) for the voxelizer and cone tests.
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <numbers>
#include <vector>

namespace odvr::testing {

// The six faces of the box [lo, hi], two triangles each, outward CCW.
inline std::vector<glm::vec3> BoxMesh(const glm::vec3& lo, const glm::vec3& hi) {
  const glm::vec3 p[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                          {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  const int quads[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 4, 7, 3}, {1, 2, 6, 5}};
  std::vector<glm::vec3> out;
  for (const auto& q : quads) {
    for (int k : {q[0], q[1], q[2], q[0], q[2], q[3]}) out.push_back(p[k]);
  }
  return out;
}

// A UV sphere: `stacks` × `slices`, vertices on the sphere (the mesh lies inside it).
inline std::vector<glm::vec3> SphereMesh(const glm::vec3& centre, float radius, int stacks, int slices) {
  auto at = [&](int i, int j) {
    const double th = std::numbers::pi * i / stacks, ph = 2 * std::numbers::pi * j / slices;
    return centre + radius * glm::vec3(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
  };
  std::vector<glm::vec3> out;
  for (int i = 0; i < stacks; ++i)
    for (int j = 0; j < slices; ++j) {
      const glm::vec3 a = at(i, j), b = at(i + 1, j), c = at(i + 1, j + 1), d = at(i, j + 1);
      if (i != 0) out.insert(out.end(), {a, d, c});
      if (i != stacks - 1) out.insert(out.end(), {a, c, b});
    }
  return out;
}

// A square of side `size` centred at `centre`, spanned by the unit vectors u and v.
inline std::vector<glm::vec3> QuadMesh(const glm::vec3& centre, const glm::vec3& u, const glm::vec3& v, float size) {
  const glm::vec3 a = centre - 0.5f * size * (u + v), b = centre + 0.5f * size * (u - v),
                  c = centre + 0.5f * size * (u + v), d = centre - 0.5f * size * (u - v);
  return {a, b, c, a, c, d};
}

}  // namespace odvr::testing
