#pragma once
// Small scenes and lightings for the renderer tests: indexed meshes with smooth normals as
// GltfScene primitives, and SG lightings with every HEALPix level filled; the scenes, views and
// lightings the renderer's pass tests share.
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <random>
#include <string>

#include "engine/lighting/sg_lighting.h"
#include "engine/render/pinhole_camera.h"
#include "engine/scene/gltf_scene.h"
#include "engine/sphere/healpix.h"

namespace odvr::testing {

inline scene::PbrMaterial Pbr(const std::string& name, glm::vec3 base, float metallic, float roughness) {
  scene::PbrMaterial m;
  m.name = name;
  m.base_color_factor = glm::vec4(base, 1);
  m.metallic_factor = metallic;
  m.roughness_factor = roughness;
  return m;
}

inline void Finish(scene::GltfScene* s) {
  s->bounds = {};
  for (const auto& p : s->primitives)
    for (const auto& v : p.positions) s->bounds.Extend(v);
}

// A UV sphere with smooth outward normals.
inline scene::ScenePrimitive SpherePrimitive(glm::vec3 centre, float radius, int material, int stacks = 24,
                                             int slices = 48) {
  scene::ScenePrimitive p;
  p.name = "sphere";
  p.material = material;
  for (int i = 0; i <= stacks; ++i)
    for (int j = 0; j <= slices; ++j) {
      const double th = std::numbers::pi * i / stacks, ph = 2 * std::numbers::pi * j / slices;
      const glm::vec3 n(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
      p.positions.push_back(centre + radius * n);
      p.normals.push_back(n);
    }
  const auto at = [&](int i, int j) { return static_cast<std::uint32_t>(i * (slices + 1) + j); };
  for (int i = 0; i < stacks; ++i)
    for (int j = 0; j < slices; ++j) {
      // Outward CCW: (i, j) → (i, j+1) → (i+1, j+1) seen from outside.
      p.indices.insert(p.indices.end(), {at(i, j), at(i, j + 1), at(i + 1, j + 1)});
      p.indices.insert(p.indices.end(), {at(i, j), at(i + 1, j + 1), at(i + 1, j)});
    }
  return p;
}

// An axis-aligned box with flat face normals (outward, CCW).
inline scene::ScenePrimitive BoxPrimitive(glm::vec3 lo, glm::vec3 hi, int material) {
  scene::ScenePrimitive p;
  p.name = "box";
  p.material = material;
  const glm::vec3 normals[6] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
  for (int f = 0; f < 6; ++f) {
    const glm::vec3 n = normals[f];
    const int axis = f / 2;
    const glm::vec3 u = axis == 0 ? glm::vec3(0, 1, 0) : (axis == 1 ? glm::vec3(0, 0, 1) : glm::vec3(1, 0, 0));
    const glm::vec3 v = glm::cross(n, u);
    const glm::vec3 c = 0.5f * (lo + hi) + 0.5f * n * (hi - lo);
    const glm::vec3 hu = 0.5f * u * (hi - lo), hv = 0.5f * v * (hi - lo);
    const auto base = static_cast<std::uint32_t>(p.positions.size());
    for (const glm::vec3& q : {c - hu - hv, c + hu - hv, c + hu + hv, c - hu + hv}) {
      p.positions.push_back(q);
      p.normals.push_back(n);
    }
    p.indices.insert(p.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  }
  return p;
}

// A lighting with every SRBF of levels 0..levels−1 (amplitudes from `radiance`, a smooth
// function of direction), an optional constant and peaks.
template <class Fn>
lighting::SgLighting FullLighting(int levels, Fn&& radiance, float scale_per_level = 0.5f) {
  lighting::SgLighting l;
  for (int s = 0; s < levels; ++s) {
    const auto& hp = sphere::Healpix(s);
    lighting::SgLevel level;
    level.level = s;
    level.lambda = hp.Lambda();
    for (int i = 0; i < hp.size(); ++i) {
      level.indices.push_back(i);
      level.amplitudes.push_back(radiance(hp.centre(i), s) * std::pow(scale_per_level, static_cast<float>(s)));
    }
    l.levels.push_back(level);
  }
  return l;
}

// A sky: bright above, dim below, warmer towards +X; positive everywhere.
inline glm::vec3 SkyRadiance(const glm::dvec3& d, int level) {
  const float up = static_cast<float>(0.5 + 0.5 * d.y), fx = static_cast<float>(0.5 + 0.5 * d.x);
  const float wiggle = level >= 2 ? static_cast<float>(0.5 + 0.5 * std::sin(5 * d.x + 3 * d.z)) : 1.f;
  return glm::vec3(0.2f + 0.6f * up + 0.2f * fx, 0.25f + 0.6f * up, 0.3f + 0.7f * up) * wiggle;
}

// The test views' size.
inline constexpr int kW = 96, kH = 64;

// A red glossy sphere beside a grey box on the ground.
inline scene::GltfScene SphereAndBox() {
  scene::GltfScene s;
  s.materials = {Pbr("paint", {0.6f, 0.1f, 0.05f}, 0.5f, 0.35f), Pbr("plastic", {0.5f, 0.5f, 0.5f}, 0.f, 0.8f)};
  s.primitives.push_back(SpherePrimitive({0, 0.5f, 0}, 0.5f, 0));
  s.primitives.push_back(BoxPrimitive({0.6f, 0, -0.6f}, {1.0f, 1.2f, 0.6f}, 1));
  Finish(&s);
  return s;
}

inline render::PinholeCamera View(int w = kW, int h = kH) {
  return render::PinholeCamera::LookAt({-1.2, 1.6, 3.2}, {0.2, 0.4, 0}, 40, w, h);
}

// Sky SGs on levels 0–3 plus a sun peak up and to the left, and a small constant.
inline lighting::SgLighting SunnySky(int levels = 4) {
  lighting::SgLighting l = FullLighting(levels, SkyRadiance);
  l.constant = glm::vec3(0.05f);
  l.peaks.push_back({glm::normalize(glm::dvec3(-0.6, 0.7, 0.3)), 3000.0, glm::vec3(2000.f, 1900.f, 1700.f)});
  return l;
}

inline scene::GltfScene LambertSphere() {
  scene::GltfScene s;
  s.materials = {Pbr("ball", {0.5f, 0.5f, 0.5f}, 0.f, 1.f)};
  s.primitives.push_back(SpherePrimitive({0, 1.0f, 0}, 0.5f, 0));
  Finish(&s);
  return s;
}

// A grey box floating 0.3 m above the ground, and a camera low beside it that sees its
// underside, front and side: the faces that see the ground it shadows.
inline scene::GltfScene FloatingBox() {
  scene::GltfScene car;
  car.materials = {Pbr("body", {0.5f, 0.5f, 0.5f}, 0.f, 0.9f)};
  car.primitives.push_back(BoxPrimitive({-1.0f, 0.3f, -0.5f}, {1.0f, 1.2f, 0.5f}, 0));
  Finish(&car);
  return car;
}

inline render::PinholeCamera FloatingBoxCamera() {
  return render::PinholeCamera::LookAt({-2.5, 0.2, 3.0}, {0, 0.6, 0}, 45, kW, kH);
}

}  // namespace odvr::testing
