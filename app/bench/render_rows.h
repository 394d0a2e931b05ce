#pragma once
// What `odvr bench render` makes of a Cycles reference, whether from the committed references,
// street_a's frame or a generalization set: the reference as the renderer takes it, one render
// of it at a configuration (a row), and the row's errors on the car's pixels.
#include <filesystem>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "engine/material/brdf.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/sphere/equirect.h"

namespace odvr::app::render_rows {

// The default configuration, the centre of the one-at-a-time sweep.
inline constexpr int kDefaultLevels = 5, kDefaultCones = 7, kDefaultVoxels = 128;

struct Row {
  std::string reference, method, lobes;  // method: "sg", "mc" or "mc-exact"; lobes: "iso-axis", ...
  int width = 0, height = 0;
  int levels = 0, cones = 0, voxels = 0, samples = 0;  // samples: MC rays per pixel
  int supersample = 1;
  double contrast = 0;  // RenderOptions::supersample_contrast (0 with supersample 1)
  double mean_rel = 0, rel_l1 = 0, bias = 0, ssim = 0, shadow_mae = -1;  // shadow_mae < 0: no shadow reference
  double shade_ms = 0, total_ms = 0;
  double frame_shade_ms = 0, frame_total_ms = 0;  // the HD row: as the window player renders (median)
  int car_pixels = 0, shadow_pixels = 0;
  // The car's silhouette by image rows (its top row to its bottom one): the errors over its upper
  // half and its lower quarter (sills, tyres, the lower bumper), where the ground's light lands.
  double upper_mean_rel = 0, upper_bias = 0, lower_mean_rel = 0, lower_bias = 0;
};

struct Reference {
  std::string name;
  sphere::EquirectImage env, rgb, shadow;  // shadow empty: none
  std::vector<float> mask;
  glm::dmat3 world_from_env{1.0};
  glm::dmat4 world_from_model{1.0};
  render::PinholeCamera camera;
  std::filesystem::path model;
  std::vector<render::MaterialOverride> materials;
  bool ground = true;  // Cycles' catcher under the car: RenderOptions::ground (and its shadow)
};

double Luma(const float* c);
// A reference's JSON file; throws odvr::Error naming it when it cannot be read or is not JSON.
nlohmann::json ReadJsonFile(const std::filesystem::path& path);
glm::dvec3 Vec3(const nlohmann::json& j);
// A reference's camera from its JSON (render_reference.py's "camera": position, target, up,
// vfov_deg, intrinsics_opencv width and height).
render::PinholeCamera CameraFromJson(const nlohmann::json& camera);
// A 4×4 matrix from its JSON rows (row-major).
glm::dmat4 Matrix4(const nlohmann::json& rows);

// Cycles' scene has the catcher under the car: seen from the car, below the horizon is that
// plane, diffuse albedo 0.18 (references.json), lit by the map's upper half. Both renderers here
// light from the map's lower half, so the map's lower half becomes that plane's radiance,
// 0.18 E / π, E the horizontal irradiance from the upper half; the car's own shadow on the plane,
// which Cycles does see, the renderers add (RenderOptions::ground_shadows_bounce). The plane
// ends (60 m): within `keep_below_horizon` radians under the horizon the car's rays pass beyond
// it and Cycles sees the map itself, which stays.
void ReplaceLowerHemisphereByGround(sphere::EquirectImage* env, double albedo, double keep_below_horizon);

// How far under the horizon the car's rays pass beyond Cycles' catcher: from the model's
// mid-height, at the mean distance from the centre of a square of half-size s to its edge,
// s (4/π) ln(1 + √2). A bright wall just under the horizon (studio.exr: mean radiance 2.9 within
// 5° under it, the stand-in 0.80) lit the car's sides in Cycles; replaced, studio_diffuse read 3.8 %
// dark (docs/notes/render_accuracy.md).
double KeepBelowHorizon(double mid_height);

// The errors of one render against its reference, into `row` (car pixels: covered fully in
// Cycles and in ours): mean relative error, rel. L1, bias, SSIM, the regions' errors, the shadow's.
void Score(const Reference& ref, const render::RenderResult& r, Row* row);

std::string LobeName(const material::LobeOptions& l);
// The lobe mode the defaults use (RenderOptions{}.lobes), as the rows name it.
std::string DefaultLobes();

// One row: `ref` rendered by `method` ("sg", "mc", "mc-exact") at the given configuration and
// scored; with a width, unscored at that size and timed as the window player renders instead.
// `base`: what every row starts from (RenderOptions' defaults but for the list options).
Row RenderRow(const render::RenderOptions& base, const Reference& ref, const std::string& method, int levels, int cones,
              int voxels, int samples, const material::LobeOptions& lobes, int width = 0, int height = 0,
              unsigned seed = 1, const std::string& images_dir = "", int supersample = 1, double contrast = 0);

}  // namespace odvr::app::render_rows
