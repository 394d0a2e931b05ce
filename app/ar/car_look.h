#pragma once
// What the player's panel edits and the augmented scene reads (app/ar/augmented_scene.h): the car's
// material and which parts of its light are used. Plain data and pure functions, so that what
// each control does is tested without a window.
#include <array>
#include <string>
#include <vector>

#include "engine/lighting/sg_lighting.h"
#include "engine/render/triple_product_renderer.h"

namespace odvr::app {

struct CarLook {
  enum class Model { kGltf, kPhong, kCookTorrance };
  Model model = Model::kGltf;  // kGltf: the model's own metallic-roughness materials
  // Overrides (every material of the car): diffuse (1 − ks)·colour plus a specular term of
  // weight ks, Phong with exponent phong_n, or Cook-Torrance (GGX α = roughness) whose Fresnel
  // reflectance at normal incidence is ks·fresnel_f0.
  std::array<float, 3> colour{0.55f, 0.06f, 0.05f};  // linear RGB
  double ks = 0.3;
  double phong_n = 60;
  double roughness = 0.25;
  double fresnel_f0 = 0.5;
  // The light: HEALPix levels of the residual transform used, its peaks (the sun), and whether
  // each peak traces its own visibility cone (sharp shadows) rather than the lobes' cones.
  std::array<bool, 6> levels{true, true, true, true, true, true};
  bool peaks = true;
  bool cones = true;

  void Check() const;  // throws odvr::UsageError naming the field
  bool operator==(const CarLook&) const = default;
};

// The renderer's overrides for the look's material (none for kGltf).
std::vector<render::MaterialOverride> MaterialOverrides(const CarLook& look);
// The light with the look's levels and peaks left out.
lighting::SgLighting ApplyLightToggles(lighting::SgLighting light, const CarLook& look);

}  // namespace odvr::app
