#include "engine/render/passes/monte_carlo_shade_pass.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/type_ptr.hpp>

#include "core/constants.h"
#include "engine/gl/shader_library.h"

namespace odvr::render {
namespace {

// The ground's unshadowed irradiance from the map's upper half (world up), which the exact ground
// lit fraction divides by (render_mc.comp's groundLitExact).
glm::dvec3 GroundIrradianceFromAbove(const sphere::EquirectImage& env, const glm::dmat3& world_from_env) {
  glm::dvec3 e(0);
  for (int y = 0; y < env.height; ++y) {
    const double lat = 0.5 * kPi - kPi * (y + 0.5) / env.height;
    const double d_omega = (2 * kPi / env.width) * (kPi / env.height) * std::cos(lat);
    for (int x = 0; x < env.width; ++x) {
      const double lon = kPi * (1 - 2 * (x + 0.5) / env.width);
      const glm::dvec3 d =
          world_from_env * glm::dvec3(std::cos(lat) * std::cos(lon), std::sin(lat), -std::cos(lat) * std::sin(lon));
      if (d.y <= 0) continue;
      for (int c = 0; c < 3; ++c) e[c] += env.at(x, y)[c] * d.y * d_omega;
    }
  }
  return e;
}

}  // namespace

MonteCarloShadePass::MonteCarloShadePass() : program_(gl::ShaderLibrary::Compute("render_mc.comp")) {}

void MonteCarloShadePass::SetEnvironment(const sphere::EquirectImage& equirect) {
  environment_ = equirect;
  // Texel probabilities ∝ (luminance + a floor) × solid angle; the floor (1e-3 of the mean)
  // keeps every direction reachable by this strategy alone.
  const int w = equirect.width, h = equirect.height;
  std::vector<double> lum(static_cast<std::size_t>(w) * h);
  double mean = 0;
  for (std::size_t i = 0; i < lum.size(); ++i) {
    const float* c = &equirect.rgb[3 * i];
    lum[i] = std::max(0.0, 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]);
    mean += lum[i] / static_cast<double>(lum.size());
  }
  const double floor_value = std::max(1e-3 * mean, 1e-12);
  std::vector<double> weight(lum.size());
  double total = 0;
  for (int y = 0; y < h; ++y) {
    const double sin_theta = std::sin(kPi * (y + 0.5) / h);
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      weight[i] = (lum[i] + floor_value) * sin_theta;
      total += weight[i];
    }
  }
  std::vector<float> prob(lum.size()), rows(static_cast<std::size_t>(h) + 1, 0.f),
      cols(static_cast<std::size_t>(h) * (w + 1), 0.f);
  double row_acc = 0;
  for (int y = 0; y < h; ++y) {
    double row_sum = 0;
    for (int x = 0; x < w; ++x) row_sum += weight[static_cast<std::size_t>(y) * w + x];
    double acc = 0;
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      prob[i] = static_cast<float>(weight[i] / total);
      acc += weight[i];
      cols[static_cast<std::size_t>(y) * (w + 1) + x + 1] = static_cast<float>(acc / row_sum);
    }
    cols[static_cast<std::size_t>(y) * (w + 1) + w] = 1.f;
    row_acc += row_sum;
    rows[static_cast<std::size_t>(y) + 1] = static_cast<float>(row_acc / total);
  }
  rows[static_cast<std::size_t>(h)] = 1.f;
  env_row_cdf_ = MakeBuffer(rows);
  env_col_cdf_ = MakeBuffer(cols);
  env_texel_prob_ = MakeBuffer(prob);
  environment_texture_ = gl::Texture::Create2D(GL_RGB32F, w, h);
  environment_texture_.Upload2D(GL_RGB, GL_FLOAT, equirect.rgb.data());
  environment_texture_.SetFilter(GL_NEAREST, GL_NEAREST);
}

void MonteCarloShadePass::Run(const RenderFrame& fr, const ShadeScene& scene, RenderTargets& targets) {
  BindShadeInputs(fr, scene, targets);
  const detail::PreparedLighting& lighting = scene.lighting.prepared();
  const visibility::VoxelGridSpec& spec = scene.voxels.spec();
  const RenderOptions& o = fr.options;
  const PinholeCamera& camera = fr.camera;
  const glm::mat3 wfc(camera.world_from_camera), efw(lighting.env_from_world);
  gl::Program& mp = program_;
  glProgramUniform2i(mp.id(), mp.Uniform("uSize"), fr.sw, fr.sh);
  glProgramUniform1ui(mp.id(), mp.Uniform("uSeed"), o.monte_carlo_seed);
  mp.Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
         static_cast<float>(camera.position.z))
      .SetMat3("uWorldFromCamera", glm::value_ptr(wfc))
      .Set("uFocal", static_cast<float>(fr.sf))
      .SetMat3("uEnvFromWorld", glm::value_ptr(efw))
      .Set("uTermsPerMaterial", TripleProductRenderer::kTermsPerMaterial)
      .Set("uMaterialCount", scene.materials.count())
      .Set("uSurfaceOffset", static_cast<float>(o.surface_offset_voxels * spec.voxel_size))
      .Set("uGround", o.ground ? 1 : 0)
      .Set("uGroundCenter", static_cast<float>(fr.ground_centre.x), static_cast<float>(fr.ground_centre.y))
      .Set("uGroundHalfSize", static_cast<float>(o.ground_half_size))
      .Set("uGroundShadowsBounce", o.ground && o.ground_shadows_bounce ? 1 : 0)
      .Set("uGroundLitHalfAngle", static_cast<float>(kGroundLitHalfAngle))
      .Set("uSamples", o.monte_carlo_samples)
      // A ray of a voxel's width: level 0 all along (cone_trace.glsl clamps the diameter).
      .Set("uShadowRayHalfAngle", 1e-4f)
      .Set("uExactTriangles", fr.geometry ? scene.model.bvh_triangle_count() : 0)
      // Off the surface by a millimetre: the G-buffer's positions are interpolated in float.
      .Set("uExactRayOffset", detail::ExactRayOffset(spec.voxel_size))
      .Set("uExactVisibility", o.monte_carlo_exact_visibility ? 1 : 0);
  if (o.monte_carlo_exact_visibility) {
    const glm::dvec3 e = GroundIrradianceFromAbove(environment_, glm::transpose(lighting.env_from_world));
    mp.Set("uGroundIrradiance", static_cast<float>(e.x), static_cast<float>(e.y), static_cast<float>(e.z));
  }
  SetGroundPeakUniforms(mp, lighting, o.peak_cones);
  SetConeTraceUniforms(mp, spec, fr.geometry, o.trace);
  environment_texture_.BindUnit(1);
  env_row_cdf_.BindBase(GL_SHADER_STORAGE_BUFFER, 8);
  env_col_cdf_.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
  env_texel_prob_.BindBase(GL_SHADER_STORAGE_BUFFER, 10);
  if (scene.model.bvh_triangle_count() > 0) {
    scene.model.bvh_nodes().BindBase(GL_SHADER_STORAGE_BUFFER, 11);
    scene.model.bvh_triangles().BindBase(GL_SHADER_STORAGE_BUFFER, 12);
  }
  mp.Use().DispatchCovering(static_cast<unsigned>(fr.sw), static_cast<unsigned>(fr.sh));
}

}  // namespace odvr::render
